//! The thermostatted r-RESPA methods (langevin-respa, sinr) on independent harmonic
//! oscillators, where the canonical answer is known: `⟨x²⟩ = kT/k`.
//!
//! Statistical tolerances come from block averages: the per-step series (x² averaged over
//! the oscillators) is cut into `BLOCKS` blocks, the standard error of the mean is the
//! standard deviation of the block means over √BLOCKS, and a test passes within
//! [`Z`] standard errors (a two-sided 4σ bound: a correct method fails by chance about once
//! in 10⁴ seeds; the seeds are fixed, so each test is deterministic). Block lengths are
//! stated per test against the correlation time of x² they must exceed.

mod common;

use common::scene;
use longstep::integrators::langevin::Langevin;
use longstep::integrators::{self, Integrator};
use longstep::io::scene::Scene;
use longstep::settings::MethodSettings;

/// Standard errors allowed between a sampled mean and the exact one.
const Z: f64 = 4.0;
const BLOCKS: usize = 40;

/// `n` independent 1-D unit-mass oscillators about the origin, each with a fast spring
/// `k_fast` and, when `k_slow > 0`, a slow spring `k_slow` (a second force level).
fn oscillators(n: usize, k_fast: f64, k_slow: f64) -> Scene {
    let mut text = String::from("version = 1\nname = \"oscillators\"\ndim = 1\n");
    text += "[anchors]\norigin = [0.0]\n";
    for i in 0..n {
        // Spread starts so the first block is not all in phase.
        let x = 0.5 + (i % 7) as f64 * 0.1;
        text += &format!("[[particles]]\nmass = 1.0\nposition = [{x}]\nmomentum = [0.0]\n");
    }
    let pairs: Vec<String> = (0..n).map(|i| format!("[\"origin\", {i}]")).collect();
    let pairs = pairs.join(", ");
    text += &format!(
        "[[terms]]\ntype = \"spring\"\nname = \"fast\"\npairs = [{pairs}]\nstiffness = {k_fast}\n\
         rest_length = 0.0\ngroup = \"fast\"\n"
    );
    if k_slow > 0.0 {
        text += &format!(
            "[[terms]]\ntype = \"spring\"\nname = \"slow\"\npairs = [{pairs}]\n\
             stiffness = {k_slow}\nrest_length = 0.0\ngroup = \"slow\"\n"
        );
    }
    scene(&text)
}

fn settings(method: &str, h: f64, inner: usize, kt: f64) -> MethodSettings {
    let mut s = MethodSettings::new(method, h);
    s.inner_steps = Some(inner);
    s.temperature = Some(kt);
    s.seed = Some(7);
    s
}

fn build(settings: &MethodSettings) -> Box<dyn Integrator> {
    integrators::build(settings, &mut Vec::new()).unwrap_or_else(|e| panic!("{e}"))
}

/// Per outer step, after `burn` steps: the mean of x² and of p²/m over the coordinates.
fn sample(
    scene: &mut Scene,
    integrator: &mut dyn Integrator,
    burn: usize,
    steps: usize,
) -> (Vec<f64>, Vec<f64>) {
    integrator.setup(&mut scene.system).unwrap();
    for _ in 0..burn {
        integrator.step(&mut scene.system).unwrap();
    }
    let n = scene.system.n_dofs() as f64;
    let (mut x2, mut kinetic) = (Vec::with_capacity(steps), Vec::with_capacity(steps));
    for _ in 0..steps {
        integrator.step(&mut scene.system).unwrap();
        let s = &scene.system;
        x2.push(s.state.q.iter().map(|x| x * x).sum::<f64>() / n);
        let twice_kinetic: f64 = s
            .state
            .p
            .iter()
            .zip(&s.inverse_mass)
            .map(|(p, w)| p * p * w)
            .sum();
        kinetic.push(twice_kinetic / n);
    }
    (x2, kinetic)
}

