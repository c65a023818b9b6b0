//! Property tests for the numerical invariants of the tangent core.
//!
//! Run with `cargo test --release --test properties`.
//!
//! What "its normal" means for a corner (the normal its tangent must be orthogonal to):
//! - normals given: the input normal of the corner's vertex, normalized, when it is finite and
//!   not zero; otherwise the face normal of the corner's triangle, `(b - a) × (c - a)` computed in
//!   f64 from the f32 positions, when that is finite and not zero; otherwise +Z (see
//!   `effective_normal` in crates/tspace-tangent/src/fallback.rs);
//! - normals generated: the generated normal of the corner's output vertex, which itself must be
//!   finite and unit.
//!
//! Vertices no triangle uses (only possible with normals given, since generated normals only
//! create used vertices) keep their place in the split and get a tangent from their own normal:
//! finite, unit, `w` = ±1, orthogonal to their normal normalized when that is finite and not zero,
//! otherwise to +Z.

use proptest::prelude::*;
use proptest::sample::Index;
use std::collections::HashMap;
use tspace_tangent::diagnostics::SAMPLE_SIZE;
use tspace_tangent::{
    CoreError, Diagnostics, Method, NormalMode, Options, Tally, Tangents, UvOrigin, Weighting,
    generate,
};
use tspace_testkit::invariants::{self, PLUS_Z, face_normal, unit64};
use tspace_testkit::random_mesh::{RandomMesh, any_mesh, full_indexed_mesh};

// ---------------------------------------------------------------------------------------------
// Reference computations (f64 unless the core's f32 rounding is part of the definition).

fn key4(t: &[f32; 4]) -> [u32; 4] {
    t.map(|x| if x == 0.0 { 0 } else { x.to_bits() })
}

fn key3(t: &[f32; 3]) -> [u32; 3] {
    t.map(|x| if x == 0.0 { 0 } else { x.to_bits() })
}

fn bits4(v: &[[f32; 4]]) -> Vec<[u32; 4]> {
    v.iter().map(|t| t.map(f32::to_bits)).collect()
}

fn bits3(v: &[[f32; 3]]) -> Vec<[u32; 3]> {
    v.iter().map(|t| t.map(f32::to_bits)).collect()
}

// ---------------------------------------------------------------------------------------------
// Checks.

/// The shared invariants (`tspace_testkit::invariants`), as proptest failures so they shrink.
fn check_tally(tally: &Tally, limit: u64, name: &str) -> Result<(), TestCaseError> {
    invariants::check_tally(tally, limit, name).map_err(TestCaseError::fail)
}

/// A generated normal is unit length, and a flat one is its own face's normal (+Z for a face
/// without a normal). A smooth normal is the weighted sum of a fan of faces joined edge by edge
/// across edges flatter than the crease, so a long fan can bend it further than the crease from
/// any one face: the crate's own tests check how fans form.
fn check_generated_normal(
    mesh: &RandomMesh,
    mode: NormalMode,
    c: usize,
    normal: [f32; 3],
) -> Result<(), TestCaseError> {
    let tri = mesh.triangle_of_corner(c).map(|v| mesh.positions[v]);
    let face = face_normal(tri).unwrap_or(PLUS_Z);
    let cos_crease = match mode {
        NormalMode::Flat => 1.0,
        NormalMode::SmoothByAngle { .. } => -1.0,
    };
    let Some(n) = unit64(normal) else {
        return Err(TestCaseError::fail(format!(
            "corner {c}: generated normal {normal:?}"
        )));
    };
    let d = n[0] * face[0] + n[1] * face[1] + n[2] * face[2];
    prop_assert!(
        cos_crease < 0.0 || d >= cos_crease - 1e-5,
        "corner {c}: generated normal {normal:?} is too far from its face normal {face:?} \
         ({mode:?}, dot {d})"
    );
    Ok(())
}

/// Everything that must hold of one successful call.
fn check_output(mesh: &RandomMesh, options: &Options, out: &Tangents) -> Result<(), TestCaseError> {
    let corner_count = mesh.corner_count();
    let split = &out.split;
    let output_count = split.source_vertex.len();

    // Shapes, every corner's tangent valid and copying the right input vertex, unused vertices
    // valid: the invariants the fuzz target checks too. That the per-corner values are
    // MikkTSpace's is the oracle tests' job.
    invariants::check_core(&mesh.input(), options, out).map_err(TestCaseError::fail)?;
    let indices = mesh.indices.as_deref();
    prop_assert_eq!(out.corner_tangents(indices).len(), corner_count);
    if let Some(normals) = &out.normals {
        for c in 0..corner_count {
            let o = split.vertex_of(c, indices);
            check_generated_normal(mesh, options.normal_mode, c, normals[o])?;
        }
    }

    // Split only where needed.
    let mut seen = HashMap::new();
    for o in 0..output_count {
        let normal = out.normals.as_ref().map(|n| key3(&n[o]));
        let key = (
            split.source_vertex[o],
            key4(&split.vertex_tangents[o]),
            normal,
        );
        if let Some(previous) = seen.insert(key, o) {
            prop_assert!(
                false,
                "output vertices {previous} and {o} copy input vertex {} with the same tangent \
                 {:?} (and normal)",
                split.source_vertex[o],
                split.vertex_tangents[o]
            );
        }
    }

    check_diagnostics(mesh, options, out)
}

