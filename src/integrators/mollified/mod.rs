//! The averaging map of the mollified impulse methods (GSS98 section 2) and the product of
//! its transposed Jacobian with a vector.
//!
//! The impulse `F(q_n)` of r-RESPA becomes `A_q(h; q_n)ᵀ F(A(h; q_n))` (GSS98 eq. (4)).
//! `A(h; q) = (2/h) b(μh)` comes from the auxiliary problem
//! `dp/dt = −W_q(q), dq/dt = M⁻¹p, db/dt = φ(t/h) q`, `p(0) = 0, q(0) = q_n, b(0) = 0`,
//! integrated by the *same* inner Verlet with the *same* `dt` as the reduced problem, with
//! the half-step `b` updates listed in GSS98 section 2. Its Jacobian is the derivative of
//! that numerical solution, not of the exact flow, computed two ways with equal results:
//!
//! * [`JacobianMode::Forward`] — the paper's propagation of `q_q, p_q, b_q`, per connected
//!   component of the fast-force graph (the Jacobian is block-diagonal over them: a water
//!   molecule is a 9×9 block). Hessian products `W_qq q_q` are batched over components, so
//!   the cost per auxiliary step is (largest block size) Hessian-vector products: quadratic
//!   in the size of one connected molecule.
//! * [`JacobianMode::Adjoint`] — reverse mode: the forward auxiliary pass stores its
//!   positions, one backward pass with one Hessian-vector product per auxiliary step gives
//!   `A_qᵀ g` for the `g` at hand. Linear in the size of the molecule.
//!
//! Cost per call, with `N = ⌈μ K⌉` auxiliary steps (`K` inner steps per outer step):
//! `N − 1` fast-force gradients (the one at q_n is the main loop's, reused; the one at the
//! last point would only serve a momentum the average never reads), one slow-force gradient
//! at `A`, and `N` Hessian-vector products (adjoint) or `N × block size` (forward).
//!
//! With constraints (rigid bonds, rigid water) the auxiliary problem is integrated by
//! RATTLE/SETTLE and the Jacobian is the adjoint through it ([`constrained`]).

mod constrained;

use nalgebra::DMatrix;

use super::integrator::StepFailure;
use crate::error::{Error, Result};
use crate::split::ForceSplit;
use crate::system::System;
use crate::system::constraints::Constraints;

/// The hook of the mollified impulse methods around the slow-force call: the impulse
/// `F(q)` of r-RESPA becomes `A_q(q)ᵀ F(A(q))` (GSS98 eq. (4)), where `A` is a time
/// average ([`Mollifier`], GSS98) or the projection onto the rest geometry of the fast
/// bonded terms ([`super::equilibrium_molly::EquilibriumMolly`], IRS99). The integrator
/// that kicks with it (impulse here; any r-RESPA-like scheme) does not know which.
///
/// Either way the mollified impulse is the gradient of `U(A(q))`, so the integrator is
/// r-RESPA for `W(q) + U(A(q))` and conserves `K + W(q) + U(A(q))`.
/// Where a [`SlowMollifier`] mollifies: the forces, the positions `q`, `∇W(q)` (level 0)
/// when the caller has it, and the slow level `U`.
pub struct MollifyAt<'a> {
    pub forces: &'a mut ForceSplit,
    pub inverse_mass: &'a [f64],
    pub q: &'a [f64],
    pub fast_gradient_at_q: Option<&'a [f64]>,
    pub slow_level: usize,
    /// The system's constraints, when it has them: the averaging integrates under them.
    pub constraints: Option<&'a mut Constraints>,
}

pub trait SlowMollifier: Send {
    /// The method's name (`"long-average"`, `"equilibrium-molly"`).
    fn name(&self) -> &'static str;

    /// Its parameters for the run header (`"jacobian = adjoint, 4 auxiliary steps"`).
    fn describe(&self) -> String;

    /// What the user should know before the run (the constraints chosen, say).
    fn notices(&self, _system: &System) -> Vec<String> {
        Vec::new()
    }

    /// Check that the mollifier applies to `system` (its levels, its bonded terms) and
    /// size every buffer, so that [`SlowMollifier::mollified_gradient`] allocates nothing.
    fn setup(&mut self, system: &System) -> Result<()>;

