//! Cost of the molecular force field on the kit's water boxes (648 and 5 184 atoms): the
//! non-bonded kernel on a valid list for each instruction set and precision, a list build,
//! a pruning, the bonded gradient, and one r-RESPA outer step (4 fs / 0.5 fs). Run with
//! `cargo bench --bench molecules`; set `RAYON_NUM_THREADS` to compare thread counts.
//! `scripts/bench_md.py` measures whole runs against GROMACS, OpenMM and LAMMPS.

use std::path::Path;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use longstep::forces::nonbonded::Nonbonded;
use longstep::forces::simd::Isa;
use longstep::forces::{ForceTerm, Precision};
use longstep::integrators;
use longstep::io::scene::{Scene, load_scene};
use longstep::settings::MethodSettings;

const SCENES: [(&str, &str); 2] = [
    ("water216", "systems/water-box/scene.toml"),
    ("water1728", "systems/water-box-1728/scene.toml"),
];

fn nonbonded(scene: &Scene) -> &Nonbonded {
    scene
        .system
        .forces
        .find::<Nonbonded>()
        .expect("a non-bonded term")
}

fn water_forces(c: &mut Criterion) {
    for (name, path) in SCENES {
        let mut scene = load_scene(Path::new(path), &[]).unwrap();
        let q = scene.system.state.q.clone();
        let mut gradient = vec![0.0; q.len()];
        for isa in Isa::available() {
            for precision in [Precision::Double, Precision::Mixed] {
                let term = nonbonded(&scene);
                term.set_isa(isa);
                term.set_precision(precision);
                c.bench_function(
                    &format!(
                        "{name}/nonbonded gradient {} {}",
                        isa.name(),
                        precision.name()
                    ),
                    |b| b.iter(|| term.add_gradient(&q, &mut gradient)),
                );
            }
        }
        let term = nonbonded(&scene);
        term.set_isa(Isa::best());
        term.set_precision(Precision::Double);
        let (outer, inner) = term.list_buffers();
        c.bench_function(&format!("{name}/list build and prune"), |b| {
            b.iter(|| {
                term.set_list_buffers(outer, inner);
                term.add_gradient(&q, &mut gradient)
            })
        });
        let forces = &mut scene.system.forces;
        c.bench_function(&format!("{name}/bonded gradient"), |b| {
            b.iter(|| forces.gradient(0, &q, &mut gradient))
        });
    }
}

fn water_step(c: &mut Criterion) {
    for (name, path) in SCENES {
        let mut scene = load_scene(Path::new(path), &[]).unwrap();
        let settings = MethodSettings::new("impulse", 4.0).with_inner_steps(8);
        let mut integrator = integrators::build(&settings, &mut Vec::new()).unwrap();
        integrator.setup(&mut scene.system).unwrap();
        c.bench_function(&format!("{name}/impulse outer step 4 fs / 0.5 fs"), |b| {
            b.iter(|| integrator.step(&mut scene.system).unwrap())
        });
    }
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
