pub mod scene;
pub mod tangent;
