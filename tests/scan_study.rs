//! `longstep scan steps SCENE --study FILE`: configurations with their own outer steps and
//! run settings in one command give the rows of their separate scans; shards of a study
//! merge into the whole; bad study files are refused before any run.

mod common;
use common::run_cli as run;
use common::{argv, scratch_dir, study_table as table, words};

use std::path::{Path, PathBuf};

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Run `longstep`, which must succeed; returns stdout.
fn ok(args: &[&str]) -> String {
    let (code, stdout, stderr) = run(args);
    assert_eq!(code, 0, "{args:?}: {stderr}");
    stdout
}

/// Two configurations of impulse on the three-spring system that differ in their inner
/// steps (4 and 8) and their outer steps, with the length and bounds of `scan_args`.
const STUDY: &str = r#"
[[config]]
label = "coarse-inner"
method = "impulse"
h = [0.05, 0.1]
inner_steps = 4

[[config]]
label = "fine-inner"
method = "impulse"
h = "0.1:0.2:0.1"
inner_steps = 8
"#;

fn write_study(dir: &Path, text: &str) -> PathBuf {
    let file = dir.join("study.toml");
    std::fs::write(&file, text).unwrap();
    file
}

/// The shared flags of every scan here: short runs, no timings.
fn scan_args<'a>(out: &'a Path, extra: &[&'a str]) -> Vec<&'a str> {
    let mut args = argv(
        "scan steps systems/three-spring.toml --t-end 10 --repeats 0 --quiet --out {}",
        &[path(out)],
    );
    args.extend_from_slice(extra);
    args
}

#[test]
fn a_study_gives_the_rows_of_its_separate_scans() {
    let dir = scratch_dir("study-rows");
    let study = write_study(&dir, STUDY);
    let whole = dir.join("study");
    let stdout = ok(&scan_args(&whole, &["--study", path(&study)]));
    let (a, b) = (dir.join("a"), dir.join("b"));
    ok(&scan_args(
        &a,
        &["--method", "impulse", "--inner", "4", "--h", "0.05,0.1"],
    ));
    ok(&scan_args(
        &b,
        &["--method", "impulse", "--inner", "8", "--h", "0.1:0.2:0.1"],
    ));
    let (header, rows) = table(&whole.join("scan.csv"));
    let (single_header, _) = table(&a.join("scan.csv"));
    // The study's table is the single scan's with `config` after `index`.
    let mut expected_header = single_header.clone();
    expected_header.insert(1, "config".into());
    assert_eq!(header, expected_header);
    let mut expected = Vec::new();
    for (label, dir) in [("coarse-inner", &a), ("fine-inner", &b)] {
        for mut row in table(&dir.join("scan.csv")).1 {
            row.insert(1, label.to_string());
            expected.push(row);
        }
    }
    // Same runs, same settings: the same bits in every column (drift included) but the
    // index, which counts through the study's points.
    assert_eq!(rows.len(), 4);
    for (k, (row, want)) in rows.iter().zip(&expected).enumerate() {
        assert_eq!(row[0], k.to_string());
        assert_eq!(row[1..], want[1..], "point {k}");
    }
    // Each configuration's own settings reach its runs: at h = 0.1 the two inner steps
    // differ, and so do their drifts and fast-force counts.
    let drift = header.iter().position(|h| h == "drift").unwrap();
    let fast = header.iter().position(|h| h == "fast_evaluations").unwrap();
    assert_ne!(rows[1][drift], rows[2][drift]);
    assert_ne!(rows[1][fast], rows[2][fast]);
    // The summary has one line per configuration.
    assert!(stdout.starts_with("configuration"), "{stdout}");
    for label in ["coarse-inner", "fine-inner"] {
        assert_eq!(
            stdout.lines().filter(|l| l.starts_with(label)).count(),
            1,
            "{stdout}"
        );
    }
}

#[test]
fn study_shards_merge_into_the_whole_study() {
    let dir = scratch_dir("study-shards");
    let study = write_study(&dir, STUDY);
    let whole = dir.join("whole");
    ok(&scan_args(&whole, &["--study", path(&study)]));
    let shards: Vec<PathBuf> = (1..=3).map(|k| dir.join(format!("shard-{k}"))).collect();
    for (k, out) in shards.iter().enumerate() {
        let shard = format!("{}/3", k + 1);
        ok(&scan_args(
            out,
            &["--study", path(&study), "--shard", &shard],
        ));
        // Shard k holds the points k − 1, k + 2, … of the four.
        let (_, rows) = table(&out.join("scan.csv"));
        let indices: Vec<usize> = rows.iter().map(|r| r[0].parse().unwrap()).collect();
        let want: Vec<usize> = (0..4).filter(|i| i % 3 == k).collect();
        assert_eq!(indices, want);
    }
    let merged = dir.join("merged");
    ok(&[
        "merge",
        path(&shards[2]),
        path(&shards[0]),
        path(&shards[1]),
        "--out",
        path(&merged),
    ]);
    let read = |d: &Path| std::fs::read_to_string(d.join("scan.csv")).unwrap();
    assert_eq!(read(&merged), read(&whole));
}

#[test]
fn shards_of_different_studies_do_not_merge() {
    let dir = scratch_dir("study-shards-differ");
    let (a, b) = (dir.join("a"), dir.join("b"));
    // The same file, labels and command; between the shards the file changes one inner
    // step: only the fingerprint of its text tells the two studies apart.
    let study = write_study(&dir, STUDY);
    ok(&scan_args(&a, &["--study", path(&study), "--shard", "1/2"]));
    write_study(&dir, &STUDY.replace("inner_steps = 8", "inner_steps = 6"));
    ok(&scan_args(&b, &["--study", path(&study), "--shard", "2/2"]));
    let (code, _, stderr) = run(&["merge", path(&a), path(&b), "--out", path(&dir.join("m"))]);
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("study_fingerprint"), "{stderr}");
}

