//! A step of a molecule scene allocates nothing, on any thread: the neighbour list, the
//! per-chunk gradient buffers and the mollifier's buffers are sized before the run, and
//! rayon's per-chunk work inside a thread pool uses the workers' own deques. A global
//! counter (this file holds one test, so nothing else runs meanwhile) counts allocations on
//! every thread, rayon's workers included. Steps run inside `ThreadPool::install`, as
//! `longstep run` does.

use std::path::Path;

#[path = "common/counting.rs"]
mod counting;

#[global_allocator]
static GLOBAL: counting::Counting = counting::Counting;

#[test]
fn molecule_steps_allocate_nothing() {
    let pool = counting::checked_pool(2);
    let molly = "equilibrium-molly";
    use longstep::forces::Precision::{Double, Mixed};
    for (scene, method, h, inner, molly_settings, precision) in [
        (
            "systems/water-box/scene.toml",
            "impulse",
            2.0,
            4,
            None,
            Double,
        ),
        (
            "systems/water-box/pme.toml",
            "impulse",
            2.0,
            4,
            None,
            Double,
        ),
        (
            "systems/water-box/scene.toml",
            "impulse",
            2.0,
            4,
            None,
            Mixed,
        ),
        (
            "systems/water-box/scene.toml",
            "long-average",
            4.0,
            8,
            None,
            Double,
        ),
        // Three levels with the distance split: its own pair list and gradient cache.
        (
            "systems/water-box/three-level.toml",
            "impulse",
            4.0,
            2,
            None,
            Double,
        ),
        (
            "systems/molecules/alanine-dipeptide.toml",
            "impulse",
            2.0,
            4,
            None,
            Double,
        ),
        // The equilibrium mollifier: a Schur solve per water, a banded KKT solve per chain.
        (
            "systems/water-box/scene.toml",
            molly,
            4.0,
            8,
            Some(("bonds-angles", "exact")),
            Double,
        ),
        (
            "systems/water-box/scene.toml",
            molly,
            4.0,
            8,
            Some(("bonds", "projection")),
            Double,
        ),
        (
            "systems/polymer-melt/scene.toml",
            molly,
            21.5,
            2,
            Some(("bonds", "exact")),
            Double,
        ),
    ] {
        let scene_path = scene;
        pool.install(|| {
            let mut scene = longstep::io::scene::load_scene(Path::new(scene_path), &[]).unwrap();
            scene.system.forces.set_precision(precision);
            let mut settings =
                longstep::settings::MethodSettings::new(method, h).with_inner_steps(inner);
            if let Some((constraints, jacobian)) = molly_settings {
                settings.molly_constraints = Some(constraints.into());
                settings.molly_jacobian = Some(jacobian.into());
            }
            let mut integrator = longstep::integrators::build(&settings, &mut Vec::new()).unwrap();
            integrator.setup(&mut scene.system).unwrap();
            // Warm up past the first list rebuilds (their buffers keep 25 % room).
            for _ in 0..40 {
                integrator.step(&mut scene.system).unwrap();
            }
            let listed = |scene: &longstep::io::scene::Scene| -> usize {
                scene
                    .system
                    .forces
                    .terms()
                    .iter()
                    .find(|t| t.name == "nonbonded")
                    .map_or(0, |t| t.term.interaction_count())
            };
            let pairs_before = listed(&scene);
            let before = counting::allocations();
            for _ in 0..40 {
                integrator.step(&mut scene.system).unwrap();
            }
            let during = counting::allocations() - before;
            assert_eq!(
                during, 0,
                "{scene_path} {method} {precision:?}: {during} allocations in 40 steps"
            );
            if scene.name == "polymer-melt" {
                // The list was rebuilt meanwhile (its pair count changed): rebuilds allocate
                // nothing either.
                assert_ne!(listed(&scene), pairs_before, "no list rebuild in 40 steps");
            }
        });
    }
}
