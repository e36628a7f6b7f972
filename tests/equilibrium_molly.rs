//! The equilibrium mollifier (IRS99): the projection `A(q)` onto the rest geometry of the
//! fast bonds (and angles), its exact Jacobian, and the method built on them.

mod common;
use common::{TestRng, argv, integrate, longstep, scene, scene_file, scratch_dir};

use longstep::integrators::equilibrium_molly::{ConstraintSet, EquilibriumMolly, MollyJacobian};
use longstep::integrators::{self, Integrator};
use longstep::io::scene::Scene;
use longstep::settings::MethodSettings;
use nalgebra::{DMatrix, Matrix3, Vector3};

const WATER: &str = "systems/water-box/scene.toml";
const DIPEPTIDE: &str = "systems/molecules/alanine-dipeptide.toml";
/// The first chain of the polymer melt alone in the melt's box (see [`melt_chain`]).
const MELT_CHAIN: &str = "melt-chain";

/// The first 50-bead chain of systems/polymer-melt, with the melt's bonds and angles, in
/// its periodic box: one chain keeps the tests fast, and its unwrapped length (≈ 50 Å of
/// backbone) exceeds half the box, so unwrapping along the bonds is exercised.
fn melt_chain() -> Scene {
    let xyz = std::fs::read_to_string("systems/polymer-melt/polymer.xyz").unwrap();
    let box_length = 61.46588547855472;
    let mut text = format!(
        "version = 1\nname = \"melt-chain\"\ndim = 3\nbox = [{box_length}, {box_length}, {box_length}]\n"
    );
    for line in xyz.lines().skip(2).take(50) {
        let x: Vec<&str> = line.split_whitespace().skip(1).collect();
        text += &format!(
            "[[particles]]\nmass = 39.948\nposition = [{}, {}, {}]\n",
            x[0], x[1], x[2]
        );
    }
    text += "[[terms]]\ntype = \"chain\"\nrange = [0, 49]\nstiffness = 20.53644010600288\nrest_length = 3.30285\n";
    let triples: Vec<String> = (0..48)
        .map(|i| format!("[{}, {}, {}]", i, i + 1, i + 2))
        .collect();
    text += &format!(
        "[[terms]]\ntype = \"angle\"\ntriples = [{}]\nstiffness = 1.1905\nrest_angle = {}\n",
        triples.join(", "),
        109.47f64.to_radians()
    );
    scene(&text)
}

fn load(path: &str) -> Scene {
    if path == MELT_CHAIN {
        melt_chain()
    } else {
        scene_file(path, &[])
    }
}

/// The tightest Newton tolerance round-off allows on these systems (coordinates of up to
/// ~20 Å, relative round-off of a squared distance a few 1e-16): with it `A` is a smooth
/// function of `q` to round-off, as finite differences need.
const TIGHT: f64 = 1e-13;

fn prepared(
    scene: &Scene,
    set: ConstraintSet,
    jacobian: MollyJacobian,
    tol: f64,
) -> EquilibriumMolly {
    let mut molly = EquilibriumMolly::new(set, jacobian, tol, 50).unwrap();
    molly.prepare(&scene.system).unwrap();
    molly
}

/// Every coordinate displaced uniformly by up to `amplitude`: off the rest manifold, so
/// the multipliers μ and the curvature term are not zero.
fn distort(scene: &mut Scene, amplitude: f64, seed: u64) {
    let mut rng = TestRng::new(seed);
    for x in &mut scene.system.state.q {
        *x += rng.uniform(-amplitude, amplitude);
    }
}

fn minimum_image(scene: &Scene, mut d: [f64; 3]) -> [f64; 3] {
    if let Some(b) = &scene.system.periodic_box {
        for (axis, x) in d.iter_mut().enumerate() {
            *x = b.wrap(axis, *x);
        }
    }
    d
}

fn position(x: &[f64], i: usize) -> [f64; 3] {
    [x[3 * i], x[3 * i + 1], x[3 * i + 2]]
}

fn largest_length(molly: &EquilibriumMolly) -> f64 {
    molly.plans().map(|p| p.length_scale).fold(0.0, f64::max)
}

/// The largest relative violation `|r² − d²|/d²` of the held distances at `x`.
fn violation(scene: &Scene, molly: &EquilibriumMolly, x: &[f64]) -> f64 {
    let mut worst: f64 = 0.0;
    for plan in molly.plans() {
        for c in &plan.constraints {
            let a = position(x, plan.atoms[c.a]);
            let b = match c.b {
                Some(b) => position(x, plan.atoms[b]),
                None => c.anchor,
            };
            let d = minimum_image(scene, [a[0] - b[0], a[1] - b[1], a[2] - b[2]]);
            let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            worst = worst.max((r2 - c.length2).abs() / c.length2);
        }
    }
    worst
}

