//! The equilibrium mollifier of Izaguirre, Reich & Skeel (IRS99: J. Chem. Phys. 110:9853,
//! 1999; NAMD `molly on`, ProtoMol `EquilibriumMOLLY`): mollified impulse whose `A(q)` is
//! not a time average but the projection of `q` onto the manifold where the fast bonded
//! terms are at rest.
//!
//! **The map.** With squared-distance constraints `g_c(A) = |A_a − A_b|² − d_c²` — bonds
//! at `r₀` (`--molly-constraints bonds`), and with `bonds-angles` also 1–3 distances from
//! the law of cosines for the angles at `θ₀` ([`selection`] chooses a non-redundant set) —
//! `A(q)` is the mass-weighted closest point of the manifold `g(A) = 0`:
//! `F₁ = M (A − q) + G(A)ᵀ μ = 0`, `F₂ = g(A) = 0`, `G = ∂g/∂A`. This is the reading we take
//! of IRS99's SHAKE-like projection `A = q − M⁻¹ G ᵀ λ`, `g(A) = 0`, with the constraint
//! gradient at `A`. (NAMD's and ProtoMol's code evaluate it at `q` instead, the SHAKE
//! form; both put `A` on the same manifold and agree to first order in the distance from
//! it. The closest-point form has a symmetric Jacobian and, when the held distances make a
//! molecule rigid — water with bonds and angle — `A(q)` is the mass-weighted Kabsch fit of
//! the rest geometry, which the tests check. We could not read IRS99's own text here, so no
//! equation numbers are quoted from it.)
//!
//! **Newton.** Full Newton on `(A, μ)` from `A = q`, `μ = 0` at every call — never a warm
//! start from the previous step, so `A` is a function of `q` alone and the step stays
//! time-reversible — with the KKT matrix `[[K, Gᵀ], [G, 0]]`, `K = M + H_μ`,
//! `H_μ = Σ_c μ_c ∇²g_c` (constant blocks `2[[I, −I], [−I, I]]` per constraint: the
//! curvature term). Where that matrix does not have the inertia of a minimum (read off its
//! `L D Lᵀ` pivots), the step drops `H_μ` (`K = M`) instead: near the manifold this never
//! happens and convergence is quadratic (3–4 iterations on water); far from it (a chain
//! held at its rest angles) plain Newton wanders for dozens of iterations or converges to
//! a saddle, which is refused. It stops when every `|g_c|/d_c²` and every `|F₁|/(m ℓ)` (ℓ the longest
//! held distance of the molecule) is at most `tol` (default 1e-10: an error of 1e-10 Å in
//! `A` changes `U(A)` by ~1e-8 kcal/mol on the water box and the slow force by a relative
//! 1e-10, far below the O(h²) energy oscillation of the method; Newton converges
//! quadratically, so the tolerance costs about one iteration over a looser one), after at
//! most `max_iter` iterations (default 50), or fails: the run stops with a
//! [`StepFailure`](crate::integrators::StepFailure) naming the molecule, the residual and
//! the iterations.
//!
//! **The Jacobian.** Differentiating `F = 0` at the solution: `K dA + Gᵀ dμ = M dq`,
//! `G dA = 0`, so `dA = P̃ M dq` with `P̃ = K⁻¹ − K⁻¹Gᵀ(G K⁻¹ Gᵀ)⁻¹G K⁻¹` (symmetric), and
//! the mollified slow gradient `A_q(q)ᵀ ∇U(A) = M P̃ ∇U(A)` is one solve with the same KKT
//! matrix, `[[K, Gᵀ], [G, 0]] [x; y] = [∇U; 0]`, `x = P̃ ∇U` (`--molly-jacobian exact`,
//! the default). The projection-only Jacobian of the older literature
//! (`--molly-jacobian projection`) drops `H_μ` (`K = M`):
//! `A_qᵀ f = f − Gᵀ(G M⁻¹ Gᵀ)⁻¹ G M⁻¹ f`. It is not the gradient of `U(A(q))`, so with it
//! the method does **not** conserve `K + W(q) + U(A(q))`; with the exact one it is r-RESPA
//! impulse for `W(q) + U(A(q))` and conserves that energy (to O(h²) oscillation, without
//! drift while stable), reported as `mollified_total` in `energy.csv`.
//!
//! **Molecules.** Each connected component of the constraint graph is solved on its own,
//! in molecule-local coordinates: positions unwrapped by minimum image along a
//! breadth-first tree of its bonds (so a chain longer than half the box is whole), and `A`
//! written back as `q` plus the displacement. The KKT system of a molecule is factored as
//! `L D Lᵀ` in skyline storage ([`kkt`]) with atoms in breadth-first order and constraint
//! rows interleaved: a water molecule is a dense 11×11 (bonds) or 12×12 (bonds and angle)
//! block, a 50-bead chain a band of width ≈ 7 (bonds) or ≈ 14 (bonds and angles), so the
//! cost is linear in the number of molecules and in the length of a chain. The last
//! factorization of Newton, at the solution, is reused for the Jacobian product.
//!
//! **Cost per outer step** (on top of impulse's `inner_steps` fast gradients and one slow
//! gradient, now at `A(q)`): no extra force evaluation; per molecule, `n + 1` KKT
//! assemblies and factorizations and `n` solves for `n` Newton iterations (3–4 on the
//! water box), then one solve for `A_qᵀ ∇U` (the projection Jacobian: one more
//! factorization). The run summary reports the mean and largest iteration counts.

