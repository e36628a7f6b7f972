//! The iterative modes (`analysis::lanczos`): Lanczos against the dense eigensolver on the
//! alanine dipeptide in vacuum, with and without constraints and HMR; constrained
//! directions projected out; a rigid-bond bend against Wilson's G matrix, the constraint
//! tension included.

mod common;

use longstep::analysis::lanczos::{
    ConstrainedHessian, LanczosOptions, lanczos_highest, lanczos_highest_with,
};
use longstep::analysis::modes::{fast_modes, fast_modes_with};
use longstep::io::scene::Scene;
use longstep::settings::RunSpec;
use longstep::system::constraints::{Constraints, DistanceConstraint};
use nalgebra::SymmetricEigen;

const DIPEPTIDE: &str = "systems/alanine-dipeptide-amber/ala2.toml";

/// The dipeptide with `--constraints h-bonds --hydrogen-mass 3amu` applied as `run` does.
fn constrained_dipeptide() -> Scene {
    let mut scene = common::scene_file(DIPEPTIDE, &[]);
    let spec = RunSpec {
        constraints: Some("h-bonds".into()),
        hydrogen_mass: Some("3amu".parse().unwrap()),
        ..RunSpec::default()
    };
    let settings = scene
        .run
        .overridden_by(&spec)
        .resolve_with_units(&scene.parameters, scene.units)
        .unwrap();
    scene
        .apply_molecular_settings(&settings, &mut Vec::new())
        .unwrap();
    assert_eq!(scene.system.constraints.as_ref().unwrap().count(), 12);
    scene
}

/// Round-off of a symmetric eigensolver and of the Hessian-vector products that built the
/// matrix: a backward error `‖E‖ ≤ c n ε ‖A‖` (Golub & Van Loan 8.1), with c = 100 covering
/// the products' sums over a few terms per coordinate.
fn round_off(n: usize, norm: f64) -> f64 {
    100.0 * n as f64 * f64::EPSILON * norm
}

#[test]
fn lanczos_matches_the_dense_modes_of_the_dipeptide_in_vacuum() {
    let mut scene = common::scene_file(DIPEPTIDE, &[]);
    let mut dense: Vec<f64> = fast_modes(&mut scene.system)
        .iter()
        .filter(|m| !m.unstable)
        .map(|m| m.frequency * m.frequency)
        .collect();
    dense.sort_by(|a, b| b.total_cmp(a));
    let mut operator = ConstrainedHessian::new(&mut scene.system, 0).unwrap();
    let n = operator.len();
    assert_eq!(n, 66);
    // 40 iterations of 66: the Krylov space is not the whole space, so the agreement is
    // Lanczos converging, not an exact similarity transform.
    let options = LanczosOptions {
        iterations: 40,
        wanted: 6,
        tolerance: 0.0,
        seed: 3,
    };
    let result = lanczos_highest(&mut operator, &mut scene.system.forces, &options);
    assert_eq!(result.iterations, 40);
    let norm = dense[0];
    for (pair, exact) in result.pairs.iter().zip(&dense) {
        // Some eigenvalue lies within the residual of each Ritz value (Parlett 4.5.1); the
        // six largest are apart by more than their residuals, so it is the same-ranked one.
        let bound = pair.residual + round_off(n, norm);
        assert!(
            (pair.value - exact).abs() <= bound,
            "Ritz {} against dense {exact}: bound {bound}",
            pair.value
        );
        // Converged, or the comparison says nothing: residual below 1e-6 of the largest.
        assert!(pair.residual <= 1e-6 * norm, "residual {}", pair.residual);
    }
}

