//! Tangent frames for normal mapping: plain slices in, per-corner tangents, a split plan and
//! diagnostics out.
//!
//! # The design decision
//!
//! This crate is pure: it takes `&[[f32; 3]]` positions and normals, `&[[f32; 2]]` texture
//! coordinates and optional `&[u32]` indices, and knows nothing of files, glTF or HTTP. Every
//! allocation is sized by the length of the input slices, never by a count read from a file, and
//! no input, however broken (NaN, infinities, degenerate and sliver triangles, zero normals),
//! makes it panic: bad numbers come out as valid tangents plus a diagnostic. It depends on rayon
//! and nothing else.
//!
//! # The guarantee
//!
//! [`Method::MikkTSpace`] (the default) is **bit-identical to the MikkTSpace reference**, as
//! ported byte for byte by [`bevy_mikktspace`](https://crates.io/crates/bevy_mikktspace) 1.0 with
//! its `corrected-edge-sorting` fix, on every corner where the reference emits a valid tangent,
//! and several times faster (10–20 times `bevy_mikktspace` on one thread, by mesh and machine;
//! see the project's `docs/benchmarks.md`). The crate's `tests/reference.rs` and the project's
//! oracle tests check this corner by corner. Where the reference emits a broken tangent
//! (unassigned `(1, 0, 0)`, zero, NaN, or off the normal's plane), this crate emits a valid one
//! and counts the corner in [`Diagnostics::fallback_tangents`] with the reason. Welding,
//! orientation groups, projection and angle weighting are the reference's; its global edge sort,
//! recursion and O(k²) sub-group search are replaced by work on the short list of corners around
//! each welded vertex.
//!
//! Whatever the method, every emitted tangent is finite, unit length (within 1e-5), orthogonal
//! to its normalized normal (within 1e-4), with `w` exactly ±1.
//!
//! # Methods
//!
//! - [`Method::MikkTSpace`]: what normal-map bakers assume and the glTF specification recommends.
//! - [`Method::Fast`]: the classic per-triangle dP/du accumulation (Lengyel), still split by
//!   handedness.
//! - [`Method::Axis`]: needs no texture coordinates: the normal crossed with the world axis least
//!   aligned with it.
//!
//! glTF puts the UV origin at the top left; as three.js, glTF-Transform and Blender do, the
//! default [`UvOrigin::TopLeft`] runs MikkTSpace on the raw UVs and negates `w`.
//!
//! # Example
//!
//! ```
//! use tspace_tangent::{MeshInput, Options, generate};
//!
//! // A unit quad in the z = 0 plane, facing +z, with u along +x and v along -y (glTF's origin).
//! let positions = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
//! let normals = [[0.0, 0.0, 1.0]; 4];
//! let uvs = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]];
//! let indices = [0, 1, 2, 0, 2, 3];
//!
//! let input = MeshInput {
//!     positions: &positions,
//!     normals: Some(&normals),
//!     uvs: Some(&uvs),
//!     indices: Some(&indices),
//! };
//! let result = generate(&input, &Options::default())?;
//!
//! // No vertex needed splitting: one tangent per input vertex, +x with w = +1.
//! assert_eq!(result.split.vertex_tangents.len(), 4);
//! for corner in 0..indices.len() {
//!     assert_eq!(result.corner_tangent(corner, input.indices), [1.0, 0.0, 0.0, 1.0]);
//! }
//! assert_eq!(result.diagnostics.fallback_tangents.corners.count, 0);
//! # Ok::<(), tspace_tangent::CoreError>(())
//! ```
//!
//! The [`SplitPlan`] says how to rebuild the vertex buffer so that every vertex has one tangent:
//! `source_vertex` lists the input vertex each output vertex copies (so skin weights, colours and
//! morph targets can be duplicated the same way), and `indices` gives every corner its output
//! vertex, triangle for triangle in input order, where any corner changed vertex (where none
//! did, the input's own indices stand, and the plan holds no copy of them).
//!
//! A service that stops waiting for a result (its request timed out, its client left) can get
//! its thread back: [`generate_cancellable`] takes a [`Cancel`] flag that another thread sets,
//! and returns [`CoreError::Cancelled`] within one pass or one run of 16,384 triangles.

