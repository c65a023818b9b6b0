//! Welding: which vertices are the same point of the surface, and which corners meet at each.
//!
//! MikkTSpace treats two corners as one vertex when position, normal and texture coordinate are
//! all equal as floats (so `-0 == 0`, and NaN equals nothing). We compute the same classes with an
//! open-addressing hash table over the input vertices, which for indexed meshes is half the work
//! of hashing every corner as the reference does.

use super::math::Mesh;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU32, Ordering};

/// Sentinel for "no entry" in index arrays.
pub(crate) const NONE: u32 = u32::MAX;

/// Maps every input vertex to a dense class id `0..class_count`.
pub(crate) struct Weld {
    pub class_of_vertex: Vec<u32>,
    pub class_count: usize,
}

#[inline]
fn canonical_bits(x: f32) -> u32 {
    // -0.0 and 0.0 compare equal, so they must hash equally.
    if x == 0.0 { 0 } else { x.to_bits() }
}

#[inline]
fn mix(h: u64, x: u32) -> u64 {
    (h ^ x as u64)
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .rotate_left(29)
}

/// Vertex identity over position, and optionally normal and texture coordinate.
pub(crate) struct Key<'a> {
    pub positions: &'a [[f32; 3]],
    pub normals: Option<&'a [[f32; 3]]>,
    pub uvs: Option<&'a [[f32; 2]]>,
}

impl Key<'_> {
    #[inline]
    fn hash(&self, v: usize) -> u64 {
        let p = self.positions[v];
        let mut h = mix(
            mix(mix(0, canonical_bits(p[0])), canonical_bits(p[1])),
            canonical_bits(p[2]),
        );
        if let Some(normals) = self.normals {
            let n = normals[v];
            h = mix(
                mix(mix(h, canonical_bits(n[0])), canonical_bits(n[1])),
                canonical_bits(n[2]),
            );
        }
        if let Some(uvs) = self.uvs {
            let t = uvs[v];
            h = mix(mix(h, canonical_bits(t[0])), canonical_bits(t[1]));
        }
        h ^ (h >> 32)
    }

    #[inline]
    fn equal(&self, a: usize, b: usize) -> bool {
        let (pa, pb) = (self.positions[a], self.positions[b]);
        if !(pa[0] == pb[0] && pa[1] == pb[1] && pa[2] == pb[2]) {
            return false;
        }
        if let Some(normals) = self.normals {
            let (na, nb) = (normals[a], normals[b]);
            if !(na[0] == nb[0] && na[1] == nb[1] && na[2] == nb[2]) {
                return false;
            }
        }
        if let Some(uvs) = self.uvs {
            let (ta, tb) = (uvs[a], uvs[b]);
            if !(ta[0] == tb[0] && ta[1] == tb[1]) {
                return false;
            }
        }
        true
    }

    /// A vertex holding NaN equals nothing, not even itself, so it never enters the table.
    #[inline]
    fn self_equal(&self, v: usize) -> bool {
        self.equal(v, v)
    }
}

/// Groups equal vertices. Class ids are assigned in order of first appearance.
pub(crate) fn weld_vertices(key: &Key<'_>) -> Weld {
    let vertex_count = key.positions.len();
    let mut buckets = 16usize;
    while buckets < vertex_count + vertex_count / 2 {
        buckets *= 2;
    }
    let mask = buckets - 1;
    // Each slot holds the first vertex of a class.
    let mut table = vec![NONE; buckets];
    let mut class_of_vertex = vec![NONE; vertex_count];
    let mut class_count = 0u32;
    // Hash a block of vertices first and touch their buckets: independent loads that the CPU
    // overlaps, where the insertion loop below would wait for one cache miss at a time.
    const BLOCK: usize = 32;
    let mut home = [0usize; BLOCK];
    for block_start in (0..vertex_count).step_by(BLOCK) {
        let block = block_start..(block_start + BLOCK).min(vertex_count);
        let mut touched = 0u32;
        for (v, slot) in block.clone().zip(&mut home) {
            *slot = key.hash(v) as usize & mask;
            touched ^= table[*slot];
        }
        std::hint::black_box(touched);
        for (v, &slot) in block.zip(&home) {
            if !key.self_equal(v) {
                class_of_vertex[v] = class_count;
                class_count += 1;
                continue;
            }
            let mut slot = slot;
            let mut probe = 0;
            loop {
                let first = table[slot];
                if first == NONE {
                    table[slot] = v as u32;
                    class_of_vertex[v] = class_count;
                    class_count += 1;
                    break;
                }
                if key.equal(first as usize, v) {
                    class_of_vertex[v] = class_of_vertex[first as usize];
                    break;
                }
                probe += 1;
                slot = (slot + probe) & mask;
            }
        }
    }
    Weld {
        class_of_vertex,
        class_count: class_count as usize,
    }
}

/// Welds the vertices MikkTSpace would weld: equal position, normal and texture coordinate.
pub(crate) fn weld_mesh(mesh: &Mesh<'_>) -> Weld {
    weld_vertices(&Key {
        positions: mesh.positions,
        normals: Some(mesh.normals),
        uvs: mesh.uvs,
    })
}

/// For each class, the corners that meet there, in ascending corner order (compressed rows).
pub(crate) struct CornerTable {
    /// `offsets[c]..offsets[c + 1]` indexes `corners` for class `c`.
    pub offsets: Vec<u32>,
    pub corners: Vec<u32>,
}