#[test]
fn the_projection_meets_the_constraints_and_is_idempotent() {
    for (path, set) in [
        (WATER, ConstraintSet::Bonds),
        (WATER, ConstraintSet::BondsAngles),
        (DIPEPTIDE, ConstraintSet::BondsAngles),
        (MELT_CHAIN, ConstraintSet::Bonds),
        (MELT_CHAIN, ConstraintSet::BondsAngles),
    ] {
        let mut s = load(path);
        distort(&mut s, 0.03, 5);
        let tol = longstep::integrators::equilibrium_molly::DEFAULT_TOLERANCE;
        let mut molly = prepared(&s, set, MollyJacobian::Exact, tol);
        let q = s.system.state.q.clone();
        molly.project(&q).unwrap();
        let a = molly.projected().to_vec();
        // Newton stops once every |g_c|/d_c² is at most the tolerance.
        let v = violation(&s, &molly, &a);
        assert!(v <= tol, "{path} {set:?}: violation {v:e} > {tol:e}");
        assert!(
            violation(&s, &molly, &q) > 1e-3,
            "{path}: the start is on the manifold, the check is empty"
        );
        // A point of the manifold is its own closest point: Newton stops before its first
        // step, and A(A(q)) = q + 0 exactly.
        molly.project(&a).unwrap();
        assert_eq!(molly.projected(), &a[..], "{path} {set:?}: A(A(q)) ≠ A(q)");
    }
}

/// The mass-weighted best rigid placement (Kabsch) of `reference` onto `target`.
fn kabsch(
    reference: &[Vector3<f64>],
    target: &[Vector3<f64>],
    masses: &[f64],
) -> Vec<Vector3<f64>> {
    let total: f64 = masses.iter().sum();
    let centre = |x: &[Vector3<f64>]| -> Vector3<f64> {
        x.iter()
            .zip(masses)
            .map(|(p, m)| p * *m)
            .sum::<Vector3<f64>>()
            / total
    };
    let (cr, ct) = (centre(reference), centre(target));
    let mut h = Matrix3::zeros();
    for ((r, t), m) in reference.iter().zip(target).zip(masses) {
        h += *m * (r - cr) * (t - ct).transpose();
    }
    let svd = h.svd(true, true);
    let (u, v_t) = (svd.u.unwrap(), svd.v_t.unwrap());
    let d = (v_t.transpose() * u.transpose()).determinant().signum();
    let rotation =
        v_t.transpose() * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * u.transpose();
    reference.iter().map(|r| rotation * (r - cr) + ct).collect()
}

#[test]
fn water_held_rigid_projects_to_the_mass_weighted_kabsch_fit() {
    // Bonds and the H–H distance make each water rigid: the mass-weighted closest point of
    // its manifold is the rest triangle placed by the mass-weighted Kabsch fit.
    let mut s = scene_file(WATER, &[]);
    distort(&mut s, 0.03, 6);
    let mut molly = prepared(&s, ConstraintSet::BondsAngles, MollyJacobian::Exact, TIGHT);
    let q = s.system.state.q.clone();
    molly.project(&q).unwrap();
    let (r0, theta0) = (1.012, 113.24f64.to_radians());
    let masses = &s.system.particles.masses;
    let mut worst: f64 = 0.0;
    for plan in molly.plans() {
        assert_eq!(plan.atoms.len(), 3);
        // Masses are internal units (amu × 418.4): the oxygen is the heaviest.
        let o = *plan
            .atoms
            .iter()
            .max_by(|&&i, &&j| masses[i].total_cmp(&masses[j]))
            .unwrap();
        let hs: Vec<usize> = plan.atoms.iter().copied().filter(|&i| i != o).collect();
        let atoms = [o, hs[0], hs[1]];
        let reference = [
            Vector3::zeros(),
            Vector3::new(r0, 0.0, 0.0),
            Vector3::new(r0 * theta0.cos(), r0 * theta0.sin(), 0.0),
        ];
        // Target and result relative to the oxygen by minimum image (the molecule may
        // straddle the box).
        let relative = |x: &[f64], i: usize| -> Vector3<f64> {
            let (p, po) = (position(x, i), position(x, o));
            Vector3::from(minimum_image(
                &s,
                [p[0] - po[0], p[1] - po[1], p[2] - po[2]],
            ))
        };
        let target: Vec<Vector3<f64>> = atoms.iter().map(|&i| relative(&q, i)).collect();
        let m: Vec<f64> = atoms.iter().map(|&i| masses[i]).collect();
        let fit = kabsch(&reference, &target, &m);
        let a_o = position(molly.projected(), o);
        let q_o = position(&q, o);
        for (k, &i) in atoms.iter().enumerate() {
            let got = relative(molly.projected(), i)
                + Vector3::from(minimum_image(
                    &s,
                    [a_o[0] - q_o[0], a_o[1] - q_o[1], a_o[2] - q_o[2]],
                ));
            worst = worst.max((got - fit[k]).amax());
        }
    }
    // Both are exact up to round-off on ~20 Å coordinates (Newton at TIGHT, an SVD of a 3×3
    // matrix): 1e-12 Å is a hundred times that, ten thousand times below the displacements
    // A − q (~0.01–0.05 Å) that a wrong projection would get wrong.
    assert!(worst < 1e-12, "Kabsch fit and A(q) differ by {worst:e} Å");
}

