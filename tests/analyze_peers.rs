//! `longstep analyze` on another engine's trajectory (issue 40): a GROMACS `.xtc` and an
//! OpenMM `.dcd` of the solvated alanine dipeptide (tests/data/peer-trajectories/, written by
//! scripts/make_peer_trajectories.py: 8 frames 50 fs apart from the 300 K start) read, their
//! energies recomputed term by term and judged; the per-term criterion on synthetic series;
//! a trajectory of another model, order or box refused.

mod common;
use common::{argv, estimate, run_cli, scene_file, scratch_dir};

use std::path::Path;

use longstep::analysis::term_energies::{evaluate, series_names};
use longstep::io::energy_table::EnergyTable;
use longstep::io::trajectory::TrajectoryReader;
use longstep::studies::criterion::reference::{judge_mean, term_bound};
use longstep::units::BOLTZMANN_KCAL_PER_K;
use serde_json::Value as Json;

const SCENE: &str = "systems/alanine-dipeptide-amber/ala2-solvated-pme.toml";

/// A 16 fs impulse run of the dipeptide into `dir`, energy rows and extended-XYZ frames
/// every 2 steps (t = 0, 4, …, 16 fs): what the term and format tests analyse.
fn short_run(dir: &Path) {
    let (code, _, stderr) = run_cli(&argv(
        "run {} --method impulse --h 2fs --inner 4 --t-end 16fs --temperature 300K --seed 3 \
         --energy-every 2 --trajectory-every 2 --out {}",
        &[SCENE, dir.to_str().unwrap()],
    ));
    assert_eq!(code, 0, "{stderr}");
}
const XTC: &str = "tests/data/peer-trajectories/ala2-gromacs.xtc";
const DCD: &str = "tests/data/peer-trajectories/ala2-openmm.dcd";
const OPENMM_TERMS: &str = "tests/data/peer-trajectories/ala2-openmm-terms.json";

/// Every term of the model, as `analyze` names its series.
const TERMS: [&str; 9] = [
    "bonds",
    "angles",
    "torsions",
    "impropers",
    "nonbonded/lennard-jones",
    "nonbonded/coulomb",
    "pme-reciprocal",
    "lj-14",
    "coulomb-14",
];

/// The entry of the JSON array `list` whose `key` is `name`.
fn entry<'a>(list: &'a Json, key: &str, name: &str) -> &'a Json {
    list.as_array()
        .unwrap()
        .iter()
        .find(|c| c[key] == name)
        .unwrap_or_else(|| panic!("no {key} {name} in {list}"))
}

fn analyze_json(args: &[&str]) -> Json {
    let (code, stdout, stderr) = run_cli(args);
    assert_eq!(code, 0, "{stderr}");
    serde_json::from_str(&stdout).expect("JSON")
}

#[test]
fn a_gromacs_xtc_is_judged_against_an_openmm_dcd() {
    let out = scratch_dir("analyze-peers-judged");
    let out = out.to_str().unwrap();
    let args = argv(
        "analyze {} {} --reference {} --json --blocks 4 --probes 1 --out {}",
        &[SCENE, XTC, DCD, out],
    );
    let summaries = analyze_json(&args);
    let run = &summaries[0];
    // GROMACS writes the start too: 9 frames, t = 0 to 0.4 ps.
    assert_eq!(run["frames"], 9);
    assert_eq!(run["energies_from"], "frames (recomputed)");
    let criteria = run["criteria"].as_array().unwrap();
    let find = |name: &str| {
        criteria
            .iter()
            .find(|c| c["name"] == name)
            .unwrap_or_else(|| panic!("no criterion {name}: {criteria:?}"))
    };
    // Every term, the configurational temperature, the potential, O-O and the basins are
    // judged: a difference, its error and a verdict from the error bar.
    let mut judged: Vec<String> = TERMS.iter().map(|t| format!("mean {t} energy")).collect();
    judged.extend(
        [
            "potential energy per molecule",
            "configurational temperature",
            "g O-O first-peak height",
            "basin alphaR population",
        ]
        .map(String::from),
    );
    for name in &judged {
        let c = find(name);
        assert!(
            ["pass", "fail", "undecided"].contains(&c["verdict"].as_str().unwrap()),
            "{c}"
        );
        let (d, e) = (c["difference"].as_f64(), c["error"].as_f64());
        assert!(
            d.is_some_and(f64::is_finite) && e.is_some_and(|e| e >= 0.0),
            "{c}"
        );
    }
    assert!(["pass", "fail", "undecided"].contains(&run["verdict"].as_str().unwrap()));

    // The lengths came over in the right unit (nm in the xtc, Å in the dcd): the water O–H
    // bonds' mean length is TIP3P's 0.9572 Å stretched by hydrogen bonding (a few 0.01 Å),
    // and the bond term of either file lies between n k_B T/2 (equipartition of the
    // fluctuation, 258 kcal/mol for n = 867 bonds at 300 K) and twice that (the mean
    // stretch adds (k/2)δ² ≈ 0.13 kcal/mol per O–H bond at δ = 0.015 Å, ~110 kcal/mol); a
    // length off by a factor 10 would put it off by 10² or more.
    let oh = run["geometry"]
        .as_array()
        .unwrap()
        .iter()
        .find(|g| g["type"] == "H-O")
        .unwrap();
    let oh = oh["mean"].as_f64().unwrap();
    assert!((0.9572..1.0).contains(&oh), "O-H {oh} Å");
    let bonds = find("mean bonds energy");
    let equipartition = 867.0 * BOLTZMANN_KCAL_PER_K * 300.0 / 2.0;
    for mean in [
        bonds["value"].as_f64().unwrap(),
        bonds["reference"].as_f64().unwrap(),
    ] {
        assert!(
            (equipartition..2.0 * equipartition).contains(&mean),
            "{mean} vs {equipartition}"
        );
    }
}

