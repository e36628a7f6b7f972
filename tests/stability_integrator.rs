//! Integrator mode: the propagation matrix of one outer step of a registered integrator,
//! measured on the horizontal three-spring scene, against what is known analytically.
//!
//! Today the registry has `verlet`, whose matrix on the linear system is exact (see
//! `verlet_three_spring_matrix`). The multiple-time-step methods are compared with GSS98
//! Lemma 4 as soon as they are registered (`every_registered_mts_method_matches_lemma_4`).

use std::f64::consts::PI;
use std::path::PathBuf;

use longstep::analysis::stability::analytic::LinearProblem;
use longstep::analysis::stability::integrator::{
    INTEGRATOR_TOLERANCE, IntegratorProbe, ProbeScene, verlet_three_spring_matrix,
};
use longstep::analysis::stability::map::{Axis, Evaluator, Grid, evaluate_all};
use longstep::analysis::stability::{AnalyticMethod, InstabilityType, classify_matrix};
use longstep::integrators::METHODS;
use longstep::settings::MethodSettings;

const EPS: f64 = f64::EPSILON;

fn verlet_probe(h: f64) -> IntegratorProbe {
    IntegratorProbe::new(ProbeScene::three_spring(), MethodSettings::new("verlet", h))
        .expect("verlet on the three-spring scene")
}

/// Largest eigenvalue of the stiffness K = [[Ω1² + ½, −½], [−½, Ω2² + ½]].
fn largest_stiffness(omega1: f64, omega2: f64) -> f64 {
    let (a, d) = (omega1 * omega1 + 0.5, omega2 * omega2 + 0.5);
    0.5 * (a + d) + (0.5 * (a - d)).hypot(0.5)
}

#[test]
fn verlet_propagation_matrix_is_the_analytic_one() {
    for h in [0.05, 0.25, 0.5] {
        let probe = verlet_probe(h);
        for (gamma1, gamma2) in [(0.0, 0.0), (0.3, 1.2), (1.5, 0.7), (1.9, 1.9), (2.5, 0.4)] {
            let measured = probe.matrix_at(gamma1, gamma2).expect("linear step");
            let exact = verlet_three_spring_matrix(h, gamma1 / h, gamma2 / h);
            // Central differences with δ = 2⁻⁷ of positions stored absolutely (|x| ≤ 3,
            // the anchors): each output carries ≲ 8 roundings of ½ ulp(3(1 + ‖M‖)), so a
            // column is exact to 8 · ε · 3 (1 + ‖M‖) / (2δ) · 2.
            let norm = exact.amax();
            let tolerance = 8.0 * EPS * 3.0 * (1.0 + norm) * 128.0;
            let error = (&measured - &exact).amax();
            assert!(
                error <= tolerance,
                "h = {h}, Γ = ({gamma1}, {gamma2}): matrix error {error:e} > {tolerance:e}\n\
                 measured {measured}\nexact {exact}"
            );
        }
    }
}

#[test]
fn verlet_spectral_radius_and_stability_limit() {
    // Verlet is stable iff h²λ_max(K) < 4: a real pair leaves the circle at −1 (type 2).
    let h = 0.5;
    let probe = verlet_probe(h);
    for (gamma1, gamma2) in [(0.5, 0.5), (1.0, 1.8), (1.95, 0.2), (2.1, 0.3), (3.0, 3.0)] {
        let point = probe.point(gamma1, gamma2).expect("linear step");
        let exact = classify_matrix(
            &verlet_three_spring_matrix(h, gamma1 / h, gamma2 / h),
            INTEGRATOR_TOLERANCE,
        );
        let limit = h * h * largest_stiffness(gamma1 / h, gamma2 / h);
        // Both matrices agree to ≈ 1e-12 (previous test); their spectral radii to that
        // times the eigenvector condition away from collisions: 1e-9 is ample.
        assert!(
            (point.spectral_radius - exact.spectral_radius).abs() <= 1e-9 * exact.spectral_radius,
            "Γ = ({gamma1}, {gamma2}): ρ {} vs {}",
            point.spectral_radius,
            exact.spectral_radius
        );
        if limit < 4.0 {
            assert_eq!(point.kind, InstabilityType::Stable, "h²λ = {limit}");
        } else {
            assert_eq!(point.kind, InstabilityType::Type2, "h²λ = {limit}");
            // The dominant eigenvalue of the unstable Verlet step: λ + 1/λ = 2 − h²λ_max.
            let c = 2.0 - limit;
            let rho = 0.5 * (c.abs() + (c * c - 4.0).sqrt());
            assert!(
                (point.spectral_radius - rho).abs() <= 1e-9 * rho,
                "ρ {} vs {rho}",
                point.spectral_radius
            );
        }
    }
}

