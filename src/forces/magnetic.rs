//! A static magnetic field acting on charged particles through its vector potential
//! `A(x)`: the non-separable Hamiltonian of CFM25 5.7,
//! `H = Σ |p_i − e_i A(x_i)|²/(2m_i) + V(x)`.
//!
//! This is the one velocity-dependent term of longstep, kept apart from the
//! potential-energy terms: it has no potential energy and no gradient
//! ([`ForceTerm::energy`] is 0), and only the structural schemes (CFM25 sections 3–4, the
//! one family whose physical equations take a general Hamiltonian) integrate it; every
//! other method is refused by the run. The state's momentum of a charged particle is its
//! **kinetic** momentum `π = m v = p − eA(x)` (so `energy.csv` shows the true
//! Hamiltonian), and the structural schemes convert to and from the canonical `p`.
//!
//! What the physical equations need (per particle, `J_ij = ∂_j A_i`):
//! `e A(x)` (the canonical shift), `e Jᵀ v` (the Lorentz force in `ṗ = −∂H/∂x`),
//! `e J v` (in `ẍ`), and `e w` with `w_j = Σ_ik ∂_k∂_j A_i v_k v_i` (in `p̈`), the last
//! from the Jacobian evaluated in dual numbers along `v`.

use super::dual::{Dual, Scalar};
use super::{ForceTerm, TermClass};

/// The vector potentials longstep knows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum VectorPotential {
    /// `A = (0, B x₁, 0)`: a uniform field `B` along the third axis (Landau gauge), the
    /// sanity-check benchmark of CFM25 5.7.2. Works in 2-D (drop the third component).
    Uniform { strength: f64 },
    /// `A = (r², r² x₂/x₁, −2 log(1 + r²))`, singular at `x₁ = 0`: CFM25 5.7.3. 3-D only.
    Cfm25Singular,
}

impl VectorPotential {
    pub fn value(&self, x: [f64; 3]) -> [f64; 3] {
        match *self {
            VectorPotential::Uniform { strength } => [0.0, strength * x[0], 0.0],
            VectorPotential::Cfm25Singular => {
                let r2 = x[0] * x[0] + x[1] * x[1] + x[2] * x[2];
                [r2, r2 * x[1] / x[0], -2.0 * (1.0 + r2).ln()]
            }
        }
    }

    /// `J[i][j] = ∂_j A_i`, in any [`Scalar`] (dual numbers give its derivative along a
    /// direction).
    pub fn jacobian<S: Scalar>(&self, x: [S; 3]) -> [[S; 3]; 3] {
        let zero = S::constant(0.0);
        match *self {
            VectorPotential::Uniform { strength } => [
                [zero, zero, zero],
                [S::constant(strength), zero, zero],
                [zero, zero, zero],
            ],
            VectorPotential::Cfm25Singular => {
                let two = S::constant(2.0);
                let r2 = x[0] * x[0] + x[1] * x[1] + x[2] * x[2];
                let a3 = S::constant(-4.0) / (S::constant(1.0) + r2);
                [
                    [two * x[0], two * x[1], two * x[2]],
                    [
                        two * x[1] - r2 * x[1] / (x[0] * x[0]),
                        (two * x[1] * x[1] + r2) / x[0],
                        two * x[2] * x[1] / x[0],
                    ],
                    [a3 * x[0], a3 * x[1], a3 * x[2]],
                ]
            }
        }
    }

    /// `w_j = Σ_ik ∂_k∂_j A_i v_k v_i`.
    pub fn curvature(&self, x: [f64; 3], v: [f64; 3]) -> [f64; 3] {
        let seeded: [Dual; 3] = std::array::from_fn(|k| Dual::seeded(x[k], v[k]));
        let jacobian = self.jacobian(seeded);
        std::array::from_fn(|j| (0..3).map(|i| jacobian[i][j].derivative * v[i]).sum())
    }
}

/// A magnetic field on a list of charged particles.
#[derive(Clone, Debug)]
pub struct MagneticTerm {
    dim: usize,
    field: VectorPotential,
    /// `(particle, charge e)`.
    particles: Vec<(usize, f64)>,
}

impl MagneticTerm {
    /// `dim` must be 2 or 3 (3 for [`VectorPotential::Cfm25Singular`]); the scene
    /// checks it.
    pub fn new(dim: usize, field: VectorPotential, particles: Vec<(usize, f64)>) -> Self {
        assert!((2..=3).contains(&dim), "a magnetic field needs dim 2 or 3");
        MagneticTerm {
            dim,
            field,
            particles,
        }
    }

    fn point(&self, q: &[f64], i: usize) -> [f64; 3] {
        let mut x = [0.0; 3];
        x[..self.dim].copy_from_slice(&q[i * self.dim..(i + 1) * self.dim]);
        x
    }

