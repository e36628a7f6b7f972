//! The asynchronous slow-fast pseudo-energy scheme of MEMM18 section 4 ((20)–(24)).
//!
//! The splitter's classes (MEMM18 4.1, [`ForceSplit::classify_particles`]): level 0 holds
//! the fast forces, every other level the slow ones; fast particles feel only fast forces,
//! slow particles only slow ones, mixed particles both. With `h_S = K h_F` and the coarse
//! interval `[t^n, t^{n+1}]` cut into `K` fine ones `[t^{n,m}, t^{n,m+1}]`:
//!
//! * slow particles fly freely over the whole coarse interval (23):
//!   `q̂_S(t) = q_S^n + (t − t^n) M_S⁻¹ p_S^{n+1/2}`;
//! * fast and mixed particles take `K` fine steps (20a), (21), each with the two-step
//!   momentum update (20b)/(22): `p^{n,m+3/2} = p^{n,m−1/2} − 2 ∫ ∂V/∂q dt` over the fine
//!   interval, the integrand evaluated with fast and mixed particles on their fine free
//!   flights and slow particles on their coarse one;
//! * slow particles then take one coarse step (24): `p_S^{n+3/2} = p_S^{n−1/2} − 2(Σ_m ∫
//!   ∂V_M/∂q_S over the fine intervals + ∫ ∂V_S/∂q_S over the coarse interval)`.
//!
//! Which slow terms go where: a slow term whose interactions touch a mixed particle (part
//! of `V_M`) is evaluated at every fine quadrature node, on a scratch position array that
//! holds the fine flights of fast and mixed particles and the coarse flight of the slow
//! ones; a slow term touching only slow particles (`V_S`) is evaluated at the coarse nodes.
//! Terms are evaluated whole, so a term mixing both kinds of interaction is evaluated on
//! the fine grid (its slow-only part then gets a finer, still exact-if-the-rule-is, quadrature
//! — Prop. 9 holds unchanged); [`Integrator::notices`] says when a scene could save work by
//! splitting such a term.
//!
//! Initialisation as (5): every half-step momentum starts at `p(t⁰)`. At the coarse nodes
//! the pseudo-energy (25) `H̃^n = V(q^n) + Σ_S ½ p^{n−1/2}·M⁻¹p^{n+1/2} + Σ_{F∪M} ½
//! p^{n,−1/2}·M⁻¹p^{n,1/2}` is conserved under exact force integration (Prop. 9).
//!
//! Cost per coarse step, for an `n`-node rule (`n − 1` for Gauss–Lobatto, whose end node is
//! the next interval's first): `K n` evaluations of the fast level and of the slow terms
//! touching mixed particles, `n` of the other slow terms — MEMM18 4.3.1's
//! `N_a = (n−1) T ((m+1)/h_F + m/h_S)` on the slow-fast FPU chain.
//!
//! On a chain that small an interaction costs less than the bookkeeping around it, so a
//! fine node does only: one index pass forming the fine and interface flights (and zeroing
//! their gradient), one call evaluating the fine grid's terms as a [`TermSet`], one index
//! pass accumulating; the nodes' products (`τ h_F`, `w h_F`, …) are computed in setup and a
//! step allocates nothing (docs/performance.md has the instruction counts).
//!
//! When the split leaves no slow particle (every particle feels a fast force, as in a
//! molecule where every atom is bonded), the scheme is the synchronous one at `h_F`: it
//! says so ([`Integrator::notices`], the summary) and runs [`PseudoEnergy`] with `K` steps
//! of `h_F` per outer step. The mass matrix must be diagonal (MEMM18 4.1).

use std::ops::Range;

use super::integrator::{Integrator, StepFailure, state_from_json, state_to_json};
use super::pseudo_energy::{PseudoEnergy, PseudoEnergyMonitor, StaggeredMomenta};
use super::quadrature::Quadrature;
use crate::error::{Error, Result};
use crate::settings::{MethodSettings, whole_ratio};
use crate::split::{ForceSplit, ParticleClass, TermSet};
use crate::system::System;

