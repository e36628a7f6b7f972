//! Constraints (SETTLE for rigid water, SHAKE/RATTLE for bonds) and hydrogen mass
//! repartitioning, through the public API of `system::constraints` and
//! `System::repartition_hydrogen_mass`: every water of the shipped box held to round-off
//! with momentum conserved, every bond within the tolerance with velocities tangent, a
//! constrained chain at its analytic frequency, a reversible constrained velocity-Verlet
//! step, the constrained degrees of freedom and start, and HMR's mass bookkeeping.

mod common;
use common::run_cli_threads as longstep_run;
use common::{TestRng, argv, scene_file, words};

use longstep::io::scene::Scene;
use longstep::system::constraints::{ConstraintSet, Constraints, DistanceConstraint, RigidWater};
use longstep::system::velocities::{DegreesOfFreedom, maxwell_boltzmann_constrained};
use longstep::units::BOLTZMANN_KCAL_PER_K;

/// Machine epsilon.
const EPS: f64 = f64::EPSILON;

fn constraints_of(scene: &Scene, set: ConstraintSet, rigid_water: bool) -> Constraints {
    let topology = scene.bonded_topology().unwrap();
    Constraints::from_topology(&topology, set, rigid_water, scene.system.periodic_box).unwrap()
}

/// The water box with every water projected onto its rigid geometry and the momenta
/// projected onto the constraints.
fn rigid_water_box() -> (Scene, Constraints) {
    let mut scene = scene_file("systems/water-box/scene.toml", &[]);
    let mut constraints = constraints_of(&scene, ConstraintSet::None, true);
    let system = &mut scene.system;
    constraints
        .project_positions(&mut system.state.q, &system.inverse_mass)
        .unwrap();
    constraints
        .constrain_velocities(&system.state.q, &mut system.state.p, &system.inverse_mass)
        .unwrap();
    (scene, constraints)
}

/// `(Σ p, Σ q × p)` over particles `atoms` (3-D), with the positions of `q`.
fn momenta(q: &[f64], p: &[f64], atoms: impl Iterator<Item = usize>) -> ([f64; 3], [f64; 3]) {
    let (mut linear, mut angular) = ([0.0; 3], [0.0; 3]);
    for i in atoms {
        let (x, v) = (&q[3 * i..3 * i + 3], &p[3 * i..3 * i + 3]);
        for a in 0..3 {
            linear[a] += v[a];
        }
        angular[0] += x[1] * v[2] - x[2] * v[1];
        angular[1] += x[2] * v[0] - x[0] * v[2];
        angular[2] += x[0] * v[1] - x[1] * v[0];
    }
    (linear, angular)
}

#[test]
fn settle_holds_every_water_of_the_box_to_round_off_and_conserves_momentum() {
    let (scene, mut constraints) = rigid_water_box();
    let system = &scene.system;
    assert_eq!(constraints.waters().len(), 216);
    assert_eq!(constraints.count(), 648);
    // The projected start is rigid to round-off (SETTLE's last pass, bound as below).
    let start = constraints.max_violation(&system.state.q);
    println!("SETTLE: projected start's largest relative violation {start:e}");
    assert!(start < 1e-13, "start {start:e}");
    // A large step: a 2 fs drift plus a random displacement of up to ±0.1 Å per coordinate
    // (10 % of a bond: far beyond any step MD takes).
    let dt = 2.0;
    let q_old = system.state.q.clone();
    let mut rng = TestRng::new(28);
    let mut q_new: Vec<f64> = q_old
        .iter()
        .zip(&system.state.p)
        .zip(&system.inverse_mass)
        .map(|((q, p), w)| q + dt * w * p + rng.uniform(-0.1, 0.1))
        .collect();
    let mut p = system.state.p.clone();
    let p_before = p.clone();
    constraints
        .constrain_positions(&q_old, &mut q_new, &mut p, &system.inverse_mass, dt)
        .unwrap();
    // SETTLE is analytic: each length is rebuilt from ~100 roundings of O(1 Å) numbers,
    // each ≤ ε relative, so |r − d|/d ≲ 100 ε ≈ 2e-14. We allow 1e-13; a SHAKE-like
    // iteration stopped at the 1e-8 tolerance would show 1e-9 and fail.
    let violation = constraints.max_violation(&q_new);
    println!("SETTLE: largest relative violation after the displaced step {violation:e}");
    assert!(violation < 1e-13, "{violation:e}");
    // The momentum change is a set of internal forces along the old bonds: per water it
    // has no net momentum and no torque about the old positions, to round-off of the
    // impulses' size (16 ε per sum of six terms, we allow 100 ε).
    let delta: Vec<f64> = p.iter().zip(&p_before).map(|(a, b)| a - b).collect();
    let mut worst_linear: f64 = 0.0;
    let mut worst_angular: f64 = 0.0;
    for w in constraints.waters() {
        let atoms = [w.oxygen, w.hydrogens[0], w.hydrogens[1]];
        // Old positions relative to the oxygen (unwrapped: the waters are whole in the file).
        let origin = &q_old[3 * w.oxygen..3 * w.oxygen + 3];
        let local: Vec<f64> = (0..q_old.len()).map(|k| q_old[k] - origin[k % 3]).collect();
        let scale: f64 = atoms
            .iter()
            .flat_map(|&i| delta[3 * i..3 * i + 3].iter())
            .map(|x| x.abs())
            .sum();
        let (linear, angular) = momenta(&local, &delta, atoms.into_iter());
        for a in 0..3 {
            worst_linear = worst_linear.max(linear[a].abs() / scale);
            worst_angular = worst_angular.max(angular[a].abs() / scale);
        }
    }
    println!("SETTLE: largest net momentum {worst_linear:e}, torque {worst_angular:e} (relative)");
    assert!(worst_linear < 100.0 * EPS, "{worst_linear:e}");
    // Torque has lengths ~1 Å in it.
    assert!(worst_angular < 100.0 * EPS, "{worst_angular:e}");
    // The velocity step: exactly tangent, and again internal impulses.
    let p_drift = p.clone();
    constraints
        .constrain_velocities(&q_new, &mut p, &system.inverse_mass)
        .unwrap();
    let residual = constraints.max_velocity_violation(&q_new, &p, &system.inverse_mass);
    let v_rms = rms_velocity(&p, &system.inverse_mass);
    println!("SETTLE velocities: largest |r̂·v| {residual:e} for v_rms {v_rms:e}");
    // Solved exactly (a 3×3 system): round-off of the velocities, ≤ 100 ε v_rms.
    assert!(residual < 100.0 * EPS * v_rms, "{residual:e}");
    let total = |p: &[f64]| momenta(&q_new, p, 0..system.n_particles());
    let (before, after) = (total(&p_drift), total(&p));
    let scale: f64 = p.iter().map(|x| x.abs()).sum();
    for a in 0..3 {
        assert!((after.0[a] - before.0[a]).abs() < 100.0 * EPS * scale);
    }
}

