//! Adaptive Verlet (HL97 section 4.2): time-reversible variable steps for
//! `H = pᵀM⁻¹p/2 + V(q)` by integrating the time-reparameterised equations
//! `dq/ds = M⁻¹p/ρ`, `dp/ds = −∇V(q)/ρ`, `dt/ds = 1/ρ`, `ρ = R(q, p)` (HL97 (4.7)–(4.8))
//! with a fixed fictive step `Δs` (`--h`) as a differential-algebraic system:
//!
//! * (4.19) `q_{n+1} = q_n + (Δs/ρ_{n+½}) M⁻¹ p_{n+½}`
//! * (4.20) `p_{n+½} = p_{n−½} − (Δs/2) ∇V(q_n) (1/ρ_{n−½} + 1/ρ_{n+½})`
//! * (4.21) `ρ_{n+½} + ρ_{n−½} = R(q_n, p_{n+½}) + R(q_n, p_{n−½})`
//! * (4.22) `t_{n+1} = t_n + Δs/ρ_{n+½}`
//!
//! With `Δt_n = Δs/ρ_{n+½}` this is velocity Verlet with step `Δt_n` (HL97's "variable
//! stepsize Störmer rule"), and the state keeps the synchronised momentum
//! `p_n = p_{n+½} + (Δt_n/2)∇V(q_n)`, so energies are measured at whole steps as for
//! Verlet; `p_{n−½}` is recovered as `p_n + (Δs/2ρ_{n−½})∇V(q_n)`.
//!
//! (4.21) is one scalar equation for `ρ_{n+½}`. For the arclength control
//! `R = (pᵀM⁻²p + |∇V|²)^{1/2}` (HL97 section 3, `R = ‖f‖`) it is the quartic of (4.23)
//! (`|M⁻¹p_{n+½}|²` is a quadratic in `1/ρ`); it is solved here, as it would be for any
//! other `R(q, p)`, by a bracketing Brent root finder on
//! `F(ρ) = ρ + ρ_{n−½} − R(q_n, p_{n+½}(ρ)) − R(q_n, p_{n−½})`, searching outward from
//! `ρ_{n−½}` so the branch continues the previous step's. Every evaluation of `F` reuses
//! the gradient `∇V(q_n)` already computed: the root finder costs no force evaluation,
//! only a few dot products (their count is the `root_evaluations` column). For the
//! minimum-distance control `R = r_min^{−α}` (HL97 section 3; `r_min` the smallest
//! distance of any non-bonded pair interaction, anchors included) `R` depends on `q` only
//! and (4.21) is explicit: `ρ_{n+½} = 2R(q_n) − ρ_{n−½}`.
//!
//! Step bounds (HL97 section 3): `R` is replaced by
//! `√(R² + m²) / (√(R² + m²)/M + 1)` with `m = Δs/Δt_max`, `M = Δs/Δt_min`, which keeps
//! `Δt` between about `--h-min` and `--h-max`; without a bound the corresponding `m = 0`
//! or `M = ∞`. Starting step (HL97, end of 4.2): `ρ_{½} = R(q₀, p_{½})` with
//! `p_{½} = p₀ − (Δs/2ρ_{½})∇V(q₀)`, solved the same way (explicit for min-distance).
//!
//! Properties: second order; time-reversible (the map `(q_n, p_n, ρ_{n−½})` →
//! `(q_{n+1}, p_{n+1}, ρ_{n+½})` run with `p` negated and `ρ_{n+½}` as its `ρ_{−½}`
//! retraces the steps, see [`AdaptiveVerlet::reverse`]); conserves the angular momentum
//! for central forces; not symplectic. Cost per step: one gradient evaluation of every
//! force level (the end-of-step gradient is the next step's first), as for Verlet, plus
//! the scalar root finding (arclength) or one pass over the pair distances
//! (min-distance), neither of them a force evaluation.

use super::integrator::{Integrator, StepFailure, drift, kick, state_from_json, state_to_json};
use crate::error::{Error, Result};
use crate::forces::TermClass;
use crate::system::System;

