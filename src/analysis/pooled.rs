//! The statistics of pooling independent runs: one quantity's pooled mean and its error
//! parts ([`pool`]), and what a pooled analysis records ([`Pooling`]); the runs' analyses
//! are pooled by [`super::pooling`].
//!
//! Independent runs pooled (`longstep analyze … --reference A --reference B`): each
//! quantity's mean weighted by the runs' sampled lengths, its error from both the runs' own
//! error bars and the scatter of their means (docs/studies.md, "A reference of several
//! runs", derives it).
//!
//! With `m` runs of sampled lengths `T_i` (after `--skip`), weights `w_i = T_i/ΣT`, means
//! `x_i` and standard errors `σ_i`:
//!
//! * pooled mean `x̄ = Σ w_i x_i` (a time average over all the runs' frames);
//! * **within-run** error `σ_w = √(Σ w_i² σ_i²)`: what the runs' own error bars say, the
//!   runs being independent;
//! * **between-run** error `σ_b = √(Σ w_i (x_i − x̄)²/(m − 1))`: an unbiased estimate of
//!   `Var(x̄)` from the means alone when each run's variance is `c/T_i` (a time average of
//!   a stationary process, whatever `c`), with `m − 1` degrees of freedom; none with one run;
//! * the error `max(σ_w, σ_b)`: the scatter of the runs is the honest measure where their
//!   own error bars are too small (slow basins: the solvated dipeptide's are ~1.7× too
//!   small), the within-run error where the scatter, from few runs, happens to be small.
//!
//! Cost: O(m) per quantity.

use serde::Serialize;

use super::block_average::Estimate;

/// One quantity pooled over independent runs (module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Pooled {
    pub mean: f64,
    /// `max(within, between)`: what a verdict uses.
    pub error: f64,
    /// `√(Σ w_i² σ_i²)`.
    pub within: f64,
    /// `√(Σ w_i (x_i − x̄)²/(m − 1))`; `None` with one run.
    pub between: Option<f64>,
    /// `m`.
    pub runs: usize,
}

impl Pooled {
    /// As an [`Estimate`] of `blocks` blocks.
    pub fn estimate(&self, blocks: usize) -> Estimate {
        Estimate {
            mean: self.mean,
            error: self.error,
            blocks,
        }
    }
}

/// The weights `w_i = T_i/ΣT` of runs of sampled lengths `lengths`; equal weights when the
/// lengths do not sum to a positive number.
pub fn weights(lengths: &[f64]) -> Vec<f64> {
    let total: f64 = lengths.iter().sum();
    if total > 0.0 && total.is_finite() {
        lengths.iter().map(|t| t / total).collect()
    } else {
        vec![1.0 / lengths.len() as f64; lengths.len()]
    }
}

/// `estimates` of independent runs of sampled lengths `lengths`, pooled (module
/// documentation). A NaN error of any run (a run of one block) makes the within-run
/// error NaN, and the pooled error with it: nothing is judged on it.
pub fn pool(estimates: &[Estimate], lengths: &[f64]) -> Pooled {
    assert_eq!(estimates.len(), lengths.len(), "one length per estimate");
    let m = estimates.len();
    let w = weights(lengths);
    let mean: f64 = w.iter().zip(estimates).map(|(w, e)| w * e.mean).sum();
    let within = w
        .iter()
        .zip(estimates)
        .map(|(w, e)| (w * e.error).powi(2))
        .sum::<f64>()
        .sqrt();
    let between = (m >= 2).then(|| {
        let squares: f64 = w
            .iter()
            .zip(estimates)
            .map(|(w, e)| w * (e.mean - mean).powi(2))
            .sum();
        (squares / (m - 1) as f64).sqrt()
    });
    let error = match between {
        _ if within.is_nan() => f64::NAN,
        Some(b) => within.max(b),
        None => within,
    };
    Pooled {
        mean,
        error,
        within,
        between,
        runs: m,
    }
}

/// What a pooled [`RunAnalysis`] records of its pooling: each run's sampled length, every
/// criterion's quantity pooled (named as the criterion), the basins' populations.
#[derive(Clone, Debug, PartialEq)]
pub struct Pooling {
    pub lengths: Vec<f64>,
    pub parts: Vec<(String, Pooled)>,
    /// Each basin's population pooled over residues, then over runs.
    pub basins: Option<[Estimate; 3]>,
}
