//! Issue 30 items 13–15: pictures a reader can read. Axes numbered with round ticks and
//! units, legends beside the plot instead of over the data, the quantity a verdict uses
//! drawn, unstable runs on the top edge with their step, a cooling drift told from a
//! heating one, error bands and a picture of the spectrum. Checked on the SVG files
//! (`common::svg`), whose elements carry positions, colours and content.

mod common;
use common::{argv, longstep, scratch_dir};

use common::svg::{
    SvgText, attribute, number, overlap, plot_frame, polyline_points, svg_tags, svg_texts,
    text_box, tick_labels,
};

const BUTANE: &str = "systems/molecules/butane.toml";

fn run_ok(args: &[&str]) -> String {
    let output = longstep().args(args).output().expect("longstep runs");
    assert!(
        output.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    String::from_utf8_lossy(&output.stdout).into_owned()
}

fn read(path: &std::path::Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The texts right of the plot: the legend column.
fn legend_texts(svg: &str) -> Vec<SvgText> {
    let right = plot_frame(svg).2;
    svg_texts(svg).into_iter().filter(|t| t.x > right).collect()
}

/// Rows of a study table (`#` line and header skipped), split at commas.
fn csv_rows(text: &str) -> Vec<Vec<String>> {
    text.lines()
        .filter(|l| !l.starts_with('#'))
        .skip(1)
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect()
}

/// Item 13: `ns-per-day` had no numbers on its y axis (a log axis inside one decade) and
/// ticks at 1.1 … 1.9 threads. Now the threads axis is ticked at whole counts only, the
/// speed axis carries at least three numbers, and axis and legend say ns/day and fs.
#[test]
fn ns_per_day_axes_are_numbered_and_threads_are_whole() {
    let out = scratch_dir("ns-per-day-axes");
    run_ok(&[
        "scan",
        "steps",
        BUTANE,
        "--methods",
        "impulse,long-average",
        "--h",
        "0.5fs,1fs",
        "--dt",
        "0.25fs",
        "--t-end",
        "0.5ps",
        // A loose bound, so that short runs pass and get timed.
        "--drift-bound",
        "10",
        "--repeats",
        "1",
        "--quiet",
        "--out",
        out.to_str().unwrap(),
    ]);
    let svg = read(&out.join("ns-per-day.svg"));
    let (x, y) = tick_labels(&svg);
    assert!(!x.is_empty(), "no thread ticks");
    for tick in &x {
        let threads: f64 = tick.parse().unwrap();
        assert!(
            threads >= 1.0 && threads.fract() == 0.0,
            "thread tick {tick}: {x:?}"
        );
    }
    assert!(y.len() >= 3, "speed axis ticks {y:?}");
    let texts = svg_texts(&svg);
    assert!(
        texts.iter().any(|t| t.content.contains("(ns/day)")),
        "no ns/day on the axis"
    );
    let legend = legend_texts(&svg);
    for method in ["impulse", "long-average"] {
        assert!(
            legend
                .iter()
                .any(|t| t.content.starts_with(method) && t.content.contains(" fs")),
            "no legend entry for {method} with its step in fs: {legend:?}"
        );
    }
}

/// Item 14: `run --plot` of a mollified method drew neither the mollified total its drift
/// verdict judges nor kinetic and potential on their own scales. Now energy.svg has three
/// panels — kinetic, potential, total with `mollified_total` — each with its legend
/// beside it, and the error picture names the judged energy.
#[test]
fn run_plot_draws_the_conserved_energy_on_its_own_panel() {
    let out = scratch_dir("run-plot-panels");
    run_ok(&argv(
        "run {} --method long-average --h 2fs --t-end 0.2ps --plot --quiet --out {}",
        &[BUTANE, out.to_str().unwrap()],
    ));
    let svg = read(&out.join("energy.svg"));
    let height = svg_tags(&svg, "svg")
        .first()
        .map(|tag| number(tag, "height"))
        .unwrap();
    let texts = svg_texts(&svg);
    let panel_of = |name: &str| {
        let text = texts
            .iter()
            .find(|t| t.content == name)
            .unwrap_or_else(|| panic!("no legend entry '{name}'"));
        ((text.y / (height / 3.0)).floor(), text.x)
    };
    let (kinetic, potential, total, conserved) = (
        panel_of("kinetic"),
        panel_of("potential"),
        panel_of("total"),
        panel_of("mollified_total"),
    );
    assert_eq!(
        (kinetic.0, potential.0, total.0, conserved.0),
        (0.0, 1.0, 2.0, 2.0)
    );
    // Legends beside the plots: right of every axis line.
    let axes_right = svg_tags(&svg, "polyline")
        .into_iter()
        .filter(|tag| attribute(tag, "stroke").as_deref() == Some("#000000"))
        .flat_map(polyline_points)
        .map(|p| p.0)
        .fold(0.0, f64::max);
    for (_, x) in [kinetic, potential, total, conserved] {
        assert!(
            x > axes_right,
            "a legend at x = {x} inside the plots (axes end at {axes_right})"
        );
    }
    let error = svg_texts(&read(&out.join("energy-error.svg")));
    assert!(
        error
            .iter()
            .any(|t| t.content == "mollified_total (judged by the drift verdict)"),
        "the error picture does not name the judged energy"
    );
}

/// Item 15, scan chart: the legend sat on the data, |drift| hid cooling, no bound was
/// drawn, h had no unit and the y axis stretched to 1e7 to place the crosses. Butane from
/// its shipped geometry cools at every stable point (all drifts negative).
#[test]
fn scan_chart_shows_signed_drift_bound_and_crosses_on_the_top_edge() {
    let out = scratch_dir("scan-chart-readable");
    run_ok(&argv(
        "scan steps {} --methods impulse,verlet --h 1fs:8fs:1fs --dt 0.25fs \
         --t-end 0.1ps --repeats 0 --quiet --out {}",
        &[BUTANE, out.to_str().unwrap()],
    ));
    let rows = csv_rows(&read(&out.join("scan.csv")));
    let stable: Vec<f64> = rows
        .iter()
        .filter(|r| r[3] != "unstable")
        .map(|r| r[4].parse::<f64>().unwrap())
        .collect();
    let negative = stable.iter().filter(|d| **d < 0.0).count();
    assert!(negative > 0, "the scan no longer cools: {stable:?}");
    assert!(rows.iter().any(|r| r[3] == "unstable"), "no unstable run");
    let largest = stable.iter().map(|d| d.abs()).fold(0.0, f64::max);

    let svg = read(&out.join("scan.svg"));
    let (left, top, right, bottom) = plot_frame(&svg);
    let texts = svg_texts(&svg);
    assert!(texts.iter().any(|t| t.content == "outer step h (fs)"));
    let legend = legend_texts(&svg);
    for entry in [
        "impulse",
        "verlet",
        "drift bound 0.05 kT/ns/dof",
        "open circle: drift < 0 (cooling)",
        "verlet unstable (top edge)",
    ] {
        assert!(
            legend.iter().any(|t| t.content == entry),
            "no '{entry}' beside the plot: {legend:?}"
        );
    }
    // Each cooling point is an open circle (a white disc under its coloured ring).
    let open = svg_tags(&svg, "circle")
        .into_iter()
        .filter(|tag| attribute(tag, "fill").as_deref() == Some("#FFFFFF"))
        .count();
    assert_eq!(open, negative);
    // Verlet's crosses (two strokes each, in its colour) sit in the band along the top.
    let crosses: Vec<(f64, f64, f64, f64)> = svg_tags(&svg, "line")
        .into_iter()
        .filter(|tag| attribute(tag, "stroke").as_deref() == Some("#FF7F0E"))
        .map(|tag| {
            let (x1, y1, x2, y2) = (
                number(tag, "x1"),
                number(tag, "y1"),
                number(tag, "x2"),
                number(tag, "y2"),
            );
            (x1.min(x2), y1.min(y2), x1.max(x2), y1.max(y2))
        })
        .filter(|b| b.0 > left && b.2 < right)
        .collect();
    assert!(!crosses.is_empty(), "no crosses drawn");
    for cross in &crosses {
        assert!(
            cross.1 >= top && cross.3 <= top + 16.0,
            "cross {cross:?} not on the top edge (plot {top}..{bottom})"
        );
        for label in texts.iter().filter(|t| t.content.contains("k=")) {
            assert!(
                !overlap(text_box(label), *cross),
                "'{}' over a cross",
                label.content
            );
        }
    }
    // The axis reaches the data, not 1e7: on a log axis the top of the range is the
    // largest |drift| times 10^(0.05 + 0.08) per decade spanned (5 % padding, 8 % room for
    // the crosses), under a factor 10 for the 2.6 decades here.
    let (_, y_ticks) = tick_labels(&svg);
    let highest = y_ticks
        .iter()
        .map(|t| t.parse::<f64>().unwrap())
        .fold(0.0, f64::max);
    assert!(
        highest <= 10.0 * largest,
        "y axis ticked up to {highest} for drifts up to {largest}"
    );
}

/// Item 15, work-precision: the unstable crosses had no step, the error axis no unit, and
/// a narrow cost range could show one tick. Verlet at 4 fs blows up on butane.
#[test]
fn work_precision_axes_carry_units_ticks_and_unstable_steps() {
    let out = scratch_dir("work-precision-readable");
    run_ok(&argv(
        "chart work-precision {} --methods impulse,verlet --h-list 1fs,2fs,4fs \
         --inner 4 --t-end 0.1ps --quiet --out {}",
        &[BUTANE, out.to_str().unwrap()],
    ));
    let rows = csv_rows(&read(&out.join("work-precision.csv")));
    assert!(
        rows.iter()
            .any(|r| r[1] == "verlet" && r[2] == "4" && r[3] != "ok"),
        "verlet at 4 fs no longer fails"
    );
    for name in [
        "error-vs-slow-evaluations",
        "error-vs-force-evaluations",
        "energy-error-vs-force-evaluations",
    ] {
        let svg = read(&out.join(format!("{name}.svg")));
        let (x, y) = tick_labels(&svg);
        for (axis, ticks) in [("x", &x), ("y", &y)] {
            assert!(ticks.len() >= 2, "{name}: {axis} ticks {ticks:?}");
            for (i, tick) in ticks.iter().enumerate() {
                assert!(
                    !ticks[i + 1..].contains(tick),
                    "{name}: {axis} tick {tick} twice"
                );
            }
        }
        let texts = svg_texts(&svg);
        assert!(
            texts
                .iter()
                .any(|t| t.content == "h = 4 fs" && t.fill == "#FF7F0E"),
            "{name}: verlet's unstable cross without its step"
        );
    }
    let svg = read(&out.join("error-vs-slow-evaluations.svg"));
    assert!(
        svg_texts(&svg)
            .iter()
            .any(|t| t.content == "max position error (Å)")
    );
}

/// Item 15, growth envelope: the legend covered the data and the axis had two ticks.
#[test]
fn growth_envelope_legend_is_beside_the_plot_with_three_ticks() {
    let dir = scratch_dir("growth-readable");
    let svg = dir.join("growth.svg");
    run_ok(&argv(
        "scan growth systems/three-spring.toml --method impulse,long-average --h 0.5 \
         --inner 10 --t-end 50 --out {} --svg {}",
        &[
            dir.join("growth.csv").to_str().unwrap(),
            svg.to_str().unwrap(),
        ],
    ));
    let svg = read(&svg);
    let legend = legend_texts(&svg);
    for method in ["impulse", "long-average"] {
        assert!(
            legend.iter().any(|t| t.content.starts_with(method)),
            "{method} not beside the plot"
        );
    }
    let (_, y) = tick_labels(&svg);
    assert!(y.len() >= 3, "y ticks {y:?}");
}

/// Item 15, stability map: under `--colour type` the title said "spectral radius", and α,
/// β, Γ were not explained.
#[test]
fn stability_map_title_says_what_is_coloured_and_explains_its_symbols() {
    let dir = scratch_dir("map-title");
    for (colour, title) in [
        ("type", "Instability type:"),
        ("radius", "Spectral radius:"),
    ] {
        let svg = dir.join(format!("{colour}.svg"));
        run_ok(&argv(
            "stability-map --method impulse --h 0.5 --gamma1 0:6.5 --gamma2 0:6.5 --n 20 \
             --colour {} --quiet --out {} --svg {}",
            &[
                colour,
                dir.join(format!("{colour}.csv")).to_str().unwrap(),
                svg.to_str().unwrap(),
            ],
        ));
        let texts = svg_texts(&read(&svg));
        assert!(
            texts.iter().any(|t| t.content.starts_with(title)),
            "no title '{title}…'"
        );
        assert!(
            texts.iter().any(|t| t.content.contains("Γ1 = hΩ1")
                && t.content.contains("slow coupling U = [[α1, β], [β, α2]]")),
            "α, β and Γ not explained"
        );
    }
}

/// Item 15, g(r): the error band rdf.csv has is drawn — one shaded polygon through every
/// bin's g ± its standard error.
#[test]
fn rdf_picture_draws_the_error_band() {
    let dir = scratch_dir("rdf-band");
    common::water_run(&dir, "20fs");
    let svg = dir.join("gr.svg");
    run_ok(&argv(
        "analyze systems/water-box/scene.toml {} --pairs O-O --blocks 2 --png {}",
        &[dir.to_str().unwrap(), svg.to_str().unwrap()],
    ));
    let svg = read(&svg);
    let polygons = svg_tags(&svg, "polygon");
    assert_eq!(polygons.len(), 1, "one band expected");
    let corners = attribute(polygons[0], "points")
        .unwrap_or_default()
        .split_whitespace()
        .count();
    let bins = std::fs::read_dir(dir.join("analysis"))
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.path())
        .find(|p| {
            p.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with("rdf"))
        })
        .map(|p| csv_rows(&read(&p)).len())
        .expect("an rdf table");
    assert_eq!(corners, 2 * bins, "the band does not follow every bin");
    assert!(
        legend_texts(&svg)
            .iter()
            .any(|t| t.content.ends_with("± 1 standard error (blocks)"))
    );
}

