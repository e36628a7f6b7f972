//! Cost of the molecular force field on the 216-water box (648 atoms, the peer kit's
//! system): non-bonded gradient (list valid), neighbour-list build, bonded gradient, and
//! one r-RESPA outer step (2 fs / 0.5 fs). Run with `cargo bench --bench molecules`; set
//! `RAYON_NUM_THREADS` to compare thread counts. `scripts/bench_vs_openmm.py` measures
//! whole runs against OpenMM and LAMMPS.

use std::path::Path;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use longstep::forces::neighbour_list::NeighbourList;
use longstep::integrators;
use longstep::io::scene::load_scene;
use longstep::settings::MethodSettings;

const SCENE: &str = "systems/water-box/scene.toml";

fn water_forces(c: &mut Criterion) {
    let mut scene = load_scene(Path::new(SCENE), &[]).unwrap();
    let system = &mut scene.system;
    let q = system.state.q.clone();
    let mut gradient = vec![0.0; q.len()];
    let slow = system.forces.n_levels() - 1;
    c.bench_function("water216/nonbonded gradient", |b| {
        b.iter(|| system.forces.gradient(slow, &q, &mut gradient))
    });
    c.bench_function("water216/bonded gradient", |b| {
        b.iter(|| system.forces.gradient(0, &q, &mut gradient))
    });
    let lengths = system.periodic_box.map(|b| b.lengths);
    let mut list = NeighbourList::new(q.len() / 3, 9.0, 1.0, lengths);
    c.bench_function("water216/neighbour list build (9 + 1 Å)", |b| {
        b.iter(|| list.build(&q, |_, _| Some(1)))
    });
}

fn water_step(c: &mut Criterion) {
    let mut scene = load_scene(Path::new(SCENE), &[]).unwrap();
    let settings = MethodSettings::new("impulse", 2.0).with_inner_steps(4);
    let mut integrator = integrators::build(&settings, &mut Vec::new()).unwrap();
    integrator.setup(&mut scene.system).unwrap();
    c.bench_function("water216/impulse outer step 2 fs / 0.5 fs", |b| {
        b.iter(|| integrator.step(&mut scene.system).unwrap())
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .measurement_time(Duration::from_secs(3))
        .warm_up_time(Duration::from_secs(1))
        .sample_size(20);
    targets = water_forces, water_step
}
criterion_main!(benches);
