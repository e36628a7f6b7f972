//! A run's other rayon workers kept looking for work between parallel loops.
//!
//! A step of a large system is some twenty parallel loops (the pair kernel and its
//! reduction, PME's splines, spreading, FFT lines and gathering, the Ewald exclusions, the
//! bonded terms, SETTLE) with short serial stretches between them. Rayon puts a worker that
//! finds no work to sleep after some thirty rounds of looking, and the next loop wakes it
//! through the kernel (a futex; on a virtual machine an interrupt to another virtual CPU):
//! a wake-up of tens of microseconds, as long as many of the loops themselves, so the
//! woken worker starts late or finds the loop done, and the calling thread does most of
//! each short loop alone. GROMACS's OpenMP threads spin between regions for the same reason.
//!
//! [`Spinners::start`] gives every other worker of the pool a job that looks for work
//! without sleeping (`rayon::yield_now`: take and run one job of the pool, stealing as an
//! idle worker does), yielding the processor to other processes between looks, until the
//! guard drops. After [`BACK_OFF_AFTER`] without work (output, a checkpoint) it looks only
//! every [`BACK_OFF_SLEEP`], so an idle stretch costs little processor time.
//!
//! Which thread runs which part of a loop never changes a result (every parallel loop of
//! the forces and constraints gives the same bits at any thread count), so neither does
//! this. Only a run that owns its pool may start spinners: a spinner occupies its worker
//! until the guard drops, so runs sharing one pool (a study's points) would wait on each
//! other's spinners.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// How long a spinner looks for work without pause after the last job it ran: longer than
/// any serial stretch inside a step (a few hundred microseconds on Trp-cage).
const BACK_OFF_AFTER: Duration = Duration::from_millis(2);

/// The pause between looks after [`BACK_OFF_AFTER`] without work.
const BACK_OFF_SLEEP: Duration = Duration::from_micros(200);

/// The spinners on the current pool's other workers; dropping it stops them.
pub struct Spinners {
    stop: Option<Arc<AtomicBool>>,
}

impl Spinners {
    /// Spinners on every worker of the current rayon pool but this one; none outside a pool
    /// or in a pool of one thread.
    pub fn start() -> Self {
        let Some(caller) = rayon::current_thread_index() else {
            return Spinners { stop: None };
        };
        if rayon::current_num_threads() < 2 {
            return Spinners { stop: None };
        }
        let stop = Arc::new(AtomicBool::new(false));
        let flag = Arc::clone(&stop);
        // The caller's own copy returns at once (it would spin on the thread that stops it).
        rayon::spawn_broadcast(move |context| {
            if context.index() != caller {
                spin(&flag);
            }
        });
        Spinners { stop: Some(stop) }
    }

    /// `work()` with spinners on the pool's other workers ([`Spinners::start`]).
    pub fn around<T>(work: impl FnOnce() -> T) -> T {
        let _spinners = Spinners::start();
        work()
    }
}

impl Drop for Spinners {
    fn drop(&mut self) {
        if let Some(stop) = &self.stop {
            stop.store(true, Ordering::Release);
        }
    }
}

/// Run the pool's jobs as they come until `stop`.
fn spin(stop: &AtomicBool) {
    let mut last_job = Instant::now();
    while !stop.load(Ordering::Acquire) {
        match rayon::yield_now() {
            Some(rayon::Yield::Executed) => last_job = Instant::now(),
            _ if last_job.elapsed() < BACK_OFF_AFTER => std::thread::yield_now(),
            _ => std::thread::sleep(BACK_OFF_SLEEP),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Spinners;
    use rayon::prelude::*;

    /// Work inside a two-thread pool with a spinner on the other worker: the spinner runs
    /// the loop's stolen halves (the result is the serial one) and the guard's drop ends
    /// it (the test returns). Outside a pool no spinner starts.
    #[test]
    fn a_parallel_loop_runs_beside_the_spinner_and_the_spinner_stops() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .expect("a pool of two threads");
        let squares = |n: u64| (0..n).into_par_iter().map(|k| k * k).sum::<u64>();
        let serial: u64 = (0..100_000u64).map(|k| k * k).sum();
        for _ in 0..3 {
            let sum = pool.install(|| Spinners::around(|| squares(100_000)));
            assert_eq!(sum, serial);
        }
        assert!(Spinners::start().stop.is_none());
    }
}
