//! Ewald electrostatics (`forces::ewald`, the `Ewald` real-space form of the cluster-pair
//! engine, the `[forcefield]` PME keys):
//!
//! * the plain Ewald sum (the reference) is converged to 1e-10 and independent of α;
//! * smooth PME's reciprocal energy and gradient converge to it with the grid at the rate
//!   of the spline order, and with the order at a fixed grid; its exclusion, self and
//!   background parts are the reference's;
//! * forces are minus the gradient of the energy, and the Hessian-vector product the
//!   derivative of the gradient (central differences);
//! * the engine's real space is the reference's real-space sum;
//! * real space + reciprocal + corrections is the converged Ewald energy at any α, within
//!   the stated bound;
//! * bad input gets an error naming the key;
//! * the water box matches OpenMM's PME (Reference platform, double precision), from the
//!   numbers `scripts/openmm_pme_reference.py` wrote into `tests/data/openmm-pme-water.json`.

mod common;
use common::{TestRng, argv, max_abs, max_abs_difference, words};

use std::path::Path;

use longstep::forces::ForceTerm;
use longstep::forces::ewald::direct::{DirectEwald, EwaldParts};
use longstep::forces::ewald::{
    EwaldParameters, EwaldRequest, PmeReciprocal, alpha_for_tolerance, grid_size, resolve,
};
use longstep::forces::nonbonded::{Electrostatics, LjPair, Nonbonded, NonbondedSpec};

const KE: f64 = 332.06371;
const CUBIC: [f64; 3] = [10.0, 10.0, 10.0];
const ORTHORHOMBIC: [f64; 3] = [9.0, 10.0, 11.5];
const EXCLUDED: [(usize, usize); 3] = [(0, 1), (2, 3), (4, 5)];

/// `n` charges in a box, at least 1.2 apart (minimum image), uniform in (−1, 1), made
/// neutral when asked.
fn charges_in_box(n: usize, lengths: [f64; 3], neutral: bool, seed: u64) -> (Vec<f64>, Vec<f64>) {
    let mut rng = TestRng::new(seed);
    let mut q: Vec<f64> = Vec::with_capacity(3 * n);
    while q.len() < 3 * n {
        let x = [0, 1, 2].map(|a| rng.uniform(0.0, lengths[a]));
        let far = q.chunks_exact(3).all(|y| {
            let r2: f64 = (0..3)
                .map(|a| {
                    let d = x[a] - y[a];
                    let d = d - lengths[a] * (d / lengths[a]).round();
                    d * d
                })
                .sum();
            r2 >= 1.2 * 1.2
        });
        if far {
            q.extend(x);
        }
    }
    let mut charges = rng.vector(n, -1.0, 1.0);
    if neutral {
        let mean = charges.iter().sum::<f64>() / n as f64;
        charges.iter_mut().for_each(|c| *c -= mean);
    }
    (q, charges)
}

/// The boxes of the tests: neutral cubic and charged orthorhombic.
fn boxes() -> [([f64; 3], Vec<f64>, Vec<f64>); 2] {
    let (q1, c1) = charges_in_box(20, CUBIC, true, 7);
    let (q2, c2) = charges_in_box(20, ORTHORHOMBIC, false, 8);
    [(CUBIC, q1, c1), (ORTHORHOMBIC, q2, c2)]
}

/// The plain Ewald sum converged far below 1e-10: erfc(α r_c) < 2e-17 at α r_c = 6, and
/// the first wave vector left out has exp(−π²m²/α²) < 1e-17 (π m/α ≥ 6.3).
fn direct(
    alpha: f64,
    lengths: [f64; 3],
    charges: &[f64],
    excluded: &[(usize, usize)],
) -> DirectEwald {
    DirectEwald {
        alpha,
        lengths,
        coulomb_constant: KE,
        charges: charges.to_vec(),
        excluded: excluded.to_vec(),
        real_cutoff: 6.0 / alpha,
        k_max: lengths.map(|l| (6.3 * alpha * l / std::f64::consts::PI).ceil() as i64),
    }
}

