//! `longstep scan steps`: the largest safe step where it is known, the timing file apart
//! from the deterministic table, the drift bound in kT/ns/dof on real scenes, the sampling
//! criterion against a reference run, and bad input.

mod common;
use common::run_cli as run;
use common::{argv, scratch_dir, study_rows as rows, words};

use std::path::Path;

/// Run `longstep`; returns (exit code, stdout, stderr).
fn ok(args: &[&str]) -> String {
    let (code, stdout, stderr) = run(args);
    assert_eq!(code, 0, "{args:?}: {stderr}");
    stdout
}

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn verlets_largest_safe_step_is_its_linear_stability_limit() {
    // Along x the three-spring system is linear (GSS98 eq. (27)): unit masses, stiffness
    // matrix [[Ω1² + ½, −½], [−½, Ω2² + ½]] with Ω1 = 10, Ω2 = 14. Verlet is stable for
    // h ω_max < 2 and grows by ρ = e^{acosh(hω/2)} per step beyond. At 1.005 h* that is
    // e^{0.1} per step, e^{70} over 100 time units: far past any blow-up factor. Below h*
    // the energy error stays bounded by 1/(1 − (hω/2)²) ≈ 100 times its scale at 0.995 h*,
    // so a blow-up factor of 1e4 separates the two; the drift bound is taken out of play
    // (this scan asks where the method is stable, not how well it conserves).
    let (a, d) = (100.5f64, 196.5f64);
    let omega_max = (0.5 * (a + d) + (0.25 * (a - d) * (a - d) + 0.25).sqrt()).sqrt();
    let limit = 2.0 / omega_max;
    let steps: Vec<f64> = [0.98, 0.995, 1.005, 1.02]
        .iter()
        .map(|f| f * limit)
        .collect();
    let list = steps
        .iter()
        .map(|h| format!("{h:.9}"))
        .collect::<Vec<_>>()
        .join(",");
    let dir = scratch_dir("scan-verlet-limit");
    let stdout = ok(&argv(
        "scan steps systems/three-spring.toml --method verlet --h {} --t-end 100 \
         --blowup 1e4 --drift-bound 1e9 --repeats 0 --quiet --out {}",
        &[&list, path(&dir)],
    ));
    let statuses: Vec<String> = rows(&dir.join("scan.csv"))
        .into_iter()
        .map(|r| r[3].clone())
        .collect();
    assert_eq!(
        statuses,
        ["pass", "pass", "unstable", "unstable"],
        "{stdout}"
    );
    let line = stdout.lines().find(|l| l.starts_with("verlet")).unwrap();
    let safe: f64 = line.split_whitespace().nth(1).unwrap().parse().unwrap();
    assert!((safe - steps[1]).abs() < 1e-8, "{line}");
}

#[test]
fn timings_live_in_their_own_file_and_the_scan_table_is_deterministic() {
    let (first, second, shard) = (
        scratch_dir("scan-timing-1"),
        scratch_dir("scan-timing-2"),
        scratch_dir("scan-timing-shard"),
    );
    let args = |out: &Path, extra: &[&str]| -> Vec<String> {
        let mut a: Vec<String> = [
            "scan",
            "steps",
            "systems/three-spring.toml",
            "--methods",
            "impulse,long-average",
            "--h",
            "0.1:0.3:0.1",
            "--inner",
            "10",
            "--t-end",
            "20",
            // Loose enough that every point passes: at the default 1e-3 impulse at 0.2 fits
            // (2.3 ± 50)e-5, an interval that reaches past 1e-3 (undecided), and this test is
            // about the timings, not the verdicts.
            "--drift-bound",
            "1e-2",
            "--quiet",
            "--out",
            path(out),
        ]
        .map(String::from)
        .to_vec();
        a.extend(extra.iter().map(|s| s.to_string()));
        a
    };
    let call = |a: Vec<String>| ok(&a.iter().map(String::as_str).collect::<Vec<_>>());
    let stdout = call(args(&first, &["--repeats", "2"]));
    call(args(&second, &["--repeats", "3"]));
    // The table is the same bit for bit whatever the timings did.
    let table = std::fs::read(first.join("scan.csv")).unwrap();
    assert_eq!(table, std::fs::read(second.join("scan.csv")).unwrap());
    let text = String::from_utf8(table).unwrap();
    assert!(
        !text.contains("wall") && !text.contains("per_day"),
        "{text}"
    );
    // The timing file: each method at its largest safe step (the end of the scan, 0.3,
    // where both are stable), at 1 thread and at all threads, medians of the repeats.
    let timing = std::fs::read_to_string(first.join("timing.csv")).unwrap();
    assert!(
        timing.starts_with("# longstep scan-steps-timing, "),
        "{timing}"
    );
    let header = timing.lines().nth(1).unwrap();
    assert_eq!(
        header,
        "method,h,threads,repeats,median_wall_seconds,time_per_day"
    );
    let timed = rows(&first.join("timing.csv"));
    for method in ["impulse", "long-average"] {
        let mine: Vec<&Vec<String>> = timed.iter().filter(|r| r[0] == method).collect();
        assert!(!mine.is_empty(), "{method}: {timing}");
        assert_eq!(mine[0][2], "1", "{timing}");
        for r in mine {
            assert_eq!((r[1].as_str(), r[3].as_str()), ("0.3", "2"), "{timing}");
            let (seconds, per_day): (f64, f64) = (r[4].parse().unwrap(), r[5].parse().unwrap());
            // 20 time units per `seconds` of wall time, per day.
            assert!(seconds > 0.0, "{timing}");
            assert!((per_day * seconds / 86_400.0 / 20.0 - 1.0).abs() < 1e-9);
        }
    }
    assert!(stdout.contains("time units/day (1 thr)"), "{stdout}");
    assert!(first.join("ns-per-day.png").exists());
    // A shard takes no timings: its safe step needs every point.
    call(args(&shard, &["--shard", "1/2"]));
    assert!(!shard.join("timing.csv").exists());
}

