//! The contact solver: soft-step sequential impulses (after Box2D v3's
//! "soft step").
//!
//! Per tick, `prepare` builds a compact array of solver bodies (awake dynamic
//! and kinematic bodies that appear in a solid contact, in slot order;
//! static and sleeping bodies are an implicit zero-velocity, infinite-mass
//! body) and one constraint per solid pair with points, in the world's
//! contact order: pair order, or colour order (see [`color`]: no two
//! constraints of a colour share a moving dynamic body). Anchors
//! are taken relative to the body centres at the start of the tick, and the
//! effective masses are computed there once (the iteration loops never
//! divide). Then, per substep:
//!
//! 1. the integrator's velocity stage (outside this module);
//! 2. [`ContactSolver::warm_start`]: last impulses applied again;
//! 3. [`ContactSolver::solve`] with bias: a soft constraint (spring at
//!    `contact_hertz`, damping ratio `contact_damping_ratio`; stiffer, and
//!    visited more often, between bodies of a high mass ratio, see
//!    [`RATIO_KEPT`]) pushes
//!    overlaps apart at no more than `max_push_out` m/s; speculative points
//!    (a gap) allow the approach that just closes the gap in one substep;
//! 4. the integrator's position stage;
//! 5. [`ContactSolver::solve`] without bias (relax): removes the velocity
//!    the soft push-out added, so resting contacts do not bounce; its
//!    friction is bounded by the load its rigid rows settle. A contact hit
//!    this tick (see [`IMPACT_RELAX_PASSES`]) is visited three more times.
//!
//! A hit's normal rows, in both passes, are first solved together as one
//! block over its patch (see `Pass::hit_row`): where that meets every
//! row with impulses ≥ 0, the point rows are skipped, so the corner
//! visited first does not take the whole hit.
//!
//! After steps 3 and 5, [`ContactSolver::shock`] visits the high-ratio
//! contacts once more from the ground up, each with its lower body held
//! still (see [`shock`]), so a heavy body cannot sink through a light one.
//!
//! After the substeps, [`ContactSolver::restitution`] gives points that hit
//! faster than `restitution_threshold` their bounce, and
//! [`ContactSolver::store_impulses`] hands the accumulated impulses back to
//! the contact pairs for warm starting next tick.
//!
//! The current separation of a point during the substeps is its separation
//! at the start of the tick plus the relative displacement of its two
//! anchors along the normal, from each body's change of position and
//! orientation since the start of the tick: no narrow phase per substep.
//! On a round shape (sphere, capsule) the anchor is the point of its core
//! behind the contact, which a rolling body carries along, not the contact
//! point, which rolls away from the contact.
//!
//! Friction acts at the centre of each manifold's contact patch (see
//! [`Patch`]): two tangent rows, held together in the friction disc, and a
//! twist row per manifold, where per-point friction needs two rows per
//! point (eight for a box face). The closed-form friction tests
//! (core/tests/friction.rs: sliding in every direction, the slide-to-roll
//! transition, convergence under refinement; the ramp and the kinematic
//! platform) hold it to their bounds.
//!
//! Each point stores `r×n` and `I⁻¹(r×n)`, and each patch the same for its
//! two tangents, so an iteration reads a relative velocity as `d·Δv +
//! (rB×d)·ωB − (rA×d)·ωA` and applies the angular part of an impulse with
//! one scaling per body; the linear part is kept along the constraint's
//! basis through a visit and applied once at its end. No cross products,
//! inertia products or divisions in the loops, and only `v` and `ω` (a
//! 48-byte state per body) are read and written.
//!
//! Angular impulses go into each dynamic body's angular momentum
//! (`ΔL = Σ r × P`), summed once per substep from each point's net impulse
//! since the last write-back; the solver's angular velocity moves by
//! `I⁻¹_world ΔL` meanwhile. A body that no contact touches keeps `L` bit for
//! bit, and the world's total angular momentum changes only by rounding of
//! the contact impulses themselves.
//!
//! Products and sums in the iterations are rounded to nearest with ties
//! toward +∞ by the solver's own [`mul`] and [`round_wide`] (cheaper than
//! `Scalar`'s ties-away rounding; the same overflow faults).
//!
//! The files, by stage: this one holds the types the stages share (solver
//! bodies, constraints, points) and the passes' entry points; `prepare`
//! builds a tick's bodies and constraints; `pass` visits one constraint on
//! the Q32.32 rows, the narrow rows ([`narrow`], the scalar twin) or their
//! lanes (`narrow::lanes`); `iterate` walks the constraints in order or
//! colour by colour over the workers; `params` holds the tick's settings
//! and [`Softness`], which the joints share; `rows` the row arithmetic and
//! its rounding; `patch` the friction patch; `shock` the high-ratio pass;
//! `color` the colouring; `wide` the exact IFMA lanes.
//!
//! Determinism: bodies in slot (handle) order; constraints in pair order
//! (ascending collider handles), or colour by colour, the colours
//! recomputed each tick from the pairs in that order (the constraints of
//! one colour give the same results in any order, on any worker); points
//! in manifold order starting at point `k mod count` in substep `k` of the
//! tick.