fn pme(alpha: f64, grid: usize, order: usize, lengths: [f64; 3], charges: &[f64]) -> PmeReciprocal {
    let params = EwaldParameters {
        alpha,
        grid: [grid; 3],
        order,
    };
    PmeReciprocal::new(params, lengths, KE, charges.to_vec(), &EXCLUDED).expect("PME term")
}

fn relative(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

#[test]
fn the_direct_sum_is_converged_and_independent_of_alpha() {
    for (lengths, q, charges) in boxes() {
        let reference = direct(0.5, lengths, &charges, &EXCLUDED);
        let parts = reference.evaluate(&q);
        let mut wider = reference.clone();
        wider.real_cutoff += 3.0;
        wider.k_max = wider.k_max.map(|k| k + 4);
        let other = direct(0.65, lengths, &charges, &EXCLUDED).evaluate(&q);
        // Each truncation is below 1e-17 relative; the sums of ~10⁴ terms of size ~10²
        // round to ~1e-13 relative.
        assert!(relative(wider.evaluate(&q).total(), parts.total()) < 1e-10);
        assert!(
            relative(other.total(), parts.total()) < 1e-10,
            "{} {}",
            other.total(),
            parts.total()
        );
        let total_gradient = |p: &EwaldParts| -> Vec<f64> {
            (0..q.len())
                .map(|k| p.real_gradient[k] + p.reciprocal_gradient[k])
                .collect()
        };
        let (g1, g2) = (total_gradient(&parts), total_gradient(&other));
        assert!(max_abs_difference(&g1, &g2) < 1e-10 * max_abs(&g1));
    }
}

/// `(relative energy error, relative max gradient error)` of PME's reciprocal part against
/// the reference's, exclusions included (both are in the term's gradient).
fn pme_error(term: &PmeReciprocal, parts: &EwaldParts, q: &[f64]) -> (f64, f64) {
    let components = term.energy_components(q);
    let mut g = vec![0.0; q.len()];
    term.add_gradient(q, &mut g);
    (
        relative(components[0].1, parts.reciprocal),
        max_abs_difference(&g, &parts.reciprocal_gradient) / max_abs(&parts.reciprocal_gradient),
    )
}

#[test]
fn pme_converges_to_the_direct_sum_with_grid_and_order() {
    let alpha = 0.5;
    for (lengths, q, charges) in boxes() {
        let parts = direct(alpha, lengths, &charges, &EXCLUDED).evaluate(&q);
        // The corrections are the same formulas: equal to round-off.
        let components = pme(alpha, 16, 5, lengths, &charges).energy_components(&q);
        assert!(relative(components[1].1, parts.exclusions) < 1e-12);
        assert!(relative(components[2].1, parts.self_energy) < 1e-12);
        if parts.background != 0.0 {
            assert!(relative(components[3].1, parts.background) < 1e-12);
        }
        let mut at_32 = Vec::new();
        for order in 4..=6 {
            let coarse = pme_error(&pme(alpha, 24, order, lengths, &charges), &parts, &q);
            let fine = pme_error(&pme(alpha, 48, order, lengths, &charges), &parts, &q);
            // SPME's interpolation error falls as h^p (EPBDLP95 section 4; the aliasing
            // sum of the B-spline of order p): halving the spacing must gain at least
            // 2^(p−1) (half the asymptotic 2^p, as 24 points are not yet asymptotic).
            let gain = coarse.0 / fine.0;
            assert!(
                gain >= 2f64.powi(order as i32 - 1),
                "order {order}: {coarse:?} {fine:?}"
            );
            at_32.push(pme_error(
                &pme(alpha, 32, order, lengths, &charges),
                &parts,
                &q,
            ));
        }
        // At a fixed grid a higher order is more accurate, in energy and gradient.
        assert!(
            at_32[0].0 > at_32[1].0 && at_32[1].0 > at_32[2].0,
            "{at_32:?}"
        );
        assert!(
            at_32[0].1 > at_32[1].1 && at_32[1].1 > at_32[2].1,
            "{at_32:?}"
        );
        // A fine grid of order 6 (h = 0.16-0.18 Å, αh < 0.1) reaches 1e-8 in energy and
        // 1e-7 in the gradient: (αh)^6 ≈ 1e-6 times the small constant of the order-6
        // aliasing sum.
        let best = pme_error(&pme(alpha, 64, 6, lengths, &charges), &parts, &q);
        assert!(best.0 < 1e-8 && best.1 < 1e-7, "{best:?}");
    }
}

/// Central differences of `f` along `v` with step `h`.
fn derivative(f: impl Fn(&[f64]) -> Vec<f64>, q: &[f64], v: &[f64], h: f64) -> Vec<f64> {
    let shifted = |s: f64| -> Vec<f64> { q.iter().zip(v).map(|(x, d)| x + s * d).collect() };
    let (plus, minus) = (f(&shifted(h)), f(&shifted(-h)));
    plus.iter()
        .zip(&minus)
        .map(|(p, m)| (p - m) / (2.0 * h))
        .collect()
}

#[test]
fn forces_are_minus_the_gradient_and_the_hessian_product_its_derivative() {
    let mut rng = TestRng::new(11);
    for (lengths, q, charges) in boxes() {
        for order in 4..=6 {
            let term = pme(0.45, 16, order, lengths, &charges);
            let gradient = |x: &[f64]| -> Vec<f64> {
                let mut g = vec![0.0; x.len()];
                term.add_gradient(x, &mut g);
                g
            };
            let g = gradient(&q);
            let v = rng.vector(q.len(), -1.0, 1.0);
            // dE/ds along v against g·v. Step 1e-5: the truncation h²E‴/6 ≲ 1e-10·|E‴|
            // and the round-off ε|E|/h ≈ 1e-16·400/1e-5 = 4e-9; 1e-6 of |g|·|v| covers both.
            let energy = |x: &[f64]| vec![term.energy(x)];
            let slope = derivative(energy, &q, &v, 1e-5)[0];
            let along: f64 = g.iter().zip(&v).map(|(a, b)| a * b).sum();
            let scale: f64 = g.iter().zip(&v).map(|(a, b)| (a * b).abs()).sum();
            assert!(
                (slope - along).abs() < 1e-6 * scale,
                "order {order}: {slope} {along}"
            );
            // The Hessian product against differences of the gradient: the gradient of
            // an order-p spline is C^(p−3) with piecewise-polynomial derivatives, so
            // the central difference errs by O(h²) away from knots and O(h) across one
            // (order 4); h = 1e-6 keeps both below 1e-5 of the product's size.
            let mut hv = vec![0.0; q.len()];
            term.add_hessian_vector(&q, &v, &mut hv);
            let fd = derivative(gradient, &q, &v, 1e-6);
            let error = max_abs_difference(&hv, &fd) / max_abs(&hv);
            assert!(error < 1e-5, "order {order}: {error:e}");
        }
    }
}

/// The cluster-pair term with the Ewald real-space form, charges only.
fn real_space_term(
    alpha: f64,
    cutoff: f64,
    lengths: [f64; 3],
    q: &[f64],
    charges: &[f64],
) -> Nonbonded {
    let spec = NonbondedSpec {
        cutoff,
        skin: 1.0,
        inner_buffer: None,
        electrostatics: Electrostatics::Ewald { alpha },
        coulomb_constant: KE,
        box_lengths: Some(lengths),
        types: vec![0; charges.len()],
        lj: vec![LjPair::default()],
        charges: charges.to_vec(),
        excluded: EXCLUDED.to_vec(),
    };
    Nonbonded::new(spec, q).expect("real-space term")
}

#[test]
fn the_engine_real_space_is_the_direct_real_space_sum() {
    for (lengths, q, charges) in boxes() {
        let (alpha, cutoff) = (0.45, 4.4);
        let term = real_space_term(alpha, cutoff, lengths, &q, &charges);
        let mut reference = direct(alpha, lengths, &charges, &EXCLUDED);
        // Below half the box only minimum images lie within the cutoff.
        reference.real_cutoff = cutoff;
        let parts = reference.evaluate(&q);
        let mut g = vec![0.0; q.len()];
        term.add_gradient(&q, &mut g);
        // The same formulas summed in another order: round-off of ~200 terms of ~10².
        assert!(relative(term.energy(&q), parts.real) < 1e-12);
        assert!(max_abs_difference(&g, &parts.real_gradient) < 1e-11 * max_abs(&g));
    }
}

#[test]
fn real_reciprocal_and_corrections_are_the_ewald_energy_at_any_alpha() {
    let cutoff = 4.4;
    for (lengths, q, charges) in boxes() {
        let exact = direct(0.5, lengths, &charges, &EXCLUDED)
            .evaluate(&q)
            .total();
        for tolerance in [1e-5, 1e-7] {
            let alpha = alpha_for_tolerance(tolerance, cutoff);
            let real = real_space_term(alpha, cutoff, lengths, &q, &charges);
            // The mesh error is a function of αh: keep αh ≤ 0.09, that of the 64-point
            // order-6 grid of the test above (α = 0.5, h ≤ 11.5/64).
            let params = EwaldParameters {
                alpha,
                grid: lengths.map(|l| grid_size(l, 0.09 / alpha, 6)),
                order: 6,
            };
            let reciprocal = PmeReciprocal::new(params, lengths, KE, charges.clone(), &EXCLUDED)
                .expect("PME term");
            let total = real.energy(&q) + reciprocal.energy(&q);
            // The stated accuracy: each pair beyond the cutoff has erfc(αr)/r ≤
            // tolerance/r_c, so the real space misses at most k_e (Σ|q_i|)² tol/r_c; the
            // mesh errs by at most 1e-8 of the reciprocal energy (the test above, at the
            // same order and αh).
            let sum_abs: f64 = charges.iter().map(|c| c.abs()).sum();
            let mesh = reciprocal.energy_components(&q)[0].1;
            let bound = KE * sum_abs * sum_abs * tolerance / cutoff + 1e-8 * mesh.abs();
            assert!(
                (total - exact).abs() < bound,
                "tol {tolerance}: {total} {exact} {bound:e}"
            );
        }
    }
}

#[test]
fn parameters_follow_the_gromacs_conventions() {
    let alpha = alpha_for_tolerance(1e-5, 9.0);
    // erfc′ = −(2/√π) e^{−x²} ≈ −6.5e-5 at the root: an α off by one ulp moves erfc by
    // ~1e-20, so the residual is round-off of erfc itself (1e-16 relative).
    assert!((libm::erfc(alpha * 9.0) - 1e-5).abs() < 1e-15, "{alpha}");
    // GROMACS prints 3.47 /nm for r_c = 0.9 nm at its default ewald-rtol.
    assert!((alpha - 0.347).abs() < 5e-4, "{alpha}");
    let water = [18.644491075500707; 3];
    let p = resolve(&EwaldRequest::default(), 9.0, Some(water)).expect("defaults");
    // 18.64/1.2 = 15.5 → 16 = 2⁴; order 5 (OpenMM's).
    assert_eq!((p.grid, p.order), ([16, 16, 16], 5));
    let request = EwaldRequest {
        spacing: Some(1.0),
        order: Some(4),
        ..EwaldRequest::default()
    };
    // 13 → 14 = 2·7, 11.5 → 12, 19.5 → 20.
    let p = resolve(&request, 4.0, Some([13.0, 11.5, 19.5])).expect("spacing 1");
    assert_eq!(p.grid, [14, 12, 20]);
    let explicit = EwaldRequest {
        alpha: Some(0.347),
        grid: Some([16, 18, 20]),
        order: Some(6),
        ..EwaldRequest::default()
    };
    let p = resolve(&explicit, 9.0, Some(water)).expect("explicit");
    assert_eq!((p.alpha, p.grid, p.order), (0.347, [16, 18, 20], 6));
}

#[test]
fn bad_parameters_name_their_key() {
    let water = Some([18.64; 3]);
    let cases: [(EwaldRequest, f64, Option<[f64; 3]>, &str); 7] = [
        (EwaldRequest::default(), 9.0, None, "periodic box"),
        (EwaldRequest::default(), 9.5, water, "cutoff"),
        (
            EwaldRequest {
                grid: Some([16, 8, 16]),
                ..EwaldRequest::default()
            },
            9.0,
            water,
            "pme_grid",
        ),
        (
            EwaldRequest {
                tolerance: Some(0.0),
                ..EwaldRequest::default()
            },
            9.0,
            water,
            "ewald_tolerance",
        ),
        (
            EwaldRequest {
                alpha: Some(-0.3),
                ..EwaldRequest::default()
            },
            9.0,
            water,
            "ewald_alpha",
        ),
        (
            EwaldRequest {
                spacing: Some(0.0),
                ..EwaldRequest::default()
            },
            9.0,
            water,
            "fourier_spacing",
        ),
        (
            EwaldRequest {
                order: Some(8),
                ..EwaldRequest::default()
            },
            9.0,
            water,
            "pme_order",
        ),
    ];
    for (request, cutoff, lengths, key) in cases {
        let message = resolve(&request, cutoff, lengths).expect_err(key);
        assert!(message.contains(key), "{key}: {message}");
    }
}

/// The water box's scene with `[forcefield]` lines replaced.
fn water_scene(coulomb: &str) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("systems/water-box/scene.toml");
    let text = std::fs::read_to_string(path).expect("water scene");
    text.replace("coulomb = \"dsf\"\ndsf_alpha = 0.0", coulomb)
}

