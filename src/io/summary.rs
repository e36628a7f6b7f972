//! The run summary: printed on one screen, or as one JSON object with `--json`.
//!
//! The JSON keys are a contract with scripts and later commands: `method`, `h`, `steps`,
//! `t_end`, `force_evaluations` (`fast`, `slow`, `hessian_vector`, …), `energy`
//! (`initial`, `final`, `max_abs_error`, `max_relative_error`), `wall_seconds`, `status`
//! (`"ok"`, `"unstable"` or `"failed"`) and `unstable_at` when not ok, `drift` (the fitted
//! energy drift and its bound, when the run was long enough to fit one), `warnings` (an
//! array, empty when there is nothing to warn about), `temperature` (the kinetic
//! temperature's `mean`, `initial`, `final` and `degrees_of_freedom`, when recorded); in a
//! scene with real units `units` (the unit of every quantity: `time` `"fs"`, `energy`
//! `"kcal/mol"`, `temperature` `"K"`, `drift` `"kT/ns/dof"`, …; `h`, `t_end` and
//! `unstable_at` are in its time unit) and `ns_per_day`. Methods and scenes may add objects
//! of their own (`pseudo_energy`, `exact_error`).
//!
//! The text form gives times in fs, ps or ns by their size in a scene with real units
//! (`h = 4 fs`, `t = 10 ps`), and every energy with its unit.

use crate::io::number::{Num, shorten_numbers};
use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::split::ForceCounts;
use crate::units::Units;

#[derive(Clone, Debug, Default, Serialize)]
pub struct ForceEvaluations {
    /// Gradient evaluations of level 0.
    pub fast: u64,
    /// Gradient evaluations of the outermost level.
    pub slow: u64,
    /// Hessian-vector products, all levels.
    pub hessian_vector: u64,
    /// Gradient evaluations per level, innermost first (more than two with recursive
    /// r-RESPA).
    pub levels: Vec<u64>,
    /// Elementary interactions evaluated (springs, pairs, angles), gradients and
    /// Hessian-vector products together.
    pub interactions: u64,
    /// Term evaluations: one per elementary interaction per force evaluation (quadrature
    /// node), the unit of MEMM18's counts N_s and N_a (4.3.1). The same number as
    /// `interactions`, under the name the pseudo-energy comparisons use.
    pub terms: u64,
}

impl From<&ForceCounts> for ForceEvaluations {
    fn from(counts: &ForceCounts) -> Self {
        ForceEvaluations {
            fast: counts.gradient.first().copied().unwrap_or(0),
            slow: counts.gradient.last().copied().unwrap_or(0),
            hessian_vector: counts.hessian_vector_total(),
            levels: counts.gradient.clone(),
            interactions: counts.interactions,
            terms: counts.interactions,
        }
    }
}

#[derive(Clone, Debug, Default, Serialize)]
pub struct EnergySummary {
    pub initial: f64,
    #[serde(rename = "final")]
    pub last: f64,
    pub max_abs_error: f64,
    pub max_relative_error: f64,
}

#[derive(Clone, Debug, Default, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    #[default]
    Ok,
    Unstable,
    Failed,
}

/// The unit of a drift in a scene with real units.
pub const REAL_DRIFT_UNIT: &str = "kT/ns/dof";

/// The drift unit of a dimensionless scene (kT by equipartition, as in real units).
pub const DIMENSIONLESS_DRIFT_UNIT: &str = "kT per unit time per dof";

/// The verdict of a drift that is not judged: a run at rest has no kT to measure it in.
pub const NO_VERDICT: &str = "none";

/// The fit of a method's conserved energy.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Conserved {
    /// Its `energy.csv` column.
    pub name: String,
    pub slope: f64,
    pub fluctuation: f64,
}

/// A fitted drift.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Drift {
    pub rows: usize,
    /// The time span fitted.
    pub from: f64,
    pub to: f64,
    pub mean_kinetic: f64,
    /// The kinetic temperature `2⟨K⟩/(n_dof k_B)` of the fitted rows, where the run
    /// records a temperature (scenes with real units).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub temperature: Option<f64>,
    /// Slope of the true energy `K + V`, energy per time.
    pub true_slope: f64,
    /// The standard deviation of the true energy about the fitted line.
    pub true_fluctuation: f64,
    /// The conserved energy's fit, when the method reports one.
    pub conserved: Option<Conserved>,
}

impl Drift {
    /// A slope in kT per unit time per degree of freedom, `slope / (2⟨K⟩)` (0 when nothing
    /// moves).
    pub fn rate(&self, slope: f64) -> f64 {
        if self.mean_kinetic > 0.0 {
            slope / (2.0 * self.mean_kinetic)
        } else {
            0.0
        }
    }