#![warn(missing_docs)]

mod acos;
mod axis;
pub mod diagnostics;
mod fallback;
mod fast;
mod fill;
pub mod marks;
mod math;
mod mikktspace;
mod normals;
mod output;
mod prefetch;
mod split;
mod triangles;
mod vectors;
mod weld;

#[cfg(test)]
mod test_support {
    /// A xorshift generator: the tests' random inputs, the same on every run.
    pub(crate) fn xorshift(mut state: u64) -> impl FnMut() -> u64 {
        move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        }
    }
}

pub use diagnostics::{Diagnostics, FallbackCounts, Tally};
pub use marks::{Marks, TriangleMarks, marks};
pub use normals::{GeneratedNormals, generate_normals};
pub use split::SplitPlan;

use rayon::prelude::*;
use std::borrow::Cow;
use std::fmt;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// A request to stop a [`generate_cancellable`] that is under way, from another thread: a
/// service whose client has gone (timed out, disconnected) wants its thread back at once, not
/// when a mesh of millions of triangles is done. Clones share one flag. The computation checks
/// it between its passes and between runs of 16,384 triangles, so it stops within one such step.
#[derive(Clone, Debug, Default)]
pub struct Cancel(Option<Arc<AtomicBool>>);

impl Cancel {
    /// A flag that [`Cancel::cancel`] can set.
    pub fn new() -> Self {
        Cancel(Some(Arc::new(AtomicBool::new(false))))
    }

    /// Asks every computation holding a clone of this flag to stop.
    pub fn cancel(&self) {
        if let Some(flag) = &self.0 {
            flag.store(true, Ordering::Relaxed);
        }
    }

    /// Whether [`Cancel::cancel`] was called; never for the default, which cannot be set.
    #[inline]
    pub fn is_cancelled(&self) -> bool {
        self.0.as_ref().is_some_and(|f| f.load(Ordering::Relaxed))
    }
}

/// How tangents are computed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Method {
    /// MikkTSpace, as the glTF specification recommends and as normal-map bakers assume.
    #[default]
    MikkTSpace,
    /// Per-triangle dP/du accumulated per welded vertex (area or angle weighted), Gram–Schmidt
    /// against the normal. Faster, smooth, but not what bakers use.
    Fast,
    /// No texture coordinates needed: the normal crossed with its least-aligned world axis.
    Axis,
}

impl Method {
    /// The name used on the command line, in query strings and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Method::MikkTSpace => "mikktspace",
            Method::Fast => "fast",
            Method::Axis => "axis",
        }
    }

    /// Every method, in the order help texts list them.
    pub const ALL: [Method; 3] = [Method::MikkTSpace, Method::Fast, Method::Axis];

    /// Other spellings [`Method::from_name`] accepts besides [`Method::name`].
    pub fn aliases(self) -> &'static [&'static str] {
        match self {
            Method::MikkTSpace => &["mikk"],
            Method::Fast | Method::Axis => &[],
        }
    }

    /// Parses a method name as accepted on the command line and in query strings: a
    /// [`Method::name`] or one of its [`Method::aliases`].
    pub fn from_name(name: &str) -> Option<Method> {
        Method::ALL
            .into_iter()
            .find(|m| m.name() == name || m.aliases().contains(&name))
    }
}

/// The one parser of method names that the command line and the query string share.
impl std::str::FromStr for Method {
    type Err = UnknownMethod;

    fn from_str(name: &str) -> Result<Method, UnknownMethod> {
        Method::from_name(name).ok_or(UnknownMethod)
    }
}

/// A method name [`Method::from_name`] does not know. Its message lists the names it does
/// (callers add which value was given, and where).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct UnknownMethod;

impl fmt::Display for UnknownMethod {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("expected ")?;
        let last = Method::ALL.len() - 1;
        for (i, method) in Method::ALL.iter().enumerate() {
            let separator = match i {
                0 => "",
                _ if i == last => " or ",
                _ => ", ",
            };
            write!(f, "{separator}{}", method.name())?;
        }
        Ok(())
    }
}

