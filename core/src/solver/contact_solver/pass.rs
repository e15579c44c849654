//! One pass over the constraints: a visit of each, on the Q32.32 rows, the
//! narrow rows (scalar twin) or their lanes.

use super::constraint::{BodyVel, Constraint, NONE, SeparationFrame, SolverBody};
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
use crate::math::Scalar;
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
        self.points(c, &mut v);
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

    /// The normal rows: non-penetration at each point's current
    /// separation, in the substep's order ([`Visit::point`]).
    #[inline(always)]
    pub(super) fn points(&self, c: &mut Constraint, v: &mut Visit) {
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
            if wide::points(batch, &mut visits, self.params, self.use_bias) {
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
