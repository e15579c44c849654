//! `MassProperties`: mass, centre of mass and inertia tensor of a body, and
//! how compound bodies add theirs up.

use serde::{Deserialize, Serialize};

use super::error::ShapeError;
use super::wide::BigInt;
use crate::math::faults::{self, Faults};
use crate::math::scalar::div_round_i128;
use crate::math::{Mat3, Scalar, SymMat3, Transform, Vec3};

/// The mass distribution of a rigid body (or one shape of it).
///
/// What the solver needs to turn impulses into velocity changes. Shapes
/// produce these from a density ([`Shape::mass_properties`](super::Shape::mass_properties));
/// compound bodies [`combine`](MassProperties::combine) the parts'.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct MassProperties {
    /// Mass in kilograms.
    pub mass: Scalar,
    /// The centre of mass in the shape's (or body's) local frame.
    pub local_center: Vec3,
    /// The inertia tensor about `local_center`, in local axes (kg·m²). The
    /// off-diagonal entries are the tensor's own (that is, minus the
    /// products of inertia).
    pub inertia: SymMat3,
}

/// `Σ a_i · b_i`, saturating with [`Faults::OVERFLOW`] (only reachable with
/// masses and offsets near the Q32.32 limits).
fn checked_sum(acc: i128, v: i128) -> i128 {
    acc.checked_add(v).unwrap_or_else(|| {
        faults::raise(Faults::OVERFLOW);
        if v < 0 { i128::MIN } else { i128::MAX }
    })
}

impl MassProperties {
    /// No mass at all: what an empty compound adds up to.
    pub const ZERO: MassProperties = MassProperties {
        mass: Scalar::ZERO,
        local_center: Vec3::ZERO,
        inertia: SymMat3::ZERO,
    };

    /// Builds the properties a shape computed, refusing a mass that rounded
    /// to zero (its inverse would be infinite).
    pub(crate) fn checked(
        mass: Scalar,
        local_center: Vec3,
        inertia: SymMat3,
        error: impl FnOnce() -> ShapeError,
    ) -> Result<MassProperties, ShapeError> {
        if mass.is_positive() {
            Ok(MassProperties {
                mass,
                local_center,
                inertia,
            })
        } else {
            Err(error())
        }
    }

    /// `1 / mass`, rounded to nearest; zero for a zero mass, the convention
    /// for bodies that impulses cannot move (static and kinematic ones).
    pub fn inverse_mass(&self) -> Scalar {
        if self.mass.is_zero() {
            Scalar::ZERO
        } else {
            self.mass.recip()
        }
    }

    /// The inverse of the inertia tensor, each entry rounded once from the
    /// exact adjugate and determinant (better than
    /// [`SymMat3::try_inverse`], which rounds the cofactors first: that
    /// matters for small bodies, whose tensors have entries of 10⁻³ or
    /// less). `None` when the tensor is singular or the inverse overflows.
    pub fn inverse_inertia(&self) -> Option<SymMat3> {
        let t = &self.inertia;
        let b = BigInt::from_scalar;
        let (a, bb, c, d, e, f) = (b(t.xx), b(t.yy), b(t.zz), b(t.xy), b(t.xz), b(t.yz));
        let minor = |p: &BigInt, q: &BigInt, r: &BigInt, s: &BigInt| p.mul(q).sub(&r.mul(s));
        // Adjugate entries (raw scale 2⁶⁴) and determinant (2⁹⁶).
        let cxx = minor(&bb, &c, &f, &f);
        let cyy = minor(&a, &c, &e, &e);
        let czz = minor(&a, &bb, &d, &d);
        let cxy = minor(&e, &f, &c, &d);
        let cxz = minor(&d, &f, &bb, &e);
        let cyz = minor(&d, &e, &a, &f);
        let det = a.mul(&cxx).add(&d.mul(&cxy)).add(&e.mul(&cxz));
        if det.is_zero() {
            return None;
        }
        // entry bits = cof · 2⁶⁴ / det: (2⁶⁴ · 2⁶⁴ / 2⁹⁶ = 2³²).
        let entry = |cof: &BigInt| cof.shl(64).div_round(&det).to_i64().map(Scalar::from_bits);
        Some(SymMat3 {
            xx: entry(&cxx)?,
            yy: entry(&cyy)?,
            zz: entry(&czz)?,
            xy: entry(&cxy)?,
            xz: entry(&cxz)?,
            yz: entry(&cyz)?,
        })
    }