mod arith;
mod color;
mod constraint;
mod iterate;
mod narrow;
mod params;
mod pass;
mod patch;
mod prepare;
mod quanta;
mod rows;
mod shock;
mod wide;

use iterate::*;
use params::*;
pub(crate) use params::{Softness, SolverParams, SolverStats};
use pass::*;

use color::{COLORS, Coloring};
use constraint::{BodyVel, Constraint, NONE, Pending, ShockRow, SolverBody};

use crate::workers::{SharedMut, Workers};

use narrow::NarrowRows;
use narrow::lanes::{Batch, Kernel};
use rows::{BodyArrays, angular_along, apply_linear, linear_basis, mul, push_angular};

use crate::body::BodyHot;
use crate::collision::{ContactPair, MAX_MANIFOLD_POINTS, PatchFriction, PointImpulse};
use crate::math::{Mat3, Scalar, Vec3};

/// The solver's buffers, kept by the world and reused every tick.
#[derive(Clone, Debug, Default)]
pub(crate) struct ContactSolver {
    bodies: Vec<SolverBody>,
    /// The velocity state of each solver body (same index as `bodies`).
    vels: Vec<BodyVel>,
    /// Angular impulse of each solver body since the last write-back.
    dls: Vec<Vec3>,
    /// The next substep's warm start, summed per solver body by the last
    /// relax pass (see [`ContactSolver::solve`]); zero otherwise.
    warm: Vec<BodyVel>,
    /// Whether `warm` holds the next warm start.
    warm_ready: bool,
    /// In a world on the narrow rows, each solver body's velocity in
    /// quanta during a pass, and its value when taken (see
    /// [`quanta::Quanta`]); empty otherwise.
    quanta: Vec<quanta::Quanta>,
    quanta0: Vec<quanta::Quanta>,
    /// In a world on the narrow rows, each solver body's pose change as
    /// the narrow separations read it (see [`narrow::PoseQ`]); empty
    /// otherwise.
    pq: Vec<narrow::PoseQ>,
    /// Slot → solver body index, or `NONE`. Only the slots of `bodies` hold
    /// an index, so a tick resets just those, never every slot.
    body_of_slot: Vec<u32>,
    /// The slots this tick's constraints touch, sorted into solver body
    /// order in `prepare`.
    touched: Vec<u32>,
    /// This tick's constraints in colour order (see [`color`]).
    constraints: Vec<Constraint>,
    /// Their narrow rows (same index; see [`narrow`]) in a world on the
    /// narrow rows, the first `rows_len` (the constraints' count, or 0 on
    /// the Q32.32 rows); entries past it are stale.
    rows: Vec<NarrowRows>,
    rows_len: usize,
    /// The colouring's buffers.
    coloring: Coloring,
    /// Per candidate pair, in pair order, what the first scan found
    /// (`prepare` only).
    pending: Vec<Pending>,
    /// Per constraint (colour order), its entry in `pending` (`prepare`
    /// only).
    placed: Vec<u32>,
    /// Where each colour's constraints start in `constraints` (colour `c`
    /// is `starts[c]..starts[c + 1]`, the overflow last).
    starts: [u32; COLORS + 2],
    /// Per solver body, the smallest inverse mass among it and the dynamic
    /// bodies it touches (`prepare` only).
    heaviest: Vec<Scalar>,
    /// The constraints with a high mass ratio (see [`RATIO_KEPT`]), which
    /// each pass visits [`HIGH_RATIO_PASSES`] more times.
    heavy: Vec<u32>,
    /// The other constraints with a point that approached faster than
    /// `restitution_threshold` at the tick's start (a hit), which each
    /// relax pass visits [`IMPACT_RELAX_PASSES`] more times.
    impact: Vec<u32>,
    /// Per solver body, its level for the shock pass (`prepare` only; see
    /// [`shock`]).
    level: Vec<u32>,
    /// The shock pass's visits, in order (see [`shock`]).
    shock: Vec<ShockRow>,
    /// Warm starts (substeps) since `prepare`: the point each manifold's
    /// solve starts from.
    substeps: u32,
    /// The bodies' poses as the solver last read them, numbered: 1 at
    /// `prepare`, one more at each [`gather`](Self::gather). A constraint
    /// whose `frame_poses` is this number has its separation frame and
    /// point separations at these poses.
    poses: u32,
    /// Whether the wide kernels are turned on (off by default; not
    /// simulation state: the same bits either way; see [`wide`]).
    wide_on: bool,
    /// Batches on the wide kernels and batches their guard refused, since
    /// the last [`take_lane_counts`](Self::take_lane_counts).
    lane_counts: wide::Tally,
    /// Narrow visits whose guard failed, since the last
    /// [`take_fallbacks`](Self::take_fallbacks).
    fallbacks: narrow::Fallbacks,
    /// The lanes' batches of this tick (entries past `lane_batches` are
    /// stale), and their count.
    batches: Vec<Batch>,
    lane_batches: u32,
    /// Whether the narrow rows' lanes are turned on (off by default; not
    /// simulation state: the same bits either way).
    lanes_on: bool,
}