fn check_diagnostics(
    mesh: &RandomMesh,
    options: &Options,
    out: &Tangents,
) -> Result<(), TestCaseError> {
    let d: &Diagnostics = &out.diagnostics;
    let corner_count = mesh.corner_count();
    let triangles = (corner_count / 3) as u64;
    let vertex_count = mesh.positions.len() as u64;
    let output_count = out.split.source_vertex.len() as u64;

    prop_assert_eq!(d.method, options.method);
    prop_assert_eq!(d.triangles, triangles);
    prop_assert_eq!(d.vertices_in, vertex_count);
    prop_assert_eq!(d.vertices_out, output_count);
    if mesh.normals.is_some() {
        prop_assert_eq!(d.vertices_added, output_count - vertex_count);
        prop_assert_eq!(d.generated_normals, None);
    } else {
        // With generated normals, unused input vertices disappear: the count cannot go negative.
        prop_assert_eq!(d.vertices_added, output_count.saturating_sub(vertex_count));
        prop_assert!(
            same_normal_mode(d.generated_normals, Some(options.normal_mode)),
            "generated_normals {:?}",
            d.generated_normals
        );
    }

    for (tally, name) in [
        (&d.duplicate_position_triangles, "duplicate_position"),
        (&d.zero_area_triangles, "zero_area"),
        (&d.zero_uv_area_triangles, "zero_uv_area"),
        (&d.mirrored_uv_triangles, "mirrored_uv"),
        (&d.non_finite_triangles, "non_finite"),
        (&d.mixed_handedness_triangles, "mixed_handedness"),
    ] {
        check_tally(tally, triangles, name)?;
    }
    // Vertex tallies refer to the vertices the tangent method saw, which are the first output
    // vertices.
    for (tally, name) in [
        (&d.zero_normals, "zero_normals"),
        (&d.non_unit_normals, "non_unit_normals"),
        (&d.handedness_flip_vertices, "handedness_flip"),
    ] {
        check_tally(tally, output_count, name)?;
    }
    let f = &d.fallback_tangents;
    check_tally(&f.corners, corner_count as u64, "fallback corners")?;
    prop_assert_eq!(
        f.corners.count,
        f.unassigned + f.zero_length + f.non_finite + f.not_orthogonal,
        "fallback reasons do not add up: {:?}",
        f
    );

    // The triangle classes are exclusive.
    prop_assert!(
        d.duplicate_position_triangles.count
            + d.zero_area_triangles.count
            + d.non_finite_triangles.count
            <= triangles
    );
    prop_assert!(
        d.zero_uv_area_triangles.count
            + d.mirrored_uv_triangles.count
            + d.non_finite_triangles.count
            <= triangles
    );
    if mesh.uvs.is_none() {
        prop_assert_eq!(d.zero_uv_area_triangles.count, 0);
        prop_assert_eq!(d.mirrored_uv_triangles.count, 0);
    }

    // Recounts of what is exactly defined.
    let mut non_finite = Vec::new();
    let mut duplicate = Vec::new();
    for t in 0..corner_count / 3 {
        let tri = mesh.triangle_of_corner(3 * t);
        let p = tri.map(|v| mesh.positions[v]);
        let finite3 = |v: &[f32; 3]| v.iter().all(|x| x.is_finite());
        let finite = p.iter().all(finite3)
            && mesh
                .normals
                .as_ref()
                .is_none_or(|n| tri.iter().all(|&v| finite3(&n[v])))
            && mesh
                .uvs
                .as_ref()
                .is_none_or(|uv| tri.iter().all(|&v| uv[v].iter().all(|x| x.is_finite())));
        if !finite {
            non_finite.push(t as u32);
        } else if p[0] == p[1] || p[1] == p[2] || p[2] == p[0] {
            duplicate.push(t as u32);
        }
    }
    check_recount(&d.non_finite_triangles, &non_finite, "non_finite_triangles")?;
    check_recount(
        &d.duplicate_position_triangles,
        &duplicate,
        "duplicate_position_triangles",
    )?;
    let indices = mesh.indices.as_deref();
    let mixed: Vec<u32> = out
        .corner_tangents(indices)
        .chunks_exact(3)
        .enumerate()
        .filter(|(_, c)| c[0][3] != c[1][3] || c[0][3] != c[2][3])
        .map(|(t, _)| t as u32)
        .collect();
    check_recount(
        &d.mixed_handedness_triangles,
        &mixed,
        "mixed_handedness_triangles",
    )?;
    // A vertex before the split is an input vertex (normals given) or an input vertex with one
    // generated normal; it flips handedness when its corners got both signs of w.
    let mut signs: HashMap<(u32, Option<[u32; 3]>), u8> = HashMap::new();
    for c in 0..corner_count {
        let o = out.split.vertex_of(c, indices);
        let normal = out.normals.as_ref().map(|n| key3(&n[o]));
        let w = out.corner_tangent(c, indices)[3];
        *signs
            .entry((out.split.source_vertex[o], normal))
            .or_default() |= if w > 0.0 { 1 } else { 2 };
    }
    let flips = signs.values().filter(|&&s| s == 3).count() as u64;
    prop_assert_eq!(d.handedness_flip_vertices.count, flips);
    if mesh.normals.is_some() {
        let mut flipped: Vec<u32> = signs
            .iter()
            .filter(|&(_, &s)| s == 3)
            .map(|(&(v, _), _)| v)
            .collect();
        flipped.sort_unstable();
        check_recount(
            &d.handedness_flip_vertices,
            &flipped,
            "handedness_flip_vertices",
        )?;
    }
    Ok(())
}

