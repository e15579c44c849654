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
//! Determinism: bodies in slot (handle) order; constraints in pair order
//! (ascending collider handles), or colour by colour, the colours
//! recomputed each tick from the pairs in that order (the constraints of
//! one colour give the same results in any order, on any worker); points
//! in manifold order starting at point `k mod count` in substep `k` of the
//! tick.

mod color;
mod narrow;
mod patch;
mod rows;
mod shock;
mod wide;

use color::{COLORS, Coloring};
use std::ops::Range;
use std::sync::atomic::{AtomicU32, Ordering};

use super::workers::{ColorGate, SharedMut, Workers};

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

/// How many constraints ahead the passes ask the CPU to load. A constraint
/// is about 1.9 KB and a pass spends a few hundred nanoseconds on it: on
/// large_pyramid (15,000 constraints, far more than the caches hold) one
/// ahead was faster than two or four, and about 10% faster than none.
const PREFETCH_AHEAD: usize = 1;

/// Visits the constraints in order, asking the CPU to load the next ones
/// first (see [`PREFETCH_AHEAD`]): the narrow rows of one on them, the
/// Q32.32 constraint of one that is not. `rs` holds the constraints' narrow
/// rows, or nothing in a world on the Q32.32 rows (each visit then gets
/// `None`).
#[inline(always)]
fn for_each_prefetched(
    cs: &mut [Constraint],
    rs: &mut [NarrowRows],
    mut f: impl FnMut(&mut Constraint, Option<&mut NarrowRows>),
) {
    let len = cs.len();
    let narrow = !rs.is_empty();
    for i in 0..len {
        if i + PREFETCH_AHEAD < len {
            match rs.get(i + PREFETCH_AHEAD) {
                Some(next) if narrow && next.on => prefetch(next),
                _ => prefetch(&cs[i + PREFETCH_AHEAD]),
            }
        }
        f(&mut cs[i], rs.get_mut(i));
    }
}

/// The constraints and their narrow rows (same index), shared by the
/// workers of one colour pass.
struct Both<'a> {
    cs: SharedMut<'a, Constraint>,
    rs: SharedMut<'a, NarrowRows>,
}

impl<'a> Both<'a> {
    fn new(cs: &'a mut [Constraint], rs: &'a mut [NarrowRows]) -> Both<'a> {
        Both {
            cs: SharedMut::new(cs),
            rs: SharedMut::new(rs),
        }
    }

    /// The constraints and rows of `r`.
    ///
    /// # Safety
    /// No other thread touches them while the slices live.
    #[allow(clippy::mut_from_ref)]
    unsafe fn slices(&self, r: Range<usize>) -> (&mut [Constraint], &mut [NarrowRows]) {
        // SAFETY: as the caller promises. No rows (a world on the Q32.32
        // rows): an empty slice of them.
        unsafe {
            let rows = if self.rs.is_empty() {
                self.rs.slice(0..0)
            } else {
                self.rs.slice(r.clone())
            };
            (self.cs.slice(r), rows)
        }
    }
}

/// Constraints a worker claims at a time within a colour: enough that
/// claiming (one atomic add) costs little beside the visits, few enough
/// that two workers end a colour of a few hundred constraints together.
const BLOCK: usize = 16;

/// Solver bodies a worker claims at a time when the velocities go to and
/// from the bodies (a few nanoseconds each).
const BODY_BLOCK: usize = 128;

/// Constraints a worker claims at a time when the impulses go back to the
/// pairs (a copy of a few words each).
const STORE_BLOCK: usize = 128;

/// Visits every constraint once, in colour order: each colour's
/// constraints split in blocks over the workers (they share no moving
/// body, so each one's result is the same whoever visits it and in any
/// order), no block of a colour before the colour before it has finished,
/// then the overflow in order on this thread. With one worker, one thread
/// visits the colours from first to last, then the overflow: the same
/// results. In pair order (no colours) it visits the array in order.
///
/// `visit` gets runs of consecutive constraints, and whether the run lies
/// inside one colour (its constraints may then be visited in any order or
/// together). A run inside a colour starts at the colour's start plus a
/// multiple of [`BLOCK`], whatever the worker count (see
/// `workers::segment`), so the wide kernels' batches of eight are the same
/// for any count.
///
/// `rows` holds the constraints' narrow rows (same index), or nothing in a
/// world on the Q32.32 rows; each run gets its own rows, or none.
fn for_each_colored<F>(
    constraints: &mut [Constraint],
    rows: &mut [NarrowRows],
    starts: &[u32; COLORS + 2],
    workers: &Workers,
    visit: F,
) where
    F: Fn(&mut [Constraint], &mut [NarrowRows], bool) + Sync,
{
    let len = constraints.len();
    let colored = (starts[COLORS] as usize).min(len);
    if colored == 0 {
        visit(constraints, rows, false);
        return;
    }
    let ranges: [Range<usize>; COLORS] = std::array::from_fn(|c| {
        (starts[c] as usize).min(colored)..(starts[c + 1] as usize).min(colored)
    });
    let (shared, overflow) = constraints.split_at_mut(colored);
    let (shared_rows, overflow_rows) = rows.split_at_mut(colored.min(rows.len()));
    if workers.count() == 1 {
        for r in ranges {
            let rs = if shared_rows.is_empty() {
                &mut []
            } else {
                &mut shared_rows[r.clone()]
            };
            visit(&mut shared[r], rs, true);
        }
    } else {
        let gate = ColorGate::<COLORS>::new(workers);
        let both = Both::new(shared, shared_rows);
        let visit_block = |r| {
            // SAFETY: each block is claimed by one worker alone (one counter
            // per segment of a colour, every worker claiming from it).
            let (cs, rs) = unsafe { both.slices(r) };
            visit(cs, rs, true)
        };
        workers.run(&|w| gate.visit(w, &ranges, BLOCK, &visit_block));
    }
    visit(overflow, overflow_rows, false);
}

