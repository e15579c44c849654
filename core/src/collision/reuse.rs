//! Contact reuse: a pair whose relative pose has barely changed since its
//! manifold was built keeps that manifold's features and recomputes only
//! where they are now.
//!
//! When the narrow phase builds a manifold, [`ReuseCache::record`] keeps,
//! for every point, the point on A's surface in A's frame and the point on
//! B's surface in B's frame, the normal in A's frame, and B's pose in A's
//! frame. While B's pose relative to A stays within [`REUSE_DISTANCE`] and
//! [`REUSE_ANGLE_SIN_HALF`] of that pose, [`ReuseCache::rebuild`] makes
//! the manifold from those anchors moved with their bodies: the normal turns
//! with A, each point's depth is the distance between its two anchors along
//! that normal, and the point is their midpoint. Feature ids stay, so the
//! warm start carries over exactly as for a fresh manifold with the same
//! features. Past either bound the full test runs and the cache is
//! recorded anew, so a pair never drifts further than the bounds from a
//! manifold the narrow phase built.
//!
//! Only pairs of flat-faced shapes (boxes, hulls, triangle meshes, height
//! fields) reuse ([`shapes_reuse`]); a pair with a sphere or a capsule runs
//! the full test every step and keeps its cache empty. The anchors are
//! material points, carried along with their bodies, which is right for a
//! polytope: its contact features (vertices, edges, faces) are points of
//! the body. The touching point of a round surface is not: it stays at the
//! bottom of a rolling ball while the ball turns under it. A reused anchor
//! on a ball rolling without slip stays where the ball touched (that point
//! of the ball is at rest) while the centre rolls on, up to the 1 mm
//! bound, so the normal force acts behind the centre and drives the roll.
//! A ball left rolling on a floor was pushed up to the speed at which it
//! leaves the bound every tick (2⁻¹⁰ m per tick, 0.059 m/s at 60 Hz, above
//! the sleep thresholds) and never came to rest. Those pairs cost the full
//! test, as before reuse; against spheres, capsules and boxes it is
//! analytic. (The contact solver follows a round shape's separation
//! through its core for the same reason; see `Shape::rounding`.)
//!
//! The cache is simulation state: it is serialised with its pair, so a
//! restored world reuses exactly what the original would have, and it is
//! in the state hash.
//!
//! Determinism: the relative pose and the rebuilt manifold are computed
//! from differences of translations, with the first collider's translation
//! added back last, so the reuse decision and the manifold are unchanged,
//! bit for bit, when both colliders move by the same offset (as the narrow
//! phase's own results are). Integer arithmetic only.

use serde::{Deserialize, Serialize};

use crate::math::{Mat3, Quat, Scalar, Transform, Vec3};
use crate::shape::Shape;

use super::manifold::{MAX_MANIFOLD_POINTS, Manifold};

/// How far B's origin may have moved in A's frame since the manifold was
/// built, m (2⁻¹⁰ m ≈ 1 mm, Jolt's body-pair cache default).
pub const REUSE_DISTANCE: Scalar = Scalar::from_bits(1 << 22);

/// sin(θ/2) of the largest rotation of B relative to A since the manifold
/// was built: θ = 2° (Jolt's default), sin 1° = 0.0174524…, in Q32.32.
pub const REUSE_ANGLE_SIN_HALF: Scalar = Scalar::from_bits(74_957_515);

/// Whether a solid pair of these shapes may reuse its manifold: not if
/// either is a sphere or a capsule, whose touching point is not a point of
/// the body (see the module docs). Such a pair's cache stays empty.
pub fn shapes_reuse(a: &Shape, b: &Shape) -> bool {
    fn material_features(s: &Shape) -> bool {
        match s {
            Shape::Sphere(_) | Shape::Capsule(_) => false,
            Shape::Cuboid(_) | Shape::ConvexHull(_) | Shape::TriMesh(_) | Shape::HeightField(_) => {
                true
            }
        }
    }
    material_features(a) && material_features(b)
}

/// What a pair keeps from its last full narrow-phase test for reuse.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ReuseCache {
    /// Whether the rest describes the pair's manifold (false: the next
    /// update runs the full test).
    pub valid: bool,
    /// B's translation in A's frame when the manifold was built.
    pub rel_translation: Vec3,
    /// B's rotation relative to A's when the manifold was built.
    pub rel_rotation: Quat,
    /// The manifold normal in A's frame.
    pub normal: Vec3,
    /// Per point: the point on A's surface in A's frame, and the point on
    /// B's surface in B's frame.
    pub anchors: [[Vec3; 2]; MAX_MANIFOLD_POINTS],
}

