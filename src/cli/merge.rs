//! `longstep merge`: the tables of `--shard` runs combined into what a single run writes,
//! and their pictures drawn again.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use clap::Args;

use super::common::{SCAN_STEPS, SCAN_STIFFNESS, WALL_TIME, WORK_PRECISION};
use super::draw::{draw_scan, draw_work_precision};
use super::scan_report::print_safe_steps;
use crate::analysis::stability::map::Shard;
use crate::error::{Error, Result};
use crate::io::csv::write_table;
use crate::io::study_csv::{Located, StudyTable, differing_setting, merge_located};
use crate::io::summary::REAL_DRIFT_UNIT;
use crate::studies::Criterion;
use crate::studies::criterion::Verdict;
use crate::studies::scan::{SafeStep, ScanPoint, safe_steps_of};
use crate::units::Units;

#[derive(Args, Debug)]
pub struct MergeArgs {
    /// Output directories (or CSV files) of the shards.
    #[arg(required = true)]
    pub inputs: Vec<PathBuf>,
    /// Where to write the merged tables and pictures.
    #[arg(long, value_name = "DIR", default_value = "out/merged")]
    pub out: PathBuf,
}

const MAP_HEADER: &str = "gamma1,gamma2,spectral_radius,type";

/// Stability-map shards are contiguous slices of the grid, which runs Γ1-major: the whole
/// map's rows are the shards' rows in shard order. Each shard's first line names its map's
/// settings and its `k/n`: the shards must agree on every setting and hold every slice
/// 1..n once, each with the rows its slice has.
fn merge_maps(maps: &[(PathBuf, StudyTable)], out: &Path) -> Result<()> {
    let (_, first) = &maps[0];
    let points = first.points()?;
    let mut slices: Vec<Option<&(PathBuf, StudyTable)>> = Vec::new();
    for entry in maps {
        let (path, table) = entry;
        let shard = map_shard(entry, &maps[0], &mut slices)?;
        let expected = shard.range(points).len();
        if table.rows.len() != expected {
            return Err(Error::Structure {
                path: path.clone(),
                message: format!(
                    "shard {}/{} of {points} points holds {} rows, not its {expected}",
                    shard.index,
                    shard.count,
                    table.rows.len()
                ),
            });
        }
        slices[shard.index - 1] = Some(entry);
    }
    if let Some(k) = slices.iter().position(Option::is_none) {
        return Err(Error::input(format!(
            "the map shards do not cover its {points} points: shard {}/{} is missing",
            k + 1,
            slices.len()
        ))
        .key("shard")
        .expected(format!("{}/{}", k + 1, slices.len())));
    }
    let path = out.join("stability-map.csv");
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let rows = slices.iter().flatten().flat_map(|(_, table)| &table.rows);
    write_table(&path, None, &first.header, rows)?;
    eprintln!(
        "merged {} map shards ({points} points) into {}",
        maps.len(),
        path.display()
    );
    Ok(())
}

/// The `k/n` of one map shard, checked against the first shard (the same settings, the
/// same `n`) and against the slices already seen (`slices`, sized at the first).
fn map_shard(
    (path, table): &(PathBuf, StudyTable),
    (first_path, first): &(PathBuf, StudyTable),
    slices: &mut Vec<Option<&(PathBuf, StudyTable)>>,
) -> Result<Shard> {
    if let Some((key, theirs, ours)) = differing_setting(&table.meta, &first.meta) {
        let message = format!(
            "the map shards differ in {key}: {theirs} in {}, {ours} in {}",
            path.display(),
            first_path.display()
        );
        return Err(Error::input(message)
            .file(path)
            .line(1)
            .key(key)
            .expected(ours)
            .got_named(theirs));
    }
    let shard = table
        .meta
        .get("shard")
        .map(|s| Shard::parse(s))
        .transpose()?
        .ok_or_else(|| Error::Structure {
            path: path.clone(),
            message: "a stability-map table without its `shard`".into(),
        })?;
    if slices.is_empty() {
        *slices = vec![None; shard.count];
    }
    if shard.count != slices.len() {
        let message = format!(
            "{} is shard {}/{} but {} is one of {}: give the shards of one --shard split",
            path.display(),
            shard.index,
            shard.count,
            first_path.display(),
            slices.len()
        );
        return Err(Error::input(message)
            .file(path)
            .line(1)
            .key("shard")
            .expected(format!("k/{}", slices.len()))
            .got_named(format!("{}/{}", shard.index, shard.count)));
    }
    if let Some((other, _)) = slices[shard.index - 1] {
        let message = format!(
            "shard {}/{} appears twice: {} and {}",
            shard.index,
            shard.count,
            other.display(),
            path.display()
        );
        return Err(Error::input(message)
            .file(path)
            .line(1)
            .key("shard")
            .got_named(format!("{}/{}", shard.index, shard.count)));
    }
    Ok(shard)
}

