//! The pictures of the studies: work-precision, scan steps (drift or sampling) and speed.
//!
//! Every picture is drawn from its study table (`src/io/study_csv.rs`), so a merged set of
//! shards gives the same pictures as a single run.

use std::collections::BTreeMap;
use std::path::Path;

use crate::analysis::modes::{fast_modes, predicted_resonances};
use crate::error::Result;
use crate::io::scene::load_scene;
use crate::io::study_csv::StudyTable;
use crate::plot::{
    AxisSpec, Colour, Corner, Guide, LineChart, MarkerSet, PALETTE, Series, SeriesStyle,
};

/// The scene's file stem and its --set values, for titles.
fn scene_label(table: &StudyTable) -> String {
    let path = table
        .meta
        .get("scene")
        .map(String::as_str)
        .unwrap_or_default();
    let stem = Path::new(path)
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let stem = if stem == "scene" {
        // systems/<name>/scene.toml: the folder names it.
        Path::new(path)
            .parent()
            .and_then(|p| p.file_name())
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or(stem)
    } else {
        stem
    };
    match table.meta.get("set").filter(|s| !s.is_empty()) {
        Some(set) => format!("{stem} ({set})"),
        None => stem,
    }
}

/// One method's runs on an error-against-cost chart: stable runs as (cost, error) with
/// their outer step, unstable runs as (cost, error).
struct MethodPoints {
    method: String,
    stable: Vec<((f64, f64), String)>,
    failed: Vec<(f64, f64)>,
}

/// Points of each method, unstable runs separated.
fn method_points(
    table: &StudyTable,
    cost: &dyn Fn(&[String]) -> f64,
    error_column: usize,
) -> Result<Vec<MethodPoints>> {
    let method = table.column("method")?;
    let status = table.column("status")?;
    let h = table.column("h")?;
    let mut groups: Vec<MethodPoints> = Vec::new();
    for row in &table.rows {
        let name = &row[method];
        let k = match groups.iter().position(|g| &g.method == name) {
            Some(k) => k,
            None => {
                groups.push(MethodPoints {
                    method: name.clone(),
                    stable: Vec::new(),
                    failed: Vec::new(),
                });
                groups.len() - 1
            }
        };
        let point = (cost(row), table.number(row, error_column));
        if row[status] == "ok" {
            groups[k].stable.push((point, format!("h = {}", row[h])));
        } else {
            groups[k].failed.push(point);
        }
    }
    Ok(groups)
}

type CostFn<'a> = Box<dyn Fn(&[String]) -> f64 + 'a>;

/// One picture of the work-precision set: its file name, axis labels and what it plots.
struct WorkPrecisionChart<'a> {
    name: &'static str,
    x_label: &'static str,
    cost: CostFn<'a>,
    error_column: usize,
    y_label: &'static str,
}

/// Error-against-cost pictures; unstable runs are drawn as crosses at the top of the plot.
pub fn draw_work_precision(
    table: &StudyTable,
    wall: Option<&StudyTable>,
    out: &Path,
) -> Result<()> {
    let slow = table.column("slow_evaluations")?;
    let weighted = table.column("weighted_evaluations")?;
    let position = table.column("max_position_error")?;
    let energy = table.column("max_relative_energy_error")?;
    let wall_of: BTreeMap<String, f64> = wall
        .map(|w| {
            w.rows
                .iter()
                .map(|r| (r[0].clone(), w.number(r, 1)))
                .collect()
        })
        .unwrap_or_default();
    let weighted_label = "force evaluations, weighted by measured cost (slow-force units)";
    let mut charts = vec![
        WorkPrecisionChart {
            name: "error-vs-slow-evaluations",
            x_label: "slow-force evaluations",
            cost: Box::new(move |r: &[String]| table.number(r, slow)),
            error_column: position,
            y_label: "max position error",
        },
        WorkPrecisionChart {
            name: "error-vs-force-evaluations",
            x_label: weighted_label,
            cost: Box::new(move |r: &[String]| table.number(r, weighted)),
            error_column: position,
            y_label: "max position error",
        },
        WorkPrecisionChart {
            name: "energy-error-vs-force-evaluations",
            x_label: weighted_label,
            cost: Box::new(move |r: &[String]| table.number(r, weighted)),
            error_column: energy,
            y_label: "max relative energy error",
        },
    ];
    if wall.is_some() {
        charts.push(WorkPrecisionChart {
            name: "error-vs-wall-time",
            x_label: "wall time (s)",
            cost: Box::new(|r: &[String]| wall_of.get(&r[0]).copied().unwrap_or(f64::NAN)),
            error_column: position,
            y_label: "max position error",
        });
    }
    let scene = scene_label(table);
    for spec in charts {
        let groups = method_points(table, spec.cost.as_ref(), spec.error_column)?;
        let chart = work_precision_chart(&scene, &spec, &groups);
        if chart.series.is_empty() && chart.markers.is_empty() {
            continue;
        }
        for extension in ["png", "svg"] {
            chart.save(&out.join(format!("{}.{extension}", spec.name)))?;
        }
    }
    Ok(())
}

