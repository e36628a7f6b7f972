//! The mollified impulse methods with constraints (issue 41, item 2): the constrained
//! averaging's Jacobian against finite differences along the constraint manifold (bonds to
//! hydrogen by SHAKE/RATTLE, rigid water by SETTLE), the constrained path with no
//! constraint against the unconstrained one, every mollified method with constraints and
//! heavy hydrogens conserving its energy to second order, and `langevin-respa` with a
//! mollifier and constraints.

mod common;

use std::path::Path;

use common::TestRng;
use longstep::integrators::Integrator;
use longstep::integrators::mollified::{Average, JacobianChoice, JacobianMode, Mollifier};
use longstep::io::forcefield::SplitSection;
use longstep::run::prepare::{PreparedRun, RunRequest, prepare};
use longstep::settings::{RunSpec, Value};
use longstep::system::System;
use longstep::system::constraints::Constraints;

const DIPEPTIDE: &str = "systems/molecules/alanine-dipeptide.toml";
const WATER: &str = "systems/water-box/scene.toml";

/// A scene with its constraints and the flags that shape its levels.
struct Case {
    scene: &'static str,
    constraints: &'static str,
    rigid_water: bool,
    hydrogen_mass: bool,
    /// `--split`: the short-range part on level 0, so that waters feel fast forces.
    split: Option<&'static str>,
}

/// The dipeptide in vacuum, bonds to hydrogen rigid, hydrogens at 3 amu: bonded terms
/// fast, non-bonded slow; clusters of one to three constraints (methyls).
const PEPTIDE: Case = Case {
    scene: DIPEPTIDE,
    constraints: "h-bonds",
    rigid_water: false,
    hydrogen_mass: true,
    split: None,
};

/// The water box with SETTLE-rigid waters and the non-bonded term split at 4–5 Å: the
/// short part fast, the remainder slow.
const RIGID_WATER: Case = Case {
    scene: WATER,
    constraints: "none",
    rigid_water: true,
    hydrogen_mass: false,
    split: Some("r_in=4,r_out=5,short_level=0,remainder_level=1"),
};

fn prepared(method: &str, case: &Case, h: &str, inner: usize, tolerance: &str) -> PreparedRun {
    let overrides = RunSpec {
        method: Some(method.into()),
        h: Some(Value::Expression(h.into())),
        inner_steps: Some(inner),
        constraints: Some(case.constraints.into()),
        rigid_water: Some(case.rigid_water),
        hydrogen_mass: case.hydrogen_mass.then(|| Value::Expression("3amu".into())),
        temperature: Some(Value::Expression("300K".into())),
        seed: Some(7),
        constraint_tolerance: Some(Value::Expression(tolerance.into())),
        ..Default::default()
    };
    let mut request = RunRequest::new(Path::new(case.scene), &[], &overrides);
    if let Some(split) = case.split {
        request.flags.electrostatics.split = Some(SplitSection::from_flag(split).unwrap());
    }
    prepare(&request).unwrap()
}

/// `U(A(q))`, with `A` the constrained average from `q`.
fn mollified_slow_energy(
    system: &mut System,
    constraints: &mut Constraints,
    mollifier: &mut Mollifier,
    q: &[f64],
) -> f64 {
    let (forces, inverse_mass) = (&mut system.forces, &system.inverse_mass);
    mollifier
        .compute_constrained_average(forces, inverse_mass, constraints, q, None)
        .unwrap();
    system.forces.energy(1, mollifier.averaged_positions())
}