    /// Compute `A(q)` at `at.q`, kept for [`SlowMollifier::mollified_positions`] and
    /// [`SlowMollifier::pull_back`]. Fails when it cannot be computed (a projection that
    /// does not converge).
    fn mollify(&mut self, at: &mut MollifyAt<'_>) -> std::result::Result<(), StepFailure>;

    /// `out = A_q(q)ᵀ g` for the `q` of the last [`SlowMollifier::mollify`].
    fn pull_back(&mut self, at: &mut MollifyAt<'_>, g: &[f64], out: &mut [f64]);

    /// The buffer `∇U(A(q))` is evaluated into, sized by [`SlowMollifier::setup`].
    fn slow_gradient_buffer(&mut self) -> &mut Vec<f64>;

    /// `out = A_q(q)ᵀ ∇U(A(q))`, `U` the level `slow_level` of `forces`: the gradient
    /// whose negative is the mollified impulse force (GSS98 eq. (4)). `fast_gradient_at_q`
    /// is `∇W(q)` (level 0) when the caller has it. The one declaration of the mollified
    /// gradient: a mollifier says how it maps and pulls back, not how the two combine.
    /// Cost: one [`SlowMollifier::mollify`], one slow-level gradient, one
    /// [`SlowMollifier::pull_back`]; allocates nothing.
    fn mollified_gradient(
        &mut self,
        mut at: MollifyAt<'_>,
        out: &mut [f64],
    ) -> std::result::Result<(), StepFailure> {
        self.mollify(&mut at)?;
        let mut slow_gradient = std::mem::take(self.slow_gradient_buffer());
        let positions = self.mollified_positions();
        at.forces
            .gradient(at.slow_level, positions, &mut slow_gradient);
        self.pull_back(&mut at, &slow_gradient, out);
        *self.slow_gradient_buffer() = slow_gradient;
        Ok(())
    }

    /// `A(q)` of the last [`SlowMollifier::mollify`].
    fn mollified_positions(&self) -> &[f64];

    /// A method-specific object for the run summary (statistics of the projection).
    fn report(&self) -> Option<serde_json::Value> {
        None
    }

    /// Whether a checkpoint can hold this mollifier's state: the GSS98 averages keep none
    /// between steps (the default); a mollifier that warm-starts a solver refuses.
    fn check_checkpoint(&self) -> Result<()> {
        Ok(())
    }
}

/// The weight function φ of the average (GSS98 section 2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Average {
    /// φ(s) = 1 on |s| < 1/2: the mean over `[−h/2, h/2]`. Support μ = 1/2.
    Short,
    /// φ(s) = 1/2 on |s| < 1: the mean over `[−h, h]`. Support μ = 1.
    Long,
    /// φ(s) = 1 − |s| on |s| ≤ 1: the triangle over `[−h, h]`. Support μ = 1.
    Linear,
}

impl Average {
    pub fn name(self) -> &'static str {
        match self {
            Average::Short => "short-average",
            Average::Long => "long-average",
            Average::Linear => "linear-average",
        }
    }

    /// The average named as on the command line (`long-average`).
    pub fn parse(name: &str) -> Result<Self> {
        [Average::Short, Average::Long, Average::Linear]
            .into_iter()
            .find(|a| a.name() == name)
            .ok_or_else(|| {
                Error::setting(
                    "mollifier",
                    format!(
                        "unknown mollifier \"{name}\"; use short-average, long-average, \
                     linear-average or equilibrium-molly"
                    ),
                )
                .expected("short-average, long-average, linear-average or equilibrium-molly")
                .got_named(name)
            })
    }

    /// μ: φ(s) = 0 for |s| > μ.
    pub fn support(self) -> f64 {
        match self {
            Average::Short => 0.5,
            Average::Long | Average::Linear => 1.0,
        }
    }

    /// φ(s) for 0 ≤ s ≤ μ, taking at s = μ the limit from inside. Stopping the auxiliary
    /// integration at t = μh with this end value is the paper's "φ(1) = 1/2, stop at t = h"
    /// for LongAverage (and the same for ShortAverage at h/2); it equals integrating on to
    /// μh + dt/2 with the paper's jump values.
    fn inside(self, s: f64) -> f64 {
        match self {
            Average::Short => 1.0,
            Average::Long => 0.5,
            Average::Linear => 1.0 - s,
        }
    }