fn build(text: &str) -> Result<longstep::io::scene::Scene, String> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("systems/water-box/pme.toml");
    longstep::io::scene::build_scene(text, &path, &[]).map_err(|e| e.to_string())
}

#[test]
fn scene_keys_build_pme_and_bad_ones_name_the_key() {
    let scene = build(&water_scene(
        "coulomb = \"pme\"\newald_alpha = \"3.47/nm\"\npme_grid = [16, 16, 16]",
    ))
    .expect("PME scene");
    let forces = &scene.system.forces;
    let pme = forces
        .terms()
        .iter()
        .find(|t| t.term.kind() == "pme-reciprocal")
        .expect("a pme-reciprocal term");
    // The slowest level by default.
    assert_eq!(pme.level, forces.n_levels() - 1);
    let term = pme
        .term
        .as_any()
        .and_then(|t| t.downcast_ref::<PmeReciprocal>());
    let params = term.expect("PmeReciprocal").parameters();
    assert!((params.alpha - 0.347).abs() < 1e-15);
    let moved = build(&water_scene("coulomb = \"pme\"\npme_level = 0")).expect("pme_level 0");
    let level = |s: &longstep::io::scene::Scene| {
        s.system
            .forces
            .terms()
            .iter()
            .find(|t| t.term.kind() == "pme-reciprocal")
            .map(|t| t.level)
    };
    assert_eq!(level(&moved), Some(0));
    for (lines, key) in [
        (
            "coulomb = \"pme\"\newald_alpha = \"0.3/furlong\"",
            "ewald_alpha",
        ),
        ("coulomb = \"pme\"\npme_grid = [16, 16, 6]", "pme_grid"),
        (
            "coulomb = \"pme\"\nfourier_spacing = -1.0",
            "fourier_spacing",
        ),
        (
            "coulomb = \"pme\"\newald_tolerance = 0.0",
            "ewald_tolerance",
        ),
        ("coulomb = \"dsf\"\npme_order = 5", "pme_order"),
    ] {
        let message = build(&water_scene(lines)).err().expect(key);
        assert!(message.contains(key), "{key}: {message}");
    }
    // A charged box: a notice and the background term.
    let charged = water_scene("coulomb = \"pme\"").replace("charge = 0.41", "charge = 0.42");
    let scene = build(&charged).expect("charged box");
    assert!(
        scene
            .forcefield_report
            .iter()
            .any(|l| l.contains("net charge"))
    );
    let term = scene
        .system
        .forces
        .terms()
        .iter()
        .find(|t| t.term.kind() == "pme-reciprocal");
    let q = &scene.system.state.q;
    let background = term.expect("pme-reciprocal").term.energy_components(q)[3];
    // −k_e π Q²/(2Vα²) with Q = 432 × 0.01 e.
    let volume = 18.644491075500707f64.powi(3);
    let alpha = alpha_for_tolerance(1e-5, 9.0);
    let expected = -KE * std::f64::consts::PI * 4.32 * 4.32 / (2.0 * volume * alpha * alpha);
    assert_eq!(background.0, "ewald-background");
    assert!(
        relative(background.1, expected) < 1e-12,
        "{background:?} {expected}"
    );
    let no_box = water_scene("coulomb = \"pme\"").replace("box = [", "# box = [");
    let message = build(&no_box).err().expect("no box");
    assert!(message.contains("box"), "{message}");
}

