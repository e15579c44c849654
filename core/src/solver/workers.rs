//! Worker threads for the contact solver's colour passes.
//!
//! A [`Workers`] holds `count − 1` helper threads, started once (when the
//! game sets the count) and parked between jobs, so a step allocates
//! nothing and starts no thread. [`Workers::run`] hands every worker,
//! the calling thread included as worker 0, the same job and returns when
//! all of them have finished it.
//!
//! Why the results never depend on the count: a job only ever splits work
//! whose pieces are independent (the constraints of one colour share no
//! moving body, so each one's result is the same whichever worker visits
//! it and in whatever order), and every colour ends at a [`SpinBarrier`]
//! before the next one starts. Nothing is summed across workers. The
//! worker count is not simulation state: it is in neither the state hash
//! nor snapshots, and tests step the same scenes with 1, 2, 3, 4 and 8
//! workers and compare every hash.
//!
//! Faults: the core's fault flags are per thread (`math::faults`). A
//! helper clears its flags before each job and hands what the job raised
//! to the pool, and [`Workers::run`] raises them on the calling thread
//! before it returns, so a fault on any worker is the step's fault, as if
//! one thread had done all the work.
//!
//! Waiting: a helper spins briefly for the next job (the solver posts one
//! per pass, microseconds apart within a step), then yields, then parks
//! until [`Workers::run`] unparks it. A barrier spins, then yields, so more
//! workers than cores still make progress.

use std::cell::UnsafeCell;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU8, AtomicU64, AtomicUsize, Ordering};

use crate::math::faults::{self, Faults};
use std::thread::JoinHandle;

/// The most workers a world takes.
pub const MAX_WORKERS: usize = 64;

/// Spins of a waiting thread before it starts yielding its core.
const SPINS: u32 = 1 << 12;
/// Yields of a waiting helper before it parks.
const YIELDS: u32 = 1 << 8;

/// A job: called once per worker with the worker's index (stored with its
/// lifetime erased; see [`Workers::run`]).
type Job = dyn Fn(usize) + Sync + 'static;

/// What the helpers share with the thread that posts jobs.
struct Shared {
    /// The current job: set before `epoch` is bumped, read by each helper
    /// once per epoch, and left alone until every helper counted itself
    /// `done`.
    job: UnsafeCell<Option<*const Job>>,
    /// Bumped once per posted job.
    epoch: AtomicU64,
    /// Helpers that finished the current job.
    done: AtomicUsize,
    /// The fault flags the helpers raised in the current job.
    faults: AtomicU8,
    /// Whether a helper's share of the current job panicked.
    panicked: AtomicBool,
    /// Set when the pool is dropped.
    stop: AtomicBool,
}

// SAFETY: `job` is written only by the posting thread while no helper reads
// it (before `epoch` is bumped with Release, after every helper counted
// itself done with Release), and read by helpers only between those points
// (after an Acquire load of the new epoch).
unsafe impl Sync for Shared {}
// SAFETY: as above; the raw job pointer is only dereferenced inside `run`.
unsafe impl Send for Shared {}

/// A fixed set of worker threads (see the module docs).
pub struct Workers {
    shared: Arc<Shared>,
    helpers: Vec<JoinHandle<()>>,
}

impl Default for Workers {
    /// One worker: the calling thread, no helper threads.
    fn default() -> Workers {
        Workers::new(1)
    }
}

impl Clone for Workers {
    /// A new pool of the same size (threads are not shared between worlds).
    fn clone(&self) -> Workers {
        Workers::new(self.count())
    }
}

impl std::fmt::Debug for Workers {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Workers")
            .field("count", &self.count())
            .finish()
    }
}

impl Workers {
    /// A pool of `count` workers (clamped to `1..=MAX_WORKERS`): the caller
    /// and `count − 1` helper threads.
    ///
    /// # Panics
    /// If the operating system refuses to start a thread.
    pub fn new(count: usize) -> Workers {
        let count = count.clamp(1, MAX_WORKERS);
        let shared = Arc::new(Shared {
            job: UnsafeCell::new(None),
            epoch: AtomicU64::new(0),
            done: AtomicUsize::new(0),
            faults: AtomicU8::new(0),
            panicked: AtomicBool::new(false),
            stop: AtomicBool::new(false),
        });
        let helpers = (1..count)
            .map(|index| {
                let shared = Arc::clone(&shared);
                std::thread::Builder::new()
                    .name(format!("lockstep-solver-{index}"))
                    .spawn(move || helper(&shared, index))
                    .expect("start a solver worker thread")
            })
            .collect();
        Workers { shared, helpers }
    }

