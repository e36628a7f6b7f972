//! `longstep analyze … --reference REF`: every run judged against a reference run, criterion
//! by criterion ([`crate::studies::criterion::reference`]): the flags, the table printed, the JSON.

use std::path::PathBuf;

use clap::Args;
use serde_json::{Value as Json, json};

use crate::analysis::pooling::{Mismatch, pool_runs};
use crate::analysis::run_analysis::RunAnalysis;
use crate::error::{Error, Result};
use crate::io::scene::Scene;
use crate::run::verdict::Verdict;
use crate::settings::Value;
use crate::studies::criterion::reference::{
    self as criteria, Criterion, CriterionSettings, DEFAULT_PEAK_BOUND, DEFAULT_POTENTIAL_BOUND,
    DEFAULT_TEMPERATURE_BOUND, Kind,
};
use crate::studies::criterion::sampling::DEFAULT_BASIN_BOUND;

#[derive(Args, Debug, Default)]
pub struct VerdictArgs {
    /// Judge every run against this reference: a run directory or a trajectory file of any
    /// engine, analysed as the runs are. Repeated, the references are independent runs
    /// pooled into one (each quantity's mean weighted by sampled length, its error the
    /// larger of the runs' own and their scatter), and each is also judged against the
    /// others pooled (a leave-one-out control).
    #[arg(long, value_name = "REF")]
    pub reference: Vec<PathBuf>,
    /// The temperature of the per-term bounds, e.g. 300K (default: the reference's kinetic
    /// temperature, else, for a trajectory file, its configurational temperature).
    #[arg(long, value_name = "T")]
    pub temperature: Option<String>,
    /// The temperature error ΔT the configurational temperature and each term's mean are
    /// held to (kelvin in a real scene).
    #[arg(long, default_value_t = DEFAULT_TEMPERATURE_BOUND, value_name = "DT")]
    pub temperature_bound: f64,
    /// Largest |Δ potential energy per molecule| that passes.
    #[arg(long, default_value_t = DEFAULT_POTENTIAL_BOUND)]
    pub potential_bound: f64,
    /// Largest |Δ g(r) first-peak height| that passes.
    #[arg(long, default_value_t = DEFAULT_PEAK_BOUND)]
    pub peak_bound: f64,
    /// Largest |Δ population| of a backbone basin that passes.
    #[arg(long, default_value_t = DEFAULT_BASIN_BOUND)]
    pub basin_bound: f64,
    /// Time between the frames of a trajectory file whose frames carry no time (.dcd, .nc),
    /// e.g. 1ps (default: times in frames).
    #[arg(long, value_name = "T")]
    pub frame_time: Option<String>,
}

impl VerdictArgs {
    /// The bounds, and the temperature: `--temperature`, else the reference's kinetic
    /// temperature (over the degrees of freedom its run counted), else (a trajectory file,
    /// no velocities) its configurational temperature, biased under constraints.
    pub fn settings(
        &self,
        scene: &Scene,
        reference: Option<&RunAnalysis>,
    ) -> Result<CriterionSettings> {
        for (value, flag) in [
            (self.temperature_bound, "--temperature-bound"),
            (self.potential_bound, "--potential-bound"),
            (self.peak_bound, "--peak-bound"),
            (self.basin_bound, "--basin-bound"),
        ] {
            if !(value > 0.0 && value.is_finite()) {
                return Err(Error::flag(flag, format!("{flag} must be positive"))
                    .expected("a positive number")
                    .got(value.to_string()));
            }
        }
        let temperature = match &self.temperature {
            Some(text) => Some(temperature_value(text, scene)?),
            None => reference.and_then(|r| {
                let kinetic = r.kinetic_temperature.mean;
                if kinetic > 0.0 && kinetic.is_finite() {
                    Some(kinetic)
                } else {
                    r.configurational.as_ref().map(|c| c.temperature.mean)
                }
            }),
        };
        Ok(CriterionSettings {
            potential_bound: self.potential_bound,
            peak_bound: self.peak_bound,
            basin_bound: self.basin_bound,
            temperature_bound: self.temperature_bound,
            temperature,
            boltzmann: scene.units.boltzmann(),
        })
    }
}

fn temperature_value(text: &str, scene: &Scene) -> Result<f64> {
    let flag = "--temperature";
    let value: Value = text
        .parse()
        .map_err(|_| Error::flag(flag, format!("{flag}: \"{text}\" is not a temperature")))?;
    let t = value.evaluate_time(&scene.parameters, flag, scene.units.temperature_units())?;
    if !(t > 0.0 && t.is_finite()) {
        return Err(Error::flag(flag, format!("{flag} must be positive")).got(text.to_string()));
    }
    Ok(t)
}

/// A run's criteria against the reference.
pub struct Verdicts {
    pub criteria: Vec<Criterion>,
    pub overall: Option<Verdict>,
}

/// Judge `run` against `reference`, in the scene's units of energy and temperature.
pub fn judge(
    units: (&str, &str),
    reference: &RunAnalysis,
    run: &RunAnalysis,
    settings: &CriterionSettings,
) -> Verdicts {
    let (energy, temperature) = units;
    let criteria = criteria::judge_runs(reference, run, settings, (energy, temperature));
    let overall = criteria::overall(&criteria);
    Verdicts { criteria, overall }
}

impl Verdicts {
    pub fn json(&self) -> Json {
        json!(self.criteria)
    }

