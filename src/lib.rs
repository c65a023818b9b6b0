pub mod cli;
pub mod config;
pub mod scene;
pub mod server;
pub mod tangent;
