//! `longstep forces SCENE`: a single-point evaluation to check a force field before a run.
//!
//! Prints the potential energy per group (bonds, angles, torsions, Lennard-Jones, Coulomb,
//! other), per level (fast, slow) and in total, in the scene's units; `--out FILE` writes the
//! per-atom forces `index,element,fx,fy,fz` (force = −gradient; in a real scene each force
//! column carries its unit, `fx[kcal/mol/angstrom]`; `--by-level` adds the force of each
//! level); `--json` prints `{"energy": {…}, "units": {…}}` instead of the table.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use clap::Args;
use serde_json::json;

use super::common::SceneArgs;
use crate::error::{Error, Result};
use crate::io::csv::write_table;
use crate::io::scene::Scene;
use crate::system::System;

#[derive(Args, Debug)]
pub struct ForcesArgs {
    /// Scene file (TOML), or a topology in its place (AMBER .prmtop/.parm7, GROMACS .top)
    /// with its coordinates (.inpcrd/.rst7, .gro) beside it, same name, or given by
    /// --coordinates.
    pub scene: PathBuf,
    /// Write the per-atom forces (index,element,fx,fy,fz) to this CSV file.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Print {"energy": {...}, "units": {...}} as JSON instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Add the force of each level to the CSV (fx_fast, ..., fx_slow, ...).
    #[arg(long)]
    pub by_level: bool,
    /// Evaluate at the positions of this structure file (same atoms) instead of the scene's.
    #[arg(long, value_name = "FILE")]
    pub positions: Option<PathBuf>,
    /// Write every force-field parameter of every interaction to this JSON file.
    #[arg(long, value_name = "FILE")]
    pub parameters: Option<PathBuf>,
    /// Set a scene parameter (repeatable).
    #[arg(long = "set", value_name = "NAME=VALUE")]
    pub set: Vec<String>,
    /// Print no force-field report or level table on stderr.
    #[arg(long)]
    pub quiet: bool,
    #[command(flatten)]
    pub source: SceneArgs,
}

/// The report group of an energy component named by its kind.
fn group_of(component: &str) -> &'static str {
    match component {
        "bond" | "spring" | "chain" => "bonds",
        "angle" => "angles",
        "torsion" => "torsions",
        "lennard-jones" | "lennard-jones-14" => "lennard_jones",
        "coulomb" | "coulomb-14" | "pme-reciprocal" | "ewald-exclusions" | "ewald-self"
        | "ewald-background" => "coulomb",
        _ => "other",
    }
}

const GROUPS: [&str; 6] = [
    "bonds",
    "angles",
    "torsions",
    "lennard_jones",
    "coulomb",
    "other",
];

pub fn forces_command(args: &ForcesArgs) -> Result<()> {
    let mut scene = args.source.load(&args.scene, &args.set)?;
    if !args.quiet {
        report_forcefield(&scene);
    }
    if let Some(path) = &args.parameters {
        write_parameters(&scene, path)?;
    }
    if let Some(path) = &args.positions {
        crate::run::prepare::start_positions(&mut scene, path, "--positions")?;
    }
    if let Some(path) = &args.out {
        super::common::check_out_file(path, "forces")?;
    }
    let q = scene.system.state.q.clone();
    let evaluation = Evaluation::at(&mut scene.system, &q);
    if let Some(path) = &args.out {
        write_forces_csv(path, &scene, &evaluation, args.by_level)?;
    }
    if args.json {
        print_json(&scene, evaluation, args)
    } else {
        print_table(&scene, &evaluation, args);
        Ok(())
    }
}

/// The force-field report and level table on stderr.
fn report_forcefield(scene: &Scene) {
    for line in &scene.forcefield_report {
        eprintln!("{line}");
    }
    eprintln!("{}", scene.system.forces.level_table());
}

/// `--parameters FILE`: the scene's force-field parameters as JSON.
fn write_parameters(scene: &Scene, path: &Path) -> Result<()> {
    let Some(parameters) = &scene.forcefield_parameters else {
        return Err(Error::flag(
            "--parameters",
            "--parameters needs a scene with a [forcefield] section",
        ));
    };
    let text = serde_json::to_string(parameters)
        .map_err(|e| Error::input(format!("cannot write JSON: {e}")))?;
    std::fs::write(path, text).map_err(|e| Error::io(path, e))
}

/// Energies per group, term and level, and the gradient of each level, at one point.
struct Evaluation {
    groups: BTreeMap<&'static str, f64>,
    terms: serde_json::Map<String, serde_json::Value>,
    level_energies: Vec<f64>,
    total: f64,
    level_gradients: Vec<Vec<f64>>,
}

