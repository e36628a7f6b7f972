//! Harmonic spring `V = (k/2)(|r_b − r_a| − L)²` between two particles or a particle and
//! an anchor. Bonded: fast by default.
//!
//! In the squared length `s`: `χ = (k/2)(√s − L)²`, `χ′ = (k/2)(1 − L/√s)`,
//! `χ″ = kL/(4 s^{3/2})`. With `L = 0` the spring is `(k/2)s`, smooth everywhere
//! (the stiff springs of the FPU chain, MEMM18 3.2).

use super::PeriodicBox;
use super::pair::{Pair, PairPotential, PairTerm};
use super::{Site, TermClass};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HarmonicBond {
    pub stiffness: f64,
    pub rest_length: f64,
}

impl PairPotential for HarmonicBond {
    #[inline(always)]
    fn value(&self, s: f64) -> f64 {
        let stretch = s.sqrt() - self.rest_length;
        0.5 * self.stiffness * stretch * stretch
    }

    #[inline(always)]
    fn d1(&self, s: f64) -> f64 {
        if self.rest_length == 0.0 {
            0.5 * self.stiffness
        } else {
            0.5 * self.stiffness * (1.0 - self.rest_length / s.sqrt())
        }
    }

    #[inline(always)]
    fn d1_d2(&self, s: f64) -> (f64, f64) {
        if self.rest_length == 0.0 {
            (0.5 * self.stiffness, 0.0)
        } else {
            let r = s.sqrt();
            (
                0.5 * self.stiffness * (1.0 - self.rest_length / r),
                0.25 * self.stiffness * self.rest_length / (s * r),
            )
        }
    }

    /// A spring of zero rest length or zero stiffness has no rest distance to hold.
    fn rest_length(&self) -> Option<f64> {
        (self.rest_length > 0.0 && self.stiffness > 0.0).then_some(self.rest_length)
    }
}

/// Harmonic springs over the given site pairs.
pub fn harmonic_springs(
    dim: usize,
    springs: Vec<(Site, Site, HarmonicBond)>,
    periodic_box: Option<PeriodicBox>,
) -> PairTerm<HarmonicBond> {
    let pairs = springs
        .into_iter()
        .map(|(a, b, potential)| Pair { a, b, potential })
        .collect();
    PairTerm::new("spring", TermClass::Bonded, dim, pairs, periodic_box)
}
