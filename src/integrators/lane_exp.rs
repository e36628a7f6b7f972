//! `e^x` and `e^x − 1` without branches or library calls, so that a loop over many
//! coordinates that calls them vectorises (SIN(R)'s thermostat flow and isokinetic kick make
//! one per degree of freedom and sub-step; with libm's `exp` those calls were most of its
//! per-step cost).
//!
//! **Method** (the textbook reduction, as in fdlibm): `x = k ln 2 + r` with `k` the nearest
//! integer to `x/ln 2` and `|r| ≤ ln 2/2`, `ln 2` split into a 33-bit head (so `k ln2_hi` is
//! exact) and a tail; `e^r − 1 = q(r)` by its Taylor series to `r¹³/13!` (the first term left
//! out, `r¹⁴/14! < 4.2e-18` relative, below half an ulp); `2^k` assembled from its bits.
//! Then `e^x = 2^k + 2^k q` and `e^x − 1 = (2^k − 1) + 2^k q` — for `k = 0` that is `q`
//! itself, so `e^x − 1` keeps its relative accuracy near 0. Errors are a few ulp (checked
//! against the library in the tests), not correctly rounded.
//!
//! **Range.** `x` is clamped to `[−708, 709]`, where `2^k` is a normal number: above, the
//! result is `e^709 ≈ 8e307` instead of overflowing; below, `e^{−708} ≈ 3e-308` instead of a
//! subnormal or 0 (for the thermostat, a factor that small is 0 in every sum it enters).
//! NaN stays NaN.
//!
//! **The same bits everywhere.** Only IEEE `+ − ×` and bit operations, no fused
//! multiply-add: a lane of any vector width computes what the scalar code computes.

const LOG2_E: f64 = std::f64::consts::LOG2_E;
/// `ln 2` to 33 bits (fdlibm's `ln2_hi`): `k · LN2_HI` is exact for `|k| < 2^20`.
const LN2_HI: f64 = f64::from_bits(0x3FE6_2E42_FEE0_0000);
/// `ln 2 − LN2_HI` (fdlibm's `ln2_lo`).
const LN2_LO: f64 = f64::from_bits(0x3DEA_39EF_3579_3C76);
/// `1.5 · 2^52`: adding it rounds to an integer held in the low mantissa bits.
const ROUNDER: f64 = 6_755_399_441_055_744.0;
const SMALLEST: f64 = -708.0;
const LARGEST: f64 = 709.0;

/// `(2^k, e^r − 1)` with `x = k ln 2 + r`, `|r| ≤ ln 2/2`.
#[inline(always)]
fn reduce(x: f64) -> (f64, f64) {
    // clamp, not max/min: a NaN passes through (max/min would replace it).
    let x = x.clamp(SMALLEST, LARGEST);
    let shifted = x * LOG2_E + ROUNDER;
    let k = shifted - ROUNDER;
    let r = (x - k * LN2_HI) - k * LN2_LO;
    // The low bits of `shifted` hold k (two's complement, |k| ≤ 1023 < 2^51).
    let k_bits = shifted.to_bits().wrapping_sub(ROUNDER.to_bits());
    let two_k = f64::from_bits(k_bits.wrapping_add(1023) << 52);
    (two_k, r * taylor_tail(r))
}

/// `(e^r − 1)/r = 1 + r/2 + r²/6 + … + r¹²/13!` by Horner's rule.
#[inline(always)]
fn taylor_tail(r: f64) -> f64 {
    const C: [f64; 13] = [
        1.0 / 6_227_020_800.0, // 1/13!
        1.0 / 479_001_600.0,
        1.0 / 39_916_800.0,
        1.0 / 3_628_800.0,
        1.0 / 362_880.0,
        1.0 / 40_320.0,
        1.0 / 5_040.0,
        1.0 / 720.0,
        1.0 / 120.0,
        1.0 / 24.0,
        1.0 / 6.0,
        1.0 / 2.0,
        1.0, // 1/1!
    ];
    let mut sum = C[0];
    for c in &C[1..] {
        sum = sum * r + c;
    }
    sum
}

/// `e^x`, branch-free (see the module doc for range and accuracy).
#[inline(always)]
pub fn exp(x: f64) -> f64 {
    let (two_k, q) = reduce(x);
    two_k + two_k * q
}

/// `e^x − 1`, branch-free, accurate relative to the result also near `x = 0`.
#[inline(always)]
pub fn exp_m1(x: f64) -> f64 {
    let (two_k, q) = reduce(x);
    (two_k - 1.0) + two_k * q
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Distance in units in the last place between two positive or two negative numbers.
    fn ulps(a: f64, b: f64) -> u64 {
        (a.to_bits() as i64 - b.to_bits() as i64).unsigned_abs()
    }

    fn samples() -> impl Iterator<Item = f64> {
        // Dense near 0 (where exp_m1 must keep relative accuracy), then out to the range ends.
        let small = (1..2000).map(|i| (i as f64 * 1e-3 - 1.0) * 1e-6);
        let moderate = (0..20_001).map(|i| -10.0 + i as f64 * 1e-3);
        let wide = (0..2001).map(|i| SMALLEST + i as f64 * (LARGEST - SMALLEST) / 2000.0);
        small.chain(moderate).chain(wide)
    }

    /// The error budget, in ulp of the result: the reduction's `r` is exact to ~1e-19
    /// relative to `x`, Horner on `|r| ≤ 0.35` damps each earlier rounding by `|r|` (its
    /// error in `q` stays below one ulp of `q`, and `|q| ≤ 0.42` is below half the result),
    /// then one multiply and one add of the reconstruction (½ ulp each): under 2 ulp in all,
    /// the library's error (< 1 ulp) on top. Measured on these samples: at most 1 (exp) and
    /// 2 (exp_m1).
    #[test]
    fn exp_is_within_two_ulp_of_the_library() {
        for x in samples() {
            assert!(
                ulps(exp(x), x.exp()) <= 2,
                "exp({x}) = {} vs {}",
                exp(x),
                x.exp()
            );
        }
    }

    #[test]
    fn exp_m1_is_within_two_ulp_of_the_library() {
        for x in samples() {
            let (ours, library) = (exp_m1(x), x.exp_m1());
            assert!(
                ulps(ours, library) <= 2,
                "exp_m1({x}) = {ours} vs {library}"
            );
        }
    }

    #[test]
    fn the_range_is_clamped_and_nan_propagates() {
        assert_eq!(exp(1e6), exp(LARGEST));
        assert!(exp(LARGEST).is_finite() && exp(LARGEST) > 8e307);
        assert_eq!(exp(-1e6), exp(SMALLEST));
        assert!(exp(SMALLEST) > 0.0 && exp(SMALLEST) < 4e-308);
        assert_eq!(exp_m1(-1e6), -1.0);
        assert_eq!(exp(0.0), 1.0);
        assert_eq!(exp_m1(0.0), 0.0);
        assert!(exp(f64::NAN).is_nan() && exp_m1(f64::NAN).is_nan());
    }
}
