//! Wall time of the asynchronous pseudo-energy scheme against the synchronous one, with the
//! pseudo-energy monitor off (the step alone):
//!
//! * the slow-fast FPU chain (MEMM18 4.3.1: h_S = 0.01, h_F = 2e-4, five-point
//!   Gauss–Lobatto), T = 1; count ratio N_a/N_s = 0.58;
//! * the inhomogeneous wave with n = 2000 cells (MEMM18 4.3.2's Δx), h_F = 0.1Δx and
//!   K = 5 (stable; MEMM18's K = 10 is not), midpoint, T = 0.05; count ratio 0.60.
//!
//! `cargo bench --bench pseudo_energy` gives the time ratios.

use std::hint::black_box;
use std::path::Path;

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use longstep::integrators::quadrature::Quadrature;
use longstep::integrators::{AsyncPseudoEnergy, Integrator, PseudoEnergy};
use longstep::io::scene::load_scene;
use longstep::system::System;

fn system(scene: &str, set: &[String]) -> System {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("systems")
        .join(scene);
    load_scene(&path, set).expect("scene").system
}

fn run(method: &mut dyn Integrator, mut system: System, steps: usize) -> f64 {
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
            black_box(run(&mut sync, system("fpu-slow-fast.toml", &[]), 5_000))
        })
    });
    group.bench_function("asynchronous h_S = 0.01, K = 50", |b| {
        b.iter(|| {
            let mut asynchronous = AsyncPseudoEnergy::new(0.01, 50, rule.clone())
                .expect("method")
                .with_monitor(false);
            black_box(run(
                &mut asynchronous,
                system("fpu-slow-fast.toml", &[]),
                100,
            ))
        })
    });
    group.finish();
}

fn inhomogeneous_wave(c: &mut Criterion) {
    let rule = Quadrature::midpoint();
    let set = vec!["n=2000".to_string()];
    let dx = 1.0 / 2000.0;
    let mut group = c.benchmark_group("wave n = 2000, T = 0.05");
    group.sample_size(10);
    // Reading the 2000-particle scene is not part of the measurement.
    group.bench_function("synchronous h = 0.1 dx", |b| {
        b.iter_batched(
            || system("wave-inhomogeneous.toml", &set),
            |scene| {
                let mut sync = PseudoEnergy::new(0.1 * dx, rule.clone())
                    .expect("method")
                    .with_monitor(false);
                black_box(run(&mut sync, scene, 1_000))
            },
            BatchSize::LargeInput,
        )
    });
    group.bench_function("asynchronous h_F = 0.1 dx, K = 5", |b| {
        b.iter_batched(
            || system("wave-inhomogeneous.toml", &set),
            |scene| {
                let mut asynchronous = AsyncPseudoEnergy::new(0.5 * dx, 5, rule.clone())
                    .expect("method")
                    .with_monitor(false);
                black_box(run(&mut asynchronous, scene, 200))
            },
            BatchSize::LargeInput,
        )
    });
    group.finish();
}

criterion_group!(benches, slow_fast_fpu, inhomogeneous_wave);
criterion_main!(benches);
