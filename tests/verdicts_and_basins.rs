//! The three-way verdict on synthetic series of known mean and error, and the backbone
//! basins of a short shipped alanine-dipeptide trajectory against a count by hand.

mod common;
use common::{argv, words};

use std::path::Path;

use longstep::analysis::block_average::from_block_means;
use longstep::analysis::dihedrals::{backbone_residues, scene_topology};
use longstep::analysis::run_analysis::{AnalysisOptions, Analyzer, RunFiles};
use longstep::io::scene::load_scene;
use longstep::run::drift::{DriftFit, judge};
use longstep::run::verdict::{self, MEAN_EXPONENT, Measurement, Verdict};
use longstep::units::Units;
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use rand_distr::StandardNormal;

/// A series of `blocks × per_block` samples whose block means are exactly `mean ± step`
/// (alternating), with a zero-mean oscillation inside each block: its mean is `mean` and the
/// standard error of its block means is `step/√(blocks − 1)`, both exact.
fn exact_series(mean: f64, step: f64, blocks: usize, per_block: usize) -> Vec<f64> {
    (0..blocks * per_block)
        .map(|i| {
            let (b, k) = (i / per_block, i % per_block);
            let sign = if b % 2 == 0 { 1.0 } else { -1.0 };
            let phase = 2.0 * std::f64::consts::PI * k as f64 / per_block as f64;
            mean + sign * step + 0.3 * phase.sin()
        })
        .collect()
}

fn block_means(series: &[f64], blocks: usize) -> Vec<f64> {
    let per = series.len() / blocks;
    series
        .chunks(per)
        .map(|c| c.iter().sum::<f64>() / c.len() as f64)
        .collect()
}

fn measured(series: &[f64], blocks: usize, span: f64) -> Measurement {
    let e = from_block_means(&block_means(series, blocks));
    Measurement {
        value: e.mean,
        error: e.error,
        fixed_error: 0.0,
        start: 0.0,
        span,
        exponent: MEAN_EXPONENT,
    }
}

#[test]
fn the_verdict_on_series_of_known_mean_and_error() {
    // 10 blocks, block means ±0.03 about the mean: error 0.03/3 = 0.01 exactly (to
    // round-off of the sums, ~1e-15), so the 2σ interval is mean ± 0.02. Bound 0.05.
    let error = 0.03 / 3.0;
    for (mean, expected) in [
        (0.01, "pass"),      // [−0.01, 0.03] within ±0.05
        (-0.2, "fail"),      // [−0.22, −0.18] wholly beyond −0.05
        (0.04, "undecided"), // [0.02, 0.06] straddles 0.05
    ] {
        let m = measured(&exact_series(mean, 0.03, 10, 50), 10, 100.0);
        assert!((m.value - mean).abs() < 1e-12 && (m.error - error).abs() < 1e-12);
        assert_eq!(verdict::judge(&m, 0.05).name(), expected, "{m:?}");
    }
    // The undecided one: the gap 0.01 is 2σ at σ = 0.005, half the error: with σ ∝ 1/√T
    // a run four times as long, 400.
    let m = measured(&exact_series(0.04, 0.03, 10, 50), 10, 100.0);
    let Verdict::Undecided { decide_at: Some(t) } = verdict::judge(&m, 0.05) else {
        panic!("{m:?}");
    };
    assert!((t - 400.0).abs() < 1e-6, "{t}");
    assert_eq!(
        verdict::judge(&m, 0.05).text(Units::Real),
        "undecided: a run of ~400 fs would decide"
    );

    // Random series: 10⁴ independent normal samples of deviation 1 about μ (seeded), so the
    // standard error is 0.01 and the estimate of it from 20 blocks is within ±40 % (five
    // times its own relative error 1/√(2·19)) for any seed. Bound 0.1: μ = 0 passes
    // (|x| + 2σ ≤ 5·0.01 + 2·0.014 < 0.1) and μ = 0.3 fails (0.3 − 0.05 − 0.028 > 0.1), with
    // the sample mean within five standard errors of μ.
    let mut rng = StdRng::seed_from_u64(29);
    for (mu, expected) in [(0.0, Verdict::Pass), (0.3, Verdict::Fail)] {
        let series: Vec<f64> = (0..10_000)
            .map(|_| mu + rng.sample::<f64, _>(StandardNormal))
            .collect();
        let m = measured(&series, 20, 1.0);
        assert!((m.error - 0.01).abs() < 0.004, "{m:?}");
        assert_eq!(verdict::judge(&m, 0.1), expected, "{m:?}");
    }
}

