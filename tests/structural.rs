//! Structural ZD/ZDS schemes (CFM25 sections 2–5): coefficients, orders, the error
//! tables 2 and 6 measured as the paper measures them (ERRATA.md), the fixed point's
//! failure mode, and the non-separable charged particle (5.7).

use std::path::Path;

use longstep::integrators::structural::coefficients::{
    MAX_BLOCK, Precision, RowBasis, StructuralCoefficients,
};
use longstep::integrators::{Integrator, Structural, StructuralKind};
use longstep::io::scene::load_scene;
use longstep::io::summary::Status;
use longstep::run::{RunOptions, run};
use longstep::system::System;

const EPS: f64 = f64::EPSILON;

fn scene(name: &str, set: &[&str]) -> System {
    let set: Vec<String> = set.iter().map(|s| s.to_string()).collect();
    load_scene(Path::new(&format!("systems/{name}.toml")), &set)
        .expect("scene")
        .system
}

fn relative_difference(a: &[f64], b: &[f64]) -> f64 {
    let scale = b.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    a.iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
        / scale
}

fn all_coefficients(c: &StructuralCoefficients) -> Vec<f64> {
    [&c.matrix_d, &c.matrix_s, &c.start_z, &c.start_d, &c.start_s]
        .iter()
        .flat_map(|v| v.iter().copied())
        .collect()
}

// ---------------------------------------------------------------------------------------
// Coefficients
// ---------------------------------------------------------------------------------------

/// R = 2 against the exact rationals (solved by hand / with Python fractions): ZD is the
/// Lobatto IIIA pair `Z₁ = Z₀ + Δt(5D₀ + 8D₁ − D₂)/12`, `Z₂ = Z₀ + Δt(D₀ + 4D₁ + D₂)/3`
/// (Simpson); ZDS has denominators 240 and 15. Correctly rounded: within one ulp.
#[test]
fn block_two_matches_exact_rationals() {
    let zd = StructuralCoefficients::new(2, 1).unwrap();
    let zds = StructuralCoefficients::new(2, 2).unwrap();
    let cases: [(&[f64], &[f64]); 6] = [
        (&zd.start_d, &[-5.0 / 12.0, -1.0 / 3.0]),
        (
            &zd.matrix_d,
            &[-2.0 / 3.0, 1.0 / 12.0, -4.0 / 3.0, -1.0 / 3.0],
        ),
        (&zds.start_d, &[-101.0 / 240.0, -7.0 / 15.0]),
        (
            &zds.matrix_d,
            &[-8.0 / 15.0, -11.0 / 240.0, -16.0 / 15.0, -7.0 / 15.0],
        ),
        (&zds.start_s, &[-13.0 / 240.0, -1.0 / 15.0]),
        (&zds.matrix_s, &[1.0 / 6.0, 1.0 / 80.0, 0.0, 1.0 / 15.0]),
    ];
    for (computed, exact) in cases {
        for (c, e) in computed.iter().zip(exact) {
            assert!((c - e).abs() <= EPS * e.abs(), "{c} vs {e}");
        }
    }
    assert!(zd.start_z.iter().chain(&zds.start_z).all(|&z| z == -1.0));
}

/// Every block size allowed: the f64 coefficients reproduce polynomials up to the
/// design degree to rounding. Correct rounding of each coefficient perturbs each term by
/// at most ε/2 of itself, so the residual relative to the sum of the terms' magnitudes is
/// at most ε/2 (plus the double-double evaluation, ~1e-32): bound ε.
#[test]
fn coefficients_are_exact_on_polynomials_for_every_block() {
    for derivatives in [1, 2] {
        for block in 1..=MAX_BLOCK {
            let c = StructuralCoefficients::new(block, derivatives).unwrap();
            let residual = c.exactness_residual();
            assert!(
                residual <= EPS,
                "S = {derivatives}, R = {block}: residual {residual:e}"
            );
        }
    }
    assert!(StructuralCoefficients::new(MAX_BLOCK + 1, 1).is_err());
    assert!(StructuralCoefficients::new(0, 2).is_err());
}

