//! GSS98 Lemma 4 and Lemma 5: the matrix A′ of the proof against the quartic (28), the
//! closed-form roots against a general eigenvalue solver, and Lemma 5's conditions
//! against the eigenvalues.

use std::f64::consts::PI;

use longstep::analysis::stability::analytic::{LinearProblem, Quartic};
use longstep::analysis::stability::{
    AnalyticMethod, Coupling, InstabilityType, classify_eigenvalues, eigenvalues,
};
use nalgebra::{Complex, DMatrix, Matrix4};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

const EPS: f64 = f64::EPSILON;

/// Characteristic polynomial det(λI − A) = λ⁴ + c1 λ³ + c2 λ² + c3 λ + c4 by
/// Faddeev–LeVerrier, highest power first.
fn characteristic_polynomial(a: &Matrix4<f64>) -> [f64; 5] {
    let mut coefficients = [1.0, 0.0, 0.0, 0.0, 0.0];
    let mut m = Matrix4::<f64>::zeros();
    for k in 1..=4 {
        m = a * m + Matrix4::identity() * coefficients[k - 1];
        coefficients[k] = -(a * m).trace() / k as f64;
    }
    coefficients
}

fn random_problem(rng: &mut StdRng, method: AnalyticMethod) -> (LinearProblem, f64, f64) {
    // A random semidefinite coupling: α_i ∈ [0, 2], β² ≤ α1 α2.
    let alpha1: f64 = rng.random_range(0.0..2.0);
    let alpha2 = rng.random_range(0.0..2.0);
    let beta = (alpha1 * alpha2).sqrt() * rng.random_range(-1.0..1.0);
    let coupling = Coupling {
        alpha1,
        alpha2,
        beta,
    };
    let h = rng.random_range(0.05..1.5);
    let problem = LinearProblem::new(method, h, coupling).expect("valid problem");
    (
        problem,
        rng.random_range(0.0..4.0 * std::f64::consts::PI),
        rng.random_range(0.0..4.0 * std::f64::consts::PI),
    )
}

#[test]
fn a_prime_has_the_quartic_of_lemma_4_as_characteristic_polynomial() {
    let mut rng = StdRng::seed_from_u64(4);
    for method in AnalyticMethod::ALL {
        let mut worst: f64 = 0.0;
        for _ in 0..2000 {
            let (problem, g1, g2) = random_problem(&mut rng, method);
            let a = problem.a_prime(g1, g2);
            let from_matrix = characteristic_polynomial(&a);
            let from_lemma = problem.quartic(g1, g2).coefficients();
            // Faddeev–LeVerrier forms products of up to four matrices: the k-th coefficient
            // carries a rounding error of about 4k ε ‖A‖ᵏ; bound all by 16 ε (1 + ‖A‖)⁴.
            let norm = a.norm();
            let tolerance = 16.0 * EPS * (1.0 + norm).powi(4);
            for k in 0..5 {
                let error = (from_matrix[k] - from_lemma[k]).abs();
                worst = worst.max(error / tolerance);
                assert!(
                    error <= tolerance,
                    "{}: coefficient {k} at h = {}, Γ = ({g1}, {g2}): A′ gives {}, (28) gives {} \
                     (tolerance {tolerance:e})",
                    method.name(),
                    problem.h,
                    from_matrix[k],
                    from_lemma[k]
                );
            }
        }
        eprintln!(
            "{}: worst coefficient error {worst:.2e} of its tolerance",
            method.name()
        );
    }
}

/// Pair each computed eigenvalue with the nearest unused root; the largest distance.
fn match_roots(eigen: &[Complex<f64>], roots: &[Complex<f64>]) -> f64 {
    let mut used = [false; 4];
    let mut worst: f64 = 0.0;
    for e in eigen {
        let (best, distance) = roots
            .iter()
            .enumerate()
            .filter(|(i, _)| !used[*i])
            .map(|(i, r)| (i, (e - r).norm()))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .expect("four roots");
        used[best] = true;
        worst = worst.max(distance);
    }
    worst
}

#[test]
fn closed_form_roots_are_the_eigenvalues_of_a_prime() {
    let mut rng = StdRng::seed_from_u64(5);
    for method in AnalyticMethod::ALL {
        for _ in 0..2000 {
            let (problem, g1, g2) = random_problem(&mut rng, method);
            let a = problem.a_prime(g1, g2);
            let eigen = eigenvalues(&DMatrix::from_iterator(4, 4, a.iter().copied()))
                .expect("finite matrix");
            let roots = problem.quartic(g1, g2).roots();
            // A perturbation of size ε‖A‖ moves a simple eigenvalue by about that much and
            // a double one (a collision, the edge of every instability region) by
            // √(ε‖A‖); a random sample lands near a collision, so bound by
            // 16 √(ε (1 + ‖A‖)) (the factor covers the eigenvector conditioning of A′).
            let tolerance = 16.0 * (EPS * (1.0 + a.norm())).sqrt();
            let distance = match_roots(&eigen, &roots);
            assert!(
                distance <= tolerance,
                "{} h = {} Γ = ({g1}, {g2}): eigenvalues {eigen:?} vs roots {roots:?}",
                method.name(),
                problem.h
            );
        }
    }
}

