//! `Capsule`: a segment along the local y axis, thickened by a radius.

use serde::{Deserialize, Serialize};

use super::error::ShapeError;
use super::mass::MassProperties;
use super::wide::{BigInt, product, ratio_to_scalar, ratio_to_scalar_saturating};
use crate::math::{Aabb, Scalar, SymMat3, Vec3};

/// All points within `radius` of the segment from `(0, −half_height, 0)` to
/// `(0, half_height, 0)`: a cylinder capped by two hemispheres.
///
/// The usual character and limb shape: round (cheap, smooth contacts) yet
/// elongated. A zero half-height is allowed and gives a sphere. The fields
/// are public so that capsules can be written as literals; [`Capsule::new`]
/// checks them, and so do deserialisation and
/// [`mass_properties`](Capsule::mass_properties).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(try_from = "RawCapsule")]
pub struct Capsule {
    /// Half the length of the core segment, ≥ 0.
    pub half_height: Scalar,
    /// The radius, > 0.
    pub radius: Scalar,
}

#[derive(Deserialize)]
struct RawCapsule {
    half_height: Scalar,
    radius: Scalar,
}

impl TryFrom<RawCapsule> for Capsule {
    type Error = ShapeError;
    fn try_from(r: RawCapsule) -> Result<Capsule, ShapeError> {
        Capsule::new(r.half_height, r.radius)
    }
}

impl Capsule {
    /// A capsule whose core segment runs along local y from `−half_height`
    /// to `+half_height`.
    ///
    /// # Errors
    /// [`ShapeError::CapsuleHalfHeight`] if `half_height < 0`;
    /// [`ShapeError::CapsuleRadius`] unless `radius > 0`.
    pub fn new(half_height: Scalar, radius: Scalar) -> Result<Capsule, ShapeError> {
        if half_height.is_negative() {
            return Err(ShapeError::CapsuleHalfHeight { half_height });
        }
        if !radius.is_positive() {
            return Err(ShapeError::CapsuleRadius { radius });
        }
        Ok(Capsule {
            half_height,
            radius,
        })
    }

    /// The two ends of the core segment, `(0, ∓half_height, 0)`.
    pub fn segment(&self) -> [Vec3; 2] {
        let top = Vec3::new(Scalar::ZERO, self.half_height, Scalar::ZERO);
        [-top, top]
    }

    /// `[−r, r] × [−(h + r), h + r] × [−r, r]`.
    pub fn local_aabb(&self) -> Aabb {
        let r = self.radius;
        let e = Vec3::new(r, self.half_height + r, r);
        Aabb::new(-e, e)
    }

    /// `π r² · 2h + 4/3 π r³`, rounded once; saturates with
    /// [`Faults::OVERFLOW`](crate::math::faults::Faults) past the Q32.32 range. Zero
    /// for invalid dimensions.
    pub fn volume(&self) -> Scalar {
        if Capsule::new(self.half_height, self.radius).is_err() {
            return Scalar::ZERO;
        }
        // raw scale 2⁹⁶ · π 2¹²⁵ → shift 189.
        let num = self.mass_poly().mul(&BigInt::pi_q125());
        ratio_to_scalar_saturating(&num, &BigInt::from_i64(3), 189)
    }

    /// `6 h r² + 4 r³` (raw scale 2⁹⁶): three times the volume over π.
    fn mass_poly(&self) -> BigInt {
        let (h, r) = (self.half_height, self.radius);
        product(&[h, r, r])
            .mul_i128(6)
            .add(&product(&[r, r, r]).mul_i128(4))
    }