mod kkt;
mod molecule;
mod schur;
pub mod selection;

use molecule::{Failure, MoleculeSolver};
pub use selection::{ConstraintKind, ConstraintSet, MoleculePlan, Selection, select};

use super::integrator::StepFailure;
use super::mollified::{MollifyAt, SlowMollifier};
use crate::error::{Error, Result};
use crate::settings::MethodSettings;
use crate::system::{PeriodicBox, System};

/// Which Jacobian of `A` the slow force is multiplied by (`--molly-jacobian`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MollyJacobian {
    /// The derivative of `A(q)`, curvature term included: conserves `K + W + U(A)`.
    Exact,
    /// The projection `I − Gᵀ(G M⁻¹ Gᵀ)⁻¹ G M⁻¹` of the older literature: does not.
    Projection,
}

impl MollyJacobian {
    pub fn parse(text: Option<&str>) -> Result<Self> {
        match text {
            None | Some("exact") => Ok(MollyJacobian::Exact),
            Some("projection") => Ok(MollyJacobian::Projection),
            Some(other) => Err(Error::setting(
                "molly_jacobian",
                format!("unknown molly_jacobian \"{other}\"; use exact or projection"),
            )
            .expected("exact or projection")
            .got_named(other)),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            MollyJacobian::Exact => "exact",
            MollyJacobian::Projection => "projection",
        }
    }
}

/// Newton stops when every relative residual is at most this (see the module comment).
pub const DEFAULT_TOLERANCE: f64 = 1e-10;
/// Newton iterations before the projection counts as failed.
pub const DEFAULT_MAX_ITERATIONS: usize = 50;
/// The largest `--max-iter` accepted (each iteration costs a factorization per molecule).
const MAX_ITERATIONS_LIMIT: usize = 10_000;

/// Newton statistics over a run, for the summary.
#[derive(Clone, Copy, Debug, Default)]
struct Statistics {
    projections: u64,
    iterations: u64,
    fallbacks: u64,
    most_iterations: usize,
}

/// The equilibrium mollifier: `A(q)` and `A_q(q)ᵀ`, a [`SlowMollifier`] for impulse.
pub struct EquilibriumMolly {
    set: ConstraintSet,
    jacobian: MollyJacobian,
    tolerance: f64,
    max_iterations: usize,
    dim: usize,
    periodic_box: Option<PeriodicBox>,
    molecules: Vec<MoleculeSolver>,
    /// `A(q)` of the last projection, every particle.
    projected: Vec<f64>,
    slow_gradient: Vec<f64>,
    counts: [usize; 3],
    statistics: Statistics,
    /// `U(A(q₀)) − U(q₀)` at setup: how much the mollified model differs at the start.
    start_shift: Option<f64>,
}

impl EquilibriumMolly {
    pub fn new(
        set: ConstraintSet,
        jacobian: MollyJacobian,
        tolerance: f64,
        max_iterations: usize,
    ) -> Result<Self> {
        if !(tolerance.is_finite() && tolerance > 0.0 && tolerance < 1.0) {
            return Err(Error::setting(
                "tol",
                "equilibrium-molly: the Newton tolerance --tol must be in (0, 1)",
            )
            .expected("a number in (0, 1)")
            .got(tolerance.to_string()));
        }
        if !(1..=MAX_ITERATIONS_LIMIT).contains(&max_iterations) {
            return Err(Error::setting(
                "max_iter",
                format!(
                    "equilibrium-molly: --max-iter must be between 1 and {MAX_ITERATIONS_LIMIT}"
                ),
            )
            .expected(format!("1 to {MAX_ITERATIONS_LIMIT}"))
            .got(max_iterations.to_string()));
        }
        Ok(EquilibriumMolly {
            set,
            jacobian,
            tolerance,
            max_iterations,
            dim: 0,
            periodic_box: None,
            molecules: Vec::new(),
            projected: Vec::new(),
            slow_gradient: Vec::new(),
            counts: [0; 3],
            statistics: Statistics::default(),
            start_shift: None,
        })
    }

