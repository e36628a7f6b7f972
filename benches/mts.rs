//! Cost of an outer step of the multiple-time-step methods on an N-bead 3-D chain (one
//! connected fast component): bonds and angles fast, springs between beads i and i+3 slow.
//!
//! * `outer step/N=1000`: impulse vs LongAverage (adjoint and forward Jacobian) at K = 10.
//! * `jacobian scaling`: LongAverage per outer step as N grows — forward mode is quadratic
//!   in the component size (one Hessian-vector product per coordinate per auxiliary step),
//!   adjoint linear.
//!
//! Run with `cargo bench --bench mts`.

use std::path::Path;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use longstep::integrators::{self, Integrator};
use longstep::io::scene::{Scene, build_scene};
use longstep::settings::MethodSettings;

/// `slow`: "springs" (i–i+3 springs, nearly free: the worst case for the mollified
/// overhead) or "lennard-jones" (all pairs within 2.5σ, the non-bonded force MTS is for).
fn chain(n: usize) -> Scene {
    chain_with(n, "springs")
}

fn chain_with(n: usize, slow_force: &str) -> Scene {
    let triples: Vec<String> = (0..n - 2)
        .map(|i| format!("[{i}, {}, {}]", i + 1, i + 2))
        .collect();
    let slow: Vec<String> = (0..n - 3).map(|i| format!("[{i}, {}]", i + 3)).collect();
    let text = format!(
        r#"
version = 1
name = "chain{n}"
dim = 3
[[particles]]
count = {n}
mass = 1.0
position = ["0.8*cos(i*pi/3)", "0.8*sin(i*pi/3)", "0.6*i"]
velocity = ["0.1*sin(7.3*i)", "0.1*cos(3.1*i)", "0.1*sin(1.7*i)"]
[[terms]]
type = "chain"
name = "bonds"
stiffness = 400.0
[[terms]]
type = "angle"
name = "bends"
triples = [{}]
stiffness = 40.0
{}
"#,
        triples.join(", "),
        if slow_force == "springs" {
            format!(
                "[[terms]]\ntype = \"spring\"\nname = \"i-i+3\"\npairs = [{}]\nstiffness = 0.5\n\
                 rest_length = \"geometry\"\ngroup = \"slow\"",
                slow.join(", ")
            )
        } else {
            "[[terms]]\ntype = \"lennard-jones\"\nepsilon = 0.1\nsigma = 0.8\ncutoff = 2.0"
                .to_string()
        }
    );
    build_scene(&text, Path::new("bench-chain.toml"), &[]).unwrap()
}

fn integrator(
    method: &str,
    jacobian: Option<&str>,
    system: &mut longstep::system::System,
) -> Box<dyn Integrator> {
    let mut settings = MethodSettings::new(method, 0.02).with_inner_steps(10);
    settings.jacobian = jacobian.map(str::to_string);
    let mut integrator = integrators::build(&settings, &mut Vec::new()).unwrap();
    integrator.setup(system).unwrap();
    integrator
}

fn mollified_overhead(c: &mut Criterion) {
    let mut group = c.benchmark_group("outer step/N=1000, K=10");
    group.sample_size(20);
    for (label, method, jacobian) in [
        ("impulse", "impulse", None),
        ("long-average adjoint", "long-average", Some("adjoint")),
        ("long-average forward", "long-average", Some("forward")),
    ] {
        let mut scene = chain(1000);
        let mut step = integrator(method, jacobian, &mut scene.system);
        if jacobian == Some("forward") {
            group.sample_size(10);
        }
        group.bench_function(label, |b| b.iter(|| step.step(&mut scene.system).unwrap()));
    }
    for (label, method) in [
        ("impulse, LJ slow", "impulse"),
        ("long-average adjoint, LJ slow", "long-average"),
    ] {
        let mut scene = chain_with(1000, "lennard-jones");
        let mut step = integrator(
            method,
            Some("adjoint").filter(|_| method != "impulse"),
            &mut scene.system,
        );
        group.sample_size(10);
        group.bench_function(label, |b| b.iter(|| step.step(&mut scene.system).unwrap()));
    }
    group.finish();
}

fn jacobian_scaling(c: &mut Criterion) {
    let mut group = c.benchmark_group("jacobian scaling/long-average outer step, K=10");
    group.sample_size(10);
    for n in [100, 1000, 10000] {
        let mut scene = chain(n);
        let mut step = integrator("long-average", Some("adjoint"), &mut scene.system);
        group.bench_with_input(BenchmarkId::new("adjoint", n), &n, |b, _| {
            b.iter(|| step.step(&mut scene.system).unwrap())
        });
    }
    // Forward mode stores four dense (3N)² blocks: 10000 beads would need 29 GB.
    for n in [100, 300, 1000] {
        let mut scene = chain(n);
        let mut step = integrator("long-average", Some("forward"), &mut scene.system);
        group.bench_with_input(BenchmarkId::new("forward", n), &n, |b, _| {
            b.iter(|| step.step(&mut scene.system).unwrap())
        });
    }
    group.finish();
}

criterion_group!(benches, mollified_overhead, jacobian_scaling);
criterion_main!(benches);
