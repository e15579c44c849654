//! `Arena`: generational slots, the storage behind every handle.
//!
//! A handle is `{index, generation}`. Removing an item bumps its slot's
//! generation, so stale handles are refused instead of aliasing a new item.
//!
//! Determinism: freed slots are reused last-freed-first, and iteration runs
//! in slot-index order. Both depend only on the sequence of inserts and
//! removals, never on addresses or hashing, so every peer that performs the
//! same operations gets the same handles and the same iteration order.

use serde::{Deserialize, Serialize};

/// A raw generational index.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct RawHandle {
    /// Slot index.
    pub index: u32,
    /// Generation of the slot when the handle was issued (starts at 1, so
    /// a zeroed handle is never valid).
    pub generation: u32,
}

#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
struct Slot<T> {
    generation: u32,
    value: Option<T>,
}

/// A generational slot map with deterministic reuse and iteration order.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Arena<T> {
    slots: Vec<Slot<T>>,
    free: Vec<u32>,
    len: usize,
}

impl<T> Default for Arena<T> {
    fn default() -> Self {
        Arena {
            slots: Vec::new(),
            free: Vec::new(),
            len: 0,
        }
    }
}

impl<T> Arena<T> {
    /// Inserts a value and returns its handle.
    pub fn insert(&mut self, value: T) -> RawHandle {
        self.len += 1;
        if let Some(index) = self.free.pop() {
            let slot = &mut self.slots[index as usize];
            slot.value = Some(value);
            RawHandle {
                index,
                generation: slot.generation,
            }
        } else {
            let index = self.slots.len() as u32;
            self.slots.push(Slot {
                generation: 1,
                value: Some(value),
            });
            RawHandle {
                index,
                generation: 1,
            }
        }
    }

    /// Removes and returns the value, or `None` for a stale handle.
    pub fn remove(&mut self, h: RawHandle) -> Option<T> {
        let slot = self.slots.get_mut(h.index as usize)?;
        if slot.generation != h.generation {
            return None;
        }
        let value = slot.value.take()?;
        slot.generation = slot.generation.wrapping_add(1).max(1);
        self.free.push(h.index);
        self.len -= 1;
        Some(value)
    }

    /// The value behind a live handle.
    #[inline]
    pub fn get(&self, h: RawHandle) -> Option<&T> {
        let slot = self.slots.get(h.index as usize)?;
        if slot.generation == h.generation {
            slot.value.as_ref()
        } else {
            None
        }
    }

    /// The value behind a live handle, mutably.
    #[inline]
    pub fn get_mut(&mut self, h: RawHandle) -> Option<&mut T> {
        let slot = self.slots.get_mut(h.index as usize)?;
        if slot.generation == h.generation {
            slot.value.as_mut()
        } else {
            None
        }
    }

    /// The value in slot `index`, if live (no generation check: for code
    /// that walks slots in order).
    #[inline]
    pub fn get_by_index(&self, index: u32) -> Option<&T> {
        self.slots
            .get(index as usize)
            .and_then(|s| s.value.as_ref())
    }

    /// The value in slot `index`, mutably, if live.
    #[inline]
    pub fn get_by_index_mut(&mut self, index: u32) -> Option<&mut T> {
        self.slots
            .get_mut(index as usize)
            .and_then(|s| s.value.as_mut())
    }

    /// The handle of the live value in slot `index`.
    pub fn handle_at(&self, index: u32) -> Option<RawHandle> {
        let slot = self.slots.get(index as usize)?;
        slot.value.as_ref().map(|_| RawHandle {
            index,
            generation: slot.generation,
        })
    }

    /// How many slots were ever used (live or free).
    pub fn slot_count(&self) -> usize {
        self.slots.len()
    }

    /// Number of live values.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether no value is live.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Number of slots (live or free): the bound for per-slot side arrays.
    pub fn capacity_slots(&self) -> usize {
        self.slots.len()
    }

    /// Checks the internal invariants a decoded arena must satisfy (free
    /// slots are in range, empty and listed once; the count matches).
    pub fn check(&self) -> Result<(), String> {
        let live = self.slots.iter().filter(|s| s.value.is_some()).count();
        if live != self.len {
            return Err(format!(
                "arena counts {} live items but holds {live}",
                self.len
            ));
        }
        let mut seen = vec![false; self.slots.len()];
        for &i in &self.free {
            let slot = self.slots.get(i as usize).ok_or("free slot out of range")?;
            if slot.value.is_some() || std::mem::replace(&mut seen[i as usize], true) {
                return Err(format!("free list entry {i} is live or repeated"));
            }
        }
        if self.free.len() + live != self.slots.len() {
            return Err("free list does not cover every empty slot".into());
        }
        Ok(())
    }

    /// Live values with their handles, in slot-index order.
    pub fn iter(&self) -> impl Iterator<Item = (RawHandle, &T)> {
        self.slots.iter().enumerate().filter_map(|(i, s)| {
            s.value.as_ref().map(|v| {
                (
                    RawHandle {
                        index: i as u32,
                        generation: s.generation,
                    },
                    v,
                )
            })
        })
    }

    /// Live values mutably with their handles, in slot-index order.
    pub fn iter_mut(&mut self) -> impl Iterator<Item = (RawHandle, &mut T)> {
        self.slots.iter_mut().enumerate().filter_map(|(i, s)| {
            let generation = s.generation;
            s.value.as_mut().map(|v| {
                (
                    RawHandle {
                        index: i as u32,
                        generation,
                    },
                    v,
                )
            })
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stale_handles_are_refused_and_slots_reused_last_freed_first() {
        let mut a = Arena::default();
        let h0 = a.insert("a");
        let h1 = a.insert("b");
        let h2 = a.insert("c");
        assert_eq!(a.remove(h1), Some("b"));
        assert_eq!(a.remove(h0), Some("a"));
        assert_eq!(a.get(h1), None);
        let h3 = a.insert("d");
        assert_eq!(h3.index, 0);
        assert_eq!(h3.generation, 2);
        let h4 = a.insert("e");
        assert_eq!(h4.index, 1);
        assert_eq!(a.get(h0), None);
        assert_eq!(a.remove(h0), None);
        let order: Vec<_> = a.iter().map(|(_, v)| *v).collect();
        assert_eq!(order, ["d", "e", "c"]);
        assert_eq!(a.len(), 3);
        assert_eq!(a.get(h2), Some(&"c"));
    }
}