    pub fn overall_name(&self) -> &'static str {
        self.overall.map_or("absent", |v| v.name())
    }

    /// The table: criterion, difference ± error, bound, verdict (`time`: the scene's unit).
    pub fn print(&self, time: &str, run: &RunAnalysis) {
        let time = criteria::time_unit(run, time);
        println!("  against the reference (difference ± combined standard error; bound):");
        for c in &self.criteria {
            let name = format!("{} [{}]", c.name, c.unit);
            let name = name.trim_end_matches(" []");
            match (c.difference, c.error, c.bound) {
                (Some(d), Some(e), Some(b)) => {
                    let decide = c.decide_at.map_or(String::new(), |t| {
                        format!(" (a run of ~{t:.3} {time} would decide)")
                    });
                    println!(
                        "    {name:<44} {d:+11.4} ± {e:9.4}  |Δ| ≤ {b:<9.4} {}{decide}",
                        c.verdict
                    );
                    // The estimator's caveat (biased under constraints) goes with its row.
                    if let (Kind::ConfigurationalTemperature, Some(note)) = (c.kind, &c.note) {
                        println!("      ({note})");
                    }
                }
                _ => println!(
                    "    {name:<44} {}: {}",
                    c.verdict,
                    c.note.as_deref().unwrap_or("")
                ),
            }
        }
        println!("  verdict: {}", self.overall_name());
    }
}

/// The reference: one run, or several independent runs pooled into one
/// ([`crate::analysis::pooling`]).
pub struct Reference {
    pub paths: Vec<PathBuf>,
    pub runs: Vec<RunAnalysis>,
    pub pooled: RunAnalysis,
}

/// Pool the analysed reference runs (`runs[i]` from `paths[i]`); runs of different models
/// or clocks are refused, naming both.
pub fn pool_reference(paths: &[PathBuf], runs: Vec<RunAnalysis>) -> Result<Reference> {
    let pooled = pool_runs(&runs).map_err(|m| mismatch(paths, &m))?;
    Ok(Reference {
        paths: paths.to_vec(),
        runs,
        pooled,
    })
}

fn mismatch(paths: &[PathBuf], m: &Mismatch) -> Error {
    let (first, other) = (paths[0].display(), paths[m.index].display());
    Error::flag(
        "--reference",
        format!(
            "--reference {other} cannot be pooled with {first}: they differ in {}",
            m.what
        ),
    )
    .key(m.what)
    .expected(m.first.clone())
    .got(m.other.clone())
}

impl Reference {
    /// Each run's label: its file or directory name.
    pub fn labels(&self) -> Vec<String> {
        self.paths
            .iter()
            .map(|p| {
                p.file_name()
                    .map_or_else(|| p.display().to_string(), |n| n.to_string_lossy().into())
            })
            .collect()
    }

    /// The reference as the JSON's `reference`: a path, or the paths of a pooled one.
    pub fn json_paths(&self) -> Json {
        match self.paths.as_slice() {
            [one] => json!(one),
            many => json!(many),
        }
    }

    /// `reference_pool`: the runs, their sampled lengths and weights, every pooled
    /// quantity's mean and error parts; `None` for one run.
    pub fn pool_json(&self) -> Option<Json> {
        let pooling = self.pooled.pooled.as_ref()?;
        let weights = crate::analysis::pooled::weights(&pooling.lengths);
        let runs: Vec<Json> = self
            .paths
            .iter()
            .zip(&pooling.lengths)
            .zip(weights)
            .map(|((p, t), w)| json!({ "run": p, "sampled_length": t, "weight": w }))
            .collect();
        let parts: Vec<Json> = pooling
            .parts
            .iter()
            .map(|(name, p)| {
                json!({ "quantity": name, "mean": p.mean, "error": p.error,
                        "within_runs": p.within, "between_runs": p.between })
            })
            .collect();
        Some(json!({
            "runs": runs,
            "between_runs_degrees_of_freedom": self.runs.len() - 1,
            "error": "max(within_runs, between_runs)",
            "parts": parts,
        }))
    }

    /// What a reader of a pooled reference should know of it; `None` for one run.
    pub fn notice(&self) -> Option<String> {
        let m = self.runs.len();
        (m >= 2).then(|| {
            let caveat = if m < MEANINGFUL_RUNS {
                format!(
                    "; with {} degree(s) of freedom the between-run part is a rough estimate \
                     (a 2σ interval on it covers ~{:.0} %, not 95 %; docs/studies.md)",
                    m - 1,
                    100.0 * STUDENT_COVERAGE[m - 2]
                )
            } else {
                String::new()
            };
            format!(
                "reference pooled from {m} runs ({}): each error the larger of the runs' own \
                 and their scatter{caveat}",
                self.labels().join(", ")
            )
        })
    }

    /// The reference run `k` against the pool of the others (a leave-one-out control).
    pub fn others(&self, k: usize) -> Result<Reference> {
        let keep = |v: &[PathBuf]| -> Vec<PathBuf> {
            v.iter()
                .enumerate()
                .filter(|&(i, _)| i != k)
                .map(|(_, p)| p.clone())
                .collect()
        };
        let runs = self
            .runs
            .iter()
            .enumerate()
            .filter(|&(i, _)| i != k)
            .map(|(_, r)| r.clone())
            .collect();
        pool_reference(&keep(&self.paths), runs)
    }
}

/// From this many runs the between-run error has 4 degrees of freedom, and a 2σ interval on
/// it covers 88 % (Student's t); fewer get a caveat in the notice.
pub const MEANINGFUL_RUNS: usize = 5;

/// `P(|t_ν| < 2)` for ν = 1, 2, 3 degrees of freedom (Student's t): the coverage of a 2σ
/// interval whose σ is estimated from ν + 1 runs.
const STUDENT_COVERAGE: [f64; 3] = [0.705, 0.816, 0.861];