    /// The filter Φ(Γ) the averaging applies to a linear spring of phase Γ = hΩ in the limit
    /// dt → 0 (GSS98 section 5): A_q = Φ(Γ).
    pub fn filter(self, gamma: f64) -> f64 {
        let sinc = |x: f64| if x == 0.0 { 1.0 } else { x.sin() / x };
        match self {
            Average::Short => sinc(gamma / 2.0),
            Average::Long => sinc(gamma),
            Average::Linear => sinc(gamma / 2.0).powi(2),
        }
    }

    /// Trapezoid weights φ(t_k/h) at the auxiliary points t_k = k dt, k = 0 … N, and N.
    fn weights(self, inner_steps: usize) -> Vec<f64> {
        let support = self.support();
        // The number of auxiliary steps: up to μh, or the first point past it.
        let exact = support * inner_steps as f64;
        let steps = if (exact - exact.round()).abs() < 1e-9 {
            exact.round() as usize
        } else {
            exact.ceil() as usize
        };
        (0..=steps)
            .map(|k| {
                let s = k as f64 / inner_steps as f64;
                if s <= support + 1e-12 {
                    self.inside(s.min(support))
                } else {
                    0.0
                }
            })
            .collect()
    }
}

/// How `A_qᵀ g` is computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JacobianMode {
    Forward,
    Adjoint,
}

impl JacobianMode {
    pub fn name(self) -> &'static str {
        match self {
            JacobianMode::Forward => "forward",
            JacobianMode::Adjoint => "adjoint",
        }
    }
}

/// The setting `--jacobian`: a mode, or `auto` to choose by the largest fast component.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JacobianChoice {
    Fixed(JacobianMode),
    Auto,
}

impl JacobianChoice {
    pub fn parse(text: Option<&str>) -> Result<Self> {
        match text {
            None | Some("auto") => Ok(JacobianChoice::Auto),
            Some("forward") => Ok(JacobianChoice::Fixed(JacobianMode::Forward)),
            Some("adjoint") => Ok(JacobianChoice::Fixed(JacobianMode::Adjoint)),
            Some(other) => Err(Error::setting(
                "jacobian",
                format!("unknown jacobian \"{other}\"; use forward, adjoint or auto"),
            )
            .expected("forward, adjoint or auto")
            .got_named(other)),
        }
    }
}

/// Forward mode chooses itself up to this many coordinates in the largest fast component:
/// beyond a single particle's block the adjoint needs fewer Hessian-vector products.
const AUTO_FORWARD_MAX_DOFS: usize = 3;

/// One diagonal block of the averaging Jacobian: a connected component of the fast graph.
#[derive(Clone, Debug)]
pub struct ComponentBlock {
    /// The coordinates (indices into q) of the component.
    pub dofs: Vec<usize>,
    /// `∂q/∂q_n`, `∂p/∂q_n`, `∂b/∂q_n` of the auxiliary solution.
    q_q: DMatrix<f64>,
    p_q: DMatrix<f64>,
    b_q: DMatrix<f64>,
    /// `W_qq(q) q_q` at the current auxiliary point.
    hq: DMatrix<f64>,
}

impl ComponentBlock {
    /// This component's block of `A_q = (2/h) b_q`.
    pub fn jacobian(&self, h: f64) -> DMatrix<f64> {
        &self.b_q * (2.0 / h)
    }
}

/// The averaging map `A(h; ·)` and `A_qᵀ`, with buffers sized once in [`Mollifier::setup`].
pub struct Mollifier {
    average: Average,
    choice: JacobianChoice,
    mode: JacobianMode,
    h: f64,
    dt: f64,
    /// φ at the auxiliary points; `weights.len() − 1` auxiliary steps.
    weights: Vec<f64>,
    p: Vec<f64>,
    q: Vec<f64>,
    fast_gradient: Vec<f64>,
    /// `b`, then `A = (2/h) b`.
    averaged: Vec<f64>,
    slow_gradient: Vec<f64>,
    // Adjoint: auxiliary positions q_0 … q_{N−1}, and the adjoint vectors.
    trajectory: Vec<f64>,
    q_adjoint: Vec<f64>,
    p_adjoint: Vec<f64>,
    hessian_vector: Vec<f64>,
    // Forward: the blocks, and a column scratch for batched Hessian products.
    blocks: Vec<ComponentBlock>,
    largest_block: usize,
    column: Vec<f64>,
    column_out: Vec<f64>,
    /// The constrained averaging's records, when the system has constraints.
    constrained: Option<Box<constrained::ConstrainedAverage>>,
}