/// What `prepare` needs to know about one pair: the body slots of its two
/// colliders and the combined material.
pub(crate) struct PairInfo {
    /// Slot of collider A's body.
    pub slot_a: u32,
    /// Slot of collider B's body.
    pub slot_b: u32,
    /// Combined friction coefficient.
    pub friction: Scalar,
    /// Combined restitution.
    pub restitution: Scalar,
    /// [`Shape::rounding`](crate::shape::Shape::rounding) of collider A's
    /// and B's shapes.
    pub rounding: [Scalar; 2],
}

impl ContactSolver {
    /// The build of the lane kernel the passes use.
    fn kernel(&self) -> Kernel {
        Kernel::best()
    }

    /// Turns the narrow rows' lanes on where the CPU has them (`true`), or
    /// off (the default: the scalar twin alone). Not simulation state: the
    /// same bits either way.
    pub(crate) fn set_lanes(&mut self, on: bool) {
        self.lanes_on = on;
    }

    /// Whether the narrow rows' lanes are on and the CPU has them, and
    /// which build runs.
    pub(crate) fn lanes(&self) -> Option<Kernel> {
        (self.lanes_on && self.kernel() != Kernel::Plain).then(|| self.kernel())
    }

    /// Turns the wide kernels on where the CPU has them (`true`), or off.
    /// Not simulation state: the results are the same bits.
    #[cfg(feature = "wide")]
    pub(crate) fn set_wide(&mut self, on: bool) {
        self.wide_on = on;
    }

    /// Whether the passes use the wide kernels: turned on, and the CPU has
    /// them.
    #[cfg(feature = "wide")]
    pub(crate) fn wide(&self) -> bool {
        self.wide_on && wide::available()
    }

