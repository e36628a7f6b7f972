//! The pictures of the studies: work-precision, scan steps (drift or sampling) and speed.
//!
//! Every picture is drawn from its study table (`src/io/study_csv.rs`), so a merged set of
//! shards gives the same pictures as a single run.

use std::collections::BTreeMap;
use std::path::Path;

use crate::analysis::modes::{Mode, Resonance, fast_modes, predicted_resonances};
use crate::error::Result;
use crate::io::scene::load_scene;
use crate::io::study_csv::StudyTable;
use crate::plot::{
    AxisSpec, Colour, Guide, Level, LineChart, MarkerSet, MarkerShape, PALETTE, Series, SeriesStyle,
};

/// The unit a study table's header gives a column (`h[fs]` → `fs`), if any.
fn unit_of(table: &StudyTable, name: &str) -> Option<String> {
    let header = &table.header[table.column(name).ok()?];
    let (_, rest) = header.split_once('[')?;
    Some(rest.trim_end_matches(']').to_string()).filter(|u| !u.is_empty())
}

/// `text (unit)` where the column carries a unit, else `text`.
fn with_unit(text: &str, table: &StudyTable, column: &str) -> String {
    match unit_of(table, column) {
        Some(unit) => format!("{text} ({unit})"),
        None => text.to_string(),
    }
}

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
    failed: Vec<((f64, f64), String)>,
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
    let h_unit = unit_of(table, "h").map_or(String::new(), |u| format!(" {u}"));
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
        let label = format!("h = {}{h_unit}", row[h]);
        if row[status] == "ok" {
            groups[k].stable.push((point, label));
        } else {
            groups[k].failed.push((point, label));
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
    y_label: String,
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
    let position_label = with_unit("max position error", table, "max_position_error");
    let mut charts = vec![
        WorkPrecisionChart {
            name: "error-vs-slow-evaluations",
            x_label: "slow-force evaluations",
            cost: Box::new(move |r: &[String]| table.number(r, slow)),
            error_column: position,
            y_label: position_label.clone(),
        },
        WorkPrecisionChart {
            name: "error-vs-force-evaluations",
            x_label: weighted_label,
            cost: Box::new(move |r: &[String]| table.number(r, weighted)),
            error_column: position,
            y_label: position_label.clone(),
        },
        WorkPrecisionChart {
            name: "energy-error-vs-force-evaluations",
            x_label: weighted_label,
            cost: Box::new(move |r: &[String]| table.number(r, weighted)),
            error_column: energy,
            y_label: "max relative energy error".to_string(),
        },
    ];
    if wall.is_some() {
        charts.push(WorkPrecisionChart {
            name: "error-vs-wall-time",
            x_label: "wall time (s)",
            cost: Box::new(|r: &[String]| wall_of.get(&r[0]).copied().unwrap_or(f64::NAN)),
            error_column: position,
            y_label: position_label.clone(),
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
    let mut chart = LineChart::new(
        &format!("Work–precision, {scene}"),
        AxisSpec::log(spec.x_label),
        AxisSpec::log(&spec.y_label),
    );
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
        // An unstable run has no meaningful error: it is drawn on the top edge of the
        // plot, labelled with its outer step.
        let (unstable, labels): (Vec<(f64, f64)>, Vec<String>) = group
            .failed
            .iter()
            .filter(|p| p.0.0 > 0.0 && p.0.0.is_finite())
            .map(|(p, label)| ((p.0, f64::NAN), label.clone()))
            .unzip();
        if !unstable.is_empty() {
            let mut set = MarkerSet::unstable_on_top(&group.method, colour, unstable);
            set.labels = labels;
            chart.markers.push(set);
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
/// compared quantity (`scan-potential`, `scan-peak`), unstable runs as crosses on the top
/// edge.
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
            AxisSpec::linear(&with_unit("outer step h", table, "h")),
            AxisSpec::linear(&with_unit(
                &format!("{label} (run − reference)"),
                table,
                column,
            )),
        );
        for (k, m) in series_names(table, method).iter().enumerate() {
            let colour = PALETTE[k % PALETTE.len()];
            let (mut points, mut unstable) = (Vec::new(), Vec::new());
            for row in table.rows.iter().filter(|r| r[method] == *m) {
                let (x, y) = (table.number(row, h), table.number(row, value));
                if row[status] == "unstable" {
                    unstable.push((x, f64::NAN));
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

/// The distinct values of a table's series column, in order of appearance.
fn series_names(table: &StudyTable, column: usize) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    for row in &table.rows {
        if !names.contains(&row[column]) {
            names.push(row[column].clone());
        }
    }
    names
}

/// A method's line through its points in order of outer step, and its unstable runs as
/// crosses on the top edge of the plot, both in its colour.
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
            .push(MarkerSet::unstable_on_top(name, colour, unstable));
    }
}

/// Simulated time per day at each method's largest safe step against the thread count,
/// from the timing table: a point per method and thread count on a linear axis from zero,
/// the threads axis ticked at the counts measured.
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
    let h_unit = unit_of(timing, "h").map_or(String::new(), |u| format!(" {u}"));
    let mut counts: Vec<f64> = timing
        .rows
        .iter()
        .map(|r| timing.number(r, threads))
        .filter(|t| t.is_finite())
        .collect();
    counts.sort_by(f64::total_cmp);
    counts.dedup();
    let (Some(&fewest), Some(&most)) = (counts.first(), counts.last()) else {
        return Ok(());
    };
    let fastest = timing
        .rows
        .iter()
        .map(|r| timing.number(r, per_day))
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    let mut chart = LineChart::new(
        &format!("Speed at the largest safe step, {}", scene_label(timing)),
        AxisSpec::linear("threads")
            .with_range(fewest - 0.5, most + 0.5)
            .with_ticks(counts.clone()),
        AxisSpec::linear(&format!("simulated time per day ({unit})"))
            .with_range(0.0, 1.1 * fastest.max(f64::MIN_POSITIVE)),
    );
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
            let name = format!("{m}, h = {step}{h_unit} ({unit})");
            let mut series = Series::line(&name, points);
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

/// Drift against outer step for each method on a logarithmic axis of |drift| — a negative
/// drift (cooling) as an open circle —, the drift bound as a dashed line, unstable runs as
/// crosses on the top edge, and the resonances predicted from the fast normal modes as
/// guide lines.
fn draw_scan_steps(table: &StudyTable, out: &Path) -> Result<()> {
    let method = series_column(table)?;
    let h = table.column("h")?;
    let status = table.column("status")?;
    let drift = table.column("drift")?;
    let scene = scene_label(table);
    let unit = table
        .meta
        .get("drift_unit")
        .map_or("kT per unit time per dof", String::as_str);
    let mut chart = LineChart::new(
        &format!("Step-size safety scan, {scene}"),
        AxisSpec::linear(&with_unit("outer step h", table, "h")),
        AxisSpec::log(&format!("|energy drift| ({unit})")),
    );
    // A drift of exactly zero still gets a place on the logarithmic axis.
    let floor = 1e-16;
    let mut cooling = false;
    for (k, name) in series_names(table, method).iter().enumerate() {
        let colour = PALETTE[k % PALETTE.len()];
        let (mut points, mut unstable) = (Vec::new(), Vec::new());
        for row in table.rows.iter().filter(|r| r[method] == *name) {
            let x = table.number(row, h);
            if row[status] == "unstable" {
                unstable.push((x, f64::NAN));
            } else if table.number(row, drift).is_finite() {
                points.push((x, table.number(row, drift)));
            }
        }
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        let hollow: Vec<bool> = points.iter().map(|p| p.1 < 0.0).collect();
        cooling |= hollow.iter().any(|&c| c);
        let magnitudes = points.iter().map(|p| (p.0, p.1.abs().max(floor))).collect();
        add_method(&mut chart, name, colour, magnitudes, unstable);
        if let Some(series) = chart.series.last_mut().filter(|s| s.name == *name) {
            series.hollow = hollow;
        }
    }
    if let Some(bound) = table
        .meta
        .get("drift_bound")
        .and_then(|b| b.parse::<f64>().ok())
        .filter(|b| *b > 0.0)
    {
        chart.levels.push(Level {
            y: bound,
            name: format!("drift bound {bound} {unit}"),
            colour: plotters::style::RGBColor(200, 0, 0),
        });
    }
    if cooling {
        chart.markers.push(MarkerSet::new(
            "open circle: drift < 0 (cooling)",
            MarkerShape::Circle,
            plotters::style::RGBColor(90, 90, 90),
            Vec::new(),
        ));
    }
    chart.guides.extend(resonance_guides(table, h));
    if chart.series.is_empty() && chart.markers.iter().all(|m| m.points.is_empty()) {
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

/// The spectrum of the fast modes as sticks at their periods (one stick per period, its
/// height the number of modes within 1 % of it) up to twice the largest outer step asked
/// about — the longest period that resonates there (h = T/2) —, and the predicted resonant
/// outer steps (h = k·T/2 and the type-2 combinations) as labelled guide lines on the same
/// time axis.
pub fn draw_modes(
    path: &Path,
    scene: &str,
    modes: &[Mode],
    resonances: &[Resonance],
    h_max: f64,
    units: crate::units::Units,
) -> Result<()> {
    let longest = 2.0 * h_max;
    let mut periods: Vec<f64> = modes
        .iter()
        .filter(|m| !m.unstable && m.frequency > 0.0 && m.period <= longest)
        .map(|m| m.period)
        .collect();
    periods.sort_by(f64::total_cmp);
    let mut sticks: Vec<(f64, f64)> = Vec::new();
    for period in periods {
        match sticks.last_mut() {
            Some(last) if period <= 1.01 * last.0 => last.1 += 1.0,
            _ => sticks.push((period, 1.0)),
        }
    }
    let unit = match units {
        crate::units::Units::Real => " (fs)",
        crate::units::Units::None => "",
    };
    let tallest = sticks.iter().map(|s| s.1).fold(1.0, f64::max);
    let mut chart = LineChart::new(
        &format!("Fast modes (sticks) and resonant outer steps (grey lines), {scene}"),
        AxisSpec::linear(&format!("period T of a mode, outer step h{unit}"))
            .with_range(0.0, longest.max(f64::MIN_POSITIVE)),
        AxisSpec::linear("modes at this period").with_range(0.0, 1.25 * tallest),
    );
    if !sticks.is_empty() {
        chart
            .series
            .push(Series::sticks("modes (stick at period T)", sticks));
    }
    for r in resonances {
        chart.guides.push(Guide {
            x: r.h,
            label: format!("{:?} k={}", r.kind, r.k).to_lowercase(),
        });
    }
    chart.save(path)
}