/// How the slow terms are evaluated, and which coordinates are slow.
#[derive(Clone, Debug, Default)]
pub struct AsyncPlan {
    /// Per level (index 0 unused): the slow terms touching a mixed particle (fine grid).
    pub fine_terms: Vec<Vec<usize>>,
    /// Per level (index 0 unused): the slow terms touching only slow particles (coarse grid).
    pub coarse_terms: Vec<Vec<usize>>,
    /// Coordinates of fast and mixed particles.
    pub fine_dofs: Vec<usize>,
    /// Coordinates of slow particles.
    pub slow_dofs: Vec<usize>,
    /// Coordinates of the slow particles the fine-grid slow terms touch (MEMM18's `V_M`
    /// partners of mixed particles): the only slow coordinates a fine step reads or writes.
    pub interface_dofs: Vec<usize>,
    /// `fine_dofs` and `interface_dofs`: everything a fine-grid evaluation writes.
    pub fine_written: Vec<usize>,
    /// The same sets as contiguous index ranges, for the loops of a step.
    fine_runs: Vec<Range<usize>>,
    slow_runs: Vec<Range<usize>>,
    fine_written_runs: Vec<Range<usize>>,
    /// `fine_written` with, per coordinate, whether it is an interface one (on the
    /// coarse flight (23) during a fine evaluation).
    fine_lanes: Vec<(usize, bool)>,
    pub n_fast: usize,
    pub n_mixed: usize,
    pub n_slow: usize,
    /// Terms evaluated on the fine grid that also hold slow-only interactions:
    /// `(name, all interactions, slow-only interactions)`.
    pub costly_terms: Vec<(String, usize, usize)>,
}

impl AsyncPlan {
    pub fn new(forces: &ForceSplit, n_particles: usize, dim: usize) -> Self {
        let classes = forces.classify_particles(n_particles);
        let n_levels = forces.n_levels();
        let mut plan = AsyncPlan {
            fine_terms: vec![Vec::new(); n_levels],
            coarse_terms: vec![Vec::new(); n_levels],
            ..Default::default()
        };
        for (i, class) in classes.iter().enumerate() {
            let dofs = (i * dim..(i + 1) * dim).collect::<Vec<_>>();
            match class {
                ParticleClass::Fast => {
                    plan.n_fast += 1;
                    plan.fine_dofs.extend(dofs);
                }
                ParticleClass::Mixed => {
                    plan.n_mixed += 1;
                    plan.fine_dofs.extend(dofs);
                }
                ParticleClass::Slow => {
                    plan.n_slow += 1;
                    plan.slow_dofs.extend(dofs);
                }
            }
        }
        for level in 1..n_levels {
            for &t in forces.level_terms(level) {
                let labelled = &forces.terms()[t];
                let couplings = labelled.term.couplings();
                let touches_mixed =
                    |c: &Vec<usize>| c.iter().any(|&i| classes[i] == ParticleClass::Mixed);
                let mixed = couplings.iter().filter(|c| touches_mixed(c)).count();
                if mixed > 0 {
                    plan.fine_terms[level].push(t);
                    for &i in couplings.iter().flatten() {
                        if classes[i] == ParticleClass::Slow {
                            plan.interface_dofs.extend(i * dim..(i + 1) * dim);
                        }
                    }
                    if mixed < couplings.len() {
                        plan.costly_terms.push((
                            labelled.name.clone(),
                            couplings.len(),
                            couplings.len() - mixed,
                        ));
                    }
                } else {
                    plan.coarse_terms[level].push(t);
                }
            }
        }
        plan.interface_dofs.sort_unstable();
        plan.interface_dofs.dedup();
        plan.fine_written = plan
            .fine_dofs
            .iter()
            .chain(&plan.interface_dofs)
            .copied()
            .collect();
        plan.fine_written.sort_unstable();
        plan.fine_runs = runs_of(&plan.fine_dofs);
        plan.slow_runs = runs_of(&plan.slow_dofs);
        plan.fine_written_runs = runs_of(&plan.fine_written);
        plan.fine_lanes = (plan.fine_written.iter())
            .map(|&i| (i, plan.interface_dofs.binary_search(&i).is_ok()))
            .collect();
        plan
    }