    /// The batches of constraints whose normal rows ran on the wide
    /// kernels, and those their range guard sent to the scalar rows, since
    /// the last call.
    pub(crate) fn take_lane_counts(&self) -> wide::Counts {
        self.lane_counts.take()
    }

    /// The constraints moved from the narrow rows to the Q32.32 rows by a
    /// failed guard since the last call.
    pub(crate) fn take_fallbacks(&self) -> u32 {
        self.fallbacks.take()
    }

    /// Whether there is anything to solve this tick.
    pub(crate) fn is_empty(&self) -> bool {
        self.constraints.is_empty()
    }

    /// Reads the bodies' current velocities and pose changes (after the
    /// integrator touched them).
    pub(crate) fn gather(&mut self, hot: &[BodyHot], workers: &Workers) {
        // New poses: every cached separation frame is stale (a tick has a
        // few gathers, so the number never wraps to 0).
        self.poses = self.poses.wrapping_add(1).max(1);
        let len = self.bodies.len();
        let (bodies, vels) = (
            SharedMut::new(&mut self.bodies),
            SharedMut::new(&mut self.vels),
        );
        // In a world on the narrow rows, the pose changes as its
        // separations read them (one per solver body).
        let pq = SharedMut::new(&mut self.pq);
        workers.for_each_block(len, BODY_BLOCK, |r| {
            // SAFETY: each block goes to one worker alone.
            let (bodies, vels) = unsafe { (bodies.slice(r.clone()), vels.slice(r.clone())) };
            let pq = if pq.is_empty() {
                &mut []
            } else {
                // SAFETY: as above.
                unsafe { pq.slice(r) }
            };
            for (sb, vel) in bodies.iter_mut().zip(vels) {
                let b = &hot[sb.slot as usize];
                vel.v = b.linear_velocity;
                vel.w = b.angular_velocity;
                sb.dp = b.center - sb.center0;
                sb.dr = Mat3::from_quat(b.rotation * sb.rotation0_inv);
            }
            for (sb, pq) in bodies.iter().zip(pq) {
                *pq = narrow::PoseQ::of(sb.dp, &sb.dr);
            }
        });
    }

    /// Reads only the velocities (the poses did not change since the last
    /// [`gather`](Self::gather)).
    pub(crate) fn gather_velocities(&mut self, hot: &[BodyHot], workers: &Workers) {
        let len = self.bodies.len();
        let (bodies, vels) = (&self.bodies, SharedMut::new(&mut self.vels));
        workers.for_each_block(len, BODY_BLOCK, |r| {
            // SAFETY: each block goes to one worker alone.
            let vels = unsafe { vels.slice(r.clone()) };
            for (sb, vel) in bodies[r].iter().zip(vels) {
                let b = &hot[sb.slot as usize];
                vel.v = b.linear_velocity;
                vel.w = b.angular_velocity;
            }
        });
    }

    /// Writes the solved velocities back, leaving the angular momenta for
    /// the next [`scatter`](Self::scatter): between a solve pass and the
    /// relax pass of one substep only the position integration runs, and it
    /// reads `ω`, not `L`.
    pub(crate) fn scatter_velocities(&self, hot: &mut [BodyHot], workers: &Workers) {
        let (bodies, vels) = (&self.bodies, &self.vels);
        let hot = SharedMut::new(hot);
        workers.for_each_block(bodies.len(), BODY_BLOCK, |r| {
            for (sb, vel) in bodies[r.clone()].iter().zip(&vels[r]) {
                if sb.dynamic {
                    // SAFETY: solver bodies have distinct slots, and each
                    // block goes to one worker alone.
                    let b = unsafe { hot.get(sb.slot as usize) };
                    b.linear_velocity = vel.v;
                    b.angular_velocity = vel.w;
                }
            }
        });
    }

