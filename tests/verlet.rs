//! Velocity Verlet: second order, and the size of its (bounded) energy error.

mod common;
use common::words;

use std::path::Path;

use longstep::integrators;
use longstep::io::scene::{build_scene, load_scene};
use longstep::run::{RunOptions, run};
use longstep::settings::MethodSettings;

const OSCILLATOR: &str = r#"
version = 1
name = "oscillator"
dim = 1
[anchors]
origin = [0.0]
[[particles]]
name = "x"
mass = 1.0
position = [1.0]
[[terms]]
type = "spring"
between = ["origin", "x"]
stiffness = 1.0
"#;

/// |q(T) − cos T| for the unit oscillator started at (q, p) = (1, 0).
fn oscillator_error(h: f64, t_end: f64) -> f64 {
    let mut scene = build_scene(OSCILLATOR, Path::new("oscillator.toml"), &[]).unwrap();
    let mut notices = Vec::new();
    let mut verlet = integrators::build(&MethodSettings::new("verlet", h), &mut notices).unwrap();
    verlet.setup(&mut scene.system).unwrap();
    let steps = (t_end / h).round() as usize;
    for _ in 0..steps {
        verlet.step(&mut scene.system).unwrap();
    }
    (scene.system.state.q[0] - t_end.cos()).abs()
}

#[test]
fn verlet_is_second_order_on_the_harmonic_oscillator() {
    // The global error of Verlet on q'' = -q is a phase error h²T/24 + O(h⁴), so halving h
    // divides it by 4 + O(h²): at h ≤ 0.1 the ratio is within 1 % of 4.
    let errors: Vec<f64> = [0.1, 0.05, 0.025]
        .iter()
        .map(|&h| oscillator_error(h, 10.0))
        .collect();
    for pair in errors.windows(2) {
        let ratio = pair[0] / pair[1];
        assert!(
            (ratio - 4.0).abs() < 0.04,
            "error ratio {ratio} when h halves (errors {errors:?})"
        );
    }
}

/// The largest normal-mode frequency of the horizontal three-spring system:
/// stiffness matrix [[Ω1² + 1/2, −1/2], [−1/2, Ω2² + 1/2]].
fn three_spring_max_frequency(omega1: f64, omega2: f64) -> f64 {
    let (a, d) = (omega1 * omega1 + 0.5, omega2 * omega2 + 0.5);
    let mean = 0.5 * (a + d);
    let spread = (0.25 * (a - d) * (a - d) + 0.25).sqrt();
    (mean + spread).sqrt()
}

#[test]
fn verlet_energy_error_on_the_three_spring_system_is_the_predicted_oscillation() {
    // The horizontal three-spring motion is linear. For each normal mode of frequency ω,
    // velocity Verlet conserves p²/(2(1 − x)) + ω²q²/2 with x = (hω)²/4, so the energy at
    // the step points deviates from E0 by at most x/(1 − x) relative. The bound with the
    // largest ω holds for the sum of modes. It is an oscillation, not a drift.
    //
    // The foundation issue asked for a relative error below 1e-3 at h = 0.05; that is
    // impossible for Verlet here: hΩ2 = 0.7 gives x ≈ 0.123. Below 1e-3 needs x ≲ 1e-3,
    // i.e. h ≲ 0.0045; we check h = 0.004.
    let omega_max = three_spring_max_frequency(10.0, 14.0);
    for (h, must_be_below) in [(0.05, None), (0.004, Some(1e-3))] {
        let mut scene = load_scene(Path::new("systems/three-spring.toml"), &[]).unwrap();
        let mut notices = Vec::new();
        let mut verlet =
            integrators::build(&MethodSettings::new("verlet", h), &mut notices).unwrap();
        let options = RunOptions {
            t_end: 100.0,
            ..Default::default()
        };
        let summary = run("three-spring", &mut scene.system, verlet.as_mut(), &options).unwrap();
        let x = (h * omega_max).powi(2) / 4.0;
        let bound = x / (1.0 - x);
        let measured = summary.energy.max_relative_error;
        assert!(
            measured <= bound,
            "h = {h}: error {measured} above the bound {bound}"
        );
        // The bound is reached within a factor 2 (the energy is in the stiff modes).
        assert!(
            measured >= 0.5 * bound,
            "h = {h}: error {measured} far below {bound}"
        );
        if let Some(limit) = must_be_below {
            assert!(measured < limit, "h = {h}: error {measured}");
        }
        assert_eq!(summary.steps, (100.0 / h).round() as u64);
        // One evaluation of each level per step, plus the first in setup.
        assert_eq!(summary.force_evaluations.fast, summary.steps + 1);
        assert_eq!(summary.force_evaluations.slow, summary.steps + 1);
    }
}

#[test]
fn run_command_writes_energy_csv_and_json_summary() {
    let dir = common::scratch_dir("verlet-json");
    let output = common::longstep()
        .args(words(
            "run systems/three-spring.toml --method verlet --h 0.05 --t-end 100 --json \
             --out",
        ))
        .arg(&dir)
        .output()
        .unwrap();
    assert!(output.status.success(), "{output:?}");
    let summary: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    for key in [
        "method",
        "h",
        "steps",
        "t_end",
        "force_evaluations",
        "energy",
        "wall_seconds",
        "status",
    ] {
        assert!(summary.get(key).is_some(), "summary lacks {key}: {summary}");
    }
    assert_eq!(summary["method"], "verlet");
    assert_eq!(summary["status"], "ok");
    assert_eq!(summary["steps"], 2000);
    assert!(summary["force_evaluations"]["fast"].as_u64().unwrap() > 0);
    assert!(summary["force_evaluations"]["hessian_vector"].is_u64());
    for key in ["initial", "final", "max_abs_error", "max_relative_error"] {
        assert!(summary["energy"][key].is_f64(), "energy.{key} missing");
    }
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.starts_with("levels: 0 (fast)"),
        "level table first: {stderr}"
    );

    let csv = std::fs::read_to_string(dir.join("energy.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(
        lines.next().unwrap(),
        "t,kinetic,potential,total,potential_fast,potential_slow"
    );
    assert_eq!(lines.count(), 2001);
}
