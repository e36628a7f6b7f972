//! The averaging Jacobian of the mollified methods, two ways: forward propagation per fast
//! component (GSS98 section 2) and the adjoint product. They must agree with each other to
//! round-off and with finite differences of the averaging map to the differences' accuracy.

mod common;

use common::{TestRng, scene};
use longstep::integrators::mollified::{Average, JacobianChoice, JacobianMode, Mollifier};
use longstep::io::scene::Scene;
use nalgebra::DMatrix;

fn mollifier(
    scene: &Scene,
    average: Average,
    mode: JacobianMode,
    h: f64,
    inner: usize,
) -> Mollifier {
    let mut mollifier = Mollifier::new(average, JacobianChoice::Fixed(mode), h, inner);
    let system = &scene.system;
    let components = system.forces.fast_components(system.n_particles());
    mollifier.setup(system.dim, &components);
    mollifier
}

/// The full Jacobian `A_q` at the scene's positions, row by row from `A_qᵀ e_i`.
fn jacobian(
    scene: &mut Scene,
    average: Average,
    mode: JacobianMode,
    h: f64,
    inner: usize,
) -> DMatrix<f64> {
    let mut m = mollifier(scene, average, mode, h, inner);
    let system = &mut scene.system;
    let n = system.n_dofs();
    let q = system.state.q.clone();
    m.compute_average(&mut system.forces, &system.inverse_mass, &q, None);
    let mut result = DMatrix::zeros(n, n);
    let mut e = vec![0.0; n];
    let mut row = vec![0.0; n];
    for i in 0..n {
        e.fill(0.0);
        e[i] = 1.0;
        m.transpose_product(&mut system.forces, &system.inverse_mass, &e, &mut row);
        for j in 0..n {
            result[(i, j)] = row[j];
        }
    }
    result
}

/// `A(q)` by the averaging map.
fn average_map(scene: &mut Scene, average: Average, h: f64, inner: usize, q: &[f64]) -> Vec<f64> {
    let mut m = mollifier(scene, average, JacobianMode::Adjoint, h, inner);
    let system = &mut scene.system;
    m.compute_average(&mut system.forces, &system.inverse_mass, q, None);
    m.averaged_positions().to_vec()
}

/// Central-difference Jacobian of the averaging map with step ε.
fn finite_difference(
    scene: &mut Scene,
    average: Average,
    h: f64,
    inner: usize,
    epsilon: f64,
) -> DMatrix<f64> {
    let q0 = scene.system.state.q.clone();
    let n = q0.len();
    let mut result = DMatrix::zeros(n, n);
    for j in 0..n {
        let mut q = q0.clone();
        q[j] = q0[j] + epsilon;
        let plus = average_map(scene, average, h, inner, &q);
        q[j] = q0[j] - epsilon;
        let minus = average_map(scene, average, h, inner, &q);
        for i in 0..n {
            result[(i, j)] = (plus[i] - minus[i]) / (2.0 * epsilon);
        }
    }
    result
}

fn check(scene_text: &str, label: &str, h: f64, inner: usize) {
    for average in [Average::Short, Average::Long, Average::Linear] {
        let mut s = scene(scene_text);
        let forward = jacobian(&mut s, average, JacobianMode::Forward, h, inner);
        let adjoint = jacobian(&mut s, average, JacobianMode::Adjoint, h, inner);
        let scale = forward.amax();
        let difference = (&forward - &adjoint).amax() / scale;
        // Both differentiate the same floating-point map exactly, in different orders: they
        // agree to round-off accumulated over the auxiliary steps.
        assert!(
            difference < 1e-12,
            "{label}, {average:?}: forward and adjoint differ by {difference:e} relative"
        );
        // Finite differences: the gap between steps ε and ε/2 measures their truncation
        // error (it falls like ε²), so the exact Jacobian must sit within a few times that
        // gap of the finer one, plus round-off ~u·|A|/ε.
        let coarse = finite_difference(&mut s, average, h, inner, 1e-4);
        let fine = finite_difference(&mut s, average, h, inner, 5e-5);
        let truncation = (&coarse - &fine).amax();
        let round_off = 1e-16 * s.system.state.q.iter().fold(1.0f64, |m, x| m.max(x.abs())) / 5e-5;
        let error = (&forward - &fine).amax();
        assert!(
            error <= 2.0 * truncation + 10.0 * round_off,
            "{label}, {average:?}: |A_q − FD| = {error:e}, FD truncation ≈ {truncation:e}"
        );
        assert!(
            (forward.clone() - DMatrix::identity(forward.nrows(), forward.ncols())).amax() > 1e-3,
            "{label}: the Jacobian is trivial, the check is empty"
        );
    }
}

