//! MikkTSpace, corner for corner, without the reference's costs.
//!
//! The reference (Morten Mikkelsen's C code, and `bevy_mikktspace`, its byte-exact port) works in
//! these steps, and so do we:
//! 1. weld corners with equal position, normal and texture coordinate;
//! 2. set aside *degenerate* triangles (two corners at the same position);
//! 3. give every other triangle a first-order frame (dP/du, dP/dv) and an orientation (the sign of
//!    its UV area); a triangle whose UV area or derivative vanishes may "group with anything";
//! 4. pair triangles across shared welded edges;
//! 5. at every welded vertex, split the triangles around it into *groups*: connected through
//!    paired edges and of one orientation;
//! 6. give each group the angle-weighted sum of its triangles' frames, projected into the plane
//!    of the normal;
//! 7. let degenerate triangles borrow the tangent of another corner at the same vertex.
//!
//! What makes it fast: the reference sorts every edge of the mesh, walks groups with recursion
//! and rebuilds candidate sub-groups with an O(k²) comparison at every corner. Here everything
//! after step 3 happens per welded vertex, over the (sorted, compressed) list of corners that meet
//! there: edges are paired from that short list, groups found by a local walk, and the sub-group
//! split, which cannot happen unless two frames point in exactly opposite directions, is checked
//! in O(k) and only done the reference's way when the check fails. Vertices are independent, so
//! they are processed in parallel. Each corner's share of step 6 (its frame projected into the
//! plane of its normal, and its angle there) is computed in the triangle pass, where the inputs
//! are at hand and a batch of triangles runs as vector loops; the per-vertex pass reads one
//! 16-byte record per corner. On a large mesh each piece of vertices computes the records of
//! just the triangles it uses, into a buffer its thread reuses, instead of reading them from an
//! array of them all (see [`Layout`]).
//!
//! The one order dependency of the reference is kept: a "group with anything" triangle takes the
//! orientation of the first group (in the reference's order) to reach it. Vertices touching such
//! triangles are therefore grouped sequentially, in that order, after the others.
//!
//! Two deliberate differences, both where the reference emits garbage:
//! - a triangle with a non-finite position or texture coordinate contributes nothing (in the
//!   reference its NaN frame spreads to every corner of its vertices);
//! - the reference's edge sort (a quicksort with an off-by-one) leaves the edges of the highest
//!   welded vertex unsorted, which can leave a few triangles there unpaired. We pair them all,
//!   as `bevy_mikktspace`'s `corrected-edge-sorting` feature does.

use super::acos::acos_slice;
use super::diagnostics::{Diagnostics, FallbackCounts, TriangleCheck};
use super::fallback::{self, Problem};
use super::math::{
    Mesh, UNASSIGNED, add, dot, encode, is_finite3, length, normalize_or_zero,
    normalize_or_zero_branchless, not_zero, reject, same_position, scale, sub,
};
use super::output::{Copies, SharedSplit};
use super::prefetch::prefetch;
use super::split::SplitPlan;
use super::triangles::{BATCH, TriangleColumns, per_triangle_pass};
use super::vectors::widest_vectors;
use super::weld::{CornerTable, NONE, weld_mesh};
use rayon::prelude::*;
use std::mem::MaybeUninit;

const DEGENERATE: u8 = 1;
const GROUP_WITH_ANY: u8 = 2;
const ORIENT_PRESERVING: u8 = 4;
/// A "group with anything" triangle whose orientation a group has already fixed.
const ORIENT_FIXED: u8 = 8;

/// A triangle's first-order frame: normalized dP/du and dP/dv, each multiplied by the orientation
/// sign, as the reference stores them. Zero where the triangle has no usable UV area.
#[derive(Clone, Copy, Default)]
struct Frame {
    s: [f32; 3],
    t: [f32; 3],
}

/// MikkTSpace tangents as a split plan: repaired where the reference's would be invalid, with
/// `w` negated when `flip_w` is set. Fills the triangle, fallback and split counts of
/// `diagnostics`.
pub(crate) fn generate(
    mesh: &Mesh<'_>,
    parallel: bool,
    flip_w: bool,
    check: &TriangleCheck<'_>,
    diagnostics: &mut Diagnostics,
) -> SplitPlan {
    let layout = if mesh.triangle_count() >= PIECES_FROM {
        Layout::Pieces {
            triangles: PIECE_TRIANGLES,
        }
    } else {
        Layout::Whole
    };
    generate_laid_out(mesh, parallel, flip_w, check, diagnostics, layout)
}

/// Where the per-vertex pass finds its corners' records.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Layout {
    /// One array of every triangle's records, written by the triangle pass.
    Whole,
    /// Each piece of vertices computes the records of the triangles its vertices use (a range
    /// of about `triangles`) into a buffer its thread reuses. On a large mesh the whole array
    /// is tens of megabytes of fresh memory, which a fresh process pays for page by page (see
    /// "The whole process on this machine" in docs/benchmarks.md); the pieces' buffers are a
    /// few megabytes, and their reads stay in cache. It costs a pass of its own for the
    /// triangles' flags and checks, and the triangles at the pieces' edges computed twice, so
    /// it is for large meshes only.
    Pieces { triangles: usize },
}

/// Triangles from which a mesh's records are computed per piece of vertices: below it, the whole
/// array is small enough to be reused memory, and the second pass over the triangles costs more
/// than it saves.
const PIECES_FROM: usize = 1 << 18;

/// Triangles per piece when records are computed per piece: a buffer of 1.5 MB.
const PIECE_TRIANGLES: usize = 1 << 15;

/// [`generate`] with the records laid out as `layout` asks (the tests compare the two).
fn generate_laid_out(
    mesh: &Mesh<'_>,
    parallel: bool,
    flip_w: bool,
    check: &TriangleCheck<'_>,
    diagnostics: &mut Diagnostics,
    layout: Layout,
) -> SplitPlan {
    let triangle_count = mesh.triangle_count();
    let weld = weld_mesh(mesh, check.all_vertices_finite(), parallel);
    // Between passes, a cancelled computation stops; its caller returns nothing of it.
    let cancelled = || check.cancel.is_cancelled();
    if cancelled() {
        return SplitPlan::default();
    }

    // The class of every corner; degenerate triangles stay out of the per-vertex lists.
    let corner_class = weld.corner_classes(mesh.indices, parallel);
    // Which classes hold more than one input vertex, where any two vertices welded. The rest
    // have one, whose tangent the one-group shortcut sets without reading its corners'
    // vertices. Those were gathered for every corner of such a mesh: DamagedHelmet, whose 200
    // duplicate vertices among 14,556 made the whole mesh pay for it, was about 6% slower.
    let several_vertices = (weld.class_count != mesh.vertex_count())
        .then(|| weld.classes_with_several_vertices(parallel));
    // The vertices' classes are not read again: let them go before the largest arrays are
    // made (4 bytes a vertex off the peak).
    let class_count = weld.class_count;
    drop(weld);
    // The flags, and the records, are written in order by the triangle pass for every
    // triangle (the records, per piece, may be written later instead). Neither is zeroed
    // first: every place is written before it is read (see `RecordSlots`, `FlagSlots`).
    let mut flags: Vec<u8> = Vec::with_capacity(triangle_count);
    let mut whole = Vec::new();
    let triangles = match layout {
        Layout::Whole => {
            whole.reserve_exact(triangle_count);
            per_triangle_pass(
                mesh,
                check,
                (
                    &mut whole.spare_capacity_mut()[..triangle_count],
                    &mut flags.spare_capacity_mut()[..triangle_count],
                ),
                parallel,
                |columns: &mut Box<FrameColumns>, triangles, (contributions, flags)| {
                    columns.compute(mesh, triangles, check, contributions, flags);
                },
            )
        }
        Layout::Pieces { .. } => per_triangle_pass(
            mesh,
            check,
            &mut flags.spare_capacity_mut()[..triangle_count],
            parallel,
            |columns: &mut FlagColumns, triangles, flags| {
                columns.compute(triangles, check, flags);
            },
        ),
    };
    if cancelled() {
        return SplitPlan::default();
    }
    // SAFETY: the triangle pass wrote the flags of every triangle, and in the whole layout
    // their records: it skips a run of triangles only once the computation is cancelled, and
    // cancelling cannot be undone, so `cancelled()` would have returned above.
    unsafe { flags.set_len(triangle_count) };
    if layout == Layout::Whole {
        // SAFETY: as for the flags.
        unsafe { whole.set_len(triangle_count) };
    }
    // By blocks, each folded whole: `any` over the bytes, a loop that may stop at each, does not
    // run as a vector loop, and on a 2M-triangle mesh it took a millisecond while the other
    // threads waited.
    let has_degenerate = flags
        .chunks(1 << 12)
        .any(|block| block.iter().fold(0, |any, &f| any | f) & DEGENERATE != 0);

    // Nearly every mesh has no degenerate triangle: its table is built without reading a
    // triangle's flags for each corner.
    let table = if has_degenerate {
        CornerTable::build_filtered(
            &corner_class,
            class_count,
            |c| flags[c / 3] & DEGENERATE == 0,
            parallel,
        )
    } else {
        CornerTable::build_filtered(&corner_class, class_count, |_| true, parallel)
    };

    if cancelled() {
        return SplitPlan::default();
    }
    let threads = if parallel {
        rayon::current_num_threads()
    } else {
        1
    };
    let (pieces, spans) = match layout {
        Layout::Whole if !parallel => (std::iter::once(0..class_count).collect(), Vec::new()),
        Layout::Whole => (table.chunks(threads * 16), Vec::new()),
        Layout::Pieces { triangles } => {
            let pieces = table.chunks((triangle_count / triangles.max(1)).max(threads * 16));
            let spans: Vec<_> = if parallel {
                pieces.par_iter().map(|p| table.triangle_span(p)).collect()
            } else {
                pieces.iter().map(|p| table.triangle_span(p)).collect()
            };
            // Where the triangles' order has little to do with their vertices' (a shuffled
            // soup), the pieces' ranges overlap, and computing them would repeat much of the
            // work: the whole array is computed instead.
            let spanned: usize = spans.iter().map(|s| s.len()).sum();
            if spanned > triangle_count + triangle_count / 4 + pieces.len() * BATCH {
                whole.reserve_exact(triangle_count);
                record_all(
                    mesh,
                    &mut whole.spare_capacity_mut()[..triangle_count],
                    parallel,
                );
                // SAFETY: `record_all` writes the records of every triangle.
                unsafe { whole.set_len(triangle_count) };
                (pieces, Vec::new())
            } else {
                (pieces, spans)
            }
        }
    };
    if cancelled() {
        return SplitPlan::default();
    }
    let shared = SharedSplit::new(mesh.indices, mesh.vertex_count(), parallel);
    let context = Context {
        mesh,
        corner_class: &corner_class,
        several_vertices: several_vertices.as_deref(),
        table: &table,
        shared: &shared,
        flip_w,
    };
    // Degenerate corners, listed by vertex: they copy the raw result of their vertex's first
    // listed corner, and are handled with it.
    let mut degenerate: Vec<(u32, u32)> = Vec::new();
    if has_degenerate {
        for (triangle, &flag) in flags.iter().enumerate() {
            if flag & DEGENERATE != 0 {
                let first = 3 * triangle;
                for (k, &class) in corner_class[first..first + 3].iter().enumerate() {
                    degenerate.push((class, (first + k) as u32));
                }
            }
        }
        degenerate.sort_unstable();
    }

    // Piece `k` of the per-vertex pass, with the records of `span` computed into `buffer` (or
    // read from the whole array, where there is one).
    let whole_records = Records {
        first_corner: 0,
        records: whole.as_flattened(),
    };
    let process_piece = |k: usize, buffer: &mut PieceRecords| {
        let mut copies = Copies::default();
        if cancelled() {
            let nothing = Piece {
                repairs: Vec::new(),
                touched: Vec::new(),
            };
            return (nothing, copies);
        }
        let records = match spans.get(k) {
            Some(span) => buffer.compute(mesh, span.clone()),
            None => whole_records,
        };
        let mut put = |c: usize, t: [f32; 4]| shared.put(&mut copies, c, t);
        let piece =
            context.process_classes(pieces[k].clone(), records, &flags, &degenerate, &mut put);
        (piece, copies)
    };
    let results: Vec<(Piece, Copies)> = if parallel {
        // A buffer per thread, handed from piece to piece (rayon may split the work into more
        // jobs than it has threads).
        let buffers = std::sync::Mutex::new(Vec::<PieceRecords>::new());
        let take = || {
            let mut buffers = buffers.lock().unwrap_or_else(|e| e.into_inner());
            buffers.pop().unwrap_or_default()
        };
        (0..pieces.len())
            .into_par_iter()
            .map(|k| {
                let mut buffer = take();
                let result = process_piece(k, &mut buffer);
                let mut buffers = buffers.lock().unwrap_or_else(|e| e.into_inner());
                buffers.push(buffer);
                result
            })
            .collect()
    } else {
        let mut buffer = PieceRecords::default();
        (0..pieces.len())
            .map(|k| process_piece(k, &mut buffer))
            .collect()
    };
    let mut parts = Vec::with_capacity(results.len() + 1);
    let mut repairs = Vec::new();
    let mut touched = Vec::new();
    for (piece, copies) in results {
        repairs.extend(piece.repairs);
        touched.extend(piece.touched);
        parts.push(copies);
    }
    if cancelled() {
        return SplitPlan::default();
    }
    // The vertices left for the sequential pass own their input vertices too: new copies. Their
    // records are read from the whole array, or computed again corner by corner.
    let records = if spans.is_empty() {
        whole_records
    } else {
        Records::NONE
    };
    let mut copies = Copies::default();
    let mut put = |c: usize, t: [f32; 4]| shared.put(&mut copies, c, t);
    context.group_touched_vertices(
        &touched,
        records,
        &mut flags,
        &degenerate,
        &mut repairs,
        &mut put,
    );
    parts.push(copies);

    diagnostics.fallback_tangents = FallbackCounts::from_unordered(repairs);
    diagnostics.set_triangles(triangles);
    shared.finish(parts, mesh.normals, diagnostics)
}