#[test]
fn terms_from_the_dcd_equal_openmms_at_the_same_positions() {
    // OpenMM's bond, angle and torsion energies (Reference platform, double) at each frame's
    // positions rounded to float32, against longstep's from the dcd's floats. Both read the
    // same prmtop digits; kJ ↔ kcal and nm ↔ Å conversions are exact to round-off (sums of
    // ~900 terms: ~1e-13 relative; 1e-10 leaves room for acos, cos). But OpenMM's
    // DCDReporter wraps each molecule into the box before rounding, and the script rounded
    // the unwrapped positions: each coordinate may differ by up to one float32 ulp of the
    // larger of the two, ≤ 2⁻²³·(|q|max + box) — to first order an energy difference of at
    // most ‖∇E_term‖₁ times that (the second order, k·ulp² ~ 1e-9, is far below).
    let scene = scene_file(SCENE, &[]);
    let terms = scene.system.forces.terms();
    let reference: Json =
        serde_json::from_str(&std::fs::read_to_string(OPENMM_TERMS).unwrap()).unwrap();
    let frames = reference["frames"].as_array().unwrap();
    let mut reader = TrajectoryReader::open(Path::new(DCD)).unwrap();
    let (mut q, mut energies) = (Vec::new(), Vec::new());
    let mut names = Vec::new();
    for expected in frames {
        reader
            .read_next(&mut q)
            .unwrap()
            .expect("a frame per reference entry");
        if names.is_empty() {
            names = series_names(terms, &q);
        }
        evaluate(terms, &q, &mut energies);
        let term = |name: &str| energies[names.iter().position(|n| n == name).unwrap()];
        let ulp = 2f64.powi(-23) * (q.iter().fold(0.0f64, |m, x| m.max(x.abs())) + 24.0);
        let gradient_norm = |names: &[&str]| {
            let mut g = vec![0.0; q.len()];
            for t in terms.iter().filter(|t| names.contains(&t.name.as_str())) {
                t.term.add_gradient(&q, &mut g);
            }
            g.iter().map(|x| x.abs()).sum::<f64>()
        };
        for (ours, theirs, parts) in [
            (term("bonds"), &expected["bonds"], vec!["bonds"]),
            (term("angles"), &expected["angles"], vec!["angles"]),
            (
                term("torsions") + term("impropers"),
                &expected["torsions"],
                vec!["torsions", "impropers"],
            ),
        ] {
            let theirs = theirs.as_f64().unwrap();
            let tolerance = 1e-10 * theirs.abs() + gradient_norm(&parts) * ulp;
            assert!(
                (ours - theirs).abs() <= tolerance,
                "{ours} vs OpenMM {theirs} (tolerance {tolerance})"
            );
        }
    }
    assert!(reader.read_next(&mut q).unwrap().is_none());
}

