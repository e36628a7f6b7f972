//! The GSS98 averages under constraints (rigid bonds, rigid water).
//!
//! **The average.** With holonomic constraints `g(q) = 0` the reduced problem of GSS98
//! section 2 is integrated by RATTLE, as the run's innermost step is
//! ([`crate::integrators::constrained`]), so the auxiliary problem is too:
//! `dp/dt = −W_q(q) + G(q)ᵀλ, dq/dt = M⁻¹p, db/dt = φ(t/h) q, g(q) = 0`, `p(0) = 0,
//! q(0) = q_n, b(0) = 0`, by the same inner step `dt`: per auxiliary step the half-kicks,
//! the velocity projection (RATTLE's, SETTLE's for water), the drift and the position
//! constraint (SHAKE, SETTLE) with its momentum change, and GSS98's trapezoid update of
//! `b`. `A(h; q_n) = (2/h) b(μh)` as without constraints; each auxiliary position lies on
//! the constraint manifold, their average in general not (a turning water's average is a
//! shrunken triangle), which is what the slow force is evaluated at.
//!
//! **The Jacobian.** The exact derivative of that numerical map, by reverse mode as in
//! [`super::JacobianMode::Adjoint`]: the forward pass stores, per auxiliary step, the
//! positions, the impulses `μ` of the velocity projection and `λ` of the position step, and
//! the projected relative velocities; the backward pass runs, per step in reverse, the
//! transposed position step and transposed projection ([`Linearized`]: their equations,
//! including the curvature terms `L_λ`, `L_μ`, `D_{v⁺}` that make the derivative exact)
//! and the transposed kicks (one Hessian-vector product of the fast level per step). The
//! derivative is that of the map with the constraints solved exactly: SHAKE's tolerance
//! (relative 1e-8 by default) is the error of this Jacobian, far below the method's O(h²)
//! energy oscillation. Forward mode is not offered with constraints.
//!
//! **The impulse.** `A_q(q_n)ᵀ ∇U(A(q_n))` (GSS98 eq. (4)) is kicked like every other force
//! through the constrained innermost step, whose velocity projection puts it on the
//! tangent space of the constraints at `q_n`; it then depends only on `A_q` along tangent
//! directions, where the derivative of the numerical map is what is needed (SETTLE, which
//! assumes the old positions rigid, and SHAKE agree to first order along the manifold).
//! So the method is RATTLE r-RESPA for `W(q) + U(A(q))` on the manifold and conserves
//! `K + W(q) + U(A(q))` (`mollified_total`) to O(h²) oscillation with no drift while
//! stable.
//!
//! **Cost** per average, with `N` auxiliary steps: as without constraints (`N − 1` fast
//! gradients, one slow gradient at `A`, `N` Hessian-vector products of the fast level),
//! plus `N` velocity projections and `N` position constraints, and per step four small
//! solves per constraint cluster ([`Linearized`]: two to recover the impulses, two in the
//! backward pass), a few hundred flops per water or bond to hydrogen. Memory: `N + 1`
//! positions and `(2 + dim) N` numbers per constraint.

use super::Mollifier;
use crate::split::ForceSplit;
use crate::system::constraints::linear::{Adjoints, Linearized};
use crate::system::constraints::{ConstraintFailure, Constraints};

/// What the constrained averaging keeps between its forward and backward passes.
pub(super) struct ConstrainedAverage {
    linear: Linearized,
    p_before: Vec<f64>,
    q_old: Vec<f64>,
    delta: Vec<f64>,
    /// `μ_k` of every auxiliary step's velocity projection, `len` numbers each.
    velocity_impulses: Vec<f64>,
    /// `λ_k` of every auxiliary step's position constraint.
    position_impulses: Vec<f64>,
    /// The relative velocities `vᵢ − vⱼ` after every projection, `len × dim` each.
    relative: Vec<f64>,
    dim: usize,
}

impl ConstrainedAverage {
    /// Buffers for `steps` auxiliary steps of `n` coordinates in `dim` dimensions.
    pub(super) fn new(constraints: &Constraints, n: usize, steps: usize, dim: usize) -> Self {
        let linear = Linearized::new(constraints, n);
        let len = linear.len();
        ConstrainedAverage {
            linear,
            p_before: vec![0.0; n],
            q_old: vec![0.0; n],
            delta: vec![0.0; n],
            velocity_impulses: vec![0.0; steps * len],
            position_impulses: vec![0.0; steps * len],
            relative: vec![0.0; steps * len * dim],
            dim,
        }
    }

    /// `delta = p − p_before`.
    fn change(&mut self, p: &[f64]) {
        for ((d, a), b) in self.delta.iter_mut().zip(p).zip(&self.p_before) {
            *d = a - b;
        }
    }
}