/// The `forces.csv` rows' forces.
fn read_forces(path: &Path) -> Vec<[f64; 3]> {
    let text = std::fs::read_to_string(path).expect("forces csv");
    text.lines()
        .skip(1)
        .map(|line| {
            let fields: Vec<&str> = line.split(',').collect();
            std::array::from_fn(|a| fields[2 + a].parse().expect("a force"))
        })
        .collect()
}

#[test]
fn the_water_box_matches_openmm_pme() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let data = std::fs::read_to_string(root.join("tests/data/openmm-pme-water.json"))
        .expect("tests/data/openmm-pme-water.json (scripts/openmm_pme_reference.py)");
    let reference: serde_json::Value = serde_json::from_str(&data).expect("JSON");
    let dir = common::scratch_dir("ewald-openmm");
    let csv = dir.join("forces.csv");
    let output = common::longstep()
        .arg("forces")
        .arg(root.join("systems/water-box/scene.toml"))
        .args(words(
            "--coulomb pme --ewald-alpha 0.347 --pme-grid 16,16,16",
        ))
        .args(["--pme-order", "5", "--json", "--quiet", "--out"])
        .arg(&csv)
        .output()
        .expect("longstep forces");
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let printed: serde_json::Value = serde_json::from_slice(&output.stdout).expect("--json");
    let energy = |v: &serde_json::Value, key: &str| v[key].as_f64().expect(key);
    // The scene's k_e = 332.06371 and OpenMM's 138.935457644 kJ/mol·nm (332.0637133 in
    // kcal/mol·Å) differ by 1e-8 relative; the rest is round-off and the solver's own
    // differences far below. 1e-6 is the bound.
    let coulomb = energy(&printed["energy"], "coulomb");
    let openmm_coulomb = energy(&reference["energy"], "coulomb");
    assert!(
        relative(coulomb, openmm_coulomb) < 1e-6,
        "{coulomb} {openmm_coulomb}"
    );
    // Like with like: the scene's Lennard-Jones is energy-shifted, so its total is OpenMM's
    // minus n_pairs V_LJ(r_c) (the script's total_shifted).
    let total = energy(&printed["energy"], "total");
    let openmm_total = energy(&reference["energy"], "total_shifted");
    assert!(
        relative(total, openmm_total) < 1e-6,
        "{total} {openmm_total}"
    );
    let forces = read_forces(&csv);
    let openmm: Vec<[f64; 3]> = reference["forces"]
        .as_array()
        .expect("forces")
        .iter()
        .map(|f| std::array::from_fn(|a| f[a].as_f64().expect("a force")))
        .collect();
    assert_eq!(forces.len(), openmm.len());
    let (mut difference, mut norm) = (0.0, 0.0);
    for (f, g) in forces.iter().zip(&openmm) {
        for a in 0..3 {
            difference += (f[a] - g[a]) * (f[a] - g[a]);
            norm += g[a] * g[a];
        }
    }
    let rms = (difference / norm).sqrt();
    assert!(rms <= 1e-6, "relative RMS force difference {rms:e}");
}

