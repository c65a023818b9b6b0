//! Welding: which vertices are the same point of the surface, and which corners meet at each.
//!
//! MikkTSpace treats two corners as one vertex when position, normal and texture coordinate are
//! all equal as floats (so `-0 == 0`, and NaN equals nothing). We compute the same classes with an
//! open-addressing hash table over the input vertices, which for indexed meshes is half the work
//! of hashing every corner as the reference does.

use super::fill::filled;
use super::math::Mesh;
use super::prefetch::prefetch;
use super::vectors::widest_vectors;
use rayon::prelude::*;
use std::borrow::Cow;
use std::mem::MaybeUninit;
use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};

/// Sentinel for "no entry" in index arrays.
pub(crate) const NONE: u32 = u32::MAX;

/// Maps every input vertex to a dense class id `0..class_count`.
pub(crate) struct Weld {
    pub class_of_vertex: Vec<u32>,
    pub class_count: usize,
}

impl Weld {
    /// For every class, whether more than one input vertex belongs to it. Classes are numbered
    /// by first appearance, so a vertex whose class is the next number starts it, and any other
    /// joins one; a block of vertices on the thread pool knows the next number from the highest
    /// class before it (the classes seen so far are `0..=highest`).
    pub fn classes_with_several_vertices(&self, parallel: bool) -> Vec<bool> {
        if !parallel || self.class_of_vertex.len() < 2 * MIN_LEN {
            let mut several = vec![false; self.class_count];
            // Without a branch: in a triangle soup, which of the two a vertex does is a coin
            // toss (SciFiHelmet's whole call 2% faster than with the branch).
            let mut started = 0u32;
            for &class in &self.class_of_vertex {
                let starts = class == started;
                several[class as usize] |= !starts;
                started += u32::from(starts);
            }
            return several;
        }
        let several = filled(self.class_count, parallel, || AtomicBool::new(false));
        let blocks: Vec<&[u32]> = self.class_of_vertex.chunks(MIN_LEN).collect();
        let highest: Vec<u32> = blocks
            .par_iter()
            .map(|block| block.iter().copied().max().unwrap_or(0))
            .collect();
        let mut starts = Vec::with_capacity(blocks.len());
        let mut next = 0u32;
        for (&block, &high) in blocks.iter().zip(&highest) {
            starts.push((next, block));
            next = next.max(high + 1);
        }
        starts.into_par_iter().for_each(|(mut started, block)| {
            for &class in block {
                if class == started {
                    started += 1;
                } else {
                    several[class as usize].store(true, Ordering::Relaxed);
                }
            }
        });
        several
            .into_par_iter()
            .with_min_len(MIN_LEN)
            .map(AtomicBool::into_inner)
            .collect()
    }

    /// The class of every corner of `indices`. Where no two vertices were welded, that is the
    /// index itself (classes are numbered in order of first appearance, so with one vertex per
    /// class, class `v` is vertex `v`), and `indices` is borrowed: on an indexed mesh, as
    /// exported meshes nearly always are, that spares 4 bytes a corner and a pass.
    pub fn corner_classes<'a>(&self, indices: &'a [u32], parallel: bool) -> Cow<'a, [u32]> {
        if self.class_count == self.class_of_vertex.len() {
            debug_assert!(self.class_of_vertex.iter().zip(0..).all(|(&c, v)| c == v));
            return Cow::Borrowed(indices);
        }
        let class_of = |&v: &u32| self.class_of_vertex[v as usize];
        Cow::Owned(if parallel {
            indices
                .par_iter()
                .with_min_len(8192)
                .map(class_of)
                .collect()
        } else {
            indices.iter().map(class_of).collect()
        })
    }
}

#[inline]
fn canonical_bits(x: f32) -> u32 {
    // -0.0 and 0.0 compare equal, so they must hash equally: adding +0 turns -0 into +0 and
    // leaves every other number as it is (one addition instead of a test per coordinate).
    (x + 0.0).to_bits()
}

/// One word of a key, mixed on its own: a multiplication and a shift, which vector lanes do
/// for many vertices at once. `salt` tells the word's place in the key apart, and is drawn at
/// random (see [`salts`]).
#[inline(always)]
fn word_mix(bits: u32, salt: u32) -> u32 {
    let x = (bits ^ salt).wrapping_mul(0x9E37_79B1);
    x ^ (x >> 15)
}

/// MurmurHash3's finalizer: every input bit reaches every output bit.
#[inline(always)]
fn finalize(mut h: u32) -> u32 {
    h ^= h >> 16;
    h = h.wrapping_mul(0x85EB_CA6B);
    h ^= h >> 13;
    h = h.wrapping_mul(0xC2B2_AE35);
    h ^ (h >> 16)
}

/// The hash's salts, one per word of a key, drawn once per process. A fixed hash would let a
/// file be made of distinct vertices that all hash alike, and weld in quadratic time (every
/// vertex compared with every earlier one in one probe chain); with salts nobody outside the
/// process knows, such a file cannot be made in advance. The classes are numbered by first
/// appearance, so they do not depend on the hash: only where the vertices lie in the table.
fn salts() -> [u32; 8] {
    static SALTS: std::sync::OnceLock<[u32; 8]> = std::sync::OnceLock::new();
    *SALTS.get_or_init(|| {
        use std::hash::{BuildHasher, Hasher};
        let random = std::collections::hash_map::RandomState::new();
        std::array::from_fn(|word| {
            let mut hasher = random.build_hasher();
            hasher.write_usize(word);
            hasher.finish() as u32
        })
    })
}

/// Vertices hashed at once by [`BlockHashes`].
const HASH_BLOCK: usize = 32;

/// The 32-bit hashes of a block of consecutive vertices. Each word of a key is mixed on its
/// own, the mixes summed and finalized, in loops over the block's vertices that run as vector
/// loops, one attribute array at a time, read in order. A hash of one vertex at a time (two
/// 64-bit multiplications to 128 bits and a third joining them, and before that a chain of
/// eight) took about 4 ns a vertex, a third of the weld of an indexed mesh; the weld of a
/// 10k-vertex grid alone is a third faster with this one, a soup's a quarter.
struct BlockHashes {
    hashes: [u32; HASH_BLOCK],
    salts: [u32; 8],
}