/// [`for_each_colored`]'s visitor for a pass that visits one constraint at
/// a time.
fn one_by_one(
    visit: impl Fn(&mut Constraint, Option<&mut NarrowRows>) + Sync,
) -> impl Fn(&mut [Constraint], &mut [NarrowRows], bool) + Sync {
    move |cs, rs, _| for_each_prefetched(cs, rs, &visit)
}

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

/// One solve or relax pass's settings and shared arrays (see
/// [`ContactSolver::solve`]).
struct Pass<'a> {
    params: &'a SolverParams,
    /// Soft push-out (the solve pass) or none (relax).
    use_bias: bool,
    /// Whether the pass also sums the next substep's warm start.
    fuse: bool,
    /// The substep count: where each manifold's points start.
    rot: usize,
    bodies: &'a [SolverBody],
    arrays: BodyArrays,
    /// Whether runs inside a colour go to the wide kernels.
    lanes: bool,
    /// The solver's pose number (see [`ContactSolver::poses`]).
    poses: u32,
    /// Where a narrow visit whose guard failed is counted.
    fallbacks: &'a narrow::Fallbacks,
    /// The lanes' batches, and the kernel build that runs them (`None`:
    /// the narrow rows' lanes are off).
    batches: &'a [Batch],
    kernel: Option<Kernel>,
}

/// One constraint's visit between its friction rows and its normal rows:
/// what [`Pass::head`] leaves for [`Pass::points`] (or the wide kernel) and
/// [`Pass::tail`].
#[derive(Clone, Copy, Default)]
struct Visit {
    va: BodyVel,
    vb: BodyVel,
    /// The linear part of the relative velocity along n, t0 and t1, kept up
    /// to date through the rows (an impulse λ along one unit direction of
    /// the basis changes it by λ(1/mA + 1/mB) along that direction and not
    /// along the other two).
    u: [Scalar; 3],
    /// The impulses applied in this visit, turned into linear velocity once
    /// at the end: three products per row instead of nine.
    applied: [Scalar; 3],
    frame: SeparationFrame,
    /// Whether `frame` and the points' separations were cached at these
    /// poses (else the points compute and cache their separations).
    cached: bool,
    /// The first point visited.
    start: usize,
}

impl Visit {
    /// The point visited at step `kk` of a manifold of `count` points: the
    /// points in order, starting at `start` and going round.
    #[inline(always)]
    fn point(&self, kk: usize, count: usize) -> usize {
        let k = kk + self.start;
        if k >= count { k - count } else { k }
    }
}

