//! The real-space term of a topology split by distance (`[topology.split]`, `--split`): the
//! short part in the cluster-pair kernel with the switch in its lanes, the remainder as the
//! full term minus it, the 1-4 pairs with the short part.

mod common;
use common::argv;

use std::path::Path;

use longstep::forces::Precision;
use longstep::io::forcefield::{ElectrostaticsOverrides, SplitSection};
use longstep::io::scene::{Scene, SceneFlags, load_scene_with};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

const DIPEPTIDE: &str = "systems/alanine-dipeptide-amber/ala2-solvated-pme.toml";

fn load(split: Option<&str>, pme_level: Option<usize>) -> Scene {
    let flags = SceneFlags {
        electrostatics: ElectrostaticsOverrides {
            split: split.map(|s| SplitSection::from_flag(s).expect("split flag")),
            pme_level,
            ..ElectrostaticsOverrides::default()
        },
        ..SceneFlags::default()
    };
    load_scene_with(Path::new(DIPEPTIDE), &flags, &[]).unwrap_or_else(|e| panic!("{e}"))
}

/// `(Σ_levels V, Σ_levels ∇V)` at `q`.
fn total(scene: &mut Scene, q: &[f64]) -> (f64, Vec<f64>) {
    let forces = &mut scene.system.forces;
    let mut gradient = vec![0.0; q.len()];
    let mut energy = 0.0;
    for level in 0..forces.n_levels() {
        energy += forces.energy(level, q);
        forces.add_gradient(level, q, &mut gradient);
    }
    (energy, gradient)
}

/// Positions moved off the minimum a little, so that many pairs sit on the switch.
fn jiggled(scene: &Scene, seed: u64) -> Vec<f64> {
    let mut rng = StdRng::seed_from_u64(seed);
    let q = &scene.system.state.q;
    q.iter()
        .map(|x| x + rng.random_range(-0.05..0.05))
        .collect()
}

#[test]
fn the_split_dipeptide_adds_up_to_the_unsplit_model() {
    let mut whole = load(None, None);
    let mut split = load(
        Some("r_in=5,r_out=6,short_level=0,remainder_level=1"),
        Some(1),
    );
    assert_eq!(split.system.forces.n_levels(), 2);
    let q = jiggled(&whole, 3);
    let (e_whole, g_whole) = total(&mut whole, &q);
    let (e_split, g_split) = total(&mut split, &q);
    // Both sums are of the same pair terms: the remainder is the full term minus the short
    // part, so they differ by the round-off of the subtraction, ~1e-16 of the largest part
    // (|short part| ~ 10⁴ kcal/mol here): 1e-12 of the scale leaves room for that and the
    // reordered sums, and no pair moved between parts could hide in it.
    let scale = e_whole.abs() + split.system.forces.energy(0, &q).abs();
    assert!(
        (e_split - e_whole).abs() <= 1e-12 * scale,
        "energy split {e_split} against unsplit {e_whole}"
    );
    let bound = 1e-11 * common::max_abs(&g_whole);
    let error = common::max_abs_difference(&g_split, &g_whole);
    assert!(
        error <= bound,
        "gradient differs by {error:e} (bound {bound:e})"
    );
}

#[test]
fn the_short_part_takes_the_1_4_pairs_and_the_reciprocal_sum_stays_slow() {
    let split = load(
        Some("r_in=5,r_out=6,short_level=0,remainder_level=1"),
        Some(1),
    );
    let table = split.system.forces.level_table();
    let (fast, slow) = table
        .split_once(" | ")
        .unwrap_or_else(|| panic!("two levels: {table}"));
    for name in [
        "\"lj-14\"",
        "\"coulomb-14\"",
        "nonbonded-short",
        "\"bonds\"",
    ] {
        assert!(fast.contains(name), "{name} not on the fast level: {table}");
    }
    for name in ["nonbonded-remainder", "\"pme-reciprocal\""] {
        assert!(slow.contains(name), "{name} not on the slow level: {table}");
    }
}

/// The switched kernel in mixed precision: within single precision's round-off of the
/// double-precision short part (relative 1e-5 of the largest force component: ~1e-7 per
/// operation over a few dozen operations per pair and ~10³ pairs per atom, summed in f64).
#[test]
fn the_mixed_short_part_is_the_double_one_within_round_off() {
    let mut double = load(
        Some("r_in=5,r_out=6,short_level=0,remainder_level=1"),
        Some(1),
    );
    let mut mixed = load(
        Some("r_in=5,r_out=6,short_level=0,remainder_level=1"),
        Some(1),
    );
    assert!(mixed.system.forces.set_precision(Precision::Mixed) > 0);
    let q = jiggled(&double, 5);
    let mut g_double = vec![0.0; q.len()];
    let mut g_mixed = vec![0.0; q.len()];
    double.system.forces.gradient(0, &q, &mut g_double);
    mixed.system.forces.gradient(0, &q, &mut g_mixed);
    let scale = common::max_abs(&g_double);
    let error = common::max_abs_difference(&g_double, &g_mixed);
    assert!(
        error > 0.0 && error <= 1e-5 * scale,
        "mixed against double: {error:e} (scale {scale:e})"
    );
}

#[test]
fn bad_splits_are_refused_by_name() {
    let cases: [(&[&str], &str); 4] = [
        (&["--split", "r_in=5"], "r_out"),
        (&["--split", "r_in=5,r_out=12"], "[topology.split]"),
        (&["--split", "r_in=5,r_out=6,width=2"], "width"),
        (
            &["--split", "r_in=5,r_out=6", "--nonbonded-level", "0"],
            "nonbonded_level",
        ),
    ];
    for (flags, expected) in cases {
        let mut args = vec!["check", DIPEPTIDE];
        args.extend_from_slice(flags);
        let (code, stdout, stderr) = common::run_cli(&args);
        assert_eq!(code, 1, "{flags:?}: exit {code}\n{stdout}{stderr}");
        assert!(
            stderr.contains(expected),
            "{flags:?}: the message should name {expected}:\n{stderr}"
        );
    }
}

#[test]
fn check_reports_the_split_and_its_levels() {
    let (code, stdout, stderr) = common::run_cli(&argv(
        "check {} --split r_in=5,r_out=6,short_level=0,remainder_level=1 --pme-level 1",
        &[DIPEPTIDE],
    ));
    assert_eq!(code, 0, "{stdout}{stderr}");
    let text = stdout + &stderr;
    for expected in [
        "nonbonded split: short-range part on level 0 switched off between r_in = 5 and \
         r_out = 6 by atom pair, computed as cluster pairs; remainder (full − short) on level 1",
        // By atom pair the short part keeps the screened erfc(αr)/r by default.
        "nonbonded split: the short part's Coulomb is the term's own form \
         (short_coulomb = \"model\")",
        "0 (fast) = ",
        "1 (slow) = ",
    ] {
        assert!(text.contains(expected), "check lacks {expected}:\n{text}");
    }
}