    /// The mass properties of a compound body made of `parts`, each given
    /// with its pose in the body frame.
    ///
    /// The total mass is the exact sum; the centre is the mass-weighted mean
    /// of the posed part centres, accumulated exactly and divided once; the
    /// inertia is the sum of each part's tensor rotated into the body axes
    /// (`R I Rᵀ`, [`SymMat3::rotate`]) and shifted to the common centre by
    /// the parallel-axis theorem ([`SymMat3::point_mass_inertia`]). With no
    /// parts, or parts of zero total mass, the result is [`Self::ZERO`]
    /// (centre at the origin).
    ///
    /// Determinism: the sum runs in slice order; reorder parts and the
    /// inertia may differ in the last bits.
    pub fn combine(parts: &[(MassProperties, Transform)]) -> MassProperties {
        let mass = parts.iter().fold(Scalar::ZERO, |m, (p, _)| m + p.mass);
        if !mass.is_positive() {
            return MassProperties::ZERO;
        }
        let centers: Vec<Vec3> = parts
            .iter()
            .map(|(p, pose)| pose.transform_point(p.local_center))
            .collect();
        let mut moment = [0i128; 3];
        for ((p, _), c) in parts.iter().zip(&centers) {
            for (k, m) in moment.iter_mut().enumerate() {
                *m = checked_sum(*m, p.mass.wide_mul(c.get(k)));
            }
        }
        // moment raw scale 2⁶⁴, mass 2³² → quotient 2³².
        let div = |m: i128| {
            Scalar::from_bits(crate::math::scalar::narrow(div_round_i128(
                m,
                mass.to_bits() as i128,
            )))
        };
        let center = Vec3::new(div(moment[0]), div(moment[1]), div(moment[2]));
        let mut inertia = SymMat3::ZERO;
        for ((p, pose), c) in parts.iter().zip(&centers) {
            let rotated = p.inertia.rotate(&Mat3::from_quat(pose.rotation));
            inertia = inertia + rotated + SymMat3::point_mass_inertia(p.mass, *c - center);
        }
        MassProperties {
            mass,
            local_center: center,
            inertia,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Quat;
    use crate::shape::{Cuboid, Shape};
    use crate::testing::{s, v};

    fn max_diff(a: &SymMat3, b: &SymMat3) -> i64 {
        [
            a.xx - b.xx,
            a.yy - b.yy,
            a.zz - b.zz,
            a.xy - b.xy,
            a.xz - b.xz,
            a.yz - b.yz,
        ]
        .iter()
        .map(|d| d.to_bits().abs())
        .max()
        .unwrap()
    }

    fn box_mp(hx: f64, hy: f64, hz: f64, rho: f64) -> MassProperties {
        Shape::Cuboid(Cuboid::new(v(hx, hy, hz)).unwrap())
            .mass_properties(s(rho))
            .unwrap()
    }

    #[test]
    fn two_boxes_side_by_side_equal_one_box_of_double_length_exactly() {
        // Dyadic sizes: every intermediate is exact, so equality is bitwise.
        let half = box_mp(1.0, 0.5, 0.25, 3.0);
        let whole = box_mp(2.0, 0.5, 0.25, 3.0);
        let left = Transform::from_translation(v(-1.0, 0.0, 0.0));
        let right = Transform::from_translation(v(1.0, 0.0, 0.0));
        let c = MassProperties::combine(&[(half, left), (half, right)]);
        assert_eq!(c, whole);
        assert_eq!(c.mass, Scalar::from_int(6));
        assert_eq!(c.inertia.xx, s(0.3125) * Scalar::TWO);
    }

    #[test]
    fn two_boxes_side_by_side_match_one_box_within_three_ulps_for_odd_sizes() {
        // Shifted off the origin and with non-dyadic sizes and density; the
        // long box is exactly twice as long as each half.
        let hx = s(0.35);
        let mp = |x: Scalar| {
            Shape::Cuboid(Cuboid::new(Vec3::new(x, s(0.7), s(1.3))).unwrap())
                .mass_properties(s(7.3))
                .unwrap()
        };
        let (half, whole) = (mp(hx), mp(hx + hx));
        let offset = v(5.0, -2.0, 1.0);
        let dx = Vec3::new(hx, Scalar::ZERO, Scalar::ZERO);
        let a = Transform::from_translation(offset - dx);
        let b = Transform::from_translation(offset + dx);
        let c = MassProperties::combine(&[(half, a), (half, b)]);
        assert!((c.mass - whole.mass).abs().to_bits() <= 1);
        assert!((c.local_center - offset).abs().max_element().to_bits() <= 1);
        let d = max_diff(&c.inertia, &whole.inertia);
        eprintln!("compound of two boxes: inertia within {d} ulp");
        assert!(d <= 3, "{:?} vs {:?}", c.inertia, whole.inertia);
    }

    #[test]
    fn a_part_turned_a_quarter_turn_swaps_its_inertia_axes() {
        let mp = box_mp(1.0, 0.5, 0.25, 2.0);
        let quarter = Quat::from_axis_angle(Vec3::Z, Scalar::FRAC_PI_2).normalize();
        let c = MassProperties::combine(&[(mp, Transform::new(v(3.0, 0.0, 0.0), quarter))]);
        let swapped = box_mp(0.5, 1.0, 0.25, 2.0);
        assert_eq!(c.mass, mp.mass);
        assert!(
            (c.local_center - v(3.0, 0.0, 0.0))
                .abs()
                .max_element()
                .to_bits()
                <= 2
        );
        let d = max_diff(&c.inertia, &swapped.inertia);
        assert!(d <= 8, "{d} ulp: {:?} vs {:?}", c.inertia, swapped.inertia);
    }

    #[test]
    fn combining_nothing_or_massless_parts_gives_zero() {
        assert_eq!(MassProperties::combine(&[]), MassProperties::ZERO);
        let massless = (
            MassProperties::ZERO,
            Transform::from_translation(v(1.0, 2.0, 3.0)),
        );
        assert_eq!(MassProperties::combine(&[massless]), MassProperties::ZERO);
        assert_eq!(MassProperties::ZERO.inverse_mass(), Scalar::ZERO);
    }

    #[test]
    fn inverse_mass_and_inverse_inertia_invert() {
        let mp = box_mp(0.05, 0.1, 0.2, 1000.0);
        assert_eq!(mp.inverse_mass(), Scalar::ONE / mp.mass);
        let inv = mp.inverse_inertia().unwrap();
        // Diagonal tensor: each entry is 1/I rounded once.
        let t = mp.inertia;
        for (i, iv) in [(t.xx, inv.xx), (t.yy, inv.yy), (t.zz, inv.zz)] {
            let exact = 1.0 / i.to_f64();
            let err = (iv.to_f64() - exact).abs() * 4_294_967_296.0;
            assert!(err <= 0.5 + 1e-6 * exact, "{iv} vs {exact}: {err} ulp");
        }
        assert_eq!(inv.xy, Scalar::ZERO);
        // A full tensor: I · I⁻¹ = 1 to the precision of the entries.
        let r = Mat3::from_quat(Quat::from_axis_angle(v(0.48, 0.6, 0.64), s(0.9)));
        let full = MassProperties {
            inertia: mp.inertia.rotate(&r),
            ..mp
        };
        let inv = full.inverse_inertia().unwrap();
        let prod = full.inertia.to_mat3() * inv.to_mat3();
        for c in 0..3 {
            for k in 0..3 {
                let want = if c == k { 1.0 } else { 0.0 };
                let got = prod.cols[c].get(k).to_f64();
                assert!((got - want).abs() < 1e-6, "({c},{k}) = {got}");
            }
        }
        assert_eq!(MassProperties::ZERO.inverse_inertia(), None);
    }
}