/// The records of a range of corners: every corner's, one piece's, or none.
#[derive(Clone, Copy)]
struct Records<'a> {
    /// The corner of `records[0]`.
    first_corner: usize,
    records: &'a [Contribution],
}

impl Records<'_> {
    /// No records: each is computed again when asked for.
    const NONE: Records<'static> = Records {
        first_corner: 0,
        records: &[],
    };

    /// Corner `corner`'s record, computed again exactly where it is not among these.
    fn get(&self, mesh: &Mesh<'_>, corner: usize) -> Contribution {
        match corner
            .checked_sub(self.first_corner)
            .and_then(|at| self.records.get(at))
        {
            Some(&record) => record,
            None => exact_record(mesh, corner),
        }
    }
}

/// Places for triangles' records, written by the passes that compute them before anything reads
/// them. The whole array of a mesh's records is not zeroed first: in a process that reuses its
/// memory (the service, the bench), the allocator's zeroing of that array was 1.3–3% of the call
/// (see "Records without zeroing" in docs/benchmarks.md).
type RecordSlots = [MaybeUninit<[Contribution; 3]>];

/// Places for triangles' flags, written by the triangle pass before any is read, as the
/// records' are (the allocator's zeroing of them and of the corner table's offsets took about
/// 2 ms of a 2M-triangle sphere's 97 ms two-thread call, on the thread the others waited for).
type FlagSlots = [MaybeUninit<u8>];

/// Writes `flags` into `out`, place by place.
#[inline(always)]
fn write_flags(out: &mut FlagSlots, flags: &[u8]) {
    for (out, &flag) in out.iter_mut().zip(flags) {
        out.write(flag);
    }
}

/// Records already made, as places to write new ones into.
fn as_slots(records: &mut [[Contribution; 3]]) -> &mut RecordSlots {
    // SAFETY: `MaybeUninit<T>` has the layout of `T`, so the slice is the same memory read as
    // the other type. Writing through it leaves the records initialized: the only writers of
    // `RecordSlots` (the functions that take them) store whole records, never an uninitialized
    // value.
    unsafe { &mut *(std::ptr::from_mut(records) as *mut RecordSlots) }
}

/// A thread's buffer for a piece's records, and the columns it computes them in.
#[derive(Default)]
struct PieceRecords {
    records: Vec<[Contribution; 3]>,
    triangles: TriangleColumns,
    columns: Box<FrameColumns>,
}

impl PieceRecords {
    /// The records of the triangles `span`, computed as the triangle pass computes them.
    fn compute(&mut self, mesh: &Mesh<'_>, span: std::ops::Range<usize>) -> Records<'_> {
        // Only grown: every place up to the span's length is written below.
        if self.records.len() < span.len() {
            self.records.resize(span.len(), [Contribution::ZERO; 3]);
        }
        let records = &mut self.records[..span.len()];
        record_triangles(
            mesh,
            span.start,
            as_slots(records),
            &mut self.triangles,
            &mut self.columns,
        );
        Records {
            first_corner: 3 * span.start,
            records: records.as_flattened(),
        }
    }
}

/// The records of the triangles from `first` on, one per place of `out`, each written.
fn record_triangles(
    mesh: &Mesh<'_>,
    first: usize,
    out: &mut RecordSlots,
    triangles: &mut TriangleColumns,
    columns: &mut FrameColumns,
) {
    for (k, out) in out.chunks_mut(BATCH).enumerate() {
        triangles.gather(mesh, first + k * BATCH, out.len());
        columns.records(mesh, triangles, out);
    }
}

/// Every triangle's records into `out`, each place written, in runs of triangles on the thread
/// pool when `parallel`.
fn record_all(mesh: &Mesh<'_>, out: &mut RecordSlots, parallel: bool) {
    const RUN: usize = 16384;
    let run = |(k, out): (usize, &mut RecordSlots)| {
        let mut triangles = TriangleColumns::default();
        let mut columns = Box::<FrameColumns>::default();
        record_triangles(mesh, k * RUN, out, &mut triangles, &mut columns);
    };
    if parallel {
        out.par_chunks_mut(RUN).enumerate().for_each(run);
    } else {
        out.chunks_mut(RUN).enumerate().for_each(run);
    }
}

/// What one worker hands back besides the tangents it wrote.
struct Piece {
    repairs: Vec<(u32, Problem)>,
    /// Vertices left for the sequential pass (they touch "group with anything" triangles).
    touched: Vec<u32>,
}

/// What the one-group shortcut needs of a corner, computed in the triangle pass (every input it
/// needs is at hand there) and read back when its vertex is grouped. Kept to 16 bytes: an array
/// of them all is most of the extra memory where there is one (see [`Layout`]), and fresh memory
/// costs a page fault per 4 KiB. The exact values behind it are recomputed for the rare vertex
/// that takes the general path (see [`Context::exact_member`]).
///
/// The normal used is the corner's own; the welded vertex's may differ from it only in the sign
/// of a zero component, which changes no bit of the sums, angles and comparisons made from it.
#[derive(Clone, Copy)]
#[repr(C)]
struct Contribution {
    /// The triangle's dP/du projected into the normal's plane and normalized, times the
    /// corner's angle in that plane: the term the reference adds for this corner.
    weighted_s: [f32; 3],
    /// The direction of dP/dv projected, as the bytes of [`scaled_to_bytes`] (zero where it
    /// has none): enough to tell that no two frames around a vertex can be opposite. The fourth
    /// place is always 0: four bytes are written (and compared) as one word.
    t_direction: [i8; 4],
}

impl Contribution {
    /// A constant, so that filling an array with it is a plain store (building a `Default`
    /// value on the stack and copying it out stalled on every element).
    const ZERO: Contribution = Contribution {
        weighted_s: [0.0; 3],
        t_direction: [0; 4],
    };
}

/// Frames, flags and corner contributions of a batch of triangles, in columns until they are
/// copied out (see [`super::triangles`]).
struct FrameColumns {
    s: [[f32; BATCH]; 3],
    t: [[f32; BATCH]; 3],
    flags: [u8; BATCH],
    /// `normal[corner][axis][k]`, and so on: per corner of the batch's triangle `k`.
    normal: [[[f32; BATCH]; 3]; 3],
    corner_s: [[[f32; BATCH]; 3]; 3],
    /// `t` scaled for bytes (see [`Contribution::t_direction`]).
    corner_t: [[[f32; BATCH]; 3]; 3],
    /// Cosine and angle of corner `corner` of triangle `k` at `corner * BATCH + k`.
    cos: [f32; 3 * BATCH],
    angle: [f32; 3 * BATCH],
}

impl Default for FrameColumns {
    fn default() -> FrameColumns {
        FrameColumns {
            s: [[0.0; BATCH]; 3],
            t: [[0.0; BATCH]; 3],
            flags: [0; BATCH],
            normal: [[[0.0; BATCH]; 3]; 3],
            corner_s: [[[0.0; BATCH]; 3]; 3],
            corner_t: [[[0.0; BATCH]; 3]; 3],
            cos: [0.0; 3 * BATCH],
            angle: [0.0; 3 * BATCH],
        }
    }
}

impl FrameColumns {
    widest_vectors! {
        /// Frames, flags, corner contributions and check events of the gathered `triangles`;
        /// the contributions and flags go to `contributions` and `flags` (one per triangle of
        /// the batch).
        fn compute / compute_avx512 / compute_avx2 (
            &mut self,
            mesh: &Mesh<'_>,
            triangles: &mut TriangleColumns,
            check: &TriangleCheck<'_>,
            contributions: &mut RecordSlots,
            flags: &mut FlagSlots,
        ) => compute_portable
    }

    widest_vectors! {
        /// The contributions alone of the gathered `triangles`, into `contributions` (one per
        /// triangle of the batch), as [`FrameColumns::compute`] computes them.
        fn records / records_avx512 / records_avx2 (
            &mut self,
            mesh: &Mesh<'_>,
            triangles: &mut TriangleColumns,
            contributions: &mut RecordSlots,
        ) => records_portable
    }

    #[inline(always)]
    fn compute_portable(
        &mut self,
        mesh: &Mesh<'_>,
        triangles: &mut TriangleColumns,
        check: &TriangleCheck<'_>,
        contributions: &mut RecordSlots,
        flags: &mut FlagSlots,
    ) {
        self.records_portable(mesh, triangles, contributions);
        triangles.check(check);
        let len = contributions.len().min(BATCH);
        write_flags(&mut flags[..len], &self.flags[..len]);
    }

