//! Cost of the constraints (issue 28 item 6): one outer step of `verlet` and of `impulse` on
//! the 5 184-atom water box (`systems/water-box-1728`), flexible, with every water rigid
//! (SETTLE: `--rigid-water`) and with the O–H bonds held by SHAKE/RATTLE (`--constraints
//! h-bonds`, 3 456 bonds, the H–O–H angle left flexible). The step is the same in every case
//! (verlet 1 fs, a step the flexible box also takes; impulse 2 fs / 1 fs), so the
//! differences are the constraints' own work: one position constraint per drift and one
//! velocity projection per run of kicks between drifts (`src/integrators/constrained.rs`).
//! Run with
//! `RAYON_NUM_THREADS=1 cargo bench --bench constraints`; the budget is +10 % per
//! outer step.

use std::path::Path;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use longstep::run::prepare::{PreparedRun, RunRequest, prepare};
use longstep::settings::{RunSpec, Value};

const BOX: &str = "systems/water-box-1728/scene.toml";

/// The box prepared as `longstep run BOX --method METHOD --h H [--inner K] [constraints]`
/// would prepare it (the start put on the constraints), its integrator set up.
fn prepared(method: &str, h: &str, inner: usize, constraints: &str, rigid: bool) -> PreparedRun {
    let overrides = RunSpec {
        method: Some(method.into()),
        h: Some(Value::Expression(h.into())),
        inner_steps: Some(inner),
        constraints: Some(constraints.into()),
        rigid_water: Some(rigid),
        ..Default::default()
    };
    let mut run =
        prepare(&RunRequest::new(Path::new(BOX), &[], &overrides)).expect("the water box prepares");
    run.integrator
        .setup(&mut run.scene.system)
        .expect("the integrator sets up");
    run
}

fn outer_step(c: &mut Criterion) {
    let methods = [("verlet", "1fs", 1), ("impulse", "2fs", 2)];
    let cases = [
        ("flexible", "none", false),
        ("rigid water (SETTLE)", "none", true),
        ("h-bonds (RATTLE)", "h-bonds", false),
    ];
    for (method, h, inner) in methods {
        for (name, constraints, rigid) in cases {
            let mut run = prepared(method, h, inner, constraints, rigid);
            let label = format!("water1728/{method} {h} outer step, {name}");
            c.bench_function(&label, |b| {
                b.iter(|| run.integrator.step(&mut run.scene.system).unwrap())
            });
        }
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .measurement_time(Duration::from_secs(10))
        .warm_up_time(Duration::from_secs(2))
        .sample_size(20);
    targets = outer_step
}
criterion_main!(benches);
