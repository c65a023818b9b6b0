//! Tangents in a quantized primitive's own precision (KHR_mesh_quantization).
//!
//! When a primitive's NORMAL is a normalized BYTE or SHORT accessor, its TANGENT is written as a
//! VEC4 of the same normalized type. These are the pure conversions: float tangents (MikkTSpace's
//! output) and morph-target tangent deltas in, little-endian accessor bytes out. No I/O, no JSON.
//!
//! Rounding each component to the nearest integer is not the best a tangent can get. The decoded
//! xyz of round-to-nearest can be up to √3/2 steps from the unit tangent, enough (for BYTE) to
//! leave it longer than the glTF-Validator accepts as unit, and among the eight ways to round
//! x, y and z down or up there is usually one closer in direction. [`quantize_tangents`] picks,
//! among those eight candidates (round-to-nearest is always one of them):
//!
//! 1. one whose decoded length is within one [`Snorm::step`] of 1 (less 1%, for readers that
//!    decode in `f32`), and never further than the glTF-Validator allows (see [`UNIT_LIMIT`]);
//! 2. of those, the one closest in angle to the float tangent;
//! 3. on a tie, the one most orthogonal to the primitive's decoded normal.
//!
//! Against round-to-nearest, over a million random pairs (normals quantized to the same type,
//! tangents orthogonal to them), this lowers the largest added angle from 0.387° to 0.354° for
//! BYTE (0.00149° to 0.00123° for SHORT), and the largest |cos| to the normal from 6.7e-3 to
//! 6.0e-3 (2.5e-5 to 2.1e-5). The price: the error it leaves lies more along the tangent, so
//! lengths are less often close to 1 (always within rule 1, though). To measure again:
//! `cargo test --release --lib scene::gltf::quantize -- --ignored --nocapture`.
//!
//! [`octahedral_tangents`] is the same choice among the values meshoptimizer's OCTAHEDRAL filter
//! decodes to, for compressed output of normals stored with that filter (gltfpack `-cc`): the
//! tangents then compress as well as their normals, at a coarser grid (0.73° at most for BYTE).

use glam::DVec3;
use rayon::prelude::*;
use std::cmp::Ordering;

/// How far from 1 a decoded tangent's length may be. The glTF-Validator reports
/// ACCESSOR_VECTOR3_NON_UNIT (an error) when `| |v| - 1 | > 0.00674`, which is less than one BYTE
/// step (1/127 ≈ 0.00787); this keeps a little under it so that a reader decoding in `f32` cannot
/// land on the other side. Some candidate always qualifies: for BYTE, every cell of the lattice that
/// the unit sphere crosses has a corner within 0.4931 steps (0.00388) of unit length (checked
/// exhaustively), and for SHORT round-to-nearest is within √3/2 steps (2.7e-5).
pub const UNIT_LIMIT: f64 = 0.0067;

/// The signed normalized component types a quantized TANGENT can take.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Snorm {
    /// BYTE (5120), normalized.
    I8,
    /// SHORT (5122), normalized.
    I16,
}

impl Snorm {
    /// The largest stored value, which decodes to 1.0: 127 or 32767.
    pub fn max(self) -> i32 {
        match self {
            Snorm::I8 => i8::MAX.into(),
            Snorm::I16 => i16::MAX.into(),
        }
    }

    /// A stored value as a reader decodes it, by glTF 2.0's rule for normalized integers (which
    /// KHR_mesh_quantization uses): `max(q / MAX, -1.0)`.
    pub fn decode(self, q: i32) -> f32 {
        (q as f32 / self.max() as f32).max(-1.0)
    }

    /// The distance between two neighbouring decoded values: `1 / MAX`.
    pub fn step(self) -> f32 {
        1.0 / self.max() as f32
    }

    /// Bytes from one morph-target delta to the next in [`quantize_deltas`]' output, which the
    /// caller must declare as the buffer view's `byteStride`: 4 for I8, 8 for I16.
    pub fn delta_stride(self) -> usize {
        4 * self.size()
    }

    /// Bytes per component.
    fn size(self) -> usize {
        match self {
            Snorm::I8 => 1,
            Snorm::I16 => 2,
        }
    }

    /// The largest `| |q| - 1 |` rule 1 accepts: one step less 1%, so that a reader decoding in
    /// `f32` (I16: ~1e-7 off) also sees it within a step, and capped by [`UNIT_LIMIT`] (only I8's
    /// step is over it). Round-to-nearest is within √3/2 ≈ 0.87 steps, so for I16 it always passes.
    fn unit_tolerance(self) -> f64 {
        (0.99 / f64::from(self.max())).min(UNIT_LIMIT)
    }

    /// `q` as the decoder sees it, in `f64` so that comparing candidates is not blurred by `f32`
    /// rounding (I16 candidates differ by about 1e-5 rad, near `f32`'s resolution).
    fn decode_xyz(self, q: [i32; 3]) -> DVec3 {
        let max = f64::from(self.max());
        DVec3::new(f64::from(q[0]), f64::from(q[1]), f64::from(q[2])) / max
    }

    /// Appends `q`, which callers keep within `[-MAX, MAX]`, little-endian.
    fn put(self, q: i32, out: &mut Vec<u8>) {
        match self {
            Snorm::I8 => out.push(q as i8 as u8),
            Snorm::I16 => out.extend_from_slice(&(q as i16).to_le_bytes()),
        }
    }
}