    /// Writes the solved velocities back, and the angular impulses summed
    /// since the last `scatter` (by the relax and restitution passes, see
    /// [`Constraint::collect_angular`]) into the angular momenta.
    pub(crate) fn scatter(&mut self, hot: &mut [BodyHot], workers: &Workers) {
        let (bodies, vels) = (&self.bodies, &self.vels);
        let dls = SharedMut::new(&mut self.dls);
        let hot = SharedMut::new(hot);
        workers.for_each_block(bodies.len(), BODY_BLOCK, |r| {
            // SAFETY: each block goes to one worker alone.
            let dls = unsafe { dls.slice(r.clone()) };
            for ((sb, vel), dl) in bodies[r.clone()].iter().zip(&vels[r]).zip(dls) {
                let dl = std::mem::take(dl);
                if !sb.dynamic {
                    continue;
                }
                // SAFETY: solver bodies have distinct slots, and each block
                // goes to one worker alone.
                let b = unsafe { hot.get(sb.slot as usize) };
                b.linear_velocity = vel.v;
                b.angular_velocity = vel.w;
                b.angular_momentum += dl;
            }
        });
    }

    /// Gives every loaded lanes' batch's state back to its rows (see
    /// `narrow::lanes::Batch`).
    fn unload_batches(&mut self) {
        let rows = &mut self.rows[..self.rows_len];
        for batch in &mut self.batches[..self.lane_batches as usize] {
            if let Some(r) = batch.loaded() {
                batch.unload(&mut rows[r]);
            }
        }
    }

    /// Applies last substep's (or last tick's) accumulated impulses again:
    /// the sums the last relax pass left in `warm` if it made them, else a
    /// pass over the constraints.
    pub(crate) fn warm_start(&mut self, workers: &Workers) {
        self.substeps = self.substeps.wrapping_add(1);
        if std::mem::take(&mut self.warm_ready) {
            let len = self.vels.len();
            let (vels, warm) = (
                SharedMut::new(&mut self.vels),
                SharedMut::new(&mut self.warm),
            );
            workers.for_each_block(len, BODY_BLOCK, |r| {
                // SAFETY: each block goes to one worker alone.
                let (vels, warm) = unsafe { (vels.slice(r.clone()), warm.slice(r)) };
                for (vel, w) in vels.iter_mut().zip(warm) {
                    let w = std::mem::take(w);
                    vel.v += w.v;
                    vel.w += w.w;
                }
            });
            return;
        }
        // The twin's warm start reads the rows.
        self.unload_batches();
        // SAFETY: the pass visits one colour at a time (`for_each_colored`).
        let arrays = unsafe { BodyArrays::new(&mut self.vels, &mut self.dls, &mut self.warm) };
        let visit = |c: &mut Constraint, r: Option<&mut NarrowRows>| {
            let (mut va, mut vb) = arrays.load(c.a, c.b);
            if let Some(r) = r.filter(|r| r.on) {
                let (da, db) = narrow::warm_start(r);
                (va.v, va.w, vb.v, vb.w) = (va.v + da.v, va.w + da.w, vb.v + db.v, vb.w + db.w);
            } else {
                c.warm_start(&mut va, &mut vb);
            }
            arrays.store(c.wa, c.wb, va, vb);
        };
        for_each_colored(
            &mut self.constraints,
            &mut self.rows[..self.rows_len],
            &self.starts,
            workers,
            one_by_one(visit),
        );
    }