#[test]
fn bad_pme_flags_exit_1_naming_the_key() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for (flags, key) in [
        (["--pme-grid", "16,16,6"], "pme_grid"),
        (["--pme-grid", "16,16"], "--pme-grid"),
        (["--ewald-alpha", "-1"], "ewald_alpha"),
        (["--pme-order", "9"], "pme_order"),
    ] {
        let output = common::longstep()
            .arg("forces")
            .arg(root.join("systems/water-box/scene.toml"))
            .args(["--coulomb", "pme", "--quiet"])
            .args(flags)
            .output()
            .expect("longstep forces");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(1), "{flags:?}: {stderr}");
        assert!(stderr.contains(key), "{flags:?}: {stderr}");
    }
}

#[test]
fn pme_gives_the_same_bits_on_one_two_and_three_threads() {
    // Above the parallel threshold (1024 atoms): the per-atom splines, spreading, the FFT's
    // line passes and the gathering run in parallel on two and three threads (slabs of
    // different sizes, uneven shares of the planes), serially on one.
    let lengths = [30.0, 31.0, 32.0];
    let (q, charges) = charges_in_box(2000, lengths, true, 21);
    let v = TestRng::new(5).vector(q.len(), -1.0, 1.0);
    let params = EwaldParameters {
        alpha: 0.35,
        // Unequal axes and an odd z: a layout or Nyquist slip would differ between passes.
        grid: [30, 32, 27],
        order: 5,
    };
    let term = PmeReciprocal::new(params, lengths, KE, charges, &EXCLUDED).expect("PME term");
    let evaluate = |threads: usize| common::term_bits(&term, &q, &v, threads);
    let serial = evaluate(1);
    assert!(serial == evaluate(2));
    assert!(serial == evaluate(3));
}

