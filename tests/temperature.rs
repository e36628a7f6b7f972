//! Start velocities at a temperature (`--temperature`, `--seed`): the Maxwell–Boltzmann
//! draw, its degrees of freedom, its determinism at any thread count, and the bad input
//! around it.

mod common;
use common::run_cli_threads as run;
use common::{argv, scene_file, scratch_dir};

use std::path::Path;

use longstep::system::velocities::{DegreesOfFreedom, maxwell_boltzmann};
use longstep::units::BOLTZMANN_KCAL_PER_K;

/// `Σ p` along each axis, and `Σ |p|` for its scale.
fn net_momentum(p: &[f64], dim: usize) -> (Vec<f64>, f64) {
    let net = (0..dim)
        .map(|a| p.iter().skip(a).step_by(dim).sum())
        .collect();
    (net, p.iter().map(|x| x.abs()).sum())
}

#[test]
fn a_maxwell_boltzmann_start_is_exactly_at_the_temperature_with_no_net_momentum() {
    let mut scene = scene_file("systems/water-box/scene.toml", &[]);
    let kt = 300.0 * BOLTZMANN_KCAL_PER_K;
    let start = maxwell_boltzmann(&mut scene.system, kt, 7).unwrap();
    let system = &scene.system;
    // Periodic water: translation invariant, so the centre-of-mass momentum is removed
    // and the temperature counted over 3·648 − 3 degrees of freedom.
    assert!(start.degrees_of_freedom.momentum_conserved);
    assert_eq!(start.degrees_of_freedom.count, 3 * 648 - 3);
    let temperature = start
        .degrees_of_freedom
        .temperature(system.kinetic_energy(), BOLTZMANN_KCAL_PER_K);
    // The rescale makes it 300 K up to the round-off of a sum of 1944 squares and one
    // square root: n·ε ≈ 2e-13 relative; 1e-12 allows a few ulps more.
    assert!(
        (temperature - 300.0).abs() <= 1e-12 * 300.0,
        "T = {temperature}"
    );
    // The removal leaves a net momentum of round-off size: each component's sum of 648
    // terms, relative to their magnitude.
    let (net, scale) = net_momentum(&system.state.p, 3);
    for (a, n) in net.iter().enumerate() {
        assert!(
            n.abs() <= 1e-12 * scale,
            "axis {a}: Σp = {n}, scale {scale}"
        );
    }
    // The draw weights each particle by its mass: m v² per component averages kT for the
    // light hydrogens and the heavy oxygens alike. Each mean is over 1296 (H) or 648 (O)
    // components of a χ²₁ variable (relative standard deviation √(2/n): 3.9 % and 5.6 %);
    // 5σ is 0.2 and 0.28. Drawing all with one mass would put them a factor 16 apart.
    let mean_m_v2 = |element: &str| {
        let mut sum = 0.0;
        let mut count = 0.0;
        for (i, name) in scene.elements.iter().enumerate() {
            if name == element {
                let m = system.particles.masses[i];
                for a in 0..3 {
                    let p = system.state.p[3 * i + a];
                    sum += p * p / m;
                    count += 1.0;
                }
            }
        }
        sum / count / kt
    };
    let (hydrogen, oxygen) = (mean_m_v2("H"), mean_m_v2("O"));
    assert!((hydrogen - 1.0).abs() < 0.2, "H: ⟨m v²⟩/kT = {hydrogen}");
    assert!((oxygen - 1.0).abs() < 0.28, "O: ⟨m v²⟩/kT = {oxygen}");
}

#[test]
fn the_same_seed_draws_the_same_velocities_and_another_seed_others() {
    let draw = |seed: u64| {
        let mut scene = scene_file("systems/molecules/butane.toml", &[]);
        maxwell_boltzmann(&mut scene.system, 0.6, seed).unwrap();
        scene.system.state.p
    };
    let (a, b, c) = (draw(7), draw(7), draw(8));
    assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
    assert!(a.iter().zip(&c).any(|(x, y)| x != y));
}

#[test]
fn an_anchored_scene_keeps_its_momentum_and_counts_every_coordinate() {
    // The three-spring system hangs between two walls: the walls take momentum, so none
    // is removed and all dim·N coordinates count.
    let mut scene = scene_file("systems/three-spring.toml", &[]);
    let dofs = DegreesOfFreedom::of(&scene.system);
    assert!(!dofs.momentum_conserved);
    assert_eq!(dofs.count, scene.system.n_dofs());
    maxwell_boltzmann(&mut scene.system, 2.0, 3).unwrap();
    let t = dofs.temperature(scene.system.kinetic_energy(), 1.0);
    assert!((t - 2.0).abs() <= 1e-14 * 2.0 * 8.0, "k_B T = {t}");
    // A free molecule (no box, no anchor) conserves its momentum: 3N − 3.
    let butane = scene_file("systems/molecules/butane.toml", &[]);
    let dofs = DegreesOfFreedom::of(&butane.system);
    assert!(dofs.momentum_conserved);
    assert_eq!(dofs.count, 3 * 14 - 3);
}

