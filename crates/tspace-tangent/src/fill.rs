//! Large working arrays, initialized by every thread at once, or not at all.
//!
//! `vec![x; n]` zero-fills through the allocator only for plain zeros; arrays of structs or
//! atomics are written element by element on one thread, and the page faults of a fresh
//! allocation are taken on that thread too. For the tens of megabytes a large mesh needs, that
//! serial start was a tenth of a two-thread run. Where the array's first values are zero bytes
//! and the pass that computes it writes it in order, it is instead allocated zeroed
//! ([`zeroed`]), and that pass takes the page faults.

use rayon::prelude::*;

/// Below this many elements one thread fills the array: splitting costs more than it saves.
const PARALLEL_FROM: usize = 1 << 16;

/// A vector of `len` values made by `make`, filled in parallel when `parallel` is set.
pub(crate) fn filled<T: Send>(len: usize, parallel: bool, make: impl Fn() -> T + Sync) -> Vec<T> {
    if parallel && len >= PARALLEL_FROM {
        (0..len)
            .into_par_iter()
            .with_min_len(PARALLEL_FROM / 4)
            .map(|_| make())
            .collect()
    } else {
        (0..len).map(|_| make()).collect()
    }
}

/// Plain data whose every byte may be zero: a value of all zero bytes is a valid one.
///
/// # Safety
/// Implement only for types for which a block of zero bytes is a valid value (no references,
/// no `NonZero` niches, no enums without a zero discriminant).
pub(crate) unsafe trait Zeroable {}

// SAFETY: zero bytes are the float zero, and arrays of such values are such values.
unsafe impl Zeroable for f32 {}
unsafe impl<T: Zeroable, const N: usize> Zeroable for [T; N] {}

/// A vector of `len` values of zero bytes, allocated zeroed rather than filled. A large block
/// comes from the kernel already zeroed (glibc's `calloc` then writes nothing), so the first
/// pass to write it, the one that computes its values, is also the first to touch its pages:
/// no pass of stores before it. A block the allocator reuses is zeroed by `calloc`'s `memset`,
/// as a fill would. Only for arrays written in order, where the page faults the first writes
/// take come one after another (taken at random, in arrays written by vertex, they cost more
/// than the fill they spare: see `docs/benchmarks.md`).
pub(crate) fn zeroed<T: Zeroable>(len: usize) -> Vec<T> {
    let layout = std::alloc::Layout::array::<T>(len).expect("an array the size of a mesh's");
    if layout.size() == 0 {
        // SAFETY: `T` is `Zeroable`, so zero bytes (here none) are a valid value.
        return (0..len).map(|_| unsafe { std::mem::zeroed() }).collect();
    }
    // SAFETY: the layout's size is not zero.
    let block = unsafe { std::alloc::alloc_zeroed(layout) };
    if block.is_null() {
        std::alloc::handle_alloc_error(layout);
    }
    // SAFETY: `block` was allocated by the global allocator with the layout of `len` values of
    // `T` (its alignment and size, `len * size_of::<T>()`), and every byte of it is zero, which
    // is a valid `T` (`Zeroable`): `len` initialized values of capacity `len`.
    unsafe { Vec::from_raw_parts(block.cast::<T>(), len, len) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zeroed_vectors_hold_zeros_and_grow_as_others() {
        for len in [0, 1, 3, 1 << 20] {
            let mut v = zeroed::<[f32; 4]>(len);
            assert_eq!(v.len(), len);
            assert!(v.iter().all(|x| *x == [0.0; 4]));
            v.push([1.0; 4]);
            assert_eq!(v[len], [1.0; 4]);
        }
    }
}
