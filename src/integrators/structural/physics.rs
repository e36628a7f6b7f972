//! The physical equations of the structural schemes (CFM25 3.1 and 4.2): the first and
//! second time derivatives of a state `(x, p)` of a Hamiltonian system.
//!
//! The Hamiltonian is `H = Σ_i |p_i − e_i A(x_i)|²/(2m_i) + V(x)`: the separable
//! `pᵀM⁻¹p/2 + V` of every other scene, plus, for scenes with a magnetic term
//! ([`MagneticTerm`]), the vector potential that makes it non-separable (CFM25 5.7). With
//! `v = M⁻¹(p − eA)` and `J_ij = ∂_j A_i` per charged particle:
//!
//! * `PE[1]`: `Dx = ∂H/∂p = v`, `Dp = −∂H/∂x = −∇V + e Jᵀ v`;
//! * `PE[2]`: `Sx = d/dt(∂H/∂p) = M⁻¹(Dp − e J Dx)`,
//!   `Sp = −d/dt(∂H/∂x) = −∇²V Dx + e (Jᵀ Sx + w)`, `w_j = Σ_ik ∂_k∂_j A_i Dx_k Dx_i`.
//!
//! Without a field these are CFM25's separable equations (`Dx = M⁻¹p`, `Dp = −∇V`,
//! `Sx = M⁻¹Dp`, `Sp = −∇²V Dx`). CFM25 5.7.1 prints `[∂ₓA] Sx` in `Sp`; its own
//! derivation two lines above gives the transpose, which is what is used here.
//!
//! Cost: `PE[1]` is one gradient evaluation of every force level; `PE[2]` one Hessian-vector
//! product of every level (counted by the [`ForceSplit`]). The magnetic field is applied
//! analytically on the level that holds it and is not counted separately.

use crate::forces::magnetic::MagneticTerm;
use crate::split::ForceSplit;

pub struct PhysicalEquations {
    inverse_mass: Vec<f64>,
    /// Whether any term is magnetic (the non-separable case).
    magnetic: bool,
    scratch: Vec<f64>,
}

fn magnetic_terms(forces: &ForceSplit) -> impl Iterator<Item = &MagneticTerm> {
    forces.terms().iter().filter_map(|t| t.term.magnetic())
}

impl PhysicalEquations {
    pub fn new(inverse_mass: &[f64], forces: &ForceSplit) -> Self {
        PhysicalEquations {
            inverse_mass: inverse_mass.to_vec(),
            magnetic: magnetic_terms(forces).next().is_some(),
            scratch: vec![0.0; inverse_mass.len()],
        }
    }

    pub fn is_separable(&self) -> bool {
        !self.magnetic
    }

    /// Canonical momentum from the kinetic momentum the state stores:
    /// `p = π + eA(x)` (a copy without a field).
    pub fn to_canonical(&self, forces: &ForceSplit, x: &[f64], kinetic: &[f64], p: &mut [f64]) {
        p.copy_from_slice(kinetic);
        for term in magnetic_terms(forces) {
            term.add_canonical_shift(x, p);
        }
    }

    /// Kinetic momentum `π = p − eA(x)` for the state.
    pub fn to_kinetic(&mut self, forces: &ForceSplit, x: &[f64], p: &[f64], kinetic: &mut [f64]) {
        kinetic.copy_from_slice(p);
        if self.magnetic {
            self.scratch.fill(0.0);
            for term in magnetic_terms(forces) {
                term.add_canonical_shift(x, &mut self.scratch);
            }
            for (k, shift) in kinetic.iter_mut().zip(&self.scratch) {
                *k -= shift;
            }
        }
    }

    /// `PE[1]`: `dx = ∂H/∂p`, `dp = −∂H/∂x` at `(x, p)`.
    pub fn first(
        &mut self,
        forces: &mut ForceSplit,
        x: &[f64],
        p: &[f64],
        dx: &mut [f64],
        dp: &mut [f64],
    ) {
        if self.magnetic {
            self.to_kinetic(forces, x, p, dx);
            for (d, w) in dx.iter_mut().zip(&self.inverse_mass) {
                *d *= w;
            }
        } else {
            for ((d, pi), w) in dx.iter_mut().zip(p).zip(&self.inverse_mass) {
                *d = w * pi;
            }
        }
        forces.total_gradient(x, dp);
        for d in dp.iter_mut() {
            *d = -*d;
        }
        if self.magnetic {
            for term in magnetic_terms(forces) {
                term.add_jacobian_transpose(x, dx, dp);
            }
        }
    }

    /// `PE[2]`: `sx = d/dt ∂H/∂p`, `sp = −d/dt ∂H/∂x` at `(x, p)` with the first
    /// derivatives `(dx, dp)` of `PE[1]`.
    #[allow(clippy::too_many_arguments)]
    pub fn second(
        &mut self,
        forces: &mut ForceSplit,
        x: &[f64],
        dx: &[f64],
        dp: &[f64],
        sx: &mut [f64],
        sp: &mut [f64],
    ) {
        sx.copy_from_slice(dp);
        if self.magnetic {
            self.scratch.fill(0.0);
            for term in magnetic_terms(forces) {
                term.add_jacobian(x, dx, &mut self.scratch);
            }
            for (s, j) in sx.iter_mut().zip(&self.scratch) {
                *s -= j;
            }
        }
        for (s, w) in sx.iter_mut().zip(&self.inverse_mass) {
            *s *= w;
        }
        sp.fill(0.0);
        for level in 0..forces.n_levels() {
            if forces.level_is_empty(level) {
                continue;
            }
            forces.hessian_vector(level, x, dx, &mut self.scratch);
            for (s, h) in sp.iter_mut().zip(&self.scratch) {
                *s -= h;
            }
        }
        if self.magnetic {
            for term in magnetic_terms(forces) {
                term.add_jacobian_transpose(x, sx, sp);
                term.add_curvature(x, dx, sp);
            }
        }
    }
}