impl std::error::Error for UnknownMethod {}

/// Where the texture-coordinate origin lies, which decides the sign of `w`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum UvOrigin {
    /// glTF: origin at the top left, v grows downwards. Tangents are computed on the raw UVs and
    /// `w` is negated, as three.js, glTF-Transform and Blender's exporter do.
    #[default]
    TopLeft,
    /// OpenGL and OBJ: origin at the bottom left, v grows upwards. `w` is used as computed.
    BottomLeft,
}

/// How [`Method::Fast`] weights each triangle's contribution at a vertex.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Weighting {
    /// By the triangle's corner angle at the vertex (insensitive to tessellation).
    #[default]
    Angle,
    /// By the triangle's area (the unnormalized cross product).
    Area,
}

/// How normals are made when the mesh has none (by [`generate`], or by [`generate_normals`] on
/// their own).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum NormalMode {
    /// One normal per triangle, as the glTF specification requires for meshes without normals.
    #[default]
    Flat,
    /// Angle-weighted vertex normals, averaged across edges whose faces meet at less than
    /// `crease_degrees`; sharper edges, and edges of more than two triangles, stay hard.
    SmoothByAngle {
        /// Faces whose normals differ by more than this many degrees keep a hard edge.
        crease_degrees: f32,
    },
}

/// Options for [`generate`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Options {
    /// How tangents are computed ([`Method::MikkTSpace`] by default).
    pub method: Method,
    /// Where the texture-coordinate origin lies, which decides the sign of `w`.
    pub uv_origin: UvOrigin,
    /// How [`Method::Fast`] weights each triangle at a vertex (ignored by the other methods).
    pub weighting: Weighting,
    /// Used only when [`MeshInput::normals`] is `None`.
    pub normal_mode: NormalMode,
    /// Spread the work over the rayon thread pool. Results are identical either way.
    pub parallel: bool,
}

/// A triangle list, indexed or not. All per-vertex slices must have the same length.
#[derive(Clone, Copy, Debug)]
pub struct MeshInput<'a> {
    /// Per-vertex positions; their length is the vertex count.
    pub positions: &'a [[f32; 3]],
    /// Per-vertex normals. When absent they are generated (see [`NormalMode`]).
    pub normals: Option<&'a [[f32; 3]]>,
    /// Per-vertex texture coordinates of the set the normal map uses. Required unless the method
    /// is [`Method::Axis`].
    pub uvs: Option<&'a [[f32; 2]]>,
    /// Three indices per triangle. When absent, every three consecutive vertices form a triangle.
    pub indices: Option<&'a [u32]>,
}

/// What [`generate`] returns.
///
/// The tangents come as a vertex buffer: [`SplitPlan::vertex_tangents`], one per output vertex,
/// with [`SplitPlan::indices`] giving every corner its vertex. That is what a scene writer needs,
/// and it is a quarter of the size of one tangent per corner; [`Tangents::corner_tangent`] and
/// [`Tangents::corner_tangents`] give the per-corner view.
#[derive(Clone, Debug)]
pub struct Tangents {
    /// How to rebuild the vertex buffer so that every vertex has one tangent.
    pub split: SplitPlan,
    /// Generated normals, one per *output* vertex of [`Tangents::split`], when the input had none.
    pub normals: Option<Vec<[f32; 3]>>,
    /// What was found in the mesh and what was done about it.
    pub diagnostics: Diagnostics,
}

impl Tangents {
    /// The tangent of one corner (index position, or vertex when the input is not indexed):
    /// `xyz` unit and orthogonal to the normal, `w` = ±1. `input_indices` are the indices of
    /// the input these tangents were generated for ([`MeshInput::indices`]).
    pub fn corner_tangent(&self, corner: usize, input_indices: Option<&[u32]>) -> [f32; 4] {
        self.split.vertex_tangents[self.split.vertex_of(corner, input_indices)]
    }

    /// The tangent of every corner, in input order (`input_indices` as for
    /// [`Tangents::corner_tangent`]).
    pub fn corner_tangents(&self, input_indices: Option<&[u32]>) -> Vec<[f32; 4]> {
        self.split
            .indices_for(input_indices)
            .iter()
            .map(|&v| self.split.vertex_tangents[v as usize])
            .collect()
    }
}

