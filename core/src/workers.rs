//! Worker threads for a world's step: the contact solver's colour passes,
//! and in either contact order the narrow phase (per block of pairs), the
//! integrators (per block of awake bodies), the solver's gathers and
//! scatters (per block of solver bodies) and `prepare`'s constant terms
//! (per block of constraints).
//!
//! A [`Workers`] holds `count − 1` helper threads, started once (when the
//! game sets the count) and parked between jobs, so a step allocates
//! nothing and starts no thread. [`Workers::run`] posts a job, runs it on
//! the calling thread (worker 0), and returns once worker 0 is done with it
//! and so is every helper that joined in meanwhile. A helper that comes
//! late (parked, or its core taken by other work on a shared machine)
//! joins nothing: every job is written so that worker 0 alone does all of
//! it (its workers claim the work from shared counters), so a slow helper
//! costs at most the block it holds, never a wait for it to arrive.
//!
//! Why the results never depend on the count: a job only ever splits work
//! whose pieces are independent (a pair's test writes that pair alone, a
//! body's integration that body alone; the constraints of one colour share
//! no moving body, so each one's result is the same whichever worker visits
//! it and in whatever order), and no block of a colour starts before every
//! block of the colour before it has finished ([`ColorGate`]). Nothing is
//! summed across workers but integer counters (exact in any order);
//! whatever must be in order (the contact events) is put in order on the
//! calling thread afterwards. The worker count is not simulation state: it
//! is in neither the state hash nor snapshots, and tests step the same
//! scenes with 1, 2, 3, 4 and 8 workers and compare every hash.
//!
//! Faults: the core's fault flags are per thread (`math::faults`). A
//! helper clears its flags before each job and hands what the job raised
//! to the pool, and [`Workers::run`] raises them on the calling thread
//! before it returns, so a fault on any worker is the step's fault, as if
//! one thread had done all the work.
//!
//! Waiting: a helper spins briefly for the next job (the solver posts one
//! per pass, microseconds apart within a step), then yields, then parks
//! until [`Workers::run`] unparks it. A worker waiting for a colour to
//! finish spins, then yields, so more workers than cores still make
//! progress.

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

/// [`Shared::state`]: the job's number (bumped per posted job) in the high
/// 32 bits, whether it is closed to late helpers, and how many helpers
/// joined it and have not finished.
const EPOCH_SHIFT: u32 = 32;
const CLOSED: u64 = 1 << 31;
const JOINED: u64 = CLOSED - 1;

/// What the helpers share with the thread that posts jobs.
struct Shared {
    /// The current job: set before its epoch is published in `state`, read
    /// by a helper only after it joined the job, and left alone until the
    /// job is closed and no helper is in it.
    job: UnsafeCell<Option<*const Job>>,
    /// Epoch, closed flag and joined helpers (see [`EPOCH_SHIFT`]). A
    /// helper joins an open job by adding one (compare-and-swap, so it can
    /// never join a closed one) and leaves by taking one away.
    state: AtomicU64,
    /// The fault flags the helpers raised in the current job.
    faults: AtomicU8,
    /// Whether a helper's share of the current job panicked.
    panicked: AtomicBool,
    /// Set when the pool is dropped.
    stop: AtomicBool,
}