#[test]
fn the_drift_bound_of_a_real_scene_is_run_s_in_kt_per_ns_per_dof() {
    let dir = scratch_dir("scan-real-bound");
    ok(&argv(
        "scan steps systems/water-box/scene.toml --methods impulse --h 2fs --inner 4 \
         --t-end 40fs --temperature 300K --seed 7 --repeats 0 --quiet --out {}",
        &[path(&dir)],
    ));
    let text = std::fs::read_to_string(dir.join("scan.csv")).unwrap();
    let first = text.lines().next().unwrap();
    for needle in [
        "drift_bound = 0.05",
        "drift_unit = kT/ns/dof",
        "temperature = 300K",
        "seed = 7",
    ] {
        assert!(first.contains(needle), "{needle}: {first}");
    } // The equilibrium mollifier's options reach every point, and the table records them.
    ok(&argv(
        "scan steps systems/water-box/scene.toml --methods equilibrium-molly \
         --molly-constraints bonds --molly-jacobian projection --h 2fs --inner 4 \
         --t-end 20fs --repeats 0 --quiet --out {}",
        &[path(&dir)],
    ));
    let text = std::fs::read_to_string(dir.join("scan.csv")).unwrap();
    assert!(
        text.lines()
            .next()
            .unwrap()
            .contains("molly = bonds projection"),
        "{text}"
    );
    // Its conserved energy is what it is judged by.
    assert_eq!(
        rows(&dir.join("scan.csv"))[0][6],
        "mollified_total",
        "{text}"
    );
}

fn reference_run(dir: &Path, temperature: &str, t_end: &str) {
    ok(&argv(
        "run systems/water-box/scene.toml --method langevin-respa --inner 1 --h 0.5fs \
         --friction 1/ps --temperature {} --t-end {} --energy-every 1 \
         --trajectory-every 8 --quiet --out {}",
        &[temperature, t_end, path(dir)],
    ));
}

