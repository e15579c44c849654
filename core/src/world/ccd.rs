//! Continuous collision (CCD): the stage of `World::step` that stops fast
//! bodies before they pass through thin shapes.
//!
//! **Who is swept.** After the substeps have moved the bodies, every awake
//! dynamic body with a solid collider is checked with a few integer
//! comparisons: it is a *candidate* when its centre moved more than
//! [`CCD_MOTION_FRACTION`] (¼) of its smallest extent this tick, when its
//! rotation (bounded by `|ω|₁·dt·r_max`) could move its surface that far, or
//! when it is a bullet. Slow bodies pay those comparisons and nothing else
//! (plus the copy of their start pose before the substeps).
//!
//! **Against what.** Candidates are swept against static shapes and
//! sleeping bodies (the broad phase's static tree, queried with the box of
//! the body's bounding sphere at the start and end of the tick). Bullets are
//! swept afterwards, also against awake dynamic and kinematic bodies, which
//! are taken at their end-of-tick poses (after their own CCD); bullets are
//! not swept against each other. Triggers, filtered pairs and the body's own
//! colliders are skipped; compound bodies sweep every solid collider with
//! the one body motion and take the earliest hit.
//!
//! **The motion** is the body's pose interpolated between the start and the
//! end of the tick: the centre linearly, the rotation at a constant rate
//! about the fixed axis taking the start orientation to the end one.
//!
//! **Time of impact** by the conservative advancement that shape sweeps use
//! too ([`crate::collision::toi`]): each advance aims at a gap of
//! [`CCD_TARGET_GAP`], a gap within [`CCD_TOLERANCE`] of it is a hit, the
//! rotation is bounded by the tick's angle times the collider's largest
//! distance from the centre of mass. The body is stopped at the last
//! fraction verified apart, also when [`CCD_MAX_ITERATIONS`] is reached
//! (early, never through). This module keeps the candidate selection, the
//! core sweep of pairs already touching, and the response.
//!
//! **Already touching.** A pair closer than `CCD_TARGET_GAP + CCD_TOLERANCE`
//! at the start of the tick (a box sliding on the floor, a body resting on
//! a wall) would report a hit at once and freeze the body; instead the pair
//! is swept again with a *core* sphere: the collider's centre with a quarter
//! of its smallest extent as radius (as Box2D v3 does). The core hits only
//! when the body is really going through; a core that already touches is
//! left to the contact solver. A core that starts within reach of the
//! target gap but not touching (the body is pressed in by nearly three
//! quarters of its extent) stops the body at fraction 0, unless the core is
//! still apart, on the same side, at the end of the motion: then it cannot
//! be going through, and a stop would only hold the body at its start pose,
//! tick after tick, while the solver kept adding velocity that never moved
//! it (a ragdoll's shin pressed into a step under a pile did exactly that,
//! and the pile exploded).
//!
//! **The response.** On a hit at fraction `t`, the body is moved to its
//! pose at `t` (a gap of about [`CCD_TARGET_GAP`] from the surface) and
//! keeps its velocities (the angular velocity is recomputed from the kept
//! angular momentum at the new orientation). The next tick's speculative
//! contact, whose reach covers the gap plus the closing distance, then stops
//! or bounces it with the material's restitution: the response is the
//! solver's, not CCD's. The time after the hit is lost for that body (one
//! tick of "pause" in front of the obstacle).
//!
//! Determinism: candidates in handle order (non-bullets first, then
//! bullets); target colliders sorted by handle; fixed iteration caps; the
//! earliest hit wins, ties keep the first in that order. Never allocates
//! once its buffers are warm (growths are counted); never panics.

use crate::body::{BodyHandle, BodyHot, BodyKind};
use crate::collider::Collider;
use crate::collision::ProxyId;
use crate::collision::narrow::gjk::{DistanceResult, SupportShape, distance};
use crate::collision::toi::{Motion, Toi, ToiSettings, shape_pose, time_of_impact};
use crate::math::elem::isqrt_u128;
use crate::math::{Aabb, Quat, Scalar, Transform, Vec3};
use crate::query::overlap::{box_in_frame, for_each_triangle, raw_box};
use crate::query::{Triangle, convex_support};
use crate::shape::{Capsule, Cuboid, Shape, Sphere};
use crate::solver::integrate::omega_from_momentum;

use super::state::World;
use crate::solver::integrate::rotation_delta;

