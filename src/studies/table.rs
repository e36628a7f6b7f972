//! The tables of a step-size scan (`scan.csv`, `timing.csv`; [`crate::io::study_csv`]):
//! their settings line, so shards of different scans never merge, and one row per point
//! (per timing) in the drift or the sampling criterion's columns.

use std::collections::BTreeMap;

use super::criterion::reference::Criterion;
use super::criterion::sampling::{SamplingCriterion, peak_height};
use super::plan::StepScanPlan;
use super::scan::{ScanSetup, StepResult, Timing};
use crate::analysis::run_analysis::RunAnalysis;
use crate::io::number::Num;
use crate::io::study_csv::StudyTable;
use crate::io::study_file::StudyFile;
use crate::io::summary::REAL_DRIFT_UNIT;
use crate::settings::RunSpec;
use crate::units::Units;

/// `default` for a setting not given, else its value.
fn or_default<T: std::fmt::Display>(value: Option<T>) -> String {
    value.map_or("default".into(), |v| v.to_string())
}

/// Simulated time per day of wall time: ns/day in a scene with real units, scene time
/// units per day otherwise.
pub fn per_day(t_end: f64, seconds: f64, units: Units) -> f64 {
    crate::io::summary::ns_per_day(t_end, seconds, units)
        .unwrap_or_else(|| t_end / (seconds / 86_400.0))
}

/// The unit of a scan's drift column.
fn drift_unit(units: Units) -> &'static str {
    match units {
        Units::Real => crate::io::summary::REAL_DRIFT_UNIT,
        Units::None => "kT per unit time per dof",
    }
}

/// The timing file: wall-clock medians, which no two machines share, apart from the
/// deterministic scan table.
pub fn timing_table(
    meta: BTreeMap<String, String>,
    timings: &[Timing],
    units: Units,
) -> StudyTable {
    let per_day_column = match units {
        Units::Real => "ns_per_day",
        Units::None => "time_per_day",
    };
    let mut table = StudyTable::new(
        "scan-steps-timing",
        meta,
        &[
            "method",
            "h",
            "threads",
            "repeats",
            "median_wall_seconds",
            per_day_column,
        ],
    );
    table = table.with_units(&[("h", units.time_name())]);
    for t in timings {
        table.rows.push(vec![
            t.method.clone(),
            Num(t.h).to_string(),
            t.threads.to_string(),
            t.repeats.to_string(),
            Num(t.median_seconds).to_string(),
            Num(per_day(t.t_end, t.median_seconds, units)).to_string(),
        ]);
    }
    with_config_column(table, timings.iter().map(|t| t.config.as_deref()))
}

/// The settings a scan's table records on its first line, so shards of different scans
/// never merge: the run length and criteria, and every method setting given.
pub fn scan_meta(
    plan: &StepScanPlan,
    setup: &ScanSetup,
    total: usize,
    sampling: Option<&(SamplingCriterion, RunAnalysis)>,
    units: Units,
) -> BTreeMap<String, String> {
    let run = &plan.run;
    let mut pairs: Vec<(&str, String)> = vec![
        ("points", total.to_string()),
        ("scene", plan.scene.display().to_string()),
        ("set", plan.set.join(" ")),
        (
            "t_end",
            run.t_end
                .as_ref()
                .map_or(setup.t_end.to_string(), |t| t.to_string()),
        ),
        ("inner_steps", or_default(run.inner_steps)),
        ("dt", or_default(run.dt.as_ref())),
        ("blowup", setup.base.blowup.unwrap_or(10.0).to_string()),
        (
            "precision",
            plan.precision.clone().unwrap_or_else(|| "double".into()),
        ),
    ];
    let given = given_settings(run);
    pairs.extend(given.iter().map(|(k, v)| (*k, v.clone())));
    if !plan.level_dt.is_empty() {
        let dts: Vec<String> = plan.level_dt.iter().map(|v| v.to_string()).collect();
        pairs.push(("level_dt", dts.join(";")));
    }
    match sampling {
        None => {
            pairs.push(("drift_bound", setup.drift_bound.to_string()));
            pairs.push(("drift_unit", drift_unit(units).to_string()));
            pairs.push(("starts", setup.starts.max(1).to_string()));
            if let Some(t) = setup.fit_from {
                pairs.push(("fit_from", t.to_string()));
            }
        }
        Some((c, reference)) => {
            pairs.extend(sampling_meta(c, reference));
        }
    }
    let mut meta: BTreeMap<String, String> = pairs
        .into_iter()
        .map(|(k, v)| (k.to_string(), v.replace(',', ";")))
        .collect();
    if let Some(shard) = &plan.shard {
        meta.insert("shard".into(), shard.clone());
    }
    meta
}