/// The drift verdict of a 0.5 ps NVE run of the PME water box with `flags`.
fn pme_water_drift(name: &str, flags: &[&str]) -> serde_json::Value {
    let out = common::scratch_dir(name);
    let mut args = argv(
        "run systems/water-box/scene.toml --coulomb pme --t-end 0.5ps --json --quiet \
         --out {}",
        &[out.to_str().unwrap()],
    );
    args.extend_from_slice(flags);
    let (code, stdout, stderr) = common::run_cli(&args);
    assert_eq!(code, 0, "{flags:?}: {stderr}");
    let json: serde_json::Value = serde_json::from_str(&stdout).expect("JSON summary");
    json["drift"].clone()
}

/// The reciprocal sum as its own level (GROMACS's `mts-level2-forces =
/// longrange-nonbonded`, factor 2): impulse with the mesh every 2 inner steps of 0.5 fs
/// keeps the energy as plain Verlet at 0.5 fs does, by the same drift criterion
/// (|drift| ≤ 0.05 kT/ns/dof, or a change within twice the energy's fluctuation). A kick
/// of the wrong length or a mesh force on the wrong level drifts far beyond both.
#[test]
fn reciprocal_sum_every_two_inner_steps_keeps_the_energy_as_verlet_does() {
    let mts = pme_water_drift(
        "pme-mts",
        &words("--nonbonded-level 0 --pme-level 1 --method impulse --h 1fs --inner 2"),
    );
    let verlet = pme_water_drift("pme-verlet", &["--method", "verlet", "--h", "0.5fs"]);
    for (label, drift) in [("impulse 1 fs / 2", &mts), ("verlet 0.5 fs", &verlet)] {
        assert_ne!(
            drift["verdict"], "fail",
            "{label}: a drift whose 2σ interval lies beyond the bound: {drift}"
        );
    }
    // Both fluctuate by the inner step's error, which the slow impulse barely adds to.
    let fluctuation = |d: &serde_json::Value| d["fluctuation"].as_f64().expect("fluctuation");
    assert!(
        fluctuation(&mts) <= 2.0 * fluctuation(&verlet),
        "impulse's energy fluctuates {} against Verlet's {}",
        fluctuation(&mts),
        fluctuation(&verlet)
    );
}