/// The kernel does not depend on the rows' polynomial basis, and the block matrices do
/// not depend on the kernel's basis (CFM25 takes an orthogonal one). Monomial rows in
/// double-double agree with Chebyshev rows in double-double to rounding (their condition
/// numbers, < 1e10 for ZDS R ≤ 4 and ZD R ≤ 8, leave > 20 of the ~32 digits). An
/// orthonormal kernel basis from an f64 SVD (as CFM25 builds it) gives the same
/// `B = A_z⁻¹A` to the SVD's accuracy, ~cond·ε ≈ 1e-13 for R = 2.
#[test]
fn coefficients_do_not_depend_on_the_bases() {
    for (derivatives, blocks) in [(1, 1..=8), (2, 1..=4)] {
        for block in blocks {
            let chebyshev = StructuralCoefficients::new(block, derivatives).unwrap();
            let monomial = StructuralCoefficients::computed(
                block,
                derivatives,
                RowBasis::Monomial,
                Precision::DoubleDouble,
            )
            .unwrap();
            let difference =
                relative_difference(&all_coefficients(&monomial), &all_coefficients(&chebyshev));
            assert!(
                difference <= 2.0 * EPS,
                "S = {derivatives}, R = {block}: {difference:e}"
            );
        }
    }
    // CFM25's construction for ZD and ZDS with R = 2: the reduced monomial matrix (rows
    // t^k, k < K; columns a_{r,s}), an orthonormal basis of its kernel from the SVD, then
    // B_d = A_z⁻¹A_d etc.
    for derivatives in [1usize, 2] {
        let block = 2usize;
        let size = 1 + derivatives * (block + 1);
        let columns = (derivatives + 1) * (block + 1);
        let entry = |k: usize, s: usize, r: usize| -> f64 {
            if k < s {
                return 0.0;
            }
            let falling: f64 = (0..s).map(|j| (k - j) as f64).product();
            falling * (r as f64).powi((k - s) as i32)
        };
        let mut m = nalgebra::DMatrix::<f64>::zeros(columns, columns);
        for k in 0..size {
            for s in 0..=derivatives {
                for r in 0..=block {
                    m[(k, s * (block + 1) + r)] = entry(k, s, r);
                }
            }
        }
        // The kernel of the first `size` rows: the right singular vectors of the zero
        // singular values (the padded rows are zero).
        let svd = m.svd(false, true);
        let v_t = svd.v_t.unwrap();
        let mut order: Vec<usize> = (0..columns).collect();
        order.sort_by(|&a, &b| svd.singular_values[a].total_cmp(&svd.singular_values[b]));
        let kernel: Vec<Vec<f64>> = order[..block]
            .iter()
            .map(|&i| v_t.row(i).iter().copied().collect())
            .collect();
        let a = |s: usize| {
            nalgebra::DMatrix::from_fn(block, block, |m, r| kernel[m][s * (block + 1) + r + 1])
        };
        let a_z_inverse = a(0).try_inverse().unwrap();
        let ours = StructuralCoefficients::new(block, derivatives).unwrap();
        let b_d = &a_z_inverse * a(1);
        let theirs: Vec<f64> = (0..block)
            .flat_map(|m| (0..block).map(move |r| (m, r)))
            .map(|(m, r)| b_d[(m, r)])
            .collect();
        let difference = relative_difference(&theirs, &ours.matrix_d);
        assert!(difference < 1e-12, "S = {derivatives}: {difference:e}");
        if derivatives == 2 {
            let b_s = &a_z_inverse * a(2);
            let theirs: Vec<f64> = (0..block)
                .flat_map(|m| (0..block).map(move |r| (m, r)))
                .map(|(m, r)| b_s[(m, r)])
                .collect();
            assert!(relative_difference(&theirs, &ours.matrix_s) < 1e-12);
        }
    }
}

/// The conditioning note of `coefficients.rs`: CFM25's monomial matrix solved in f64
/// loses digits as R grows — here the loss measured against the double-double result.
/// The bounds are the orders of magnitude the condition numbers predict (cond·ε: 5e3·ε
/// ≈ 1e-12 for ZD R = 4, 6e9·ε ≈ 1e-6 for ZD R = 8, 3e8·ε ≈ 7e-8 for ZDS R = 4): a loss
/// at least 100× above ε at ZD R = 8 and ZDS R = 4, and far below 1.
#[test]
fn f64_monomial_rows_lose_digits_as_r_grows() {
    let mut report = Vec::new();
    for (derivatives, block) in [
        (1, 2),
        (1, 4),
        (1, 6),
        (1, 8),
        (2, 1),
        (2, 2),
        (2, 3),
        (2, 4),
    ] {
        let exact = StructuralCoefficients::new(block, derivatives).unwrap();
        let f64_monomial = StructuralCoefficients::computed(
            block,
            derivatives,
            RowBasis::Monomial,
            Precision::Double,
        )
        .unwrap();
        let f64_chebyshev = StructuralCoefficients::computed(
            block,
            derivatives,
            RowBasis::Chebyshev,
            Precision::Double,
        )
        .unwrap();
        let loss = relative_difference(&all_coefficients(&f64_monomial), &all_coefficients(&exact));
        let chebyshev_loss =
            relative_difference(&all_coefficients(&f64_chebyshev), &all_coefficients(&exact));
        report.push((derivatives, block, loss, chebyshev_loss));
        println!(
            "{} R = {block}: f64 monomial rows relative error {loss:.1e}, f64 Chebyshev rows \
             {chebyshev_loss:.1e}",
            if derivatives == 1 { "ZD " } else { "ZDS" }
        );
        assert!(loss < 1e-3);
        // Chebyshev rows keep f64 itself within a few hundred ulps.
        assert!(chebyshev_loss < 1e3 * EPS);
    }
    let loss_of = |s: usize, r: usize| {
        report
            .iter()
            .find(|&&(d, b, _, _)| d == s && b == r)
            .map(|&(_, _, l, _)| l)
            .unwrap()
    };
    assert!(loss_of(1, 8) > 100.0 * EPS && loss_of(2, 4) > 100.0 * EPS);
    assert!(loss_of(1, 8) > loss_of(1, 2));
}

// ---------------------------------------------------------------------------------------
// Running the schemes
// ---------------------------------------------------------------------------------------

/// Step `system` with a structural scheme over `steps` nodes; `observe(step, system)`
/// after each. Fails on a `StepFailure`.
fn integrate(
    system: &mut System,
    kind: StructuralKind,
    block: usize,
    h: f64,
    steps: usize,
    mut observe: impl FnMut(usize, &System),
) -> Result<Structural, String> {
    let mut method = Structural::new(kind, h, block, 1e-15, 1000).map_err(|e| e.to_string())?;
    method.setup(system).map_err(|e| e.to_string())?;
    for n in 1..=steps {
        method.step(system).map_err(|f| f.0)?;
        system.state.t = n as f64 * h;
        observe(n, system);
    }
    Ok(method)
}

