//! PME's reciprocal sum in mixed precision (`Precision::Mixed`: the mesh in f32, the
//! per-atom forces and the energy accumulated in f64), against the same term in double:
//!
//! * on the water boxes, the relative RMS force and the energy differ from double by no
//!   more than f32 round-off over the accumulation depth, and far less than the PME
//!   discretisation error itself (double PME against the converged plain Ewald sum);
//! * the same bits at one, two and three threads (gradient, Hessian-vector product,
//!   energy);
//! * switching back to double gives double's bits again.

mod common;

use std::path::Path;

use common::{TestRng, rms};
use longstep::forces::ewald::direct::DirectEwald;
use longstep::forces::ewald::{EwaldParameters, PmeReciprocal};
use longstep::forces::{ForceTerm, Precision};
use longstep::io::forcefield::ElectrostaticsOverrides;
use longstep::io::scene::SceneFlags;

const KE: f64 = 332.06371;
/// The unit round-off of f32, 2⁻²⁴.
const F32_ROUNDOFF: f64 = 5.96e-8;

/// Positions, charges, box and PME parameters of a shipped water box with `coulomb = "pme"`
/// at the scene's defaults and pme_order `order`.
fn water(path: &str, order: usize) -> (Vec<f64>, Vec<f64>, [f64; 3], EwaldParameters) {
    let flags = SceneFlags {
        electrostatics: ElectrostaticsOverrides {
            coulomb: Some("pme".into()),
            pme_order: Some(order),
            ..ElectrostaticsOverrides::default()
        },
        ..SceneFlags::default()
    };
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let scene = longstep::io::scene::load_scene_with(&root.join(path), &flags, &[]).expect(path);
    let system = &scene.system;
    let term = system
        .forces
        .find::<PmeReciprocal>()
        .expect("a pme-reciprocal term");
    let lengths = system.periodic_box.expect("a box").lengths;
    (
        system.state.q.clone(),
        term.charges().to_vec(),
        lengths,
        term.parameters(),
    )
}

/// `(mesh energy, gradient)` of the mesh alone (no excluded pairs) in `precision`.
fn mesh(term: &PmeReciprocal, q: &[f64], precision: Precision) -> (f64, Vec<f64>) {
    assert!(term.set_precision(precision));
    assert_eq!(term.precision(), precision);
    let mut g = vec![0.0; q.len()];
    term.add_gradient(q, &mut g);
    (term.energy_components(q)[0].1, g)
}

fn relative_rms(a: &[f64], b: &[f64]) -> f64 {
    rms(a.iter().zip(b).map(|(x, y)| x - y)) / rms(b.iter().copied())
}

/// The round-off bound of the f32 mesh, relative to the RMS mesh force (and to the mesh
/// energy): each f32 operation errs by at most u = 2⁻²⁴ relative, and an error passes on
/// through the sums it enters, so the bound is u times the accumulation depth. A grid
/// value sums the charges whose stencils cover it (at most the atoms in an `(n h)³` cube,
/// `n` the order and `h` the spacing: `density (n h)³`); the 3-D FFT forward and back is
/// `2 log₂(K_x K_y K_z)` butterfly passes, each adding u to the relative error of the
/// transform's norm; the B-spline weights are `n` recursion steps per axis (`3n`); the
/// gathering sums `n³` products. Everything else (placement, charges, the force's sum) is
/// in f64.
fn f32_bound(atoms: usize, lengths: [f64; 3], params: &EwaldParameters) -> f64 {
    let n = params.order as f64;
    let volume: f64 = lengths.iter().product();
    let cube: f64 = (0..3)
        .map(|a| n * lengths[a] / params.grid[a] as f64)
        .product();
    let spread = atoms as f64 / volume * cube;
    let points: f64 = params.grid.iter().map(|&k| k as f64).product();
    let fft = 2.0 * points.log2();
    F32_ROUNDOFF * (spread + fft + 3.0 * n + n * n * n)
}