    /// One pass over every constraint: the normal impulses (soft with
    /// `use_bias`, rigid without), then friction.
    ///
    /// The relax pass (`use_bias == false`) also sums each constraint's
    /// angular impulses into its bodies' write-back (one pass over the
    /// constraints fewer than a separate sum: the sums are exact integer
    /// additions, so their order does not change the result).
    ///
    /// With `warm_next` (a relax pass with a substep after it) it also sums
    /// each constraint's warm start of the next substep into `warm`, while
    /// the constraint is at hand: its impulses are final once its visit
    /// ends, and the warm start's changes do not depend on the velocities
    /// (see [`Constraint::warm_start`]), so [`warm_start`](Self::warm_start)
    /// then adds the sums instead of reading every constraint again: the
    /// same bits. Not when the high-ratio visits, the hits' visits or the
    /// shock pass change impulses after the pass.
    pub(crate) fn solve(
        &mut self,
        params: &SolverParams,
        use_bias: bool,
        warm_next: bool,
        workers: &Workers,
    ) {
        let fuse = warm_next
            && !use_bias
            && self.heavy.is_empty()
            && self.impact.is_empty()
            && self.shock.is_empty();
        // SAFETY: the pass visits one colour at a time (`for_each_colored`),
        // then the heavy constraints on this thread alone.
        // On the narrow rows, the velocities are in quanta for the pass.
        let quanta = self.rows_len > 0;
        if quanta {
            quanta::quantize(&self.vels, &mut self.quanta, &mut self.quanta0);
        }
        let mut arrays = unsafe { BodyArrays::new(&mut self.vels, &mut self.dls, &mut self.warm) };
        if quanta {
            // SAFETY: as above.
            arrays = unsafe { arrays.with_quanta(&mut self.quanta, &mut self.quanta0) };
        }
        let kernel = if params.narrow && self.lane_batches > 0 {
            self.lanes()
        } else {
            None
        };
        let pass = Pass {
            params,
            use_bias,
            fuse,
            // Substep k starts each manifold's points at point k (mod
            // count), forward in even substeps and backward in odd ones
            // (`constraint::row_order`, which says why).
            rot: self.substeps as usize,
            bodies: &self.bodies,
            pq: &self.pq,
            arrays,
            // The wide kernels are the Q32.32 rows' lanes.
            lanes: self.wide_on && wide::available() && !params.narrow,
            poses: self.poses,
            fallbacks: &self.fallbacks,
            kernel,
            batches: SharedMut::new(&mut self.batches[..self.lane_batches as usize]),
        };
        let counts = &self.lane_counts;
        let run = |cs: &mut [Constraint], rs: &mut [NarrowRows], independent: bool| {
            if independent && pass.lanes {
                counts.add(pass.visit_batches(cs, rs));
            } else if let (true, Some(kernel)) = (independent, pass.kernel) {
                pass.visit_narrow_run(cs, rs, kernel);
            } else {
                for_each_prefetched(cs, rs, |c, r| pass.visit(c, r));
            }
        };
        let rows = &mut self.rows[..self.rows_len];
        for_each_colored(&mut self.constraints, rows, &self.starts, workers, run);
        self.warm_ready = fuse;
        if quanta {
            quanta::flush(&mut self.vels, &self.quanta, &mut self.quanta0);
        }
        for _ in 0..HIGH_RATIO_PASSES {
            for &i in &self.heavy {
                // The high-ratio constraints are on the Q32.32 rows.
                pass.visit_exact(&mut self.constraints[i as usize]);
            }
        }
        if !use_bias {
            for _ in 0..IMPACT_RELAX_PASSES {
                for &i in &self.impact {
                    // So are the hits.
                    pass.visit_exact(&mut self.constraints[i as usize]);
                }
            }
        }
    }

    /// Step 5 of [`prepare`](Self::prepare): the hits of this tick, the
    /// constraints (not high-ratio ones) with a point whose normal velocity
    /// at the tick's start approaches faster than `restitution_threshold`.
    /// Like the high-ratio contacts they go to the Q32.32 rows for the
    /// tick: returns how many of them were on the narrow rows.
    fn find_impacts(&mut self, params: &SolverParams) -> u32 {
        let mut left_narrow = 0;
        self.impact.clear();
        let threshold = -params.restitution_threshold;
        let mut heavy = self.heavy.iter().peekable();
        for (i, c) in self.constraints.iter_mut().enumerate() {
            if heavy.next_if_eq(&&(i as u32)).is_some() {
                continue;
            }
            let count = c.count.min(MAX_MANIFOLD_POINTS);
            if c.points[..count]
                .iter()
                .any(|cp| cp.relative_velocity < threshold)
            {
                c.hit = true;
                self.impact.push(i as u32);
                if let Some(r) = self.rows[..self.rows_len].get_mut(i) {
                    left_narrow += u32::from(std::mem::take(&mut r.on));
                }
            }
        }
        left_narrow
    }