/// The step control `R` of HL97 section 3.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Control {
    /// `R = (pᵀM⁻²p + |∇V(q)|²)^{1/2}`, the norm of the vector field.
    Arclength,
    /// `R = r_min^{−α}` over the non-bonded pair interactions.
    MinDistance { alpha: f64 },
}

impl Control {
    /// The exponent of `min-distance` when none is given: Δt ∝ r^{3/2} follows the
    /// Kepler time scale of a close gravitational encounter.
    pub const DEFAULT_ALPHA: f64 = 1.5;

    /// `arclength`, `min-distance` or `min-distance=α` (for example `min-distance=2`).
    pub fn parse(text: &str) -> Result<Self> {
        let text = text.trim();
        match text.split_once('=') {
            None if text == "arclength" => Ok(Control::Arclength),
            None if text == "min-distance" => Ok(Control::MinDistance {
                alpha: Self::DEFAULT_ALPHA,
            }),
            Some((name, alpha)) if name.trim() == "min-distance" => {
                let alpha: f64 = alpha.trim().parse().map_err(|_| {
                    Error::setting(
                        "control",
                        format!(
                            "control \"{text}\": the exponent α after min-distance= must be a \
                         number"
                        ),
                    )
                    .expected("min-distance=ALPHA with a number ALPHA")
                    .got(format!("\"{}\"", alpha.trim()))
                })?;
                if !(alpha.is_finite() && alpha > 0.0) {
                    return Err(Error::setting(
                        "control",
                        format!("control \"{text}\": the exponent α must be positive"),
                    )
                    .expected("a positive exponent α")
                    .got(alpha.to_string()));
                }
                Ok(Control::MinDistance { alpha })
            }
            _ => Err(Error::setting(
                "control",
                format!(
                    "unknown step control \"{text}\" for adaptive-verlet; known: arclength, \
                 min-distance, min-distance=ALPHA"
                ),
            )
            .expected("arclength, min-distance or min-distance=ALPHA")
            .got_named(format!("\"{text}\""))),
        }
    }
}

impl std::fmt::Display for Control {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Control::Arclength => write!(f, "arclength"),
            Control::MinDistance { alpha } => write!(f, "min-distance (alpha = {alpha})"),
        }
    }
}

/// Dot products that make `R(q_n, p_n − σ∇V(q_n))` a closed form in the kick scale `σ`:
/// `|M⁻¹(p − σg)|² = a − 2σb + σ²c`, plus `|g|²`.
#[derive(Clone, Copy, Debug, Default)]
struct Arclength {
    a: f64,
    b: f64,
    c: f64,
    force_squared: f64,
}

impl Arclength {
    fn new(p: &[f64], gradient: &[f64], inverse_mass: &[f64]) -> Self {
        let mut s = Arclength::default();
        for ((pi, gi), wi) in p.iter().zip(gradient).zip(inverse_mass) {
            let (u, w) = (wi * pi, wi * gi);
            s.a += u * u;
            s.b += u * w;
            s.c += w * w;
            s.force_squared += gi * gi;
        }
        s
    }

    fn value(&self, sigma: f64) -> f64 {
        // Rounding can make the quadratic a hair negative when p − σg ≈ 0.
        let velocity_squared = (self.a - 2.0 * sigma * self.b + sigma * sigma * self.c).max(0.0);
        (velocity_squared + self.force_squared).sqrt()
    }
}

pub struct AdaptiveVerlet {
    /// The fictive step `Δs`.
    fictive_step: f64,
    control: Control,
    h_min: Option<f64>,
    h_max: Option<f64>,
    /// HL97's `m = Δs/Δt_max` (0 without a maximum).
    lower: f64,
    /// HL97's `M = Δs/Δt_min` (∞ without a minimum).
    upper: f64,
    gradient: Vec<f64>,
    /// `ρ_{n−½}`; `None` before the starting step.
    rho_half: Option<f64>,
    last_dt: f64,
    last_root_evaluations: u32,
    root_evaluations: u64,
    smallest_dt: f64,
    largest_dt: f64,
}

