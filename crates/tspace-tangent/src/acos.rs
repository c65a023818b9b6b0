//! The corner angle's arccosine, exactly as the reference rounds it, without calling libm.
//!
//! MikkTSpace weights each corner by `acos(cos)` computed in double precision and rounded to
//! float (`(x as f64).acos() as f32`). That call was an eighth of our running time and keeps the
//! loop around it from vectorizing. Here the arccosine is a polynomial in f64, accurate to about
//! 2e-14 relative, and its result is rounded to f32 only when the whole error interval around it
//! rounds to the same float (Ziv's rounding test); the rare remaining inputs (about one in a
//! million, and NaN) go to libm. Either way the f32 result is the correctly rounded value of the
//! f64 arccosine, the same bits the reference gets, which `exhaustive_over_every_f32` checks for
//! all 2^31 inputs in [-1, 1].

use std::f64::consts::{FRAC_PI_2, PI};

/// Least-squares fit of `(asin(√w) − √w) / w^1.5` on `w ∈ [0, 1/4]` (degree 9, max relative
/// error of the resulting arcsine 1.3e-14 on `[0, 1/2]`).
const ASIN_COEFFICIENTS: [f64; 10] = [
    0.16666666666661878,
    0.07500000003782922,
    0.04464285222417601,
    0.03038219162935859,
    0.022365882515612154,
    0.017443628149945288,
    0.013173365233711152,
    0.015733489741212338,
    -0.0030636532508882723,
    0.02801752120423027,
];

/// A bound on the relative error of the estimate ([`acos_from_asin`] of [`asin_small`]), with a
/// wide margin (the measured error is under 2e-14).
const RELATIVE_ERROR_BOUND: f64 = 1e-12;

/// `asin(z)` for `z ∈ [0, 1/2]`.
#[inline(always)]
fn asin_small(z: f64) -> f64 {
    let w = z * z;
    let mut p = ASIN_COEFFICIENTS[9];
    for &c in ASIN_COEFFICIENTS[..9].iter().rev() {
        p = p * w + c;
    }
    z + z * w * p
}

/// What [`asin_small`] is taken of for `acos(x)`: `|x|` near zero, `√((1 − |x|)/2)` towards ±1
/// (where `1 − |x|` is exact for `|x| ≥ 1/2`).
#[inline(always)]
fn asin_argument(x: f64) -> f64 {
    let a = x.abs();
    if a <= 0.5 {
        a
    } else {
        ((1.0 - a) * 0.5).sqrt()
    }
}

/// `acos(x)` from `p = asin_small(asin_argument(x))`: `π/2 ∓ p` near zero (acos(x) = π/2 −
/// asin(x)), `2p` or `π − 2p` towards ±1.
#[inline(always)]
fn acos_from_asin(x: f64, p: f64) -> f64 {
    if x.abs() <= 0.5 {
        FRAC_PI_2 - if x < 0.0 { -p } else { p }
    } else if x < 0.0 {
        PI - 2.0 * p
    } else {
        2.0 * p
    }
}

/// `acos(x)` for `x ∈ [-1, 1]`, within [`RELATIVE_ERROR_BOUND`].
#[cfg(test)]
fn acos_estimate(x: f64) -> f64 {
    acos_from_asin(x, asin_small(asin_argument(x)))
}

/// The f32 rounding of `estimate` when the whole interval of its error bound rounds to it, NaN
/// otherwise.
#[inline(always)]
fn round_if_certain(estimate: f64) -> f32 {
    let margin = estimate * RELATIVE_ERROR_BOUND;
    let low = (estimate - margin) as f32;
    let high = (estimate + margin) as f32;
    if low == high { low } else { f32::NAN }
}

/// The f32 rounding of `acos_estimate(x)` when it is certain, NaN otherwise.
#[cfg(test)]
fn acos_if_certain(x: f32) -> f32 {
    round_if_certain(acos_estimate(x as f64))
}

/// `(x as f64).acos() as f32`, bit for bit.
#[cfg(test)]
fn acos(x: f32) -> f32 {
    let fast = acos_if_certain(x);
    if fast.is_nan() {
        (x as f64).acos() as f32
    } else {
        fast
    }
}

/// How many values [`acos_slice`] takes through its steps at a time, in f64 on the stack.
const STEP: usize = 64;

