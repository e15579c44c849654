//! Time of impact: the one conservative-advancement routine behind shape
//! sweeps (`World::cast_shape`,
//! [`sweep_shape`](crate::query::sweep::sweep_shape)) and continuous
//! collision (the CCD stage of `World::step`).
//!
//! **The motion.** A body frame moves over the fraction `t ∈ [0, 1]`: its
//! centre of mass linearly from `c0` by `delta`, its rotation at a constant
//! rate by `angle` about the fixed `axis` (a sweep query has no rotation).
//! The moving shape sits at `local` in that frame, and every point of it lies
//! within `rho` of the centre of mass.
//!
//! **The advance** (Mirtich; Erin Catto, GDC 2013 "Continuous Collision"):
//! at the fraction `t`, GJK gives the gap `g` and the unit normal `n` from the
//! moving shape to the target. No point of the moving shape approaches the
//! plane through the target's closest point faster than `delta·n + angle·ρ`
//! per unit of `t`, so advancing by `(g − target) / (delta·n + angle·ρ)`
//! keeps the gap at least `target`.
//!
//! **How it ends**, in this order at each fraction:
//! * the shapes overlap at the start: [`Toi::Overlapping`];
//! * the bound is not positive (moving apart or sideways): [`Toi::Miss`];
//! * `g ≤ target + tolerance`: [`Toi::Hit`] at `t`;
//! * the next fraction passes `limit`: [`Toi::Miss`];
//! * an advance lands in contact (only rounding can do that): the interval
//!   between the last fraction verified apart and that one is halved until a
//!   fraction is within `target + tolerance`, or the halving stops; the hit is
//!   the last fraction verified apart;
//! * the iteration cap: [`Toi::Exhausted`] at the last fraction verified
//!   apart (glancing approaches close a share of the gap per step).
//!
//! Every fraction reported in a hit was *measured* apart by GJK: the moving
//! shape placed there does not overlap the target.
//!
//! Determinism: integer arithmetic only, fixed caps, no allocation.

use crate::collision::narrow::gjk::{DistanceResult, SupportShape, distance};
use crate::math::{Quat, Scalar, Transform, Vec3};

/// The motion of a body frame over one sweep (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Motion {
    /// Centre of mass at fraction 0.
    pub c0: Vec3,
    /// Rotation at fraction 0.
    pub q0: Quat,
    /// Motion of the centre of mass over the whole sweep.
    pub delta: Vec3,
    /// Unit rotation axis (any unit vector when `angle` is 0).
    pub axis: Vec3,
    /// Rotation over the whole sweep, radians (not negative).
    pub angle: Scalar,
    /// The centre of mass in the body frame.
    pub local_center: Vec3,
}

impl Motion {
    /// A pure translation of the frame at `pose` by `translation`.
    pub fn linear(pose: &Transform, translation: Vec3) -> Motion {
        Motion {
            c0: pose.translation,
            q0: pose.rotation,
            delta: translation,
            axis: Vec3::X,
            angle: Scalar::ZERO,
            local_center: Vec3::ZERO,
        }
    }

    /// Centre of mass and rotation at fraction `t`.
    pub fn at(&self, t: Scalar) -> (Vec3, Quat) {
        let c = self.c0 + self.delta * t;
        if self.angle.is_zero() {
            return (c, self.q0);
        }
        let q = (Quat::from_axis_angle(self.axis, self.angle * t) * self.q0).normalize();
        (c, q)
    }

    /// The body frame's pose at fraction `t`.
    pub fn origin_at(&self, t: Scalar) -> Transform {
        let (c, q) = self.at(t);
        if self.local_center == Vec3::ZERO {
            return Transform::new(c, q);
        }
        Transform::new(c - q.rotate(self.local_center), q)
    }
}

/// When the advance stops.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ToiSettings {
    /// The gap each advance aims at.
    pub target: Scalar,
    /// A gap within `target + tolerance` is a hit.
    pub tolerance: Scalar,
    /// The most GJK distance evaluations for the advance (the halving after
    /// a landed advance has as many again).
    pub max_iterations: usize,
}

/// A fraction verified apart, with what GJK measured there.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ToiPoint {
    /// The fraction of the motion.
    pub fraction: Scalar,
    /// The gap at that fraction.
    pub gap: Scalar,
    /// The target's closest point to the moving shape.
    pub point: Vec3,
    /// Unit normal from the target towards the moving shape.
    pub normal: Vec3,
}

/// How a sweep ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Toi {
    /// Within `target + tolerance` at this fraction, approaching.
    Hit {
        /// The hit.
        at: ToiPoint,
        /// Already so at fraction 0, before any advance.
        at_start: bool,
    },
    /// The iteration cap was reached: this fraction is the last verified
    /// apart (and safe), but no contact was reached.
    Exhausted(ToiPoint),
    /// The shapes overlap at fraction 0.
    Overlapping,
    /// No contact up to the limit.
    Miss,
}