/// Input the core cannot work with at all. Anything softer (degenerate or non-finite data) is
/// handled and reported in [`Diagnostics`] instead.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum CoreError {
    /// A per-vertex slice does not have as many entries as `positions`.
    AttributeLength {
        /// `"normals"`, `"uvs"`, or `"smoothing_groups"` (one per triangle) for
        /// [`generate_normals`].
        attribute: &'static str,
        /// The number of positions.
        expected: usize,
        /// The attribute's length.
        found: usize,
    },
    /// The index (or vertex) count is not a multiple of three.
    NotTriangles {
        /// The index count (the vertex count when not indexed).
        count: usize,
    },
    /// An index points past the end of the vertex arrays.
    IndexOutOfRange {
        /// Its position in the index slice.
        corner: usize,
        /// The index itself.
        index: u32,
        /// The number of vertices.
        vertex_count: usize,
    },
    /// The method needs texture coordinates and none were given.
    MissingUvs {
        /// The method asked for.
        method: Method,
    },
    /// More vertices or corners than 32-bit indices can address.
    TooLarge {
        /// The vertex or corner count.
        count: usize,
    },
    /// [`Cancel::cancel`] was called; nothing was computed.
    Cancelled,
}

impl fmt::Display for CoreError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CoreError::AttributeLength {
                attribute,
                expected,
                found,
            } => write!(
                f,
                "{attribute} has {found} entries but there are {expected} positions"
            ),
            CoreError::NotTriangles { count } => {
                write!(f, "{count} indices do not make whole triangles")
            }
            CoreError::IndexOutOfRange {
                corner,
                index,
                vertex_count,
            } => write!(
                f,
                "index {index} at position {corner} is out of range for {vertex_count} vertices"
            ),
            CoreError::MissingUvs { method } => write!(
                f,
                "the {} method needs texture coordinates; use the axis method for meshes without UVs",
                method.name()
            ),
            CoreError::TooLarge { count } => {
                write!(f, "{count} elements exceed what 32-bit indices can address")
            }
            CoreError::Cancelled => f.write_str("the computation was cancelled"),
        }
    }
}

impl std::error::Error for CoreError {}

/// Computes tangents for one triangle list.
pub fn generate(input: &MeshInput<'_>, options: &Options) -> Result<Tangents, CoreError> {
    generate_cancellable(input, options, &Cancel::default())
}

/// [`generate`], which stops with [`CoreError::Cancelled`] soon after `cancel` is set.
pub fn generate_cancellable(
    input: &MeshInput<'_>,
    options: &Options,
    cancel: &Cancel,
) -> Result<Tangents, CoreError> {
    check_lengths(input, options.parallel)?;
    if options.method != Method::Axis && input.uvs.is_none() {
        return Err(CoreError::MissingUvs {
            method: options.method,
        });
    }
    let prepared = Prepared::new(input, options.normal_mode);
    let mesh = prepared.mesh();
    if cancel.is_cancelled() {
        return Err(CoreError::Cancelled);
    }
    let (mut diagnostics, mut split) = run_method(&mesh, options, cancel);
    // A cancelled pass leaves what it had not done at its defaults: nothing of it is returned.
    if cancel.is_cancelled() {
        return Err(CoreError::Cancelled);
    }
    let normals = prepared.express_in_input_vertices(&mut split, &mut diagnostics);
    Ok(Tangents {
        split,
        normals,
        diagnostics,
    })
}

/// The mesh every method works on: indexed, with normals. Generated normals come with their
/// own vertex split (flat normals give every triangle its own corners), so positions and UVs
/// are copied into that split's vertices.
enum Prepared<'a> {
    Given {
        input: &'a MeshInput<'a>,
        normals: &'a [[f32; 3]],
        /// `0, 1, 2, …` when the input is not indexed.
        indices: Cow<'a, [u32]>,
    },
    Generated {
        vertices_in: usize,
        generated: normals::GeneratedNormals,
        positions: Vec<[f32; 3]>,
        uvs: Option<Vec<[f32; 2]>>,
        normal_mode: NormalMode,
    },
}