/// The normal tallies, recounted: zero normals are exactly zero; non-unit ones are more than 0.1%
/// off unit length (measured in f64, so that no length under- or overflows). Generated normals
/// are unit.
fn check_normal_counts(mesh: &RandomMesh, d: &Diagnostics) -> Result<(), TestCaseError> {
    let (mut zero, mut non_unit) = (Vec::new(), Vec::new());
    for (v, n) in mesh.normals.iter().flatten().enumerate() {
        if !n.iter().all(|x| x.is_finite()) {
            continue;
        }
        let len = n.iter().map(|&x| f64::from(x).powi(2)).sum::<f64>().sqrt();
        if len == 0.0 {
            zero.push(v as u32);
        } else if (len - 1.0).abs() > 1e-3 {
            non_unit.push(v as u32);
        }
    }
    check_recount(&d.zero_normals, &zero, "zero_normals")?;
    check_recount(&d.non_unit_normals, &non_unit, "non_unit_normals")
}

fn check_recount(tally: &Tally, expected: &[u32], name: &str) -> Result<(), TestCaseError> {
    prop_assert_eq!(tally.count, expected.len() as u64, "{} count", name);
    prop_assert_eq!(
        &tally.first[..],
        &expected[..expected.len().min(SAMPLE_SIZE)],
        "{} first",
        name
    );
    Ok(())
}

/// `Diagnostics` equality, with the crease angle compared bitwise (a NaN crease is legal input).
fn same_diagnostics(a: &Diagnostics, b: &Diagnostics) -> bool {
    same_normal_mode(a.generated_normals, b.generated_normals)
        && Diagnostics {
            generated_normals: None,
            ..a.clone()
        } == Diagnostics {
            generated_normals: None,
            ..b.clone()
        }
}

fn same_normal_mode(a: Option<NormalMode>, b: Option<NormalMode>) -> bool {
    let bits = |m: Option<NormalMode>| {
        m.map(|m| match m {
            NormalMode::Flat => None,
            NormalMode::SmoothByAngle { crease_degrees } => Some(crease_degrees.to_bits()),
        })
    };
    bits(a) == bits(b)
}

/// Bit-identical results for `mesh`.
fn check_identical(
    mesh: &RandomMesh,
    a: &Tangents,
    b: &Tangents,
    what: &str,
) -> Result<(), TestCaseError> {
    let indices = mesh.indices.as_deref();
    prop_assert_eq!(
        bits4(&a.corner_tangents(indices)),
        bits4(&b.corner_tangents(indices)),
        "{}: corner tangents differ",
        what
    );
    prop_assert_eq!(&a.split.source_vertex, &b.split.source_vertex, "{}", what);
    prop_assert_eq!(&a.split.indices, &b.split.indices, "{}", what);
    prop_assert_eq!(
        bits4(&a.split.vertex_tangents),
        bits4(&b.split.vertex_tangents),
        "{}: vertex tangents differ",
        what
    );
    prop_assert_eq!(
        a.normals.as_deref().map(bits3),
        b.normals.as_deref().map(bits3),
        "{}: normals differ",
        what
    );
    prop_assert!(
        same_diagnostics(&a.diagnostics, &b.diagnostics),
        "{what}: diagnostics differ: {:?} vs {:?}",
        a.diagnostics,
        b.diagnostics
    );
    Ok(())
}

/// The other UV origin only negates `w` of the UV methods (and changes which triangles count as
/// mirrored).
fn check_origin_swap(
    mesh: &RandomMesh,
    method: Method,
    a: &Tangents,
    b: &Tangents,
) -> Result<(), TestCaseError> {
    let indices = mesh.indices.as_deref();
    for (c, (ta, tb)) in a
        .corner_tangents(indices)
        .iter()
        .zip(&b.corner_tangents(indices))
        .enumerate()
    {
        let expected_w = if method == Method::Axis {
            ta[3]
        } else {
            -ta[3]
        };
        prop_assert!(
            ta[..3]
                .iter()
                .zip(&tb[..3])
                .all(|(x, y)| x.to_bits() == y.to_bits())
                && tb[3] == expected_w,
            "corner {c}: {ta:?} with one UV origin, {tb:?} with the other"
        );
    }
    prop_assert_eq!(&a.split.source_vertex, &b.split.source_vertex);
    prop_assert_eq!(&a.split.indices, &b.split.indices);
    let (da, db) = (&a.diagnostics, &b.diagnostics);
    prop_assert_eq!(&da.handedness_flip_vertices, &db.handedness_flip_vertices);
    prop_assert_eq!(
        &da.mixed_handedness_triangles,
        &db.mixed_handedness_triangles
    );
    prop_assert_eq!(&da.fallback_tangents, &db.fallback_tangents);
    prop_assert_eq!(&da.zero_uv_area_triangles, &db.zero_uv_area_triangles);
    prop_assert_eq!(&da.non_finite_triangles, &db.non_finite_triangles);
    Ok(())
}

/// The case count: `default`, times `PROPERTIES_SCALE` when that is set (for long runs:
/// `PROPERTIES_SCALE=100` runs every property 100 times longer). Note that `PROPTEST_CASES`
/// overrides every count, the large-mesh one included, with one number.
fn cases(default: u32) -> u32 {
    std::env::var("PROPERTIES_SCALE")
        .ok()
        .and_then(|v| v.parse::<f64>().ok())
        .map_or(default, |k| (f64::from(default) * k).clamp(1.0, 1e9) as u32)
}

// ---------------------------------------------------------------------------------------------
// Strategies for options.

fn method_config() -> impl Strategy<Value = (Method, Weighting)> {
    prop_oneof![
        3 => Just((Method::MikkTSpace, Weighting::Angle)),
        1 => Just((Method::Fast, Weighting::Angle)),
        1 => Just((Method::Fast, Weighting::Area)),
        1 => Just((Method::Axis, Weighting::Angle)),
    ]
}

