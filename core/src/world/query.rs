//! Scene queries on the `World`: ray casts (closest, any, all), shape
//! sweeps, shape and box overlaps. The geometry is in [`crate::query`].
//!
//! Every query walks the broad-phase trees for candidates, then runs the
//! exact test on each candidate the [`QueryFilter`] accepts. Results never
//! depend on the trees' shape: closest hits are the minimum of
//! `(fraction, collider handle)` (the traversal still visits every box
//! entered at the best fraction so far), and every other query sorts its
//! candidates or results by collider handle.
//!
//! Candidates come from the broad phase's fat boxes as the last step (or
//! `set_pose`) left them: the collision stage refreshes them at the start
//! of a step, and the margin plus the predictive stretch along the velocity
//! cover the step's motion, so a body that moved within its fat box is
//! found; one whose velocity changed by more than `margin / dt` within the
//! step (a violent collision) may be missed until the next step.
//!
//! Queries take `&self` and change nothing: not the state, not the state
//! hash, not the world's fault flags. Arithmetic faults a query might raise
//! (only with coordinates beyond the ranges the per-shape code documents)
//! are contained: the thread's fault flags are restored when it returns.

use crate::collider::{Collider, ColliderHandle};
use crate::collision::ProxyKey;
use crate::math::{Aabb, FaultScope, Scalar, Transform, Vec3};
use crate::query::convex_support;
use crate::query::{
    OverlapHit, QueryError, QueryFilter, Ray, RayHit, ShapeHit, cast_ray_shape, shapes_overlap,
    sweep_shape,
};
use crate::shape::Shape;

use super::state::World;

/// Refuses query shapes that are not convex, before any candidate is seen
/// (so the error does not depend on what is nearby).
fn check_convex(shape: &Shape) -> Result<(), QueryError> {
    match convex_support(shape) {
        Some(_) => Ok(()),
        None => Err(QueryError::NonConvexQueryShape { kind: shape.kind() }),
    }
}

/// Runs `f` without leaving faults in the thread's flags.
fn contained<T>(f: impl FnOnce() -> T) -> T {
    FaultScope::run(f).0
}

impl World {
    /// The collider behind `key` if it is live and `filter` accepts it, with
    /// its world pose.
    fn query_candidate(
        &self,
        key: ProxyKey,
        filter: &QueryFilter<'_>,
    ) -> Option<(ColliderHandle, &Collider, Transform)> {
        let h = super::collide::collider_of(key);
        let c = self.colliders.get(h.0)?;
        if !filter.accepts(h, c) {
            return None;
        }
        Some((h, c, c.world_pose(&self.body_origin(c.body))))
    }

    /// The candidates whose fat boxes overlap `aabb`, sorted by handle.
    fn sorted_candidates(&self, aabb: &Aabb) -> Vec<ProxyKey> {
        let mut keys = Vec::new();
        self.broad.query(aabb, |_, k| {
            keys.push(k);
            true
        });
        keys.sort_unstable();
        keys.dedup();
        keys
    }

    /// The nearest collider the ray hits, the lowest collider handle among
    /// equal fractions. `None` for a miss or a zero translation.
    ///
    /// A ray starting inside (or on) a solid shape hits it at fraction 0
    /// with the normal opposite the ray; see [`crate::query::ray`].
    ///
    /// ```
    /// use lockstep_core::query::{QueryFilter, Ray};
    /// use lockstep_core::{BodyDesc, ColliderDesc, Vec3, World, WorldConfig, scalar};
    ///
    /// let mut world = World::new(WorldConfig::default())?;
    /// // A 2 m box whose top face is y = 1.
    /// let block = world.create_body(&BodyDesc::fixed())?;
    /// world.add_collider(block, ColliderDesc::cuboid(scalar!(1), scalar!(1), scalar!(1)))?;
    ///
    /// // Straight down from 9 m, 16 m long: the top face is halfway.
    /// let ray = Ray::new(Vec3::from_ints(0, 9, 0), Vec3::from_ints(0, -16, 0));
    /// let hit = world.cast_ray_closest(&ray, &QueryFilter::default()).unwrap();
    /// assert_eq!(hit.body, block);
    /// assert_eq!(hit.fraction, scalar!(0.5));
    /// assert_eq!(hit.point, Vec3::from_ints(0, 1, 0));
    /// assert_eq!(hit.normal, Vec3::Y);
    ///
    /// // Bodies can be left out (a shooter's own body, say).
    /// let filter = QueryFilter { exclude_bodies: &[block], ..QueryFilter::default() };
    /// assert!(world.cast_ray_closest(&ray, &filter).is_none());
    /// # Ok::<(), lockstep_core::WorldError>(())
    /// ```
    pub fn cast_ray_closest(&self, ray: &Ray, filter: &QueryFilter<'_>) -> Option<RayHit> {
        contained(|| {
            let mut best: Option<RayHit> = None;
            self.broad
                .ray_cast(ray.origin, ray.translation, Scalar::ONE, |_, key, max| {
                    let Some((h, c, pose)) = self.query_candidate(key, filter) else {
                        return Some(max);
                    };
                    if let Some(x) = cast_ray_shape(&c.shape, &pose, ray, max) {
                        let better =
                            best.is_none_or(|b| (x.fraction, h) < (b.fraction, b.collider));
                        if better {
                            best = Some(RayHit {
                                collider: h,
                                body: c.body,
                                fraction: x.fraction,
                                point: x.point,
                                normal: x.normal,
                            });
                            return Some(x.fraction);
                        }
                    }
                    Some(max)
                });
            best
        })
    }

