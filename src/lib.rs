pub mod cli;
pub mod config;
#[doc(hidden)]
pub mod fuzz_targets;
pub mod scene;
pub mod server;