/// Evaluations of `F` the root finder may spend (bracketing included) before it gives up;
/// Brent needs a few dozen at most once a bracket is found.
const MAX_ROOT_EVALUATIONS: u32 = 300;

impl AdaptiveVerlet {
    pub fn new(
        fictive_step: f64,
        control: Control,
        h_min: Option<f64>,
        h_max: Option<f64>,
    ) -> Result<Self> {
        if !(fictive_step.is_finite() && fictive_step > 0.0) {
            return Err(
                Error::setting("h", "fictive step Δs (--h) must be positive and finite")
                    .expected("a positive finite step")
                    .got(fictive_step.to_string()),
            );
        }
        for (name, bound) in [("h_min", h_min), ("h_max", h_max)] {
            if let Some(b) = bound
                && !(b.is_finite() && b > 0.0)
            {
                return Err(
                    Error::setting(name, format!("{name} must be positive and finite"))
                        .expected("a positive finite number")
                        .got(b.to_string()),
                );
            }
        }
        if let (Some(lo), Some(hi)) = (h_min, h_max)
            && lo >= hi
        {
            return Err(Error::setting(
                "h_min",
                format!("h_min must be smaller than h_max = {hi}"),
            )
            .expected(format!("less than h_max = {hi}"))
            .got(lo.to_string()));
        }
        Ok(AdaptiveVerlet {
            fictive_step,
            control,
            h_min,
            h_max,
            lower: h_max.map_or(0.0, |h| fictive_step / h),
            upper: h_min.map_or(f64::INFINITY, |h| fictive_step / h),
            gradient: Vec::new(),
            rho_half: None,
            last_dt: f64::NAN,
            last_root_evaluations: 0,
            root_evaluations: 0,
            smallest_dt: f64::INFINITY,
            largest_dt: 0.0,
        })
    }

    /// `ρ_{n−½}` of the last step (`None` before the first).
    pub fn rho_half(&self) -> Option<f64> {
        self.rho_half
    }

    /// The physical step `Δt` of the last step.
    pub fn last_step(&self) -> f64 {
        self.last_dt
    }

    /// Smallest and largest physical step so far.
    pub fn step_range(&self) -> (f64, f64) {
        (self.smallest_dt, self.largest_dt)
    }

    /// Evaluations of the scalar equation (4.21) so far, over all steps.
    pub fn root_evaluations(&self) -> u64 {
        self.root_evaluations
    }

    /// HL97 section 3: `R` with the step bounds built in.
    fn bounded(&self, r: f64) -> f64 {
        if self.lower == 0.0 && self.upper == f64::INFINITY {
            return r;
        }
        let shifted = (r * r + self.lower * self.lower).sqrt();
        shifted / (shifted / self.upper + 1.0)
    }

    /// `r_min^{−α}` over the non-bonded pair terms.
    fn min_distance_control(system: &System, alpha: f64) -> f64 {
        let r_min = system
            .forces
            .terms()
            .iter()
            .filter(|t| t.term.class() == TermClass::Nonbonded)
            .filter_map(|t| t.term.min_distance(&system.state.q))
            .fold(f64::INFINITY, f64::min);
        r_min.powf(-alpha)
    }

