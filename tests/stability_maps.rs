//! GSS98 Figures 1–5 and the census of instability types, from Lemma 4 (analytic mode,
//! h = 1/2, the three-spring coupling α1 = α2 = 1/2, β = −1/2).
//!
//! All run in `make test`, the 4000 × 4000 census included (about 11 s of CPU).

use std::f64::consts::PI;

use longstep::analysis::stability::AnalyticMethod;
use longstep::analysis::stability::InstabilityType;
use longstep::analysis::stability::analytic::LinearProblem;
use longstep::analysis::stability::map::{Axis, Evaluator, Grid, census, evaluate_all};

fn long_average() -> LinearProblem {
    LinearProblem::three_spring(AnalyticMethod::LongAverage, 0.5).expect("valid")
}

fn square_grid(end: f64, n: usize) -> Grid {
    let axis = Axis::new(0.0, end, n, "Γ").expect("valid axis");
    Grid {
        gamma1: axis,
        gamma2: axis,
    }
}

/// Which types occur (stable, 1, 2, 3) on an n × n grid of [0, 4π]².
fn types_present(method: AnalyticMethod, n: usize) -> ([usize; 5], Vec<i32>) {
    let problem = LinearProblem::three_spring(method, 0.5).expect("valid");
    let points = evaluate_all(&Evaluator::Analytic(problem), &square_grid(4.0 * PI, n))
        .expect("analytic maps cannot fail");
    let counts = census(&points);
    let present = (1..=3)
        .filter(|&t| counts[t] > 0)
        .map(|t| t as i32)
        .collect();
    (counts, present)
}

fn expected_types(method: AnalyticMethod) -> Vec<i32> {
    // ERRATA.md: what Lemma 4 gives (the section-3 prose also gives ShortAverage type 3).
    match method {
        AnalyticMethod::Impulse => vec![1, 2, 3],
        AnalyticMethod::ShortAverage => vec![1, 2],
        AnalyticMethod::LongAverage => vec![1],
        AnalyticMethod::LinearAverage => vec![1, 2],
    }
}

#[test]
fn census_of_instability_types_over_0_4pi_squared() {
    // 1000 × 1000 points, spacing 4π/999 ≈ 0.0126. The narrowest regions counted are
    // strips about 0.01 wide crossed by every grid row at a varying offset, so each one
    // holds grid points (the counts below show how many).
    for method in AnalyticMethod::ALL {
        let (counts, present) = types_present(method, 1000);
        eprintln!(
            "{:<14} stable {}, type 1 {}, type 2 {}, type 3 {}",
            method.paper_name(),
            counts[0],
            counts[1],
            counts[2],
            counts[3]
        );
        assert_eq!(counts[4], 0, "no overflow in analytic mode");
        assert_eq!(present, expected_types(method), "{}", method.paper_name());
    }
}

/// The census at the full 4000 × 4000 (1.6e7 points per method, spacing 0.0031, a third
/// of the narrowest strips' width): the same types as at 1000 × 1000. About 11 s of CPU
/// (both cores), measured under load.
#[test]
fn fine_census_of_instability_types_over_0_4pi_squared() {
    for method in AnalyticMethod::ALL {
        let (counts, present) = types_present(method, 4000);
        eprintln!("{:<14} {counts:?}", method.paper_name());
        assert_eq!(present, expected_types(method), "{}", method.paper_name());
    }
}

#[test]
fn mollified_methods_have_no_type_3_where_impulse_has_it() {
    // Proposition 3 puts Impulse's type 3 just below Γ1 = 2πk (by ½h²α1/(2πk) ≈ 0.005 for
    // k = 1). ShortAverage, LongAverage and LinearAverage all have Φ(2πk) = 0; scan
    // Γ1 ∈ [2πk − 0.05, 2πk + 0.01] with step 1e-6, far finer than any region there.
    for k in [1.0, 2.0] {
        for gamma2 in [0.5, 1.0, 2.0, 2.5, 4.0, 5.0] {
            let impulse = LinearProblem::three_spring(AnalyticMethod::Impulse, 0.5).expect("valid");
            let mut impulse_type3 = 0;
            for method in [
                AnalyticMethod::ShortAverage,
                AnalyticMethod::LongAverage,
                AnalyticMethod::LinearAverage,
            ] {
                let problem = LinearProblem::three_spring(method, 0.5).expect("valid");
                for i in 0..=60_000 {
                    let g1 = 2.0 * PI * k - 0.05 + 1e-6 * i as f64;
                    let point = problem.point(g1, gamma2);
                    assert!(
                        point.kind != InstabilityType::Type3,
                        "{} type 3 at ({g1}, {gamma2}): ρ = {}",
                        method.paper_name(),
                        point.spectral_radius
                    );
                    if method == AnalyticMethod::ShortAverage
                        && impulse.point(g1, gamma2).kind == InstabilityType::Type3
                    {
                        impulse_type3 += 1;
                    }
                }
            }
            assert!(
                impulse_type3 > 0,
                "the scan near 2π·{k} at Γ2 = {gamma2} should cross Impulse's type-3 region"
            );
        }
    }
}

