//! Reading a large OBJ in chunks, in parallel, to the same [`Obj`] the sequential reader makes.
//!
//! Design decision: the chunked reader handles the files exporters write and gives up on
//! anything else, which [`super::parse_sequentially`] then reads from the start. Giving up
//! costs one chunk's work at most twice; in exchange the chunked path never has to reproduce
//! an error (with its line) or a rare rule, only the common statements. It gives up on any
//! error, on a negative (relative) index, and on an `s` with the one value it reserves.
//!
//! Reading one line depends on the lines before it in four ways, each resolved after every
//! chunk has been read, in file order:
//! - **Indices** are 1-based into the elements defined so far, most of which lie in earlier
//!   chunks. A chunk keeps them as read and records, per kind, how far past its own elements
//!   they reach; the file is valid when no chunk reaches past what the chunks before it define.
//! - **The group key** (`o`, `g`, `usemtl`): a chunk's faces join *segments*, each with the key
//!   fields set within the chunk; the others come from the chunk before. Segments are then
//!   replayed into [`FaceGroup`]s by the sequential reader's own rule.
//! - **Smoothing groups**: triangles read before a chunk's first `s` hold [`INHERITED`] until
//!   the value in force at the chunk's start is known.
//! - **Polygons** are triangulated in their plane, from positions that may lie in an earlier
//!   chunk: their corners are kept, and their triangles made once all positions are known, in
//!   parallel again, and put where the face was.

use super::{
    Corner, FaceGroup, GroupKey, Limits, Lines, Obj, ObjError, ObjErrorKind, Reader, Triangulation,
    corner_index, error, parse_i64, triangulate,
};
use rayon::prelude::*;

/// The smoothing group of triangles read before the chunk's first `s`.
pub(super) const INHERITED: u32 = u32::MAX;

/// Bits naming the fields of [`GroupKey`].
pub(super) const OBJECT: u8 = 1;
pub(super) const GROUPS: u8 = 2;
pub(super) const MATERIAL: u8 = 4;

/// Files smaller than this are read on one thread: splitting them saves less than it costs.
const MIN_PARALLEL_BYTES: usize = 1 << 21;

/// Chunks per thread: a few, so that a thread whose chunk reads slowly (long polygons, many
/// names) does not hold the others up.
const CHUNKS_PER_THREAD: usize = 4;

/// The error a chunk gives up with; its caller reads the file sequentially, which finds the
/// real error, if there is one, with its line.
pub(super) fn unreadable(line: usize) -> ObjError {
    error(
        line,
        ObjErrorKind::LimitExceeded {
            what: "statements a chunk can read",
            limit: 0,
        },
    )
}

/// A chunk's first run of faces is given room for a triangle per this many bytes of the
/// chunk's text: about what an exporter writes per triangle (a face line of three or four
/// `v/vt/vn` corners, and its share of the vertex lines). Grown from nothing, the runs were
/// copied and faulted in again at every doubling: on the 1M-triangle sphere of `whole_path`, a
/// third of the process's page faults (see docs/benchmarks.md). Where the text has more
/// triangles than that the run grows as before; where fewer, the room never touched costs no
/// memory.
const BYTES_PER_TRIANGLE: usize = 64;

/// What a chunk's reader keeps besides [`Reader`]'s own state.
#[derive(Default)]
pub(super) struct ChunkState {
    /// Triangles the next run is made with room for (see [`BYTES_PER_TRIANGLE`]); the first
    /// run takes it all.
    room_for_triangles: usize,
    segments: Vec<Segment>,
    /// The key fields set within the chunk so far.
    set_fields: u8,
    /// Whether the key changed since the last segment began (or the chunk did).
    changed: bool,
    /// Per kind (position, texture coordinate, normal): the largest `index - defined` over the
    /// chunk's corners, where `defined` counts the chunk's own elements read before the face.
    /// The file is valid when, for every chunk, this is at most what earlier chunks define.
    reach: [i64; 3],
    polygons: Vec<Polygon>,
    polygon_corners: Vec<Corner>,
}

/// A run of a chunk's faces under one key.
struct Segment {
    /// Triangles and smoothing groups; the key fields set within the chunk.
    group: FaceGroup,
    set_fields: u8,
    /// Whether the key changed between the previous segment (or the chunk's start) and this one.
    changed_before: bool,
}