/// The gap continuous collision leaves between a stopped body and the
/// obstacle: 2⁻⁸ m ≈ 3.9 mm. Well inside the default 2 cm contact margin
/// (so the next tick's speculative contact sees it), well above the GJK's
/// resolution and the rounding of the interpolated pose (nanometres).
pub const CCD_TARGET_GAP: Scalar = Scalar::from_bits(1 << 24);

/// How close to [`CCD_TARGET_GAP`] an advance must land to count as a hit:
/// 2⁻¹⁰ m ≈ 1 mm. A face-on approach lands within it after one advance.
pub const CCD_TOLERANCE: Scalar = Scalar::from_bits(1 << 22);

/// The most GJK distance evaluations per collider pair. Translation-only
/// approaches need two or three; a spinning body closes a fixed share of the
/// remaining gap per iteration. When the cap is reached the body is stopped
/// at the last fraction reached (which was verified apart): early, never
/// through.
pub const CCD_MAX_ITERATIONS: usize = 32;

/// Bodies moving more than this fraction of their smallest extent in one
/// tick are swept: ¼ (the speculative contacts handle slower ones).
pub const CCD_MOTION_FRACTION: Scalar = Scalar::from_bits(1 << 30);

/// What the CCD stage did.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct CcdStats {
    /// Bodies whose motion was swept.
    pub bodies: u32,
    /// Bodies moved back to a time of impact.
    pub hits: u32,
    /// Buffer growths (allocations).
    pub growths: u32,
}

/// A collider's extents about its own origin, for CCD.
#[derive(Clone, Copy, Debug)]
struct Extent {
    /// A point well inside the shape (local frame): the core sphere's centre.
    center: Vec3,
    /// The smallest distance from `center` to the surface (a lower bound).
    min: Scalar,
    /// The largest distance from the shape's origin to a point of it (an
    /// upper bound).
    radius: Scalar,
}

/// The extents of a convex shape; `None` for meshes and height fields
/// (static only, never swept).
fn extent_of(shape: &Shape) -> Option<Extent> {
    match shape {
        Shape::Sphere(s) => Some(Extent {
            center: Vec3::ZERO,
            min: s.radius,
            radius: s.radius,
        }),
        Shape::Capsule(c) => Some(Extent {
            center: Vec3::ZERO,
            min: c.radius,
            radius: c.half_height + c.radius,
        }),
        Shape::Cuboid(b) => Some(Extent {
            center: Vec3::ZERO,
            min: b.half_extents.min_element(),
            radius: b.half_extents.length(),
        }),
        Shape::ConvexHull(h) => {
            let vs = h.vertices();
            let n = vs.len().max(1) as i128;
            let mut sum = [0i128; 3];
            let mut far = 0u128;
            for v in vs {
                for (k, s) in sum.iter_mut().enumerate() {
                    *s += v.get(k).to_bits() as i128;
                }
                far = far.max(v.length_squared_wide());
            }
            let c = Vec3::new(
                Scalar::from_bits((sum[0] / n) as i64),
                Scalar::from_bits((sum[1] / n) as i64),
                Scalar::from_bits((sum[2] / n) as i64),
            );
            let min = h
                .faces()
                .iter()
                .map(|f| f.offset() - f.normal().dot(c))
                .min()
                .unwrap_or(Scalar::ZERO)
                .max(Scalar::ZERO);
            Some(Extent {
                center: c,
                min,
                // Round the square root up so the bound stays an upper one.
                radius: Scalar::from_bits(isqrt_u128(far) as i64 + 1),
            })
        }
        Shape::TriMesh(_) | Shape::HeightField(_) => None,
    }
}

/// The CCD settings: aim at the target gap, a hit within the tolerance of
/// it.
const SETTINGS: ToiSettings = ToiSettings {
    target: CCD_TARGET_GAP,
    tolerance: CCD_TOLERANCE,
    max_iterations: CCD_MAX_ITERATIONS,
};

/// How one collider pair's sweep ended, for CCD.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Outcome {
    /// Stop at this fraction.
    Hit(Scalar),
    /// No contact up to the limit.
    Miss,
    /// Already within `touch` at the start (or overlapping), and
    /// approaching.
    Touching,
}

