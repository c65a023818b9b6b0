//! A hint to the cache that a value will be read soon.
//!
//! The per-vertex and welding passes read arrays at addresses they know well before they need
//! them (the next vertices' slots, the next corners' records). Touching those with an ordinary
//! load, as safe code can, makes the load a dependency that holds up the pipeline when it
//! misses; a prefetch instruction retires at once and lets the miss overlap the work before it.

/// Asks for the cache line holding `value` to be fetched; on other architectures, nothing.
#[inline(always)]
pub(crate) fn prefetch<T>(value: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch is only a hint: it reads no memory the program can observe and cannot
    // fault, and SSE, which it needs, is part of the x86-64 baseline.
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(
            (value as *const T).cast(),
        )
    };
    #[cfg(not(target_arch = "x86_64"))]
    let _ = value;
}
