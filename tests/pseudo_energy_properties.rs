//! Structural properties of the pseudo-energy schemes: time reversibility (MEMM18 Prop. 4),
//! momentum conservation (Remark 3), the linear stability bound (Prop. 6), adaptive halving
//! (Remark 8), the asynchronous scheme's fallback, and the mass-matrix contract.

use std::path::{Path, PathBuf};

use longstep::analysis::async_stability::{Scheme, amplification_matrix, dense_spectral_radius};
use longstep::integrators::quadrature::Quadrature;
use longstep::integrators::{self, AsyncPseudoEnergy, Integrator, PseudoEnergy};
use longstep::io::scene::{build_scene, load_scene};
use longstep::run::{RunOptions, run};
use longstep::settings::MethodSettings;
use longstep::system::System;
use nalgebra::DMatrix;
use rand::{RngExt, SeedableRng};

fn systems() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("systems")
}

fn scene(name: &str, set: &[&str]) -> System {
    let set: Vec<String> = set.iter().map(|s| s.to_string()).collect();
    load_scene(&systems().join(name), &set).unwrap().system
}

fn inline(text: &str) -> System {
    build_scene(text, Path::new("inline.toml"), &[])
        .unwrap()
        .system
}

fn max_abs_difference(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

#[test]
fn the_scheme_retraces_its_steps_backwards() {
    // Prop. 4: forward N variable steps, reverse the momenta (p^{n−1/2}, p^{n+1/2}) →
    // (−p^{n+1/2}, −p^{n−1/2}), the same steps in reverse order: back to the start.
    let steps = 2_000;
    let mut rng = rand::rngs::StdRng::seed_from_u64(3);
    let sequence: Vec<f64> = (0..steps)
        .map(|_| rng.random_range(0.5e-3..1.5e-3))
        .collect();
    for rule in ["midpoint", "gl3", "gauss5"] {
        let mut system = scene("fpu.toml", &[]);
        let (q0, p0) = (system.state.q.clone(), system.state.p.clone());
        let mut method = PseudoEnergy::new(1e-3, Quadrature::by_name(rule).unwrap()).unwrap();
        method.setup(&mut system).unwrap();
        let mut scale: f64 = 0.0;
        let mut track = |system: &System| {
            for x in system.state.q.iter().chain(&system.state.p) {
                scale = scale.max(x.abs());
            }
        };
        for &h in &sequence {
            method.set_step(h);
            method.step(&mut system).unwrap();
            track(&system);
        }
        method.reverse(&mut system);
        for &h in sequence.iter().rev() {
            method.set_step(h);
            method.step(&mut system).unwrap();
            track(&system);
        }
        // Back at the start: (q⁰, −p^{1/2}, −p^{−1/2}) = (q⁰, −p⁰, −p⁰).
        let (p_minus, p_plus) = method.half_step_momenta();
        let minus_p0: Vec<f64> = p0.iter().map(|p| -p).collect();
        let q_error = max_abs_difference(&system.state.q, &q0);
        let p_error =
            max_abs_difference(p_minus, &minus_p0).max(max_abs_difference(p_plus, &minus_p0));
        println!("{rule}: |q - q0| = {q_error:.2e}, |p± + p0| = {p_error:.2e}, scale {scale:.2}");
        // 4000 steps, each rounding at a few ulps of the largest |q|, |p|; the FPU flow over
        // t ≈ 4 amplifies little (hω ≤ 0.075, no resonance), so at worst the roundings add:
        // 4000 · 8 ε · scale ≈ 1e-11.
        let bound = 2.0 * steps as f64 * 8.0 * f64::EPSILON * scale;
        assert!(q_error < bound && p_error < bound, "{rule}");
    }
}

/// A free 3-D cluster: a ring of springs and Lennard-Jones between all pairs, no anchors.
const CLUSTER: &str = r#"
version = 1
name = "cluster"
dim = 3
[[particles]]
count = 6
mass = "1 + i/3"
position = ["1.2*cos(i)", "1.2*sin(i)", "0.3*i"]
momentum = ["0.1*sin(3*i)", "0.2*cos(2*i)", "-0.1*i + 0.25"]
[[terms]]
type = "chain"
stiffness = 20.0
[[terms]]
type = "lennard-jones"
epsilon = 0.5
sigma = 0.8
"#;

#[test]
fn an_isolated_system_keeps_its_momentum() {
    // Remark 3: Σ∇V = 0, so Σ p^{n+1/2} is conserved by (6b), whatever the quadrature.
    for rule in ["midpoint", "gauss3"] {
        let mut system = inline(CLUSTER);
        let total = |p: &[f64]| -> [f64; 3] {
            let mut sum = [0.0; 3];
            for (k, x) in p.iter().enumerate() {
                sum[k % 3] += x;
            }
            sum
        };
        let p_start = total(&system.state.p);
        let mut method = PseudoEnergy::new(2e-3, Quadrature::by_name(rule).unwrap()).unwrap();
        method.setup(&mut system).unwrap();
        let mut worst: f64 = 0.0;
        let mut scale: f64 = 0.0;
        for _ in 0..5_000 {
            method.step(&mut system).unwrap();
            let (_, p_plus) = method.half_step_momenta();
            let p_now = total(p_plus);
            scale = scale.max(p_plus.iter().map(|x| x.abs()).sum());
            for a in 0..3 {
                worst = worst.max((p_now[a] - p_start[a]).abs());
            }
        }
        println!("{rule}: max |ΔP| = {worst:.2e} (Σ|p| up to {scale:.2e})");
        // Each step adds forces that cancel in exact arithmetic: a rounding of a few ulps
        // of Σ|p| per step, at worst linearly: 5000 · 4 ε · Σ|p|.
        assert!(
            worst < 5_000.0 * 4.0 * f64::EPSILON * scale,
            "{rule}: {worst:e}"
        );
    }
}

/// Unit masses on a line between fixed ends, springs k (rest length 0): `(n + 1)` links.
fn harmonic_chain(n: usize, k: f64) -> System {
    inline(&format!(
        r#"
version = 1
name = "chain"
dim = 1
[anchors]
left = [0.0]
right = [0.0]
[[particles]]
count = {n}
mass = 1.0
position = ["sin(0.7*(i + 1))"]
momentum = ["cos(1.3*i)"]
[[terms]]
type = "chain"
start = "left"
end = "right"
stiffness = {k}
rest_length = 0.0
"#
    ))
}

#[test]
fn linear_stability_bound_holds_just_below_and_fails_just_above() {
    // Prop. 6: h ≤ 2√(μ/λ), μ the smallest mass (1 here), λ the largest Hessian eigenvalue.
    let (n, k) = (10, 100.0);
    let mut system = harmonic_chain(n, k);
    // λ from the Hessian itself (assembled by Hessian-vector products), not a formula.
    let mut hessian = DMatrix::zeros(n, n);
    let mut unit = vec![0.0; n];
    let mut column = vec![0.0; n];
    for j in 0..n {
        unit[j] = 1.0;
        system
            .forces
            .hessian_vector(0, &system.state.q, &unit, &mut column);
        unit[j] = 0.0;
        for i in 0..n {
            hessian[(i, j)] = column[i];
        }
    }
    let lambda = hessian.symmetric_eigenvalues().max();
    // Closed form for the check: 4k sin²(nπ/(2(n + 1))).
    let closed = 4.0
        * k
        * (n as f64 * std::f64::consts::PI / (2.0 * (n + 1) as f64))
            .sin()
            .powi(2);
    assert!((lambda - closed).abs() < 1e-10 * closed);
    let h_max = 2.0 / lambda.sqrt();

    let run_max = |system: &mut System, h: f64, steps: usize| -> (f64, f64) {
        let mut method = PseudoEnergy::new(h, Quadrature::midpoint()).unwrap();
        method.setup(system).unwrap();
        let (mut first, mut second) = (0.0f64, 0.0f64);
        for s in 0..steps {
            method.step(system).unwrap();
            let size = system.state.q.iter().map(|x| x.abs()).fold(0.0, f64::max);
            if s < steps / 2 {
                first = first.max(size);
            } else {
                second = second.max(size);
            }
        }
        (first, second)
    };

    // Just below: every eigenvalue of the step map on the unit circle (to round-off of
    // the eigenvalue computation, 1e-8 with margin), and a 10 000-step run that does not
    // grow: its second half stays within 1.1 × the first half's maximum (a spectral radius
    // 1 + δ would grow it by e^{5000 δ}).
    let below = 0.99 * h_max;
    let mut scheme = Scheme::synchronous(below, Quadrature::midpoint()).unwrap();
    let radius = dense_spectral_radius(
        &amplification_matrix(&mut harmonic_chain(n, k), &mut scheme).unwrap(),
    );
    println!("h = 0.99 h_max: spectral radius {radius}");
    assert!(radius < 1.0 + 1e-8);
    let (first, second) = run_max(&mut harmonic_chain(n, k), below, 10_000);
    assert!(second <= 1.1 * first, "{first} then {second}");

    // Just above: X² − (h²σ − 2)X + 1 has a real root of modulus
    // ((h²σ − 2) + √((h²σ − 2)² − 4))/2 = 1.33 for h²σ = 4·1.01²; the run explodes.
    let above = 1.01 * h_max;
    let mut scheme = Scheme::synchronous(above, Quadrature::midpoint()).unwrap();
    let radius = dense_spectral_radius(
        &amplification_matrix(&mut harmonic_chain(n, k), &mut scheme).unwrap(),
    );
    let b = 4.0 * 1.01f64.powi(2) - 2.0;
    let predicted = (b + (b * b - 4.0).sqrt()) / 2.0;
    println!("h = 1.01 h_max: spectral radius {radius} (predicted {predicted})");
    assert!((radius - predicted).abs() < 1e-8 * predicted);
    let (first, second) = run_max(&mut harmonic_chain(n, k), above, 200);
    assert!(second > 1e6 * first, "{first} then {second}");
}

#[test]
fn adaptive_halving_keeps_the_jumps_below_the_bound() {
    // Remark 8 on MEMM18 3.3's hardest case (α = 0.99, A = 0.3), ε = 0.03 %, nominal
    // h = 0.005 (just below MEMM18's largest stable constant step 0.0055).
    let epsilon = 3e-4;
    let h = 0.005;
    let mut system = scene("string-nonlinear.toml", &[]);
    let mut method = PseudoEnergy::new(h, Quadrature::by_name("gauss3").unwrap())
        .unwrap()
        .with_adaptive(epsilon, h / 64.0)
        .unwrap();
    method.setup(&mut system).unwrap();
    let mut row = Vec::new();
    let mut previous_pseudo = method.monitor().last;
    let mut steps = Vec::new();
    while system.state.t < 0.99 {
        method.step(&mut system).unwrap();
        row.clear();
        method.extra_values(&system, &mut row);
        let (pseudo, discrete, step) = (row[0], row[1], row[2]);
        // (17): H − H̃ = ⅛|M^{−1/2}[p]|² ≥ 0, and the control keeps it ≤ ε|H̃| (of the node
        // before, which is what the check uses; H̃ moves by < 1e-9 relative per step here).
        assert!(discrete - pseudo >= -1e-15 * pseudo.abs());
        assert!(discrete - pseudo <= epsilon * previous_pseudo.abs() * (1.0 + 1e-9));
        previous_pseudo = pseudo;
        steps.push(step);
    }
    let smallest = steps.iter().copied().fold(f64::INFINITY, f64::min);
    let largest = steps.iter().copied().fold(0.0, f64::max);
    println!("adaptive: {} steps in [{smallest}, {largest}]", steps.len());
    // Every step is the nominal one halved a whole number of times.
    for step in &steps {
        let halvings = (h / step).log2();
        assert!((halvings - halvings.round()).abs() < 1e-12 && halvings >= 0.0);
    }

    // Without the control the same nominal step violates the bound somewhere.
    let mut system = scene("string-nonlinear.toml", &[]);
    let mut fixed = PseudoEnergy::new(h, Quadrature::by_name("gauss3").unwrap()).unwrap();
    fixed.setup(&mut system).unwrap();
    assert!(fixed.monitor().last > 0.0);
    let mut violated = false;
    while system.state.t < 0.99 {
        let before = fixed.monitor().last;
        fixed.step(&mut system).unwrap();
        row.clear();
        fixed.extra_values(&system, &mut row);
        violated |= row[1] - row[0] > epsilon * before.abs();
    }
    assert!(violated);
}

#[test]
fn adaptive_halving_stops_with_a_message_at_the_floor() {
    let mut system = scene("string-nonlinear.toml", &[]);
    let mut method = PseudoEnergy::new(0.005, Quadrature::midpoint())
        .unwrap()
        .with_adaptive(1e-9, 0.004)
        .unwrap();
    method.setup(&mut system).unwrap();
    let failure = (0..400)
        .find_map(|_| method.step(&mut system).err())
        .unwrap();
    println!("{}", failure.0);
    assert!(failure.0.contains("h_min = 0.004") && failure.0.contains("--h-min"));
}

#[test]
fn async_without_slow_particles_falls_back_to_the_synchronous_scheme() {
    // MEMM18 3.2's FPU alternates stiff and soft springs: every particle is mixed.
    let mut settings = MethodSettings::new("async-pseudo-energy", 5e-3);
    settings.ratio = Some(5);
    settings.quadrature = Some("gl3".into());
    let mut notices = Vec::new();
    let mut method = integrators::build(&settings, &mut notices).unwrap();
    let mut system = scene("fpu.toml", &[]);
    let said = method.notices(&system);
    assert!(
        said.iter()
            .any(|n| n.contains("no slow particles") && n.contains("synchronous"))
    );
    method.setup(&mut system).unwrap();
    let mut sync_system = scene("fpu.toml", &[]);
    let mut sync = PseudoEnergy::new(1e-3, Quadrature::by_name("gl3").unwrap()).unwrap();
    sync.setup(&mut sync_system).unwrap();
    for _ in 0..200 {
        method.step(&mut system).unwrap();
        for _ in 0..5 {
            sync.step(&mut sync_system).unwrap();
        }
    }
    // The same operations in the same order: identical to the last bit.
    assert_eq!(system.state.q, sync_system.state.q);
    let (key, report) = method.report().unwrap();
    assert_eq!(key, "pseudo_energy");
    assert_eq!(report["scheme"], "synchronous (no slow particles)");
}

#[test]
fn async_takes_its_steps_from_h_slow_and_h_fast_or_ratio() {
    let mut settings = MethodSettings::new("async-pseudo-energy", 0.01);
    settings.h_fast = Some(2e-4);
    let method = integrators::build(&settings, &mut Vec::new()).unwrap();
    assert!(method.describe().contains("K = 50"));
    settings.ratio = Some(40);
    let error = integrators::build(&settings, &mut Vec::new())
        .err()
        .unwrap();
    assert!(error.to_string().contains("ratio = 40"));
    settings.h_fast = Some(3e-4);
    settings.ratio = None;
    let error = integrators::build(&settings, &mut Vec::new())
        .err()
        .unwrap();
    assert!(error.to_string().contains("does not divide"));
    settings.h_fast = None;
    let error = integrators::build(&settings, &mut Vec::new())
        .err()
        .unwrap();
    assert!(error.to_string().contains("--h-fast or --ratio"));
    let mut async_method = AsyncPseudoEnergy::new(0.01, 50, Quadrature::midpoint()).unwrap();
    let mut string = scene("string-nonlinear.toml", &[]);
    assert!(async_method.setup(&mut string).is_err());
}

fn scratch_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("longstep-pe-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn a_mass_matrix_is_refused_by_methods_that_cannot_use_it_and_can_be_lumped() {
    let text = std::fs::read_to_string(systems().join("string-nonlinear.toml")).unwrap();
    let path = systems().join("string-nonlinear.toml");
    let mut string = build_scene(&text, &path, &[]).unwrap();
    let mut verlet =
        integrators::build(&MethodSettings::new("verlet", 0.0033), &mut Vec::new()).unwrap();
    let options = RunOptions {
        t_end: 0.033,
        ..RunOptions::default()
    };
    let error = run("string", &mut string.system, verlet.as_mut(), &options)
        .err()
        .unwrap()
        .to_string();
    assert!(
        error.contains("mass matrix") && error.contains("lump = true"),
        "{error}"
    );

    let lumped_text = text.replace("lump = false", "lump = true");
    let mut lumped = build_scene(&lumped_text, &path, &[]).unwrap();
    assert!(lumped.system.mass_matrix.is_none());
    // Row sums of the matrix as given: Δx inside, 5Δx/6 at the two end nodes, whose
    // coupling to the fixed ends is not part of the particles' matrix.
    let masses = &lumped.system.particles.masses;
    let n = masses.len();
    for (i, m) in masses.iter().enumerate() {
        let expected = if i == 0 || i + 1 == n {
            0.05 / 6.0
        } else {
            0.01
        };
        assert!((m - expected).abs() < 1e-15, "particle {i}: {m}");
    }
    let summary = run("string", &mut lumped.system, verlet.as_mut(), &options).unwrap();
    assert_eq!(summary.steps, 10);
}

#[test]
fn a_run_reports_pseudo_energy_columns_and_summary() {
    let dir = scratch_dir("columns");
    let mut string = load_scene(&systems().join("string-nonlinear.toml"), &[]).unwrap();
    let mut settings = MethodSettings::new("pseudo-energy", 0.005);
    settings.adaptive = Some(3e-4);
    settings.quadrature = Some("gauss3".into());
    let mut method = integrators::build(&settings, &mut Vec::new()).unwrap();
    let options = RunOptions {
        t_end: 0.1,
        energy_csv: Some(dir.join("energy.csv")),
        ..RunOptions::default()
    };
    let summary = run("string", &mut string.system, method.as_mut(), &options).unwrap();
    let json = serde_json::to_value(&summary).unwrap();
    for key in ["initial", "max_abs_error", "max_relative_error"] {
        assert!(json["pseudo_energy"][key].is_number(), "{key}");
    }
    assert_eq!(
        json["force_evaluations"]["terms"],
        json["force_evaluations"]["interactions"]
    );
    let csv = std::fs::read_to_string(dir.join("energy.csv")).unwrap();
    let header = csv.lines().next().unwrap();
    assert!(
        header.ends_with("pseudo_energy,discrete_energy,h"),
        "{header}"
    );
    // The run's total energy is the discrete energy H^n of Remark 8.
    for line in csv.lines().skip(1) {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        assert!((v[3] - v[v.len() - 2]).abs() <= 1e-14 * v[3].abs());
    }
    std::fs::remove_dir_all(dir).unwrap();
}
