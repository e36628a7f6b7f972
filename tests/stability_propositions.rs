//! GSS98 Propositions 1–4 and footnote 2, from Lemma 4 (analytic mode).
//!
//! Propositions 1–3 give worst-case spectral radii `1 + c h² + O(h⁴)`. Each test computes
//! the remainder `r(h) = ρ(h) − 1 − c h²` at h = 1/2, 1/4, …, 1/128: if it is O(h⁴),
//! `r(h) / r(h/2) → 16`, with a relative deviation of order h² from the next term
//! (`r = a h⁴ + b h⁶ + …` gives `r(h)/r(h/2) = 16 (1 + ¾ (b/a) h² + …)`). Where c is small
//! against the O(h⁴) constant (a filter nearly zero at Γ or Γ̄) the asymptotic regime starts
//! late, so the test asserts it on the last three pairs: the deviation shrinks at least
//! twofold per halving (fourfold is expected) and ends below 1/2.

use std::f64::consts::PI;

use longstep::analysis::stability::analytic::LinearProblem;
use longstep::analysis::stability::{AnalyticMethod, Coupling, InstabilityType};

const EPS: f64 = f64::EPSILON;
/// Where the exact spectral radius is 1 on a stability boundary, the closed form's S and √D
/// carry ≈ 8 ε of rounding, so m = a − 1 ≤ 4 ε and ρ − 1 = m + √(m(m + 2)) ≤ √(8 ε) + 4ε.
const BOUNDARY_ROUND_OFF: f64 = 4.3e-8;

const STEPS: [f64; 7] = [0.5, 0.25, 0.125, 0.0625, 0.03125, 0.015625, 0.0078125];

/// Check `ρ(h) = 1 + c h² + O(h⁴)` over [`STEPS`]; `excess(h)` = ρ(h) − 1 and `c` given.
fn assert_second_order(what: &str, c: f64, excess: impl Fn(f64) -> f64) {
    let remainders: Vec<f64> = STEPS.iter().map(|&h| excess(h) - c * h * h).collect();
    let mut deviations = Vec::new();
    for k in 0..STEPS.len() - 1 {
        let ratio = remainders[k] / remainders[k + 1];
        eprintln!(
            "{what}: h = {}: ρ − 1 = {:.6e}, c h² = {:.6e}, r(h)/r(h/2) = {ratio:.4}",
            STEPS[k],
            excess(STEPS[k]),
            c * STEPS[k] * STEPS[k]
        );
        deviations.push((ratio - 16.0).abs());
    }
    // The deviation from 16 is O(h²): over the last three pairs it must shrink at least
    // twofold per halving and end below 1/2 (h = 1/64 → 1/128).
    // Rounding: ρ − 1 (`excess`) is accurate to relative round-off (closed form without
    // cancellation), and r ≈ ρ − 1 times O(h²) ≥ 1e-5 (ρ − 1) here, so r carries a
    // relative error of at most ≈ 1e-16 / 1e-5 · (a few) ≈ 1e-10 at h = 1/128.
    let tail = &deviations[deviations.len() - 3..];
    for pair in tail.windows(2) {
        assert!(
            pair[1] <= 0.5 * pair[0],
            "{what}: deviations of r(h)/r(h/2) from 16 do not shrink like h²: {deviations:?}"
        );
    }
    let last = tail[tail.len() - 1];
    assert!(
        last <= 0.5,
        "{what}: r(h)/r(h/2) is {last} from 16 at h = {}: not O(h⁴)",
        STEPS[STEPS.len() - 2]
    );
}

/// The Proposition-1 point: Γ1 = Γ − ½h²α1Φ(Γ)²/Γ, Γ2 = Γ̄ − ½h²α2Φ(Γ̄)²/Γ̄.
fn proposition1_excess(method: AnalyticMethod, gamma: f64, gamma_bar: f64, h: f64) -> f64 {
    let coupling = Coupling::default();
    let problem = LinearProblem::new(method, h, coupling).expect("valid");
    let phi = |g: f64| method.filter(g);
    let g1 = gamma - 0.5 * h * h * coupling.alpha1 * phi(gamma).powi(2) / gamma;
    let g2 = gamma_bar - 0.5 * h * h * coupling.alpha2 * phi(gamma_bar).powi(2) / gamma_bar;
    let point = problem.point(g1, g2);
    // Asymptotically a type-1 point (at h = 1/2 a large shift can leave the strip).
    if h <= 0.0625 {
        assert_eq!(
            point.kind,
            InstabilityType::Type1,
            "{method:?} at ({g1}, {g2})"
        );
    }
    point.excess
}

