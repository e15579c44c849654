//! A fixed-capacity map from tick to value, stored at `tick % capacity`.
//!
//! Every piece of per-tick state in the room and the session lives in one of
//! these instead of a growing map, so a match that runs for hours uses the
//! same memory as one that runs for seconds. Each entry remembers its tick, so
//! a stale entry left behind by an old tick is never mistaken for a new one.

/// Fixed-capacity tick-indexed storage; inserting tick `t` evicts whatever
/// tick shared its slot (`t - capacity`, or older).
#[derive(Debug, Clone)]
pub(crate) struct TickRing<T> {
    slots: Vec<Option<(u64, T)>>,
}

impl<T> TickRing<T> {
    /// A ring holding `capacity` ticks (at least one).
    pub(crate) fn new(capacity: usize) -> Self {
        let capacity = capacity.max(1);
        let mut slots = Vec::with_capacity(capacity);
        slots.resize_with(capacity, || None);
        Self { slots }
    }

    /// Number of ticks the ring can hold at once.
    pub(crate) fn capacity(&self) -> usize {
        self.slots.len()
    }

    fn index(&self, tick: u64) -> usize {
        // The remainder is below the capacity, which is a usize.
        (tick % self.slots.len() as u64) as usize
    }

    /// The value stored for `tick`, if that exact tick is present.
    pub(crate) fn get(&self, tick: u64) -> Option<&T> {
        match &self.slots[self.index(tick)] {
            Some((t, v)) if *t == tick => Some(v),
            _ => None,
        }
    }

    /// Mutable access to the value stored for `tick`.
    pub(crate) fn get_mut(&mut self, tick: u64) -> Option<&mut T> {
        let i = self.index(tick);
        match &mut self.slots[i] {
            Some((t, v)) if *t == tick => Some(v),
            _ => None,
        }
    }

    /// Whether `tick` is present.
    pub(crate) fn contains(&self, tick: u64) -> bool {
        self.get(tick).is_some()
    }

    /// Stores `value` for `tick`, returning the entry it replaced (the same
    /// tick, or an older tick that shared the slot).
    pub(crate) fn insert(&mut self, tick: u64, value: T) -> Option<(u64, T)> {
        let i = self.index(tick);
        self.slots[i].replace((tick, value))
    }

    /// Removes and returns the value for `tick`, if present.
    pub(crate) fn remove(&mut self, tick: u64) -> Option<T> {
        let i = self.index(tick);
        match &self.slots[i] {
            Some((t, _)) if *t == tick => self.slots[i].take().map(|(_, v)| v),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::TickRing;

    #[test]
    fn insert_evicts_the_tick_one_capacity_older_and_nothing_else() {
        let mut r = TickRing::new(4);
        for t in 0..4u64 {
            assert!(r.insert(t, t * 10).is_none());
        }
        assert_eq!(r.insert(5, 50), Some((1, 10)));
        assert_eq!(r.get(1), None);
        assert_eq!(r.get(5), Some(&50));
        assert_eq!(r.get(0), Some(&0));
        assert_eq!(r.get(9), None, "tick 9 shares tick 5's slot but is absent");
    }

    #[test]
    fn remove_only_takes_the_exact_tick() {
        let mut r = TickRing::new(3);
        r.insert(7, 'a');
        assert_eq!(r.remove(4), None);
        assert_eq!(r.remove(10), None);
        assert_eq!(r.remove(7), Some('a'));
        assert!(!r.contains(7));
        r.insert(8, 'b');
        assert!(r.contains(8));
        assert_eq!(r.capacity(), 3);
    }

    #[test]
    fn zero_capacity_is_raised_to_one() {
        let mut r = TickRing::new(0);
        assert_eq!(r.capacity(), 1);
        r.insert(u64::MAX, 1u8);
        assert_eq!(r.get(u64::MAX), Some(&1));
        if let Some(v) = r.get_mut(u64::MAX) {
            *v = 2;
        }
        assert_eq!(r.insert(3, 3), Some((u64::MAX, 2)));
    }
}
