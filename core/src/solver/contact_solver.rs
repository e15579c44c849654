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
//!    the soft push-out added, so resting contacts do not bounce.
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

mod color;
mod iterate;
mod narrow;
mod params;
mod pass;
mod patch;
mod prepare;
mod rows;
mod shock;
mod wide;

use iterate::*;
use params::*;
pub(crate) use params::{Softness, SolverParams, SolverStats};
use pass::*;
use prepare::*;

use color::{COLORS, Coloring};
use std::ops::Range;
use std::sync::atomic::{AtomicU32, Ordering};

use crate::workers::{ColorGate, SharedMut, Workers};

use narrow::NarrowRows;
use narrow::lanes::{Batch, Kernel, LANES};
use patch::{Patch, prepare_patch, solve_patch};
use rows::{
    BodyArrays, along, angular_along, apply_linear, combine3, cross, effective, inverse_or_zero,
    linear_basis, mul, prefetch, push_angular, round_wide, scale, tangent_of, vel_or_zero,
};

use crate::body::{BodyHot, BodyKind};
use crate::collision::contacts::reserve_near;
use crate::collision::{ContactPair, MAX_MANIFOLD_POINTS, PairKind, PatchFriction, PointImpulse};
use crate::math::scalar::wide_sum;
use crate::math::{Mat3, Quat, Scalar, SymMat3, Vec3};

/// Marks "no solver body": a static or sleeping body.
const NONE: u32 = u32::MAX;

/// The solver's per-body velocity state, the only body data the iteration
/// loops read and write (48 bytes).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct BodyVel {
    /// Linear velocity.
    v: Vec3,
    /// Angular velocity, world axes.
    w: Vec3,
}

/// The solver's per-body constants for the tick and its pose change since
/// the start of the tick (read once per constraint and pass, never written
/// by the iterations).
#[derive(Clone, Copy, Debug, Default)]
struct SolverBody {
    /// The body's slot in the body set.
    slot: u32,
    /// Whether impulses move it (dynamic) or it only pushes (kinematic).
    dynamic: bool,
    /// 1/mass (0 for kinematic).
    inv_mass: Scalar,
    /// World inverse inertia `R I⁻¹ Rᵀ` at the start of the tick (zero for
    /// kinematic).
    inv_inertia: SymMat3,
    /// Whether `inv_inertia` is a multiple of the identity (`xx`).
    isotropic: bool,
    /// Centre at the start of the tick.
    center0: Vec3,
    /// Conjugate of the rotation at the start of the tick.
    rotation0_inv: Quat,
    /// Displacement of the centre since the start of the tick.
    dp: Vec3,
    /// Rotation since the start of the tick, as a matrix.
    dr: Mat3,
}

impl SolverBody {
    /// `I⁻¹ v` in world axes (one scale for an isotropic body).
    #[inline]
    fn inv_inertia_mul(&self, v: Vec3) -> Vec3 {
        if self.isotropic {
            scale(v, self.inv_inertia.xx)
        } else {
            self.inv_inertia.mul_vec(v)
        }
    }
}

/// One contact point's constant terms and accumulated impulses.
///
/// The relative velocity of the anchors along a direction `d` is
/// `d·(vB − vA) + (rB×d)·ωB − (rA×d)·ωA`, and an impulse `λ` along `d`
/// changes `ω` by `λ·I⁻¹(r×d)`: both products are stored here, so an
/// iteration neither forms a cross product nor multiplies by an inertia.
#[derive(Clone, Copy, Debug, Default)]
struct ConstraintPoint {
    /// The point of A's core behind the contact (the contact point for a
    /// flat-faced shape), relative to A's centre at the start of the tick:
    /// what the separation is followed through. Zero for no body.
    ra: Vec3,
    /// The same on B.
    rb: Vec3,
    /// `ra × n`, `rb × n`.
    ra_n: Vec3,
    rb_n: Vec3,
    /// `I⁻¹A (ra × n)`, `I⁻¹B (rb × n)`.
    ia_n: Vec3,
    ib_n: Vec3,
    /// Separation at the start of the tick minus `n·(rb − ra)`: adding the
    /// current anchor offset along `n` gives the current separation.
    adjusted_separation: Scalar,
    /// Normal velocity (B relative to A) at the start of the tick, or at
    /// the first push if the approach was faster then: what restitution
    /// reflects.
    relative_velocity: Scalar,
    /// `1/k` along the normal.
    normal_mass: Scalar,
    /// Accumulated normal impulse (per substep).
    normal_impulse: Scalar,
    /// The normal impulse at the last write-back of angular impulses (zero
    /// after a warm start, which applies it all again).
    mark: Scalar,
    /// The largest normal impulse seen this tick (restitution only applies
    /// to points that pushed).
    max_normal_impulse: Scalar,
    /// The current separation, as the constraint's cached frame gives it
    /// (see [`Constraint::frame_poses`]).
    separation: Scalar,
}

