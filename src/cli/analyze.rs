//! `longstep analyze SCENE RUN…`: configurational analysis of finished runs.
//!
//! Each RUN is a run directory holding the `energy.csv` and the trajectory of one run of
//! SCENE (or of a peer code written in the same form: `scripts/openmm_mts_langevin.py`), or a
//! trajectory file of any engine (`.xtc`, `.trr`, `.dcd`, `.nc`, longstep's `.xyz`) whose
//! energies are recomputed frame by frame with SCENE's force field
//! ([`crate::analysis::trajectory_input`]); SCENE may be a topology file. With `--reference
//! REF` (a run directory or a trajectory file) every run is judged against REF, criterion by
//! criterion ([`crate::studies::criterion::reference`], printed by `analyze_verdicts`). For every run it
//! prints (or, with `--json`, emits as one JSON array) the mean potential energy per
//! molecule, the kinetic and configurational temperatures, the first peak of g(r) for each
//! `--pairs` entry and the mean bond lengths and angles, each with a block-average error
//! bar, and writes the tables (`rdf.csv`, `blocks.csv`, `blocking.csv`, `geometry.csv`) and
//! `summary.json` into `RUN_DIR/analysis/` (or `--out DIR/<label>/`). With several runs it
//! adds each run's difference to the first in units of their combined error, and `--png`
//! overlays their g(r). docs/analysis.md describes the estimators.

use std::path::{Path, PathBuf};

use clap::Args;

use super::analyze_verdicts::{Reference, VerdictArgs, pool_reference};
use serde_json::{Value as Json, json};

use crate::analysis::block_average::Estimate;
use crate::analysis::dihedrals::{BASINS, backbone_residues, scene_topology};
use crate::analysis::run_analysis::{
    AnalysisOptions, Analyzer, EnergySource, RunAnalysis, RunFiles, parse_pair,
};
use crate::analysis::run_dir::run_files;
use crate::analysis::trajectory_input::TrajectoryInput;
use crate::error::{Error, Result};
use crate::io::scene::Scene;
use crate::plot::{AxisSpec, Band, LineChart, PALETTE, Series};
use crate::settings::Value;
use crate::studies::criterion::reference::CriterionSettings;