    #[inline(always)]
    fn records_portable(
        &mut self,
        mesh: &Mesh<'_>,
        triangles: &mut TriangleColumns,
        contributions: &mut RecordSlots,
    ) {
        triangles.gather_normals(mesh, &mut self.normal);
        let lanes = triangles.lanes();
        let [sx, sy, sz] = &mut self.s;
        let [tx, ty, tz] = &mut self.t;
        for k in 0..lanes {
            let (p, uv) = triangles.corners(k);
            let (frame, flag) = triangle_frame(&p, &uv);
            (sx[k], sy[k], sz[k]) = (frame.s[0], frame.s[1], frame.s[2]);
            (tx[k], ty[k], tz[k]) = (frame.t[0], frame.t[1], frame.t[2]);
            self.flags[k] = flag;
        }
        self.corner_columns::<0>(triangles, lanes);
        self.corner_columns::<1>(triangles, lanes);
        self.corner_columns::<2>(triangles, lanes);
        for corner in 0..3 {
            let places = corner * BATCH..corner * BATCH + lanes;
            acos_slice(&self.cos[places.clone()], &mut self.angle[places.clone()]);
            let angle = &self.angle[places];
            for column in &mut self.corner_s[corner] {
                for (x, &angle) in column[..lanes].iter_mut().zip(angle) {
                    *x *= angle;
                }
            }
        }
        let len = contributions.len().min(BATCH);
        store_contributions(&self.corner_s, &self.corner_t, &mut contributions[..len]);
    }

    /// [`corner_arithmetic`] for corner `CORNER` of every triangle of the batch (a constant, so
    /// that the loop indexes no array by a variable).
    #[inline(always)]
    fn corner_columns<const CORNER: usize>(&mut self, triangles: &TriangleColumns, lanes: usize) {
        let [sx, sy, sz] = &self.s;
        let [tx, ty, tz] = &self.t;
        let [nx, ny, nz] = &self.normal[CORNER];
        let [csx, csy, csz] = &mut self.corner_s[CORNER];
        let [ctx, cty, ctz] = &mut self.corner_t[CORNER];
        let cos = &mut self.cos[CORNER * BATCH..(CORNER + 1) * BATCH];
        for k in 0..lanes {
            let (p, _) = triangles.corners(k);
            let frame = Frame {
                s: [sx[k], sy[k], sz[k]],
                t: [tx[k], ty[k], tz[k]],
            };
            let (s, t, c) = corner_arithmetic(&p, CORNER, &frame, [nx[k], ny[k], nz[k]]);
            let t = scaled_to_bytes(t);
            cos[k] = c;
            (csx[k], csy[k], csz[k]) = (s[0], s[1], s[2]);
            (ctx[k], cty[k], ctz[k]) = (t[0], t[1], t[2]);
        }
    }
}

/// The flags of a batch of triangles, for a pass that computes no contributions.
struct FlagColumns {
    flags: [u8; BATCH],
}

impl Default for FlagColumns {
    fn default() -> FlagColumns {
        FlagColumns { flags: [0; BATCH] }
    }
}

impl FlagColumns {
    widest_vectors! {
        /// Flags and check events of the gathered `triangles`; the flags go to `flags` (one per
        /// triangle of the batch).
        fn compute / compute_avx512 / compute_avx2 (
            &mut self,
            triangles: &mut TriangleColumns,
            check: &TriangleCheck<'_>,
            flags: &mut FlagSlots,
        ) => compute_portable
    }

    #[inline(always)]
    fn compute_portable(
        &mut self,
        triangles: &mut TriangleColumns,
        check: &TriangleCheck<'_>,
        flags: &mut FlagSlots,
    ) {
        for k in 0..triangles.lanes() {
            let (p, uv) = triangles.corners(k);
            self.flags[k] = triangle_frame(&p, &uv).1;
        }
        triangles.check(check);
        let len = flags.len().min(BATCH);
        write_flags(&mut flags[..len], &self.flags[..len]);
    }
}

/// Copies a batch's contributions (`weighted[corner][axis][k]`, `directions[corner][axis][k]`)
/// out of their columns into `out`, one record per corner, for the batch's first `out.len()`
/// triangles (up to `BATCH`), writing each of their places. Done one value at a time, this interleaving was a fifth of the triangle pass; with
/// AVX2 it is a transpose of four columns into records, eight corners at a time (AVX-512 would
/// do sixteen, but its intrinsics need a newer compiler than the crate asks for, and the records
/// are stored one by one either way).
#[inline(always)]
fn store_contributions(
    weighted: &[[[f32; BATCH]; 3]; 3],
    directions: &[[[f32; BATCH]; 3]; 3],
    out: &mut RecordSlots,
) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU was just found to support AVX2, the only requirement.
        unsafe { store_contributions_avx2(weighted, directions, out) };
        return;
    }
    store_contributions_portable(weighted, directions, out);
}

/// [`store_contributions`] one value at a time.
#[inline(always)]
fn store_contributions_portable(
    weighted: &[[[f32; BATCH]; 3]; 3],
    directions: &[[[f32; BATCH]; 3]; 3],
    out: &mut RecordSlots,
) {
    for (k, out) in out.iter_mut().enumerate().take(BATCH) {
        out.write([0, 1, 2].map(|corner| {
            let [wx, wy, wz] = &weighted[corner];
            let [tx, ty, tz] = &directions[corner];
            Contribution {
                weighted_s: [wx[k], wy[k], wz[k]],
                t_direction: [tx[k] as i8, ty[k] as i8, tz[k] as i8, 0],
            }
        }));
    }
}

const _: () = assert!(std::mem::size_of::<Contribution>() == 16 && BATCH % 8 == 0);

/// [`store_contributions`] with AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn store_contributions_avx2(
    weighted: &[[[f32; BATCH]; 3]; 3],
    directions: &[[[f32; BATCH]; 3]; 3],
    out: &mut RecordSlots,
) {
    use std::arch::x86_64::*;
    let len = out.len().min(BATCH);
    let records = out.as_mut_ptr().cast::<Contribution>();
    // SAFETY: the loads read 8 values from `block < len <= BATCH` on, within the columns (whose
    // length, BATCH, is a multiple of 8); the stores write record `3k + corner` of `out` for
    // `k < len <= out.len()`, and a `Contribution` is 16 bytes of plain data (`repr(C)`, no
    // padding), so any four words are a valid one; `loadu` and `storeu` need no alignment. (One
    // block for the whole body: the compilers the crate supports differ in which of the other
    // intrinsics need one.)
    unsafe {
        for corner in 0..3 {
            let [wx, wy, wz] = &weighted[corner];
            let [tx, ty, tz] = &directions[corner];
            for block in (0..len).step_by(8) {
                let load = |column: &[f32; BATCH]| _mm256_loadu_ps(column.as_ptr().add(block));
                let (x, y, z) = (load(wx), load(wy), load(wz));
                // The direction's components truncated to bytes (all below 128 in magnitude
                // and so in range; NaN gives 0x80000000, whose low byte is 0, as `NaN as i8`
                // is) in one word.
                let byte = |column: &[f32; BATCH]| {
                    _mm256_and_si256(_mm256_cvttps_epi32(load(column)), _mm256_set1_epi32(0xff))
                };
                let t = _mm256_castsi256_ps(_mm256_or_si256(
                    byte(tx),
                    _mm256_or_si256(
                        _mm256_slli_epi32::<8>(byte(ty)),
                        _mm256_slli_epi32::<16>(byte(tz)),
                    ),
                ));
                // In each 128-bit lane `l`, the four corners `4l..4l + 4` of the block: first
                // pairs (x y x y, z t z t), then the pairs' halves put together as records.
                let (xy_low, xy_high) = (_mm256_unpacklo_ps(x, y), _mm256_unpackhi_ps(x, y));
                let (zt_low, zt_high) = (_mm256_unpacklo_ps(z, t), _mm256_unpackhi_ps(z, t));
                let join = |low: __m256, high: __m256, upper: bool| {
                    let (low, high) = (_mm256_castps_pd(low), _mm256_castps_pd(high));
                    _mm256_castpd_ps(if upper {
                        _mm256_unpackhi_pd(low, high)
                    } else {
                        _mm256_unpacklo_pd(low, high)
                    })
                };
                let by_corner = [
                    join(xy_low, zt_low, false),
                    join(xy_low, zt_low, true),
                    join(xy_high, zt_high, false),
                    join(xy_high, zt_high, true),
                ];
                for (lane, offset) in [0, 4].into_iter().enumerate() {
                    for (j, &four) in by_corner.iter().enumerate() {
                        let k = block + offset + j;
                        if k >= len {
                            break;
                        }
                        let record = if lane == 0 {
                            _mm256_castps256_ps128(four)
                        } else {
                            _mm256_extractf128_ps::<1>(four)
                        };
                        _mm_storeu_ps(records.add(3 * k + corner).cast(), record);
                    }
                }
            }
        }
    }
}

/// The reference's per-corner arithmetic, in its operation order: the triangle's frame projected
/// into the plane of the corner's normal (`s` normalized, `t` not) and the cosine of the corner's
/// angle in that plane. Both the batched triangle pass and [`Context::exact_member`] use it, so
/// they agree bit for bit.
#[inline(always)]
fn corner_arithmetic(
    p: &[[f32; 3]; 3],
    corner: usize,
    frame: &Frame,
    normal: [f32; 3],
) -> ([f32; 3], [f32; 3], f32) {
    let s = normalize_or_zero_branchless(reject(frame.s, normal));
    let t = reject(frame.t, normal);
    let here = p[corner];
    let v1 = normalize_or_zero_branchless(reject(sub(p[NEXT[corner]], here), normal));
    let v2 = normalize_or_zero_branchless(reject(sub(p[PREV[corner]], here), normal));
    (s, t, dot(v1, v2).clamp(-1.0, 1.0))
}

/// `t` times the power of two that puts its largest component's magnitude in [64, 128), so that
/// truncated to bytes it keeps its direction (see [`T_DIRECTIONS_CLOSE`]); zero where the largest
/// component is below 2^-121 or not finite. Only the one-group test reads the result, so it
/// need not be `t` normalized: an exponent taken from the bits spares the square root and the
/// division a normalization costs every corner. Branch-free, so that the corner loop
/// vectorizes.
#[inline(always)]
fn scaled_to_bytes(t: [f32; 3]) -> [f32; 3] {
    // The largest magnitude's biased exponent (as integers, NaN ranks above infinity).
    let exponent = t
        .map(|x| x.to_bits() & 0x7fff_ffff)
        .into_iter()
        .fold(0, u32::max)
        >> 23;
    let usable = (6..=254).contains(&exponent);
    // 2^(133 - e), whose biased exponent is 260 - e: from [2^(e-127), 2^(e-126)) into [64, 128).
    let factor = f32::from_bits(260u32.wrapping_sub(exponent) << 23);
    t.map(|x| if usable { x * factor } else { 0.0 })
}

/// The reference's per-triangle set-up, in its operation order so results are bit-identical.
/// Branch-free (every value is computed, then the right ones selected), so that the loop over a
/// batch (see [`super::triangles`]) vectorizes.
#[inline(always)]
fn triangle_frame(p: &[[f32; 3]; 3], tx: &[[f32; 2]; 3]) -> (Frame, u8) {
    let degenerate =
        same_position(p[0], p[1]) | same_position(p[1], p[2]) | same_position(p[2], p[0]);
    let d_tx = [
        [tx[1][0] - tx[0][0], tx[1][1] - tx[0][1]],
        [tx[2][0] - tx[0][0], tx[2][1] - tx[0][1]],
    ];
    let d_v = [sub(p[1], p[0]), sub(p[2], p[0])];
    let signed_area = d_tx[0][0] * d_tx[1][1] - d_tx[0][1] * d_tx[1][0];
    let area = signed_area.abs();
    let s = sub(scale(d_v[0], d_tx[1][1]), scale(d_v[1], d_tx[0][1]));
    let tt = add(scale(d_v[0], -d_tx[1][0]), scale(d_v[1], d_tx[0][0]));

    let preserving = signed_area > 0.0;
    let finite = is_finite3(p[0])
        & is_finite3(p[1])
        & is_finite3(p[2])
        & tx[0][0].is_finite()
        & tx[0][1].is_finite()
        & tx[1][0].is_finite()
        & tx[1][1].is_finite()
        & tx[2][0].is_finite()
        & tx[2][1].is_finite();
    let usable = finite & not_zero(area);
    let sign = if preserving { 1.0 } else { -1.0 };
    let frame = Frame {
        s: scale(normalize_or_zero_branchless(s), sign),
        t: scale(normalize_or_zero_branchless(tt), sign),
    };
    let solid = not_zero(length(s) / area) & not_zero(length(tt) / area);
    let orientation = if preserving { ORIENT_PRESERVING } else { 0 };
    let any = if usable & solid { 0 } else { GROUP_WITH_ANY };
    if degenerate {
        (Frame::default(), DEGENERATE)
    } else if usable {
        (frame, any | orientation)
    } else {
        (Frame::default(), GROUP_WITH_ANY | orientation)
    }
}

