//! Pendulum potential `V = k(1 − cos x)` on one coordinate `x` (axis `axis`) of each
//! listed particle: the pendulum of CFM25 with `k = g/ℓ` and unit mass. An external
//! field: non-bonded, slow by default.
//!
//! `∂V/∂x = k sin x`, `∂²V/∂x² = k cos x`; the Hessian is diagonal.

use super::{ForceTerm, TermClass};

#[derive(Clone, Debug)]
pub struct Pendulum {
    dim: usize,
    /// `(particle, axis, k)`.
    coordinates: Vec<(usize, usize, f64)>,
}

impl Pendulum {
    pub fn new(dim: usize, coordinates: Vec<(usize, usize, f64)>) -> Self {
        Pendulum { dim, coordinates }
    }

    fn index(&self, particle: usize, axis: usize) -> usize {
        particle * self.dim + axis
    }
}

impl ForceTerm for Pendulum {
    fn kind(&self) -> &'static str {
        "pendulum"
    }

    fn class(&self) -> TermClass {
        TermClass::Nonbonded
    }

    fn energy(&self, q: &[f64]) -> f64 {
        self.coordinates
            .iter()
            .map(|&(i, axis, k)| k * (1.0 - q[self.index(i, axis)].cos()))
            .sum()
    }

    fn add_gradient(&self, q: &[f64], gradient: &mut [f64]) {
        for &(i, axis, k) in &self.coordinates {
            let index = self.index(i, axis);
            gradient[index] += k * q[index].sin();
        }
    }

    fn add_hessian_vector(&self, q: &[f64], v: &[f64], out: &mut [f64]) {
        for &(i, axis, k) in &self.coordinates {
            let index = self.index(i, axis);
            out[index] += k * q[index].cos() * v[index];
        }
    }

    fn couplings(&self) -> Vec<Vec<usize>> {
        self.coordinates.iter().map(|&(i, _, _)| vec![i]).collect()
    }

    fn interaction_count(&self) -> usize {
        self.coordinates.len()
    }
}
