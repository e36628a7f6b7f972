//! Cost of one outer step of the equilibrium mollifier (IRS99) against plain impulse on
//! the 216-water box (648 atoms), same non-bonded engine, same build, h = 4 fs, dt = 0.5 fs
//! (8 inner steps): the bound is equilibrium-molly ≤ 1.3× impulse per outer step.
//! LongAverage (GSS98) is measured beside them. Run with `cargo bench --bench mollifier`
//! (one thread: `RAYON_NUM_THREADS=1`). Instruction counts, which do not depend on what
//! else the machine runs: `scripts/callgrind_per_step.sh` (docs/performance.md).
//!
//! Every method starts from the kit's state and is set up again from it every
//! [`RESTART`] steps, outside the timing, so impulse (which heats at 4 fs) and the others
//! are timed on comparable configurations and never far from the start.

use std::path::Path;
use std::time::{Duration, Instant};

use criterion::{Criterion, criterion_group, criterion_main};
use longstep::integrators;
use longstep::io::scene::load_scene;
use longstep::settings::MethodSettings;

const SCENE: &str = "systems/water-box/scene.toml";
const H_FS: f64 = 4.0;
const INNER: usize = 8;
/// Outer steps between restarts from the kit's state (2 ps).
const RESTART: u64 = 500;

/// The method flags of each benchmark: name, method, molly_constraints, molly_jacobian.
const CASES: &[(&str, &str, Option<&str>, Option<&str>)] = &[
    ("impulse", "impulse", None, None),
    (
        "equilibrium-molly bonds exact",
        "equilibrium-molly",
        Some("bonds"),
        Some("exact"),
    ),
    (
        "equilibrium-molly bonds-angles exact",
        "equilibrium-molly",
        Some("bonds-angles"),
        Some("exact"),
    ),
    (
        "equilibrium-molly bonds-angles projection",
        "equilibrium-molly",
        Some("bonds-angles"),
        Some("projection"),
    ),
    ("long-average", "long-average", None, None),
];

fn outer_steps(c: &mut Criterion) {
    for &(label, method, constraints, jacobian) in CASES {
        let mut scene = load_scene(Path::new(SCENE), &[]).unwrap();
        let start = scene.system.state.clone();
        let mut settings = MethodSettings::new(method, H_FS).with_inner_steps(INNER);
        settings.molly_constraints = constraints.map(str::to_string);
        settings.molly_jacobian = jacobian.map(str::to_string);
        let mut integrator = integrators::build(&settings, &mut Vec::new()).unwrap();
        integrator.setup(&mut scene.system).unwrap();
        let mut taken = 0;
        c.bench_function(&format!("water216/{label} outer step 4 fs / 0.5 fs"), |b| {
            b.iter_custom(|iters| {
                let mut total = Duration::ZERO;
                for _ in 0..iters {
                    if taken == RESTART {
                        scene.system.state = start.clone();
                        integrator.setup(&mut scene.system).unwrap();
                        taken = 0;
                    }
                    let clock = Instant::now();
                    integrator.step(&mut scene.system).unwrap();
                    total += clock.elapsed();
                    taken += 1;
                }
                total
            })
        });
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .measurement_time(Duration::from_secs(5))
        .warm_up_time(Duration::from_secs(1))
        .sample_size(20);
    targets = outer_steps
}
criterion_main!(benches);
