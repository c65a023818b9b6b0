//! What every result of the tangent core must satisfy, whatever the input: checked by the
//! property tests (`tests/properties.rs`, which add oracles of their own on top) and by the
//! `core` fuzz target on arbitrary bytes.
//!
//! The checks return `Err` with a message rather than panicking, so that proptest can shrink
//! a failure (`.map_err(TestCaseError::fail)`) and a fuzz target can panic on it.
//!
//! "Its normal", for a corner: the input normal of its vertex, normalized, when finite and not
//! zero; otherwise the face normal of its triangle, `(b - a) × (c - a)` in f64 from the f32
//! positions, when finite and not zero; otherwise +Z. With generated normals, the generated
//! normal of its output vertex, which itself must be finite and unit.

use glam::DVec3;
use tspace_tangent::diagnostics::SAMPLE_SIZE;
use tspace_tangent::{MeshInput, Options, Tally, Tangents};

pub const UNIT_TOLERANCE: f64 = 1e-5;
pub const ORTHOGONAL_TOLERANCE: f64 = 1e-4;
pub const PLUS_Z: [f64; 3] = [0.0, 0.0, 1.0];

/// `v` normalized in f64, unless it is not finite or zero.
pub fn unit64(v: [f32; 3]) -> Option<[f64; 3]> {
    if !v.iter().all(|x| x.is_finite()) || v.iter().all(|&x| x == 0.0) {
        return None;
    }
    let v = DVec3::from(v.map(f64::from));
    Some((v / v.length()).to_array())
}

/// The unit face normal `(b - a) × (c - a)` in f64, unless it is zero or not finite.
pub fn face_normal(p: [[f32; 3]; 3]) -> Option<[f64; 3]> {
    let [a, b, c] = p.map(|v| DVec3::from(v.map(f64::from)));
    let n = (b - a).cross(c - a);
    let len = n.length();
    (len > 0.0 && len.is_finite()).then(|| (n / len).to_array())
}

/// `assert!` that returns the message as an `Err` instead of panicking.
macro_rules! ensure {
    ($condition:expr, $($message:tt)+) => {
        // Bound first, so that a comparison with NaN fails the check.
        let holds: bool = $condition;
        if !holds {
            return Err(format!($($message)+));
        }
    };
}

/// `assert_eq!` that returns the message, with both values, as an `Err`.
macro_rules! ensure_eq {
    ($left:expr, $right:expr, $($message:tt)+) => {{
        let (left, right) = (&$left, &$right);
        if left != right {
            return Err(format!("{}: {left:?} != {right:?}", format!($($message)+)));
        }
    }};
}

/// Finite, unit, `w` = ±1, orthogonal to `normal`: the promise made of every emitted
/// tangent.
pub fn check_tangent(t: [f32; 4], normal: [f64; 3], what: &str) -> Result<(), String> {
    ensure!(
        t.iter().all(|x| x.is_finite()),
        "{what}: tangent {t:?} is not finite"
    );
    let v = DVec3::new(t[0].into(), t[1].into(), t[2].into());
    let len = v.length();
    ensure!(
        (len - 1.0).abs() <= UNIT_TOLERANCE,
        "{what}: tangent {t:?} has length {len}"
    );
    let d = v.dot(DVec3::from(normal));
    ensure!(
        d.abs() <= ORTHOGONAL_TOLERANCE,
        "{what}: tangent {t:?} has dot {d} with its normal {normal:?}"
    );
    ensure!(
        t[3] == 1.0 || t[3] == -1.0,
        "{what}: tangent {t:?} has w {}",
        t[3]
    );
    Ok(())
}