/// [`corner_arithmetic`] for one corner, from the mesh.
fn exact_corner(mesh: &Mesh<'_>, corner: usize) -> ([f32; 3], [f32; 3], f32) {
    let triangle = mesh.triangle(corner / 3);
    let p = triangle.map(|v| mesh.positions[v]);
    let uv = triangle.map(|v| mesh.uv(v));
    let (frame, _) = triangle_frame(&p, &uv);
    let normal = mesh.normals[mesh.indices[corner] as usize];
    corner_arithmetic(&p, corner % 3, &frame, normal)
}

/// A corner's record computed again from the mesh: the same values, bit for bit, as the
/// triangle pass stores (the same functions, and the arccosine the batched one matches).
fn exact_record(mesh: &Mesh<'_>, corner: usize) -> Contribution {
    let (s, t, cos) = exact_corner(mesh, corner);
    let angle = (cos as f64).acos() as f32;
    let t = scaled_to_bytes(t);
    Contribution {
        weighted_s: s.map(|x| x * angle),
        t_direction: [t[0] as i8, t[1] as i8, t[2] as i8, 0],
    }
}

struct Context<'a> {
    mesh: &'a Mesh<'a>,
    corner_class: &'a [u32],
    /// Which classes hold more than one input vertex; `None` where no two vertices welded, so
    /// that a class is the one input vertex of that number (and `corner_class` is the index
    /// buffer).
    several_vertices: Option<&'a [bool]>,
    table: &'a CornerTable,
    shared: &'a SharedSplit<'a>,
    flip_w: bool,
}

/// Per-vertex working memory, reused from vertex to vertex.
#[derive(Default)]
struct Scratch {
    /// Half-edges around the vertex.
    half_edges: Vec<HalfEdge>,
    /// For each corner around the vertex, the local index of the corner across its incoming
    /// edge (`[0]`, from the previous corner) and its outgoing edge (`[1]`), or `NONE`.
    links: Vec<[u32; 2]>,
    labels: Vec<u32>,
    stack: Vec<u32>,
    eval: EvalScratch,
}

#[derive(Clone, Copy)]
struct HalfEdge {
    other: u32,
    local: u32,
    /// 0: the edge arrives at this vertex; 1: it leaves it.
    side: u8,
}

