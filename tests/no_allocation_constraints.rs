//! A constrained step allocates nothing: SETTLE works on the stack, SHAKE/RATTLE use the
//! buffer of old bond vectors sized when the constraints are built, and the constrained
//! innermost step sizes its copy of the positions in `setup`, as the constrained averaging
//! of the mollified methods sizes its records (and its constraint clusters' scratch)
//! there. A global counter (this file
//! holds one test, so nothing else runs meanwhile) counts allocations on every thread.

use std::path::Path;

use longstep::run::prepare::{RunRequest, prepare};
use longstep::settings::{RunSpec, Value};

#[path = "common/counting.rs"]
mod counting;

#[global_allocator]
static GLOBAL: counting::Counting = counting::Counting;

#[test]
fn constrained_steps_allocate_nothing() {
    let pool = counting::checked_pool(2);
    let cases = [
        ("systems/water-box/scene.toml", "verlet", "none", true),
        (
            "systems/water-box/scene.toml",
            "langevin-respa",
            "none",
            true,
        ),
        (
            "systems/molecules/alanine-dipeptide.toml",
            "impulse",
            "all-bonds",
            false,
        ),
        (
            "systems/molecules/alanine-dipeptide.toml",
            "long-average",
            "h-bonds",
            false,
        ),
        (
            "systems/water-box/scene.toml",
            "linear-average",
            "none",
            true,
        ),
    ];
    for (scene, method, set, rigid_water) in cases {
        let overrides = RunSpec {
            method: Some(method.into()),
            h: Some(Value::Expression("2fs".into())),
            inner_steps: Some(2),
            constraints: Some(set.into()),
            rigid_water: Some(rigid_water),
            temperature: Some(Value::Expression("300K".into())),
            ..Default::default()
        };
        pool.install(|| {
            let mut run = prepare(&RunRequest::new(Path::new(scene), &[], &overrides)).unwrap();
            let system = &mut run.scene.system;
            run.integrator.setup(system).unwrap();
            let during = counting::allocations_in_steps(run.integrator.as_mut(), system, 40, 40);
            assert_eq!(
                during, 0,
                "{scene} {method}: {during} allocations in 40 steps"
            );
        });
    }
}
