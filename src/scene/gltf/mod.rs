//! glTF 2.0: the GLB container, the accessor decoder, and the lossless JSON reader and splice
//! editor that lets output keep every byte of the input it did not change.

pub mod accessor;
pub mod glb;
pub mod json;
pub mod meshopt;
