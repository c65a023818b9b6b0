//! Scenes in and out: glTF, GLB and (later) OBJ files turned into primitives the tangent core can
//! take, and written back with only the members tspace changed.
//!
//! Everything here reads untrusted bytes. Nothing panics on them, every allocation is bounded by
//! the bytes actually present or by an explicit limit, and every recursion has a depth limit.

pub mod gltf;
pub mod uri;
