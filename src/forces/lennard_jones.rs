//! Lennard-Jones 12-6 pair `V = 4ε((σ/r)¹² − (σ/r)⁶)` with a cutoff `r_c`, energy-shifted
//! so that `V(r_c) = 0` when `shift` is set. Non-bonded: slow by default.
//!
//! With `x = σ²/s`: `χ = 4ε(x⁶ − x³)`, `χ′ = −12ε(2x⁶ − x³)/s`, `χ″ = 12ε(14x⁶ − 4x³)/s²`;
//! all three vanish beyond the cutoff. This is the plain all-pairs form: every pair of
//! the listed particles not excluded.

use super::PeriodicBox;
use super::pair::{Pair, PairPotential, PairTerm};
use super::{Site, TermClass};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LennardJones {
    pub epsilon: f64,
    pub sigma_squared: f64,
    pub cutoff_squared: f64,
    /// `χ(r_c²)`, subtracted from the energy when shifted (else 0).
    pub energy_shift: f64,
}

impl LennardJones {
    pub fn new(epsilon: f64, sigma: f64, cutoff: f64, shift: bool) -> Self {
        let mut lj = LennardJones {
            epsilon,
            sigma_squared: sigma * sigma,
            cutoff_squared: cutoff * cutoff,
            energy_shift: 0.0,
        };
        if shift && cutoff.is_finite() {
            lj.energy_shift = lj.unshifted(lj.cutoff_squared);
        }
        lj
    }

    #[inline(always)]
    fn unshifted(&self, s: f64) -> f64 {
        let x3 = (self.sigma_squared / s).powi(3);
        4.0 * self.epsilon * (x3 * x3 - x3)
    }
}

impl PairPotential for LennardJones {
    #[inline(always)]
    fn value(&self, s: f64) -> f64 {
        if s >= self.cutoff_squared {
            return 0.0;
        }
        self.unshifted(s) - self.energy_shift
    }

    #[inline(always)]
    fn d1(&self, s: f64) -> f64 {
        if s >= self.cutoff_squared {
            return 0.0;
        }
        let x3 = (self.sigma_squared / s).powi(3);
        -12.0 * self.epsilon * (2.0 * x3 * x3 - x3) / s
    }

    #[inline(always)]
    fn d1_d2(&self, s: f64) -> (f64, f64) {
        if s >= self.cutoff_squared {
            return (0.0, 0.0);
        }
        let x3 = (self.sigma_squared / s).powi(3);
        let x6 = x3 * x3;
        (
            -12.0 * self.epsilon * (2.0 * x6 - x3) / s,
            12.0 * self.epsilon * (14.0 * x6 - 4.0 * x3) / (s * s),
        )
    }
}

/// Lennard-Jones between every pair of `particles` except the `excluded` ones.
pub fn lennard_jones_pairs(
    dim: usize,
    particles: &[usize],
    excluded: &[(usize, usize)],
    potential: LennardJones,
    periodic_box: Option<PeriodicBox>,
) -> PairTerm<LennardJones> {
    let excluded: std::collections::HashSet<(usize, usize)> = excluded
        .iter()
        .map(|&(i, j)| (i.min(j), i.max(j)))
        .collect();
    let mut pairs = Vec::new();
    for (n, &i) in particles.iter().enumerate() {
        for &j in &particles[n + 1..] {
            if !excluded.contains(&(i.min(j), i.max(j))) {
                pairs.push(Pair {
                    a: Site::Particle(i),
                    b: Site::Particle(j),
                    potential,
                });
            }
        }
    }
    PairTerm::new(
        "lennard-jones",
        TermClass::Nonbonded,
        dim,
        pairs,
        periodic_box,
    )
}