#[test]
fn scans_refuse_bad_input_with_a_clear_message() {
    let dir = scratch_dir("scan-bad-input");
    let out = dir.join("out");
    let water = argv(
        "scan steps systems/water-box/scene.toml --h 1fs --inner 2 --t-end 20fs \
         --temperature 300K --quiet --out {}",
        &[path(&out)],
    );
    let with = |extra: &[&str]| -> (i32, String) {
        let mut a: Vec<&str> = water.to_vec();
        a.extend(extra);
        if !extra.contains(&"--repeats") {
            a.extend(["--repeats", "0"]);
        }
        let (code, _, stderr) = run(&a);
        (code, stderr)
    };
    // A thermostatted method is never judged by NVE drift.
    for extra in [
        &["--methods", "langevin-respa"][..],
        &["--methods", "impulse,sinr", "--criterion", "drift"][..],
    ] {
        let (code, stderr) = with(extra);
        assert_eq!(code, 1, "{stderr}");
        assert!(
            stderr.contains("thermostatted") && stderr.contains("--criterion sampling"),
            "{stderr}"
        );
    }
    let (code, stderr) = with(&["--methods", "langevin-respa", "--criterion", "sampling"]);
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("needs --reference"), "{stderr}");
    // A reference directory without energy.csv.
    let empty = dir.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let sampling = words("--methods langevin-respa --criterion sampling --blocks 2 --reference");
    let mut extra = sampling.to_vec();
    extra.push(path(&empty));
    let (code, stderr) = with(&extra);
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("energy.csv"), "{stderr}");
    // A reference at another temperature: refused, naming both.
    let hot = dir.join("hot");
    reference_run(&hot, "400K", "40fs");
    let mut extra = sampling.to_vec();
    extra.push(path(&hot));
    let (code, stderr) = with(&extra);
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("temperature") && stderr.contains("300 K"),
        "{stderr}"
    );
    // Unbounded sizes are bounded.
    let (code, stderr) = with(&["--methods", "impulse", "--repeats", "1000"]);
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("--repeats"), "{stderr}");
    let (code, _, stderr) = run(&["scan", "steps", "systems/three-spring.toml", "--h", "0.1"]);
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("--methods"), "{stderr}");
}

#[test]
fn the_sampling_criterion_passes_the_reference_itself_and_fails_a_biased_sampler() {
    // The reference: BAOAB (langevin-respa on one level) at 0.5 fs, γ = 1/ps, 300 K, 0.4 ps.
    let dir = scratch_dir("scan-sampling");
    let reference = dir.join("reference");
    reference_run(&reference, "300K", "0.4ps");
    let out = dir.join("scan");
    ok(&[
        "scan",
        "steps",
        "systems/water-box/scene.toml",
        "--methods",
        "langevin-respa",
        "--h",
        "0.5fs,2fs,4fs",
        "--dt",
        "0.5fs",
        "--friction",
        "1/ps",
        "--temperature",
        "300K",
        "--t-end",
        "0.4ps",
        "--criterion",
        "sampling",
        "--reference",
        path(&reference),
        // Over 0.4 ps the peak height's combined error (≈ 0.055) is wider than the default
        // bound 0.05 can decide (a 2σ interval of ±0.11): every point would be undecided on
        // the peak. This test is about the potential energy; the peak bound is put out of
        // play.
        "--peak-bound",
        "0.5",
        // Likewise the configurational temperature and the per-term means: over 0.4 ps the
        // reference against itself is 0 ± 2.1 K, undecided against ΔT = 3 K (and the 2 fs
        // point's angle energy fails, −26 ± 1.4 kcal/mol: flexible water's bend is
        // resolved at 0.5 fs, not at 2). `the_scans_verdict_on_a_point_is_analyzes_on_the_same_run`
        // tests those criteria; here their bound is put out of play.
        "--temperature-bound",
        "1e9",
        "--repeats",
        "1",
        "--quiet",
        "--out",
        path(&out),
    ]);
    // At 0.5 fs the point is the reference run itself (same seed, same frames): the same
    // bits, so both differences are exactly zero.
    assert_eq!(
        std::fs::read(reference.join("energy.csv")).unwrap(),
        std::fs::read(out.join("runs/0000-langevin-respa-h0.5/energy.csv")).unwrap()
    );
    // The headers carry the real scene's units, as energy.csv's do (issue 30 item 12).
    let text = std::fs::read_to_string(out.join("scan.csv")).unwrap();
    let header = text.lines().nth(1).unwrap();
    for field in [
        "h[fs]",
        "potential_difference[kcal/mol]",
        "potential_combined_error[kcal/mol]",
        "peak_difference",
        "kinetic_temperature[K]",
        "decide_at[fs]",
    ] {
        assert!(header.split(',').any(|f| f == field), "{field} in {header}");
    }
    let table = rows(&out.join("scan.csv"));
    let number = |row: &[String], k: usize| -> f64 { row[k].parse().unwrap() };
    assert_eq!(table[0][3], "pass", "{table:?}");
    assert_eq!((number(&table[0], 4), number(&table[0], 6)), (0.0, 0.0));
    // Every point starts from the same velocities and draws the same noise, so a step's
    // bias shows against small paired differences. At 4 fs langevin-respa's potential energy
    // is biased (GSS98-type resonance heating of the O–H stretch, about 0.3 kcal/mol per
    // molecule here); the criterion's 0.1 kcal/mol bound must catch it, beyond its combined
    // standard error (≈ 0.02) many times over. At 2 fs the bias is well inside the bound.
    let pe_4 = number(&table[2], 4);
    let pe_4_error = number(&table[2], 5);
    assert_eq!(table[2][3], "fail", "{table:?}");
    assert!(pe_4 > 0.1 && pe_4 > 5.0 * pe_4_error, "{table:?}");
    assert_eq!(table[1][3], "pass", "{table:?}");
    // ns/day at the largest passing step, 2 fs, in the timing file.
    let timing = rows(&out.join("timing.csv"));
    assert!(!timing.is_empty());
    for r in &timing {
        assert_eq!((r[0].as_str(), r[1].as_str()), ("langevin-respa", "2"));
        assert!(r[5].parse::<f64>().unwrap() > 0.0);
    }
}