    /// One pass over the coordinates a fine evaluation writes, at fine node `τ` of fine
    /// step `m`: `out = q + s v` with `s = s_fine = τ h_F` on fast and mixed coordinates
    /// (20a) and `s = s_slow = (m + τ) h_F` on interface ones (the coarse flight (23)), and
    /// `gradient = 0` there. An index loop: on a few coordinates a contiguous loop's
    /// vector prologue costs more than the work (13 instructions per coordinate here
    /// against ≈ 140 per call for the run-wise loops on the slow-fast chain).
    fn fine_flights(&self, s: [f64; 2], q: &[f64], v: &[f64], out: &mut [f64], g: &mut [f64]) {
        let [s_fine, s_slow] = s;
        // All of one length, so one bounds check per coordinate serves every array.
        let n = q.len();
        let (v, out, g) = (&v[..n], &mut out[..n], &mut g[..n]);
        for &(i, coarse) in &self.fine_lanes {
            let s = if coarse { s_slow } else { s_fine };
            out[i] = q[i] + s * v[i];
            g[i] = 0.0;
        }
    }

    /// `integral += w g` on fast and mixed coordinates (the fine step's `Σ w ∇V`, (20b)),
    /// `integral += w h_F g` on interface ones (their share of `∫ ∂V_M/∂q_S`, (24b)), in
    /// one pass; `w = [w, w h_F]`.
    fn accumulate_fine(&self, w: [f64; 2], integral: &mut [f64], g: &[f64]) {
        let [w_fine, w_slow] = w;
        let n = integral.len();
        let g = &g[..n];
        for &(i, coarse) in &self.fine_lanes {
            let w = if coarse { w_slow } else { w_fine };
            integral[i] += w * g[i];
        }
    }
}

/// One node of the quadrature rule with the products every step reuses (fixed `h_F`,
/// `h_S = K h_F`): computed once in setup, the same bits as computing them per node.
#[derive(Clone, Copy, Debug)]
struct Node {
    tau: f64,
    w: f64,
    /// `τ h_F`: the fine flight's time offset.
    s_fine: f64,
    /// `w h_F`: the weight of an interface gradient in `∫ ∂V_M/∂q_S` (24b).
    w_fine: f64,
    /// `τ h_S`, `w h_S`: the coarse grid's offset and weight (23), (24b).
    s_coarse: f64,
    w_coarse: f64,
}

/// Sorted indices as maximal contiguous ranges.
fn runs_of(sorted: &[usize]) -> Vec<Range<usize>> {
    let mut runs: Vec<Range<usize>> = Vec::new();
    for &i in sorted {
        match runs.last_mut() {
            Some(run) if run.end == i => run.end = i + 1,
            _ => runs.push(i..i + 1),
        }
    }
    runs
}

/// `out = q + s v` on the runs (a free flight sampled at time offset `s`).
fn flight(runs: &[Range<usize>], out: &mut [f64], q: &[f64], v: &[f64], s: f64) {
    for r in runs {
        for ((o, qi), vi) in out[r.clone()]
            .iter_mut()
            .zip(&q[r.clone()])
            .zip(&v[r.clone()])
        {
            *o = qi + s * vi;
        }
    }
}

/// `acc += w g` on the runs.
fn accumulate(runs: &[Range<usize>], acc: &mut [f64], g: &[f64], w: f64) {
    for r in runs {
        for (a, gi) in acc[r.clone()].iter_mut().zip(&g[r.clone()]) {
            *a += w * gi;
        }
    }
}

fn zero(runs: &[Range<usize>], x: &mut [f64]) {
    for r in runs {
        x[r.clone()].fill(0.0);
    }
}

/// The two-step update on some coordinates: `p_next = p_minus − scale · integral`,
/// `q += h M⁻¹ p_plus`, then the half-step momenta (and velocities) shift by one.
struct HalfSteps<'a> {
    q: &'a mut [f64],
    p_minus: &'a mut [f64],
    p_plus: &'a mut [f64],
    v_minus: &'a mut [f64],
    v_plus: &'a mut [f64],
    integral: &'a [f64],
    inverse_mass: &'a [f64],
}