/// A face of more than three corners, triangulated once every position is known.
struct Polygon {
    segment: usize,
    /// The number of the segment's triangles before it.
    at: usize,
    corners: std::ops::Range<usize>,
    smoothing: u32,
}

impl ChunkState {
    /// The state of a chunk of `length` bytes.
    pub(super) fn for_length(length: usize) -> ChunkState {
        ChunkState {
            room_for_triangles: length / BYTES_PER_TRIANGLE,
            ..ChunkState::default()
        }
    }

    pub(super) fn key_changed(&mut self, field: u8) {
        self.set_fields |= field;
        self.changed = true;
    }

    /// The segment a face joins: the last one, unless the key changed since it began.
    pub(super) fn current_group(
        &mut self,
        key: &GroupKey,
        group_current: &mut bool,
    ) -> &mut FaceGroup {
        if !*group_current || self.segments.is_empty() {
            let room = std::mem::take(&mut self.room_for_triangles);
            self.segments.push(Segment {
                group: FaceGroup {
                    object: key.object.clone(),
                    groups: key.groups.clone(),
                    material: key.material.clone(),
                    triangles: Vec::with_capacity(room),
                    smoothing: Vec::with_capacity(room),
                },
                set_fields: self.set_fields,
                changed_before: self.changed,
            });
            self.changed = false;
            *group_current = true;
        }
        let last = self.segments.len() - 1;
        &mut self.segments[last].group
    }

    /// A face's corner from its three index tokens: positive indices only, kept as they are,
    /// with how far they reach recorded (see [`ChunkState::reach`]).
    pub(super) fn corner(
        &mut self,
        (position, uv, normal): (&[u8], Option<&[u8]>, Option<&[u8]>),
        obj: &Obj,
        line: usize,
    ) -> Result<Corner, ObjError> {
        let defined = [obj.positions.len(), obj.uvs.len(), obj.normals.len()];
        let mut index = |kind: usize, token: &[u8]| -> Result<u32, ObjError> {
            let i = parse_i64(token)
                .filter(|&i| i > 0)
                .ok_or_else(|| unreadable(line))?;
            let zero_based = corner_index(i - 1).ok_or_else(|| unreadable(line))?;
            self.reach_one(kind, i, defined[kind]);
            Ok(zero_based)
        };
        Ok(Corner::new(
            index(0, position)?,
            uv.map(|t| index(1, t)).transpose()?,
            normal.map(|t| index(2, t)).transpose()?,
        ))
    }

    /// Records how far a plain triangle's corner reaches (see [`ChunkState::reach`]): its
    /// 1-based indices, where present, against the elements `defined` in the chunk so far.
    pub(super) fn reach_to(&mut self, indices: [Option<u32>; 3], defined: [usize; 3]) {
        for (kind, (index, defined)) in indices.into_iter().zip(defined).enumerate() {
            if let Some(i) = index {
                self.reach_one(kind, i64::from(i), defined);
            }
        }
    }

    /// Records that a 1-based `index` of one `kind` reaches past the `defined` elements.
    fn reach_one(&mut self, kind: usize, index: i64, defined: usize) {
        self.reach[kind] = self.reach[kind].max(index - defined as i64);
    }

    #[cfg(test)]
    pub(super) fn reach_for_testing(&self) -> [i64; 3] {
        self.reach
    }

    /// Keeps a polygon for later, at its place in the last segment.
    pub(super) fn defer_polygon(&mut self, corners: &[Corner], smoothing: u32) {
        let segment = self.segments.len().saturating_sub(1);
        let at = self.segments.last().map_or(0, |s| s.group.triangles.len());
        let start = self.polygon_corners.len();
        self.polygon_corners.extend_from_slice(corners);
        self.polygons.push(Polygon {
            segment,
            at,
            corners: start..self.polygon_corners.len(),
            smoothing,
        });
    }
}

/// One chunk, read.
struct Chunk {
    obj: Obj,
    state: ChunkState,
    /// The key and smoothing group in force at its end, for the fields it set.
    key: GroupKey,
    smoothing: u32,
    triangles: usize,
}