/// A quantized TANGENT accessor's data, and what quantizing cost.
#[derive(Clone, Debug, PartialEq)]
pub struct QuantizedTangents {
    /// Little-endian elements, 4 components each: 4 bytes per element for I8, 8 for I16
    /// (both multiples of 4, as glTF requires of vertex attributes, so no stride is needed).
    pub bytes: Vec<u8>,
    /// The largest angle, in degrees, between a tangent's xyz and its decoded quantized xyz; 180
    /// when some tangent had no direction to keep (non-finite or zero xyz). 0 for no tangents.
    pub max_added_degrees: f32,
}

/// Quantizes tangents to `ty`, choosing each one's rounding by the rules in the module docs.
///
/// `tangents`: unit xyz and `w` = ±1, as MikkTSpace writes them. `normals`: the primitive's normals
/// as decoded floats (what a viewer will see), one per tangent; a missing, zero or non-finite
/// normal only drops rule 3 for its tangent. `w` is written as exactly ±MAX (+MAX unless `w < 0`).
/// A tangent with no direction (non-finite or zero xyz) is written as the axis most orthogonal to
/// its normal (+X without one), and counts as 180° in `max_added_degrees`.
pub fn quantize_tangents(
    tangents: &[[f32; 4]],
    normals: &[[f32; 3]],
    ty: Snorm,
) -> QuantizedTangents {
    let chosen = per_tangent(tangents, normals, |tangent, normal, _| match tangent {
        Some(tangent) => choose(tangent, normal, ty),
        None => (axis_across(normal, ty), 180.0),
    });
    let mut bytes = Vec::with_capacity(tangents.len() * 4 * ty.size());
    let mut max_added = 0.0f64;
    for ((xyz, added), t) in chosen.into_iter().zip(tangents) {
        for q in [xyz[0], xyz[1], xyz[2], w_of(t, ty)] {
            ty.put(q, &mut bytes);
        }
        max_added = max_added.max(added);
    }
    QuantizedTangents {
        bytes,
        max_added_degrees: max_added as f32,
    }
}

/// [`quantize_tangents`] restricted to the values meshoptimizer's OCTAHEDRAL filter decodes to,
/// for compressed output whose normals the input already stored with that filter: the tangents
/// then take the normals' own representation, and compress as well as they do. Returns the
/// tangents (what a reader decodes) and the filter's stored values for them (x and y on the
/// octahedron, the encoding of 1.0, and `w`), in the same element layout.
///
/// Each tangent takes, of the nine octahedral codes around its own, the one whose decoded value
/// passes rule 1 and is closest in angle, then most orthogonal to the normal, as in
/// [`quantize_tangents`]; the octahedral grid is coarser than the type's (for BYTE, 0.73° at most
/// over a million random tangents, against 0.35°), which `max_added_degrees` reports. A tangent with no direction is
/// written as +Z (0, 0, MAX on the octahedron) and counts as 180°.
pub fn octahedral_tangents(
    tangents: &[[f32; 4]],
    normals: &[[f32; 3]],
    ty: Snorm,
) -> (QuantizedTangents, Vec<u8>) {
    let stride = 4 * ty.size();
    let chosen = per_tangent(tangents, normals, |tangent, normal, t| match tangent {
        Some(tangent) => choose_octahedral(tangent, normal, ty, w_of(t, ty)),
        None => ([0, 0], [0, 0, ty.max()], 180.0),
    });
    let mut bytes = Vec::with_capacity(tangents.len() * stride);
    let mut stored = Vec::with_capacity(tangents.len() * stride);
    let mut max_added = 0.0f64;
    for ((code, decoded, added), t) in chosen.into_iter().zip(tangents) {
        let w = w_of(t, ty);
        for q in [code[0], code[1], ty.max(), w] {
            ty.put(q, &mut stored);
        }
        for q in [decoded[0], decoded[1], decoded[2], w] {
            ty.put(q, &mut bytes);
        }
        max_added = max_added.max(added);
    }
    let tangents = QuantizedTangents {
        bytes,
        max_added_degrees: max_added as f32,
    };
    (tangents, stored)
}

/// The octahedral code of `tangent` (unit) and its eight neighbours, each decoded exactly as
/// meshoptimizer's decoder does (`tspace_meshopt::unfilter`); the best by [`Score::rank`].
fn choose_octahedral(
    tangent: DVec3,
    normal: Option<DVec3>,
    ty: Snorm,
    w: i32,
) -> ([i32; 2], [i32; 3], f64) {
    let max = ty.max();
    // The octahedral map: project onto |x| + |y| + |z| = 1, fold the lower half outwards.
    let n = tangent / tangent.abs().element_sum();
    let (x, y) = if n.z >= 0.0 {
        (n.x, n.y)
    } else {
        (
            (1.0 - n.y.abs()).copysign(n.x),
            (1.0 - n.x.abs()).copysign(n.y),
        )
    };
    let (x, y) = (x * f64::from(max), y * f64::from(max));
    let centre = [x.round() as i32, y.round() as i32];
    let mut best: Option<([i32; 2], [i32; 3], Score)> = None;
    let consider = |best: &mut Option<([i32; 2], [i32; 3], Score)>, code: [i32; 2]| {
        let code = [code[0].clamp(-max, max), code[1].clamp(-max, max)];
        let decoded = decode_octahedral(code, ty, w);
        let score = Score::of(ty.decode_xyz(decoded), tangent, normal, ty);
        if best
            .as_ref()
            .is_none_or(|(_, _, b)| score.rank(b) == Ordering::Less)
        {
            *best = Some((code, decoded, score));
        }
    };
    // The four codes around the tangent's own point (x and y rounded down or up) hold the
    // closest nearly always; should none of them decode within rule 1, the nine around the
    // rounded point, then the ring around those.
    for (fx, fy) in [(false, false), (false, true), (true, false), (true, true)] {
        let pick = |v: f64, up: bool| if up { v.ceil() } else { v.floor() } as i32;
        consider(&mut best, [pick(x, fx), pick(y, fy)]);
    }
    for radius in 1i32..=2 {
        if best.as_ref().is_some_and(|(_, _, b)| !b.off_unit) {
            break;
        }
        for dx in -radius..=radius {
            for dy in -radius..=radius {
                if dx.abs().max(dy.abs()) < radius && radius > 1 {
                    continue;
                }
                consider(&mut best, [centre[0] + dx, centre[1] + dy]);
            }
        }
    }
    best.map_or(([0, 0], [0, 0, max], 180.0), |(code, decoded, _)| {
        (
            code,
            decoded,
            angle(ty.decode_xyz(decoded), tangent).to_degrees(),
        )
    })
}

