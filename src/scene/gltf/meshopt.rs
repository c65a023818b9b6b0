//! EXT_meshopt_compression: decoding of meshoptimizer-compressed buffer views (in progress).