impl Context<'_> {
    /// A corner's contribution with the values it was made from, computed again exactly as
    /// the triangle pass did (the same functions, and the arccosine the batched one matches).
    fn exact_member(&self, corner: usize) -> Member {
        let (s, t, cos) = self.exact_corner(corner);
        Member {
            s,
            t,
            angle: (cos as f64).acos() as f32,
            any: false,
        }
    }

    /// [`exact_corner`] of this context's mesh.
    fn exact_corner(&self, corner: usize) -> ([f32; 3], [f32; 3], f32) {
        exact_corner(self.mesh, corner)
    }

    /// The one-group sum for a vertex whose frames spread too widely for the records' test
    /// (hard-surface meshes with smoothed normals: SciFiHelmet has about a hundred such
    /// vertices, each of which took the general path, its exact members and its O(k²) sub-group
    /// search, at about 1 µs a vertex). The reference puts two corners in different sub-groups
    /// only if their exact frames fail its similarity test; this runs that test, on the exact
    /// frames, for every pair. If every pair passes, every corner's sub-group is the whole
    /// group, and its tangent the records' sum in ascending order, as in the shortcut. `None`
    /// if any pair fails (including on NaN), for the general path to decide.
    fn sum_unless_frames_oppose(
        &self,
        corners: &[u32],
        records: &[Contribution],
    ) -> Option<[f32; 3]> {
        const MAX: usize = 32;
        if corners.len() > MAX {
            return None;
        }
        let mut frames = [([0.0f32; 3], [0.0f32; 3]); MAX];
        for (frame, &corner) in frames.iter_mut().zip(corners) {
            let (s, t, _) = self.exact_corner(corner as usize);
            *frame = (s, normalize_or_zero(t));
        }
        let frames = &frames[..corners.len()];
        for (a, &(sa, ta)) in frames.iter().enumerate() {
            for (b, &(sb, tb)) in frames.iter().enumerate().skip(a + 1) {
                // As `evaluate_group` compares members (no corner here groups with anything).
                let same_face = corners[a] / 3 == corners[b] / 3;
                if !(same_face || (dot(sa, sb) > -1.0 && dot(ta, tb) > -1.0)) {
                    return None;
                }
            }
        }
        // The order and operations of `sum_of_one_group`.
        Some(
            records
                .iter()
                .fold([0.0f32; 3], |sum, record| add(sum, record.weighted_s)),
        )
    }

    /// Groups and evaluates the vertices `classes`, except those touching "group with anything"
    /// triangles, which are handed back for the sequential pass.
    fn process_classes<P: FnMut(usize, [f32; 4])>(
        &self,
        classes: std::ops::Range<usize>,
        records: Records<'_>,
        flags: &[u8],
        degenerate: &[(u32, u32)],
        put: &mut P,
    ) -> Piece {
        let mut scratch = Scratch::default();
        let mut piece = Piece {
            repairs: Vec::new(),
            touched: Vec::new(),
        };
        let mut run = Run::default();
        let mut start = classes.start;
        while start < classes.end {
            // A run of vertices with about RUN_CORNERS corners between them.
            let first_slot = self.table.offsets[start] as usize;
            let mut end = start + 1;
            while end < classes.end
                && self.table.offsets[end + 1] as usize - first_slot <= RUN_CORNERS
            {
                end += 1;
            }
            let slots = first_slot..self.table.offsets[end] as usize;
            run.gather(self, records, flags, &self.table.corners[slots]);
            for class in start..end {
                let corners = self.table.of(class);
                let offset = self.table.offsets[class] as usize - first_slot;
                let slots = offset..offset + corners.len();
                // The flags all corners' triangles have, and those any of them has.
                let (all, any) = run.flags[slots.clone()]
                    .iter()
                    .fold((u8::MAX, 0u8), |(all, any), &flag| (all & flag, any | flag));
                if any & GROUP_WITH_ANY != 0 {
                    piece.touched.push(class as u32);
                    continue;
                }
                let one_orientation = (all ^ any) & ORIENT_PRESERVING == 0;
                if one_orientation
                    && self.try_one_group(
                        class,
                        any & ORIENT_PRESERVING,
                        &run.ends[slots.clone()],
                        &run.contributions[slots.start..],
                        degenerate,
                        &mut piece.repairs,
                        put,
                    )
                {
                    continue;
                }
                self.pair_edges(class, &mut scratch);
                label_components(corners, flags, &mut scratch);
                self.evaluate(class, records, flags, &scratch.labels, &mut scratch.eval);
                self.finish_class(
                    class,
                    &scratch.eval.raw,
                    degenerate,
                    &mut piece.repairs,
                    put,
                );
            }
            start = end;
        }
        piece
    }

    /// The common vertex, without the general machinery: its triangles share one orientation
    /// (the caller checks that, and that none may "group with anything"; `orientation` is their
    /// `ORIENT_PRESERVING` bit),
    /// every edge around it pairs unambiguously (no other vertex is reached twice the same way),
    /// the pairs connect all its corners into one group, and no two frames can be opposite.
    /// Then the general path would find one group summed in ascending order, which is what is
    /// computed here. Returns false, having written nothing, for any other vertex. `records`
    /// starts with the vertex's corners' records, and holds anything after them up to a
    /// multiple of four (see [`sum_of_one_group`]).
    #[allow(clippy::too_many_arguments)]
    fn try_one_group<P: FnMut(usize, [f32; 4])>(
        &self,
        class: usize,
        orientation: u8,
        ends: &[[u32; 2]],
        records: &[Contribution],
        degenerate: &[(u32, u32)],
        repairs: &mut Vec<(u32, Problem)>,
        put: &mut P,
    ) -> bool {
        let corners = self.table.of(class);
        let k = corners.len();
        // Most vertices have at most eight corners, and on meshes with many seams at most four:
        // arrays that size are set up in a few stores.
        let one_fan = match k {
            0 => false,
            1..=4 => one_small_fan::<1>(ends),
            5..=8 => one_small_fan::<2>(ends),
            9..=32 => one_fan::<32>(ends),
            _ => false,
        };
        if !one_fan {
            return false;
        }

        let Some(sum) = sum_of_one_group(records, k)
            .or_else(|| self.sum_unless_frames_oppose(corners, &records[..k]))
        else {
            return false;
        };
        let raw = encode(normalize_or_zero(sum), orientation != 0);
        let indices = self.mesh.indices;
        // The class's input vertex, where it has one; else its first corner's.
        let (first_vertex, one_vertex) = match self.several_vertices {
            None => (class, true),
            Some(several) => (indices[corners[0] as usize] as usize, !several[class]),
        };
        let normal = self.mesh.normals[first_vertex];
        if fallback::check_normal(normal).is_some_and(|n| fallback::passes(&raw, &n)) {
            // Valid: every corner gets the same finished tangent, and no other vertex has
            // corners of these input vertices, so each is given it once, as its only tangent.
            let tangent = fallback::with_w_convention(raw, self.flip_w);
            if one_vertex {
                self.shared.set_only_tangent(first_vertex, tangent);
            } else {
                let mut previous = NONE;
                for &corner in corners {
                    let vertex = indices[corner as usize];
                    if vertex != previous {
                        self.shared.set_only_tangent(vertex as usize, tangent);
                        previous = vertex;
                    }
                }
            }
        } else {
            for &corner in corners {
                self.finish_corner(corner as usize, raw, false, repairs, put);
            }
        }
        self.finish_degenerate(class, raw, degenerate, repairs, put);
        true
    }

    /// Validates, repairs where needed, converts `w` and writes the corners of one vertex.
    fn finish_class<P: FnMut(usize, [f32; 4])>(
        &self,
        class: usize,
        raw: &[[f32; 4]],
        degenerate: &[(u32, u32)],
        repairs: &mut Vec<(u32, Problem)>,
        put: &mut P,
    ) {
        let corners = self.table.of(class);
        let Some(&first) = corners.first() else {
            self.finish_degenerate(class, UNASSIGNED, degenerate, repairs, put);
            return;
        };
        let normal = self.mesh.normals[self.mesh.indices[first as usize] as usize];
        let check_normal = fallback::check_normal(normal);
        for (&corner, &tangent) in corners.iter().zip(raw) {
            let ok = check_normal.is_some_and(|n| fallback::passes(&tangent, &n));
            self.finish_corner(corner as usize, tangent, ok, repairs, put);
        }
        self.finish_degenerate(class, raw[0], degenerate, repairs, put);
    }

    #[inline]
    fn finish_corner<P: FnMut(usize, [f32; 4])>(
        &self,
        corner: usize,
        tangent: [f32; 4],
        known_valid: bool,
        repairs: &mut Vec<(u32, Problem)>,
        put: &mut P,
    ) {
        let tangent = fallback::finish_corner(
            self.mesh,
            corner,
            tangent,
            known_valid,
            self.flip_w,
            repairs,
        );
        put(corner, tangent);
    }

    /// Degenerate triangles (two corners at one position) take the raw result of the first
    /// listed corner of their vertex, `first_raw`, as the reference does.
    fn finish_degenerate<P: FnMut(usize, [f32; 4])>(
        &self,
        class: usize,
        first_raw: [f32; 4],
        degenerate: &[(u32, u32)],
        repairs: &mut Vec<(u32, Problem)>,
        put: &mut P,
    ) {
        if degenerate.is_empty() {
            return;
        }
        let start = degenerate.partition_point(|&(c, _)| (c as usize) < class);
        for &(c, corner) in &degenerate[start..] {
            if c as usize != class {
                break;
            }
            self.finish_corner(corner as usize, first_raw, false, repairs, put);
        }
    }

    /// Pairs the triangles around `class` across the edges they share, as the reference does:
    /// the edges with the same two (welded) ends are taken in triangle order, and each edge not
    /// yet paired takes the first later edge running the opposite way that is not paired either.
    fn pair_edges(&self, class: usize, scratch: &mut Scratch) {
        let corners = self.table.of(class);
        scratch.half_edges.clear();
        for (local, &corner) in corners.iter().enumerate() {
            let corner = corner as usize;
            let triangle = corner / 3;
            let base = triangle * 3;
            let next = self.corner_class[base + (corner + 1) % 3];
            let prev = self.corner_class[base + (corner + 2) % 3];
            let local = local as u32;
            scratch.half_edges.push(HalfEdge {
                other: prev,
                local,
                side: 0,
            });
            scratch.half_edges.push(HalfEdge {
                other: next,
                local,
                side: 1,
            });
        }
        let edges = &mut scratch.half_edges;
        if edges.len() <= 24 {
            // Insertion sort: the lists are short and already ordered by triangle.
            for i in 1..edges.len() {
                let mut j = i;
                while j > 0 && edges[j - 1].other > edges[j].other {
                    edges.swap(j - 1, j);
                    j -= 1;
                }
            }
        } else {
            edges.sort_by_key(|e| e.other);
        }
        scratch.links.clear();
        scratch.links.resize(corners.len(), [NONE; 2]);
        let mut run_start = 0;
        while run_start < edges.len() {
            let other = edges[run_start].other;
            let mut run_end = run_start + 1;
            while run_end < edges.len() && edges[run_end].other == other {
                run_end += 1;
            }
            if run_end - run_start >= 2 && other != NONE {
                for a in run_start..run_end {
                    let ea = edges[a];
                    if scratch.links[ea.local as usize][ea.side as usize] != NONE {
                        continue;
                    }
                    // The opposite direction means the other side at this vertex: an edge that
                    // leaves this vertex in one triangle arrives at it in its neighbour.
                    let partner = edges[a + 1..run_end].iter().find(|eb| {
                        eb.side != ea.side
                            && scratch.links[eb.local as usize][eb.side as usize] == NONE
                    });
                    if let Some(eb) = partner {
                        scratch.links[ea.local as usize][ea.side as usize] = eb.local;
                        scratch.links[eb.local as usize][eb.side as usize] = ea.local;
                    }
                }
            }
            run_start = run_end;
        }
    }

    /// Groups the vertices that touch "group with anything" triangles, in the reference's order:
    /// seeds by ascending corner, each group walked depth first, incoming edge before outgoing.
    fn group_touched_vertices<P: FnMut(usize, [f32; 4])>(
        &self,
        touched: &[u32],
        records: Records<'_>,
        flags: &mut [u8],
        degenerate: &[(u32, u32)],
        repairs: &mut Vec<(u32, Problem)>,
        put: &mut P,
    ) {
        if touched.is_empty() {
            return;
        }
        let mut scratch = Scratch::default();
        // Links and labels of every touched vertex, laid out one vertex after another.
        let mut link_offsets = Vec::with_capacity(touched.len() + 1);
        let mut links: Vec<[u32; 2]> = Vec::new();
        link_offsets.push(0usize);
        for &class in touched {
            self.pair_edges(class as usize, &mut scratch);
            links.extend_from_slice(&scratch.links);
            link_offsets.push(links.len());
        }
        let mut labels = vec![NONE; links.len()];
        // Seeds in ascending corner order: (corner, touched vertex number, local index).
        let mut seeds: Vec<(u32, u32, u32)> = Vec::with_capacity(links.len());
        for (k, &class) in touched.iter().enumerate() {
            for (local, &corner) in self.table.of(class as usize).iter().enumerate() {
                seeds.push((corner, k as u32, local as u32));
            }
        }
        seeds.sort_unstable();
        let mut stack: Vec<u32> = Vec::new();
        for &(corner, k, local) in &seeds {
            let k = k as usize;
            let base = link_offsets[k];
            let corners = self.table.of(touched[k] as usize);
            let seed_triangle = corner as usize / 3;
            if flags[seed_triangle] & GROUP_WITH_ANY != 0 || labels[base + local as usize] != NONE {
                continue;
            }
            let orientation = flags[seed_triangle] & ORIENT_PRESERVING;
            labels[base + local as usize] = corner;
            let [incoming, outgoing] = links[base + local as usize];
            stack.clear();
            stack.extend([outgoing, incoming].into_iter().filter(|&l| l != NONE));
            while let Some(next) = stack.pop() {
                let slot = base + next as usize;
                if labels[slot] != NONE {
                    continue;
                }
                let triangle = corners[next as usize] as usize / 3;
                let flag = &mut flags[triangle];
                if *flag & GROUP_WITH_ANY != 0 && *flag & ORIENT_FIXED == 0 {
                    // The first group to reach it decides its orientation.
                    *flag = (*flag & !ORIENT_PRESERVING) | orientation;
                }
                if *flag & ORIENT_PRESERVING != orientation {
                    continue;
                }
                if *flag & GROUP_WITH_ANY != 0 {
                    *flag |= ORIENT_FIXED;
                }
                labels[slot] = corner;
                let [incoming, outgoing] = links[slot];
                stack.extend([outgoing, incoming].into_iter().filter(|&l| l != NONE));
            }
        }
        for (k, &class) in touched.iter().enumerate() {
            let class = class as usize;
            let labels = &labels[link_offsets[k]..link_offsets[k + 1]];
            self.evaluate(class, records, flags, labels, &mut scratch.eval);
            self.finish_class(class, &scratch.eval.raw, degenerate, repairs, put);
        }
    }

    /// Computes the raw tangent of every corner around `class` into `eval.raw`, from its group
    /// label (`NONE`: no group, the corner stays unassigned).
    fn evaluate(
        &self,
        class: usize,
        records: Records<'_>,
        flags: &[u8],
        labels: &[u32],
        eval: &mut EvalScratch,
    ) {
        let corners = self.table.of(class);
        eval.raw.clear();
        eval.raw.resize(corners.len(), UNASSIGNED);
        // The exact members are computed again only for a vertex with a group that needs them
        // (see `one_subgroup_from_records`).
        eval.members.clear();

        // Corners in group order: by label, then ascending (which is ascending triangle order,
        // the order the reference sums in).
        eval.order.clear();
        eval.order
            .extend((0..corners.len() as u32).filter(|&j| labels[j as usize] != NONE));
        if eval.order.len() <= 16 {
            for i in 1..eval.order.len() {
                let mut j = i;
                while j > 0 && labels[eval.order[j - 1] as usize] > labels[eval.order[j] as usize] {
                    eval.order.swap(j - 1, j);
                    j -= 1;
                }
            }
        } else {
            eval.order.sort_by_key(|&j| labels[j as usize]);
        }
        let mut start = 0;
        while start < eval.order.len() {
            let label = labels[eval.order[start] as usize];
            let mut end = start + 1;
            while end < eval.order.len() && labels[eval.order[end] as usize] == label {
                end += 1;
            }
            eval.group.clear();
            eval.group.extend_from_slice(&eval.order[start..end]);
            let first = corners[eval.group[0] as usize] as usize;
            let orientation_preserving = flags[first / 3] & ORIENT_PRESERVING != 0;
            if let Some(tangent) = self.one_subgroup_from_records(corners, records, flags, eval) {
                for &j in &eval.group {
                    eval.raw[j as usize] = encode(tangent, orientation_preserving);
                }
            } else {
                if eval.members.is_empty() {
                    for &corner in corners {
                        let any = flags[corner as usize / 3] & GROUP_WITH_ANY != 0;
                        eval.members.push(if any {
                            Member {
                                any,
                                ..Member::default()
                            }
                        } else {
                            self.exact_member(corner as usize)
                        });
                    }
                }
                self.evaluate_group(corners, orientation_preserving, eval);
            }
            start = end;
        }
    }

    /// The tangent of `eval.group` from the triangle pass's records, when they show it is one
    /// sub-group, as the one-group shortcut does (see `sum_of_one_group`): then the reference's
    /// sub-groups are each the whole group, and the result is the sum of its weighted frames in
    /// group order, which are exactly the records' (`scale(s, angle)`, the same products).
    /// `None` for a group with a "group with anything" corner, or one the test cannot clear:
    /// those take the exact members.
    fn one_subgroup_from_records(
        &self,
        corners: &[u32],
        records: Records<'_>,
        flags: &[u8],
        eval: &mut EvalScratch,
    ) -> Option<[f32; 3]> {
        eval.records.clear();
        for &j in &eval.group {
            let corner = corners[j as usize] as usize;
            if flags[corner / 3] & GROUP_WITH_ANY != 0 {
                return None;
            }
            eval.records.push(records.get(self.mesh, corner));
        }
        sum_of_one_group_portable(&eval.records).map(normalize_or_zero)
    }

    fn evaluate_group(
        &self,
        corners: &[u32],
        orientation_preserving: bool,
        eval: &mut EvalScratch,
    ) {
        let members = &eval.members;
        let group = &eval.group;
        let out = &mut eval.raw;
        // A member leaves another's sub-group only if their projected frames point in exactly
        // opposite directions (cosine <= -1 in float) or are NaN. If every frame lies within
        // ~89° of the first, no pair can be opposite and the group is one sub-group. (`t` is
        // not normalized, so its test compares squares: cos > 0.01 ⇔ d > 0 and d² > 1e-4 |a|²|b|².)
        let reference = group.iter().map(|&j| &members[j as usize]).find(|m| !m.any);
        let single = match reference {
            None => true,
            Some(r) => {
                let rt2 = dot(r.t, r.t);
                group.iter().map(|&j| &members[j as usize]).all(|m| {
                    let d = dot(m.t, r.t);
                    m.any
                        || (dot(m.s, r.s) > 0.01 && d > 0.0 && d * d > 1e-4 * (dot(m.t, m.t) * rt2))
                })
            }
        };
        if single || group.len() > MAX_EXACT_SUBGROUP {
            let tangent = sum_tangents(group.iter().map(|&j| &members[j as usize]));
            for &j in group {
                out[j as usize] = encode(tangent, orientation_preserving);
            }
            return;
        }
        // The reference's sub-groups: for each member, the members it is "similar" to.
        let unit_t = |m: &Member| normalize_or_zero(m.t);
        for &a in group {
            let ma = &members[a as usize];
            let ta = unit_t(ma);
            let subgroup = group.iter().filter(|&&b| {
                let mb = &members[b as usize];
                let same_face = corners[a as usize] / 3 == corners[b as usize] / 3;
                ma.any
                    || mb.any
                    || same_face
                    || (dot(ma.s, mb.s) > -1.0 && dot(ta, unit_t(mb)) > -1.0)
            });
            let tangent = sum_tangents(subgroup.map(|&j| &members[j as usize]));
            out[a as usize] = encode(tangent, orientation_preserving);
        }
    }
}