/// B's pose in A's frame, from two world poses: the translation from the
/// exact difference of the two translations.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RelativePose {
    /// B's translation in A's frame.
    pub translation: Vec3,
    /// B's rotation in A's frame.
    pub rotation: Quat,
}

impl RelativePose {
    /// B's pose relative to A's.
    pub fn between(a: &Transform, b: &Transform) -> RelativePose {
        let inv = a.rotation.conjugate();
        RelativePose {
            translation: inv.rotate(b.translation - a.translation),
            rotation: inv * b.rotation,
        }
    }
}

/// A collider's world pose and its rotation as a matrix
/// (`Mat3::from_quat` of the pose's rotation): a bare [`Transform`] works
/// the matrix out, the narrow phase's pose table has it already.
pub(crate) trait PoseAndMatrix {
    /// The pose and `Mat3::from_quat(pose.rotation)`.
    fn pose_and_matrix(&self) -> (Transform, Mat3);
}

impl PoseAndMatrix for Transform {
    fn pose_and_matrix(&self) -> (Transform, Mat3) {
        (*self, Mat3::from_quat(self.rotation))
    }
}

impl ReuseCache {
    /// An empty cache: the next update runs the full test.
    pub const EMPTY: ReuseCache = ReuseCache {
        valid: false,
        rel_translation: Vec3::ZERO,
        rel_rotation: Quat::IDENTITY,
        normal: Vec3::ZERO,
        anchors: [[Vec3::ZERO; 2]; MAX_MANIFOLD_POINTS],
    };

    /// Whether `rel` is close enough to the recorded pose to reuse the
    /// manifold: B's origin within [`REUSE_DISTANCE`] of where it was in
    /// A's frame and its rotation relative to A within 2° of what it was.
    /// Compared in exact squares.
    pub(crate) fn holds_for(&self, rel: &RelativePose) -> bool {
        if !self.valid {
            return false;
        }
        let d = rel.translation - self.rel_translation;
        let limit = REUSE_DISTANCE.wide_mul(REUSE_DISTANCE) as u128;
        if d.length_squared_wide() > limit {
            return false;
        }
        // The rotation from the recorded relative rotation to the current
        // one; its vector part has length sin(θ/2), whichever sign the
        // quaternion has.
        let delta = self.rel_rotation.conjugate() * rel.rotation;
        let s = REUSE_ANGLE_SIN_HALF.wide_mul(REUSE_ANGLE_SIN_HALF) as u128;
        delta.xyz().length_squared_wide() <= s
    }

    /// Records a manifold the narrow phase just built for colliders at
    /// `a` and `b` (`rel` is `RelativePose::between` them); an empty
    /// manifold leaves the cache invalid.
    pub(crate) fn record(
        &mut self,
        a: &impl PoseAndMatrix,
        b: &impl PoseAndMatrix,
        rel: &RelativePose,
        m: &Manifold,
    ) {
        self.valid = !m.is_empty();
        if !self.valid {
            return;
        }
        let (a, ra) = a.pose_and_matrix();
        let (b, rb) = b.pose_and_matrix();
        self.rel_translation = rel.translation;
        self.rel_rotation = rel.rotation;
        self.normal = ra.transpose_mul_vec(m.normal);
        // Each point lies midway between the surfaces: A's surface point
        // is half the depth further along the normal, B's half the depth
        // back. Both relative to A's translation, exactly.
        let ab = b.translation - a.translation;
        for (slot, p) in self.anchors.iter_mut().zip(m.points()) {
            let mid = p.point - a.translation;
            let half = m.normal * p.depth.half();
            slot[0] = ra.transpose_mul_vec(mid + half);
            slot[1] = rb.transpose_mul_vec(mid - half - ab);
        }
    }

    /// Rebuilds `m`, the manifold this cache was recorded from (same
    /// features, same point count), for colliders now at `a` and `b`: the
    /// recorded normal turned with A, and per point its anchors moved with
    /// their bodies, the depth their distance along the normal, the point
    /// their midpoint. Ids stay.
    pub(crate) fn rebuild(&self, a: &impl PoseAndMatrix, b: &impl PoseAndMatrix, m: &mut Manifold) {
        let (a, ra) = a.pose_and_matrix();
        let (b, rb) = b.pose_and_matrix();
        let ab = b.translation - a.translation;
        let n = ra.mul_vec(self.normal);
        m.normal = n;
        let count = m.points().len();
        for (anchors, p) in self.anchors.iter().zip(&mut m.points[..count]) {
            let sa = ra.mul_vec(anchors[0]);
            let sb = rb.mul_vec(anchors[1]) + ab;
            p.point = a.translation + (sa + sb).half();
            p.depth = (sa - sb).dot(n);
        }
    }

