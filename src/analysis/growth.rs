//! Long-time energy growth (GSS98 section 3, Figures 6–10): the envelope of a long run's
//! energy error and its exponential growth rate per outer step.
//!
//! On the linear problem (27) one outer step is a linear map `z ↦ A z` with spectral radius
//! ρ. The state grows like ρⁿ and the energy, a quadratic form of the state, like ρ²ⁿ: once
//! the growing eigenvector dominates, the energy error grows at `2 ln ρ` per step. A type-1
//! instability (dominant eigenvalue ρe^{iφ}, not real) modulates the energy by a factor
//! `α + β cos(2nφ + ψ)`, so the values themselves do not grow smoothly; their envelope does.
//! [`window_maxima`] takes the envelope as the largest `|E_n − E_0|` in consecutive windows
//! of W steps and [`fit_rate`] fits a least-squares line to its logarithm.
//!
//! How far such a fit can be off (used by the tests of `tests/stability_growth.rs`): if
//! every `ln` of a window maximum deviates from `2 ln ρ · t + c` by an amount within an
//! interval of width Δ, the fitted slope is within `(Δ/2) · lever` of `2 ln ρ`, with
//! `lever = Σ|t − t̄| / Σ(t − t̄)²` over the fitted windows ([`RateFit::lever`]). For a
//! window of W steps Δ collects: where in the window the maximum falls (≤ 2W ln ρ; zero
//! for a real dominant eigenvalue, whose energy grows monotonically), how close the
//! modulation comes to its peak inside every window (≤ `ln(2/(1 + cos(g/2)))` when the
//! angles `2nφ mod 2π` of W consecutive steps leave no gap wider than g on the circle,
//! [`modulation_gap`]), and the parts of the state that do not grow.

use std::f64::consts::TAU;

use crate::error::Result;
use crate::integrators::Integrator;
use crate::system::System;

/// The largest `|E_n − E_0|` in consecutive windows of `window` steps, with the last step
/// of each window: `errors[n]` is the error after step n (`errors[0]`, the start, is not in
/// any window); windows cover steps `1..=W`, `W+1..=2W`, …; a last partial window is kept.
pub fn window_maxima(errors: &[f64], window: usize) -> Vec<(usize, f64)> {
    let window = window.max(1);
    let mut maxima = Vec::with_capacity(errors.len() / window + 1);
    let mut first = 1;
    while first < errors.len() {
        let last = (first + window - 1).min(errors.len() - 1);
        let max = errors[first..=last]
            .iter()
            .fold(0.0_f64, |m, e| m.max(e.abs()));
        maxima.push((last, max));
        first = last + 1;
    }
    maxima
}

/// A least-squares line through `ln(max)` against the step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RateFit {
    /// Growth rate per outer step: the slope of `ln |ΔE|` (2 ln ρ for a linear instability).
    pub rate: f64,
    /// Intercept of the line at step 0 (`ln |ΔE|`).
    pub intercept: f64,
    pub first_step: usize,
    pub last_step: usize,
    pub windows: usize,
    /// `Σ|t − t̄| / Σ(t − t̄)²`: deviations from a line within an interval of width Δ move
    /// the slope by at most `Δ/2 · lever` (module documentation).
    pub lever: f64,
}

/// Fit `ln(max)` against the step over `points` (window maxima); `None` for fewer than two
/// points or a non-positive maximum.
pub fn fit_rate(points: &[(usize, f64)]) -> Option<RateFit> {
    if points.len() < 2 || points.iter().any(|&(_, m)| !(m > 0.0 && m.is_finite())) {
        return None;
    }
    let n = points.len() as f64;
    let mean_t = points.iter().map(|&(t, _)| t as f64).sum::<f64>() / n;
    let mean_y = points.iter().map(|&(_, m)| m.ln()).sum::<f64>() / n;
    let (mut covariance, mut variance, mut spread) = (0.0, 0.0, 0.0);
    for &(t, m) in points {
        let dt = t as f64 - mean_t;
        covariance += dt * (m.ln() - mean_y);
        variance += dt * dt;
        spread += dt.abs();
    }
    let rate = covariance / variance;
    Some(RateFit {
        rate,
        intercept: mean_y - rate * mean_t,
        first_step: points[0].0,
        last_step: points[points.len() - 1].0,
        windows: points.len(),
        lever: spread / variance,
    })
}

