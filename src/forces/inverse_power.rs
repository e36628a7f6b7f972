//! Inverse-power pair potential `V = c (r + a)^{−n}` between two particles or a particle
//! and an anchor: the singular wall `1/(2q²)` of HL97's bond problem (3.5) (`c = 1/2`,
//! `n = 2`, `a = 0`), the softened Coulomb potential `−1/(0.1 + |x|)` of CFM25 5.7.2
//! (`c = −1`, `n = 1`, `a = 0.1`), or a bare Coulomb/gravity-like `c/r`. Non-bonded: slow by
//! default.
//!
//! With `r = √s`, `u = r + a`, `g(r) = −n c u^{−n−1}` (= dV/dr) and
//! `g′(r) = n(n+1) c u^{−n−2}`: `χ = c u^{−n}`, `χ′ = g/(2r)`, `χ″ = (g′r − g)/(4r³)`.

use super::PeriodicBox;
use super::pair::{Pair, PairPotential, PairTerm};
use super::{Site, TermClass};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InversePower {
    /// `c`; negative for an attraction.
    pub coefficient: f64,
    /// `n > 0`.
    pub power: f64,
    /// `a ≥ 0`, the softening length.
    pub softening: f64,
}

impl InversePower {
    /// `(g, g′)`: the first and second derivatives of `V` in `r`.
    #[inline(always)]
    fn radial(&self, r: f64) -> (f64, f64) {
        let u = r + self.softening;
        let u_n1 = u.powf(-self.power - 1.0);
        let g = -self.power * self.coefficient * u_n1;
        let g1 = self.power * (self.power + 1.0) * self.coefficient * u_n1 / u;
        (g, g1)
    }
}

impl PairPotential for InversePower {
    #[inline(always)]
    fn value(&self, s: f64) -> f64 {
        self.coefficient * (s.sqrt() + self.softening).powf(-self.power)
    }

    #[inline(always)]
    fn d1(&self, s: f64) -> f64 {
        let r = s.sqrt();
        self.radial(r).0 / (2.0 * r)
    }

    #[inline(always)]
    fn d1_d2(&self, s: f64) -> (f64, f64) {
        let r = s.sqrt();
        let (g, g1) = self.radial(r);
        (g / (2.0 * r), (g1 * r - g) / (4.0 * s * r))
    }
}

/// Inverse-power interactions over the given site pairs.
pub fn inverse_power_pairs(
    dim: usize,
    pairs: Vec<(Site, Site, InversePower)>,
    periodic_box: Option<PeriodicBox>,
) -> PairTerm<InversePower> {
    let pairs = pairs
        .into_iter()
        .map(|(a, b, potential)| Pair { a, b, potential })
        .collect();
    PairTerm::new(
        "inverse-power",
        TermClass::Nonbonded,
        dim,
        pairs,
        periodic_box,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// χ′ and χ″ against central differences of χ and χ′; the step 1e-5 gives a
    /// truncation error ~1e-10 relative and a round-off error ~1e-11, so 1e-7 is loose.
    #[test]
    fn derivatives_match_finite_differences() {
        for potential in [
            InversePower {
                coefficient: 0.5,
                power: 2.0,
                softening: 0.0,
            },
            InversePower {
                coefficient: -1.0,
                power: 1.0,
                softening: 0.1,
            },
        ] {
            for s in [0.3, 1.0, 2.5] {
                let step = 1e-5;
                let d1 = (potential.value(s + step) - potential.value(s - step)) / (2.0 * step);
                let d2 = (potential.d1(s + step) - potential.d1(s - step)) / (2.0 * step);
                let (a1, a2) = potential.d1_d2(s);
                assert!((a1 - d1).abs() <= 1e-7 * d1.abs(), "{a1} vs {d1}");
                assert!((a2 - d2).abs() <= 1e-7 * d2.abs(), "{a2} vs {d2}");
                assert_eq!(a1, potential.d1(s));
            }
        }
    }
}