/// What meshoptimizer's OCTAHEDRAL filter decodes `code` to (the reference decoder's own
/// arithmetic, through tspace's copy of it).
fn decode_octahedral(code: [i32; 2], ty: Snorm, w: i32) -> [i32; 3] {
    // One element on the stack: 4 bytes for BYTE, 8 for SHORT.
    let mut element = [0u8; 8];
    let size = 4 * ty.size();
    for (i, q) in [code[0], code[1], ty.max(), w].into_iter().enumerate() {
        match ty {
            Snorm::I8 => element[i] = q as i8 as u8,
            Snorm::I16 => element[2 * i..2 * i + 2].copy_from_slice(&(q as i16).to_le_bytes()),
        }
    }
    let element = &mut element[..size];
    tspace_meshopt::unfilter(tspace_meshopt::Filter::Octahedral, size, element);
    let read = |i: usize| match ty {
        Snorm::I8 => i32::from(element[i] as i8),
        Snorm::I16 => i32::from(i16::from_le_bytes([element[2 * i], element[2 * i + 1]])),
    };
    [read(0), read(1), read(2)]
}

/// Quantizes morph-target TANGENT deltas (VEC3) to `ty`, each component rounded to nearest (so
/// within half a step), or `None` when some component is not finite or outside `[-1, 1]`: a
/// normalized type cannot hold it, and the caller keeps float deltas instead.
///
/// Each element is padded to 4 bytes with zeros (I8: 3 bytes + 1, I16: 6 bytes + 2), as glTF
/// requires of vertex attributes, so the caller must declare `byteStride` [`Snorm::delta_stride`]
/// (4 or 8) on the buffer view.
pub fn quantize_deltas(deltas: &[[f32; 3]], ty: Snorm) -> Option<Vec<u8>> {
    if !deltas
        .iter()
        .flatten()
        .all(|c| c.is_finite() && c.abs() <= 1.0)
    {
        return None;
    }
    let max = f64::from(ty.max());
    let mut bytes = Vec::with_capacity(deltas.len() * ty.delta_stride());
    for delta in deltas {
        for &c in delta {
            // |c| <= 1, so the rounded value is within [-MAX, MAX].
            ty.put((f64::from(c) * max).round() as i32, &mut bytes);
        }
        bytes.resize(bytes.len() + ty.size(), 0);
    }
    Some(bytes)
}

/// Tangents per parallel task: each takes a few hundred nanoseconds, so smaller primitives stay on
/// the calling thread.
const PARALLEL_CHUNK: usize = 2048;

/// `choose` for every tangent, given its direction (`None`: it has none) and its normal's, on the
/// rayon pool for large primitives; results in tangent order.
fn per_tangent<T: Send>(
    tangents: &[[f32; 4]],
    normals: &[[f32; 3]],
    choose: impl Fn(Option<DVec3>, Option<DVec3>, &[f32; 4]) -> T + Sync,
) -> Vec<T> {
    tangents
        .par_iter()
        .enumerate()
        .with_min_len(PARALLEL_CHUNK)
        .map(|(i, t)| {
            let normal = normals.get(i).and_then(|&n| direction(n));
            choose(direction([t[0], t[1], t[2]]), normal, t)
        })
        .collect()
}

/// `w` as exactly ±MAX: +MAX unless `w < 0`.
fn w_of(t: &[f32; 4], ty: Snorm) -> i32 {
    if t[3] < 0.0 { -ty.max() } else { ty.max() }
}

/// `v` scaled to unit length, or `None` when it has no direction (non-finite or zero). In `f64`
/// every finite non-zero `f32` vector normalizes, however small or large.
fn direction(v: [f32; 3]) -> Option<DVec3> {
    let v = DVec3::new(v[0].into(), v[1].into(), v[2].into());
    let length = v.length();
    (v.is_finite() && length > 0.0).then(|| v / length)
}