/// ½|β| √(Φ(Γ)²Γ⁻¹ Φ(Γ̄)²Γ̄⁻¹): the h² coefficient of Proposition 1.
fn proposition1_coefficient(method: AnalyticMethod, gamma: f64, gamma_bar: f64) -> f64 {
    let beta = Coupling::default().beta;
    let phi = |g: f64| method.filter(g);
    0.5 * beta.abs() * (phi(gamma).powi(2) / gamma * phi(gamma_bar).powi(2) / gamma_bar).sqrt()
}

#[test]
fn proposition_1_long_average_at_two_thirds_pi() {
    let method = AnalyticMethod::LongAverage;
    let (gamma, gamma_bar) = (2.0 * PI / 3.0, 4.0 * PI / 3.0);
    // The paper's closed form 1 + h²|β|·81/(128√2π³) is Proposition 1's coefficient here:
    // Φ(2π/3) = 3√3/(4π), Φ(4π/3) = −3√3/(8π).
    let beta = Coupling::default().beta;
    let paper = beta.abs() * 81.0 / (128.0 * 2f64.sqrt() * PI.powi(3));
    let general = proposition1_coefficient(method, gamma, gamma_bar);
    assert!(
        (paper - general).abs() <= 16.0 * EPS * paper,
        "81/(128√2π³)|β| = {paper} but Proposition 1's coefficient is {general}"
    );
    assert_second_order("LongAverage, Γ = 2π/3", paper, |h| {
        proposition1_excess(method, gamma, gamma_bar, h)
    });
}

#[test]
fn proposition_1_holds_for_every_method_along_the_first_strip() {
    // Γ + Γ̄ = 2π with Γ not a multiple of π; and Γ + Γ̄ = 4π for the second strip. (Where
    // a filter nearly vanishes, as LinearAverage's at Γ̄ = 2π − 0.7, c is tiny and the
    // O(h⁴) term dominates down to h ≈ 1/100: not a worst case, not tested here.)
    for method in AnalyticMethod::ALL {
        for (gamma, total) in [(2.0 * PI / 3.0, 2.0 * PI), (2.0, 2.0 * PI), (4.0, 4.0 * PI)] {
            let gamma_bar = total - gamma;
            let c = proposition1_coefficient(method, gamma, gamma_bar);
            if c == 0.0 {
                continue;
            }
            assert_second_order(
                &format!("{} Γ = {gamma}, Γ̄ = {gamma_bar:.4}", method.paper_name()),
                c,
                |h| proposition1_excess(method, gamma, gamma_bar, h),
            );
        }
    }
}

/// Γ1 = Γ − ½h²α1Φ(Γ)²/Γ with the given Γ, and Γ2 fixed.
fn shifted_excess(
    method: AnalyticMethod,
    gamma: f64,
    gamma2: f64,
    h: f64,
) -> (f64, InstabilityType) {
    let coupling = Coupling::default();
    let problem = LinearProblem::new(method, h, coupling).expect("valid");
    let g1 = gamma - 0.5 * h * h * coupling.alpha1 * method.filter(gamma).powi(2) / gamma;
    let point = problem.point(g1, gamma2);
    (point.excess, point.kind)
}

#[test]
fn proposition_2_type_2_near_odd_multiples_of_pi() {
    let alpha1 = Coupling::default().alpha1;
    for method in [
        AnalyticMethod::Impulse,
        AnalyticMethod::ShortAverage,
        AnalyticMethod::LinearAverage,
    ] {
        for (gamma, gamma2) in [(PI, 1.0), (PI, 0.0), (3.0 * PI, 2.0)] {
            let c = 0.5 * alpha1 * method.filter(gamma).powi(2) / gamma;
            let (_, kind) = shifted_excess(method, gamma, gamma2, 0.5);
            assert_eq!(kind, InstabilityType::Type2, "{method:?} Γ = {gamma}");
            assert_second_order(
                &format!(
                    "{} type 2, Γ = {:.4}, Γ2 = {gamma2}",
                    method.paper_name(),
                    gamma
                ),
                c,
                |h| shifted_excess(method, gamma, gamma2, h).0,
            );
        }
    }
}

#[test]
fn long_average_has_no_type_2_at_odd_multiples_of_pi() {
    // Φ(π) = sin π / π = 0 (GSS98 after Proposition 2): the shift vanishes and so does the
    // instability. Scan Γ1 across π and 3π finely (step 1e-5) at several Γ2.
    let problem = LinearProblem::three_spring(AnalyticMethod::LongAverage, 0.5).expect("valid");
    for centre in [PI, 3.0 * PI] {
        for gamma2 in [0.0, 1.0, 2.0, 4.0] {
            for k in -10_000..=10_000 {
                let g1 = centre + 1e-5 * k as f64;
                let point = problem.point(g1, gamma2);
                assert!(
                    point.kind != InstabilityType::Type2
                        && point.spectral_radius <= 1.0 + BOUNDARY_ROUND_OFF,
                    "LongAverage at ({g1}, {gamma2}): ρ = {}, {:?}",
                    point.spectral_radius,
                    point.kind
                );
            }
        }
    }
}

