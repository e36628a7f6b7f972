//! GSS98 section 4, Figures 11 and 12: the largest position error against the stiff
//! spring's frequency Ω1 on the two-spring scene (the paper's initial data, Ω1 from 0 to 32,
//! i.e. stiffness up to 1024), and `longstep scan stiffness` itself.
//!
//! Grids: 400 values of Ω1 (spacing 0.08) as in the paper's range, t = 8 for Impulse and 16
//! for LongAverage as in the paper. Inner and reference steps are the command's defaults:
//! K = M = 320 at h = 1/2 (dt·Ω1 ≤ 0.05).

mod common;
use common::words;

use std::f64::consts::PI;
use std::path::Path;

use longstep::analysis::stiffness::{StiffnessPoint, StiffnessStudy};
use longstep::settings::RunSpec;
use rayon::prelude::*;

fn omega_values(n: usize, hi: f64) -> Vec<f64> {
    (0..n).map(|i| hi * i as f64 / (n - 1) as f64).collect()
}

fn study(scene: &Path, methods: &[&str], steps: &[f64], t_end: f64) -> Vec<StiffnessPoint> {
    let study = StiffnessStudy::new(
        scene,
        Vec::new(),
        "omega1",
        omega_values(400, 32.0),
        methods.iter().map(|m| m.to_string()).collect(),
        steps.to_vec(),
        RunSpec::default(),
        t_end,
        None,
    )
    .expect("study");
    let mut points: Vec<StiffnessPoint> = study
        .units()
        .par_iter()
        .map(|&unit| study.evaluate(unit).expect("unit"))
        .flatten()
        .collect();
    points.sort_by_key(|p| p.index);
    // The reference is good to well below anything measured: every measured error is the
    // method's to 0.1 %.
    let smallest = points
        .iter()
        .map(|p| p.max_error)
        .fold(f64::INFINITY, f64::min);
    let reference = points.iter().map(|p| p.reference_error).fold(0.0, f64::max);
    assert!(
        reference <= 1e-3 * smallest,
        "reference error {reference:e} against errors from {smallest:e}"
    );
    assert!(points.iter().all(|p| p.status == "ok"));
    points
}

/// (Ω1, error) of the largest error of `method` at `h`, optionally only for Ω1 ≥ `from`.
fn peak(points: &[StiffnessPoint], method: &str, h: f64, from: f64) -> (f64, f64) {
    points
        .iter()
        .filter(|p| p.method == method && p.h == h && p.value >= from)
        .max_by(|a, b| a.max_error.total_cmp(&b.max_error))
        .map(|p| (p.value, p.max_error))
        .expect("points")
}

#[test]
fn figure_11_impulse_error_is_first_order_and_peaks_below_h_omega_2pi() {
    let points = study(
        Path::new("systems/two-spring.toml"),
        &["impulse"],
        &[0.5, 0.25],
        8.0,
    );
    let (at_half, max_half) = peak(&points, "impulse", 0.5, 0.0);
    let (at_quarter, max_quarter) = peak(&points, "impulse", 0.25, 0.0);
    let order = (max_half / max_quarter).log2();
    eprintln!(
        "impulse: max {max_half:.4} at Ω1 = {at_half:.3} (hΩ1 = {:.3}π), h = 1/4: {max_quarter:.4} \
         at Ω1 = {at_quarter:.3} (hΩ1 = {:.3}π); observed order {order:.2}",
        0.5 * at_half / PI,
        0.25 * at_quarter / PI
    );
    // GSS98: "maximum error ≈ 0.07" and "≈ 0.03", one significant figure: the intervals
    // that round to them.
    assert!((0.065..0.075).contains(&max_half), "{max_half}");
    assert!((0.025..0.035).contains(&max_quarter), "{max_quarter}");
    // First order: halving h halves the maximum. Orders within ±1/2 of 1 separate it from
    // the second order of the mollified methods (next test).
    assert!((0.5..1.5).contains(&order), "order {order}");
    // ERRATA.md: with zero initial potential energy the peaks sit below hΩ1 = 2π (at
    // hΩ1 = 2π the outer steps sample the fast oscillation at its zero crossings). "Near":
    // within a quarter of the resonance spacing 2π, and clearly (π/8) below it.
    for (h, at) in [(0.5, at_half), (0.25, at_quarter)] {
        let phase = h * at;
        assert!(
            (1.5 * PI..2.0 * PI - PI / 8.0).contains(&phase),
            "h = {h}: peak at hΩ1 = {phase}"
        );
    }
}

