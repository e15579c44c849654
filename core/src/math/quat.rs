//! `Quat`: a rotation as a unit quaternion.
//!
//! Products accumulate their four terms exactly in `i128` and round once.
//! Normalisation is deterministic (integer square root of the exact `i128`
//! norm), so every peer renormalises to the same bits.

use std::ops::Mul;

use serde::{Deserialize, Serialize};

use super::elem;
use super::scalar::{Scalar, wide_sum};
use super::vec3::Vec3;

/// A quaternion `w + xi + yj + zk`; rotations use unit quaternions.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Quat {
    /// i component.
    pub x: Scalar,
    /// j component.
    pub y: Scalar,
    /// k component.
    pub z: Scalar,
    /// Real part.
    pub w: Scalar,
}

impl Default for Quat {
    fn default() -> Quat {
        Quat::IDENTITY
    }
}

impl std::fmt::Debug for Quat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "[w {}, x {}, y {}, z {}]",
            self.w, self.x, self.y, self.z
        )
    }
}

#[inline(always)]
fn dot4(a: [Scalar; 4], b: [Scalar; 4]) -> i128 {
    wide_sum([
        a[0].wide_mul(b[0]),
        a[1].wide_mul(b[1]),
        a[2].wide_mul(b[2]),
        a[3].wide_mul(b[3]),
    ])
}

impl Quat {
    /// No rotation.
    pub const IDENTITY: Quat =
        Quat::from_xyzw(Scalar::ZERO, Scalar::ZERO, Scalar::ZERO, Scalar::ONE);

    /// A quaternion from its components (not normalised).
    pub const fn from_xyzw(x: Scalar, y: Scalar, z: Scalar, w: Scalar) -> Quat {
        Quat { x, y, z, w }
    }

    /// The components `[x, y, z, w]` as the nearest `f32`s, the order glam,
    /// nalgebra and mint use, for a renderer: output only, never fed back
    /// into the simulation.
    ///
    /// ```
    /// use lockstep_core::{Quat, Scalar, Vec3};
    ///
    /// let q = Quat::from_axis_angle(Vec3::Y, Scalar::FRAC_PI_2);
    /// let [x, y, z, w] = q.to_f32_array();
    /// assert_eq!([x, z], [0.0, 0.0]);
    /// assert!((y - 0.5f32.sqrt()).abs() < 1e-6 && (w - 0.5f32.sqrt()).abs() < 1e-6);
    /// ```
    pub fn to_f32_array(self) -> [f32; 4] {
        [self.x, self.y, self.z, self.w].map(Scalar::to_f32)
    }

    /// The components `[x, y, z, w]` as `f64`s (exact), for output.
    pub fn to_f64_array(self) -> [f64; 4] {
        [self.x, self.y, self.z, self.w].map(Scalar::to_f64)
    }

    /// The vector part.
    #[inline(always)]
    pub const fn xyz(self) -> Vec3 {
        Vec3::new(self.x, self.y, self.z)
    }

    /// The rotation by `angle` radians about the unit vector `axis`.
    pub fn from_axis_angle(axis: Vec3, angle: Scalar) -> Quat {
        let (s, c) = elem::sin_cos(angle.half());
        let v = axis * s;
        Quat::from_xyzw(v.x, v.y, v.z, c)
    }

    /// The rotation taking body axes to world axes for a rotation vector
    /// `r` (axis × angle); the identity for a zero vector.
    pub fn from_rotation_vector(r: Vec3) -> Quat {
        match r.normalize_and_length() {
            Some((axis, angle)) => Quat::from_axis_angle(axis, angle),
            None => Quat::IDENTITY,
        }
    }

    /// The conjugate (the inverse of a unit quaternion).
    #[inline(always)]
    pub fn conjugate(self) -> Quat {
        Quat::from_xyzw(-self.x, -self.y, -self.z, self.w)
    }

    /// The exact squared norm, Q64.64.
    #[inline(always)]
    pub fn norm_squared_wide(self) -> u128 {
        let a = [self.x, self.y, self.z, self.w];
        dot4(a, a) as u128
    }

    /// Dot product of the four components, rounded once.
    pub fn dot(self, o: Quat) -> Scalar {
        Scalar::from_wide(dot4([self.x, self.y, self.z, self.w], [o.x, o.y, o.z, o.w]))
    }

    /// The unit quaternion in the same direction, to within 1 ulp per
    /// component; the identity for the zero quaternion. Deterministic: the
    /// norm is the integer square root of the exact sum of squares, scaled up
    /// to 126 bits before the root so no precision is lost.
    pub fn normalize(self) -> Quat {
        let sq = self.norm_squared_wide();
        if sq == 0 {
            return Quat::IDENTITY;
        }
        let [x, y, z, w] = super::vec3::scale_to_unit([self.x, self.y, self.z, self.w], sq);
        Quat::from_xyzw(x, y, z, w)
    }