#[derive(Args, Debug)]
pub struct AnalyzeArgs {
    /// The scene the runs were made from (atoms, box, force field).
    pub scene: PathBuf,
    /// Runs: directories with energy.csv and a trajectory, or trajectory files of any
    /// engine (.xtc, .trr, .dcd, .nc, .xyz).
    #[arg(required = true, value_name = "RUN")]
    pub runs: Vec<PathBuf>,
    #[command(flatten)]
    pub verdicts: VerdictArgs,
    /// Element pairs for g(r), comma-separated, or "none" (default: O-O in a periodic
    /// box, none without one).
    #[arg(long, value_delimiter = ',')]
    pub pairs: Vec<String>,
    /// Count pairs within one molecule in g(r) (default: only pairs in different molecules).
    #[arg(long)]
    pub intramolecular: bool,
    /// Leave out the start of each run (equilibration), e.g. 5ps; in the scene's time unit
    /// when it has no suffix.
    #[arg(long, default_value = "0")]
    pub skip: String,
    /// Analyse up to this time (default: the end of each run).
    #[arg(long)]
    pub until: Option<String>,
    /// Number of equal time blocks for the error bars.
    #[arg(long, default_value_t = 10)]
    pub blocks: usize,
    /// g(r) bin width, in the scene's length unit.
    #[arg(long, default_value_t = 0.02)]
    pub bin: f64,
    /// g(r) range (default and largest: half the shortest box edge).
    #[arg(long)]
    pub r_max: Option<f64>,
    /// The first peak is the first bin that is the largest within ± this distance.
    #[arg(long, default_value_t = 0.25)]
    pub peak_window: f64,
    /// Half-width of the parabola fitted around the first peak.
    #[arg(long, default_value_t = 0.1)]
    pub peak_fit: f64,
    /// Hutchinson probe vectors per frame for the non-bonded Laplacian.
    #[arg(long, default_value_t = crate::analysis::configurational::DEFAULT_PROBES)]
    pub probes: usize,
    /// Seed of the probe vectors.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Skip the configurational temperature (a gradient and a few Hessian-vector products
    /// per frame: the costliest part).
    #[arg(long)]
    pub no_configurational: bool,
    /// Degrees of freedom for the kinetic temperature (default: as each run counted them,
    /// from its manifest: 3N − constraints − 3 with the centre-of-mass momentum removed;
    /// 3N for a run directory without a manifest).
    #[arg(long)]
    pub dof: Option<f64>,
    /// The energy.csv column holding the kinetic energy.
    #[arg(long, default_value = "kinetic", value_name = "NAME")]
    pub kinetic_column: String,
    /// Use every K-th trajectory frame.
    #[arg(long, default_value_t = 1, value_name = "K")]
    pub stride: usize,
    /// Trajectory file name in each run directory (default: the scene's [output]
    /// trajectory, else trajectory.xyz).
    #[arg(long, value_name = "NAME")]
    pub trajectory: Option<String>,
    /// Labels of the runs, comma-separated (default: the directory names).
    #[arg(long, value_delimiter = ',')]
    pub labels: Vec<String>,
    /// Write each run's tables to DIR/<label>/ instead of RUN_DIR/analysis/.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Draw every run's g(r) overlaid: FILE for one pair, FILE-<pair>.png for several.
    #[arg(long, value_name = "FILE")]
    pub png: Option<PathBuf>,
    /// Print the summaries as a JSON array on stdout.
    #[arg(long)]
    pub json: bool,
    /// No progress bar (there is one only on a terminal).
    #[arg(long)]
    pub quiet: bool,
    /// Set a scene parameter (repeatable).
    #[arg(long = "set", value_name = "NAME=VALUE")]
    pub set: Vec<String>,
    #[command(flatten)]
    pub source: super::common::SceneArgs,
}

fn time_value(text: &str, flag: &str, scene: &Scene) -> Result<f64> {
    let value: Value = text
        .parse()
        .map_err(|_| Error::flag(flag, format!("{flag}: \"{text}\" is not a time")))?;
    let t = value.evaluate_time(&scene.parameters, flag, scene.units.time_units())?;
    if !(t >= 0.0 && t.is_finite()) {
        return Err(
            Error::flag(flag, format!("{flag} must be a time of zero or more"))
                .got(format!("\"{text}\"")),
        );
    }
    Ok(t)
}

fn options(args: &AnalyzeArgs, scene: &Scene) -> Result<AnalysisOptions> {
    let none = args.pairs.len() == 1 && args.pairs[0].trim() == "none";
    let pairs = if none {
        Vec::new()
    } else if args.pairs.is_empty() {
        // g(r) needs a density, which only a periodic box gives.
        match scene.system.periodic_box {
            Some(_) => vec![parse_pair("O-O")?],
            None => Vec::new(),
        }
    } else {
        args.pairs
            .iter()
            .map(|p| parse_pair(p))
            .collect::<Result<_>>()?
    };
    Ok(AnalysisOptions {
        pairs,
        intramolecular: args.intramolecular,
        skip: time_value(&args.skip, "--skip", scene)?,
        until: match &args.until {
            Some(text) => Some(time_value(text, "--until", scene)?),
            None => None,
        },
        blocks: args.blocks,
        bin_width: args.bin,
        r_max: args.r_max,
        peak_window: args.peak_window,
        peak_fit: args.peak_fit,
        probes: args.probes,
        seed: args.seed,
        configurational: !args.no_configurational,
        dof: args.dof,
        kinetic_column: args.kinetic_column.clone(),
        stride: args.stride,
    })
}