fn normal_mode() -> impl Strategy<Value = NormalMode> {
    prop_oneof![
        2 => Just(NormalMode::Flat),
        2 => prop_oneof![Just(0.0f32), Just(30.0), Just(60.0), Just(180.0), 0.0f32..180.0]
            .prop_map(|crease_degrees| NormalMode::SmoothByAngle { crease_degrees }),
        1 => prop_oneof![Just(f32::NAN), Just(-45.0f32), Just(f32::INFINITY), Just(720.0)]
            .prop_map(|crease_degrees| NormalMode::SmoothByAngle { crease_degrees }),
    ]
}

fn options() -> impl Strategy<Value = Options> {
    (method_config(), normal_mode(), any::<bool>()).prop_map(
        |((method, weighting), normal_mode, top_left)| Options {
            method,
            weighting,
            normal_mode,
            uv_origin: if top_left {
                UvOrigin::TopLeft
            } else {
                UvOrigin::BottomLeft
            },
            parallel: false,
        },
    )
}

fn run(mesh: &RandomMesh, options: &Options) -> Result<Tangents, TestCaseError> {
    generate(&mesh.input(), options)
        .map_err(|e| TestCaseError::fail(format!("unexpected error {e:?} for {options:?}")))
}

/// One mesh, one option set: validity, split, diagnostics, determinism and the UV origin swap.
fn check_everything(mesh: &RandomMesh, options: Options) -> Result<(), TestCaseError> {
    let mut options = options;
    if mesh.uvs.is_none() && options.method != Method::Axis {
        let err = generate(&mesh.input(), &options).err();
        prop_assert_eq!(
            err,
            Some(CoreError::MissingUvs {
                method: options.method
            })
        );
        options.method = Method::Axis;
    }
    let sequential = run(mesh, &options)?;
    check_output(mesh, &options, &sequential)?;
    let parallel = run(
        mesh,
        &Options {
            parallel: true,
            ..options
        },
    )?;
    check_identical(mesh, &sequential, &parallel, "sequential vs parallel")?;
    let other_origin = Options {
        uv_origin: match options.uv_origin {
            UvOrigin::TopLeft => UvOrigin::BottomLeft,
            UvOrigin::BottomLeft => UvOrigin::TopLeft,
        },
        ..options
    };
    let swapped = run(mesh, &other_origin)?;
    check_output(mesh, &other_origin, &swapped)?;
    check_origin_swap(mesh, options.method, &sequential, &swapped)?;
    if options.method == Method::Axis && mesh.uvs.is_some() {
        // Axis tangents do not depend on texture coordinates at all.
        let without = RandomMesh {
            uvs: None,
            ..mesh.clone()
        };
        let bare = run(&without, &options)?;
        let indices = mesh.indices.as_deref();
        prop_assert_eq!(
            bits4(&bare.corner_tangents(indices)),
            bits4(&sequential.corner_tangents(indices))
        );
        prop_assert_eq!(&bare.split, &sequential.split);
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: cases(6000),
        max_shrink_iters: 20_000,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    /// Every tangent valid, the split exact and minimal, diagnostics consistent, parallel equal
    /// to sequential, the UV origin only flipping `w`.
    #[test]
    fn tangents_are_valid_and_split_exactly(mesh in any_mesh(), options in options()) {
        check_everything(&mesh, options)?;
    }
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: cases(1000),
        max_shrink_iters: 20_000,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    /// The normal tallies of the diagnostics count exactly what they describe. (Kept apart from
    /// the property above so that a miscount does not hide the other invariants.)
    #[test]
    fn normal_counts_are_exact(mesh in any_mesh(), options in options()) {
        let options = Options { method: Method::Axis, ..options };
        let out = run(&mesh, &options)?;
        check_normal_counts(&mesh, &out.diagnostics)?;
    }
}

// ---------------------------------------------------------------------------------------------
// Indexed and unindexed input describe the same surface: the UV methods weld by value, so the
// per-corner tangents must not depend on how the mesh was indexed (as in the reference, which
// welds corners by value). Only for finite meshes with normals: a vertex holding NaN equals
// nothing, so indexing legitimately changes what is shared there, and generated normals depend
// on the index buffer.

/// The mesh with every NaN or infinity replaced by 0.5.
fn make_finite(mut mesh: RandomMesh) -> RandomMesh {
    let fix = |x: &mut f32| {
        if !x.is_finite() {
            *x = 0.5;
        }
    };
    mesh.positions.iter_mut().flatten().for_each(fix);
    mesh.normals.iter_mut().flatten().flatten().for_each(fix);
    mesh.uvs.iter_mut().flatten().flatten().for_each(fix);
    mesh
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: cases(1500),
        max_shrink_iters: 20_000,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn indexing_does_not_change_tangents(
        mesh in full_indexed_mesh().prop_map(make_finite),
        options in options(),
    ) {
        let indexed = run(&mesh, &options)?;
        let unindexed_mesh = mesh.unindexed();
        let unindexed = run(&unindexed_mesh, &options)?;
        check_output(&unindexed_mesh, &options, &unindexed)?;
        let (indexed, unindexed) = (
            indexed.corner_tangents(mesh.indices.as_deref()),
            unindexed.corner_tangents(None),
        );
        for (c, (a, b)) in indexed.iter().zip(&unindexed).enumerate() {
            prop_assert_eq!(key4(a), key4(b), "corner {}: indexed {:?}, unindexed {:?}", c, a, b);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Errors, not panics.

#[derive(Clone, Debug)]
enum Corruption {
    IndexOutOfRange(Index, u32),
    IndexCount(usize),
    VertexCount(usize),
    NormalCount(bool),
    UvCount(bool),
}

fn corruption() -> impl Strategy<Value = Corruption> {
    prop_oneof![
        (
            any::<Index>(),
            prop_oneof![Just(0u32), Just(1), Just(1000), Just(u32::MAX)]
        )
            .prop_map(|(i, over)| Corruption::IndexOutOfRange(i, over)),
        (1usize..3).prop_map(Corruption::IndexCount),
        (1usize..3).prop_map(Corruption::VertexCount),
        any::<bool>().prop_map(Corruption::NormalCount),
        any::<bool>().prop_map(Corruption::UvCount),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: cases(3000),
        max_shrink_iters: 20_000,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    /// Input broken in exactly one way gives exactly the matching error.
    #[test]
    fn broken_input_is_an_error(
        mesh in any_mesh(),
        corruption in corruption(),
        options in options(),
        parallel in any::<bool>(),
    ) {
        let options = Options { parallel, ..options };
        let mut mesh = mesh;
        let vertex_count = mesh.positions.len();
        let expected = match corruption {
            Corruption::IndexOutOfRange(at, over) => {
                let Some(indices) = mesh.indices.as_mut() else { return Ok(()) };
                if indices.is_empty() {
                    return Ok(());
                }
                let corner = at.index(indices.len());
                let index = (vertex_count as u32).saturating_add(over);
                indices[corner] = index;
                let corner = indices.iter().position(|&i| i as usize >= vertex_count).unwrap();
                CoreError::IndexOutOfRange { corner, index: indices[corner], vertex_count }
            }
            Corruption::IndexCount(extra) => {
                let Some(indices) = mesh.indices.as_mut() else { return Ok(()) };
                indices.extend(std::iter::repeat_n(0, extra));
                CoreError::NotTriangles { count: indices.len() }
            }
            Corruption::VertexCount(extra) => {
                if mesh.indices.is_some() {
                    return Ok(());
                }
                mesh.positions.extend(std::iter::repeat_n([0.0; 3], extra));
                if let Some(n) = mesh.normals.as_mut() {
                    n.extend(std::iter::repeat_n([0.0, 0.0, 1.0], extra));
                }
                if let Some(t) = mesh.uvs.as_mut() {
                    t.extend(std::iter::repeat_n([0.0; 2], extra));
                }
                CoreError::NotTriangles { count: mesh.positions.len() }
            }
            Corruption::NormalCount(longer) => {
                let normals = mesh.normals.get_or_insert_with(|| vec![[0.0, 0.0, 1.0]; vertex_count]);
                if longer || normals.is_empty() {
                    normals.push([0.0, 0.0, 1.0]);
                } else {
                    normals.pop();
                }
                CoreError::AttributeLength {
                    attribute: "normals",
                    expected: vertex_count,
                    found: normals.len(),
                }
            }
            Corruption::UvCount(longer) => {
                let uvs = mesh.uvs.get_or_insert_with(|| vec![[0.0; 2]; vertex_count]);
                if longer || uvs.is_empty() {
                    uvs.push([0.0; 2]);
                } else {
                    uvs.pop();
                }
                CoreError::AttributeLength {
                    attribute: "uvs",
                    expected: vertex_count,
                    found: uvs.len(),
                }
            }
        };
        let result = generate(&mesh.input(), &options);
        prop_assert_eq!(result.err(), Some(expected));
    }

    /// Anything at all: arbitrary bit patterns, lengths and indices. Either a well-formed result
    /// or an error the input explains; never a panic.
    #[test]
    fn arbitrary_input_never_panics(
        positions in proptest::collection::vec(any::<[u32; 3]>(), 0..10),
        normals in proptest::option::of(proptest::collection::vec(any::<[u32; 3]>(), 0..10)),
        uvs in proptest::option::of(proptest::collection::vec(any::<[u32; 2]>(), 0..10)),
        indices in proptest::option::of(proptest::collection::vec(0u32..12, 0..16)),
        options in options(),
        parallel in any::<bool>(),
    ) {
        let options = Options { parallel, ..options };
        let mesh = RandomMesh {
            positions: positions.iter().map(|p| p.map(f32::from_bits)).collect(),
            normals: normals.map(|n| n.iter().map(|v| v.map(f32::from_bits)).collect()),
            uvs: uvs.map(|t| t.iter().map(|v| v.map(f32::from_bits)).collect()),
            indices,
        };
        let vertex_count = mesh.positions.len();
        let corner_count = mesh.corner_count();
        let bad_lengths = mesh.normals.as_ref().is_some_and(|n| n.len() != vertex_count)
            || mesh.uvs.as_ref().is_some_and(|t| t.len() != vertex_count)
            || !corner_count.is_multiple_of(3)
            || mesh.indices.iter().flatten().any(|&i| i as usize >= vertex_count);
        let missing_uvs = mesh.uvs.is_none() && options.method != Method::Axis;
        match generate(&mesh.input(), &options) {
            Ok(out) => {
                prop_assert!(!bad_lengths && !missing_uvs, "accepted broken input");
                check_output(&mesh, &options, &out)?;
            }
            Err(e) => {
                let explained = match e {
                    CoreError::MissingUvs { method } => method == options.method && missing_uvs,
                    CoreError::TooLarge { .. } => false,
                    _ => bad_lengths,
                };
                prop_assert!(explained, "unexplained error {e:?}");
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Large meshes, where the parallel paths really split the work (chunks of 4096 to 16384).

/// SplitMix64.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }

    fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }

    fn chance(&mut self, one_in: usize) -> bool {
        self.below(one_in) == 0
    }
}

fn large_mesh(seed: u64) -> RandomMesh {
    let mut rng = Rng(seed);
    let side = 90 + rng.below(40);
    let mut positions = Vec::with_capacity(side * side);
    let mut normals = Vec::with_capacity(side * side);
    let mut uvs = Vec::with_capacity(side * side);
    let mirrored = rng.chance(2);
    for j in 0..side {
        for i in 0..side {
            let (x, y) = (i as f32 * 0.1, j as f32 * 0.1);
            let z = (x * 1.3).sin() * (y * 0.7).cos();
            positions.push([x, y, z]);
            let n = [
                -(x * 1.3).cos() * 1.3 * (y * 0.7).cos(),
                (x * 1.3).sin() * 0.7 * (y * 0.7).sin(),
                1.0,
            ];
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            normals.push(n.map(|c| c / len));
            let u = i as f32 / (side - 1) as f32;
            let u = if mirrored { (2.0 * u - 1.0).abs() } else { u };
            uvs.push([u, j as f32 / (side - 1) as f32]);
        }
    }
    let mut indices = Vec::with_capacity(6 * side * side);
    for j in 0..side - 1 {
        for i in 0..side - 1 {
            let a = (j * side + i) as u32;
            let (b, c, d) = (a + 1, a + side as u32 + 1, a + side as u32);
            if rng.chance(2) {
                indices.extend([a, b, c, a, c, d]);
            } else {
                indices.extend([a, b, d, b, c, d]);
            }
        }
    }
    // Sprinkle damage.
    let n = positions.len();
    let specials = [f32::NAN, f32::INFINITY, 0.0, 1.0e-30, 1.0e20];
    for _ in 0..n / 50 {
        let v = rng.below(n);
        match rng.below(7) {
            0 => positions[v][rng.below(3)] = specials[rng.below(2)],
            1 => positions[v] = positions[rng.below(n)],
            2 => normals[v] = [0.0; 3].map(|_| specials[rng.below(specials.len())]),
            3 => normals[v] = normals[v].map(|c| c * 3.0),
            4 => uvs[v] = [rng.unit(), uvs[v][1]],
            5 => uvs[v] = uvs[rng.below(n)],
            _ => {
                let t = rng.below(indices.len() / 3);
                indices[3 * t + 1] = indices[3 * t];
            }
        }
    }
    for _ in 0..n / 100 {
        let (a, b, c) = (rng.below(n), rng.below(n), rng.below(n));
        indices.extend([a as u32, b as u32, c as u32]);
    }
    let mut mesh = RandomMesh {
        positions,
        normals: Some(normals),
        uvs: Some(uvs),
        indices: Some(indices),
    };
    match rng.below(5) {
        0 => mesh.normals = None,
        1 => {
            for p in &mut mesh.positions {
                *p = p.map(|x| x + 1.0e7);
            }
        }
        2 => mesh = mesh.unindexed(),
        _ => {}
    }
    mesh
}

/// Runs `generate` on a rayon pool of `threads` threads (the parallel paths size their chunks by
/// the pool).
fn run_on_pool(
    mesh: &RandomMesh,
    options: &Options,
    threads: usize,
) -> Result<Tangents, TestCaseError> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| TestCaseError::fail(format!("no thread pool: {e}")))?;
    pool.install(|| run(mesh, options))
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: cases(16),
        max_shrink_iters: 0,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn large_meshes_are_deterministic_and_valid(
        seed in any::<u64>(),
        smooth in any::<bool>(),
        threads in prop_oneof![Just(1usize), 3usize..9],
    ) {
        let mesh = large_mesh(seed);
        for (method, weighting) in [
            (Method::MikkTSpace, Weighting::Angle),
            (Method::Fast, Weighting::Angle),
            (Method::Fast, Weighting::Area),
            (Method::Axis, Weighting::Angle),
        ] {
            let options = Options {
                method,
                weighting,
                uv_origin: UvOrigin::TopLeft,
                normal_mode: if smooth {
                    NormalMode::SmoothByAngle { crease_degrees: 45.0 }
                } else {
                    NormalMode::Flat
                },
                parallel: false,
            };
            let sequential = run(&mesh, &options)?;
            check_output(&mesh, &options, &sequential)?;
            let parallel = Options { parallel: true, ..options };
            let what = format!("{method:?} {weighting:?}");
            check_identical(&mesh, &sequential, &run(&mesh, &parallel)?, &what)?;
            let on_pool = run_on_pool(&mesh, &parallel, threads)?;
            check_identical(&mesh, &sequential, &on_pool, &what)?;
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Plain tests.

fn all_options() -> Vec<Options> {
    let mut all = Vec::new();
    for (method, weighting) in [
        (Method::MikkTSpace, Weighting::Angle),
        (Method::Fast, Weighting::Angle),
        (Method::Fast, Weighting::Area),
        (Method::Axis, Weighting::Angle),
    ] {
        for uv_origin in [UvOrigin::TopLeft, UvOrigin::BottomLeft] {
            for parallel in [false, true] {
                all.push(Options {
                    method,
                    weighting,
                    uv_origin,
                    parallel,
                    ..Options::default()
                });
            }
        }
    }
    all
}

fn assert_valid(mesh: &RandomMesh, options: &Options) -> Tangents {
    let out = generate(&mesh.input(), options).expect("generate");
    if let Err(e) = check_output(mesh, options, &out) {
        panic!("{options:?}: {e}");
    }
    out
}

#[test]
fn mirrored_half_quad_flips_handedness() {
    // Two triangles sharing the diagonal 0–2; the second one's UVs wind the other way.
    let mesh = RandomMesh {
        positions: vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ],
        normals: Some(vec![[0.0, 0.0, 1.0]; 4]),
        uvs: Some(vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [2.0, 0.0]]),
        indices: Some(vec![0, 1, 2, 0, 2, 3]),
    };
    for options in all_options() {
        if options.method == Method::Axis {
            continue;
        }
        let out = assert_valid(&mesh, &options);
        let indices = mesh.indices.as_deref();
        let w = out
            .corner_tangents(indices)
            .iter()
            .map(|t| t[3])
            .collect::<Vec<_>>();
        assert!(w[0] == w[1] && w[1] == w[2], "{options:?}: {w:?}");
        assert!(w[3] == w[4] && w[4] == w[5], "{options:?}: {w:?}");
        assert_eq!(w[0], -w[3], "{options:?}: {w:?}");
        // Unmirrored with the OpenGL convention: tangent +X, bitangent +Y, right-handed.
        let expected_w = match options.uv_origin {
            UvOrigin::BottomLeft => 1.0,
            UvOrigin::TopLeft => -1.0,
        };
        assert_eq!(w[0], expected_w, "{options:?}");
        for t in &out.corner_tangents(indices)[..3] {
            assert!((t[0] - 1.0).abs() < 1e-6, "{options:?}: {t:?}");
        }
        let d = &out.diagnostics;
        assert_eq!(d.handedness_flip_vertices.count, 2, "{options:?}: {d:?}");
        assert_eq!(d.handedness_flip_vertices.first, vec![0, 2]);
        assert_eq!(d.mixed_handedness_triangles.count, 0);
        assert_eq!(d.mirrored_uv_triangles.count, 1);
        assert_eq!(d.vertices_added, 2);
        assert_eq!(out.split.source_vertex, vec![0, 1, 2, 3, 0, 2]);
        assert_eq!(d.fallback_tangents.corners.count, 0, "{options:?}: {d:?}");
    }
}

#[test]
fn all_degenerate_mesh_falls_back_everywhere() {
    // Repeated vertices and repeated positions only: no triangle has a frame.
    let mesh = RandomMesh {
        positions: vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [-0.0, 1.0, 0.0],
        ],
        normals: Some(vec![
            [0.0, 0.0, 1.0],
            [0.0, 0.0, 2.0],
            [0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [f32::NAN, 0.0, 1.0],
        ]),
        uvs: Some(vec![
            [0.0, 0.0],
            [1.0, 0.0],
            [0.0, 1.0],
            [0.5, 0.5],
            [1.0, 1.0],
        ]),
        indices: Some(vec![0, 0, 1, 1, 2, 3, 3, 4, 0, 2, 2, 2, 4, 1, 4]),
    };
    for with_normals in [true, false] {
        let mesh = RandomMesh {
            normals: if with_normals {
                mesh.normals.clone()
            } else {
                None
            },
            ..mesh.clone()
        };
        for options in all_options() {
            let out = assert_valid(&mesh, &options);
            let d = &out.diagnostics;
            assert_eq!(
                d.duplicate_position_triangles.count + d.non_finite_triangles.count,
                5,
                "{options:?}: {d:?}"
            );
            if options.method == Method::Axis {
                assert_eq!(d.fallback_tangents.corners.count, 0, "{options:?}: {d:?}");
            } else {
                assert_eq!(d.fallback_tangents.corners.count, 15, "{options:?}: {d:?}");
                assert_eq!(
                    d.fallback_tangents.corners.first,
                    (0..8).collect::<Vec<_>>()
                );
            }
        }
    }
}

#[test]
fn collinear_and_sliver_triangles_get_valid_tangents() {
    let mesh = RandomMesh {
        positions: vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [1.0, 1.0e-6, 0.0],
            [1.0e7, 1.0e7, 1.0e7],
            [1.0e7 + 1.0, 1.0e7, 1.0e7],
            [1.0e7 + 2.0, 1.0e7 + 1.0, 1.0e7],
        ],
        normals: Some(vec![[0.0, 0.0, 1.0]; 7]),
        uvs: Some(vec![
            [0.0, 0.0],
            [1.0, 0.0],
            [0.0, 1.0],
            [0.5, 0.5],
            [0.0, 0.0],
            [1.0, 0.0],
            [1.0, 1.0],
        ]),
        indices: Some(vec![0, 1, 2, 0, 2, 3, 4, 5, 6]),
    };
    for options in all_options() {
        let out = assert_valid(&mesh, &options);
        assert!(
            out.diagnostics.zero_area_triangles.count >= 1,
            "{options:?}"
        );
    }
}

#[test]
fn axis_needs_no_uvs_and_the_uv_methods_do() {
    let mesh = RandomMesh {
        positions: vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 1.0],
        ],
        normals: Some(vec![
            [0.0, 0.0, 1.0],
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 0.0],
            [0.0, 0.0, 0.0],
        ]),
        uvs: None,
        indices: Some(vec![0, 1, 2, 2, 1, 3]),
    };
    for with_normals in [true, false] {
        let mesh = RandomMesh {
            normals: if with_normals {
                mesh.normals.clone()
            } else {
                None
            },
            ..mesh.clone()
        };
        for options in all_options() {
            let result = generate(&mesh.input(), &options);
            if options.method == Method::Axis {
                let out = assert_valid(&mesh, &options);
                let indices = mesh.indices.as_deref();
                assert!(out.corner_tangents(indices).iter().all(|t| t[3] == 1.0));
                assert_eq!(out.diagnostics.fallback_tangents.corners.count, 0);
            } else {
                assert_eq!(
                    result.err(),
                    Some(CoreError::MissingUvs {
                        method: options.method
                    })
                );
            }
        }
    }
}

#[test]
fn empty_mesh_is_fine() {
    let mesh = RandomMesh {
        positions: vec![],
        normals: Some(vec![]),
        uvs: Some(vec![]),
        indices: None,
    };
    for options in all_options() {
        let out = assert_valid(&mesh, &options);
        assert!(out.corner_tangents(None).is_empty() && out.split.source_vertex.is_empty());
    }
    let unused_only = RandomMesh {
        positions: vec![[0.0; 3]; 4],
        normals: Some(vec![
            [0.0, 0.0, 1.0],
            [0.0; 3],
            [f32::NAN; 3],
            [3.0, 4.0, 0.0],
        ]),
        uvs: Some(vec![[0.0; 2]; 4]),
        indices: Some(vec![]),
    };
    for options in all_options() {
        let out = assert_valid(&unused_only, &options);
        assert_eq!(out.split.source_vertex, vec![0, 1, 2, 3]);
    }
}

// ---------------------------------------------------------------------------------------------
// Regressions: minimized failures of the properties above.

/// The normal an unused vertex's tangent must be orthogonal to: its own, normalized.
fn check_unused_vertex(normal: [f32; 3]) {
    let mesh = RandomMesh {
        positions: vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [5.0, 5.0, 5.0],
        ],
        normals: Some(vec![
            [0.0, 0.0, 1.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, 1.0],
            normal,
        ]),
        uvs: Some(vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.0, 0.0]]),
        indices: Some(vec![0, 1, 2]),
    };
    for options in all_options() {
        assert_valid(&mesh, &options);
    }
}