    /// The drift rate of the true energy, kT per unit time per degree of freedom.
    pub fn true_rate(&self) -> f64 {
        self.rate(self.true_slope)
    }

    /// The drift rate of the conserved energy, when the method reports one.
    pub fn conserved_rate(&self) -> Option<f64> {
        self.conserved.as_ref().map(|c| self.rate(c.slope))
    }

    /// The energy a method is judged by: its conserved energy when it reports one, else
    /// the true energy; with its name, slope and fluctuation about the line.
    pub fn judged(&self) -> (&str, f64, f64) {
        match &self.conserved {
            Some(c) => (&c.name, c.slope, c.fluctuation),
            None => ("total", self.true_slope, self.true_fluctuation),
        }
    }
}

/// A drift judged against its bound, for the summary and the JSON (`drift`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DriftReport {
    /// The energy judged: the method's conserved energy (its `energy.csv` column), or
    /// `total`.
    pub energy: String,
    /// Its drift, in `unit`.
    pub value: f64,
    /// The drift of the true energy `K + V`, in `unit`.
    pub true_energy: f64,
    /// The drift of the conserved energy, when the method reports one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub conserved_energy: Option<f64>,
    /// `kT/ns/dof` in a scene with real units, `kT per unit time per dof` in a
    /// dimensionless one (`crate::run::drift`).
    pub unit: String,
    pub bound: f64,
    /// `|value| > bound`.
    pub exceeded: bool,
    /// The standard error of `value`: the judged energy's fluctuation about its line over
    /// the fitted span, converted like the slope (`crate::run::drift::judge`).
    pub error: f64,
    /// `pass`, `fail` or `undecided` (`crate::run::verdict`), or `none` for a run at rest
    /// (no kT to measure a drift in), and the run length (scene time unit) that would
    /// decide an undecided drift, when one would.
    pub verdict: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub decide_at: Option<f64>,
    /// The verdict in words, as every command prints it.
    pub verdict_text: String,
    /// The half-width of the verdict's confidence interval in standard errors.
    pub z: f64,
    /// The fitted change of the judged energy over the span, and its standard deviation
    /// about the fitted line, in the scene's energy unit.
    pub change: f64,
    pub fluctuation: f64,
    /// The time span fitted, in the scene's time unit, and the rows in it.
    pub from: f64,
    pub to: f64,
    pub rows: usize,
}

impl DriftReport {
    /// One line: the judged drift, the true one beside it, the span and the bound.
    pub fn to_text(&self, units: Units) -> String {
        let time = |t: f64| format_time(t, units);
        if self.verdict == NO_VERDICT {
            return format!(
                "{}; the {} energy changed by {} over t = {}–{} ({} rows)",
                self.verdict_text,
                if self.energy == "total" {
                    "true"
                } else {
                    &self.energy
                },
                format!("{} {}", signed(self.change), units.energy_name()).trim_end(),
                time(self.from),
                time(self.to),
                self.rows,
            );
        }
        let by = match &self.conserved_energy {
            Some(_) => format!(
                "by the conserved energy ({}); true energy {}",
                self.energy,
                signed(self.true_energy)
            ),
            None => "by the true energy".to_string(),
        };
        let unit = &self.unit;
        format!(
            "{} ± {} {unit} {by}; fitted over t = {}–{} ({} rows); bound {} at {}σ: {}",
            signed(self.value),
            significant(self.error, 2),
            time(self.from),
            time(self.to),
            self.rows,
            self.bound,
            self.z,
            self.verdict_text
        )
    }

    /// The warning of a drift beyond its bound.
    pub fn warning(&self) -> Option<String> {
        if self.verdict != "fail" {
            return None;
        }
        Some(format!(
            "the energy drifts by {} {} ({}), beyond the bound {}: this run {} — not \
             energy-conserving at this step; try a smaller outer step (`longstep scan steps` \
             finds the largest safe one) or raise --drift-bound",
            signed(self.value),
            self.unit,
            if self.conserved_energy.is_some() {
                format!("conserved energy {}", self.energy)
            } else {
                "true energy".to_string()
            },
            self.bound,
            if self.value > 0.0 { "heats" } else { "cools" }
        ))
    }
}

/// A signed number for reading: three significant digits, in exponent form when very
/// large or small.
fn signed(x: f64) -> String {
    if x != 0.0 && (x.abs() < 1e-3 || x.abs() >= 1e5) {
        format!("{x:+.2e}")
    } else {
        let text = significant(x, 3);
        if x >= 0.0 { format!("+{text}") } else { text }
    }
}

