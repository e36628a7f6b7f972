//! The backbone basin criterion: each (φ, ψ) basin's population in a run against the
//! reference's, pooled over every residue with φ and ψ, with the span the run's error bars
//! shrink with. Shared by the per-term criteria ([`super::reference`]) and the scan's
//! sampling criterion ([`super::sampling`]), which both import it.

use serde::Serialize;

use crate::analysis::block_average::Estimate;
use crate::analysis::dihedrals::{BASINS, ResidueBasins, pooled_populations};
use crate::run::verdict::{self, MEAN_EXPONENT, Measurement};

/// One backbone basin's population in a run against the reference's.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BasinComparison {
    /// Its name ([`BASINS`]).
    pub basin: String,
    /// The run's population and its block error.
    pub population: f64,
    pub error: f64,
    /// Run minus reference, and `√(σ_run² + σ_ref²)`.
    pub difference: f64,
    pub combined_error: f64,
    pub verdict: verdict::Verdict,
}

/// Each basin's population in `run` against `reference`, pooled over residues, judged
/// against `bound` with the span of `bounds`; none when either has no backbone.
pub fn compare_basins(
    reference: &[ResidueBasins],
    run: &[ResidueBasins],
    bounds: &Bounds,
    bound: f64,
) -> Vec<BasinComparison> {
    compare_populations(
        pooled_populations(reference),
        pooled_populations(run),
        bounds,
        bound,
    )
}

/// Each basin's population in a run against the reference's, both already pooled over
/// residues ([`crate::analysis::run_analysis::RunAnalysis::basin_populations`]: a pooled
/// reference's are pooled over its runs too); none when either is `None`.
pub fn compare_populations(
    reference: Option<[Estimate; 3]>,
    run: Option<[Estimate; 3]>,
    bounds: &Bounds,
    bound: f64,
) -> Vec<BasinComparison> {
    let (Some(reference), Some(run)) = (reference, run) else {
        return Vec::new();
    };
    BASINS
        .iter()
        .zip(run.iter().zip(&reference))
        .map(|(name, (p, r))| {
            let m = difference(p, r, bounds);
            // A zero error is no transition seen in any block of either run: not a
            // measured certainty, so it decides nothing.
            let verdict = match m.standard_error() > 0.0 {
                true => verdict::judge(&m, bound),
                false => verdict::Verdict::Undecided { decide_at: None },
            };
            BasinComparison {
                basin: name.to_string(),
                population: p.mean,
                error: p.error,
                difference: m.value,
                combined_error: m.standard_error(),
                verdict,
            }
        })
        .collect()
}

/// The bounds of the comparison and the analysed span of the run, `[start, start + span]`
/// (scene time unit): the span the run's error bars shrink with.
#[derive(Clone, Copy, Debug)]
pub struct Bounds {
    pub potential: f64,
    pub peak: f64,
    pub start: f64,
    pub span: f64,
}

/// A difference of two estimates as a measurement over the run's analysed span: the run's
/// error shrinks with a longer run, the reference's does not.
fn difference(run: &Estimate, reference: &Estimate, bounds: &Bounds) -> Measurement {
    Measurement {
        value: run.mean - reference.mean,
        error: run.error,
        fixed_error: reference.error,
        start: bounds.start,
        span: bounds.span,
        exponent: MEAN_EXPONENT,
    }
}