impl BlockHashes {
    fn with_salts(salts: [u32; 8]) -> BlockHashes {
        BlockHashes {
            hashes: [0; HASH_BLOCK],
            salts,
        }
    }

    /// The hashes of vertices `start..` (up to [`HASH_BLOCK`] of them, fewer at the end).
    fn of_block(&mut self, key: &Key<'_>, start: usize) -> &[u32] {
        self.compute(key, start);
        &self.hashes[..HASH_BLOCK.min(key.positions.len() - start)]
    }

    widest_vectors! {
        /// Hashes vertices `start..` (up to [`HASH_BLOCK`] of them) into `self.hashes`.
        fn compute / compute_avx512 / compute_avx2 (&mut self, key: &Key<'_>, start: usize)
            => compute_portable
    }

    #[inline(always)]
    fn compute_portable(&mut self, key: &Key<'_>, start: usize) {
        let len = HASH_BLOCK.min(key.positions.len() - start);
        let hashes = &mut self.hashes[..len];
        let s = self.salts;
        let add_three = |h: &mut u32, w: &[f32; 3], salts: [u32; 3]| {
            *h = h
                .wrapping_add(word_mix(canonical_bits(w[0]), salts[0]))
                .wrapping_add(word_mix(canonical_bits(w[1]), salts[1]))
                .wrapping_add(word_mix(canonical_bits(w[2]), salts[2]));
        };
        for (h, p) in hashes.iter_mut().zip(&key.positions[start..]) {
            *h = 0;
            add_three(h, p, [s[0], s[1], s[2]]);
        }
        if let Some(normals) = key.normals {
            for (h, n) in hashes.iter_mut().zip(&normals[start..]) {
                add_three(h, n, [s[3], s[4], s[5]]);
            }
        }
        if let Some(uvs) = key.uvs {
            for (h, t) in hashes.iter_mut().zip(&uvs[start..]) {
                *h = h
                    .wrapping_add(word_mix(canonical_bits(t[0]), s[6]))
                    .wrapping_add(word_mix(canonical_bits(t[1]), s[7]));
            }
        }
        for h in hashes.iter_mut() {
            *h = finalize(*h);
        }
    }
}

/// Vertex identity over position, and optionally normal and texture coordinate.
pub(crate) struct Key<'a> {
    pub positions: &'a [[f32; 3]],
    pub normals: Option<&'a [[f32; 3]]>,
    pub uvs: Option<&'a [[f32; 2]]>,
    /// Whether every value of the key is known to be finite (the core's vertex checks found no
    /// other), so that no vertex can hold NaN and [`Key::self_equal`] need not compare.
    pub finite: bool,
}

impl Key<'_> {
    /// Comparisons combined without branching, in two groups: keys that differ nearly always
    /// differ in position (a hash collision), and the rest, when positions agree, is mostly
    /// equal (a welded vertex), so one branch per group beats one per coordinate.
    #[inline]
    fn equal(&self, a: usize, b: usize) -> bool {
        let (pa, pb) = (self.positions[a], self.positions[b]);
        if !((pa[0] == pb[0]) & (pa[1] == pb[1]) & (pa[2] == pb[2])) {
            return false;
        }
        let mut same = true;
        if let Some(normals) = self.normals {
            let (na, nb) = (normals[a], normals[b]);
            same &= (na[0] == nb[0]) & (na[1] == nb[1]) & (na[2] == nb[2]);
        }
        if let Some(uvs) = self.uvs {
            let (ta, tb) = (uvs[a], uvs[b]);
            same &= (ta[0] == tb[0]) & (ta[1] == tb[1]);
        }
        same
    }

    /// The vertex's key in one array: position, normal, texture coordinate (zeros for the
    /// attributes the key leaves out, which then compare equal).
    #[inline]
    fn flat(&self, v: usize) -> [f32; 8] {
        let p = self.positions[v];
        let n = self.normals.map_or([0.0; 3], |normals| normals[v]);
        let t = self.uvs.map_or([0.0; 2], |uvs| uvs[v]);
        [p[0], p[1], p[2], n[0], n[1], n[2], t[0], t[1]]
    }

    /// A vertex holding NaN equals nothing, not even itself, so it never enters the table.
    /// Known finite keys skip the comparison (on an indexed mesh, a tenth of the weld).
    #[inline]
    fn self_equal(&self, v: usize) -> bool {
        self.finite || self.equal(v, v)
    }
}

/// Groups equal vertices. Class ids are assigned in order of first appearance, so the result
/// is the same whether or not it is computed in parallel.
pub(crate) fn weld_vertices(key: &Key<'_>, parallel: bool) -> Weld {
    weld(key, false, parallel)
}

/// [`weld_vertices`], told whether most vertices are expected to repeat.
fn weld(key: &Key<'_>, mostly_repeated: bool, parallel: bool) -> Weld {
    let salts = salts();
    if one_table_buckets(key.positions.len()) <= ONE_TABLE_MAX_BUCKETS {
        return if mostly_repeated {
            weld_in_one_table::<FirstKeys>(key, salts)
        } else {
            weld_in_one_table::<FirstVertices>(key, salts)
        };
    }
    weld_in_shards(key, salts, parallel)
}

/// Up to this many slots (1 MiB with their tags), one table stays in a core's L2 or nearby L3
/// cache and beats the shards' extra passes, even on two threads (a 70k-vertex mesh welds about
/// 7% faster than in shards; a 100k-vertex one, whose table would be twice the size, about 15%
/// slower). Beyond it, the table is split into shards (see [`weld_in_shards`]). On one thread,
/// the weld alone of a 100k-vertex mesh is 13% faster in one table than in shards, but the
/// whole call was not (the 200k torus 2.5% slower in five interleaved rounds), so the limit is
/// the same there.
const ONE_TABLE_MAX_BUCKETS: usize = 1 << 17;

/// The slots one table over `vertex_count` vertices would have at the least, which decides
/// between one table and shards: a power of two, at least 1.5 per vertex.
fn one_table_buckets(vertex_count: usize) -> usize {
    table_buckets(vertex_count, false)
}