/// Bisect `f` (opposite signs at `a` and `b`) to the resolution of the doubles.
fn bisect(f: impl Fn(f64) -> f64, mut a: f64, mut b: f64) -> f64 {
    let fa = f(a);
    assert!(fa * f(b) < 0.0, "no sign change on [{a}, {b}]");
    for _ in 0..200 {
        let mid = 0.5 * (a + b);
        if mid == a || mid == b {
            break;
        }
        if f(mid) * fa > 0.0 {
            a = mid;
        } else {
            b = mid;
        }
    }
    0.5 * (a + b)
}

/// The LongAverage strip near Γ1 + Γ2 = 2π, crossed along the unit direction `(v1, v2)`
/// through its centre on the line Γ2 = π − u (for v = (1, 0)) or Γ1 = π − u (v = (0, 1)),
/// or on Γ2 = π − u for the normal direction. Returns (centre, width).
///
/// The centre is where c1 = c2 (D = 4θ²ε1ε2 < 0 there: inside the strip); the edges are
/// the zeros of D, (29), on either side, found by bisection.
fn strip_crossing(u: f64, direction: (f64, f64), swap: bool) -> ((f64, f64), f64) {
    let problem = long_average();
    let quartic = |g1: f64, g2: f64| {
        if swap {
            problem.quartic(g2, g1)
        } else {
            problem.quartic(g1, g2)
        }
    };
    let fixed = PI - u;
    // c1 − c2 changes sign across the strip near Γ1 = 2π − Γ2 (its derivative −sin Γ1
    // is far from zero there, for u ≥ 0.005).
    let guess = 2.0 * PI - fixed;
    let half = 0.3 * u.min(1.0);
    let centre = bisect(
        |g1| quartic(g1, fixed).difference,
        guess - half,
        guess + half,
    );
    assert!(
        quartic(centre, fixed).d < 0.0,
        "the strip is absent at u = {u}: D ≥ 0 at its centre"
    );
    let along = |t: f64| quartic(centre + t * direction.0, fixed + t * direction.1).d;
    let edge = |sign: f64| {
        let mut step = 1e-12;
        while along(sign * step) < 0.0 {
            step *= 2.0;
        }
        bisect(along, 0.0, sign * step)
    };
    let (low, high) = (edge(-1.0), edge(1.0));
    ((centre, fixed), high - low)
}

const ACROSS_GAMMA1: (f64, f64) = (1.0, 0.0);

#[test]
fn long_average_strip_is_present_and_narrows_towards_pi_pi() {
    // Along Γ1 at fixed Γ2 = π − u, from the wide end (u near π) to (π, π) (u → 0).
    let us = [3.0, 2.5, 2.0, 1.0, 0.3, 0.1, 0.03, 0.01, 0.006];
    let widths: Vec<f64> = us
        .iter()
        .map(|&u| {
            let (centre, width) = strip_crossing(u, ACROSS_GAMMA1, false);
            eprintln!(
                "u = {u:<5} Γ2 = {:.6}: centre Γ1 = {:.9}, width along Γ1 = {width:.4e}",
                centre.1, centre.0
            );
            width
        })
        .collect();
    assert!(widths.iter().all(|&w| w > 0.0));
    // From u = 2 towards (π, π) the strip narrows monotonically.
    for k in 2..us.len() - 1 {
        assert!(
            widths[k + 1] < widths[k],
            "width at u = {} ({}) is not below that at u = {} ({})",
            us[k + 1],
            widths[k + 1],
            us[k],
            widths[k]
        );
    }
}