#[test]
fn mixed_mesh_is_within_f32_roundoff_of_double_and_far_inside_the_pme_error() {
    // The 648-atom box at OpenMM's order 5 and GROMACS's order 4 (grid 16³ from 1.2 Å),
    // against the plain Ewald sum converged far below 1e-10 (tests/ewald.rs).
    for order in [4, 5] {
        let (q, charges, lengths, params) = water("systems/water-box/scene.toml", order);
        let term = PmeReciprocal::new(params, lengths, KE, charges.clone(), &[]).expect("PME");
        let (e_double, g_double) = mesh(&term, &q, Precision::Double);
        let (e_mixed, g_mixed) = mesh(&term, &q, Precision::Mixed);
        let exact = DirectEwald {
            alpha: params.alpha,
            lengths,
            coulomb_constant: KE,
            charges: charges.clone(),
            excluded: Vec::new(),
            real_cutoff: 6.0 / params.alpha,
            k_max: lengths.map(|l| (6.3 * params.alpha * l / std::f64::consts::PI).ceil() as i64),
        }
        .evaluate(&q);
        let discretisation = relative_rms(&g_double, &exact.reciprocal_gradient);
        let discretisation_energy = (e_double - exact.reciprocal).abs() / exact.reciprocal.abs();
        let force = relative_rms(&g_mixed, &g_double);
        let energy = (e_mixed - e_double).abs() / e_double.abs();
        let bound = f32_bound(charges.len(), lengths, &params);
        println!(
            "order {order}: mixed-double force {force:.2e} energy {energy:.2e} (bound \
             {bound:.2e}); double-exact force {discretisation:.2e} energy \
             {discretisation_energy:.2e}"
        );
        assert!(force < bound, "order {order}: force {force:e} > {bound:e}");
        assert!(
            energy < bound,
            "order {order}: energy {energy:e} > {bound:e}"
        );
        // "Far inside": the precision costs less than a tenth of what the mesh itself costs.
        assert!(force < 0.1 * discretisation, "{force:e} {discretisation:e}");
        assert!(
            energy < 0.1 * discretisation_energy,
            "{energy:e} {discretisation_energy:e}"
        );
        // Back to double: double's bits again.
        let (e_again, g_again) = mesh(&term, &q, Precision::Double);
        assert_eq!(e_again.to_bits(), e_double.to_bits());
        assert!(
            g_again
                .iter()
                .zip(&g_double)
                .all(|(a, b)| a.to_bits() == b.to_bits())
        );
    }
}

#[test]
fn mixed_mesh_of_the_benchmark_box_is_within_f32_roundoff_of_double() {
    // The 5 184-atom box at the head-to-head's PME (GROMACS defaults: order 4, grid 32³),
    // excluded pairs included as the run has them.
    let (q, charges, lengths, params) = water("systems/water-box-1728/scene.toml", 4);
    assert_eq!(params.grid, [32; 3]);
    let excluded: Vec<(usize, usize)> = (0..charges.len() / 3)
        .flat_map(|m| {
            [
                (3 * m, 3 * m + 1),
                (3 * m, 3 * m + 2),
                (3 * m + 1, 3 * m + 2),
            ]
        })
        .collect();
    let bound = f32_bound(charges.len(), lengths, &params);
    let bare = PmeReciprocal::new(params, lengths, KE, charges.clone(), &[]).expect("PME");
    let (e_double, g_double) = mesh(&bare, &q, Precision::Double);
    let (e_mixed, g_mixed) = mesh(&bare, &q, Precision::Mixed);
    let force = relative_rms(&g_mixed, &g_double);
    let energy = (e_mixed - e_double).abs() / e_double.abs();
    println!("5184 atoms: mixed-double force {force:.2e} energy {energy:.2e} (bound {bound:.2e})");
    assert!(force < bound, "force {force:e} > {bound:e}");
    assert!(energy < bound, "energy {energy:e} > {bound:e}");
    // With the excluded pairs (f64 in both) the mesh's round-off is the same absolute
    // error; the term's force is smaller where the two nearly cancel, so its relative
    // error is scaled by RMS(mesh force) / RMS(term force).
    let term = PmeReciprocal::new(params, lengths, KE, charges, &excluded).expect("PME");
    let mut g_d = vec![0.0; q.len()];
    let mut g_m = vec![0.0; q.len()];
    assert!(term.set_precision(Precision::Double));
    term.add_gradient(&q, &mut g_d);
    assert!(term.set_precision(Precision::Mixed));
    term.add_gradient(&q, &mut g_m);
    let scale = rms(g_double.iter().copied()) / rms(g_d.iter().copied());
    let with_exclusions = relative_rms(&g_m, &g_d);
    assert!(
        with_exclusions < bound * scale,
        "{with_exclusions:e} > {bound:e} x {scale}"
    );
}

#[test]
fn mixed_pme_gives_the_same_bits_on_one_two_and_three_threads() {
    // As tests/ewald.rs does in double: above the parallel threshold (1024 atoms), unequal
    // axes and an odd z.
    let lengths = [30.0, 31.0, 32.0];
    let mut rng = TestRng::new(21);
    let q: Vec<f64> = (0..3 * 2000)
        .map(|k| rng.uniform(0.0, lengths[k % 3]))
        .collect();
    let mut charges = rng.vector(2000, -1.0, 1.0);
    let mean = charges.iter().sum::<f64>() / charges.len() as f64;
    charges.iter_mut().for_each(|c| *c -= mean);
    let v = TestRng::new(5).vector(q.len(), -1.0, 1.0);
    let params = EwaldParameters {
        alpha: 0.35,
        grid: [30, 32, 27],
        order: 5,
    };
    let excluded = [(0, 1), (2, 3), (4, 5)];
    let term = PmeReciprocal::new(params, lengths, KE, charges, &excluded).expect("PME term");
    assert!(term.set_precision(Precision::Mixed));
    let evaluate = |threads: usize| common::term_bits(&term, &q, &v, threads);
    let serial = evaluate(1);
    assert!(serial == evaluate(2));
    assert!(serial == evaluate(3));
}