/// How often a non-bonded term's cluster-pair list was built and pruned over a run
/// (GROMACS's `nstlist` and its dynamic pruning interval): the list holds the pairs within
/// `cutoff + outer_buffer` and is rebuilt when two atoms may have closed the outer buffer;
/// the kernel runs over the pairs within `cutoff + inner_buffer`, pruned again when two
/// atoms may have closed the inner one (`forces::clusters`). Every build prunes too.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct PairListSummary {
    /// The term's name (`nonbonded`).
    pub term: String,
    pub builds: u64,
    /// Prunings, the one after each build included.
    pub prunes: u64,
    /// The cutoff; `None` where there is none (every pair is listed; JSON has no infinity).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cutoff: Option<f64>,
    pub outer_buffer: f64,
    pub inner_buffer: f64,
    /// Atom pairs of the outer list and of the inner one at the end of the run.
    pub outer_pairs: usize,
    pub inner_pairs: usize,
}

impl PairListSummary {
    /// The summary's `pair list` line over `steps` outer steps.
    fn line(&self, steps: u64, units: Units) -> String {
        let every = |count: u64| {
            if count == 0 {
                "none".to_string()
            } else {
                significant(steps as f64 / count as f64, 3)
            }
        };
        let cutoff = match self.cutoff {
            Some(c) => format!("beyond the cutoff {}", units.length(c)),
            None => "(no cutoff)".to_string(),
        };
        format!(
            "pair list  {}: {} builds, {} prunes (one per {} / {} outer steps), buffers outer {} / \
             inner {} {cutoff}, {} / {} atom pairs",
            self.term,
            self.builds,
            self.prunes,
            every(self.builds),
            every(self.prunes),
            units.length(self.outer_buffer),
            units.length(self.inner_buffer),
            self.outer_pairs,
            self.inner_pairs
        )
    }
}

/// The kinetic temperature `2K / (n_dof k_B)` over the recorded rows.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct TemperatureSummary {
    pub mean: f64,
    pub initial: f64,
    #[serde(rename = "final")]
    pub last: f64,
    pub rows: usize,
    pub degrees_of_freedom: usize,
}

#[derive(Clone, Debug, Default, Serialize)]
pub struct RunSummary {
    pub scene: String,
    pub method: String,
    pub parameters: String,
    pub h: f64,
    pub steps: u64,
    /// The time reached (the requested end time, or the time of a blow-up).
    pub t_end: f64,
    /// The end time asked for (`--t-end`): a whole number of steps of `h` may pass it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub requested_t_end: Option<f64>,
    pub force_evaluations: ForceEvaluations,
    /// The non-bonded terms' pair lists over the run (`run::prepare` fills it).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub pair_lists: Vec<PairListSummary>,
    pub energy: EnergySummary,
    pub wall_seconds: f64,
    pub status: Status,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unstable_at: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub message: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub energy_csv: Option<String>,
    /// The unit of every quantity, in a scene with real units.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub units: Option<BTreeMap<&'static str, &'static str>>,
    /// Simulated time per day of wall time, in a scene with real units.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ns_per_day: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub temperature: Option<TemperatureSummary>,
    /// The fitted energy drift judged against its bound ([`RunSummary::judge_drift`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub drift: Option<DriftReport>,
    pub warnings: Vec<String>,
    /// The raw drift fit of the run loop.
    #[serde(skip)]
    pub fit: Option<Drift>,
    /// The run's energy scale (`|E0|`, or `K0 + Σ|V|` when `E0` is nearly zero).
    #[serde(skip)]
    pub energy_reference: f64,
    /// The scene's units, for the text form.
    #[serde(skip)]
    pub scene_units: Units,
    /// Method- or scene-specific objects, each a top-level key of the JSON summary
    /// (`pseudo_energy` from the pseudo-energy methods, `exact_error` from scenes with an
    /// exact solution).
    #[serde(flatten)]
    pub extra: BTreeMap<String, serde_json::Value>,
    /// A run continued from a checkpoint (`run --restart`): its steps, energy errors,
    /// drift fit and temperature cover only the continued part.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub continued_from: Option<Continuation>,
}

/// Where a continued run took over.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Continuation {
    pub checkpoint: String,
    /// The checkpoint's outer step, counted from the start of the whole run.
    pub step: u64,
    pub t: f64,
    /// The time the whole run started at.
    pub t0: f64,
}