#[test]
fn long_average_strip_width_follows_u_squared_over_4_pi_cubed() {
    // ERRATA: near (π, π) the width along Γ1 is u²/(4π³), u = π − Γ2. From (29):
    // D = (c1 − c2)² + h⁴β²Φ1²Φ2² sinc Γ1 sinc Γ2 with Φ = sinc, so across the strip
    // |c1 − c2| < h²|β| |sinc Γ1 sinc Γ2|^{3/2} with c1 − c2 ≈ x sin u (x the offset along Γ1),
    // and sinc(π ± u) = ∓ sin u/(π ± u): the width is
    // 2h²|β| sin²u/(π² − u²)^{3/2} = (u²/(4π³)) (sin u/u)² (1 − u²/π²)^{−3/2}
    // at h = 1/2, β = −1/2, i.e. the law times 1 − 0.181u² + O(u⁴). The ε terms add a
    // relative O(u): the strip's centre sits at Γ1 = π + u − (h²α/π³)u² (where c1 = c2) and
    // ε1 adds (3/2)(h²α/π³)u² to the slope sin u of c1 − c2; together at most
    // 3h²αu/π³ relative. The test allows 0.25u² + 3h²αu/π³.
    let (h, alpha) = (0.5, 0.5);
    for u in [0.3, 0.1, 0.03, 0.01, 0.006] {
        let (_, width) = strip_crossing(u, ACROSS_GAMMA1, false);
        let law = u * u / (4.0 * PI.powi(3));
        let ratio = width / law;
        let tolerance = 0.25 * u * u + 3.0 * h * h * alpha * u / PI.powi(3);
        eprintln!(
            "u = {u}: width {width:.5e}, u²/(4π³) = {law:.5e}, ratio {ratio:.6} (allowed ±{tolerance:.1e})"
        );
        assert!(
            (ratio - 1.0).abs() <= tolerance,
            "u = {u}: width {width:e} vs u²/(4π³) = {law:e}"
        );
    }
}

#[test]
fn long_average_strip_is_symmetric_in_gamma1_gamma2() {
    // The width along Γ2 at fixed Γ1 = π − u equals the width along Γ1 at fixed Γ2 = π − u.
    // Bisection resolves the edges to a few ulps of Γ (≈ 1e-15); the root of D moves by
    // its rounding (relative ε on each term of D) over |dD/dΓ|: both far below 1e-8 of
    // the narrowest width (3e-7).
    for u in [3.0, 2.0, 1.0, 0.1, 0.006] {
        let (_, along_gamma1) = strip_crossing(u, ACROSS_GAMMA1, false);
        let (_, along_gamma2) = strip_crossing(u, ACROSS_GAMMA1, true);
        assert!(
            (along_gamma1 - along_gamma2).abs() <= 1e-8 * along_gamma1,
            "u = {u}: {along_gamma1:e} along Γ1 vs {along_gamma2:e} along Γ2"
        );
    }
    // And the map: on a 601 × 601 grid of [0, 2π]² the types are symmetric except where
    // D is within its rounding (≈ 1e-16 × its terms) of zero.
    let problem = long_average();
    let n = 601;
    let axis = Axis::new(0.0, 2.0 * PI, n, "Γ").expect("valid");
    for i in 0..n {
        for j in 0..i {
            let (a, b) = (axis.value(i), axis.value(j));
            let (p, q) = (problem.point(a, b), problem.point(b, a));
            if p.kind != q.kind {
                let quartic = problem.quartic(a, b);
                let scale = quartic.difference.powi(2) + quartic.cross.abs();
                assert!(
                    quartic.d.abs() <= 16.0 * f64::EPSILON * scale,
                    "asymmetric types at ({a}, {b}): {:?} vs {:?}",
                    p.kind,
                    q.kind
                );
            }
        }
    }
}

#[test]
fn long_average_strip_normal_width_grows_then_levels_near_0_01() {
    // Normal to the line Γ1 + Γ2 = 2π, direction (1, 1)/√2, the width grows from (π, π)
    // up to u = π − Γ2 ≈ 2 and then stays about constant to the wide end near Γ2 = 0 —
    // where GSS98 says "approximately 0.1" and ERRATA measures about 0.01.
    let normal = (0.5f64.sqrt(), 0.5f64.sqrt());
    let us = [0.1, 0.3, 1.0, 2.0, 2.5, 3.0];
    let widths: Vec<f64> = us
        .iter()
        .map(|&u| {
            let (_, width) = strip_crossing(u, normal, false);
            let (_, along) = strip_crossing(u, ACROSS_GAMMA1, false);
            eprintln!("u = {u}: width normal to the strip {width:.4e}, along Γ1 {along:.4e}");
            width
        })
        .collect();
    for pair in widths[..4].windows(2) {
        assert!(
            pair[1] > pair[0],
            "normal widths not increasing: {widths:?}"
        );
    }
    // The wide end (u = 2, 2.5, 3): within 10 % of each other, and a width of order 0.01
    // (below 0.02), not 0.1.
    let wide = &widths[3..];
    let (low, high) = wide
        .iter()
        .fold((f64::INFINITY, 0.0_f64), |(a, b), &w| (a.min(w), b.max(w)));
    assert!(high <= 1.1 * low && high < 0.02, "wide-end widths {wide:?}");
    // The tip near Γ2 = 0: the strip's extent along Γ2 at fixed Γ1 (informational).
    let problem = long_average();
    for g1 in [5.90, 5.92, 5.93] {
        let inside: Vec<f64> = (0..=200_000)
            .map(|k| 0.2 * k as f64 / 200_000.0)
            .filter(|&g2| problem.quartic(g1, g2).d < 0.0)
            .collect();
        if let (Some(low), Some(high)) = (inside.first(), inside.last()) {
            eprintln!(
                "Γ1 = {g1}: type 1 for Γ2 in [{low:.4}, {high:.4}] (extent {:.4})",
                high - low
            );
        }
    }
}

