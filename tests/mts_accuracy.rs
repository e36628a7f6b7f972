//! Accuracy of the impulse and mollified methods: the filters of GSS98 section 5, the
//! opening example of section 2, second-order convergence, and the order reduction of the
//! impulse method at hΩ = 2π (section 6).

mod common;

use common::{integrate, method, scene};
use longstep::integrators::mollified::{Average, JacobianChoice, JacobianMode, Mollifier};

/// A unit mass on a linear spring of frequency `omega` to the origin, 1-D, plus an optional
/// constant slow force `force`.
fn stiff_spring(omega: f64, force: f64, q0: f64, p0: f64) -> String {
    format!(
        r#"
version = 1
name = "stiff-spring"
dim = 1
[anchors]
origin = [0.0]
[[particles]]
mass = 1.0
position = [{q0}]
momentum = [{p0}]
[[terms]]
type = "spring"
between = ["origin", 0]
stiffness = {k}
[[terms]]
type = "field"
force = [{force}]
"#,
        k = omega * omega
    )
}

/// A_q of the averaging on the linear stiff spring (a 1×1 Jacobian) with `inner` steps.
fn linear_filter(average: Average, gamma: f64, inner: usize) -> f64 {
    let h = 1.0;
    let mut s = scene(&stiff_spring(gamma / h, 0.0, 0.3, 0.0));
    let mut m = Mollifier::new(
        average,
        JacobianChoice::Fixed(JacobianMode::Adjoint),
        h,
        inner,
    );
    m.setup(1, &[vec![0]]);
    let system = &mut s.system;
    let q = system.state.q.clone();
    m.compute_average(&mut system.forces, &system.inverse_mass, &q, None);
    let mut out = [0.0];
    m.transpose_product(&mut system.forces, &system.inverse_mass, &[1.0], &mut out);
    // On a linear problem A is linear in q: A(q) = A_q q.
    let average_ratio = m.averaged_positions()[0] / q[0];
    assert!(
        (average_ratio - out[0]).abs() < 1e-12,
        "A ≠ A_q q on a linear spring"
    );
    out[0]
}

#[test]
fn averaging_on_a_linear_spring_gives_the_filters_of_section_5() {
    // As dt → 0 the averaging of q(t) = q0 cos Ωt gives A_q = Φ(Γ), Γ = hΩ:
    // sin(Γ/2)/(Γ/2) (Short), sin Γ/Γ (Long), (sin(Γ/2)/(Γ/2))² (Linear); Impulse has Φ = 1.
    // The numerical average differs by the inner Verlet's phase error and the trapezoid
    // rule, both O((Ω dt)²): the error must fall at least ~4-fold when the inner step halves
    // (faster where the O(dt²) term vanishes, e.g. LinearAverage at Γ = 2π).
    for average in [Average::Short, Average::Long, Average::Linear] {
        for gamma in [
            1.0,
            2.5,
            std::f64::consts::PI,
            5.0,
            2.0 * std::f64::consts::PI,
            9.0,
        ] {
            let exact = average.filter(gamma);
            let coarse = (linear_filter(average, gamma, 400) - exact).abs();
            let fine = (linear_filter(average, gamma, 800) - exact).abs();
            assert!(fine < 2e-4, "{average:?}, Γ = {gamma}: error {fine:e}");
            if coarse > 1e-10 {
                let ratio = coarse / fine;
                assert!(ratio > 3.5, "{average:?}, Γ = {gamma}: ratio {ratio}");
            }
        }
    }
}

#[test]
fn opening_example_impulse_drifts_by_h_f_per_step_mollified_methods_do_not() {
    // GSS98 section 2: q'' = −Ω²q + F, q(0) = 0, p(0) = 1, hΩ = 2π. The exact momentum is
    // p(t) = cos Ωt + (F/Ω) sin Ωt = 1 at every t = nh. The impulse method adds hF per step
    // (the reduced flow returns to its start after one period); the mollified methods'
    // filters vanish at Γ = 2π, so they stay near 1 (within O(h); here the remainder is
    // the O((Ω dt)²) of the inner Verlet).
    let (omega, force, inner, steps) = (20.0, 0.3, 200, 40);
    let h = std::f64::consts::TAU / omega;
    let mut s = scene(&stiff_spring(omega, force, 0.0, 1.0));
    let (_, p) = integrate(&mut s, method("impulse", h, Some(inner)).as_mut(), steps);
    let drift = p[0] - 1.0;
    let expected = steps as f64 * h * force;
    assert!(
        (drift - expected).abs() < 0.02 * expected,
        "impulse: momentum drift {drift}, n h F = {expected}"
    );
    for name in ["short-average", "long-average", "linear-average"] {
        let mut s = scene(&stiff_spring(omega, force, 0.0, 1.0));
        let mut integrator = method(name, h, Some(inner));
        integrator.setup(&mut s.system).unwrap();
        let mut worst: f64 = 0.0;
        for _ in 0..steps {
            integrator.step(&mut s.system).unwrap();
            worst = worst.max((s.system.state.p[0] - 1.0).abs());
        }
        assert!(
            worst < h * force,
            "{name}: |p − 1| reaches {worst}, h F = {}",
            h * force
        );
    }
}

/// The nonlinear two-spring system of GSS98 section 4 (Ω1 = 10, 2-D initial data).
fn two_spring() -> longstep::io::scene::Scene {
    common::scene_file("systems/two-spring.toml", &[])
}