/// CFM25 5.1, Table 2: `max(|x_N − x(T)|, |p_N − p(T)|)` at T = 100 (ERRATA.md: not the
/// position alone), x = cos t.
fn mass_spring_error(kind: StructuralKind, block: usize, steps: usize) -> Result<f64, String> {
    let mut system = scene("mass-spring", &[]);
    let h = 100.0 / steps as f64;
    integrate(&mut system, kind, block, h, steps, |_, _| {})?;
    let t: f64 = 100.0;
    Ok((system.state.q[0] - t.cos())
        .abs()
        .max((system.state.p[0] + t.sin()).abs()))
}

/// Jacobi `sn(u|m)` and `cn(u|m)` by the arithmetic-geometric mean (Abramowitz & Stegun
/// 16.4), `u` first reduced modulo the period `4K`; with it `K = π/(2 a_N)`.
fn jacobi_sn_cn(u: f64, m: f64) -> (f64, f64) {
    let mut a = vec![1.0];
    let mut c = vec![m.sqrt()];
    let mut b = (1.0 - m).sqrt();
    while c.last().unwrap().abs() > EPS {
        let (an, bn) = (*a.last().unwrap(), b);
        a.push(0.5 * (an + bn));
        c.push(0.5 * (an - bn));
        b = (an * bn).sqrt();
    }
    let n = a.len() - 1;
    let quarter = std::f64::consts::PI / (2.0 * a[n]);
    let u = u - 4.0 * quarter * (u / (4.0 * quarter)).round();
    let mut phi = 2f64.powi(n as i32) * a[n] * u;
    for j in (1..=n).rev() {
        phi = 0.5 * (phi + (c[j] / a[j] * phi.sin()).asin());
    }
    (phi.sin(), phi.cos())
}

/// The pendulum of `systems/pendulum.toml` (x(0) = π/4 at rest, m = g = ℓ = 1):
/// `sin(x/2) = k sn(K − t | k²)`, `p = −2k cn(K − t | k²)`, `k = sin(π/8)`.
fn pendulum_exact(t: f64) -> (f64, f64) {
    let k = (std::f64::consts::PI / 8.0).sin();
    let m = k * k;
    // K(m) = π/(2 AGM(1, √(1 − m))).
    let (mut a, mut b) = (1.0f64, (1.0 - m).sqrt());
    while (a - b).abs() > EPS * a {
        let an = 0.5 * (a + b);
        b = (a * b).sqrt();
        a = an;
    }
    let quarter = std::f64::consts::PI / (2.0 * a);
    let (sn, cn) = jacobi_sn_cn(quarter - t, m);
    (2.0 * (k * sn).asin(), -2.0 * k * cn)
}

/// CFM25 5.3.2 prints x(100) and p(100) in double precision; the elliptic-function
/// solution reproduces them to the reduction error of u ≈ 98 modulo 4K (~100ε) plus a
/// few ulps: bound 1e-13.
#[test]
fn pendulum_reference_matches_cfm25() {
    let (x, p) = pendulum_exact(100.0);
    assert!((x + 0.2633498226088722).abs() < 1e-13, "{x}");
    assert!((p + 0.7189111241830892).abs() < 1e-13, "{p}");
    let (x0, p0) = pendulum_exact(0.0);
    assert!((x0 - std::f64::consts::FRAC_PI_4).abs() < 1e-14 && p0.abs() < 1e-14);
}

/// CFM25 5.3, Table 6: the maximum over the block-end nodes of the position error
/// (ERRATA.md), T = 100.
fn pendulum_error(kind: StructuralKind, block: usize, steps: usize) -> Result<f64, String> {
    let mut system = scene("pendulum", &[]);
    let h = 100.0 / steps as f64;
    let mut worst: f64 = 0.0;
    integrate(&mut system, kind, block, h, steps, |n, s| {
        if n % block == 0 {
            let (x, _) = pendulum_exact(n as f64 * h);
            worst = worst.max((s.state.q[0] - x).abs());
        }
    })?;
    Ok(worst)
}

/// The round-off floor of a run of `n` steps on these O(1) problems: each node rounds
/// sums of `2R + 2` to `3R + 3` terms, a few ulps, and the errors accumulate at most
/// linearly: `4nε` (4e-13 at N = 480, 1.7e-12 at N = 1920). The paper (quadruple
/// precision) tabulates values down to 1e-14, which double precision cannot reach.
fn double_floor(n: usize) -> f64 {
    4.0 * n as f64 * EPS
}

/// `(N, paper)` rows of one column of a CFM25 table; `None` where the paper has no
/// value.
type Column = (StructuralKind, usize, [Option<f64>; 4]);