/// A study that must be refused with exit 1, naming the study file and each of `names`,
/// before any run: no scan.csv is written.
fn refused(name: &str, text: &str, names: &[&str]) {
    let dir = scratch_dir(&format!("study-bad-{name}"));
    let study = write_study(&dir, text);
    let out = dir.join("out");
    let (code, _, stderr) = run(&scan_args(&out, &["--study", path(&study)]));
    assert_eq!(code, 1, "{name}: {stderr}");
    assert!(stderr.contains("study.toml"), "{name}: {stderr}");
    for n in names {
        assert!(stderr.contains(n), "{name}: {n} not in {stderr}");
    }
    assert!(!out.join("scan.csv").exists(), "{name}: a run started");
}

#[test]
fn bad_studies_are_refused_by_file_configuration_and_key() {
    let one = |extra: &str| format!("[[config]]\nlabel = \"c1\"\n{extra}\n");
    refused(
        "unknown-key",
        &one("method = \"verlet\"\nh = [0.1]\ninner_stepz = 4"),
        &["\"c1\"", "`inner_stepz`"],
    );
    refused(
        "top-level-key",
        &format!("methods = 1\n{}", one("method = \"verlet\"\nh = [0.1]")),
        &["`methods`"],
    );
    refused("no-method", &one("h = [0.1]"), &["\"c1\"", "`method`"]);
    refused("no-h", &one("method = \"verlet\""), &["\"c1\"", "`h`"]);
    refused(
        "duplicate-label",
        &format!(
            "{}{}",
            one("method = \"verlet\"\nh = [0.1]"),
            one("method = \"verlet\"\nh = [0.1]")
        ),
        &["\"c1\"", "twice"],
    );
    // A value of the wrong type, refused by the [run] parser itself.
    refused(
        "run-type",
        &one("method = \"verlet\"\nh = [0.1]\ninner_steps = \"four\""),
        &["\"c1\"", "`inner_steps`"],
    );
    // A value [run] parses but the method's settings refuse: found when every point is
    // built, before the first run.
    refused(
        "run-value",
        &one("method = \"verlet\"\nh = [0.1]\nconstraints = \"some-bonds\""),
        &["\"c1\"", "some-bonds"],
    );
    refused(
        "unknown-method",
        &format!(
            "{}[[config]]\nlabel = \"c2\"\nmethod = \"no-such-method\"\nh = [0.1]\n",
            one("method = \"verlet\"\nh = [0.1]")
        ),
        &["\"c2\"", "no-such-method"],
    );
}

#[test]
fn a_study_refuses_the_single_scan_flags() {
    let dir = scratch_dir("study-flags");
    let study = write_study(&dir, STUDY);
    let out = dir.join("out");
    let (code, _, stderr) = run(&scan_args(
        &out,
        &["--study", path(&study), "--methods", "verlet"],
    ));
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("--methods"), "{stderr}");
}

