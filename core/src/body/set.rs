//! `BodySet`: bodies stored as hot and cold arrays sharing slot indices.

use serde::{Deserialize, Serialize};

use crate::arena::Arena;
use crate::math::Vec3;

use super::awake::{AwakeIndex, moves, push_counted};
use super::state::{BodyCold, BodyHot, BodyKind};
use crate::handles::BodyHandle;

/// All bodies of a world. Cold data lives in a generational arena; hot data
/// in a plain array indexed by the same slot index, so the integrator walks
/// contiguous memory.
///
/// The set also keeps the list of awake slots (see `body/awake.rs`), so the
/// step's per-body stages cost nothing for sleeping and static bodies.
///
/// Determinism: iteration is in slot-index order (handle order), and so is
/// the awake list.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct BodySet {
    cold: Arena<BodyCold>,
    hot: Vec<BodyHot>,
    /// Whether slot i is live (mirrors the arena, for the hot loops).
    live: Vec<bool>,
    /// Derived: the awake slots (rebuilt after decoding; never compared).
    #[serde(skip)]
    awake: AwakeIndex,
}

impl BodySet {
    /// Adds a body.
    pub(crate) fn insert(&mut self, hot: BodyHot, cold: BodyCold) -> BodyHandle {
        let h = self.cold.insert(cold);
        let i = h.index as usize;
        if self.awake.valid {
            if hot.kind == BodyKind::Dynamic {
                self.awake.dynamic += 1;
                self.awake.awake_dynamic += u32::from(hot.is_moving());
            }
            if hot.is_moving() {
                self.awake.joined.push(h.index);
            }
        }
        if i == self.hot.len() {
            self.hot.push(hot);
            self.live.push(true);
        } else {
            self.hot[i] = hot;
            self.live[i] = true;
        }
        BodyHandle(h)
    }

    /// Removes a body, returning its cold data.
    pub(crate) fn remove(&mut self, h: BodyHandle) -> Option<BodyCold> {
        let cold = self.cold.remove(h.0)?;
        let i = h.0.index as usize;
        if self.awake.valid {
            if self.hot[i].kind == BodyKind::Dynamic {
                self.awake.dynamic -= 1;
                self.awake.awake_dynamic -= u32::from(self.hot[i].is_moving());
            }
            if self.hot[i].is_moving() {
                self.awake.left = true;
            }
        }
        self.hot[i] = BodyHot::default();
        self.live[i] = false;
        Some(cold)
    }

    /// Whether the handle names a live body.
    pub fn contains(&self, h: BodyHandle) -> bool {
        self.cold.get(h.0).is_some()
    }

    /// Hot state of a live body.
    pub fn hot(&self, h: BodyHandle) -> Option<&BodyHot> {
        self.cold.get(h.0).map(|_| &self.hot[h.0.index as usize])
    }

    /// Hot state of a live body, mutably.
    pub(crate) fn hot_mut(&mut self, h: BodyHandle) -> Option<&mut BodyHot> {
        if self.cold.get(h.0).is_some() {
            Some(&mut self.hot[h.0.index as usize])
        } else {
            None
        }
    }

    /// Cold data of a live body.
    pub fn cold(&self, h: BodyHandle) -> Option<&BodyCold> {
        self.cold.get(h.0)
    }

    /// Cold data of a live body, mutably.
    pub(crate) fn cold_mut(&mut self, h: BodyHandle) -> Option<&mut BodyCold> {
        self.cold.get_mut(h.0)
    }

    /// Both parts of a live body, mutably.
    pub(crate) fn both_mut(&mut self, h: BodyHandle) -> Option<(&mut BodyHot, &mut BodyCold)> {
        let cold = self.cold.get_mut(h.0)?;
        Some((&mut self.hot[h.0.index as usize], cold))
    }

    /// Number of live bodies.
    pub fn len(&self) -> usize {
        self.cold.len()
    }

    /// Whether there are no bodies.
    pub fn is_empty(&self) -> bool {
        self.cold.is_empty()
    }