/// Item 15, modes: a picture of the spectrum with every predicted resonant step marked.
#[test]
fn modes_picture_marks_every_predicted_resonant_step() {
    let dir = scratch_dir("modes-picture");
    let svg = dir.join("modes.svg");
    let json = run_ok(&["modes", BUTANE, "--json", "--svg", svg.to_str().unwrap()]);
    let json: serde_json::Value = serde_json::from_str(&json).unwrap();
    let resonances = json["resonances"].as_array().unwrap().len();
    assert!(resonances > 0);
    let svg = read(&svg);
    // Guide lines: grey (black at 40 %) verticals.
    let guides = svg_tags(&svg, "polyline")
        .into_iter()
        .filter(|tag| attribute(tag, "opacity").as_deref() == Some("0.4"))
        .filter(|tag| {
            let p = polyline_points(tag);
            p.len() == 2 && p[0].0 == p[1].0
        })
        .count();
    assert_eq!(guides, resonances);
    let texts = svg_texts(&svg);
    assert!(texts.iter().any(|t| t.content.contains("k=")));
    assert!(
        texts
            .iter()
            .any(|t| t.content == "period T of a mode, outer step h (fs)")
    );
    assert!(
        legend_texts(&svg)
            .iter()
            .any(|t| t.content.starts_with("modes"))
    );
}