fn rms_velocity(p: &[f64], inverse_mass: &[f64]) -> f64 {
    let sum: f64 = p
        .iter()
        .zip(inverse_mass)
        .map(|(x, w)| (w * x).powi(2))
        .sum();
    (sum / p.len() as f64).sqrt()
}

/// Velocity-Verlet steps with constraints (RATTLE, And83) of step `h`: the inverse masses,
/// the constraints, the force (writes the gradient at `q`) and the gradient at the current
/// positions.
struct Rattle<'a, F: FnMut(&[f64], &mut [f64])> {
    inverse_mass: &'a [f64],
    constraints: &'a mut Constraints,
    force: F,
    gradient: Vec<f64>,
    h: f64,
}

impl<'a, F: FnMut(&[f64], &mut [f64])> Rattle<'a, F> {
    /// Starts at `q` (its gradient evaluated once).
    fn new(
        q: &[f64],
        inverse_mass: &'a [f64],
        constraints: &'a mut Constraints,
        force: F,
        h: f64,
    ) -> Self {
        let mut rattle = Rattle {
            inverse_mass,
            constraints,
            force,
            gradient: vec![0.0; q.len()],
            h,
        };
        (rattle.force)(q, &mut rattle.gradient);
        rattle
    }

    /// One step: half kick and velocity projection, drift and position constraint, new
    /// force, half kick and projection.
    fn step(&mut self, q: &mut [f64], p: &mut [f64]) {
        let (h, w) = (self.h, self.inverse_mass);
        for (pk, g) in p.iter_mut().zip(self.gradient.iter()) {
            *pk -= 0.5 * h * g;
        }
        self.constraints.constrain_velocities(q, p, w).unwrap();
        let q_old = q.to_vec();
        for ((qk, pk), w) in q.iter_mut().zip(p.iter()).zip(w) {
            *qk += h * w * pk;
        }
        self.constraints
            .constrain_positions(&q_old, q, p, w, h)
            .unwrap();
        (self.force)(q, &mut self.gradient);
        for (pk, g) in p.iter_mut().zip(self.gradient.iter()) {
            *pk -= 0.5 * h * g;
        }
        self.constraints.constrain_velocities(q, p, w).unwrap();
    }
}

#[test]
fn rattle_keeps_every_bond_within_tolerance_and_velocities_tangent() {
    // The alanine dipeptide with all bonds constrained: chains of coupled constraints
    // around every heavy atom, solved iteratively. Rest lengths come from the geometry, so
    // the start satisfies them.
    let mut scene = scene_file("systems/molecules/alanine-dipeptide.toml", &[]);
    let mut constraints = constraints_of(&scene, ConstraintSet::AllBonds, false);
    let tolerance = constraints.tolerance();
    let kt = 300.0 * BOLTZMANN_KCAL_PER_K;
    maxwell_boltzmann_constrained(&mut scene.system, &mut constraints, kt, 5).unwrap();
    let system = &mut scene.system;
    let w = system.inverse_mass.clone();
    let (mut q, mut p) = (system.state.q.clone(), system.state.p.clone());
    let forces = &mut system.forces;
    let force = |q: &[f64], g: &mut [f64]| forces.total_gradient(q, g);
    let mut rattle = Rattle::new(&q, &w, &mut constraints, force, 2.0);
    let (mut worst, mut worst_velocity): (f64, f64) = (0.0, 0.0);
    // 200 steps of 2 fs: 0.4 ps, many periods of the heavy-atom bends.
    for _ in 0..200 {
        rattle.step(&mut q, &mut p);
        let constraints = &rattle.constraints;
        worst = worst.max(constraints.max_violation(&q));
        let v_rms = rms_velocity(&p, &w);
        worst_velocity = worst_velocity.max(constraints.max_velocity_violation(&q, &p, &w) / v_rms);
    }
    println!(
        "RATTLE ({} bonds): largest |r − d|/d {worst:e}, largest |r̂·v|/v_rms {worst_velocity:e}",
        constraints.count()
    );
    // SHAKE stops when |r² − d²| ≤ 2 tol d², i.e. |r − d|/d ≤ tol (1 + tol/2 + …).
    assert!(worst <= tolerance * (1.0 + tolerance), "{worst:e}");
    // RATTLE stops when |r̂·v| ≤ tol v_rms at the start of its call; rescaling v_rms
    // within the call is bounded by the kinetic energy the projection removes, ≪ 2×.
    assert!(worst_velocity <= 2.0 * tolerance, "{worst_velocity:e}");
    assert!(p.iter().all(|x| x.is_finite()));
}

/// Three rigid dumbbells in a line along x, joined by two harmonic springs: along the
/// line each dumbbell moves as one mass `M`, so the chain's frequencies are those of
/// three masses and two springs, `ω² = k/M` and `3k/M`.
/// Springs `(i, j, rest length)`.
type Springs = [(usize, usize, f64); 2];

