//! A global allocator that counts every allocation and reallocation on every thread,
//! rayon's workers included, for the no-allocation tests. A test binary that installs it
//! holds one test, so nothing else allocates while it counts:
//!
//! ```ignore
//! #[path = "common/counting.rs"]
//! mod counting;
//! #[global_allocator]
//! static GLOBAL: counting::Counting = counting::Counting;
//! ```
// Not every test that installs the counter uses every helper.
#![allow(dead_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

pub struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

/// Allocations so far, on every thread.
pub fn allocations() -> usize {
    ALLOCATIONS.load(Ordering::Relaxed)
}

/// Checks that the counter sees an allocation (so that a count of zero means something) and
/// returns a rayon pool of `threads` workers for the steps to run in.
pub fn checked_pool(threads: usize) -> rayon::ThreadPool {
    let before = allocations();
    let probe = std::hint::black_box(vec![1.0f64; 16]);
    assert!(allocations() > before && probe.len() == 16);
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
}

/// Takes `warm_up` steps of `integrator` on `system` (past the first neighbour-list
/// rebuilds), then returns the allocations, on every thread, of `counted` more.
pub fn allocations_in_steps(
    integrator: &mut dyn longstep::integrators::Integrator,
    system: &mut longstep::system::System,
    warm_up: usize,
    counted: usize,
) -> usize {
    for _ in 0..warm_up {
        integrator.step(system).unwrap();
    }
    let before = allocations();
    for _ in 0..counted {
        integrator.step(system).unwrap();
    }
    allocations() - before
}
