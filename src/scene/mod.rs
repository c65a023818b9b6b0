//! Scenes in and out: glTF, GLB and OBJ files turned into primitives the tangent core can take,
//! and written back with only the members tspace changed. `uri` decides what a glTF's URIs may
//! name (data, caller-supplied parts, or on the command line a file beside it); `obj` reads
//! Wavefront OBJ and MTL.
//!
//! Everything here reads untrusted bytes. Nothing panics on them, every allocation is bounded by
//! the bytes actually present or by an explicit limit, and every recursion has a depth limit.

pub mod error;
pub mod folder;
pub mod gltf;
pub mod input;
pub mod layout;
pub mod obj;
pub mod obj_gltf;
pub mod options;
pub mod pictures;
pub mod pieces;
pub mod report;
pub mod uri;

pub use options::{Normals, OutputFormat, Processed, SceneLimits, SceneOptions, TangentType};

/// A position in one of a document's JSON arrays in 32 bits, as the per-primitive records hold
/// it (a scene may have a hundred thousand primitives): every element of such an array takes
/// at least a byte of a text under 4 GiB, so every position fits.
pub fn index32(index: usize) -> u32 {
    u32::try_from(index).unwrap_or(u32::MAX)
}