    /// Feeds the cache into the state hash.
    pub(crate) fn hash_into(&self, h: &mut crate::hash::StateHasher, points: usize) {
        h.word(self.valid as u64);
        if !self.valid {
            return;
        }
        h.vec3(self.rel_translation);
        h.scalar(self.rel_rotation.x);
        h.scalar(self.rel_rotation.y);
        h.scalar(self.rel_rotation.z);
        h.scalar(self.rel_rotation.w);
        h.vec3(self.normal);
        for [pa, pb] in self.anchors.iter().take(points) {
            h.vec3(*pa);
            h.vec3(*pb);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::collision::manifold::{ContactPoint, FeatureId};

    fn s(v: f64) -> Scalar {
        Scalar::from_f64_lossy(v)
    }

    fn v(x: f64, y: f64, z: f64) -> Vec3 {
        Vec3::new(s(x), s(y), s(z))
    }

    fn pose(t: Vec3, axis: Vec3, deg: f64) -> Transform {
        Transform::new(t, Quat::from_axis_angle(axis, s(deg.to_radians())))
    }

    /// A manifold of two points between A's top face (y = 0.5 in A's frame)
    /// and B resting 1 mm deep on it.
    fn resting(a: &Transform) -> Manifold {
        let mut m = Manifold::EMPTY;
        m.normal = a.transform_vector(Vec3::Y);
        for (i, x) in [-0.25, 0.25].into_iter().enumerate() {
            m.push(ContactPoint {
                point: a.transform_point(v(x, 0.5, 0.0)),
                depth: s(0.001),
                id: FeatureId::pair(i as u16, 3),
            });
        }
        m
    }

    #[test]
    fn the_same_poses_give_back_the_manifold_to_within_rounding() {
        let a = pose(v(1.0, 2.0, 3.0), v(0.0, 0.0, 1.0), 10.0);
        let b = pose(v(1.0, 2.9, 3.0), v(0.0, 1.0, 0.0), 30.0);
        let m = resting(&a);
        let rel = RelativePose::between(&a, &b);
        let mut c = ReuseCache::EMPTY;
        c.record(&a, &b, &rel, &m);
        assert!(c.holds_for(&rel));
        let mut out = m;
        c.rebuild(&a, &b, &mut out);
        assert_eq!(out.count, m.count);
        let ulps = |x: Scalar, y: Scalar| (x.to_bits() - y.to_bits()).abs();
        for (p, q) in out.points().iter().zip(m.points()) {
            assert_eq!(p.id, q.id);
            assert!(ulps(p.depth, q.depth) <= 16, "{:?} {:?}", p.depth, q.depth);
            for i in 0..3 {
                assert!(ulps(p.point.get(i), q.point.get(i)) <= 16);
            }
        }
        for i in 0..3 {
            assert!(ulps(out.normal.get(i), m.normal.get(i)) <= 16);
        }
    }

    #[test]
    fn depth_follows_the_bodies_and_the_points_move_with_them() {
        let a = Transform::IDENTITY;
        let b = Transform::from_translation(v(0.0, 0.999, 0.0));
        let m = resting(&a);
        let mut c = ReuseCache::EMPTY;
        c.record(&a, &b, &RelativePose::between(&a, &b), &m);
        // B rises 0.5 mm: every point is 0.5 mm deep.
        let b2 = Transform::from_translation(v(0.0, 0.9995, 0.0));
        assert!(c.holds_for(&RelativePose::between(&a, &b2)));
        let mut out = m;
        c.rebuild(&a, &b2, &mut out);
        for p in out.points() {
            assert!((p.depth.to_f64() - 0.0005).abs() < 1e-8, "{}", p.depth);
        }
        // Both move together by 700 km and turn by 40°: the same depths,
        // and the points moved with them.
        let off = v(700_000.0, -3.0, 12.5);
        let q = Quat::from_axis_angle(v(0.6, 0.0, 0.8), s(0.7));
        let a3 = Transform::new(off, q);
        let b3 = Transform::new(off + q.rotate(b2.translation), q);
        let rel3 = RelativePose::between(&a3, &b3);
        assert!(c.holds_for(&rel3));
        let mut out3 = m;
        c.rebuild(&a3, &b3, &mut out3);
        for (p, p0) in out3.points().iter().zip(out.points()) {
            assert!((p.depth - p0.depth).abs().to_f64() < 1e-8);
            let want = a3.transform_point(p0.point);
            assert!((p.point - want).length().to_f64() < 1e-8);
        }
    }

    #[test]
    fn translation_by_a_common_offset_changes_no_bit() {
        let a = pose(v(0.1, 0.2, 0.3), v(1.0, 0.0, 0.0), 12.0);
        let b = pose(v(0.15, 1.1, 0.25), v(0.0, 1.0, 0.0), 70.0);
        let m = resting(&a);
        let mut c = ReuseCache::EMPTY;
        c.record(&a, &b, &RelativePose::between(&a, &b), &m);
        let off = Vec3::from_ints(1_000_000, -250_000, 3);
        let moved = |t: &Transform| Transform::new(t.translation + off, t.rotation);
        let (a2, b2) = (moved(&a), moved(&b));
        assert_eq!(
            RelativePose::between(&a, &b),
            RelativePose::between(&a2, &b2)
        );
        let (mut o1, mut o2) = (m, m);
        c.rebuild(&a, &b, &mut o1);
        c.rebuild(&a2, &b2, &mut o2);
        assert_eq!(o1.normal, o2.normal);
        for (p, q) in o1.points().iter().zip(o2.points()) {
            assert_eq!(p.depth, q.depth);
            assert_eq!(p.point + off, q.point);
        }
    }

    #[test]
    fn the_bounds_are_one_millimetre_and_two_degrees() {
        let a = Transform::IDENTITY;
        let b = Transform::from_translation(v(0.0, 1.0, 0.0));
        let m = resting(&a);
        let mut c = ReuseCache::EMPTY;
        c.record(&a, &b, &RelativePose::between(&a, &b), &m);
        let at = |t: Vec3, axis: Vec3, deg: f64| {
            let b = Transform::new(
                b.translation + t,
                Quat::from_axis_angle(axis, s(deg.to_radians())),
            );
            c.holds_for(&RelativePose::between(&a, &b))
        };
        assert!(at(v(0.0009, 0.0, 0.0), Vec3::Y, 0.0));
        assert!(at(v(0.0, 0.0, -0.0009), Vec3::Y, 0.0));
        assert!(!at(v(0.0011, 0.0, 0.0), Vec3::Y, 0.0));
        assert!(!at(v(0.0, 0.0008, 0.0008), Vec3::Y, 0.0));
        assert!(at(Vec3::ZERO, Vec3::Y, 1.99));
        assert!(at(Vec3::ZERO, Vec3::X, -1.99));
        assert!(!at(Vec3::ZERO, Vec3::Z, 2.01));
        assert!(!at(Vec3::ZERO, Vec3::Y, 180.0));
        // The same rotation given as −q still counts as no turn.
        let neg = Quat::from_xyzw(-Scalar::ZERO, Scalar::ZERO, Scalar::ZERO, -Scalar::ONE);
        let bn = Transform::new(b.translation, neg);
        assert!(c.holds_for(&RelativePose::between(&a, &bn)));
        // A turn of A moves B in A's frame: seen as the relative pose.
        let a2 = pose(Vec3::ZERO, Vec3::Z, 0.1);
        assert!(!c.holds_for(&RelativePose::between(&a2, &b)));
        // An empty manifold records nothing.
        let mut e = ReuseCache::EMPTY;
        e.record(&a, &b, &RelativePose::between(&a, &b), &Manifold::EMPTY);
        assert!(!e.holds_for(&RelativePose::between(&a, &b)));
    }

    #[test]
    fn the_hash_sees_every_recorded_field() {
        let a = Transform::IDENTITY;
        let b = Transform::from_translation(v(0.0, 1.0, 0.0));
        let m = resting(&a);
        let mut c = ReuseCache::EMPTY;
        c.record(&a, &b, &RelativePose::between(&a, &b), &m);
        let hash = |c: &ReuseCache| {
            let mut h = crate::hash::StateHasher::new();
            c.hash_into(&mut h, m.points().len());
            h.finish()
        };
        let base = hash(&c);
        let nudge = Scalar::from_bits(1);
        let mut changed = Vec::new();
        let mut d = c;
        d.valid = false;
        changed.push(d);
        let mut d = c;
        d.rel_translation.x += nudge;
        changed.push(d);
        let mut d = c;
        d.rel_rotation.w -= nudge;
        changed.push(d);
        let mut d = c;
        d.normal.z += nudge;
        changed.push(d);
        for i in 0..m.points().len() {
            for k in 0..2 {
                let mut d = c;
                d.anchors[i][k].y += nudge;
                changed.push(d);
            }
        }
        for d in &changed {
            assert_ne!(hash(d), base, "{d:?}");
        }
    }
}