/// Mean of `series` and its standard error from [`BLOCKS`] block means.
fn block_mean(series: &[f64]) -> (f64, f64) {
    let length = series.len() / BLOCKS;
    let means: Vec<f64> = series
        .chunks_exact(length)
        .map(|b| b.iter().sum::<f64>() / length as f64)
        .collect();
    let mean = means.iter().sum::<f64>() / means.len() as f64;
    let variance = means.iter().map(|m| (m - mean).powi(2)).sum::<f64>() / (means.len() - 1) as f64;
    (mean, (variance / means.len() as f64).sqrt())
}

fn assert_within(what: &str, mean: f64, error: f64, exact: f64) {
    let deviation = (mean - exact).abs();
    assert!(
        deviation <= Z * error,
        "{what}: {mean} ± {error} (block SE) against {exact}: {:.1} SE off",
        deviation / error
    );
    eprintln!(
        "{what}: {mean:.5} ± {error:.5} against {exact:.5} ({:.2} SE)",
        deviation / error
    );
}

/// The stationary `(⟨x²⟩, ⟨p²⟩)` at step ends of BAOAB r-RESPA on one unit-mass oscillator
/// `k_fast + k_slow`, exactly: the scheme is linear in (x, p) plus Gaussian noise, so its stationary
/// covariance Σ is the fixed point of `Σ ← T Σ Tᵀ` through the kicks and drifts and
/// `Σ ← D Σ D + diag(0, (1 − a²) kT)` through the O step. Iterated to convergence.
fn baoab_respa_variance(
    k_fast: f64,
    k_slow: f64,
    h: f64,
    inner: usize,
    gamma: f64,
    kt: f64,
) -> (f64, f64) {
    type M = [[f64; 2]; 2];
    let apply = |s: &M, t: &M| -> M {
        let mut ts = [[0.0; 2]; 2];
        let mut out = [[0.0; 2]; 2];
        for i in 0..2 {
            for j in 0..2 {
                ts[i][j] = t[i][0] * s[0][j] + t[i][1] * s[1][j];
            }
        }
        for i in 0..2 {
            for j in 0..2 {
                out[i][j] = ts[i][0] * t[j][0] + ts[i][1] * t[j][1];
            }
        }
        out
    };
    let kick = |k: f64, tau: f64| -> M { [[1.0, 0.0], [-tau * k, 1.0]] };
    let drift = |tau: f64| -> M { [[1.0, tau], [0.0, 1.0]] };
    let dt = h / inner as f64;
    let a = (-gamma * dt).exp();
    let mut s: M = [[kt / (k_fast + k_slow), 0.0], [0.0, kt]];
    for _ in 0..200_000 {
        let before = s[0][0];
        s = apply(&s, &kick(k_slow, h / 2.0));
        for _ in 0..inner {
            s = apply(&s, &kick(k_fast, dt / 2.0));
            s = apply(&s, &drift(dt / 2.0));
            s = [
                [s[0][0], a * s[0][1]],
                [a * s[1][0], a * a * s[1][1] + (1.0 - a * a) * kt],
            ];
            s = apply(&s, &drift(dt / 2.0));
            s = apply(&s, &kick(k_fast, dt / 2.0));
        }
        s = apply(&s, &kick(k_slow, h / 2.0));
        if (s[0][0] - before).abs() < 1e-15 * s[0][0] {
            break;
        }
    }
    (s[0][0], s[1][1])
}

