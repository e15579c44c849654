//! `Sphere`: the ball centred on the body's local origin.

use serde::{Deserialize, Serialize};

use super::error::ShapeError;
use super::mass::MassProperties;
use super::wide::{BigInt, product, ratio_to_scalar, ratio_to_scalar_saturating};
use crate::math::{Aabb, Scalar, SymMat3, Vec3};

/// A solid ball of the given radius, centred on the local origin.
///
/// The cheapest shape to collide and the only one whose world bounding box
/// needs no rotation. The field is public so that spheres can be written as
/// literals; [`Sphere::new`] checks the radius, and so do deserialisation and
/// [`mass_properties`](Sphere::mass_properties).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(try_from = "RawSphere")]
pub struct Sphere {
    /// The radius, > 0.
    pub radius: Scalar,
}

#[derive(Deserialize)]
struct RawSphere {
    radius: Scalar,
}

impl TryFrom<RawSphere> for Sphere {
    type Error = ShapeError;
    fn try_from(r: RawSphere) -> Result<Sphere, ShapeError> {
        Sphere::new(r.radius)
    }
}

impl Sphere {
    /// A sphere of radius `radius`.
    ///
    /// # Errors
    /// [`ShapeError::SphereRadius`] unless `radius > 0`.
    pub fn new(radius: Scalar) -> Result<Sphere, ShapeError> {
        if radius.is_positive() {
            Ok(Sphere { radius })
        } else {
            Err(ShapeError::SphereRadius { radius })
        }
    }

    /// The box `[−r, r]³`.
    pub fn local_aabb(&self) -> Aabb {
        let r = Vec3::splat(self.radius);
        Aabb::new(-r, r)
    }

    /// `4/3 π r³`, rounded once from the exact product (π carried to 125
    /// bits); saturates with [`Faults::OVERFLOW`](crate::math::faults::Faults) past
    /// the Q32.32 range (radius above about 800 m). Zero for an invalid
    /// (non-positive) radius.
    pub fn volume(&self) -> Scalar {
        let r = self.radius.max(Scalar::ZERO);
        // raw scale: r³ 2⁹⁶ · π 2¹²⁵ = 2²²¹; result 2³² → shift 189.
        let num = product(&[r, r, r]).mul(&BigInt::pi_q125()).mul_i128(4);
        ratio_to_scalar_saturating(&num, &BigInt::from_i64(3), 189)
    }

