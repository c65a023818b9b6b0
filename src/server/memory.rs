//! How the service's freed memory is kept for its next requests, and when it is given back.
//!
//! Every scene request buffers megabytes: the body as it arrives, the whole body, the written
//! scene. By default glibc maps blocks of 128 KiB and more afresh and trims the top of a heap
//! once 128 KiB lie free there, raising both thresholds to the largest block freed; a service
//! of megabyte buffers kept crossing them, so each request's buffers came from fresh pages. On
//! DamagedHelmet (3.8 MB), one client posting it 200 times with curl: 650–2,100 page faults a
//! request, and the kernel zeroing and unmapping those pages was a fifth of the server's CPU.
//! With fixed thresholds (blocks under 8 MiB from the heaps, a heap's top trimmed once 16 MiB
//! lie free there) the same loop makes 1–5 faults a request, and the server spends 4.9–7.3 ms
//! of CPU a request instead of 8.2–10.2; in the load test the capacity rose 7% and the
//! goodput at twice it 10% (docs/benchmarks.md). Larger blocks are mapped and unmapped whole,
//! as before.
//!
//! The thresholds bound what is kept. A body refused at the limit (a compression bomb decoded up to
//! `--body-limit`) leaves that much freed in the arena of the connection thread that read it, while
//! the next one lands in another thread's arena; so after such a refusal the free memory of every
//! arena is handed back ([`give_back_freed_memory`](crate::memory::give_back_freed_memory)).
//! Measured before any of this: two bombs refused one after the other grew the peak RSS by 63 MiB
//! and then 130 MiB at a 64 MiB limit, and the server went on holding 63 MiB. `malloc_trim` cannot
//! release the free top of a thread's heap, which the trim threshold bounds: with blocks up to 32
//! MiB from the heaps and 64 MiB kept at their tops (tried first; it would also have kept the
//! buffers of scenes of tens of megabytes), two bombs left 34–95 MiB behind; with these thresholds,
//! 1–2 MiB.
//!
//! The same hand-back runs once more where one request frees much in small blocks and then
//! asks for one large block: the scene layer frees the parse tree of a document of megabytes
//! (several times its text) and then puts the output's JSON together, about the size of that
//! text, mapped afresh since it is above the mapping threshold. Keeping the tree's memory as
//! well raised the peak on the JSON-heavy scene without normals (27 MB) to 288 MB; handed
//! back, 262 MB.
//!
//! The command line hands the tree's memory back the same way (see [`crate::memory`]).
//!
//! Tried before and not kept: a fixed *small* mapping threshold (128 KiB or 1 MiB), which
//! kept every large buffer out of the heaps and halved the capacity in the load test, since
//! every request's buffers were then faulted in afresh.

/// Blocks under this size come from the allocator's heaps; larger ones are mapped whole.
pub(super) const MAPPED_FROM: usize = 8 << 20;

/// A heap's top is trimmed once this much lies free there.
const TRIMMED_FROM: i32 = 16 << 20;

/// Keeps the megabyte buffers scene requests free for the next requests (see the module's
/// documentation). Process-wide; called when a server starts.
pub fn keep_freed_memory_for_reuse() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only changes the allocator's thresholds; it is thread-safe.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, MAPPED_FROM as i32);
        libc::mallopt(libc::M_TRIM_THRESHOLD, TRIMMED_FROM);
    }
}