#[test]
fn proposition_3_impulse_type_3_below_even_multiples_of_pi() {
    let alpha1 = Coupling::default().alpha1;
    let method = AnalyticMethod::Impulse;
    // Γ2 must not be an even multiple of π (ERRATA: with Γ2 = 0, (31) cannot hold).
    for (gamma, gamma2) in [(2.0 * PI, 1.0), (4.0 * PI, 2.5)] {
        let c = 0.5 * alpha1 * method.filter(gamma).powi(2) / gamma;
        let (_, kind) = shifted_excess(method, gamma, gamma2, 0.5);
        assert_eq!(kind, InstabilityType::Type3, "Γ = {gamma}");
        assert_second_order(
            &format!("Impulse type 3, Γ = {gamma:.4}, Γ2 = {gamma2}"),
            c,
            |h| shifted_excess(method, gamma, gamma2, h).0,
        );
    }
    // With Γ2 = 0 the same point is not type 3 (ERRATA, Figure 10).
    let (rho, kind) = shifted_excess(method, 2.0 * PI, 0.0, 0.5);
    assert!(
        kind != InstabilityType::Type3,
        "Impulse at Γ2 = 0 near 2π: ρ = {rho}, {kind:?}"
    );
}

#[test]
fn proposition_4_long_average_is_stable_below_pi_for_h_omega_up_to_2() {
    // The three-spring form of the coupling scaled to hω: α1 = α2 = ω²/2, β = −ω²/2
    // (ω² is U's largest eigenvalue). Only h²α and h²β enter Lemma 4, so fix h = 1/2 and
    // vary ω. Sampling: Γ1, Γ2 on a 241-point grid of [0, π] (both ends included) plus
    // the points π − 10⁻ᵏ, k = 1…8, where the filters and cos Γ + 1 vanish together; hω
    // from 0.1 to 2 in steps of 0.1 (the limit 2 included).
    let h = 0.5;
    let mut gammas: Vec<f64> = (0..=240).map(|i| PI * i as f64 / 240.0).collect();
    gammas.extend((1..=8).map(|k| PI - 10f64.powi(-k)));
    let mut checked = 0usize;
    let mut worst: f64 = 0.0;
    for step in 1..=20 {
        let h_omega = 0.1 * step as f64;
        let omega2 = (h_omega / h).powi(2);
        let coupling = Coupling {
            alpha1: 0.5 * omega2,
            alpha2: 0.5 * omega2,
            beta: -0.5 * omega2,
        };
        let problem = LinearProblem::new(AnalyticMethod::LongAverage, h, coupling).expect("valid");
        for &g1 in &gammas {
            for &g2 in &gammas {
                let point = problem.point(g1, g2);
                worst = worst.max(point.spectral_radius - 1.0);
                assert!(
                    point.spectral_radius <= 1.0 + BOUNDARY_ROUND_OFF,
                    "LongAverage unstable at hω = {h_omega}, Γ = ({g1}, {g2}): ρ = {}, {:?}",
                    point.spectral_radius,
                    point.kind
                );
                checked += 1;
            }
        }
    }
    eprintln!("Proposition 4 (three-spring coupling): {checked} points, max ρ − 1 = {worst:e}");
}

#[test]
fn proposition_4_holds_for_random_semidefinite_couplings() {
    use rand::rngs::StdRng;
    use rand::{RngExt, SeedableRng};
    // Proposition 4 covers any semidefinite U with hω ≤ 2: draw U = R diag(λ1, λ2) Rᵀ with
    // h²λ_max uniform in (0, 4], λ_min/λ_max uniform in [0, 1], a random rotation, and
    // Γ1, Γ2 uniform in [0, π].
    let mut rng = StdRng::seed_from_u64(44);
    let h = 0.5;
    let mut worst: f64 = 0.0;
    for _ in 0..200_000 {
        let largest = rng.random_range(0.0..=4.0) / (h * h);
        let smallest = largest * rng.random_range(0.0..=1.0);
        let angle: f64 = rng.random_range(0.0..PI);
        let (s, c) = angle.sin_cos();
        let coupling = Coupling {
            alpha1: largest * c * c + smallest * s * s,
            alpha2: largest * s * s + smallest * c * c,
            beta: (largest - smallest) * s * c,
        };
        assert!(h * h * coupling.omega_squared() <= 4.0 * (1.0 + 4.0 * EPS));
        let problem = LinearProblem::new(AnalyticMethod::LongAverage, h, coupling).expect("valid");
        let (g1, g2) = (rng.random_range(0.0..=PI), rng.random_range(0.0..=PI));
        let point = problem.point(g1, g2);
        worst = worst.max(point.spectral_radius - 1.0);
        assert!(
            point.spectral_radius <= 1.0 + BOUNDARY_ROUND_OFF,
            "LongAverage unstable with {coupling:?}, Γ = ({g1}, {g2}): ρ = {}",
            point.spectral_radius
        );
    }
    eprintln!("Proposition 4 (random couplings): max ρ − 1 = {worst:e}");
}

