//! Energy drift: a least-squares line through the energy of the recorded rows, fitted as
//! the run goes (Welford's updates: no stored series, no allocation, no cancellation of
//! large sums).
//!
//! The rate is reported in kT per unit time per degree of freedom, with kT estimated from
//! the mean kinetic energy by equipartition, `kT = 2⟨K⟩/n_dof`: the rate is
//! `slope / (2⟨K⟩)` and needs no temperature in the scene. For a scene in femtoseconds,
//! 0.05 kT/ns/dof (the criterion of the water-box comparisons) is 5e-8 per fs.
//!
//! Two energies are fitted: the true energy `K + V`, and, for a method that conserves
//! another one and records it in `energy.csv` ([`CONSERVED_COLUMNS`]: the mollified
//! methods' `mollified_total`, the pseudo-energy schemes' `pseudo_energy`), that one too.
//! A method is judged by the energy it conserves: its true energy only fluctuates about it.
//!
//! The verdict ([`judge`]) is the three-way one of [`crate::run::verdict`]. The drift's
//! standard error is the judged energy's fluctuation about its fitted line over the fitted
//! span, `σ_E / T` in slope: conservative for white noise (whose slope error is
//! `σ_E √(12/n) / T`), and honest for energies that oscillate, whose rows are correlated over
//! a period: a short run of a method whose energy oscillates cannot show a small drift, and
//! is not said to. The fluctuation does not shrink with the run, so the error goes as `1/T`
//! and the run that would decide an undecided drift follows from that. A dimensionless
//! scene is judged the same way, in kT per unit time per degree of freedom (default bound
//! [`DEFAULT_DIMENSIONLESS_BOUND`]), and `scan steps` judges every run with this same
//! [`judge`]. A run at rest (kinetic temperature below [`AT_REST_TEMPERATURE`], or no
//! kinetic energy) has no kT to measure a drift in: it gets no verdict, and says why.

use std::collections::BTreeMap;

use crate::error::{Error, Result};
use crate::io::summary::{
    Conserved, DIMENSIONLESS_DRIFT_UNIT, Drift, DriftReport, NO_VERDICT, REAL_DRIFT_UNIT,
    format_time,
};
use crate::run::verdict::{self, Measurement, Verdict, Z};
use crate::settings::Value;
use crate::units::Units;

/// The default bound of a run in a scene with real units, in kT/ns/dof: the criterion of
/// the water-box comparisons (docs/performance.md).
pub const DEFAULT_REAL_BOUND: f64 = 0.05;

/// The default bound in a dimensionless scene, in kT per unit time per degree of freedom
/// (kT by equipartition, as in real units): `run` and `scan steps` judge alike.
pub const DEFAULT_DIMENSIONLESS_BOUND: f64 = 1e-3;

/// Below this kinetic temperature (K) of the fitted rows a run is at rest — no temperature
/// given, a structure at its minimum moving only under its residual forces — and a drift
/// in kT/ns/dof would divide by a kT nearly zero: the drift of a run at rest is not
/// judged. 1 K is 300 times below the room temperature at which the default bound is set,
/// and far above the millikelvins a minimised molecule reaches from rest.
pub const AT_REST_TEMPERATURE: f64 = 1.0;

/// The `energy.csv` columns of a method's conserved energy, when it reports one.
pub const CONSERVED_COLUMNS: &[&str] = &["mollified_total", "pseudo_energy"];

/// A user's drift bound (`--drift-bound`), checked positive and finite.
pub fn check_bound(bound: Option<f64>) -> Result<Option<f64>> {
    match bound {
        Some(b) if !(b.is_finite() && b > 0.0) => Err(Error::flag(
            "--drift-bound",
            "--drift-bound must be positive and finite",
        )
        .got(b.to_string())),
        other => Ok(other),
    }
}

/// The start of the fit (`--fit-from`) in scene time units, checked to lie in [0, t_end).
pub fn fit_from(
    value: Option<&Value>,
    parameters: &BTreeMap<String, f64>,
    units: Units,
    t_end: f64,
) -> Result<Option<f64>> {
    let Some(value) = value else {
        return Ok(None);
    };
    let t = value.evaluate_time(parameters, "--fit-from", units.time_units())?;
    if !(0.0..t_end).contains(&t) {
        return Err(Error::flag(
            "--fit-from",
            format!(
                "--fit-from {} is outside the run [0, {}): the fit needs rows after it",
                format_time(t, units),
                format_time(t_end, units)
            ),
        ));
    }
    Ok(Some(t))
}

