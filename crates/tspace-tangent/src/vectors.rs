//! Column loops compiled for the widest vector extension the CPU has.
//!
//! The crate is built for the x86-64 baseline (SSE2), so that one binary runs anywhere. The
//! loops that carry the arithmetic (a batch of triangles, a batch of corners) are also compiled
//! for AVX2 and AVX-512 and chosen at run time. Only the vector width changes: Rust never fuses a
//! multiply and an add unless asked (`mul_add`), so every operation rounds as in the baseline
//! build and the results are bit-identical whichever runs.

/// Inside an `impl`, defines method `$name`, which runs the `#[inline(always)]` method
/// `$portable` compiled for AVX-512F or AVX2 when the CPU has them (through the methods `$avx512`
/// and `$avx2`, which it also defines), else as built.
///
/// A macro rather than a function taking a closure: a closure's body is not reliably inlined
/// into the function that carries the target features, and then it runs without them (the
/// column loops lost a third of their speed that way).
macro_rules! widest_vectors {
    (
        $(#[$doc:meta])*
        fn $name:ident / $avx512:ident / $avx2:ident
            (&mut self $(, $arg:ident: $ty:ty)* $(,)?) => $portable:ident
    ) => {
        $(#[$doc])*
        fn $name(&mut self $(, $arg: $ty)*) {
            #[cfg(target_arch = "x86_64")]
            {
                if std::arch::is_x86_feature_detected!("avx512f") {
                    // SAFETY: the CPU was just found to support AVX-512F, the only requirement.
                    return unsafe { self.$avx512($($arg),*) };
                }
                if std::arch::is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU was just found to support AVX2, the only requirement.
                    return unsafe { self.$avx2($($arg),*) };
                }
            }
            self.$portable($($arg),*)
        }

        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx512f")]
        unsafe fn $avx512(&mut self $(, $arg: $ty)*) {
            self.$portable($($arg),*)
        }

        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2")]
        unsafe fn $avx2(&mut self $(, $arg: $ty)*) {
            self.$portable($($arg),*)
        }
    };
}

pub(crate) use widest_vectors;