/// Reads `bytes` in chunks on the current thread pool, or returns `None` for a file to read
/// sequentially: a small one, or one a chunk gives up on (see the module documentation).
pub(super) fn parse_in_chunks(bytes: &[u8], limits: &Limits) -> Option<Obj> {
    let threads = rayon::current_num_threads();
    if bytes.len() < MIN_PARALLEL_BYTES || threads < 2 {
        return None;
    }
    read_pieces(&split_at_lines(bytes, threads * CHUNKS_PER_THREAD), limits)
}

/// The file made of `pieces`, each read as a chunk.
pub(super) fn read_pieces(pieces: &[&[u8]], limits: &Limits) -> Option<Obj> {
    let chunks: Vec<Chunk> = pieces
        .par_iter()
        .enumerate()
        .map(|(i, piece)| read_chunk(piece, i == 0, limits))
        .collect::<Option<_>>()?;
    assemble(chunks, limits)
}

/// `bytes` cut into about `count` pieces, each ending at a line end that no `\` continues.
pub(super) fn split_at_lines(bytes: &[u8], count: usize) -> Vec<&[u8]> {
    let target = bytes.len().div_ceil(count.max(1)).max(1);
    let mut pieces = Vec::with_capacity(count);
    let mut rest = bytes;
    while !rest.is_empty() {
        // Forward from the target to the end of a line that is not continued on the next.
        let mut from = target.min(rest.len()) - 1;
        let end = loop {
            let Some(at) = memchr::memchr(b'\n', &rest[from..]) else {
                break rest.len();
            };
            let newline = from + at;
            let line_start = memchr::memrchr(b'\n', &rest[..newline]).map_or(0, |i| i + 1);
            if super::continued(&rest[line_start..newline]).is_none() {
                break newline + 1;
            }
            from = newline + 1;
            if from >= rest.len() {
                break rest.len();
            }
        };
        let (piece, tail) = rest.split_at(end);
        pieces.push(piece);
        rest = tail;
    }
    pieces
}

fn read_chunk(bytes: &[u8], first: bool, limits: &Limits) -> Option<Chunk> {
    let mut reader = Reader::new(limits, Some(Box::new(ChunkState::for_length(bytes.len()))));
    let lines = if first {
        Lines::new(bytes)
    } else {
        Lines::continuing(bytes)
    };
    reader.read(lines).ok()?;
    let state = *reader.chunk?;
    Some(Chunk {
        obj: reader.obj,
        state,
        key: reader.key,
        smoothing: reader.smoothing,
        triangles: reader.triangles,
    })
}

/// The key fields `set` from `own`, the others from `before`.
fn resolve_key(own: &GroupKey, set: u8, before: &GroupKey) -> GroupKey {
    let pick = |bit: u8| set & bit != 0;
    GroupKey {
        object: if pick(OBJECT) {
            &own.object
        } else {
            &before.object
        }
        .clone(),
        groups: if pick(GROUPS) {
            &own.groups
        } else {
            &before.groups
        }
        .clone(),
        material: if pick(MATERIAL) {
            &own.material
        } else {
            &before.material
        }
        .clone(),
    }
}

