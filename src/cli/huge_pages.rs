//! Large allocations on transparent huge pages, for the one-shot commands.
//!
//! A command that processes a large mesh and exits touches every page of its working arrays
//! once, so it pays a page fault per 4 KiB: 56,800 faults for the 2M-triangle sphere of the
//! `whole_path` bench, about a fifth of its time. Linux's transparent huge pages serve such
//! arrays in 2 MiB pages, but where the kernel is set to `madvise` (as on this project's
//! machines, and Ubuntu's default) only for memory a program asks for, so the allocator asks
//! for every allocation of 4 MiB or more (where the setting is `always`, the advice changes
//! nothing; where it is `never`, it is ignored). Measured, interleaved runs of each binary on
//! that sphere: 15,400 faults instead of 56,800, and a median of 0.26 s instead of 0.315–0.33 s;
//! smaller scenes never reach the threshold.
//!
//! Only the commands turn it on ([`enable`]); the service does not. A long-running server
//! reuses its allocator's memory across requests, and a huge page fault may stall to compact
//! memory, which a service would rather not do in the middle of a request.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, Ordering};

/// Allocations at least this large are advised.
const ADVISED_FROM: usize = 4 << 20;

/// The size (and alignment) of a transparent huge page on x86-64 and most aarch64 kernels.
const HUGE_PAGE: usize = 2 << 20;

static ENABLED: AtomicBool = AtomicBool::new(false);

/// From now on, large allocations ask for huge pages (when the binary's allocator is
/// [`LargeOnHugePages`]).
pub fn enable() {
    ENABLED.store(true, Ordering::Relaxed);
}

/// The system allocator, advising the kernel to back large allocations with huge pages once
/// [`enable`]d. The binary makes it the global allocator; the library does not, so that tests
/// and benches keep their own.
pub struct LargeOnHugePages;

// SAFETY: every call is passed to the system allocator unchanged; the advice only changes how
// the kernel backs pages of the block returned, never its contents or its extent.
unsafe impl GlobalAlloc for LargeOnHugePages {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract for `alloc` is passed on unchanged.
        let block = unsafe { System.alloc(layout) };
        advise(block, layout.size());
        block
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: as for `alloc`.
        let block = unsafe { System.alloc_zeroed(layout) };
        advise(block, layout.size());
        block
    }

    unsafe fn dealloc(&self, block: *mut u8, layout: Layout) {
        // SAFETY: as for `alloc`.
        unsafe { System.dealloc(block, layout) }
    }

    unsafe fn realloc(&self, block: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: as for `alloc`.
        let moved = unsafe { System.realloc(block, layout, new_size) };
        advise(moved, new_size);
        moved
    }
}

/// Advises huge pages for the whole huge pages inside the block (its ends are shared with
/// whatever the allocator put beside it, and keep normal pages).
fn advise(block: *mut u8, size: usize) {
    if size < ADVISED_FROM || block.is_null() || !ENABLED.load(Ordering::Relaxed) {
        return;
    }
    let start = (block as usize).next_multiple_of(HUGE_PAGE);
    let end = (block as usize).saturating_add(size) & !(HUGE_PAGE - 1);
    if end > start {
        advise_range(start, end - start);
    }
}

#[cfg(target_os = "linux")]
fn advise_range(start: usize, len: usize) {
    // SAFETY: the range lies inside a block the allocator just handed out; MADV_HUGEPAGE only
    // changes how its pages are backed. A refusal (no THP in this kernel) leaves it as it was.
    unsafe {
        libc::madvise(start as *mut libc::c_void, len, libc::MADV_HUGEPAGE);
    }
}

#[cfg(not(target_os = "linux"))]
fn advise_range(_start: usize, _len: usize) {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_keep_their_contents_through_the_allocator() {
        enable();
        let allocator = LargeOnHugePages;
        for size in [
            16,
            ADVISED_FROM - 1,
            ADVISED_FROM,
            ADVISED_FROM + 3 * HUGE_PAGE + 5,
        ] {
            let layout = Layout::from_size_align(size, 16).unwrap();
            // SAFETY: a non-zero size; the block is written within its size and freed with
            // the layout it was made with.
            unsafe {
                let block = allocator.alloc_zeroed(layout);
                assert!(!block.is_null());
                assert!(
                    std::slice::from_raw_parts(block, size)
                        .iter()
                        .all(|&b| b == 0)
                );
                block.write_bytes(7, size);
                let grown = allocator.realloc(block, layout, size * 2);
                assert!(
                    std::slice::from_raw_parts(grown, size)
                        .iter()
                        .all(|&b| b == 7)
                );
                allocator.dealloc(grown, Layout::from_size_align(size * 2, 16).unwrap());
            }
        }
    }

    /// The `VmFlags` of the mapping that holds `address`, from `/proc/self/smaps`.
    #[cfg(target_os = "linux")]
    fn flags_at(address: usize) -> Option<String> {
        let smaps = std::fs::read_to_string("/proc/self/smaps").ok()?;
        let mut inside = false;
        for line in smaps.lines() {
            if let Some((range, _)) = line.split_once(' ')
                && let Some((from, to)) = range.split_once('-')
                && let (Ok(from), Ok(to)) = (
                    usize::from_str_radix(from, 16),
                    usize::from_str_radix(to, 16),
                )
            {
                inside = (from..to).contains(&address);
            } else if inside && let Some(flags) = line.strip_prefix("VmFlags:") {
                return Some(flags.trim().to_owned());
            }
        }
        None
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn a_large_block_is_advised() {
        if !std::path::Path::new("/sys/kernel/mm/transparent_hugepage").exists() {
            eprintln!("skipped: this kernel has no transparent huge pages");
            return;
        }
        enable();
        let allocator = LargeOnHugePages;
        let large = Layout::from_size_align(ADVISED_FROM + 2 * HUGE_PAGE, 16).unwrap();
        // SAFETY: a non-zero size, freed with the layout it was made with.
        unsafe {
            let block = allocator.alloc(large);
            let inner = (block as usize).next_multiple_of(HUGE_PAGE);
            let flags = flags_at(inner).unwrap_or_default();
            allocator.dealloc(block, large);
            // `hg`: the kernel's VM_HUGEPAGE, set by MADV_HUGEPAGE.
            assert!(flags.split(' ').any(|f| f == "hg"), "{flags}");
        }
    }
}