/// The stretch of `points` to fit: from the first point whose maximum is at least `lo` to
/// the last point before the first one, after it, that exceeds `hi` (the growth leaves the
/// range where it is measured: a nonlinearity, an overflow). Empty if no point reaches `lo`.
pub fn fit_range(points: &[(usize, f64)], lo: f64, hi: f64) -> &[(usize, f64)] {
    let Some(start) = points.iter().position(|&(_, m)| m >= lo) else {
        return &[];
    };
    let end = points[start..]
        .iter()
        .position(|&(_, m)| m > hi || m.is_nan())
        .map_or(points.len(), |k| start + k);
    &points[start..end]
}

/// The widest gap left on the circle by the angles `2nφ mod 2π` of `window` consecutive
/// steps (the same for every window: a shift of n rotates them all). A type-1 modulation
/// `α + β cos(2nφ + ψ)` then reaches at least `α + |β| cos(gap/2)` in every window.
pub fn modulation_gap(phi: f64, window: usize) -> f64 {
    let mut angles: Vec<f64> = (0..window.max(1))
        .map(|n| (2.0 * n as f64 * phi).rem_euclid(TAU))
        .collect();
    angles.sort_by(f64::total_cmp);
    let wrap = angles[0] + TAU - angles[angles.len() - 1];
    angles.windows(2).map(|w| w[1] - w[0]).fold(wrap, f64::max)
}

/// The shortest window (up to `max_window`) whose modulation gap is at most `gap`.
pub fn modulation_window(phi: f64, gap: f64, max_window: usize) -> Option<usize> {
    (1..=max_window).find(|&w| modulation_gap(phi, w) <= gap)
}

/// How a run of [`energy_errors`] ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RunEnd {
    /// All steps taken.
    Finished,
    /// The energy became non-finite.
    Overflow,
    /// The method could not take a step.
    Failed,
}

impl RunEnd {
    pub fn name(self) -> &'static str {
        match self {
            RunEnd::Finished => "ok",
            RunEnd::Overflow => "overflow",
            RunEnd::Failed => "failed",
        }
    }
}

/// Take up to `steps` outer steps (after `setup`), recording `|E_n − E_0| / |E_0|` after
/// each (`[0]` is the start, 0). No blow-up limit: growth studies follow the error as far
/// as the numbers go, and stop only at a non-finite energy or a failed step.
pub fn energy_errors(
    system: &mut System,
    integrator: &mut dyn Integrator,
    steps: usize,
) -> Result<(Vec<f64>, RunEnd)> {
    integrator.setup(system)?;
    let e0 = system.total_energy();
    let scale = if e0 != 0.0 { e0.abs() } else { 1.0 };
    let mut errors = Vec::with_capacity(steps + 1);
    errors.push(0.0);
    for _ in 0..steps {
        if integrator.step(system).is_err() {
            return Ok((errors, RunEnd::Failed));
        }
        let error = (system.total_energy() - e0).abs() / scale;
        if !error.is_finite() {
            return Ok((errors, RunEnd::Overflow));
        }
        errors.push(error);
    }
    Ok((errors, RunEnd::Finished))
}

