//! Sticky arithmetic-fault flags.
//!
//! Fixed-point arithmetic can overflow, and a division by zero or the square
//! root of a negative number has no answer. None of these may panic (a peer
//! that panics has desynced) and none may pass silently. Every operation in
//! the math module that can fail returns a deterministic value (saturated, or
//! zero where documented) and raises a flag here.
//!
//! The flags live in a thread-local cell so that the arithmetic operators need
//! no context argument. A [`World`](crate::World) brackets each `step()` with
//! [`FaultScope`], so the faults of one step are attributed to that world and
//! reported in its [`StepReport`](crate::StepReport), even when several worlds
//! share a thread. Reading the cell only happens on the cold path (a fault);
//! the hot path pays one predictable branch.

use std::cell::Cell;

use serde::{Deserialize, Serialize};

/// A set of arithmetic faults, as bits.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Faults(u8);

impl Faults {
    /// No fault.
    pub const NONE: Faults = Faults(0);
    /// A result did not fit in Q32.32 (or an intermediate in i128) and was
    /// saturated.
    pub const OVERFLOW: Faults = Faults(1);
    /// A division by zero was attempted; the result was saturated.
    pub const DIV_BY_ZERO: Faults = Faults(2);
    /// The square root (or reciprocal square root) of a negative number, or
    /// the reciprocal square root of zero, was asked for.
    pub const DOMAIN: Faults = Faults(4);

    /// Whether no fault is set.
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// Whether every fault in `other` is set in `self`.
    pub const fn contains(self, other: Faults) -> bool {
        self.0 & other.0 == other.0
    }

    /// The union of two sets.
    pub const fn union(self, other: Faults) -> Faults {
        Faults(self.0 | other.0)
    }

    /// The raw bits (stable: used in snapshots and hashes).
    pub const fn bits(self) -> u8 {
        self.0
    }

    /// Builds a set from raw bits, dropping unknown bits.
    pub const fn from_bits(bits: u8) -> Faults {
        Faults(bits & 7)
    }
}

impl std::fmt::Display for Faults {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.is_empty() {
            return f.write_str("none");
        }
        let mut first = true;
        for (flag, name) in [
            (Faults::OVERFLOW, "overflow"),
            (Faults::DIV_BY_ZERO, "division by zero"),
            (Faults::DOMAIN, "domain error"),
        ] {
            if self.contains(flag) {
                if !first {
                    f.write_str(", ")?;
                }
                f.write_str(name)?;
                first = false;
            }
        }
        Ok(())
    }
}

thread_local! {
    static FAULTS: Cell<u8> = const { Cell::new(0) };
}

/// Raises `fault` in the current thread's sticky set. Cold: only called when
/// something went wrong.
#[cold]
#[inline(never)]
pub fn raise(fault: Faults) {
    FAULTS.with(|c| c.set(c.get() | fault.0));
}

/// The faults raised on this thread since the last [`take`].
pub fn peek() -> Faults {
    FAULTS.with(|c| Faults(c.get()))
}

/// Returns and clears the faults raised on this thread.
pub fn take() -> Faults {
    FAULTS.with(|c| Faults(c.replace(0)))
}

/// Brackets a computation whose faults must be attributed to one owner.
///
/// `enter()` saves and clears the thread's flags; `finish()` returns the
/// faults raised inside the scope and restores the saved ones (merged with
/// nothing from the scope), so nesting scopes never loses or misattributes a
/// fault.
#[derive(Debug)]
pub struct FaultScope {
    saved: u8,
}

impl FaultScope {
    /// Starts a scope.
    pub fn enter() -> FaultScope {
        FaultScope {
            saved: take().bits(),
        }
    }

    /// Ends the scope, returning the faults raised inside it.
    pub fn finish(self) -> Faults {
        let inside = take();
        FAULTS.with(|c| c.set(self.saved));
        inside
    }

    /// Runs `f` in a scope and returns its value with the faults it raised.
    pub fn run<T>(f: impl FnOnce() -> T) -> (T, Faults) {
        let scope = FaultScope::enter();
        let value = f();
        (value, scope.finish())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scopes_attribute_faults_to_the_inner_computation_only() {
        take();
        raise(Faults::DOMAIN);
        let ((), inner) = FaultScope::run(|| raise(Faults::OVERFLOW));
        assert_eq!(inner, Faults::OVERFLOW);
        assert_eq!(take(), Faults::DOMAIN);
    }

    #[test]
    fn display_names_every_fault() {
        let all = Faults::OVERFLOW
            .union(Faults::DIV_BY_ZERO)
            .union(Faults::DOMAIN);
        assert_eq!(all.to_string(), "overflow, division by zero, domain error");
        assert_eq!(Faults::NONE.to_string(), "none");
    }
}