fn sampling_meta(c: &SamplingCriterion, reference: &RunAnalysis) -> Vec<(&'static str, String)> {
    let peak = peak_height(reference);
    vec![
        ("criterion", "sampling".into()),
        ("reference", c.reference.display().to_string()),
        ("pair", format!("{}-{}", c.pair.0, c.pair.1)),
        ("potential_bound", c.potential_bound.to_string()),
        ("peak_bound", c.peak_bound.to_string()),
        ("basin_bound", c.basin_bound.to_string()),
        ("basins", basins_notice(c, reference)),
        ("discard", c.discard.to_string()),
        ("blocks", c.blocks.to_string()),
        ("frames", c.frames.to_string()),
        (
            "reference_potential",
            format!(
                "{} ± {}",
                reference.potential_per_molecule.mean, reference.potential_per_molecule.error
            ),
        ),
        (
            "reference_peak",
            peak.map_or("none".into(), |p| format!("{} ± {}", p.mean, p.error)),
        ),
    ]
}

/// The method settings given on the command line, in the user's terms: the method
/// parameters (`inner_steps` aside, recorded given or not; the equilibrium mollifier's two
/// as one `molly`), the temperature and the seed.
fn given_settings(run: &RunSpec) -> Vec<(&'static str, String)> {
    let mut given: Vec<(&'static str, String)> = run
        .given_parameters()
        .into_iter()
        .filter(|(name, _)| {
            !matches!(
                *name,
                "inner_steps" | "molly_constraints" | "molly_jacobian"
            )
        })
        .collect();
    if let Some(t) = &run.temperature {
        given.push(("temperature", t.to_string()));
    }
    if let Some(seed) = run.seed {
        given.push(("seed", seed.to_string()));
    }
    if let Some(c) = &run.molly_constraints {
        let jacobian = run.molly_jacobian.as_deref().unwrap_or("default");
        given.push(("molly", format!("{c} {jacobian}")));
    }
    given
}

/// The scan's study table by the drift criterion (see `src/io/study_csv.rs`): one row per
/// point in index order.
pub fn scan_table(meta: BTreeMap<String, String>, results: &[StepResult]) -> StudyTable {
    let mut table = StudyTable::new(
        "scan-steps",
        meta.clone(),
        &[
            "index",
            "method",
            "h",
            "status",
            "drift",
            "true_drift",
            "judged_energy",
            "blowup_time",
            "max_relative_error",
            "steps",
            "slow_evaluations",
            "fast_evaluations",
            "hessian_vector",
            "drift_error",
            "decide_at",
            "starts",
        ],
    );
    let drift = match meta.get("drift_unit").map(String::as_str) {
        Some(REAL_DRIFT_UNIT) => (REAL_DRIFT_UNIT, Units::Real.time_name()),
        _ => ("", ""),
    };
    table = table.with_units(&[
        ("h", drift.1),
        ("drift", drift.0),
        ("true_drift", drift.0),
        ("blowup_time", drift.1),
        ("drift_error", drift.0),
        ("decide_at", drift.1),
    ]);
    for r in results {
        let detail = r.drift_detail.as_ref();
        table.rows.push(vec![
            r.index.to_string(),
            r.method.clone(),
            Num(r.h).to_string(),
            r.verdict.name().to_string(),
            Num(r.drift).to_string(),
            detail.map_or(String::new(), |d| Num(d.true_energy).to_string()),
            detail.map_or(String::new(), |d| d.energy.clone()),
            r.blowup_time.map_or(String::new(), |t| Num(t).to_string()),
            Num(r.max_relative_error).to_string(),
            r.steps.to_string(),
            r.slow_evaluations.to_string(),
            r.fast_evaluations.to_string(),
            r.hessian_vector.to_string(),
            detail.map_or(String::new(), |d| Num(d.error).to_string()),
            r.decide_at.map_or(String::new(), |t| Num(t).to_string()),
            r.starts.to_string(),
        ]);
    }
    with_config_column(table, results.iter().map(|r| r.config.as_deref()))
}

/// A study's table gains a `config` column after `index`, the label of each row's
/// configuration; a single scan's table is left as it was.
fn with_config_column<'a>(
    mut table: StudyTable,
    labels: impl Iterator<Item = Option<&'a str>>,
) -> StudyTable {
    let labels: Vec<Option<&str>> = labels.collect();
    if labels.iter().all(Option::is_none) {
        return table;
    }
    table.header.insert(1, "config".into());
    for (row, label) in table.rows.iter_mut().zip(labels) {
        row.insert(1, label.unwrap_or_default().to_string());
    }
    table
}