/// The pose of the moving shape at fraction `t`.
pub(crate) fn shape_pose(m: &Motion, local: &Transform, t: Scalar) -> Transform {
    let frame = m.origin_at(t);
    if *local == Transform::IDENTITY {
        frame
    } else {
        frame.mul_transform(local)
    }
}

/// Conservative advancement of `a` (at `local` in the moving frame, every
/// point within `rho` of the centre of mass) along `m` towards the fixed `b`
/// at `pose_b`, up to the fraction `limit` (see the module docs).
#[allow(clippy::too_many_arguments)]
pub fn time_of_impact<A: SupportShape + ?Sized, B: SupportShape + ?Sized>(
    a: &A,
    local: &Transform,
    rho: Scalar,
    m: &Motion,
    b: &B,
    pose_b: &Transform,
    limit: Scalar,
    settings: &ToiSettings,
) -> Toi {
    let spin = m.angle * rho;
    let reach = settings.target + settings.tolerance;
    let mut t = Scalar::ZERO;
    let mut last: Option<ToiPoint> = None;
    for _ in 0..settings.max_iterations {
        match distance(a, &shape_pose(m, local, t), b, pose_b) {
            DistanceResult::Overlapping => {
                return match last {
                    Some(apart) => Toi::Hit {
                        at: bisect(a, local, m, b, pose_b, apart, t, settings),
                        at_start: false,
                    },
                    None => Toi::Overlapping,
                };
            }
            DistanceResult::Separated {
                distance: gap,
                point_b,
                normal,
                ..
            } => {
                let here = ToiPoint {
                    fraction: t,
                    gap,
                    point: point_b,
                    normal: -normal,
                };
                let bound = m.delta.dot(normal) + spin;
                if !bound.is_positive() {
                    return Toi::Miss;
                }
                if gap <= reach {
                    return Toi::Hit {
                        at: here,
                        at_start: last.is_none(),
                    };
                }
                let Some(step) = (gap - settings.target).checked_div(bound) else {
                    return Toi::Miss;
                };
                let next = t + step;
                if next > limit {
                    return Toi::Miss;
                }
                last = Some(here);
                t = next;
            }
        }
    }
    match last {
        Some(apart) => Toi::Exhausted(apart),
        None => Toi::Miss,
    }
}