#[test]
fn terms_recomputed_from_a_longstep_trajectory_equal_the_runs_energies() {
    // A short impulse run writing energy rows and extended-XYZ frames at the same steps: the
    // frames hold every coordinate to the shortest decimal that reads back to the same
    // double, so the recomputed terms are the run's to round-off. The run's energy.csv has
    // the potential per level (fast: bonds, angles, torsions, impropers; slow: the rest) and
    // the total. The terms are summed in another order than the levels' sums and the
    // non-bonded lists are built at other positions (the same pairs within the cutoff), so
    // they agree to the round-off of sums whose parts reach |E| ~ 7e3 kcal/mol over ~5e5
    // pairs: √(5e5)·1.1e-16·7e3 ≈ 5e-10 kcal/mol; 1e-8 kcal/mol bounds it with room.
    let out = scratch_dir("analyze-peers-longstep");
    let dir = out.join("run");
    short_run(&dir);
    let scene = scene_file(SCENE, &[]);
    let terms = scene.system.forces.terms();
    let table = EnergyTable::read(
        &dir.join("energy.csv"),
        &["t", "potential", "potential_fast", "potential_slow"],
    )
    .unwrap();
    let mut reader = TrajectoryReader::open(&dir.join("trajectory.xyz")).unwrap();
    let (mut q, mut energies) = (Vec::new(), Vec::new());
    let mut frames = 0;
    while let Some(info) = reader.read_next(&mut q).unwrap() {
        let names = series_names(terms, &q);
        evaluate(terms, &q, &mut energies);
        let row = table
            .column(0)
            .iter()
            .position(|&t| (t - info.time.unwrap()).abs() < 1e-9)
            .expect("an energy row per frame");
        let fast: f64 = names
            .iter()
            .zip(&energies)
            .filter(|(n, _)| ["bonds", "angles", "torsions", "impropers"].contains(&n.as_str()))
            .map(|(_, e)| e)
            .sum();
        let total: f64 = energies.iter().sum();
        for (ours, theirs) in [
            (fast, table.column(2)[row]),
            (total - fast, table.column(3)[row]),
            (total, table.column(1)[row]),
        ] {
            assert!((ours - theirs).abs() < 1e-8, "{ours} vs the run's {theirs}");
        }
        frames += 1;
    }
    assert_eq!(frames, 5, "frames at t = 0, 4, …, 16 fs");
}

#[test]
fn the_per_term_criterion_on_series_of_known_mean_and_error() {
    // A harmonic term of n = 100 pieces at T = 300 K: Var = n (k_B T)²/2, so the bound for
    // ΔT = 3 K is n k_B ΔT/2 exactly (equipartition).
    let (n, t, dt) = (100.0, 300.0, 3.0);
    let kt = BOLTZMANN_KCAL_PER_K * t;
    let variance = n * kt * kt / 2.0;
    let bound = term_bound(variance, t, dt, BOLTZMANN_KCAL_PER_K);
    let expected = n * BOLTZMANN_KCAL_PER_K * dt / 2.0;
    assert!((bound - expected).abs() < 1e-12 * expected, "{bound}");

    // Reference mean n k_B T/2 with error 0.01; the run's mean off by known amounts with
    // error 0.02: combined error √(0.0005) = 0.02236, 2σ = 0.0447. The bound is 0.298.
    let reference = estimate(n * kt / 2.0, 0.01);
    let sigma2 = 2.0 * 0.0005f64.sqrt();
    for (offset, verdict) in [
        (0.0, "pass"),
        (bound - sigma2 - 0.01, "pass"),
        (bound - sigma2 + 0.01, "undecided"),
        (bound + sigma2 - 0.01, "undecided"),
        (-(bound + sigma2 + 0.01), "fail"),
        // A run biased by 2ΔT in equipartition temperature: twice the bound.
        (2.0 * expected, "fail"),
    ] {
        let run = estimate(reference.mean + offset, 0.02);
        let c = judge_mean(
            "mean bonds energy",
            "kcal/mol",
            &run,
            &reference,
            bound,
            (0.0, 10.0),
        );
        assert_eq!(c.verdict, verdict, "offset {offset}: {c:?}");
        assert!((c.difference.unwrap() - offset).abs() < 1e-9);
        assert!((c.error.unwrap() - 0.0005f64.sqrt()).abs() < 1e-15);
    }
}

fn refused(args: &[&str]) -> String {
    let (code, _, stderr) = run_cli(args);
    assert_ne!(code, 0, "accepted: {args:?}");
    stderr
}

