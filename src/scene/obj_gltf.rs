//! OBJ (+ MTL) to a glTF document (in progress).