/// The shards' tables, by the study each names, and the stability-map shards apart.
type Shards = (BTreeMap<String, Vec<Located>>, Vec<(PathBuf, StudyTable)>);

/// `longstep merge DIR…`: combine shard outputs into what a single run writes.
pub fn merge_command(args: &MergeArgs) -> Result<()> {
    let (by_study, maps) = read_shards(&args.inputs)?;
    if !maps.is_empty() && !by_study.is_empty() {
        return Err(Error::input(format!(
            "the inputs mix stability-map shards ({}) with study tables ({}): merge each \
             study's shards on their own",
            maps[0].0.display(),
            by_study.keys().cloned().collect::<Vec<_>>().join(", ")
        )));
    }
    if !maps.is_empty() {
        return merge_maps(&maps, &args.out);
    }
    // Merge every study before writing anything, so a failed merge leaves no `--out`.
    let mut merged = Vec::new();
    for (study, tables) in by_study {
        let count = tables.len();
        let table = merge_located(tables)?;
        check_study_rows(&table)?;
        merged.push((study, count, table));
    }
    std::fs::create_dir_all(&args.out).map_err(|e| Error::io(&args.out, e))?;
    let mut merged_tables = BTreeMap::new();
    for (study, count, merged) in merged {
        let name = match study.as_str() {
            "work-precision" => WORK_PRECISION,
            "work-precision-wall-time" => WALL_TIME,
            "scan-steps" => SCAN_STEPS,
            "scan-stiffness" => SCAN_STIFFNESS,
            _ => "merged.csv",
        };
        merged.table.write(&args.out.join(name))?;
        eprintln!(
            "merged {count} shards of {study} into {}",
            args.out.join(name).display()
        );
        merged_tables.insert(study, merged);
    }
    draw_merged(&merged_tables, &args.out)
}

/// Every study table of the inputs (directories, or CSV files), grouped by the study it
/// names, so shard files may be called anything.
fn read_shards(inputs: &[PathBuf]) -> Result<Shards> {
    let mut by_study: BTreeMap<String, Vec<Located>> = BTreeMap::new();
    let mut maps: Vec<(PathBuf, StudyTable)> = Vec::new();
    for input in inputs {
        let files: Vec<PathBuf> = if input.is_dir() {
            [WORK_PRECISION, WALL_TIME, SCAN_STEPS, SCAN_STIFFNESS]
                .iter()
                .map(|f| input.join(f))
                .filter(|p| p.exists())
                .collect()
        } else {
            vec![input.clone()]
        };
        if files.is_empty() {
            return Err(Error::input(format!(
                "no study table ({WORK_PRECISION}, {SCAN_STEPS}, {SCAN_STIFFNESS}) in it"
            ))
            .file(input));
        }
        for file in files {
            let text = std::fs::read_to_string(&file).map_err(|e| Error::io(&file, e))?;
            if text.starts_with(MAP_HEADER) {
                return Err(Error::Structure {
                    path: file.clone(),
                    message: "a whole stability map (written without --shard): merge takes \
                              the shards of one map"
                        .into(),
                });
            }
            let located = Located::read(&file)?;
            if located.table.study == "stability-map" {
                maps.push((file.clone(), located.table));
                continue;
            }
            by_study
                .entry(located.table.study.clone())
                .or_default()
                .push(located);
        }
    }
    Ok((by_study, maps))
}

