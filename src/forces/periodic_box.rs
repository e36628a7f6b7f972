//! The minimum image in an orthorhombic box, written once: [`minimum_image`] (`d − L
//! round(d/L)`, by division) for every scalar path, [`minimum_image_baseline`] (the same
//! bits with the rounding written out, for scalar loops compiled for the x86-64 baseline),
//! [`PeriodicBox::wrap`] (the same with a branch that skips the rounding for the near
//! differences of bonded terms), [`near_image`] (`wrap` in SIMD lanes, by compare and
//! select, for bonded differences `|d| ≤ L`: SETTLE's lanes) and [`MinimumImage`] (by a
//! multiplication with `1/L`, the distance split's inner loops).
//! The division forms and [`MinimumImage`] round `d/L` and `d·(1/L)` and so may pick
//! different images of a difference within an ulp of `L/2` (equally near, both minimum);
//! each path keeps its form, so every output keeps its bits.

use super::simd::{Real, Simd};

/// The minimum image `d − L round(d/L)` of a difference `d` along a box edge `L`: the
/// image in `[−L/2, L/2]`. One division and one rounding.
#[inline(always)]
pub fn minimum_image(d: f64, length: f64) -> f64 {
    d - length * (d / length).round()
}

/// [`minimum_image`] with its rounding written out ([`nearest`]): the same bits, without
/// the libm call that `round` is in code compiled for the x86-64 baseline. For scalar loops
/// there (the Ewald exclusions); a loop that vectorises keeps [`minimum_image`] (the
/// integer casts of [`nearest`] do not vectorise without AVX-512).
///
/// A difference within a quarter box (every bonded or excluded pair's) skips the division:
/// there `|d/L| ≤ ¼(1 + 2⁻⁵²) < ½` rounds to `±0`, and `d − L·(±0)` is `d`, or `+0` for
/// `d = −0`, which is `d + 0`. So the same bits with one compare in place of a division
/// (tested against the division form).
#[inline(always)]
pub fn minimum_image_baseline(d: f64, length: f64) -> f64 {
    if d.abs() <= 0.25 * length {
        return d + 0.0;
    }
    d - length * nearest(d / length)
}

/// `x.round()` (the nearest integer, halves away from zero) without the libm call that
/// `round` is on the x86-64 baseline: `x ± (½ − 2⁻⁵⁴)` truncated by a cast to an integer and
/// given `x`'s sign (`round(−0.3) = −0`), as LLVM lowers `round` where the processor has a
/// truncating instruction. The added constant is the largest double below ½, so `x + c`
/// reaches the next integer only when `x` is at least halfway to it (for `|x| < 2⁵²`);
/// larger magnitudes, infinities and NaN go to `round` (they are integers or not numbers
/// already). The same bits as `round` for every `x` (tested).
#[inline(always)]
fn nearest(x: f64) -> f64 {
    const BELOW_HALF: f64 = 0.499_999_999_999_999_94;
    if x.abs() < 4_503_599_627_370_496.0 {
        (((x + BELOW_HALF.copysign(x)) as i64) as f64).copysign(x)
    } else {
        x.round()
    }
}

/// [`PeriodicBox::wrap`] in SIMD lanes, branch-free: `d − L` where `d ≥ L/2`, `d + L`
/// where `d ≤ −L/2`, `d` elsewhere (lengths `length`, one per lane). For `|d| ≤ L` (the
/// difference of two coordinates inside the box, or of two atoms less than `L/2` apart
/// however far they are from it) these are [`minimum_image`]'s and `wrap`'s bits: `d/L`
/// then lies in `[1/2, 1]` or `[−1, −1/2]` (division is monotone), which round to `±1`,
/// and `L · (±1)` is exact. Beyond `|d| > L` it is not the minimum image (one period is
/// taken off at most): for bonded terms only. Two comparisons, two selects and a
/// subtraction; no division, no rounding, no library call.
#[inline(always)]
pub fn near_image<S: Simd>(s: S, d: S::V, length: S::V) -> S::V {
    let half = s.mul(length, s.splat(S::R::of(0.5)));
    let minus_half = s.mul(length, s.splat(S::R::of(-0.5)));
    let zero = s.splat(S::R::of(0.0));
    let minus_length = s.sub(zero, length);
    let below = s.select(s.less_equal(d, minus_half), minus_length, zero);
    s.sub(d, s.select(s.less_equal(half, d), length, below))
}

/// An orthorhombic periodic box; pair terms use the minimum-image displacement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PeriodicBox {
    pub lengths: [f64; 3],
}

impl PeriodicBox {
    /// Minimum-image displacement along axis `axis` for a raw difference `d`
    /// ([`minimum_image`]).
    #[inline]
    pub fn wrap(&self, axis: usize, d: f64) -> f64 {
        let length = self.lengths[axis];
        // Bonded neighbours are nearly always within half a box: no division or rounding
        // (a library call on baseline x86-64) for them.
        if d.abs() < 0.5 * length {
            return d;
        }
        minimum_image(d, length)
    }
}

