//! FPU quartic spring `V = c(|r_b − r_a| − L)⁴`; with `L = 0` and `c = 1` it is the soft
//! spring `(q_{i+1} − q_i)⁴` of the Fermi–Pasta–Ulam chain (MEMM18 3.2). Bonded: fast by
//! default (the FPU scenes assign it explicitly).
//!
//! With `u = √s − L`: `χ = c u⁴`, `χ′ = 2c u³/√s`, `χ″ = 3c u²/s − c u³/s^{3/2}`;
//! for `L = 0`: `χ = c s²`, `χ′ = 2cs`, `χ″ = 2c`.

use super::PeriodicBox;
use super::pair::{Pair, PairPotential, PairTerm};
use super::{Site, TermClass};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QuarticBond {
    pub coefficient: f64,
    pub rest_length: f64,
}

impl PairPotential for QuarticBond {
    #[inline(always)]
    fn value(&self, s: f64) -> f64 {
        if self.rest_length == 0.0 {
            self.coefficient * s * s
        } else {
            let u = s.sqrt() - self.rest_length;
            self.coefficient * u * u * u * u
        }
    }

    #[inline(always)]
    fn d1(&self, s: f64) -> f64 {
        if self.rest_length == 0.0 {
            2.0 * self.coefficient * s
        } else {
            let r = s.sqrt();
            let u = r - self.rest_length;
            2.0 * self.coefficient * u * u * u / r
        }
    }

    #[inline(always)]
    fn d1_d2(&self, s: f64) -> (f64, f64) {
        let c = self.coefficient;
        if self.rest_length == 0.0 {
            (2.0 * c * s, 2.0 * c)
        } else {
            let r = s.sqrt();
            let u = r - self.rest_length;
            (
                2.0 * c * u * u * u / r,
                3.0 * c * u * u / s - c * u * u * u / (s * r),
            )
        }
    }
}

/// Quartic springs over the given site pairs.
pub fn quartic_springs(
    dim: usize,
    springs: Vec<(Site, Site, QuarticBond)>,
    periodic_box: Option<PeriodicBox>,
) -> PairTerm<QuarticBond> {
    let pairs = springs
        .into_iter()
        .map(|(a, b, potential)| Pair { a, b, potential })
        .collect();
    PairTerm::new(
        "quartic-spring",
        TermClass::Bonded,
        dim,
        pairs,
        periodic_box,
    )
}
