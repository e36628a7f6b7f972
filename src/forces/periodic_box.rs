//! The minimum image in an orthorhombic box, written once: [`minimum_image`] (`d − L
//! round(d/L)`, by division) for every scalar path, [`PeriodicBox::wrap`] (the same with a
//! branch that skips the rounding for the near differences of bonded terms), and
//! [`MinimumImage`] (by a multiplication with `1/L`, the distance split's inner loops).
//! The two forms round `d/L` and `d·(1/L)` and so may pick different images of a
//! difference within an ulp of `L/2` (equally near, both minimum); each path keeps its
//! form, so every output keeps its bits.

/// The minimum image `d − L round(d/L)` of a difference `d` along a box edge `L`: the
/// image in `[−L/2, L/2]`. One division and one rounding.
#[inline(always)]
pub fn minimum_image(d: f64, length: f64) -> f64 {
    d - length * (d / length).round()
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
