//! Newtonian gravity `V = −G m_a m_b / |r_b − r_a|` between every pair of the listed
//! particles, and optionally towards a fixed central mass (the Kepler problem of HL97 5.1
//! and CFM25). Non-bonded: slow by default.
//!
//! With `g = G m_a m_b`: `χ = −g s^{−1/2}`, `χ′ = (g/2) s^{−3/2}`, `χ″ = −(3g/4) s^{−5/2}`.

use super::pair::{Pair, PairPotential, PairTerm};
use super::{Site, TermClass};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Newton {
    /// `G m_a m_b`.
    pub strength: f64,
}

impl PairPotential for Newton {
    #[inline(always)]
    fn value(&self, s: f64) -> f64 {
        -self.strength / s.sqrt()
    }

    #[inline(always)]
    fn d1(&self, s: f64) -> f64 {
        0.5 * self.strength / (s * s.sqrt())
    }

    #[inline(always)]
    fn d1_d2(&self, s: f64) -> (f64, f64) {
        let r3 = s * s.sqrt();
        (0.5 * self.strength / r3, -0.75 * self.strength / (s * r3))
    }
}

/// A fixed attracting mass.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CentralMass {
    pub position: [f64; 3],
    pub mass: f64,
}

/// Gravity among `particles` (with their `masses`, indexed by particle) and towards an
/// optional fixed `center`.
pub fn gravity(
    dim: usize,
    gravitational_constant: f64,
    particles: &[usize],
    masses: &[f64],
    center: Option<CentralMass>,
) -> PairTerm<Newton> {
    let mut pairs = Vec::new();
    for (n, &i) in particles.iter().enumerate() {
        for &j in &particles[n + 1..] {
            pairs.push(Pair {
                a: Site::Particle(i),
                b: Site::Particle(j),
                potential: Newton {
                    strength: gravitational_constant * masses[i] * masses[j],
                },
            });
        }
        if let Some(center) = center {
            pairs.push(Pair {
                a: Site::Fixed(center.position),
                b: Site::Particle(i),
                potential: Newton {
                    strength: gravitational_constant * center.mass * masses[i],
                },
            });
        }
    }
    PairTerm::new("gravity", TermClass::Nonbonded, dim, pairs, None)
}