fn labels(args: &AnalyzeArgs) -> Result<Vec<String>> {
    if args.labels.is_empty() {
        return Ok(args
            .runs
            .iter()
            .map(|d| {
                d.file_name()
                    .map_or_else(|| d.display().to_string(), |n| n.to_string_lossy().into())
            })
            .collect());
    }
    if args.labels.len() != args.runs.len() {
        return Err(Error::flag(
            "--labels",
            format!(
                "--labels gives {} labels for {} runs",
                args.labels.len(),
                args.runs.len()
            ),
        ));
    }
    if let Some(k) = args.labels.iter().position(|l| l.trim().is_empty()) {
        return Err(Error::flag(
            "--labels",
            format!("--labels: label {} is empty; each run needs a name", k + 1),
        ));
    }
    Ok(args.labels.clone())
}

pub fn analyze_command(args: &AnalyzeArgs) -> Result<()> {
    let scene = args.source.load(&args.scene, &args.set)?;
    let mut analyzer = Analyzer::new(&scene, options(args, &scene)?)?;
    if let Some(topology) = scene_topology(&args.scene)? {
        analyzer.set_backbone(backbone_residues(&topology));
    }
    let labels = labels(args)?;
    let trajectory = args
        .trajectory
        .clone()
        .or_else(|| scene.output.trajectory.clone())
        .unwrap_or_else(|| "trajectory.xyz".into());
    let frame_time = match &args.verdicts.frame_time {
        Some(text) => Some(time_value(text, "--frame-time", &scene)?),
        None => None,
    };
    let input =
        |path: &PathBuf| open_input(args, (&scene, &analyzer), path, (&trajectory, frame_time));
    let runs: Vec<RunInput> = args.runs.iter().map(input).collect::<Result<_>>()?;
    let references: Vec<RunInput> = args
        .verdicts
        .reference
        .iter()
        .map(input)
        .collect::<Result<_>>()?;
    let reference = analyse_reference(args, &references, &analyzer)?;
    let settings = args
        .verdicts
        .settings(&scene, reference.as_ref().map(|r| &r.pooled))?;
    let context = Context {
        args,
        scene: &scene,
        analyzer: &analyzer,
        settings: &settings,
    };
    let mut results = Vec::new();
    let mut summaries = Vec::new();
    for ((path, label), run) in args.runs.iter().zip(&labels).zip(&runs) {
        // The share of the run's span analysed, in percent.
        let what = format!("analyze {label}");
        let bar = super::common::counted_bar(100, args.quiet, &what, "% of its time span");
        let result = run.analyze_with(&analyzer, &mut |share| {
            bar.set_position((share * 100.0) as u64)
        });
        bar.finish_and_clear();
        let result = result?;
        summaries.push(context.report(label, path, &result, reference.as_ref())?);
        results.push(result);
    }
    if let Some(reference) = reference.as_ref().filter(|r| r.runs.len() >= 2) {
        summaries.extend(context.controls(reference)?);
    }
    if results.len() > 1 && !args.json {
        print_differences(&labels, &results);
    }
    if let Some(png) = &args.png {
        draw_rdf(png, &scene, &labels, &results)?;
    }
    if args.json {
        let text = serde_json::to_string_pretty(&Json::Array(summaries))
            .map_err(|e| Error::input(format!("cannot write JSON: {e}")))?;
        println!("{text}");
    }
    Ok(())
}

/// The reference runs analysed and pooled into one (`None` without `--reference`), and the
/// notice a pooled one gives.
fn analyse_reference(
    args: &AnalyzeArgs,
    references: &[RunInput],
    analyzer: &Analyzer,
) -> Result<Option<Reference>> {
    if references.is_empty() {
        return Ok(None);
    }
    let analysed = references
        .iter()
        .map(|r| r.analyze(analyzer))
        .collect::<Result<_>>()?;
    let reference = pool_reference(&args.verdicts.reference, analysed)?;
    if let Some(notice) = reference.notice() {
        eprintln!("notice: {notice}");
    }
    Ok(Some(reference))
}

/// What every run's report needs: the flags, the scene, its analyzer, the criteria's bounds.
struct Context<'a> {
    args: &'a AnalyzeArgs,
    scene: &'a Scene,
    analyzer: &'a Analyzer<'a>,
    settings: &'a CriterionSettings,
}

