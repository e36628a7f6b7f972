//! Per-level cost of the distance split (`[forcefield.split]`): the gradient of each level
//! of the three-level water scenes — bonded (level 0), short-range non-bonded (level 1),
//! remainder (level 2) — beside the unsplit non-bonded term of the same model, on the
//! 216-water box (9 Å) and the 1728-water long-cutoff box (12 Å). The remainder is timed as
//! r-RESPA pays for it, with the short part at the same positions (whose gradient it reuses
//! from the cache): "levels 1 + 2" less "level 1" is the remainder's cost, about one full
//! non-bonded evaluation. Each iteration moves to other positions (the cache would serve a
//! repeat). Lists are built before timing.
//! Run with `cargo bench --bench distance_split`; `RAYON_NUM_THREADS` sets the threads.

use std::path::Path;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use longstep::io::scene::load_scene;

/// Scene pairs: (label, unsplit two-level scene, three-level split scene).
const SCENES: [(&str, &str, &str); 2] = [
    (
        "water216 9 Å",
        "systems/water-box/scene.toml",
        "systems/water-box/three-level.toml",
    ),
    (
        "water1728 12 Å",
        "systems/water-box/long-cutoff.toml",
        "systems/water-box/long-cutoff-three-level.toml",
    ),
];

/// The scene's start positions and a copy moved by 1e-7 in one coordinate: alternating
/// between them defeats the short part's gradient cache (which serves repeated positions)
/// without rebuilding a list.
fn two_positions(q: &[f64]) -> [Vec<f64>; 2] {
    let mut moved = q.to_vec();
    moved[0] += 1e-7;
    [q.to_vec(), moved]
}

fn levels(c: &mut Criterion) {
    for (label, unsplit, split) in SCENES {
        let mut scene = load_scene(Path::new(unsplit), &[]).unwrap();
        let system = &mut scene.system;
        let qs = two_positions(&system.state.q);
        let mut gradient = vec![0.0; qs[0].len()];
        system.forces.gradient(1, &qs[0], &mut gradient);
        let mut k = 0;
        c.bench_function(&format!("{label}/unsplit non-bonded gradient"), |b| {
            b.iter(|| {
                k ^= 1;
                system.forces.gradient(1, &qs[k], &mut gradient)
            })
        });
        let mut scene = load_scene(Path::new(split), &[]).unwrap();
        let system = &mut scene.system;
        for level in [0, 1, 2] {
            system.forces.gradient(level, &qs[0], &mut gradient);
        }
        for (name, levels) in [
            ("level 0 bonded", &[0][..]),
            ("level 1 short-range", &[1][..]),
            ("levels 1 + 2 short-range and remainder", &[1, 2][..]),
        ] {
            c.bench_function(&format!("{label}/{name} gradient"), |b| {
                b.iter(|| {
                    k ^= 1;
                    for &level in levels {
                        system.forces.gradient(level, &qs[k], &mut gradient);
                    }
                })
            });
        }
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .measurement_time(Duration::from_secs(3))
        .warm_up_time(Duration::from_secs(1))
        .sample_size(10);
    targets = levels
}
criterion_main!(benches);
