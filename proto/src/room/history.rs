//! Closed tick bundles kept for resending, and the choice of which of them go
//! into each player's next datagram.

use crate::codec::body_len;
use crate::message::{Slot, TickBundle};
use crate::ring::TickRing;

use super::arbiter::{SlotMask, bit};

#[derive(Debug)]
struct Closed {
    bundle: TickBundle,
    /// Exact encoded size of `bundle`, computed once when the tick closes.
    len: usize,
    /// Players whose late input for this tick has already been counted.
    late_seen: SlotMask,
}

/// The bundle a player needs next was already dropped from the history.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct FellBehind;

/// The most recent closed bundles, in a ring.
#[derive(Debug)]
pub(crate) struct History {
    ring: TickRing<Closed>,
    /// One past the newest closed tick.
    end: u64,
}

impl History {
    pub(crate) fn new(capacity: usize) -> Self {
        Self {
            ring: TickRing::new(capacity),
            end: 0,
        }
    }

    /// Stores the bundle of the tick just closed (ticks close in order).
    pub(crate) fn push(&mut self, bundle: TickBundle) {
        let len = body_len(&bundle);
        let tick = bundle.tick;
        self.end = tick + 1;
        self.ring.insert(
            tick,
            Closed {
                bundle,
                len,
                late_seen: 0,
            },
        );
    }

    /// The bundle of `tick`, if still kept.
    pub(crate) fn get(&self, tick: u64) -> Option<&TickBundle> {
        self.ring.get(tick).map(|c| &c.bundle)
    }

    /// Marks `slot`'s input for closed `tick` as arrived late; true the first
    /// time for a tick where that player's input was substituted.
    pub(crate) fn mark_late(&mut self, tick: u64, slot: Slot) -> bool {
        let Some(c) = self.ring.get_mut(tick) else {
            return false;
        };
        let substituted = c
            .bundle
            .inputs
            .iter()
            .any(|p| p.slot == slot && p.substituted);
        if !substituted || c.late_seen & bit(slot) != 0 {
            return false;
        }
        c.late_seen |= bit(slot);
        true
    }

    /// Chooses the bundles from tick `from` onward to put in one datagram of
    /// at most `budget` bytes of bundles and `max_count` bundles.
    ///
    /// When every unacknowledged bundle fits, all of them go (each bundle is
    /// then repeated until acknowledged). Otherwise half the budget goes to
    /// the newest bundles, so fresh ticks keep flowing at any round trip, and
    /// the rest to the oldest unacknowledged ones, so a bundle lost in every
    /// copy is repaired as soon as the client's ack stalls on it.
    ///
    /// # Errors
    /// [`FellBehind`] when the bundle of `from` is no longer kept.
    pub(crate) fn select(
        &self,
        from: u64,
        budget: usize,
        max_count: usize,
    ) -> Result<Vec<TickBundle>, FellBehind> {
        if from >= self.end {
            return Ok(Vec::new());
        }
        if !self.ring.contains(from) {
            return Err(FellBehind);
        }
        let len_of = |t: u64| self.ring.get(t).map_or(usize::MAX, |c| c.len);
        let count = self.end - from;
        let total: usize = (from..self.end).map(len_of).fold(0, usize::saturating_add);
        if count <= max_count as u64 && total <= budget {
            return Ok((from..self.end)
                .filter_map(|t| self.get(t).cloned())
                .collect());
        }
        // Newest first, at least one, within half the count and byte budget.
        let mut picked_new = Vec::new();
        let mut bytes = 0usize;
        let half_count = max_count - max_count / 2;
        let mut t = self.end;
        while t > from {
            let len = len_of(t - 1);
            let fits_half = picked_new.len() < half_count && bytes + len <= budget / 2;
            if !(fits_half || picked_new.is_empty() && len <= budget) {
                break;
            }
            t -= 1;
            bytes += len;
            picked_new.push(t);
        }
        // Then the oldest unacknowledged, up to the full budget.
        let newest_floor = t;
        let mut picked_old = Vec::new();
        let mut t = from;
        while t < newest_floor && picked_new.len() + picked_old.len() < max_count {
            let len = len_of(t);
            if bytes + len > budget {
                break;
            }
            bytes += len;
            picked_old.push(t);
            t += 1;
        }
        Ok(picked_old
            .into_iter()
            .chain(picked_new.into_iter().rev())
            .filter_map(|t| self.get(t).cloned())
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::message::PlayerInput;

    fn history(ticks: u64) -> History {
        let mut h = History::new(64);
        for tick in 0..ticks {
            h.push(TickBundle {
                tick,
                inputs: vec![PlayerInput {
                    slot: Slot(0),
                    input: vec![1; 8],
                    substituted: tick == 2,
                }],
            });
        }
        h
    }

    fn ticks(v: &[TickBundle]) -> Vec<u64> {
        v.iter().map(|b| b.tick).collect()
    }

    #[test]
    fn everything_unacknowledged_goes_when_it_fits() {
        let h = history(10);
        assert_eq!(
            ticks(&h.select(4, 1000, 16).unwrap()),
            vec![4, 5, 6, 7, 8, 9]
        );
        assert!(h.select(10, 1000, 16).unwrap().is_empty());
    }

    #[test]
    fn backlog_splits_between_newest_and_oldest() {
        let h = history(40);
        // Each bundle encodes to 13 bytes: tick 1, count 1, slot 1, len 1,
        // input 8, flag 1. Count-bound: 8 newest + 8 oldest.
        assert_eq!(body_len(h.get(5).unwrap()), 13);
        let got = ticks(&h.select(10, 1000, 16).unwrap());
        assert_eq!(
            got,
            vec![
                10, 11, 12, 13, 14, 15, 16, 17, 32, 33, 34, 35, 36, 37, 38, 39
            ]
        );
        // Byte-bound: 52 bytes = 4 bundles; 2 newest (half budget), 2 oldest.
        assert_eq!(ticks(&h.select(10, 52, 16).unwrap()), vec![10, 11, 38, 39]);
        // A budget for a single bundle still carries the newest.
        assert_eq!(ticks(&h.select(10, 13, 16).unwrap()), vec![39]);
    }

    #[test]
    fn a_bundle_no_longer_kept_means_fell_behind() {
        let h = history(100);
        assert_eq!(h.select(35, 1000, 16), Err(FellBehind));
        assert!(h.select(36, 1000, 16).is_ok());
    }

    #[test]
    fn late_input_is_counted_once_and_only_where_substituted() {
        let mut h = history(5);
        assert!(!h.mark_late(1, Slot(0)));
        assert!(h.mark_late(2, Slot(0)));
        assert!(!h.mark_late(2, Slot(0)));
        assert!(!h.mark_late(2, Slot(1)));
    }
}