impl Mollifier {
    /// The auxiliary problem from `q` under `constraints` (the module's doc): sets
    /// `A(h; q)` and keeps what [`Mollifier::transpose_product`] needs. `q` must satisfy the
    /// constraints. Fails as the run's constrained step does (SHAKE beyond its iteration
    /// cap, SETTLE beyond reach).
    pub fn compute_constrained_average(
        &mut self,
        forces: &mut ForceSplit,
        inverse_mass: &[f64],
        constraints: &mut Constraints,
        q: &[f64],
        fast_gradient_at_q: Option<&[f64]>,
    ) -> Result<(), ConstraintFailure> {
        let Some(mut aux) = self.constrained.take() else {
            return Err(ConstraintFailure(format!(
                "{} was set up without constraints",
                self.average.name()
            )));
        };
        self.start_average(forces, q, fast_gradient_at_q);
        let steps = self.auxiliary_steps();
        let mut result = Ok(());
        for k in 0..steps {
            result = self.constrained_step(&mut aux, forces, inverse_mass, constraints, k);
            if result.is_err() {
                break;
            }
        }
        self.constrained = Some(aux);
        result?;
        let n = self.q.len();
        self.trajectory[steps * n..].copy_from_slice(&self.q);
        let scale = 2.0 / self.h;
        for b in &mut self.averaged {
            *b *= scale;
        }
        Ok(())
    }

    /// Auxiliary step `k`: the half-kick at `q_k`, the projection, the drift with the
    /// position constraint, the fast gradient and half-kick at `q_{k+1}` (not after the
    /// last step), and the trapezoid term; the impulses are recovered and kept.
    fn constrained_step(
        &mut self,
        aux: &mut ConstrainedAverage,
        forces: &mut ForceSplit,
        inverse_mass: &[f64],
        constraints: &mut Constraints,
        k: usize,
    ) -> Result<(), ConstraintFailure> {
        let (dt, half) = (self.dt, 0.5 * self.dt);
        let steps = self.auxiliary_steps();
        let (n, len, dim) = (self.q.len(), aux.linear.len(), aux.dim);
        for (p, g) in self.p.iter_mut().zip(&self.fast_gradient) {
            *p -= half * g;
        }
        aux.p_before.copy_from_slice(&self.p);
        constraints.constrain_velocities(&self.q, &mut self.p, inverse_mass)?;
        aux.change(&self.p);
        let mu = &mut aux.velocity_impulses[k * len..(k + 1) * len];
        aux.linear
            .multipliers(&self.q, &aux.delta, inverse_mass, mu);
        let relative = &mut aux.relative[k * len * dim..(k + 1) * len * dim];
        aux.linear
            .relative_velocities(&self.p, inverse_mass, relative);
        self.trajectory[k * n..(k + 1) * n].copy_from_slice(&self.q);
        aux.q_old.copy_from_slice(&self.q);
        for ((x, p), w) in self.q.iter_mut().zip(&self.p).zip(inverse_mass) {
            *x += dt * (w * p);
        }
        aux.p_before.copy_from_slice(&self.p);
        constraints.constrain_positions(&aux.q_old, &mut self.q, &mut self.p, inverse_mass, dt)?;
        aux.change(&self.p);
        let lambda = &mut aux.position_impulses[k * len..(k + 1) * len];
        aux.linear
            .multipliers(&aux.q_old, &aux.delta, inverse_mass, lambda);
        if k + 1 < steps {
            forces.gradient(0, &self.q, &mut self.fast_gradient);
            for (p, g) in self.p.iter_mut().zip(&self.fast_gradient) {
                *p -= half * g;
            }
        }
        let weight = if k + 1 == steps { half } else { dt } * self.weights[k + 1];
        for (b, x) in self.averaged.iter_mut().zip(&self.q) {
            *b += weight * x;
        }
        Ok(())
    }

    /// `out = A_qᵀ g` through the constrained auxiliary steps in reverse (the module's doc):
    /// per step the transposed position step and projection, then the transposed kicks at
    /// `q_k` with the trapezoid term, as [`Mollifier::adjoint_product`] does without
    /// constraints (the same bits when there are none).
    pub(super) fn constrained_adjoint(
        &mut self,
        forces: &mut ForceSplit,
        inverse_mass: &[f64],
        g: &[f64],
        out: &mut [f64],
    ) {
        let Some(aux) = self.constrained.as_mut() else {
            return;
        };
        let n = g.len();
        let (len, dim) = (aux.linear.len(), aux.dim);
        let steps = self.weights.len() - 1;
        let (dt, half, scale) = (self.dt, 0.5 * self.dt, 2.0 / self.h);
        let last = half * self.weights[steps] * scale;
        for (qa, gi) in self.q_adjoint.iter_mut().zip(g) {
            *qa = last * gi;
        }
        self.p_adjoint.fill(0.0);
        for k in (0..steps).rev() {
            let before = &self.trajectory[k * n..(k + 1) * n];
            let after = &self.trajectory[(k + 1) * n..(k + 2) * n];
            aux.linear.shake_transpose(
                before,
                after,
                &aux.position_impulses[k * len..(k + 1) * len],
                inverse_mass,
                dt,
                Adjoints {
                    q: &mut self.q_adjoint,
                    p: &mut self.p_adjoint,
                },
            );
            aux.linear.projection_transpose(
                before,
                &aux.velocity_impulses[k * len..(k + 1) * len],
                &aux.relative[k * len * dim..(k + 1) * len * dim],
                inverse_mass,
                Adjoints {
                    q: &mut self.q_adjoint,
                    p: &mut self.p_adjoint,
                },
            );
            let c = if k == 0 { half } else { dt };
            forces.hessian_vector(0, before, &self.p_adjoint, &mut self.hessian_vector);
            let along = c * self.weights[k] * scale;
            for ((qa, gi), hv) in self.q_adjoint.iter_mut().zip(g).zip(&self.hessian_vector) {
                *qa += along * gi - c * hv;
            }
        }
        out.copy_from_slice(&self.q_adjoint);
    }
}
