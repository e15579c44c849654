//! A counting global allocator: the system allocator with bookkeeping, for
//! a test or benchmark binary that installs it with `#[global_allocator]`.
//!
//! It keeps two things. Per thread, the number of allocations (and
//! reallocations) made on that thread, so a test can prove that a warm step
//! allocates nothing while the harness's own threads allocate at any time
//! ([`allocations`]). For the process, the bytes live now and their peak
//! since the last reset, so a benchmark can report the heap an engine
//! holds ([`live`], [`reset_peak`], [`peak`]). The cost is a few
//! nanoseconds per allocation.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Held for the length of one high-water measurement, so two measurements
/// (e.g. tests running in parallel) do not reset each other's peak.
pub static MEASUREMENT: Mutex<()> = Mutex::new(());

/// The system allocator, counting allocations per thread and live bytes
/// with their peak.
pub struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    // Const-initialised and without a destructor: reading it never allocates.
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
}

fn counted() {
    // `try_with` so an allocation during thread teardown is simply not counted.
    let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
}

fn grew(bytes: usize) {
    let now = LIVE.fetch_add(bytes, Ordering::Relaxed) + bytes;
    PEAK.fetch_max(now, Ordering::Relaxed);
}

// SAFETY: every call is forwarded unchanged to `System`; the counters are
// only bookkeeping.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        counted();
        // SAFETY: forwarded with the caller's layout.
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        counted();
        // SAFETY: forwarded with the caller's layout.
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` came from this allocator with this layout.
        unsafe { System.dealloc(ptr, layout) };
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        counted();
        // SAFETY: forwarded with the caller's pointer, layout and size.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
            grew(new_size);
        }
        p
    }
}

/// Allocations and reallocations made on this thread so far (only while
/// [`Counting`] is the global allocator).
pub fn allocations() -> u64 {
    ALLOCATIONS.with(Cell::get)
}

/// Bytes allocated and not yet freed.
pub fn live() -> usize {
    LIVE.load(Ordering::Relaxed)
}

/// Starts a new high-water measurement at the current live bytes; returns
/// them (the baseline to subtract from [`peak`]).
pub fn reset_peak() -> usize {
    let now = live();
    PEAK.store(now, Ordering::Relaxed);
    now
}

/// The most bytes live at once since the last [`reset_peak`].
pub fn peak() -> usize {
    PEAK.load(Ordering::Relaxed)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[global_allocator]
    static COUNTING: Counting = Counting;

    #[test]
    fn peak_tracks_a_large_allocation_after_it_is_freed() {
        let _one_at_a_time = MEASUREMENT.lock().unwrap_or_else(|e| e.into_inner());
        // The counters are the process's: the harness and the other tests'
        // threads allocate and free while this runs. Between the reset and
        // the allocation they may free some of what they held (well under
        // 1 MiB in this binary: a few strings), so the peak is only bounded
        // below by the baseline plus the allocation minus that slack. A
        // 16 MiB allocation keeps the bound far from the noise.
        const BIG: usize = 16 << 20;
        const SLACK: usize = 1 << 20;
        let base = reset_peak();
        let v = vec![0u8; BIG];
        std::hint::black_box(&v);
        drop(v);
        let peak = peak();
        assert!(
            peak + SLACK >= base + BIG,
            "peak {peak} B, baseline {base} B: the 16 MiB allocation was not counted"
        );
    }

    #[test]
    fn allocations_count_on_this_thread() {
        let before = allocations();
        let v = std::hint::black_box(vec![1u8; 64]);
        drop(v);
        assert_eq!(allocations(), before + 1);
    }
}
