//! `--velocities FILE` (and `[topology] velocities`): a topology's start velocities from a
//! restart file other than its coordinates.

mod common;

use std::path::{Path, PathBuf};

use longstep::io::scene::{SceneFlags, load_scene_with};
use longstep::io::topology::inpcrd::VELOCITY_TO_ANGSTROM_PER_FS;

fn system(file: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("systems/alanine-dipeptide-amber")
        .join(file)
}

/// A restart of the vacuum dipeptide: its coordinates, then a velocity block whose value
/// for coordinate k is `velocity(k)` in AMBER's unit (Å per 1/20.455 ps).
fn restart_with_velocities(dir: &Path, velocity: impl Fn(usize) -> f64) -> PathBuf {
    let inpcrd = std::fs::read_to_string(system("ala2.inpcrd")).unwrap();
    let mut lines: Vec<String> = inpcrd.lines().map(String::from).collect();
    let n_atoms: usize = lines[1].split_whitespace().next().unwrap().parse().unwrap();
    let values: Vec<f64> = (0..3 * n_atoms).map(velocity).collect();
    for row in values.chunks(6) {
        lines.push(row.iter().map(|v| format!("{v:12.7}")).collect());
    }
    let path = dir.join("ala2-v.rst7");
    std::fs::write(&path, lines.join("\n") + "\n").unwrap();
    path
}

fn velocity(k: usize) -> f64 {
    ((k * 7) % 13) as f64 * 0.25 - 1.5
}

#[test]
fn velocities_come_from_the_given_file_in_angstrom_per_fs() {
    let dir = common::scratch_dir("topology-velocities");
    let flags = SceneFlags {
        velocities: Some(restart_with_velocities(&dir, velocity)),
        ..SceneFlags::default()
    };
    let scene = load_scene_with(&system("ala2.prmtop"), &flags, &[]).unwrap();
    let s = &scene.system;
    for (k, p) in s.state.p.iter().enumerate() {
        // p = m v, v converted from AMBER's unit; the file prints 7 decimals, exact here.
        let expected = velocity(k) * VELOCITY_TO_ANGSTROM_PER_FS;
        let got = p * s.inverse_mass[k];
        assert!(
            (got - expected).abs() <= 1e-12 * expected.abs().max(1.0),
            "coordinate {k}: {got} Å/fs, expected {expected}"
        );
    }
    // Without the flag, the coordinates (no velocity block) start at rest.
    let at_rest = load_scene_with(&system("ala2.prmtop"), &SceneFlags::default(), &[]).unwrap();
    assert!(at_rest.system.state.p.iter().all(|&p| p == 0.0));
}

#[test]
fn a_velocity_file_without_velocities_or_on_a_scene_is_refused() {
    let run = |args: &[&str]| {
        let (code, _, stderr) = common::run_cli(args);
        (code, stderr)
    };
    let prmtop = system("ala2.prmtop");
    let inpcrd = system("ala2.inpcrd");
    let (code, stderr) = run(&[
        "check",
        prmtop.to_str().unwrap(),
        "--velocities",
        inpcrd.to_str().unwrap(),
    ]);
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("has no velocities"), "{stderr}");
    assert!(stderr.contains("ala2.inpcrd"), "{stderr}");
    let scene = system("ala2.toml");
    let (code, stderr) = run(&[
        "check",
        scene.to_str().unwrap(),
        "--velocities",
        inpcrd.to_str().unwrap(),
    ]);
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("--velocities"), "{stderr}");
}