/// What holds of every successful call, with no oracle: shapes, every corner's tangent valid
/// against its normal and copying the right vertex, unused vertices valid against their own
/// normal, generated normals finite and unit.
pub fn check_core(input: &MeshInput<'_>, options: &Options, out: &Tangents) -> Result<(), String> {
    let vertex_count = input.positions.len();
    let corner_count = input.indices.map_or(vertex_count, <[u32]>::len);
    let vertex_of = |c: usize| input.indices.map_or(c, |i| i[c] as usize);
    let split = &out.split;
    let output_count = split.source_vertex.len();
    // The plan leaves the input's indices where they stand, and only there.
    ensure_eq!(
        split.indices.is_none(),
        out.normals.is_none() && output_count == vertex_count,
        "{options:?}: the plan's own indices"
    );
    let indices = split.indices_for(input.indices);
    ensure_eq!(indices.len(), corner_count, "{options:?}");
    ensure_eq!(split.vertex_tangents.len(), output_count, "{options:?}");
    ensure!(
        split
            .source_vertex
            .iter()
            .all(|&v| (v as usize) < vertex_count),
        "source vertex out of range"
    );
    ensure!(
        indices.iter().all(|&v| (v as usize) < output_count),
        "split index out of range"
    );
    match (input.normals, &out.normals) {
        (Some(_), None) => {
            ensure!(
                output_count >= vertex_count,
                "{output_count} output vertices for {vertex_count} input vertices"
            );
            ensure!(
                split.source_vertex[..vertex_count]
                    .iter()
                    .enumerate()
                    .all(|(i, &v)| v as usize == i),
                "the first {vertex_count} source vertices are not the identity"
            );
        }
        (None, Some(normals)) => {
            ensure_eq!(normals.len(), output_count, "generated normals");
            for (v, n) in normals.iter().enumerate() {
                let len = n.iter().map(|&x| f64::from(x).powi(2)).sum::<f64>().sqrt();
                ensure!(
                    n.iter().all(|x| x.is_finite()) && (len - 1.0).abs() <= UNIT_TOLERANCE,
                    "generated normal {n:?} of output vertex {v} is not finite and unit"
                );
            }
        }
        (given, returned) => {
            return Err(format!(
                "normals given: {}, normals returned: {}",
                given.is_some(),
                returned.is_some()
            ));
        }
    }
    let mut used = vec![false; output_count];
    for c in 0..corner_count {
        let o = indices[c] as usize;
        used[o] = true;
        let normal = match (&out.normals, input.normals) {
            (Some(generated), _) => unit64(generated[o]).unwrap_or(PLUS_Z),
            (None, Some(given)) => unit64(given[vertex_of(c)]).unwrap_or_else(|| {
                let base = c - c % 3;
                let tri = [base, base + 1, base + 2].map(|k| input.positions[vertex_of(k)]);
                face_normal(tri).unwrap_or(PLUS_Z)
            }),
            (None, None) => return Err("no normals given or returned".into()),
        };
        check_tangent(
            split.vertex_tangents[o],
            normal,
            &format!("corner {c} ({options:?})"),
        )?;
        ensure_eq!(
            split.source_vertex[o] as usize,
            vertex_of(c),
            "corner {c}: output vertex {o} copies the wrong input vertex"
        );
    }
    for (o, &is_used) in used.iter().enumerate() {
        if is_used {
            continue;
        }
        let Some(given) = input
            .normals
            .filter(|_| out.normals.is_none() && o < vertex_count)
        else {
            return Err(format!("output vertex {o} is not used by any corner"));
        };
        check_tangent(
            split.vertex_tangents[o],
            unit64(given[o]).unwrap_or(PLUS_Z),
            &format!("unused vertex {o} ({options:?})"),
        )?;
    }
    Ok(())
}

/// A tally's sample holds its first indices: as many as the count allows (up to
/// [`SAMPLE_SIZE`]), strictly ascending, each below `limit`; and the count is at most `limit`.
pub fn check_tally(tally: &Tally, limit: u64, name: &str) -> Result<(), String> {
    ensure_eq!(
        tally.first.len() as u64,
        tally.count.min(SAMPLE_SIZE as u64),
        "{name}: {tally:?}"
    );
    ensure!(
        tally.first.windows(2).all(|w| w[0] < w[1]),
        "{name}: not strictly ascending: {tally:?}"
    );
    ensure!(
        tally.first.iter().all(|&i| u64::from(i) < limit),
        "{name}: index out of range (limit {limit}): {tally:?}"
    );
    ensure!(
        tally.count <= limit,
        "{name}: count over {limit}: {tally:?}"
    );
    Ok(())
}