/// Groups larger than this skip the reference's O(k²) sub-group search and use the whole group,
/// which differs from the reference only if two of their frames are exactly opposite.
const MAX_EXACT_SUBGROUP: usize = 2048;

#[derive(Clone, Copy, Default)]
struct Member {
    /// The triangle's dP/du projected into the normal's plane, normalized.
    s: [f32; 3],
    /// Its dP/dv projected, not normalized (only the sub-group test needs it).
    t: [f32; 3],
    /// The corner's angle in the normal's plane: the weight.
    angle: f32,
    any: bool,
}

/// What the one-group shortcut reads of each corner of a run of vertices, gathered in table
/// order before any of them is grouped: the reads are scattered over the mesh, and in one tight
/// loop they overlap, where between the branches of the grouping they would wait one by one.
#[derive(Default)]
struct Run {
    contributions: Vec<Contribution>,
    /// The other ends (their classes) of the edges arriving at and leaving each corner.
    ends: Vec<[u32; 2]>,
    /// Its triangle's flags.
    flags: Vec<u8>,
}

/// How many corners ahead [`Run::gather`] asks for a corner's record: enough to cover a miss
/// to memory at the loop's pace.
const PREFETCH_AHEAD: usize = 16;

/// Above this many corners a run is closed (a vertex with more corners gets one of its own).
const RUN_CORNERS: usize = 512;

impl Run {
    /// Out of line: inlined into the grouping, its loops ran short of registers and read their
    /// pointers back from the stack.
    #[inline(never)]
    fn gather(
        &mut self,
        context: &Context<'_>,
        records: Records<'_>,
        flags: &[u8],
        corners: &[u32],
    ) {
        let len = corners.len();
        // Only grown, never cleared: every place up to `len` is written below.
        if self.flags.len() < len {
            // Three places more, for the last vertex's last four (see `sum_of_one_group`).
            self.contributions.resize(len + 3, Contribution::ZERO);
            self.ends.resize(len, [0; 2]);
            self.flags.resize(len, 0);
        }
        let contributions = &mut self.contributions[..len];
        let ends = &mut self.ends[..len];
        let corner_flags = &mut self.flags[..len];
        // The records as one array of corners (a triangle's three are contiguous), so that a
        // corner's record and a prefetch of one ahead need no division by three. Two loops, the
        // records first: in one, the pointers it needed did not fit in registers.
        let (first, records) = (records.first_corner, records.records);
        let classes = context.corner_class;
        // All but the last PREFETCH_AHEAD corners ask for the record of the corner that far
        // ahead, and for its classes, which the second loop reads; the rest are on their way.
        let ahead = corners.get(PREFETCH_AHEAD..).unwrap_or_default();
        for ((&corner, &later), record) in corners.iter().zip(ahead).zip(contributions.iter_mut()) {
            prefetch(&records[later as usize - first]);
            prefetch(&classes[later as usize]);
            *record = records[corner as usize - first];
        }
        for (&corner, record) in corners.iter().zip(contributions).skip(ahead.len()) {
            *record = records[corner as usize - first];
        }
        for ((&corner, end), flag) in corners.iter().zip(ends).zip(corner_flags) {
            let corner = corner as usize;
            let triangle = corner / 3;
            let first = 3 * triangle;
            let i = corner - first;
            *end = [classes[first + PREV[i]], classes[first + NEXT[i]]];
            *flag = flags[triangle];
        }
    }
}

/// The sum of a vertex's weighted `s`, in order, if its corners make one sub-group: unless two
/// frames can be opposite (see `evaluate_group`), which they cannot be if every `s` lies within
/// ~89.4° of the first (a weighted `s` has its direction, or is zero and fails) and every `t`
/// within ~89.4° (see [`T_DIRECTIONS_CLOSE`]). The sum is made whether or not the test passes (it
/// nearly always does). The corners' records are `records[..k]`, at least one; `records` goes
/// on to a multiple of four with places whatever they hold, so that the last four are loaded
/// whole (then left out of the verdict) instead of being copied out first.
#[inline(always)]
fn sum_of_one_group(records: &[Contribution], k: usize) -> Option<[f32; 3]> {
    #[cfg(target_arch = "x86_64")]
    return sum_of_one_group_sse2(records, k);
    #[cfg(not(target_arch = "x86_64"))]
    return sum_of_one_group_portable(&records[..k]);
}

#[inline(always)]
fn sum_of_one_group_portable(contributions: &[Contribution]) -> Option<[f32; 3]> {
    let (rs, rt) = (contributions[0].weighted_s, contributions[0].t_direction);
    let rs2 = dot(rs, rs);
    let mut single = true;
    let mut sum = [0.0f32; 3];
    for &Contribution {
        weighted_s,
        t_direction,
    } in contributions
    {
        let d = dot(weighted_s, rs);
        single &= d > 0.0 && d * d > 1e-4 * (dot(weighted_s, weighted_s) * rs2);
        single &= dot_i8(t_direction, rt) > T_DIRECTIONS_CLOSE;
        sum = add(sum, weighted_s);
    }
    single.then_some(sum)
}

/// [`sum_of_one_group_portable`] four corners at a time (SSE2, part of the x86-64 baseline): the
/// records are transposed into columns, tested with the same operations in the same order (so
/// the verdict is the same), and summed as whole records, which adds each component in the
/// same order too. Scalar, the test was a quarter of the per-vertex pass.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn sum_of_one_group_sse2(records: &[Contribution], k: usize) -> Option<[f32; 3]> {
    use std::arch::x86_64::*;
    let groups = &records[..k.next_multiple_of(4)];
    let first = groups[0];
    let (rs, rt) = (first.weighted_s, first.t_direction);
    let rs2 = dot(rs, rs);
    // SAFETY: SSE2 is part of the x86-64 baseline. Every load reads one 16-byte record
    // (`Contribution` is `repr(C)`: three floats and four bytes).
    unsafe {
        let load = |record: &Contribution| _mm_loadu_ps((record as *const Contribution).cast());
        let (rx, ry, rz) = (_mm_set1_ps(rs[0]), _mm_set1_ps(rs[1]), _mm_set1_ps(rs[2]));
        let (bound, rs2) = (_mm_set1_ps(1e-4), _mm_set1_ps(rs2));
        let [r0, r1, r2, r3] = rt.map(i16::from);
        let rt = _mm_set_epi16(r3, r2, r1, r0, r3, r2, r1, r0);
        let close = _mm_set1_epi32(T_DIRECTIONS_CLOSE);
        // The fourth lane of a record is its direction's bytes, not a number: zeroed before
        // the sum, which never reads it, since as a number it may be subnormal, and some CPUs
        // add those slowly.
        let xyz = _mm_castsi128_ps(_mm_set_epi32(0, -1, -1, -1));
        let mut sum = _mm_setzero_ps();
        for record in &groups[..k] {
            sum = _mm_add_ps(sum, _mm_and_ps(load(record), xyz));
        }
        // A bit for every corner that fails, and for none of the places after the corners.
        let mut fails = 0i32;
        for (g, four) in groups.chunks_exact(4).enumerate() {
            let four = [
                load(&four[0]),
                load(&four[1]),
                load(&four[2]),
                load(&four[3]),
            ];
            // Columns x, y, z and the directions' words.
            let low01 = _mm_unpacklo_ps(four[0], four[1]);
            let low23 = _mm_unpacklo_ps(four[2], four[3]);
            let high01 = _mm_unpackhi_ps(four[0], four[1]);
            let high23 = _mm_unpackhi_ps(four[2], four[3]);
            let (x, y) = (_mm_movelh_ps(low01, low23), _mm_movehl_ps(low23, low01));
            let (z, t) = (_mm_movelh_ps(high01, high23), _mm_movehl_ps(high23, high01));
            // `dot(s, rs)` and `dot(s, s)`, each as `dot` adds its products.
            let d = _mm_add_ps(
                _mm_add_ps(_mm_mul_ps(x, rx), _mm_mul_ps(y, ry)),
                _mm_mul_ps(z, rz),
            );
            let ss = _mm_add_ps(
                _mm_add_ps(_mm_mul_ps(x, x), _mm_mul_ps(y, y)),
                _mm_mul_ps(z, z),
            );
            let s_close = _mm_and_ps(
                _mm_cmpgt_ps(d, _mm_setzero_ps()),
                _mm_cmpgt_ps(_mm_mul_ps(d, d), _mm_mul_ps(bound, _mm_mul_ps(ss, rs2))),
            );
            // The directions' bytes widened to 16 bits (each byte doubled, then shifted down
            // with its sign), multiplied by the first's and added in pairs, then the pairs of
            // each corner added.
            let t = _mm_castps_si128(t);
            let low = _mm_srai_epi16::<8>(_mm_unpacklo_epi8(t, t));
            let high = _mm_srai_epi16::<8>(_mm_unpackhi_epi8(t, t));
            let (low, high) = (
                _mm_castsi128_ps(_mm_madd_epi16(low, rt)),
                _mm_castsi128_ps(_mm_madd_epi16(high, rt)),
            );
            let t_dot = _mm_add_epi32(
                _mm_castps_si128(_mm_shuffle_ps::<0b10_00_10_00>(low, high)),
                _mm_castps_si128(_mm_shuffle_ps::<0b11_01_11_01>(low, high)),
            );
            let t_close = _mm_castsi128_ps(_mm_cmpgt_epi32(t_dot, close));
            let corners = (k - 4 * g).min(4);
            fails |= !_mm_movemask_ps(_mm_and_ps(s_close, t_close)) & ((1 << corners) - 1);
        }
        let mut lanes = [0.0f32; 4];
        _mm_storeu_ps(lanes.as_mut_ptr(), sum);
        (fails == 0).then_some([lanes[0], lanes[1], lanes[2]])
    }
}

/// The least dot product of two [`Contribution::t_direction`]s whose vectors are sure to make a
/// cosine above 0.01. Before truncation each vector `A` had its largest component in [64, 128),
/// so `64 <= |A| < 128 √3 < 221.8`. Truncation moves each component less than 1, so the bytes'
/// dot product lies less than `√3 (|A| + |B|) + 3 < 772` from `A · B`; above this bound
/// `A · B > 508`, and `cos = A · B / (|A| |B|) > 508 / 221.8² ≈ 0.0103`.
const T_DIRECTIONS_CLOSE: i32 = 1280;

#[inline(always)]
fn dot_i8(a: [i8; 4], b: [i8; 4]) -> i32 {
    a.iter()
        .zip(&b)
        .map(|(&x, &y)| i32::from(x) * i32::from(y))
        .sum()
}

