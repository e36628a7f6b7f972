//! `longstep run` with the multiple-time-step methods: the runs of the "done when",
//! and force-evaluation counts that match the cost of each method exactly.

mod common;

use common::{longstep, run_cli, scratch_dir, words};

fn run_json(args: &[&str]) -> serde_json::Value {
    let out = scratch_dir(&format!(
        "mts-cli-{}",
        args.join("-").replace(['/', '.'], "_")
    ));
    let output = longstep()
        .args(args)
        .args(["--json", "--quiet", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    serde_json::from_slice(&output.stdout).unwrap()
}

#[test]
fn three_spring_runs_report_energies_and_force_counts() {
    let (h, inner, t_end) = (0.5, 50u64, 1000.0);
    let steps = (t_end / h) as u64;
    for method in ["impulse", "short-average", "long-average", "linear-average"] {
        let line = format!(
            "run systems/three-spring.toml --method {method} --h 0.5 --inner 50 --t-end 1000"
        );
        let summary = run_json(&words(&line));
        assert_eq!(summary["status"], "ok", "{method}: {summary}");
        assert_eq!(summary["steps"], steps);
        let counts = &summary["force_evaluations"];
        let (fast, slow, hv) = (
            counts["fast"].as_u64().unwrap(),
            counts["slow"].as_u64().unwrap(),
            counts["hessian_vector"].as_u64().unwrap(),
        );
        // One slow evaluation per outer step plus the first (the second kick's force is the
        // next step's first).
        assert_eq!(slow, steps + 1, "{method}");
        // Oscillation: `inner` fast gradients per step, plus the first.
        let oscillation = steps * inner + 1;
        // Averaging, once per step and once at the start: ⌈μK⌉ auxiliary steps, each one
        // fast gradient but the last; forward Jacobian (the three-spring components are single masses,
        // 2 coordinates): 2 Hessian-vector products per auxiliary point.
        let auxiliary = match method {
            "impulse" => 0,
            "short-average" => inner / 2,
            _ => inner,
        };
        let averaging = auxiliary.saturating_sub(1);
        assert_eq!(fast, oscillation + (steps + 1) * averaging, "{method}");
        assert_eq!(hv, (steps + 1) * auxiliary * 2, "{method}");
        let energy = &summary["energy"];
        assert!(
            energy["max_relative_error"].as_f64().unwrap() < 0.2,
            "{method}: {energy}"
        );
        assert!(
            summary["parameters"]
                .as_str()
                .unwrap()
                .contains("inner_steps = 50")
        );
    }
}

#[test]
fn adjoint_jacobian_counts_one_hessian_vector_product_per_auxiliary_step() {
    let summary = run_json(&words(
        "run systems/three-spring.toml --method long-average --h 0.5 --inner 20 --t-end 10 \
         --jacobian adjoint",
    ));
    let hv = summary["force_evaluations"]["hessian_vector"]
        .as_u64()
        .unwrap();
    assert_eq!(hv, 21 * 20);
    assert!(
        summary["parameters"]
            .as_str()
            .unwrap()
            .contains("jacobian = adjoint")
    );
}

#[test]
fn dt_gives_the_inner_step_and_must_divide_h() {
    let summary = run_json(&words(
        "run systems/three-spring.toml --method impulse --h 0.5 --dt 0.01 --t-end 1",
    ));
    assert!(
        summary["parameters"]
            .as_str()
            .unwrap()
            .contains("inner_steps = 50")
    );
    let (code, _, stderr) = run_cli(&words(
        "run systems/three-spring.toml --method impulse --h 0.5 --dt 0.03 --t-end 1",
    ));
    assert_eq!(code, 1);
    assert!(
        stderr.contains("does not divide the outer step h = 0.5"),
        "{stderr}"
    );
    let (code, _, stderr) = run_cli(&words(
        "run systems/three-spring.toml --method long-average --h 0.5 --t-end 1",
    ));
    assert_eq!(code, 1);
    assert!(
        stderr.contains("long-average needs the inner step"),
        "{stderr}"
    );
    let (_, _, stderr) = run_cli(&words(
        "run systems/three-spring.toml --method long-average --h 0.5 --inner 10 --t-end 1 \
         --jacobian reverse",
    ));
    assert!(stderr.contains("unknown jacobian \"reverse\""), "{stderr}");
}