/// The scan's study table by the sampling criterion: each point's differences to the
/// reference and their combined errors; with a peptide backbone, each basin's Δp, its
/// combined error and the run's population; then the configurational temperature's and
/// each term's ([`add_criterion_columns`]). In a scene with real units the headers carry
/// them (`h[fs]`, `potential_difference[kcal/mol]`, `kinetic_temperature[K]`).
pub fn sampling_table(
    meta: BTreeMap<String, String>,
    results: &[StepResult],
    (criterion, reference): (&SamplingCriterion, &RunAnalysis),
    units: Units,
) -> StudyTable {
    let mut table = StudyTable::new(
        "scan-steps",
        meta,
        &[
            "index",
            "method",
            "h",
            "status",
            "potential_difference",
            "potential_combined_error",
            "peak_difference",
            "peak_combined_error",
            "potential_per_molecule",
            "potential_error",
            "peak_height",
            "peak_error",
            "kinetic_temperature",
            "kinetic_temperature_error",
            "blowup_time",
            "steps",
            "slow_evaluations",
            "fast_evaluations",
            "decide_at",
        ],
    )
    .with_units(&sampling_units(units));
    for r in results {
        let mut row = vec![
            r.index.to_string(),
            r.method.clone(),
            Num(r.h).to_string(),
            r.verdict.name().to_string(),
        ];
        match &r.sampling {
            Some(c) => row.extend(
                [
                    c.potential_difference,
                    c.potential_combined_error,
                    c.peak_difference,
                    c.peak_combined_error,
                    c.potential,
                    c.potential_error,
                    c.peak,
                    c.peak_error,
                    c.kinetic_temperature,
                    c.kinetic_temperature_error,
                ]
                .map(|x| Num(x).to_string()),
            ),
            None => row.extend(std::iter::repeat_n(String::new(), 10)),
        }
        row.extend([
            r.blowup_time.map_or(String::new(), |t| Num(t).to_string()),
            r.steps.to_string(),
            r.slow_evaluations.to_string(),
            r.fast_evaluations.to_string(),
            r.decide_at.map_or(String::new(), |t| Num(t).to_string()),
        ]);
        table.rows.push(row);
    }
    if !criterion.backbone.is_empty() {
        add_basin_columns(&mut table, results);
    }
    // The columns are the reference's criteria (the reference judged against itself), so
    // every shard of a scan has the same whatever its points did.
    let own = super::criterion::sampling::compare(
        reference,
        reference,
        &criterion.settings(units),
        units,
    );
    add_criterion_columns(&mut table, results, &own.criteria);
    with_config_column(table, results.iter().map(|r| r.config.as_deref()))
}

/// The units of the sampling table's columns (empty in a dimensionless scene; the g(r) peak
/// heights and the basin populations have none).
fn sampling_units(units: Units) -> [(&'static str, &'static str); 9] {
    let (time, energy, temperature) = (
        units.time_name(),
        units.energy_name(),
        units.temperature_name(),
    );
    [
        ("h", time),
        ("potential_difference", energy),
        ("potential_combined_error", energy),
        ("potential_per_molecule", energy),
        ("potential_error", energy),
        ("kinetic_temperature", temperature),
        ("kinetic_temperature_error", temperature),
        ("blowup_time", time),
        ("decide_at", time),
    ]
}

