//! Closest points between a point and a segment, and between two segments:
//! the core of every sphere and capsule contact.
//!
//! Exactness: dot products are accumulated exactly in `i128` and each
//! parameter is one rounded ratio of exact integers. The inputs must be small
//! enough that squared lengths and dot products fit a Scalar (coordinates
//! below about 2¹⁵ m); the pair functions guarantee it by rejecting far
//! pairs before calling these and by working relative to one shape.

use super::shared::{ratio01, widen};
use crate::math::{Scalar, Vec3};

/// The closest point to `p` on the segment `a`–`b`: its parameter `t` in
/// `[0, 1]` (0 at `a`) and position. A zero-length segment gives `t = 0`.
pub fn closest_point_on_segment(p: Vec3, a: Vec3, b: Vec3) -> (Scalar, Vec3) {
    let d = b - a;
    let t = ratio01((p - a).dot_wide(d), d.dot_wide(d));
    (t, a + d * t)
}

/// The result of [`closest_points_segments`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SegmentClosest {
    /// Parameter on the first segment, `[0, 1]`.
    pub s: Scalar,
    /// Parameter on the second segment, `[0, 1]`.
    pub t: Scalar,
    /// The point on the first segment.
    pub p1: Vec3,
    /// The point on the second segment.
    pub p2: Vec3,
    /// Whether the segments were treated as parallel (the sine of their
    /// angle below 2⁻¹⁴), in which case the documented choice below was used.
    pub parallel: bool,
}