/// Bug: crates/tspace-tangent/src/split.rs gives vertices no triangle uses a tangent from their normal
/// normalized with an f32 `length`, which overflows for |n| above ~1e19: the normal becomes zero
/// and the tangent (1, 0, 0), parallel to a normal (1e20, 0, 0).
#[test]
fn regression_unused_vertex_with_huge_normal() {
    check_unused_vertex([1.0e20, 0.0, 0.0]);
    check_unused_vertex([0.0, -3.0e30, 0.0]);
}

/// Bug: same place; the f32 `length` underflows to 0 below ~1e-19, the normal is taken as +Z and
/// the tangent (0, 1, 0) has a dot of 0.577 with the normal (1, 1, 1) / sqrt(3).
#[test]
fn regression_unused_vertex_with_tiny_normal() {
    check_unused_vertex([1.0e-30, 1.0e-30, 1.0e-30]);
    check_unused_vertex([0.0, -1.0e-30, 0.0]);
}

/// Bug: crates/tspace-tangent/src/fallback.rs `unit` (used by `effective_normal`) treats a normal whose largest
/// component is subnormal as zero (`!largest.is_normal()`), although it is finite and not zero,
/// so the corner is made orthogonal to the face normal instead: here the tangent is (1, 0, 0)
/// while the normal points along +X.
#[test]
fn regression_subnormal_normal_is_a_normal() {
    let mesh = RandomMesh {
        positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        normals: Some(vec![[1.0e-39, 0.0, 0.0]; 3]),
        uvs: Some(vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]),
        indices: None,
    };
    for options in all_options() {
        assert_valid(&mesh, &options);
    }
}

