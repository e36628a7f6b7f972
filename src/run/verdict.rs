//! One verdict for every criterion with an error bar: **pass**, **fail** or **undecided**.
//!
//! An estimate `x` with standard error `σ` is judged against a bound `b` on `|x|` by its
//! confidence interval `x ± zσ`, `z = 2` ([`Z`], about 95 % for a normal error):
//!
//! * **pass** when the whole interval lies within the bound, `|x| + zσ ≤ b`;
//! * **fail** when it lies wholly outside, `|x| − zσ > b`;
//! * **undecided** otherwise: the error bar is too wide to tell.
//!
//! Never "pass by the mean": an undecided verdict says how long a run would decide, from
//! how the error bar shrinks with the measured span `T`. The part of `σ` that shrinks goes
//! as `T^(−p)`: `p = 1/2` for the mean of a correlated series (block averages, σ ∝ 1/√T),
//! `p = 1` for a drift whose error is the energy's fluctuation over the span (the
//! fluctuation about the line does not shrink, the span grows: [`crate::run::drift`]). A
//! part that does not shrink (a reference run's error, which a longer run of the point does
//! not touch) is kept apart. The interval clears the bound, with the current estimate, when
//! `z √(σ_s² (T/T')^(2p) + σ_f²) = | |x| − b |`, so
//!
//! `T' = T (σ_s² / ((|x| − b)²/z² − σ_f²))^(1/(2p))`,
//!
//! and no run length decides when the right side is not positive (the estimate on the bound,
//! or the fixed error alone too wide). The message is one wording everywhere:
//! `undecided: a run of ~X ps would decide` ([`Verdict::text`]).
//!
//! `run`'s drift verdict ([`crate::run::drift::judge`]), `scan steps`' drift and sampling
//! judgements and the sampling criterion all come through [`judge`].

use serde::Serialize;

use crate::io::summary::{format_time, significant};
use crate::units::Units;

/// The width of the confidence interval in standard errors.
pub const Z: f64 = 2.0;

/// How an error bar shrinks: the mean of a correlated series, σ ∝ T^(−1/2).
pub const MEAN_EXPONENT: f64 = 0.5;

/// An estimate and its error bar over a measured span of a run.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Measurement {
    pub value: f64,
    /// The standard error that a longer run shrinks, as `span^(−exponent)`.
    pub error: f64,
    /// A standard error that a longer run does not shrink (a reference's); 0 if none.
    pub fixed_error: f64,
    /// Where the measured span starts (a skipped equilibration) and its length, in the
    /// scene's time unit: the run that decides is `start + T'`.
    pub start: f64,
    pub span: f64,
    /// `p` of `σ ∝ T^(−p)`; 0: the error does not shrink with the run's length.
    pub exponent: f64,
}

impl Measurement {
    /// The combined standard error.
    pub fn standard_error(&self) -> f64 {
        self.error.hypot(self.fixed_error)
    }
}

/// The verdict on a [`Measurement`] against a bound.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(tag = "verdict", rename_all = "lowercase")]
pub enum Verdict {
    Pass,
    Fail,
    /// `decide_at`: the run length (scene time unit) at which the interval would clear the
    /// bound given the current estimate; `None` when no length would.
    Undecided {
        decide_at: Option<f64>,
    },
}

impl Verdict {
    /// `pass`, `fail` or `undecided`.
    pub fn name(&self) -> &'static str {
        match self {
            Verdict::Pass => "pass",
            Verdict::Fail => "fail",
            Verdict::Undecided { .. } => "undecided",
        }
    }

    /// The verdict in words: `pass`, `fail`, `undecided: a run of ~X ps would decide`.
    pub fn text(&self, units: Units) -> String {
        match self {
            Verdict::Undecided { decide_at: Some(t) } => format!(
                "undecided: a run of ~{} would decide",
                format_time(round_up(*t), units)
            ),
            Verdict::Undecided { decide_at: None } => {
                "undecided: no longer run alone would decide".to_string()
            }
            _ => self.name().to_string(),
        }
    }
}

/// Judge `m` against the bound `|value| ≤ bound` (see the module documentation). A NaN
/// value or error decides nothing.
pub fn judge(m: &Measurement, bound: f64) -> Verdict {
    let sigma = m.standard_error();
    let distance = m.value.abs() - bound;
    if !(distance.is_finite() && sigma.is_finite()) {
        return Verdict::Undecided { decide_at: None };
    }
    if distance + Z * sigma <= 0.0 {
        Verdict::Pass
    } else if distance - Z * sigma > 0.0 {
        Verdict::Fail
    } else {
        Verdict::Undecided {
            decide_at: decide_at(m, distance.abs()),
        }
    }
}

