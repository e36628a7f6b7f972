//! A PME step above the parallel threshold allocates nothing on any thread: the 5 184-atom
//! water box with the reciprocal sum on its own level (GROMACS's `mts-level2-forces =
//! longrange-nonbonded`), on two threads, so that the splines, spreading slabs, the FFT's
//! line passes, the gathering and the excluded pairs' two phases all run over rayon. A
//! global counter (this file holds one test, so nothing else runs meanwhile) counts
//! allocations on every thread, rayon's workers included. In double precision, then in
//! mixed (the f32 mesh).

use std::path::Path;

use longstep::forces::Precision;
use longstep::io::forcefield::ElectrostaticsOverrides;
use longstep::io::scene::SceneFlags;

#[path = "common/counting.rs"]
mod counting;

#[global_allocator]
static GLOBAL: counting::Counting = counting::Counting;

#[test]
fn parallel_pme_steps_allocate_nothing() {
    let pool = counting::checked_pool(2);
    let flags = SceneFlags {
        electrostatics: ElectrostaticsOverrides {
            coulomb: Some("pme".into()),
            pme_order: Some(4),
            nonbonded_level: Some(0),
            pme_level: Some(1),
            ..ElectrostaticsOverrides::default()
        },
        ..SceneFlags::default()
    };
    let path = Path::new("systems/water-box-1728/scene.toml");
    pool.install(|| {
        let mut scene = longstep::io::scene::load_scene_with(path, &flags, &[]).unwrap();
        let settings = longstep::settings::MethodSettings::new("impulse", 1.0).with_inner_steps(2);
        let mut integrator = longstep::integrators::build(&settings, &mut Vec::new()).unwrap();
        integrator.setup(&mut scene.system).unwrap();
        // Steps allocated in after a warm-up past the first list rebuilds (their buffers keep
        // 25 % room).
        let mut allocations_in_steps = |system: &mut longstep::system::System| {
            counting::allocations_in_steps(integrator.as_mut(), system, 10, 10)
        };
        let during = allocations_in_steps(&mut scene.system);
        assert_eq!(
            during, 0,
            "{during} allocations in 10 PME steps on two threads"
        );
        // Mixed precision: the f32 mesh (and the f32 real-space kernel) is built when the
        // precision changes, and its steps allocate nothing either.
        assert!(scene.system.forces.set_precision(Precision::Mixed) >= 2);
        let during = allocations_in_steps(&mut scene.system);
        assert_eq!(
            during, 0,
            "{during} allocations in 10 mixed-precision PME steps on two threads"
        );
    });
}