/// The closest points between segments `p1`–`q1` and `p2`–`q2`.
///
/// Deterministic choices where the answer is not unique:
/// - both segments are points: their start points;
/// - one segment is a point: `s = 0` (or `t = 0`) for it, the closest point
///   on the other;
/// - parallel segments (sine of the angle below 2⁻¹⁴): on the first segment,
///   the middle of the part that overlaps the second in projection (or the
///   end nearest to it when they do not overlap), then the closest point on
///   the second segment, then the first re-projected if the second clamped.
///   The middle keeps a capsule resting on a parallel capsule centred.
pub fn closest_points_segments(p1: Vec3, q1: Vec3, p2: Vec3, q2: Vec3) -> SegmentClosest {
    let d1 = q1 - p1;
    let d2 = q2 - p2;
    let r = p1 - p2;
    let a = d1.dot(d1);
    let e = d2.dot(d2);
    let f = d2.dot(r);
    let done = |s: Scalar, t: Scalar, parallel: bool| SegmentClosest {
        s,
        t,
        p1: p1 + d1 * s,
        p2: p2 + d2 * t,
        parallel,
    };
    if a.is_zero() && e.is_zero() {
        return done(Scalar::ZERO, Scalar::ZERO, false);
    }
    if a.is_zero() {
        return done(
            Scalar::ZERO,
            ratio01(f.to_bits() as i128, e.to_bits() as i128),
            false,
        );
    }
    let c = d1.dot(r);
    if e.is_zero() {
        return done(
            ratio01(-(c.to_bits() as i128), a.to_bits() as i128),
            Scalar::ZERO,
            false,
        );
    }
    let b = d1.dot(d2);
    let ae = a.wide_mul(e);
    let denom = ae - b.wide_mul(b);
    let parallel = denom <= ae >> 28;
    let s = if parallel {
        // Parameters of the second segment's ends along the first.
        let u0 = (-c).checked_div(a).unwrap_or(Scalar::ZERO);
        let u1 = (b - c).checked_div(a).unwrap_or(Scalar::ZERO);
        let lo = u0.min(u1).clamp(Scalar::ZERO, Scalar::ONE);
        let hi = u0.max(u1).clamp(Scalar::ZERO, Scalar::ONE);
        (lo + hi).half()
    } else {
        ratio01(b.wide_mul(f) - c.wide_mul(e), denom)
    };
    let tnum = b.wide_mul(s) + widen(f);
    let eden = widen(e);
    let t = ratio01(tnum, eden);
    let s = if tnum <= 0 || tnum >= eden {
        ratio01(b.wide_mul(t) - widen(c), widen(a))
    } else {
        s
    };
    done(s, t, parallel)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: f64, y: f64, z: f64) -> Vec3 {
        Vec3::new(
            Scalar::from_f64_lossy(x),
            Scalar::from_f64_lossy(y),
            Scalar::from_f64_lossy(z),
        )
    }

    #[test]
    fn point_segment_projects_inside_and_clamps_outside() {
        let (a, b) = (v(0.0, 0.0, 0.0), v(4.0, 0.0, 0.0));
        assert_eq!(
            closest_point_on_segment(v(1.0, 3.0, 0.0), a, b),
            (Scalar::from_ratio(1, 4), v(1.0, 0.0, 0.0))
        );
        assert_eq!(
            closest_point_on_segment(v(-2.0, 1.0, 0.0), a, b),
            (Scalar::ZERO, a)
        );
        assert_eq!(
            closest_point_on_segment(v(9.0, 1.0, 0.0), a, b),
            (Scalar::ONE, b)
        );
        assert_eq!(
            closest_point_on_segment(v(9.0, 1.0, 0.0), a, a),
            (Scalar::ZERO, a)
        );
    }

    #[test]
    fn crossing_segments_meet_at_their_crossing_point() {
        let r = closest_points_segments(
            v(-1.0, 0.0, 0.0),
            v(3.0, 0.0, 0.0),
            v(0.5, -2.0, 1.0),
            v(0.5, 2.0, 1.0),
        );
        assert!(!r.parallel);
        assert_eq!((r.s, r.t), (Scalar::from_ratio(3, 8), Scalar::HALF));
        assert_eq!((r.p1, r.p2), (v(0.5, 0.0, 0.0), v(0.5, 0.0, 1.0)));
    }

    #[test]
    fn skew_segments_clamp_to_an_end_and_reproject() {
        // The second segment lies wholly beyond the first's end.
        let r = closest_points_segments(
            v(0.0, 0.0, 0.0),
            v(1.0, 0.0, 0.0),
            v(3.0, -1.0, 1.0),
            v(3.0, 1.0, 1.0),
        );
        assert_eq!((r.s, r.t), (Scalar::ONE, Scalar::HALF));
        assert_eq!((r.p1, r.p2), (v(1.0, 0.0, 0.0), v(3.0, 0.0, 1.0)));
    }

    #[test]
    fn parallel_overlapping_segments_pick_the_middle_of_the_overlap() {
        let r = closest_points_segments(
            v(0.0, 0.0, 0.0),
            v(4.0, 0.0, 0.0),
            v(5.0, 1.0, 0.0),
            v(1.0, 1.0, 0.0),
        );
        assert!(r.parallel);
        assert_eq!(r.p1, v(2.5, 0.0, 0.0));
        assert_eq!(r.p2, v(2.5, 1.0, 0.0));
        // Disjoint in projection: the nearest ends.
        let r = closest_points_segments(
            v(0.0, 0.0, 0.0),
            v(1.0, 0.0, 0.0),
            v(2.0, 1.0, 0.0),
            v(3.0, 1.0, 0.0),
        );
        assert_eq!((r.p1, r.p2), (v(1.0, 0.0, 0.0), v(2.0, 1.0, 0.0)));
    }

    #[test]
    fn degenerate_segments_use_their_start_points() {
        let p = v(1.0, 2.0, 3.0);
        let r = closest_points_segments(p, p, v(0.0, 0.0, 0.0), v(0.0, 0.0, 0.0));
        assert_eq!(
            (r.s, r.t, r.p1, r.p2),
            (Scalar::ZERO, Scalar::ZERO, p, Vec3::ZERO)
        );
        let r = closest_points_segments(p, p, v(0.0, 0.0, 0.0), v(0.0, 4.0, 0.0));
        assert_eq!((r.t, r.p2), (Scalar::HALF, v(0.0, 2.0, 0.0)));
        let r = closest_points_segments(v(0.0, 0.0, 0.0), v(0.0, 4.0, 0.0), p, p);
        assert_eq!((r.s, r.p1), (Scalar::HALF, v(0.0, 2.0, 0.0)));
    }
}
