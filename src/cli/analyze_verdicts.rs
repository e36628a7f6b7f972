//! `longstep analyze … --reference REF`: every run judged against a reference run, criterion
//! by criterion ([`crate::studies::criterion::reference`]): the flags, the table printed, the JSON.

use std::path::PathBuf;

use clap::Args;
use serde_json::{Value as Json, json};

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
    /// engine, analysed as the runs are.
    #[arg(long, value_name = "REF")]
    pub reference: Option<PathBuf>,
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