/// [`one_fan`] for vertices of at most `4 * BLOCKS` corners (1 or 2 blocks: most vertices of a
/// mesh with many UV seams, DamagedHelmet's for one, have at most four, and one block is set up
/// and compared in half the instructions, which made that mesh 4% faster), nearly every vertex
/// of a mesh. Each edge is matched against a block of four with one vector comparison, and the
/// corners' followers are kept as four-bit numbers in one word, so the walk through them is a
/// shift and a mask a step (from an array, each step waited on a load it had just stored).
#[inline(always)]
fn one_small_fan<const BLOCKS: usize>(ends: &[[u32; 2]]) -> bool {
    let k = ends.len();
    debug_assert!((1..=4 * BLOCKS).contains(&k));
    // Unused places hold `NONE`, which no class equals.
    let mut arriving = [[NONE; 4]; BLOCKS];
    for (j, &[arrives, _]) in ends.iter().enumerate().take(4 * BLOCKS) {
        arriving[j / 4][j % 4] = arrives;
    }
    // `successors`: four bits a corner, the corner whose arriving edge pairs with the edge
    // leaving it, or `NO_SUCCESSOR`; `paired`: the corners that follow another.
    const NO_SUCCESSOR: u32 = 15;
    let (mut successors, mut paired, mut pairs) = (0u32, 0u32, 0u32);
    for (j, &[_, leaves]) in ends.iter().enumerate().take(4 * BLOCKS) {
        let mut matches = 0u32;
        for (b, block) in arriving.iter().enumerate() {
            matches |= equal_lanes(block, leaves) << (4 * b);
        }
        // More than one candidate on either side is the ambiguous case the general path
        // resolves.
        if matches & matches.wrapping_sub(1) != 0 || matches & paired != 0 {
            return false;
        }
        paired |= matches;
        pairs += u32::from(matches != 0);
        successors |= matches.trailing_zeros().min(NO_SUCCESSOR) << (4 * j);
    }
    // As in `one_fan`: a single cycle through corner 0, or a single path from the corner that
    // follows none.
    let start = if pairs as usize == k {
        0
    } else if pairs as usize + 1 == k {
        (!paired).trailing_zeros()
    } else {
        return false;
    };
    let (mut at, mut visited) = (start, 1);
    loop {
        let next = (successors >> (4 * at)) & 15;
        if next == NO_SUCCESSOR || next == start || visited > k {
            break;
        }
        (at, visited) = (next, visited + 1);
    }
    visited == k
}

/// Bit `i` set where `block[i] == x`: one comparison of four lanes (SSE2, part of the x86-64
/// baseline).
#[inline(always)]
fn equal_lanes(block: &[u32; 4], x: u32) -> u32 {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{
            _mm_castsi128_ps, _mm_cmpeq_epi32, _mm_loadu_si128, _mm_movemask_ps, _mm_set1_epi32,
        };
        // SAFETY: SSE2 is part of the x86-64 baseline; the load reads the 16 bytes of `block`.
        unsafe {
            let lanes = _mm_loadu_si128(block.as_ptr().cast());
            let equal = _mm_cmpeq_epi32(lanes, _mm_set1_epi32(x as i32));
            _mm_movemask_ps(_mm_castsi128_ps(equal)) as u32
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    matches_in_block(block, x)
}

/// Whether the edges around a vertex pair unambiguously (no other vertex is reached twice the
/// same way) and connect all its corners, given each corner's [`Run::ends`]; at most `MAX`
/// corners. [`one_small_fan`] decides the same for vertices of up to eight.
#[inline(always)]
fn one_fan<const MAX: usize>(ends: &[[u32; 2]]) -> bool {
    let k = ends.len();
    // The other ends of the edges arriving at and leaving each corner. Unused places of
    // `arriving` hold `NONE`, which no class equals, so that the matching below can compare
    // whole blocks of four or eight (a few vector instructions) instead of looping over k.
    let mut arriving = [NONE; MAX];
    let mut leaving = [0u32; MAX];
    for (j, &[arrives, leaves]) in ends.iter().enumerate().take(MAX) {
        (arriving[j], leaving[j]) = (arrives, leaves);
    }
    let width = const { if MAX < 8 { MAX } else { 8 } };
    let blocks = k.div_ceil(width);
    // Pair each leaving edge with the arriving edge from the same vertex; more than one
    // candidate on either side is the ambiguous case the general path resolves.
    // `follows[j]`: the corners whose arriving edge pairs with the edge leaving corner j.
    // Each corner must have at most one follower and follow at most one corner; then the
    // pairs form paths and cycles, and the corners are connected exactly when they make a
    // single path or a single cycle, which one walk decides (where a flood fill over an
    // adjacency matrix took O(k²) steps).
    let mut paired = 0u32;
    let mut follows = [0u32; MAX];
    for (follow, &leaves) in follows[..k].iter_mut().zip(&leaving) {
        let mut matches = 0u32;
        for (b, block) in arriving.chunks_exact(width).take(blocks).enumerate() {
            matches |= matches_in_block(block, leaves) << (width * b);
        }
        if matches & (matches.wrapping_sub(1)) != 0 || matches & paired != 0 {
            return false;
        }
        paired |= matches;
        *follow = matches;
    }
    let pairs = paired.count_ones() as usize;
    let start = if pairs == k {
        // All in cycles: one cycle through corner 0, or more than one group.
        0
    } else if pairs + 1 == k {
        // One path, from the corner that follows none, or a path and cycles.
        (!paired).trailing_zeros() as usize
    } else {
        return false;
    };
    let mut at = start;
    let mut visited = 1;
    while follows[at] != 0 && visited <= k {
        at = follows[at].trailing_zeros() as usize;
        if at == start {
            break;
        }
        visited += 1;
    }
    visited == k
}

/// Bit `i` set where `block[i] == x`.
#[inline(always)]
fn matches_in_block(block: &[u32], x: u32) -> u32 {
    let mut bits = 0u32;
    for (i, &y) in block.iter().enumerate() {
        bits |= u32::from(y == x) << i;
    }
    bits
}

const NEXT: [usize; 3] = [1, 2, 0];
const PREV: [usize; 3] = [2, 0, 1];

#[derive(Default)]
struct EvalScratch {
    members: Vec<Member>,
    /// A group's records, in group order.
    records: Vec<Contribution>,
    /// The result of every corner around the vertex, before validation.
    raw: Vec<[f32; 4]>,
    order: Vec<u32>,
    group: Vec<u32>,
}

/// The reference's sum: angle-weighted projected frames of the members that are not "group with
/// anything", added in ascending triangle order, then normalized.
fn sum_tangents<'a>(members: impl Iterator<Item = &'a Member>) -> [f32; 3] {
    let mut sum = [0.0f32; 3];
    for m in members {
        if !m.any {
            sum = add(sum, scale(m.s, m.angle));
        }
    }
    normalize_or_zero(sum)
}

