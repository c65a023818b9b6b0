pub mod tangent;
