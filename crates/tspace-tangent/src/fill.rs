//! Large working arrays, initialized by every thread at once.
//!
//! `vec![x; n]` zero-fills through the allocator only for plain zeros; arrays of structs or
//! atomics are written element by element on one thread, and the page faults of a fresh
//! allocation are taken on that thread too. For the tens of megabytes a large mesh needs, that
//! serial start was a tenth of a two-thread run.

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