impl CornerTable {
    /// Builds the table from the class of every corner; corners whose class is [`NONE`] are
    /// left out.
    #[cfg(test)]
    pub fn build(corner_class: &[u32], class_count: usize) -> CornerTable {
        Self::build_filtered(corner_class, class_count, |_| true, false)
    }

    /// Builds the table over the corners for which `keep(corner)` holds (and whose class is not
    /// [`NONE`]). In parallel, a counting sort per block of corners: each block counts its
    /// corners per class, the counts are laid out block after block within each class, and each
    /// block fills its own places, so the order within a class stays ascending.
    pub fn build_filtered(
        corner_class: &[u32],
        class_count: usize,
        keep: impl Fn(usize) -> bool + Sync,
        parallel: bool,
    ) -> CornerTable {
        let corner_count = corner_class.len();
        let blocks = if parallel && corner_count >= 1 << 16 {
            rayon::current_num_threads().clamp(1, 8)
        } else {
            1
        };
        let block_len = corner_count.div_ceil(blocks).max(1);
        let class_of = |c: usize| {
            let class = corner_class[c];
            if class != NONE && keep(c) {
                class
            } else {
                NONE
            }
        };
        // counts[block][class], then turned into each block's first place in every class.
        let count_block = |b: usize| {
            let mut counts = vec![0u32; class_count];
            for c in b * block_len..((b + 1) * block_len).min(corner_count) {
                let class = class_of(c);
                if class != NONE {
                    counts[class as usize] += 1;
                }
            }
            counts
        };
        let mut counts: Vec<Vec<u32>> = if blocks > 1 {
            (0..blocks).into_par_iter().map(count_block).collect()
        } else {
            vec![count_block(0)]
        };
        let mut offsets = vec![0u32; class_count + 1];
        let mut running = 0u32;
        for class in 0..class_count {
            offsets[class] = running;
            for block in counts.iter_mut() {
                let n = block[class];
                block[class] = running;
                running += n;
            }
        }
        offsets[class_count] = running;

        let corners = if blocks > 1 {
            let corners: Vec<AtomicU32> = (0..running).map(|_| AtomicU32::new(0)).collect();
            let fill_block = |(b, mut next): (usize, Vec<u32>)| {
                for c in b * block_len..((b + 1) * block_len).min(corner_count) {
                    let class = class_of(c);
                    if class != NONE {
                        let at = next[class as usize];
                        next[class as usize] += 1;
                        // Every place is written by exactly one block, and rayon's join makes
                        // the writes visible before the table is read: relaxed stores suffice.
                        corners[at as usize].store(c as u32, Ordering::Relaxed);
                    }
                }
            };
            counts.into_par_iter().enumerate().for_each(fill_block);
            corners.into_iter().map(AtomicU32::into_inner).collect()
        } else {
            let mut corners = vec![0u32; running as usize];
            let next = &mut counts[0];
            for c in 0..corner_count {
                let class = class_of(c);
                if class != NONE {
                    corners[next[class as usize] as usize] = c as u32;
                    next[class as usize] += 1;
                }
            }
            corners
        };
        CornerTable { offsets, corners }
    }

    /// Splits the classes into about `pieces` ranges holding similar numbers of corners.
    pub fn chunks(&self, pieces: usize) -> Vec<std::ops::Range<usize>> {
        let class_count = self.offsets.len() - 1;
        let total = self.corners.len();
        let target = (total / pieces.max(1)).max(4096);
        let mut ranges = Vec::with_capacity(pieces + 1);
        let mut start = 0;
        while start < class_count {
            let limit = self.offsets[start] as usize + target;
            // The first class whose corners end at or beyond the limit closes the range.
            let end =
                self.offsets[start + 1..].partition_point(|&o| (o as usize) < limit) + start + 1;
            let end = end.min(class_count);
            ranges.push(start..end);
            start = end;
        }
        ranges
    }

    #[inline]
    pub fn of(&self, class: usize) -> &[u32] {
        &self.corners[self.offsets[class] as usize..self.offsets[class + 1] as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn welds_equal_vertices_and_keeps_distinct_ones() {
        let positions = [
            [0.0, 0.0, 0.0],
            [-0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [f32::NAN, 0.0, 0.0],
            [f32::NAN, 0.0, 0.0],
        ];
        let uvs = [[0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]];
        let weld = weld_vertices(&Key {
            positions: &positions,
            normals: None,
            uvs: Some(&uvs),
        });
        assert_eq!(weld.class_of_vertex, vec![0, 0, 1, 2, 3]);
        assert_eq!(weld.class_count, 4);
    }

    #[test]
    fn texture_coordinates_separate_vertices() {
        let positions = [[0.0, 0.0, 0.0]; 3];
        let uvs = [[0.0, 0.0], [0.5, 0.0], [0.0, 0.0]];
        let weld = weld_vertices(&Key {
            positions: &positions,
            normals: None,
            uvs: Some(&uvs),
        });
        assert_eq!(weld.class_of_vertex, vec![0, 1, 0]);
    }

    #[test]
    fn corner_table_lists_corners_in_order() {
        let table = CornerTable::build(&[1, 0, 1, NONE, 0], 2);
        assert_eq!(table.of(0), &[1, 4]);
        assert_eq!(table.of(1), &[0, 2]);
    }
}
