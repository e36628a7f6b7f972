//! Where a molecule run's time goes, in process CPU time (robust against other jobs on a
//! shared machine, unlike wall time): the numbers behind docs/performance.md's profile.
//!
//!     cargo run --release --example nonbonded_profile -- run SCENE [steps] [h fs] [inner]
//!         [outer buffer Å] [inner buffer Å] [double|mixed]
//!     cargo run --release --example nonbonded_profile -- parts SCENE [repeats] [kernel|build|bonded]
//!
//! `run`: r-RESPA impulse steps and the cluster list's counters (builds, prunes, pairs).
//! `parts`: CPU time per non-bonded evaluation on a valid list for every instruction set
//! and precision, per list build (search and pruning), and per bonded gradient.

use std::path::Path;
use std::time::Instant;

use longstep::forces::nonbonded::Nonbonded;
use longstep::forces::simd::Isa;
use longstep::forces::{ForceTerm, Precision};
use longstep::integrators;
use longstep::io::scene::{Scene, load_scene};
use longstep::settings::MethodSettings;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mode = args.first().map_or("run", |s| s.as_str());
    let scene = args
        .get(1)
        .map_or("systems/water-box/scene.toml", |s| s.as_str());
    let number = |k: usize, default: f64| {
        args.get(k)
            .map_or(default, |s| s.parse().expect("a number"))
    };
    match mode {
        "run" => run(
            scene,
            &args,
            number(2, 100.0) as usize,
            number(3, 4.0),
            number(4, 8.0) as usize,
        ),
        "parts" => parts(
            scene,
            number(2, 20.0) as usize,
            args.get(3).map(String::as_str),
        ),
        other => panic!("unknown mode {other}: run or parts"),
    }
}

fn run(path: &str, args: &[String], steps: usize, h: f64, inner: usize) {
    let mut scene = load_scene(Path::new(path), &[]).expect("scene");
    let term = nonbonded(&scene);
    if let Some(outer) = args.get(5) {
        let outer: f64 = outer.parse().expect("a number");
        let inner_buffer = args
            .get(6)
            .map_or(outer / 2.0, |s| s.parse().expect("a number"));
        term.set_list_buffers(outer, inner_buffer);
    }
    if args.get(7).map(String::as_str) == Some("mixed") {
        term.set_precision(Precision::Mixed);
    }
    let settings = MethodSettings::new("impulse", h).with_inner_steps(inner);
    let mut integrator = integrators::build(&settings, &mut Vec::new()).expect("method");
    integrator.setup(&mut scene.system).expect("setup");
    let start = Instant::now();
    let cpu_start = cpu_seconds();
    for _ in 0..steps {
        integrator.step(&mut scene.system).expect("step");
    }
    let cpu = cpu_seconds() - cpu_start;
    let wall = start.elapsed().as_secs_f64();
    let counts = nonbonded(&scene).list_counts();
    let atoms = scene.system.n_particles();
    println!(
        "{path}: {atoms} atoms, {steps} outer steps of {h} fs / {inner}: {:.1} steps/s CPU \
         time ({:.1} wall), {:.3} us CPU per atom and step; builds {}, prunes {}, clusters {}, \
         outer pairs {:.0}/atom, inner pairs {:.0}/atom",
        steps as f64 / cpu,
        steps as f64 / wall,
        1e6 * cpu / (steps * atoms) as f64,
        counts.builds,
        counts.prunes,
        counts.clusters,
        counts.outer_pairs as f64 / atoms as f64,
        counts.inner_pairs as f64 / atoms as f64,
    );
}

fn parts(path: &str, repeats: usize, only: Option<&str>) {
    let wanted = |what: &str| only.is_none_or(|o| o == what);
    let mut scene = load_scene(Path::new(path), &[]).expect("scene");
    let q = scene.system.state.q.clone();
    let mut gradient = vec![0.0; q.len()];
    let time = |f: &mut dyn FnMut()| {
        f();
        let start = cpu_seconds();
        for _ in 0..repeats {
            f();
        }
        1e3 * (cpu_seconds() - start) / repeats as f64
    };
    let term = nonbonded(&scene);
    let pairs = term.list_counts().inner_pairs as f64;
    for isa in Isa::available().into_iter().filter(|_| wanted("kernel")) {
        for precision in [Precision::Double, Precision::Mixed] {
            term.set_isa(isa);
            term.set_precision(precision);
            let ms = time(&mut || term.add_gradient(&q, &mut gradient));
            println!(
                "{path}: nonbonded gradient {:>8} {:>6}: {ms:8.3} ms CPU ({:.2} ns per listed pair)",
                isa.name(),
                precision.name(),
                1e6 * ms / pairs
            );
        }
    }
    term.set_isa(Isa::best());
    term.set_precision(Precision::Double);
    let (outer, inner) = term.list_buffers();
    if wanted("build") {
        let ms = time(&mut || {
            term.set_list_buffers(outer, inner);
            term.add_gradient(&q, &mut gradient)
        });
        println!("{path}: list build, pruning and one gradient: {ms:8.3} ms CPU");
    }
    if wanted("bonded") {
        let forces = &mut scene.system.forces;
        let ms = time(&mut || forces.gradient(0, &q, &mut gradient));
        println!("{path}: bonded gradient: {ms:8.3} ms CPU");
    }
}

fn nonbonded(scene: &Scene) -> &Nonbonded {
    scene
        .system
        .forces
        .find::<Nonbonded>()
        .expect("a non-bonded term")
}

/// CPU time of the process (all threads), seconds.
fn cpu_seconds() -> f64 {
    let mut t = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: a valid pointer to a timespec.
    unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut t) };
    t.tv_sec as f64 + 1e-9 * t.tv_nsec as f64
}