impl<'a> Prepared<'a> {
    fn new(input: &'a MeshInput<'a>, normal_mode: NormalMode) -> Self {
        match input.normals {
            Some(normals) => Prepared::Given {
                input,
                normals,
                indices: match input.indices {
                    Some(indices) => Cow::Borrowed(indices),
                    None => Cow::Owned((0..input.positions.len() as u32).collect()),
                },
            },
            None => {
                let generated = normals::generate(input, normal_mode, None);
                let remap = &generated.source_vertex;
                let positions = remap.iter().map(|&v| input.positions[v as usize]).collect();
                let uvs = input
                    .uvs
                    .map(|uvs| remap.iter().map(|&v| uvs[v as usize]).collect());
                Prepared::Generated {
                    vertices_in: input.positions.len(),
                    generated,
                    positions,
                    uvs,
                    normal_mode,
                }
            }
        }
    }

    fn mesh(&self) -> math::Mesh<'_> {
        match self {
            Prepared::Given {
                input,
                normals,
                indices,
            } => math::Mesh {
                positions: input.positions,
                normals,
                uvs: input.uvs,
                indices,
            },
            Prepared::Generated {
                generated,
                positions,
                uvs,
                ..
            } => math::Mesh {
                positions,
                normals: &generated.normals,
                uvs: uvs.as_deref(),
                indices: &generated.indices,
            },
        }
    }

    /// With generated normals, the plan so far speaks of the normals' split: re-expressed in
    /// terms of the caller's vertices, with the normals handed back one per output vertex.
    fn express_in_input_vertices(
        self,
        split: &mut SplitPlan,
        diagnostics: &mut Diagnostics,
    ) -> Option<Vec<[f32; 3]>> {
        let Prepared::Generated {
            vertices_in,
            generated,
            normal_mode,
            ..
        } = self
        else {
            return None;
        };
        let source_vertex = &generated.source_vertex;
        let normals = split
            .source_vertex
            .iter()
            .map(|&v| generated.normals[v as usize])
            .collect();
        for v in &mut split.source_vertex {
            *v = source_vertex[*v as usize];
        }
        // The normals' split numbered the corners' vertices anew: the plan's indices, even
        // where they are that split's own, are not the caller's.
        if split.indices.is_none() {
            split.indices = Some(generated.indices);
        }
        diagnostics.generated_normals = Some(normal_mode);
        diagnostics.vertices_in = vertices_in as u64;
        diagnostics.vertices_added = split.source_vertex.len().saturating_sub(vertices_in) as u64;
        Some(normals)
    }
}

/// The vertex checks, then the chosen method (which checks the triangles in its own pass, but
/// for axis, which needs one of its own); the diagnostics and the split plan it makes.
fn run_method(
    mesh: &math::Mesh<'_>,
    options: &Options,
    cancel: &Cancel,
) -> (Diagnostics, SplitPlan) {
    let (mut diagnostics, non_finite_vertex) = diagnostics::analyze_vertices(mesh, options);
    let triangle_check = diagnostics::TriangleCheck {
        uv_origin: options.uv_origin,
        has_uvs: mesh.uvs.is_some(),
        non_finite_vertex: &non_finite_vertex,
        cancel,
    };
    // Axis tangents have no UV handedness to convert.
    let flip_w = options.method != Method::Axis && options.uv_origin == UvOrigin::TopLeft;
    let split = match options.method {
        Method::MikkTSpace => mikktspace::generate(
            mesh,
            options.parallel,
            flip_w,
            &triangle_check,
            &mut diagnostics,
        ),
        Method::Fast => fast::generate(
            mesh,
            options.weighting,
            options.parallel,
            flip_w,
            &triangle_check,
            &mut diagnostics,
        ),
        Method::Axis => {
            diagnostics.set_triangles(diagnostics::analyze_triangles(
                mesh,
                &triangle_check,
                options.parallel,
            ));
            let mut corners = axis::generate(mesh);
            diagnostics.fallback_tangents = fallback::repair(mesh, &mut corners, options.parallel);
            split::plan(
                mesh.indices,
                mesh.vertex_count(),
                &corners,
                mesh.normals,
                &mut diagnostics,
            )
        }
    };
    (diagnostics, split)
}