/// CFM25 Table 2 (mass-spring, N = 120, 240, 480, 960). Every entry above the double
/// floor is reproduced to the paper's three printed digits: within 1% (half a unit of the
/// third digit is at most 0.5%) plus our round-off floor. Below the floor (ZDS R = 4,
/// N = 960: 1.30e-14) we can only show we reach the floor. The starred entries were
/// computed by CFM25 at N = 156 (ZD R = 8: 156 is not a multiple of 8, so not reproducible
/// as printed; ZDS R = 4: checked at N = 156 below), and ZDS R = 4 at N = 120 does not
/// converge (the fixed point diverges), which is presumably why CFM25 moved it.
#[test]
fn mass_spring_reproduces_cfm25_table_2() {
    use StructuralKind::{Zd, Zds};
    let steps = [120, 240, 480, 960];
    let table: [Column; 8] = [
        (
            Zd,
            2,
            [Some(7.22e-1), Some(5.43e-2), Some(3.57e-3), Some(2.25e-4)],
        ),
        (
            Zd,
            4,
            [Some(2.26e-1), Some(5.04e-3), Some(8.67e-5), Some(1.39e-6)],
        ),
        (
            Zd,
            6,
            [Some(4.53e-2), Some(5.07e-4), Some(2.45e-6), Some(1.01e-8)],
        ),
        (Zd, 8, [None, Some(5.17e-5), Some(7.48e-8), Some(7.97e-11)]),
        (
            Zds,
            1,
            [Some(5.43e-2), Some(3.57e-3), Some(2.25e-4), Some(1.41e-5)],
        ),
        (
            Zds,
            2,
            [Some(2.59e-3), Some(4.58e-5), Some(7.38e-7), Some(1.16e-8)],
        ),
        (
            Zds,
            3,
            [Some(1.20e-4), Some(6.73e-7), Some(2.85e-9), Some(1.14e-11)],
        ),
        (
            Zds,
            4,
            [None, Some(1.10e-8), Some(1.28e-11), Some(1.30e-14)],
        ),
    ];
    for (kind, block, paper) in table {
        let mut row = Vec::new();
        for (&n, expected) in steps.iter().zip(paper) {
            let error = mass_spring_error(kind, block, n);
            row.push(match &error {
                Ok(e) => format!("{e:.3e}"),
                Err(_) => "failed".into(),
            });
            let Some(expected) = expected else { continue };
            let error = error.unwrap();
            if expected > double_floor(n) {
                assert!(
                    (error - expected).abs() <= 0.01 * expected + double_floor(n),
                    "{kind:?} R = {block}, N = {n}: {error:e} vs CFM25 {expected:e}"
                );
            } else {
                assert!(
                    error <= double_floor(n),
                    "{kind:?} R = {block}, N = {n}: {error:e}"
                );
            }
        }
        println!("Table 2 {kind:?} R = {block}: {}", row.join("  "));
    }
    // The dagger: ZDS R = 4 at N = 156 (CFM25: 5.67e-7).
    let error = mass_spring_error(StructuralKind::Zds, 4, 156).unwrap();
    println!("Table 2 ZDS R = 4, N = 156: {error:.3e} (CFM25 5.67e-7)");
    assert!((error - 5.67e-7).abs() <= 0.01 * 5.67e-7);
    // ZDS R = 4 at N = 120: the fixed point does not converge, and says so.
    let failure = mass_spring_error(StructuralKind::Zds, 4, 120).unwrap_err();
    assert!(failure.contains("did not converge") || failure.contains("diverged"));
}

/// CFM25 Table 6 (pendulum, position error, maximum over block ends). ZD R = 4, 6, 8 and
/// ZDS R = 1–4 reproduce to the three printed digits (1%) wherever the entry is above
/// the double floor. ZD R = 2 does not, and is not compared (ERRATA.md: an independent
/// implementation does not reproduce that column either): ours are 1.32, 3.61e-2,
/// 2.43e-3, 1.53e-4, 9.63e-6 against CFM25's 8.27e-1, 3.36e-2, 2.45e-3, 1.58e-4, 9.80e-6
/// (1.6× at N = 120, 1–3% at N ≥ 480; the mass-spring table matches exactly with the same
/// code, so the cause is not found). Its fourth order is checked by `observed_orders`.
/// Entries below the floor (ZDS R = 3 at N = 1920, ZDS R = 4 at N =
/// 960 — CFM25's own "***" at 1920 — is 1.21e-13 in quad) are checked against the floor.
#[test]
fn pendulum_reproduces_cfm25_table_6() {
    use StructuralKind::{Zd, Zds};
    let steps = [120, 240, 480, 960, 1920];
    type Row = (StructuralKind, usize, [Option<f64>; 5], f64, usize);
    // (kind, R, paper, relative tolerance, first N index compared)
    let table: [Row; 8] = [
        (
            Zd,
            2,
            [
                Some(8.27e-1),
                Some(3.36e-2),
                Some(2.45e-3),
                Some(1.58e-4),
                Some(9.80e-6),
            ],
            0.0,
            5, // not compared: ERRATA.md
        ),
        (
            Zd,
            4,
            [
                Some(3.32e-1),
                Some(1.11e-2),
                Some(5.56e-5),
                Some(8.81e-7),
                Some(1.43e-8),
            ],
            0.01,
            0,
        ),
        (
            Zd,
            6,
            [
                Some(3.25e-2),
                Some(2.24e-4),
                Some(4.85e-6),
                Some(1.05e-8),
                Some(4.27e-11),
            ],
            0.01,
            0,
        ),
        (
            Zd,
            8,
            [
                None,
                Some(1.32e-2),
                Some(6.89e-6),
                Some(4.92e-9),
                Some(7.98e-13),
            ],
            0.01,
            0,
        ),
        (
            Zds,
            1,
            [
                Some(3.93e-2),
                Some(2.63e-3),
                Some(1.66e-4),
                Some(1.04e-5),
                Some(6.52e-7),
            ],
            0.01,
            0,
        ),
        (
            Zds,
            2,
            [
                Some(1.26e-2),
                Some(2.16e-5),
                Some(4.35e-7),
                Some(6.93e-9),
                Some(1.09e-10),
            ],
            0.01,
            0,
        ),
        (
            Zds,
            3,
            [
                Some(2.00e-3),
                Some(6.24e-6),
                Some(1.94e-9),
                Some(6.25e-12),
                Some(4.02e-14),
            ],
            0.01,
            0,
        ),
        (
            Zds,
            4,
            [None, Some(1.58e-5), Some(3.32e-9), Some(1.21e-13), None],
            0.01,
            0,
        ),
    ];
    for (kind, block, paper, tolerance, first) in table {
        let mut row = Vec::new();
        for (index, (&n, expected)) in steps.iter().zip(paper).enumerate() {
            let error = pendulum_error(kind, block, n);
            row.push(match &error {
                Ok(e) => format!("{e:.3e}"),
                Err(_) => "failed".into(),
            });
            let Some(expected) = expected else { continue };
            if index < first {
                continue;
            }
            let error = error.unwrap();
            if expected > double_floor(n) {
                assert!(
                    (error - expected).abs() <= tolerance * expected + double_floor(n),
                    "{kind:?} R = {block}, N = {n}: {error:e} vs CFM25 {expected:e}"
                );
            } else {
                assert!(
                    error <= double_floor(n),
                    "{kind:?} R = {block}, N = {n}: {error:e}"
                );
            }
        }
        println!("Table 6 {kind:?} R = {block}: {}", row.join("  "));
    }
}