#[test]
fn a_drift_is_judged_by_its_slope_and_the_energys_fluctuation() {
    // E = slope·t + A sin(ωt) over 0–20 ps, K = 1 kcal/mol: the rate in kT/ns/dof is
    // slope/(2K) per fs × 1e6. The error is the residual rms (A/√2, the oscillation's) over
    // the span, converted alike: 0.3/√2/2e4/2 × 1e6 ≈ 5.3 kT/ns/dof.
    let fit = |slope: f64, amplitude: f64| {
        let mut f = DriftFit::default();
        for i in 0..=20_000 {
            let t = i as f64;
            f.add(t, 1.0, slope * t + amplitude * (0.37 * t).sin(), None);
        }
        f.result(None, 20_000.0).unwrap()
    };
    let rate = |slope: f64| slope / 2.0 * 1e6;
    // No oscillation: an exact line; 0.02 kT/ns/dof passes the bound 0.05, 0.2 fails.
    assert_eq!(judge(&fit(4e-8, 0.0), Units::Real, None).verdict, "pass");
    let heating = judge(&fit(4e-7, 0.0), Units::Real, None);
    assert_eq!(heating.verdict, "fail");
    assert!((heating.value - rate(4e-7)).abs() < 1e-9);
    // The same slopes under a ±0.3 kcal/mol oscillation: error ≈ 5.3, both undecided, and
    // the run that would decide is T · 2σ/|value − bound| (σ ∝ 1/T).
    let noisy = judge(&fit(4e-7, 0.3), Units::Real, None);
    let expected_error = 0.3 / 2f64.sqrt() / 20_000.0 / 2.0 * 1e6;
    assert!(
        (noisy.error / expected_error - 1.0).abs() < 0.01,
        "{noisy:?}"
    );
    assert_eq!(noisy.verdict, "undecided", "{noisy:?}");
    let expected = 20_000.0 * 2.0 * noisy.error / (noisy.value.abs() - 0.05).abs();
    let at = noisy.decide_at.unwrap();
    assert!((at - expected).abs() < 1e-9 * expected, "{noisy:?}");
}

/// Positions per frame and each frame's time from an extended XYZ file.
fn read_xyz(path: &Path) -> Vec<(f64, Vec<[f64; 3]>)> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let mut frames = Vec::new();
    while let Some(count) = lines.next() {
        let n: usize = count.trim().parse().unwrap();
        let comment = lines.next().unwrap();
        let time = comment
            .split_whitespace()
            .find_map(|w| w.strip_prefix("time="))
            .unwrap()
            .parse()
            .unwrap();
        let atoms = (0..n)
            .map(|_| {
                let w: Vec<f64> = lines
                    .next()
                    .unwrap()
                    .split_whitespace()
                    .skip(1)
                    .map(|x| x.parse().unwrap())
                    .collect();
                [w[0], w[1], w[2]]
            })
            .collect();
        frames.push((time, atoms));
    }
    frames
}

/// The dihedral angle in degrees by the Blondel–Karplus formula,
/// `atan2(|b₂| b₁·(b₂×b₃), (b₁×b₂)·(b₂×b₃))`, `bᵢ` the bond vectors along the chain.
fn dihedral(p: [[f64; 3]; 4]) -> f64 {
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let (b1, b2, b3) = (sub(p[1], p[0]), sub(p[2], p[1]), sub(p[3], p[2]));
    let y = dot(b2, b2).sqrt() * dot(b1, cross(b2, b3));
    let x = dot(cross(b1, b2), cross(b2, b3));
    y.atan2(x).to_degrees()
}