    /// From `--molly-constraints`, `--molly-jacobian`, `--tol`, `--max-iter`.
    pub fn from_settings(settings: &MethodSettings) -> Result<Self> {
        EquilibriumMolly::new(
            ConstraintSet::parse(settings.molly_constraints.as_deref())?,
            MollyJacobian::parse(settings.molly_jacobian.as_deref())?,
            settings.tol.unwrap_or(DEFAULT_TOLERANCE),
            settings.max_iter.unwrap_or(DEFAULT_MAX_ITERATIONS),
        )
    }

    pub fn constraint_set(&self) -> ConstraintSet {
        self.set
    }

    pub fn jacobian(&self) -> MollyJacobian {
        self.jacobian
    }

    /// Held bonds, held 1–3 distances and molecules (after setup).
    pub fn counts(&self) -> [usize; 3] {
        self.counts
    }

    /// The molecules' plans (after setup).
    pub fn plans(&self) -> impl Iterator<Item = &MoleculePlan> {
        self.molecules.iter().map(MoleculeSolver::plan)
    }

    /// Choose the constraints and size every buffer for `system`.
    pub fn prepare(&mut self, system: &System) -> Result<()> {
        let selection = select(system, self.set)?;
        self.dim = system.dim;
        self.periodic_box = system.periodic_box;
        self.counts = [selection.bonds, selection.angles, selection.molecules.len()];
        let masses = &system.particles.masses;
        self.molecules = selection
            .molecules
            .into_iter()
            .map(|plan| MoleculeSolver::new(plan, masses, system.dim, self.jacobian))
            .collect();
        self.projected = vec![0.0; system.n_dofs()];
        self.slow_gradient = vec![0.0; system.n_dofs()];
        self.statistics = Statistics::default();
        Ok(())
    }

    /// `A(q)` (then [`EquilibriumMolly::projected`]); the KKT factors are kept for
    /// [`EquilibriumMolly::transpose_product`].
    pub fn project(&mut self, q: &[f64]) -> Result<(), StepFailure> {
        self.projected.copy_from_slice(q);
        for (index, molecule) in self.molecules.iter_mut().enumerate() {
            let periodic_box = self.periodic_box.as_ref();
            match molecule.project(q, periodic_box, self.tolerance, self.max_iterations) {
                Ok((iterations, fallbacks)) => {
                    self.statistics.iterations += iterations as u64;
                    self.statistics.fallbacks += fallbacks as u64;
                    self.statistics.most_iterations =
                        self.statistics.most_iterations.max(iterations);
                }
                Err(failure) => return Err(self.failure(index, failure)),
            }
            molecule.write_back(q, &mut self.projected);
        }
        self.statistics.projections += 1;
        Ok(())
    }

    fn failure(&self, index: usize, failure: Failure) -> StepFailure {
        let plan = self.molecules[index].plan();
        let first = plan.atoms.iter().min().copied().unwrap_or(0);
        let what = format!(
            "the projection of molecule {index} ({} atoms, the first is particle {first})",
            plan.atoms.len()
        );
        let angles = plan
            .constraints
            .iter()
            .any(|c| c.kind == ConstraintKind::Angle);
        let hint = if angles {
            " (a soft angle far from θ₀ may be the cause: try --molly-constraints bonds)"
        } else {
            ""
        };
        let message = match failure {
            Failure::NotConverged {
                residual,
                iterations,
            } => format!(
                "{what} did not converge: relative residual {residual:.3e} after {iterations} \
                 Newton iterations (tolerance {:e}); the positions are too far from the rest \
                 geometry",
                self.tolerance
            ),
            Failure::Singular { row, iterations } => format!(
                "{what} failed: its KKT matrix is singular at row {row} (Newton iteration \
                 {iterations}); the molecule is too distorted to project"
            ),
            Failure::Saddle { iterations } => format!(
                "{what} converged in {iterations} Newton iterations to a point that is not the \
                 closest one on the rest manifold; the molecule is too distorted to project"
            ),
        };
        StepFailure(message + hint)
    }

    /// `A(q)` of the last [`EquilibriumMolly::project`].
    pub fn projected(&self) -> &[f64] {
        &self.projected
    }

    /// `out = A_q(q)ᵀ v` at the `q` of the last [`EquilibriumMolly::project`] (`out = v` on
    /// particles no constraint holds).
    pub fn transpose_product(&mut self, v: &[f64], out: &mut [f64]) {
        out.copy_from_slice(v);
        for molecule in &mut self.molecules {
            molecule.transpose_product(v, out);
        }
    }

