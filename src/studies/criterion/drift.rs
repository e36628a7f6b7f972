//! The drift criterion of a step-size scan: an NVE run is judged by the drift of the energy
//! its method conserves.
//!
//! * **unstable** — the run blew up (non-finite energy, or |E − E₀| beyond the blow-up
//!   factor) or its method failed;
//! * otherwise the verdict of [`crate::run::verdict`] on its energy drift — the fitted slope
//!   of the energy the method conserves (its `mollified_total` or `pseudo_energy` when it
//!   reports one, else `K + V`; [`crate::run::drift`]) with its error bar against the
//!   bound: **pass**, **fail** or **undecided** (with the run length that would decide).
//!
//! The drift is judged exactly as `longstep run` judges it ([`judge`]), the same verdict
//! and wording: kT/ns/dof with real units (default bound 0.05), and in a dimensionless
//! scene the rate in kT per unit time per degree of freedom (default bound 1e-3): kT is
//! estimated from the mean kinetic energy by equipartition,
//! `kT = 2⟨K⟩/n_dof`, so the rate is `slope / (2⟨K⟩)` and needs no thermostat or temperature
//! in the scene; its error bar is the energy's fluctuation over the span, converted alike.
//!
//! **Several starts.** A point of N independent starts is judged on their mean drift
//! `d̄ = Σdᵢ/N` ([`combine_starts`]) with the standard error `σ = max(√(Σσᵢ²)/N, s_d/√N)`:
//! the larger of the error the runs' own fits give the mean and the spread of the N drifts
//! about it (`s_d` their sample standard deviation; only for N ≥ 2), so neither a lucky
//! agreement of few starts nor fits too optimistic for a correlated series makes the bar too
//! narrow. The verdict is [`verdict::judge`]'s with drift exponent 1 (each fit's error is
//! the fluctuation over the span), so an undecided point says how long a run would decide.
//! Any start unstable makes the point unstable.
//!
//! A thermostatted method exchanges energy with its bath by design: it is never judged by
//! drift, only by the sampling criterion ([`super::sampling`]).

use serde::Serialize;

use super::Verdict;
use crate::io::summary::{RunSummary, Status};
use crate::run::drift::{judge, verdict_of};
use crate::run::verdict::{self, Measurement};

/// The default drift bound of a scan in a dimensionless scene, in kT per unit time per
/// degree of freedom (in a scene with real units it is `run`'s, 0.05 kT/ns/dof).
pub const DEFAULT_DIMENSIONLESS_BOUND: f64 = crate::run::drift::DEFAULT_DIMENSIONLESS_BOUND;

/// Energy drift in kT per unit time per degree of freedom, from `(t, kinetic, total)`
/// samples: the least-squares slope of E(t) divided by `2⟨K⟩`.
pub fn drift_rate(series: &[[f64; 3]]) -> f64 {
    let n = series.len() as f64;
    if series.len() < 2 {
        return 0.0;
    }
    let mean_t = series.iter().map(|s| s[0]).sum::<f64>() / n;
    let mean_e = series.iter().map(|s| s[2]).sum::<f64>() / n;
    let mean_k = series.iter().map(|s| s[1]).sum::<f64>() / n;
    let (mut covariance, mut variance) = (0.0, 0.0);
    for s in series {
        covariance += (s[0] - mean_t) * (s[2] - mean_e);
        variance += (s[0] - mean_t) * (s[0] - mean_t);
    }
    if variance == 0.0 || mean_k <= 0.0 {
        return 0.0;
    }
    (covariance / variance) / (2.0 * mean_k)
}

/// A finished run's drift as a scan reports it: the judged energy's rate and its standard
/// error, the true energy's, which energy was judged, and the verdict.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ScanDrift {
    pub value: f64,
    pub error: f64,
    pub true_energy: f64,
    pub energy: String,
    #[serde(skip)]
    pub verdict: verdict::Verdict,
    /// What was judged: the rate, its error over the fitted span, and how it shrinks.
    #[serde(skip)]
    pub measurement: Measurement,
}

/// The drift of a finished run in the scan's unit (kT/ns/dof with real units, kT per unit
/// time per dof otherwise), judged by the energy the method conserves against `bound`;
/// `None` without a fit (too few rows).
pub fn scan_drift(summary: &RunSummary, bound: f64) -> Option<ScanDrift> {
    let fit = summary.fit.as_ref()?;
    let report = judge(fit, summary.scene_units, Some(bound));
    Some(ScanDrift {
        value: report.value,
        error: report.error,
        true_energy: report.true_energy,
        verdict: verdict_of(&report),
        measurement: Measurement {
            value: report.value,
            error: report.error,
            fixed_error: 0.0,
            start: report.from,
            span: report.to - report.from,
            exponent: 1.0,
        },
        energy: report.energy,
    })
}

/// The verdict on a finished run by the drift criterion, and its drift. A finished run
/// too short to fit a drift is undecided.
pub fn classify(summary: &RunSummary, drift_bound: f64) -> (Verdict, Option<ScanDrift>) {
    let drift = scan_drift(summary, drift_bound);
    let verdict = match (&summary.status, &drift) {
        (Status::Unstable | Status::Failed, _) => Verdict::Unstable,
        (Status::Ok, Some(d)) => Verdict::of(&d.verdict),
        (Status::Ok, None) => Verdict::Undecided,
    };
    (verdict, drift)
}

