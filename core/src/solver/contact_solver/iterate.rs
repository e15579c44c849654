//! How the passes walk the constraints: in order with prefetching, or
//! colour by colour over the workers.

use super::color::COLORS;
use super::constraint::Constraint;
use super::narrow::NarrowRows;
use super::rows::prefetch;
use crate::workers::{ColorGate, SharedMut, Workers};
use std::ops::Range;

/// How many constraints ahead the passes ask the CPU to load. A constraint
/// is about 1.9 KB and a pass spends a few hundred nanoseconds on it: on
/// large_pyramid (15,000 constraints, far more than the caches hold) one
/// ahead was faster than two or four, and about 10% faster than none.
pub(super) const PREFETCH_AHEAD: usize = 1;

/// Visits the constraints in order, asking the CPU to load the next ones
/// first (see [`PREFETCH_AHEAD`]): the narrow rows of one on them, the
/// Q32.32 constraint of one that is not. `rs` holds the constraints' narrow
/// rows, or nothing in a world on the Q32.32 rows (each visit then gets
/// `None`).
#[inline(always)]
pub(super) fn for_each_prefetched(
    cs: &mut [Constraint],
    rs: &mut [NarrowRows],
    mut f: impl FnMut(&mut Constraint, Option<&mut NarrowRows>),
) {
    let len = cs.len();
    let narrow = !rs.is_empty();
    for i in 0..len {
        if i + PREFETCH_AHEAD < len {
            match rs.get(i + PREFETCH_AHEAD) {
                Some(next) if narrow && next.on => prefetch(next),
                _ => prefetch(&cs[i + PREFETCH_AHEAD]),
            }
        }
        f(&mut cs[i], rs.get_mut(i));
    }
}

/// The constraints and their narrow rows (same index), shared by the
/// workers of one colour pass.
pub(super) struct Both<'a> {
    pub(super) cs: SharedMut<'a, Constraint>,
    pub(super) rs: SharedMut<'a, NarrowRows>,
}

impl<'a> Both<'a> {
    pub(super) fn new(cs: &'a mut [Constraint], rs: &'a mut [NarrowRows]) -> Both<'a> {
        Both {
            cs: SharedMut::new(cs),
            rs: SharedMut::new(rs),
        }
    }

    /// The constraints and rows of `r`.
    ///
    /// # Safety
    /// No other thread touches them while the slices live.
    #[allow(clippy::mut_from_ref)]
    pub(super) unsafe fn slices(&self, r: Range<usize>) -> (&mut [Constraint], &mut [NarrowRows]) {
        // SAFETY: as the caller promises. No rows (a world on the Q32.32
        // rows): an empty slice of them.
        unsafe {
            let rows = if self.rs.is_empty() {
                self.rs.slice(0..0)
            } else {
                self.rs.slice(r.clone())
            };
            (self.cs.slice(r), rows)
        }
    }
}

/// Constraints a worker claims at a time within a colour: enough that
/// claiming (one atomic add) costs little beside the visits, few enough
/// that two workers end a colour of a few hundred constraints together.
pub(super) const BLOCK: usize = 16;

/// Solver bodies a worker claims at a time when the velocities go to and
/// from the bodies (a few nanoseconds each).
pub(super) const BODY_BLOCK: usize = 128;

/// Constraints a worker claims at a time when the impulses go back to the
/// pairs (a copy of a few words each).
pub(super) const STORE_BLOCK: usize = 128;

/// Visits every constraint once, in colour order: each colour's
/// constraints split in blocks over the workers (they share no moving
/// body, so each one's result is the same whoever visits it and in any
/// order), no block of a colour before the colour before it has finished,
/// then the overflow in order on this thread. With one worker, one thread
/// visits the colours from first to last, then the overflow: the same
/// results. In pair order (no colours) it visits the array in order.
///
/// `visit` gets runs of consecutive constraints, and whether the run lies
/// inside one colour (its constraints may then be visited in any order or
/// together). A run inside a colour starts at the colour's start plus a
/// multiple of [`BLOCK`], whatever the worker count (see
/// `workers::segment`), so the wide kernels' batches of eight are the same
/// for any count.
///
/// `rows` holds the constraints' narrow rows (same index), or nothing in a
/// world on the Q32.32 rows; each run gets its own rows, or none.
pub(super) fn for_each_colored<F>(
    constraints: &mut [Constraint],
    rows: &mut [NarrowRows],
    starts: &[u32; COLORS + 2],
    workers: &Workers,
    visit: F,
) where
    F: Fn(&mut [Constraint], &mut [NarrowRows], bool) + Sync,
{
    let len = constraints.len();
    let colored = (starts[COLORS] as usize).min(len);
    if colored == 0 {
        visit(constraints, rows, false);
        return;
    }
    let ranges: [Range<usize>; COLORS] = std::array::from_fn(|c| {
        (starts[c] as usize).min(colored)..(starts[c + 1] as usize).min(colored)
    });
    let (shared, overflow) = constraints.split_at_mut(colored);
    let (shared_rows, overflow_rows) = rows.split_at_mut(colored.min(rows.len()));
    if workers.count() == 1 {
        for r in ranges {
            let rs = if shared_rows.is_empty() {
                &mut []
            } else {
                &mut shared_rows[r.clone()]
            };
            visit(&mut shared[r], rs, true);
        }
    } else {
        let gate = ColorGate::<COLORS>::new(workers);
        let both = Both::new(shared, shared_rows);
        let visit_block = |r| {
            // SAFETY: each block is claimed by one worker alone (one counter
            // per segment of a colour, every worker claiming from it).
            let (cs, rs) = unsafe { both.slices(r) };
            visit(cs, rs, true)
        };
        workers.run(&|w| gate.visit(w, &ranges, BLOCK, &visit_block));
    }
    visit(overflow, overflow_rows, false);
}

/// [`for_each_colored`]'s visitor for a pass that visits one constraint at
/// a time.
pub(super) fn one_by_one(
    visit: impl Fn(&mut Constraint, Option<&mut NarrowRows>) + Sync,
) -> impl Fn(&mut [Constraint], &mut [NarrowRows], bool) + Sync {
    move |cs, rs, _| for_each_prefetched(cs, rs, &visit)
}
