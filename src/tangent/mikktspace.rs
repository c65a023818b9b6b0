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
//! they are processed in parallel.
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

use super::math::{
    Mesh, UNASSIGNED, add, dot, encode, is_finite3, normalize_or_zero, not_zero, reject,
    same_position, scale, sub,
};
use super::weld::{CornerTable, NONE, weld_mesh};
use rayon::prelude::*;

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

pub(crate) fn generate(mesh: &Mesh<'_>, parallel: bool) -> Vec<[f32; 4]> {
    let triangle_count = mesh.triangle_count();
    let weld = weld_mesh(mesh);

    let mut frames = vec![Frame::default(); triangle_count];
    let mut flags = vec![0u8; triangle_count];
    let classify = |(t, (frame, flag)): (usize, (&mut Frame, &mut u8))| {
        (*frame, *flag) = triangle_frame(mesh, t);
    };
    if parallel {
        frames
            .par_iter_mut()
            .zip(flags.par_iter_mut())
            .enumerate()
            .with_min_len(4096)
            .for_each(classify);
    } else {
        frames
            .iter_mut()
            .zip(flags.iter_mut())
            .enumerate()
            .for_each(classify);
    }

    // The class of every corner; degenerate triangles stay out of the per-vertex lists.
    let class_of = |&v: &u32| weld.class_of_vertex[v as usize];
    let corner_class: Vec<u32> = if parallel {
        mesh.indices
            .par_iter()
            .with_min_len(8192)
            .map(class_of)
            .collect()
    } else {
        mesh.indices.iter().map(class_of).collect()
    };
    let table = CornerTable::build_filtered(
        &corner_class,
        weld.class_count,
        |c| flags[c / 3] & DEGENERATE == 0,
        parallel,
    );

    let context = Context {
        mesh,
        corner_class: &corner_class,
        frames: &frames,
        table: &table,
    };

    // Results are laid out like `table.corners`, so that each vertex owns a contiguous slice.
    let mut results = vec![UNASSIGNED; table.corners.len()];
    let pieces = if parallel {
        rayon::current_num_threads() * 16
    } else {
        1
    };
    let touched_lists: Vec<Vec<u32>> = {
        let pieces = table.split_by_class(&mut results, pieces);
        let run = |(range, out): (std::ops::Range<usize>, &mut [[f32; 4]])| {
            let mut scratch = Scratch::default();
            let mut touched = Vec::new();
            let base = table.offsets[range.start] as usize;
            for class in range {
                let corners = table.of(class);
                if corners
                    .iter()
                    .any(|&c| flags[c as usize / 3] & GROUP_WITH_ANY != 0)
                {
                    touched.push(class as u32);
                    continue;
                }
                let start = table.offsets[class] as usize - base;
                let out = &mut out[start..start + corners.len()];
                context.pair_edges(class, &mut scratch);
                label_components(corners, &flags, &mut scratch);
                context.evaluate(class, &flags, &scratch.labels, out, &mut scratch.eval);
            }
            touched
        };
        if parallel {
            pieces.into_par_iter().map(run).collect()
        } else {
            pieces.into_iter().map(run).collect()
        }
    };
    let touched: Vec<u32> = touched_lists.into_iter().flatten().collect();
    if !touched.is_empty() {
        context.group_touched_vertices(&touched, &mut flags, &mut results);
    }

    // Gather per corner. Degenerate corners borrow from the first good corner of their vertex.
    let slot_of_corner = &table.slot_of_corner;
    let gather = |(c, out): (usize, &mut [f32; 4])| {
        let slot = slot_of_corner[c];
        *out = if slot != NONE {
            results[slot as usize]
        } else {
            let class = corner_class[c];
            let first = table.offsets[class as usize];
            if first < table.offsets[class as usize + 1] {
                results[first as usize]
            } else {
                UNASSIGNED
            }
        };
    };
    let mut out = vec![UNASSIGNED; corner_class.len()];
    if parallel {
        out.par_iter_mut()
            .enumerate()
            .with_min_len(8192)
            .for_each(gather);
    } else {
        out.iter_mut().enumerate().for_each(gather);
    }
    out
}

/// The reference's per-triangle set-up, in its operation order so results are bit-identical.
fn triangle_frame(mesh: &Mesh<'_>, t: usize) -> (Frame, u8) {
    let [a, b, c] = mesh.triangle(t);
    let p = [mesh.positions[a], mesh.positions[b], mesh.positions[c]];
    if same_position(p[0], p[1]) || same_position(p[1], p[2]) || same_position(p[2], p[0]) {
        return (Frame::default(), DEGENERATE);
    }
    let tx = [mesh.uv(a), mesh.uv(b), mesh.uv(c)];
    let d_tx = [
        [tx[1][0] - tx[0][0], tx[1][1] - tx[0][1]],
        [tx[2][0] - tx[0][0], tx[2][1] - tx[0][1]],
    ];
    let d_v = [sub(p[1], p[0]), sub(p[2], p[0])];
    let signed_area = d_tx[0][0] * d_tx[1][1] - d_tx[0][1] * d_tx[1][0];
    let area = signed_area.abs();
    let s = sub(scale(d_v[0], d_tx[1][1]), scale(d_v[1], d_tx[0][1]));
    let tt = add(scale(d_v[0], -d_tx[1][0]), scale(d_v[1], d_tx[0][0]));

    let mut flag = GROUP_WITH_ANY;
    if signed_area > 0.0 {
        flag |= ORIENT_PRESERVING;
    }
    let finite = is_finite3(p[0])
        && is_finite3(p[1])
        && is_finite3(p[2])
        && tx.iter().flatten().all(|x| x.is_finite());
    if !finite || !not_zero(area) {
        return (Frame::default(), flag);
    }
    let sign = if flag & ORIENT_PRESERVING != 0 {
        1.0
    } else {
        -1.0
    };
    let frame = Frame {
        s: scale(normalize_or_zero(s), sign),
        t: scale(normalize_or_zero(tt), sign),
    };
    let s_magnitude = super::math::length(s) / area;
    let t_magnitude = super::math::length(tt) / area;
    if not_zero(s_magnitude) && not_zero(t_magnitude) {
        flag &= !GROUP_WITH_ANY;
    }
    (frame, flag)
}