fn check_lengths(input: &MeshInput<'_>, parallel: bool) -> Result<(), CoreError> {
    let vertex_count = input.positions.len();
    if vertex_count > u32::MAX as usize {
        return Err(CoreError::TooLarge {
            count: vertex_count,
        });
    }
    if let Some(normals) = input.normals {
        if normals.len() != vertex_count {
            return Err(CoreError::AttributeLength {
                attribute: "normals",
                expected: vertex_count,
                found: normals.len(),
            });
        }
    }
    if let Some(uvs) = input.uvs {
        if uvs.len() != vertex_count {
            return Err(CoreError::AttributeLength {
                attribute: "uvs",
                expected: vertex_count,
                found: uvs.len(),
            });
        }
    }
    let corner_count = input.indices.map_or(vertex_count, <[u32]>::len);
    if corner_count % 3 != 0 {
        return Err(CoreError::NotTriangles {
            count: corner_count,
        });
    }
    if corner_count > u32::MAX as usize / 2 {
        return Err(CoreError::TooLarge {
            count: corner_count,
        });
    }
    if let Some(indices) = input.indices {
        let out_of_range = |&i: &u32| i as usize >= vertex_count;
        // A chunk's largest index, found by a vector loop, clears the whole chunk; only a chunk
        // that holds a bad index is searched for the first one. By chunks in parallel too:
        // rayon's per-element `position_first` cost twenty times the serial scan.
        const CHUNK: usize = 1 << 16;
        let has_bad = |chunk: &[u32]| {
            chunk.iter().fold(0, |largest: u32, &i| largest.max(i)) as usize >= vertex_count
        };
        let find_bad = |chunk: usize| {
            let at = chunk * CHUNK;
            indices[at..].iter().position(out_of_range).map(|i| at + i)
        };
        let first_bad = if parallel && indices.len() > CHUNK {
            indices
                .par_chunks(CHUNK)
                .position_first(has_bad)
                .and_then(find_bad)
        } else {
            indices.chunks(CHUNK).position(has_bad).and_then(find_bad)
        };
        if let Some(corner) = first_bad {
            return Err(CoreError::IndexOutOfRange {
                corner,
                index: indices[corner],
                vertex_count,
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    type Grid = (Vec<[f32; 3]>, Vec<[f32; 3]>, Vec<[f32; 2]>, Vec<u32>);

    /// An `n` × `n` grid of quads in the z = 0 plane with UVs along x and y, welded: positions,
    /// normals, UVs and indices.
    fn grid(n: u32) -> Grid {
        let side = n + 1;
        let mut positions = Vec::new();
        let mut uvs = Vec::new();
        for y in 0..side {
            for x in 0..side {
                positions.push([x as f32, y as f32, 0.0]);
                uvs.push([x as f32 / n as f32, y as f32 / n as f32]);
            }
        }
        let mut indices = Vec::new();
        for y in 0..n {
            for x in 0..n {
                let v = y * side + x;
                indices.extend_from_slice(&[v, v + 1, v + side + 1, v, v + side + 1, v + side]);
            }
        }
        let normals = vec![[0.0, 0.0, 1.0]; positions.len()];
        (positions, normals, uvs, indices)
    }

    /// A flag set before the start stops every method at once; set at any moment during the
    /// work, it gives either the whole, valid result or `Cancelled`, never a panic or a
    /// partial plan (the passes it interrupts leave defaults behind, which must not leak).
    #[test]
    fn a_cancelled_computation_returns_nothing_and_never_panics() {
        let (positions, normals, uvs, indices) = grid(400);
        let input = MeshInput {
            positions: &positions,
            normals: Some(&normals),
            uvs: Some(&uvs),
            indices: Some(&indices),
        };
        for method in Method::ALL {
            for parallel in [false, true] {
                let options = Options {
                    method,
                    parallel,
                    ..Options::default()
                };
                let whole = generate(&input, &options).unwrap();
                let cancel = Cancel::new();
                cancel.cancel();
                assert_eq!(
                    generate_cancellable(&input, &options, &cancel).unwrap_err(),
                    CoreError::Cancelled
                );
                let mut stopped = 0;
                for delay_us in (0..4000).step_by(250) {
                    let cancel = Cancel::new();
                    let result = std::thread::scope(|scope| {
                        let flag = cancel.clone();
                        scope.spawn(move || {
                            std::thread::sleep(std::time::Duration::from_micros(delay_us));
                            flag.cancel();
                        });
                        generate_cancellable(&input, &options, &cancel)
                    });
                    match result {
                        Ok(tangents) => assert_eq!(tangents.split, whole.split, "{method:?}"),
                        Err(e) => {
                            assert_eq!(e, CoreError::Cancelled);
                            stopped += 1;
                        }
                    }
                }
                assert!(stopped > 0, "{method:?}: never cancelled");
            }
        }
    }

    #[test]
    fn method_names_parse_back_and_unknown_ones_say_what_is_accepted() {
        for method in Method::ALL {
            assert_eq!(method.name().parse(), Ok(method));
            for alias in method.aliases() {
                assert_eq!(alias.parse(), Ok(method));
            }
        }
        assert_eq!("mikk".parse(), Ok(Method::MikkTSpace));
        let error = "magic".parse::<Method>().unwrap_err();
        assert_eq!(error.to_string(), "expected mikktspace, fast or axis");
    }

    /// Normals are screened in blocks: a block with one odd normal among unit ones still
    /// reports it, at its own index, whichever block and chunk it lies in, and a normal within
    /// 1e-3 of unit length is not reported.
    #[test]
    fn odd_normals_are_found_wherever_they_lie_among_unit_ones() {
        let (positions, mut normals, mut uvs, indices) = grid(300);
        let zero = [3, 64, 70_000];
        let non_unit = [(63, 2.0), (65, 0.5), (90_000, 1.002)];
        let nearly_unit = [(128, 1.0009), (129, 0.9991)];
        for &v in &zero {
            normals[v] = [0.0; 3];
        }
        for &(v, length) in non_unit.iter().chain(&nearly_unit) {
            normals[v] = [0.0, 0.0, length];
        }
        uvs[80_000] = [f32::INFINITY, 0.0];
        let input = MeshInput {
            positions: &positions,
            normals: Some(&normals),
            uvs: Some(&uvs),
            indices: Some(&indices),
        };
        for parallel in [false, true] {
            let options = Options {
                parallel,
                ..Options::default()
            };
            let diagnostics = generate(&input, &options).unwrap().diagnostics;
            assert_eq!(diagnostics.zero_normals.first, zero.map(|v| v as u32));
            assert_eq!(
                diagnostics.non_unit_normals.first,
                non_unit.map(|(v, _)| v as u32)
            );
            assert!(diagnostics.non_finite_triangles.count > 0);
        }
    }

    /// The parallel index check names the same first bad corner as the serial one, wherever
    /// it lies among the chunks.
    #[test]
    fn the_first_out_of_range_index_is_reported_in_parallel_too() {
        let positions = [[0.0f32; 3]; 3];
        let normals = [[0.0f32, 0.0, 1.0]; 3];
        let uvs = [[0.0f32; 2]; 3];
        for bad in [[5usize, 200_000], [131_071, 131_072], [299_999, 299_998]] {
            let mut indices = vec![1u32; 300_000];
            indices[bad[0]] = 3;
            indices[bad[1]] = 7;
            let input = MeshInput {
                positions: &positions,
                normals: Some(&normals),
                uvs: Some(&uvs),
                indices: Some(&indices),
            };
            let first = bad[0].min(bad[1]);
            for parallel in [false, true] {
                let options = Options {
                    parallel,
                    ..Options::default()
                };
                let error = generate(&input, &options).map(|_| ()).unwrap_err();
                assert_eq!(
                    error,
                    CoreError::IndexOutOfRange {
                        corner: first,
                        index: indices[first],
                        vertex_count: 3,
                    }
                );
            }
        }
    }
}