impl HalfSteps<'_> {
    /// An index loop over `dofs`: a fine step updates a few coordinates, for which a
    /// contiguous loop's vector set-up costs more than the work.
    fn advance(&mut self, dofs: &[usize], scale: f64, h: f64) {
        let n = self.q.len();
        let (p_minus, p_plus) = (&mut self.p_minus[..n], &mut self.p_plus[..n]);
        let (v_minus, v_plus) = (&mut self.v_minus[..n], &mut self.v_plus[..n]);
        let (integral, inverse_mass) = (&self.integral[..n], &self.inverse_mass[..n]);
        for &i in dofs {
            let next = p_minus[i] - scale * integral[i];
            self.q[i] += h * v_plus[i];
            p_minus[i] = p_plus[i];
            v_minus[i] = v_plus[i];
            p_plus[i] = next;
            v_plus[i] = inverse_mass[i] * next;
        }
    }
}

enum Mode {
    /// Not set up yet.
    Unset,
    Async,
    /// No slow particles: the synchronous scheme at `h_F`, `K` steps per outer step.
    Synchronous(Box<PseudoEnergy>),
}

pub struct AsyncPseudoEnergy {
    h_slow: f64,
    h_fast: f64,
    ratio: usize,
    quadrature: Quadrature,
    track: bool,
    mode: Mode,
    plan: AsyncPlan,
    /// `p^{n∓1/2}` (slow particles), `p^{n,∓1/2}` (fast and mixed), their velocities and
    /// the pseudo-energy monitor.
    staggered: StaggeredMomenta,
    /// On fast and mixed coordinates `Σ w ∇V` over the current fine step; on slow ones
    /// `∫ ∂V/∂q_S dt` over the coarse step (disjoint sets, so one array).
    integral: Vec<f64>,
    /// The fine grid's terms (fast level, then the slow terms touching mixed particles)
    /// and the coarse grid's (the other slow terms), each evaluated in one call.
    fine_set: TermSet,
    coarse_set: TermSet,
    nodes: Vec<Node>,
    gradient: Vec<f64>,
    scratch: Vec<f64>,
    fine_start: Vec<f64>,
    fine_end: Vec<f64>,
    fine_start_valid: bool,
    coarse_start: Vec<f64>,
    coarse_end: Vec<f64>,
    coarse_start_valid: bool,
}

impl AsyncPseudoEnergy {
    /// Coarse step `h_slow = ratio · h_fast`; the fine step is `h_slow / ratio`.
    pub fn new(h_slow: f64, ratio: usize, quadrature: Quadrature) -> Result<Self> {
        if !(h_slow.is_finite() && h_slow > 0.0) {
            return Err(
                Error::setting("h_slow", "coarse step h_slow must be positive and finite")
                    .expected("a positive finite step")
                    .got(h_slow.to_string()),
            );
        }
        if ratio == 0 {
            return Err(
                Error::setting("ratio", "ratio K = h_slow / h_fast must be at least 1")
                    .expected("a whole number ≥ 1")
                    .got(ratio.to_string()),
            );
        }
        Ok(AsyncPseudoEnergy {
            h_slow,
            h_fast: h_slow / ratio as f64,
            ratio,
            quadrature,
            track: true,
            mode: Mode::Unset,
            plan: AsyncPlan::default(),
            staggered: StaggeredMomenta::default(),
            integral: Vec::new(),
            fine_set: TermSet::default(),
            coarse_set: TermSet::default(),
            nodes: Vec::new(),
            gradient: Vec::new(),
            scratch: Vec::new(),
            fine_start: Vec::new(),
            fine_end: Vec::new(),
            fine_start_valid: false,
            coarse_start: Vec::new(),
            coarse_end: Vec::new(),
            coarse_start_valid: false,
        })
    }