#[test]
fn the_other_methods_are_unstable_below_pi_at_small_h_omega() {
    // GSS98 section 3: "for the other methods as the Γi approaches π, the stability
    // threshold for hω goes to 0". At Γ2 = 1 and Γ1 just below π (Proposition 2's point)
    // Impulse, ShortAverage and LinearAverage are unstable for hω = 2, 1, 1/2, 1/8.
    for method in [
        AnalyticMethod::Impulse,
        AnalyticMethod::ShortAverage,
        AnalyticMethod::LinearAverage,
    ] {
        for h_omega in [2.0, 1.0, 0.5, 0.125] {
            let h: f64 = 0.5;
            let omega2 = (h_omega / h).powi(2);
            let coupling = Coupling {
                alpha1: 0.5 * omega2,
                alpha2: 0.5 * omega2,
                beta: -0.5 * omega2,
            };
            let problem = LinearProblem::new(method, h, coupling).expect("valid");
            let shift = 0.5 * h * h * coupling.alpha1 * method.filter(PI).powi(2) / PI;
            let point = problem.point(PI - shift, 1.0);
            assert_eq!(
                point.kind,
                InstabilityType::Type2,
                "{method:?} hω = {h_omega}: ρ = {}",
                point.spectral_radius
            );
        }
    }
}

#[test]
fn footnote_2_impulse_unstable_at_three_quarters_pi_and_mollified_methods_not() {
    // αi = ω²/2, β = −ω²/2, hω = √2, Γ1 = Γ2 = 3π/4; h = 1/2 (only hω matters).
    let h = 0.5;
    let omega2 = 2.0 / (h * h);
    let coupling = Coupling {
        alpha1: 0.5 * omega2,
        alpha2: 0.5 * omega2,
        beta: -0.5 * omega2,
    };
    let gamma = 0.75 * PI;
    // By hand for Impulse (Φ = 1): sinc(3π/4) = 2√2/(3π), h²α = 1, so ε = sinc/2,
    // c = cos(3π/4) − ε, S = 2c, D = h⁴β² sinc² = sinc²; condition 2 of Lemma 5,
    // S ≥ −2 + √D, fails, and Lemma 7 gives ρ = 1 + δ/2 + √(δ + δ²/4), δ = |S| − 2 + √D.
    let sinc = 2.0 * 2f64.sqrt() / (3.0 * PI);
    let s = 2.0 * (-(0.5f64.sqrt()) - 0.5 * sinc);
    let root_d = sinc;
    assert!(s < -2.0 + root_d, "condition 2 of Lemma 5 should fail");
    let delta = s.abs() - 2.0 + root_d;
    let lemma7 = 1.0 + 0.5 * delta + (delta + 0.25 * delta * delta).sqrt();
    let impulse = LinearProblem::new(AnalyticMethod::Impulse, h, coupling)
        .expect("valid")
        .point(gamma, gamma);
    assert_eq!(impulse.kind, InstabilityType::Type2);
    // The two evaluations differ by the rounding of a few trigonometric values (≈ 4 ε
    // each) amplified by dρ/dδ = O(1/√δ) ≈ 4 here: 64 ε is ample.
    assert!(
        (impulse.spectral_radius - lemma7).abs() <= 64.0 * EPS,
        "Impulse ρ = {} but Lemma 7 gives {lemma7}",
        impulse.spectral_radius
    );
    eprintln!("footnote 2: Impulse ρ = {}", impulse.spectral_radius);
    for method in [
        AnalyticMethod::ShortAverage,
        AnalyticMethod::LongAverage,
        AnalyticMethod::LinearAverage,
    ] {
        let point = LinearProblem::new(method, h, coupling)
            .expect("valid")
            .point(gamma, gamma);
        let quartic = LinearProblem::new(method, h, coupling)
            .expect("valid")
            .quartic(gamma, gamma);
        assert!(
            point.kind.is_stable() && quartic.lemma5_stable(),
            "{method:?} at footnote 2's point: ρ = {}, S = {}, D = {}",
            point.spectral_radius,
            quartic.s,
            quartic.d
        );
    }
}