impl Context<'_> {
    /// A run's summary (JSON) with its verdicts against `reference`, its tables written,
    /// and, without `--json`, printed.
    fn report(
        &self,
        label: &str,
        path: &Path,
        result: &RunAnalysis,
        reference: Option<&Reference>,
    ) -> Result<Json> {
        let args = self.args;
        let out_dir = match &args.out {
            Some(out) => out.join(label),
            None if path.is_dir() => path.join("analysis"),
            None => path.with_extension("analysis"),
        };
        let mut summary = summary_json(self.scene, label, path, result, self.analyzer);
        let (_, energy, temperature, time) = units(self.scene);
        let verdicts = reference.map(|r| {
            super::analyze_verdicts::judge((energy, temperature), &r.pooled, result, self.settings)
        });
        if let (Some(v), Some(r), Json::Object(map)) = (&verdicts, reference, &mut summary) {
            map.insert("reference".into(), r.json_paths());
            if let Some(pool) = r.pool_json() {
                map.insert("reference_pool".into(), pool);
            }
            map.insert("criteria".into(), v.json());
            map.insert("verdict".into(), json!(v.overall_name()));
        }
        super::analyze_output::write_tables(&out_dir, result, &summary)?;
        if !args.json {
            print_summary(self.scene, label, &out_dir, result);
            if let (Some(v), Some(r)) = (&verdicts, reference) {
                print_pool(r);
                v.print(time, result);
            }
        }
        Ok(summary)
    }

    /// Leave-one-out controls: each reference run judged against the others pooled, as a
    /// run is (its summary's `role` is `control`, its tables under `control-<label>`).
    fn controls(&self, reference: &Reference) -> Result<Vec<Json>> {
        let labels = reference.labels();
        let mut summaries = Vec::new();
        for (k, (run, path)) in reference.runs.iter().zip(&reference.paths).enumerate() {
            let others = reference.others(k)?;
            let label = format!("control-{}", labels[k]);
            if !self.args.json {
                println!(
                    "control: reference run {} against the others pooled",
                    labels[k]
                );
            }
            let mut summary =
                self.report(&label, &control_dir(path, &label), run, Some(&others))?;
            if let Json::Object(map) = &mut summary {
                map.insert("role".into(), json!("control"));
            }
            summaries.push(summary);
        }
        Ok(summaries)
    }
}

/// Where a control's tables go without `--out`: beside the reference run, never over its
/// own analysis.
fn control_dir(path: &Path, label: &str) -> PathBuf {
    path.parent()
        .map_or_else(|| PathBuf::from(label), |p| p.join(label))
}

/// A pooled reference's runs and each quantity's error parts (nothing for one run).
fn print_pool(reference: &Reference) {
    let Some(pooling) = &reference.pooled.pooled else {
        return;
    };
    let weights = crate::analysis::pooled::weights(&pooling.lengths);
    let runs: Vec<String> = reference
        .labels()
        .iter()
        .zip(weights)
        .map(|(l, w)| format!("{l} (weight {w:.3})"))
        .collect();
    println!("  reference pooled from {}:", runs.join(", "));
    for (name, p) in &pooling.parts {
        let between = p.between.map_or("-".into(), |b| format!("{b:.4}"));
        println!(
            "    {name:<44} {:+11.4} ± {:9.4} (within runs {:.4}, between {between})",
            p.mean, p.error, p.within
        );
    }
}

/// The run at `path`: a run directory (its degrees of freedom from its manifest unless
/// `--dof` gives them) or a trajectory file, whose clock is checked before anything is read.
fn open_input(
    args: &AnalyzeArgs,
    (scene, analyzer): (&Scene, &Analyzer),
    path: &Path,
    (trajectory, frame_time): (&str, Option<f64>),
) -> Result<RunInput> {
    let mut input = RunInput::of(path, trajectory, scene, frame_time)?;
    match &mut input {
        RunInput::Directory(files) if args.dof.is_none() => {
            files.dof = super::run_dof::run_dof(path, &args.scene, &args.source, &args.set)?
        }
        RunInput::File(file) => analyzer.check_clock(file)?,
        RunInput::Directory(_) => {}
    }
    Ok(input)
}

