//! `prepare`: the solver bodies and constraints of a tick, from the
//! contact pairs, in pair or colour order; and the lanes' batches.

use super::color::COLORS;
use super::constraint::{BodyVel, Constraint, NONE, Pending, SolverBody};
use super::iterate::{BLOCK, Both, PREFETCH_AHEAD};
use super::narrow::lanes::{Batch, LANES};
use super::narrow::{self, NarrowRows};
use super::params::{Softness, SolverParams, SolverStats};
use super::patch::prepare_patch;
use super::rows::{
    along, cross, effective, inverse_or_zero, prefetch, scale, tangent_of, vel_or_zero,
};
use super::{ContactSolver, PairInfo};
use crate::body::{BodyHot, BodyKind};
use crate::collision::contacts::reserve_near;
use crate::collision::{ContactPair, MAX_MANIFOLD_POINTS, PairKind};
use crate::math::{Mat3, Scalar, SymMat3, Vec3};
use crate::scratch::Capacities;
use crate::workers::{SharedMut, Workers};
use std::sync::atomic::{AtomicU32, Ordering};

/// Candidate pairs a worker scans at a time in `prepare`.
pub(super) const SCAN_BLOCK: usize = 64;

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
        workers: &Workers,
    ) -> SolverStats {
        let caps = self.capacities();
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
        self.quanta.clear();
        self.quanta0.clear();
        self.pq.clear();
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
            workers.for_each_block(candidates, SCAN_BLOCK, |r| {
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
            if params.narrow {
                self.quanta.push(Default::default());
                self.quanta0.push(Default::default());
                self.pq.push(narrow::PoseQ::ZERO);
            }
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
            c.hit = false;
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
        workers.for_each_block(used, BLOCK, |r| {
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
        // 5. The hits of this tick (extra relax visits).
        on_narrow -= self.find_impacts(params);
        // 6. The shock pass's order over the high-ratio contacts.
        self.order_shock();
        // 7. The lanes' batches: runs of eight constraints of one colour on
        //    the narrow rows with one point count, from each colour's start.
        self.batch_lanes(lanes);
        let grew = self.capacities().grew_since(&caps);
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

    /// The capacities of every buffer `prepare` fills: a tick that changed
    /// one grew a buffer (`SolverStats::growths`).
    fn capacities(&self) -> Capacities<22> {
        let [c0, c1, c2] = self.coloring.buffers();
        Capacities::of([
            &self.bodies,
            &self.vels,
            &self.dls,
            &self.warm,
            &self.quanta,
            &self.quanta0,
            &self.pq,
            &self.body_of_slot,
            &self.constraints,
            &self.rows,
            &self.batches,
            &self.touched,
            &self.heaviest,
            &self.heavy,
            &self.impact,
            &self.level,
            &self.shock,
            &self.pending,
            &self.placed,
            c0,
            c1,
            c2,
        ])
    }

    /// Step 7 of [`prepare`](Self::prepare): copies the constants of every
    /// run of eight constraints that can go to the lanes together (one
    /// colour, all on the narrow rows, one point count; each run starts at
    /// its colour's start plus a multiple of eight, as the worker blocks
    /// do) into a batch, and marks its first constraint's rows with it.
    pub(super) fn batch_lanes(&mut self, lanes: bool) {
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
                        self.batches[used].fill(rows, i);
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
    pub(super) fn lanes_will_run(&self, params: &SolverParams) -> bool {
        params.narrow && params.colored && self.lanes().is_some()
    }
}