/// The default stretch of an envelope to fit. The error starts from zero, so its level at
/// the start is taken as the largest window maximum in the first 5 % of the run; the fit goes
/// from ten times that to a tenth of the run's largest (leaving out the start, where the
/// parts that do not grow are comparable, and a saturation). When fewer than three windows
/// qualify (a bounded run) it takes every window after the first 5 %: the rate is then
/// near zero.
pub fn default_fit_range(points: &[(usize, f64)]) -> &[(usize, f64)] {
    let Some(&(last_step, _)) = points.last() else {
        return points;
    };
    let early = points
        .iter()
        .position(|&(step, _)| step * 20 > last_step)
        .unwrap_or(points.len())
        .max(1);
    let start = points[..early].iter().fold(0.0_f64, |m, p| m.max(p.1));
    let largest = points.iter().fold(0.0_f64, |m, p| m.max(p.1));
    let stretch = fit_range(points, 10.0 * start, 0.1 * largest);
    if stretch.len() >= 3 {
        stretch
    } else {
        &points[early.min(points.len() - 1)..]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn window_maxima_cover_every_step_once() {
        let errors: Vec<f64> = (0..11)
            .map(|n| n as f64 * if n % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        let maxima = window_maxima(&errors, 4);
        assert_eq!(maxima, vec![(4, 4.0), (8, 8.0), (10, 10.0)]);
        assert!(window_maxima(&[0.0], 3).is_empty());
    }

    #[test]
    fn fit_recovers_an_exact_exponential_and_its_lever() {
        let points: Vec<(usize, f64)> = (1..=10)
            .map(|k| (10 * k, (0.01 * (10 * k) as f64 + 2.0).exp()))
            .collect();
        let fit = fit_rate(&points).expect("fit");
        assert!((fit.rate - 0.01).abs() < 1e-14, "{}", fit.rate);
        assert!((fit.intercept - 2.0).abs() < 1e-12);
        // t = 10, 20, …, 100: Σ|t − t̄| = 250, Σ(t − t̄)² = 8250.
        assert!((fit.lever - 250.0 / 8250.0).abs() < 1e-15);
        assert!(fit_rate(&points[..1]).is_none());
    }

    #[test]
    fn fit_range_stops_where_the_growth_leaves_the_range() {
        let points = vec![(1, 0.5), (2, 2.0), (3, 5.0), (4, 50.0), (5, 3.0)];
        assert_eq!(fit_range(&points, 1.0, 10.0), &points[1..3]);
        assert!(fit_range(&points, 100.0, 1e3).is_empty());
        assert_eq!(fit_range(&points, 0.0, f64::INFINITY), &points[..]);
    }

    #[test]
    fn default_fit_skips_the_start_and_the_saturation() {
        // Growth by e every 10 steps from step 100 to 400, then flat.
        let points: Vec<(usize, f64)> = (1..=100)
            .map(|k| {
                let step = 10 * k;
                let level = if step < 100 {
                    1.0
                } else {
                    ((step.min(400) - 100) as f64 / 10.0).exp()
                };
                (step, level)
            })
            .collect();
        let stretch = default_fit_range(&points);
        // From 10× the level of the first 5 % (steps ≤ 50: 1) to a tenth of the largest.
        assert!(
            stretch[0].1 >= 10.0 && stretch[0].0 == 130,
            "{:?}",
            stretch[0]
        );
        assert!(stretch.last().unwrap().0 < 400);
        let fit = fit_rate(stretch).expect("fit");
        assert!((fit.rate - 0.1).abs() < 1e-12);
        // A flat run: everything after the first 5 %.
        let flat: Vec<(usize, f64)> = (1..=100)
            .map(|k| (k, 1.0 + 0.1 * (k as f64).sin()))
            .collect();
        assert_eq!(default_fit_range(&flat)[0].0, 6);
    }

    #[test]
    fn modulation_gaps() {
        // φ = π/2: 2nφ alternates between 0 and π, a gap of π whatever the window.
        assert!(
            (modulation_gap(std::f64::consts::FRAC_PI_2, 50) - std::f64::consts::PI).abs() < 1e-9
        );
        // φ = 0 (a real positive eigenvalue): one angle, the whole circle is the gap.
        assert_eq!(modulation_gap(0.0, 10), TAU);
        // An irrational rotation fills the circle.
        let w = modulation_window(1.0, 0.1, 10_000).expect("fills");
        assert!(modulation_gap(1.0, w) <= 0.1 && modulation_gap(1.0, w - 1) > 0.1);
    }
}