/// The basin columns of the sampling table: `{basin}_difference`, `{basin}_combined_error`
/// and `{basin}_population` for each basin (`/` written `_`); empty for a point without a
/// comparison (unstable).
fn add_basin_columns(table: &mut StudyTable, results: &[StepResult]) {
    for name in crate::analysis::dihedrals::BASINS {
        let key = name.replace('/', "_");
        for part in ["difference", "combined_error", "population"] {
            table.header.push(format!("{key}_{part}"));
        }
    }
    for (row, r) in table.rows.iter_mut().zip(results) {
        let basins = r.sampling.as_ref().map_or(&[][..], |c| &c.basins[..]);
        for name in crate::analysis::dihedrals::BASINS {
            match basins.iter().find(|b| b.basin == name) {
                Some(b) => row.extend(
                    [b.difference, b.combined_error, b.population].map(|x| Num(x).to_string()),
                ),
                None => row.extend(std::iter::repeat_n(String::new(), 3)),
            }
        }
    }
}

/// The columns of the criteria the fixed columns do not carry (the configurational
/// temperature, each force-field term's mean): `{key}_difference`, `{key}_combined_error`
/// (with the criterion's unit) and `{key}_verdict` (`pass`, `fail`, `undecided`, `absent`),
/// for each such criterion of `own` (the reference's); empty cells for a point without it
/// (unstable).
fn add_criterion_columns(table: &mut StudyTable, results: &[StepResult], own: &[Criterion]) {
    use super::criterion::reference::Kind;
    let columns: Vec<(String, String)> = own
        .iter()
        .filter(|c| matches!(c.kind, Kind::ConfigurationalTemperature | Kind::Term))
        .map(|c| (c.key(), c.unit.clone()))
        .collect();
    for (key, unit) in &columns {
        let unit = match unit.is_empty() {
            true => String::new(),
            false => format!("[{unit}]"),
        };
        table.header.push(format!("{key}_difference{unit}"));
        table.header.push(format!("{key}_combined_error{unit}"));
        table.header.push(format!("{key}_verdict"));
    }
    for (row, r) in table.rows.iter_mut().zip(results) {
        let criteria = r.sampling.as_ref().map_or(&[][..], |c| &c.criteria[..]);
        for (key, _) in &columns {
            match criteria.iter().find(|c| c.key() == *key) {
                Some(c) => row.extend([
                    c.difference.map_or(String::new(), |x| Num(x).to_string()),
                    c.error.map_or(String::new(), |x| Num(x).to_string()),
                    c.verdict.to_string(),
                ]),
                None => row.extend(std::iter::repeat_n(String::new(), 3)),
            }
        }
    }
}

/// The settings the study's table records beside the command line's: the study file, the
/// fingerprint of its text and its labels, so shards of different studies never merge.
pub fn study_meta(study: &StudyFile, meta: &mut BTreeMap<String, String>) {
    meta.insert("study".into(), study.path.display().to_string());
    meta.insert("study_fingerprint".into(), study.fingerprint.clone());
    let labels: Vec<&str> = study.configs.iter().map(|c| c.label.as_str()).collect();
    meta.insert("configs".into(), labels.join(";").replace(',', ";"));
}

/// The reference's basin populations with their errors and the residues pooled, or that
/// there is no peptide backbone.
pub fn basins_notice(c: &SamplingCriterion, reference: &RunAnalysis) -> String {
    let note = c.basins_note();
    match crate::analysis::dihedrals::pooled_populations(&reference.basins) {
        Some(p) => {
            let cells: Vec<String> = crate::analysis::dihedrals::BASINS
                .iter()
                .zip(p)
                .map(|(name, e)| format!("{name} {:.3} ± {:.3}", e.mean, e.error))
                .collect();
            format!("{note}: reference {}", cells.join(", "))
        }
        None => note,
    }
}
