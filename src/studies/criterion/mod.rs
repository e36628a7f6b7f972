//! The criteria that judge a point of a step-size scan, in one place: the drift criterion
//! of NVE runs ([`drift`]) and the sampling criterion of thermostatted runs ([`sampling`]),
//! and the verdict they share ([`Verdict`]).
//!
//! Both give the three-way verdict of [`crate::run::verdict`] — **pass** when the whole 2σ
//! interval of what they measure lies within its bound, **fail** when wholly outside,
//! **undecided** otherwise (with the run length that would decide) — and a run that blew up
//! or whose method failed is **unstable** whatever the criterion.
//!
//! A criterion judges what a finished run left (its summary, its analysed files); running
//! the points is the scan's ([`super::scan`]), so this module imports nothing of it.

use serde::Serialize;

use crate::run::verdict;

pub mod basins;
pub mod drift;
pub mod reference;
pub mod sampling;

/// A scan point's verdict: unstable, or the verdict of its criterion
/// ([`crate::run::verdict::Verdict`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Verdict {
    Unstable,
    /// The criterion's whole confidence interval lies within its bound.
    Pass,
    /// It lies wholly outside: the run drifts, or samples another distribution.
    Fail,
    /// The error bar is too wide to tell.
    Undecided,
}

impl Verdict {
    pub fn name(self) -> &'static str {
        match self {
            Verdict::Unstable => "unstable",
            Verdict::Pass => "pass",
            Verdict::Fail => "fail",
            Verdict::Undecided => "undecided",
        }
    }

    /// A verdict by its name; the names of tables written before the three-way verdict
    /// (`stable`, `passes`; `drifting`, `fails`) read as pass and fail.
    pub fn parse(text: &str) -> Option<Self> {
        match text {
            "stable" | "passes" => return Some(Verdict::Pass),
            "drifting" | "fails" => return Some(Verdict::Fail),
            _ => {}
        }
        [
            Verdict::Unstable,
            Verdict::Pass,
            Verdict::Fail,
            Verdict::Undecided,
        ]
        .into_iter()
        .find(|v| v.name() == text)
    }

    /// The scan's verdict of a criterion's verdict.
    pub fn of(verdict: &verdict::Verdict) -> Self {
        match verdict {
            verdict::Verdict::Pass => Verdict::Pass,
            verdict::Verdict::Fail => Verdict::Fail,
            verdict::Verdict::Undecided { .. } => Verdict::Undecided,
        }
    }

    /// Whether the point is safe by its criterion (an undecided point is not).
    pub fn is_safe(self) -> bool {
        self == Verdict::Pass
    }
}