/// The measurement of a point's starts (module documentation): the mean of their values,
/// the larger of `√(Σσᵢ²)/N` and the sample deviation over `√N` as its error, the first
/// start's span and exponent. `None` for no starts.
pub fn combine_starts(starts: &[Measurement]) -> Option<Measurement> {
    let first = starts.first()?;
    let n = starts.len() as f64;
    let mean = starts.iter().map(|m| m.value).sum::<f64>() / n;
    let own = starts.iter().map(|m| m.error * m.error).sum::<f64>().sqrt() / n;
    let spread = if starts.len() >= 2 {
        let squares: f64 = starts.iter().map(|m| (m.value - mean).powi(2)).sum();
        (squares / (n - 1.0)).sqrt() / n.sqrt()
    } else {
        0.0
    };
    Some(Measurement {
        value: mean,
        error: own.max(spread),
        ..*first
    })
}

/// The drift of a point's starts, judged against `bound`: one start's as it is, several
/// combined ([`combine_starts`]), their true-energy drifts averaged.
pub fn combined_drift(drifts: &[ScanDrift], bound: f64) -> Option<ScanDrift> {
    if drifts.len() == 1 {
        return drifts.first().cloned();
    }
    let measurements: Vec<Measurement> = drifts.iter().map(|d| d.measurement).collect();
    let measurement = combine_starts(&measurements)?;
    let true_energy = drifts.iter().map(|d| d.true_energy).sum::<f64>() / drifts.len() as f64;
    Some(ScanDrift {
        value: measurement.value,
        error: measurement.error,
        true_energy,
        energy: drifts[0].energy.clone(),
        verdict: verdict::judge(&measurement, bound),
        measurement,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn series(slope: f64, kinetic: f64) -> Vec<[f64; 3]> {
        (0..100)
            .map(|i| {
                let t = i as f64 * 0.1;
                // An oscillation on top of the drift: it must not bias the slope.
                [t, kinetic, 3.0 + slope * t + 0.01 * (7.0 * t).sin()]
            })
            .collect()
    }

    #[test]
    fn drift_is_the_fitted_slope_over_twice_the_kinetic_energy() {
        let rate = drift_rate(&series(0.2, 0.5));
        assert!((rate - 0.2).abs() < 5e-3, "{rate}");
        assert!(drift_rate(&series(0.0, 0.5)).abs() < 5e-3);
        assert_eq!(drift_rate(&series(0.2, 0.0)), 0.0);
    }

    fn start(value: f64, error: f64) -> Measurement {
        crate::run::verdict::measured(value, error, 1.0)
    }

    #[test]
    fn starts_combine_to_their_mean_with_the_wider_error() {
        let combined = |starts: &[(f64, f64)]| {
            let m: Vec<Measurement> = starts.iter().map(|&(v, e)| start(v, e)).collect();
            combine_starts(&m).unwrap()
        };
        let third = 1.0 / 3f64.sqrt();
        // The fits' error wins: mean 0.010, √(3·0.015²)/3 = 0.015/√3 against the spread
        // 0.002/√3; 0.010 + 2·0.00866 = 0.027 ≤ 0.05: pass.
        let pass = combined(&[(0.010, 0.015), (0.012, 0.015), (0.008, 0.015)]);
        assert!((pass.value - 0.010).abs() < 1e-15, "{pass:?}");
        assert!((pass.error - 0.015 * third).abs() < 1e-15, "{pass:?}");
        assert_eq!(verdict::judge(&pass, 0.05), verdict::Verdict::Pass);
        // The spread wins: drifts 0.2, 0.3, 0.1 of tiny fit errors have the sample
        // deviation 0.1, so σ = 0.1/√3 = 0.0577; 0.2 − 2σ = 0.085 > 0.05: fail.
        let fail = combined(&[(0.2, 0.001), (0.3, 0.001), (0.1, 0.001)]);
        assert!((fail.value - 0.2).abs() < 1e-15, "{fail:?}");
        assert!((fail.error - 0.1 * third).abs() < 1e-15, "{fail:?}");
        assert_eq!(verdict::judge(&fail, 0.05), verdict::Verdict::Fail);
        // 0.04 ± 2·0.02/√3 straddles 0.05. The gap 0.01 is 2σ at σ = 0.005: with the
        // drift's σ ∝ 1/T, a run 0.01155/0.005 = 2.309 times the span of 10 decides.
        let open = combined(&[(0.04, 0.02), (0.05, 0.02), (0.03, 0.02)]);
        let verdict::Verdict::Undecided { decide_at: Some(t) } = verdict::judge(&open, 0.05) else {
            panic!("{open:?}");
        };
        let expected = 10.0 * (0.02 * third) / 0.005;
        assert!((t - expected).abs() < 1e-9, "{t} vs {expected}");
        // One start is itself: no spread, its own error.
        assert_eq!(combined(&[(0.04, 0.02)]), start(0.04, 0.02));
        assert!(combine_starts(&[]).is_none());
    }
}