#[test]
fn a_configurations_pme_levels_reach_a_topology_scene() {
    // The dipeptide's PME scene reads a [topology]: `nonbonded_level = 0, pme_level = 1`
    // must give the rows of the single scan with --nonbonded-level 0 --pme-level 1, and
    // differ from the default levels (real space slow): the real-space term moves to the
    // fast level, so each outer step evaluates it at every inner step.
    let dir = scratch_dir("study-pme-levels");
    let study = write_study(
        &dir,
        r#"
[[config]]
label = "default-levels"
method = "impulse"
h = ["1fs"]
dt = "0.5fs"

[[config]]
label = "reciprocal-slow"
method = "impulse"
h = ["1fs"]
dt = "0.5fs"
nonbonded_level = 0
pme_level = 1
"#,
    );
    let scene = "systems/alanine-dipeptide-amber/ala2-solvated-pme.toml";
    let scan = |out: &Path, extra: &[&str]| {
        let mut args = argv(
            "scan steps {} --t-end 2fs --repeats 0 --quiet --out",
            &[scene],
        );
        args.push(path(out));
        args.extend_from_slice(extra);
        ok(&args);
    };
    let (whole, single) = (dir.join("study"), dir.join("single"));
    scan(&whole, &["--study", path(&study)]);
    scan(
        &single,
        &words("--method impulse --h 1fs --dt 0.5fs --nonbonded-level 0 --pme-level 1"),
    );
    let (header, rows) = table(&whole.join("scan.csv"));
    let (_, single_rows) = table(&single.join("scan.csv"));
    assert_eq!(rows[1][2..], single_rows[0][1..]);
    // A real scene's header carries the unit: `drift[kT/ns/dof]`.
    let drift = header
        .iter()
        .position(|h| h == "drift" || h.starts_with("drift["))
        .unwrap();
    assert_ne!(rows[0][drift], rows[1][drift]);
}

#[test]
fn the_shipped_dipeptide_studies_read_and_the_nve_one_runs() {
    // Both shipped study files parse with the configurations docs/studies.md lists.
    let labels = |file: &str| -> Vec<String> {
        longstep::io::study_file::read_study(Path::new(file))
            .unwrap_or_else(|e| panic!("{file}: {e}"))
            .configs
            .into_iter()
            .map(|c| c.label)
            .collect()
    };
    assert_eq!(labels("studies/ala2-production-nve.toml").len(), 8);
    assert_eq!(labels("studies/ala2-production-sampling.toml").len(), 3);
    // The NVE study builds and runs every point end to end (20 fs runs: a smoke test of
    // the pipeline, not a verdict): 2 + 3 + 3 + 4 + 4 + 3 + 3 + 3 points.
    let out = scratch_dir("study-ala2-nve");
    ok(&argv(
        "scan steps systems/alanine-dipeptide-amber/ala2-solvated-pme.toml \
         --study studies/ala2-production-nve.toml --t-end 20fs --repeats 0 --quiet \
         --out {}",
        &[path(&out)],
    ));
    let (_, rows) = table(&out.join("scan.csv"));
    assert_eq!(rows.len(), 25);
    let mut seen: Vec<&str> = rows.iter().map(|r| r[1].as_str()).collect();
    seen.dedup();
    assert_eq!(seen, labels("studies/ala2-production-nve.toml"));
}

#[test]
fn the_sampling_criterion_counts_a_constrained_models_degrees_of_freedom() {
    // 216 rigid waters (SETTLE: 3 constraints each) leave 3·648 − 648 = 1296 degrees of
    // freedom for the kinetic temperature; the flexible model keeps the analyzer's 3N.
    use longstep::settings::RunSpec;
    use longstep::studies::scan::ScanSetup;
    use longstep::studies::scan::constrained_dof;
    let setup = |rigid: Option<bool>| ScanSetup {
        scene: PathBuf::from("systems/water-box/scene.toml"),
        base: RunSpec {
            rigid_water: rigid,
            inner_steps: Some(4),
            temperature: Some("300K".parse().unwrap()),
            ..Default::default()
        },
        t_end: 4.0,
        energy_every: 1,
        ..Default::default()
    };
    let rigid = constrained_dof(&setup(Some(true)), "langevin-respa", 2.0).unwrap();
    assert_eq!(rigid, Some(1296.0));
    let flexible = constrained_dof(&setup(None), "langevin-respa", 2.0).unwrap();
    assert_eq!(flexible, None);
}