/// The best of the eight roundings of `tangent` (unit) and its angle to `tangent` in degrees.
fn choose(tangent: DVec3, normal: Option<DVec3>, ty: Snorm) -> ([i32; 3], f64) {
    corners(tangent, ty)
        .map(|q| (q, Score::of(ty.decode_xyz(q), tangent, normal, ty)))
        .min_by(|(_, a), (_, b)| a.rank(b))
        .map_or(
            // Never taken: `corners` always yields eight candidates.
            ([ty.max(), 0, 0], 180.0),
            |(q, _)| (q, angle(ty.decode_xyz(q), tangent).to_degrees()),
        )
}

/// The eight integer vectors around `tangent * MAX`: each component rounded down or up. Rounding
/// to nearest picks one of the two for every component, so it is among them.
fn corners(tangent: DVec3, ty: Snorm) -> impl Iterator<Item = [i32; 3]> {
    let max = f64::from(ty.max());
    let scaled = tangent * max;
    let (low, high) = (scaled.floor(), scaled.ceil());
    (0..8).map(move |bits: usize| {
        let pick = |axis: usize| {
            let v = if bits >> axis & 1 == 0 {
                low[axis]
            } else {
                high[axis]
            };
            // A unit tangent is within [-1, 1]; the clamp only absorbs an ulp over.
            v.clamp(-max, max) as i32
        };
        [pick(0), pick(1), pick(2)]
    })
}

/// What rules 1 to 3 look at, for one candidate.
#[derive(Clone, Copy)]
struct Score {
    /// Rule 1 fails: the decoded length is off unit by more than [`Snorm::unit_tolerance`].
    off_unit: bool,
    /// Rule 2: how far the candidate turns from the float tangent ([`turn`]: the angle's sine
    /// squared, which ranks alike).
    angle: f64,
    /// Rule 3: |cos| of the angle to the normal; 0 without a normal.
    skew: f64,
}

impl Score {
    fn of(decoded: DVec3, tangent: DVec3, normal: Option<DVec3>, ty: Snorm) -> Score {
        let length = decoded.length();
        Score {
            off_unit: (length - 1.0).abs() > ty.unit_tolerance(),
            angle: turn(decoded, tangent),
            skew: normal.map_or(0.0, |n| (decoded.dot(n) / length).abs()),
        }
    }

    /// Lexicographic: rule 1, then 2, then 3.
    ///
    /// Weighing skew against angle instead, `cost = angle² + λ·skew²`, was measured on a million
    /// random pairs and on the 95k real tangents of the corpus's glTF samples (normals quantized,
    /// tangents made orthogonal to them), both types. λ = 0.5 lowers the largest |cos| to the
    /// normal by 15–19% (random I8: 5.9e-3 → 4.7e-3), but raises the largest angle by up to 4.3%
    /// and the mean in-plane angle (the error left after projecting onto the surface) by 7–9%,
    /// and is further in angle than round-to-nearest on 3% of tangents; larger λ trades more
    /// (λ = 4: largest angle +39% for I8). Orthogonality is the smaller worry: for a normal-mapped
    /// normal θ away from N, turning T by δ within the surface turns it by δ·sin θ, while tilting
    /// T out of the surface by ε (skew = sin ε) moves it by at most ε·sin² θ, and by nothing in a
    /// viewer that re-orthogonalizes T against N. So angle comes first. Exact angle ties did not
    /// occur on those 1.1 million tangents: rule 3 keeps the choice well defined on symmetric
    /// inputs rather than changing typical results.
    fn rank(&self, other: &Score) -> Ordering {
        self.off_unit
            .cmp(&other.off_unit)
            .then(self.angle.total_cmp(&other.angle))
            .then(self.skew.total_cmp(&other.skew))
    }
}

/// A stand-in for the angle between `a` and unit `b` that ranks the same way and costs no
/// square root or arctangent (this runs eight or nine times per tangent): its sine squared,
/// |a × b|² / |a|². Candidates lie within a step or two of the tangent, far under 90°, where the
/// sine grows with the angle; the chosen one's angle proper is computed once.
fn turn(a: DVec3, b: DVec3) -> f64 {
    a.cross(b).length_squared() / a.length_squared()
}

/// The angle between `a` and `b` in radians. `atan2` of |a × b| and a · b, rather than `acos`,
/// stays accurate for the tiny angles I16 candidates differ by.
fn angle(a: DVec3, b: DVec3) -> f64 {
    a.cross(b).length().atan2(a.dot(b))
}