struct Context<'a> {
    mesh: &'a Mesh<'a>,
    corner_class: &'a [u32],
    frames: &'a [Frame],
    table: &'a CornerTable,
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
    fn group_touched_vertices(&self, touched: &[u32], flags: &mut [u8], results: &mut [[f32; 4]]) {
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
            let range = self.table.offsets[class] as usize..self.table.offsets[class + 1] as usize;
            let labels = &labels[link_offsets[k]..link_offsets[k + 1]];
            self.evaluate(class, flags, labels, &mut results[range], &mut scratch.eval);
        }
    }

    /// Computes the tangent of every corner around `class` from its group label (`NONE`: no
    /// group, the corner stays unassigned).
    fn evaluate(
        &self,
        class: usize,
        flags: &[u8],
        labels: &[u32],
        out: &mut [[f32; 4]],
        eval: &mut EvalScratch,
    ) {
        let corners = self.table.of(class);
        let Some(&first) = corners.first() else {
            return;
        };
        let normal = self.mesh.normals[self.mesh.indices[first as usize] as usize];

        // Per-corner contribution, computed once.
        eval.members.clear();
        for &corner in corners {
            let corner = corner as usize;
            let triangle = corner / 3;
            let any = flags[triangle] & GROUP_WITH_ANY != 0;
            let mut member = Member {
                any,
                ..Member::default()
            };
            if !any {
                let frame = &self.frames[triangle];
                member.s = normalize_or_zero(reject(frame.s, normal));
                member.t = normalize_or_zero(reject(frame.t, normal));
                member.angle = self.corner_angle(corner, normal);
            }
            eval.members.push(member);
        }

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
            self.evaluate_group(corners, orientation_preserving, out, eval);
            start = end;
        }
    }

    fn evaluate_group(
        &self,
        corners: &[u32],
        orientation_preserving: bool,
        out: &mut [[f32; 4]],
        eval: &mut EvalScratch,
    ) {
        let members = &eval.members;
        let group = &eval.group;
        // A member leaves another's sub-group only if their projected frames point in exactly
        // opposite directions (cosine <= -1 in float) or are NaN. If every frame lies within
        // ~89° of the first, no pair can be opposite and the group is one sub-group.
        let reference = group.iter().map(|&j| &members[j as usize]).find(|m| !m.any);
        let single = match reference {
            None => true,
            Some(r) => group
                .iter()
                .map(|&j| &members[j as usize])
                .all(|m| m.any || (dot(m.s, r.s) > 0.01 && dot(m.t, r.t) > 0.01)),
        };
        if single || group.len() > MAX_EXACT_SUBGROUP {
            let tangent = sum_tangents(group.iter().map(|&j| &members[j as usize]));
            for &j in group {
                out[j as usize] = encode(tangent, orientation_preserving);
            }
            return;
        }
        // The reference's sub-groups: for each member, the members it is "similar" to.
        for &a in group {
            let ma = &members[a as usize];
            let subgroup = group.iter().filter(|&&b| {
                let mb = &members[b as usize];
                let same_face = corners[a as usize] / 3 == corners[b as usize] / 3;
                ma.any || mb.any || same_face || (dot(ma.s, mb.s) > -1.0 && dot(ma.t, mb.t) > -1.0)
            });
            let tangent = sum_tangents(subgroup.map(|&j| &members[j as usize]));
            out[a as usize] = encode(tangent, orientation_preserving);
        }
    }

    /// The angle of the triangle at `corner`, measured in the plane of `normal`, as the reference
    /// weights it.
    fn corner_angle(&self, corner: usize, normal: [f32; 3]) -> f32 {
        let base = corner - corner % 3;
        let i = corner % 3;
        let idx = self.mesh.indices;
        let p_next = self.mesh.positions[idx[base + (i + 1) % 3] as usize];
        let p_here = self.mesh.positions[idx[corner] as usize];
        let p_prev = self.mesh.positions[idx[base + (i + 2) % 3] as usize];
        let v1 = normalize_or_zero(reject(sub(p_next, p_here), normal));
        let v2 = normalize_or_zero(reject(sub(p_prev, p_here), normal));
        let cos = dot(v1, v2).clamp(-1.0, 1.0);
        (cos as f64).acos() as f32
    }
}

/// Groups larger than this skip the reference's O(k²) sub-group search and use the whole group,
/// which differs from the reference only if two of their frames are exactly opposite.
const MAX_EXACT_SUBGROUP: usize = 2048;

#[derive(Clone, Copy, Default)]
struct Member {
    s: [f32; 3],
    t: [f32; 3],
    angle: f32,
    any: bool,
}

#[derive(Default)]
struct EvalScratch {
    members: Vec<Member>,
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