#[test]
fn with_an_initial_stretch_the_impulse_peak_moves_to_h_omega_2pi() {
    // The same scene with the first spring stretched by 0.03: the fast oscillation no longer
    // starts at a zero crossing, and the peaks move onto hΩ1 = 2π (within π/8) — the
    // explanation ERRATA.md gives for Figure 11.
    let text = std::fs::read_to_string("systems/two-spring.toml").expect("scene");
    let stretched = text.replacen("position = [1.0, 0.0]", "position = [1.03, 0.0]", 1);
    assert_ne!(text, stretched);
    let dir = common::scratch_dir("stiffness-stretched");
    let scene = dir.join("stretched.toml");
    std::fs::write(&scene, stretched).expect("write");
    let points = study(&scene, &["impulse"], &[0.5, 0.25], 8.0);
    for h in [0.5, 0.25] {
        let (at, max) = peak(&points, "impulse", h, 0.0);
        eprintln!("stretched, h = {h}: max {max:.4} at hΩ1 = {:.4}", h * at);
        assert!(
            (h * at - 2.0 * PI).abs() <= PI / 8.0,
            "h = {h}: peak at hΩ1 = {}",
            h * at
        );
    }
}

#[test]
fn figure_12_long_average_error_drops_fourfold_when_h_halves() {
    let points = study(
        Path::new("systems/two-spring.toml"),
        &["long-average"],
        &[0.5, 0.25],
        16.0,
    );
    let (at_half, max_half) = peak(&points, "long-average", 0.5, 0.0);
    let (at_quarter, max_quarter) = peak(&points, "long-average", 0.25, 0.0);
    let (stiff_half_at, stiff_half) = peak(&points, "long-average", 0.5, 5.0);
    let (stiff_quarter_at, stiff_quarter) = peak(&points, "long-average", 0.25, 5.0);
    eprintln!(
        "long-average: max {max_half:.4} at Ω1 = {at_half:.3}, h = 1/4: {max_quarter:.4} at \
         Ω1 = {at_quarter:.3} (ratio {:.2}); for Ω1 ≥ 5: {stiff_half:.4} at {stiff_half_at:.3}, \
         {stiff_quarter:.4} at {stiff_quarter_at:.3} (ratio {:.2})",
        max_half / max_quarter,
        stiff_half / stiff_quarter
    );
    // "Halving the step size reduces the maximum error from 0.2 to 0.05": a factor 4,
    // second order. Orders within ±1/2 of 2 (a factor between 2√2 and 8), both overall and
    // where spring 1 is stiff.
    for (big, small) in [(max_half, max_quarter), (stiff_half, stiff_quarter)] {
        let order = (big / small).log2();
        assert!((1.5..2.5).contains(&order), "order {order}");
    }
    // ERRATA.md: the absolute maxima do not reproduce — they are larger, set by narrow
    // spikes at small Ω1 where spring 1 is not stiff (Ω1 below twice the slow frequency 1).
    assert!(
        max_half > 0.2 && max_quarter > 0.05,
        "{max_half}, {max_quarter}"
    );
    assert!(at_half < 2.0 && at_quarter < 2.0, "{at_half}, {at_quarter}");
}

// ---------------------------------------------------------------------------------------
// The command
// ---------------------------------------------------------------------------------------

fn scan(args: &[&str]) -> std::process::Output {
    common::longstep()
        .args(["scan", "stiffness", "systems/two-spring.toml"])
        .args(args)
        .output()
        .expect("runs")
}

fn rows(path: &Path) -> (String, Vec<String>) {
    let text = std::fs::read_to_string(path).expect("csv");
    let mut lines = text.lines();
    let first = lines.next().expect("comment").to_string();
    let header = lines.next().expect("header");
    assert_eq!(
        header,
        "index,method,h,omega1,max_error,error_time,reference_error,inner_steps,reference_steps,status"
    );
    (first, lines.map(str::to_string).collect())
}