#[test]
fn a_trajectory_of_another_model_is_refused() {
    // The vacuum dipeptide (22 atoms) against the solvated box's frames (1291).
    let vacuum = "systems/alanine-dipeptide-amber/ala2.prmtop";
    let stderr = refused(&argv("analyze {} {}", &[vacuum, XTC]));
    assert!(
        stderr.contains(XTC) && stderr.contains("1291 atoms"),
        "{stderr}"
    );

    // The right count, another order: two atoms of the dipeptide swapped with two waters'.
    let out = scratch_dir("analyze-peers-refused");
    let swapped = out.join("swapped.dcd");
    let no_box = out.join("no-box.dcd");
    let mut input = chemfiles::Trajectory::open(DCD, 'r').unwrap();
    let mut frame = chemfiles::Frame::new();
    input.read(&mut frame).unwrap();
    {
        let mut other = chemfiles::Trajectory::open(&swapped, 'w').unwrap();
        let mut changed = frame.clone();
        let positions = changed.positions_mut();
        positions.swap(4, 600);
        positions.swap(8, 900);
        other.write(&changed).unwrap();
        let mut open = chemfiles::Trajectory::open(&no_box, 'w').unwrap();
        frame.set_cell(&chemfiles::UnitCell::infinite());
        open.write(&frame).unwrap();
    }
    let swapped = swapped.to_str().unwrap();
    let stderr = refused(&argv("analyze {} {} --blocks 2", &[SCENE, swapped]));
    assert!(
        stderr.contains(swapped) && stderr.contains("not in the order"),
        "{stderr}"
    );
    let no_box = no_box.to_str().unwrap();
    let stderr = refused(&argv("analyze {} {} --blocks 2", &[SCENE, no_box]));
    assert!(
        stderr.contains(no_box) && stderr.contains("no box"),
        "{stderr}"
    );

    // A model without units cannot say what the dcd's ångström are.
    let stderr = refused(&argv(
        "analyze systems/chain/scene.toml {} --blocks 2",
        &[DCD],
    ));
    assert!(
        stderr.contains(DCD) && stderr.contains("cannot tell its units"),
        "{stderr}"
    );
}

/// Write the frames of longstep's extended XYZ `xyz` to `path` (a `.trr` or `.nc`, by its
/// extension) through chemfiles, each frame's box kept and, when `times`, its time in ps
/// (`.trr`: GROMACS's unit; longstep's frames are in fs).
fn convert(xyz: &Path, path: &Path, times: bool) -> usize {
    let mut input = chemfiles::Trajectory::open(xyz, 'r').unwrap();
    let mut output = chemfiles::Trajectory::open(path, 'w').unwrap();
    let mut frame = chemfiles::Frame::new();
    for k in 0..input.nsteps() {
        input.read_step(k, &mut frame).unwrap();
        if times {
            let t = match frame.get("time") {
                Some(chemfiles::Property::Double(t)) => t,
                Some(chemfiles::Property::String(s)) => s.trim().parse().unwrap(),
                other => panic!("frame {k} has no time: {other:?}"),
            };
            frame.set("time", t / 1000.0);
        }
        output.write(&frame).unwrap();
    }
    input.nsteps()
}

