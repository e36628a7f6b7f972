//! Wall time of the asynchronous pseudo-energy scheme against the synchronous one on the
//! slow-fast FPU chain (MEMM18 4.3.1: h_S = 0.01, h_F = 2e-4, five-point Gauss–Lobatto),
//! over T = 1 with the pseudo-energy monitor off (the step alone). The count ratio
//! N_a/N_s is 0.58; `cargo bench --bench pseudo_energy` gives the time ratio.

use std::hint::black_box;
use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};
use longstep::integrators::quadrature::Quadrature;
use longstep::integrators::{AsyncPseudoEnergy, Integrator, PseudoEnergy};
use longstep::io::scene::load_scene;
use longstep::system::System;

fn system() -> System {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("systems/fpu-slow-fast.toml");
    load_scene(&path, &[]).expect("scene").system
}

fn run(method: &mut dyn Integrator, steps: usize) -> f64 {
    let mut system = system();
    method.setup(&mut system).expect("setup");
    for _ in 0..steps {
        method.step(&mut system).expect("step");
    }
    system.state.q[0]
}

fn slow_fast_fpu(c: &mut Criterion) {
    let rule = Quadrature::by_name("gl5").expect("rule");
    let mut group = c.benchmark_group("slow-fast FPU, T = 1");
    group.sample_size(30);
    group.bench_function("synchronous h = 2e-4", |b| {
        b.iter(|| {
            let mut sync = PseudoEnergy::new(2e-4, rule.clone())
                .expect("method")
                .with_monitor(false);
            black_box(run(&mut sync, 5_000))
        })
    });
    group.bench_function("asynchronous h_S = 0.01, K = 50", |b| {
        b.iter(|| {
            let mut asynchronous = AsyncPseudoEnergy::new(0.01, 50, rule.clone())
                .expect("method")
                .with_monitor(false);
            black_box(run(&mut asynchronous, 100))
        })
    });
    group.finish();
}

criterion_group!(benches, slow_fast_fpu);
criterion_main!(benches);
