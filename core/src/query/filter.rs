//! [`QueryFilter`]: which colliders a scene query may report.

use crate::body::BodyHandle;
use crate::collider::{Collider, ColliderHandle};

/// A caller-supplied test run on each candidate that passed the bit and body
/// tests: return `false` to skip the collider.
///
/// It must be a pure function of its arguments (it is called in an order
/// that depends on the broad-phase trees, and not for every collider).
pub type QueryPredicate<'a> = &'a dyn Fn(ColliderHandle, &Collider) -> bool;

/// Which colliders a scene query considers.
///
/// A collider `c` is considered when all of these hold, tested in this order:
/// 1. bits: `c.filter.category & self.mask != 0` and
///    `self.category & c.filter.mask != 0` (the query behaves like a collider
///    with these bits; collision groups are ignored, a query has none);
/// 2. `c`'s body is not in `exclude_bodies` (a character casting from inside
///    its own capsule excludes itself);
/// 3. `c` is not a trigger, unless `include_triggers`;
/// 4. `predicate`, if any, returns `true`.
///
/// The default (category 1, mask all bits, nothing excluded, no triggers,
/// no predicate) considers every solid collider whose mask accepts
/// category 1, i.e. every collider with the default [`CollisionFilter`](crate::CollisionFilter).
#[derive(Clone, Copy)]
pub struct QueryFilter<'a> {
    /// The categories the query belongs to (tested against colliders' masks).
    pub category: u32,
    /// The collider categories the query reports.
    pub mask: u32,
    /// Bodies whose colliders are never reported.
    pub exclude_bodies: &'a [BodyHandle],
    /// Whether trigger colliders are reported.
    pub include_triggers: bool,
    /// A last, caller-defined test.
    pub predicate: Option<QueryPredicate<'a>>,
}

impl Default for QueryFilter<'_> {
    fn default() -> Self {
        QueryFilter {
            category: 1,
            mask: u32::MAX,
            exclude_bodies: &[],
            include_triggers: false,
            predicate: None,
        }
    }
}

impl std::fmt::Debug for QueryFilter<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("QueryFilter")
            .field("category", &self.category)
            .field("mask", &self.mask)
            .field("exclude_bodies", &self.exclude_bodies)
            .field("include_triggers", &self.include_triggers)
            .field("predicate", &self.predicate.map(|_| "fn"))
            .finish()
    }
}

impl<'a> QueryFilter<'a> {
    /// The default filter (see the type's documentation).
    pub fn new() -> QueryFilter<'a> {
        QueryFilter::default()
    }

    /// Sets the query's category and mask bits.
    pub fn bits(mut self, category: u32, mask: u32) -> QueryFilter<'a> {
        self.category = category;
        self.mask = mask;
        self
    }

    /// Skips the colliders of these bodies.
    pub fn exclude(mut self, bodies: &'a [BodyHandle]) -> QueryFilter<'a> {
        self.exclude_bodies = bodies;
        self
    }

    /// Reports triggers too (or not).
    pub fn triggers(mut self, include: bool) -> QueryFilter<'a> {
        self.include_triggers = include;
        self
    }

    /// Adds a caller-defined test.
    pub fn predicate(mut self, p: QueryPredicate<'a>) -> QueryFilter<'a> {
        self.predicate = Some(p);
        self
    }

    /// Whether the query considers collider `c` (handle `h`).
    pub fn accepts(&self, h: ColliderHandle, c: &Collider) -> bool {
        c.filter.category & self.mask != 0
            && self.category & c.filter.mask != 0
            && !self.exclude_bodies.contains(&c.body)
            && (self.include_triggers || !c.is_trigger)
            && self.predicate.is_none_or(|p| p(h, c))
    }
}