/// `(v·A_qᵀ∇U(A), (U(A(q + εv)) − U(A(q − εv)))/2ε)` for `v` tangent to the constraints.
fn directional_derivatives(
    system: &mut System,
    mollifier: &mut Mollifier,
    v: &[f64],
    eps: f64,
) -> (f64, f64) {
    let mut constraints = system.constraints.take().unwrap();
    let q = system.state.q.clone();
    let n = q.len();
    mollified_slow_energy(system, &mut constraints, mollifier, &q);
    let mut g = vec![0.0; n];
    system
        .forces
        .gradient(1, mollifier.averaged_positions(), &mut g);
    let mut pulled = vec![0.0; n];
    mollifier.transpose_product(&mut system.forces, &system.inverse_mass, &g, &mut pulled);
    let adjoint: f64 = v.iter().zip(&pulled).map(|(a, b)| a * b).sum();
    let shifted =
        |sign: f64| -> Vec<f64> { q.iter().zip(v).map(|(x, d)| x + sign * eps * d).collect() };
    let up = mollified_slow_energy(system, &mut constraints, mollifier, &shifted(1.0));
    let down = mollified_slow_energy(system, &mut constraints, mollifier, &shifted(-1.0));
    system.constraints = Some(constraints);
    (adjoint, (up - down) / (2.0 * eps))
}

/// A random direction tangent to the constraints at the current positions (the velocity
/// of projected random momenta), scaled to a largest entry of 1.
fn tangent_direction(system: &mut System, rng: &mut TestRng) -> Vec<f64> {
    let mut p: Vec<f64> = (0..system.n_dofs())
        .map(|_| rng.uniform(-1.0, 1.0))
        .collect();
    let constraints = system.constraints.as_mut().unwrap();
    constraints
        .constrain_velocities(&system.state.q, &mut p, &system.inverse_mass)
        .unwrap();
    let v: Vec<f64> = p
        .iter()
        .zip(&system.inverse_mass)
        .map(|(p, w)| p * w)
        .collect();
    let largest = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    v.iter().map(|x| x / largest).collect()
}

#[test]
fn the_constrained_jacobian_matches_finite_differences_along_the_manifold() {
    // The adjoint through RATTLE/SETTLE is the exact derivative of the constrained
    // averaging (src/integrators/mollified/constrained.rs), so along a tangent direction
    // v it must give d/dε U(A(q + εv)). Central differences at ε = 1e-4 Å err by
    // ε²/6 |d³U(A)/dε³|: with curvatures of U∘A on the scale of 1 Å that is ~1e-9 of the
    // derivative; the constraints are solved to 1e-12 (relative), which moves U(A) by
    // ~1e-12 |∇U| Å and the difference by 1e-8 of the derivative; round-off in U (|U| ≲
    // 1e4 kcal/mol, ε_mach |U|/ε ≈ 1e-8) likewise. 1e-6 relative holds that with room
    // (1e-9 to 1.4e-7 seen), and is 1e-3 of what the Jacobian changes: taking A_q = I
    // (the check's other number) misses by more than 1e-3 (2.7e-3 to 1.5 seen).
    let mut rng = TestRng::new(41);
    for (case, h, inner) in [(PEPTIDE, "8fs", 8), (RIGID_WATER, "8fs", 4)] {
        let mut run = prepared("long-average", &case, h, inner, "1e-12");
        let system = &mut run.scene.system;
        let h = run.settings.h;
        for average in [Average::Long, Average::Linear] {
            let mut mollifier = Mollifier::new(average, JacobianChoice::Auto, h, inner);
            let components = system.forces.fast_components(system.n_particles());
            let constraints = system.constraints.as_ref().unwrap();
            mollifier
                .setup_constrained(system.dim, &components, constraints)
                .unwrap();
            assert_eq!(mollifier.mode(), JacobianMode::Adjoint);
            for _ in 0..3 {
                let v = tangent_direction(system, &mut rng);
                let (adjoint, fd) = directional_derivatives(system, &mut mollifier, &v, 1e-4);
                // The same derivative with A_q = I: v·∇U(A).
                let mut g = vec![0.0; v.len()];
                system
                    .forces
                    .gradient(1, mollifier.averaged_positions(), &mut g);
                let plain: f64 = v.iter().zip(&g).map(|(a, b)| a * b).sum();
                let error = (adjoint - fd).abs() / fd.abs();
                let without = (plain - fd).abs() / fd.abs();
                println!(
                    "{} {average:?}: adjoint {adjoint:.9e}, differences {fd:.9e}: relative \
                     error {error:.1e} (A_q = I: {without:.1e})",
                    case.scene
                );
                assert!(error <= 1e-6, "{error:e}");
                assert!(without >= 1e-3, "{without:e}");
            }
        }
    }
}