    /// Rotates a vector: `q v q*`, as `v + w t + q×t` with `t = 2 q×v`.
    #[inline]
    pub fn rotate(self, v: Vec3) -> Vec3 {
        let q = self.xyz();
        let t = q.cross(v);
        let t = t + t;
        v + t * self.w + q.cross(t)
    }

    /// Rotates a vector by the inverse rotation.
    #[inline]
    pub fn inverse_rotate(self, v: Vec3) -> Vec3 {
        self.conjugate().rotate(v)
    }

    /// Integrates an angular velocity `omega` (world frame) over `dt`:
    /// `q + ½·dt·(ω,0)⊗q`, then renormalised. First order in the angle, as
    /// every engine's position step is; the normalisation keeps it a
    /// rotation.
    pub fn integrate(self, omega: Vec3, dt: Scalar) -> Quat {
        let h = (omega * dt).half();
        let dq = Quat::from_xyzw(h.x, h.y, h.z, Scalar::ZERO) * self;
        Quat::from_xyzw(self.x + dq.x, self.y + dq.y, self.z + dq.z, self.w + dq.w).normalize()
    }

    /// The same rotation with a non-negative real part (q and −q are the
    /// same rotation): a canonical form for comparisons and hashing.
    pub fn canonical(self) -> Quat {
        if self.w.is_negative() {
            Quat::from_xyzw(-self.x, -self.y, -self.z, -self.w)
        } else {
            self
        }
    }
}

impl Mul for Quat {
    type Output = Quat;
    /// Hamilton product; each component rounded once.
    #[inline]
    fn mul(self, o: Quat) -> Quat {
        let (a, b) = (self, o);
        Quat::from_xyzw(
            Scalar::from_wide(dot4([a.w, a.x, a.y, -a.z], [b.x, b.w, b.z, b.y])),
            Scalar::from_wide(dot4([a.w, -a.x, a.y, a.z], [b.y, b.z, b.w, b.x])),
            Scalar::from_wide(dot4([a.w, a.x, -a.y, a.z], [b.z, b.y, b.x, b.w])),
            Scalar::from_wide(dot4([a.w, -a.x, -a.y, -a.z], [b.w, b.x, b.y, b.z])),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::s;

    #[test]
    fn quarter_turn_about_y_takes_x_to_minus_z() {
        let q = Quat::from_axis_angle(Vec3::Y, Scalar::FRAC_PI_2);
        let r = q.rotate(Vec3::X);
        assert!(
            (r - (-Vec3::Z)).abs().max_element() <= Scalar::from_bits(4),
            "{r:?}"
        );
        let back = q.inverse_rotate(r);
        assert!((back - Vec3::X).abs().max_element() <= Scalar::from_bits(8));
    }

    #[test]
    fn product_composes_rotations() {
        let a = Quat::from_axis_angle(Vec3::X, s(0.7));
        let b = Quat::from_axis_angle(Vec3::new(s(0.6), s(0.0), s(0.8)), s(-1.9));
        let v = Vec3::new(s(1.5), s(-2.0), s(0.25));
        let composed = (a * b).rotate(v);
        let step = a.rotate(b.rotate(v));
        assert!((composed - step).abs().max_element() <= Scalar::from_bits(16));
    }

    #[test]
    fn normalize_is_unit_within_an_ulp_and_keeps_direction() {
        let q = Quat::from_xyzw(s(1.0), s(2.0), s(-2.0), s(4.0)).normalize();
        let n = q.norm_squared_wide() as f64 / 2f64.powi(64);
        assert!((n - 1.0).abs() < 4.0 / 4_294_967_296.0);
        assert_eq!(q.w, Scalar::from_ratio(4, 5));
        assert_eq!(
            Quat::from_xyzw(s(0.0), s(0.0), s(0.0), s(0.0)).normalize(),
            Quat::IDENTITY
        );
    }

    #[test]
    fn integrating_a_constant_spin_turns_by_omega_t() {
        let mut q = Quat::IDENTITY;
        let omega = Vec3::new(s(0.0), s(0.0), Scalar::PI); // half a turn per second
        let dt = Scalar::from_ratio(1, 600);
        for _ in 0..300 {
            q = q.integrate(omega, dt);
        }
        // After 0.5 s: a quarter turn about z.
        let r = q.rotate(Vec3::X);
        assert!(
            (r.x.to_f64()).abs() < 1e-5 && (r.y.to_f64() - 1.0).abs() < 1e-5,
            "{r:?}"
        );
    }
}