/// Running sums of a least-squares fit of energies against time.
#[derive(Clone, Debug, Default)]
pub struct DriftFit {
    rows: usize,
    first_t: f64,
    mean_t: f64,
    mean_kinetic: f64,
    mean_total: f64,
    mean_conserved: f64,
    /// `Σ (t − t̄)²`.
    spread_t: f64,
    /// `Σ (t − t̄)(E − Ē)` for the true and the conserved energy.
    co_total: f64,
    co_conserved: f64,
    /// `Σ (E − Ē)²` for the true and the conserved energy.
    spread_total: f64,
    spread_conserved: f64,
}

impl DriftFit {
    /// Add a row: time, kinetic energy, true total energy, conserved energy (if any).
    pub fn add(&mut self, t: f64, kinetic: f64, total: f64, conserved: Option<f64>) {
        if self.rows == 0 {
            self.first_t = t;
        }
        self.rows += 1;
        let n = self.rows as f64;
        let dt = t - self.mean_t;
        self.mean_t += dt / n;
        self.mean_kinetic += (kinetic - self.mean_kinetic) / n;
        let de = total - self.mean_total;
        self.mean_total += de / n;
        // Welford: the product of the deviation before and after the update of the means.
        self.spread_t += dt * (t - self.mean_t);
        self.co_total += dt * (total - self.mean_total);
        self.spread_total += de * (total - self.mean_total);
        if let Some(c) = conserved {
            let dc = c - self.mean_conserved;
            self.mean_conserved += dc / n;
            self.co_conserved += dt * (c - self.mean_conserved);
            self.spread_conserved += dc * (c - self.mean_conserved);
        }
    }

    pub fn rows(&self) -> usize {
        self.rows
    }

    /// The fit, when it has at least three rows over a positive time span (two points
    /// always lie on a line); `conserved` names the conserved energy if one was added.
    pub fn result(&self, conserved: Option<&str>, last_t: f64) -> Option<Drift> {
        if self.rows < 3 || self.spread_t <= 0.0 {
            return None;
        }
        // The residual standard deviation about the line, from the sums:
        // Σr² = Σ(E − Ē)² − b² Σ(t − t̄)², over n − 2 degrees of freedom.
        let residual = |co: f64, spread: f64| {
            let slope = co / self.spread_t;
            let squares = (spread - slope * slope * self.spread_t).max(0.0);
            (slope, (squares / (self.rows - 2) as f64).sqrt())
        };
        let (true_slope, true_fluctuation) = residual(self.co_total, self.spread_total);
        Some(Drift {
            rows: self.rows,
            from: self.first_t,
            to: last_t,
            mean_kinetic: self.mean_kinetic,
            // The run sets it where it records a temperature.
            temperature: None,
            true_slope,
            true_fluctuation,
            conserved: conserved.map(|name| {
                let (slope, fluctuation) = residual(self.co_conserved, self.spread_conserved);
                Conserved {
                    name: name.to_string(),
                    slope,
                    fluctuation,
                }
            }),
        })
    }
}

/// A conversion of a slope into the unit a drift is judged in.
type Convert<'a> = Box<dyn Fn(f64) -> f64 + 'a>;

/// Judge `drift` against `bound` (the default for the scene's units when `None`): the
/// rate in kT per unit time per degree of freedom (kT/ns/dof in real units), the same for
/// `run` and `scan steps`. A run at rest ([`at_rest`]) gets no verdict.
pub fn judge(drift: &Drift, units: Units, bound: Option<f64>) -> DriftReport {
    let (energy, slope, fluctuation) = drift.judged();
    let span = drift.to - drift.from;
    let (convert, unit, default, exponent): (Convert, &str, f64, f64) = match units {
        Units::Real => {
            let per_ns = units
                .time_units()
                .iter()
                .find(|(name, _)| *name == "ns")
                .map_or(1e6, |(_, value)| *value);
            (
                Box::new(move |s| drift.rate(s) * per_ns),
                REAL_DRIFT_UNIT,
                DEFAULT_REAL_BOUND,
                1.0,
            )
        }
        Units::None => (
            Box::new(move |s| drift.rate(s)),
            DIMENSIONLESS_DRIFT_UNIT,
            DEFAULT_DIMENSIONLESS_BOUND,
            1.0,
        ),
    };
    let bound = bound.unwrap_or(default);
    let measurement = Measurement {
        value: convert(slope),
        error: convert(fluctuation / span).abs(),
        fixed_error: 0.0,
        start: drift.from,
        span,
        exponent,
    };
    let verdict = verdict::judge(&measurement, bound);
    let rest = at_rest(drift, units);
    DriftReport {
        energy: energy.to_string(),
        value: measurement.value,
        true_energy: convert(drift.true_slope),
        conserved_energy: drift.conserved.as_ref().map(|c| convert(c.slope)),
        unit: unit.to_string(),
        bound,
        exceeded: rest.is_none() && measurement.value.abs() > bound,
        error: measurement.error,
        verdict: match rest {
            Some(_) => NO_VERDICT.to_string(),
            None => verdict.name().to_string(),
        },
        decide_at: match verdict {
            Verdict::Undecided { decide_at } if rest.is_none() => decide_at,
            _ => None,
        },
        verdict_text: rest.unwrap_or_else(|| verdict.text(units)),
        z: Z,
        change: slope * span,
        fluctuation,
        from: drift.from,
        to: drift.to,
        rows: drift.rows,
    }
}