#[test]
fn a_run_at_the_wrong_temperature_fails_the_sampling_comparison() {
    // Two BAOAB runs, one started at 300 K and one at 400 K. Half of the start's excess
    // kinetic energy flows into the potential within a few vibrational periods, and the
    // thermostat (γ = 1/ps) pulls the rest back only over picoseconds, so over 0.2 ps the warm
    // run's water sits near 340 K against the cool run's 290 K, and its potential energy per
    // molecule is higher by about 0.5 kcal/mol (≈ 0.01 kcal/mol/K per molecule for the
    // potential of SPC/Fw water, times 50 K; `longstep analyze` of these runs gives
    // +0.55 ± 0.05): beyond the bound of 0.1 and beyond three combined standard errors (a
    // difference the statistics resolve). A run against itself passes with zero differences.
    use longstep::analysis::run_analysis::{Analyzer, RunFiles};
    use longstep::run::verdict::Verdict;
    use longstep::studies::criterion::reference::Kind;
    use longstep::studies::criterion::sampling::{SamplingCriterion, compare};
    use longstep::units::Units;
    let dir = scratch_dir("scan-sampling-temperature");
    let (cool, warm) = (dir.join("300"), dir.join("400"));
    reference_run(&cool, "300K", "0.2ps");
    reference_run(&warm, "400K", "0.2ps");
    let scene = common::scene_file("systems/water-box/scene.toml", &[]);
    let criterion = SamplingCriterion {
        reference: cool.clone(),
        pair: ("O".into(), "O".into()),
        potential_bound: 0.1,
        peak_bound: 0.05,
        basin_bound: 0.1,
        temperature_bound: 3.0,
        temperature: Some(300.0),
        backbone: Vec::new(),
        discard: 40.0,
        blocks: 5,
        frames: 50,
        runs: dir.clone(),
    };
    let analyzer = Analyzer::new(&scene, criterion.analysis_options()).unwrap();
    let files = |d: &Path| RunFiles {
        energy: d.join("energy.csv"),
        trajectory: d.join("trajectory.xyz"),
        dof: None,
    };
    let reference = analyzer.analyze(&files(&cool)).unwrap();
    let hot = analyzer.analyze(&files(&warm)).unwrap();
    let settings = criterion.settings(Units::Real);
    let same = compare(&reference, &reference, &settings, Units::Real);
    println!("the reference against itself: {same:?}");
    assert!(same.potential_difference == 0.0, "{same:?}");
    assert_ne!(same.verdict, Verdict::Fail, "{same:?}");
    let wrong = compare(&reference, &hot, &settings, Units::Real);
    let potential = wrong.criteria.iter().find(|c| c.kind == Kind::Potential);
    assert_eq!(potential.unwrap().verdict, "fail", "{wrong:?}");
    assert_eq!(wrong.verdict, Verdict::Fail, "{wrong:?}");
    assert!(
        wrong.potential_difference > 0.1
            && wrong.potential_difference > 3.0 * wrong.potential_combined_error,
        "{wrong:?}"
    );
}