/// The chunks joined into the file's [`Obj`], or `None` where the file is invalid (an index
/// reaching past what is defined, a limit exceeded), for the sequential reader to report.
fn assemble(mut chunks: Vec<Chunk>, limits: &Limits) -> Option<Obj> {
    // What each chunk's indices may refer to, and the smoothing group at its start.
    let mut defined = [0usize; 3];
    let mut triangles = 0usize;
    let mut smoothing = 0u32;
    let mut inherited_smoothing = Vec::with_capacity(chunks.len());
    for chunk in &chunks {
        for (kind, &reach) in chunk.state.reach.iter().enumerate() {
            if reach > defined[kind] as i64 {
                return None;
            }
        }
        let obj = &chunk.obj;
        for (total, own) in
            defined
                .iter_mut()
                .zip([obj.positions.len(), obj.uvs.len(), obj.normals.len()])
        {
            *total += own;
        }
        triangles += chunk.triangles;
        inherited_smoothing.push(smoothing);
        if chunk.smoothing != INHERITED {
            smoothing = chunk.smoothing;
        }
    }
    if defined.iter().any(|&n| n > limits.max_vertices) || triangles > limits.max_triangles {
        return None;
    }

    let mut obj = Obj::default();
    join_vertices(&mut obj, &mut chunks, defined);

    // Polygons and inherited smoothing groups, chunk by chunk in parallel.
    let positions = &obj.positions;
    let fanned: usize = chunks
        .par_iter_mut()
        .zip(&inherited_smoothing)
        .map(|(chunk, &smoothing)| finish_segments(&mut chunk.state, positions, smoothing))
        .sum();
    obj.warnings.polygons_fanned += fanned;

    // Segments into groups, by the sequential reader's rule (see `Reader::current_group`).
    let mut key = GroupKey::default();
    let mut group_current = false;
    for chunk in chunks {
        let Chunk {
            obj: part,
            state,
            key: end_key,
            ..
        } = chunk;
        for segment in state.segments {
            let Segment {
                group,
                set_fields,
                changed_before,
            } = segment;
            if changed_before {
                group_current = false;
            }
            let own = GroupKey {
                object: group.object,
                groups: group.groups,
                material: group.material,
            };
            key = resolve_key(&own, set_fields, &key);
            let reusable = obj.groups.last().is_some_and(|g| {
                g.object == key.object && g.groups == key.groups && g.material == key.material
            });
            // A segment that continues the last group's run becomes a group of its own with
            // the same key rather than being copied onto it: the run is split where the chunks
            // were cut, as `FaceGroup` allows, and a million triangles are not copied again.
            let run_key = match obj.groups.last() {
                Some(last) if group_current || reusable => GroupKey {
                    object: last.object.clone(),
                    groups: last.groups.clone(),
                    material: last.material.clone(),
                },
                _ => key.clone(),
            };
            obj.groups.push(FaceGroup {
                object: run_key.object,
                groups: run_key.groups,
                material: run_key.material,
                triangles: group.triangles,
                smoothing: group.smoothing,
            });
            group_current = true;
        }
        if state.changed {
            group_current = false;
        }
        key = resolve_key(&end_key, state.set_fields, &key);
        merge_counts(&mut obj, part);
    }
    obj.groups.retain(|g| !g.triangles.is_empty());
    Some(obj)
}

/// The runs [`assemble`] split where the chunks were cut, joined again: the groups the
/// sequential reader makes, for comparing the two readers.
pub(super) fn join_split_runs(obj: &mut Obj) {
    let mut joined: Vec<FaceGroup> = Vec::with_capacity(obj.groups.len());
    for group in std::mem::take(&mut obj.groups) {
        match joined.last_mut() {
            Some(last)
                if last.object == group.object
                    && last.groups == group.groups
                    && last.material == group.material =>
            {
                last.triangles.extend(group.triangles);
                last.smoothing.extend(group.smoothing);
            }
            _ => joined.push(group),
        }
    }
    obj.groups = joined;
}

/// Positions, colours, texture coordinates and normals, chunk after chunk.
fn join_vertices(obj: &mut Obj, chunks: &mut [Chunk], [positions, uvs, normals]: [usize; 3]) {
    let coloured = chunks.iter().any(|c| c.obj.colors.is_some());
    if coloured {
        obj.colors = Some(Vec::with_capacity(positions));
    }
    for chunk in chunks.iter_mut() {
        let part = &mut chunk.obj;
        if let Some(colors) = obj.colors.as_mut() {
            match part.colors.take() {
                Some(own) => colors.extend_from_slice(&own),
                None => {
                    // White, and counted, as the sequential reader does once any position
                    // anywhere has a colour.
                    colors.extend(std::iter::repeat_n([1.0; 3], part.positions.len()));
                    part.warnings.vertices_without_color += part.positions.len();
                }
            }
        }
    }
    obj.positions = joined(chunks.iter_mut().map(|c| &mut c.obj.positions), positions);
    obj.uvs = joined(chunks.iter_mut().map(|c| &mut c.obj.uvs), uvs);
    obj.normals = joined(chunks.iter_mut().map(|c| &mut c.obj.normals), normals);
}

/// The `parts` one after the other, `total` elements in all. The first part that has any is
/// grown to hold them, rather than copied into a new vector with the rest: exporters write each
/// kind of vertex line in one block, which one or two chunks hold, so this spares copying (and
/// faulting in again) about half of them.
fn joined<'a, T: 'a>(parts: impl Iterator<Item = &'a mut Vec<T>>, total: usize) -> Vec<T> {
    let mut all = Vec::new();
    for part in parts.filter(|part| !part.is_empty()) {
        if all.is_empty() {
            all = std::mem::take(part);
            all.reserve_exact(total.saturating_sub(all.len()));
        } else {
            all.append(part);
        }
    }
    all
}