    /// Step 4 of [`prepare`](Self::prepare) for a scene with high mass
    /// ratios: each contact's spring and the high-ratio list (see
    /// [`RATIO_KEPT`]). The high-ratio contacts go to the Q32.32 rows (the
    /// shock pass and their extra visits work on their Q32.32 impulses):
    /// returns how many of them were on the narrow rows.
    fn assign_ratio_springs(&mut self, params: &SolverParams) -> u32 {
        let mut left_narrow = 0;
        self.heaviest.clear();
        self.heaviest.extend(
            self.bodies
                .iter()
                .map(|b| if b.dynamic { b.inv_mass } else { Scalar::MAX }),
        );
        for c in &self.constraints {
            let (ia, ib) = (c.inv_mass_a, c.inv_mass_b);
            if c.a != NONE && ib.is_positive() {
                let h = &mut self.heaviest[c.a as usize];
                *h = (*h).min(ib);
            }
            if c.b != NONE && ia.is_positive() {
                let h = &mut self.heaviest[c.b as usize];
                *h = (*h).min(ia);
            }
        }
        for (i, c) in self.constraints.iter_mut().enumerate() {
            let mut lo = Scalar::MAX;
            for x in [c.a, c.b] {
                if x != NONE {
                    lo = lo.min(self.heaviest[x as usize]);
                }
            }
            let hi = c.inv_mass_a.max(c.inv_mass_b);
            let (soft, high) = Softness::for_ratio(params, lo, hi);
            // Only between two dynamic bodies: stiffening the static
            // contact under a light body as well (both its contacts stiff)
            // let a box 1,000 times heavier through it.
            let both = c.inv_mass_a.is_positive() && c.inv_mass_b.is_positive();
            c.softness = if both { soft } else { params.softness };
            if high {
                self.heavy.push(i as u32);
                if let Some(r) = self.rows[..self.rows_len].get_mut(i) {
                    left_narrow += u32::from(std::mem::take(&mut r.on));
                }
            }
        }
        left_narrow
    }

    /// After the substeps: points that approached faster than the threshold
    /// and pushed get the normal velocity `−e·v_before`.
    pub(crate) fn restitution(&mut self, params: &SolverParams, workers: &Workers) {
        // The write-back below reads the rows.
        self.unload_batches();
        // SAFETY: the pass visits one colour at a time (`for_each_colored`).
        let arrays = unsafe { BodyArrays::new(&mut self.vels, &mut self.dls, &mut self.warm) };
        let threshold = -params.restitution_threshold;
        let bodies = &self.bodies;
        let visit = |c: &mut Constraint, r: Option<&mut NarrowRows>| {
            // The narrow rows' impulses back in Q32.32 (here, where the
            // constraint is at hand anyway): restitution and the stored
            // impulses read them.
            if let Some(r) = r.filter(|r| r.on) {
                r.on = false;
                narrow::write_back(r, c);
            }
            if c.restitution.is_zero() {
                return;
            }
            let (mut va, mut vb) = arrays.load(c.a, c.b);
            let mut un = linear_basis(c, &va, &vb)[0];
            let mut applied = Scalar::ZERO;
            let both = (c.a != NONE && c.b != NONE)
                .then(|| (&bodies[c.a as usize], &bodies[c.b as usize]))
                .filter(|(a, b)| a.dynamic && b.dynamic);
            for cp in &mut c.points[..c.count] {
                if cp.relative_velocity > threshold || cp.max_normal_impulse.is_zero() {
                    continue;
                }
                let arms = both.map(|(ba, bb)| common_point_arms(c.normal, c.rounding, cp, ba, bb));
                let (ra_n, rb_n, ia_n, ib_n, mass) = match arms {
                    Some(x) => x,
                    None => (cp.ra_n, cp.rb_n, cp.ia_n, cp.ib_n, cp.normal_mass),
                };
                let vn = un + angular_along(&va, &vb, ra_n, rb_n);
                let lambda = -(mass * (vn + c.restitution * cp.relative_velocity));
                let old = cp.normal_impulse;
                let new = (old + lambda).max(Scalar::ZERO);
                let d = new - old;
                cp.normal_impulse = new;
                cp.max_normal_impulse = cp.max_normal_impulse.max(new);
                if !d.is_zero() {
                    un += mul(c.inv_mass_sum, d);
                    applied += d;
                    push_angular(&mut va, &mut vb, c.a, c.b, d, ia_n, ib_n);
                    if arms.is_some() {
                        // Its angular impulse goes in here, at these arms.
                        cp.mark += d;
                        arrays.add_dl(c.wa, -arith::scale(ra_n, d));
                        arrays.add_dl(c.wb, arith::scale(rb_n, d));
                    }
                }
            }
            apply_linear(c, &mut va, &mut vb, [applied, Scalar::ZERO, Scalar::ZERO]);
            arrays.store(c.wa, c.wb, va, vb);
            c.collect_angular(&arrays);
        };
        for_each_colored(
            &mut self.constraints,
            &mut self.rows[..self.rows_len],
            &self.starts,
            workers,
            one_by_one(visit),
        );
    }