#[test]
fn with_no_constraint_the_constrained_averaging_is_the_unconstrained_one_bit_for_bit() {
    // The constrained averaging with an empty constraint set runs every projection,
    // position constraint, multiplier recovery and transposed step, each of which then
    // changes nothing, and the same arithmetic in the same order as the unconstrained
    // averaging: the same bits for A and A_qᵀ∇U(A), for every average.
    let mut scene = common::scene_file(WATER, &[]);
    let system = &mut scene.system;
    let n = system.n_dofs();
    let components = system.forces.fast_components(system.n_particles());
    let mut empty =
        Constraints::new(3, system.n_particles(), vec![], vec![], system.periodic_box).unwrap();
    for average in [Average::Short, Average::Long, Average::Linear] {
        let choice = JacobianChoice::Fixed(JacobianMode::Adjoint);
        let mut plain = Mollifier::new(average, choice, 4.0, 4);
        plain.setup(3, &components);
        let mut constrained = Mollifier::new(average, JacobianChoice::Auto, 4.0, 4);
        constrained
            .setup_constrained(3, &components, &empty)
            .unwrap();
        let (forces, w, q) = (&mut system.forces, &system.inverse_mass, &system.state.q);
        plain.compute_average(forces, w, q, None);
        constrained
            .compute_constrained_average(forces, w, &mut empty, q, None)
            .unwrap();
        assert_eq!(plain.averaged_positions(), constrained.averaged_positions());
        let mut g = vec![0.0; n];
        forces.gradient(1, plain.averaged_positions(), &mut g);
        let (mut a, mut b) = (vec![0.0; n], vec![0.0; n]);
        plain.transpose_product(forces, w, &g, &mut a);
        constrained.transpose_product(forces, w, &g, &mut b);
        assert_eq!(a, b, "{average:?}");
        // And the averaging did something: A ≠ q, A_qᵀ g ≠ g.
        assert_ne!(plain.averaged_positions(), &q[..]);
        assert_ne!(a, g);
    }
}

/// The largest |E(t) − E(0)| of `mollified_total` over `t_end` at `h` (fs), `inner`
/// inner steps, and the largest constraint violation seen.
fn mollified_energy_error(method: &str, h: f64, inner: usize, t_end: f64) -> (f64, f64) {
    let mut run = prepared(method, &PEPTIDE, &format!("{h}fs"), inner, "1e-10");
    let (integrator, system) = (&mut run.integrator, &mut run.scene.system);
    integrator.setup(system).unwrap();
    let total = |integrator: &dyn Integrator, system: &System| {
        let mut out = Vec::new();
        integrator.extra_values(system, &mut out);
        out[0]
    };
    assert_eq!(integrator.extra_columns(), vec!["mollified_total"]);
    let start = total(integrator.as_ref(), system);
    let (mut worst, mut violation) = (0.0f64, 0.0f64);
    for _ in 0..(t_end / h).round() as usize {
        integrator.step(system).unwrap();
        worst = worst.max((total(integrator.as_ref(), system) - start).abs());
        let constraints = system.constraints.as_ref().unwrap();
        violation = violation.max(constraints.max_violation(&system.state.q));
    }
    (worst, violation)
}