#[test]
fn trr_and_nc_frames_give_the_energies_of_the_xyz_they_hold() {
    // A short run's extended-XYZ frames (t = 0, 4, …, 16 fs) written again as a GROMACS
    // .trr (nm, times in ps) and an AMBER .nc (Å, no times: --frame-time places them), and
    // all three analysed from t = 4 fs: the same four frames, and the same energies to the
    // files' float32 rounding. Each coordinate is rounded by at most 2⁻²⁴ of the largest
    // |q| (relative rounding of a float32; the .trr's nm scale by 10 is exact in the
    // relative sense up to one more rounding: 2⁻²³ bounds both), so a term's energy moves by
    // at most ‖∇E‖₁ · 2⁻²³ · max|q| per frame to first order (the second order, k·δ² ~ 1e-9
    // kcal/mol, is far below), and its mean over frames by the largest of those.
    let out = scratch_dir("analyze-peers-trr-nc");
    let dir = out.join("run");
    short_run(&dir);
    let xyz = dir.join("trajectory.xyz");
    let (trr, nc) = (out.join("run.trr"), out.join("run.nc"));
    assert_eq!(convert(&xyz, &trr, true), 5);
    assert_eq!(convert(&xyz, &nc, false), 5);
    let tables = out.join("analysis");
    let analyse = |file: &Path, extra: &[&str]| -> Json {
        let mut args = argv(
            "analyze {} {} --skip 4fs --blocks 2 --no-configurational --json --quiet --out {}",
            &[SCENE, file.to_str().unwrap(), tables.to_str().unwrap()],
        );
        args.extend(extra);
        analyze_json(&args)[0].clone()
    };
    let own = analyse(&xyz, &[]);
    let from_trr = analyse(&trr, &[]);
    let from_nc = analyse(&nc, &["--frame-time", "4fs"]);
    // The largest first-order change of each term over the analysed frames.
    let scene = scene_file(SCENE, &[]);
    let terms = scene.system.forces.terms();
    let mut reader = TrajectoryReader::open(&xyz).unwrap();
    let mut q = Vec::new();
    let mut shift = std::collections::HashMap::<String, f64>::new();
    while let Some(info) = reader.read_next(&mut q).unwrap() {
        if info.time.unwrap() < 4.0 - 1e-9 {
            continue;
        }
        let ulp = 2f64.powi(-23) * q.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        for t in terms {
            let mut g = vec![0.0; q.len()];
            t.term.add_gradient(&q, &mut g);
            let bound = g.iter().map(|x| x.abs()).sum::<f64>() * ulp;
            let entry = shift.entry(t.name.clone()).or_insert(0.0);
            *entry = entry.max(bound);
        }
    }
    for (label, other) in [("trr", &from_trr), ("nc", &from_nc)] {
        assert_eq!(other["frames"], 4, "{label}: {other}");
        assert_eq!(own["frames"], 4);
        // The .trr holds its times as float32 ps: equal to 2⁻²³ relative.
        for end in ["start", "end"] {
            let (a, b) = (other["span"][end].as_f64(), own["span"][end].as_f64());
            let (a, b) = (a.unwrap(), b.unwrap());
            assert!(
                (a - b).abs() <= 2f64.powi(-23) * b.abs(),
                "{label} {end}: {a} vs {b}"
            );
        }
        for name in ["bonds", "angles", "torsions", "pme-reciprocal", "lj-14"] {
            let mean = |summary: &Json| {
                let terms = summary["terms"].as_array().unwrap();
                let t = terms.iter().find(|t| t["term"] == name).unwrap();
                t["mean"].as_f64().unwrap()
            };
            let (ours, theirs) = (mean(&own), mean(other));
            let tolerance = shift[name];
            assert!(
                (ours - theirs).abs() <= tolerance,
                "{label} {name}: {theirs} vs the xyz's {ours} (tolerance {tolerance})"
            );
        }
    }
    // Without --frame-time the .nc's times are frame numbers: a --skip in fs cannot be
    // placed, and is refused.
    let (code, _, stderr) = run_cli(&argv(
        "analyze {} {} --skip 4fs --no-configurational --json --quiet",
        &[SCENE, nc.to_str().unwrap()],
    ));
    assert_ne!(code, 0);
    assert!(stderr.contains("--frame-time"), "{stderr}");
    // Every input is checked before any is read: with a reference that does not exist, the
    // refusal is still the .nc's clock (the reference, read first, would fail otherwise).
    let (code, _, stderr) = run_cli(&argv(
        "analyze {} {} --skip 4fs --reference {} --no-configurational --json --quiet",
        &[SCENE, nc.to_str().unwrap(), "no-such-reference-run"],
    ));
    assert_ne!(code, 0);
    assert!(stderr.contains("--frame-time"), "{stderr}");
}

#[test]
fn an_openmm_dcd_is_judged_against_a_longstep_run_directory() {
    // What scripts/production_peers.py --judge does with a peer's row: a trajectory file
    // (energies recomputed from its frames) against a longstep run directory (energies from
    // its energy.csv, kinetic temperature over its manifest's degrees of freedom). The .dcd
    // carries no times: --frame-time 50fs puts its 8 frames at t = 0, 50, …, 350 fs.
    let dir = scratch_dir("analyze-peers-dcd-vs-run");
    let reference = dir.join("reference");
    short_run(&reference);
    let out = dir.join("analysis");
    let args = argv(
        "analyze {} {} --reference {} --frame-time 50fs --temperature 300K --json --blocks 2 \
         --probes 1 --quiet --out {}",
        &[
            SCENE,
            DCD,
            reference.to_str().unwrap(),
            out.to_str().unwrap(),
        ],
    );
    let run = &analyze_json(&args)[0];
    assert_eq!(run["frames"], 8);
    assert_eq!(run["span"]["end"], 350.0);
    assert_eq!(run["energies_from"], "frames (recomputed)");
    let criteria = run["criteria"].as_array().unwrap();
    for name in [
        "potential energy per molecule",
        "configurational temperature",
        "mean bonds energy",
        "g O-O first-peak height",
    ] {
        let c = criteria.iter().find(|c| c["name"] == name).unwrap();
        assert!(
            ["pass", "fail", "undecided"].contains(&c["verdict"].as_str().unwrap()),
            "{c}"
        );
        assert!(c["difference"].as_f64().is_some_and(f64::is_finite), "{c}");
    }
    assert!(["pass", "fail", "undecided"].contains(&run["verdict"].as_str().unwrap()));
}

