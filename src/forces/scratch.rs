//! Bonded gradients of large systems in two phases: the per-interaction work (distances,
//! angles, `atan2`) in parallel into a reused buffer, then the additions to the gradient on
//! the calling thread in interaction order — the same operations in the same order as the
//! serial loop, so the same bits at any thread count, and the same bits as below the
//! threshold.

use std::sync::{Mutex, MutexGuard};

use rayon::prelude::*;

/// From this many interactions on, a bonded gradient runs its first phase in parallel (the
/// 5 184-atom water box has 3 456 bonds and 1 728 angles; below, rayon's start costs more
/// than the work).
pub const PARALLEL_MIN_INTERACTIONS: usize = 1024;

/// From this many dihedrals on, a dihedral term's gradient runs its first phase in
/// parallel: a dihedral costs about 1 000 instructions (two cross products, an `atan2`, a
/// sine per cosine; callgrind on Trp-cage, 0.91 M for its 896 dihedrals), so a task of
/// 256 is some 250 000 instructions, far more than rayon's start.
pub const PARALLEL_MIN_DIHEDRALS: usize = 256;

/// Interactions per parallel task.
const TASK: usize = 256;

/// The first phase's results, one per interaction; grown on the first call, then reused.
#[derive(Default)]
pub struct Scratch<T>(Mutex<Vec<T>>);

impl<T: Copy + Default> Clone for Scratch<T> {
    /// A buffer of the same length (its contents are overwritten before they are read).
    fn clone(&self) -> Self {
        let len = self.0.lock().map_or(0, |b| b.len());
        Scratch(Mutex::new(vec![T::default(); len]))
    }
}

impl<T> std::fmt::Debug for Scratch<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Scratch")
    }
}

/// Whether a term of `n` interactions takes the two phases: from the threshold on, on a
/// worker of a rayon pool with more than one thread (outside a pool, rayon's hand-over of
/// the work to its global pool allocates now and then: runs step inside a pool).
pub fn parallel(n: usize) -> bool {
    parallel_from(n, PARALLEL_MIN_INTERACTIONS)
}

/// [`parallel`] with the threshold `min` (a term whose interactions cost more than a bond's).
pub fn parallel_from(n: usize, min: usize) -> bool {
    n >= min && rayon::current_thread_index().is_some() && rayon::current_num_threads() > 1
}

impl<T: Copy + Default + Send> Scratch<T> {
    /// A buffer for `n` interactions, sized now so that no step allocates.
    pub fn with_len(n: usize) -> Self {
        Self::with_len_from(n, PARALLEL_MIN_INTERACTIONS)
    }

    /// A buffer for `n` interactions of a term that takes the two phases from `min` on.
    pub fn with_len_from(n: usize, min: usize) -> Self {
        let len = if n >= min { n } else { 0 };
        Scratch(Mutex::new(vec![T::default(); len]))
    }

    /// `compute(k)` for every interaction `k < n` in parallel, then `apply(k, result)` for
    /// each in order on this thread.
    pub fn two_phase(
        &self,
        n: usize,
        compute: impl Fn(usize) -> T + Sync,
        apply: impl FnMut(usize, &T),
    ) {
        let compute = |first: usize, slots: &mut [T]| {
            for (k, slot) in slots.iter_mut().enumerate() {
                *slot = compute(first + k);
            }
        };
        self.two_phase_chunks(n, compute, apply);
    }

    /// As [`Self::two_phase`], with `compute(first, slots)` filling the results of the
    /// interactions `first … first + slots.len()` (a task's, for work done in batches).
    pub fn two_phase_chunks(
        &self,
        n: usize,
        compute: impl Fn(usize, &mut [T]) + Sync,
        mut apply: impl FnMut(usize, &T),
    ) {
        let buffer = self.computed(n, compute);
        for (k, result) in buffer[..n].iter().enumerate() {
            apply(k, result);
        }
    }

    /// The first phase alone: `compute(first, slots)` in parallel tasks of [`TASK`]
    /// interactions (whatever the thread count), and the buffer, held locked, whose first
    /// `n` entries are the results, for the caller to apply in order (when what it applies
    /// to is also what the first phase reads).
    pub fn computed(
        &self,
        n: usize,
        compute: impl Fn(usize, &mut [T]) + Sync,
    ) -> MutexGuard<'_, Vec<T>> {
        // A panic elsewhere while the lock was held leaves a buffer that is overwritten anyway.
        let mut buffer = self.0.lock().unwrap_or_else(|e| e.into_inner());
        if buffer.len() < n {
            buffer.resize(n, T::default());
        }
        buffer[..n]
            .par_chunks_mut(TASK)
            .enumerate()
            .for_each(|(task, slots)| compute(task * TASK, slots));
        buffer
    }
}