/// Labels the corners around a vertex with their group: corners of triangles connected through
/// paired edges and of one orientation. Only for vertices without "group with anything"
/// triangles, where groups do not depend on the order they are found in.
fn label_components(corners: &[u32], flags: &[u8], scratch: &mut Scratch) {
    scratch.labels.clear();
    scratch.labels.resize(corners.len(), NONE);
    for seed in 0..corners.len() {
        if scratch.labels[seed] != NONE {
            continue;
        }
        let orientation = flags[corners[seed] as usize / 3] & ORIENT_PRESERVING;
        scratch.labels[seed] = seed as u32;
        scratch.stack.clear();
        scratch.stack.push(seed as u32);
        while let Some(at) = scratch.stack.pop() {
            for next in scratch.links[at as usize] {
                if next == NONE || scratch.labels[next as usize] != NONE {
                    continue;
                }
                if flags[corners[next as usize] as usize / 3] & ORIENT_PRESERVING != orientation {
                    continue;
                }
                scratch.labels[next as usize] = seed as u32;
                scratch.stack.push(next);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::xorshift;

    /// `scaled_to_bytes` puts the largest component in [64, 128) and keeps the direction, or
    /// gives zero; and two vectors whose bytes pass `T_DIRECTIONS_CLOSE` make a cosine above
    /// 0.01, over pairs drawn near the bound from every range of magnitudes.
    #[test]
    fn byte_directions_that_pass_are_within_the_bound() {
        let mut random = xorshift(0x5851_f42d_4c95_7f2d);
        let mut unit = move || (random() >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0;
        let bytes = |t: [f32; 3]| {
            let b = scaled_to_bytes(t).map(|x| x as i8);
            [b[0], b[1], b[2], 0]
        };
        for t in [
            [0.0; 3],
            [1e-38, 0.0, 0.0],
            [f32::NAN, 1.0, 0.0],
            [f32::INFINITY, 0.0, 0.0],
        ] {
            assert_eq!(scaled_to_bytes(t), [0.0; 3], "{t:?}");
        }
        let (mut passed, mut near) = (0, 0);
        for round in 0..400_000 {
            let magnitude = 2f32.powi((round % 60) - 30);
            let a = [unit(), unit(), unit()].map(|x| x * magnitude);
            // `b` a random turn of `a` by up to about 100 degrees, at another magnitude.
            let turn = [unit(), unit(), unit()].map(|x| x * magnitude * 1.2);
            let b = [0, 1, 2].map(|i| (a[i] + turn[i]) * 2f32.powi(round % 7 - 3));
            let largest = scaled_to_bytes(a).iter().fold(0f32, |m, x| m.max(x.abs()));
            if a.iter().any(|&x| x != 0.0) {
                assert!((64.0..128.0).contains(&largest), "{a:?} -> {largest}");
            }
            let [a64, b64] = [a, b].map(|v| v.map(f64::from));
            let dot = a64.iter().zip(&b64).map(|(x, y)| x * y).sum::<f64>();
            let norm = |v: [f64; 3]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
            let cos = dot / (norm(a64) * norm(b64));
            if dot_i8(bytes(a), bytes(b)) > T_DIRECTIONS_CLOSE {
                assert!(cos > 0.01, "{a:?} {b:?}: cos {cos}");
                passed += 1;
                near += usize::from(cos < 0.3);
            }
        }
        assert!(
            passed > 100_000 && near > 100,
            "{passed} passed, {near} of them near"
        );
    }

    /// The vector test of one sub-group gives the scalar one's verdict and sum, bit for bit,
    /// for vertices of every size up to 12 corners, whose records are drawn from near-parallel
    /// frames (passing), a few opposite or crossed ones, zero, NaN, tiny and huge values.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn one_group_test_does_not_depend_on_the_vector_extension() {
        let mut next = xorshift(0x2545_f491_4f6c_dd1d);
        let mut record = |base: [f32; 3], base_t: [i8; 4]| {
            let r = next();
            let jitter = |shift: u32| ((r >> shift) & 0xff) as f32 / 2550.0;
            let mut s = [
                base[0] + jitter(0),
                base[1] - jitter(8),
                base[2] + jitter(16),
            ];
            let mut t = base_t;
            match r >> 58 {
                0 => s = [-s[0], -s[1], -s[2]],
                1 => s = [0.0; 3],
                2 => s[1] = f32::NAN,
                3 => s = s.map(|x| x * 1e-25),
                4 => s = s.map(|x| x * 1e25),
                5 => t = [-t[0], -t[1], -t[2], 0],
                6 => t = [t[1], -t[0], t[2], 0],
                7 => t[0] = t[0].saturating_add(((r >> 24) & 0x3f) as i8),
                _ => {}
            }
            Contribution {
                weighted_s: s,
                t_direction: t,
            }
        };
        let (mut passed, mut failed) = (0, 0);
        for round in 0..20_000 {
            let k = 1 + round % 12;
            let base = [0.6, -0.3, 0.7];
            let base_t = [90, 40, -80, 0];
            let records: Vec<Contribution> = (0..k).map(|_| record(base, base_t)).collect();
            let bits = |sum: Option<[f32; 3]>| sum.map(|s| s.map(f32::to_bits));
            let expected = sum_of_one_group_portable(&records);
            // The places after the corners hold anything, here records that would fail.
            let mut padded = records.clone();
            padded.extend((0..3).map(|_| record(base.map(|x| -x), base_t)));
            assert_eq!(bits(sum_of_one_group_sse2(&padded, k)), bits(expected));
            if expected.is_some() {
                passed += 1;
            } else {
                failed += 1;
            }
        }
        assert!(
            passed > 2_000 && failed > 2_000,
            "{passed} passed, {failed} failed"
        );
    }

    /// The small fans' vector matching and word of followers decide what the general version
    /// does, over random vertices whose edges' other ends come from a few classes (so that
    /// cycles, paths, splits and ambiguous pairs all occur), and over a closed fan and an open
    /// one of every size.
    #[test]
    fn small_fans_are_decided_as_in_general() {
        let mut random = xorshift(0x9e37_79b9_7f4a_7c15);
        let mut next = move |below: u64| (random() % below) as u32;
        let decide = |ends: &[[u32; 2]]| match ends.len() {
            1..=4 => one_small_fan::<1>(ends),
            _ => one_small_fan::<2>(ends),
        };
        let mut connected = 0;
        for _ in 0..200_000 {
            let k = 1 + next(8) as usize;
            let classes = 1 + u64::from(next(9));
            let ends: Vec<[u32; 2]> = (0..k).map(|_| [next(classes), next(classes)]).collect();
            let expected = one_fan::<32>(&ends);
            assert_eq!(decide(&ends), expected, "{ends:?}");
            connected += usize::from(expected);
        }
        assert!(
            connected > 1_000,
            "too few connected fans drawn: {connected}"
        );
        for k in 1..=8u32 {
            // Corner j runs from class j to class j + 1: a path, closed into a cycle by the
            // last corner returning to class 0, and broken by a corner that goes elsewhere.
            let open: Vec<[u32; 2]> = (0..k).map(|j| [j, j + 1]).collect();
            let mut closed = open.clone();
            closed[k as usize - 1][1] = 0;
            let mut broken = open.clone();
            broken[0][0] = 100;
            broken[k as usize - 1][1] = 200;
            if k > 2 {
                broken[k as usize / 2] = [300, 400];
            }
            for (ends, expected) in [(&open, true), (&closed, true), (&broken, k <= 2)] {
                assert_eq!(decide(ends), expected, "{ends:?}");
                assert_eq!(one_fan::<32>(ends), expected, "{ends:?}");
            }
        }
    }

    /// The AVX2 transpose writes what the portable copy writes, bit for bit, for every batch
    /// length, with NaN and the extreme directions among the values.
    #[test]
    fn stored_contributions_do_not_depend_on_the_vector_extension() {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            let mut random = xorshift(0x2545_f491_4f6c_dd1d);
            let mut next = move || {
                let state = random();
                let specials = [f32::NAN, 127.0, -127.0, 127.00001, -0.0, 0.0];
                match state % 16 {
                    0..6 => specials[(state % 16) as usize],
                    _ => (state >> 40) as f32 / (1u64 << 24) as f32 * 254.0 - 127.0,
                }
            };
            let mut weighted = [[[0.0f32; BATCH]; 3]; 3];
            let mut directions = [[[0.0f32; BATCH]; 3]; 3];
            for x in weighted
                .iter_mut()
                .chain(&mut directions)
                .flatten()
                .flatten()
            {
                *x = next();
            }
            let bits = |records: &[[Contribution; 3]]| -> Vec<([u32; 3], [i8; 4])> {
                let bits = |c: &Contribution| (c.weighted_s.map(f32::to_bits), c.t_direction);
                records.iter().flatten().map(bits).collect()
            };
            for len in [1, 2, 3, 4, 5, 15, 16, 17, 31, 32, 33, 48, 63, 64] {
                let mut portable = vec![[Contribution::ZERO; 3]; len];
                let mut avx2 = vec![[Contribution::ZERO; 3]; len];
                store_contributions_portable(&weighted, &directions, as_slots(&mut portable));
                // SAFETY: the CPU was just found to support AVX2.
                unsafe { store_contributions_avx2(&weighted, &directions, as_slots(&mut avx2)) };
                assert_eq!(bits(&portable), bits(&avx2), "batch of {len}");
            }
        }
    }

    /// A mesh with every kind of vertex the per-vertex pass tells apart: a bumpy grid of
    /// `n` × `n` quads with a UV seam down the middle (its vertices doubled), a mirrored half,
    /// welded duplicates, triangles of zero UV area ("group with anything"), degenerate
    /// triangles and one vertex at NaN; its triangles in the order `order` gives.
    struct TestMesh {
        positions: Vec<[f32; 3]>,
        normals: Vec<[f32; 3]>,
        uvs: Vec<[f32; 2]>,
        indices: Vec<u32>,
    }

    impl TestMesh {
        fn new(n: u32, order: impl FnOnce(&mut Vec<[u32; 3]>)) -> TestMesh {
            let (mut positions, mut normals, mut uvs) = (Vec::new(), Vec::new(), Vec::new());
            let side = n + 1;
            for y in 0..side {
                for x in 0..side {
                    let (u, v) = (x as f32 / n as f32, y as f32 / n as f32);
                    let z = 0.2 * (5.0 * u).sin() * (3.0 * v).cos();
                    positions.push([u, v, z]);
                    let normal = [-z * 0.5, z * 0.3, 1.0];
                    let length = dot(normal, normal).sqrt();
                    normals.push(normal.map(|c| c / length));
                    // The left half mirrored in u.
                    uvs.push([if x < side / 2 { 1.0 - u } else { u }, v]);
                }
            }
            let vertex = |x: u32, y: u32| y * side + x;
            // The seam: the middle column's vertices again, with the other half's UVs.
            let seam_first = positions.len() as u32;
            for y in 0..side {
                let v = vertex(side / 2, y) as usize;
                positions.push(positions[v]);
                normals.push(normals[v]);
                uvs.push([1.0 - uvs[v][0], uvs[v][1]]);
            }
            // Welded duplicates: every seventh vertex again, exactly, used by some corners.
            let duplicate_first = positions.len() as u32;
            let duplicated: Vec<u32> = (0..side * side).step_by(7).collect();
            for &v in &duplicated {
                positions.push(positions[v as usize]);
                normals.push(normals[v as usize]);
                uvs.push(uvs[v as usize]);
            }
            let mut triangles = Vec::new();
            for y in 0..n {
                for x in 0..n {
                    let corner = |x: u32, y: u32, t: usize| {
                        let v = vertex(x, y);
                        if x == side / 2 && y < side && t % 2 == 0 {
                            // Triangles left of the middle take its seam copies.
                            seam_first + y
                        } else if v % 7 == 0 && t % 3 == 0 {
                            duplicate_first + v / 7
                        } else {
                            v
                        }
                    };
                    let left = x < side / 2;
                    let t = (y * n + x) as usize;
                    let (a, b) = (2 * t + if left { 0 } else { 1 }, 2 * t + 1);
                    triangles.push([
                        corner(x, y, a),
                        corner(x + 1, y, a),
                        corner(x + 1, y + 1, a),
                    ]);
                    triangles.push([
                        corner(x, y, b),
                        corner(x + 1, y + 1, b),
                        corner(x, y + 1, b),
                    ]);
                }
            }
            // Zero UV area: three vertices of one row given the same UV.
            for x in 2..5 {
                uvs[vertex(x, n / 3) as usize] = [0.7, 0.4];
            }
            // Degenerate: two corners at one position, here and there.
            for t in (5..triangles.len()).step_by(41) {
                triangles[t][1] = triangles[t][0];
            }
            positions[vertex(n - 2, n - 3) as usize][2] = f32::NAN;
            order(&mut triangles);
            TestMesh {
                positions,
                normals,
                uvs,
                indices: triangles.into_iter().flatten().collect(),
            }
        }

        fn mesh(&self) -> Mesh<'_> {
            Mesh {
                positions: &self.positions,
                normals: &self.normals,
                uvs: Some(&self.uvs),
                indices: &self.indices,
            }
        }
    }

    /// The plan and diagnostics of `mesh` with its records laid out as `layout`.
    fn laid_out(mesh: &Mesh<'_>, parallel: bool, layout: Layout) -> (SplitPlan, Diagnostics) {
        let options = crate::Options {
            parallel,
            ..crate::Options::default()
        };
        let (mut diagnostics, non_finite_vertex) =
            crate::diagnostics::analyze_vertices(mesh, &options);
        let check = TriangleCheck {
            uv_origin: options.uv_origin,
            has_uvs: mesh.uvs.is_some(),
            non_finite_vertex: &non_finite_vertex,
            cancel: &crate::Cancel::default(),
        };
        let plan = generate_laid_out(mesh, parallel, true, &check, &mut diagnostics, layout);
        (plan, diagnostics)
    }

    /// Records per piece of vertices give the plan and diagnostics of the whole array, bit for
    /// bit: in pieces small enough that every vertex kind lies on a piece's edge, on one thread
    /// and many, in the triangles' own order, reversed, and shuffled (whose pieces overlap so
    /// much that the whole array is computed after all).
    #[test]
    fn records_per_piece_give_the_whole_arrays_plan() {
        let mut random = xorshift(0x9e37_79b9_7f4a_7c15);
        type Reorder = Box<dyn FnOnce(&mut Vec<[u32; 3]>)>;
        let orders: [(&str, Reorder); 3] = [
            ("own order", Box::new(|_| {})),
            ("reversed", Box::new(|t| t.reverse())),
            (
                "shuffled",
                Box::new(move |t| {
                    for i in (1..t.len()).rev() {
                        t.swap(i, random() as usize % (i + 1));
                    }
                }),
            ),
        ];
        for (name, order) in orders {
            let test_mesh = TestMesh::new(40, order);
            let mesh = test_mesh.mesh();
            let bits = |(plan, diagnostics): (SplitPlan, Diagnostics)| {
                let tangents: Vec<[u32; 4]> = plan
                    .vertex_tangents
                    .iter()
                    .map(|t| t.map(f32::to_bits))
                    .collect();
                (tangents, plan.source_vertex, plan.indices, diagnostics)
            };
            let whole = bits(laid_out(&mesh, false, Layout::Whole));
            // The mesh has what it is meant to have.
            let diagnostics = &whole.3;
            assert!(diagnostics.fallback_tangents.corners.count > 0, "{name}");
            assert!(diagnostics.duplicate_position_triangles.count > 0, "{name}");
            assert!(diagnostics.zero_uv_area_triangles.count > 0, "{name}");
            assert!(diagnostics.mirrored_uv_triangles.count > 0, "{name}");
            assert!(diagnostics.non_finite_triangles.count > 0, "{name}");
            assert!(diagnostics.vertices_added > 0, "{name}");
            for parallel in [false, true] {
                assert_eq!(
                    bits(laid_out(&mesh, parallel, Layout::Whole)),
                    whole,
                    "{name}"
                );
                for triangles in [1, 7, 64, 1000] {
                    let pieces = bits(laid_out(&mesh, parallel, Layout::Pieces { triangles }));
                    assert_eq!(pieces, whole, "{name}, {triangles} triangles a piece");
                }
            }
        }
    }

    /// A record computed again corner by corner is the triangle pass's, bit for bit, on a mesh
    /// whose corners include NaN, zero UV area, degenerate triangles and every batch position.
    #[test]
    fn records_computed_again_are_the_triangle_passs() {
        let test_mesh = TestMesh::new(13, |_| {});
        let mesh = test_mesh.mesh();
        let mut records = vec![[Contribution::ZERO; 3]; mesh.triangle_count()];
        record_all(&mesh, as_slots(&mut records), false);
        let bits = |c: &Contribution| (c.weighted_s.map(f32::to_bits), c.t_direction);
        for (corner, record) in records.as_flattened().iter().enumerate() {
            let again = Records::NONE.get(&mesh, corner);
            assert_eq!(bits(&again), bits(record), "corner {corner}");
        }
    }
}