    /// Hands the accumulated impulses back to the pairs (warm starting next
    /// tick).
    ///
    /// In blocks of constraints over the workers: each constraint writes
    /// its own pair (`prepare` makes at most one constraint per pair).
    pub(crate) fn store_impulses(&self, pairs: &mut [ContactPair], workers: &Workers) {
        let constraints = &self.constraints;
        let pairs = SharedMut::new(pairs);
        workers.for_each_block(constraints.len(), STORE_BLOCK, |r| {
            for c in &constraints[r] {
                // SAFETY: no other constraint holds this pair (above), and
                // each block goes to one worker alone.
                let p = unsafe { pairs.get(c.pair as usize) };
                for (k, cp) in c.points[..c.count].iter().enumerate() {
                    p.impulses[k] = PointImpulse {
                        normal: cp.normal_impulse,
                    };
                }
                p.friction = PatchFriction {
                    tangent: c.patch.tangent_impulse,
                    twist: c.patch.twist_impulse,
                };
            }
        });
    }
}

/// The arms of point `cp` from the centres of two moving bodies `a` and
/// `b` to one common point now: the midpoint of the point's two material
/// points (each carried with its body since the tick's start). Equal and
/// opposite impulses there change the bodies' total angular momentum by
/// nothing. Returns `r×n` and `I⁻¹(r×n)` of each and the effective mass.
fn common_point_arms(
    n: Vec3,
    rounding: [Scalar; 2],
    cp: &constraint::ConstraintPoint,
    a: &SolverBody,
    b: &SolverBody,
) -> (Vec3, Vec3, Vec3, Vec3, Scalar) {
    // The arms to the contact point at the tick's start (without the
    // rounding's offset).
    let ra = cp.ra + arith::scale(n, rounding[0]);
    let rb = cp.rb - arith::scale(n, rounding[1]);
    // B's centre from A's now.
    let d = (b.center0 + b.dp) - (a.center0 + a.dp);
    let ra_now = (a.dr.mul_vec(ra) + d + b.dr.mul_vec(rb)).half();
    let rb_now = ra_now - d;
    let ra_n = arith::cross(ra_now, n);
    let rb_n = arith::cross(rb_now, n);
    let ia_n = a.inv_inertia_mul(ra_n);
    let ib_n = b.inv_inertia_mul(rb_n);
    let k = rows::effective(a, b, ra_n, rb_n, ia_n, ib_n);
    (ra_n, rb_n, ia_n, ib_n, arith::inverse_or_zero(k))
}