impl Pass<'_> {
    /// One visit of constraint `c`: friction, then the normal rows, on the
    /// narrow rows if the constraint is on them (see [`narrow`]), else on
    /// the Q32.32 rows. A narrow visit whose guard fails writes nothing;
    /// the constraint's impulses go back to Q32.32 and the Q32.32 rows
    /// solve it from this visit to the end of the tick.
    #[inline(always)]
    fn visit(&self, c: &mut Constraint, r: Option<&mut NarrowRows>) {
        if let Some(r) = r.filter(|r| r.on) {
            if narrow::visit(&self.narrow_args(), r) {
                self.accepted(c, r);
            } else {
                self.refused(c, r);
            }
            return;
        }
        self.visit_exact(c);
    }

    /// What the narrow rows' visits read of this pass.
    #[inline(always)]
    fn narrow_args(&self) -> narrow::VisitArgs<'_> {
        narrow::VisitArgs {
            params: self.params,
            bodies: self.bodies,
            arrays: &self.arrays,
            use_bias: self.use_bias,
            rot: self.rot,
            poses: self.poses,
        }
    }

    /// After a narrow visit that its guard accepted: the next warm start,
    /// if this pass sums it.
    #[inline(always)]
    fn accepted(&self, c: &Constraint, r: &mut NarrowRows) {
        if self.fuse {
            let (da, db) = narrow::warm_start(r);
            self.arrays.add_warm(c.wa, c.wb, da, db);
        }
    }

    /// After a narrow visit that its guard refused (it wrote nothing): the
    /// impulses back in Q32.32, and the constraint on the Q32.32 rows from
    /// this visit to the end of the tick.
    #[inline(never)]
    fn refused(&self, c: &mut Constraint, r: &mut NarrowRows) {
        narrow::write_back(r, c);
        r.on = false;
        self.fallbacks.add();
        self.visit_exact(c);
    }

    /// Visits a run of constraints of one colour on the narrow rows: each
    /// batch of eight (see `narrow::lanes`) on the lanes, the others one at
    /// a time. The same bits as visiting them in order: each constraint's
    /// visit reads and writes only its own data and its bodies.
    fn visit_narrow_run(&self, cs: &mut [Constraint], rs: &mut [NarrowRows], kernel: Kernel) {
        let len = cs.len().min(rs.len());
        let args = self.narrow_args();
        let mut i = 0;
        while i < len {
            let b = rs[i].batch;
            if b != NONE && i + LANES <= len && Batch::fits(&rs[i..i + LANES]) {
                // Ask for the next batch's rows while this one runs (the
                // lanes read their state, and the biases their terms).
                for r in rs.iter().skip(i + LANES).take(LANES) {
                    prefetch(r);
                }
                let next = rs.get(i + LANES).map(|r| r.batch as usize);
                if let Some(next) = next.and_then(|b| self.batches.get(b)) {
                    prefetch(next);
                }
                let batch = &self.batches[b as usize];
                let rows = &mut rs[i..i + LANES];
                let refused = narrow::lanes::visit(&args, batch, rows, kernel);
                if self.fuse && !refused.contains(&true) {
                    // The next warm start of the whole batch on the lanes.
                    let warm = narrow::lanes::warm_start(batch, rows);
                    for (c, (da, db)) in cs[i..i + LANES].iter().zip(warm) {
                        self.arrays.add_warm(c.wa, c.wb, da, db);
                    }
                } else {
                    for (l, &no) in refused.iter().enumerate() {
                        let (c, r) = (&mut cs[i + l], &mut rs[i + l]);
                        if no {
                            self.refused(c, r);
                        } else {
                            self.accepted(c, r);
                        }
                    }
                }
                i += LANES;
            } else {
                if i + PREFETCH_AHEAD < len {
                    prefetch(&rs[i + PREFETCH_AHEAD]);
                }
                self.visit(&mut cs[i], Some(&mut rs[i]));
                i += 1;
            }
        }
    }

    /// One visit of constraint `c` on the Q32.32 rows.
    #[inline(always)]
    fn visit_exact(&self, c: &mut Constraint) {
        let mut v = self.head(c);
        self.points(c, &mut v);
        self.tail(c, &mut v);
    }

    /// The visit up to the normal rows: the velocities, the friction rows
    /// and the separation frame.
    #[inline(always)]
    fn head(&self, c: &mut Constraint) -> Visit {
        let (mut va, mut vb) = self.arrays.load(c.a, c.b);
        let u = linear_basis(c, &va, &vb);
        let mut applied = [Scalar::ZERO; 3];
        let count = c.count.min(MAX_MANIFOLD_POINTS);
        // Friction at the patch centre, bounded by μ times the manifold's
        // total normal impulse of the warm start, the one the last
        // substep's relax pass settled (see [`solve_patch`]). A contact
        // without one (new this substep) takes its current total: an exact
        // sum, whatever the order of its points.
        let total = if c.warm_total.is_positive() {
            c.warm_total
        } else {
            let mut total = Scalar::ZERO;
            for cp in &c.points[..count] {
                total += cp.normal_impulse;
            }
            total
        };
        solve_patch(c, &mut va, &mut vb, &u, &mut applied, total);
        let cached = c.frame_poses == self.poses;
        if !cached {
            c.frame = SeparationFrame::of(c, self.bodies);
            c.frame_poses = self.poses;
        }
        Visit {
            va,
            vb,
            u,
            applied,
            frame: c.frame,
            cached,
            start: if count == 0 { 0 } else { self.rot % count },
        }
    }

    /// The normal rows: non-penetration at each point's current
    /// separation, in the order that starts at `v.start`.
    #[inline(always)]
    fn points(&self, c: &mut Constraint, v: &mut Visit) {
        let params = self.params;
        let count = c.count.min(MAX_MANIFOLD_POINTS);
        for kk in 0..count {
            let cp = &mut c.points[v.point(kk, count)];
            let s = if v.cached {
                cp.separation
            } else {
                let s = v.frame.separation(cp);
                cp.separation = s;
                s
            };
            let (bias, mass_scale, impulse_scale) = if s.is_positive() {
                (s * params.inv_h, Scalar::ONE, Scalar::ZERO)
            } else if self.use_bias {
                (
                    (c.softness.bias_rate * s).max(-params.max_push_out),
                    c.softness.mass_scale,
                    c.softness.impulse_scale,
                )
            } else {
                (Scalar::ZERO, Scalar::ONE, Scalar::ZERO)
            };
            let vn = v.u[0] + angular_along(&v.va, &v.vb, cp.ra_n, cp.rb_n);
            let lambda = -mul(mul(cp.normal_mass, mass_scale), vn + bias)
                - mul(impulse_scale, cp.normal_impulse);
            let old = cp.normal_impulse;
            let new = (old + lambda).max(Scalar::ZERO);
            let d = new - old;
            if cp.max_normal_impulse.is_zero() && new.is_positive() {
                // First push this tick (in a solve or a relax pass): the
                // approach speed at impact, gravity included up to this
                // substep, is what restitution reflects, not the speed at
                // the start of the tick.
                cp.relative_velocity = cp.relative_velocity.min(vn);
            }
            cp.normal_impulse = new;
            cp.max_normal_impulse = cp.max_normal_impulse.max(new);
            if !d.is_zero() {
                v.u[0] += mul(c.inv_mass_sum, d);
                v.applied[0] += d;
                push_angular(&mut v.va, &mut v.vb, c.a, c.b, d, cp.ia_n, cp.ib_n);
            }
        }
    }

    /// The visit after the normal rows: the linear impulses, the
    /// velocities back, and (relax) the angular write-back and the next
    /// warm start.
    #[inline(always)]
    fn tail(&self, c: &mut Constraint, v: &mut Visit) {
        apply_linear(c, &mut v.va, &mut v.vb, v.applied);
        self.arrays.store(c.wa, c.wb, v.va, v.vb);
        if !self.use_bias {
            c.collect_angular(&self.arrays);
        }
        if self.fuse {
            let (mut da, mut db) = (BodyVel::default(), BodyVel::default());
            c.warm_start(&mut da, &mut db);
            self.arrays.add_warm(c.wa, c.wb, da, db);
        }
    }

    /// Visits a run of constraints of one colour (no two share a moving
    /// body): in batches of [`wide::LANES`], each batch's normal rows on
    /// the wide kernel (or, if its range guard refuses the batch, one
    /// constraint at a time), then the rest one at a time. The same bits as
    /// visiting them in order: each constraint's visit reads and writes
    /// only its own data and its bodies.
    fn visit_batches(&self, cs: &mut [Constraint], rs: &mut [NarrowRows]) -> wide::Counts {
        let mut counts = wide::Counts::default();
        let whole = cs.len() / wide::LANES * wide::LANES;
        for first in (0..whole).step_by(wide::LANES) {
            let mut visits: [Visit; wide::LANES] = std::array::from_fn(|i| {
                // Ask for the next constraint while this one's head runs
                // (see [`PREFETCH_AHEAD`]).
                if let Some(next) = cs.get(first + i + PREFETCH_AHEAD) {
                    prefetch(next);
                }
                self.head(&mut cs[first + i])
            });
            let batch: &mut [Constraint; wide::LANES] = (&mut cs[first..first + wide::LANES])
                .try_into()
                .expect("a whole batch");
            if wide::points(batch, &mut visits, self.params, self.use_bias) {
                counts.lanes += 1;
            } else {
                counts.guarded += 1;
                for (c, v) in batch.iter_mut().zip(&mut visits) {
                    self.points(c, v);
                }
            }
            for (c, v) in batch.iter_mut().zip(&mut visits) {
                self.tail(c, v);
            }
        }
        // Rows only in a world on the narrow rows (the wide kernels never
        // run there).
        let rest = if rs.is_empty() { rs } else { &mut rs[whole..] };
        for_each_prefetched(&mut cs[whole..], rest, |c, r| self.visit(c, r));
        counts
    }
}