impl Mollifier {
    pub fn new(average: Average, choice: JacobianChoice, h: f64, inner_steps: usize) -> Self {
        Mollifier {
            average,
            choice,
            mode: JacobianMode::Adjoint,
            h,
            dt: h / inner_steps as f64,
            weights: average.weights(inner_steps),
            p: Vec::new(),
            q: Vec::new(),
            fast_gradient: Vec::new(),
            averaged: Vec::new(),
            slow_gradient: Vec::new(),
            trajectory: Vec::new(),
            q_adjoint: Vec::new(),
            p_adjoint: Vec::new(),
            hessian_vector: Vec::new(),
            blocks: Vec::new(),
            largest_block: 0,
            column: Vec::new(),
            column_out: Vec::new(),
            constrained: None,
        }
    }

    pub fn average(&self) -> Average {
        self.average
    }

    /// The mode in use (after [`Mollifier::setup`] resolved `auto`).
    pub fn mode(&self) -> JacobianMode {
        self.mode
    }

    /// Number of auxiliary Verlet steps per average.
    pub fn auxiliary_steps(&self) -> usize {
        self.weights.len() - 1
    }

    /// Size the buffers for a system of `n_particles × dim` coordinates whose fast
    /// components (lists of particles) are `components`.
    pub fn setup(&mut self, dim: usize, components: &[Vec<usize>]) {
        self.constrained = None;
        self.size(dim, components, false);
    }

    /// [`Mollifier::setup`] for a system with `constraints`: the averaging integrates
    /// under them and the Jacobian is the adjoint through them ([`constrained`]); forward
    /// mode is refused.
    pub fn setup_constrained(
        &mut self,
        dim: usize,
        components: &[Vec<usize>],
        constraints: &Constraints,
    ) -> Result<()> {
        if self.choice == JacobianChoice::Fixed(JacobianMode::Forward) {
            return Err(Error::setting(
                "jacobian",
                format!(
                    "{} with constraints differentiates the constrained averaging in reverse \
                     mode only; use --jacobian adjoint (or auto), or drop the constraints",
                    self.average.name()
                ),
            )
            .expected("adjoint or auto with constraints")
            .got("forward"));
        }
        self.size(dim, components, true);
        let n = self.q.len();
        let steps = self.auxiliary_steps();
        self.trajectory = vec![0.0; (steps + 1) * n];
        self.constrained = Some(Box::new(constrained::ConstrainedAverage::new(
            constraints,
            n,
            steps,
            dim,
        )));
        Ok(())
    }

    /// Size the buffers; `adjoint` forces reverse mode.
    fn size(&mut self, dim: usize, components: &[Vec<usize>], adjoint: bool) {
        let n: usize = components.iter().map(Vec::len).sum::<usize>() * dim;
        let largest = components.iter().map(Vec::len).max().unwrap_or(0) * dim;
        self.mode = match self.choice {
            _ if adjoint => JacobianMode::Adjoint,
            JacobianChoice::Fixed(mode) => mode,
            JacobianChoice::Auto if largest <= AUTO_FORWARD_MAX_DOFS => JacobianMode::Forward,
            JacobianChoice::Auto => JacobianMode::Adjoint,
        };
        for buffer in [
            &mut self.p,
            &mut self.q,
            &mut self.fast_gradient,
            &mut self.averaged,
            &mut self.slow_gradient,
        ] {
            *buffer = vec![0.0; n];
        }
        self.blocks.clear();
        self.trajectory.clear();
        match self.mode {
            JacobianMode::Adjoint => {
                self.trajectory = vec![0.0; self.auxiliary_steps() * n];
                self.q_adjoint = vec![0.0; n];
                self.p_adjoint = vec![0.0; n];
                self.hessian_vector = vec![0.0; n];
            }
            JacobianMode::Forward => {
                self.largest_block = largest;
                self.column = vec![0.0; n];
                self.column_out = vec![0.0; n];
                for component in components {
                    let dofs: Vec<usize> = component
                        .iter()
                        .flat_map(|&i| (i * dim)..(i * dim + dim))
                        .collect();
                    let d = dofs.len();
                    self.blocks.push(ComponentBlock {
                        dofs,
                        q_q: DMatrix::identity(d, d),
                        p_q: DMatrix::zeros(d, d),
                        b_q: DMatrix::zeros(d, d),
                        hq: DMatrix::zeros(d, d),
                    });
                }
            }
        }
    }

