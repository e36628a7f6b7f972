//! The tables `longstep analyze` writes for each run (through the csv crate): `rdf.csv`,
//! `blocks.csv`, `blocking.csv`, `geometry.csv`, with a backbone `basins.csv` and
//! `ramachandran.csv`, and `summary.json`. Headers carry units
//! in brackets (`r [angstrom]`).

use std::path::Path;

use serde_json::Value as Json;

use crate::analysis::dihedrals::{BASINS, HISTOGRAM_BINS};
use crate::analysis::run_analysis::RunAnalysis;
use crate::error::{Error, Result};
use crate::io::csv::write_table;

fn write_csv(path: &Path, header: &[String], rows: &[Vec<String>]) -> Result<()> {
    write_table(path, None, header, rows)
}

fn unit(summary: &Json, key: &str) -> String {
    summary["units"][key]
        .as_str()
        .unwrap_or("scene")
        .to_string()
}

/// Write every table of `result` and `summary` into `dir` (created if needed).
pub fn write_tables(dir: &Path, result: &RunAnalysis, summary: &Json) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let (length, energy, temperature, time) = (
        unit(summary, "length"),
        unit(summary, "energy"),
        unit(summary, "temperature"),
        unit(summary, "time"),
    );
    if !result.rdf.is_empty() {
        write_rdf(&dir.join("rdf.csv"), result, &length)?;
    }
    write_blocks(
        &dir.join("blocks.csv"),
        result,
        &energy,
        &temperature,
        &time,
    )?;
    let blocking: Vec<Vec<String>> = result
        .blocking
        .iter()
        .map(|level| {
            vec![
                level.block_size.to_string(),
                (level.block_size as f64 * result.row_interval).to_string(),
                level.blocks.to_string(),
                level.error.to_string(),
                level.error_of_error.to_string(),
            ]
        })
        .collect();
    write_csv(
        &dir.join("blocking.csv"),
        &[
            "block_rows".into(),
            format!("block_time [{time}]"),
            "blocks".into(),
            format!("pe_per_molecule_error [{energy}]"),
            format!("error_of_error [{energy}]"),
        ],
        &blocking,
    )?;
    let geometry: Vec<Vec<String>> = result
        .geometry
        .iter()
        .map(|g| {
            let unit = if g.kind == "bond" {
                length.as_str()
            } else {
                "degree"
            };
            vec![
                g.kind.into(),
                g.name.clone(),
                g.count.to_string(),
                g.mean.mean.to_string(),
                g.mean.error.to_string(),
                unit.into(),
            ]
        })
        .collect();
    let header = ["kind", "type", "count", "mean", "error", "unit"].map(String::from);
    write_csv(&dir.join("geometry.csv"), &header, &geometry)?;
    if !result.basins.is_empty() {
        write_basins(dir, result)?;
    }
    let path = dir.join("summary.json");
    let text = serde_json::to_string_pretty(summary)
        .map_err(|e| Error::input(format!("cannot write JSON: {e}")))?;
    std::fs::write(&path, text + "\n").map_err(|e| Error::io(&path, e))
}

/// `basins.csv`: each backbone residue's basin populations with their errors;
/// `ramachandran.csv`: its (φ, ψ) histogram, one row per non-empty 10° × 10° bin.
fn write_basins(dir: &Path, result: &RunAnalysis) -> Result<()> {
    let mut populations = Vec::new();
    let mut bins = Vec::new();
    let width = 360.0 / HISTOGRAM_BINS as f64;
    for residue in &result.basins {
        for (name, p) in BASINS.iter().zip(&residue.populations) {
            populations.push(vec![
                residue.label.clone(),
                name.to_string(),
                p.mean.to_string(),
                p.error.to_string(),
                residue.frames.to_string(),
            ]);
        }
        for (k, &fraction) in residue.histogram.iter().enumerate() {
            if fraction > 0.0 {
                let (i, j) = (k / HISTOGRAM_BINS, k % HISTOGRAM_BINS);
                bins.push(vec![
                    residue.label.clone(),
                    (-180.0 + i as f64 * width).to_string(),
                    (-180.0 + j as f64 * width).to_string(),
                    fraction.to_string(),
                ]);
            }
        }
    }
    let header = ["residue", "basin", "population", "error", "frames"].map(String::from);
    write_csv(&dir.join("basins.csv"), &header, &populations)?;
    let header = [
        "residue",
        "phi_from [degree]",
        "psi_from [degree]",
        "fraction",
    ]
    .map(String::from);
    write_csv(&dir.join("ramachandran.csv"), &header, &bins)
}

fn write_rdf(path: &Path, result: &RunAnalysis, length: &str) -> Result<()> {
    let mut header = vec![format!("r [{length}]")];
    for rdf in &result.rdf {
        header.push(format!("g_{}", rdf.name));
        header.push(format!("g_{}_error", rdf.name));
    }
    let bins = result.rdf[0].r.len();
    let rows: Vec<Vec<String>> = (0..bins)
        .map(|k| {
            let mut row = vec![result.rdf[0].r[k].to_string()];
            for rdf in &result.rdf {
                row.push(rdf.g[k].to_string());
                row.push(rdf.g_error[k].to_string());
            }
            row
        })
        .collect();
    write_csv(path, &header, &rows)
}

fn write_blocks(
    path: &Path,
    result: &RunAnalysis,
    energy: &str,
    temperature: &str,
    time: &str,
) -> Result<()> {
    let mut header = vec![
        "block".to_string(),
        format!("t_start [{time}]"),
        format!("t_end [{time}]"),
        "energy_rows".into(),
        "frames".into(),
        format!("pe_per_molecule [{energy}]"),
        format!("kinetic_temperature [{temperature}]"),
    ];
    if result.configurational.is_some() {
        header.push(format!("configurational_temperature [{temperature}]"));
    }
    let blocks = result.blocks;
    let rows: Vec<Vec<String>> = (0..blocks.count)
        .map(|b| {
            let mut row = vec![
                b.to_string(),
                (blocks.start + b as f64 * blocks.length()).to_string(),
                (blocks.start + (b + 1) as f64 * blocks.length()).to_string(),
                result.rows_per_block[b].to_string(),
                result.frames_per_block[b].to_string(),
                result.potential_block_means[b].to_string(),
                result.kinetic_block_means[b].to_string(),
            ];
            if let Some(c) = &result.configurational {
                row.push(c.block_values[b].to_string());
            }
            row
        })
        .collect();
    write_csv(path, &header, &rows)
}