#[test]
fn constrained_lanczos_matches_the_dense_projected_operator_and_leaves_constraints_alone() {
    let mut scene = constrained_dipeptide();
    let mut operator = ConstrainedHessian::new(&mut scene.system, 0).unwrap();
    let n = operator.len();
    let matrix = operator.dense(&mut scene.system.forces);
    let mut dense: Vec<f64> = SymmetricEigen::new(matrix.clone())
        .eigenvalues
        .iter()
        .copied()
        .collect();
    dense.sort_by(|a, b| b.total_cmp(a));
    let norm = matrix.norm();
    // The 12 constrained directions are exact zero modes of P A P, so at least 12 of the
    // 66 eigenvalues vanish to round-off, and the 3 translations with them (the bonded
    // terms are translation invariant; rotations are not zero modes away from a minimum).
    let zeros = dense
        .iter()
        .filter(|l| l.abs() <= round_off(n, norm))
        .count();
    assert!(zeros >= 12 + 3, "{zeros} zero eigenvalues: {dense:?}");
    let options = LanczosOptions {
        iterations: 40,
        wanted: 6,
        tolerance: 0.0,
        seed: 5,
    };
    let result = lanczos_highest(&mut operator, &mut scene.system.forces, &options);
    let mut components = vec![0.0; operator.constraint_count()];
    for (pair, exact) in result.pairs.iter().zip(&dense) {
        let bound = pair.residual + round_off(n, norm);
        assert!(
            (pair.value - exact).abs() <= bound,
            "Ritz {} against dense {exact}: bound {bound}",
            pair.value
        );
        assert!(
            pair.residual <= 1e-6 * dense[0],
            "residual {}",
            pair.residual
        );
        // No component along a constraint gradient: N x = 0 to round-off. Each Lanczos
        // vector is w/β with w = A v − α v − β' v' − (reorthogonalisation), A v projected to
        // ~10 ε ‖A‖ ‖N_c‖ (‖N_c‖ ≤ √2 with masses ≥ 1 amu); dividing by β (≳ 10⁻² ‖A‖ here)
        // amplifies that by ‖A‖/β ≲ 10², and 40 such vectors accumulate: 10 ε · 10² · 40.
        operator.constraint_components(&pair.vector, &mut components);
        let largest = components.iter().fold(0.0f64, |m, c| m.max(c.abs()));
        assert!(
            largest <= 10.0 * f64::EPSILON * 1e2 * 40.0 * 2f64.sqrt(),
            "component {largest} along a constraint"
        );
    }
    // Unconstrained, the dipeptide's fastest bonded mode is an X–H stretch above 2900
    // cm⁻¹; with h-bonds held and HMR the fastest is far below (a C=O stretch or a heavy
    // bend), so the projection did remove something.
    let free = fast_modes(&mut common::scene_file(DIPEPTIDE, &[]).system)[0].frequency;
    assert!(
        dense[0].sqrt() < 0.7 * free,
        "{} against {free}",
        dense[0].sqrt()
    );
}

/// A water molecule whose O–H springs rest at 0.9572 Å held rigid at 1.012 Å: the springs
/// pull along the bonds and the constraint forces hold them (λ ≠ 0).
fn stretched_water(r: f64, theta: f64) -> String {
    let kcal = 4.184e-4;
    let (hx, hy) = (r * (theta / 2.0).sin(), r * (theta / 2.0).cos());
    format!(
        r#"
version = 1
name = "water"
dim = 3
[[particles]]
name = "O"
mass = 15.9994
position = [0.0, 0.0, 0.0]
[[particles]]
name = "H1"
mass = 1.008
position = [{hx}, {hy}, 0.0]
[[particles]]
name = "H2"
mass = 1.008
position = [{mhx}, {hy}, 0.0]
[[terms]]
type = "spring"
name = "O-H"
pairs = [["O", "H1"], ["O", "H2"]]
stiffness = {kb}
rest_length = 0.9572
[[terms]]
type = "angle"
name = "H-O-H"
between = ["H1", "O", "H2"]
stiffness = {ka}
rest_angle = {theta}
[run]
h = 1.0
t_end = 10.0
"#,
        mhx = -hx,
        kb = 1059.162 * kcal,
        ka = 75.90 * kcal,
    )
}

