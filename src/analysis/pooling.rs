//! Independent runs' analyses pooled into one [`RunAnalysis`] (`longstep analyze …
//! --reference A --reference B`), each judged quantity by [`super::pooled::pool`] (its
//! module documentation gives the statistics; docs/studies.md, "A reference of several
//! runs", derives them), after checking that the runs are of one model and one clock.
//!
//! Cost: a pass over each run's results; no frame is read again.

use super::block_average::Estimate;
use super::dihedrals::{BASINS, pooled_populations};
use super::pooled::{Pooled, Pooling, pool, weights};
use super::run_analysis::{ConfigurationalResult, EnergySource, RunAnalysis};

/// Two runs that cannot be pooled: what differs, in run `index` (0-based) against run 0.
#[derive(Clone, Debug, PartialEq)]
pub struct Mismatch {
    pub what: &'static str,
    pub index: usize,
    pub first: String,
    pub other: String,
}

/// What must be equal for runs to be of one model: molecules, terms, g(r) pairs, backbone
/// residues, the clock's unit, the degrees of freedom of runs with kinetic energies.
fn signature(run: &RunAnalysis) -> [(&'static str, String); 6] {
    let names = |v: Vec<&str>| v.join(",");
    [
        ("molecules", run.molecules.to_string()),
        (
            "terms",
            names(run.terms.iter().map(|t| t.name.as_str()).collect()),
        ),
        (
            "g(r) pairs",
            names(run.rdf.iter().map(|r| r.name.as_str()).collect()),
        ),
        (
            "backbone residues",
            names(run.basins.iter().map(|b| b.label.as_str()).collect()),
        ),
        (
            "time unit",
            match run.source {
                EnergySource::Frames { times: false } => "frame numbers (give --frame-time)",
                _ => "the scene's time unit",
            }
            .to_string(),
        ),
        (
            "degrees of freedom",
            match run.source {
                EnergySource::Table => run.dof.to_string(),
                EnergySource::Frames { .. } => "any (no velocities)".to_string(),
            },
        ),
    ]
}

/// Refuse runs of different models or clocks (the first difference against run 0).
pub fn check_poolable(runs: &[RunAnalysis]) -> Result<(), Mismatch> {
    let Some(first) = runs.first() else {
        return Ok(());
    };
    let reference = signature(first);
    for (index, run) in runs.iter().enumerate().skip(1) {
        for ((what, a), (_, b)) in reference.iter().zip(signature(run)) {
            let any = |s: &str| s.starts_with("any");
            if *a != b && !any(a) && !any(&b) {
                return Err(Mismatch {
                    what,
                    index,
                    first: a.clone(),
                    other: b,
                });
            }
        }
    }
    Ok(())
}

/// Independent runs of one model pooled into one [`RunAnalysis`] (module documentation):
/// every judged quantity's mean and error pooled, recorded in its [`Pooling`]; the rest
/// (g(r) curves, geometry, blocking tables) is run 0's. One run is returned as it is.
pub fn pool_runs(runs: &[RunAnalysis]) -> Result<RunAnalysis, Mismatch> {
    check_poolable(runs)?;
    let first = runs.first().expect("at least one run to pool");
    if runs.len() == 1 {
        return Ok(first.clone());
    }
    let lengths: Vec<f64> = runs.iter().map(|r| r.blocks.end - r.blocks.start).collect();
    let mut parts = Parts {
        lengths: &lengths,
        blocks: runs.iter().map(|r| r.blocks.count).sum(),
        parts: Vec::new(),
    };
    let mut out = first.clone();
    let each = |of: &dyn Fn(&RunAnalysis) -> Option<Estimate>| runs.iter().map(of).collect();
    out.potential_per_molecule = parts
        .take(
            "potential energy per molecule",
            each(&|r| Some(r.potential_per_molecule)),
        )
        .expect("every run has a potential energy");
    let kinetic = each(&|r| Some(r.kinetic_temperature).filter(|e| e.mean.is_finite()));
    out.kinetic_temperature = parts
        .take("kinetic temperature", kinetic)
        .unwrap_or(Estimate {
            mean: f64::NAN,
            error: f64::NAN,
            blocks: parts.blocks,
        });
    let configurational = each(&|r| r.configurational.as_ref().map(|c| c.temperature));
    let configurational = parts.take("configurational temperature", configurational);
    out.configurational = match (out.configurational.take(), configurational) {
        (Some(c), Some(temperature)) => Some(ConfigurationalResult { temperature, ..c }),
        _ => None,
    };
    pool_terms_and_peaks(&mut out, runs, &mut parts);
    let per_run: Option<Vec<[Estimate; 3]>> =
        runs.iter().map(|r| pooled_populations(&r.basins)).collect();
    let basins = per_run.map(|p| {
        std::array::from_fn(|k| {
            let estimates = Some(p.iter().map(|p| p[k]).collect());
            let name = format!("basin {} population", BASINS[k]);
            parts
                .take(&name, estimates)
                .expect("every run has the basins")
        })
    });
    out.blocks.end = out.blocks.start + lengths.iter().sum::<f64>();
    out.blocks.count = parts.blocks;
    out.frames = runs.iter().map(|r| r.frames).sum();
    out.rows = runs.iter().map(|r| r.rows).sum();
    let parts = parts.parts;
    out.pooled = Some(Box::new(Pooling {
        lengths,
        parts,
        basins,
    }));
    Ok(out)
}

/// The pooled quantities so far, and what pooling needs: the runs' lengths, their blocks.
struct Parts<'a> {
    lengths: &'a [f64],
    blocks: usize,
    parts: Vec<(String, Pooled)>,
}