    /// Some collider the ray hits, for yes/no questions (line of sight):
    /// candidates are tested in collider-handle order and the first hit
    /// ends the query, so the hit is the lowest-handle collider hit, not
    /// necessarily the nearest.
    pub fn cast_ray_any(&self, ray: &Ray, filter: &QueryFilter<'_>) -> Option<RayHit> {
        contained(|| {
            let mut keys = Vec::new();
            self.broad
                .ray_cast(ray.origin, ray.translation, Scalar::ONE, |_, key, max| {
                    keys.push(key);
                    Some(max)
                });
            keys.sort_unstable();
            keys.dedup();
            keys.into_iter().find_map(|key| {
                let (h, c, pose) = self.query_candidate(key, filter)?;
                let x = cast_ray_shape(&c.shape, &pose, ray, Scalar::ONE)?;
                Some(RayHit {
                    collider: h,
                    body: c.body,
                    fraction: x.fraction,
                    point: x.point,
                    normal: x.normal,
                })
            })
        })
    }

    /// Every collider the ray hits (its nearest hit on each), written to
    /// `out` (cleared first) sorted by fraction, then collider handle.
    pub fn cast_ray_all(&self, ray: &Ray, filter: &QueryFilter<'_>, out: &mut Vec<RayHit>) {
        out.clear();
        contained(|| {
            self.broad
                .ray_cast(ray.origin, ray.translation, Scalar::ONE, |_, key, max| {
                    if let Some((h, c, pose)) = self.query_candidate(key, filter)
                        && let Some(x) = cast_ray_shape(&c.shape, &pose, ray, Scalar::ONE)
                    {
                        out.push(RayHit {
                            collider: h,
                            body: c.body,
                            fraction: x.fraction,
                            point: x.point,
                            normal: x.normal,
                        });
                    }
                    Some(max)
                });
        });
        out.sort_unstable_by_key(|h| (h.fraction, h.collider));
    }

    /// Sweeps the convex `shape` from `pose` along `translation` and returns
    /// the first collider it touches: the smallest time of impact, the
    /// lowest collider handle on ties. Colliders the shape already overlaps
    /// at `pose` are reported at fraction 0 with `initially_overlapping`;
    /// one the shape only touches (within the tolerance) is a hit at 0 while
    /// the shape moves towards it, and no hit when it slides along or away.
    ///
    /// The fraction is safe (the shape placed there does not overlap the
    /// collider) and within [`SWEEP_TOLERANCE`](crate::query::sweep::SWEEP_TOLERANCE)
    /// of the exact contact along the normal; see [`crate::query::sweep`].
    ///
    /// # Errors
    /// [`QueryError::NonConvexQueryShape`] for a mesh or height field.
    pub fn cast_shape(
        &self,
        shape: &Shape,
        pose: &Transform,
        translation: Vec3,
        filter: &QueryFilter<'_>,
    ) -> Result<Option<ShapeHit>, QueryError> {
        check_convex(shape)?;
        contained(|| {
            let mut best: Option<ShapeHit> = None;
            let mut error = None;
            // The tree walk clips to the best fraction so far but still
            // visits boxes entered exactly there, so the minimum of
            // (fraction, handle) does not depend on the visit order.
            self.broad.box_cast(
                &shape.aabb(pose),
                translation,
                Scalar::ONE,
                |_, key, max| {
                    let Some((h, c, cpose)) = self.query_candidate(key, filter) else {
                        return Some(max);
                    };
                    match sweep_shape(shape, pose, translation, &c.shape, &cpose, max) {
                        Ok(Some(x)) => {
                            if best.is_none_or(|b| (x.fraction, h) < (b.fraction, b.collider)) {
                                best = Some(ShapeHit {
                                    collider: h,
                                    body: c.body,
                                    fraction: x.fraction,
                                    point: x.point,
                                    normal: x.normal,
                                    initially_overlapping: x.initially_overlapping,
                                });
                                return Some(x.fraction);
                            }
                            Some(max)
                        }
                        Ok(None) => Some(max),
                        Err(e) => {
                            error = Some(e);
                            None
                        }
                    }
                },
            );
            match error {
                Some(e) => Err(e),
                None => Ok(best),
            }
        })
    }

    /// The colliders the convex `shape` at `pose` intersects (touching
    /// counts), written to `out` (cleared first) by collider handle.
    ///
    /// # Errors
    /// [`QueryError::NonConvexQueryShape`] for a mesh or height field.
    pub fn overlap_shape(
        &self,
        shape: &Shape,
        pose: &Transform,
        filter: &QueryFilter<'_>,
        out: &mut Vec<OverlapHit>,
    ) -> Result<(), QueryError> {
        out.clear();
        check_convex(shape)?;
        contained(|| {
            for key in self.sorted_candidates(&shape.aabb(pose)) {
                let Some((h, c, cpose)) = self.query_candidate(key, filter) else {
                    continue;
                };
                if shapes_overlap(shape, pose, &c.shape, &cpose)? {
                    out.push(OverlapHit {
                        collider: h,
                        body: c.body,
                    });
                }
            }
            Ok(())
        })
    }

    /// The colliders whose tight world boxes overlap `aabb` (touching
    /// counts), written to `out` (cleared first) by collider handle: the
    /// broad phase's fat boxes give the candidates, each collider's own box
    /// at its current pose decides.
    pub fn overlap_aabb(&self, aabb: &Aabb, filter: &QueryFilter<'_>, out: &mut Vec<OverlapHit>) {
        out.clear();
        contained(|| {
            for key in self.sorted_candidates(aabb) {
                if let Some((h, c, pose)) = self.query_candidate(key, filter)
                    && c.shape.aabb(&pose).overlaps(aabb)
                {
                    out.push(OverlapHit {
                        collider: h,
                        body: c.body,
                    });
                }
            }
        });
    }
}
