//! The minimum image in an orthorhombic box, written once: [`minimum_image`] (`d − L
//! round(d/L)`, by division) for every scalar path, [`minimum_image_baseline`] (the same
//! bits with the rounding written out, for scalar loops compiled for the x86-64 baseline),
//! [`PeriodicBox::wrap`] (the same with a branch that skips the rounding for the near
//! differences of bonded terms), and [`MinimumImage`] (by a multiplication with `1/L`, the
//! distance split's inner loops).
//! The division forms and [`MinimumImage`] round `d/L` and `d·(1/L)` and so may pick
//! different images of a difference within an ulp of `L/2` (equally near, both minimum);
//! each path keeps its form, so every output keeps its bits.

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
#[inline(always)]
pub fn minimum_image_baseline(d: f64, length: f64) -> f64 {
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
}