/// A run to analyse: a run directory's files, or a trajectory file alone.
enum RunInput {
    Directory(RunFiles),
    File(TrajectoryInput),
}

impl RunInput {
    fn of(path: &Path, trajectory: &str, scene: &Scene, frame_time: Option<f64>) -> Result<Self> {
        if path.is_file() {
            return Ok(RunInput::File(TrajectoryInput::new(
                path, scene, frame_time,
            )?));
        }
        Ok(RunInput::Directory(run_files(path, trajectory)?))
    }

    fn analyze(&self, analyzer: &Analyzer) -> Result<RunAnalysis> {
        self.analyze_with(analyzer, &mut |_| {})
    }

    /// [`RunInput::analyze`] with `progress` the share of the span done.
    fn analyze_with(
        &self,
        analyzer: &Analyzer,
        progress: &mut dyn FnMut(f64),
    ) -> Result<RunAnalysis> {
        match self {
            RunInput::Directory(files) => analyzer.analyze_with(files, progress),
            RunInput::File(input) => analyzer.analyze_trajectory_with(input, progress),
        }
    }
}

fn estimate_json(e: &Estimate) -> Json {
    json!({ "mean": e.mean, "error": e.error })
}

/// Unit names (length, energy, temperature, time) of the scene.
fn units(scene: &Scene) -> (&'static str, &'static str, &'static str, &'static str) {
    match scene.units {
        crate::units::Units::Real => ("angstrom", "kcal/mol", "K", "fs"),
        crate::units::Units::None => ("scene", "scene", "kT (k_B = 1)", "scene"),
    }
}

fn summary_json(
    scene: &Scene,
    label: &str,
    dir: &Path,
    r: &RunAnalysis,
    analyzer: &Analyzer,
) -> Json {
    let (length, energy, temperature, time) = units(scene);
    let rdf: serde_json::Map<String, Json> = r
        .rdf
        .iter()
        .map(|rdf| {
            let peak = rdf.peak.map(|p| {
                json!({
                    "position": rdf.peak_position.as_ref().map(estimate_json),
                    "height": rdf.peak_height.as_ref().map(estimate_json),
                    "highest_bin": { "r": (p.bin as f64 + 0.5) * analyzer.options().bin_width, "g": p.bin_height },
                    "fitted": p.fitted,
                })
            });
            (rdf.name.clone(), json!({ "first_peak": peak }))
        })
        .collect();
    let geometry: Vec<Json> = r
        .geometry
        .iter()
        .map(|g| {
            json!({
                "kind": g.kind, "type": g.name, "count": g.count,
                "mean": g.mean.mean, "error": g.mean.error,
                "unit": if g.kind == "bond" { length } else { "degree" },
            })
        })
        .collect();
    let configurational = r.configurational.as_ref().map(|c| json!({
        "mean": c.temperature.mean, "error": c.temperature.error,
        "gradient_squared": c.gradient_squared, "laplacian": c.laplacian,
        "exact_terms": c.exact_terms, "estimated_terms": c.estimated_terms,
        "probes": c.probes, "colours": c.colours,
        "hessian_vector_products_per_frame": { "exact": c.products_per_frame.0, "hutchinson": c.products_per_frame.1 },
        "hutchinson_relative_error_per_frame": c.hutchinson_relative_error,
    }));
    let options = analyzer.options();
    json!({
        "label": label,
        "run": dir.display().to_string(),
        "scene": scene.path.display().to_string(),
        "units": { "length": length, "energy": energy, "temperature": temperature, "time": time },
        "span": { "start": r.blocks.start, "end": r.blocks.end, "skip": options.skip },
        "blocks": { "count": r.blocks.count, "length": r.blocks.length() },
        "energy_rows": r.rows,
        "frames": r.frames,
        "molecules": r.molecules,
        "potential_energy_per_molecule": {
            "mean": r.potential_per_molecule.mean, "error": r.potential_per_molecule.error,
            "blocks_long_enough": r.blocks_long_enough,
        },
        "kinetic_temperature": {
            "mean": r.kinetic_temperature.mean, "error": r.kinetic_temperature.error,
            "dof": r.dof, "column": options.kinetic_column,
        },
        "configurational_temperature": configurational,
        "rdf": rdf,
        "rdf_intramolecular_pairs": options.intramolecular,
        "geometry": geometry,
        "basins": basins_json(r),
        "terms": terms_json(r),
        "energies_from": match r.source {
            EnergySource::Table => "energy.csv",
            EnergySource::Frames { times: true } => "frames (recomputed)",
            EnergySource::Frames { times: false } => "frames (recomputed; times are frame numbers)",
        },
    })
}

