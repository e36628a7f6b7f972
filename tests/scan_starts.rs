//! `scan steps --starts N`: a point's drift is the mean over N seeded starts with the wider
//! of the two error bars, the same at any thread count; refused where the starts could not
//! differ. `--criterion sampling` on a peptide compares its backbone basin populations.

mod common;
use common::{argv, run_cli, scratch_dir, study_table as table, words};

use std::path::Path;

const ALA2: &str = "systems/alanine-dipeptide-amber/ala2.toml";

/// A short scan of the dipeptide in vacuum by velocity Verlet at 0.5 and 1 fs, 300 K starts.
fn scan(out: &Path, extra: &[&str], threads: Option<&str>) -> (Vec<String>, Vec<Vec<String>>) {
    let mut command = common::longstep();
    command.args(argv(
        "scan steps {} --method verlet --h 0.5fs,1fs --t-end 500fs --temperature 300K \
         --repeats 0 --quiet --out {}",
        &[ALA2, out.to_str().unwrap()],
    ));
    command.args(extra);
    if let Some(n) = threads {
        command.env("RAYON_NUM_THREADS", n);
    }
    let output = command.output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{extra:?}: {stderr}");
    table(&out.join("scan.csv"))
}

fn number(row: &[String], header: &[String], name: &str) -> f64 {
    // A real scene's header carries units (`drift[kT/ns/dof]`).
    let k = header
        .iter()
        .position(|h| h == name || h.starts_with(&format!("{name}[")))
        .unwrap();
    row[k].parse().unwrap_or_else(|_| panic!("{name}: {row:?}"))
}

#[test]
fn two_starts_are_the_mean_of_the_two_seeds() {
    let dir = scratch_dir("scan-starts");
    let (header, both) = scan(&dir.join("both"), &["--starts", "2", "--seed", "7"], None);
    let (_, first) = scan(&dir.join("seed7"), &["--seed", "7"], None);
    let (_, second) = scan(&dir.join("seed8"), &["--seed", "8"], None);
    assert_eq!(both.len(), 2);
    for (k, row) in both.iter().enumerate() {
        assert_eq!(number(row, &header, "starts"), 2.0);
        let (a, b) = (&first[k], &second[k]);
        assert_eq!(number(a, &header, "starts"), 1.0);
        let (da, db) = (number(a, &header, "drift"), number(b, &header, "drift"));
        // Two draws of 300 K velocities are different runs.
        assert_ne!(da, db, "{a:?} {b:?}");
        // The mean of the two, to the round-off of one sum and one division.
        let mean = 0.5 * (da + db);
        let drift = number(row, &header, "drift");
        assert!(
            (drift - mean).abs() <= 1e-12 * mean.abs().max(1e-300),
            "{drift} vs {mean}"
        );
        // The error: the larger of √(σa² + σb²)/2 and |da − db|/2 (the sample deviation
        // |da − db|/√2 over √2).
        let (ea, eb) = (
            number(a, &header, "drift_error"),
            number(b, &header, "drift_error"),
        );
        let expected = (ea.hypot(eb) / 2.0).max((da - db).abs() / 2.0);
        let error = number(row, &header, "drift_error");
        assert!(
            (error - expected).abs() <= 1e-12 * expected,
            "{error} vs {expected}"
        );
        let status = header.iter().position(|h| h == "status").unwrap();
        assert!(
            ["pass", "fail", "undecided", "unstable"].contains(&row[status].as_str()),
            "{row:?}"
        );
    }
    // The starts of every point run in parallel: one thread gives the same bits.
    let (_, serial) = scan(
        &dir.join("serial"),
        &["--starts", "2", "--seed", "7"],
        Some("1"),
    );
    assert_eq!(serial, both);
}