#[test]
fn the_scans_verdict_on_a_point_is_analyzes_on_the_same_run() {
    // One criterion module for both: `scan steps --criterion sampling` judges its point (BAOAB
    // 2 fs on the water box) by the criteria `analyze --reference` gives the same run
    // directory with the same discard, blocks and temperature — every criterion, present or
    // absent, with the same numbers to the bit and the same verdicts.
    let dir = scratch_dir("scan-sampling-analyze");
    let reference = dir.join("reference");
    reference_run(&reference, "300K", "0.4ps");
    let out = dir.join("scan");
    ok(&argv(
        "scan steps systems/water-box/scene.toml --methods langevin-respa --inner 1 --h 2fs \
         --friction 1/ps --temperature 300K --t-end 0.4ps --criterion sampling --reference {} \
         --discard 0.1ps --blocks 5 --frames 50 --repeats 0 --quiet --out {}",
        &[path(&reference), path(&out)],
    ));
    let point = out.join("runs/0000-langevin-respa-h2");
    let scan: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(point.join("criteria.json")).unwrap())
            .unwrap();
    let stdout = ok(&argv(
        "analyze systems/water-box/scene.toml {} --reference {} --skip 0.1ps --blocks 5 \
         --temperature 300K --json --quiet --out {}",
        &[path(&point), path(&reference), path(&dir.join("analysis"))],
    ));
    let analyze: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(
        scan, analyze[0]["criteria"],
        "scan {scan:#}\nanalyze {analyze:#}"
    );
    // The criteria are there to be compared: the configurational temperature and the terms
    // are judged (a water box has no backbone: its basins are absent, said so).
    let criteria = scan.as_array().unwrap();
    let verdict_of = |kind: &str| -> Vec<&str> {
        criteria
            .iter()
            .filter(|c| c["kind"] == kind)
            .map(|c| c["verdict"].as_str().unwrap())
            .collect()
    };
    assert_eq!(verdict_of("basin"), ["absent"], "{scan:#}");
    for kind in ["configurational_temperature", "term", "potential", "peak"] {
        let verdicts = verdict_of(kind);
        assert!(!verdicts.is_empty(), "{kind}: {scan:#}");
        assert!(verdicts.iter().all(|v| *v != "absent"), "{kind}: {scan:#}");
    }
    // The scan's verdict on the point is analyze's overall verdict, and its table carries
    // the configurational temperature's difference and verdict as the criterion has them.
    let (header, rows) = common::study_table(&out.join("scan.csv"));
    assert_eq!(
        rows[0][3],
        analyze[0]["verdict"].as_str().unwrap(),
        "{rows:?}"
    );
    let column = |name: &str| header.iter().position(|h| h == name).unwrap();
    let t_conf = criteria
        .iter()
        .find(|c| c["kind"] == "configurational_temperature")
        .unwrap();
    let difference: f64 = rows[0][column("configurational_temperature_difference[K]")]
        .parse()
        .unwrap();
    assert_eq!(difference, t_conf["difference"].as_f64().unwrap());
    assert_eq!(
        rows[0][column("configurational_temperature_verdict")],
        t_conf["verdict"].as_str().unwrap()
    );
}

#[test]
fn level_dt_holds_the_inner_levels_fixed_while_h_varies() {
    // Three levels (bonded, short-range non-bonded, the rest): with --level-dt 2fs,0.5fs
    // the point at h has level steps h/2fs and 4, so h/0.5fs innermost (bonded) steps per
    // outer step: over 24 fs, 6 steps of 4 fs and 4 of 6 fs each take 48 bonded steps,
    // 48 + 1 bonded evaluations (the first step's start is the one more), and one slow
    // evaluation per outer step plus the first.
    let dir = scratch_dir("scan-level-dt");
    let args = |h: &str| -> Vec<String> {
        [
            "scan",
            "steps",
            "systems/water-box/three-level.toml",
            "--methods",
            "impulse",
            "--h",
            h,
            "--level-dt",
            "2fs,0.5fs",
            "--t-end",
            "24fs",
            "--repeats",
            "0",
            "--quiet",
            "--out",
            path(&dir),
        ]
        .map(String::from)
        .to_vec()
    };
    let a = args("4fs,6fs");
    ok(&a.iter().map(String::as_str).collect::<Vec<_>>());
    let table = rows(&dir.join("scan.csv"));
    for (row, steps) in table.iter().zip([6u64, 4]) {
        assert_eq!(row[9], steps.to_string(), "{row:?}");
        assert_eq!(row[10], (steps + 1).to_string(), "{row:?}");
        assert_eq!(row[11], "49", "{row:?}");
    }
    // A step that the fixed level does not divide is refused before any run.
    let a = args("5fs");
    let (code, _, stderr) = run(&a.iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("--level-dt step 1") && stderr.contains("5"),
        "{stderr}"
    );
}
