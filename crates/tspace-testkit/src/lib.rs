//! What the tests, benches and fuzz targets share, in one dev-only crate, so that no file
//! includes another by path and nothing is restated.
//!
//! The design decision: everything here serves checking tspace, never running it. It may panic
//! on bad input, lean on heavy crates (`gltf`, `proptest`, `serde_json`) and read files by path;
//! that is why it is a crate of its own that only `[dev-dependencies]` name, and why nothing in
//! it is reachable from the `tspace` binary.
//!
//! - [`reference`](mod@reference): the oracle, `bevy_mikktspace` 1.0.
//! - [`invariants`]: what every emitted tangent and split plan must satisfy, checked by the
//!   property tests and the `core` fuzz target alike.
//! - [`shapes`], [`random_mesh`]: generated meshes: a sphere and a torus with exact tangents,
//!   and proptest strategies for damaged ones.
//! - [`meshes`]: reading known-good glTF and OBJ files (through the `gltf` crate) for oracles.
//! - [`fixtures`], [`glb_builder`]: the project's test files, and small GLBs built in tests.
//! - [`validator`]: the Khronos glTF-Validator, run under Node.js where installed.
//! - [`process`]: the real `tspace serve` as a child process.
//! - [`fuzz`]: the fuzz targets' bodies, so `tests/fuzz_replay.rs` replays exactly what the
//!   fuzzers ran.
//! - [`written`]: tspace's output read back through its own decoders (meshopt, quantized), and
//!   its tangents checked against the reference on the written geometry.

pub mod fixtures;
pub mod fuzz;
pub mod glb_builder;
pub mod invariants;
pub mod json_heavy;
pub mod meshes;
pub mod process;
pub mod random_mesh;
pub mod reference;
pub mod shapes;
pub mod validator;
pub mod written;

pub use fixtures::{assert_valid_output, fixture, glb_json};
pub use reference::{reference_is_valid, reference_tangents};
pub use shapes::angle_degrees;