/// The shared time-of-impact routine, read for CCD: a pair that starts
/// within `touch` while approaching (or overlapping) is
/// [`Outcome::Touching`]; one that starts within reach but not within
/// `touch` (only a core) is too if the motion leaves it apart on the same
/// side, else it stops at fraction 0; a converged or exhausted sweep stops
/// the body at the last fraction verified apart.
#[allow(clippy::too_many_arguments)]
fn sweep<A: SupportShape + ?Sized, B: SupportShape + ?Sized>(
    a: &A,
    local: &Transform,
    rho: Scalar,
    m: &Motion,
    b: &B,
    pose_b: &Transform,
    limit: Scalar,
    touch: Scalar,
) -> Outcome {
    let limit = limit.min(Scalar::ONE);
    match time_of_impact(a, local, rho, m, b, pose_b, limit, &SETTINGS) {
        Toi::Overlapping => Outcome::Touching,
        Toi::Hit { at, at_start: true } if at.gap <= touch => Outcome::Touching,
        Toi::Hit { at, at_start: true } => {
            // Within reach at the start but not touching (only a core gets
            // here). Stopping at fraction 0 keeps it from going through a
            // thin wall; but if the motion leaves it apart on the same side
            // at the end, it cannot go through, and a stop would only hold
            // the body at its start pose, tick after tick, while the solver
            // kept adding velocity that never moved it. That is left to the
            // solver.
            match distance(a, &shape_pose(m, local, limit), b, pose_b) {
                DistanceResult::Separated { normal, .. }
                    if (-normal).dot(at.normal).is_positive() =>
                {
                    Outcome::Touching
                }
                _ => Outcome::Hit(at.fraction),
            }
        }
        Toi::Hit { at, .. } | Toi::Exhausted(at) => Outcome::Hit(at.fraction),
        Toi::Miss => Outcome::Miss,
    }
}

/// One solid collider of a swept body, with its CCD extents.
#[derive(Clone, Copy)]
struct Part<'a> {
    collider: &'a Collider,
    ext: Extent,
    /// Largest distance of its points from the body's centre of mass.
    rho: Scalar,
}

/// The sweep of one moving collider against one convex target. A pair that
/// already touches at the start is swept again with the collider's *core*
/// (the shape shrunk by three quarters of its smallest extent: a sphere or
/// capsule of a quarter of the radius, a box with every face moved in by
/// that much, a sphere at a hull's vertex centroid), which may come as
/// close as the target gap before it is stopped.
fn sweep_pair<B: SupportShape + ?Sized>(
    part: &Part<'_>,
    m: &Motion,
    b: &B,
    pose_b: &Transform,
    limit: Scalar,
) -> Option<Scalar> {
    let mover = part.collider;
    let a = convex_support(&mover.shape)?;
    let local = &mover.local_pose;
    let first = CCD_TARGET_GAP + CCD_TOLERANCE;
    let toi = match sweep(a, local, part.rho, m, b, pose_b, limit, first) {
        Outcome::Touching => {
            let quarter = part.ext.min.half().half();
            let inset = part.ext.min - quarter;
            // A core that itself touches is deep in: the solver's job.
            let touch = CCD_TOLERANCE.half();
            match &mover.shape {
                Shape::Sphere(_) => {
                    let core = Sphere { radius: quarter };
                    sweep(&core, local, part.rho, m, b, pose_b, limit, touch)
                }
                Shape::Capsule(c) => {
                    let core = Capsule {
                        half_height: c.half_height,
                        radius: quarter,
                    };
                    sweep(&core, local, part.rho, m, b, pose_b, limit, touch)
                }
                Shape::Cuboid(c) => {
                    let core = Cuboid {
                        half_extents: c.half_extents - Vec3::splat(inset),
                    };
                    sweep(&core, local, part.rho, m, b, pose_b, limit, touch)
                }
                _ => {
                    let core = Sphere { radius: quarter };
                    let at = Transform::new(local.transform_point(part.ext.center), Quat::IDENTITY);
                    sweep(&core, &at, part.rho, m, b, pose_b, limit, touch)
                }
            }
        }
        other => other,
    };
    match toi {
        Outcome::Hit(t) => Some(t),
        Outcome::Miss | Outcome::Touching => None,
    }
}

impl World {
    /// Recomputes a body's CCD extents from its solid colliders (after a
    /// collider or the mass changed).
    pub(crate) fn refresh_ccd_extents(&mut self, h: BodyHandle) {
        let Some(cold) = self.bodies.cold(h) else {
            return;
        };
        let mut min: Option<Scalar> = None;
        let mut radius = Scalar::ZERO;
        for ch in &cold.colliders {
            let Some(c) = self.colliders.get(ch.0) else {
                continue;
            };
            if c.is_trigger {
                continue;
            }
            let Some(e) = extent_of(&c.shape) else {
                continue;
            };
            min = Some(min.map_or(e.min, |m| m.min(e.min)));
            let off = (c.local_pose.translation - cold.local_center).length();
            radius = radius.max(off + e.radius);
        }
        if let Some(hot) = self.bodies.hot_mut(h) {
            hot.ccd_extent = min.unwrap_or(Scalar::ZERO);
            hot.ccd_radius = radius;
        }
    }