#[test]
fn backbone_basins_of_a_shipped_trajectory_match_a_count_by_hand() {
    // tests/data/ala2-basins: 200 ps of the vacuum alanine dipeptide at 1000 K (hot, so that
    // 21 frames, one every 10 ps, visit all three basins; README.md there has the command).
    let scene_path = Path::new("systems/alanine-dipeptide-amber/ala2.toml");
    let scene = load_scene(scene_path, &[]).unwrap();
    let topology = scene_topology(scene_path)
        .unwrap()
        .expect("a [topology] scene");
    let residues = backbone_residues(&topology);
    // ala2.prmtop's atoms: ACE (H1 CH3 H2 H3 C O), ALA (N H CA HA CB HB1 HB2 HB3 C O),
    // NME (N H C H1 H2 H3): φ = C(4)–N(6)–CA(8)–C(14), ψ = N(6)–CA(8)–C(14)–N(16).
    assert_eq!(residues.len(), 1, "{residues:?}");
    assert_eq!(residues[0].label, "ALA2");
    assert_eq!(
        (residues[0].phi, residues[0].psi),
        ([4, 6, 8, 14], [6, 8, 14, 16])
    );

    let blocks = 4;
    let options = AnalysisOptions {
        pairs: Vec::new(),
        intramolecular: false,
        skip: 0.0,
        until: None,
        blocks,
        bin_width: 0.02,
        r_max: None,
        peak_window: 0.25,
        peak_fit: 0.1,
        probes: 1,
        seed: 1,
        configurational: false,
        dof: None,
        kinetic_column: "kinetic".into(),
        stride: 1,
    };
    let mut analyzer = Analyzer::new(&scene, options).unwrap();
    analyzer.set_backbone(residues);
    let dir = Path::new("tests/data/ala2-basins");
    let result = analyzer
        .analyze(&RunFiles {
            energy: dir.join("energy.csv"),
            trajectory: dir.join("trajectory.xyz"),
            dof: None,
        })
        .unwrap();

    // By hand: each frame's (φ, ψ), its basin by the boxes of src/analysis/dihedrals.rs
    // (φ ≥ 0: αL; else αR for −120° ≤ ψ < 50°; else C7eq/β), and its block over the energy
    // rows' span 0–200 ps cut in 4 (a frame at the end belongs to the last block).
    let frames = read_xyz(&dir.join("trajectory.xyz"));
    assert_eq!(frames.len(), 21);
    let mut counts = vec![[0.0f64; 3]; blocks];
    let mut per_block = vec![0.0f64; blocks];
    let (mut previous, mut changes) = (None, 0usize);
    for (t, q) in &frames {
        let phi = dihedral([q[4], q[6], q[8], q[14]]);
        let psi = dihedral([q[6], q[8], q[14], q[16]]);
        let basin = if phi >= 0.0 {
            2
        } else if (-120.0..50.0).contains(&psi) {
            1
        } else {
            0
        };
        // A change of basin is counted between cores: the boxes less a 30° band along
        // every edge (φ = 0, ±180°; ψ = −120°, 50° for φ < 0), angles around the circle.
        let far = |a: f64, edge: f64| {
            let d = (a - edge).rem_euclid(360.0);
            d.min(360.0 - d) >= 30.0
        };
        let in_core = far(phi, 0.0)
            && far(phi, 180.0)
            && (basin == 2 || (far(psi, -120.0) && far(psi, 50.0)));
        if in_core {
            changes += usize::from(previous.is_some_and(|b| b != basin));
            previous = Some(basin);
        }
        let block = ((t / 50_000.0).floor() as usize).min(blocks - 1);
        counts[block][basin] += 1.0;
        per_block[block] += 1.0;
    }
    let b = &result.basins;
    assert_eq!((b.len(), b[0].frames), (1, 21));
    for k in 0..3 {
        let total: f64 = counts.iter().map(|c| c[k]).sum();
        // Every basin is visited: the test checks a partition, not one box.
        assert!(total > 0.0, "basin {k} empty: {counts:?}");
        let fractions: Vec<f64> = (0..blocks).map(|i| counts[i][k] / per_block[i]).collect();
        // The block error, but never below the floor from the count of core changes n:
        // 2 p̃(1 − p̃)/√(n + 1) with p̃ = (n p + 1/2)/(n + 1) (src/analysis/dihedrals.rs).
        let n = changes as f64;
        let shrunk = (n * total / 21.0 + 0.5) / (n + 1.0);
        let floor = 2.0 * shrunk * (1.0 - shrunk) / (n + 1.0).sqrt();
        let error = from_block_means(&fractions).error.max(floor);
        let p = &b[0].populations[k];
        // Sums of at most 21 ones and zeros: exact but for the last bit of a division.
        assert!((p.mean - total / 21.0).abs() < 1e-12, "basin {k}: {p:?}");
        assert!(
            (p.error - error).abs() < 1e-12,
            "basin {k}: {p:?} vs {error}"
        );
    }
    // The histogram holds every frame once.
    let sum: f64 = b[0].histogram.iter().sum();
    assert!((sum - 1.0).abs() < 1e-12);
}