// SAFETY: `job` is written only by the posting thread while no helper reads
// it (before the new epoch is stored with Release, after the last job was
// closed and every helper in it left, with Release), and read by a helper
// only between those points (after joining the open job with Acquire).
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
            state: AtomicU64::new(CLOSED),
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

    /// Runs `job(0)` on the calling thread, and `job(i)` on each helper `i`
    /// that joins before worker 0 is done (each at most once); returns when
    /// worker 0 and every helper that joined have finished. So `job` must
    /// get all its work done when worker 0 alone runs it (see the module
    /// docs).
    pub(crate) fn run<'a>(&self, job: &'a (dyn Fn(usize) + Sync + 'a)) {
        if self.helpers.is_empty() {
            job(0);
            return;
        }
        // SAFETY: the pointer's lifetime is erased, but it is read only by
        // helpers that joined the job, this function does not return before
        // each of them has left it (below), and none can join after that
        // (the job is closed), so `job` outlives its use.
        let ptr: *const Job =
            unsafe { std::mem::transmute::<&'a (dyn Fn(usize) + Sync + 'a), &'static Job>(job) };
        let state = &self.shared.state;
        let last = state.load(Ordering::Acquire);
        debug_assert!(last & CLOSED != 0 && last & JOINED == 0);
        // SAFETY: no helper reads `job` now: the last job is closed and
        // every helper that joined it left (`run` waited for that), and a
        // helper reads `job` only after joining an open job.
        unsafe { *self.shared.job.get() = Some(ptr) };
        let epoch = (last >> EPOCH_SHIFT).wrapping_add(1);
        state.store(epoch << EPOCH_SHIFT, Ordering::Release);
        for h in &self.helpers {
            h.thread().unpark();
        }
        // Worker 0's panic is held until the helpers are done with the job
        // (which borrows this frame); waiting workers see the flag and give
        // up.
        let mine = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| job(0)));
        if mine.is_err() {
            self.shared.panicked.store(true, Ordering::Relaxed);
        }
        // Late helpers may no longer join; wait for those inside.
        state.fetch_or(CLOSED, Ordering::AcqRel);
        let mut waited = 0u32;
        while state.load(Ordering::Acquire) & JOINED != 0 {
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
        // Each worker starts on a contiguous segment of its own (see
        // [`ColorGate`]): its blocks are neighbours in memory, and its
        // claims go to a counter on its own cache line.
        let segments = self.count().min(SEGMENTS);
        let claimed: [Row<1>; SEGMENTS] = std::array::from_fn(|_| Row::new());
        self.run(&|w| claim_segmented(0..len, segments, w, block, |s| &claimed[s].0[0], &visit));
    }
}

/// Segment `s` of `segments` contiguous, nearly equal pieces of `range`,
/// each starting at `range.start` plus a multiple of `block`: the blocks
/// claimed from the segments then start where they would for one segment,
/// whatever the number of workers (the wide solver kernels batch a block's
/// constraints from its start, and count their batches).
fn segment(range: Range<usize>, segments: usize, s: usize, block: usize) -> Range<usize> {
    let block = block.max(1);
    let at = |k: usize| {
        if k >= segments {
            range.end
        } else {
            range.start + range.len() * k / segments / block * block
        }
    };
    at(s)..at(s + 1)
}

