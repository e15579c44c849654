//! The awake index: which body slots the step must visit.
//!
//! Sleeping and static bodies should cost nothing per step, so the step's
//! per-body stages walk a list of the *awake* slots (live dynamic bodies
//! that do not sleep, and kinematic bodies) instead of every slot. The list
//! is derived data: it is neither serialized nor compared, and it is rebuilt
//! by one scan of all slots when it is missing (a new or restored world,
//! before either is handed out).
//!
//! Between scans it is kept up to date by the transitions themselves: a body
//! that wakes or is inserted is queued in `joined`; a body that falls asleep
//! or is removed sets `left`, and the next [`refresh`](AwakeIndex) drops the
//! slots that no longer move. Both cost in proportion to the awake bodies
//! and the transitions, never to the sleepers.
//!
//! Determinism: the list is kept in ascending slot order (handle order), so
//! every stage that walks it visits bodies in exactly the order a walk over
//! all slots would; it depends only on the bodies' states.

use super::state::{BodyHot, BodyKind};

/// Whether the step moves a body in this slot (awake dynamic or kinematic).
#[inline]
pub(crate) fn moves(live: bool, b: &BodyHot) -> bool {
    live && b.is_moving()
}

/// The awake slots and the bookkeeping that keeps them current (see the
/// module docs). Equality ignores it: it is derived from the bodies.
#[derive(Clone, Debug, Default)]
pub(crate) struct AwakeIndex {
    /// Whether `slots` and the counters describe the bodies (false in a
    /// default or decoded set until the first refresh; `World::new` and
    /// `World::restore` refresh at once).
    pub valid: bool,
    /// Awake slots, ascending.
    pub slots: Vec<u32>,
    /// Slots that may have started moving since the last refresh (woken or
    /// inserted), in no order, possibly repeated.
    pub joined: Vec<u32>,
    /// Whether a slot in `slots` may have stopped moving (fell asleep or was
    /// removed) since the last refresh.
    pub left: bool,
    /// Slots whose sleep state changed since the broad-phase proxies were
    /// last synchronised, in no order, possibly repeated.
    pub changed: Vec<u32>,
    /// Whether every slot must be synchronised (after a rebuild: the proxy
    /// kinds stored in a snapshot are not trusted to match).
    pub sync_all: bool,
    /// Sleeping slots whose force or torque is not zero (put to sleep by
    /// the game after a force was applied): the step clears them as it
    /// clears the awake bodies' forces.
    pub forced_sleepers: Vec<u32>,
    /// Live dynamic bodies.
    pub dynamic: u32,
    /// Awake dynamic bodies: kept current by every transition between
    /// refreshes (the sleep stage, which writes the flags itself, leaves it
    /// to the refresh that follows), so `slots` may lag it but the count
    /// does not.
    pub awake_dynamic: u32,
    /// Times one of these buffers had to grow since the last
    /// [`take_growths`](AwakeIndex::take_growths).
    pub growths: u32,
}

impl PartialEq for AwakeIndex {
    /// Always equal: the index is derived from the bodies it describes.
    fn eq(&self, _: &AwakeIndex) -> bool {
        true
    }
}

impl Eq for AwakeIndex {}

/// Pushes `v`, counting a growth when the buffer is full.
#[inline]
pub(crate) fn push_counted(buf: &mut Vec<u32>, v: u32, growths: &mut u32) {
    if buf.len() == buf.capacity() {
        *growths += 1;
    }
    buf.push(v);
}

impl AwakeIndex {
    /// Rebuilds everything from one scan of all slots.
    pub fn rebuild(&mut self, hot: &[BodyHot], live: &[bool]) {
        self.slots.clear();
        self.joined.clear();
        self.changed.clear();
        self.forced_sleepers.clear();
        self.dynamic = 0;
        self.awake_dynamic = 0;
        for (i, (b, &l)) in hot.iter().zip(live).enumerate() {
            if l && b.kind == BodyKind::Dynamic {
                self.dynamic += 1;
                if b.sleeping && (!b.force.is_zero() || !b.torque.is_zero()) {
                    self.forced_sleepers.push(i as u32);
                }
            }
            if moves(l, b) {
                self.slots.push(i as u32);
                if b.kind == BodyKind::Dynamic {
                    self.awake_dynamic += 1;
                }
            }
        }
        self.left = false;
        self.sync_all = true;
        self.valid = true;
    }

    /// Brings `slots` up to date after transitions: drops slots that no
    /// longer move (a live one is recorded in `changed`, its proxy must turn
    /// to sleeping) and merges the joined ones. Rebuilds if invalid.
    pub fn refresh(&mut self, hot: &[BodyHot], live: &[bool]) {
        if !self.valid {
            self.rebuild(hot, live);
            return;
        }
        if !self.left && self.joined.is_empty() {
            return;
        }
        if self.left {
            let AwakeIndex {
                slots,
                changed,
                growths,
                ..
            } = self;
            slots.retain(|&s| {
                let i = s as usize;
                let keep = moves(live[i], &hot[i]);
                if !keep && live[i] {
                    push_counted(changed, s, growths);
                }
                keep
            });
            self.left = false;
        }
        if !self.joined.is_empty() {
            let cap = self.slots.capacity();
            for &s in &self.joined {
                let i = s as usize;
                if i < hot.len() && moves(live[i], &hot[i]) {
                    self.slots.push(s);
                }
            }
            self.joined.clear();
            // Determinism: slot numbers are a total order.
            self.slots.sort_unstable();
            self.slots.dedup();
            if self.slots.capacity() != cap {
                self.growths += 1;
            }
        }
        self.awake_dynamic = self
            .slots
            .iter()
            .filter(|&&s| hot[s as usize].kind == BodyKind::Dynamic)
            .count() as u32;
    }

    /// Buffer growths since the last call.
    pub fn take_growths(&mut self) -> u32 {
        std::mem::take(&mut self.growths)
    }
}