/// The verdict on several criteria together: fail when any fails, pass when all pass,
/// otherwise undecided, decided by the longest run any undecided one needs (none when one of
/// them has none).
pub fn all(verdicts: &[Verdict]) -> Verdict {
    if verdicts.contains(&Verdict::Fail) {
        return Verdict::Fail;
    }
    let mut longest: Option<Option<f64>> = None;
    for v in verdicts {
        if let Verdict::Undecided { decide_at } = v {
            longest = Some(match (longest, decide_at) {
                (None, at) => *at,
                (Some(Some(a)), Some(b)) => Some(a.max(*b)),
                _ => None,
            });
        }
    }
    match longest {
        None => Verdict::Pass,
        Some(decide_at) => Verdict::Undecided { decide_at },
    }
}

/// The run length at which `z σ(T')` equals `gap` (module documentation).
fn decide_at(m: &Measurement, gap: f64) -> Option<f64> {
    let room = (gap / Z).powi(2) - m.fixed_error.powi(2);
    if m.exponent <= 0.0 || m.span <= 0.0 || m.error <= 0.0 || room <= 0.0 {
        return None;
    }
    let factor = (m.error * m.error / room).powf(0.5 / m.exponent);
    let at = m.start + m.span * factor;
    at.is_finite().then_some(at)
}

/// Up to two significant digits, rounded up (a run that long decides; one shorter might
/// not).
fn round_up(t: f64) -> f64 {
    if !(t.is_finite() && t > 0.0) {
        return t;
    }
    let scale = 10f64.powi(t.log10().floor() as i32 - 1);
    let up = (t / scale).ceil() * scale;
    significant(up, 2).parse().unwrap_or(up)
}

/// A measurement over the span 0 … 10 with no fixed error: the tests' fixture.
#[cfg(test)]
pub(crate) fn measured(value: f64, error: f64, exponent: f64) -> Measurement {
    Measurement {
        value,
        error,
        fixed_error: 0.0,
        start: 0.0,
        span: 10.0,
        exponent,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mean(value: f64, error: f64) -> Measurement {
        measured(value, error, MEAN_EXPONENT)
    }

    #[test]
    fn the_interval_decides() {
        assert_eq!(judge(&mean(0.01, 0.01), 0.05), Verdict::Pass);
        assert_eq!(judge(&mean(-0.2, 0.01), 0.05), Verdict::Fail);
        // 0.04 ± 2·0.01: the interval [0.02, 0.06] straddles 0.05. The gap 0.01 is z σ when
        // σ = 0.005, half of 0.01: with σ ∝ 1/√T, 4 times the span of 10.
        let v = judge(&mean(0.04, 0.01), 0.05);
        let Verdict::Undecided { decide_at: Some(t) } = v else {
            panic!("{v:?}");
        };
        assert!((t - 40.0).abs() < 1e-9, "{t}");
        assert_eq!(v.text(Units::None), "undecided: a run of ~40 would decide");
    }

    #[test]
    fn a_fixed_error_too_wide_leaves_no_length() {
        let m = Measurement {
            fixed_error: 0.01,
            ..mean(0.04, 0.01)
        };
        assert_eq!(judge(&m, 0.05), Verdict::Undecided { decide_at: None });
        assert_eq!(judge(&mean(f64::NAN, 0.01), 0.05).name(), "undecided");
    }

    #[test]
    fn criteria_together() {
        let undecided = |at| Verdict::Undecided { decide_at: at };
        use Verdict::{Fail, Pass};
        assert_eq!(all(&[Pass, Pass]), Pass);
        assert_eq!(all(&[undecided(Some(3.0)), Fail]), Fail);
        assert_eq!(
            all(&[undecided(Some(3.0)), Pass, undecided(Some(5.0))]),
            undecided(Some(5.0))
        );
        assert_eq!(
            all(&[undecided(Some(3.0)), undecided(None)]),
            undecided(None)
        );
    }

    #[test]
    fn run_lengths_round_up_to_two_digits() {
        assert_eq!(round_up(1234.0), 1300.0);
        assert_eq!(round_up(160.0), 160.0);
        assert_eq!(round_up(0.0123), 0.013);
    }
}