/// Worker `worker`'s share of `range` cut into `segments` segments, each
/// with its own claim counter (`claimed(s)`): the blocks of segment
/// `worker % segments` first, then what is left in the others, in turn.
/// When every worker of a job calls it with the same counters, each block
/// is visited once, by one worker, whichever of them joined.
fn claim_segmented<'c>(
    range: Range<usize>,
    segments: usize,
    worker: usize,
    block: usize,
    claimed: impl Fn(usize) -> &'c AtomicUsize,
    visit: &impl Fn(Range<usize>),
) {
    for k in 0..segments {
        let s = (worker + k) % segments;
        claim_blocks(
            segment(range.clone(), segments, s, block),
            block,
            claimed(s),
            visit,
        );
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

    /// Whether it shares no item.
    pub(crate) fn is_empty(&self) -> bool {
        self.len == 0
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
            let s = shared.state.load(Ordering::Acquire);
            let epoch = s >> EPOCH_SHIFT;
            if epoch != seen {
                if s & CLOSED != 0 {
                    // Too late for this one: wait for the next.
                    seen = epoch;
                    continue;
                }
                let joined = shared.state.compare_exchange_weak(
                    s,
                    s + 1,
                    Ordering::AcqRel,
                    Ordering::Acquire,
                );
                if joined.is_ok() {
                    seen = epoch;
                    break;
                }
                continue;
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
        // SAFETY: see `Shared`: this helper joined the open job (Acquire)
        // after the posting thread wrote it.
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
        shared.state.fetch_sub(1, Ordering::Release);
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

/// Segments a colour is cut into for its workers (see [`ColorGate`]); a
/// worker past the last one starts on segment `worker % SEGMENTS`.
const SEGMENTS: usize = 8;

/// One counter per colour on cache lines of its own: the counters a worker
/// touches on every block are not on the lines the others touch on theirs.
#[repr(align(128))]
struct Row<const N: usize>([AtomicUsize; N]);

impl<const N: usize> Row<N> {
    fn new() -> Row<N> {
        Row(std::array::from_fn(|_| AtomicUsize::new(0)))
    }
}

/// The order of a colour pass's blocks across workers: no block of a
/// colour starts before every block of the colours before it has finished.
/// It counts finished blocks, not arrived workers, so a worker that has not
/// joined the job holds nothing up.
///
/// Each colour is cut into one contiguous segment per worker (at most
/// [`SEGMENTS`]), and a worker claims the blocks of its own segment first,
/// then those left in the others'. The constraints are in pair order within
/// a colour, so a worker's segments of successive colours mostly touch the
/// same bodies, whose velocities then stay in its core's caches instead of
/// crossing to the other core at every colour; and the claims and the
/// finished counts go to counters on the worker's own cache lines. Which
/// worker visits a block changes no result (the constraints of a colour
/// share no moving body), and a worker that never joins leaves its segment
/// to the others.
pub(crate) struct ColorGate<'a, const N: usize> {
    /// Set when a worker of the job panicked: a waiter would wait forever,
    /// so it panics too (and `Workers::run` reports the first).
    abandon: &'a AtomicBool,
    /// Segments per colour: the job's workers, at most [`SEGMENTS`].
    segments: usize,
    /// Per segment and colour, its blocks claimed so far.
    claimed: [Row<N>; SEGMENTS],
    /// Per worker row (`worker % segments`) and colour, the blocks of the
    /// colour that the row's workers finished, from any segment.
    finished: [Row<N>; SEGMENTS],
}

impl<const N: usize> ColorGate<'_, N> {
    /// A gate for a job on `pool`, over `N` colours.
    pub(crate) fn new(pool: &Workers) -> ColorGate<'_, N> {
        ColorGate {
            abandon: &pool.shared.panicked,
            segments: pool.count().min(SEGMENTS),
            claimed: std::array::from_fn(|_| Row::new()),
            finished: std::array::from_fn(|_| Row::new()),
        }
    }

    /// The blocks of `block` items that the segments of `range` hold.
    fn blocks(&self, range: &Range<usize>, block: usize) -> usize {
        (0..self.segments)
            .map(|s| {
                segment(range.clone(), self.segments, s, block)
                    .len()
                    .div_ceil(block)
            })
            .sum()
    }

    /// Worker `worker`'s share of the colours' ranges `ranges[c]` (in
    /// colour order), in blocks of `block`: for each colour, it waits until
    /// the colour before it (the last non-empty one) has finished all its
    /// blocks, then claims and visits blocks, from its own segment and then
    /// from the others', until none is left. Every worker of the job calls
    /// it with its index and the same other arguments; any number of them
    /// (worker 0 alone included) visits every block once.
    pub(crate) fn visit(
        &self,
        worker: usize,
        ranges: &[Range<usize>; N],
        block: usize,
        visit: &impl Fn(Range<usize>),
    ) {
        let block = block.max(1);
        let own = worker % self.segments;
        let mut before: Option<usize> = None;
        for (c, range) in ranges.iter().enumerate() {
            if range.is_empty() {
                continue;
            }
            if let Some(p) = before {
                let blocks = self.blocks(&ranges[p], block);
                let mut waited = 0u32;
                // Acquire: every write of the colour's visits (each
                // finished with a Release add to its worker's row) is
                // seen after this. Each row only grows, so the sum reaches
                // `blocks` only once every block has finished.
                loop {
                    let done: usize = self.finished[..self.segments]
                        .iter()
                        .map(|row| row.0[p].load(Ordering::Acquire))
                        .sum();
                    if done >= blocks {
                        break;
                    }
                    if self.abandon.load(Ordering::Relaxed) {
                        panic!("another solver worker panicked");
                    }
                    pause(&mut waited);
                }
            }
            claim_segmented(
                range.clone(),
                self.segments,
                own,
                block,
                |s| &self.claimed[s].0[c],
                &|r| {
                    visit(r);
                    self.finished[own].0[c].fetch_add(1, Ordering::Release);
                },
            );
            before = Some(c);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::Rng;

    #[test]
    fn for_each_block_visits_every_item_once_in_blocks() {
        for count in [1, 2, 3, 8] {
            let w = Workers::new(count);
            for (len, block) in [(0, 4), (1, 4), (4, 4), (5, 4), (1000, 7), (1000, 128)] {
                let mut seen = vec![0u8; len];
                let shared = SharedMut::new(&mut seen);
                w.for_each_block(len, block, |r| {
                    assert!(r.start < r.end && r.end <= len);
                    // Blocks of `block` items at most (one call over it
                    // all with one worker).
                    assert!(r.len() <= block || (count == 1 && r == (0..len)));
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

    /// Inside a job on `count` workers: waits until every helper has
    /// joined it (each adds one to `joined`), so a test can rely on all of
    /// them running it. Worker 0 holds the job open meanwhile.
    fn hold_until_all_joined(joined: &AtomicUsize, count: usize) {
        while joined.load(Ordering::Acquire) < count {
            std::hint::spin_loop();
            std::thread::yield_now();
        }
    }

    #[test]
    fn worker_0_runs_each_job_helpers_at_most_once_and_run_waits_for_them() {
        for count in [1, 2, 3, 4, 8] {
            let w = Workers::new(count);
            assert_eq!(w.count(), count);
            let hits: Vec<AtomicUsize> = (0..count).map(|_| AtomicUsize::new(0)).collect();
            let inside = AtomicUsize::new(0);
            for round in 1..=200 {
                w.run(&|i| {
                    inside.fetch_add(1, Ordering::AcqRel);
                    hits[i].fetch_add(1, Ordering::Relaxed);
                    // Keep a late joiner busy for a while: `run` must still
                    // wait for it.
                    if i != 0 {
                        for _ in 0..1000 {
                            std::hint::spin_loop();
                        }
                    }
                    inside.fetch_sub(1, Ordering::AcqRel);
                });
                assert_eq!(inside.load(Ordering::Acquire), 0, "{count} workers");
                assert_eq!(hits[0].load(Ordering::Relaxed), round);
                for (i, h) in hits.iter().enumerate() {
                    assert!(h.load(Ordering::Relaxed) <= round, "worker {i} of {count}");
                }
            }
            // Held open, every helper joins, once.
            let joined = AtomicUsize::new(0);
            let before: Vec<usize> = hits.iter().map(|h| h.load(Ordering::Relaxed)).collect();
            w.run(&|i| {
                hits[i].fetch_add(1, Ordering::Relaxed);
                joined.fetch_add(1, Ordering::AcqRel);
                if i == 0 {
                    hold_until_all_joined(&joined, count);
                }
            });
            for (i, h) in hits.iter().enumerate() {
                assert_eq!(
                    h.load(Ordering::Relaxed),
                    before[i] + 1,
                    "worker {i} of {count}"
                );
            }
        }
    }

    #[test]
    fn a_fault_raised_on_a_helper_is_raised_on_the_calling_thread() {
        for count in [2, 3, 8] {
            let w = Workers::new(count);
            faults::take();
            let joined = AtomicUsize::new(0);
            w.run(&|i| {
                if i == count - 1 {
                    faults::raise(Faults::OVERFLOW);
                }
                joined.fetch_add(1, Ordering::AcqRel);
                if i == 0 {
                    hold_until_all_joined(&joined, count);
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
        let joined = AtomicUsize::new(0);
        let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            w.run(&|i| {
                joined.fetch_add(1, Ordering::AcqRel);
                if i == 1 {
                    panic!("worker 1 fails on purpose");
                }
                hold_until_all_joined(&joined, 2);
            });
        }));
        assert!(caught.is_err(), "the helper's panic reaches run's caller");
        let hits = AtomicUsize::new(0);
        w.run(&|_| {
            hits.fetch_add(1, Ordering::Relaxed);
        });
        assert!((1..=2).contains(&hits.load(Ordering::Relaxed)));
    }

    /// Ranges of `N` colours of random sizes (some empty) laid end to end.
    fn random_ranges<const N: usize>(rng: &mut Rng) -> [Range<usize>; N] {
        let mut at = 0;
        std::array::from_fn(|_| {
            let x = rng.next_u64();
            let len = match (x >> 33) % 4 {
                0 => 0,
                1 => (x >> 40) as usize % 5,
                _ => (x >> 40) as usize % 200,
            };
            at += len;
            at - len..at
        })
    }

    #[test]
    fn the_gate_visits_every_block_once_never_before_the_colours_before_it() {
        const N: usize = 24;
        let mut rng = Rng::new(7);
        for count in [1, 2, 3, 4, 8] {
            let w = Workers::new(count);
            for round in 0..30 {
                let ranges = random_ranges::<N>(&mut rng);
                let len = ranges[N - 1].end;
                let colour_of = |i: usize| ranges.iter().position(|r| r.contains(&i)).unwrap();
                let seen: Vec<AtomicUsize> = (0..len).map(|_| AtomicUsize::new(0)).collect();
                let early = AtomicBool::new(false);
                let block = 1 + round % 9;
                let gate = ColorGate::<N>::new(&w);
                w.run(&|i| {
                    gate.visit(i, &ranges, block, &|r: Range<usize>| {
                        let c = colour_of(r.start);
                        assert!(r.len() <= block && ranges[c].contains(&(r.end - 1)));
                        // Every item of the colours before is done (Relaxed
                        // loads: the gate's Acquire ordered them).
                        let earlier = ranges[..c].iter().flat_map(|r| r.clone());
                        if earlier
                            .into_iter()
                            .any(|i| seen[i].load(Ordering::Relaxed) != 1)
                        {
                            early.store(true, Ordering::Relaxed);
                        }
                        for i in r {
                            seen[i].fetch_add(1, Ordering::Relaxed);
                        }
                    });
                });
                assert!(
                    !early.load(Ordering::Relaxed),
                    "{count} workers, round {round}"
                );
                assert!(
                    seen.iter().all(|n| n.load(Ordering::Relaxed) == 1),
                    "{count} workers, round {round}"
                );
            }
        }
    }

    #[test]
    fn a_panic_in_a_gated_colour_does_not_leave_the_others_waiting() {
        const N: usize = 4;
        for (count, failing) in [(2, 0), (2, 1), (4, 2)] {
            let w = Workers::new(count);
            let gate = ColorGate::<N>::new(&w);
            let ranges = [0..8, 8..16, 16..24, 24..32];
            let joined = AtomicUsize::new(0);
            let failed = AtomicBool::new(false);
            let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                w.run(&|i| {
                    joined.fetch_add(1, Ordering::AcqRel);
                    hold_until_all_joined(&joined, count);
                    gate.visit(i, &ranges, 1, &|r: Range<usize>| {
                        // The failing worker dies on its first block (of
                        // colour 0: the others hold theirs until it has
                        // one), so colour 0 never finishes.
                        if i == failing {
                            failed.store(true, Ordering::Release);
                            panic!("worker {i} fails on purpose");
                        }
                        while r.start < 8 && !failed.load(Ordering::Acquire) {
                            std::thread::yield_now();
                        }
                    });
                });
            }));
            assert!(caught.is_err(), "{count} workers, worker {failing} failing");
            let hits = AtomicUsize::new(0);
            w.run(&|_| {
                hits.fetch_add(1, Ordering::Relaxed);
            });
            assert!((1..=count).contains(&hits.load(Ordering::Relaxed)));
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
        let joined = AtomicUsize::new(0);
        // Held open until the parked helper has woken and joined.
        w.run(&|i| {
            hits.fetch_add(1, Ordering::Relaxed);
            joined.fetch_add(1, Ordering::AcqRel);
            if i == 0 {
                hold_until_all_joined(&joined, 2);
            }
        });
        // Worker 0 twice, the helper in the second job (and maybe the
        // first).
        assert!((3..=4).contains(&hits.load(Ordering::Relaxed)));
    }
}