#[test]
fn verlet_map_is_stable_exactly_below_its_limit() {
    // A 41 × 41 map over [0, 3]², h = 1/2: stable iff h²λ_max(K) < 4, except within the
    // band where ρ − 1 ≤ INTEGRATOR_TOLERANCE: just past the limit ρ ≈ 1 + √(h²λ − 4),
    // so points with h²λ − 4 < 1e-12 may read as stable (none on this grid).
    let h = 0.5;
    let axis = Axis::new(0.0, 3.0, 41, "Γ").expect("axis");
    let grid = Grid {
        gamma1: axis,
        gamma2: axis,
    };
    let points = evaluate_all(&Evaluator::Integrator(Box::new(verlet_probe(h))), &grid)
        .expect("integrator map");
    let mut stable = 0;
    for (k, point) in points.iter().enumerate() {
        let (g1, g2) = grid.point(k);
        let limit = h * h * largest_stiffness(g1 / h, g2 / h);
        assert!((limit - 4.0).abs() > 1e-12, "a grid point on the limit");
        assert_eq!(
            point.kind.is_stable(),
            limit < 4.0,
            "Γ = ({g1}, {g2}): h²λ = {limit}, ρ = {}",
            point.spectral_radius
        );
        stable += point.kind.is_stable() as usize;
    }
    eprintln!("verlet map: {stable} of {} points stable", points.len());
    assert!(stable > 0 && stable < points.len());
}

#[test]
fn integrator_mode_rejects_a_scene_not_at_equilibrium_and_unknown_methods() {
    let text = longstep::analysis::stability::integrator::THREE_SPRING_SCENE
        .replace("position = [1.0, 0.0]", "position = [1.1, 0.0]");
    let scene = ProbeScene {
        text,
        path: PathBuf::from("moved.toml"),
    };
    let probe = IntegratorProbe::new(scene, MethodSettings::new("verlet", 0.5)).expect("builds");
    let error = probe.matrix_at(1.0, 1.0).expect_err("not an equilibrium");
    let message = error.to_string();
    assert!(
        message.contains("moved.toml") && message.contains("not an equilibrium"),
        "{message}"
    );
    let unknown =
        IntegratorProbe::new(ProbeScene::three_spring(), MethodSettings::new("nope", 0.5));
    let message = unknown.err().expect("unknown method").to_string();
    assert!(message.contains("unknown method \"nope\""), "{message}");
}

#[test]
fn every_registered_mts_method_matches_lemma_4() {
    // Lemma 4 assumes an exact reduced flow and exact averages; with K inner Verlet steps
    // the reduced rotation's phase is off by ≈ K (Γ/K)³/24 = Γ³/(24K²) per outer step,
    // ≤ 2.2e-4 at Γ ≤ 2π, K = 200. The test points sit inside instability regions whose
    // Γ-widths are ≥ 5e-3 (or deep in the stable region), where ρ − 1 changes by a
    // relative O((2.2e-4 / 5e-3)²) ≈ 2e-3 from such a shift; 5 % leaves room for the O(dt²)
    // error of the averages.
    let h = 0.5;
    let inner_steps = 200;
    let mut checked = Vec::new();
    for method in AnalyticMethod::ALL {
        if !METHODS.iter().any(|m| m.name == method.name()) {
            continue;
        }
        let probe = IntegratorProbe::new(
            ProbeScene::three_spring(),
            MethodSettings::new(method.name(), h).with_inner_steps(inner_steps),
        )
        .expect("builds");
        let problem = LinearProblem::three_spring(method, h).expect("valid");
        let alpha1 = 0.5;
        let shift = |gamma: f64| 0.5 * h * h * alpha1 * method.filter(gamma).powi(2) / gamma;
        let points = [
            (0.5, 0.8),
            (2.0, 1.0),
            (PI - shift(PI), 1.0),
            (2.0 * PI - shift(2.0 * PI), 1.0),
        ];
        for (g1, g2) in points {
            let analytic = problem.point(g1, g2);
            let measured = probe.point(g1, g2).expect("linear step");
            if analytic.kind.is_stable() {
                assert!(
                    measured.kind.is_stable(),
                    "{} at ({g1}, {g2}): analytic stable, integrator ρ = {}",
                    method.name(),
                    measured.spectral_radius
                );
            } else {
                assert_eq!(
                    measured.kind,
                    analytic.kind,
                    "{} at ({g1}, {g2})",
                    method.name()
                );
                assert!(
                    (measured.excess - analytic.excess).abs() <= 0.05 * analytic.excess,
                    "{} at ({g1}, {g2}): ρ − 1 = {} (integrator) vs {} (Lemma 4)",
                    method.name(),
                    measured.excess,
                    analytic.excess
                );
            }
        }
        checked.push(method.name());
    }
    eprintln!("methods compared with Lemma 4: {checked:?} (others not registered yet)");
}