fn dumbbell_chain() -> (Vec<f64>, Vec<f64>, Constraints, Springs) {
    let masses = [1.0, 2.0, 1.0, 2.0, 1.0, 2.0];
    let x = [0.0, 1.0, 2.5, 3.5, 5.0, 6.0];
    let q: Vec<f64> = x.iter().flat_map(|&x| [x, 0.0, 0.0]).collect();
    let inverse_mass: Vec<f64> = masses.iter().flat_map(|&m| [1.0 / m; 3]).collect();
    let rigid = |i, j| DistanceConstraint { i, j, length: 1.0 };
    let constraints = Constraints::new(
        3,
        6,
        vec![rigid(0, 1), rigid(2, 3), rigid(4, 5)],
        Vec::new(),
        None,
    )
    .unwrap();
    // Springs 1–2 and 3–4, rest length 1.5, stiffness 4.
    (q, inverse_mass, constraints, [(1, 2, 1.5), (3, 4, 1.5)])
}

fn spring_gradient(springs: &[(usize, usize, f64)], k: f64, q: &[f64], g: &mut [f64]) {
    g.fill(0.0);
    for &(i, j, rest) in springs {
        let d: Vec<f64> = (0..3).map(|a| q[3 * j + a] - q[3 * i + a]).collect();
        let r = d.iter().map(|x| x * x).sum::<f64>().sqrt();
        for a in 0..3 {
            let f = k * (r - rest) * d[a] / r;
            g[3 * j + a] += f;
            g[3 * i + a] -= f;
        }
    }
}

#[test]
fn a_constrained_chain_oscillates_at_its_analytic_frequency() {
    let (mut q, w, mut constraints, springs) = dumbbell_chain();
    let (k, m_body) = (4.0, 3.0);
    // The symmetric mode of three equal masses (outer bodies out of phase, middle at rest)
    // has ω² = k/M; the antisymmetric-centre one (1, −2, 1) has ω² = 3k/M.
    for (mode, omega2) in [
        ([1.0, 0.0, -1.0], k / m_body),
        ([1.0, -2.0, 1.0], 3.0 * k / m_body),
    ] {
        let omega: f64 = f64::sqrt(omega2);
        let h = 0.01;
        let (q0, amplitude) = (q.clone(), 0.01);
        for (body, shift) in mode.iter().enumerate() {
            for atom in [2 * body, 2 * body + 1] {
                q[3 * atom] = q0[3 * atom] + amplitude * shift;
            }
        }
        let mut p = vec![0.0; q.len()];
        let force = |q: &[f64], g: &mut [f64]| spring_gradient(&springs, k, q, g);
        let mut rattle = Rattle::new(&q, &w, &mut constraints, force, h);
        // Count upward zero crossings of the first body's displacement over many periods.
        let displacement = |q: &[f64]| q[0] - q0[0];
        let steps = 200_000;
        let (mut crossings, mut first, mut last) = (0, 0.0, 0.0);
        let mut previous = displacement(&q);
        for n in 1..=steps {
            rattle.step(&mut q, &mut p);
            let now = displacement(&q);
            if previous < 0.0 && now >= 0.0 {
                // Linear interpolation of the crossing time.
                let t = h * (n as f64 - now / (now - previous));
                if crossings == 0 {
                    first = t;
                }
                last = t;
                crossings += 1;
            }
            previous = now;
        }
        let measured = 2.0 * std::f64::consts::PI * (crossings - 1) as f64 / (last - first);
        // Velocity Verlet's own frequency for ω: (2/h) asin(ωh/2); the spring's
        // nonlinearity is second order in the amplitude (0.01: a 1e-4 relative shift at
        // most, and zero along the line where the springs stay straight). The crossing
        // times come from linear interpolation with error O((ωh)²) per crossing, not
        // accumulating: over ~N periods the frequency is good to ~(ωh)²/N ≪ 1e-6.
        let expected = 2.0 / h * (omega * h / 2.0).asin();
        let error = (measured - expected).abs() / expected;
        println!(
            "chain mode ω² = {omega2}: measured {measured}, Verlet's {expected}, error {error:e}"
        );
        assert!(error < 1e-6, "{measured} vs {expected}");
        // The dumbbells stayed rigid.
        assert!(constraints.max_violation(&q) <= 1.01 * constraints.tolerance());
        q = q0;
    }
}

#[test]
fn the_constrained_verlet_step_is_time_reversible() {
    // The rigid water box: SETTLE is analytic, so reversing the momenta retraces the steps
    // to round-off amplified by the dynamics' divergence over the 2×20 steps.
    let (mut scene, mut constraints) = rigid_water_box();
    let system = &mut scene.system;
    let w = system.inverse_mass.clone();
    let (q0, p0) = (system.state.q.clone(), system.state.p.clone());
    let (mut q, mut p) = (q0.clone(), p0.clone());
    let forces = &mut system.forces;
    let force = |q: &[f64], g: &mut [f64]| forces.total_gradient(q, g);
    let mut rattle = Rattle::new(&q, &w, &mut constraints, force, 2.0);
    let steps = 20;
    for _ in 0..steps {
        rattle.step(&mut q, &mut p);
    }
    let moved = common::max_abs_difference(&q, &q0);
    p.iter_mut().for_each(|x| *x = -*x);
    for _ in 0..steps {
        rattle.step(&mut q, &mut p);
    }
    p.iter_mut().for_each(|x| *x = -*x);
    let q_error = common::max_abs_difference(&q, &q0);
    let p_error = common::max_abs_difference(&p, &p0) / common::max_abs(&p0);
    println!(
        "reversibility: atoms moved up to {moved:.3} Å, returned to {q_error:e} Å, momenta to \
         {p_error:e} (relative)"
    );
    // Round-off of positions ~10 Å is 2e-15 Å per operation; 40 steps of a liquid whose
    // errors grow by a factor of a few per 10 fs leave ≲ 1e-12 Å. A scheme that is not
    // symmetric (SETTLE without the momentum correction, or projecting velocities with
    // the old bonds) returns only to O(h³) ≈ 1e-3 Å.
    assert!(moved > 0.05);
    assert!(q_error < 1e-10, "{q_error:e}");
    assert!(p_error < 1e-8, "{p_error:e}");
}

