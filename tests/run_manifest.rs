//! A run folder holds one run: `run` refuses (or with `--force` clears) an earlier run's
//! outputs, writes `manifest.json`, and `analyze` refuses an energy table and a trajectory
//! from different runs (issue 30 item 1).

mod common;
use common::{argv, run_cli, scratch_dir};

use std::path::Path;

const SPRINGS: &str = "systems/three-spring.toml";
const WATER: &str = "systems/water-box/scene.toml";

/// A short three-spring run into `out`, with `extra` flags.
fn springs(out: &Path, extra: &[&str]) -> (i32, String) {
    let mut args = vec!["run", SPRINGS, "--t-end", "1", "--quiet"];
    args.extend_from_slice(extra);
    args.extend(["--out", out.to_str().unwrap()]);
    let (code, _, stderr) = run_cli(&args);
    (code, stderr)
}

/// A water-box run of `t_end` into `out` with a row and a frame every step.
fn water(out: &Path, t_end: &str) {
    common::water_run(out, t_end);
}

fn manifest(dir: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(dir.join("manifest.json")).expect("manifest.json");
    serde_json::from_str(&text).expect("manifest.json is JSON")
}

fn listed(manifest: &serde_json::Value) -> Vec<String> {
    manifest["files"]
        .as_array()
        .expect("a list of files")
        .iter()
        .map(|f| f["name"].as_str().unwrap().to_string())
        .collect()
}

#[test]
fn a_second_run_into_a_used_folder_is_refused_naming_the_stale_files() {
    let out = scratch_dir("manifest-refused");
    let (code, stderr) = springs(&out, &["--trajectory-every", "1"]);
    assert_eq!(code, 0, "{stderr}");
    let first = std::fs::read(out.join("energy.csv")).unwrap();
    // Without a trajectory this run would leave the first one's trajectory.xyz beside its
    // own energy.csv: it is refused before it writes anything.
    let (code, stderr) = springs(&out, &[]);
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("earlier run")
            && stderr.contains("trajectory.xyz")
            && stderr.contains("energy.csv")
            && stderr.contains("--force"),
        "{stderr}"
    );
    assert_eq!(std::fs::read(out.join("energy.csv")).unwrap(), first);
}

#[test]
fn force_removes_exactly_the_earlier_runs_files() {
    let out = scratch_dir("manifest-force");
    let (code, stderr) = springs(&out, &["--trajectory-every", "1"]);
    assert_eq!(code, 0, "{stderr}");
    let first_id = manifest(&out)["run_id"].as_str().unwrap().to_string();
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    let (code, stderr) = springs(&out, &["--force"]);
    assert_eq!(code, 0, "{stderr}");
    assert!(
        stderr.contains("removed") && stderr.contains("trajectory.xyz"),
        "{stderr}"
    );
    assert!(
        !out.join("trajectory.xyz").exists(),
        "stale trajectory kept"
    );
    assert!(out.join("energy.csv").is_file());
    // A file longstep did not write stays.
    assert_eq!(
        std::fs::read_to_string(out.join("notes.txt")).unwrap(),
        "mine"
    );
    let second = manifest(&out);
    assert_eq!(listed(&second), ["energy.csv"]);
    assert_ne!(second["run_id"].as_str().unwrap(), first_id);
}

#[test]
fn analyze_refuses_a_trajectory_and_energy_table_of_different_runs() {
    let a = scratch_dir("manifest-run-a");
    let b = scratch_dir("manifest-run-b");
    // Two runs of different lengths: their trajectories differ (the same run twice would
    // write the same bytes, which analyze rightly takes).
    water(&a, "20fs");
    water(&b, "24fs");
    // Run B's energy table beside run A's trajectory, under B's name and under another.
    std::fs::copy(a.join("trajectory.xyz"), b.join("from-a.xyz")).unwrap();
    let (code, _, stderr) = run_cli(&argv(
        "analyze {} {} --blocks 2 --trajectory from-a.xyz",
        &[WATER, b.to_str().unwrap()],
    ));
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("energy.csv and from-a.xyz do not come from the same run"),
        "{stderr}"
    );
    std::fs::copy(a.join("trajectory.xyz"), b.join("trajectory.xyz")).unwrap();
    let (code, _, stderr) = run_cli(&["analyze", WATER, b.to_str().unwrap(), "--blocks", "2"]);
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("energy.csv and trajectory.xyz do not come from the same run"),
        "{stderr}"
    );
}

#[test]
fn a_run_lists_its_files_and_analyze_takes_them() {
    let out = scratch_dir("manifest-normal");
    water(&out, "20fs");
    let record = manifest(&out);
    assert_eq!(listed(&record), ["energy.csv", "trajectory.xyz"]);
    let id = record["run_id"].as_str().unwrap();
    assert!(
        id.len() == 16 && id.chars().all(|c| c.is_ascii_hexdigit()),
        "{id}"
    );
    assert_eq!(record["command"][1], "run");
    assert!(record["finished"].is_string());
    for file in record["files"].as_array().unwrap() {
        let name = file["name"].as_str().unwrap();
        let size = std::fs::metadata(out.join(name)).unwrap().len();
        assert_eq!(file["bytes"].as_u64(), Some(size), "{name}");
    }
    let (code, stdout, stderr) = run_cli(&argv(
        "analyze {} {} --blocks 2 --no-configurational",
        &[WATER, out.to_str().unwrap()],
    ));
    assert_eq!(code, 0, "{stderr}");
    assert!(stdout.contains("11 frames"), "{stdout}");
}