#[test]
fn baoab_samples_the_harmonic_configuration_exactly() {
    // One level: BAOAB, whose x-marginal is exactly canonical for a harmonic force at any
    // stable step (LM13), here ω dt = 0.5. γ = 1 = ω: x² decorrelates in a few time units
    // (the underdamped envelope e^{−γt/2} squared), so blocks of 250 steps = 125 time units
    // are ≥ 25 correlation times. 40 blocks; 64 oscillators per step.
    let (k, kt) = (1.0, 1.0);
    let mut s = oscillators(64, k, 0.0);
    let mut settings = settings("langevin-respa", 0.5, 1, kt);
    settings.friction = Some(1.0);
    let mut method = build(&settings);
    let (x2, kinetic) = sample(&mut s, method.as_mut(), 200, 250 * BLOCKS);
    let (mean, error) = block_mean(&x2);
    assert_within("BAOAB <x²>", mean, error, kt / k);
    // The exact stationary law of the discrete scheme: ⟨x²⟩ = kT/k (LM13), and at step ends
    // ⟨p²⟩ = m kT (1 − (ω dt)²/4), low by 1/16 here: the kinetic temperature from step-end
    // momenta runs cold on stiff modes (on the water box, 0.5 fs inner steps make it ~1 %).
    let (exact, momentum) = baoab_respa_variance(k, 0.0, 0.5, 1, 1.0, kt);
    assert!((exact - kt / k).abs() < 1e-12, "{exact}");
    assert!(
        (momentum - kt * (1.0 - 0.25 * 0.25)).abs() < 1e-12,
        "{momentum}"
    );
    let (mean, error) = block_mean(&kinetic);
    assert_within("BAOAB <p²> at step ends", mean, error, momentum);
}

#[test]
fn langevin_respa_samples_its_stationary_law() {
    // Two levels, k_fast = 1, k_slow = 0.25, h = 1 with 4 inner steps, γ = 1: not exact
    // for the split force, so the reference is the scheme's own stationary ⟨x²⟩
    // (baoab_respa_variance), which must also be within 5 % of kT/k (a thermostat at T; the 4 % between them is ~25 SE, so the test tells the scheme apart
    // from merely "canonical").
    // Blocks of 500 outer steps = 500 time units, ≥ 100 correlation times (γ = 1).
    let (kf, ks, kt) = (1.0, 0.25, 0.7);
    let mut s = oscillators(64, kf, ks);
    let mut settings = settings("langevin-respa", 1.0, 4, kt);
    settings.friction = Some(1.0);
    let mut method = build(&settings);
    let (x2, _) = sample(&mut s, method.as_mut(), 100, 500 * BLOCKS);
    let (mean, error) = block_mean(&x2);
    let (exact, _) = baoab_respa_variance(kf, ks, 1.0, 4, 1.0, kt);
    assert_within("BAOAB-RESPA <x²>", mean, error, exact);
    let canonical = kt / (kf + ks);
    assert!(
        (exact / canonical - 1.0).abs() < 0.05,
        "stationary {exact} vs canonical {canonical}"
    );
}

fn sinr_settings(h: f64, inner: usize, kt: f64, thermostats: usize) -> MethodSettings {
    let mut s = settings("sinr", h, inner, kt);
    s.thermostats = Some(thermostats);
    s.tau = Some(1.0);
    s.friction = Some(1.0);
    s
}

#[test]
fn sinr_samples_the_harmonic_configuration() {
    // One level, ω = 1, dt = 0.1, τ = 1, γ = 1 (on the thermostats). The block standard
    // error of x² stops growing with the block length from about 50 time units on (checked
    // at 10 … 400 time units: 50, 100 and 200 agree within their ~10 % scatter), so blocks
    // of 1000 steps = 100 time units. The configurational part is canonical, ⟨x²⟩ = kT/k;
    // the kinetic part holds ⟨m v²⟩ = L/(L+1) kT (the constraint shares L kT between v and
    // L thermostats equally on average). Discretisation bias at ω dt = 0.1: not resolved
    // at this SE (the same runs at dt = 0.05 agree).
    for thermostats in [1, 3] {
        let (k, kt) = (1.0, 0.5);
        let mut s = oscillators(64, k, 0.0);
        let mut method = build(&sinr_settings(0.1, 1, kt, thermostats));
        let (x2, kinetic) = sample(&mut s, method.as_mut(), 1000, 1000 * BLOCKS);
        let (mean, error) = block_mean(&x2);
        assert_within(
            &format!("SIN(R) L = {thermostats} <x²>"),
            mean,
            error,
            kt / k,
        );
        let (mean, error) = block_mean(&kinetic);
        let expected = kt * thermostats as f64 / (thermostats + 1) as f64;
        assert_within(
            &format!("SIN(R) L = {thermostats} <m v²>"),
            mean,
            error,
            expected,
        );
    }
}