/// Observed orders on the mass-spring (final-time error, Table 2's measure) and the
/// pendulum (Table 6's): ZD `R + 2` for even R and `R + 1` for odd R (collocation at
/// equally spaced nodes: a closed Newton–Cotes rule), ZDS `2(R + 1)`. The order is taken
/// from the two finest step counts whose errors are above 5× the double floor (round-off
/// then moves each error by at most 20%, the order by at most 0.26 — the floor is a
/// bound, the measured round-off is far lower); in the asymptotic regime the next error
/// term shifts the ratio of successive errors by well under 2^0.25, so the observed order
/// is within 0.5.
#[test]
fn observed_orders() {
    use StructuralKind::{Zd, Zds};
    let cases = [
        (Zd, 1),
        (Zd, 2),
        (Zd, 3),
        (Zd, 4),
        (Zd, 6),
        (Zds, 1),
        (Zds, 2),
        (Zds, 3),
    ];
    type Problem = fn(StructuralKind, usize, usize) -> Result<f64, String>;
    let problems: [(&str, Problem); 2] = [
        ("mass-spring", mass_spring_error),
        ("pendulum", pendulum_error),
    ];
    for (name, error_of) in problems {
        for (kind, block) in cases {
            let expected = kind.order(block) as f64;
            let errors: Vec<(usize, f64)> = [240, 480, 960, 1920]
                .iter()
                .filter(|&&n| n % block == 0)
                .map(|&n| (n, error_of(kind, block, n).unwrap()))
                .filter(|&(n, e)| e > 5.0 * double_floor(n))
                .collect();
            let [.., (n1, e1), (n2, e2)] = errors[..] else {
                panic!("{name} {kind:?} R = {block}: fewer than two errors above the floor");
            };
            let order = (e1 / e2).ln() / (n2 as f64 / n1 as f64).ln();
            println!(
                "{name} {kind:?} R = {block}: order {order:.2} (N = {n1} → {n2}), expected {expected}"
            );
            assert!(
                (order - expected).abs() < 0.5,
                "{name} {kind:?} R = {block}: {order}"
            );
        }
    }
}

// ---------------------------------------------------------------------------------------
// The fixed point
// ---------------------------------------------------------------------------------------

/// A too-large step fails clearly (exit status "failed", the time and the reason), and
/// the iteration count is reported per block and stays below the cap.
#[test]
fn fixed_point_reports_iterations_and_fails_clearly() {
    let options = RunOptions {
        t_end: 100.0,
        energy_every: 1,
        blowup: 10.0,
        energy_csv: None,
        trajectory: None,
        ..Default::default()
    };
    // Converging: ZDS R = 2, N = 480 on the pendulum.
    let mut system = scene("pendulum", &[]);
    let mut method = Structural::new(StructuralKind::Zds, 100.0 / 480.0, 2, 1e-14, 50).unwrap();
    let summary = run("pendulum", &mut system, &mut method, &options).unwrap();
    assert_eq!(summary.status, Status::Ok);
    let per_block = method.total_iterations() as f64 / method.blocks() as f64;
    println!(
        "pendulum ZDS R = 2, N = 480: {} blocks, {:.2} iterations per block (most {}), {} \
         gradient evaluations = {:.2} per step",
        method.blocks(),
        per_block,
        method.most_iterations(),
        summary.force_evaluations.slow,
        summary.force_evaluations.slow as f64 / summary.steps as f64
    );
    assert!(method.most_iterations() < 50 && per_block >= 1.0);
    // Gradient evaluations: R per iteration plus R for the predictor, plus PE at t = 0.
    let expected = 2 * (method.total_iterations() + method.blocks()) + 1;
    assert_eq!(summary.force_evaluations.slow, expected);
    assert_eq!(summary.force_evaluations.hessian_vector, expected);

    // Failing: the same with a cap of 2 iterations.
    let mut system = scene("pendulum", &[]);
    let mut method = Structural::new(StructuralKind::Zds, 100.0 / 480.0, 2, 1e-14, 2).unwrap();
    let summary = run("pendulum", &mut system, &mut method, &options).unwrap();
    assert_eq!(summary.status, Status::Failed);
    let message = summary.message.unwrap();
    assert!(
        message.contains("structural-zds") && message.contains("did not converge in 2"),
        "{message}"
    );
    assert_eq!(summary.unstable_at, Some(0.0));
}