#[test]
fn degrees_of_freedom_count_the_constraints_and_the_start_is_on_the_manifold() {
    let (mut scene, mut constraints) = rigid_water_box();
    let kt = 300.0 * BOLTZMANN_KCAL_PER_K;
    let start = maxwell_boltzmann_constrained(&mut scene.system, &mut constraints, kt, 11).unwrap();
    let dofs = start.degrees_of_freedom;
    // 3·648 − 648 constraints − 3 (centre of mass).
    assert_eq!(dofs.count, 3 * 648 - 648 - 3);
    assert_eq!(
        dofs,
        DegreesOfFreedom::constrained(&scene.system, constraints.count())
    );
    assert!(dofs.describe(3, 648).contains("648 constraints"));
    let system = &scene.system;
    let temperature = dofs.temperature(system.kinetic_energy(), BOLTZMANN_KCAL_PER_K);
    assert!((temperature - 300.0).abs() < 1e-10, "{temperature}");
    let v_rms = rms_velocity(&system.state.p, &system.inverse_mass);
    let residual =
        constraints.max_velocity_violation(&system.state.q, &system.state.p, &system.inverse_mass);
    assert!(residual < 100.0 * EPS * v_rms, "{residual:e}");
    let (linear, _) = momenta(&system.state.q, &system.state.p, 0..648);
    let scale: f64 = system.state.p.iter().map(|x| x.abs()).sum();
    assert!(linear.iter().all(|x| x.abs() < 100.0 * EPS * scale));
}

#[test]
fn hydrogen_mass_repartitioning_keeps_the_total_and_refuses_bad_input() {
    let mut scene = scene_file("systems/molecules/butane.toml", &[]);
    let topology = scene.bonded_topology().unwrap();
    let units = scene.units;
    let system = &mut scene.system;
    let before: f64 = system.particles.masses.iter().sum();
    let velocities: Vec<f64> = system
        .state
        .p
        .iter()
        .zip(&system.inverse_mass)
        .map(|(p, w)| p * w)
        .collect();
    let report = system
        .repartition_hydrogen_mass(&topology, 3.0, units)
        .unwrap();
    let after: f64 = system.particles.masses.iter().sum();
    println!("{:?}", report.lines);
    // Ten sums of ~14 masses: round-off ≲ 14 ε relative.
    assert!(
        (after - before).abs() <= 20.0 * EPS * before,
        "{before} → {after}"
    );
    assert_eq!((report.hydrogens, report.heavy_atoms), (10, 4));
    for (i, element) in topology.elements.iter().enumerate() {
        let m = units.mass_in_scene_units(system.particles.masses[i]);
        if element == "H" {
            assert!((m - 3.0).abs() < 1e-12, "H {i}: {m}");
        } else {
            // CH3: 12.011 − 3 × (3 − 1.008); CH2: 12.011 − 2 × (3 − 1.008).
            assert!(m < 12.011 - 3.9 && m > 12.011 - 6.0, "C {i}: {m}");
        }
        assert_eq!(system.inverse_mass[3 * i], 1.0 / system.particles.masses[i]);
    }
    let kept: Vec<f64> = system
        .state
        .p
        .iter()
        .zip(&system.inverse_mass)
        .map(|(p, w)| p * w)
        .collect();
    assert!(
        common::max_abs_difference(&kept, &velocities) <= 4.0 * EPS * common::max_abs(&velocities)
    );

    // A methyl carbon cannot give 3 × (4.5 − 1.008) = 10.5 amu and stay heavier than its H.
    let mut scene = scene_file("systems/molecules/butane.toml", &[]);
    let too_heavy = scene
        .system
        .repartition_hydrogen_mass(&topology, 4.5, units)
        .unwrap_err();
    assert!(
        too_heavy.to_string().contains("not more than"),
        "{too_heavy}"
    );
    for bad in [0.0, -1.0, f64::NAN] {
        let e = scene
            .system
            .repartition_hydrogen_mass(&topology, bad, units)
            .unwrap_err();
        assert!(e.to_string().contains("positive"), "{e}");
    }
    // Water is left alone: the water box has no hydrogen to repartition.
    let mut water = scene_file("systems/water-box/scene.toml", &[]);
    let water_topology = water.bonded_topology().unwrap();
    let masses = water.system.particles.masses.clone();
    let e = water
        .system
        .repartition_hydrogen_mass(&water_topology, 3.0, water.units)
        .unwrap_err();
    assert!(e.to_string().contains("no hydrogen"), "{e}");
    assert_eq!(water.system.particles.masses, masses);
}

#[test]
fn bad_constraint_input_is_refused() {
    let scene = scene_file("systems/water-box/scene.toml", &[]);
    let set = constraints_of(&scene, ConstraintSet::HBonds, false);
    assert_eq!(set.count(), 432);
    assert!(set.clone().with_tolerance(0.0).is_err());
    assert!(set.clone().with_tolerance(-1e-8).is_err());
    assert!(set.with_max_iterations(0).is_err());
    assert!(
        ConstraintSet::parse("hbonds")
            .unwrap_err()
            .contains("h-bonds")
    );
    // A particle in a water and in a bond.
    let water = RigidWater {
        oxygen: 0,
        hydrogens: [1, 2],
        oh: 1.0,
        hh: 1.6,
    };
    let bond = DistanceConstraint {
        i: 2,
        j: 3,
        length: 1.0,
    };
    let e = Constraints::new(3, 4, vec![bond], vec![water], None).unwrap_err();
    assert!(e.to_string().contains("rigid water and in another"), "{e}");
    // A scene without a force field has no bonds to constrain.
    let plain = scene_file("systems/two-masses.toml", &[]);
    let e = plain.bonded_topology().unwrap_err();
    assert!(e.to_string().contains("molecular scene"), "{e}");
}