impl Continuation {
    /// The summary's `continued` line.
    fn line(&self, units: Units) -> String {
        let time = |t: f64| format_time(t, units);
        format!(
            "continued  from {} at step {}, t = {} (the run began at t0 = {}): E0 is the whole \
             run's; steps, max |dE|, the drift fit and the temperature cover t ≥ {} only",
            self.checkpoint,
            self.step,
            time(self.t),
            time(self.t0),
            time(self.t)
        )
    }
}

impl RunSummary {
    /// Set the scene's units: the JSON's `units` object and `ns_per_day` in a real scene.
    pub fn set_units(&mut self, units: Units) {
        self.scene_units = units;
        if units == Units::Real {
            let mut map: BTreeMap<&'static str, &'static str> =
                units.labels().into_iter().collect();
            map.insert("temperature", units.temperature_name());
            map.insert("drift", REAL_DRIFT_UNIT);
            self.units = Some(map);
            self.ns_per_day = ns_per_day(self.t_end, self.wall_seconds, units);
        }
    }

    /// `" (past --t-end 21 fs: a whole number of steps of 2 fs)"` when the run ended
    /// later than asked (more than rounding), else empty.
    fn past_end_note(&self) -> String {
        let units = self.scene_units;
        match self.requested_t_end {
            Some(asked) if self.status == Status::Ok && self.t_end > asked + 1e-9 * self.h => {
                format!(
                    " (past --t-end {}: a whole number of steps of {})",
                    format_time(asked, units),
                    format_time(self.h, units)
                )
            }
            _ => String::new(),
        }
    }

    /// `ok`, or `UNSTABLE at t = …: message` (`FAILED …` for a method that failed).
    fn status_text(&self) -> String {
        let time = |t: f64| format_time(t, self.scene_units);
        match (&self.status, self.unstable_at) {
            (Status::Ok, _) => "ok".to_string(),
            (status, Some(t)) => format!(
                "{} at t = {}: {}",
                if *status == Status::Unstable {
                    "UNSTABLE"
                } else {
                    "FAILED"
                },
                time(t),
                self.message.as_deref().unwrap_or("")
            ),
            (_, None) => "failed".to_string(),
        }
    }

    /// The one-screen text form.
    pub fn to_text(&self) -> String {
        let units = self.scene_units;
        let time = |t: f64| format_time(t, units);
        let energy_unit = match units {
            Units::None => String::new(),
            _ => format!(" {}", units.energy_name()),
        };
        let f = &self.force_evaluations;
        let mut lines = vec![
            format!("scene      {}", self.scene),
            format!(
                "method     {} ({})",
                self.method,
                annotate_times(&self.parameters, units)
            ),
            format!(
                "steps      {} to t = {}{}",
                self.steps,
                time(self.t_end),
                self.past_end_note()
            ),
            format!(
                "forces     fast {}, slow {}, hessian-vector {}  (per level: {:?})",
                f.fast, f.slow, f.hessian_vector, f.levels
            ),
            format!(
                "energy     E0 = {:.10e}{energy_unit}, final = {:.10e}{energy_unit}, max |dE| = {:.3e}{energy_unit}, max |dE|/|E0| = {:.3e}",
                self.energy.initial,
                self.energy.last,
                self.energy.max_abs_error,
                self.energy.max_relative_error
            ),
        ];
        lines.extend(self.pair_lists.iter().map(|p| p.line(self.steps, units)));
        lines.extend(self.continued_from.as_ref().map(|c| c.line(units)));
        if let Some(t) = &self.temperature {
            let unit = match units {
                Units::None => " (k_B T)".to_string(),
                _ => format!(" {}", units.temperature_name()),
            };
            lines.push(format!(
                "temperature mean {:.4}{unit} over {} rows (start {:.4}, final {:.4}; {} degrees of freedom)",
                t.mean, t.rows, t.initial, t.last, t.degrees_of_freedom
            ));
        }
        if let Some(drift) = &self.drift {
            lines.push(format!("drift      {}", drift.to_text(units)));
        }
        lines.push(match self.ns_per_day {
            Some(rate) => format!(
                "wall time  {:.3} s ({} ns/day)",
                self.wall_seconds,
                significant(rate, 4)
            ),
            None => format!("wall time  {:.3} s", self.wall_seconds),
        });
        for warning in &self.warnings {
            lines.push(format!("warning    {warning}"));
        }
        lines.push(format!("status     {}", self.status_text()));
        for (key, value) in &self.extra {
            lines.push(format!(
                "{:<10} {}",
                key.replace('_', "-"),
                compact_json(value, units)
            ));
        }
        if let Some(path) = &self.energy_csv {
            lines.push(format!("output     {path}"));
        }
        lines.join("\n")
    }
}