    /// The averaged positions `A(h; q)` of the last [`Mollifier::compute_average`].
    pub fn averaged_positions(&self) -> &[f64] {
        &self.averaged
    }

    /// Forward mode's Jacobian blocks of the last average (empty in adjoint mode).
    pub fn blocks(&self) -> &[ComponentBlock] {
        &self.blocks
    }

    /// Integrate the auxiliary problem from `q` with the fast level (level 0) of `forces`:
    /// sets `A(h; q)` and, in forward mode, the Jacobian blocks. `fast_gradient_at_q`, when
    /// given, is `∇W(q)`, saving one evaluation.
    pub fn compute_average(
        &mut self,
        forces: &mut ForceSplit,
        inverse_mass: &[f64],
        q: &[f64],
        fast_gradient_at_q: Option<&[f64]>,
    ) {
        self.start_average(forces, q, fast_gradient_at_q);
        let steps = self.auxiliary_steps();
        for k in 0..steps {
            // The GSS98 section 2 step, on (p, q, b) and, in forward mode, on their
            // derivatives with respect to q_n.
            let weight = self.auxiliary_step(forces, inverse_mass, k, steps);
            if self.mode == JacobianMode::Forward {
                self.jacobian_step(forces, inverse_mass, k + 1 < steps, weight);
            }
        }
        let scale = 2.0 / self.h;
        for b in &mut self.averaged {
            *b *= scale;
        }
    }

    /// The auxiliary problem's start `(q, 0)` with `∇W(q)`, the first trapezoid term of
    /// the average and, in forward mode, the Jacobian blocks at the identity.
    fn start_average(
        &mut self,
        forces: &mut ForceSplit,
        q: &[f64],
        fast_gradient_at_q: Option<&[f64]>,
    ) {
        let half = 0.5 * self.dt;
        self.q.copy_from_slice(q);
        self.p.fill(0.0);
        match fast_gradient_at_q {
            Some(gradient) => self.fast_gradient.copy_from_slice(gradient),
            None => forces.gradient(0, &self.q, &mut self.fast_gradient),
        }
        // b accumulates the trapezoid rule of ∫φ(t/h) q dt: dt/2 at the ends, dt inside.
        let first = half * self.weights[0];
        for (b, x) in self.averaged.iter_mut().zip(&self.q) {
            *b = first * x;
        }
        if self.mode == JacobianMode::Forward {
            for block in &mut self.blocks {
                block.q_q.fill_with_identity();
                block.p_q.fill(0.0);
                block.b_q.fill_with_identity();
                block.b_q *= first;
            }
            self.block_hessian_products(forces);
        }
    }

    /// Step `k` of `steps` on `(p, q)` and its trapezoid term added to the average.
    /// Returns the term's weight (the forward mode's `b_q` takes the same).
    fn auxiliary_step(
        &mut self,
        forces: &mut ForceSplit,
        inverse_mass: &[f64],
        k: usize,
        steps: usize,
    ) -> f64 {
        let (dt, half) = (self.dt, 0.5 * self.dt);
        let n = self.q.len();
        for (p, g) in self.p.iter_mut().zip(&self.fast_gradient) {
            *p -= half * g;
        }
        if self.mode == JacobianMode::Adjoint {
            self.trajectory[k * n..(k + 1) * n].copy_from_slice(&self.q);
        }
        for ((x, p), w) in self.q.iter_mut().zip(&self.p).zip(inverse_mass) {
            *x += dt * (w * p);
        }
        // The last half-kick would only update p, which the average does not use.
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
        weight
    }

