//! What the core noticed about a mesh: counts, with the first few offending indices of each.
//!
//! Everything here is gathered in one pass over triangles and one over vertices, cheap enough to
//! be always on.

use super::math::{Mesh, cross, dot, is_finite3, length, same_position, sub};
use super::{Method, NormalMode, Options, UvOrigin};
use rayon::prelude::*;

/// How many offending indices a [`Tally`] keeps.
pub const SAMPLE_SIZE: usize = 8;

/// A count of offending items and the first few of their indices, ascending.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Tally {
    /// How many items there are.
    pub count: u64,
    /// The first [`SAMPLE_SIZE`] of their indices (triangles, vertices or corners), ascending.
    pub first: Vec<u32>,
}

impl Tally {
    /// Counts one more item, keeping its index while there is room in the sample.
    pub fn add(&mut self, index: u32) {
        self.count += 1;
        if self.first.len() < SAMPLE_SIZE {
            self.first.push(index);
        }
    }

    /// Appends a tally of later items.
    pub fn append(&mut self, later: &Tally) {
        self.count += later.count;
        let room = SAMPLE_SIZE - self.first.len();
        self.first.extend(later.first.iter().take(room));
    }

    /// True when nothing was counted.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }
}

/// Corners whose tangent had to be replaced by a fallback, and why.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct FallbackCounts {
    /// All replaced corners (corner = position in the index buffer).
    pub corners: Tally,
    /// Every replaced corner, ascending, where [`FallbackCounts::corners`] keeps the first few:
    /// what a picture of the mesh marks. One entry per repair, so usually empty.
    pub all_corners: Vec<u32>,
    /// The method gave the corner no tangent at all (only degenerate or unmapped triangles meet
    /// at its vertex).
    pub unassigned: u64,
    /// The tangent was zero (the contributions cancelled or had no length in the normal's plane).
    pub zero_length: u64,
    /// The tangent held NaN or infinity.
    pub non_finite: u64,
    /// The tangent was not unit length or not orthogonal to the normal (usually because the
    /// input normal was not unit length).
    pub not_orthogonal: u64,
}

/// The diagnostics record of one [`super::generate`] call.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Diagnostics {
    /// The method that made the tangents.
    pub method: Method,
    /// Triangles in the mesh.
    pub triangles: u64,
    /// Vertices before the split.
    pub vertices_in: u64,
    /// Vertices after the split.
    pub vertices_out: u64,
    /// `vertices_out - vertices_in`: copies made where corners of one vertex needed different
    /// tangents (or, with generated normals, different normals).
    pub vertices_added: u64,
    /// Set when the mesh had no normals and they were generated.
    pub generated_normals: Option<NormalMode>,
    /// Triangles with two corners at exactly the same position.
    pub duplicate_position_triangles: Tally,
    /// Other triangles whose area is negligible against their longest edge (slivers, collinear).
    pub zero_area_triangles: Tally,
    /// Triangles whose texture-coordinate area is zero or negligible.
    pub zero_uv_area_triangles: Tally,
    /// Triangles whose texture coordinates wind the other way (mirrored UVs), given the UV
    /// origin convention.
    pub mirrored_uv_triangles: Tally,
    /// Triangles with a NaN or infinite position, normal or texture coordinate.
    pub non_finite_triangles: Tally,
    /// Vertices whose normal is zero.
    pub zero_normals: Tally,
    /// Vertices whose normal is more than 0.1% away from unit length (but not zero).
    pub non_unit_normals: Tally,
    /// Vertices whose corners received tangents of both handedness (these are split).
    pub handedness_flip_vertices: Tally,
    /// Triangles whose three corners do not share one `w`.
    pub mixed_handedness_triangles: Tally,
    /// Corners given a fallback tangent because the method's own was not valid, by reason.
    pub fallback_tangents: FallbackCounts,
}

/// Relative size below which an area counts as zero: the triangle's height is under 1e-7 of its
/// longest edge, about where f32 positions stop resolving it.
const RELATIVE_AREA_EPSILON: f32 = 1e-7;