    /// Workers, the calling thread included.
    pub fn count(&self) -> usize {
        self.helpers.len() + 1
    }

    /// Runs `job(i)` once on every worker `i` (0 on the calling thread) and
    /// returns when all have finished.
    pub(crate) fn run<'a>(&self, job: &'a (dyn Fn(usize) + Sync + 'a)) {
        if self.helpers.is_empty() {
            job(0);
            return;
        }
        // SAFETY: the pointer's lifetime is erased, but it is read only
        // until every helper has counted itself done below, and this
        // function does not return before that, so `job` outlives its use.
        let ptr: *const Job =
            unsafe { std::mem::transmute::<&'a (dyn Fn(usize) + Sync + 'a), &'static Job>(job) };
        // SAFETY: no helper reads `job` now: each finished the last job
        // (counted in `done`) and waits for a new epoch.
        unsafe { *self.shared.job.get() = Some(ptr) };
        self.shared.done.store(0, Ordering::Relaxed);
        self.shared.epoch.fetch_add(1, Ordering::Release);
        for h in &self.helpers {
            h.thread().unpark();
        }
        // Worker 0's panic is held until the helpers are done with the job
        // (which borrows this frame); barriers see the flag and give up.
        let mine = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| job(0)));
        if mine.is_err() {
            self.shared.panicked.store(true, Ordering::Relaxed);
        }
        let mut waited = 0u32;
        while self.shared.done.load(Ordering::Acquire) < self.helpers.len() {
            pause(&mut waited);
        }
        let raised = self.shared.faults.swap(0, Ordering::Relaxed);
        if raised != 0 {
            faults::raise(Faults::from_bits(raised));
        }
        let helper_panicked = self.shared.panicked.swap(false, Ordering::Relaxed);
        if let Err(payload) = mine {
            std::panic::resume_unwind(payload);
        }
        if helper_panicked {
            panic!("a solver worker thread panicked (its message is above)");
        }
    }
}

impl Drop for Workers {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::Release);
        for h in &self.helpers {
            h.thread().unpark();
        }
        for h in self.helpers.drain(..) {
            let _ = h.join();
        }
    }
}

/// A helper thread's loop: wait for a new epoch, run the job, count itself
/// done.
fn helper(shared: &Shared, index: usize) {
    let mut seen = 0u64;
    loop {
        let mut waited = 0u32;
        loop {
            let epoch = shared.epoch.load(Ordering::Acquire);
            if epoch != seen {
                seen = epoch;
                break;
            }
            if shared.stop.load(Ordering::Acquire) {
                return;
            }
            if waited >= SPINS + YIELDS {
                // `run` unparks after bumping the epoch, so a park that
                // races with it returns at once and the loop sees the job.
                std::thread::park();
            } else {
                pause(&mut waited);
            }
        }
        // SAFETY: see `Shared`: the epoch was loaded with Acquire after the
        // posting thread wrote the job.
        if let Some(job) = unsafe { *shared.job.get() } {
            faults::take();
            // A panic must not leave `run` waiting for this helper forever:
            // it is caught, counted done, and raised again on the caller.
            // SAFETY: `run` does not return (so the job lives) until this
            // helper counts itself done below.
            let ran =
                std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| unsafe { (*job)(index) }));
            if ran.is_err() {
                shared.panicked.store(true, Ordering::Relaxed);
            }
            let raised = faults::take().bits();
            if raised != 0 {
                shared.faults.fetch_or(raised, Ordering::Relaxed);
            }
        }
        shared.done.fetch_add(1, Ordering::Release);
    }
}

/// One wait step: spin a while, then yield the core.
fn pause(waited: &mut u32) {
    if *waited < SPINS {
        std::hint::spin_loop();
    } else {
        std::thread::yield_now();
    }
    *waited = waited.saturating_add(1);
}

/// A barrier for the workers of one job: every worker calls
/// [`wait`](SpinBarrier::wait) the same number of times, and none returns
/// from its `k`th call before all have made it. Its Acquire/Release pair
/// orders every write before the barrier before every read after it.
pub(crate) struct SpinBarrier<'a> {
    /// Set when a worker of the job panicked: a waiter would wait forever,
    /// so it panics too (and `Workers::run` reports the first).
    abandon: &'a AtomicBool,
    workers: usize,
    arrived: AtomicUsize,
    generation: AtomicUsize,
}