#[test]
fn lemma_5_conditions_decide_stability_like_the_eigenvalues_of_a_prime() {
    let mut rng = StdRng::seed_from_u64(6);
    let mut counts = [0usize; 4];
    for method in AnalyticMethod::ALL {
        for _ in 0..4000 {
            let (problem, g1, g2) = random_problem(&mut rng, method);
            let quartic = problem.quartic(g1, g2);
            // Lemma 5's margins; skip points within 1e-6 of a boundary, where the
            // eigenvalue solver's √(ε‖A‖) ≈ 1e-7 error could flip the answer.
            let margin = quartic
                .d
                .abs()
                .min((2.0 - quartic.d.max(0.0).sqrt() - quartic.s.abs()).abs());
            if margin < 1e-6 {
                continue;
            }
            let a = problem.a_prime(g1, g2);
            let eigen = eigenvalues(&DMatrix::from_iterator(4, 4, a.iter().copied()))
                .expect("finite matrix");
            // Stable eigenvalues have modulus 1 up to √(ε‖A‖) (collisions); 1e-6 is
            // far above that for ‖A‖ ≤ 100 and far below the margin's effect on ρ
            // (ρ − 1 ≥ √margin / 2 ≈ 5e-4 at an unstable point with margin 1e-6).
            let from_eigen = classify_eigenvalues(&eigen, 1e-6);
            let closed = quartic.classify();
            assert_eq!(
                quartic.lemma5_stable(),
                from_eigen.kind.is_stable(),
                "{} h = {} Γ = ({g1}, {g2}): Lemma 5 and the eigenvalues disagree (S = {}, D = {}, ρ = {})",
                method.name(),
                problem.h,
                quartic.s,
                quartic.d,
                from_eigen.spectral_radius
            );
            assert_eq!(
                closed.kind,
                from_eigen.kind,
                "{} h = {} Γ = ({g1}, {g2}): types differ",
                method.name(),
                problem.h
            );
            // Away from collisions the eigenvalues are simple: ρ agrees to about
            // ε‖A‖ times the eigenvector conditioning; 1e-9 allows a condition of 1e5.
            assert!(
                (closed.spectral_radius - from_eigen.spectral_radius).abs()
                    <= 1e-9 * (1.0 + a.norm()),
                "{} Γ = ({g1}, {g2}): ρ {} (roots) vs {} (eigenvalues)",
                method.name(),
                closed.spectral_radius,
                from_eigen.spectral_radius
            );
            counts[match closed.kind {
                InstabilityType::Stable => 0,
                InstabilityType::Type1 => 1,
                InstabilityType::Type2 => 2,
                _ => 3,
            }] += 1;
        }
    }
    eprintln!("checked points: stable, type 1, type 2, type 3 = {counts:?}");
    // The random sample must exercise every branch, or the test proves little.
    assert!(counts.iter().all(|&c| c > 20), "{counts:?}");
}

#[test]
fn boundary_conditions_30_and_31_put_a_root_at_minus_one_and_plus_one() {
    // On (30) the quartic vanishes at λ = −1, on (31) at λ = +1. Find such points by
    // bisection in Γ1 at fixed Γ2 and check A′ itself there.
    let problem = LinearProblem::three_spring(AnalyticMethod::Impulse, 0.5).expect("valid");
    let gamma2 = 1.0;
    type Boundary = fn(&Quartic) -> f64;
    // Type 2 just below Γ1 = π, type 3 just below 2π: the upper ends are Propositions 2
    // and 3's points Γ − ½h²α1Φ(Γ)²/Γ (Φ = 1), inside the regions.
    let shift = |gamma: f64| 0.5 * 0.25 * 0.5 / gamma;
    let cases: [(f64, f64, Boundary, f64); 2] = [
        (3.0, PI - shift(PI), |q| q.type2_boundary(), -1.0),
        (6.2, 2.0 * PI - shift(2.0 * PI), |q| q.type3_boundary(), 1.0),
    ];
    for (mut low, mut high, boundary, root) in cases {
        let f = |g1: f64| boundary(&problem.quartic(g1, gamma2));
        assert!(
            f(low) * f(high) < 0.0,
            "no sign change of the boundary function on [{low}, {high}]"
        );
        for _ in 0..200 {
            let mid = 0.5 * (low + high);
            if f(mid) * f(low) > 0.0 {
                low = mid;
            } else {
                high = mid;
            }
        }
        let a = problem.a_prime(low, gamma2);
        let determinant = (Matrix4::identity() * root - a).determinant();
        // det(λI − A′) at λ = ±1 is 4 × the boundary function; at the root its size is
        // the rounding of a 4×4 determinant, ≈ 24 ε ‖A‖⁴.
        let tolerance = 24.0 * EPS * (1.0 + a.norm()).powi(4);
        assert!(
            determinant.abs() <= tolerance,
            "det(±I − A′) = {determinant:e} at Γ1 = {low} (tolerance {tolerance:e})"
        );
        // And the quartic's identity: boundary = ((2 ∓ S)² − D)/4.
        let q = problem.quartic(low, gamma2);
        let identity = 0.25 * ((2.0 - root * q.s).powi(2) - q.d);
        assert!((boundary(&q) - identity).abs() <= 16.0 * EPS);
    }
}