/// Each force-field term's mean energy, its error and its variance over frames.
fn terms_json(r: &RunAnalysis) -> Json {
    r.terms
        .iter()
        .map(|t| {
            json!({ "term": t.name, "mean": t.mean.mean, "error": t.mean.error,
                    "basin_error": t.basin_error, "variance": t.variance })
        })
        .collect()
}

/// Per backbone residue: each basin's population and error.
fn basins_json(r: &RunAnalysis) -> Json {
    r.basins
        .iter()
        .map(|b| {
            let populations: serde_json::Map<String, Json> = BASINS
                .iter()
                .zip(&b.populations)
                .map(|(name, p)| (name.to_string(), estimate_json(p)))
                .collect();
            json!({ "residue": b.label, "frames": b.frames, "changes_of_basin": b.transitions,
                    "populations": populations })
        })
        .collect()
}

/// Per backbone residue: each basin's population with its error, and the changes of core.
fn print_basins(r: &RunAnalysis) {
    for b in &r.basins {
        let populations: Vec<String> = BASINS
            .iter()
            .zip(&b.populations)
            .map(|(name, p)| format!("{name} {}", pm(p, 3)))
            .collect();
        println!(
            "  basins {:<8} {} ({} changes of basin core)",
            b.label,
            populations.join(", "),
            b.transitions
        );
    }
}

fn pm(e: &Estimate, digits: usize) -> String {
    format!("{:.digits$} ± {:.digits$}", e.mean, e.error)
}

fn print_summary(scene: &Scene, label: &str, out_dir: &Path, r: &RunAnalysis) {
    let (length, energy, temperature, time) = units(scene);
    let time = crate::studies::criterion::reference::time_unit(r, time);
    println!(
        "run {label}: t = {} to {} {time}, {} blocks of {} {time}, {} energy rows, {} frames",
        r.blocks.start,
        r.blocks.end,
        r.blocks.count,
        r.blocks.length(),
        r.rows,
        r.frames
    );
    let check = if r.blocks_long_enough {
        "blocks long enough"
    } else {
        "WARNING: blocks too short (see blocking.csv)"
    };
    println!(
        "  PE per molecule     {} {energy} ({} molecules; {check})",
        pm(&r.potential_per_molecule, 4),
        r.molecules
    );
    if r.source == EnergySource::Table {
        println!(
            "  T kinetic           {} {temperature} (n_dof = {})",
            pm(&r.kinetic_temperature, 2),
            r.dof
        );
    } else {
        println!("  T kinetic           absent (a trajectory file has no velocities)");
    }
    for t in &r.terms {
        println!("  E {:<26} {} {energy}", t.name, pm(&t.mean, 3));
    }
    if let Some(c) = &r.configurational {
        println!(
            "  T configurational   {} {temperature} (Hutchinson {} probes on {})",
            pm(&c.temperature, 2),
            c.probes,
            if c.estimated_terms.is_empty() {
                "no term".into()
            } else {
                c.estimated_terms.join(", ")
            }
        );
    }
    for rdf in &r.rdf {
        match (&rdf.peak_position, &rdf.peak_height) {
            (Some(position), Some(height)) => println!(
                "  g {:<6} 1st peak  r = {} {length}, g = {}",
                rdf.name,
                pm(position, 4),
                pm(height, 4)
            ),
            _ => println!("  g {:<6} 1st peak  not found", rdf.name),
        }
    }
    print_basins(r);
    for g in &r.geometry {
        let unit = if g.kind == "bond" { length } else { "degree" };
        println!(
            "  {:<5} {:<12} {} {unit} (×{})",
            g.kind,
            g.name,
            pm(&g.mean, 5),
            g.count
        );
    }
    println!("  tables in {}", out_dir.display());
}

