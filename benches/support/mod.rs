//! Pieces of the `tangents` bench binary. A folder without `main.rs`, so Cargo does not take it
//! for a bench target of its own.

pub mod alloc;
pub mod chart;
pub mod contenders;
pub mod corpus;
pub mod cpu;