// ---------------------------------------------------------------------------------------
// Non-separable: the charged particle (CFM25 5.7)
// ---------------------------------------------------------------------------------------

/// CFM25 5.7.3 (singular vector potential, non-separable): the state at t = 2 converges
/// at the schemes' orders, measured against a ZDS R = 3 run at h = 1/384 (error ~1e-15),
/// and the Hamiltonian stays conserved to the same orders. Order from h = 1/24 → 1/48
/// → 1/96, within 0.5 as above.
#[test]
fn charged_particle_converges_at_the_design_order() {
    let t_end = 2.0;
    let state_at = |kind, block, per_unit: usize| -> (Vec<f64>, f64) {
        let mut system = scene("charged-particle-singular", &[]);
        let e0 = system.total_energy();
        let steps = (t_end as usize) * per_unit;
        let mut worst: f64 = 0.0;
        integrate(
            &mut system,
            kind,
            block,
            1.0 / per_unit as f64,
            steps,
            |_, s| {
                worst = worst.max((s.total_energy() - e0).abs());
            },
        )
        .unwrap();
        let mut state = system.state.q.clone();
        state.extend(&system.state.p);
        (state, worst)
    };
    let (reference, _) = state_at(StructuralKind::Zds, 3, 384);
    for (kind, block) in [(StructuralKind::Zd, 2), (StructuralKind::Zds, 2)] {
        let runs: Vec<(f64, f64)> = [24, 48, 96]
            .iter()
            .map(|&k| {
                let (state, energy_error) = state_at(kind, block, k);
                let error = state
                    .iter()
                    .zip(&reference)
                    .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
                (error, energy_error)
            })
            .collect();
        let expected = kind.order(block) as f64;
        for pair in runs.windows(2) {
            let order = (pair[0].0 / pair[1].0).log2();
            let energy_order = (pair[0].1 / pair[1].1).log2();
            println!(
                "charged particle {kind:?} R = {block}: state error {:.2e} → {:.2e} (order \
                 {order:.2}), max |H − H0| {:.2e} → {:.2e} (order {energy_order:.2})",
                pair[0].0, pair[1].0, pair[0].1, pair[1].1
            );
            assert!((order - expected).abs() < 0.5, "{kind:?}: {order}");
            assert!(
                (energy_order - expected).abs() < 0.5,
                "{kind:?}: {energy_order}"
            );
        }
    }
}

/// The magnetic term has no gradient: every method but the structural schemes must
/// refuse it rather than silently drop the Lorentz force.
#[test]
fn verlet_refuses_a_magnetic_field() {
    let mut system = scene("charged-particle", &[]);
    let mut verlet = longstep::integrators::VelocityVerlet::new(1e-3).unwrap();
    let options = RunOptions {
        t_end: 1.0,
        ..RunOptions::default()
    };
    let error = run("charged-particle", &mut system, &mut verlet, &options)
        .expect_err("verlet must refuse");
    assert!(error.to_string().contains("magnetic"), "{error}");
}

/// CFM25 5.7.2 as printed (B = 1000, canonical p(0) = (0, 101, 0)) gyrates at eB/m =
/// 1000, so its grid N = 12T (h = 1/12, h·1000 ≈ 83) cannot converge: the fixed point
/// diverges and the run says so. A step with h·eB/m = 0.2 runs, and conserves H to the
/// scheme's accuracy.
#[test]
fn charged_particle_as_printed_needs_a_finer_grid() {
    let options = |t_end| RunOptions {
        t_end,
        energy_every: 1,
        blowup: 10.0,
        energy_csv: None,
        trajectory: None,
        ..Default::default()
    };
    let mut system = scene("charged-particle", &[]);
    let mut coarse = Structural::new(StructuralKind::Zds, 1.0 / 12.0, 2, 1e-14, 100).unwrap();
    let summary = run(
        "charged-particle",
        &mut system,
        &mut coarse,
        &options(100.0),
    )
    .unwrap();
    assert_eq!(summary.status, Status::Failed);
    println!("h = 1/12: {}", summary.message.unwrap_or_default());

    let mut system = scene("charged-particle", &[]);
    let mut fine = Structural::new(StructuralKind::Zds, 2e-4, 2, 1e-14, 100).unwrap();
    let summary = run("charged-particle", &mut system, &mut fine, &options(1.0)).unwrap();
    println!(
        "h = 2e-4: max |H − H0|/|H0| = {:.2e} over {} steps",
        summary.energy.max_relative_error, summary.steps
    );
    assert_eq!(summary.status, Status::Ok);
    // Sixth order at h·ω = 0.2: (0.2)^6 ≈ 6e-5 per gyration in the phase, times the
    // energy's sensitivity to it, leaves far less than 1e-6 relative.
    assert!(summary.energy.max_relative_error < 1e-6);
}

// ---------------------------------------------------------------------------------------
// Systems: CFM25 Tables 4, 9, 11 and 13
// ---------------------------------------------------------------------------------------

/// `(kind, R, [paper at the coarse grid, paper at the fine grid])`.
type Pair = (StructuralKind, usize, [f64; 2]);

