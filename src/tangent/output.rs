//! Per-corner results written straight into their final place, from one thread or from many.
//!
//! The methods work vertex by vertex, so each worker writes the corners around its vertices:
//! places scattered over the whole output, but every place written by exactly one worker. Safe
//! Rust has no `&mut` for such a pattern; relaxed atomic stores of the four lanes compile to plain
//! stores, and the buffer is converted back in place (same size and alignment) when done. A single
//! thread writes to a plain slice and skips that conversion.

use std::sync::atomic::{AtomicU32, Ordering};

/// Per-corner output shared between workers.
pub(crate) struct SharedCorners(Vec<[AtomicU32; 4]>);

impl SharedCorners {
    pub fn new(corner_count: usize) -> SharedCorners {
        SharedCorners(
            (0..corner_count)
                .map(|_| [const { AtomicU32::new(0) }; 4])
                .collect(),
        )
    }

    #[inline]
    pub fn put(&self, corner: usize, tangent: [f32; 4]) {
        let place = &self.0[corner];
        for (lane, value) in place.iter().zip(tangent) {
            // Each corner is written by one worker, and rayon's join publishes the writes before
            // the buffer is read, so no ordering is needed here.
            lane.store(value.to_bits(), Ordering::Relaxed);
        }
    }

    pub fn into_vec(self) -> Vec<[f32; 4]> {
        // Same size and alignment, so the standard library reuses the allocation.
        self.0
            .into_iter()
            .map(|lanes| lanes.map(|lane| f32::from_bits(lane.into_inner())))
            .collect()
    }
}