#[test]
fn every_mollified_method_with_constraints_conserves_its_energy_to_second_order() {
    // With constraints each mollified method is RATTLE r-RESPA for W(q) + U(A(q)) on the
    // constraint manifold (the exact Jacobian, projected like every kick): a symplectic
    // second-order scheme, whose energy error max |ΔE| over a fixed time is C h² with no
    // drift while stable. Halving h and dt together (inner steps fixed) must divide it by
    // 4; the O(h⁴) rest and the SHAKE tolerance (1e-10, ~1e-9 kcal/mol) move the ratio by
    // far less than the ±25 % allowed. A force that is not the gradient of U(A(q)) on the
    // manifold adds a drift that does not scale so (the equilibrium mollifier's projection
    // Jacobian: tests/equilibrium_molly.rs). Dipeptide in vacuum, bonds to hydrogen rigid,
    // hydrogens at 3 amu, 300 K, 0.5 ps at h = 2 and 1 fs with 4 inner steps.
    for method in [
        "short-average",
        "long-average",
        "linear-average",
        "equilibrium-molly",
    ] {
        let (coarse, violation_coarse) = mollified_energy_error(method, 2.0, 4, 500.0);
        let (fine, violation_fine) = mollified_energy_error(method, 1.0, 4, 500.0);
        let ratio = coarse / fine;
        println!(
            "{method}: max |ΔE| {coarse:.3e} (h = 2 fs), {fine:.3e} (1 fs) kcal/mol, ratio \
             {ratio:.2}; largest constraint violation {:.1e}",
            violation_coarse.max(violation_fine)
        );
        assert!((3.0..5.0).contains(&ratio), "{method}: ratio {ratio}");
        // SHAKE's tolerance, with the round-off of |r² − d²| ≤ 2 tol d² read as |r − d|/d.
        assert!(violation_coarse.max(violation_fine) <= 1.01e-10);
    }
}

#[test]
fn langevin_respa_runs_a_mollifier_with_constraints() {
    // BAOAB-RESPA with the mollified slow impulse (the constrained averaging, then the
    // projection every kick gets): 0.2 ps of the dipeptide at h = 4 fs finishes (exit 0),
    // its header naming the mollifier's parameters.
    for (mollifier, parameters) in [
        ("long-average", "jacobian = adjoint, 4 auxiliary steps"),
        ("equilibrium-molly", "molly_constraints = bonds"),
    ] {
        let out = common::scratch_dir(&format!("mollified-constraints-langevin-{mollifier}"));
        let args = common::argv(
            "run {} --method langevin-respa --mollifier {} --h 4fs --inner 4 \
             --constraints h-bonds --hydrogen-mass 3amu --temperature 300K --seed 3 \
             --t-end 0.2ps --json --out {}",
            &[DIPEPTIDE, mollifier, out.to_str().unwrap()],
        );
        let (code, stdout, stderr) = common::run_cli(&args);
        assert_eq!(code, 0, "{mollifier}: {stderr}");
        let summary: serde_json::Value = serde_json::from_str(&stdout).unwrap();
        let described = summary["parameters"].as_str().unwrap();
        assert!(described.contains(parameters), "{mollifier}: {described}");
        assert!(
            described.contains("constrained"),
            "{mollifier}: {described}"
        );
    }
}

#[test]
fn forward_mode_with_constraints_is_refused_naming_jacobian() {
    // The constrained averaging is differentiated in reverse mode only: `--jacobian
    // forward` with constraints stops at setup with the key, what is expected and the
    // value, printed once.
    let overrides = RunSpec {
        method: Some("long-average".into()),
        h: Some(Value::Expression("2fs".into())),
        inner_steps: Some(2),
        jacobian: Some("forward".into()),
        constraints: Some("h-bonds".into()),
        ..Default::default()
    };
    let mut run = prepare(&RunRequest::new(Path::new(DIPEPTIDE), &[], &overrides)).unwrap();
    let Err(error) = run.integrator.setup(&mut run.scene.system) else {
        panic!("forward mode was set up with constraints");
    };
    let problem = error.problem().expect("the error's fields");
    assert_eq!(problem.location.key.as_deref(), Some("jacobian"));
    assert_eq!(problem.got.as_deref(), Some("forward"));
    assert!(
        problem.expected.as_deref().unwrap().contains("adjoint"),
        "{problem:?}"
    );
    assert_eq!(error.to_string().matches("forward").count(), 1, "{error}");
}