/// The slots of a table for `vertex_count` vertices, a power of two. Where most vertices are
/// distinct, nearly every vertex takes a slot, and a table at most a third full (three slots a
/// vertex) makes a vertex's first probe nearly always find its slot empty: at two thirds, a
/// third of the first probes met another class, a branch the CPU could not predict (a loop of
/// 10k-vertex welds alone about a quarter faster). Where most repeat, the classes are a
/// fraction of the vertices and 1.5 slots a vertex leaves the table as empty.
fn table_buckets(vertex_count: usize, mostly_distinct: bool) -> usize {
    let slots = if mostly_distinct {
        3 * vertex_count
    } else {
        vertex_count + vertex_count / 2
    };
    slots.next_power_of_two().max(16)
}
/// About this many vertices per shard: a shard's table (8 bytes a slot, 1.5 to 3 slots a
/// vertex) then stays within a core's L2 cache.
const SHARD_VERTICES: usize = 1 << 13;

/// Welding for large meshes. One table over a million vertices misses the cache on nearly every
/// probe, and cannot be shared between threads. Instead, equal vertices having equal hashes,
/// the vertices are dealt into shards by the top bits of their hash, and each shard is welded
/// on its own with a table that fits in cache, taking its vertices in ascending order so that
/// the first of each class is found first. Class ids are then numbered by first appearance,
/// exactly as [`weld_in_one_table`] numbers them.
fn weld_in_shards(key: &Key<'_>, salts: [u32; 8], parallel: bool) -> Weld {
    match first_equal_vertices(key, salts, parallel) {
        Some(first_of_vertex) => number_classes(first_of_vertex, parallel),
        // Every vertex is its own class, as in nearly every indexed mesh.
        None => {
            let vertices = 0..key.positions.len() as u32;
            Weld {
                class_of_vertex: if parallel {
                    vertices.into_par_iter().with_min_len(MIN_LEN).collect()
                } else {
                    vertices.collect()
                },
                class_count: key.positions.len(),
            }
        }
    }
}

/// The smallest piece of a per-vertex pass worth handing to another thread.
const MIN_LEN: usize = 1 << 14;

/// Vertices dealt into shards per block of this many: a block's hashes and counts stay in
/// cache while its vertices are dealt.
const DEAL_BLOCK: usize = 1 << 16;

/// One block of vertices dealt into shards: each shard's `(vertex, hash)` pairs in ascending
/// vertex order, shard after shard.
struct Dealt {
    /// `starts[s]..starts[s + 1]` indexes `pairs` for shard `s`.
    starts: Vec<u32>,
    pairs: Vec<[u32; 2]>,
}

impl Dealt {
    /// Hashes vertices `vertices` and deals them into `1 << shard_bits` shards by their hash's
    /// top bits. A vertex that equals nothing (NaN) goes into none.
    fn of(key: &Key<'_>, salts: [u32; 8], shard_bits: u32, vertices: Range<usize>) -> Dealt {
        let mut hashes = Vec::with_capacity(vertices.len());
        let mut block = BlockHashes::with_salts(salts);
        for start in vertices.clone().step_by(HASH_BLOCK) {
            hashes.extend_from_slice(block.of_block(key, start));
        }
        hashes.truncate(vertices.len());
        let shard_of = |(v, &hash): (usize, &u32)| {
            key.self_equal(v)
                .then(|| (hash >> (32 - shard_bits)) as usize)
        };
        let mut starts = vec![0u32; (1 << shard_bits) + 1];
        for shard in vertices.clone().zip(&hashes).filter_map(shard_of) {
            starts[shard + 1] += 1;
        }
        for s in 1..starts.len() {
            starts[s] += starts[s - 1];
        }
        let mut next = starts.clone();
        let mut pairs = vec![[0u32; 2]; starts.last().map_or(0, |&n| n as usize)];
        for (v, &hash) in vertices.zip(&hashes) {
            if let Some(shard) = shard_of((v, &hash)) {
                pairs[next[shard] as usize] = [v as u32, hash];
                next[shard] += 1;
            }
        }
        Dealt { starts, pairs }
    }

    fn shard(&self, s: usize) -> &[[u32; 2]] {
        &self.pairs[self.starts[s] as usize..self.starts[s + 1] as usize]
    }
}

/// For every vertex, the first vertex (lowest index) with an equal key: the vertices are hashed
/// and dealt into shards by their hash's top bits, block by block, and each shard is welded in a
/// table of its own. `None` when every vertex is its own first, which spares putting the firsts
/// back in vertex order.
///
/// Each block carries its vertices' hashes with them into the shards, where a list of vertex
/// numbers per shard had the weld read each vertex's hash from an array of them all, a cache
/// miss a vertex.
fn first_equal_vertices(key: &Key<'_>, salts: [u32; 8], parallel: bool) -> Option<Vec<u32>> {
    let vertex_count = key.positions.len();
    let shard_bits = (vertex_count / SHARD_VERTICES)
        .next_power_of_two()
        .trailing_zeros()
        .clamp(1, 12);
    let shard_count = 1usize << shard_bits;
    let deal = |b: usize| {
        let start = b * DEAL_BLOCK;
        Dealt::of(
            key,
            salts,
            shard_bits,
            start..(start + DEAL_BLOCK).min(vertex_count),
        )
    };
    let blocks = vertex_count.div_ceil(DEAL_BLOCK);
    let dealt: Vec<Dealt> = if parallel {
        (0..blocks).into_par_iter().map(deal).collect()
    } else {
        (0..blocks).map(deal).collect()
    };

    // The shard's vertices (blocks in order, so ascending) that equal an earlier one, each with
    // that first one.
    let weld_shard = |shard: usize| {
        let mut welded = Vec::new();
        let size: usize = dealt.iter().map(|d| d.shard(shard).len()).sum();
        // Not the roomier table of the one-table weld: three slots a vertex made the 200k
        // meshes, welded in shards, no faster (six interleaved rounds).
        let buckets = table_buckets(size, false);
        let mask = buckets - 1;
        // (first vertex, its hash); `NONE` marks an empty slot.
        let mut table = vec![(NONE, 0u32); buckets];
        for &[v, tag] in dealt.iter().flat_map(|d| d.shard(shard)) {
            let mut slot = tag as usize & mask;
            let mut probe = 0;
            loop {
                let (held, held_tag) = table[slot];
                if held == NONE {
                    table[slot] = (v, tag);
                    break;
                }
                if held_tag == tag && key.equal(held as usize, v as usize) {
                    welded.push([v, held]);
                    break;
                }
                probe += 1;
                slot = (slot + probe) & mask;
            }
        }
        welded
    };
    let welded: Vec<Vec<[u32; 2]>> = if parallel {
        (0..shard_count).into_par_iter().map(weld_shard).collect()
    } else {
        (0..shard_count).map(weld_shard).collect()
    };
    drop(dealt);
    if welded.iter().all(Vec::is_empty) {
        return None;
    }

    // Back to vertex order; every other vertex is its own first.
    let mut first_of_vertex: Vec<u32> = (0..vertex_count as u32).collect();
    for &[v, first] in welded.iter().flatten() {
        first_of_vertex[v as usize] = first;
    }
    Some(first_of_vertex)
}