    fn vector(&self, v: &[f64], i: usize) -> [f64; 3] {
        self.point(v, i)
    }

    fn add(&self, out: &mut [f64], i: usize, value: [f64; 3], scale: f64) {
        for a in 0..self.dim {
            out[i * self.dim + a] += scale * value[a];
        }
    }

    /// `out += e A(x)` per particle: canonical momentum = kinetic momentum + this.
    pub fn add_canonical_shift(&self, q: &[f64], out: &mut [f64]) {
        for &(i, charge) in &self.particles {
            self.add(out, i, self.field.value(self.point(q, i)), charge);
        }
    }

    /// `out += e Jᵀ v` per particle.
    pub fn add_jacobian_transpose(&self, q: &[f64], v: &[f64], out: &mut [f64]) {
        for &(i, charge) in &self.particles {
            let jacobian = self.field.jacobian(self.point(q, i));
            let vi = self.vector(v, i);
            let value = std::array::from_fn(|j| (0..3).map(|k| jacobian[k][j] * vi[k]).sum());
            self.add(out, i, value, charge);
        }
    }

    /// `out += e J v` per particle.
    pub fn add_jacobian(&self, q: &[f64], v: &[f64], out: &mut [f64]) {
        for &(i, charge) in &self.particles {
            let jacobian = self.field.jacobian(self.point(q, i));
            let vi = self.vector(v, i);
            let value = std::array::from_fn(|k| (0..3).map(|j| jacobian[k][j] * vi[j]).sum());
            self.add(out, i, value, charge);
        }
    }

    /// `out += e w(x; v)` per particle, `w_j = Σ_ik ∂_k∂_j A_i v_k v_i`.
    pub fn add_curvature(&self, q: &[f64], v: &[f64], out: &mut [f64]) {
        for &(i, charge) in &self.particles {
            let w = self.field.curvature(self.point(q, i), self.vector(v, i));
            self.add(out, i, w, charge);
        }
    }
}

impl ForceTerm for MagneticTerm {
    fn kind(&self) -> &'static str {
        "magnetic"
    }

    fn class(&self) -> TermClass {
        TermClass::Nonbonded
    }

    /// A magnetic field does no work: no potential energy.
    fn energy(&self, _q: &[f64]) -> f64 {
        0.0
    }

    /// The Lorentz force depends on the velocity, not on a potential: nothing here (the
    /// structural schemes apply it through [`ForceTerm::magnetic`]).
    fn add_gradient(&self, _q: &[f64], _gradient: &mut [f64]) {}

    fn add_hessian_vector(&self, _q: &[f64], _v: &[f64], _out: &mut [f64]) {}

    fn couplings(&self) -> Vec<Vec<usize>> {
        self.particles.iter().map(|&(i, _)| vec![i]).collect()
    }

    fn interaction_count(&self) -> usize {
        self.particles.len()
    }

    fn magnetic(&self) -> Option<&MagneticTerm> {
        Some(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Jacobian and the curvature against central differences of `A` and of `J`;
    /// step 1e-6 on O(1) values: truncation ~1e-12, round-off ~1e-10, so 1e-7 relative
    /// to the largest entry is loose.
    #[test]
    fn singular_field_derivatives_match_finite_differences() {
        let field = VectorPotential::Cfm25Singular;
        let x = [0.5, -0.25, -0.3];
        let v = [0.3, -0.7, 0.4];
        let step = 1e-6;
        let jacobian = field.jacobian(x);
        let scale = jacobian
            .iter()
            .flatten()
            .fold(0.0f64, |m, v| m.max(v.abs()));
        for j in 0..3 {
            let mut plus = x;
            let mut minus = x;
            plus[j] += step;
            minus[j] -= step;
            let (ap, am) = (field.value(plus), field.value(minus));
            for i in 0..3 {
                let numeric = (ap[i] - am[i]) / (2.0 * step);
                assert!(
                    (numeric - jacobian[i][j]).abs() <= 1e-7 * scale,
                    "J[{i}][{j}]"
                );
            }
        }
        // w_j = Σ_i (d/dε J_ij(x + εv)) v_i.
        let plus: [f64; 3] = std::array::from_fn(|k| x[k] + step * v[k]);
        let minus: [f64; 3] = std::array::from_fn(|k| x[k] - step * v[k]);
        let (jp, jm) = (field.jacobian(plus), field.jacobian(minus));
        let w = field.curvature(x, v);
        for j in 0..3 {
            let numeric: f64 = (0..3)
                .map(|i| (jp[i][j] - jm[i][j]) / (2.0 * step) * v[i])
                .sum();
            assert!((numeric - w[j]).abs() <= 1e-7 * scale, "w[{j}]");
        }
    }
}