/// `out[i] = acos(x[i])` for every `i`: a vectorizable estimate, then libm for the few uncertain
/// lanes. Always inlined, so that it is compiled with the target features of its caller (the
/// corner loop of the MikkTSpace triangle pass).
///
/// The estimate is three loops, not one: in one loop the compiler copied the polynomial into
/// both arms of the choice between `|x|` and the square root (the result's formula depends on
/// the same choice), so that the vectorized loop evaluated it twice in every lane, a sixth of
/// the triangle pass. Loops are not merged, so the polynomial runs once per value.
#[inline(always)]
pub(crate) fn acos_slice(x: &[f32], out: &mut [f32]) {
    let mut asin = [0.0f64; STEP];
    for (x, out) in x.chunks(STEP).zip(out.chunks_mut(STEP)) {
        let asin = &mut asin[..x.len().min(out.len())];
        for (z, &x) in asin.iter_mut().zip(x) {
            *z = asin_argument(x as f64);
        }
        for p in asin.iter_mut() {
            *p = asin_small(*p);
        }
        for ((o, &x), &p) in out.iter_mut().zip(x).zip(asin.iter()) {
            *o = round_if_certain(acos_from_asin(x as f64, p));
        }
    }
    // Nearly always none: found in one vector pass (a fold, where `any` would stop early and
    // stay scalar) before a scalar one looks for them.
    if !out
        .iter()
        .fold(false, |uncertain, o| uncertain | o.is_nan())
    {
        return;
    }
    for (o, &x) in out.iter_mut().zip(x) {
        if o.is_nan() {
            *o = (x as f64).acos() as f32;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn reference(x: f32) -> f32 {
        (x as f64).acos() as f32
    }

    #[test]
    fn matches_libm_on_special_and_sampled_inputs() {
        let special = [
            -1.0f32,
            1.0,
            0.0,
            -0.0,
            0.5,
            -0.5,
            f32::from_bits(0.5f32.to_bits() + 1),
            f32::from_bits(0.5f32.to_bits() - 1),
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            f32::from_bits(1),
            f32::from_bits(1.0f32.to_bits() - 1),
            -f32::from_bits(1.0f32.to_bits() - 1),
        ];
        for x in special {
            assert_eq!(acos(x).to_bits(), reference(x).to_bits(), "acos({x:e})");
        }
        // Every 4099th float in [-1, 1]: about a million inputs spread over all exponents.
        let mut inputs = Vec::new();
        for bits in (0..=1.0f32.to_bits()).step_by(4099) {
            let x = f32::from_bits(bits);
            inputs.extend([x, -x]);
        }
        let mut out = vec![0.0; inputs.len()];
        acos_slice(&inputs, &mut out);
        for (&x, &o) in inputs.iter().zip(&out) {
            assert_eq!(o.to_bits(), reference(x).to_bits(), "acos({x:e})");
            assert_eq!(acos(x).to_bits(), o.to_bits(), "acos({x:e})");
        }
    }

    #[test]
    fn nan_stays_nan() {
        assert!(acos(f32::NAN).is_nan());
        let mut out = [0.0];
        acos_slice(&[f32::NAN], &mut out);
        assert!(out[0].is_nan());
    }

    /// Every float in [-1, 1]. About a minute in release mode:
    /// `cargo test --release --lib -- --ignored exhaustive_over_every_f32`.
    #[test]
    #[ignore]
    fn exhaustive_over_every_f32() {
        let top = 1.0f32.to_bits();
        let mut inputs = vec![0.0f32; 1 << 16];
        let mut out = vec![0.0f32; 1 << 16];
        let mut uncertain = 0u64;
        for sign in [0u32, 0x8000_0000] {
            let mut start = 0u32;
            while start <= top {
                let end = (start as u64 + (1 << 16)).min(top as u64 + 1) as u32;
                let n = (end - start) as usize;
                for (i, x) in inputs[..n].iter_mut().enumerate() {
                    *x = f32::from_bits((start + i as u32) | sign);
                }
                acos_slice(&inputs[..n], &mut out[..n]);
                for (&x, &o) in inputs[..n].iter().zip(&out[..n]) {
                    assert_eq!(o.to_bits(), reference(x).to_bits(), "acos({x:e})");
                    uncertain += acos_if_certain(x).is_nan() as u64;
                }
                start = end;
            }
        }
        eprintln!("uncertain inputs sent to libm: {uncertain}");
    }
}