impl SpinBarrier<'_> {
    /// A barrier for every worker of `pool`.
    pub(crate) fn new(pool: &Workers) -> SpinBarrier<'_> {
        SpinBarrier {
            abandon: &pool.shared.panicked,
            workers: pool.count(),
            arrived: AtomicUsize::new(0),
            generation: AtomicUsize::new(0),
        }
    }

    pub(crate) fn wait(&self) {
        if self.workers <= 1 {
            return;
        }
        let generation = self.generation.load(Ordering::Acquire);
        if self.arrived.fetch_add(1, Ordering::AcqRel) + 1 == self.workers {
            self.arrived.store(0, Ordering::Relaxed);
            self.generation.fetch_add(1, Ordering::Release);
        } else {
            let mut waited = 0u32;
            while self.generation.load(Ordering::Acquire) == generation {
                if self.abandon.load(Ordering::Relaxed) {
                    panic!("another solver worker panicked");
                }
                pause(&mut waited);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_worker_runs_each_job_once_and_run_waits_for_all() {
        for count in [1, 2, 3, 4, 8] {
            let w = Workers::new(count);
            assert_eq!(w.count(), count);
            let hits: Vec<AtomicUsize> = (0..count).map(|_| AtomicUsize::new(0)).collect();
            for round in 1..=50 {
                w.run(&|i| {
                    hits[i].fetch_add(1, Ordering::Relaxed);
                });
                for (i, h) in hits.iter().enumerate() {
                    assert_eq!(h.load(Ordering::Relaxed), round, "worker {i} of {count}");
                }
            }
        }
    }

    #[test]
    fn a_fault_raised_on_a_helper_is_raised_on_the_calling_thread() {
        for count in [2, 3, 8] {
            let w = Workers::new(count);
            faults::take();
            w.run(&|i| {
                if i == count - 1 {
                    faults::raise(Faults::OVERFLOW);
                }
            });
            assert!(faults::take().contains(Faults::OVERFLOW), "{count} workers");
            // Nothing carries over into the next job.
            w.run(&|_| {});
            assert!(faults::take().is_empty(), "{count} workers");
        }
    }

    #[test]
    fn a_panic_on_a_helper_reaches_the_caller_and_the_pool_still_works() {
        let w = Workers::new(2);
        let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            w.run(&|i| {
                if i == 1 {
                    panic!("worker 1 fails on purpose");
                }
            });
        }));
        assert!(caught.is_err(), "the helper's panic reaches run's caller");
        let hits = AtomicUsize::new(0);
        w.run(&|_| {
            hits.fetch_add(1, Ordering::Relaxed);
        });
        assert_eq!(hits.load(Ordering::Relaxed), 2);
    }

    #[test]
    fn a_panic_before_a_barrier_does_not_leave_the_others_waiting() {
        for (count, failing) in [(2, 0), (2, 1), (4, 2)] {
            let w = Workers::new(count);
            let barrier = SpinBarrier::new(&w);
            let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                w.run(&|i| {
                    if i == failing {
                        panic!("worker {i} fails on purpose");
                    }
                    barrier.wait();
                });
            }));
            assert!(caught.is_err(), "{count} workers, worker {failing} failing");
            let hits = AtomicUsize::new(0);
            w.run(&|_| {
                hits.fetch_add(1, Ordering::Relaxed);
            });
            assert_eq!(hits.load(Ordering::Relaxed), count);
        }
    }

    #[test]
    fn the_barrier_holds_every_worker_until_all_arrive() {
        for count in [2, 3, 4, 8] {
            let w = Workers::new(count);
            let barrier = SpinBarrier::new(&w);
            let phase = AtomicUsize::new(0);
            let late = AtomicBool::new(false);
            w.run(&|_| {
                for k in 0..20 {
                    phase.fetch_add(1, Ordering::AcqRel);
                    barrier.wait();
                    // Everyone has added its k-th increment before anyone
                    // passes the k-th barrier.
                    if phase.load(Ordering::Acquire) < (k + 1) * count {
                        late.store(true, Ordering::Relaxed);
                    }
                    barrier.wait();
                }
            });
            assert!(!late.load(Ordering::Relaxed), "{count} workers");
            assert_eq!(phase.load(Ordering::Relaxed), 20 * count);
        }
    }

    #[test]
    fn a_pool_idle_past_its_spin_wakes_for_the_next_job() {
        let w = Workers::new(2);
        let hits = AtomicUsize::new(0);
        w.run(&|_| {
            hits.fetch_add(1, Ordering::Relaxed);
        });
        // Long enough for the helper to stop spinning and park.
        std::thread::sleep(std::time::Duration::from_millis(50));
        w.run(&|_| {
            hits.fetch_add(1, Ordering::Relaxed);
        });
        assert_eq!(hits.load(Ordering::Relaxed), 4);
    }
}