/// The contact between `apart` (verified apart) and `overlapping` (in
/// contact): halves the interval, keeping the lower end apart, until a
/// fraction is apart by at most `target + tolerance` or the interval cannot
/// be halved. Returns the last fraction verified apart.
#[allow(clippy::too_many_arguments)]
fn bisect<A: SupportShape + ?Sized, B: SupportShape + ?Sized>(
    a: &A,
    local: &Transform,
    m: &Motion,
    b: &B,
    pose_b: &Transform,
    apart: ToiPoint,
    overlapping: Scalar,
    settings: &ToiSettings,
) -> ToiPoint {
    let reach = settings.target + settings.tolerance;
    let mut lo = apart;
    let mut hi = overlapping;
    for _ in 0..settings.max_iterations {
        // The midpoint rounded down, so that it never reaches `hi`; the
        // difference of two fractions in [0, 1] cannot overflow.
        let span = hi.to_bits() - lo.fraction.to_bits();
        let mid = Scalar::from_bits(lo.fraction.to_bits() + (span >> 1));
        if mid == lo.fraction {
            break;
        }
        match distance(a, &shape_pose(m, local, mid), b, pose_b) {
            DistanceResult::Overlapping => hi = mid,
            DistanceResult::Separated {
                distance: gap,
                point_b,
                normal,
                ..
            } => {
                lo = ToiPoint {
                    fraction: mid,
                    gap,
                    point: point_b,
                    normal: -normal,
                };
                if gap <= reach {
                    break;
                }
            }
        }
    }
    lo
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shape::{Cuboid, Sphere};

    fn settings() -> ToiSettings {
        ToiSettings {
            target: Scalar::from_bits(1 << 17),
            tolerance: Scalar::from_bits(1 << 17),
            max_iterations: 32,
        }
    }

    /// The interval a landed advance leaves: the result is apart, within the
    /// reach of the exact contact, and no later.
    #[test]
    fn bisecting_a_landed_advance_reports_a_fraction_apart() {
        let ball = Sphere::new(Scalar::ONE).unwrap();
        let m = Motion::linear(&Transform::IDENTITY, Vec3::from_ints(10, 0, 0));
        let target = Transform::from_translation(Vec3::from_ints(5, 0, 0));
        let s = settings();
        // The spheres touch when the mover has gone 3 m: fraction 0.3.
        let apart = ToiPoint {
            fraction: Scalar::from_ratio(1, 10),
            gap: Scalar::from_int(2),
            point: Vec3::ZERO,
            normal: -Vec3::X,
        };
        let id = Transform::IDENTITY;
        let h = bisect(
            &ball,
            &id,
            &m,
            &ball,
            &target,
            apart,
            Scalar::from_ratio(1, 2),
            &s,
        );
        let exact = Scalar::from_ratio(3, 10);
        assert!(h.fraction <= exact, "{}", h.fraction);
        assert!((exact - h.fraction) * Scalar::from_int(10) <= s.target + s.tolerance);
        assert!(matches!(
            distance(&ball, &m.origin_at(h.fraction), &ball, &target),
            DistanceResult::Separated { .. }
        ));
        assert_eq!(h.normal, -Vec3::X);
        // Nothing apart left in the interval: the fraction verified apart
        // is kept.
        let h = bisect(
            &ball,
            &id,
            &m,
            &ball,
            &target,
            apart,
            Scalar::from_ratio(1, 10) + Scalar::from_bits(1),
            &s,
        );
        assert_eq!(h, apart);
    }

    /// A head-on approach: one advance, then a hit within the reach.
    #[test]
    fn head_on_hit_is_within_the_reach_and_apart() {
        let ball = Sphere::new(Scalar::ONE).unwrap();
        let m = Motion::linear(&Transform::IDENTITY, Vec3::from_ints(10, 0, 0));
        let target = Transform::from_translation(Vec3::from_ints(5, 0, 0));
        let s = settings();
        let Toi::Hit { at, at_start } = time_of_impact(
            &ball,
            &Transform::IDENTITY,
            Scalar::ZERO,
            &m,
            &ball,
            &target,
            Scalar::ONE,
            &s,
        ) else {
            panic!("no hit");
        };
        assert!(!at_start);
        assert!(at.gap <= s.target + s.tolerance && at.gap.is_positive());
        let exact = Scalar::from_ratio(3, 10);
        assert!(at.fraction <= exact);
        assert_eq!(at.normal, -Vec3::X);
        // Moving away, or stopping short of the target, is a miss.
        let away = Motion::linear(&Transform::IDENTITY, Vec3::from_ints(-10, 0, 0));
        let id = Transform::IDENTITY;
        let run = |m: &Motion, limit| {
            time_of_impact(&ball, &id, Scalar::ZERO, m, &ball, &target, limit, &s)
        };
        assert_eq!(run(&away, Scalar::ONE), Toi::Miss);
        assert_eq!(run(&m, Scalar::from_ratio(1, 5)), Toi::Miss);
        // Starting inside the target.
        let inside = Motion::linear(
            &Transform::from_translation(Vec3::from_ints(4, 0, 0)),
            Vec3::X,
        );
        assert_eq!(run(&inside, Scalar::ONE), Toi::Overlapping);
    }

    /// A spinning plank reaches a wall it could not reach by translation:
    /// the rotation bound finds it, and the reported pose is apart.
    #[test]
    fn rotation_alone_reaches_the_target() {
        let plank = Cuboid::new(Vec3::new(
            Scalar::from_int(2),
            Scalar::from_ratio(1, 10),
            Scalar::from_ratio(1, 10),
        ))
        .unwrap();
        let wall = Cuboid::new(Vec3::new(
            Scalar::from_int(5),
            Scalar::from_ratio(1, 2),
            Scalar::from_int(5),
        ))
        .unwrap();
        // The plank lies along x; the wall's face is at y = 1.5, beyond the
        // plank's reach unless it turns about z.
        let wall_pose = Transform::new(
            Vec3::new(Scalar::ZERO, Scalar::from_int(2), Scalar::ZERO),
            Quat::IDENTITY,
        );
        let m = Motion {
            c0: Vec3::ZERO,
            q0: Quat::IDENTITY,
            delta: Vec3::ZERO,
            axis: Vec3::Z,
            angle: Scalar::FRAC_PI_2,
            local_center: Vec3::ZERO,
        };
        let rho = plank.half_extents.length();
        let s = settings();
        let id = Transform::IDENTITY;
        let toi = time_of_impact(&plank, &id, rho, &m, &wall, &wall_pose, Scalar::ONE, &s);
        let at = match toi {
            Toi::Hit { at, .. } | Toi::Exhausted(at) => at,
            other => panic!("{other:?}"),
        };
        assert!(at.fraction.is_positive() && at.fraction < Scalar::ONE);
        assert!(matches!(
            distance(&plank, &m.origin_at(at.fraction), &wall, &wall_pose),
            DistanceResult::Separated { .. }
        ));
        // Past the reported fraction by a degree, the plank is in the wall.
        let past = at.fraction + Scalar::from_ratio(1, 90);
        assert!(matches!(
            distance(&plank, &m.origin_at(past), &wall, &wall_pose),
            DistanceResult::Overlapping
        ));
    }
}