/// One error-against-cost chart: a line per method with each point labelled by its outer
/// step, and the method's unstable runs as crosses in its colour at the top.
fn work_precision_chart(
    scene: &str,
    spec: &WorkPrecisionChart,
    groups: &[MethodPoints],
) -> LineChart {
    let finite = |p: &(f64, f64)| p.0 > 0.0 && p.1 > 0.0 && p.0.is_finite() && p.1.is_finite();
    let top = groups
        .iter()
        .flat_map(|g| g.stable.iter().map(|s| s.0))
        .filter(finite)
        .map(|p| p.1)
        .fold(f64::NAN, f64::max);
    let mut chart = LineChart::new(
        &format!("Work–precision, {scene}"),
        AxisSpec::log(spec.x_label),
        AxisSpec::log(spec.y_label),
    );
    chart.legend = Corner::LowerLeft;
    for (k, group) in groups.iter().enumerate() {
        let colour = PALETTE[k % PALETTE.len()];
        let (points, labels): (Vec<(f64, f64)>, Vec<String>) = group
            .stable
            .iter()
            .filter(|s| finite(&s.0))
            .cloned()
            .unzip();
        if !points.is_empty() {
            let mut series = Series::line(&group.method, points);
            series.style = SeriesStyle::LineAndPoints;
            series.colour = Some(colour);
            series.point_labels = labels;
            chart.series.push(series);
        }
        // An unstable run has no meaningful error: it is drawn at the top of the plot.
        let ceiling = if top.is_finite() { 2.0 * top } else { 1.0 };
        let unstable: Vec<(f64, f64)> = group
            .failed
            .iter()
            .filter(|p| p.0 > 0.0 && p.0.is_finite())
            .map(|p| (p.0, ceiling))
            .collect();
        if !unstable.is_empty() {
            chart
                .markers
                .push(MarkerSet::unstable_of(&group.method, colour, unstable));
        }
    }
    chart
}

/// The pictures of a scan's table: by its criterion.
/// The column that names a scan's series: a study's `config` label, else the `method`.
fn series_column(table: &StudyTable) -> Result<usize> {
    table.column("config").or_else(|_| table.column("method"))
}

pub fn draw_scan(table: &StudyTable, out: &Path) -> Result<()> {
    if table.meta.get("criterion").map(String::as_str) == Some("sampling") {
        draw_scan_sampling(table, out)
    } else {
        draw_scan_steps(table, out)
    }
}

/// The sampling criterion's differences to the reference against outer step, one chart per
/// compared quantity (`scan-potential`, `scan-peak`), unstable runs as crosses.
fn draw_scan_sampling(table: &StudyTable, out: &Path) -> Result<()> {
    let (method, h, status) = (
        series_column(table)?,
        table.column("h")?,
        table.column("status")?,
    );
    let scene = scene_label(table);
    let quantities = [
        (
            "potential_difference",
            "Δ potential energy per molecule",
            "scan-potential",
        ),
        ("peak_difference", "Δ g(r) first-peak height", "scan-peak"),
    ];
    for (column, label, name) in quantities {
        let value = table.column(column)?;
        let mut chart = LineChart::new(
            &format!("Sampling against the reference, {scene}"),
            AxisSpec::linear("outer step h"),
            AxisSpec::linear(&format!("{label} (run − reference)")),
        );
        chart.legend = Corner::UpperLeft;
        let mut methods: Vec<&str> = Vec::new();
        for row in &table.rows {
            if !methods.contains(&row[method].as_str()) {
                methods.push(&row[method]);
            }
        }
        for (k, m) in methods.iter().enumerate() {
            let colour = PALETTE[k % PALETTE.len()];
            let (mut points, mut unstable) = (Vec::new(), Vec::new());
            for row in table.rows.iter().filter(|r| r[method] == *m) {
                let (x, y) = (table.number(row, h), table.number(row, value));
                if row[status] == "unstable" {
                    unstable.push((x, 0.0));
                } else if y.is_finite() {
                    points.push((x, y));
                }
            }
            add_method(&mut chart, m, colour, points, unstable);
        }
        if chart.series.is_empty() && chart.markers.is_empty() {
            continue;
        }
        for extension in ["png", "svg"] {
            chart.save(&out.join(format!("{name}.{extension}")))?;
        }
    }
    Ok(())
}

/// A method's line through its points in order of outer step, and its unstable runs as
/// crosses, both in its colour.
fn add_method(
    chart: &mut LineChart,
    name: &str,
    colour: Colour,
    mut points: Vec<(f64, f64)>,
    unstable: Vec<(f64, f64)>,
) {
    points.sort_by(|a, b| a.0.total_cmp(&b.0));
    if !points.is_empty() {
        let mut series = Series::line(name, points);
        series.style = SeriesStyle::LineAndPoints;
        series.colour = Some(colour);
        chart.series.push(series);
    }
    if !unstable.is_empty() {
        chart
            .markers
            .push(MarkerSet::unstable_of(name, colour, unstable));
    }
}