/// `(value − first)/√(σ² + σ_first²)`.
fn sigmas(a: &Estimate, b: &Estimate) -> (f64, f64) {
    let difference = a.mean - b.mean;
    (
        difference,
        difference / (a.error * a.error + b.error * b.error).sqrt(),
    )
}

fn print_differences(labels: &[String], results: &[RunAnalysis]) {
    let first = &results[0];
    println!(
        "differences to {} (in combined standard errors):",
        labels[0]
    );
    for (label, r) in labels.iter().zip(results).skip(1) {
        let mut items = vec![
            (
                "PE per molecule".to_string(),
                sigmas(&r.potential_per_molecule, &first.potential_per_molecule),
            ),
            (
                "T kinetic".to_string(),
                sigmas(&r.kinetic_temperature, &first.kinetic_temperature),
            ),
        ];
        if let (Some(a), Some(b)) = (&r.configurational, &first.configurational) {
            items.push((
                "T configurational".into(),
                sigmas(&a.temperature, &b.temperature),
            ));
        }
        for (rdf, rdf0) in r.rdf.iter().zip(&first.rdf) {
            if let (Some(h), Some(h0), Some(p), Some(p0)) = (
                &rdf.peak_height,
                &rdf0.peak_height,
                &rdf.peak_position,
                &rdf0.peak_position,
            ) {
                items.push((format!("g {} peak height", rdf.name), sigmas(h, h0)));
                items.push((format!("g {} peak position", rdf.name), sigmas(p, p0)));
            }
        }
        println!("  {label}");
        for (name, (difference, sigma)) in items {
            println!("    {name:<24} {difference:+.5} ({sigma:+.2} σ)");
        }
    }
}

/// The file of one pair's chart: `FILE` for a single pair, `FILE-<pair>.ext` for several.
fn chart_path(png: &Path, pair: &str, pairs: usize) -> PathBuf {
    if pairs == 1 {
        return png.to_path_buf();
    }
    let stem = png
        .file_stem()
        .map_or("gr".into(), |s| s.to_string_lossy().into_owned());
    let extension = png
        .extension()
        .map_or("png".into(), |e| e.to_string_lossy().into_owned());
    png.with_file_name(format!("{stem}-{pair}.{extension}"))
}

fn draw_rdf(png: &Path, scene: &Scene, labels: &[String], results: &[RunAnalysis]) -> Result<()> {
    let pairs = results.first().map_or(0, |r| r.rdf.len());
    if pairs == 0 {
        return Err(Error::flag("--png", "--png draws g(r): give --pairs"));
    }
    let (length, ..) = units(scene);
    let length = if length == "angstrom" { "Å" } else { length };
    for k in 0..pairs {
        let name = &results[0].rdf[k].name;
        let mut chart = LineChart::new(
            &format!("g(r) {name}"),
            AxisSpec::linear(&format!("r ({length})")),
            AxisSpec::linear("g(r)"),
        );
        for (index, (label, r)) in labels.iter().zip(results).enumerate() {
            let rdf = &r.rdf[k];
            let colour = PALETTE[index % PALETTE.len()];
            let points = rdf.r.iter().copied().zip(rdf.g.iter().copied()).collect();
            let mut series = Series::line(label, points);
            series.colour = Some(colour);
            chart.series.push(series);
            // rdf.csv's error column: the standard error of the blocks' g(r), per bin.
            let band: Vec<(f64, f64, f64)> = rdf
                .r
                .iter()
                .zip(&rdf.g)
                .zip(&rdf.g_error)
                .filter(|(_, e)| e.is_finite())
                .map(|((&r, &g), &e)| (r, g - e, g + e))
                .collect();
            if !band.is_empty() {
                chart.bands.push(Band {
                    name: format!("{label} ± 1 standard error (blocks)"),
                    points: band,
                    colour,
                });
            }
        }
        let path = chart_path(png, name, pairs);
        chart.save(&path)?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}
