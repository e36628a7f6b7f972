//! `longstep stability-map` and `longstep spectral-radius` as a user runs them.

mod common;
use common::{argv, words};

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use longstep::analysis::stability::AnalyticMethod;
use longstep::analysis::stability::analytic::LinearProblem;

fn longstep(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_longstep"))
        .args(args)
        .output()
        .expect("the longstep binary runs")
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("longstep-stability-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir.join(name)
}

fn text(path: &Path) -> String {
    std::fs::read_to_string(path).expect("output file")
}

#[test]
fn stability_map_writes_csv_png_and_svg() {
    let csv = scratch("map.csv");
    let png = scratch("map.png");
    let svg = scratch("map.svg");
    let output = longstep(&argv(
        "stability-map --method long-average --h 0.5 --gamma1 0:2*pi --gamma2 0:2*pi \
         --n 50 --out {} --png {} --svg {}",
        &[
            csv.to_str().expect("utf-8"),
            png.to_str().expect("utf-8"),
            svg.to_str().expect("utf-8"),
        ],
    ));
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let content = text(&csv);
    let mut lines = content.lines();
    assert_eq!(lines.next(), Some("gamma1,gamma2,spectral_radius,type"));
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|x| x.parse().expect("number")).collect())
        .collect();
    assert_eq!(rows.len(), 2500);
    // Row order: Γ1 slow, Γ2 fast; the last point is (2π, 2π); values match the library.
    assert_eq!(rows[1][0], 0.0);
    assert!((rows[1][1] - 2.0 * std::f64::consts::PI / 49.0).abs() < 1e-15);
    let problem = LinearProblem::three_spring(AnalyticMethod::LongAverage, 0.5).expect("valid");
    for row in &rows {
        let point = problem.point(row[0], row[1]);
        assert_eq!(row[2], point.spectral_radius);
        assert_eq!(row[3], point.kind.code() as f64);
    }
    let png_bytes = std::fs::read(&png).expect("png");
    assert!(png_bytes.starts_with(b"\x89PNG\r\n\x1a\n") && png_bytes.len() > 10_000);
    let svg_text = text(&svg);
    assert!(svg_text.contains("<svg") && svg_text.contains("LongAverage"));
    // Not --quiet and not a terminal: a summary, no progress bar.
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("2500 points"), "{stderr}");
}

#[test]
fn shards_concatenate_to_the_whole_map() {
    let whole = scratch("whole.csv");
    let common = words(
        "stability-map --method impulse --h 0.5 --gamma1 0:4*pi --gamma2 1:3 --n 37 \
         --quiet",
    );
    let mut args: Vec<&str> = common.to_vec();
    args.extend(["--out", whole.to_str().expect("utf-8")]);
    let output = longstep(&args);
    assert!(output.status.success());
    assert!(output.stderr.is_empty(), "--quiet prints nothing");
    let mut joined = String::new();
    for k in 1..=3 {
        let part = scratch(&format!("part{k}.csv"));
        let shard = format!("{k}/3");
        let mut args: Vec<&str> = common.to_vec();
        args.extend(["--out", part.to_str().expect("utf-8"), "--shard", &shard]);
        let output = longstep(&args);
        assert!(
            output.status.success(),
            "{}",
            String::from_utf8_lossy(&output.stderr)
        );
        // A shard names its settings on a first `# longstep stability-map` line (for merge).
        let content = text(&part);
        let (study, rest) = content.split_once('\n').expect("study line");
        assert!(study.starts_with("# longstep stability-map, "), "{study}");
        let body = rest.split_once('\n').expect("header").1;
        joined.push_str(body);
    }
    let content = text(&whole);
    assert_eq!(joined, content.split_once('\n').expect("header").1);
}

#[test]
fn spectral_radius_json_for_footnote_2() {
    let output = longstep(&words(
        "spectral-radius --method impulse --h 0.5 --gamma1 3*pi/4 --gamma2 3*pi/4 \
         --alpha1 4 --alpha2 4 --beta -4 --json",
    ));
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let value: serde_json::Value = serde_json::from_slice(&output.stdout).expect("one JSON object");
    assert_eq!(value["type"], 2);
    let rho = value["spectral_radius"].as_f64().expect("number");
    assert!(rho > 1.1, "{rho}");
}

#[test]
fn integrator_mode_runs_verlet() {
    let output = longstep(&words(
        "spectral-radius --mode integrator --method verlet --h 0.5 --gamma1 3 \
         --gamma2 1 --json",
    ));
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let value: serde_json::Value = serde_json::from_slice(&output.stdout).expect("JSON");
    assert_eq!(value["type"], 2, "Verlet at hΩ1 = 3 > 2 is unstable");
}

#[test]
fn bad_input_is_a_clear_error_with_exit_code_1() {
    let csv = scratch("bad.csv");
    let out = csv.to_str().expect("utf-8");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            argv("stability-map --method nope --h 0.5 --out {}", &[out]),
            "analytic mode knows",
        ),
        (
            argv(
                "stability-map --method impulse --h 0.5 --gamma1 5:1 --out {}",
                &[out],
            ),
            "--gamma1",
        ),
        (
            argv(
                "stability-map --method impulse --h 0.5 --shard 0/3 --out {}",
                &[out],
            ),
            "--shard",
        ),
        (
            argv(
                "stability-map --method impulse --h 0.5 --inner 4 --out {}",
                &[out],
            ),
            "--inner applies to --mode integrator",
        ),
        (
            argv("stability-map --method impulse --h -1 --out {}", &[out]),
            "--h must be positive",
        ),
        (
            argv(
                "stability-map --method impulse --h 0.5 --beta 2 --out {}",
                &[out],
            ),
            "not positive semidefinite",
        ),
        (
            argv(
                "stability-map --method impulse --h 0.5 --png map.jpg --out {}",
                &[out],
            ),
            ".png or .svg",
        ),
        (
            words("stability-map --method impulse --h 0.5 --out /nonexistent-dir/x.csv"),
            "/nonexistent-dir/x.csv",
        ),
        (
            words("spectral-radius --mode integrator --method nope --h 0.5 --gamma1 1 --gamma2 1"),
            "unknown method \"nope\"",
        ),
        (
            words("spectral-radius --method impulse --h 0.5 --gamma1 sin( --gamma2 1"),
            "--gamma1",
        ),
    ];
    for (args, expected) in cases {
        let output = longstep(&args);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(
            stderr.contains(expected),
            "{args:?}: expected \"{expected}\" in: {stderr}"
        );
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
}