#[test]
fn a_rigid_bond_bend_has_the_g_matrix_frequency_whatever_the_bond_tension() {
    let (r, theta) = (1.012, 113.24f64.to_radians());
    let dir = common::scratch_dir("lanczos-water");
    let path = dir.join("water.toml");
    std::fs::write(&path, stretched_water(r, theta)).unwrap();
    let mut scene = common::scene_file(path.to_str().unwrap(), &[]);
    let pairs = vec![
        DistanceConstraint {
            i: 0,
            j: 1,
            length: r,
        },
        DistanceConstraint {
            i: 0,
            j: 2,
            length: r,
        },
    ];
    scene.system.constraints = Some(Constraints::new(3, 3, pairs, Vec::new(), None).unwrap());
    let mut operator = ConstrainedHessian::new(&mut scene.system, 0).unwrap();
    let matrix = operator.dense(&mut scene.system.forces);
    let mut eigenvalues: Vec<f64> = SymmetricEigen::new(matrix.clone())
        .eigenvalues
        .iter()
        .copied()
        .collect();
    eigenvalues.sort_by(|a, b| b.total_cmp(a));
    // With both bonds rigid the only internal coordinate is θ, and its kinetic energy is
    // ½ θ̇² (G⁻¹)_θθ with ṙ₁ = ṙ₂ = 0 (Wilson, Decius & Cross: T = ½ ṡᵀ G⁻¹ ṡ), so
    // ω² = k_θ / (G⁻¹)_θθ = k_θ (G_θθ − 2 G_rθ² / (G_rr + G_rr')): the Schur complement of
    // the stretches' block, with the XY₂ elements G_rr = 1/m_O + 1/m_H, G_rr' = cos θ/m_O,
    // G_rθ = −sin θ/(r m_O), G_θθ = 2/(r² m_H) + 2(1 − cos θ)/(r² m_O). (k_θ G_θθ alone, the
    // flexible molecule's diagonal element, is 0.3 % higher here.)
    let kcal = 4.184e-4;
    let (mo, mh) = (15.9994, 1.008);
    let g_rr = 1.0 / mo + 1.0 / mh;
    let g_rr2 = theta.cos() / mo;
    let g_rt = -theta.sin() / (r * mo);
    let g_tt = 2.0 / (r * r * mh) + 2.0 * (1.0 - theta.cos()) / (r * r * mo);
    let bend = 75.90 * kcal * (g_tt - 2.0 * g_rt * g_rt / (g_rr + g_rr2));
    let tolerance = round_off(9, matrix.norm());
    assert!(
        (eigenvalues[0] - bend).abs() <= tolerance,
        "bend {} against G-matrix {bend} (± {tolerance})",
        eigenvalues[0]
    );
    // Everything else (two constrained stretches, three rotations, three translations) is
    // zero. Without the tension term λ∇²g the rotations would have ω² ≈ k_b (r − r0)/(r m)
    // ≈ 0.02 fs⁻², ten million times this tolerance.
    for l in &eigenvalues[1..] {
        assert!(l.abs() <= tolerance, "{eigenvalues:?}");
    }
    let options = LanczosOptions {
        iterations: 9,
        wanted: 1,
        tolerance: 0.0,
        seed: 1,
    };
    let result = lanczos_highest(&mut operator, &mut scene.system.forces, &options);
    let top = &result.pairs[0];
    assert!((top.value - bend).abs() <= top.residual + tolerance);
}

/// Issue 43 item 16, the progress of `modes` alone: the dense path reports each batched
/// Hessian column once, in order, up to the largest fast component's coordinates (the
/// dipeptide in vacuum is one component of 22 atoms: 66), and the modes are those without
/// a progress callback; Lanczos reports each iteration against the most it may take.
#[test]
fn modes_report_their_progress_column_by_column() {
    let mut scene = common::scene_file(DIPEPTIDE, &[]);
    let mut seen = Vec::new();
    let modes = fast_modes_with(&mut scene.system, &mut |done, total| {
        seen.push((done, total))
    });
    let expected: Vec<(usize, usize)> = (1..=66).map(|j| (j, 66)).collect();
    assert_eq!(seen, expected);
    let plain = fast_modes(&mut scene.system);
    let frequencies = |m: &[longstep::analysis::modes::Mode]| -> Vec<u64> {
        m.iter().map(|m| m.frequency.to_bits()).collect()
    };
    assert_eq!(frequencies(&modes), frequencies(&plain));

    let mut operator = ConstrainedHessian::new(&mut scene.system, 0).unwrap();
    let options = LanczosOptions {
        iterations: 30,
        wanted: 4,
        tolerance: 0.0,
        seed: 3,
    };
    let mut steps = Vec::new();
    let result = lanczos_highest_with(
        &mut operator,
        &mut scene.system.forces,
        &options,
        &mut |done, most| steps.push((done, most)),
    );
    let expected: Vec<(usize, usize)> = (1..=result.iterations).map(|j| (j, 30)).collect();
    assert_eq!(result.iterations, 30);
    assert_eq!(steps, expected);
}
