//! Worker threads for a world's step: the contact solver's colour passes,
//! and in either contact order the narrow phase (per block of pairs), the
//! integrators (per block of awake bodies), the solver's gathers and
//! scatters (per block of solver bodies) and `prepare`'s constant terms
//! (per block of constraints).
//!
//! A [`Workers`] holds `count − 1` helper threads, started once (when the
//! game sets the count) and parked between jobs, so a step allocates
//! nothing and starts no thread. [`Workers::run`] hands every worker,
//! the calling thread included as worker 0, the same job and returns when
//! all of them have finished it.
//!
//! Why the results never depend on the count: a job only ever splits work
//! whose pieces are independent (a pair's test writes that pair alone, a
//! body's integration that body alone; the constraints of one colour share
//! no moving body, so each one's result is the same whichever worker visits
//! it and in whatever order), and every colour ends at a [`SpinBarrier`]
//! before the next one starts. Nothing is summed across workers but
//! integer counters (exact in any order); whatever must be in order (the
//! contact events) is put in order on the calling thread afterwards. The
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
use std::marker::PhantomData;
use std::ops::Range;
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

impl Workers {
    /// Calls `visit` on blocks that cover `0..len` once: `block` items
    /// each (the last one shorter), shared out over the workers in any
    /// order. Only for work whose items are independent: each item's result
    /// depends on nothing another item's visit writes, so it is the same
    /// whoever visits it, and a count of blocks or workers changes nothing.
    /// With one worker, or a single block, the calling thread visits
    /// `0..len` in one call.
    pub(crate) fn for_each_block(
        &self,
        len: usize,
        block: usize,
        visit: impl Fn(Range<usize>) + Sync,
    ) {
        if len == 0 {
            return;
        }
        if self.count() == 1 || len <= block {
            visit(0..len);
            return;
        }
        let claimed = AtomicUsize::new(0);
        self.run(&|_| claim_blocks(0..len, block, &claimed, &visit));
    }
}

/// One worker's share of `range`: blocks of `block` items claimed from
/// `claimed` (the block index past `range.start`) until none is left. When
/// every worker of a job claims from the same counter, which starts at zero,
/// each block is visited once, by one worker.
pub(crate) fn claim_blocks(
    range: Range<usize>,
    block: usize,
    claimed: &AtomicUsize,
    visit: &impl Fn(Range<usize>),
) {
    let block = block.max(1);
    loop {
        let first = range.start + claimed.fetch_add(1, Ordering::Relaxed) * block;
        if first >= range.end {
            break;
        }
        visit(first..(first + block).min(range.end));
    }
}

/// A mutable slice the workers of one job share, each touching only the
/// items it alone claimed (with [`claim_blocks`], or by an index no other
/// worker holds).
pub(crate) struct SharedMut<'a, T> {
    ptr: *mut T,
    len: usize,
    _slice: PhantomData<&'a mut [T]>,
}

// SAFETY: the wrapper only hands out items through `unsafe` methods whose
// callers promise that no two threads touch one item; `T: Send` because
// items are written from other threads.
unsafe impl<T: Send> Sync for SharedMut<'_, T> {}
// SAFETY: as above.
unsafe impl<T: Send> Send for SharedMut<'_, T> {}

impl<'a, T> SharedMut<'a, T> {
    /// Shares `items` (held mutably for the wrapper's life).
    pub(crate) fn new(items: &'a mut [T]) -> SharedMut<'a, T> {
        SharedMut {
            ptr: items.as_mut_ptr(),
            len: items.len(),
            _slice: PhantomData,
        }
    }

    /// The items of `range`.
    ///
    /// # Safety
    /// No other thread touches these items while the returned slice lives.
    /// (An out-of-bounds range panics.)
    #[allow(clippy::mut_from_ref)]
    pub(crate) unsafe fn slice(&self, range: Range<usize>) -> &mut [T] {
        assert!(range.start <= range.end && range.end <= self.len);
        // SAFETY: in bounds (checked), and the caller holds these items
        // alone.
        unsafe { std::slice::from_raw_parts_mut(self.ptr.add(range.start), range.len()) }
    }

    /// Item `i`.
    ///
    /// # Safety
    /// No other thread touches this item while the returned reference
    /// lives. (An out-of-bounds index panics.)
    #[allow(clippy::mut_from_ref)]
    pub(crate) unsafe fn get(&self, i: usize) -> &mut T {
        assert!(i < self.len);
        // SAFETY: in bounds (checked), and the caller holds this item alone.
        unsafe { &mut *self.ptr.add(i) }
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
    fn for_each_block_visits_every_item_once_in_whole_blocks() {
        for count in [1, 2, 3, 8] {
            let w = Workers::new(count);
            for (len, block) in [(0, 4), (1, 4), (4, 4), (5, 4), (1000, 7), (1000, 128)] {
                let mut seen = vec![0u8; len];
                let shared = SharedMut::new(&mut seen);
                w.for_each_block(len, block, |r| {
                    assert!(r.start < r.end && r.end <= len);
                    // Blocks start on a multiple of `block` and end at the
                    // next one or at `len` (one call with one worker).
                    assert!(r.start % block == 0);
                    assert!(r.end == len || (count > 1 && r.len() == block));
                    // SAFETY: the blocks are disjoint (checked by the counts
                    // below).
                    for x in unsafe { shared.slice(r) } {
                        *x += 1;
                    }
                });
                assert!(
                    seen.iter().all(|&n| n == 1),
                    "{count} workers, {len}/{block}"
                );
            }
        }
    }

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
