//! One pass over the constraints: a visit of each, on the Q32.32 rows, the
//! narrow rows (scalar twin) or their lanes.

use super::arith::{round_wide, scale};
use super::constraint::{BodyVel, Constraint, ConstraintPoint, NONE, SeparationFrame, SolverBody};
use super::iterate::{PREFETCH_AHEAD, for_each_prefetched};
use super::narrow::lanes::{Batch, Kernel, LANES};
use super::narrow::{self, NarrowRows};
use super::params::SolverParams;
use super::patch::solve_patch;
use super::rows::{
    BodyArrays, angular_along, apply_linear, linear_basis, mul, prefetch, push_angular,
};
use super::wide;
use crate::collision::MAX_MANIFOLD_POINTS;
use crate::math::scalar::wide_sum;
use crate::math::{Scalar, SymMat3, Vec3};
use crate::workers::SharedMut;

/// One solve or relax pass's settings and shared arrays (see
/// [`ContactSolver::solve`]).
pub(super) struct Pass<'a> {
    pub(super) params: &'a SolverParams,
    /// Soft push-out (the solve pass) or none (relax).
    pub(super) use_bias: bool,
    /// Whether the pass also sums the next substep's warm start.
    pub(super) fuse: bool,
    /// The substep count: where each manifold's points start.
    pub(super) rot: usize,
    pub(super) bodies: &'a [SolverBody],
    /// The narrow separations' pose changes (empty off the narrow rows).
    pub(super) pq: &'a [narrow::PoseQ],
    pub(super) arrays: BodyArrays,
    /// Whether runs inside a colour go to the wide kernels.
    pub(super) lanes: bool,
    /// The solver's pose number (see [`ContactSolver::poses`]).
    pub(super) poses: u32,
    /// Where a narrow visit whose guard failed is counted.
    pub(super) fallbacks: &'a narrow::Fallbacks,
    /// The lanes' batches (each visited by the worker whose block holds
    /// its constraints), and the kernel build that runs them (`None`: the
    /// narrow rows' lanes are off).
    pub(super) batches: SharedMut<'a, Batch>,
    pub(super) kernel: Option<Kernel>,
}

/// One constraint's visit from its velocities to its write-back: what
/// [`Pass::head`] leaves for [`Pass::points`] (or the wide kernel),
/// [`Pass::friction`] and [`Pass::tail`].
#[derive(Clone, Copy, Default)]
pub(super) struct Visit {
    pub(super) va: BodyVel,
    pub(super) vb: BodyVel,
    /// The linear part of the relative velocity along n, t0 and t1, kept up
    /// to date through the rows (an impulse λ along one unit direction of
    /// the basis changes it by λ(1/mA + 1/mB) along that direction and not
    /// along the other two).
    pub(super) u: [Scalar; 3],
    /// The impulses applied in this visit, turned into linear velocity once
    /// at the end: three products per row instead of nine.
    pub(super) applied: [Scalar; 3],
    pub(super) frame: SeparationFrame,
    /// Whether `frame` and the points' separations were cached at these
    /// poses (else the points compute and cache their separations).
    pub(super) cached: bool,
    /// The substep counter: the order of the normal rows
    /// ([`row_order`](super::constraint::row_order)).
    pub(super) rot: usize,
}

impl Visit {
    /// The point visited at step `kk` of a manifold of `count` points
    /// ([`row_order`](super::constraint::row_order)).
    #[inline(always)]
    pub(super) fn point(&self, kk: usize, count: usize) -> usize {
        super::constraint::row_order(kk, count, self.rot)
    }

    /// Point `cp`'s current separation: cached at these poses, or computed
    /// from the frame and cached.
    #[inline(always)]
    pub(super) fn separation(&self, cp: &mut ConstraintPoint) -> Scalar {
        if self.cached {
            cp.separation
        } else {
            let s = self.frame.separation(cp);
            cp.separation = s;
            s
        }
    }
}

