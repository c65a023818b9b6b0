//! A counting wrapper around the system allocator, so the bench can report how much heap a
//! generator needs on top of its input and output.
//!
//! It tracks the bytes currently allocated and the highest value reached since the last
//! [`peak_during`] started. Counters are relaxed atomics: rayon's worker threads allocate too,
//! and an exact global order is not needed for a byte count. The cost (two atomic operations per
//! allocation) is paid by every contender alike, and the generators allocate a few large buffers
//! rather than many small ones.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

pub struct CountingAllocator;

static CURRENT: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

fn record_growth(bytes: usize) {
    let now = CURRENT.fetch_add(bytes, Ordering::Relaxed) + bytes;
    PEAK.fetch_max(now, Ordering::Relaxed);
}

fn record_shrink(bytes: usize) {
    CURRENT.fetch_sub(bytes, Ordering::Relaxed);
}

// SAFETY: every call is forwarded unchanged to `System`; the wrapper only counts sizes.
unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: same contract as our caller's.
        let ptr = unsafe { System.alloc(layout) };
        if !ptr.is_null() {
            record_growth(layout.size());
        }
        ptr
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // Kept distinct from `alloc` so that `vec![0; n]` still gets lazily zeroed pages, as it
        // would without the wrapper.
        // SAFETY: same contract as our caller's.
        let ptr = unsafe { System.alloc_zeroed(layout) };
        if !ptr.is_null() {
            record_growth(layout.size());
        }
        ptr
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as our caller's.
        unsafe { System.dealloc(ptr, layout) };
        record_shrink(layout.size());
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: same contract as our caller's.
        let new_ptr = unsafe { System.realloc(ptr, layout, new_size) };
        if !new_ptr.is_null() {
            if new_size >= layout.size() {
                record_growth(new_size - layout.size());
            } else {
                record_shrink(layout.size() - new_size);
            }
        }
        new_ptr
    }
}

/// Heap use of one call.
#[derive(Clone, Copy, Debug)]
pub struct HeapUse {
    /// Highest heap level reached during the call, above the level before it.
    pub peak: usize,
    /// Bytes still allocated when the call returned, above the level before it: the returned
    /// value (the generators keep no global state).
    pub retained: usize,
}

impl HeapUse {
    /// Peak heap beyond what the returned value itself occupies: the generator's scratch memory.
    pub fn extra(&self) -> usize {
        self.peak.saturating_sub(self.retained)
    }
}

/// Runs `f` and reports its heap use. Not reentrant: do not nest, and keep other threads quiet.
pub fn peak_during<R>(f: impl FnOnce() -> R) -> (R, HeapUse) {
    let before = CURRENT.load(Ordering::Relaxed);
    PEAK.store(before, Ordering::Relaxed);
    let result = f();
    let after = CURRENT.load(Ordering::Relaxed);
    let peak = PEAK.load(Ordering::Relaxed);
    let usage = HeapUse {
        peak: peak.saturating_sub(before),
        retained: after.saturating_sub(before),
    };
    (result, usage)
}