impl Parts<'_> {
    /// Pool one quantity of every run (`None` when a run lacks it: nothing pooled).
    fn take(&mut self, name: &str, estimates: Option<Vec<Estimate>>) -> Option<Estimate> {
        let pooled = pool(&estimates?, self.lengths);
        self.parts.push((name.to_string(), pooled));
        Some(pooled.estimate(self.blocks))
    }
}

/// Each term's mean (its spread and basin error too) and each g(r) peak, pooled.
fn pool_terms_and_peaks(out: &mut RunAnalysis, runs: &[RunAnalysis], parts: &mut Parts) {
    for k in 0..out.terms.len() {
        let name = format!("mean {} energy", out.terms[k].name);
        let means = runs.iter().map(|r| r.terms[k].mean).collect();
        out.terms[k].mean = parts.take(&name, Some(means)).expect("every term");
        pool_term_spread(out, runs, k, parts.lengths);
    }
    for k in 0..out.rdf.len() {
        let name = format!("g {} first-peak height", out.rdf[k].name);
        let heights = runs.iter().map(|r| r.rdf[k].peak_height).collect();
        out.rdf[k].peak_height = parts.take(&name, heights);
        let name = format!("g {} first-peak position", out.rdf[k].name);
        let positions = runs.iter().map(|r| r.rdf[k].peak_position).collect();
        out.rdf[k].peak_position = parts.take(&name, positions);
    }
}

/// Term `k`'s basin-coupled error `√(Σ w_i² b_i²)` and its variance over the pooled frames,
/// `Σ w_i (Var_i + (x_i − x̄)²)` (the bound's scale: the runs' spread of means counts).
fn pool_term_spread(out: &mut RunAnalysis, runs: &[RunAnalysis], k: usize, lengths: &[f64]) {
    let w = weights(lengths);
    let mean = out.terms[k].mean.mean;
    let terms = runs.iter().map(|r| &r.terms[k]);
    out.terms[k].basin_error = w
        .iter()
        .zip(terms.clone())
        .map(|(w, t)| (w * t.basin_error).powi(2))
        .sum::<f64>()
        .sqrt();
    out.terms[k].variance = w
        .iter()
        .zip(terms)
        .map(|(w, t)| w * (t.variance + (t.mean.mean - mean).powi(2)))
        .sum();
}