/// How a constraint follows its points' current separation through the
/// substeps: a point's is its adjusted separation plus `n·(Δp_B − Δp_A) +
/// n·(ΔR_B r_B) − n·(ΔR_A r_A)`, and `n·(ΔR r) = (ΔRᵀ n)·r`, so the two
/// rotated normals and the displacement term are formed once per
/// constraint and visit, not two rotated anchors per point.
#[derive(Clone, Copy, Debug, Default)]
struct SeparationFrame {
    /// `ΔR_Aᵀ n` and `ΔR_Bᵀ n` (zero for no body).
    na: Vec3,
    nb: Vec3,
    /// `n·(Δp_B − Δp_A)`, unrounded.
    base: i128,
}

impl SeparationFrame {
    /// The frame of `c` at its bodies' current pose changes.
    #[inline(always)]
    fn of(c: &Constraint, bodies: &[SolverBody]) -> SeparationFrame {
        SeparationFrame::at(c.normal, c.a, c.b, bodies)
    }

    /// The frame of normal `n` between solver bodies `a` and `b` (or
    /// `NONE`) at their current pose changes.
    #[inline(always)]
    fn at(n: Vec3, a: u32, b: u32, bodies: &[SolverBody]) -> SeparationFrame {
        let (na, dpa) = if a == NONE {
            (Vec3::ZERO, Vec3::ZERO)
        } else {
            let b = &bodies[a as usize];
            (b.dr.transpose_mul_vec(n), b.dp)
        };
        let (nb, dpb) = if b == NONE {
            (Vec3::ZERO, Vec3::ZERO)
        } else {
            let b = &bodies[b as usize];
            (b.dr.transpose_mul_vec(n), b.dp)
        };
        SeparationFrame {
            na,
            nb,
            base: n.dot_wide(dpb - dpa),
        }
    }

    /// The current separation of point `cp` of the constraint.
    #[inline(always)]
    fn separation(&self, cp: &ConstraintPoint) -> Scalar {
        self.separation_at(cp.ra, cp.rb, cp.adjusted_separation)
    }

    /// The current separation of a point with anchors `ra`, `rb` and
    /// adjusted separation `adjusted` (see [`ConstraintPoint`]).
    #[inline(always)]
    fn separation_at(&self, ra: Vec3, rb: Vec3, adjusted: Scalar) -> Scalar {
        round_wide(wide_sum([
            self.base,
            self.nb.dot_wide(rb),
            -self.na.dot_wide(ra),
        ])) + adjusted
    }
}

/// One solid pair's constraint.
#[derive(Clone, Copy, Debug, Default)]
struct Constraint {
    /// Index of the pair in the contact set.
    pair: u32,
    /// Solver body indices (or `NONE`).
    a: u32,
    b: u32,
    /// The same for the bodies the passes write: `a` and `b` if dynamic,
    /// `NONE` for a kinematic body (whose velocity no impulse changes, and
    /// which two constraints of one colour may share).
    wa: u32,
    wb: u32,
    normal: Vec3,
    tangent: [Vec3; 2],
    /// `1/mass` of A and of B (zero for none, static or kinematic).
    inv_mass_a: Scalar,
    inv_mass_b: Scalar,
    /// Their sum: how fast the relative velocity along a unit direction
    /// changes per unit impulse along it, linear part.
    inv_mass_sum: Scalar,
    /// The contact spring of this constraint's soft pass: the world's, or
    /// a stiffer one for a high mass ratio (see [`RATIO_KEPT`]).
    softness: Softness,
    friction: Scalar,
    restitution: Scalar,
    /// How far A's and B's surfaces lie out from their cores (see
    /// [`PairInfo::rounding`]); read by `prepare` only.
    rounding: [Scalar; 2],
    /// The manifold's total normal impulse at this substep's warm start
    /// (the last substep's, or last tick's): what bounds friction through
    /// the substep's passes.
    warm_total: Scalar,
    /// The friction rows, acting at the centre of the patch.
    patch: Patch,
    count: usize,
    points: [ConstraintPoint; MAX_MANIFOLD_POINTS],
    /// The separation frame at the bodies' poses numbered `frame_poses`
    /// (see [`ContactSolver::poses`]), and each point's separation from it:
    /// the poses change once per substep (before the relax pass), but the
    /// next substep's solve pass, and every extra pass or visit at the same
    /// poses, would compute the same frame again. Set by a visit's first
    /// pass at new poses; 0 (never a pose number) after `prepare`.
    frame: SeparationFrame,
    frame_poses: u32,
}