/// The full Jacobian rows `A_qᵀ e_i` for the coordinates `dofs`, and the central
/// finite-difference columns `∂A/∂q_i` with step ε, restricted to `dofs`.
fn jacobians(
    s: &Scene,
    molly: &mut EquilibriumMolly,
    dofs: &[usize],
    epsilon: f64,
) -> (DMatrix<f64>, DMatrix<f64>) {
    let q = s.system.state.q.clone();
    let n = q.len();
    molly.project(&q).unwrap();
    let mut analytic = DMatrix::zeros(dofs.len(), dofs.len());
    let (mut e, mut row) = (vec![0.0; n], vec![0.0; n]);
    for (r, &i) in dofs.iter().enumerate() {
        e.fill(0.0);
        e[i] = 1.0;
        // (A_qᵀ e_i)_j = (A_q)_{ij}: row i of A_q.
        molly.transpose_product(&e, &mut row);
        for (c, &j) in dofs.iter().enumerate() {
            analytic[(r, c)] = row[j];
        }
    }
    let mut fd = DMatrix::zeros(dofs.len(), dofs.len());
    let mut x = q.clone();
    for (c, &j) in dofs.iter().enumerate() {
        x[j] = q[j] + epsilon;
        molly.project(&x).unwrap();
        let plus = molly.projected().to_vec();
        x[j] = q[j] - epsilon;
        molly.project(&x).unwrap();
        let minus = molly.projected().to_vec();
        x[j] = q[j];
        for (r, &i) in dofs.iter().enumerate() {
            fd[(r, c)] = (plus[i] - minus[i]) / (2.0 * epsilon);
        }
    }
    (analytic, fd)
}

fn check_jacobian(path: &str, set: ConstraintSet, dofs: std::ops::Range<usize>, seed: u64) {
    let mut s = load(path);
    distort(&mut s, 0.03, seed);
    let dofs: Vec<usize> = dofs.collect();
    let mut exact = prepared(&s, set, MollyJacobian::Exact, TIGHT);
    let mut projection = prepared(&s, set, MollyJacobian::Projection, TIGHT);
    let (coarse, fine) = (1e-4, 5e-5);
    let (j_exact, fd_coarse) = jacobians(&s, &mut exact, &dofs, coarse);
    let (j_projection, fd_fine) = jacobians(&s, &mut projection, &dofs, fine);
    // The difference of the two steps measures the ε² truncation of the coarser one, and
    // bounds the finer one's (4× smaller); round-off of A (~TIGHT · ℓ from Newton, a few
    // ulps of ~20 Å coordinates) enters divided by ε.
    let truncation = (&fd_coarse - &fd_fine).amax();
    let round_off = (TIGHT * largest_length(&exact) + 1e-16 * 20.0) / fine;
    let bound = 2.0 * truncation + 10.0 * round_off;
    let error = (&j_exact - &fd_fine).amax();
    eprintln!(
        "{path} {set:?}: |exact − FD| = {error:.2e}, bound {bound:.2e}, |projection − FD| = {:.2e}",
        (&j_projection - &fd_fine).amax()
    );
    assert!(
        error <= bound,
        "{path} {set:?}: |A_q − FD| = {error:e} > {bound:e}"
    );
    // The projection Jacobian drops the curvature term μ·∇²g, of relative size |μ|/m ~
    // the relative distance from the manifold (~1e-2 here): measurably wrong.
    let wrong = (&j_projection - &fd_fine).amax();
    assert!(
        wrong > 100.0 * bound,
        "{path} {set:?}: the projection Jacobian is within {wrong:e} of FD"
    );
    let identity = DMatrix::<f64>::identity(dofs.len(), dofs.len());
    assert!(
        (&j_exact - identity).amax() > 0.1,
        "{path}: trivial Jacobian"
    );
}