fn water_run(out: &Path, seed: &str, threads: usize) -> (String, String) {
    let (code, stdout, stderr) = run(
        &argv(
            "run systems/water-box/scene.toml --method impulse --h 2fs --inner 4 \
             --t-end 40fs --energy-every 1 --temperature 300K --seed {} --out {}",
            &[seed, out.to_str().unwrap()],
        ),
        Some(threads),
    );
    assert_eq!(code, 0, "{stderr}");
    let csv = std::fs::read_to_string(out.join("energy.csv")).unwrap();
    assert!(stdout.contains("temperature mean"), "{stdout}");
    (csv, stderr)
}

#[test]
fn a_seeded_start_gives_the_same_bits_on_one_and_two_threads() {
    let (one, stderr) = water_run(&scratch_dir("temperature-1-thread"), "7", 1);
    let (two, _) = water_run(&scratch_dir("temperature-2-threads"), "7", 2);
    assert!(one == two, "energy.csv differs between 1 and 2 threads");
    let (other, _) = water_run(&scratch_dir("temperature-seed-8"), "8", 2);
    assert!(other != one, "another seed gave the same trajectory");
    // The header says what replaced what, the seed and the degrees of freedom.
    assert!(
        stderr.contains("Maxwell–Boltzmann velocities at 300 K (seed 7)"),
        "{stderr}"
    );
    assert!(stderr.contains("replacing the velocities of"), "{stderr}");
    assert!(
        stderr.contains("1941 degrees of freedom (3·648 − 3"),
        "{stderr}"
    );
    // The first row's kinetic temperature is the requested one.
    let mut lines = one.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let column = header.iter().position(|h| *h == "temperature[K]").unwrap();
    let first: f64 = lines
        .next()
        .unwrap()
        .split(',')
        .nth(column)
        .unwrap()
        .parse()
        .unwrap();
    assert!((first - 300.0).abs() <= 1e-9, "T(0) = {first}");
}

#[test]
fn without_a_seed_the_default_one_is_named() {
    let out = scratch_dir("temperature-default-seed");
    let (code, _, stderr) = run(
        &argv(
            "run systems/molecules/butane.toml --h 1fs --t-end 10fs --temperature 300K \
             --out {}",
            &[out.to_str().unwrap()],
        ),
        None,
    );
    assert_eq!(code, 0, "{stderr}");
    assert!(stderr.contains("(seed 2013, the default"), "{stderr}");
    assert!(!stderr.contains("replacing"), "{stderr}");
    assert!(!stderr.contains("starts at rest"), "{stderr}");
}

#[test]
fn a_scene_at_rest_without_a_temperature_gets_a_notice() {
    let out = scratch_dir("temperature-at-rest");
    let (code, _, stderr) = run(
        &argv(
            "run systems/molecules/butane.toml --h 1fs --t-end 10fs --out {}",
            &[out.to_str().unwrap()],
        ),
        None,
    );
    assert_eq!(code, 0, "{stderr}");
    assert!(
        stderr.contains("notice: every particle starts at rest and no temperature is given"),
        "{stderr}"
    );
}

#[test]
fn bad_temperatures_and_unused_seeds_are_refused() {
    let out = scratch_dir("temperature-bad");
    let out = out.to_str().unwrap();
    let water = "systems/water-box/scene.toml";
    let spring = "systems/three-spring.toml";
    let cases: &[(&str, &[&str], &str)] = &[
        (
            water,
            &["--temperature", "-5K"],
            "temperature must be positive, got -5 K",
        ),
        (
            spring,
            &["--temperature", "300K"],
            "the unit 'K' needs a scene with units = \"real\"",
        ),
        (
            spring,
            &["--temperature", "0"],
            "temperature must be positive",
        ),
        (
            spring,
            &["--seed", "3"],
            "--seed 3 is given, but nothing uses it",
        ),
        (
            water,
            &["--seed", "3", "--method", "long-average"],
            "long-average is not a stochastic method",
        ),
    ];
    for (scene, extra, fragment) in cases {
        let mut args = vec!["run", scene, "--t-end", "4", "--h", "1", "--out", out];
        args.extend_from_slice(extra);
        let (code, _, stderr) = run(&args, None);
        assert_eq!(code, 1, "{extra:?}: {stderr}");
        assert!(stderr.contains(fragment), "{extra:?}: {stderr}");
    }
    // A temperature given as a plain number in a dimensionless scene is k_B T: fine, and
    // the seed then has a use.
    let (code, _, stderr) = run(
        &argv(
            "run {} --t-end 1 --h 0.05 --temperature 2 --seed 3 --out {}",
            &[spring, out],
        ),
        None,
    );
    assert_eq!(code, 0, "{stderr}");
}

#[test]
fn start_velocities_and_method_noise_share_one_default_seed() {
    assert_eq!(
        longstep::system::velocities::DEFAULT_SEED,
        longstep::integrators::langevin::DEFAULT_SEED
    );
}