    /// Mass, centre (the origin) and inertia, each rounded once from exact
    /// integer polynomials in `h` and `r` (π carried to 125 bits).
    ///
    /// With the cylinder mass `m_c = ρ π r² 2h` and the hemispheres' total
    /// `m_s = ρ 4/3 π r³`:
    /// * about the axis (y): `I_y = m_c r²/2 + m_s · 2r²/5`;
    /// * across it (x, z): the cylinder gives `m_c (r²/4 + h²/3)`; each
    ///   hemisphere has `2/5 m r²` about a diameter of its flat face, its
    ///   centroid sits `3r/8` beyond the face, so moving the axis from the
    ///   face through the centroid (−(3r/8)²) to the capsule centre
    ///   (+(h + 3r/8)²) adds `m (h² + 3hr/4)`: in all
    ///   `m_s (2r²/5 + h² + 3hr/4)`.
    ///
    /// Expanded: `I_x = ρπ/30 (16 r⁵ + 45 h r⁴ + 40 h² r³ + 20 h³ r²)`,
    /// `I_y = ρπ/15 (8 r⁵ + 15 h r⁴)`, `m = ρπ/3 (6 h r² + 4 r³)`.
    ///
    /// # Errors
    /// [`ShapeError::CapsuleHalfHeight`] or [`ShapeError::CapsuleRadius`]
    /// for a literal with bad dimensions;
    /// [`ShapeError::InvalidDensity`] unless `density > 0`;
    /// [`ShapeError::MassOutOfRange`] when a value does not fit Q32.32 or
    /// the mass rounds to zero.
    pub fn mass_properties(&self, density: Scalar) -> Result<MassProperties, ShapeError> {
        Capsule::new(self.half_height, self.radius)?;
        if !density.is_positive() {
            return Err(ShapeError::InvalidDensity { density });
        }
        let out_of_range = || ShapeError::MassOutOfRange {
            kind: "capsule",
            density,
        };
        let (h, r) = (self.half_height, self.radius);
        let rho_pi = BigInt::from_scalar(density).mul(&BigInt::pi_q125());
        // mass raw scale 2³² · 2¹²⁵ · 2⁹⁶ = 2²⁵³ → shift 221.
        let mass = ratio_to_scalar(&rho_pi.mul(&self.mass_poly()), &BigInt::from_i64(3), 221)
            .ok_or_else(out_of_range)?;
        let term = |k: i128, xs: &[Scalar]| product(xs).mul_i128(k);
        let across = term(16, &[r, r, r, r, r])
            .add(&term(45, &[h, r, r, r, r]))
            .add(&term(40, &[h, h, r, r, r]))
            .add(&term(20, &[h, h, h, r, r]));
        let along = term(8, &[r, r, r, r, r]).add(&term(15, &[h, r, r, r, r]));
        // inertia raw scale 2³² · 2¹²⁵ · 2¹⁶⁰ = 2³¹⁷ → shift 285.
        let ix = ratio_to_scalar(&rho_pi.mul(&across), &BigInt::from_i64(30), 285)
            .ok_or_else(out_of_range)?;
        let iy = ratio_to_scalar(&rho_pi.mul(&along), &BigInt::from_i64(15), 285)
            .ok_or_else(out_of_range)?;
        MassProperties::checked(
            mass,
            Vec3::ZERO,
            SymMat3::from_diagonal(Vec3::new(ix, iy, ix)),
            out_of_range,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shape::Sphere;
    use crate::testing::s;
    use std::f64::consts::PI;

    const ULP: f64 = 1.0 / 4_294_967_296.0;

    /// Mass, I_x and I_y of a capsule by slicing it into discs along y and
    /// integrating with the midpoint rule in f64. Each disc of radius ρ at
    /// height y has mass dm = ρ_d π ρ² dy, I_y = dm ρ²/2 and
    /// I_x = dm (ρ²/4 + y²).
    fn integrate(h: f64, r: f64, rho: f64, slices: usize) -> (f64, f64, f64) {
        let total = 2.0 * (h + r);
        let dy = total / slices as f64;
        let (mut m, mut ix, mut iy) = (0.0, 0.0, 0.0);
        for k in 0..slices {
            let y = -(h + r) + (k as f64 + 0.5) * dy;
            let beyond = (y.abs() - h).max(0.0);
            let rr = (r * r - beyond * beyond).max(0.0);
            let dm = rho * PI * rr * dy;
            m += dm;
            iy += dm * rr / 2.0;
            ix += dm * (rr / 4.0 + y * y);
        }
        (m, ix, iy)
    }

    #[test]
    fn capsule_mass_properties_match_a_fine_numerical_integration() {
        let mut worst: f64 = 0.0;
        for (h, r, rho) in [
            (0.5, 0.25, 1000.0),
            (1.0, 1.0, 1.0),
            (0.05, 0.3, 2700.0),
            (2.0, 0.1, 3.5),
        ] {
            let cap = Capsule::new(s(h), s(r)).unwrap();
            let mp = cap.mass_properties(s(rho)).unwrap();
            let (h, r, rho) = (s(h).to_f64(), s(r).to_f64(), s(rho).to_f64());
            let (m, ix, iy) = integrate(h, r, rho, 2_000_000);
            for (got, want) in [(mp.mass, m), (mp.inertia.xx, ix), (mp.inertia.yy, iy)] {
                // Q32.32 holds small values to 2⁻³³ absolute: allow half an
                // ulp on top of the relative tolerance.
                let err = (got.to_f64() - want).abs();
                worst = worst.max(err / ULP);
                assert!(err <= 1e-9 * want + 0.5 * ULP, "{got} vs {want}: {err:e}");
            }
            assert_eq!(mp.inertia.zz, mp.inertia.xx);
            assert_eq!(mp.local_center, Vec3::ZERO);
        }
        eprintln!("capsule vs integration: worst difference {worst:.3} ulp");
    }

    #[test]
    fn capsule_mass_properties_are_within_half_an_ulp_of_the_closed_form() {
        let mut worst: f64 = 0.0;
        for (h, r, rho) in [(0.5, 0.25, 1000.0), (1.0, 1.0, 1.0), (0.9, 0.45, 1.0)] {
            let cap = Capsule::new(s(h), s(r)).unwrap();
            let mp = cap.mass_properties(s(rho)).unwrap();
            let (h, r, rho) = (s(h).to_f64(), s(r).to_f64(), s(rho).to_f64());
            let mc = rho * PI * r * r * 2.0 * h;
            let ms = rho * 4.0 / 3.0 * PI * r * r * r;
            let m = mc + ms;
            let ix = mc * (r * r / 4.0 + h * h / 3.0) + ms * (0.4 * r * r + h * h + 0.75 * h * r);
            let iy = mc * r * r / 2.0 + ms * 0.4 * r * r;
            for (got, want) in [(mp.mass, m), (mp.inertia.xx, ix), (mp.inertia.yy, iy)] {
                let e = (got.to_f64() - want).abs() / ULP;
                worst = worst.max(e);
                assert!(e <= 0.51, "{got} vs {want}: {e} ulp");
            }
            let v = PI * r * r * 2.0 * h + 4.0 / 3.0 * PI * r * r * r;
            assert!((cap.volume().to_f64() - v).abs() <= 0.51 * ULP);
        }
        eprintln!("capsule vs closed form: worst error {worst:.3} ulp");
    }

    #[test]
    fn capsule_of_zero_height_is_a_sphere() {
        let r = s(0.6);
        let cap = Capsule::new(Scalar::ZERO, r)
            .unwrap()
            .mass_properties(s(3.0))
            .unwrap();
        let sph = Sphere::new(r).unwrap().mass_properties(s(3.0)).unwrap();
        assert_eq!(cap, sph);
    }

    #[test]
    fn capsule_rejects_bad_dimensions() {
        assert_eq!(
            Capsule::new(s(-0.5), Scalar::ONE),
            Err(ShapeError::CapsuleHalfHeight {
                half_height: s(-0.5)
            })
        );
        assert_eq!(
            Capsule::new(Scalar::ONE, Scalar::ZERO)
                .unwrap_err()
                .to_string(),
            "capsule radius must be positive, got 0"
        );
        assert_eq!(
            Capsule::new(s(-0.5), Scalar::ONE).unwrap_err().to_string(),
            "capsule half-height must not be negative, got -0.5"
        );
        let literal = Capsule {
            half_height: Scalar::ONE,
            radius: -Scalar::ONE,
        };
        assert_eq!(
            literal.mass_properties(Scalar::ONE),
            Err(ShapeError::CapsuleRadius {
                radius: -Scalar::ONE
            })
        );
        assert_eq!(literal.volume(), Scalar::ZERO);
    }
}