    /// `ρ_{n+½}` from the current state `(q_n, p_n)`, `∇V(q_n)` and `ρ_{n−½}` (or the
    /// starting value when `rho_half` is `None`), without changing anything but the
    /// root-evaluation counts.
    fn next_rho(&mut self, system: &System) -> Result<f64, StepFailure> {
        let half_ds = 0.5 * self.fictive_step;
        let rho = match self.control {
            Control::MinDistance { alpha } => {
                let r = self.bounded(Self::min_distance_control(system, alpha));
                self.last_root_evaluations = 0;
                match self.rho_half {
                    None => r,
                    Some(previous) => 2.0 * r - previous,
                }
            }
            Control::Arclength => {
                let closed = Arclength::new(&system.state.p, &self.gradient, &system.inverse_mass);
                // F(ρ) = ρ − offset − R(q_n, p_n − (Δs/2ρ)∇V(q_n)).
                let (offset, guess) = match self.rho_half {
                    None => (0.0, self.bounded(closed.value(0.0))),
                    Some(previous) => {
                        // p_{n−½} = p_n + (Δs/2ρ_{n−½})∇V(q_n): σ = −Δs/(2ρ_{n−½}).
                        let r_previous = self.bounded(closed.value(-half_ds / previous));
                        (r_previous - previous, previous)
                    }
                };
                let f = |rho: f64| rho - offset - self.bounded(closed.value(half_ds / rho));
                let (root, evaluations) = solve_positive_root(f, guess).ok_or_else(|| {
                    StepFailure(format!(
                        "no positive solution ρ of the step equation HL97 (4.21) near \
                         ρ = {guess:.6e} at t = {}: the step control broke down (try a \
                         smaller Δs or set h_min/h_max)",
                        system.state.t
                    ))
                })?;
                self.last_root_evaluations = evaluations;
                root
            }
        };
        self.root_evaluations += self.last_root_evaluations as u64;
        if !(rho.is_finite() && rho > 0.0) {
            return Err(StepFailure(format!(
                "the step control gave ρ = {rho:e} at t = {} (it must be positive and \
                 finite): the two-step recursion HL97 (4.21) broke down; use a smaller Δs \
                 or set h_min/h_max",
                system.state.t
            )));
        }
        Ok(rho)
    }

    /// Reverse the direction of time: negate the momenta and take as `ρ_{−½}` of the
    /// reversed run the `ρ_{n+½}` the forward run would take next. N steps after this,
    /// N forward steps are undone (to round-off): HL97's time reversibility. Costs no
    /// force evaluation. Before the first step only the momenta are negated.
    pub fn reverse(&mut self, system: &mut System) -> Result<(), StepFailure> {
        if self.rho_half.is_some() {
            let next = self.next_rho(system)?;
            self.rho_half = Some(next);
        }
        for p in system.state.p.iter_mut() {
            *p = -*p;
        }
        Ok(())
    }
}

/// The positive root of `f` nearest `guess` on its side: bracket by doubling or halving
/// from `guess` until `f` changes sign, then Brent's method to about two ulps. Returns the
/// root and the number of evaluations of `f`, or `None` when no sign change is found or
/// the evaluations run out.
pub fn solve_positive_root(mut f: impl FnMut(f64) -> f64, guess: f64) -> Option<(f64, u32)> {
    if !(guess.is_finite() && guess > 0.0) {
        return None;
    }
    let mut evaluations = 1;
    let f_guess = f(guess);
    if f_guess == 0.0 {
        return Some((guess, evaluations));
    }
    if !f_guess.is_finite() {
        return None;
    }
    // Walk away from the guess in the direction that changes the sign (F grows with ρ
    // on the branch of interest: F → +∞ as ρ → ∞).
    let factor = if f_guess < 0.0 { 2.0 } else { 0.5 };
    let (mut near, mut f_near) = (guess, f_guess);
    loop {
        let far = near * factor;
        let f_far = f(far);
        evaluations += 1;
        if !(far.is_finite() && far > 0.0 && f_far.is_finite())
            || evaluations > MAX_ROOT_EVALUATIONS
        {
            return None;
        }
        if f_far == 0.0 {
            return Some((far, evaluations));
        }
        if (f_far < 0.0) != (f_near < 0.0) {
            let (root, used) = brent(&mut f, near, f_near, far, f_far, MAX_ROOT_EVALUATIONS)?;
            return Some((root, evaluations + used));
        }
        near = far;
        f_near = f_far;
    }
}