/// For a tangent with no direction: the positive axis least aligned with `normal` (exactly unit
/// when decoded, and a valid tangent as far as the precision allows), or +X without a normal.
fn axis_across(normal: Option<DVec3>, ty: Snorm) -> [i32; 3] {
    let axis = normal.map_or(0, |n| n.abs().min_position());
    let mut q = [0; 3];
    q[axis] = ty.max();
    q
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const TYPES: [Snorm; 2] = [Snorm::I8, Snorm::I16];

    /// The bound on the angle between a unit tangent and its chosen rounding, in degrees.
    ///
    /// Rounding to nearest moves each component of `t * MAX` by at most half a step, so it lands
    /// within √3/2 steps of the unit tangent, which seen from the origin is at most
    /// asin(√3/2 · step) away. The chosen candidate is at most as far in angle as round-to-nearest
    /// whenever round-to-nearest passes rule 1. It fails it only for I8, at 168 lattice points,
    /// which `t * MAX` rounds to only from within 0.027 (per component) of a cell's centre, so
    /// every corner is about √3/2 steps away, and the candidates left are those that are off
    /// mostly sideways; sampling t there gave at most 0.359°, under the bound's 0.391°. Measured
    /// over a million pairs: 0.354° (I8) and 0.00123° (I16), against 0.391° and 0.00151°.
    fn angle_bound(ty: Snorm) -> f64 {
        (3f64.sqrt() / 2.0 * f64::from(ty.step()))
            .asin()
            .to_degrees()
    }

    /// The bound on |cos| between a chosen rounding and the normal, when the float tangent is
    /// orthogonal to it: the chosen xyz is at most `angle_bound` away from a vector in the plane,
    /// so its cosine to the normal is at most sin(angle_bound) = √3/2 · step. The slack covers
    /// the float tangent's own `f32` rounding (its cosine to the normal is ~1e-8, not 0).
    fn skew_bound(ty: Snorm) -> f64 {
        3f64.sqrt() / 2.0 * f64::from(ty.step()) + 1e-7
    }

    /// Reads back `quantize_tangents`' output.
    fn stored(bytes: &[u8], ty: Snorm) -> Vec<[i32; 4]> {
        let values: Vec<i32> = match ty {
            Snorm::I8 => bytes.iter().map(|&b| i32::from(b as i8)).collect(),
            Snorm::I16 => bytes
                .chunks_exact(2)
                .map(|c| i32::from(i16::from_le_bytes([c[0], c[1]])))
                .collect(),
        };
        values
            .chunks_exact(4)
            .map(|c| [c[0], c[1], c[2], c[3]])
            .collect()
    }

    fn decoded(q: [i32; 4], ty: Snorm) -> DVec3 {
        DVec3::new(
            ty.decode(q[0]).into(),
            ty.decode(q[1]).into(),
            ty.decode(q[2]).into(),
        )
    }

    fn exact(q: [i32; 4], ty: Snorm) -> DVec3 {
        ty.decode_xyz([q[0], q[1], q[2]])
    }

    fn xyz(t: [f32; 4]) -> DVec3 {
        DVec3::new(t[0].into(), t[1].into(), t[2].into())
    }

    /// Plain round-to-nearest of each component, the naive way to quantize.
    fn nearest(t: [f32; 4], ty: Snorm) -> [i32; 4] {
        let m = ty.max() as f32;
        let r = |c: f32| (c * m).round() as i32;
        [
            r(t[0]),
            r(t[1]),
            r(t[2]),
            if t[3] < 0.0 { -ty.max() } else { ty.max() },
        ]
    }

    /// A normal as a quantized NORMAL accessor holds it, decoded; and a unit tangent orthogonal
    /// to it, from another direction `r`, as MikkTSpace would give in `f32`. `None` when `n` or
    /// `r` gives no direction.
    fn pair(n: [f32; 3], r: [f32; 3], w: f32, ty: Snorm) -> Option<([f32; 4], [f32; 3])> {
        let n = direction(n)?;
        let m = f64::from(ty.max());
        let nq = (n * m).round();
        let normal = [nq.x, nq.y, nq.z].map(|c| ty.decode(c as i32));
        let unit_normal = direction(normal)?;
        let t = unit_normal.cross(direction(r)?);
        if t.length() < 1e-3 {
            return None;
        }
        let t = t.normalize();
        Some(([t.x as f32, t.y as f32, t.z as f32, w], normal))
    }

    fn off_unit(v: DVec3) -> f64 {
        (v.length() - 1.0).abs()
    }

    fn skew(v: DVec3, normal: [f32; 3]) -> f64 {
        direction(normal).map_or(0.0, |n| (v.dot(n) / v.length()).abs())
    }

    fn any_direction() -> impl Strategy<Value = [f32; 3]> {
        prop::array::uniform3(-1.0f32..1.0)
    }

    proptest! {
        #[test]
        fn tangents_stay_unit_close_and_orthogonal(
            raw in proptest::collection::vec(
                (any_direction(), any_direction(), prop::sample::select(vec![1.0f32, -1.0])),
                1..48,
            ),
        ) {
            for ty in TYPES {
                let (tangents, normals): (Vec<_>, Vec<_>) =
                    raw.iter().filter_map(|&(n, r, w)| pair(n, r, w, ty)).unzip();
                let out = quantize_tangents(&tangents, &normals, ty);
                prop_assert_eq!(out.bytes.len(), 4 * ty.size() * tangents.len());
                let elements = stored(&out.bytes, ty);
                let mut largest = 0.0f64;
                for ((q, t), n) in elements.iter().zip(&tangents).zip(&normals) {
                    largest = largest.max(angle(exact(*q, ty), xyz(*t)).to_degrees());
                    let d = decoded(*q, ty);
                    prop_assert!(off_unit(d) <= f64::from(ty.step()), "{ty:?} {q:?} off unit by {}", off_unit(d));
                    prop_assert!(off_unit(d) <= UNIT_LIMIT, "{ty:?} {q:?} off unit by {}", off_unit(d));
                    let degrees = angle(d, xyz(*t)).to_degrees();
                    prop_assert!(degrees <= angle_bound(ty), "{ty:?} {t:?} -> {q:?}: {degrees}°");
                    prop_assert!(skew(d, *n) <= skew_bound(ty), "{ty:?} {t:?} -> {q:?}: cos {}", skew(d, *n));
                    prop_assert_eq!(ty.decode(q[3]), t[3]);
                }
                let reported = f64::from(out.max_added_degrees);
                prop_assert!((reported - largest).abs() <= 1e-6 * largest.max(1e-3), "{reported} vs {largest}");
            }
        }

        #[test]
        fn deltas_in_range_round_trip_within_half_a_step(
            deltas in proptest::collection::vec(prop::array::uniform3(-1.0f32..=1.0), 0..32),
        ) {
            for ty in TYPES {
                let bytes = quantize_deltas(&deltas, ty);
                prop_assert!(bytes.is_some());
                let bytes = bytes.unwrap_or_default();
                let stride = ty.delta_stride();
                prop_assert_eq!(bytes.len(), stride * deltas.len());
                for (element, delta) in bytes.chunks_exact(stride).zip(&deltas) {
                    // Read as a 4-component element, the padding is the fourth.
                    let q = stored(element, ty)[0];
                    prop_assert_eq!(q[3], 0);
                    for axis in 0..3 {
                        let back = f64::from(q[axis]) / f64::from(ty.max());
                        let error = (back - f64::from(delta[axis])).abs();
                        // The step in f64: `step()`'s f32 is 3e-11 short of 1/127, and a delta
                        // exactly between two codes (-0.5 as a byte: -63.5) is half a step off.
                        let half_step = 0.5 / f64::from(ty.max());
                        prop_assert!(error <= half_step + 1e-12, "{ty:?} {delta:?} -> {q:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn a_delta_halfway_between_two_codes_takes_one_of_them() {
        // -0.5 is -63.5 bytes: the property above found it, with a tolerance too tight by the
        // f32 step's rounding.
        let bytes = quantize_deltas(&[[-0.5, 0.5, 0.0]], Snorm::I8).unwrap();
        let q = stored(&bytes, Snorm::I8)[0];
        assert!(matches!(q[0], -64 | -63), "{q:?}");
        assert!(matches!(q[1], 63 | 64), "{q:?}");
    }

    #[test]
    fn deltas_a_normalized_type_cannot_hold_are_refused() {
        for ty in TYPES {
            for bad in [1.0001, -1.5, f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
                assert_eq!(
                    quantize_deltas(&[[0.0; 3], [0.5, bad, 0.0]], ty),
                    None,
                    "{bad}"
                );
            }
            assert_eq!(quantize_deltas(&[], ty), Some(vec![]));
        }
        assert_eq!(
            quantize_deltas(&[[1.0, -1.0, 0.0]], Snorm::I8),
            Some(vec![127, 0x81, 0, 0])
        );
        assert_eq!(
            quantize_deltas(&[[1.0, -1.0, 0.0]], Snorm::I16),
            Some(vec![0xff, 0x7f, 0x01, 0x80, 0, 0, 0, 0])
        );
    }

    #[test]
    fn snorm_decodes_as_gltf_says() {
        assert_eq!((Snorm::I8.max(), Snorm::I16.max()), (127, 32767));
        for ty in TYPES {
            assert_eq!(ty.decode(ty.max()), 1.0);
            assert_eq!(ty.decode(-ty.max()), -1.0);
            assert_eq!(ty.decode(-ty.max() - 1), -1.0);
            assert_eq!(ty.decode(0), 0.0);
            assert_eq!(ty.step(), 1.0 / ty.max() as f32);
        }
    }

    /// Round-to-nearest, the naive rule, against the chosen one on the same inputs: never worse
    /// on rule 1 and never further in angle when round-to-nearest passes rule 1; strictly better
    /// on length where round-to-nearest breaks the validator's limit (the BYTE tangent first), and
    /// more orthogonal to the normal on many inputs. Measured on the 20,000 pairs per type: more
    /// orthogonal on 4,649 (less on 1,933) for I8 and 5,737 (less 2,354) for I16, largest |cos|
    /// 6.37e-3 → 5.30e-3 and 2.47e-5 → 1.94e-5; closer to unit on none, since the candidate that
    /// is closer in angle than the nearest point is further along the tangent.
    #[test]
    fn chosen_rounding_beats_round_to_nearest() {
        // A BYTE tangent whose round-to-nearest is longer than the glTF-Validator accepts:
        // t * 127 = (77.501, 75.501, 66.501) rounds to (78, 76, 67), of length 1.006798 > 1.00674.
        let t = DVec3::new(77.5, 75.5, 66.5).normalize();
        let t = [t.x as f32, t.y as f32, t.z as f32, 1.0];
        let naive = nearest(t, Snorm::I8);
        assert_eq!(naive, [78, 76, 67, 127]);
        assert!(off_unit(decoded(naive, Snorm::I8)) > 0.00674);
        let chosen = stored(&quantize_tangents(&[t], &[], Snorm::I8).bytes, Snorm::I8)[0];
        // Length 1.002693, 0.358° from t; (78, 76, 67) was 0.025° off but the validator rejects it.
        assert_eq!(chosen, [78, 76, 66, 127]);
        assert!(off_unit(decoded(chosen, Snorm::I8)) < 0.0027);
        println!(
            "I8 {t:?}: nearest {naive:?} off unit {:.6}, {:.4}°; chosen {chosen:?} off unit {:.6}, {:.4}°",
            off_unit(decoded(naive, Snorm::I8)),
            angle(decoded(naive, Snorm::I8), xyz(t)).to_degrees(),
            off_unit(decoded(chosen, Snorm::I8)),
            angle(decoded(chosen, Snorm::I8), xyz(t)).to_degrees(),
        );

        for ty in TYPES {
            let mut rng = SplitMix(0x5eed);
            let (mut tried, mut better_skew, mut worse_skew, mut better_unit) = (0, 0, 0, 0);
            let (mut naive_skew, mut chosen_skew) = (0.0f64, 0.0f64);
            while tried < 20_000 {
                let Some((t, n)) = pair(rng.direction(), rng.direction(), 1.0, ty) else {
                    continue;
                };
                tried += 1;
                // Decoded in f64, as the rules compare them; I16 neighbours are near f32's resolution.
                let naive = exact(nearest(t, ty), ty);
                let chosen = exact(stored(&quantize_tangents(&[t], &[n], ty).bytes, ty)[0], ty);
                let naive_passes = off_unit(naive) <= ty.unit_tolerance();
                assert!(off_unit(chosen) <= ty.unit_tolerance(), "{ty:?} {t:?}");
                if naive_passes {
                    assert!(
                        angle(chosen, xyz(t)) <= angle(naive, xyz(t)),
                        "{ty:?} {t:?}"
                    );
                }
                better_skew += usize::from(skew(chosen, n) < skew(naive, n));
                worse_skew += usize::from(skew(chosen, n) > skew(naive, n));
                better_unit += usize::from(off_unit(chosen) < off_unit(naive));
                naive_skew = naive_skew.max(skew(naive, n));
                chosen_skew = chosen_skew.max(skew(chosen, n));
            }
            println!(
                "{ty:?}: of {tried}, more orthogonal {better_skew} (less {worse_skew}), closer to \
                 unit {better_unit}; \
                 largest |cos| to the normal {naive_skew:.3e} (nearest) -> {chosen_skew:.3e}"
            );
            assert!(better_skew > tried / 5, "{ty:?}");
            assert!(chosen_skew < naive_skew, "{ty:?}");
        }
    }

    #[test]
    fn rules_rank_in_order() {
        let score = |off_unit, angle, skew| Score {
            off_unit,
            angle,
            skew,
        };
        let ranked = |a: Score, b: Score| a.rank(&b) == Ordering::Less;
        assert!(ranked(score(false, 0.9, 0.9), score(true, 0.0, 0.0)));
        assert!(ranked(score(false, 0.1, 0.9), score(false, 0.2, 0.0)));
        assert!(ranked(score(false, 0.1, 0.1), score(false, 0.1, 0.2)));
    }

    #[test]
    fn degenerate_inputs_still_give_unit_tangents() {
        let tangents = [
            [f32::NAN, 0.0, 0.0, 1.0],
            [0.0, 0.0, 0.0, -1.0],
            [f32::INFINITY, 1.0, 0.0, f32::NAN],
            [1e-40, 0.0, 0.0, 1.0],
            [f32::MAX, f32::MAX, 0.0, -1.0],
            [0.0, 1.0, 0.0, 0.0],
        ];
        let normal_sets: [&[[f32; 3]]; 4] = [
            &[],
            &[[0.0, 0.0, 1.0]],
            &[[1.0, 0.0, 0.0], [0.0; 3], [f32::NAN; 3], [0.0, 0.0, 1.0]],
            &[[0.0, 1.0, 0.0]; 9],
        ];
        for ty in TYPES {
            for normals in normal_sets {
                let out = quantize_tangents(&tangents, normals, ty);
                assert_eq!(out.max_added_degrees, 180.0);
                let elements = stored(&out.bytes, ty);
                assert_eq!(elements.len(), tangents.len());
                for q in &elements {
                    assert!(off_unit(decoded(*q, ty)) <= ty.unit_tolerance(), "{q:?}");
                    assert_eq!(q[3].abs(), ty.max());
                }
                // The directionless one lies across its normal when it has one, else along +X.
                match normals.first() {
                    Some(&n) => assert_eq!(skew(decoded(elements[0], ty), n), 0.0),
                    None => assert_eq!(elements[0][..3], [ty.max(), 0, 0]),
                }
                // Tiny and huge but finite tangents keep their direction.
                assert_eq!(elements[3][..3], [ty.max(), 0, 0]);
                assert_eq!(elements[4][3], -ty.max());
                assert_eq!(elements[5], [0, ty.max(), 0, ty.max()]);
            }
            let empty = quantize_tangents(&[], &[[0.0, 1.0, 0.0]], ty);
            assert_eq!((empty.bytes.len(), empty.max_added_degrees), (0, 0.0));
        }
    }

    /// A small deterministic generator for the sweeps (proptest drives the property tests).
    struct SplitMix(u64);

    impl SplitMix {
        fn next(&mut self) -> u64 {
            self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let z = (self.0 ^ (self.0 >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            let z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            z ^ (z >> 31)
        }

        /// Uniform in [-1, 1).
        fn signed(&mut self) -> f32 {
            ((self.next() >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
        }

        /// A direction uniform on the sphere (rejection from the cube), not normalized.
        fn direction(&mut self) -> [f32; 3] {
            loop {
                let v = [self.signed(), self.signed(), self.signed()];
                let l = v.iter().map(|c| c * c).sum::<f32>();
                if l > 1e-4 && l <= 1.0 {
                    return v;
                }
            }
        }
    }

    /// The figures behind the choice of rule, against round-to-nearest over a million random
    /// pairs per type: `cargo test --release --lib scene::gltf::quantize -- --ignored --nocapture`.
    #[test]
    #[ignore = "a measurement, not a check; takes a few seconds"]
    fn measure_against_round_to_nearest() {
        for ty in TYPES {
            let mut rng = SplitMix(1);
            let (mut tangents, mut normals) = (Vec::new(), Vec::new());
            while tangents.len() < 1_000_000 {
                if let Some((t, n)) = pair(rng.direction(), rng.direction(), 1.0, ty) {
                    tangents.push(t);
                    normals.push(n);
                }
            }
            let out = quantize_tangents(&tangents, &normals, ty);
            let chosen = stored(&out.bytes, ty);
            for (name, rounding) in [
                (
                    "nearest",
                    tangents.iter().map(|&t| nearest(t, ty)).collect(),
                ),
                ("chosen", chosen),
            ] {
                let (mut degrees, mut cos, mut unit) = (0.0f64, 0.0f64, 0.0f64);
                let (mut sum_degrees, mut sum_cos) = (0.0, 0.0);
                for ((q, t), n) in rounding.iter().zip(&tangents).zip(&normals) {
                    let d = decoded(*q, ty);
                    let a = angle(d, xyz(*t)).to_degrees();
                    degrees = degrees.max(a);
                    cos = cos.max(skew(d, *n));
                    unit = unit.max(off_unit(d));
                    sum_degrees += a;
                    sum_cos += skew(d, *n);
                }
                let count = tangents.len() as f64;
                println!(
                    "{ty:?} {name:>8}: max angle {degrees:.4e}° (mean {:.4e}°), max |cos| to N \
                     {cos:.4e} (mean {:.4e}), max | |q| - 1 | {unit:.4e}",
                    sum_degrees / count,
                    sum_cos / count,
                );
            }
            println!(
                "{ty:?} reported max_added_degrees {:.4e}; bounds: angle {:.4e}°, |cos| {:.4e}",
                out.max_added_degrees,
                angle_bound(ty),
                skew_bound(ty)
            );
        }
    }

    proptest! {
        /// Octahedral tangents: what the filter decodes the stored values to is exactly the
        /// tangent written, unit within rule 1, w exactly ±1, and within the octahedral grid's
        /// own angle of the float tangent.
        #[test]
        fn octahedral_tangents_are_what_the_filter_decodes(
            pairs in proptest::collection::vec((unit(), any::<bool>()), 1..64),
        ) {
            for ty in TYPES {
                let tangents: Vec<[f32; 4]> = pairs
                    .iter()
                    .map(|(t, flip)| [t[0], t[1], t[2], if *flip { -1.0 } else { 1.0 }])
                    .collect();
                let (quantized, mut stored) = octahedral_tangents(&tangents, &[], ty);
                tspace_meshopt::unfilter(tspace_meshopt::Filter::Octahedral, 4 * ty.size(), &mut stored);
                prop_assert_eq!(&stored, &quantized.bytes);
                for (element, t) in quantized.bytes.chunks_exact(4 * ty.size()).zip(&tangents) {
                    let q = read_element(element, ty);
                    let decoded = ty.decode_xyz([q[0], q[1], q[2]]);
                    prop_assert!((decoded.length() - 1.0).abs() <= ty.unit_tolerance());
                    prop_assert_eq!(q[3], if t[3] < 0.0 { -ty.max() } else { ty.max() });
                    let exact = DVec3::new(t[0].into(), t[1].into(), t[2].into());
                    let degrees = angle(decoded, exact).to_degrees();
                    prop_assert!(degrees <= octahedral_bound(ty), "{:?}: {}", ty, degrees);
                }
            }
        }
    }

    /// The octahedral grid is coarser than the type's own (one code step on the octahedron's
    /// faces turns a vector by up to about 1.4 of the type's steps), and the decoder rounds its
    /// result to the type again; measured over a million random tangents
    /// (`measure_octahedral_angles`): 0.733° (BYTE) and 0.00284° (SHORT) at most.
    fn octahedral_bound(ty: Snorm) -> f64 {
        match ty {
            Snorm::I8 => 0.75,
            Snorm::I16 => 0.003,
        }
    }

    /// Random unit vectors (directions of a cube's points, normalized; the zero vector avoided).
    fn unit() -> impl Strategy<Value = [f32; 3]> {
        any_direction()
            .prop_filter("has a direction", |v| v.iter().any(|c| c.abs() > 1e-3))
            .prop_map(|v| {
                let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                [v[0] / l, v[1] / l, v[2] / l]
            })
    }

    fn read_element(element: &[u8], ty: Snorm) -> [i32; 4] {
        let at = |i: usize| match ty {
            Snorm::I8 => i32::from(element[i] as i8),
            Snorm::I16 => i32::from(i16::from_le_bytes([element[2 * i], element[2 * i + 1]])),
        };
        [at(0), at(1), at(2), at(3)]
    }

    /// The octahedral grid's largest angle over a million random tangents, for the bound above.
    #[test]
    #[ignore]
    fn measure_octahedral_angles() {
        use proptest::strategy::ValueTree;
        let mut runner = proptest::test_runner::TestRunner::deterministic();
        for ty in TYPES {
            let mut worst = 0f64;
            for _ in 0..1_000_000 {
                let t = unit().new_tree(&mut runner).unwrap().current();
                let (q, _) = octahedral_tangents(&[[t[0], t[1], t[2], 1.0]], &[], ty);
                worst = worst.max(f64::from(q.max_added_degrees));
            }
            println!("{ty:?}: largest angle {worst:.5} degrees");
        }
    }
}