/// Simulated time per day at each method's largest safe step against the thread count,
/// from the timing table.
pub fn draw_ns_per_day(timing: &StudyTable, out: &Path) -> Result<()> {
    let (method, h, threads) = (
        series_column(timing)?,
        timing.column("h")?,
        timing.column("threads")?,
    );
    let (per_day, unit) = match timing.column("ns_per_day") {
        Ok(c) => (c, "ns/day"),
        Err(_) => (timing.column("time_per_day")?, "time units/day"),
    };
    let mut chart = LineChart::new(
        &format!("Speed at the largest safe step, {}", scene_label(timing)),
        AxisSpec::linear("threads"),
        AxisSpec::log(&format!("simulated time per day ({unit})")),
    );
    chart.legend = Corner::UpperLeft;
    let mut methods: Vec<(&str, &str)> = Vec::new();
    for row in &timing.rows {
        if !methods.contains(&(row[method].as_str(), row[h].as_str())) {
            methods.push((&row[method], &row[h]));
        }
    }
    for (m, step) in methods {
        let points: Vec<(f64, f64)> = timing
            .rows
            .iter()
            .filter(|r| r[method] == m)
            .map(|r| (timing.number(r, threads), timing.number(r, per_day)))
            .filter(|p| p.1.is_finite() && p.1 > 0.0)
            .collect();
        if !points.is_empty() {
            let mut series = Series::line(&format!("{m}, h = {step}"), points);
            series.style = SeriesStyle::LineAndPoints;
            chart.series.push(series);
        }
    }
    if chart.series.is_empty() {
        return Ok(());
    }
    for extension in ["png", "svg"] {
        chart.save(&out.join(format!("ns-per-day.{extension}")))?;
    }
    Ok(())
}

/// Drift against outer step for each method, unstable runs as crosses, and the resonances
/// predicted from the fast normal modes as guide lines.
fn draw_scan_steps(table: &StudyTable, out: &Path) -> Result<()> {
    let method = series_column(table)?;
    let h = table.column("h")?;
    let status = table.column("status")?;
    let drift = table.column("drift")?;
    let scene = scene_label(table);
    let mut chart = LineChart::new(
        &format!("Step-size safety scan, {scene}"),
        AxisSpec::linear("outer step h"),
        AxisSpec::log(&format!(
            "|energy drift| ({})",
            table
                .meta
                .get("drift_unit")
                .map_or("kT per unit time per dof", String::as_str)
        )),
    );
    chart.legend = Corner::UpperLeft;
    let floor = 1e-16;
    let mut methods: Vec<&str> = Vec::new();
    for row in &table.rows {
        if !methods.contains(&row[method].as_str()) {
            methods.push(&row[method]);
        }
    }
    let top = table
        .rows
        .iter()
        .map(|r| table.number(r, drift).abs())
        .filter(|d| d.is_finite())
        .fold(floor, f64::max);
    for (k, name) in methods.iter().enumerate() {
        let colour = PALETTE[k % PALETTE.len()];
        let (mut points, mut unstable) = (Vec::new(), Vec::new());
        for row in table.rows.iter().filter(|r| r[method] == *name) {
            let x = table.number(row, h);
            if row[status] == "unstable" {
                unstable.push((x, 10.0 * top));
            } else {
                points.push((x, table.number(row, drift).abs().max(floor)));
            }
        }
        add_method(&mut chart, name, colour, points, unstable);
    }
    chart.guides.extend(resonance_guides(table, h));
    if chart.series.is_empty() && chart.markers.is_empty() {
        return Ok(());
    }
    for extension in ["png", "svg"] {
        chart.save(&out.join(format!("scan.{extension}")))?;
    }
    Ok(())
}

/// Guide lines at the resonances predicted from the scene's fast modes, within the scanned
/// range of a scan table's `h` column.
fn resonance_guides(table: &StudyTable, h: usize) -> Vec<Guide> {
    let mut guides = Vec::new();
    let hs: Vec<f64> = table.rows.iter().map(|r| table.number(r, h)).collect();
    let (lo, hi) = (
        hs.iter().copied().fold(f64::INFINITY, f64::min),
        hs.iter().copied().fold(0.0, f64::max),
    );
    if let Some(path) = table.meta.get("scene") {
        let set: Vec<String> = table
            .meta
            .get("set")
            .map(|s| {
                s.split(' ')
                    .filter(|x| !x.is_empty())
                    .map(str::to_string)
                    .collect()
            })
            .unwrap_or_default();
        if let Ok(mut scene) = load_scene(Path::new(path), &set) {
            let modes = fast_modes(&mut scene.system);
            for r in predicted_resonances(&modes, lo, hi, 3) {
                guides.push(Guide {
                    x: r.h,
                    label: format!("{:?} k={}", r.kind, r.k).to_lowercase(),
                });
            }
        }
    }
    guides
}
