//! Stability maps: the analytic 1000 × 1000 map (goal: under 1 s on 2 cores) and an
//! integrator-mode maps (verlet, and LongAverage with K = 20 inner steps).

use std::f64::consts::PI;
use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use longstep::analysis::stability::AnalyticMethod;
use longstep::analysis::stability::analytic::LinearProblem;
use longstep::analysis::stability::integrator::{IntegratorProbe, ProbeScene};
use longstep::analysis::stability::map::{Axis, Evaluator, Grid, evaluate_all};
use longstep::settings::MethodSettings;

fn grid(end: f64, n: usize) -> Grid {
    let axis = Axis::new(0.0, end, n, "Γ").expect("axis");
    Grid {
        gamma1: axis,
        gamma2: axis,
    }
}

fn analytic_map(c: &mut Criterion) {
    let mut group = c.benchmark_group("stability_map");
    group.sample_size(10);
    for method in [AnalyticMethod::LongAverage, AnalyticMethod::LinearAverage] {
        let evaluator =
            Evaluator::Analytic(LinearProblem::three_spring(method, 0.5).expect("valid"));
        let grid = grid(6.5, 1000);
        group.bench_function(format!("analytic_1000x1000_{}", method.name()), |b| {
            b.iter(|| black_box(evaluate_all(&evaluator, &grid).expect("analytic")))
        });
    }
    let probe = IntegratorProbe::new(
        ProbeScene::three_spring(),
        MethodSettings::new("verlet", 0.5),
    )
    .expect("verlet");
    let evaluator = Evaluator::Integrator(Box::new(probe));
    let grid = grid(2.0 * PI, 200);
    group.bench_function("integrator_200x200_verlet", |b| {
        b.iter(|| black_box(evaluate_all(&evaluator, &grid).expect("integrator")))
    });
    // The goal: LongAverage with K = 20 inner steps, 200 × 200, under 30 s on 2 cores.
    let probe = IntegratorProbe::new(
        ProbeScene::three_spring(),
        MethodSettings::new("long-average", 0.5).with_inner_steps(20),
    )
    .expect("long-average");
    let evaluator = Evaluator::Integrator(Box::new(probe));
    group.bench_function("integrator_200x200_long_average_k20", |b| {
        b.iter(|| black_box(evaluate_all(&evaluator, &grid).expect("integrator")))
    });
    group.finish();
}

criterion_group!(benches, analytic_map);
criterion_main!(benches);
