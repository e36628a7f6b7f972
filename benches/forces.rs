//! Cost of the force kernels and of a Verlet step: the units every cost chart is built on.
//! Run with `cargo bench --bench forces`.

use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};
use longstep::integrators;
use longstep::io::scene::load_scene;
use longstep::settings::MethodSettings;

fn chain_forces(c: &mut Criterion) {
    let mut scene = load_scene(Path::new("systems/chain/scene.toml"), &[]).unwrap();
    let system = &mut scene.system;
    let q = system.state.q.clone();
    let mut gradient = vec![0.0; q.len()];
    let v: Vec<f64> = (0..q.len()).map(|k| (k as f64 * 0.37).sin()).collect();
    let mut out = vec![0.0; q.len()];
    c.bench_function("chain100/fast gradient (99 springs)", |b| {
        b.iter(|| system.forces.gradient(0, &q, &mut gradient))
    });
    c.bench_function("chain100/fast Hessian-vector (99 springs)", |b| {
        b.iter(|| system.forces.hessian_vector(0, &q, &v, &mut out))
    });
    c.bench_function("chain100/slow gradient (4950 LJ pairs)", |b| {
        b.iter(|| system.forces.gradient(1, &q, &mut gradient))
    });
}

fn verlet_step(c: &mut Criterion) {
    let mut scene = load_scene(Path::new("systems/fpu.toml"), &[]).unwrap();
    let mut notices = Vec::new();
    let mut verlet =
        integrators::build(&MethodSettings::new("verlet", 1e-3), &mut notices).unwrap();
    verlet.setup(&mut scene.system).unwrap();
    c.bench_function("fpu/verlet step (6 particles, 1-D)", |b| {
        b.iter(|| verlet.step(&mut scene.system).unwrap())
    });
}

criterion_group!(benches, chain_forces, verlet_step);
criterion_main!(benches);