    /// The coarse step is `--h-slow` (else `--h`); the fine step `--h-fast`, or the coarse
    /// one over `--ratio K` (both given: they must agree).
    pub fn from_settings(settings: &MethodSettings, notices: &mut Vec<String>) -> Result<Self> {
        let quadrature = Quadrature::by_name(settings.quadrature.as_deref().unwrap_or("midpoint"))?;
        let h_slow = settings.h_slow.unwrap_or(settings.h);
        if settings.h_slow.is_some() && (h_slow - settings.h).abs() > 1e-12 * h_slow {
            notices.push(format!(
                "async-pseudo-energy: the outer step is h_slow = {h_slow} (h = {} is not used)",
                settings.h
            ));
        }
        let ratio = match (settings.h_fast, settings.ratio) {
            (Some(h_fast), None) => {
                whole_ratio(h_slow, h_fast, "h_fast", "h_slow").map_err(|e| e.key("h_fast"))?
            }
            (None, Some(k)) => k,
            (Some(h_fast), Some(k)) => {
                let from_steps =
                    whole_ratio(h_slow, h_fast, "h_fast", "h_slow").map_err(|e| e.key("h_fast"))?;
                if from_steps != k {
                    return Err(Error::setting(
                        "ratio",
                        format!(
                            "h_slow / h_fast = {from_steps} but ratio = {k}: give one of \
                         --h-fast and --ratio, or consistent values"
                        ),
                    )
                    .expected(from_steps.to_string()));
                }
                k
            }
            (None, None) => {
                return Err(Error::setting(
                    "h_fast",
                    "async-pseudo-energy needs the fine step: give --h-fast or --ratio K \
                     (h_slow = K h_fast)",
                )
                .expected("--h-fast or --ratio K"));
            }
        };
        Self::new(h_slow, ratio, quadrature)
    }

    /// See [`PseudoEnergy::with_monitor`].
    pub fn with_monitor(mut self, track: bool) -> Self {
        self.track = track;
        self
    }

    pub fn h_slow(&self) -> f64 {
        self.h_slow
    }

    pub fn h_fast(&self) -> f64 {
        self.h_fast
    }

    pub fn ratio(&self) -> usize {
        self.ratio
    }

    /// Whether [`Integrator::setup`] fell back to the synchronous scheme.
    pub fn is_synchronous_fallback(&self) -> bool {
        matches!(self.mode, Mode::Synchronous(_))
    }

    pub fn plan(&self) -> &AsyncPlan {
        &self.plan
    }

    pub fn monitor(&self) -> &PseudoEnergyMonitor {
        match &self.mode {
            Mode::Synchronous(sync) => sync.monitor(),
            _ => &self.staggered.monitor,
        }
    }

    /// The state `Z = (q, p^{n−1/2}, p^{n+1/2})` at a coarse node (fast and mixed
    /// particles: `p^{n,−1/2}`, `p^{n,1/2}`), length `3 n_dofs`.
    pub fn state_vector(&self, system: &System, z: &mut [f64]) {
        if let Mode::Synchronous(sync) = &self.mode {
            return sync.state_vector(system, z);
        }
        self.staggered.state_vector(system, z);
    }

    /// Replace the state by `Z` (see [`AsyncPseudoEnergy::state_vector`]).
    pub fn set_state_vector(&mut self, system: &mut System, z: &[f64]) {
        if let Mode::Synchronous(sync) = &mut self.mode {
            return sync.set_state_vector(system, z);
        }
        self.staggered.set_state_vector(system, z);
        self.fine_start_valid = false;
        self.coarse_start_valid = false;
    }

    /// The term sets and node table a step reuses (setup).
    fn prepare(&mut self, forces: &ForceSplit) {
        let mut fine: Vec<usize> = forces.level_terms(0).to_vec();
        let mut coarse = Vec::new();
        for level in 1..forces.n_levels() {
            fine.extend(&self.plan.fine_terms[level]);
            coarse.extend(&self.plan.coarse_terms[level]);
        }
        self.fine_set = forces.term_set(&fine);
        self.coarse_set = forces.term_set(&coarse);
        let (h_fast, h_slow) = (self.h_fast, self.ratio as f64 * self.h_fast);
        let rule = &self.quadrature;
        self.nodes = (rule.nodes().iter().zip(rule.weights()))
            .map(|(&tau, &w)| Node {
                tau,
                w,
                s_fine: tau * h_fast,
                w_fine: w * h_fast,
                s_coarse: tau * h_slow,
                w_coarse: w * h_slow,
            })
            .collect();
    }