/// Per-triangle findings, gathered by whichever pass already visits the triangles.
#[derive(Default)]
pub(crate) struct TriangleTallies {
    duplicate: Tally,
    zero_area: Tally,
    zero_uv: Tally,
    mirrored: Tally,
    non_finite: Tally,
}

/// What the triangle checks need to know besides the triangle itself.
pub(crate) struct TriangleCheck<'a> {
    pub uv_origin: UvOrigin,
    pub has_uvs: bool,
    /// Vertices with a non-finite position, normal or texture coordinate; empty when there are
    /// none (the common case, which then costs nothing per triangle).
    pub non_finite_vertex: &'a [bool],
    /// Checked by the passes over triangles between runs; a cancelled pass skips its remaining
    /// runs, and its caller returns nothing of it.
    pub cancel: &'a crate::Cancel,
}

impl TriangleCheck<'_> {
    /// Whether every position, normal and texture coordinate is finite.
    pub fn all_vertices_finite(&self) -> bool {
        self.non_finite_vertex.is_empty()
    }

    /// Checks triangle `index`, whose vertices are `vertices`, positions `p` and texture
    /// coordinates `uv` (zeros without UVs).
    #[inline]
    pub fn check(
        &self,
        tallies: &mut TriangleTallies,
        index: usize,
        vertices: [usize; 3],
        p: &[[f32; 3]; 3],
        uv: &[[f32; 2]; 3],
    ) {
        if self.touches_non_finite(vertices) {
            tallies.add_non_finite(index);
            return;
        }
        self.record(tallies, index, self.events(p, uv));
    }

    /// Whether any vertex has a non-finite value (if not, no triangle needs looking up).
    #[inline]
    pub fn has_non_finite(&self) -> bool {
        !self.non_finite_vertex.is_empty()
    }

    /// Whether the triangle uses a vertex with a non-finite value: then it is counted as such
    /// and nothing else.
    #[inline]
    pub fn touches_non_finite(&self, vertices: [usize; 3]) -> bool {
        !self.non_finite_vertex.is_empty() && vertices.iter().any(|&v| self.non_finite_vertex[v])
    }

    /// What the checks find in a triangle of finite vertices, as bits (`DUPLICATE` and the
    /// others). Branch-free, so that a loop over many triangles vectorizes.
    #[inline(always)]
    pub fn events(&self, p: &[[f32; 3]; 3], uv: &[[f32; 2]; 3]) -> u8 {
        let duplicate =
            same_position(p[0], p[1]) | same_position(p[1], p[2]) | same_position(p[2], p[0]);
        let e = [sub(p[1], p[0]), sub(p[2], p[0]), sub(p[2], p[1])];
        let longest = dot(e[0], e[0]).max(dot(e[1], e[1])).max(dot(e[2], e[2]));
        let zero_area = length(cross(e[0], e[1])) <= RELATIVE_AREA_EPSILON * longest;
        let mut events = if duplicate {
            DUPLICATE
        } else if zero_area {
            ZERO_AREA
        } else {
            0
        };
        if self.has_uvs {
            let d1 = [uv[1][0] - uv[0][0], uv[1][1] - uv[0][1]];
            let d2 = [uv[2][0] - uv[0][0], uv[2][1] - uv[0][1]];
            let d3 = [uv[2][0] - uv[1][0], uv[2][1] - uv[1][1]];
            let signed = d1[0] * d2[1] - d1[1] * d2[0];
            let square = |d: [f32; 2]| d[0] * d[0] + d[1] * d[1];
            let longest = square(d1).max(square(d2)).max(square(d3));
            let zero_uv = signed.abs() <= RELATIVE_AREA_EPSILON * longest;
            // With the origin at the top left (glTF), v runs downwards, so an unmirrored
            // front face has a negative raw UV area.
            let mirrored = match self.uv_origin {
                UvOrigin::TopLeft => signed > 0.0,
                UvOrigin::BottomLeft => signed < 0.0,
            };
            events |= if zero_uv {
                ZERO_UV
            } else if mirrored {
                MIRRORED
            } else {
                0
            };
        }
        events
    }

    /// Adds triangle `index` to the tallies its `events` name.
    #[inline]
    pub fn record(&self, tallies: &mut TriangleTallies, index: usize, events: u8) {
        if events == 0 {
            return;
        }
        let index = index as u32;
        for (bit, tally) in [
            (DUPLICATE, &mut tallies.duplicate),
            (ZERO_AREA, &mut tallies.zero_area),
            (ZERO_UV, &mut tallies.zero_uv),
            (MIRRORED, &mut tallies.mirrored),
        ] {
            if events & bit != 0 {
                tally.add(index);
            }
        }
    }
}