#[test]
fn a_constrained_verlet_run_keeps_every_water_rigid_at_every_step() {
    use longstep::run::prepare::{RunRequest, prepare};
    use longstep::settings::{RunSpec, Value};
    let overrides = RunSpec {
        method: Some("verlet".into()),
        h: Some(Value::Expression("2fs".into())),
        rigid_water: Some(true),
        ..Default::default()
    };
    let path = std::path::Path::new("systems/water-box/scene.toml");
    let mut run = prepare(&RunRequest::new(path, &[], &overrides)).unwrap();
    assert_eq!(run.degrees_of_freedom.unwrap().count, 3 * 648 - 648 - 3);
    let system = &mut run.scene.system;
    run.integrator.setup(system).unwrap();
    let (mut worst, mut worst_velocity): (f64, f64) = (0.0, 0.0);
    for _ in 0..200 {
        run.integrator.step(system).unwrap();
        let constraints = system.constraints.as_ref().unwrap();
        let (q, p, w) = (&system.state.q, &system.state.p, &system.inverse_mass);
        worst = worst.max(constraints.max_violation(q));
        let v_rms = rms_velocity(p, w);
        worst_velocity = worst_velocity.max(constraints.max_velocity_violation(q, p, w) / v_rms);
    }
    println!(
        "verlet + SETTLE, 200 steps of 2 fs: largest |r − d|/d {worst:e}, |r̂·v|/v_rms \
         {worst_velocity:e}"
    );
    // Each step rebuilds every water exactly (SETTLE) and solves its velocities exactly:
    // round-off as in the single step above (≲ 100 ε), not accumulating.
    assert!(worst < 1e-13, "{worst:e}");
    assert!(worst_velocity < 100.0 * EPS, "{worst_velocity:e}");
}

#[test]
fn a_rigid_water_box_at_two_femtoseconds_conserves_energy() {
    // 4 ps of the 216 rigid waters at h = 2 fs: the run's own drift estimate (a linear fit
    // of the total energy, in kT/ns per degree of freedom over the 1293 left) must stay
    // within its bound of 0.05 kT/ns/dof. The flexible box at 2 fs exceeds it (+0.276
    // kT/ns/dof over the same 4 ps, its energy fluctuating 4.6 kcal/mol rms against 0.11:
    // the O–H stretch, period ≈ 9 fs, is barely resolved).
    let out = common::scratch_dir("constraints-nve");
    let args = argv(
        "run systems/water-box/scene.toml --method verlet --h 2fs --rigid-water \
         --t-end 4ps --json --out {}",
        &[out.to_str().unwrap()],
    );
    let (code, stdout, stderr) = longstep_run(&args, None);
    assert_eq!(code, 0, "{stderr}");
    let summary: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let drift = &summary["drift"];
    println!("rigid water, 2 fs, 4 ps: drift {drift}");
    assert_eq!(summary["temperature"]["degrees_of_freedom"], 1293);
    assert_eq!(drift["exceeded"], false, "{drift}");
    assert!(drift["value"].as_f64().unwrap().abs() <= 0.05, "{drift}");
}

#[test]
fn constrained_runs_are_the_same_bits_on_one_and_two_threads() {
    let energy = |threads: usize, method: &str| {
        let out = common::scratch_dir(&format!("constraints-threads-{method}-{threads}"));
        let args = argv(
            "run systems/water-box/scene.toml --method {} --h 4fs --inner 2 --rigid-water \
             --temperature 300K --t-end 0.2ps --out {}",
            &[method, out.to_str().unwrap()],
        );
        let (code, _, stderr) = longstep_run(&args, Some(threads));
        assert_eq!(code, 0, "{stderr}");
        std::fs::read(out.join("energy.csv")).unwrap()
    };
    for method in ["impulse", "langevin-respa"] {
        assert_eq!(energy(1, method), energy(2, method), "{method}");
    }
}

/// The 1 728-water box has more waters than `forces::scratch::PARALLEL_MIN_INTERACTIONS`
/// (1 024), so on two and three threads its SETTLE passes (positions and momenta) compute
/// the waters' changes in parallel blocks and add them in water order: the energies of
/// every step are the bits of one thread.
#[test]
fn parallel_settle_gives_the_same_bits_on_one_two_and_three_threads() {
    let energy = |threads: usize, method: &str| {
        let out = common::scratch_dir(&format!("constraints-settle-threads-{method}-{threads}"));
        let args = argv(
            "run systems/water-box-1728/scene.toml --method {} --h 4fs --inner 2 \
             --rigid-water --temperature 300K --seed 3 --t-end 40fs --energy-every 1 --out {}",
            &[method, out.to_str().unwrap()],
        );
        let (code, _, stderr) = longstep_run(&args, Some(threads));
        assert_eq!(code, 0, "{stderr}");
        std::fs::read(out.join("energy.csv")).unwrap()
    };
    for method in ["impulse", "langevin-respa"] {
        let one = energy(1, method);
        assert_eq!(
            String::from_utf8_lossy(&one).lines().count(),
            12,
            "{method}"
        );
        assert_eq!(one, energy(2, method), "{method}: 2 threads");
        assert_eq!(one, energy(3, method), "{method}: 3 threads");
    }
}

#[test]
fn methods_and_scenes_that_cannot_take_constraints_refuse_them() {
    let water = "systems/water-box/scene.toml";
    let cases: [(&[&str], &str); 5] = [
        (
            &argv(
                "run {} --method sinr --rigid-water --temperature 300K",
                &[water],
            ),
            "sinr does not run with constraints (rigid_water): its isokinetic constraint",
        ),
        (
            &["run", water, "--rigid-water", "--constraint-tolerance", "0"],
            "constraint_tolerance must lie between 0 and 1",
        ),
        (
            &["run", water, "--hydrogen-mass", "3amu"],
            "no hydrogen bonded to a heavy atom outside water",
        ),
        (
            &["run", water, "--constraints", "hbonds"],
            "constraints must be one of none, h-bonds, all-bonds",
        ),
        (
            &words("run systems/two-masses.toml --constraints h-bonds --t-end 1"),
            "need a molecular scene",
        ),
    ];
    for (args, message) in cases {
        let (code, _, stderr) = longstep_run(args, None);
        assert_eq!(code, 1, "{args:?}: {stderr}");
        assert!(stderr.contains(message), "{args:?}: {stderr}");
    }
}