/// Softness of the contact spring for a substep.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Softness {
    /// `ω/(2ζ + hω)`: converts a separation into a velocity bias.
    pub bias_rate: Scalar,
    /// `hω(2ζ + hω)/(1 + hω(2ζ + hω))`: scales the effective mass.
    pub mass_scale: Scalar,
    /// `1/(1 + hω(2ζ + hω))`: how much of the accumulated impulse relaxes.
    pub impulse_scale: Scalar,
}

impl Softness {
    /// Whether this is no softness at all: no bias, the whole effective
    /// mass, nothing relaxed.
    #[inline]
    pub(crate) fn is_rigid(&self) -> bool {
        self.bias_rate.is_zero() && self.mass_scale == Scalar::ONE && self.impulse_scale.is_zero()
    }

    /// The spring of a contact whose lighter body has inverse mass `hi` and
    /// touches (through it or its partner) a body of inverse mass `lo`, and
    /// whether that ratio counts as high. See [`RATIO_KEPT`].
    pub(crate) fn for_ratio(params: &SolverParams, lo: Scalar, hi: Scalar) -> (Softness, bool) {
        if !lo.is_positive() || !params.omega.is_positive() {
            return (params.softness, false);
        }
        // R = m_heavy/m_light = hi/lo.
        let Some(ratio) = hi.checked_div(lo) else {
            return (params.softness, false);
        };
        if ratio <= Scalar::from_int(RATIO_KEPT) {
            return (params.softness, false);
        }
        let f = (ratio + Scalar::ONE).div_int(RATIO_KEPT as i64 + 1);
        let omega = (params.omega * crate::math::elem::sqrt(f)).min(params.omega_max);
        (Softness::from_omega(omega, params.zeta, params.h), true)
    }

    /// A spring of `hertz` with damping ratio `zeta`, stepped at `h`
    /// (Box2D's `b2MakeSoft`). A zero frequency gives a rigid constraint
    /// without bias.
    pub(crate) fn new(hertz: Scalar, zeta: Scalar, h: Scalar) -> Softness {
        if !hertz.is_positive() {
            return Softness {
                bias_rate: Scalar::ZERO,
                mass_scale: Scalar::ONE,
                impulse_scale: Scalar::ZERO,
            };
        }
        Softness::from_omega(Scalar::TAU * hertz, zeta, h)
    }

    /// A spring of angular frequency `omega` (> 0), damping ratio `zeta`,
    /// stepped at `h`.
    pub(crate) fn from_omega(omega: Scalar, zeta: Scalar, h: Scalar) -> Softness {
        let a1 = Scalar::TWO * zeta + h * omega;
        let a2 = h * omega * a1;
        let a3 = (Scalar::ONE + a2).recip();
        Softness {
            bias_rate: omega.checked_div(a1).unwrap_or(Scalar::ZERO),
            mass_scale: a2 * a3,
            impulse_scale: a3,
        }
    }
}

/// The mass ratio up to which a contact keeps the world's spring: there
/// its static depth, (1 + R)·g/ω² for a light body under a heavy one (the
/// effective mass is about the light body's, the load the heavy one's), is
/// at most 4.5 mm at 60 Hz. Above it the spring's ω is raised by
/// `√((1 + R)/(1 + RATIO_KEPT))` (up to `omega_max`) so the depth stays
/// there, and the pass visits the contact [`HIGH_RATIO_PASSES`] more times:
/// Gauss–Seidel between a light and a heavy body converges about R times
/// slower, and with a single visit the stiffer spring let a box 1,000
/// times heavier through the light one.
const RATIO_KEPT: i32 = 64;

/// Extra visits per pass of the high-ratio contacts (see [`RATIO_KEPT`]).
const HIGH_RATIO_PASSES: u32 = 3;

/// Settings the solver reads each tick.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SolverParams {
    /// The substep `h` and `1/h`.
    pub h: Scalar,
    pub inv_h: Scalar,
    /// The contact spring.
    pub softness: Softness,
    /// Its angular frequency and its damping ratio.
    pub omega: Scalar,
    pub zeta: Scalar,
    /// The stiffest spring a high-ratio contact may get (see
    /// [`RATIO_KEPT`]).
    pub omega_max: Scalar,
    /// Cap on the push-out speed of overlapping shapes, m/s.
    pub max_push_out: Scalar,
    /// Normal approach speed below which there is no bounce, m/s.
    pub restitution_threshold: Scalar,
    /// Whether the constraints are solved in colour order (see [`color`])
    /// rather than pair order.
    pub colored: bool,
    /// Whether the passes solve the contacts on the narrow rows (see
    /// [`narrow`]) where they fit, rather than on the Q32.32 rows.
    pub narrow: bool,
}

/// Counters from one tick's solve.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct SolverStats {
    /// Constraints (solid pairs with points).
    pub constraints: u32,
    /// Colours with at least one constraint (see [`color`]).
    pub colors: u32,
    /// Constraints that found no free colour (solved after the colours).
    pub overflow: u32,
    /// Times a buffer grew.
    pub growths: u32,
    /// Constraints that start the tick on the narrow rows.
    pub narrow: u32,
    /// Batches of eight of them that the lanes may visit together.
    pub lane_batches: u32,
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
    /// The threads the colour passes are split over (not simulation state:
    /// any count gives the same bits).
    workers: Workers,
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

