//! Bonded gradients of large systems in two phases: the per-interaction work (distances,
//! angles, `atan2`) in parallel into a reused buffer, then the additions to the gradient on
//! the calling thread in interaction order — the same operations in the same order as the
//! serial loop, so the same bits at any thread count, and the same bits as below the
//! threshold.

use std::sync::Mutex;

use rayon::prelude::*;

/// From this many interactions on, a bonded gradient runs its first phase in parallel (the
/// 5 184-atom water box has 3 456 bonds and 1 728 angles; below, rayon's start costs more
/// than the work).
pub const PARALLEL_MIN_INTERACTIONS: usize = 1024;

/// Interactions per parallel task.
const TASK: usize = 256;

/// The first phase's results, one per interaction; grown on the first call, then reused.
#[derive(Default)]
pub struct Scratch<T>(Mutex<Vec<T>>);

impl<T> Clone for Scratch<T> {
    /// An empty buffer: a copy of a term grows its own.
    fn clone(&self) -> Self {
        Scratch(Mutex::new(Vec::new()))
    }
}

impl<T> std::fmt::Debug for Scratch<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Scratch")
    }
}

impl<T: Copy + Default + Send> Scratch<T> {
    /// `compute(k)` for every interaction `k < n` in parallel, then `apply(k, result)` for
    /// each in order on this thread.
    pub fn two_phase(
        &self,
        n: usize,
        compute: impl Fn(usize) -> T + Sync,
        mut apply: impl FnMut(usize, &T),
    ) {
        // A panic elsewhere while the lock was held leaves a buffer that is overwritten anyway.
        let mut buffer = self.0.lock().unwrap_or_else(|e| e.into_inner());
        if buffer.len() < n {
            buffer.resize(n, T::default());
        }
        buffer[..n]
            .par_chunks_mut(TASK)
            .enumerate()
            .for_each(|(task, slots)| {
                for (k, slot) in slots.iter_mut().enumerate() {
                    *slot = compute(task * TASK + k);
                }
            });
        for (k, result) in buffer[..n].iter().enumerate() {
            apply(k, result);
        }
    }
}