/// Classes numbered by first appearance: a prefix count of the vertices that are their own
/// first, block by block, then every vertex takes its first's class. Only where some vertex
/// welded (where none did, [`weld_in_shards`] knows the classes are the vertices).
fn number_classes(first_of_vertex: Vec<u32>, parallel: bool) -> Weld {
    let vertex_count = first_of_vertex.len();
    let blocks = if parallel {
        rayon::current_num_threads().clamp(1, 64) * 4
    } else {
        1
    };
    let block_len = vertex_count.div_ceil(blocks).max(1);
    let count_firsts = |(b, firsts): (usize, &[u32])| {
        let start = (b * block_len) as u32;
        firsts
            .iter()
            .zip(start..)
            .filter(|&(&first, v)| first == v)
            .count() as u32
    };
    let counts: Vec<u32> = if parallel {
        first_of_vertex
            .par_chunks(block_len)
            .enumerate()
            .map(count_firsts)
            .collect()
    } else {
        first_of_vertex
            .chunks(block_len)
            .enumerate()
            .map(count_firsts)
            .collect()
    };
    let (block_starts, class_count) = starts_and_total(&counts);
    // Own classes first (NONE elsewhere), then every vertex takes its first's class.
    let mut own_class = vec![NONE; vertex_count];
    let number = |(b, (own, firsts)): (usize, (&mut [u32], &[u32]))| {
        let mut next = block_starts[b];
        for ((class, &first), v) in own.iter_mut().zip(firsts).zip((b * block_len) as u32..) {
            if first == v {
                *class = next;
                next += 1;
            }
        }
    };
    if parallel {
        own_class
            .par_chunks_mut(block_len)
            .zip(first_of_vertex.par_chunks(block_len))
            .enumerate()
            .for_each(number);
    } else {
        own_class
            .chunks_mut(block_len)
            .zip(first_of_vertex.chunks(block_len))
            .enumerate()
            .for_each(number);
    }
    let class_of = |&first: &u32| own_class[first as usize];
    let class_of_vertex: Vec<u32> = if parallel {
        first_of_vertex
            .par_iter()
            .with_min_len(MIN_LEN)
            .map(class_of)
            .collect()
    } else {
        first_of_vertex.iter().map(class_of).collect()
    };
    Weld {
        class_of_vertex,
        class_count: class_count as usize,
    }
}