    /// Mass `ρ · 4/3 π r³`, centre at the origin, inertia `2/5 m r²` on the
    /// diagonal (= `8/15 ρ π r⁵`), each rounded once from exact integers:
    /// within half an ulp of the true value (plus π's 2⁻¹²⁷ relative error).
    ///
    /// # Errors
    /// [`ShapeError::SphereRadius`] for a literal with a bad radius;
    /// [`ShapeError::InvalidDensity`] unless `density > 0`;
    /// [`ShapeError::MassOutOfRange`] when the mass or inertia does not fit
    /// Q32.32 or the mass rounds to zero.
    pub fn mass_properties(&self, density: Scalar) -> Result<MassProperties, ShapeError> {
        Sphere::new(self.radius)?;
        if !density.is_positive() {
            return Err(ShapeError::InvalidDensity { density });
        }
        let r = self.radius;
        let out_of_range = || ShapeError::MassOutOfRange {
            kind: "sphere",
            density,
        };
        let rho_pi = BigInt::from_scalar(density).mul(&BigInt::pi_q125());
        // mass raw scale: ρ 2³² · π 2¹²⁵ · r³ 2⁹⁶ = 2²⁵³ → shift 221.
        let mass_num = rho_pi.mul(&product(&[r, r, r])).mul_i128(4);
        let mass =
            ratio_to_scalar(&mass_num, &BigInt::from_i64(3), 221).ok_or_else(out_of_range)?;
        // inertia raw scale: 2³² · 2¹²⁵ · 2¹⁶⁰ = 2³¹⁷ → shift 285.
        let i_num = rho_pi.mul(&product(&[r, r, r, r, r])).mul_i128(8);
        let i = ratio_to_scalar(&i_num, &BigInt::from_i64(15), 285).ok_or_else(out_of_range)?;
        MassProperties::checked(
            mass,
            Vec3::ZERO,
            SymMat3::from_diagonal(Vec3::splat(i)),
            out_of_range,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::FaultScope;
    use crate::math::Faults;
    use crate::testing::s;

    const ULP: f64 = 1.0 / 4_294_967_296.0;

    #[test]
    fn sphere_mass_properties_are_within_half_an_ulp_of_the_closed_form() {
        let mut worst: f64 = 0.0;
        for (r, rho) in [(0.5, 1000.0), (0.1, 7850.0), (1.7, 2.5), (3.0, 0.125)] {
            let sphere = Sphere::new(s(r)).unwrap();
            let (r, rho) = (s(r).to_f64(), s(rho).to_f64());
            let mp = sphere.mass_properties(s(rho)).unwrap();
            let m = rho * 4.0 / 3.0 * std::f64::consts::PI * r * r * r;
            let i = 0.4 * m * r * r;
            let em = (mp.mass.to_f64() - m).abs() / ULP;
            let ei = (mp.inertia.xx.to_f64() - i).abs() / ULP;
            worst = worst.max(em).max(ei);
            assert!(em <= 0.51, "mass {} vs {m}: {em} ulp", mp.mass);
            assert!(ei <= 0.51, "inertia {} vs {i}: {ei} ulp", mp.inertia.xx);
            assert_eq!(mp.inertia.yy, mp.inertia.xx);
            assert_eq!(mp.inertia.zz, mp.inertia.xx);
            assert_eq!(mp.inertia.xy, Scalar::ZERO);
            assert_eq!(mp.local_center, Vec3::ZERO);
            let v = 4.0 / 3.0 * std::f64::consts::PI * r * r * r;
            assert!((sphere.volume().to_f64() - v).abs() <= 0.51 * ULP);
        }
        eprintln!("sphere: worst error {worst:.3} ulp");
    }

    #[test]
    fn unit_sphere_of_unit_density_has_four_thirds_pi_mass() {
        let mp = Sphere::new(Scalar::ONE)
            .unwrap()
            .mass_properties(Scalar::ONE)
            .unwrap();
        // 4/3 π · 2³² = 17990716939.36… → 17990716939.
        assert_eq!(mp.mass.to_bits(), 17_990_716_939);
        // 8/15 π · 2³² = 7196286775.75… → 7196286776.
        assert_eq!(mp.inertia.xx.to_bits(), 7_196_286_776);
    }

    #[test]
    fn sphere_rejects_non_positive_radius_with_a_clear_message() {
        let e = Sphere::new(Scalar::NEG_ONE).unwrap_err();
        assert_eq!(
            e,
            ShapeError::SphereRadius {
                radius: Scalar::NEG_ONE
            }
        );
        assert_eq!(e.to_string(), "sphere radius must be positive, got -1");
        assert!(Sphere::new(Scalar::ZERO).is_err());
        assert!(Sphere::new(Scalar::DELTA).is_ok());
        // A literal with a bad radius is caught when its mass is asked for.
        let literal = Sphere {
            radius: -Scalar::HALF,
        };
        assert_eq!(
            literal.mass_properties(Scalar::ONE),
            Err(ShapeError::SphereRadius {
                radius: -Scalar::HALF
            })
        );
        assert_eq!(literal.volume(), Scalar::ZERO);
    }

    #[test]
    fn huge_sphere_mass_is_reported_out_of_range_and_volume_saturates() {
        let sphere = Sphere::new(Scalar::from_int(10_000)).unwrap();
        assert_eq!(
            sphere.mass_properties(Scalar::ONE),
            Err(ShapeError::MassOutOfRange {
                kind: "sphere",
                density: Scalar::ONE
            })
        );
        let (v, f) = FaultScope::run(|| sphere.volume());
        assert_eq!(v, Scalar::MAX);
        assert_eq!(f, Faults::OVERFLOW);
    }
}