    /// Records every awake body's pose at the start of the tick (before the
    /// substeps move them): the start of the motion CCD sweeps. Only awake
    /// dynamic bodies are swept, so sleepers' entries are left as they are.
    /// Returns the buffer growths.
    #[inline(never)]
    pub(crate) fn stage_ccd_begin(&mut self) -> u32 {
        let (hot, awake) = self.bodies.awake_slots_mut();
        let start = &mut self.ccd.start;
        let growths = u32::from(start.capacity() < hot.len());
        if start.len() < hot.len() {
            start.resize(hot.len(), (Vec3::ZERO, Quat::IDENTITY));
        }
        for &s in awake {
            let b = &hot[s as usize];
            start[s as usize] = (b.center, b.rotation);
        }
        growths
    }

    /// Whether a body must be swept this tick (see the module docs): one
    /// squared-length comparison for the translation, one product for the
    /// rotation bound.
    fn is_ccd_candidate(b: &BodyHot, start: (Vec3, Quat), dt: Scalar) -> bool {
        if b.kind != BodyKind::Dynamic || b.sleeping || !b.ccd_extent.is_positive() {
            return false;
        }
        if b.bullet {
            return true;
        }
        let limit = b.ccd_extent * CCD_MOTION_FRACTION;
        let limit_sq = limit.wide_mul(limit) as u128;
        if (b.center - start.0).length_squared_wide() > limit_sq {
            return true;
        }
        // |ω|·dt·r ≤ |ω|₁·dt·r, compared exactly in i128.
        let w = b.angular_velocity;
        let l1 = (w.x.abs() + w.y.abs() + w.z.abs()) * dt;
        l1.wide_mul(b.ccd_radius) > (limit.to_bits() as i128) << 32
    }

    /// The CCD stage (see the module docs). Called after the substeps and
    /// before kinematic targets are snapped.
    ///
    /// Determinism: must run in the same place of every step; candidates in
    /// handle order, non-bullets before bullets.
    #[inline(never)]
    pub(crate) fn stage_ccd(&mut self) -> CcdStats {
        let mut stats = CcdStats::default();
        let dt = self.config.dt();
        // Pass 1: fast non-bullets against the static tree.
        let mut growths = 0;
        let mut has_bullets = false;
        {
            let World { bodies, ccd, .. } = &mut *self;
            ccd.movers.clear();
            // Only awake dynamic bodies are candidates.
            for (h, hot) in bodies.iter_awake() {
                let Some(&start) = ccd.start.get(h.index() as usize) else {
                    continue;
                };
                if !World::is_ccd_candidate(hot, start, dt) {
                    continue;
                }
                if hot.bullet {
                    has_bullets = true;
                    continue;
                }
                growths += u32::from(ccd.movers.len() == ccd.movers.capacity());
                ccd.movers.push(h);
            }
        }
        for i in 0..self.ccd.movers.len() {
            let h = self.ccd.movers[i];
            stats.bodies += 1;
            if self.sweep_body(h, false, &mut growths) {
                stats.hits += 1;
            }
        }
        // Pass 2: bullets, against everything at its end-of-tick pose. The
        // moving tree's boxes are brought up to date first, so bodies that
        // moved this tick are found where they are now.
        if has_bullets {
            self.sync_proxies(true);
            let World { bodies, ccd, .. } = &mut *self;
            ccd.movers.clear();
            for (h, hot) in bodies.iter_awake() {
                let Some(&start) = ccd.start.get(h.index() as usize) else {
                    continue;
                };
                if hot.bullet && World::is_ccd_candidate(hot, start, dt) {
                    growths += u32::from(ccd.movers.len() == ccd.movers.capacity());
                    ccd.movers.push(h);
                }
            }
            for i in 0..self.ccd.movers.len() {
                let h = self.ccd.movers[i];
                stats.bodies += 1;
                if self.sweep_body(h, true, &mut growths) {
                    stats.hits += 1;
                }
            }
        }
        stats.growths = growths;
        stats
    }