/// Bits of [`TriangleCheck::events`].
const DUPLICATE: u8 = 1;
const ZERO_AREA: u8 = 2;
const ZERO_UV: u8 = 4;
const MIRRORED: u8 = 8;

/// Tallies of consecutive runs of triangles, appended in order.
impl std::iter::Sum for TriangleTallies {
    fn sum<I: Iterator<Item = TriangleTallies>>(runs: I) -> TriangleTallies {
        runs.fold(TriangleTallies::default(), TriangleTallies::append)
    }
}

impl TriangleTallies {
    pub fn add_non_finite(&mut self, index: usize) {
        self.non_finite.add(index as u32);
    }

    /// Appends the tallies of later triangles.
    pub fn append(mut self, later: TriangleTallies) -> TriangleTallies {
        self.duplicate.append(&later.duplicate);
        self.zero_area.append(&later.zero_area);
        self.zero_uv.append(&later.zero_uv);
        self.mirrored.append(&later.mirrored);
        self.non_finite.append(&later.non_finite);
        self
    }
}

impl Diagnostics {
    pub(crate) fn set_triangles(&mut self, tallies: TriangleTallies) {
        self.duplicate_position_triangles = tallies.duplicate;
        self.zero_area_triangles = tallies.zero_area;
        self.zero_uv_area_triangles = tallies.zero_uv;
        self.mirrored_uv_triangles = tallies.mirrored;
        self.non_finite_triangles = tallies.non_finite;
    }
}

/// The triangle checks as a pass of their own, for the methods that do not visit triangles
/// anyway.
pub(crate) fn analyze_triangles(
    mesh: &Mesh<'_>,
    check: &TriangleCheck<'_>,
    parallel: bool,
) -> TriangleTallies {
    let triangle_count = mesh.triangle_count();
    const CHUNK: usize = 16384;
    let chunk_count = triangle_count.div_ceil(CHUNK);
    let chunk = |i: usize| {
        let mut tallies = TriangleTallies::default();
        for t in i * CHUNK..((i + 1) * CHUNK).min(triangle_count) {
            let v = mesh.triangle(t);
            // Element by element: `v.map(..)` builds the arrays on the stack in pieces.
            let p = [
                mesh.positions[v[0]],
                mesh.positions[v[1]],
                mesh.positions[v[2]],
            ];
            let uv = [mesh.uv(v[0]), mesh.uv(v[1]), mesh.uv(v[2])];
            check.check(&mut tallies, t, v, &p, &uv);
        }
        tallies
    };
    if parallel {
        (0..chunk_count)
            .into_par_iter()
            .map(chunk)
            .collect::<Vec<_>>()
            .into_iter()
            .sum()
    } else {
        (0..chunk_count).map(chunk).sum()
    }
}

/// Normals are screened this many at a time; a block that holds any normal that is not nearly
/// unit is looked at normal by normal.
const SCREEN: usize = 64;