    /// Fine-grid gradient at `scratch` (only what the fine-grid terms write is zeroed and
    /// later read: a fine evaluation costs O(fast + mixed + interface)).
    fn fine_gradient(&mut self, forces: &mut ForceSplit) {
        zero(&self.plan.fine_written_runs, &mut self.gradient);
        forces.add_set_gradient(&self.fine_set, &self.scratch, &mut self.gradient);
    }

    fn coarse_gradient(&mut self, forces: &mut ForceSplit) {
        zero(&self.plan.slow_runs, &mut self.gradient);
        forces.add_set_gradient(&self.coarse_set, &self.scratch, &mut self.gradient);
    }

    /// Fine step `m` (20a), (20b)/(22) of the fast and mixed coordinates, adding the
    /// interface coordinates' share of `∫ ∂V_M/∂q_S` (24b) to `integral`. Per node one pass
    /// forms the flights (and zeroes the gradient), one call evaluates the fine set, one
    /// pass accumulates. Cost: one fine-set evaluation per node (`n − 1` for Gauss–Lobatto,
    /// whose first node is the previous fine step's last).
    fn fine_step(&mut self, system: &mut System, m: usize) {
        let ends = self.quadrature.has_end_nodes();
        let reuse_start = ends && self.fine_start_valid;
        let h_fast = self.h_fast;
        zero(&self.plan.fine_runs, &mut self.integral);
        // Slices held across the node loop (the evaluation writes the last node's
        // gradient straight into `fine_end`, kept for the next fine step).
        let Self {
            plan,
            nodes,
            fine_set,
            staggered,
            scratch,
            gradient,
            integral,
            fine_start,
            fine_end,
            ..
        } = self;
        let (q, forces) = (&system.state.q[..], &mut system.forces);
        for node in nodes.iter() {
            let reuse = node.tau == 0.0 && reuse_start;
            let gradient: &[f64] = if reuse {
                fine_start
            } else {
                let out = if node.tau == 1.0 && ends {
                    &mut fine_end[..]
                } else {
                    &mut gradient[..]
                };
                // Slow partners on their coarse flight (23), at the same time.
                let s = [node.s_fine, (m as f64 + node.tau) * h_fast];
                plan.fine_flights(s, q, &staggered.v_plus, scratch, out);
                forces.add_set_gradient(fine_set, scratch, out);
                out
            };
            plan.accumulate_fine([node.w, node.w_fine], integral, gradient);
        }
        // (20a), (20b)/(22) for fast and mixed particles.
        self.advance(system, false, 2.0 * h_fast, h_fast);
        if ends {
            std::mem::swap(&mut self.fine_start, &mut self.fine_end);
            self.fine_start_valid = true;
        }
    }

    /// `∫ ∂V_S/∂q_S` over the coarse interval (24b), added to `integral` on the slow
    /// coordinates. Cost: one coarse-set evaluation per node (`n − 1` for Gauss–Lobatto).
    fn coarse_integral(&mut self, system: &mut System) {
        let ends = self.quadrature.has_end_nodes();
        for node in &self.nodes {
            let reuse = node.tau == 0.0 && ends && self.coarse_start_valid;
            if !reuse {
                let (q, v) = (&system.state.q, &self.staggered.v_plus);
                flight(&self.plan.slow_runs, &mut self.scratch, q, v, node.s_coarse);
                zero(&self.plan.slow_runs, &mut self.gradient);
                let forces = &mut system.forces;
                forces.add_set_gradient(&self.coarse_set, &self.scratch, &mut self.gradient);
            }
            let gradient = if reuse {
                &self.coarse_start
            } else {
                &self.gradient
            };
            let runs = &self.plan.slow_runs;
            accumulate(runs, &mut self.integral, gradient, node.w_coarse);
            if node.tau == 1.0 && ends {
                std::mem::swap(&mut self.coarse_end, &mut self.gradient);
            }
        }
        if ends {
            std::mem::swap(&mut self.coarse_start, &mut self.coarse_end);
            self.coarse_start_valid = true;
        }
    }