impl Pass<'_> {
    /// One visit of constraint `c`: the normal rows, then friction, on the
    /// narrow rows if the constraint is on them (see [`narrow`]), else on
    /// the Q32.32 rows. A narrow visit whose guard fails writes nothing;
    /// the constraint's impulses go back to Q32.32 and the Q32.32 rows
    /// solve it from this visit to the end of the tick.
    #[inline(always)]
    pub(super) fn visit(&self, c: &mut Constraint, r: Option<&mut NarrowRows>) {
        let narrow_world = r.is_some();
        if let Some(r) = r.filter(|r| r.on) {
            if narrow::visit(&self.narrow_args(), r) {
                self.accepted(c, r);
            } else {
                self.refused(c, r);
            }
            return;
        }
        if narrow_world {
            // A world on the narrow rows: its velocities are in quanta.
            self.visit_exact_in_quanta(c);
        } else {
            self.visit_exact(c);
        }
    }

    /// One visit of `c` on the Q32.32 rows during a narrow pass: its
    /// bodies' Q32.32 velocities take their change in quanta first, and
    /// their quanta are taken again after (see [`narrow::Quanta`]).
    #[inline(never)]
    pub(super) fn visit_exact_in_quanta(&self, c: &mut Constraint) {
        self.arrays.flush_one(c.wa);
        self.arrays.flush_one(c.wb);
        self.visit_exact(c);
        self.arrays.requantize_one(c.wa);
        self.arrays.requantize_one(c.wb);
    }

    /// What the narrow rows' visits read of this pass.
    #[inline(always)]
    pub(super) fn narrow_args(&self) -> narrow::VisitArgs<'_> {
        narrow::VisitArgs {
            params: self.params,
            pq: self.pq,
            arrays: &self.arrays,
            use_bias: self.use_bias,
            rot: self.rot,
            poses: self.poses,
        }
    }

    /// After a narrow visit that its guard accepted: the next warm start,
    /// if this pass sums it.
    #[inline(always)]
    pub(super) fn accepted(&self, c: &Constraint, r: &mut NarrowRows) {
        if self.fuse {
            let (da, db) = narrow::warm_start(r);
            self.arrays.add_warm(c.wa, c.wb, da, db);
        }
    }

    /// After a narrow visit that its guard refused (it wrote nothing): the
    /// impulses back in Q32.32, and the constraint on the Q32.32 rows from
    /// this visit to the end of the tick.
    #[inline(never)]
    pub(super) fn refused(&self, c: &mut Constraint, r: &mut NarrowRows) {
        narrow::write_back(r, c);
        r.on = false;
        self.fallbacks.add();
        self.visit_exact_in_quanta(c);
    }

    /// Visits a run of constraints of one colour on the narrow rows: each
    /// batch of eight (see `narrow::lanes`) on the lanes, the others one at
    /// a time. The same bits as visiting them in order: each constraint's
    /// visit reads and writes only its own data and its bodies.
    pub(super) fn visit_narrow_run(
        &self,
        cs: &mut [Constraint],
        rs: &mut [NarrowRows],
        kernel: Kernel,
    ) {
        let len = cs.len().min(rs.len());
        let args = self.narrow_args();
        let mut i = 0;
        while i < len {
            let b = rs[i].batch;
            if b != NONE && i + LANES <= len {
                debug_assert!(Batch::fits(&rs[i..i + LANES]));
                // SAFETY: batch `b` holds constraints `i..i + LANES` of
                // this worker's block alone (`batch_lanes`).
                let batch = unsafe { self.batches.get(b as usize) };
                let rows = &mut rs[i..i + LANES];
                let refused = narrow::lanes::visit(&args, batch, rows, kernel);
                if !refused.contains(&true) {
                    if self.fuse {
                        // The next warm start of the whole batch on the
                        // lanes.
                        let warm = narrow::lanes::warm_start(batch, rows);
                        for (c, (da, db)) in cs[i..i + LANES].iter().zip(warm) {
                            self.arrays.add_warm(c.wa, c.wb, da, db);
                        }
                    }
                } else {
                    // The batch's state went back to the rows: the twin
                    // visits these constraints for the rest of the tick.
                    rows[0].batch = NONE;
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
    pub(super) fn visit_exact(&self, c: &mut Constraint) {
        let mut v = self.head(c);
        self.normal_rows(c, &mut v);
        self.friction(c, &mut v);
        self.tail(c, &mut v);
    }

    /// The visit up to the normal rows: the velocities and the separation
    /// frame.
    #[inline(always)]
    pub(super) fn head(&self, c: &mut Constraint) -> Visit {
        let (va, vb) = self.arrays.load(c.a, c.b);
        let u = linear_basis(c, &va, &vb);
        let cached = c.frame_poses == self.poses;
        if !cached {
            c.frame = SeparationFrame::of(c, self.bodies);
            c.frame_poses = self.poses;
        }
        Visit {
            va,
            vb,
            u,
            applied: [Scalar::ZERO; 3],
            frame: c.frame,
            cached,
            rot: self.rot,
        }
    }

    /// The normal rows of a visit: a hit's as a block where it holds
    /// (see [`hit_row`](Self::hit_row)), else one point at a time.
    #[inline(always)]
    pub(super) fn normal_rows(&self, c: &mut Constraint, v: &mut Visit) {
        if !(c.hit && self.hit_row(c, v)) {
            self.points(c, v);
        }
    }

    /// A hit's normal rows solved together (a block solve), where the
    /// rigid solution holds. Each point's row asks for the approach it
    /// allows (a gap closed within the substep; none once touching, or the
    /// soft pass's push-out). The block takes the points that push (first
    /// those holding an impulse or approaching faster than allowed; if
    /// some would then pull, those released and the rest again):
    /// one impulse per mode of their patch, its push (every point alike)
    /// and its tilts (shares linear in each point's offset from their mean
    /// along each direction of the patch), which reach every point of a
    /// rigid face at once. It is kept when the pushing points' accumulated
    /// impulses stay ≥ 0 and the released points move apart no slower
    /// than their rows allow: every row is then met, as the point rows
    /// would meet them if they converged, and they are skipped; otherwise
    /// nothing is written and the point rows work alone.
    ///
    /// In the soft pass a touching point asks for the spring's push-out
    /// (its bias, capped at `max_push_out`) with the whole effective mass:
    /// the block is rigid, as the relax pass's rows are. A hit lasts a tick
    /// or two; the spring's softness is for the loads that stay.
    ///
    /// One row after another, the first corner visited took the whole hit
    /// and pitched the box about it: a box landing flat while it slid
    /// came off the hit with a roll and a sideways speed (4.2 cm/s at
    /// 3,840 Hz) that its rest point kept; now 0.
    ///
    /// Ranges: the tilt modes are scaled to at most 1 at any point, so each
    /// mode's sums are at most four points' `r×n`, `I⁻¹(r×n)` and impulses,
    /// the sizes the point rows already form, and round as theirs do. A
    /// block that [`SymMat3::try_inverse`] cannot invert (singular, as
    /// three points in a line are, or out of range) is not used, and one
    /// near singular (a thin patch, or targets no rigid face can meet) is
    /// caught before any result is narrowed: its impulses are formed in
    /// 128 bits with checked sums and refused past [`HitPoints::limit`].
    /// So a refused block raises no fault (before that bound, one did, in
    /// `engines`' convex pile). Nothing divides by zero.
    #[inline(never)]
    pub(super) fn hit_row(&self, c: &mut Constraint, v: &mut Visit) -> bool {
        let count = c.count.min(MAX_MANIFOLD_POINTS);
        if count < 2 {
            return false;
        }
        let inv_h = self.params.inv_h;
        let mut hit = HitPoints::default();
        for (k, cp) in c.points[..count].iter_mut().enumerate() {
            let s = v.separation(cp);
            hit.allowed[k] = if s.is_positive() {
                -(s * inv_h)
            } else if self.use_bias {
                -(c.softness.bias_rate * s).max(-self.params.max_push_out)
            } else {
                Scalar::ZERO
            };
            hit.vn[k] = v.u[0] + angular_along(&v.va, &v.vb, cp.ra_n, cp.rb_n);
            hit.at[k] = if c.b == NONE { cp.ra } else { cp.rb };
        }
        // The points that push first: those that push now and those
        // approaching faster than their rows allow.
        let mut pushing = [false; MAX_MANIFOLD_POINTS];
        for (k, cp) in c.points[..count].iter().enumerate() {
            pushing[k] = cp.normal_impulse.is_positive() || hit.vn[k] < hit.allowed[k];
        }
        if !pushing.contains(&true) {
            return false;
        }
        let Some(first) = hit.block(c, count, pushing) else {
            return false;
        };
        let d = if first[..count].iter().all(|x| !x.is_negative()) {
            first
        } else {
            for k in 0..count {
                pushing[k] = first[k].is_positive();
            }
            let Some(d) = hit.block(c, count, pushing) else {
                return false;
            };
            d
        };
        if d[..count].iter().any(|x| x.is_negative()) || !hit.meets_rows(c, count, &d) {
            return false;
        }
        for (k, cp) in c.points[..count].iter_mut().enumerate() {
            let change = d[k] - cp.normal_impulse;
            if change.is_zero() {
                continue;
            }
            if cp.max_normal_impulse.is_zero() && d[k].is_positive() {
                // The first push this tick: its approach speed is what
                // restitution reflects (as in `points`).
                cp.relative_velocity = cp.relative_velocity.min(hit.vn[k]);
            }
            cp.normal_impulse = d[k];
            cp.max_normal_impulse = cp.max_normal_impulse.max(d[k]);
            v.u[0] += mul(c.inv_mass_sum, change);
            v.applied[0] += change;
            push_angular(&mut v.va, &mut v.vb, c.a, c.b, change, cp.ia_n, cp.ib_n);
        }
        true
    }

    /// The normal rows: non-penetration at each point's current
    /// separation, in the substep's order ([`Visit::point`]).
    #[inline(always)]
    pub(super) fn points(&self, c: &mut Constraint, v: &mut Visit) {
        let params = self.params;
        let count = c.count.min(MAX_MANIFOLD_POINTS);
        for kk in 0..count {
            let cp = &mut c.points[v.point(kk, count)];
            let s = v.separation(cp);
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

    /// Friction at the patch centre, after the normal rows, bounded by μ
    /// times the manifold's total normal impulse: in a soft pass, the warm
    /// start's (the one the last substep's relax pass settled); in a relax
    /// pass, or for a contact without a warm start (new this substep), the
    /// one its normal rows just settled. An exact sum, whatever the order
    /// of its points (see [`solve_patch`]). The relax pass's rows are rigid
    /// and its velocities are the ones the substep keeps, so its friction
    /// takes the load they settled: under a load that falls within a tick
    /// (the end of a hit) the warm start's total is stale, and a box
    /// landing flat while it slid lost up to 1.6 times the speed Coulomb's
    /// law allows in one tick and tipped over its leading edge. The soft
    /// pass keeps the warm start's total: its rows carry the push-out,
    /// and bounding friction by that let tall stacks lean (`stress`
    /// stack_height 50 → 40).
    #[inline(always)]
    pub(super) fn friction(&self, c: &mut Constraint, v: &mut Visit) {
        // A soft pass on a warm-started contact: the warm start's total,
        // and the twist keeps its impulse (see `solve_patch`).
        let warm = self.use_bias && c.warm_total.is_positive();
        let total = if warm {
            c.warm_total
        } else {
            let count = c.count.min(MAX_MANIFOLD_POINTS);
            let mut total = Scalar::ZERO;
            for cp in &c.points[..count] {
                total += cp.normal_impulse;
            }
            total
        };
        solve_patch(c, &mut v.va, &mut v.vb, &v.u, &mut v.applied, total, !warm);
    }

    /// The visit after the normal rows and friction: the linear impulses, the
    /// velocities back, and (relax) the angular write-back and the next
    /// warm start.
    #[inline(always)]
    pub(super) fn tail(&self, c: &mut Constraint, v: &mut Visit) {
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
    pub(super) fn visit_batches(
        &self,
        cs: &mut [Constraint],
        rs: &mut [NarrowRows],
    ) -> wide::Counts {
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
            if batch.iter().any(|c| c.hit) {
                // A hit's normal rows are a block (see `hit_row`): this
                // batch one constraint at a time.
                for (c, v) in batch.iter_mut().zip(&mut visits) {
                    self.normal_rows(c, v);
                }
            } else if wide::points(batch, &mut visits, self.params, self.use_bias) {
                counts.lanes += 1;
            } else {
                counts.guarded += 1;
                for (c, v) in batch.iter_mut().zip(&mut visits) {
                    self.points(c, v);
                }
            }
            for (c, v) in batch.iter_mut().zip(&mut visits) {
                self.friction(c, v);
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

/// What [`Pass::hit_row`] reads of a hit's points: the normal velocity
/// each had at the visit's start, the velocity its row allows, and its
/// position on the body the patch's offsets are measured on.
#[derive(Default)]
struct HitPoints {
    vn: [Scalar; MAX_MANIFOLD_POINTS],
    allowed: [Scalar; MAX_MANIFOLD_POINTS],
    at: [Vec3; MAX_MANIFOLD_POINTS],
}

/// How far a point's normal velocity after a hit's block may be from what
/// its row asks (rounding), m/s: about 10⁻⁶.
const HIT_SLACK: Scalar = Scalar::from_bits(1 << 12);

impl HitPoints {
    /// The accumulated impulses with the points of `pushing` meeting their
    /// rows and the others at zero (in the least-squares sense of the
    /// patch's modes: exact for a rigid face's rows), or `None` if the
    /// block is singular or near it (its impulses past
    /// [`limit`](Self::limit)).
    fn block(
        &self,
        c: &Constraint,
        count: usize,
        pushing: [bool; MAX_MANIFOLD_POINTS],
    ) -> Option<[Scalar; MAX_MANIFOLD_POINTS]> {
        let pts = &c.points[..count];
        let mut out = [Scalar::ZERO; MAX_MANIFOLD_POINTS];
        let active: u32 = pushing[..count].iter().map(|&p| u32::from(p)).sum();
        if active == 0 {
            return Some(out);
        }
        // What the accumulated impulses do now: the block replaces them.
        let mut now = Response::default();
        for cp in pts {
            now.add(cp, cp.normal_impulse);
        }
        let n = i64::from(active);
        let mut mean = Vec3::ZERO;
        let mut ends = [Vec3::ZERO; 2];
        for (seen, k) in (0..count).filter(|&k| pushing[k]).enumerate() {
            mean += self.at[k];
            if let Some(end) = ends.get_mut(seen) {
                *end = self.at[k];
            }
        }
        let mean = Vec3::new(mean.x.div_int(n), mean.y.div_int(n), mean.z.div_int(n));
        // Two points have one tilt, along their line; three or more, one
        // along each tangent.
        let dirs = if active == 2 {
            [ends[1] - ends[0], Vec3::ZERO]
        } else {
            c.tangent
        };
        let mut modes = [[Scalar::ZERO; 3]; MAX_MANIFOLD_POINTS];
        let mut reach = [Scalar::ZERO; 3];
        for k in (0..count).filter(|&k| pushing[k]) {
            let d = self.at[k] - mean;
            modes[k] = [Scalar::ONE, d.dot(dirs[0]), d.dot(dirs[1])];
            for j in 1..3 {
                reach[j] = reach[j].max(modes[k][j].abs());
            }
        }
        // Each tilt in units of its largest offset (at most 1 at any
        // point, 1 at some): the block's entries are of one size whatever
        // the patch's shape. Only the tilts the points have.
        let tilts = match active {
            1 => 0,
            2 => 1,
            _ => 2,
        };
        for j in 1..=tilts {
            let unit = Scalar::ONE.checked_div(reach[j])?;
            for m in &mut modes[..count] {
                m[j] = mul(m[j], unit);
            }
        }
        // Each mode's response, and what it must make up at its points.
        let mut resp = [Response::default(); 3];
        let mut miss = [Scalar::ZERO; 3];
        for (k, cp) in pts.iter().enumerate().filter(|&(k, _)| pushing[k]) {
            let want = self.allowed[k] - self.vn[k] + now.at(c, cp);
            for j in 0..3 {
                let e = modes[k][j];
                resp[j].add(cp, e);
                miss[j] += mul(e, want);
            }
        }
        let entry = |i: usize, j: usize| resp[i].dot(c, &resp[j]);
        let (one, zero) = (Scalar::ONE, Scalar::ZERO);
        let block = match active {
            1 => SymMat3::from_diagonal(Vec3::new(entry(0, 0), one, one)),
            2 => SymMat3 {
                xx: entry(0, 0),
                yy: entry(1, 1),
                zz: one,
                xy: entry(0, 1),
                xz: zero,
                yz: zero,
            },
            _ => SymMat3 {
                xx: entry(0, 0),
                yy: entry(1, 1),
                zz: entry(2, 2),
                xy: entry(0, 1),
                xz: entry(0, 2),
                yz: entry(1, 2),
            },
        };
        // A block near singular (a patch thin across one tilt, as points
        // nearly in a line) asks for huge impulses of opposite signs: the
        // products below are checked, and a result past `limit` is not
        // used. Nothing here raises a fault.
        let inv = block.try_inverse()?;
        let miss = Vec3::new(miss[0], miss[1], miss[2]);
        let rows = [
            Vec3::new(inv.xx, inv.xy, inv.xz),
            Vec3::new(inv.xy, inv.yy, inv.yz),
            Vec3::new(inv.xz, inv.yz, inv.zz),
        ];
        let mut mu = [Scalar::ZERO; 3];
        for (m, row) in mu.iter_mut().zip(rows) {
            let acc = row
                .x
                .wide_mul(miss.x)
                .checked_add(row.y.wide_mul(miss.y))?
                .checked_add(row.z.wide_mul(miss.z))?;
            *m = checked_round(acc)?;
        }
        let limit = self.limit(c, count);
        for k in (0..count).filter(|&k| pushing[k]) {
            let m = modes[k];
            // |m| ≤ 1 and |mu| < 2⁶³ (in 2⁻³² units): each product is
            // below 2⁹⁵, the sum below 2⁹⁷.
            let acc = m[0].wide_mul(mu[0]) + m[1].wide_mul(mu[1]) + m[2].wide_mul(mu[2]);
            if acc.unsigned_abs() > limit {
                return None;
            }
            out[k] = checked_round(acc)?;
        }
        Some(out)
    }

    /// The largest accumulated impulse a block may give a point, in
    /// units of 2⁻⁶⁴: sixteen times what stopping every point on its own
    /// row takes (`Σ |allowed − vn|·m_point`) plus twice the impulses held
    /// now. A rigid face's solution is of the order of the first (the
    /// whole face's mass against its points' sum of effective masses);
    /// past the bound the block is taken as singular.
    fn limit(&self, c: &Constraint, count: usize) -> u128 {
        let mut sum: u128 = 1 << 64;
        for (k, cp) in c.points[..count].iter().enumerate() {
            let want = (self.allowed[k] - self.vn[k]).abs();
            // Saturating: a bound past any impulse that fits is no bound.
            let stop = want.wide_mul(cp.normal_mass).unsigned_abs();
            let held = (cp.normal_impulse.to_bits().unsigned_abs() as u128) << 32;
            sum = sum
                .saturating_add(stop.saturating_mul(16))
                .saturating_add(held.saturating_mul(2));
        }
        sum
    }

    /// Whether accumulated impulses `new` meet every row: the pushing
    /// points (`new > 0`) at what they allow, the others moving apart no
    /// slower, each within [`HIT_SLACK`].
    fn meets_rows(
        &self,
        c: &Constraint,
        count: usize,
        new: &[Scalar; MAX_MANIFOLD_POINTS],
    ) -> bool {
        let pts = &c.points[..count];
        let mut change = Response::default();
        for (k, cp) in pts.iter().enumerate() {
            change.add(cp, new[k] - cp.normal_impulse);
        }
        pts.iter().enumerate().all(|(k, cp)| {
            let off = self.vn[k] + change.at(c, cp) - self.allowed[k];
            if new[k].is_positive() {
                off.abs() <= HIT_SLACK
            } else {
                off >= -HIT_SLACK
            }
        })
    }
}

/// The response of a constraint's bodies to normal impulses at its points:
/// their sum and their sums weighted by each point's `r×n` and `I⁻¹(r×n)`.
#[derive(Clone, Copy, Default)]
struct Response {
    lin: Scalar,
    ra: Vec3,
    ia: Vec3,
    rb: Vec3,
    ib: Vec3,
}

impl Response {
    /// Adds impulse `x` at point `cp`.
    #[inline(always)]
    fn add(&mut self, cp: &ConstraintPoint, x: Scalar) {
        self.lin += x;
        self.ra += scale(cp.ra_n, x);
        self.ia += scale(cp.ia_n, x);
        self.rb += scale(cp.rb_n, x);
        self.ib += scale(cp.ib_n, x);
    }

    /// The change of point `cp`'s normal velocity.
    #[inline(always)]
    fn at(&self, c: &Constraint, cp: &ConstraintPoint) -> Scalar {
        round_wide(wide_sum([
            c.inv_mass_sum.wide_mul(self.lin),
            cp.ra_n.dot_wide(self.ia),
            cp.rb_n.dot_wide(self.ib),
        ]))
    }

    /// `xᵀ A y` for the impulses `x` (this) and `y` (`other`).
    #[inline(always)]
    fn dot(&self, c: &Constraint, other: &Response) -> Scalar {
        round_wide(wide_sum([
            mul(self.lin, other.lin).wide_mul(c.inv_mass_sum),
            self.ra.dot_wide(other.ia),
            self.rb.dot_wide(other.ib),
        ]))
    }
}

/// A Q64.64 value rounded to Q32.32 (to nearest, ties toward +∞, as
/// [`round_wide`]), or `None` if it does not fit: no fault.
fn checked_round(acc: i128) -> Option<Scalar> {
    let q = acc.checked_add(1 << 31)? >> 32;
    i64::try_from(q).ok().map(Scalar::from_bits)
}