/// Brent's method (zeroin) on a bracket `[a, b]` with `f(a) f(b) < 0`, to a tolerance of
/// `2ε|x|`. Returns the root and the number of evaluations of `f`.
fn brent(
    f: &mut impl FnMut(f64) -> f64,
    mut a: f64,
    mut fa: f64,
    mut b: f64,
    mut fb: f64,
    max_evaluations: u32,
) -> Option<(f64, u32)> {
    let (mut c, mut fc) = (a, fa);
    let mut d = b - a;
    let mut e = d;
    for evaluations in 0..max_evaluations {
        if (fb > 0.0) == (fc > 0.0) {
            c = a;
            fc = fa;
            d = b - a;
            e = d;
        }
        if fc.abs() < fb.abs() {
            a = b;
            b = c;
            c = a;
            fa = fb;
            fb = fc;
            fc = fa;
        }
        let tol = 2.0 * f64::EPSILON * b.abs() + 0.5 * f64::MIN_POSITIVE;
        let m = 0.5 * (c - b);
        if m.abs() <= tol || fb == 0.0 {
            return Some((b, evaluations));
        }
        if e.abs() >= tol && fa.abs() > fb.abs() {
            // Inverse quadratic interpolation, or the secant when only two points differ.
            let s = fb / fa;
            let (mut p, mut q) = if a == c {
                (2.0 * m * s, 1.0 - s)
            } else {
                let q = fa / fc;
                let r = fb / fc;
                (
                    s * (2.0 * m * q * (q - r) - (b - a) * (r - 1.0)),
                    (q - 1.0) * (r - 1.0) * (s - 1.0),
                )
            };
            if p > 0.0 {
                q = -q;
            } else {
                p = -p;
            }
            if 2.0 * p < (3.0 * m * q - (tol * q).abs()).min((e * q).abs()) {
                e = d;
                d = p / q;
            } else {
                d = m;
                e = m;
            }
        } else {
            d = m;
            e = m;
        }
        a = b;
        fa = fb;
        b += if d.abs() > tol { d } else { tol.copysign(m) };
        fb = f(b);
        if !fb.is_finite() {
            return None;
        }
    }
    None
}

impl Integrator for AdaptiveVerlet {
    fn name(&self) -> &'static str {
        "adaptive-verlet"
    }

    fn describe(&self) -> String {
        let bound = |b: Option<f64>| b.map_or("none".to_string(), |b| b.to_string());
        format!(
            "Δs = {}, control = {}, h_min = {}, h_max = {}",
            self.fictive_step,
            self.control,
            bound(self.h_min),
            bound(self.h_max)
        )
    }

    fn outer_step(&self) -> f64 {
        self.fictive_step
    }

    fn setup(&mut self, system: &mut System) -> Result<()> {
        if let Control::MinDistance { .. } = self.control {
            let has_pairs = system.forces.terms().iter().any(|t| {
                t.term.class() == TermClass::Nonbonded
                    && t.term.min_distance(&system.state.q).is_some()
            });
            if !has_pairs {
                return Err(Error::setting(
                    "control",
                    "adaptive-verlet --control min-distance needs a non-bonded pair \
                     interaction (gravity, Lennard-Jones, inverse-power) to measure r_min",
                )
                .expected("a scene with a non-bonded pair term"));
            }
        }
        self.gradient = vec![0.0; system.n_dofs()];
        system
            .forces
            .total_gradient(&system.state.q, &mut self.gradient);
        self.rho_half = None;
        self.last_dt = f64::NAN;
        self.root_evaluations = 0;
        self.last_root_evaluations = 0;
        self.smallest_dt = f64::INFINITY;
        self.largest_dt = 0.0;
        Ok(())
    }

    fn step(&mut self, system: &mut System) -> Result<(), StepFailure> {
        let rho = self.next_rho(system)?;
        let dt = self.fictive_step / rho;
        let half = 0.5 * dt;
        let state = &mut system.state;
        kick(&mut state.p, &self.gradient, half);
        drift(&mut state.q, &state.p, &system.inverse_mass, dt);
        system.forces.total_gradient(&state.q, &mut self.gradient);
        kick(&mut state.p, &self.gradient, half);
        state.t += dt;
        self.rho_half = Some(rho);
        self.last_dt = dt;
        self.smallest_dt = self.smallest_dt.min(dt);
        self.largest_dt = self.largest_dt.max(dt);
        Ok(())
    }

    fn fixed_step(&self) -> bool {
        false
    }

    /// HL97's `ρ_{n−½}` (the next step's root search starts from it) and the step
    /// statistics; the gradient is recomputed by `setup`.
    fn save_state(&self) -> Result<serde_json::Value> {
        let state = AdaptiveState {
            rho_half: self.rho_half,
            last_dt: self.last_dt.is_finite().then_some(self.last_dt),
            last_root_evaluations: self.last_root_evaluations,
            root_evaluations: self.root_evaluations,
            smallest_dt: self.smallest_dt.is_finite().then_some(self.smallest_dt),
            largest_dt: self.largest_dt,
        };
        state_to_json(self.name(), &state)
    }

    fn restore_state(&mut self, state: &serde_json::Value) -> Result<()> {
        let saved: AdaptiveState = state_from_json(self.name(), state)?;
        self.rho_half = saved.rho_half;
        self.last_dt = saved.last_dt.unwrap_or(f64::NAN);
        self.last_root_evaluations = saved.last_root_evaluations;
        self.root_evaluations = saved.root_evaluations;
        self.smallest_dt = saved.smallest_dt.unwrap_or(f64::INFINITY);
        self.largest_dt = saved.largest_dt;
        Ok(())
    }

    fn extra_columns(&self) -> Vec<&'static str> {
        vec!["dt", "root_evaluations"]
    }

    fn extra_values(&self, _system: &System, out: &mut Vec<f64>) {
        out.push(self.last_dt);
        out.push(self.last_root_evaluations as f64);
    }
}