    /// The two-step update with `integral` on the slow (else the fast and mixed)
    /// coordinates.
    fn advance(&mut self, system: &mut System, slow: bool, scale: f64, h: f64) {
        let dofs = if slow {
            &self.plan.slow_dofs
        } else {
            &self.plan.fine_dofs
        };
        let staggered = &mut self.staggered;
        HalfSteps {
            q: &mut system.state.q,
            p_minus: &mut staggered.p_minus,
            p_plus: &mut staggered.p_plus,
            v_minus: &mut staggered.v_minus,
            v_plus: &mut staggered.v_plus,
            integral: &self.integral,
            inverse_mass: &system.inverse_mass,
        }
        .advance(dofs, scale, h);
    }

    /// One coarse step: `K` fine steps, the coarse integral, (24a)/(24b) for the slow
    /// particles. Allocates nothing.
    fn async_step(&mut self, system: &mut System) {
        // h_S as K h_F, so the slow flight sampled at the last fine node and the slow
        // drift agree to the last bit (the end gradient is reused).
        let h_slow = self.ratio as f64 * self.h_fast;
        zero(&self.plan.slow_runs, &mut self.integral);
        for m in 0..self.ratio {
            self.fine_step(system, m);
        }
        if !self.coarse_set.is_empty() {
            self.coarse_integral(system);
        }
        // (24a), (24b) for slow particles.
        self.advance(system, true, 2.0, h_slow);
        self.staggered.sync_state(system);
    }
}

impl Integrator for AsyncPseudoEnergy {
    /// The staggered momenta of both grids and the pseudo-energy statistics (the
    /// synchronous fallback's own state when it runs). Nothing else carries over a coarse
    /// step: `integral` is zeroed where each step starts, the cached end-node gradients
    /// are recomputed by `setup` at the same positions (the flights end on the drifts'
    /// bits, `h_S = K h_F`).
    fn save_state(&self) -> Result<serde_json::Value> {
        match &self.mode {
            Mode::Synchronous(sync) => sync.save_state(),
            Mode::Async => state_to_json(self.name(), &self.staggered),
            Mode::Unset => Err(Error::input(format!(
                "{}: a checkpoint before setup",
                self.name()
            ))),
        }
    }

    /// Restore what [`Integrator::save_state`] saved, after `setup` chose the same mode
    /// (the split of the same system).
    fn restore_state(&mut self, state: &serde_json::Value) -> Result<()> {
        let name = self.name();
        match &mut self.mode {
            Mode::Synchronous(sync) => sync.restore_state(state),
            Mode::Async => {
                let saved: StaggeredMomenta = state_from_json(name, state)?;
                self.staggered.restore(name, saved)
            }
            Mode::Unset => Err(Error::input(format!("{name}: a restore before setup"))),
        }
    }