/// A merged `scan steps --study` table: its `config` column and its `configs` setting come
/// together, and every row's configuration is one the study names.
fn check_study_rows(merged: &Located) -> Result<()> {
    let table = &merged.table;
    let (column, configs) = match (table.column("config"), table.meta.get("configs")) {
        (Err(_), None) => return Ok(()),
        (Ok(column), Some(configs)) => (column, configs),
        _ => {
            return Err(Error::setting(
                "configs",
                format!(
                    "the merged {} table has a `config` column without its study's `configs` \
                 setting, or the reverse: shards of a study are written by `scan steps --study`",
                    table.study
                ),
            )
            .expected("a `config` column and a `configs` setting together"));
        }
    };
    let labels: Vec<&str> = configs.split(';').collect();
    match table
        .rows
        .iter()
        .zip(&merged.sources)
        .find(|(row, _)| !labels.contains(&row[column].as_str()))
    {
        Some((row, source)) => Err(source
            .error(format!(
                "point {} of the merged {} table is of configuration \"{}\", which its study \
                 ({configs}) does not name",
                row[0], table.study, row[column]
            ))
            .key("config")
            .expected(configs.replace(';', ", "))
            .got_named(row[column].clone())),
        None => Ok(()),
    }
}

/// The pictures of the merged tables, as the studies draw them.
fn draw_merged(merged_tables: &BTreeMap<String, Located>, out: &Path) -> Result<()> {
    if let Some(merged) = merged_tables.get("work-precision") {
        let wall_time = merged_tables.get("work-precision-wall-time");
        draw_work_precision(&merged.table, wall_time.map(|m| &m.table), out)?;
    }
    if let Some(merged) = merged_tables.get("scan-steps") {
        draw_scan(&merged.table, out)?;
        print_merged_safe_steps(merged)?;
    }
    if merged_tables.contains_key("scan-stiffness") {
        eprintln!(
            "notice: a merged stiffness scan is a table only; its picture is drawn by \
             `longstep scan stiffness` itself"
        );
    }
    Ok(())
}

/// The safe-step table of a merged step scan, as an unsharded `scan steps` prints it
/// (without the timing columns: shards take no timings).
fn print_merged_safe_steps(merged: &Located) -> Result<()> {
    let table = &merged.table;
    let (method, h, status) = (
        table.column("method")?,
        table.column("h")?,
        table.column("status")?,
    );
    let config = table.column("config").ok();
    let mut points = Vec::with_capacity(table.rows.len());
    for (row, source) in table.rows.iter().zip(&merged.sources) {
        let verdict = Verdict::parse(&row[status]).ok_or_else(|| {
            source
                .error(format!(
                    "point {} of the merged scan has status \"{}\", which is no verdict",
                    row[0], row[status]
                ))
                .key("status")
                .got_named(row[status].clone())
        })?;
        points.push(ScanPoint {
            config: config.map(|c| row[c].clone()),
            method: row[method].clone(),
            h: table.number(row, h),
            verdict,
        });
    }
    let steps = |s: &SafeStep| -> Vec<f64> {
        points
            .iter()
            .filter(|p| p.method == s.method && p.config == s.config)
            .map(|p| p.h)
            .collect()
    };
    let sampling = table.meta.get("criterion").map(String::as_str) == Some("sampling");
    let real =
        sampling || table.meta.get("drift_unit").map(String::as_str) == Some(REAL_DRIFT_UNIT);
    let units = if real { Units::Real } else { Units::None };
    let criterion = if sampling {
        Criterion::Sampling
    } else {
        Criterion::Drift
    };
    print_safe_steps(
        &safe_steps_of(&points),
        &steps,
        &[],
        units,
        (criterion, None),
    );
    Ok(())
}