/// Whether a normal is finite and of length within 1e-3 of 1, without a branch or a square root:
/// most normals are unit, and a squared length this close to 1 in f32 (rounding moves it by
/// about 1e-7) puts the length well within 1e-3 of 1. A non-finite component makes the squared
/// length NaN or infinite, which fails the comparison.
#[inline(always)]
fn nearly_unit(n: [f32; 3]) -> bool {
    let len2 = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
    (0.9985..=1.0015).contains(&len2)
}

/// Whether every component of every item is finite: branch-free over the whole slice, so that it
/// runs as vector loops (an early exit at the first non-finite item, which nearly no mesh has,
/// would test one component at a time).
fn all_finite<const N: usize>(items: &[[f32; N]]) -> bool {
    items
        .as_flattened()
        .iter()
        .fold(true, |finite, &x| finite & x.is_finite())
}

/// Input-side diagnostics that look at vertices: normal checks, and which vertices hold
/// non-finite values (returned for [`TriangleCheck`]; empty when all are finite). Triangle
/// checks and output-side counts (split, handedness, fallbacks) are filled in by the steps that
/// see them.
pub(crate) fn analyze_vertices(mesh: &Mesh<'_>, options: &Options) -> (Diagnostics, Vec<bool>) {
    const CHUNK: usize = 1 << 16;
    // (zero normals, non-unit normals, any non-finite normal) of one chunk of normals.
    let check_normals = |(chunk, normals): (usize, &[[f32; 3]])| {
        let mut zero = Tally::default();
        let mut non_unit = Tally::default();
        let mut non_finite = false;
        let first = chunk * CHUNK;
        for (block, normals) in normals.chunks(SCREEN).enumerate() {
            if normals.iter().fold(true, |unit, &n| unit & nearly_unit(n)) {
                continue;
            }
            for (v, &n) in (first + block * SCREEN..).zip(normals) {
                if !is_finite3(n) {
                    non_finite = true;
                    continue;
                }
                if nearly_unit(n) {
                    continue;
                }
                // In f64: an f32 length underflows to zero for tiny normals the core still uses.
                let w = n.map(f64::from);
                let len = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
                if len == 0.0 {
                    zero.add(v as u32);
                } else if (len - 1.0).abs() > 1e-3 {
                    non_unit.add(v as u32);
                }
            }
        }
        (zero, non_unit, non_finite)
    };
    let chunks: Vec<(Tally, Tally, bool)> = if options.parallel {
        mesh.normals
            .par_chunks(CHUNK)
            .enumerate()
            .map(check_normals)
            .collect()
    } else {
        mesh.normals
            .chunks(CHUNK)
            .enumerate()
            .map(check_normals)
            .collect()
    };
    // In chunk order, so the first few indices listed are the lowest, as in one pass.
    let mut zero_normals = Tally::default();
    let mut non_unit_normals = Tally::default();
    let mut any_non_finite = false;
    for (zero, non_unit, non_finite) in &chunks {
        zero_normals.append(zero);
        non_unit_normals.append(non_unit);
        any_non_finite |= non_finite;
    }
    let finite_vertex = |v: usize| {
        is_finite3(mesh.positions[v])
            && is_finite3(mesh.normals[v])
            && mesh.uv(v).iter().all(|x| x.is_finite())
    };
    any_non_finite = any_non_finite
        || if options.parallel {
            !mesh.positions.par_chunks(CHUNK).all(all_finite)
                || mesh
                    .uvs
                    .is_some_and(|uvs| !uvs.par_chunks(CHUNK).all(all_finite))
        } else {
            !all_finite(mesh.positions) || mesh.uvs.is_some_and(|uvs| !all_finite(uvs))
        };
    let non_finite_vertex = if any_non_finite {
        (0..mesh.vertex_count())
            .map(|v| !finite_vertex(v))
            .collect()
    } else {
        Vec::new()
    };

    let diagnostics = Diagnostics {
        method: options.method,
        triangles: mesh.triangle_count() as u64,
        vertices_in: mesh.vertex_count() as u64,
        zero_normals,
        non_unit_normals,
        ..Diagnostics::default()
    };
    (diagnostics, non_finite_vertex)
}