#[test]
fn three_spring_jacobians_agree() {
    let text = std::fs::read_to_string("systems/three-spring.toml").unwrap();
    // Off equilibrium, so the fast forces act during the average.
    let text = text
        .replace("position = [1.0, 0.0]", "position = [1.04, 0.07]")
        .replace("position = [2.0, 0.0]", "position = [1.98, -0.05]");
    check(&text, "three-spring", 0.5, 50);
}

#[test]
fn fifty_bead_chain_jacobians_agree() {
    // A 3-D helix with bond length 1, each bead displaced randomly by up to 0.05.
    let mut rng = TestRng::new(11);
    let mut text = String::from("version = 1\nname = \"chain50\"\ndim = 3\n");
    for i in 0..50 {
        let angle = i as f64 * std::f64::consts::PI / 3.0;
        let d = rng.vector(3, -0.05, 0.05);
        text += &format!(
            "[[particles]]\nmass = 1.0\nposition = [{}, {}, {}]\n",
            0.8 * angle.cos() + d[0],
            0.8 * angle.sin() + d[1],
            0.6 * i as f64 + d[2]
        );
    }
    text += "[[terms]]\ntype = \"chain\"\nstiffness = 400.0\nrest_length = 1.0\n";
    let s = scene(&text);
    assert_eq!(s.system.n_particles(), 50);
    assert_eq!(s.system.forces.fast_components(50).len(), 1);
    check(&text, "50-bead chain", 0.2, 10);
}

#[test]
fn random_spring_and_angle_network_jacobians_agree() {
    let mut rng = TestRng::new(12);
    let n = 8;
    let mut text = String::from("version = 1\nname = \"network\"\ndim = 3\n");
    for _ in 0..n {
        let x = rng.vector(3, -1.5, 1.5);
        text += &format!(
            "[[particles]]\nmass = {}\nposition = [{}, {}, {}]\n",
            rng.uniform(0.5, 2.0),
            x[0],
            x[1],
            x[2]
        );
    }
    // A random spanning tree plus extra bonds, and angles along some bonds.
    let mut pairs = Vec::new();
    for i in 1..n {
        let j = (rng.next_u64() % i as u64) as usize;
        pairs.push((j, i));
    }
    pairs.push((0, n - 1));
    pairs.push((2, 5));
    let list: Vec<String> = pairs.iter().map(|(a, b)| format!("[{a}, {b}]")).collect();
    text += &format!(
        "[[terms]]\ntype = \"spring\"\npairs = [{}]\nstiffness = 200.0\nrest_length = 1.2\n",
        list.join(", ")
    );
    let triples: Vec<String> = pairs
        .windows(2)
        .filter_map(|w| {
            let (a, b) = w[0];
            let (c, d) = w[1];
            // Two bonds sharing a particle make an angle.
            if b == c {
                Some(format!("[{a}, {b}, {d}]"))
            } else if a == c && b != d {
                Some(format!("[{b}, {a}, {d}]"))
            } else {
                None
            }
        })
        .collect();
    assert!(!triples.is_empty());
    text += &format!(
        "[[terms]]\ntype = \"angle\"\ntriples = [{}]\nstiffness = 50.0\nrest_angle = 1.9\n",
        triples.join(", ")
    );
    check(&text, "random network", 0.25, 10);
}