#[test]
fn the_exact_jacobian_matches_finite_differences_and_the_projection_does_not() {
    // Three waters of the periodic box (the Jacobian is block-diagonal over molecules).
    check_jacobian(WATER, ConstraintSet::Bonds, 0..27, 7);
    check_jacobian(WATER, ConstraintSet::BondsAngles, 0..27, 8);
    // A branched molecule with sp2 and sp3 centres: every coordinate.
    check_jacobian(DIPEPTIDE, ConstraintSet::BondsAngles, 0..66, 9);
    // A chain of the melt, longer than half the box once unwrapped: the entries of A_q
    // among its first 12 beads (with angles every bead moves every other).
    check_jacobian(MELT_CHAIN, ConstraintSet::Bonds, 0..36, 10);
    check_jacobian(MELT_CHAIN, ConstraintSet::BondsAngles, 0..36, 11);
}

fn molly_method(h: f64, inner: usize, jacobian: &str) -> Box<dyn Integrator> {
    let mut settings = MethodSettings::new("equilibrium-molly", h).with_inner_steps(inner);
    settings.molly_jacobian = Some(jacobian.into());
    integrators::build(&settings, &mut Vec::new()).unwrap()
}

/// `mollified_total = K + W(q) + U(A(q))` at the current state.
fn mollified_total(integrator: &dyn Integrator, scene: &Scene) -> f64 {
    assert_eq!(integrator.extra_columns(), vec!["mollified_total"]);
    let mut out = Vec::new();
    integrator.extra_values(&scene.system, &mut out);
    out[0]
}

/// The largest |E(t) − E(0)| of the mollified energy over `steps` outer steps.
fn mollified_energy_error(h: f64, inner: usize, jacobian: &str, steps: usize) -> f64 {
    let mut s = scene_file(WATER, &[]);
    let mut integrator = molly_method(h, inner, jacobian);
    integrator.setup(&mut s.system).unwrap();
    let start = mollified_total(integrator.as_ref(), &s);
    let mut worst: f64 = 0.0;
    for _ in 0..steps {
        integrator.step(&mut s.system).unwrap();
        worst = worst.max((mollified_total(integrator.as_ref(), &s) - start).abs());
    }
    worst
}

#[test]
fn the_exact_jacobian_conserves_the_mollified_energy_and_the_projection_does_not() {
    // Water box, 0.25 ps. With the exact Jacobian the method is r-RESPA for W + U∘A, a
    // second-order symplectic scheme: halving h and dt together divides the energy error
    // by 4 (the O(h⁴) rest and the chaos of 648 atoms move the ratio by well under 25 %).
    let coarse = mollified_energy_error(2.0, 4, "exact", 125);
    let fine = mollified_energy_error(1.0, 4, "exact", 250);
    let ratio = coarse / fine;
    eprintln!("exact: max |ΔE| {coarse:.3} (h = 2 fs), {fine:.3} (h = 1 fs), ratio {ratio:.2}");
    assert!(
        (3.0..5.0).contains(&ratio),
        "exact: ratio {ratio} when h halves"
    );
    // The projection Jacobian's force is not −∇(W + U∘A): the energy drifts at a rate that
    // does not vanish with h, far beyond the exact method's O(h²) error.
    let projection = mollified_energy_error(1.0, 4, "projection", 250);
    eprintln!("projection: max |ΔE| {projection:.3} (h = 1 fs)");
    assert!(
        projection > 10.0 * coarse,
        "projection: max |ΔE| {projection} is not beyond the exact method's {coarse}"
    );
}

