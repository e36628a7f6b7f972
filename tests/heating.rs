//! A run whose energy drifts beyond its bound says so: a warning line, a `warnings` array
//! and the `drift` object in the JSON; a run within its bound does not.

mod common;
use common::{argv, longstep, scratch_dir};

fn run_json(args: &[&str]) -> serde_json::Value {
    let output = longstep().args(args).output().expect("longstep runs");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(0), "{args:?}: {stderr}");
    serde_json::from_slice(&output.stdout).expect("JSON summary")
}

/// Butane at 300 K (seed 7) with impulse for 10 ps at outer step `h`, K = 2h/fs.
fn butane(h: u32, extra: &[&str]) -> serde_json::Value {
    let out = scratch_dir(&format!("heating-butane-{h}"));
    let (h_text, inner) = (format!("{h}fs"), (2 * h).to_string());
    let mut args = argv(
        "run systems/molecules/butane.toml --method impulse --h {} --inner {} \
         --t-end 10ps --temperature 300K --seed 7 --json --quiet --out {}",
        &[&h_text, &inner, out.to_str().unwrap()],
    );
    args.extend_from_slice(extra);
    run_json(&args)
}

/// The water box from the kit's velocities with impulse at outer step `h`, dt = 0.5 fs.
fn water(name: &str, h: &str, t_end: &str, extra: &[&str]) -> serde_json::Value {
    let out = scratch_dir(name);
    let mut args = argv(
        "run systems/water-box/scene.toml --method impulse --h {} --dt 0.5fs --t-end {} \
         --json --quiet --out {}",
        &[h, t_end, out.to_str().unwrap()],
    );
    args.extend_from_slice(extra);
    run_json(&args)
}

#[test]
fn a_heating_run_warns_and_a_safe_one_does_not() {
    // At h = 4.5 fs impulse sits in the O–H resonance band of the water box (4.52–4.66 fs
    // by `longstep modes`; docs/studies.md): the energy climbs by hundreds of kcal/mol in
    // 1 ps, far beyond its fluctuation, without blowing up.
    let heating = water("heating-water-4.5", "4.5fs", "1ps", &[]);
    assert_eq!(heating["status"], "ok", "it ran: {heating}");
    let drift = &heating["drift"];
    assert_eq!(drift["energy"], "total");
    assert_eq!(drift["unit"], "kT/ns/dof");
    assert_eq!(drift["bound"], 0.05);
    assert!(drift["value"].as_f64().unwrap() > 0.05, "{drift}");
    // Its whole 2σ interval lies beyond the bound: a fail, not an undecided.
    assert_eq!(drift["verdict"], "fail", "{drift}");
    let warnings = heating["warnings"].as_array().unwrap();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(
        warnings[0].as_str().unwrap().contains("this run heats"),
        "{warnings:?}"
    );
    // The bound is the user's: raised above the drift, the same run passes.
    let value = drift["value"].as_f64().unwrap();
    let bound = (2.0 * value).to_string();
    let loose = water(
        "heating-water-loose",
        "4.5fs",
        "1ps",
        &["--drift-bound", &bound],
    );
    assert!(loose["warnings"].as_array().unwrap().is_empty(), "{loose}");

    // Butane at 3 fs: within the bound.
    let safe = butane(3, &[]);
    assert!(
        safe["drift"]["value"].as_f64().unwrap().abs() <= 0.05,
        "{safe}"
    );
    assert!(safe["warnings"].as_array().unwrap().is_empty(), "{safe}");
}

#[test]
fn a_drift_within_the_energys_fluctuation_is_not_called_heating() {
    // Impulse at 4 fs heats the water box by ≈ 6 kT/ns/dof, but over 2 ps its true energy
    // swings by ±30 kcal/mol about the fitted line, more than the fitted change: the
    // drift is reported beyond the bound, undecided (with the run length that would
    // decide), and no warning is raised.
    let short = water("heating-water-4-short", "4fs", "2ps", &[]);
    let drift = &short["drift"];
    assert_eq!(drift["exceeded"], true, "{drift}");
    assert_eq!(drift["verdict"], "undecided", "{drift}");
    // The error bar σ_E/T shrinks as 1/T: the interval clears the bound at
    // T' = T · 2σ / (|value| − bound) (src/run/verdict.rs), a longer run than this one.
    let number = |key: &str| drift[key].as_f64().unwrap();
    let span = number("to") - number("from");
    let expected = number("from") + span * 2.0 * number("error") / (number("value").abs() - 0.05);
    let decide_at = number("decide_at");
    assert!(
        decide_at > number("to") && (decide_at - expected).abs() <= 1e-9 * expected,
        "{drift}"
    );
    assert!(
        drift["verdict_text"]
            .as_str()
            .unwrap()
            .starts_with("undecided: a run of ~"),
        "{drift}"
    );
    let (change, fluctuation) = (
        drift["change"].as_f64().unwrap(),
        drift["fluctuation"].as_f64().unwrap(),
    );
    assert!(change.abs() <= 2.0 * fluctuation, "{drift}");
    assert!(short["warnings"].as_array().unwrap().is_empty(), "{short}");
}

#[test]
fn a_mollified_method_is_judged_by_its_conserved_energy() {
    let out = scratch_dir("heating-long-average");
    let summary = run_json(&argv(
        "run systems/three-spring.toml --method long-average --h 0.5 --inner 50 \
         --t-end 200 --json --quiet --out {}",
        &[out.to_str().unwrap()],
    ));
    let drift = &summary["drift"];
    assert_eq!(drift["energy"], "mollified_total", "{drift}");
    assert_eq!(drift["unit"], "kT per unit time per dof");
    assert!(drift["conserved_energy"].is_number() && drift["true_energy"].is_number());
    assert_eq!(drift["value"], drift["conserved_energy"]);
    // A dimensionless scene keeps its energy.csv: no units, no temperature column.
    let csv = std::fs::read_to_string(out.join("energy.csv")).unwrap();
    assert_eq!(
        csv.lines().next().unwrap(),
        "t,kinetic,potential,total,potential_fast,potential_slow,mollified_total"
    );
    assert!(summary.get("units").is_none() && summary.get("temperature").is_none());
}

#[test]
fn a_fit_window_skips_the_start_and_a_bad_one_is_refused() {
    // The fit starts at the first recorded row at or after 2 ps: rows come every 10 steps
    // of 3 fs (the scene's energy_every).
    let from = butane(3, &["--fit-from", "2ps"]);
    let start = from["drift"]["from"].as_f64().unwrap();
    assert!((2000.0..2030.0).contains(&start), "{from}");
    let out = scratch_dir("heating-bad-window");
    for (extra, fragment) in [
        (
            ["--fit-from", "20ps"],
            "--fit-from 20 ps is outside the run [0, 10 fs)",
        ),
        (["--drift-bound", "0"], "--drift-bound must be positive"),
    ] {
        let mut args = argv(
            "run systems/molecules/butane.toml --h 1fs --t-end 10fs --out {}",
            &[out.to_str().unwrap()],
        );
        args.extend(extra);
        let output = longstep().args(&args).output().unwrap();
        assert_eq!(output.status.code(), Some(1));
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(stderr.contains(fragment), "{stderr}");
    }
}
