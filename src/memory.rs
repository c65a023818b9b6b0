//! The allocator's freed memory, handed back to the system where holding it would raise the
//! peak: shared by the service (`server::memory`, which also sets how much the allocator keeps)
//! and the command line.
//!
//! The case both meet: the scene layer frees the parse tree of a document of megabytes, all of
//! it small blocks, and then puts the output's JSON together, one block about the size of the
//! document's text and too large to come from the freed tree (glibc maps blocks over 32 MiB
//! afresh, whatever its thresholds). A process that keeps the tree's memory holds both.
//! Measured on the command line (`tspace process`, `/usr/bin/time`, 2026-11-28): the
//! JSON-heavy scene written with `--compress meshopt` (35.7 MB, a 72 MB output document) peaked
//! at 399 MiB keeping it and at 342 MiB handing it back; the same scene without normals at 251
//! and 233 MiB. Ten interleaved runs of each put the hand-back's cost below what they could
//! tell apart (0.82 s against 0.82 s of wall time, 0.90 against 0.89 s of CPU).

/// Returns the allocator's free memory to the system: the free pages inside every heap and
/// the main heap's top. Called by the service after a request whose body was refused at the
/// limit, and by the scene layer once it has freed the parse tree of a large document
/// ([`SceneOptions::release_freed_memory`](crate::scene::SceneOptions::release_freed_memory));
/// its cost, a walk over the arenas (8–10 ms after a 27 MB JSON-heavy scene's tree), is small
/// beside reading that body or building that tree.
pub fn give_back_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only releases free memory; it is thread-safe.
    unsafe {
        libc::malloc_trim(0);
    }
}