impl Evaluation {
    fn at(system: &mut System, q: &[f64]) -> Self {
        let n_levels = system.forces.n_levels();
        let mut groups: BTreeMap<&'static str, f64> = GROUPS.iter().map(|&g| (g, 0.0)).collect();
        let mut terms = serde_json::Map::new();
        for labelled in system.forces.terms() {
            for (component, energy) in labelled.term.energy_components(q) {
                *groups.entry(group_of(component)).or_insert(0.0) += energy;
                let key = if labelled.term.energy_components(q).len() > 1 {
                    format!("{}/{component}", labelled.name)
                } else {
                    labelled.name.clone()
                };
                terms.insert(key, json!(energy));
            }
        }
        let level_energies: Vec<f64> = (0..n_levels)
            .map(|level| system.forces.energy(level, q))
            .collect();
        let total: f64 = level_energies.iter().sum();

        // Per-level gradients (forces are their negatives).
        let mut level_gradients = vec![vec![0.0; q.len()]; n_levels];
        for (level, gradient) in level_gradients.iter_mut().enumerate() {
            system.forces.gradient(level, q, gradient);
        }
        Evaluation {
            groups,
            terms,
            level_energies,
            total,
            level_gradients,
        }
    }
}

/// The label of one of the scene's units (`energy`, `force`, …), or "scene".
fn unit(scene: &Scene, name: &str) -> &'static str {
    scene
        .units
        .labels()
        .iter()
        .find(|(k, _)| *k == name)
        .map(|(_, v)| *v)
        .unwrap_or("scene")
}

/// `--out FILE`: the per-atom forces `index,element,fx,fy,fz` (and per level with
/// `--by-level`).
fn write_forces_csv(
    path: &Path,
    scene: &Scene,
    evaluation: &Evaluation,
    by_level: bool,
) -> Result<()> {
    let system = &scene.system;
    let level_gradients = &evaluation.level_gradients;
    let dim = system.dim;
    let rows = (0..system.n_particles()).map(|i| {
        let mut row = vec![i.to_string(), scene.elements[i].clone()];
        for a in 0..dim {
            let f: f64 = -level_gradients.iter().map(|g| g[i * dim + a]).sum::<f64>();
            row.push(f.to_string());
        }
        if by_level {
            for gradient in level_gradients {
                row.extend((0..dim).map(|a| (-gradient[i * dim + a]).to_string()));
            }
        }
        row
    });
    write_table(path, None, forces_header(scene, by_level), rows)
}

/// The column names of the forces CSV.
fn forces_header(scene: &Scene, by_level: bool) -> Vec<String> {
    let system = &scene.system;
    let dim = system.dim;
    let axes = ["x", "y", "z"];
    // In a real scene each force column carries its unit (`fx[kcal/mol/angstrom]`), as
    // in energy.csv.
    let force_unit = match scene.units {
        crate::units::Units::None => String::new(),
        _ => format!("[{}]", unit(scene, "force")),
    };
    let mut header: Vec<String> = vec!["index".into(), "element".into()];
    header.extend(axes[..dim].iter().map(|a| format!("f{a}{force_unit}")));
    if by_level {
        for level in 0..system.forces.n_levels() {
            let name = system.forces.level_name(level).replace(' ', "_");
            header.extend(
                axes[..dim]
                    .iter()
                    .map(|a| format!("f{a}_{name}{force_unit}")),
            );
        }
    }
    header
}

/// `--json`: `{"energy": {…}, "units": {…}}` on stdout.
fn print_json(scene: &Scene, evaluation: Evaluation, args: &ForcesArgs) -> Result<()> {
    let Evaluation {
        groups,
        terms,
        level_energies,
        total,
        ..
    } = evaluation;
    let mut energy = serde_json::Map::new();
    for (group, value) in &groups {
        energy.insert(group.to_string(), json!(value));
    }
    energy.insert("fast".into(), json!(level_energies.first().copied()));
    energy.insert("slow".into(), json!(level_energies.last().copied()));
    energy.insert("levels".into(), json!(level_energies));
    energy.insert("total".into(), json!(total));
    energy.insert("terms".into(), serde_json::Value::Object(terms));
    let units: serde_json::Map<String, serde_json::Value> = scene
        .units
        .labels()
        .iter()
        .map(|(k, v)| (k.to_string(), json!(v)))
        .collect();
    let mut report = json!({ "energy": energy, "units": units });
    if let Some(path) = &args.out {
        report["forces_csv"] = json!(path.display().to_string());
    }
    let text = serde_json::to_string_pretty(&report)
        .map_err(|e| Error::input(format!("cannot write JSON: {e}")))?;
    println!("{text}");
    Ok(())
}

/// The energy table on stdout.
fn print_table(scene: &Scene, evaluation: &Evaluation, args: &ForcesArgs) {
    println!("scene      {}", scene.name);
    println!("energy ({})", unit(scene, "energy"));
    for group in GROUPS {
        println!("  {group:<15} {:.10}", evaluation.groups[group]);
    }
    for (level, energy) in evaluation.level_energies.iter().enumerate() {
        let name = format!("{} (level {level})", scene.system.forces.level_name(level));
        println!("  {name:<15} {energy:.10}");
    }
    println!("  {:<15} {:.10}", "total", evaluation.total);
    if let Some(path) = &args.out {
        println!(
            "forces     {} ({}; columns index,element,fx,fy,fz)",
            path.display(),
            unit(scene, "force")
        );
    }
}
