//! A uniform external force field `V = −Σ_i f·q_i` on the listed particles: a constant
//! force (the opening example of GSS98 section 2, a charge in a uniform electric field).
//! Non-bonded: slow by default.
//!
//! `∇V = −f` on every listed particle; the Hessian is zero.

use super::{ForceTerm, TermClass};

#[derive(Clone, Debug)]
pub struct UniformField {
    dim: usize,
    particles: Vec<usize>,
    /// The force on each particle (first `dim` components used).
    force: [f64; 3],
}

impl UniformField {
    pub fn new(dim: usize, particles: Vec<usize>, force: [f64; 3]) -> Self {
        UniformField {
            dim,
            particles,
            force,
        }
    }
}

impl ForceTerm for UniformField {
    fn kind(&self) -> &'static str {
        "field"
    }

    fn class(&self) -> TermClass {
        TermClass::Nonbonded
    }

    fn energy(&self, q: &[f64]) -> f64 {
        self.particles
            .iter()
            .map(|&i| {
                (0..self.dim)
                    .map(|a| -self.force[a] * q[i * self.dim + a])
                    .sum::<f64>()
            })
            .sum()
    }

    fn add_gradient(&self, _q: &[f64], gradient: &mut [f64]) {
        for &i in &self.particles {
            for a in 0..self.dim {
                gradient[i * self.dim + a] -= self.force[a];
            }
        }
    }

    fn add_hessian_vector(&self, _q: &[f64], _v: &[f64], _out: &mut [f64]) {}

    fn couplings(&self) -> Vec<Vec<usize>> {
        self.particles.iter().map(|&i| vec![i]).collect()
    }

    fn interaction_count(&self) -> usize {
        self.particles.len()
    }
}