    /// Sweeps one body; on a hit moves it to its pose at the time of impact.
    /// Returns whether it was moved.
    fn sweep_body(&mut self, h: BodyHandle, bullet: bool, growths: &mut u32) -> bool {
        let World {
            bodies,
            colliders,
            broad,
            ccd,
            joints,
            ..
        } = &mut *self;
        let (Some(hot), Some(cold)) = (bodies.hot(h), bodies.cold(h)) else {
            return false;
        };
        let Some(&(c0, q0)) = ccd.start.get(h.index() as usize) else {
            return false;
        };
        let (axis, angle) = rotation_delta(q0, hot.rotation)
            .normalize_and_length()
            .unwrap_or((Vec3::X, Scalar::ZERO));
        let m = Motion {
            c0,
            q0,
            delta: hot.center - c0,
            axis,
            angle,
            local_center: cold.local_center,
        };
        // The box of the body's bounding sphere at both ends of the motion.
        let reach = hot.ccd_radius + CCD_TARGET_GAP + CCD_TOLERANCE;
        let half = Vec3::splat(reach);
        let swept = Aabb::from_center_half_extents(c0, half)
            .union(&Aabb::from_center_half_extents(hot.center, half));

        // Candidate target colliders, sorted by handle.
        ccd.keys.clear();
        let keys = &mut ccd.keys;
        let mut collect = |data: u64| {
            if let Ok(key) = broad.key(ProxyId::from_index(data as u32)) {
                *growths += u32::from(keys.len() == keys.capacity());
                keys.push(key);
            }
            true
        };
        broad.static_tree().query(&swept, |_, d| collect(d));
        if bullet {
            broad.moving_tree().query(&swept, |_, d| collect(d));
        }
        keys.sort_unstable();
        keys.dedup();

        let mut best: Option<Scalar> = None;
        for &key in keys.iter() {
            let Some(target) = colliders.get(super::collide::collider_of(key).0) else {
                continue;
            };
            // Nor what a joint keeps it from colliding with (a door's own
            // hinge post: they touch at the hinge, and the door froze there).
            if target.is_trigger || target.body == h || joints.blocks(h, target.body) {
                continue;
            }
            let (Some(thot), Some(tcold)) = (bodies.hot(target.body), bodies.cold(target.body))
            else {
                continue;
            };
            if thot.bullet && thot.kind == BodyKind::Dynamic && !thot.sleeping {
                continue;
            }
            let tpose = target.world_pose(&thot.origin_pose(tcold.local_center));
            for ch in &cold.colliders {
                let Some(mover) = colliders.get(ch.0) else {
                    continue;
                };
                if mover.is_trigger || !mover.filter.allows(&target.filter) {
                    continue;
                }
                let Some(ext) = extent_of(&mover.shape) else {
                    continue;
                };
                let center_off = (mover.local_pose.translation - cold.local_center).length();
                let part = Part {
                    collider: mover,
                    ext,
                    rho: center_off + ext.radius,
                };
                let limit = best.unwrap_or(Scalar::ONE);
                let hit = if let Some(b) = convex_support(&target.shape) {
                    sweep_pair(&part, &m, b, &tpose, limit)
                } else {
                    // Mesh or height field: the triangles under the swept box.
                    let Ok(cube) = Cuboid::new(swept.half_extents()) else {
                        continue;
                    };
                    let query = Shape::Cuboid(cube);
                    let local = box_in_frame(
                        &query,
                        &Transform::new(swept.center(), Quat::IDENTITY),
                        &tpose,
                    );
                    let mut tri_best: Option<Scalar> = None;
                    for_each_triangle(&target.shape, &raw_box(&local), |_, tri| {
                        let lim = tri_best.unwrap_or(limit);
                        if let Some(t) = sweep_pair(&part, &m, &Triangle(tri), &tpose, lim)
                            && tri_best.is_none_or(|b| t < b)
                        {
                            tri_best = Some(t);
                        }
                        true
                    });
                    tri_best
                };
                if let Some(t) = hit
                    && best.is_none_or(|b| t < b)
                {
                    best = Some(t);
                }
            }
        }

        let Some(t) = best else {
            return false;
        };
        let (center, rotation) = m.at(t);
        let Some(hot) = bodies.hot_mut(h) else {
            return false;
        };
        hot.center = center;
        hot.rotation = rotation;
        if !hot.isotropic {
            hot.angular_velocity =
                omega_from_momentum(rotation, &hot.inv_inertia, hot.angular_momentum);
        }
        true
    }
}