#[test]
fn a_step_is_time_reversible() {
    // Forward n steps, momenta reversed, n steps, momenta reversed: the start again, up to
    // round-off amplified by the dynamics. Impulse on the same system calibrates that
    // amplification; A depends on q alone (Newton starts from A = q, μ = 0 every call), so
    // the mollified method must come back as closely, within a factor for its extra
    // arithmetic (a warm start from the previous step's A would leave errors of the Newton
    // tolerance, 1e-10 relative, ~1e-10 Å).
    let round_trip = |method: &mut dyn Integrator| -> f64 {
        let mut s = scene_file(WATER, &[]);
        let q0 = s.system.state.q.clone();
        method.setup(&mut s.system).unwrap();
        for _ in 0..10 {
            method.step(&mut s.system).unwrap();
        }
        s.system.state.p.iter_mut().for_each(|p| *p = -*p);
        method.setup(&mut s.system).unwrap();
        for _ in 0..10 {
            method.step(&mut s.system).unwrap();
        }
        common::max_abs_difference(&s.system.state.q, &q0)
    };
    let impulse = round_trip(common::method("impulse", 4.0, Some(8)).as_mut());
    let molly = round_trip(molly_method(4.0, 8, "exact").as_mut());
    eprintln!("round trip: impulse {impulse:e} Å, equilibrium-molly {molly:e} Å");
    assert!(
        molly < 100.0 * impulse.max(1e-15),
        "{molly:e} Å vs impulse {impulse:e} Å"
    );
    assert!(molly < 1e-11, "{molly:e} Å");
}

/// Two particles on springs to walls (fast, rest length 1, so each is held on a circle),
/// with an optional slow spring between them (mts_exactness's three-spring system).
fn three_spring(slow: bool) -> String {
    common::three_spring(if slow { common::SLOW_MIDDLE } else { "" }, "fast")
}

#[test]
fn without_slow_forces_it_is_the_reduced_verlet_trajectory_bit_for_bit() {
    let (h, inner, steps) = (0.4, 8, 25);
    let mut reference = scene(&three_spring(false));
    let (q_ref, p_ref) = integrate(
        &mut reference,
        common::method("verlet", h / inner as f64, None).as_mut(),
        inner * steps,
    );
    for jacobian in ["exact", "projection"] {
        let mut s = scene(&three_spring(false));
        let (q, p) = integrate(&mut s, molly_method(h, inner, jacobian).as_mut(), steps);
        assert_eq!(q, q_ref, "{jacobian}: positions differ from reduced Verlet");
        assert_eq!(p, p_ref, "{jacobian}: momenta differ from reduced Verlet");
    }
}

/// `max |Jᵀ Ω J − Ω|` of the one-step map, J by fourth-order central differences.
fn symplecticity_defect(jacobian: &str) -> f64 {
    let text = three_spring(true);
    common::symplecticity_defect(&text, &|| molly_method(0.3, 12, jacobian)).0
}

#[test]
fn with_the_exact_jacobian_the_step_is_symplectic() {
    // The mollified impulse A_qᵀ ∇U(A) is the gradient of U(A(q)) only with the exact
    // Jacobian: then the step is a composition of symplectic maps. The differences are
    // accurate to ~1e-11 here (as in tests/mts_exactness.rs), and Newton's tolerance puts
    // A within 1e-10 · 1 of its exact value by a smooth function of q: a defect below
    // 1e-9 is symplecticity. The projection Jacobian misses the curvature term, relative
    // size |μ|/m ~ the distance from the circles (~5 %): its defect is O(h · 5 % · k_slow).
    let exact = symplecticity_defect("exact");
    let projection = symplecticity_defect("projection");
    eprintln!("|JᵀΩJ − Ω|: exact {exact:e}, projection {projection:e}");
    assert!(exact < 1e-9, "exact: {exact:e}");
    assert!(projection > 1e-5, "projection: {projection:e}");
}