/// The minimum image in a box periodic along some axes: `d − L round(d·(1/L))` per axis,
/// `L = 0` along an open axis (`d − 0·round(d·0) = d`): a multiplication where
/// [`minimum_image`] divides, for the distance split's loops.
#[derive(Clone, Copy, Debug)]
pub(crate) struct MinimumImage {
    pub period: [f64; 3],
    pub inverse: [f64; 3],
}

impl MinimumImage {
    pub fn new(lengths: Option<[f64; 3]>) -> Self {
        let period = lengths.unwrap_or([0.0; 3]);
        let inverse = period.map(|l| if l > 0.0 { 1.0 / l } else { 0.0 });
        MinimumImage { period, inverse }
    }

    /// Minimum image of a displacement `d`.
    #[inline(always)]
    pub fn of(&self, d: [f64; 3]) -> [f64; 3] {
        std::array::from_fn(|k| d[k] - self.period[k] * (d[k] * self.inverse[k]).round())
    }

    /// `x` moved into `[0, L)` along a periodic `axis` (unchanged along an open one).
    #[inline(always)]
    pub fn wrapped(&self, axis: usize, x: f64) -> f64 {
        let (period, inverse) = (self.period[axis], self.inverse[axis]);
        if period > 0.0 {
            x - period * (x * inverse).floor()
        } else {
            x
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::forces::simd::{Isa, Portable};

    /// [`nearest`] is `round` on halves, their neighbours, integers, signed zeros and the
    /// edges of its fast range.
    #[test]
    fn nearest_is_round() {
        let mut xs = vec![0.0, -0.0, 1e300, -1e300, f64::INFINITY, f64::NEG_INFINITY];
        for k in -8..=8 {
            for base in [k as f64, k as f64 + 0.5, 4_503_599_627_370_496.0 + k as f64] {
                for x in [base, base.next_up(), base.next_down()] {
                    xs.extend([x, -x]);
                }
            }
        }
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        for _ in 0..10_000 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            xs.push(((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 6.0);
        }
        for x in xs {
            assert_eq!(nearest(x).to_bits(), x.round().to_bits(), "{x:e}");
        }
        assert!(nearest(f64::NAN).is_nan());
    }

    /// `minimum_image_baseline` (with its quarter-box shortcut) is `minimum_image` bit for
    /// bit: signed zeros, the quarter and half edges and an ulp either side, beyond a box,
    /// and a pseudo-random spread over three boxes.
    #[test]
    fn minimum_image_baseline_is_minimum_image() {
        for length in [10.0, 31.17, 62.5e-3] {
            let mut ds = vec![0.0, -0.0, f64::INFINITY, 1e300];
            for edge in [0.25, 0.5, 1.0, 1.5] {
                let x: f64 = edge * length;
                ds.extend([x, x.next_up(), x.next_down()]);
            }
            let mut state = 0x9e37_79b9_7f4a_7c15_u64;
            for _ in 0..10_000 {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                ds.push(((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 3.0 * length);
            }
            for d in ds.clone().into_iter().chain(ds.into_iter().map(|d| -d)) {
                let (fast, division) =
                    (minimum_image_baseline(d, length), minimum_image(d, length));
                assert!(
                    fast.to_bits() == division.to_bits() || fast.is_nan() && division.is_nan(),
                    "d {d:e} L {length}: {fast:e} against {division:e}"
                );
            }
        }
    }

    /// `near_image` gives `wrap`'s bits for every `|d| ≤ L`: the edges `±L/2`, `±L`, an ulp
    /// either side of them, zeros of both signs and a grid across `[−L, L]`, in each lane.
    #[test]
    fn near_image_is_wrap_bit_for_bit_within_a_box_length() {
        assert!(Isa::available().contains(&Isa::Portable));
        let s = Portable::<f64>::new();
        for length in [10.0, 31.17, 62.5e-3] {
            let pbc = PeriodicBox {
                lengths: [length; 3],
            };
            let below = |x: f64| f64::from_bits(x.to_bits() - 1);
            let half = 0.5 * length;
            let mut ds = vec![0.0, -0.0, half, -half, below(half), -below(half), length];
            ds.extend([
                -length,
                below(length),
                -below(length),
                half + half * f64::EPSILON,
            ]);
            ds.extend((0..=2000).map(|k| length * (k as f64 / 1000.0 - 1.0)));
            for chunk in ds.chunks(4) {
                let mut d = [0.0; 4];
                d[..chunk.len()].copy_from_slice(chunk);
                let lanes = near_image(s, d, [length; 4]);
                for (x, image) in d.iter().zip(lanes) {
                    assert_eq!(
                        image.to_bits(),
                        pbc.wrap(0, *x).to_bits(),
                        "d {x} L {length}"
                    );
                }
            }
        }
    }
}