#[test]
fn analyze_prints_and_writes_the_basins() {
    let out = common::scratch_dir("analyze-basins");
    let (code, stdout, stderr) = common::run_cli(&argv(
        "analyze systems/alanine-dipeptide-amber/ala2.toml tests/data/ala2-basins \
         --blocks 4 --out {}",
        &[out.to_str().unwrap()],
    ));
    assert_eq!(code, 0, "{stderr}");
    assert!(stdout.contains("basins ALA2"), "{stdout}");
    // The label is the run directory's name.
    let table = std::fs::read_to_string(out.join("ala2-basins/basins.csv")).unwrap();
    let rows: Vec<&str> = table.lines().collect();
    assert!(
        rows.len() == 4 && rows[0] == "residue,basin,population,error,frames",
        "{table}"
    );
    let total: f64 = rows[1..]
        .iter()
        .map(|r| r.split(',').nth(2).unwrap().parse::<f64>().unwrap())
        .sum();
    assert!((total - 1.0).abs() < 1e-12, "{table}");
}

#[test]
fn scan_steps_says_how_long_a_run_would_decide_and_runs_it_until_decided() {
    // Impulse on the three-spring system at h = 0.2 over 20 time units: its drift, about
    // 2e-5 ± 5e-4 kT per unit time per dof, leaves a 2σ interval reaching past the default
    // bound 1e-3 (undecided), and the interval would clear the bound at a run of about 20.3
    // (the error falls as 1/T). With --until-decided 4 the point runs again at 40 (twice the
    // steps), which decides it.
    let scan = |name: &str, extra: &[&str]| {
        let dir = common::scratch_dir(name);
        let mut args = argv(
            "scan steps systems/three-spring.toml --methods impulse --h 0.2 --inner 10 \
             --t-end 20 --repeats 0 --out {}",
            &[dir.to_str().unwrap()],
        );
        args.extend(extra);
        let (code, _, stderr) = common::run_cli(&args);
        assert_eq!(code, 0, "{stderr}");
        let (header, rows) = common::study_table(&dir.join("scan.csv"));
        (header, rows, stderr)
    };
    let (header, short, stderr) = scan("scan-undecided", &[]);
    // The columns by name, from the table's own header.
    let header_of = |name: &str| -> usize { header.iter().position(|c| c == name).unwrap() };
    let (status, steps, decide_at) = (
        header_of("status"),
        header_of("steps"),
        header_of("decide_at"),
    );
    assert_eq!(short[0][status], "undecided", "{short:?}");
    let at: f64 = short[0][decide_at].parse().unwrap();
    assert!(at > 20.0 && at < 40.0, "{short:?}");
    assert!(
        stderr.contains("impulse at h = 0.2 (a run of 20): undecided: a run of ~"),
        "{stderr}"
    );
    let (_, long, _) = scan("scan-until-decided", &["--until-decided", "4"]);
    assert_ne!(long[0][status], "undecided", "{long:?}");
    let (n_short, n_long): (u64, u64) = (
        short[0][steps].parse().unwrap(),
        long[0][steps].parse().unwrap(),
    );
    assert_eq!(n_long, 2 * n_short, "{long:?}");
    // A factor outside [1, 64] is refused.
    let (code, _, stderr) = common::run_cli(&words(
        "scan steps systems/three-spring.toml --methods impulse --h 0.2 --t-end 20 \
         --until-decided 0.5",
    ));
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("--until-decided"), "{stderr}");
}