/// `n` independent 1-D oscillators about the origin in the single-well anharmonic
/// potential `x²/2 + c x⁴`: the harmonic spring on the fast level, the quartic one on the
/// slow level. Masses alternate 1 and 16 (a hydrogen and an oxygen), so a method whose
/// configurational law depended on the mass would sample the two halves differently.
fn anharmonic_oscillators(n: usize, quartic: f64) -> Scene {
    let mut text = String::from("version = 1\nname = \"anharmonic\"\ndim = 1\n");
    text += "[anchors]\norigin = [0.0]\n";
    for i in 0..n {
        let mass = if i % 2 == 0 { 1.0 } else { 16.0 };
        let x = 0.3 + (i % 7) as f64 * 0.1;
        text += &format!("[[particles]]\nmass = {mass}\nposition = [{x}]\nmomentum = [0.0]\n");
    }
    let pairs: Vec<String> = (0..n).map(|i| format!("[\"origin\", {i}]")).collect();
    let pairs = pairs.join(", ");
    text += &format!(
        "[[terms]]\ntype = \"spring\"\nname = \"fast\"\npairs = [{pairs}]\nstiffness = 1.0\n\
         rest_length = 0.0\ngroup = \"fast\"\n\
         [[terms]]\ntype = \"quartic-spring\"\nname = \"slow\"\npairs = [{pairs}]\n\
         coefficient = {quartic}\nrest_length = 0.0\ngroup = \"slow\"\n"
    );
    scene(&text)
}

/// The canonical `⟨x²⟩` in `V = x²/2 + c x⁴` at `kt`, by the trapezoidal rule on
/// [−12, 12] with 2·10⁵ intervals: the weight is below e⁻¹⁰⁰⁰ at the ends for kT ≤ 5 and
/// the rule is exponentially accurate for a smooth, decaying integrand (error ≪ 1e-12).
fn canonical_x2_quartic(quartic: f64, kt: f64) -> f64 {
    let (n, a) = (200_000, 12.0);
    let dx = 2.0 * a / n as f64;
    let (mut z, mut m) = (0.0, 0.0);
    for i in 0..=n {
        let x = -a + i as f64 * dx;
        let w = (-(0.5 * x * x + quartic * x.powi(4)) / kt).exp();
        z += w;
        m += w * x * x;
    }
    m / z
}

#[test]
fn sinr_samples_an_anharmonic_two_level_configuration_at_any_mass() {
    // Two levels (harmonic spring fast, quartic spring slow, c = 1/4), h = 0.1 with 2 inner
    // steps, τ = 1, γ = 1, kT = 1, L = 1 and 4: the configurational law must be
    // exp(−V/kT) for the light (m = 1, ω ≥ 1) and the heavy (m = 16, ω ≥ 1/4) particles
    // alike, so each half's ⟨x²⟩ is compared with the quadrature. Blocks of 1000 outer
    // steps = 100 time units, 4 periods of the slowest (heavy, ω = 1/4) oscillator, whose
    // thermostat (τ = 1) decorrelates x² within about one period: 20000-unit runs of this
    // system give the potential's SE within 5 % for blocks of 25 to 450 time units, with
    // L = 1 and 4. Discretisation bias at
    // h = 0.1: not resolved (runs of 20000 time units at h = 0.05 and 0.1 put the mean
    // potential within 1 of their 0.25 % standard errors of the quadrature), far below the
    // ≈ 2.5 % that 4 SE allow here. Sampling at a wrong temperature moves ⟨x²⟩ by far more:
    // −38 % at L/(L+1) kT (L = 1), +138 % at L kT (L = 4).
    let (quartic, kt) = (0.25, 1.0);
    let exact = canonical_x2_quartic(quartic, kt);
    for thermostats in [1, 4] {
        let mut s = anharmonic_oscillators(64, quartic);
        let mut method = build(&sinr_settings(0.1, 2, kt, thermostats));
        method.setup(&mut s.system).unwrap();
        for _ in 0..1000 {
            method.step(&mut s.system).unwrap();
        }
        let (mut light, mut heavy) = (Vec::new(), Vec::new());
        for _ in 0..1000 * BLOCKS {
            method.step(&mut s.system).unwrap();
            let q = &s.system.state.q;
            let half = q.len() as f64 / 2.0;
            light.push(q.iter().step_by(2).map(|x| x * x).sum::<f64>() / half);
            heavy.push(q.iter().skip(1).step_by(2).map(|x| x * x).sum::<f64>() / half);
        }
        for (what, series) in [("light", &light), ("heavy", &heavy)] {
            let (mean, error) = block_mean(series);
            assert_within(
                &format!("SIN(R) L = {thermostats}, two levels, {what} <x²>"),
                mean,
                error,
                exact,
            );
        }
    }
}