impl Constraint {
    /// Adds the angular impulse of every impulse change since its mark
    /// (`r×n Δλ_n` per point; `ra×t_j Δλ_tj` and `n Δλ_twist` for the
    /// patch, all from stored products) to the write-back sums `dls` of A
    /// (negated) and B, and moves the marks.
    #[inline(always)]
    fn collect_angular(&mut self, arrays: &BodyArrays) {
        let (a, b) = (self.wa, self.wb);
        for cp in &mut self.points[..self.count] {
            let dn = cp.normal_impulse - cp.mark;
            if dn.is_zero() {
                continue;
            }
            cp.mark = cp.normal_impulse;
            if a != NONE {
                arrays.add_dl(a, -scale(cp.ra_n, dn));
            }
            if b != NONE {
                arrays.add_dl(b, scale(cp.rb_n, dn));
            }
        }
        let f = &mut self.patch;
        let now = [f.tangent_impulse[0], f.tangent_impulse[1], f.twist_impulse];
        if now == f.mark {
            return;
        }
        let [d0, d1, dw] = [now[0] - f.mark[0], now[1] - f.mark[1], now[2] - f.mark[2]];
        f.mark = now;
        let n = self.normal;
        if a != NONE {
            arrays.add_dl(a, -combine3(f.ra_t[0], d0, f.ra_t[1], d1, n, dw));
        }
        if b != NONE {
            arrays.add_dl(b, combine3(f.rb_t[0], d0, f.rb_t[1], d1, n, dw));
        }
    }

    /// Applies the accumulated impulses to the velocities `va`, `vb` of A
    /// and B (the warm start), records their total normal impulse and
    /// clears the marks (the angular write-back takes them all again).
    ///
    /// Every change is a rounded product of the impulses and this
    /// constraint's constant terms, added to the velocity: none depends on
    /// the velocities, so the changes may be summed apart (from zero) and
    /// added later, to the same bits.
    #[inline(always)]
    fn warm_start(&mut self, va: &mut BodyVel, vb: &mut BodyVel) {
        let (a, b) = (self.a, self.b);
        // The linear change is the same direction for every point: sum the
        // impulses (exactly) and scale once per constraint.
        let mut total = Scalar::ZERO;
        for cp in &mut self.points[..self.count] {
            cp.mark = Scalar::ZERO;
            let ni = cp.normal_impulse;
            if ni.is_zero() {
                continue;
            }
            total += ni;
            push_angular(va, vb, a, b, ni, cp.ia_n, cp.ib_n);
        }
        self.warm_total = total;
        let f = &mut self.patch;
        f.mark = [Scalar::ZERO; 3];
        let [i0, i1] = f.tangent_impulse;
        let iw = f.twist_impulse;
        if !(i0.is_zero() && i1.is_zero() && iw.is_zero()) {
            if a != NONE {
                va.w -= combine3(f.ia_t[0], i0, f.ia_t[1], i1, f.ia_w, iw);
            }
            if b != NONE {
                vb.w += combine3(f.ib_t[0], i0, f.ib_t[1], i1, f.ib_w, iw);
            }
        }
        apply_linear(self, va, vb, [total, i0, i1]);
    }
}

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
    /// [`narrow::Quanta`]); empty otherwise.
    quanta: Vec<narrow::Quanta>,
    quanta0: Vec<narrow::Quanta>,
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
    /// Per solver body, its level for the shock pass (`prepare` only; see
    /// [`shock`]).
    level: Vec<u32>,
    /// The shock pass's visits, in order (see [`shock`]).
    shock: Vec<shock::ShockRow>,
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

    /// One pass over every constraint: friction, then the normal impulses
    /// (soft with `use_bias`, rigid without).
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
    /// same bits. Not when the high-ratio visits or the shock pass change
    /// impulses after the pass.
    pub(crate) fn solve(
        &mut self,
        params: &SolverParams,
        use_bias: bool,
        warm_next: bool,
        workers: &Workers,
    ) {
        let fuse = warm_next && !use_bias && self.heavy.is_empty() && self.shock.is_empty();
        // SAFETY: the pass visits one colour at a time (`for_each_colored`),
        // then the heavy constraints on this thread alone.
        // On the narrow rows, the velocities are in quanta for the pass.
        let quanta = self.rows_len > 0;
        if quanta {
            narrow::quantize(&self.vels, &mut self.quanta, &mut self.quanta0);
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
            // count) and goes round: always the same order lets the first
            // point of a manifold take more than its share of the load, and
            // that keeps a tall stack rocking (without sleeping, the stack
            // of 20's top box swung by 8 cm; rotating the start keeps it
            // within a millimetre).
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
            narrow::flush(&mut self.vels, &self.quanta, &mut self.quanta0);
        }
        for _ in 0..HIGH_RATIO_PASSES {
            for &i in &self.heavy {
                // The high-ratio constraints are on the Q32.32 rows.
                pass.visit_exact(&mut self.constraints[i as usize]);
            }
        }
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
            for cp in &mut c.points[..c.count] {
                if cp.relative_velocity > threshold || cp.max_normal_impulse.is_zero() {
                    continue;
                }
                let vn = un + angular_along(&va, &vb, cp.ra_n, cp.rb_n);
                let lambda = -(cp.normal_mass * (vn + c.restitution * cp.relative_velocity));
                let old = cp.normal_impulse;
                let new = (old + lambda).max(Scalar::ZERO);
                let d = new - old;
                cp.normal_impulse = new;
                cp.max_normal_impulse = cp.max_normal_impulse.max(new);
                if !d.is_zero() {
                    un += mul(c.inv_mass_sum, d);
                    applied += d;
                    push_angular(&mut va, &mut vb, c.a, c.b, d, cp.ia_n, cp.ib_n);
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