/// How [`weld_in_one_table`] remembers each class's first vertex and compares a vertex with it.
trait Firsts {
    /// Whether most vertices are expected to repeat, so that most find their class.
    const REPEATED: bool;
    /// An empty record for a weld of `vertex_count` vertices.
    fn for_vertices(vertex_count: usize) -> Self;
    /// Records vertex `v` as the first of the next class.
    fn add(&mut self, key: &Key<'_>, v: usize);
    /// Whether vertex `v` equals the first vertex of `class`.
    fn same(&self, key: &Key<'_>, class: u32, v: usize) -> bool;
}

/// The first vertex's index: comparing reads its attributes from the mesh. For meshes whose
/// vertices are mostly distinct, where few comparisons are made.
struct FirstVertices(Vec<u32>);

impl Firsts for FirstVertices {
    const REPEATED: bool = false;

    /// Room for a class per vertex, which is what such a mesh has: grown by doubling, the list
    /// was copied a dozen times.
    fn for_vertices(vertex_count: usize) -> Self {
        FirstVertices(Vec::with_capacity(vertex_count))
    }

    #[inline]
    fn add(&mut self, _: &Key<'_>, v: usize) {
        self.0.push(v as u32);
    }

    #[inline]
    fn same(&self, key: &Key<'_>, class: u32, v: usize) -> bool {
        key.equal(self.0[class as usize] as usize, v)
    }
}

/// A copy of the first vertex's key, for meshes that repeat most vertices (triangle soups):
/// there nearly every vertex is compared with the first of its class, and the copies in one
/// array make that read one cache line instead of one per attribute array. Where vertices are
/// mostly distinct, writing the copies costs more than it saves.
struct FirstKeys(Vec<[f32; 8]>);

impl Firsts for FirstKeys {
    const REPEATED: bool = true;

    /// Grown as classes come: a soup has a fraction as many classes as vertices.
    fn for_vertices(_: usize) -> Self {
        FirstKeys(Vec::new())
    }

    #[inline]
    fn add(&mut self, key: &Key<'_>, v: usize) {
        self.0.push(key.flat(v));
    }

    #[inline]
    fn same(&self, key: &Key<'_>, class: u32, v: usize) -> bool {
        let (a, b) = (&self.0[class as usize], &key.flat(v));
        // Combined without branching, as in `Key::equal`.
        a.iter().zip(b).fold(true, |same, (x, y)| same & (x == y))
    }
}

/// One hash table over all the vertices: for meshes small enough that it stays in cache.
fn weld_in_one_table<F: Firsts>(key: &Key<'_>, salts: [u32; 8]) -> Weld {
    let vertex_count = key.positions.len();
    // Within the limit on one table's size (the choice of one table was made at 1.5 slots a
    // vertex), so that it stays in cache.
    let buckets = table_buckets(vertex_count, !F::REPEATED)
        .min(ONE_TABLE_MAX_BUCKETS)
        .max(one_table_buckets(vertex_count));
    let mask = buckets - 1;
    // Each slot holds a class and its first vertex's hash (its tag): a probe that meets another
    // class is then nearly always decided by the tags, without reading that class's vertex
    // from wherever it lies in the mesh (a cache miss in most collisions).
    let mut table = vec![(NONE, 0u32); buckets];
    let mut firsts = F::for_vertices(vertex_count);
    let mut class_of_vertex = Vec::with_capacity(vertex_count);
    let mut class_count = 0u32;
    // Two stages over blocks of vertices, the first two blocks ahead of the second, so that a
    // block's misses overlap the work on the blocks before it instead of holding up its own:
    // (1) hash the block and prefetch its home slots; (2) probe and insert. (Prefetches rather
    // than loads: a load that misses holds up everything after it until it arrives.) A stage
    // between them that read the slots a block ahead, to prefetch the first key of the class
    // each held, made a triangle soup's weld slower, not faster: a soup's first keys are the
    // classes found most recently, still in cache, and the stage's loads of the slots waited
    // on the prefetches just made (see "The soup weld without its middle stage" in
    // docs/benchmarks.md).
    const BLOCK: usize = HASH_BLOCK;
    let block_count = vertex_count.div_ceil(BLOCK);
    let block_of = |b: usize| b * BLOCK..((b + 1) * BLOCK).min(vertex_count);
    let mut homes = [[(0usize, 0u32); BLOCK]; 3];
    let mut hashes = BlockHashes::with_salts(salts);
    let mut hash_block = |b: usize, home: &mut [(usize, u32); BLOCK], table: &[(u32, u32)]| {
        // The whole hash is the tag (the slot is its low bits, but a probe moves on from there).
        for (&hash, (slot, tag)) in hashes.of_block(key, b * BLOCK).iter().zip(home) {
            (*slot, *tag) = (hash as usize & mask, hash);
            prefetch(&table[*slot]);
        }
    };
    for (b, home) in homes.iter_mut().enumerate().take(block_count.min(2)) {
        hash_block(b, home, &table);
    }
    for b in 0..block_count {
        if b + 2 < block_count {
            hash_block(b + 2, &mut homes[(b + 2) % 3], &table);
        }
        for (v, &(mut slot, tag)) in block_of(b).zip(&homes[b % 3]) {
            // A vertex holding NaN equals no class, and gets a class of its own but no slot.
            // Where most vertices are new, it is told apart before probing, from its key just
            // hashed, as before; where most repeat, only where it would take a new slot, since
            // one that matches a class cannot hold NaN (SciFiHelmet's weld, alone, 20% faster).
            if !F::REPEATED && !key.self_equal(v) {
                firsts.add(key, v);
                class_count += 1;
                class_of_vertex.push(class_count - 1);
                continue;
            }
            let mut probe = 0;
            class_of_vertex.push(loop {
                let (class, held_tag) = table[slot];
                if class == NONE {
                    if !F::REPEATED || key.self_equal(v) {
                        table[slot] = (class_count, tag);
                    }
                    firsts.add(key, v);
                    class_count += 1;
                    break class_count - 1;
                }
                if held_tag == tag && firsts.same(key, class, v) {
                    break class;
                }
                probe += 1;
                slot = (slot + probe) & mask;
            });
        }
    }
    Weld {
        class_of_vertex,
        class_count: class_count as usize,
    }
}

/// Welds the vertices MikkTSpace would weld: equal position, normal and texture coordinate.
/// `finite`: the core's vertex checks found no non-finite value in the mesh.
pub(crate) fn weld_mesh(mesh: &Mesh<'_>, finite: bool, parallel: bool) -> Weld {
    // About one vertex per corner (a triangle soup, or an index buffer that does not share):
    // most vertices are then copies; a mesh whose corners share vertices has few.
    let mostly_repeated = mesh.indices.len() < 2 * mesh.vertex_count();
    weld(
        &Key {
            positions: mesh.positions,
            normals: Some(mesh.normals),
            uvs: mesh.uvs,
            finite,
        },
        mostly_repeated,
        parallel,
    )
}

/// Turns `counts[block][class]` into each block's first place in each class, classes after one
/// another and blocks in order within a class, from place `start` on; `offsets` takes each class's
/// first place, each of its places written. Returns the place after the last.
fn lay_out<C: AsMut<[u32]>>(counts: &mut [C], offsets: &mut [MaybeUninit<u32>], start: u32) -> u32 {
    let mut running = start;
    for (class, offset) in offsets.iter_mut().enumerate() {
        offset.write(running);
        for block in counts.iter_mut() {
            let place = &mut block.as_mut()[class];
            (*place, running) = (running, running + *place);
        }
    }
    running
}

/// Calls `each(corner, class)` for the corners of `span` that have a class and that `keep`
/// keeps, in ascending order. The classes are walked as a slice taken once: written as indexing
/// through a closure that captured `corner_class`, the loops that count and place corners read
/// its pointer and length back from the stack on every corner, since their stores might have
/// changed them (a quarter of the table's time on a 20k-triangle sphere).
#[inline(always)]
fn for_each_kept(
    corner_class: &[u32],
    span: std::ops::Range<usize>,
    keep: &impl Fn(usize) -> bool,
    mut each: impl FnMut(u32, u32),
) {
    let first = span.start;
    for (c, &class) in (first..).zip(&corner_class[span]) {
        if class != NONE && keep(c) {
            each(c as u32, class);
        }
    }
}

/// Where each of `counts` starts when they are laid end to end, and where the last ends.
fn starts_and_total(counts: &[u32]) -> (Vec<u32>, u32) {
    let mut total = 0u32;
    let starts = counts
        .iter()
        .map(|&n| {
            let start = total;
            total += n;
            start
        })
        .collect();
    (starts, total)
}

/// Classes per piece of [`lay_out_in_parallel`].
const LAY_OUT_CLASSES: usize = 1 << 15;

/// [`lay_out`] from place 0, on the thread pool: each piece of classes is summed, the sums give
/// each piece its first place, and the pieces are laid out side by side. (On one thread, the
/// layout of a mesh of a million vertices took 2–4 ms, where the passes around it are shared.)
fn lay_out_in_parallel(counts: &mut [Vec<u32>], offsets: &mut [MaybeUninit<u32>]) -> u32 {
    let pieces = offsets.len().div_ceil(LAY_OUT_CLASSES);
    let sums: Vec<u32> = (0..pieces)
        .into_par_iter()
        .map(|piece| {
            let classes =
                piece * LAY_OUT_CLASSES..((piece + 1) * LAY_OUT_CLASSES).min(offsets.len());
            counts
                .iter()
                .map(|block| block[classes.clone()].iter().sum::<u32>())
                .sum()
        })
        .collect();
    let (starts, running) = starts_and_total(&sums);
    // Each piece of classes, with its places in every block's counts.
    let mut by_piece: Vec<Vec<&mut [u32]>> = (0..pieces).map(|_| Vec::new()).collect();
    for block in counts.iter_mut() {
        for (piece, places) in by_piece.iter_mut().zip(block.chunks_mut(LAY_OUT_CLASSES)) {
            piece.push(places);
        }
    }
    offsets
        .par_chunks_mut(LAY_OUT_CLASSES)
        .zip(by_piece)
        .zip(starts)
        .for_each(|((offsets, mut counts), start)| {
            lay_out(&mut counts, offsets, start);
        });
    running
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
        let block_of = |b: usize| b * block_len..((b + 1) * block_len).min(corner_count);
        // counts[block][class], then turned into each block's first place in every class.
        let count_block = |b: usize| {
            let mut counts = vec![0u32; class_count];
            for_each_kept(corner_class, block_of(b), &keep, |_, class| {
                counts[class as usize] += 1;
            });
            counts
        };
        let mut counts: Vec<Vec<u32>> = if blocks > 1 {
            (0..blocks).into_par_iter().map(count_block).collect()
        } else {
            vec![count_block(0)]
        };
        // Not zeroed first: the layout writes every class's place, and the end is written
        // after it (the allocator's zeroing was on the one thread the others waited for).
        let mut offsets: Vec<u32> = Vec::with_capacity(class_count + 1);
        let places = &mut offsets.spare_capacity_mut()[..class_count + 1];
        let running = if blocks > 1 {
            lay_out_in_parallel(&mut counts, &mut places[..class_count])
        } else {
            lay_out(&mut counts, &mut places[..class_count], 0)
        };
        places[class_count].write(running);
        // SAFETY: `lay_out` and `lay_out_in_parallel` write every place they are given, and
        // the last was written just above.
        unsafe { offsets.set_len(class_count + 1) };

        let corners = if blocks > 1 {
            let corners: Vec<AtomicU32> = filled(running as usize, true, || AtomicU32::new(0));
            let fill_block = |(b, mut next): (usize, Vec<u32>)| {
                let next = next.as_mut_slice();
                for_each_kept(corner_class, block_of(b), &keep, |c, class| {
                    let at = &mut next[class as usize];
                    // Every place is written by exactly one block, and rayon's join makes
                    // the writes visible before the table is read: relaxed stores suffice.
                    corners[*at as usize].store(c, Ordering::Relaxed);
                    *at += 1;
                });
            };
            counts.into_par_iter().enumerate().for_each(fill_block);
            corners.into_iter().map(AtomicU32::into_inner).collect()
        } else {
            let mut corners = vec![0u32; running as usize];
            // Slices, not the vectors: through a `&mut Vec` the loop read the vector's pointer
            // and length again after every store into `corners`, which it could not tell apart.
            let (next, places) = (counts[0].as_mut_slice(), corners.as_mut_slice());
            for_each_kept(corner_class, 0..corner_count, &keep, |c, class| {
                let at = &mut next[class as usize];
                places[*at as usize] = c;
                *at += 1;
            });
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

    /// The triangles the corners of `classes` belong to, from the first to the last (empty
    /// where they have no corners).
    pub fn triangle_span(&self, classes: &std::ops::Range<usize>) -> std::ops::Range<usize> {
        let slots = self.offsets[classes.start] as usize..self.offsets[classes.end] as usize;
        let corners = &self.corners[slots];
        if corners.is_empty() {
            return 0..0;
        }
        let (low, high) = corners
            .iter()
            .fold((u32::MAX, 0), |(low, high), &c| (low.min(c), high.max(c)));
        low as usize / 3..high as usize / 3 + 1
    }

    #[inline]
    pub fn of(&self, class: usize) -> &[u32] {
        &self.corners[self.offsets[class] as usize..self.offsets[class + 1] as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn weld_positions_and_uvs(positions: &[[f32; 3]], uvs: &[[f32; 2]]) -> Weld {
        let key = Key {
            positions,
            normals: None,
            uvs: Some(uvs),
            finite: false,
        };
        weld_vertices(&key, false)
    }

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
        let weld = weld_positions_and_uvs(&positions, &uvs);
        assert_eq!(weld.class_of_vertex, vec![0, 0, 1, 2, 3]);
        assert_eq!(weld.class_count, 4);
    }

    #[test]
    fn texture_coordinates_separate_vertices() {
        let positions = [[0.0, 0.0, 0.0]; 3];
        let uvs = [[0.0, 0.0], [0.5, 0.0], [0.0, 0.0]];
        let weld = weld_positions_and_uvs(&positions, &uvs);
        assert_eq!(weld.class_of_vertex, vec![0, 1, 0]);
    }

    /// The sharded weld numbers classes exactly as the single table does, in parallel or not:
    /// many duplicates (near and far apart), signed zeros and NaN vertices.
    #[test]
    fn sharded_and_soup_welds_match_one_table() {
        // Twelve shards' worth, so that they are many.
        let count = SHARD_VERTICES * 12 + 17;
        let mut random = crate::test_support::xorshift(0x2545_f491_4f6c_dd1d);
        let mut positions = Vec::with_capacity(count);
        let mut uvs = Vec::with_capacity(count);
        for v in 0..count {
            let r = random();
            let (p, t) = match r % 8 {
                // A copy of an earlier vertex, near or far.
                0 | 1 if v > 0 => {
                    let earlier = if r % 2 == 0 {
                        v - 1 - (r >> 8) as usize % v.min(4)
                    } else {
                        (r >> 8) as usize % v
                    };
                    (positions[earlier], uvs[earlier])
                }
                2 => ([-0.0, (r % 5) as f32, 0.0], [0.0, -0.0]),
                3 => ([f32::NAN, 1.0, 2.0], [0.0, 0.0]),
                _ => (
                    [
                        (r % 97) as f32,
                        ((r >> 16) % 89) as f32,
                        ((r >> 32) % 3) as f32,
                    ],
                    [((r >> 40) % 2) as f32, 0.5],
                ),
            };
            positions.push(p);
            uvs.push(t);
        }
        let key = Key {
            positions: &positions,
            normals: None,
            uvs: Some(&uvs),
            finite: false,
        };
        let expected = weld_in_one_table::<FirstVertices>(&key, salts());
        assert!(
            expected.class_count < count / 2,
            "the test should weld a lot"
        );
        for parallel in [false, true] {
            let sharded = weld_in_shards(&key, salts(), parallel);
            assert_eq!(sharded.class_count, expected.class_count);
            assert!(sharded.class_of_vertex == expected.class_of_vertex);
        }
        // The soup variant, with and without normals in the key.
        let with_normals = Key {
            normals: Some(&positions),
            ..key
        };
        for key in [key, with_normals] {
            let expected = weld_in_one_table::<FirstVertices>(&key, salts());
            let keyed = weld_in_one_table::<FirstKeys>(&key, salts());
            assert_eq!(keyed.class_count, expected.class_count);
            assert!(keyed.class_of_vertex == expected.class_of_vertex);
        }
    }

    /// Keys known to be finite skip the test for NaN, and weld as keys tested vertex by vertex,
    /// in one table of either kind and in shards.
    #[test]
    fn finite_keys_weld_as_tested_keys() {
        let count = SHARD_VERTICES * 3 + 5;
        let mut random = crate::test_support::xorshift(0x6a09_e667_f3bc_c908);
        let mut positions: Vec<[f32; 3]> = Vec::with_capacity(count);
        let mut normals: Vec<[f32; 3]> = Vec::with_capacity(count);
        for v in 0..count {
            let r = random();
            let (p, n) = if r % 4 == 0 && v > 0 {
                let earlier = (r >> 8) as usize % v;
                (positions[earlier], normals[earlier])
            } else {
                let p = [(r % 61) as f32, ((r >> 16) % 53) as f32, -0.0];
                (p, [0.0, 0.0, ((r >> 32) % 2) as f32])
            };
            positions.push(p);
            normals.push(n);
        }
        let tested = Key {
            positions: &positions,
            normals: Some(&normals),
            uvs: None,
            finite: false,
        };
        let finite = Key {
            finite: true,
            ..tested
        };
        let expected = weld_in_one_table::<FirstVertices>(&tested, salts());
        assert!(
            expected.class_count < count * 9 / 10,
            "the test should weld"
        );
        let welds = [
            weld_in_one_table::<FirstVertices>(&finite, salts()),
            weld_in_one_table::<FirstKeys>(&finite, salts()),
            weld_in_shards(&finite, salts(), false),
            weld_in_shards(&finite, salts(), true),
        ];
        for weld in welds {
            assert_eq!(weld.class_count, expected.class_count);
            assert!(weld.class_of_vertex == expected.class_of_vertex);
        }
    }

    /// The hashes of `positions` (the key's only attribute) under `salts`.
    fn hashes_of(positions: &[[f32; 3]], salts: [u32; 8]) -> Vec<u32> {
        let key = Key {
            positions,
            normals: None,
            uvs: None,
            finite: true,
        };
        let mut hashes = BlockHashes::with_salts(salts);
        (0..positions.len())
            .step_by(HASH_BLOCK)
            .flat_map(|start| hashes.of_block(&key, start).to_vec())
            .collect()
    }

    /// Distinct vertices made to hash alike under known salts (each word's mix can be undone)
    /// all share one probe chain there; under other salts they spread out. Without the salts
    /// such a file would weld in quadratic time in any process.
    #[test]
    fn vertices_made_to_collide_under_known_salts_do_not_collide_under_others() {
        let known = [1, 2, 3, 4, 5, 6, 7, 8];
        // The inverse of `word_mix` with salt 0: the shift undone, then the multiplication.
        let mut inverse = 0x9E37_79B1u32;
        for _ in 0..5 {
            inverse = inverse.wrapping_mul(2u32.wrapping_sub(0x9E37_79B1u32.wrapping_mul(inverse)));
        }
        let unmix = |y: u32| (y ^ (y >> 15) ^ (y >> 30)).wrapping_mul(inverse);
        assert_eq!(unmix(word_mix(12345, 0)), 12345);
        let target = 0x1234_5678u32;
        let positions: Vec<[f32; 3]> = (0..4000u32)
            .filter_map(|i| {
                let x = 1.0 + i as f32 / 4096.0;
                let rest = target.wrapping_sub(word_mix(x.to_bits(), known[0]));
                let y = f32::from_bits(unmix(rest) ^ known[1]);
                // Only words that hash as they are: finite, and not -0 (hashed as +0).
                (y.is_finite() && y.to_bits() != (-0.0f32).to_bits()).then_some([x, y, 0.0])
            })
            .collect();
        assert!(positions.len() > 3000);
        let under_known = hashes_of(&positions, known);
        assert!(under_known.iter().all(|&h| h == under_known[0]));
        let mut under_others = hashes_of(&positions, salts());
        under_others.sort_unstable();
        under_others.dedup();
        assert!(under_others.len() > positions.len() * 99 / 100);
    }

    /// The classes are numbered by first appearance, whatever the salts: only the places the
    /// vertices take in the table change.
    #[test]
    fn welds_do_not_depend_on_the_salts() {
        let mut random = crate::test_support::xorshift(0xbb67_ae85_84ca_a73b);
        let count = SHARD_VERTICES * 3;
        let mut positions: Vec<[f32; 3]> = Vec::with_capacity(count);
        for v in 0..count {
            let r = random();
            positions.push(if r % 3 == 0 && v > 0 {
                positions[(r >> 8) as usize % v]
            } else {
                [
                    (r % 71) as f32,
                    ((r >> 16) % 67) as f32,
                    ((r >> 32) % 5) as f32,
                ]
            });
        }
        let key = Key {
            positions: &positions,
            normals: None,
            uvs: None,
            finite: true,
        };
        let other = [9, 8, 7, 6, 5, 4, 3, 2];
        let welds = |salts: [u32; 8]| {
            [
                weld_in_one_table::<FirstVertices>(&key, salts),
                weld_in_one_table::<FirstKeys>(&key, salts),
                weld_in_shards(&key, salts, true),
            ]
        };
        for (a, b) in welds(salts()).into_iter().zip(welds(other)) {
            assert_eq!(a.class_count, b.class_count);
            assert!(a.class_of_vertex == b.class_of_vertex);
        }
    }

    /// The one-table welds, whose stages run blocks ahead of one another, against a weld by a
    /// map of the keys' bits, over counts around the blocks' edges (none, one, two and three
    /// blocks, whole and not).
    #[test]
    fn one_table_welds_match_a_map_at_every_block_count() {
        let mut random = crate::test_support::xorshift(0x3c6e_f372_fe94_f82b);
        for count in [0, 1, 2, 31, 32, 33, 63, 64, 65, 95, 96, 97, 200] {
            let mut positions: Vec<[f32; 3]> = Vec::with_capacity(count);
            let mut uvs: Vec<[f32; 2]> = Vec::with_capacity(count);
            for v in 0..count {
                let r = random();
                let (p, t) = match r % 6 {
                    0 | 1 if v > 0 => {
                        let earlier = (r >> 8) as usize % v;
                        (positions[earlier], uvs[earlier])
                    }
                    2 => ([f32::NAN, 0.0, 0.0], [0.0, 0.0]),
                    3 => ([-0.0, (r % 3) as f32, 0.0], [0.0, 0.0]),
                    _ => ([(r % 7) as f32, 0.0, 0.0], [((r >> 9) % 2) as f32, 0.0]),
                };
                positions.push(p);
                uvs.push(t);
            }
            let mut by_bits = std::collections::HashMap::new();
            let mut expected = Vec::with_capacity(count);
            let mut classes = 0u32;
            for (p, t) in positions.iter().zip(&uvs) {
                let words = [p[0], p[1], p[2], t[0], t[1]];
                if words.iter().any(|x| x.is_nan()) {
                    expected.push(classes);
                    classes += 1;
                    continue;
                }
                let bits = words.map(canonical_bits);
                expected.push(*by_bits.entry(bits).or_insert_with(|| {
                    classes += 1;
                    classes - 1
                }));
            }
            let key = Key {
                positions: &positions,
                normals: None,
                uvs: Some(&uvs),
                finite: false,
            };
            for weld in [
                weld_in_one_table::<FirstVertices>(&key, salts()),
                weld_in_one_table::<FirstKeys>(&key, salts()),
            ] {
                assert_eq!(weld.class_count, classes as usize, "{count} vertices");
                assert!(weld.class_of_vertex == expected, "{count} vertices");
            }
        }
    }

    /// Where no two vertices are equal (copies of a NaN vertex equal nothing either), the
    /// sharded weld gives every vertex its own class, as one table does.
    #[test]
    fn sharded_weld_of_distinct_vertices_is_the_identity() {
        let count = SHARD_VERTICES * 12 + 17;
        let positions: Vec<[f32; 3]> = (0..count)
            .map(|v| {
                if v % 1000 == 7 {
                    [f32::NAN, 0.0, 0.0]
                } else {
                    [v as f32, -0.0, 1.0]
                }
            })
            .collect();
        let key = Key {
            positions: &positions,
            normals: None,
            uvs: None,
            finite: false,
        };
        let expected = weld_in_one_table::<FirstVertices>(&key, salts());
        assert_eq!(expected.class_count, count);
        for parallel in [false, true] {
            let sharded = weld_in_shards(&key, salts(), parallel);
            assert_eq!(sharded.class_count, count);
            assert!(sharded.class_of_vertex == expected.class_of_vertex);
        }
    }

    /// In parallel (blocks of corners, pieces of classes laid out side by side) the table is the
    /// one built on one thread, filtered or not.
    #[test]
    fn corner_tables_built_in_parallel_match() {
        let class_count = 3 * LAY_OUT_CLASSES + 5;
        let mut random = crate::test_support::xorshift(0x9e37_79b9);
        let corner_class: Vec<u32> = (0..4 * class_count)
            .map(|_| match random() % 16 {
                0 => NONE,
                r if r < 8 => (random() % class_count as u64) as u32,
                // Runs of neighbouring classes, as in a mesh.
                _ => (random() % 64) as u32 + (random() % 4) as u32,
            })
            .collect();
        let keep_odd = |c: usize| c % 3 != 1;
        let one_thread = CornerTable::build_filtered(&corner_class, class_count, keep_odd, false);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(3)
            .build()
            .unwrap();
        let parallel = pool
            .install(|| CornerTable::build_filtered(&corner_class, class_count, keep_odd, true));
        assert!(parallel.offsets == one_thread.offsets);
        assert!(parallel.corners == one_thread.corners);
        let kept = (0..corner_class.len()).filter(|&c| corner_class[c] != NONE && keep_odd(c));
        assert_eq!(one_thread.corners.len(), kept.count());
    }

    #[test]
    fn corner_table_lists_corners_in_order() {
        let table = CornerTable::build(&[1, 0, 1, NONE, 0], 2);
        assert_eq!(table.of(0), &[1, 4]);
        assert_eq!(table.of(1), &[0, 2]);
    }

    /// Which classes hold several vertices, on one thread and on the pool (whose blocks each
    /// start from the highest class before them), against a count per class: classes of one
    /// vertex, of several, some spanning blocks, and numbers that start in one block and recur
    /// in the next.
    #[test]
    fn classes_with_several_vertices_are_those_with_more_than_one() {
        let mut random = crate::test_support::xorshift(0x3c6e_f372_fe94_f82b);
        for count in [0, 1, 5, 2 * MIN_LEN - 1, 5 * MIN_LEN + 3] {
            let mut class_of_vertex = Vec::with_capacity(count);
            let mut classes = 0u32;
            for _ in 0..count {
                let r = random();
                // A new class two times in three, else an earlier one, near or far.
                let class = if classes == 0 || r % 3 != 0 {
                    classes += 1;
                    classes - 1
                } else if r % 2 == 0 {
                    classes - 1 - (r >> 8) as u32 % classes.min(3)
                } else {
                    (r >> 8) as u32 % classes
                };
                class_of_vertex.push(class);
            }
            let mut members = vec![0usize; classes as usize];
            for &class in &class_of_vertex {
                members[class as usize] += 1;
            }
            let expected: Vec<bool> = members.iter().map(|&m| m > 1).collect();
            assert!(count < 5 || expected.iter().any(|&s| s) && expected.iter().any(|&s| !s));
            let weld = Weld {
                class_of_vertex,
                class_count: classes as usize,
            };
            for parallel in [false, true] {
                assert!(
                    weld.classes_with_several_vertices(parallel) == expected,
                    "{count}"
                );
            }
        }
    }
}