/// Gives the triangles read before the chunk's first `s` the group in force at its start, and
/// puts the polygons' triangles in their places. Returns the number of polygons fanned.
fn finish_segments(state: &mut ChunkState, positions: &[[f32; 3]], smoothing: u32) -> usize {
    let inherit = |s: u32| if s == INHERITED { smoothing } else { s };
    for segment in &mut state.segments {
        for s in &mut segment.group.smoothing {
            *s = inherit(*s);
        }
    }
    let mut fanned = 0;
    let mut polygons = state.polygons.iter().peekable();
    let mut polygon_points = Vec::new();
    let mut local = Vec::new();
    for (index, segment) in state.segments.iter_mut().enumerate() {
        if polygons.peek().is_none_or(|p| p.segment != index) {
            continue;
        }
        let group = &mut segment.group;
        let old_triangles = std::mem::take(&mut group.triangles);
        let old_smoothing = std::mem::take(&mut group.smoothing);
        let mut copied = 0;
        while let Some(polygon) = polygons.next_if(|p| p.segment == index) {
            group
                .triangles
                .extend_from_slice(&old_triangles[copied..polygon.at]);
            group
                .smoothing
                .extend_from_slice(&old_smoothing[copied..polygon.at]);
            copied = polygon.at;
            let corners = &state.polygon_corners[polygon.corners.clone()];
            polygon_points.clear();
            polygon_points.extend(corners.iter().map(|c| {
                positions
                    .get(c.position as usize)
                    .copied()
                    .unwrap_or_default()
            }));
            local.clear();
            if triangulate(&polygon_points, &mut local) == Triangulation::Fan {
                fanned += 1;
            }
            group
                .triangles
                .extend(local.iter().map(|t| t.map(|i| corners[i])));
            group
                .smoothing
                .extend(std::iter::repeat_n(inherit(polygon.smoothing), local.len()));
        }
        group.triangles.extend_from_slice(&old_triangles[copied..]);
        group.smoothing.extend_from_slice(&old_smoothing[copied..]);
    }
    fanned
}

/// A chunk's counts, names and warnings added to the file's.
fn merge_counts(obj: &mut Obj, part: Obj) {
    obj.material_libraries.extend(part.material_libraries);
    obj.smoothing_declared |= part.smoothing_declared;
    obj.statements += part.statements;
    let (w, p) = (&mut obj.warnings, part.warnings);
    w.unsupported_statements += p.unsupported_statements;
    for keyword in p.unsupported_keywords {
        if w.unsupported_keywords.len() < super::MAX_NAMED_KEYWORDS
            && !w.unsupported_keywords.contains(&keyword)
        {
            w.unsupported_keywords.push(keyword);
        }
    }
    w.faces_with_partial_uvs += p.faces_with_partial_uvs;
    w.faces_with_partial_normals += p.faces_with_partial_normals;
    w.faces_too_few_corners += p.faces_too_few_corners;
    w.polygons_fanned += p.polygons_fanned;
    w.lines_skipped += p.lines_skipped;
    w.points_skipped += p.points_skipped;
    w.vertices_without_color += p.vertices_without_color;
    w.vertices_with_odd_value_count += p.vertices_with_odd_value_count;
}

#[cfg(test)]
mod tests {
    use super::super::parse_sequentially;
    use super::*;
    use proptest::prelude::*;

    /// Whether reading `text` in `count` chunks gives what the sequential reader gives, or
    /// gives up; returns whether it gave up.
    fn chunked_matches_sequential(text: &[u8], count: usize, limits: &Limits) -> bool {
        let pieces = split_at_lines(text, count);
        assert_eq!(pieces.concat(), text, "the pieces are the text");
        for piece in &pieces[..pieces.len().saturating_sub(1)] {
            assert!(piece.ends_with(b"\n"));
        }
        let Some(mut chunked) = read_pieces(&pieces, limits) else {
            return true;
        };
        join_split_runs(&mut chunked);
        let sequential = parse_sequentially(text, limits);
        assert_eq!(
            Ok(&chunked),
            sequential.as_ref(),
            "{}",
            String::from_utf8_lossy(text)
        );
        false
    }