fn run_cli(args: &[&str]) -> (i32, String) {
    let output = longstep().args(args).output().expect("longstep runs");
    (
        output.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

#[test]
fn bad_input_is_refused_clearly() {
    let out = scratch_dir("molly-bad");
    let out = out.to_str().unwrap();
    // No fast bonds: the LJ chain of three-body? A Kepler orbit has none.
    let (code, stderr) = run_cli(&argv(
        "run systems/kepler.toml --method equilibrium-molly --h 0.01 --inner 2 --t-end 0.1 \
         --out {}",
        &[out],
    ));
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("fast level has none"), "{stderr}");
    for (flag, value, known) in [
        ("--molly-constraints", "angles", "bonds or bonds-angles"),
        ("--molly-jacobian", "adjoint", "exact or projection"),
    ] {
        let (code, stderr) = run_cli(&argv(
            "run {} --method equilibrium-molly --h 2fs --inner 4 --t-end 4fs {} {} --out {}",
            &[WATER, flag, value, out],
        ));
        assert_eq!(code, 1, "{stderr}");
        assert!(stderr.contains(value) && stderr.contains(known), "{stderr}");
    }
}

#[test]
fn a_start_too_distorted_to_project_stops_with_its_time() {
    // One water whose first hydrogen sits on its oxygen: 1e-20 apart, so the scene loads
    // (the spring's force is finite), but in the molecule's frame, where the other hydrogen
    // is 1 away, they coincide. The O–H bond has no direction to be restored along.
    let dir = scratch_dir("molly-distorted");
    let scene_path = dir.join("water.toml");
    std::fs::write(
        &scene_path,
        r#"
version = 1
name = "crushed-water"
dim = 3
[[particles]]
mass = 16.0
position = [0.0, 0.0, 0.0]
[[particles]]
mass = 1.0
position = [1e-20, 0.0, 0.0]
[[particles]]
mass = 1.0
position = [-0.3, 0.95, 0.0]
[[terms]]
type = "spring"
pairs = [[0, 1], [0, 2]]
stiffness = 1000.0
rest_length = 1.0
[[terms]]
type = "lennard-jones"
particles = [1, 2]
epsilon = 0.1
sigma = 0.5
"#,
    )
    .unwrap();
    let out = dir.join("out");
    let output = longstep()
        .args(argv(
            "run {} --method equilibrium-molly --h 0.01 --inner 4 --t-end 0.1 --out {} \
             --json",
            &[scene_path.to_str().unwrap(), out.to_str().unwrap()],
        ))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(3), "{stderr}");
    let summary: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(summary["status"], "failed", "{summary}");
    assert_eq!(summary["t_end"], 0.0, "{summary}");
    let message = summary["message"].as_str().unwrap();
    assert!(
        message.contains("equilibrium-molly") && message.contains("molecule 0"),
        "{message}"
    );
    // energy.csv holds its header and the row at t = 0.
    let csv = std::fs::read_to_string(out.join("energy.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), 2, "{csv}");
    assert!(
        lines[0].ends_with("mollified_total") && lines[1].starts_with("0,"),
        "{csv}"
    );
}

#[test]
fn langevin_respa_takes_the_equilibrium_mollifier() {
    // langevin-respa --mollifier equilibrium-molly with γ = 1e-300 (a = 1 exactly, noise
    // below half an ulp of p) is equilibrium-molly up to the rounding of the drift taken in
    // two halves (≤ 1 ulp of q per inner step). Alanine dipeptide from its start geometry,
    // 20 outer steps of 1 fs: 22 atoms over 20 fs amplify round-off by orders, not by the
    // ~10⁹ between that bound and 1e-6 (the printed difference shows how far it is).
    // Unwired, the slow force would be the plain one at q: against plain langevin-respa the
    // positions part by ~1e-2 Å in these 20 fs (measured 9.9e-3), far above both bounds.
    let (h, inner, steps) = (1.0, 4, 20);
    let mut settings = MethodSettings::new("langevin-respa", h).with_inner_steps(inner);
    settings.temperature = Some(300.0);
    settings.friction = Some(1e-300);
    settings.mollifier = Some("equilibrium-molly".into());
    settings.molly_constraints = Some("bonds".into());
    let mut notices = Vec::new();
    let mut langevin = integrators::build(&settings, &mut notices).unwrap();
    assert!(notices.is_empty(), "{notices:?}");
    settings.mollifier = None;
    let mut plain = integrators::build(&settings, &mut Vec::new()).unwrap();
    let mut settings = MethodSettings::new("equilibrium-molly", h).with_inner_steps(inner);
    settings.molly_constraints = Some("bonds".into());
    let mut molly = integrators::build(&settings, &mut Vec::new()).unwrap();

    let run = |method: &mut dyn Integrator| {
        let mut s = scene_file(DIPEPTIDE, &[]);
        integrate(&mut s, method, steps).0
    };
    let (q_langevin, q_plain, q_molly) = (
        run(langevin.as_mut()),
        run(plain.as_mut()),
        run(molly.as_mut()),
    );
    assert_eq!(langevin.extra_columns(), vec!["mollified_total"]);
    let same = common::max_abs_difference(&q_langevin, &q_molly);
    let unmollified = common::max_abs_difference(&q_langevin, &q_plain);
    eprintln!(
        "max |Δq|: {same:.2e} Å against equilibrium-molly, {unmollified:.2e} Å against plain langevin-respa"
    );
    assert!(same < 1e-6, "{same}");
    assert!(unmollified > 1e-3, "{unmollified}");
}