#[test]
fn two_reference_runs_are_pooled_and_each_is_a_control_against_the_other() {
    // The .xtc and the .dcd (given a clock) as two reference runs of one model: pooled,
    // each quantity's mean is the length-weighted mean of the two, and with two runs the
    // between-run error is √(w₁ w₂)·|x₁ − x₂| (docs/studies.md), the error the larger of
    // it and the within-run √(w₁² σ₁² + w₂² σ₂²). Each reference run is also judged
    // against the other (the leave-one-out control), which gives both runs' means.
    let out = scratch_dir("analyze-pooled-reference");
    let args = argv(
        "analyze {} {} --reference {} --reference {} --frame-time 50fs --no-configurational \
         --temperature 300K --blocks 4 --json --quiet --out {}",
        &[SCENE, XTC, XTC, DCD, out.to_str().unwrap()],
    );
    let summaries = analyze_json(&args);
    let summaries = summaries.as_array().unwrap();
    assert_eq!(summaries.len(), 3, "the run and two controls");
    let run = &summaries[0];
    assert_eq!(run["reference"], serde_json::json!([XTC, DCD]));
    let pool = &run["reference_pool"];
    let weights: Vec<f64> = pool["runs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["weight"].as_f64().unwrap())
        .collect();
    assert_eq!(weights.len(), 2);
    assert!((weights[0] + weights[1] - 1.0).abs() < 1e-12);
    // Control k is reference run k against the other: `value` is run k's mean.
    let controls: Vec<&Json> = summaries
        .iter()
        .filter(|s| s["role"] == "control")
        .collect();
    assert_eq!(controls.len(), 2);
    let mean_of = |summary: &Json, name: &str| {
        entry(&summary["criteria"], "name", name)["value"]
            .as_f64()
            .unwrap()
    };
    for name in ["mean bonds energy", "potential energy per molecule"] {
        let (x1, x2) = (mean_of(controls[0], name), mean_of(controls[1], name));
        let part = entry(&pool["parts"], "quantity", name);
        let mean = part["mean"].as_f64().unwrap();
        // Sums of a few numbers of size ~|x|: round-off ~1e-15 relative.
        let scale = x1.abs().max(x2.abs());
        assert!(
            (mean - (weights[0] * x1 + weights[1] * x2)).abs() < 1e-12 * scale,
            "{name}: {mean} from {x1}, {x2}"
        );
        let between = part["between_runs"].as_f64().unwrap();
        let expected = (weights[0] * weights[1]).sqrt() * (x1 - x2).abs();
        assert!(
            (between - expected).abs() < 1e-12 * scale,
            "{between} vs {expected}"
        );
        let (error, within) = (
            part["error"].as_f64().unwrap(),
            part["within_runs"].as_f64().unwrap(),
        );
        assert_eq!(error, within.max(between));
        // The run's criterion carries the pooled reference and its error.
        let criterion = entry(&run["criteria"], "name", name);
        assert!((criterion["reference"].as_f64().unwrap() - mean).abs() < 1e-12 * scale);
    }
}

#[test]
fn a_reference_on_another_clock_is_not_pooled() {
    // Without --frame-time the .dcd's times are frame numbers, the .xtc's picoseconds: the
    // two cannot be weighted by length together, and the refusal names the flag and both.
    let stderr = refused(&argv(
        "analyze {} {} --reference {} --reference {} --no-configurational --blocks 2 --quiet",
        &[SCENE, XTC, XTC, DCD],
    ));
    assert!(
        stderr.contains("--reference") && stderr.contains(DCD) && stderr.contains("time unit"),
        "{stderr}"
    );
}