#[test]
fn every_method_but_the_constrained_ones_refuses_constraints_with_exit_1() {
    // Issue 28 Done-when 4, with issue 41's mollified methods: each method outside verlet,
    // impulse, the mollified four and langevin-respa, asked for rigid water or for
    // constrained bonds, stops before it runs (exit 1) with a message naming the method
    // and what was asked; none of them runs unconstrained.
    use longstep::integrators::METHODS;
    use longstep::integrators::constrained::CONSTRAINED_METHODS;
    let out = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("constraints-refused");
    let refusing: Vec<&str> = METHODS
        .iter()
        .map(|m| m.name)
        .filter(|name| !CONSTRAINED_METHODS.contains(name))
        .collect();
    assert_eq!(
        refusing,
        [
            "impulse-midpoint",
            "sinr",
            "adaptive-verlet",
            "structural-zd",
            "structural-zds",
            "pseudo-energy",
            "async-pseudo-energy"
        ]
    );
    for method in refusing {
        for (flags, asked) in [
            (&["--rigid-water"][..], "rigid_water"),
            (&["--constraints", "h-bonds"][..], "constraints = h-bonds"),
        ] {
            let mut args = argv(
                "run systems/water-box/scene.toml --method {} --temperature 300K --t-end 4fs \
                 --out {}",
                &[method, out.to_str().unwrap()],
            );
            args.extend_from_slice(flags);
            let (code, _, stderr) = longstep_run(&args, None);
            assert_eq!(code, 1, "{args:?}: {stderr}");
            let message = format!("{method} does not run with constraints ({asked})");
            assert!(stderr.contains(&message), "{args:?}: {stderr}");
            // The message lists the methods that do.
            assert!(
                stderr.contains(&CONSTRAINED_METHODS.join(", ")),
                "{args:?}: {stderr}"
            );
        }
    }
}

#[test]
fn constraints_and_hmr_on_a_scene_without_hydrogen() {
    // The bead-spring melt has bonds but no hydrogen and no water: `--constraints h-bonds`
    // runs with a notice that nothing is constrained (exit 0, all 3N − 3 degrees of freedom
    // kept); `--hydrogen-mass` and a tolerance ≤ 0 are errors (exit 1) saying why.
    let melt = "systems/polymer-melt/scene.toml";
    // A fresh folder: a run refuses one holding an earlier run's outputs.
    let out = common::scratch_dir("constraints-melt");
    let out = out.to_str().unwrap();
    let base = [
        "run", melt, "--method", "verlet", "--h", "10fs", "--t-end", "20fs",
    ];
    let with = |extra: &[&'static str]| {
        let mut args = base.to_vec();
        args.extend_from_slice(&["--json", "--out", out]);
        args.extend_from_slice(extra);
        longstep_run(&args, Some(1))
    };
    let (code, stdout, stderr) = with(&["--constraints", "h-bonds"]);
    assert_eq!(code, 0, "{stderr}");
    assert!(
        stderr.contains("notice: constraints h-bonds: the scene has no such bond and no water, so nothing is constrained"),
        "{stderr}"
    );
    let summary: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(summary["temperature"]["degrees_of_freedom"], 3 * 5000 - 3);
    let refused: [(&[&str], &str); 3] = [
        (
            &["--hydrogen-mass", "3amu"],
            "hydrogen_mass: the scene has no hydrogen bonded to a heavy atom",
        ),
        (
            &["--constraints", "all-bonds", "--constraint-tolerance", "0"],
            "constraint_tolerance must lie between 0 and 1",
        ),
        (
            &["--constraints", "all-bonds", "--constraint-tolerance=-1e-8"],
            "constraint_tolerance must lie between 0 and 1",
        ),
    ];
    for (extra, message) in refused {
        let (code, _, stderr) = with(extra);
        assert_eq!(code, 1, "{extra:?}: {stderr}");
        assert!(stderr.contains(message), "{extra:?}: {stderr}");
    }
}