/// Simulated ns per day of wall time for a run from t = 0 to `t_end` (scene time units).
pub fn ns_per_day(t_end: f64, wall_seconds: f64, units: Units) -> Option<f64> {
    let ns = units.time_units().iter().find(|(name, _)| *name == "ns")?.1;
    (wall_seconds > 0.0).then(|| t_end / ns / (wall_seconds / 86_400.0))
}

/// A time for reading: in a scene with real units in fs, ps or ns by its size (`4 fs`,
/// `10 ps`, `2.5 ns`; six significant digits); as the plain number otherwise.
pub fn format_time(t: f64, units: Units) -> String {
    if units != Units::Real || !t.is_finite() {
        return Num(t).to_string();
    }
    let (scale, name) = match t.abs() {
        x if x < 1e3 => (1.0, "fs"),
        x if x < 1e6 => (1e3, "ps"),
        _ => (1e6, "ns"),
    };
    format!("{} {name}", significant(t / scale, 6))
}

pub use crate::units::significant;

/// A method's parameter line with units on its times in a real scene: `h = 4, dt = 0.5`
/// → `h = 4 fs, dt = 0.5 fs` (the names of steps: `h`, `dt`, `h_slow`, `h_fast`, `h_min`,
/// `h_max`, `tau`).
pub fn annotate_times(parameters: &str, units: Units) -> String {
    if units != Units::Real {
        return shorten_numbers(parameters);
    }
    const TIMES: &[&str] = &["h", "dt", "h_slow", "h_fast", "h_min", "h_max", "tau"];
    parameters
        .split(", ")
        .map(|part| match part.split_once(" = ") {
            Some((name, value)) => match value.parse::<f64>() {
                Ok(t) if TIMES.contains(&name) => format!("{name} = {}", format_time(t, units)),
                Ok(x) => format!("{name} = {}", with_unit(name, x, units)),
                Err(_) => annotate_leading(name, value, units),
            },
            None => part.to_string(),
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// `value` (`"0.1 (on v2)"`) with the unit of `name` after its leading number, in a real scene.
fn annotate_leading(name: &str, value: &str, units: Units) -> String {
    match value.split_once(' ') {
        Some((number, rest)) => match number.parse::<f64>() {
            Ok(x) => format!("{name} = {} {rest}", with_unit(name, x, units)),
            Err(_) => format!("{name} = {value}"),
        },
        None => format!("{name} = {value}"),
    }
}

/// A run parameter with its unit in a real scene: `kT` as energy (6 significant digits),
/// `friction` as a rate (1/fs); anything else as it is.
fn with_unit(name: &str, x: f64, units: Units) -> String {
    match name {
        "kT" => format!("{} {}", significant(x, 6), units.energy_name()),
        "friction" => format!("{} 1/{}", Num(x), units.time_name()),
        _ => Num(x).to_string(),
    }
}

/// A JSON object on one line, numbers in short exponent form: `a = 1.2e-13, b = "gl3"`.
/// In a real scene `kT`, `friction` and `tau` carry their units (`kT = 5.961613e-1 kcal/mol`).
fn compact_json(value: &serde_json::Value, units: Units) -> String {
    match value {
        serde_json::Value::Object(map) => map
            .iter()
            .map(|(k, v)| {
                let unit = match (units, k.as_str()) {
                    (Units::None, _) => String::new(),
                    (_, "kT") => format!(" {}", units.energy_name()),
                    (_, "friction") => format!(" 1/{}", units.time_name()),
                    (_, "tau") => format!(" {}", units.time_name()),
                    _ => String::new(),
                };
                format!("{k} = {}{unit}", compact_json(v, units))
            })
            .collect::<Vec<_>>()
            .join(", "),
        serde_json::Value::Number(n) => match n.as_f64() {
            Some(x) if n.is_f64() => format!("{x:.6e}"),
            _ => n.to_string(),
        },
        other => other.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_read_in_fs_ps_or_ns() {
        assert_eq!(format_time(4.0, Units::Real), "4 fs");
        assert_eq!(format_time(0.5, Units::Real), "0.5 fs");
        assert_eq!(format_time(10_000.0, Units::Real), "10 ps");
        assert_eq!(format_time(2_500.000_000_01, Units::Real), "2.5 ps");
        assert_eq!(format_time(3e6, Units::Real), "3 ns");
        assert_eq!(format_time(0.25, Units::None), "0.25");
        assert_eq!(
            annotate_times("h = 4, inner_steps = 8, dt = 0.5", Units::Real),
            "h = 4 fs, inner_steps = 8, dt = 0.5 fs"
        );
        assert_eq!(annotate_times("h = 4", Units::None), "h = 4");
    }
}