    /// The same step on the forward mode's derivatives `p_q`, `q_q` and `b_q` (trapezoid
    /// `weight`); `more` when another step follows.
    fn jacobian_step(
        &mut self,
        forces: &mut ForceSplit,
        inverse_mass: &[f64],
        more: bool,
        weight: f64,
    ) {
        let (dt, half) = (self.dt, 0.5 * self.dt);
        for block in &mut self.blocks {
            add_scaled(&mut block.p_q, -half, &block.hq);
            let d = block.dofs.len();
            for (r, &dof) in block.dofs.iter().enumerate() {
                let factor = dt * inverse_mass[dof];
                for c in 0..d {
                    block.q_q[(r, c)] += factor * block.p_q[(r, c)];
                }
            }
        }
        // W_qq q_q at the new point, needed by the second half-kick (not after the
        // last step, where p_q no longer matters).
        if more {
            self.block_hessian_products(forces);
            for block in &mut self.blocks {
                add_scaled(&mut block.p_q, -half, &block.hq);
            }
        }
        for block in &mut self.blocks {
            add_scaled(&mut block.b_q, weight, &block.q_q);
        }
    }

    /// `hq = W_qq(q) q_q` for every block: one batched Hessian-vector product per column
    /// index, since blocks of different components do not interact through fast forces.
    fn block_hessian_products(&mut self, forces: &mut ForceSplit) {
        for j in 0..self.largest_block {
            self.column.fill(0.0);
            for block in &self.blocks {
                if j < block.dofs.len() {
                    for (r, &dof) in block.dofs.iter().enumerate() {
                        self.column[dof] = block.q_q[(r, j)];
                    }
                }
            }
            forces.hessian_vector(0, &self.q, &self.column, &mut self.column_out);
            for block in &mut self.blocks {
                if j < block.dofs.len() {
                    for (r, &dof) in block.dofs.iter().enumerate() {
                        block.hq[(r, j)] = self.column_out[dof];
                    }
                }
            }
        }
    }

    /// `out = A_q(h; q)ᵀ g` for the `q` of the last [`Mollifier::compute_average`] (or
    /// [`Mollifier::compute_constrained_average`]).
    pub fn transpose_product(
        &mut self,
        forces: &mut ForceSplit,
        inverse_mass: &[f64],
        g: &[f64],
        out: &mut [f64],
    ) {
        if self.constrained.is_some() {
            return self.constrained_adjoint(forces, inverse_mass, g, out);
        }
        let scale = 2.0 / self.h;
        match self.mode {
            JacobianMode::Forward => {
                for block in &self.blocks {
                    for (c, &column_dof) in block.dofs.iter().enumerate() {
                        let mut sum = 0.0;
                        for (r, &row_dof) in block.dofs.iter().enumerate() {
                            sum += block.b_q[(r, c)] * g[row_dof];
                        }
                        out[column_dof] = scale * sum;
                    }
                }
            }
            JacobianMode::Adjoint => self.adjoint_product(forces, inverse_mass, g, out),
        }
    }

    /// Reverse mode through the auxiliary Verlet steps. With `b̄ = (2/h) g` (constant, as b
    /// only accumulates) and `p̄ = 0`, `q̄ = (dt/2) φ_N b̄` at the end, each step backwards is
    /// `p̄ += dt M⁻¹ q̄; q̄ += c (φ_k b̄ − W_qq(q_k) p̄)` with `c = dt` inside and `dt/2` at
    /// k = 0 (the two half-kicks and half-step b updates meeting at each inner point use the
    /// same p̄). Then `q̄ = A_qᵀ g`.
    fn adjoint_product(
        &mut self,
        forces: &mut ForceSplit,
        inverse_mass: &[f64],
        g: &[f64],
        out: &mut [f64],
    ) {
        let n = g.len();
        let steps = self.auxiliary_steps();
        let (dt, half, scale) = (self.dt, 0.5 * self.dt, 2.0 / self.h);
        let last = half * self.weights[steps] * scale;
        for (qa, gi) in self.q_adjoint.iter_mut().zip(g) {
            *qa = last * gi;
        }
        self.p_adjoint.fill(0.0);
        for k in (0..steps).rev() {
            for ((pa, qa), w) in self
                .p_adjoint
                .iter_mut()
                .zip(&self.q_adjoint)
                .zip(inverse_mass)
            {
                *pa += dt * (w * qa);
            }
            let c = if k == 0 { half } else { dt };
            let position = &self.trajectory[k * n..(k + 1) * n];
            forces.hessian_vector(0, position, &self.p_adjoint, &mut self.hessian_vector);
            let along = c * self.weights[k] * scale;
            for ((qa, gi), hv) in self.q_adjoint.iter_mut().zip(g).zip(&self.hessian_vector) {
                *qa += along * gi - c * hv;
            }
        }
        out.copy_from_slice(&self.q_adjoint);
    }
}