#[test]
fn sinr_holds_its_constraint_past_the_impulse_resonance() {
    // Two levels, ω_fast ≈ 1: h = π is impulse's first resonance (h = half the fast
    // period). SIN(R) stays bounded there and holds its constraint to round-off on every
    // degree of freedom after every step (largest violation over the run ≤ 1e-10 relative;
    // each operator keeps it to a few ulps and the thermostat flow re-imposes it).
    let (kf, ks, kt) = (1.0, 0.25, 0.5);
    let mut s = oscillators(16, kf, ks);
    let mut method = build(&sinr_settings(std::f64::consts::PI, 32, kt, 2));
    let (x2, _) = sample(&mut s, method.as_mut(), 0, 4000);
    let (_, report) = method.report().unwrap();
    let violation = report["constraint_max_violation"].as_f64().unwrap();
    assert!(violation <= 1e-10, "constraint violated by {violation}");
    let largest = x2.iter().cloned().fold(0.0, f64::max);
    // 16 oscillators at kT/k = 0.4: the mean of x² exceeds 10× that only if it blew up.
    assert!(largest < 4.0, "x² reached {largest}");
    eprintln!(
        "SIN(R) at h = π: violation {violation:e}, mean x² {}",
        x2.iter().sum::<f64>() / x2.len() as f64
    );
}

/// Three particles in 2-D joined by springs of rest length 1 (a nonlinear force), one level.
const TRIANGLE: &str = r#"
version = 1
name = "triangle"
dim = 2
[[particles]]
mass = 1.0
position = [0.0, 0.0]
momentum = [0.3, -0.1]
[[particles]]
mass = 2.0
position = [1.1, 0.0]
momentum = [0.0, 0.2]
[[particles]]
mass = 1.5
position = [0.4, 0.9]
momentum = [-0.2, 0.0]
[[terms]]
type = "spring"
pairs = [[0, 1], [1, 2], [0, 2]]
stiffness = 30.0
rest_length = 1.0
"#;

#[test]
fn one_level_langevin_respa_is_baoab_bit_for_bit() {
    // Plain BAOAB written out from the primitives (LM13: B A O A B with the force at the
    // new positions), with the O step drawn from the same seeded stream.
    let (h, kt, gamma, seed, steps) = (0.01, 0.3, 2.0, 11, 500);
    let mut settings = settings("langevin-respa", h, 1, kt);
    settings.friction = Some(gamma);
    settings.seed = Some(seed);
    let mut method = build(&settings);
    let mut ours = scene(TRIANGLE);
    // One force level: the slow level exists but is empty, so it never kicks.
    assert!(ours.system.forces.level_is_empty(1));
    common::integrate(&mut ours, method.as_mut(), steps);

    let mut reference = scene(TRIANGLE);
    let system = &mut reference.system;
    let mut langevin = Langevin::new(kt, gamma, seed);
    langevin.setup(h, &system.inverse_mass);
    let mut gradient = vec![0.0; system.n_dofs()];
    system.forces.gradient(0, &system.state.q, &mut gradient);
    for _ in 0..steps {
        let state = &mut system.state;
        integrators::kick(&mut state.p, &gradient, 0.5 * h);
        integrators::drift(&mut state.q, &state.p, &system.inverse_mass, 0.5 * h);
        langevin.apply(&mut state.p);
        integrators::drift(&mut state.q, &state.p, &system.inverse_mass, 0.5 * h);
        system.forces.gradient(0, &system.state.q, &mut gradient);
        integrators::kick(&mut system.state.p, &gradient, 0.5 * h);
    }
    assert_eq!(ours.system.state.q, reference.system.state.q);
    assert_eq!(ours.system.state.p, reference.system.state.p);
}

