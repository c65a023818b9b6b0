//! Giving memory back to the system after a request that buffered a great deal for nothing.
//!
//! glibc keeps memory freed in its per-thread arenas for reuse, which is what a service wants
//! for the buffers every request needs. But a body refused at the limit (a compression bomb
//! decoded up to `--body-limit`) leaves that much freed in the arena of the connection thread
//! that read it, and the next one lands in another thread's arena. Measured: two bombs refused
//! one after the other grew the peak RSS by 63 MiB and then 130 MiB at a 64 MiB limit, and the
//! server went on holding 63 MiB. So after such a refusal the free memory of every arena is
//! handed back (`malloc_trim`). Keeping large blocks out of the arenas altogether (a fixed
//! `M_MMAP_THRESHOLD` of 128 KiB or 1 MiB) also fixed it, but halved the service's capacity in
//! the load test: every request's megabyte buffers were then mapped and faulted in afresh.

/// Returns the allocator's free memory to the system. Called after a request whose body was
/// refused at the limit; its cost, a walk over the arenas, is small beside reading that body.
pub fn give_back_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only releases free memory; it is thread-safe.
    unsafe {
        libc::malloc_trim(0);
    }
}