impl SlowMollifier for Mollifier {
    fn name(&self) -> &'static str {
        self.average.name()
    }

    fn describe(&self) -> String {
        format!(
            "jacobian = {}, {} auxiliary steps",
            self.mode.name(),
            self.auxiliary_steps()
        )
    }

    fn setup(&mut self, system: &System) -> Result<()> {
        let levels = system.forces.n_levels();
        if levels != 2 {
            return Err(Error::setting(
                "method",
                format!(
                    "{} averages with the fast forces and mollifies the slow ones: it needs \
                 exactly two force levels, the scene has {levels} (use impulse for \
                 recursive r-RESPA)",
                    self.average.name()
                ),
            )
            .expected("a scene of two force levels")
            .got_named(self.average.name()));
        }
        let components = system.forces.fast_components(system.n_particles());
        match &system.constraints {
            Some(constraints) => self.setup_constrained(system.dim, &components, constraints),
            None => {
                Mollifier::setup(self, system.dim, &components);
                Ok(())
            }
        }
    }

    /// `A(h; q)`: the auxiliary problem integrated with the fast level, under the
    /// constraints when the system has them.
    fn mollify(&mut self, at: &mut MollifyAt<'_>) -> std::result::Result<(), StepFailure> {
        if self.constrained.is_none() {
            self.compute_average(at.forces, at.inverse_mass, at.q, at.fast_gradient_at_q);
            return Ok(());
        }
        let name = self.average.name();
        let Some(constraints) = at.constraints.as_deref_mut() else {
            return Err(StepFailure(format!(
                "{name} was set up with constraints, but none were given to its averaging"
            )));
        };
        self.compute_constrained_average(
            at.forces,
            at.inverse_mass,
            constraints,
            at.q,
            at.fast_gradient_at_q,
        )
        .map_err(|e| StepFailure(format!("constraints failed in the {name} averaging: {e}")))
    }

    fn pull_back(&mut self, at: &mut MollifyAt<'_>, g: &[f64], out: &mut [f64]) {
        self.transpose_product(at.forces, at.inverse_mass, g, out);
    }

    fn slow_gradient_buffer(&mut self) -> &mut Vec<f64> {
        &mut self.slow_gradient
    }

    fn mollified_positions(&self) -> &[f64] {
        &self.averaged
    }
}

/// `target += a · x`, in place.
fn add_scaled(target: &mut DMatrix<f64>, a: f64, x: &DMatrix<f64>) {
    for (t, v) in target.as_mut_slice().iter_mut().zip(x.as_slice()) {
        *t += a * v;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_follow_the_paper_end_convention() {
        // LongAverage, K = 4: φ = 1/2 at t = 0, h/4, h/2, 3h/4 and, by the convention, at h.
        assert_eq!(Average::Long.weights(4), vec![0.5; 5]);
        // ShortAverage stops at h/2 (K even) with the interior value.
        assert_eq!(Average::Short.weights(4), vec![1.0; 3]);
        // K odd: the first point past h/2 has φ = 0.
        assert_eq!(Average::Short.weights(3), vec![1.0, 1.0, 0.0]);
        // LinearAverage: the triangle, zero at t = h.
        assert_eq!(Average::Linear.weights(4), vec![1.0, 0.75, 0.5, 0.25, 0.0]);
    }

    #[test]
    fn weights_integrate_to_one_half() {
        // ∫_0^μ φ = 1/2 for every even φ of unit integral; the trapezoid is exact for these
        // piecewise-linear φ when μK is whole.
        for average in [Average::Short, Average::Long, Average::Linear] {
            let k = 8;
            let w = average.weights(k);
            let n = w.len() - 1;
            let integral: f64 = (0..n).map(|i| 0.5 * (w[i] + w[i + 1]) / k as f64).sum();
            assert!((integral - 0.5).abs() < 1e-15, "{average:?}: {integral}");
        }
    }
}