#[test]
fn constrained_verlet_agrees_with_openmm_on_the_rigid_water_box() {
    // tests/data/openmm-constrained-water.json: OpenMM 8.6.1, Reference platform (double),
    // VerletIntegrator with SETTLE at 2 fs and constraint tolerance 1e-12, 50 steps from
    // its own constrained start; made by `python3 scripts/openmm_constrained.py` from
    // longstep's parameter dump. We start from the same constrained state and take the
    // same 50 steps with the constrained `verlet`.
    let text = std::fs::read_to_string("tests/data/openmm-constrained-water.json").unwrap();
    let reference: serde_json::Value = serde_json::from_str(&text).unwrap();
    let flat = |key: &str| common::flat(&reference[key]);
    let mut scene = scene_file("systems/water-box/scene.toml", &[]);
    let system = &mut scene.system;
    system.state.q = flat("positions_start");
    // OpenMM's VerletIntegrator is leapfrog: the velocities it reports lag the positions by
    // half a step, `v₋½`, and `x₁ = x₀ + h v½` with `v½ = v₋½ + h a₀` (then SETTLE, and
    // `v½ = (x₁ − x₀)/h`). Velocity Verlet from `p₀ = m v₋½ + (h/2) F(x₀)` takes the same
    // positions (both project along the bonds at `x₀`).
    let velocities = flat("velocities_start");
    let mut gradient = vec![0.0; velocities.len()];
    system.forces.total_gradient(&system.state.q, &mut gradient);
    for (k, p) in system.state.p.iter_mut().enumerate() {
        *p = velocities[k] / system.inverse_mass[k] - 0.5 * 2.0 * gradient[k];
    }
    // OpenMM's Reference SETTLE holds the distances rounded to single precision: its
    // waters' O–H are 5.5e-9 Å short of 1.012 Å (float32(0.1012 nm)) and H–H 4.6e-8 Å
    // short. We hold the same rigid geometry, measured from its first water.
    let q = &system.state.q;
    let distance = |i: usize, j: usize| -> f64 {
        (0..3)
            .map(|a| (q[3 * i + a] - q[3 * j + a]).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    let (oh, hh) = (distance(0, 1), distance(1, 2));
    let nominal = constraints_of(
        &scene_file("systems/water-box/scene.toml", &[]),
        ConstraintSet::None,
        true,
    );
    let waters: Vec<RigidWater> = nominal
        .waters()
        .iter()
        .map(|w| RigidWater { oh, hh, ..*w })
        .collect();
    let constraints = Constraints::new(3, 648, Vec::new(), waters, system.periodic_box).unwrap();
    let start_violation = constraints.max_violation(&system.state.q);
    println!(
        "OpenMM start against its own geometry: largest relative violation {start_violation:e}"
    );
    // Rigid to OpenMM's round-off in double (its SETTLE is analytic).
    assert!(start_violation < 1e-13, "{start_violation:e}");
    constraints
        .project_positions(&mut system.state.q, &system.inverse_mass)
        .unwrap();
    system.constraints = Some(constraints);
    let constraints_velocities = |system: &mut longstep::system::System| {
        let state = &mut system.state;
        let set = system.constraints.as_mut().unwrap();
        set.constrain_velocities(&state.q, &mut state.p, &system.inverse_mass)
            .unwrap();
    };
    let mut settings = longstep::settings::MethodSettings::new("verlet", 2.0);
    settings.rigid_water = true;
    let mut verlet = longstep::integrators::build(&settings, &mut Vec::new()).unwrap();
    verlet.setup(system).unwrap();
    constraints_velocities(system);
    let steps = reference["steps"].as_u64().unwrap();
    let mut previous = system.state.q.clone();
    for _ in 0..steps {
        previous.copy_from_slice(&system.state.q);
        verlet.step(system).unwrap();
    }
    let (x, v) = (flat("positions_end"), flat("velocities_end"));
    let lengths = system.periodic_box.unwrap().lengths;
    // The leapfrog velocity of the last step, as OpenMM reports it.
    let leapfrog: Vec<f64> = (0..x.len())
        .map(|k| (system.state.q[k] - previous[k]) / 2.0)
        .collect();
    let position_error = system
        .state
        .q
        .iter()
        .zip(&x)
        .enumerate()
        .map(|(k, (a, b))| {
            let d = a - b;
            (d - lengths[k % 3] * (d / lengths[k % 3]).round()).abs()
        })
        .fold(0.0, f64::max);
    let velocity_error = common::max_abs_difference(&leapfrog, &v) / common::max_abs(&v);
    println!(
        "OpenMM, {steps} constrained steps of 2 fs: positions within {position_error:e} Å, \
         velocities within {velocity_error:e} (relative to the largest)"
    );
    // The forces agree to ~1e-13 relative (tests/molecules.rs compares them to 1e-9) and
    // both SETTLEs are analytic: differences start at round-off (~1e-15 Å) and grow with
    // the liquid's divergence over 100 fs (a factor ~10–100: 7e-13 Å seen). Starting
    // from the reported velocities as if they were on-step (ignoring the leapfrog
    // half-step) already differs by 0.13 Å; a wrong constraint length or a missing
    // momentum correction likewise by far more than 1e-10.
    assert!(position_error < 1e-10, "{position_error:e}");
    assert!(velocity_error < 1e-10, "{velocity_error:e}");
}

#[test]
fn hydrogen_mass_repartitioning_makes_four_femtoseconds_conserve_energy() {
    // The alanine dipeptide at h = 4 fs with bonds to hydrogen constrained, 200 ps from
    // a 300 K start: with HMR (3 amu) the run's drift fit (a linear fit over the 5001
    // rows; −0.004 kT/ns/dof seen, its change within the energy's fluctuation) stays within
    // the bound of 0.05 kT/ns/dof; without HMR the same run heats beyond it (+1.21, a
    // change of 6.4 kcal/mol against a fluctuation of 0.89: resolved), or heats until a
    // constraint fails (exit 3: seen at t ≈ 123 ps, the total energy up from 51 to 258
    // kcal/mol, 2000 K, once the kicks' projections were merged, a round-off change of a
    // chaotic, unstable trajectory). So the test sees the difference the masses make, not
    // a bound loose enough for both.
    let run = |hmr: bool| {
        let out = common::scratch_dir(&format!("constraints-hmr-{hmr}"));
        let mut args = argv(
            "run systems/molecules/alanine-dipeptide.toml --method verlet --h 4fs \
             --constraints h-bonds --temperature 300K --t-end 200ps --json --out {}",
            &[out.to_str().unwrap()],
        );
        if hmr {
            args.extend(["--hydrogen-mass", "3amu"]);
        }
        let (code, stdout, stderr) = longstep_run(&args, None);
        if !hmr && code == 3 {
            assert!(stderr.contains("constraints failed"), "{stderr}");
            return None;
        }
        assert_eq!(code, 0, "{stderr}");
        let summary: serde_json::Value = serde_json::from_str(&stdout).unwrap();
        // 3·22 − 12 constraints − 3.
        assert_eq!(summary["temperature"]["degrees_of_freedom"], 51);
        Some(summary["drift"].clone())
    };
    let with = run(true).expect("the HMR run finishes");
    println!("4 fs, h-bonds: with HMR {with}");
    assert_eq!(with["exceeded"], false, "{with}");
    assert!(with["value"].as_f64().unwrap().abs() <= 0.05, "{with}");
    match run(false) {
        None => println!("  without: a constraint failed (exit 3)"),
        Some(without) => {
            println!("  without {without}");
            assert_eq!(without["exceeded"], true, "{without}");
            // Its 2σ interval (error = fluctuation over the span, ≈ 0.17) lies wholly beyond.
            assert_eq!(without["verdict"], "fail", "{without}");
        }
    }
}

#[test]
fn a_topology_file_gives_its_bonds_and_waters_to_the_constraints() {
    // The solvated alanine dipeptide from its AMBER prmtop: 12 bonds to hydrogen in the
    // peptide, 423 TIP3P waters (listed with an H–H bond, whose rest length SETTLE uses).
    let scene = scene_file("systems/alanine-dipeptide-amber/ala2-solvated.toml", &[]);
    let constraints = constraints_of(&scene, ConstraintSet::HBonds, true);
    assert_eq!(constraints.pairs().len(), 12);
    assert_eq!(constraints.waters().len(), 423);
    assert_eq!(constraints.count(), 12 + 3 * 423);
    let mut q = scene.system.state.q.clone();
    constraints
        .project_positions(&mut q, &scene.system.inverse_mass)
        .unwrap();
    let violation = constraints.max_violation(&q);
    assert!(
        violation <= constraints.tolerance() * (1.0 + 1e-6),
        "{violation:e}"
    );
    // HMR on the peptide in vacuum: 12 hydrogens on 4 carbons and 2 nitrogens.
    let mut vacuum = scene_file("systems/alanine-dipeptide-amber/ala2.toml", &[]);
    let topology = vacuum.bonded_topology().unwrap();
    let report = vacuum
        .system
        .repartition_hydrogen_mass(&topology, 3.0, vacuum.units)
        .unwrap();
    assert_eq!((report.hydrogens, report.heavy_atoms), (12, 6));
}

/// One outer step of constrained endpoint impulse on two levels as it was before the
/// projections were merged: every kick followed by its own velocity projection.
fn impulse_projecting_every_kick(
    system: &mut longstep::system::System,
    gradients: &mut [Vec<f64>; 2],
    h: f64,
    inner: usize,
) {
    let dt = h / inner as f64;
    let kick_and_project = |system: &mut longstep::system::System, g: &[f64], scale: f64| {
        for (pk, gk) in system.state.p.iter_mut().zip(g) {
            *pk -= scale * gk;
        }
        let constraints = system.constraints.as_mut().unwrap();
        let state = &mut system.state;
        let w = &system.inverse_mass;
        constraints
            .constrain_velocities(&state.q, &mut state.p, w)
            .unwrap();
    };
    kick_and_project(system, &gradients[1], 0.5 * h);
    for _ in 0..inner {
        kick_and_project(system, &gradients[0], 0.5 * dt);
        let q_old = system.state.q.clone();
        let state = &mut system.state;
        for ((qk, pk), w) in state.q.iter_mut().zip(&state.p).zip(&system.inverse_mass) {
            *qk += dt * w * pk;
        }
        let constraints = system.constraints.as_mut().unwrap();
        let w = &system.inverse_mass;
        constraints
            .constrain_positions(&q_old, &mut state.q, &mut state.p, w, dt)
            .unwrap();
        system
            .forces
            .gradient(0, &system.state.q, &mut gradients[0]);
        kick_and_project(system, &gradients[0], 0.5 * dt);
    }
    system
        .forces
        .gradient(1, &system.state.q, &mut gradients[1]);
    kick_and_project(system, &gradients[1], 0.5 * h);
}

/// The largest `|a − b|` over two slices.
fn largest_difference(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

#[test]
fn one_projection_for_consecutive_kicks_is_a_projection_after_each() {
    use longstep::run::prepare::{RunRequest, prepare};
    use longstep::settings::{RunSpec, Value};
    // `impulse` with constraints projects the momenta once for the kicks between two
    // drifts (src/integrators/constrained.rs): 3 projections per outer step here instead
    // of 6. The projection at fixed q is linear and idempotent, so after 10 outer steps of
    // 2 fs / 2 inner steps the run is the one that projects after every kick: to round-off
    // for rigid water (SETTLE is exact), to the RATTLE tolerance for h-bonds.
    for (constraints, rigid, bound_q, bound_p) in [
        // Round-off: ε·|q| ≈ 1e-14 Å per operation, grown over 40 kicks and 20 drifts of
        // a chaotic liquid; 1e-10 leaves room for that and is 1e-8 of a step's motion.
        ("none", true, 1e-10, 1e-10),
        // RATTLE meets |r̂·Δv| ≤ tol·v_rms (tol 1e-8) whichever sum it projects:
        // either way: momenta may differ by ~1e-8 of a momentum, positions by that over 20 fs.
        ("h-bonds", false, 1e-8, 1e-7),
    ] {
        let overrides = RunSpec {
            method: Some("impulse".into()),
            h: Some(Value::Expression("2fs".into())),
            inner_steps: Some(2),
            constraints: Some(constraints.into()),
            rigid_water: Some(rigid),
            ..Default::default()
        };
        let path = std::path::Path::new("systems/water-box/scene.toml");
        let mut run = prepare(&RunRequest::new(path, &[], &overrides)).unwrap();
        let mut reference = prepare(&RunRequest::new(path, &[], &overrides)).unwrap();
        let system = &mut run.scene.system;
        assert_eq!(system.forces.n_levels(), 2);
        run.integrator.setup(system).unwrap();
        let other = &mut reference.scene.system;
        let n = other.n_dofs();
        let mut gradients = [vec![0.0; n], vec![0.0; n]];
        for (level, g) in gradients.iter_mut().enumerate() {
            other.forces.gradient(level, &other.state.q, g);
        }
        let h = run.integrator.outer_step();
        let start = system.state.q.clone();
        for _ in 0..10 {
            run.integrator.step(system).unwrap();
            impulse_projecting_every_kick(other, &mut gradients, h, 2);
        }
        let moved = largest_difference(&system.state.q, &start);
        let dq = largest_difference(&system.state.q, &other.state.q);
        let dp = largest_difference(&system.state.p, &other.state.p);
        let p_scale = other.state.p.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        println!(
            "{constraints} rigid={rigid}: moved {moved:.3e}, |Δq| {dq:.3e}, |Δp| {dp:.3e} \
             (largest |p| {p_scale:.3e})"
        );
        assert!(moved > 0.01, "{moved}");
        assert!(dq <= bound_q, "{constraints}: {dq:e}");
        assert!(dp <= bound_p * p_scale, "{constraints}: {dp:e}");
    }
}