/// Bug: crates/tspace-tangent/src/normals.rs `face_normal` normalizes with an f32 `length` whose square goes
/// subnormal for cross products below ~1e-19 (triangles with edges around 1e-10, or slivers at
/// 1e-7 scale), so generated flat normals are not unit (here about 1.006 long).
#[test]
fn regression_generated_normals_of_tiny_triangles_are_unit() {
    let tiny = RandomMesh {
        positions: vec![[0.0, 0.0, 0.0], [1.0e-11, 0.0, 0.0], [0.0, 1.3e-11, 0.0]],
        normals: None,
        uvs: Some(vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]),
        indices: None,
    };
    // Found by `tangents_are_valid_and_split_exactly` (a sliver of a mesh scaled by 1e-7).
    let sliver = RandomMesh {
        positions: vec![
            [2e-7, 0.0, 1.167_282_5e-8],
            [1e-7, 0.0, 0.0],
            [1.897_899_7e-7, 0.0, 1.048_102_7e-8],
        ],
        normals: None,
        uvs: Some(vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]),
        indices: None,
    };
    for mesh in [tiny, sliver] {
        for options in all_options() {
            for normal_mode in [
                NormalMode::Flat,
                NormalMode::SmoothByAngle {
                    crease_degrees: 60.0,
                },
            ] {
                assert_valid(
                    &mesh,
                    &Options {
                        normal_mode,
                        ..options
                    },
                );
            }
        }
    }
}

/// Bug: crates/tspace-tangent/src/diagnostics.rs `analyze` measures normals with an f32 `length`, whose square
/// underflows to 0 below ~1e-19: the normal (0, 0, 1e-30), which the core uses as a valid +Z
/// normal, is counted in `zero_normals` instead of `non_unit_normals`. Expected: zero_normals
/// {1}, non_unit_normals {0}; actual: zero_normals {0, 1}, non_unit_normals {}.
#[test]
fn regression_tiny_normals_are_non_unit_not_zero() {
    let mesh = RandomMesh {
        positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        normals: Some(vec![[0.0, 0.0, 1.0e-30], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
        uvs: Some(vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]),
        indices: None,
    };
    for options in all_options() {
        let out = assert_valid(&mesh, &options);
        let d = &out.diagnostics;
        assert_eq!(d.zero_normals.first, vec![1], "{options:?}");
        assert_eq!(d.non_unit_normals.first, vec![0], "{options:?}");
    }
}
