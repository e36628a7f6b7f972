//! A step allocates nothing: integrators size their buffers in `setup`, force kernels write
//! into the buffers they are given. A counting global allocator checks it for every method
//! of the family, with both Jacobian modes of the mollified methods.

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

struct Counting;

thread_local! {
    // Per thread, so tests running in parallel do not count each other.
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.with(|c| c.set(c.get() + 1));
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.with(|c| c.set(c.get() + 1));
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocations() -> usize {
    ALLOCATIONS.with(|c| c.get())
}

/// Allocations made by five steps of the integrator `settings` builds, after its setup and
/// a first step (which may size its buffers).
fn allocations_in_five_steps(
    settings: &longstep::settings::MethodSettings,
    system: &mut longstep::system::System,
) -> usize {
    let mut integrator = longstep::integrators::build(settings, &mut Vec::new()).unwrap();
    integrator.setup(system).unwrap();
    integrator.step(system).unwrap();
    let before = allocations();
    for _ in 0..5 {
        integrator.step(system).unwrap();
    }
    allocations() - before
}

#[test]
fn steps_allocate_nothing() {
    // The counter sees allocations at all.
    let before = allocations();
    let probe = std::hint::black_box(vec![1.0f64; 16]);
    assert!(allocations() > before && probe.len() == 16);
    let chain = "systems/chain/scene.toml";
    let mut cases: Vec<(String, Option<&str>)> = vec![("verlet".into(), None)];
    for name in common::MTS_METHODS {
        cases.push((name.into(), None));
    }
    for name in ["short-average", "long-average", "linear-average"] {
        cases.push((name.into(), Some("forward")));
        cases.push((name.into(), Some("adjoint")));
    }
    for jacobian in ["exact", "projection"] {
        cases.push(("equilibrium-molly".into(), Some(jacobian)));
    }
    for (name, jacobian) in cases {
        let mut scene = common::scene_file(chain, &[]);
        let mut settings = longstep::settings::MethodSettings::new(&name, 0.02);
        if name != "verlet" {
            settings.inner_steps = Some(4);
        }
        if name == "equilibrium-molly" {
            settings.molly_jacobian = jacobian.map(str::to_string);
        } else {
            settings.jacobian = jacobian.map(str::to_string);
        }
        let during = allocations_in_five_steps(&settings, &mut scene.system);
        assert_eq!(
            during, 0,
            "{name} ({jacobian:?}): {during} allocations in 5 steps"
        );
    }
}

#[test]
fn thermostatted_steps_allocate_nothing() {
    // The O step, SIN(R)'s operators and watches, with a mollified slow force too.
    let chain = "systems/chain/scene.toml";
    for name in ["langevin-respa", "sinr"] {
        for mollifier in [None, Some("long-average")] {
            let mut scene = common::scene_file(chain, &[]);
            let mut settings = longstep::settings::MethodSettings::new(name, 0.02);
            settings.inner_steps = Some(4);
            settings.temperature = Some(0.5);
            settings.friction = Some(1.0);
            settings.tau = Some(0.2);
            settings.mollifier = mollifier.map(str::to_string);
            let during = allocations_in_five_steps(&settings, &mut scene.system);
            assert_eq!(
                during, 0,
                "{name} ({mollifier:?}): {during} allocations in 5 steps"
            );
        }
    }
}

#[test]
fn pseudo_energy_steps_allocate_nothing() {
    // The synchronous scheme and the asynchronous one on a scene with slow particles (its
    // fine steps, coarse step and monitor), for a rule with end nodes and one without.
    for rule in ["gl5", "gauss3"] {
        for name in ["pseudo-energy", "async-pseudo-energy"] {
            let mut scene = common::scene_file("systems/fpu-slow-fast.toml", &[]);
            let mut settings = longstep::settings::MethodSettings::new(name, 0.01);
            settings.quadrature = Some(rule.into());
            if name == "async-pseudo-energy" {
                settings.ratio = Some(10);
            }
            let during = allocations_in_five_steps(&settings, &mut scene.system);
            assert_eq!(
                during, 0,
                "{name} ({rule}): {during} allocations in 5 steps"
            );
        }
    }
}