/// Run `name` with `steps` nodes of step `h` and return the maximum over block-end
/// nodes of `measure(t, system)` — ERRATA.md: Tables 4, 6 and 9 are maxima over block
/// ends, and so is Table 11.
fn max_over_block_ends(
    name: &str,
    set: &[&str],
    kind: StructuralKind,
    block: usize,
    h: f64,
    steps: usize,
    mut measure: impl FnMut(f64, &System) -> f64,
) -> f64 {
    let mut system = scene(name, set);
    let mut worst: f64 = 0.0;
    integrate(&mut system, kind, block, h, steps, |n, s| {
        if n % block == 0 {
            worst = worst.max(measure(n as f64 * h, s));
        }
    })
    .unwrap();
    worst
}

/// Check a table against the paper: within `tolerance` relative plus the round-off floor
/// where the entry is above the floor, below the floor otherwise. Prints the row.
fn check_row(
    table: &str,
    kind: StructuralKind,
    block: usize,
    ours: [f64; 2],
    paper: [f64; 2],
    steps: [usize; 2],
    tolerance: f64,
) {
    println!(
        "{table} {kind:?} R = {block}: {:.3e} {:.3e} (CFM25 {:.2e} {:.2e})",
        ours[0], ours[1], paper[0], paper[1]
    );
    for i in 0..2 {
        let floor = double_floor(steps[i]);
        if paper[i] > floor {
            assert!(
                (ours[i] - paper[i]).abs() <= tolerance * paper[i] + floor,
                "{table} {kind:?} R = {block}: {:e} vs CFM25 {:e}",
                ours[i],
                paper[i]
            );
        } else {
            assert!(
                ours[i] <= floor,
                "{table} {kind:?} R = {block}: {:e}",
                ours[i]
            );
        }
    }
}

/// CFM25 Table 4 (two masses, T = 100, N = 480 and 3840): the maximum over block ends of
/// the position error of either mass, against CFM25's analytical solution. Reproduced to
/// the printed digits (1%); ZDS R = 3 at N = 3840 (7.20e-12) is at our floor.
#[test]
fn two_masses_reproduce_cfm25_table_4() {
    use StructuralKind::{Zd, Zds};
    let (k1, k2, m1, m2) = (1.0f64, 5.0f64, 2.0f64, 1.0f64);
    let w1 = ((8.0 - 3.0 * 6f64.sqrt()) / 2.0).sqrt();
    let w2 = ((8.0 + 3.0 * 6f64.sqrt()) / 2.0).sqrt();
    let (a, b) = (1.0, 2.0);
    let (phase1, phase2) = (std::f64::consts::FRAC_PI_2, -std::f64::consts::FRAC_PI_4);
    let ratio1 = (k1 + k2 - m1 * w1 * w1) / k2;
    let ratio2 = k2 / (k2 - m2 * w2 * w2);
    let position = |t: f64| {
        let (c1, c2) = ((w1 * t + phase1).cos(), (w2 * t + phase2).cos());
        [a * c1 + b * c2, a * ratio1 * c1 + b * ratio2 * c2]
    };
    let table: [Pair; 7] = [
        (Zd, 2, [2.29e0, 6.19e-4]),
        (Zd, 4, [3.70e-1, 1.83e-6]),
        (Zd, 6, [5.91e-2, 6.42e-9]),
        (Zd, 8, [8.94e-3, 2.41e-11]),
        (Zds, 1, [1.53e-1, 3.88e-5]),
        (Zds, 2, [3.66e-3, 1.53e-8]),
        (Zds, 3, [9.38e-5, 7.20e-12]),
    ];
    let steps = [480, 3840];
    for (kind, block, paper) in table {
        let ours = steps.map(|n| {
            max_over_block_ends(
                "two-masses",
                &[],
                kind,
                block,
                100.0 / n as f64,
                n,
                |t, s| {
                    let x = position(t);
                    (s.state.q[0] - x[0]).abs().max((s.state.q[1] - x[1]).abs())
                },
            )
        });
        check_row("Table 4", kind, block, ours, paper, steps, 0.01);
    }
}

fn angular_momentum_2d(s: &System) -> f64 {
    let (q, p) = (&s.state.q, &s.state.p);
    (0..s.n_particles())
        .map(|i| q[2 * i] * p[2 * i + 1] - q[2 * i + 1] * p[2 * i])
        .sum()
}

/// CFM25 Table 9 (Kepler, x(0) = (0.4, 0), p(0) = (0, 2): `systems/kepler.toml` with
/// e = 0.6; T = 100, N = 24T and 96T): maxima over block ends of |H − H₀| and |L − L₀|.
/// Reproduced to the printed digits (1%) above the floor (4nε times the invariants'
/// scale, O(1)); ZDS R = 4 at N = 96T (2.73e-14, 6.02e-15) is below it.
#[test]
fn kepler_reproduces_cfm25_table_9() {
    use StructuralKind::{Zd, Zds};
    // (kind, R, eH, eL)
    let table: [(StructuralKind, usize, [f64; 2], [f64; 2]); 8] = [
        (Zd, 2, [4.15e-5, 1.81e-7], [3.25e-5, 1.28e-7]),
        (Zd, 4, [2.01e-5, 3.83e-9], [6.40e-6, 1.36e-9]),
        (Zd, 6, [1.52e-5, 1.06e-10], [1.41e-5, 3.89e-11]),
        (Zd, 8, [2.52e-5, 4.58e-12], [1.14e-5, 2.45e-12]),
        (Zds, 1, [4.83e-5, 1.88e-7], [1.27e-5, 4.93e-8]),
        (Zds, 2, [1.97e-6, 4.47e-10], [4.62e-7, 1.06e-10]),
        (Zds, 3, [3.08e-7, 2.47e-12], [6.02e-8, 5.62e-13]),
        (Zds, 4, [5.96e-8, 2.73e-14], [1.04e-8, 6.02e-15]),
    ];
    let steps = [2400, 9600];
    for (kind, block, paper_h, paper_l) in table {
        let mut ours_h = [0.0; 2];
        let mut ours_l = [0.0; 2];
        for (i, &n) in steps.iter().enumerate() {
            let reference = scene("kepler", &["eccentricity=0.6"]);
            let (h0, l0) = (reference.total_energy(), angular_momentum_2d(&reference));
            let mut worst_l: f64 = 0.0;
            ours_h[i] = max_over_block_ends(
                "kepler",
                &["eccentricity=0.6"],
                kind,
                block,
                100.0 / n as f64,
                n,
                |_, s| {
                    worst_l = worst_l.max((angular_momentum_2d(s) - l0).abs());
                    (s.total_energy() - h0).abs()
                },
            );
            ours_l[i] = worst_l;
        }
        check_row("Table 9 eH", kind, block, ours_h, paper_h, steps, 0.01);
        check_row("Table 9 eL", kind, block, ours_l, paper_l, steps, 0.01);
    }
}