    /// Statements the chunked reader reads itself, once [`HEADER`] has defined what their
    /// faces refer to.
    const COMMON: &[&str] = &[
        "v 0 0 0\n",
        "v 1 0 0\n",
        "v 0 1 0\n",
        "v 1 1 0.5\n",
        "v 0 1 0 0.5 0.5 0.5\n",
        "v 2 2 2 1\n",
        "vt 0.5 1\n",
        "vt 0 0\n",
        "vn 0 0 1\n",
        "vn 0 1 0\n",
        "f 1 2 3\n",
        "f 1 2 3 4\n",
        "f 4 3 2 1 2\n",
        "f 1/1 2/2 3/1\n",
        "f 1//1 2//2 3//1\n",
        "f 1/1/1 2/1/2 3/2/1 4/2/2\n",
        "f 1/1 2 3\n",
        "f 1 2\n",
        "o a\n",
        "o b\n",
        "o\n",
        "g x y\n",
        "g\n",
        "usemtl m\n",
        "usemtl n\n",
        "usemtl\n",
        "s 1\n",
        "s 2\n",
        "s off\n",
        "mtllib a.mtl\n",
        "l 1 2\n",
        "p 1\n",
        "curv 0 1\n",
        "cstype bezier\n",
        "# comment\n",
        "\n",
        "v 1 2 \\\n 3\n",
        "f 1 2 \\\r\n3\r\n",
        "vn 1 0 0 # end\r\n",
    ];

    const HEADER: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 1\nvt 0 0\nvt 1 1\nvn 0 0 1\nvn 1 0 0\n";

    /// Statements on which a chunk gives up, or that make the file invalid.
    const RARE: &[&str] = &[
        "v 1 2\n",
        "f 1 2 9\n",
        "f -1 -2 -3\n",
        "f 0 1 2\n",
        "s 4294967295\n",
    ];

    proptest! {
        #[test]
        fn chunks_read_what_the_sequential_reader_reads(
            parts in proptest::collection::vec(prop::sample::select(COMMON), 0..80),
            count in 1..12usize,
        ) {
            let text = HEADER.to_owned() + &parts.concat();
            let gave_up = chunked_matches_sequential(text.as_bytes(), count, &Limits::default());
            prop_assert!(!gave_up);
            let tight = Limits { max_vertices: 6, max_triangles: 5, max_polygon_corners: 4 };
            chunked_matches_sequential(text.as_bytes(), count, &tight);
        }

        #[test]
        fn chunks_give_up_or_agree_on_any_statements(
            parts in proptest::collection::vec(
                prop::sample::select([COMMON, RARE].concat()),
                0..80,
            ),
            count in 1..12usize,
        ) {
            chunked_matches_sequential(parts.concat().as_bytes(), count, &Limits::default());
        }
    }

    /// The common statements never make the chunked reader give up.
    #[test]
    fn chunks_of_an_exported_mesh_are_read_in_parallel() {
        let mut text = String::from("\u{feff}mtllib scene.mtl\no first\nusemtl a\n");
        for i in 0..200 {
            text += &format!("v {i} {} 0.5\nvt 0.{i} 0.5\nvn 0 0 1\n", i % 7);
            if i >= 3 {
                let (a, b, c) = (i - 2, i - 1, i);
                match i % 9 {
                    0 => text += "usemtl b\ns 1\n",
                    4 => text += "g part\ns off\n",
                    7 => text += "o second\nusemtl a\n",
                    _ => {}
                }
                text += &format!("f {a}/{a}/{a} {b}/{b}/{b} {c}/{c}/{c}\n");
                text += &format!("f {c}//{c} {b}//{b} {a}//{a} 1//1\n");
            }
        }
        for count in 1..40 {
            assert!(!chunked_matches_sequential(
                text.as_bytes(),
                count,
                &Limits::default()
            ));
        }
    }

    #[test]
    fn a_continued_line_is_never_cut() {
        let text = b"v 1 2 \\\n3\nv 4 \\\r\n5 6\nf 1 2 \\\n 1\n";
        for count in 1..text.len() {
            for piece in split_at_lines(text, count) {
                assert!(super::super::continued(piece.trim_ascii_end()).is_none());
            }
        }
    }
}