    fn name(&self) -> &'static str {
        "async-pseudo-energy"
    }

    fn describe(&self) -> String {
        let fallback = if self.is_synchronous_fallback() {
            " (no slow particles: synchronous at h_fast)"
        } else {
            ""
        };
        format!(
            "h_slow = {}, h_fast = {}, K = {}, quadrature {}{fallback}",
            self.h_slow,
            self.h_fast,
            self.ratio,
            self.quadrature.name()
        )
    }

    fn outer_step(&self) -> f64 {
        self.h_slow
    }

    fn setup(&mut self, system: &mut System) -> Result<()> {
        if system.mass_matrix.is_some() {
            return Err(Error::input(
                "async-pseudo-energy needs a diagonal mass matrix (MEMM18 4.1)",
            ));
        }
        self.plan = AsyncPlan::new(&system.forces, system.n_particles(), system.dim);
        if self.plan.n_slow == 0 {
            let mut sync =
                PseudoEnergy::new(self.h_fast, self.quadrature.clone())?.with_monitor(self.track);
            sync.setup(system)?;
            self.mode = Mode::Synchronous(Box::new(sync));
            return Ok(());
        }
        self.mode = Mode::Async;
        let n = system.n_dofs();
        self.staggered.start(system);
        self.integral = vec![0.0; n];
        self.prepare(&system.forces);
        self.gradient = vec![0.0; n];
        self.scratch = system.state.q.clone();
        self.fine_start = vec![0.0; n];
        self.fine_end = vec![0.0; n];
        self.coarse_start = vec![0.0; n];
        self.coarse_end = vec![0.0; n];
        self.fine_start_valid = false;
        self.coarse_start_valid = false;
        if self.quadrature.has_end_nodes() {
            self.fine_gradient(&mut system.forces);
            self.fine_start.copy_from_slice(&self.gradient);
            self.fine_start_valid = true;
            if !self.coarse_set.is_empty() {
                self.coarse_gradient(&mut system.forces);
                self.coarse_start.copy_from_slice(&self.gradient);
                self.coarse_start_valid = true;
            }
        }
        self.staggered.start_monitor(system);
        Ok(())
    }

    fn step(&mut self, system: &mut System) -> Result<(), StepFailure> {
        match &mut self.mode {
            Mode::Unset => Err(StepFailure("step before setup".into())),
            Mode::Synchronous(sync) => {
                for _ in 0..self.ratio {
                    sync.step(system)?;
                }
                Ok(())
            }
            Mode::Async => {
                self.async_step(system);
                system.state.t += self.h_slow;
                if self.track {
                    self.staggered.record(system);
                }
                Ok(())
            }
        }
    }

    fn extra_columns(&self) -> Vec<&'static str> {
        vec!["pseudo_energy", "discrete_energy"]
    }

    fn extra_values(&self, system: &System, out: &mut Vec<f64>) {
        match &self.mode {
            Mode::Synchronous(sync) => sync.extra_values(system, out),
            _ => {
                let (pseudo, discrete) = self.staggered.energies(system);
                out.extend([pseudo, discrete]);
            }
        }
    }

    fn notices(&self, system: &System) -> Vec<String> {
        let plan = AsyncPlan::new(&system.forces, system.n_particles(), system.dim);
        let mut notices = Vec::new();
        if plan.n_slow == 0 {
            notices.push(format!(
                "async-pseudo-energy: no slow particles ({} fast, {} mixed): every particle \
                 feels a fast force, so there is nothing to step at h_slow; running the \
                 synchronous pseudo-energy scheme at h_fast = {} instead",
                plan.n_fast, plan.n_mixed, self.h_fast
            ));
        } else {
            notices.push(format!(
                "async-pseudo-energy: {} fast, {} mixed, {} slow particles (MEMM18 4.1)",
                plan.n_fast, plan.n_mixed, plan.n_slow
            ));
            for (name, all, slow_only) in &plan.costly_terms {
                notices.push(format!(
                    "async-pseudo-energy: slow term \"{name}\" touches mixed particles, so all \
                     {all} of its interactions are evaluated at every fine step, {slow_only} \
                     of them joining slow particles only; a term of their own would evaluate \
                     them once per coarse step"
                ));
            }
        }
        notices
    }

    fn report(&self) -> Option<(&'static str, serde_json::Value)> {
        let mut map = self.monitor().to_json();
        map.insert("quadrature".into(), self.quadrature.name().into());
        map.insert("ratio".into(), self.ratio.into());
        map.insert("h_fast".into(), self.h_fast.into());
        map.insert("h_slow".into(), self.h_slow.into());
        map.insert(
            "scheme".into(),
            if self.is_synchronous_fallback() {
                "synchronous (no slow particles)"
            } else {
                "asynchronous"
            }
            .into(),
        );
        map.insert("fast_particles".into(), self.plan.n_fast.into());
        map.insert("mixed_particles".into(), self.plan.n_mixed.into());
        map.insert("slow_particles".into(), self.plan.n_slow.into());
        Some(("pseudo_energy", serde_json::Value::Object(map)))
    }
}