#[test]
fn figure_5_short_average_type_2_dominates_its_surface() {
    // GSS98 Figure 5: on ShortAverage's spectral-radius surface "the type-2 instability
    // region shows up well" while type 1 is too thin for the mesh: on a 400 × 400 grid of
    // [0, 2π]² at h = 1/2 the largest ρ is on a type-2 point and exceeds every type-1 ρ.
    let problem = LinearProblem::three_spring(AnalyticMethod::ShortAverage, 0.5).expect("valid");
    let points =
        evaluate_all(&Evaluator::Analytic(problem), &square_grid(2.0 * PI, 400)).expect("analytic");
    let largest = |kind: InstabilityType| {
        points
            .iter()
            .filter(|p| p.kind == kind)
            .map(|p| p.spectral_radius)
            .fold(f64::NAN, f64::max)
    };
    let (type1, type2) = (
        largest(InstabilityType::Type1),
        largest(InstabilityType::Type2),
    );
    let counts = census(&points);
    eprintln!("ShortAverage on [0, 2π]²: {counts:?}; max ρ type 1 {type1}, type 2 {type2}");
    assert!(type2 > type1, "type 2 max {type2} vs type 1 max {type1}");
    assert_eq!(counts[3], 0);
}

#[test]
fn figure_1_long_average_first_instability_is_the_strip() {
    // "It is the first that we encounter as we increase the step size with given Ω1, Ω2":
    // along rays Γ = s·(Ω1, Ω2) from 0, LongAverage's first unstable point lies on the
    // strip near Γ1 + Γ2 = 2π (type 1), for rays through the first quadrant.
    let problem = long_average();
    // Rays near the diagonal cross the strip near (π, π), where it is narrower than the
    // ray's sampling (2e-5); on the diagonal itself c1 = c2 and D > 0: no type 1.
    for angle in [0.1, 0.3, 0.5, 1.07, 1.27, 1.47] {
        let (c, s) = (f64::cos(angle), f64::sin(angle));
        let first = (1..=400_000)
            .map(|k| 8.0 * k as f64 / 400_000.0)
            .map(|r| (r * c, r * s))
            .find(|&(g1, g2)| !problem.point(g1, g2).kind.is_stable());
        let (g1, g2) = first.expect("the ray crosses the strip before |Γ| = 8");
        let point = problem.point(g1, g2);
        eprintln!(
            "angle {angle}: first unstable at ({g1:.5}, {g2:.5}), Γ1 + Γ2 = {:.5}",
            g1 + g2
        );
        assert_eq!(point.kind, InstabilityType::Type1);
        // The strip lies within 0.4 of Γ1 + Γ2 = 2π (its tips curve in by ≈ 0.35 where
        // ε2 ≈ h²α2/2 shifts c2 at Γ2 → 0; see the narrowing test's centres).
        assert!(
            (g1 + g2 - 2.0 * PI).abs() < 0.4,
            "first instability at ({g1}, {g2}) is not on the strip"
        );
    }
}

#[test]
fn shards_partition_the_points_in_order() {
    use longstep::analysis::stability::map::Shard;
    for total in [0usize, 1, 7, 100, 1001, 160_000] {
        for count in [1usize, 2, 3, 7, 64] {
            let mut next = 0;
            for index in 1..=count {
                let range = Shard::parse(&format!("{index}/{count}"))
                    .expect("valid shard")
                    .range(total);
                assert_eq!(range.start, next, "shard {index}/{count} of {total}");
                // Balanced: sizes differ by at most one point.
                assert!(range.len() <= total / count + 1 && range.len() >= total / count);
                next = range.end;
            }
            assert_eq!(next, total, "shards of {total} by {count} do not cover it");
        }
    }
    for bad in ["0/3", "4/3", "1/0", "a/b", "3", "1/2/3"] {
        assert!(Shard::parse(bad).is_err(), "{bad} should be rejected");
    }
}