#[test]
fn starts_that_cannot_differ_are_refused() {
    let out = scratch_dir("scan-starts-refused");
    let out = out.to_str().unwrap();
    // (what the command adds to a 10 fs scan of ALA2, what the refusal must say)
    let cases: [(&[&str], &str); 3] = [
        // No temperature: every start would take the scene's own velocities.
        (
            &["--method", "verlet", "--starts", "2"],
            "--starts 2 needs start velocities",
        ),
        (
            &words("--method verlet --temperature 300K --starts 65"),
            "--starts must be between 1 and 64",
        ),
        // The sampling criterion judges one run per point.
        (
            &argv(
                "--method langevin-respa --temperature 300K --criterion sampling --reference {} \
                 --starts 2",
                &[out],
            ),
            "applies to the drift criterion",
        ),
    ];
    for (extra, message) in cases {
        let mut args = vec!["scan", "steps", ALA2, "--h", "1fs", "--t-end", "10fs"];
        args.extend_from_slice(extra);
        args.extend_from_slice(&["--repeats", "0", "--out", out]);
        let (code, _, stderr) = run_cli(&args);
        assert_ne!(code, 0, "{extra:?}");
        assert!(stderr.contains(message), "{extra:?}: {stderr}");
    }
}

#[test]
fn a_study_configuration_takes_its_own_starts() {
    let dir = scratch_dir("scan-starts-study");
    let study = dir.join("study.toml");
    std::fs::write(
        &study,
        "[[config]]\nlabel = \"one\"\nmethod = \"verlet\"\nh = [\"1fs\"]\n\
         temperature = \"300K\"\n\n[[config]]\nlabel = \"three\"\nmethod = \"verlet\"\n\
         h = [\"1fs\"]\ntemperature = \"300K\"\nstarts = 3\n",
    )
    .unwrap();
    let out = dir.join("out");
    let (code, _, stderr) = run_cli(&argv(
        "scan steps {} --study {} --t-end 100fs --repeats 0 --quiet --out {}",
        &[ALA2, study.to_str().unwrap(), out.to_str().unwrap()],
    ));
    assert_eq!(code, 0, "{stderr}");
    let (header, rows) = table(&out.join("scan.csv"));
    let starts: Vec<f64> = rows.iter().map(|r| number(r, &header, "starts")).collect();
    assert_eq!(starts, [1.0, 3.0]);
}

#[test]
fn the_sampling_criterion_compares_the_dipeptides_basins() {
    // The solvated dipeptide (one backbone residue, ALA2): a 0.4 ps Langevin reference and a
    // scan of the same method at 1 fs; strong friction (50/ps) brings the minimised start to
    // 300 K within the discarded 0.2 ps. The run is far too short to judge the basins (no
    // transition: an undecided verdict); what is checked is that they are compared.
    let dir = scratch_dir("scan-basins");
    let scene = "systems/alanine-dipeptide-amber/ala2-solvated-pme.toml";
    let reference = dir.join("reference");
    let (code, _, stderr) = run_cli(&argv(
        "run {} --method langevin-respa --inner 1 --h 1fs --friction 50/ps \
         --temperature 300K --trajectory-every 20 --t-end 0.4ps --out {}",
        &[scene, reference.to_str().unwrap()],
    ));
    assert_eq!(code, 0, "{stderr}");
    let out = dir.join("scan");
    let (code, _, stderr) = run_cli(&argv(
        "scan steps {} --method langevin-respa --inner 1 --friction 50/ps --h 1fs \
         --t-end 0.4ps --discard 0.2ps --temperature 300K --criterion sampling \
         --reference {} --frames 20 --blocks 4 --repeats 0 --out {}",
        &[scene, reference.to_str().unwrap(), out.to_str().unwrap()],
    ));
    assert_eq!(code, 0, "{stderr}");
    assert!(
        stderr.contains("notice: backbone basins: pooled over ALA2: reference C7eq/beta"),
        "{stderr}"
    );
    let (header, rows) = table(&out.join("scan.csv"));
    // The run repeats the reference's method, step, seed and frames (400 steps / 20 frames:
    // one every 20 steps): its populations are the reference's, Δp = 0 in every basin.
    for basin in ["C7eq_beta", "alphaR", "alphaL"] {
        let difference = number(&rows[0], &header, &format!("{basin}_difference"));
        assert_eq!(difference, 0.0, "{basin}: {rows:?}");
        let population = number(&rows[0], &header, &format!("{basin}_population"));
        assert!((0.0..=1.0).contains(&population), "{basin}: {rows:?}");
    }
}