/// CFM25 Table 11 (figure-eight, T = 10, N = 12T and 48T): maximum over block ends of
/// |H − H₀|. Reproduced to the printed digits (1%); ZDS R = 4 at 48T (8.55e-14) is at
/// our floor.
#[test]
fn figure_eight_reproduces_cfm25_table_11() {
    use StructuralKind::{Zd, Zds};
    let table: [Pair; 8] = [
        (Zd, 2, [5.05e-5, 1.60e-7]),
        (Zd, 4, [6.88e-5, 9.82e-9]),
        (Zd, 6, [4.20e-5, 4.10e-10]),
        (Zd, 8, [9.16e-5, 3.52e-11]),
        (Zds, 1, [7.67e-5, 2.98e-7]),
        (Zds, 2, [3.62e-6, 8.14e-10]),
        (Zds, 3, [1.10e-6, 5.41e-12]),
        (Zds, 4, [8.74e-7, 8.55e-14]),
    ];
    let steps = [120, 480];
    let h0 = scene("three-body-figure-eight", &[]).total_energy();
    for (kind, block, paper) in table {
        let ours = steps.map(|n| {
            max_over_block_ends(
                "three-body-figure-eight",
                &[],
                kind,
                block,
                10.0 / n as f64,
                n,
                |_, s| (s.total_energy() - h0).abs(),
            )
        });
        check_row("Table 11", kind, block, ours, paper, steps, 0.01);
    }
}

/// CFM25 Table 13 (outer solar system, T = 100 000 days, N = 480 and 1920): the maximum
/// over block ends of |H − H₀|/|H₀|. Reproduced in magnitude only — ours are 0.63–1.56×
/// CFM25's (the Table 12 data as printed, rounded to 8 digits, may differ from what was
/// run; the cause is not found). Without a cause there is no tolerance to derive, so the
/// comparison with the paper is the claim the docs make, "the same magnitude": within a
/// factor 2, or both values below our floor (ZDS R = 4 at N = 1920: CFM25 1.03e-14).
/// What can be derived is checked on our own values: the error falls at the scheme's
/// order from N = 480 to 1920 (as in `observed_orders`, where both errors are above 5×
/// the floor: within 0.5; refining by 4 the next error term moves log₄ of the ratio less
/// than the factor-2 refinement there).
#[test]
fn outer_solar_system_matches_cfm25_table_13_in_magnitude() {
    use StructuralKind::{Zd, Zds};
    let table: [Pair; 8] = [
        (Zd, 2, [3.06e-4, 1.26e-6]),
        (Zd, 4, [1.07e-4, 2.72e-8]),
        (Zd, 6, [4.02e-5, 5.11e-10]),
        (Zd, 8, [3.79e-5, 2.29e-11]),
        (Zds, 1, [7.92e-5, 3.10e-7]),
        (Zds, 2, [2.33e-6, 5.69e-10]),
        (Zds, 3, [9.99e-8, 1.52e-12]),
        (Zds, 4, [3.48e-8, 1.03e-14]),
    ];
    let steps = [480, 1920];
    let h0 = scene("outer-solar-system", &[]).total_energy();
    for (kind, block, paper) in table {
        let ours = steps.map(|n| {
            max_over_block_ends(
                "outer-solar-system",
                &[],
                kind,
                block,
                100_000.0 / n as f64,
                n,
                |_, s| ((s.total_energy() - h0) / h0).abs(),
            )
        });
        println!(
            "Table 13 {kind:?} R = {block}: {:.3e} {:.3e} (CFM25 {:.2e} {:.2e})",
            ours[0], ours[1], paper[0], paper[1]
        );
        if ours[1] > 5.0 * double_floor(steps[1]) {
            let order = (ours[0] / ours[1]).ln() / 4f64.ln();
            let expected = kind.order(block) as f64;
            assert!(
                (order - expected).abs() <= 0.5,
                "{kind:?} R = {block}: order {order:.2}, expected {expected}"
            );
        }
        for i in 0..2 {
            let floor = double_floor(steps[i]);
            let ratio = ours[i] / paper[i];
            let at_floor = paper[i] <= floor && ours[i] <= floor;
            assert!(
                (0.5..2.0).contains(&ratio) || at_floor,
                "{kind:?} R = {block}: {:e} vs CFM25 {:e}",
                ours[i],
                paper[i]
            );
        }
    }
}