#[test]
fn scan_stiffness_writes_csv_and_pictures_and_shards_partition_it() {
    let dir = common::scratch_dir("scan-stiffness");
    let whole = dir.join("whole.csv");
    let png = dir.join("err.png");
    let svg = dir.join("err.svg");
    let common_args = words(
        "--method impulse,long-average --param omega1 --range 0:4*pi --n 7 --h 0.5,1/4 \
         --t-end 4 --quiet",
    );
    let output = scan(
        &[
            &common_args[..],
            &[
                "--out",
                whole.to_str().unwrap(),
                "--png",
                png.to_str().unwrap(),
                "--svg",
                svg.to_str().unwrap(),
            ],
        ]
        .concat(),
    );
    assert!(output.status.success(), "{output:?}");
    let (first, all) = rows(&whole);
    // The study line names the size and every setting (so merge can check shards).
    assert!(
        first.starts_with("# longstep scan-stiffness, ")
            && first.contains(", points = 28, ")
            && first.contains(", method = impulse long-average, ")
            && !first.contains("shard"),
        "{first}"
    );
    assert_eq!(all.len(), 28);
    for (k, row) in all.iter().enumerate() {
        let fields: Vec<&str> = row.split(',').collect();
        assert_eq!(fields[0], k.to_string(), "rows in index order");
        assert_eq!(fields[9], "ok");
        let error: f64 = fields[4].parse().expect("error");
        assert!(error.is_finite() && error > 0.0);
    }
    assert!(std::fs::metadata(&png).expect("png").len() > 1000);
    let svg_text = std::fs::read_to_string(&svg).expect("svg");
    assert!(svg_text.contains("<svg"));

    // Two shards: together exactly the whole study's rows.
    let mut merged = Vec::new();
    for shard in ["1/2", "2/2"] {
        let path = dir.join(format!("shard-{}.csv", &shard[..1]));
        let output = scan(
            &[
                &common_args[..],
                &["--out", path.to_str().unwrap(), "--shard", shard],
            ]
            .concat(),
        );
        assert!(output.status.success(), "{output:?}");
        let (first, rows) = rows(&path);
        assert!(
            first.contains(", points = 28, ") && first.contains(&format!("shard = {shard}")),
            "{first}"
        );
        assert!(!rows.is_empty() && rows.len() < 28);
        merged.extend(rows);
    }
    merged.sort_by_key(|row| row.split(',').next().unwrap().parse::<usize>().unwrap());
    assert_eq!(merged, all);
}

#[test]
fn scan_stiffness_rejects_bad_input_naming_the_flag() {
    let dir = common::scratch_dir("scan-stiffness-bad");
    let out = dir.join("x.csv");
    let out = out.to_str().unwrap();
    let good = |replace: &[(&str, &str)]| -> Vec<String> {
        let mut args: Vec<(String, String)> = [
            ("--method", "impulse"),
            ("--param", "omega1"),
            ("--range", "0:32"),
            ("--n", "5"),
            ("--h", "0.5"),
            ("--t-end", "8"),
            ("--out", out),
        ]
        .iter()
        .map(|(a, b)| (a.to_string(), b.to_string()))
        .collect();
        for (flag, value) in replace {
            match args.iter_mut().find(|(a, _)| a == flag) {
                Some(slot) => slot.1 = value.to_string(),
                None => args.push((flag.to_string(), value.to_string())),
            }
        }
        args.into_iter().flat_map(|(a, b)| [a, b]).collect()
    };
    let cases: &[(&[(&str, &str)], &str)] = &[
        (&[("--param", "omega9")], "--param omega9"),
        (&[("--range", "5")], "--range"),
        (&[("--range", "3:1")], "--range"),
        (&[("--range", "0:bogus")], "--range"),
        (&[("--n", "1")], "--n"),
        (&[("--n", "100000000")], "--n"),
        (&[("--range", "0:1e9")], "--inner"),
        (&[("--h", "1e-9")], "outer steps"),
        (&[("--h", "-0.5")], "--h"),
        (&[("--h", "0.3")], "--t-end"),
        (&[("--t-end", "0")], "--t-end"),
        (&[("--method", "nope")], "--method nope"),
        (&[("--shard", "3/2")], "--shard"),
        (&[("--shard", "0/2")], "--shard"),
        (&[("--png", "x.jpg")], "x.jpg"),
        (&[("--reference-steps", "0")], "--reference-steps"),
        (&[("--set", "nothing=1")], "--set nothing"),
        (&[("--inner", "4"), ("--dt", "0.1")], "not both"),
    ];
    for (replace, expected) in cases {
        let args = good(replace);
        let output = common::longstep()
            .args(["scan", "stiffness", "systems/two-spring.toml"])
            .args(&args)
            .output()
            .expect("runs");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(
            stderr.contains(expected) && !stderr.contains("panicked"),
            "{args:?}: expected \"{expected}\" in: {stderr}"
        );
    }
    let output = common::longstep()
        .args(["scan", "stiffness", "no-such-scene.toml"])
        .args(good(&[]))
        .output()
        .expect("runs");
    assert_eq!(output.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&output.stderr).contains("no-such-scene.toml"));
}