/// Max position error at the step points on [0, t_end] against a fine Verlet reference.
fn max_position_error(name: &str, h: f64, inner: usize, t_end: f64) -> f64 {
    let reference_steps_per_h = 2000;
    let mut reference = two_spring();
    let mut verlet = method("verlet", h / reference_steps_per_h as f64, None);
    verlet.setup(&mut reference.system).unwrap();
    let mut s = two_spring();
    let mut integrator = method(name, h, Some(inner));
    integrator.setup(&mut s.system).unwrap();
    let steps = (t_end / h).round() as usize;
    let mut worst: f64 = 0.0;
    for _ in 0..steps {
        for _ in 0..reference_steps_per_h {
            verlet.step(&mut reference.system).unwrap();
        }
        integrator.step(&mut s.system).unwrap();
        worst = worst.max(common::max_abs_difference(
            &s.system.state.q,
            &reference.system.state.q,
        ));
    }
    worst
}

#[test]
fn all_methods_are_second_order_on_the_nonlinear_two_spring_system() {
    // Fixed stiffness (Ω1 = 10), inner steps K = 10 so dt = h/10 shrinks with h: every
    // method is a second-order scheme, and halving h must divide the error by 4 (the
    // O(h⁴) remainder at hΩ1 ≤ 0.5 moves the ratio by well under 15 %).
    for name in common::MTS_METHODS {
        let errors: Vec<f64> = [0.05, 0.025, 0.0125]
            .iter()
            .map(|&h| max_position_error(name, h, 10, 4.0))
            .collect();
        for pair in errors.windows(2) {
            let ratio = pair[0] / pair[1];
            assert!(
                (3.4..4.6).contains(&ratio),
                "{name}: error ratio {ratio} when h halves (errors {errors:?})"
            );
        }
    }
}

/// GSS98 section 6: three-spring system with Ω2 = 0 in 1-D, hΩ1 = 2π held as h → 0, started
/// on the fast eigenmode. Returns the max position error over [0, t_end].
fn order_reduction_error(name: &str, h: f64, t_end: f64) -> f64 {
    let omega1 = std::f64::consts::TAU / h;
    // The fast frequency Ω+ of K = [[Ω1² + 1/2, −1/2], [−1/2, 1/2]] and its eigenmode.
    let (a, d) = (omega1 * omega1 + 0.5, 0.5);
    let fast = (0.5 * (a + d) + (0.25 * (a - d) * (a - d) + 0.25).sqrt()).sqrt();
    let big_q0 = 1.0 / fast;
    let small_q0 = -big_q0 / (2.0 * fast * fast - 1.0);
    let text = format!(
        r#"
version = 1
name = "section6"
dim = 1
[anchors]
wall = [0.0]
[[particles]]
mass = 1.0
position = [{x1}]
[[particles]]
mass = 1.0
position = [{x2}]
[[terms]]
type = "spring"
between = ["wall", 0]
stiffness = {k}
rest_length = 1.0
[[terms]]
type = "spring"
between = [0, 1]
stiffness = 0.5
rest_length = 1.0
group = "slow"
"#,
        x1 = 1.0 + big_q0,
        x2 = 2.0 + small_q0,
        k = omega1 * omega1
    );
    // Fine inner steps: the paper assumes the reduced flow exact; Ω1 dt = 2π/2000.
    let inner = 2000;
    let mut s = scene(&text);
    let mut integrator = method(name, h, Some(inner));
    integrator.setup(&mut s.system).unwrap();
    let steps = (t_end / h).round() as usize;
    let mut worst: f64 = 0.0;
    for n in 1..=steps {
        integrator.step(&mut s.system).unwrap();
        let t = n as f64 * h;
        // The exact solution is the eigenmode: both coordinates ∝ cos(Ω+ t).
        let exact = [
            1.0 + big_q0 * (fast * t).cos(),
            2.0 + small_q0 * (fast * t).cos(),
        ];
        worst = worst.max(common::max_abs_difference(&s.system.state.q, &exact));
    }
    worst
}

#[test]
fn impulse_is_first_order_and_long_average_second_order_at_h_omega_2_pi() {
    // Impulse: q_n = (1/Ω+)(1 − cos(√2/2 t)) + O(h²) = O(h) while the exact q is O(h³), so
    // the error halves with h. LongAverage keeps its O(h²) bound independent of Ω1 (GSS98
    // Theorem 1): the error quarters. t_end = 4.4 ≈ π/(√2/2), where 1 − cos peaks.
    let t_end = 4.4;
    let hs = [1.0 / 8.0, 1.0 / 16.0, 1.0 / 32.0];
    let impulse: Vec<f64> = hs
        .iter()
        .map(|&h| order_reduction_error("impulse", h, t_end))
        .collect();
    let long: Vec<f64> = hs
        .iter()
        .map(|&h| order_reduction_error("long-average", h, t_end))
        .collect();
    for pair in impulse.windows(2) {
        let ratio = pair[0] / pair[1];
        assert!(
            (1.7..2.3).contains(&ratio),
            "impulse ratio {ratio}, errors {impulse:?}"
        );
    }
    for pair in long.windows(2) {
        let ratio = pair[0] / pair[1];
        assert!(ratio > 3.4, "long-average ratio {ratio}, errors {long:?}");
    }
    // And in size: impulse ≈ 2/Ω+ ≈ h/π at the peak of 1 − cos.
    let h = hs[0];
    assert!(
        (impulse[0] / (h / std::f64::consts::PI) - 1.0).abs() < 0.2,
        "{impulse:?}"
    );
}
