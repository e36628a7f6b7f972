//! `minimize`, `modes`, `chart work-precision`, `scan steps` and `analyze` take a topology
//! in place of a scene (each goes through `run::prepare`), and the commands that run
//! dynamics or modes take `--start`.

mod common;
use common::argv;

use std::path::PathBuf;

fn ala2(file: &str) -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("systems/alanine-dipeptide-amber")
        .join(file)
        .display()
        .to_string()
}

fn ok(args: &[&str]) -> String {
    let (code, stdout, stderr) = common::run_cli(args);
    assert_eq!(code, 0, "{args:?}: {stderr}");
    stdout
}

/// The energies `E a kcal/mol -> b kcal/mol` of a minimisation report (the number before
/// its unit).
fn energies(report: &str) -> (f64, f64) {
    let line = report
        .lines()
        .find(|l| l.contains(" -> "))
        .expect("E a -> b");
    let after_e = line.split(" E ").nth(1).expect("E");
    let mut parts = after_e.split(" -> ");
    let number = |part: &str| -> f64 { part.split_whitespace().next().unwrap().parse().unwrap() };
    let a = number(parts.next().unwrap());
    let b = number(parts.next().unwrap().split(',').next().unwrap());
    (a, b)
}

#[test]
fn minimize_and_modes_read_a_topology_and_modes_start_where_told() {
    let dir = common::scratch_dir("topology-commands-modes");
    let saved = dir.join("min.xyz").display().to_string();
    let prmtop = ala2("ala2.prmtop");
    let report = ok(&argv(
        "minimize {} --max-iterations 300 --save {}",
        &[&prmtop, &saved],
    ));
    let (before, after) = energies(&report);
    assert!(after < before, "{report}");
    let at_file = ok(&["modes", &prmtop, "--json"]);
    let at_minimum = ok(&["modes", &prmtop, "--json", "--start", &saved]);
    let modes = |json: &str| -> Vec<f64> {
        let value: serde_json::Value = serde_json::from_str(json).unwrap();
        value["modes"]
            .as_array()
            .unwrap()
            .iter()
            .map(|m| m["frequency"].as_f64().unwrap())
            .collect()
    };
    let (a, b) = (modes(&at_file), modes(&at_minimum));
    assert_eq!(a.len(), b.len());
    assert!(!a.is_empty());
    // The modes are of the minimised geometry, not the file's.
    assert_ne!(a, b);
}

#[test]
fn work_precision_and_scan_steps_run_on_a_topology_from_a_start() {
    let dir = common::scratch_dir("topology-commands-studies");
    let prmtop = ala2("ala2.prmtop");
    let saved = dir.join("min.xyz").display().to_string();
    ok(&argv(
        "minimize {} --max-iterations 100 --save {}",
        &[&prmtop, &saved],
    ));
    let chart = dir.join("wp").display().to_string();
    ok(&argv(
        "chart work-precision {} --methods verlet,impulse --h-list 1fs,2fs --t-end 20fs \
         --inner 4 --out {} --quiet --start {}",
        &[&prmtop, &chart, &saved],
    ));
    let table = std::fs::read_to_string(dir.join("wp/work-precision.csv")).unwrap();
    let rows = table.lines().filter(|l| l.starts_with(char::is_numeric));
    assert_eq!(rows.count(), 4, "{table}");
    let scan = dir.join("scan").display().to_string();
    ok(&argv(
        "scan steps {} --methods verlet --h 0.5fs,1fs --t-end 50fs --repeats 0 --out {} \
         --quiet --start {}",
        &[&prmtop, &scan, &saved],
    ));
    // A start of another system is refused, naming the flag.
    let water = common::run_cli(&[
        "scan",
        "steps",
        &prmtop,
        "--methods",
        "verlet",
        "--h",
        "1fs",
        "--t-end",
        "10fs",
        "--repeats",
        "0",
        "--out",
        &scan,
        "--quiet",
        "--start",
        &format!(
            "{}/systems/molecules/butane.xyz",
            env!("CARGO_MANIFEST_DIR")
        ),
    ]);
    assert_eq!(water.0, 1, "{}", water.2);
    assert!(water.2.contains("--start"), "{}", water.2);
}

#[test]
fn analyze_reads_the_topology_its_run_was_made_from() {
    let dir = common::scratch_dir("topology-commands-analyze");
    let prmtop = ala2("ala2.prmtop");
    let out = dir.join("run").display().to_string();
    ok(&argv(
        "run {} --method verlet --h 0.5fs --t-end 100fs --trajectory-every 10 --out {} \
         --quiet",
        &[&prmtop, &out],
    ));
    let json = ok(&argv(
        "analyze {} {} --json --no-configurational --blocks 2",
        &[&prmtop, &out],
    ));
    let value: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert!(value.as_array().is_some_and(|a| a.len() == 1), "{json}");
}

/// `minimize --save` writes every coordinate in full precision: the forces at the saved
/// positions are the minimiser's last, within its tolerance (with 6 significant digits
/// the largest was 4.5e-3 kcal/mol/Å, issue 30 item 2).
#[test]
fn a_saved_minimum_is_the_minimum_the_summary_reported() {
    let dir = common::scratch_dir("topology-commands-saved-minimum");
    let prmtop = ala2("ala2.prmtop");
    let saved = dir.join("min.xyz").display().to_string();
    let forces = dir.join("forces.csv").display().to_string();
    let tolerance = 1e-6;
    let report = ok(&["minimize", &prmtop, "--tolerance", "1e-6", "--save", &saved]);
    assert!(!report.contains("not converged"), "{report}");
    ok(&["forces", &prmtop, "--positions", &saved, "--out", &forces]);
    let table = std::fs::read_to_string(&forces).unwrap();
    let largest = table
        .lines()
        .skip(1)
        .flat_map(|l| {
            l.split(',')
                .skip(2)
                .map(|x| x.parse::<f64>().unwrap().abs())
        })
        .fold(0.0, f64::max);
    // The same doubles give the same forces: the minimiser stopped below its tolerance.
    assert!(
        largest < tolerance,
        "largest force {largest} at the saved minimum"
    );
}