/// What a checkpoint holds of adaptive Verlet.
#[derive(serde::Serialize, serde::Deserialize)]
struct AdaptiveState {
    rho_half: Option<f64>,
    /// `None` before the first step (NaN then).
    last_dt: Option<f64>,
    last_root_evaluations: u32,
    root_evaluations: u64,
    smallest_dt: Option<f64>,
    largest_dt: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn controls_parse() {
        assert_eq!(Control::parse("arclength").unwrap(), Control::Arclength);
        assert_eq!(
            Control::parse("min-distance").unwrap(),
            Control::MinDistance { alpha: 1.5 }
        );
        assert_eq!(
            Control::parse("min-distance=2").unwrap(),
            Control::MinDistance { alpha: 2.0 }
        );
        for bad in ["curvature", "min-distance=x", "min-distance=-1"] {
            assert!(Control::parse(bad).is_err(), "{bad}");
        }
    }

    /// A quartic with a known root, from either side: Brent must land within its
    /// tolerance of two ulps of the root.
    #[test]
    fn root_finder_finds_the_root_from_either_side() {
        let root = 3.7;
        let f = |x: f64| (x - root) * (x * x + 1.0) * (x + 0.5);
        for guess in [0.01, 1.0, 3.7, 50.0, 1e6] {
            let (x, evaluations) = solve_positive_root(f, guess).unwrap();
            assert!(
                (x - root).abs() <= 4.0 * f64::EPSILON * root,
                "{x} from {guess}"
            );
            assert!(evaluations < 100);
        }
        // No positive root: x + 1 > 0 for x > 0.
        assert!(solve_positive_root(|x| x + 1.0, 1.0).is_none());
    }

    /// HL97 section 3: with both bounds the bounded control stays in (m/(1 + m/M), M).
    #[test]
    fn bounds_limit_the_control() {
        let av = AdaptiveVerlet::new(0.01, Control::Arclength, Some(1e-4), Some(0.1)).unwrap();
        let (m, big_m) = (0.01 / 0.1, 0.01 / 1e-4);
        for r in [0.0, 1e-3, 1.0, 1e2, 1e8] {
            let b = av.bounded(r);
            assert!(
                b >= m / (1.0 + m / big_m) * (1.0 - 1e-12) && b < big_m,
                "{r} -> {b}"
            );
        }
    }
}