/// Why a run is at rest, when it is: its kinetic temperature below
/// [`AT_REST_TEMPERATURE`], or no kinetic energy at all.
fn at_rest(drift: &Drift, units: Units) -> Option<String> {
    let why = match drift.temperature {
        Some(t) if t < AT_REST_TEMPERATURE => format!(
            "mean kinetic temperature {} {} over the fit, below {AT_REST_TEMPERATURE} {}",
            crate::io::summary::significant(t, 2),
            units.temperature_name(),
            units.temperature_name()
        ),
        _ if drift.mean_kinetic <= 0.0 => "no kinetic energy".to_string(),
        _ => return None,
    };
    Some(format!(
        "no verdict: the run is at rest ({why}), so there is no kT to measure its drift in; \
         give it a temperature (--temperature) to judge its drift"
    ))
}

/// The verdict of a judged drift.
pub fn verdict_of(report: &DriftReport) -> Verdict {
    match report.verdict.as_str() {
        "pass" => Verdict::Pass,
        "fail" => Verdict::Fail,
        _ => Verdict::Undecided {
            decide_at: report.decide_at,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_running_fit_is_the_least_squares_slope() {
        // E = 3 + 0.2 t + an oscillation, C = 1 − 0.5 t; K = 0.5: rate 0.2 / (2·0.5) = 0.2.
        // The two-pass slope of the same samples is the reference, to round-off.
        let mut fit = DriftFit::default();
        let samples: Vec<(f64, f64, f64)> = (0..100)
            .map(|i| {
                let t = 1e4 + i as f64 * 0.1;
                (t, 3.0 + 0.2 * t + 0.01 * (7.0 * t).sin(), 1.0 - 0.5 * t)
            })
            .collect();
        for &(t, e, c) in &samples {
            fit.add(t, 0.5, e, Some(c));
        }
        let n = samples.len() as f64;
        let mean_t = samples.iter().map(|s| s.0).sum::<f64>() / n;
        let mean_e = samples.iter().map(|s| s.1).sum::<f64>() / n;
        let (mut cov, mut var) = (0.0, 0.0);
        for s in &samples {
            cov += (s.0 - mean_t) * (s.1 - mean_e);
            var += (s.0 - mean_t) * (s.0 - mean_t);
        }
        let drift = fit.result(Some("mollified_total"), 1e4 + 9.9).unwrap();
        assert!(
            (drift.true_slope - cov / var).abs() <= 1e-9 * (cov / var).abs(),
            "{} vs {}",
            drift.true_slope,
            cov / var
        );
        assert!((drift.conserved_rate().unwrap() + 0.5).abs() < 1e-9);
        assert_eq!(drift.judged().0, "mollified_total");
        // The residual of E about its line is the oscillation 0.01 sin(7t): rms 0.01/√2.
        assert!((drift.true_fluctuation - 0.01 / 2f64.sqrt()).abs() < 1e-3);
        assert!(drift.conserved.as_ref().unwrap().fluctuation < 1e-9);
        assert_eq!(drift.rows, 100);
        assert_eq!(drift.from, 1e4);
    }

    #[test]
    fn too_few_rows_give_no_fit() {
        let mut fit = DriftFit::default();
        fit.add(0.0, 1.0, 1.0, None);
        fit.add(1.0, 1.0, 2.0, None);
        assert!(fit.result(None, 1.0).is_none());
        fit.add(2.0, 0.0, 3.0, None);
        let drift = fit.result(None, 2.0).unwrap();
        assert_eq!(drift.judged(), ("total", 1.0, 0.0));
        // A straight line: no fluctuation, so the drift 1/(2·⟨K⟩) = 1/(2·2/3) = 0.75 kT per
        // unit time per dof fails its bound 1e-3.
        let report = judge(&drift, Units::None, None);
        assert_eq!((report.error, report.verdict.as_str()), (0.0, "fail"));
    }
}