    fn selection_notice(&self, selection: &Selection) -> String {
        let largest = selection
            .molecules
            .iter()
            .map(|m| m.atoms.len())
            .max()
            .unwrap_or(0);
        let rows = selection
            .molecules
            .iter()
            .map(MoleculePlan::kkt_size)
            .max()
            .unwrap_or(0);
        let mut text = format!(
            "equilibrium-molly holds {} bonds{} at rest, in {} molecules of up to {largest} \
             atoms (KKT systems of up to {rows} rows); Jacobian {}, Newton to {:e} in at most \
             {} iterations",
            selection.bonds,
            match self.set {
                ConstraintSet::Bonds => String::new(),
                ConstraintSet::BondsAngles =>
                    format!(" and {} angles (as 1–3 distances)", selection.angles),
            },
            selection.molecules.len(),
            self.jacobian.name(),
            self.tolerance,
            self.max_iterations
        );
        if self.jacobian == MollyJacobian::Projection {
            text += "; the projection Jacobian is not the gradient of U(A(q)): \
                     mollified_total is not conserved";
        }
        text
    }
}

/// The left-out constraints, as a notice, if any.
fn skipped_notice(skipped: &selection::Skipped) -> Option<String> {
    let parts: Vec<String> = [
        (skipped.linear, "linear angles (θ₀ within 5° of 180°)"),
        (skipped.planar, "third angles of planar centres"),
        (
            skipped.redundant_angles,
            "angles redundant with those kept (rank check, or a 1–3 pair already held)",
        ),
        (
            skipped.without_arm,
            "angles whose arms are not both held bonds",
        ),
        (skipped.anchored, "angles at a fixed anchor"),
        (
            skipped.dependent_bonds,
            "bonds dependent on the others (rank check)",
        ),
    ]
    .iter()
    .filter(|(count, _)| *count > 0)
    .map(|(count, what)| format!("{count} {what}"))
    .collect();
    (!parts.is_empty()).then(|| format!("equilibrium-molly left out {}", parts.join(", ")))
}

/// Checkpoints: the mollifier keeps no state between steps that a continued run cannot
/// make again bit for bit. Newton starts from `A = q`, `μ = 0` at every call (no warm
/// start), so `A(q)`, the KKT factors and the slow gradient at `A(q)` are functions of
/// `q` (and of the pair lists, which the checkpoint restores), and the impulse method's
/// `setup` recomputes them at the checkpoint's positions ([`SlowMollifier::check_checkpoint`]
/// keeps its default). The Newton statistics and `slow_energy_shift_at_start` of the
/// summary then describe the continued part, as the step count and drift fit do.
impl SlowMollifier for EquilibriumMolly {
    fn name(&self) -> &'static str {
        "equilibrium-molly"
    }

    fn describe(&self) -> String {
        format!(
            "molly_constraints = {}, molly_jacobian = {}, tol = {:e}, max_iter = {}",
            self.set.name(),
            self.jacobian.name(),
            self.tolerance,
            self.max_iterations
        )
    }

    fn notices(&self, system: &System) -> Vec<String> {
        let Ok(selection) = select(system, self.set) else {
            return Vec::new(); // setup reports the error
        };
        let mut notices = vec![self.selection_notice(&selection)];
        notices.extend(skipped_notice(&selection.skipped));
        notices
    }

    fn setup(&mut self, system: &System) -> Result<()> {
        self.prepare(system)?;
        let top = system.forces.n_levels() - 1;
        self.start_shift = self.project(&system.state.q).ok().map(|()| {
            system.forces.energy(top, &self.projected) - system.forces.energy(top, &system.state.q)
        });
        self.statistics = Statistics::default();
        Ok(())
    }

    /// The projection of `q` onto the rest geometry (IRS99).
    fn mollify(&mut self, at: &mut MollifyAt<'_>) -> Result<(), StepFailure> {
        self.project(at.q)
    }

    fn pull_back(&mut self, _at: &mut MollifyAt<'_>, g: &[f64], out: &mut [f64]) {
        self.transpose_product(g, out);
    }

    fn slow_gradient_buffer(&mut self) -> &mut Vec<f64> {
        &mut self.slow_gradient
    }

    fn mollified_positions(&self) -> &[f64] {
        &self.projected
    }

    fn report(&self) -> Option<serde_json::Value> {
        let s = &self.statistics;
        Some(serde_json::json!({
            "kind": "equilibrium-molly",
            "molly_constraints": self.set.name(),
            "molly_jacobian": self.jacobian.name(),
            "bonds": self.counts[0],
            "angles": self.counts[1],
            "molecules": self.counts[2],
            "newton_tolerance": self.tolerance,
            "projections": s.projections,
            "mean_newton_iterations": if s.projections > 0 {
                s.iterations as f64 / s.projections as f64 / self.molecules.len().max(1) as f64
            } else { 0.0 },
            "max_newton_iterations": s.most_iterations,
            "newton_steps_without_curvature": s.fallbacks,
            "slow_energy_shift_at_start": self.start_shift,
        }))
    }
}
