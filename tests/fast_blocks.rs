//! Impulse's inner loop block by block (`split::Blocks`): with more than one thread the fast
//! level of a box of molecules runs per block of whole molecules in parallel, and must give
//! the bits of the serial inner loop.

mod common;

use std::path::Path;

use longstep::integrators::Integrator;
use longstep::integrators::impulse::{Impulse, Variant};
use longstep::io::scene::load_scene;
use longstep::settings::MethodSettings;

fn bits(x: &[f64]) -> Vec<u64> {
    x.iter().map(|v| v.to_bits()).collect()
}

/// (q, p) after `steps` impulse steps on `threads` threads, and the number of blocks.
fn run(scene: &str, h: f64, inner: usize, steps: usize, threads: usize) -> (Vec<u64>, usize) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let mut scene = load_scene(Path::new(scene), &[]).unwrap();
        let mut settings = MethodSettings::new("impulse", h);
        settings.inner_steps = Some(inner);
        let mut impulse = Impulse::new(&settings, Variant::Endpoint, None).unwrap();
        impulse.setup(&mut scene.system).unwrap();
        let blocks = impulse.fast_blocks().map_or(0, |b| b.len());
        for _ in 0..steps {
            impulse.step(&mut scene.system).unwrap();
        }
        let counts = scene.system.forces.counts().gradient.clone();
        assert_eq!(
            counts[0],
            (1 + steps * inner) as u64,
            "fast gradients counted"
        );
        let state = &scene.system.state;
        ([bits(&state.q), bits(&state.p)].concat(), blocks)
    })
}

#[test]
fn blocks_of_molecules_give_the_serial_bits() {
    // Waters (3 atoms each, bonds and angles) and chains of 50 beads (bonds and angles).
    for (scene, h, inner) in [
        ("systems/water-box/scene.toml", 4.0, 8),
        ("systems/polymer-melt/scene.toml", 21.562, 2),
    ] {
        let (serial, none) = run(scene, h, inner, 5, 1);
        assert_eq!(none, 0, "{scene}: one thread runs the serial loop");
        for threads in [2, 3] {
            let (parallel, blocks) = run(scene, h, inner, 5, threads);
            assert_eq!(blocks, threads, "{scene}: blocks at {threads} threads");
            assert!(parallel == serial, "{scene}: {threads} threads differ");
        }
    }
}