    /// Live body handles in handle order.
    pub fn handles(&self) -> impl Iterator<Item = BodyHandle> + '_ {
        self.cold.iter().map(|(h, _)| BodyHandle(h))
    }

    /// Live bodies (handle, hot, cold) in handle order.
    pub fn iter(&self) -> impl Iterator<Item = (BodyHandle, &BodyHot, &BodyCold)> {
        self.cold
            .iter()
            .map(|(h, c)| (BodyHandle(h), &self.hot[h.index as usize], c))
    }

    /// The hot array with its liveness mask, for the step's inner loops.
    pub(crate) fn hot_slots_mut(&mut self) -> (&mut [BodyHot], &[bool]) {
        (&mut self.hot, &self.live)
    }

    /// Checks that the hot arrays match the arena (for decoded snapshots).
    pub(crate) fn check(&self) -> Result<(), String> {
        self.cold.check()?;
        let n = self.cold.capacity_slots();
        if self.hot.len() != n || self.live.len() != n {
            return Err("body arrays disagree in length".into());
        }
        for (i, &l) in self.live.iter().enumerate() {
            if l != self.cold.get_by_index(i as u32).is_some() {
                return Err(format!("body slot {i} liveness disagrees"));
            }
        }
        Ok(())
    }

    /// Puts a live dynamic body to sleep or wakes it, keeping the awake list
    /// current. Returns whether its state changed (other kinds never sleep).
    /// Does not touch velocities or rest counters.
    pub(crate) fn set_sleeping(&mut self, h: BodyHandle, sleeping: bool) -> bool {
        if self.cold.get(h.0).is_none() {
            return false;
        }
        let slot = h.0.index;
        let b = &mut self.hot[slot as usize];
        if b.kind != BodyKind::Dynamic || b.sleeping == sleeping {
            return false;
        }
        b.sleeping = sleeping;
        if !self.awake.valid {
            return true;
        }
        let a = &mut self.awake;
        push_counted(&mut a.changed, slot, &mut a.growths);
        if sleeping {
            a.awake_dynamic -= 1;
            a.left = true;
            if !b.force.is_zero() || !b.torque.is_zero() {
                push_counted(&mut a.forced_sleepers, slot, &mut a.growths);
            }
        } else {
            a.awake_dynamic += 1;
            push_counted(&mut a.joined, slot, &mut a.growths);
        }
        true
    }

    /// The number of awake slots, as of the last refresh.
    pub(crate) fn awake_len(&self) -> usize {
        self.awake.slots.len()
    }

    /// The `k`-th awake body (slot order) and its hot state, as of the last
    /// refresh.
    pub(crate) fn awake_at(&self, k: usize) -> Option<(BodyHandle, &BodyHot)> {
        let s = *self.awake.slots.get(k)?;
        let h = self.cold.handle_at(s)?;
        Some((BodyHandle(h), &self.hot[s as usize]))
    }

    /// Brings the awake list up to date (one scan of all slots if it is
    /// missing, as in a decoded set, otherwise work in proportion to the awake bodies and the
    /// transitions since the last refresh).
    pub(crate) fn refresh_awake(&mut self) {
        self.awake.refresh(&self.hot, &self.live);
        debug_assert!(self.awake_list_is_exact(), "awake list out of date");
    }

    /// Whether the awake list equals a scan of all slots (for tests and
    /// debug assertions).
    pub(crate) fn awake_list_is_exact(&self) -> bool {
        let mut listed = self.awake.slots.iter().copied();
        let mut awake_dynamic = 0;
        let mut dynamic = 0;
        for (i, (b, &l)) in self.hot.iter().zip(&self.live).enumerate() {
            if l && b.kind == BodyKind::Dynamic {
                dynamic += 1;
            }
            if moves(l, b) {
                if b.kind == BodyKind::Dynamic {
                    awake_dynamic += 1;
                }
                if listed.next() != Some(i as u32) {
                    return false;
                }
            }
        }
        listed.next().is_none()
            && self.awake.awake_dynamic == awake_dynamic
            && self.awake.dynamic == dynamic
    }

    /// The hot array with the awake slots (ascending), for the step's inner
    /// loops. Call [`refresh_awake`](Self::refresh_awake) first.
    pub(crate) fn awake_slots_mut(&mut self) -> (&mut [BodyHot], &[u32]) {
        (&mut self.hot, &self.awake.slots)
    }

    /// The awake bodies in handle order, as of the last refresh.
    pub(crate) fn iter_awake(&self) -> impl Iterator<Item = (BodyHandle, &BodyHot)> {
        self.awake.slots.iter().filter_map(|&s| {
            let h = self.cold.handle_at(s)?;
            Some((BodyHandle(h), &self.hot[s as usize]))
        })
    }

    /// Sleeping dynamic bodies: a maintained count (no scan), exact between
    /// steps too (inserting, removing, waking or putting a body to sleep
    /// adjusts it at once) and in a restored world (`World::restore`
    /// rebuilds the index before returning; it used to wait for the first
    /// step and report 0 until then).
    pub fn sleeping_count(&self) -> u32 {
        self.awake.dynamic - self.awake.awake_dynamic
    }

    /// Calls `f` on each awake body's hot and cold state in slot order (the
    /// kinematic stages read and write the cold target).
    pub(crate) fn for_each_awake_mut(&mut self, mut f: impl FnMut(&mut BodyHot, &mut BodyCold)) {
        for &s in &self.awake.slots {
            if let Some(cold) = self.cold.get_by_index_mut(s) {
                f(&mut self.hot[s as usize], cold);
            }
        }
    }

    /// Zeroes the force and torque of every awake body and of the sleepers
    /// that still held one (the forces of one step are used up by it).
    pub(crate) fn clear_forces(&mut self) {
        let a = &mut self.awake;
        for &s in a.slots.iter().chain(&a.forced_sleepers) {
            let (i, b) = (s as usize, &mut self.hot[s as usize]);
            if self.live[i] {
                b.force = Vec3::ZERO;
                b.torque = Vec3::ZERO;
            }
        }
        a.forced_sleepers.clear();
    }

    /// Calls `f` on every body whose broad-phase proxies may need to follow
    /// it: the awake bodies and those whose sleep state changed since the
    /// last call (or every live body after a rebuild), in slot order, once
    /// each. Clears the record of changes.
    pub(crate) fn for_each_to_sync(&mut self, mut f: impl FnMut(BodyHandle, &BodyHot, &BodyCold)) {
        let a = &mut self.awake;
        if a.sync_all || !a.valid {
            for (h, c) in self.cold.iter() {
                f(BodyHandle(h), &self.hot[h.index as usize], c);
            }
            a.sync_all = false;
            a.changed.clear();
            return;
        }
        // Determinism: slot numbers are a total order.
        a.changed.sort_unstable();
        a.changed.dedup();
        let (mut i, mut j) = (0, 0);
        let (awake, changed) = (&a.slots, &a.changed);
        loop {
            let next = match (awake.get(i), changed.get(j)) {
                (Some(&x), Some(&y)) if x == y => {
                    i += 1;
                    j += 1;
                    x
                }
                (Some(&x), Some(&y)) if x < y => {
                    i += 1;
                    x
                }
                (_, Some(&y)) => {
                    j += 1;
                    y
                }
                (Some(&x), None) => {
                    i += 1;
                    x
                }
                (None, None) => break,
            };
            if let Some(h) = self.cold.handle_at(next)
                && let Some(c) = self.cold.get_by_index(next)
            {
                f(BodyHandle(h), &self.hot[next as usize], c);
            }
        }
        a.changed.clear();
    }

    /// Buffer growths of the awake bookkeeping since the last call.
    pub(crate) fn take_awake_growths(&mut self) -> u32 {
        self.awake.take_growths()
    }
}
