//! `BodySet`: bodies stored as hot and cold arrays sharing slot indices.

use serde::{Deserialize, Serialize};

use crate::arena::Arena;

use super::{BodyCold, BodyHandle, BodyHot};

/// All bodies of a world. Cold data lives in a generational arena; hot data
/// in a plain array indexed by the same slot index, so the integrator walks
/// contiguous memory.
///
/// Determinism: iteration is in slot-index order (handle order).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct BodySet {
    cold: Arena<BodyCold>,
    hot: Vec<BodyHot>,
    /// Whether slot i is live (mirrors the arena, for the hot loops).
    live: Vec<bool>,
}

impl BodySet {
    /// Adds a body.
    pub(crate) fn insert(&mut self, hot: BodyHot, cold: BodyCold) -> BodyHandle {
        let h = self.cold.insert(cold);
        let i = h.index as usize;
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

    /// Calls `f` on every live body's hot and cold state, in handle order.
    pub(crate) fn for_each_mut(&mut self, mut f: impl FnMut(&mut BodyHot, &mut BodyCold)) {
        for (h, cold) in self.cold.iter_mut() {
            f(&mut self.hot[h.index as usize], cold);
        }
    }
}