/// What `prepare`'s first scan found for one candidate pair, before its
/// constraint's place in colour order is known.
#[derive(Clone, Copy, Debug, Default)]
struct Pending {
    /// Whether the pair makes a constraint this tick (solid, with points,
    /// and a moving dynamic body); if not, the rest is unset.
    used: bool,
    pair: u32,
    /// Slots of the moving bodies (`NONE` for a static or sleeping one).
    a: u32,
    b: u32,
    /// Slots of the moving dynamic bodies, the ones a colour takes (`NONE`
    /// for any other).
    dyn_a: u32,
    dyn_b: u32,
    friction: Scalar,
    restitution: Scalar,
    rounding: [Scalar; 2],
}

/// Candidate pairs a worker scans at a time in `prepare`.
const SCAN_BLOCK: usize = 64;

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
    /// Builds the solver bodies and constraints for this tick from the
    /// contact pairs (at the poses and velocities of the start of the tick).
    ///
    /// `active`, when given, lists the indices (ascending) of the only pairs
    /// that may make a constraint (those with a moving body); otherwise
    /// every pair is looked at. The work is proportional to those pairs and
    /// the bodies they touch, not to all pairs or body slots.
    ///
    /// Determinism: pairs in contact-set order; bodies in slot order.
    pub(crate) fn prepare(
        &mut self,
        pairs: &[ContactPair],
        active: Option<&[u32]>,
        hot: &[BodyHot],
        params: &SolverParams,
        info: impl Fn(&ContactPair) -> Option<PairInfo> + Sync,
    ) -> SolverStats {
        let caps = (
            self.bodies.capacity(),
            self.vels.capacity(),
            (self.dls.capacity(), self.warm.capacity()),
            self.body_of_slot.capacity(),
            (
                self.constraints.capacity(),
                self.rows.capacity(),
                self.batches.capacity(),
            ),
            self.touched.capacity(),
            self.heaviest.capacity(),
            self.heavy.capacity(),
            self.level.capacity(),
            self.shock.capacity(),
            (self.pending.capacity(), self.placed.capacity()),
            self.coloring.capacities(),
        );
        self.substeps = 0;
        self.poses = 1;
        for sb in &self.bodies {
            if let Some(idx) = self.body_of_slot.get_mut(sb.slot as usize) {
                *idx = NONE;
            }
        }
        self.body_of_slot.resize(hot.len(), NONE);
        self.touched.clear();
        self.bodies.clear();
        self.vels.clear();
        self.dls.clear();
        self.warm.clear();
        self.warm_ready = false;
        let moves = |slot: u32| {
            let b = &hot[slot as usize];
            b.kind != BodyKind::Static && !b.sleeping
        };
        // 1. The constraints in pair order, each with its colour, and the
        //    set of bodies they touch. First each candidate pair on its own
        //    (its colliders, material and bodies; in blocks over the
        //    workers), then the marks and colours in pair order on this
        //    thread, from the compact results.
        let candidates = active.map_or(pairs.len(), <[u32]>::len);
        // Only grows: every entry below `candidates` is written next.
        self.pending.resize(candidates, Pending::default());
        {
            let found = SharedMut::new(&mut self.pending[..candidates]);
            let scan = |k: usize| -> Option<Pending> {
                let i = active.map_or(k, |a| a[k] as usize);
                let p = pairs.get(i)?;
                if p.kind != PairKind::Solid || p.manifold.is_empty() {
                    return None;
                }
                let pi = info(p)?;
                if pi.slot_a as usize >= hot.len() || pi.slot_b as usize >= hot.len() {
                    return None;
                }
                let (ma, mb) = (moves(pi.slot_a), moves(pi.slot_b));
                let dyn_a = ma && hot[pi.slot_a as usize].kind == BodyKind::Dynamic;
                let dyn_b = mb && hot[pi.slot_b as usize].kind == BodyKind::Dynamic;
                if !dyn_a && !dyn_b {
                    return None;
                }
                let slot = |on: bool, slot: u32| if on { slot } else { NONE };
                Some(Pending {
                    used: true,
                    pair: i as u32,
                    a: slot(ma, pi.slot_a),
                    b: slot(mb, pi.slot_b),
                    dyn_a: slot(dyn_a, pi.slot_a),
                    dyn_b: slot(dyn_b, pi.slot_b),
                    friction: pi.friction,
                    restitution: pi.restitution,
                    rounding: pi.rounding,
                })
            };
            self.workers.for_each_block(candidates, SCAN_BLOCK, |r| {
                // SAFETY: each block goes to one worker alone.
                let out = unsafe { found.slice(r.clone()) };
                for (k, pc) in r.zip(out) {
                    *pc = scan(k).unwrap_or_default();
                }
            });
        }
        let pending = &self.pending[..candidates];
        let used = pending.iter().filter(|pc| pc.used).count();
        // A constraint is over a kilobyte: grown once, to the count and an
        // eighth more (`reserve_near`), rather than doubled as it is pushed
        // (which held up to twice what a pyramid needs, and three times that
        // while it moved).
        reserve_near(&mut self.constraints, used);
        self.coloring.reserve(used);
        self.coloring.begin(hot.len(), params.colored);
        for pc in pending.iter().filter(|pc| pc.used) {
            for slot in [pc.a, pc.b] {
                if slot == NONE {
                    continue;
                }
                let idx = &mut self.body_of_slot[slot as usize];
                if *idx == NONE {
                    // Marked; the index is set in step 2.
                    *idx = 0;
                    self.touched.push(slot);
                }
            }
            self.coloring.assign(pc.dyn_a, pc.dyn_b);
        }
        // Each constraint goes to the next place of its colour's range
        // (`placed`; its fields are set in step 3). Constraints are
        // overwritten in place and the rest cut off: a fresh push would
        // build each (over a kilobyte) on the stack and copy it.
        self.starts = self.coloring.finish();
        while self.constraints.len() < used {
            self.constraints.push(Constraint::default());
        }
        self.constraints.truncate(used);
        self.placed.clear();
        self.placed.resize(used, 0);
        let mut next = self.starts;
        let found = pending.iter().enumerate().filter(|(_, pc)| pc.used);
        let lanes = self.lanes_will_run(params);
        if lanes {
            // Each colour's constraints by point count (then pair order),
            // so that runs of eight with the same count can go to the
            // lanes together (see `narrow::lanes`). The order inside a
            // colour does not change a bit: its constraints share no
            // moving body. The overflow, visited in order, keeps pair
            // order. Only for the lanes: nothing else gains from it.
            let count_of = |k: usize| {
                let points = pairs[pending[k].pair as usize].manifold.points().len();
                points.clamp(1, MAX_MANIFOLD_POINTS) - 1
            };
            let mut at = [[0u32; MAX_MANIFOLD_POINTS]; COLORS + 1];
            for (j, (k, _)) in found.clone().enumerate() {
                let color = self.coloring.color_of(j);
                if color < COLORS {
                    at[color][count_of(k)] += 1;
                }
            }
            for (c, at) in at.iter_mut().enumerate().take(COLORS) {
                let mut place = self.starts[c];
                for n in at.iter_mut() {
                    (*n, place) = (place, place + *n);
                }
            }
            for (j, (k, _)) in found.enumerate() {
                let color = self.coloring.color_of(j);
                let slot = if color < COLORS {
                    &mut at[color][count_of(k)]
                } else {
                    &mut next[color]
                };
                self.placed[*slot as usize] = k as u32;
                *slot += 1;
            }
        } else {
            for (j, (k, _)) in found.enumerate() {
                let color = self.coloring.color_of(j);
                self.placed[next[color] as usize] = k as u32;
                next[color] += 1;
            }
        }
        // 2. Solver bodies in slot order, and the range of their inverse
        //    masses (for step 4).
        self.touched.sort_unstable();
        let (mut lightest, mut heaviest) = (Scalar::ZERO, Scalar::MAX);
        for &slot in &self.touched {
            self.body_of_slot[slot as usize] = self.bodies.len() as u32;
            let b = &hot[slot as usize];
            let dynamic = b.kind == BodyKind::Dynamic;
            if dynamic {
                lightest = lightest.max(b.inv_mass);
                heaviest = heaviest.min(b.inv_mass);
            }
            // An isotropic inertia (a cube, a sphere) is the same in every
            // frame: no rotation, and products with it are one scale.
            let isotropic = dynamic && b.isotropic;
            let inv_inertia = if isotropic {
                b.inv_inertia
            } else if dynamic {
                b.inv_inertia.rotate(&Mat3::from_quat(b.rotation))
            } else {
                SymMat3::ZERO
            };
            self.bodies.push(SolverBody {
                slot,
                dynamic,
                inv_mass: if dynamic { b.inv_mass } else { Scalar::ZERO },
                inv_inertia,
                isotropic,
                center0: b.center,
                rotation0_inv: b.rotation.conjugate(),
                dp: Vec3::ZERO,
                dr: Mat3::IDENTITY,
            });
            self.vels.push(BodyVel {
                v: b.linear_velocity,
                w: b.angular_velocity,
            });
            self.dls.push(Vec3::ZERO);
            self.warm.push(BodyVel::default());
        }
        // Step 4's shortcut, known now: when even the lightest solver body
        // against the heaviest is not a high ratio, every contact keeps the
        // world's spring, set in step 3.
        let uniform = heaviest.is_positive() && !Softness::for_ratio(params, heaviest, lightest).1;
        // 3. Constant terms of each point: each constraint from its own pair
        //    and bodies alone, so the workers share them out in any order.
        let zero = SolverBody::default();
        let (bodies, vels, body_of_slot) = (&self.bodies, &self.vels, &self.body_of_slot);
        let pending = &self.pending;
        let constants = |c: &mut Constraint, k: u32| {
            // Every other field is set below (`points` up to `count`,
            // which is all any pass reads).
            let pc = &pending[k as usize];
            c.pair = pc.pair;
            c.a = pc.a;
            c.b = pc.b;
            c.friction = pc.friction;
            c.restitution = pc.restitution;
            c.rounding = pc.rounding;
            c.frame_poses = 0;
            let p = &pairs[c.pair as usize];
            c.a = if c.a == NONE {
                NONE
            } else {
                body_of_slot[c.a as usize]
            };
            c.b = if c.b == NONE {
                NONE
            } else {
                body_of_slot[c.b as usize]
            };
            let ba = if c.a == NONE {
                &zero
            } else {
                &bodies[c.a as usize]
            };
            let bb = if c.b == NONE {
                &zero
            } else {
                &bodies[c.b as usize]
            };
            c.wa = if ba.dynamic { c.a } else { NONE };
            c.wb = if bb.dynamic { c.b } else { NONE };
            let (va, vb) = (vel_or_zero(vels, c.a), vel_or_zero(vels, c.b));
            let n = p.manifold.normal;
            let t0 = tangent_of(n);
            let t1 = n.cross(t0);
            c.inv_mass_a = ba.inv_mass;
            c.inv_mass_b = bb.inv_mass;
            c.inv_mass_sum = ba.inv_mass + bb.inv_mass;
            c.normal = n;
            c.tangent = [t0, t1];
            c.count = p.manifold.points().len();
            let mut ks = [Scalar::ZERO; MAX_MANIFOLD_POINTS];
            for (k, (mp, imp)) in p.manifold.points().iter().zip(&p.impulses).enumerate() {
                let cp = &mut c.points[k];
                // Static bodies contribute nothing through their anchor, so
                // any reference point works; the contact point itself keeps
                // the numbers small.
                let ra = if c.a == NONE {
                    Vec3::ZERO
                } else {
                    mp.point - ba.center0
                };
                let rb = if c.b == NONE {
                    Vec3::ZERO
                } else {
                    mp.point - bb.center0
                };
                // The separation is followed through the point of each
                // shape's core behind the contact (one rounding radius in
                // from it, see `Shape::rounding`), a point of the body: the
                // contact point itself moves over a round surface, and as a
                // sphere rolled by θ in a tick its old contact point rose
                // by r(1 − cos θ), so the solver let it fall through the
                // second half of every tick (it rolled 2 mm deep, at
                // −g·dt/2 at each tick's end) and the friction of the
                // substeps that pushed it back up overshot μmg.
                let [round_a, round_b] = c.rounding;
                cp.ra = if c.a == NONE || round_a.is_zero() {
                    ra
                } else {
                    ra - scale(n, round_a)
                };
                cp.rb = if c.b == NONE || round_b.is_zero() {
                    rb
                } else {
                    rb + scale(n, round_b)
                };
                cp.adjusted_separation = -mp.depth - n.dot(cp.rb - cp.ra);
                cp.ra_n = cross(ra, n);
                cp.rb_n = cross(rb, n);
                cp.ia_n = ba.inv_inertia_mul(cp.ra_n);
                cp.ib_n = bb.inv_inertia_mul(cp.rb_n);
                ks[k] = effective(ba, bb, cp.ra_n, cp.rb_n, cp.ia_n, cp.ib_n);
                cp.normal_mass = inverse_or_zero(ks[k]);
                cp.relative_velocity = along(&va, &vb, n, cp.ra_n, cp.rb_n);
                cp.normal_impulse = imp.normal;
                cp.mark = imp.normal;
                cp.max_normal_impulse = Scalar::ZERO;
            }
            let patch = prepare_patch(p, c, ba, bb);
            c.patch = patch;
            if uniform {
                c.softness = params.softness;
            }
            ks
        };
        let placed = &self.placed;
        // Only grows; every entry below `used` is written next. A world on
        // the Q32.32 rows has none.
        self.rows_len = if params.narrow { used } else { 0 };
        if self.rows.len() < self.rows_len {
            self.rows.resize(self.rows_len, NarrowRows::default());
        }
        let both = Both::new(&mut self.constraints, &mut self.rows[..self.rows_len]);
        let on_narrow = AtomicU32::new(0);
        self.workers.for_each_block(used, BLOCK, |r| {
            // SAFETY: each block goes to one worker alone.
            let (block, rows) = unsafe { both.slices(r.clone()) };
            let placed = &placed[r];
            let mut narrow_here = 0;
            for (i, &k) in placed.iter().enumerate() {
                if let Some(&ahead) = placed.get(i + PREFETCH_AHEAD) {
                    prefetch(&block[i + PREFETCH_AHEAD]);
                    // In colour order the pairs are read out of order: ask
                    // for the next one's points too.
                    if let Some(p) = pairs.get(pending[ahead as usize].pair as usize) {
                        prefetch(&p.manifold);
                        prefetch(&p.impulses);
                    }
                }
                let ks = constants(&mut block[i], k);
                if let Some(row) = rows.get_mut(i) {
                    row.on = narrow::prepare(row, &block[i], &ks);
                    narrow_here += u32::from(row.on);
                }
            }
            // An exact count, whatever the order the blocks add in.
            on_narrow.fetch_add(narrow_here, Ordering::Relaxed);
        });
        let mut on_narrow = on_narrow.into_inner();
        // 4. The heaviest body each solver body touches (smallest inverse
        //    mass, its own included), then each contact's spring from the
        //    ratio of that to its lighter body, and the high-ratio list.
        //    No contact's ratio exceeds that of the lightest to the heaviest
        //    solver body (division rounds monotonically), so when even that
        //    one is not high (`uniform`), every contact kept the world's
        //    spring in step 3: the same result without the two walks.
        self.heavy.clear();
        if !uniform {
            on_narrow -= self.assign_ratio_springs(params);
        }
        // 5. The shock pass's order over the high-ratio contacts.
        self.order_shock();
        // 6. The lanes' batches: runs of eight constraints of one colour on
        //    the narrow rows with one point count, from each colour's start.
        self.batch_lanes(lanes);
        let grew = (
            self.bodies.capacity(),
            self.vels.capacity(),
            (self.dls.capacity(), self.warm.capacity()),
            self.body_of_slot.capacity(),
            (
                self.constraints.capacity(),
                self.rows.capacity(),
                self.batches.capacity(),
            ),
            self.touched.capacity(),
            self.heaviest.capacity(),
            self.heavy.capacity(),
            self.level.capacity(),
            self.shock.capacity(),
            (self.pending.capacity(), self.placed.capacity()),
            self.coloring.capacities(),
        ) != caps;
        let (colors, overflow) = self.coloring.report();
        SolverStats {
            constraints: self.constraints.len() as u32,
            colors,
            overflow,
            growths: grew as u32,
            narrow: on_narrow,
            lane_batches: self.lane_batches,
        }
    }

    /// Step 6 of [`prepare`](Self::prepare): copies the constants of every
    /// run of eight constraints that can go to the lanes together (one
    /// colour, all on the narrow rows, one point count; each run starts at
    /// its colour's start plus a multiple of eight, as the worker blocks
    /// do) into a batch, and marks its first constraint's rows with it.
    fn batch_lanes(&mut self, lanes: bool) {
        let n = self.constraints.len();
        let mut used = 0;
        if lanes {
            for c in 0..COLORS {
                let (start, end) = (
                    self.starts[c] as usize,
                    (self.starts[c + 1] as usize).min(n),
                );
                let mut i = start;
                while i + LANES <= end {
                    let rows = &mut self.rows[i..i + LANES];
                    if Batch::fits(rows) {
                        if used == self.batches.len() {
                            self.batches.push(Batch::default());
                        }
                        self.batches[used].fill(rows);
                        rows[0].batch = used as u32;
                        for r in &mut rows[1..] {
                            r.batch = NONE;
                        }
                        used += 1;
                    } else {
                        for r in rows {
                            r.batch = NONE;
                        }
                    }
                    i += LANES;
                }
                for r in &mut self.rows[i..end] {
                    r.batch = NONE;
                }
            }
            let colored = (self.starts[COLORS] as usize).min(n);
            for r in &mut self.rows[colored..n] {
                r.batch = NONE;
            }
        } else {
            for r in &mut self.rows[..self.rows_len] {
                r.batch = NONE;
            }
        }
        self.lane_batches = used as u32;
    }

    /// Whether this tick's passes may visit constraints on the narrow rows'
    /// lanes: narrow rows in colour order, the lanes on, and a CPU with
    /// them.
    fn lanes_will_run(&self, params: &SolverParams) -> bool {
        params.narrow && params.colored && self.lanes().is_some()
    }

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

    /// Sets the number of threads the colour passes use (1: this thread
    /// only). Starts or stops threads only when the count changes.
    pub(crate) fn set_workers(&mut self, count: usize) {
        if count.clamp(1, super::workers::MAX_WORKERS) != self.workers.count() {
            self.workers = Workers::new(count);
        }
    }

    /// Turns the wide kernels on where the CPU has them (`true`), or off.
    /// Not simulation state: the results are the same bits.
    pub(crate) fn set_wide(&mut self, on: bool) {
        self.wide_on = on;
    }

    /// Whether the passes use the wide kernels: turned on, and the CPU has
    /// them.
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

    /// The number of threads the colour passes use.
    pub(crate) fn workers(&self) -> usize {
        self.workers.count()
    }

    /// The world's worker pool (the solver holds it; the narrow phase and
    /// the integrators split their work over it too).
    pub(crate) fn pool(&self) -> &Workers {
        &self.workers
    }

    /// Whether there is anything to solve this tick.
    pub(crate) fn is_empty(&self) -> bool {
        self.constraints.is_empty()
    }

    /// Reads the bodies' current velocities and pose changes (after the
    /// integrator touched them).
    pub(crate) fn gather(&mut self, hot: &[BodyHot]) {
        // New poses: every cached separation frame is stale (a tick has a
        // few gathers, so the number never wraps to 0).
        self.poses = self.poses.wrapping_add(1).max(1);
        let len = self.bodies.len();
        let (bodies, vels) = (
            SharedMut::new(&mut self.bodies),
            SharedMut::new(&mut self.vels),
        );
        self.workers.for_each_block(len, BODY_BLOCK, |r| {
            // SAFETY: each block goes to one worker alone.
            let (bodies, vels) = unsafe { (bodies.slice(r.clone()), vels.slice(r)) };
            for (sb, vel) in bodies.iter_mut().zip(vels) {
                let b = &hot[sb.slot as usize];
                vel.v = b.linear_velocity;
                vel.w = b.angular_velocity;
                sb.dp = b.center - sb.center0;
                sb.dr = Mat3::from_quat(b.rotation * sb.rotation0_inv);
            }
        });
    }

    /// Reads only the velocities (the poses did not change since the last
    /// [`gather`](Self::gather)).
    pub(crate) fn gather_velocities(&mut self, hot: &[BodyHot]) {
        let len = self.bodies.len();
        let (bodies, vels) = (&self.bodies, SharedMut::new(&mut self.vels));
        self.workers.for_each_block(len, BODY_BLOCK, |r| {
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
    pub(crate) fn scatter_velocities(&self, hot: &mut [BodyHot]) {
        let (bodies, vels) = (&self.bodies, &self.vels);
        let hot = SharedMut::new(hot);
        self.workers.for_each_block(bodies.len(), BODY_BLOCK, |r| {
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
    pub(crate) fn scatter(&mut self, hot: &mut [BodyHot]) {
        let (bodies, vels) = (&self.bodies, &self.vels);
        let dls = SharedMut::new(&mut self.dls);
        let hot = SharedMut::new(hot);
        self.workers.for_each_block(bodies.len(), BODY_BLOCK, |r| {
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

    /// Applies last substep's (or last tick's) accumulated impulses again:
    /// the sums the last relax pass left in `warm` if it made them, else a
    /// pass over the constraints.
    pub(crate) fn warm_start(&mut self) {
        self.substeps = self.substeps.wrapping_add(1);
        if std::mem::take(&mut self.warm_ready) {
            let len = self.vels.len();
            let (vels, warm) = (
                SharedMut::new(&mut self.vels),
                SharedMut::new(&mut self.warm),
            );
            self.workers.for_each_block(len, BODY_BLOCK, |r| {
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
            &self.workers,
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
    pub(crate) fn solve(&mut self, params: &SolverParams, use_bias: bool, warm_next: bool) {
        let fuse = warm_next && !use_bias && self.heavy.is_empty() && self.shock.is_empty();
        // SAFETY: the pass visits one colour at a time (`for_each_colored`),
        // then the heavy constraints on this thread alone.
        let arrays = unsafe { BodyArrays::new(&mut self.vels, &mut self.dls, &mut self.warm) };
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
            arrays,
            // The wide kernels are the Q32.32 rows' lanes.
            lanes: self.wide_on && wide::available() && !params.narrow,
            poses: self.poses,
            fallbacks: &self.fallbacks,
            batches: &self.batches[..self.lane_batches as usize],
            kernel: if params.narrow && self.lane_batches > 0 {
                self.lanes()
            } else {
                None
            },
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
        for_each_colored(
            &mut self.constraints,
            rows,
            &self.starts,
            &self.workers,
            run,
        );
        self.warm_ready = fuse;
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
    pub(crate) fn restitution(&mut self, params: &SolverParams) {
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
            &self.workers,
            one_by_one(visit),
        );
    }

    /// Hands the accumulated impulses back to the pairs (warm starting next
    /// tick).
    ///
    /// In blocks of constraints over the workers: each constraint writes
    /// its own pair (`prepare` makes at most one constraint per pair).
    pub(crate) fn store_impulses(&self, pairs: &mut [ContactPair]) {
        let constraints = &self.constraints;
        let pairs = SharedMut::new(pairs);
        self.workers
            .for_each_block(constraints.len(), STORE_BLOCK, |r| {
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
