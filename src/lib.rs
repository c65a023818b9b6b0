//! tspace adds glTF `TANGENT` attributes: the root library behind the `tspace` binary.
//!
//! It holds the layers above the pure crates: [`scene`] reads glTF, GLB and OBJ scenes, computes
//! tangents with `tspace-tangent` and writes the scenes back through `tspace-json`'s lossless
//! editor (and `tspace-meshopt`'s decoder); [`server`] is the HTTP service, [`cli`] the command
//! line, [`config`] the service's settings, and [`memory`] the allocator's freed memory handed back
//! where keeping it would raise the peak.
//!
//! The design: the server and the command line are thin transports over one scene entry point
//! ([`scene::input::process`]), and the scene layer over crates that do pure computation on
//! bytes and numbers. So what is read, decided and written is the same everywhere, the scene
//! layer knows nothing of HTTP or of the command line (its errors carry a transport-agnostic
//! [`scene::error::ProblemCode`]), and the crates know nothing of scenes.

pub mod cli;
pub mod config;
pub mod memory;
pub mod scene;
pub mod server;