#[test]
fn langevin_respa_without_friction_is_impulse_to_round_off() {
    // γ = 1e-300: a = 1 exactly and the noise (~1e-150) is below half an ulp of p, so the
    // only difference is the drift taken as two halves, a rounding of ≤ 1 ulp of q per
    // inner step. On a stable linear scene the differences add without growing: after
    // n inner steps they stay below 10 n ε max|state| (not bit for bit: x + a + a ≠ x + 2a).
    let (h, inner, steps) = (0.5, 5, 200);
    let mut s1 = oscillators(8, 1.0, 0.25);
    let mut s2 = oscillators(8, 1.0, 0.25);
    let mut settings = settings("langevin-respa", h, inner, 1.0);
    settings.friction = Some(1e-300);
    let mut langevin = build(&settings);
    let mut impulse = common::method("impulse", h, Some(inner));
    let (q1, p1) = common::integrate(&mut s1, langevin.as_mut(), steps);
    let (q2, p2) = common::integrate(&mut s2, impulse.as_mut(), steps);
    let scale = common::max_abs(&q2).max(common::max_abs(&p2));
    let bound = 10.0 * (steps * inner) as f64 * f64::EPSILON * scale;
    let difference = common::max_abs_difference(&q1, &q2).max(common::max_abs_difference(&p1, &p2));
    assert!(difference <= bound, "{difference} > {bound}");
    assert!(difference > 0.0 || q1 == q2);
}

#[test]
fn thermostatted_methods_need_a_temperature() {
    for method in ["langevin-respa", "sinr"] {
        let mut settings = MethodSettings::new(method, 0.1);
        settings.inner_steps = Some(2);
        settings.friction = Some(1.0);
        settings.tau = Some(1.0);
        let error = integrators::build(&settings, &mut Vec::new())
            .err()
            .unwrap();
        assert!(error.to_string().contains("needs a temperature"), "{error}");
    }
    // A dimensionless scene has no default friction (langevin) or τ (sinr).
    let mut settings = MethodSettings::new("langevin-respa", 0.1);
    settings.temperature = Some(1.0);
    let error = integrators::build(&settings, &mut Vec::new())
        .err()
        .unwrap();
    assert!(error.to_string().contains("--friction"), "{error}");
    let mut settings = MethodSettings::new("sinr", 0.1);
    settings.temperature = Some(1.0);
    let error = integrators::build(&settings, &mut Vec::new())
        .err()
        .unwrap();
    assert!(error.to_string().contains("--tau"), "{error}");
    settings.tau = Some(1.0);
    settings.thermostats = Some(17);
    let error = integrators::build(&settings, &mut Vec::new())
        .err()
        .unwrap();
    assert!(error.to_string().contains("between 1 and 16"), "{error}");
}

#[test]
fn the_same_seed_gives_the_same_steps_and_another_seed_does_not() {
    let run = |method: &str, seed: u64| {
        let mut s = oscillators(4, 1.0, 0.25);
        let mut settings = if method == "sinr" {
            sinr_settings(0.5, 4, 1.0, 2)
        } else {
            settings(method, 0.5, 4, 1.0)
        };
        settings.friction = Some(1.0);
        settings.seed = Some(seed);
        common::integrate(&mut s, build(&settings).as_mut(), 50)
    };
    for method in ["langevin-respa", "sinr"] {
        assert_eq!(run(method, 1), run(method, 1), "{method}");
        assert_ne!(run(method, 1).0, run(method, 2).0, "{method}");
    }
}
