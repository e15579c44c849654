//! `Cuboid`: the box, centred on the local origin and aligned with the local
//! axes.

use serde::{Deserialize, Serialize};

use super::error::ShapeError;
use super::mass::MassProperties;
use super::wide::{BigInt, product, ratio_to_scalar, ratio_to_scalar_saturating};
use crate::math::{Aabb, Scalar, SymMat3, Vec3};

/// A solid box `[−h, h]` on each local axis (the shape named "box").
///
/// Stored by half-extents because that is what the support function, SAT
/// and the bounding box all use. The field is public so that boxes can be
/// written as literals; [`Cuboid::new`] checks it, and so do
/// deserialisation and [`mass_properties`](Cuboid::mass_properties).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(try_from = "RawCuboid")]
pub struct Cuboid {
    /// Half the size along each local axis; each > 0.
    pub half_extents: Vec3,
}

#[derive(Deserialize)]
struct RawCuboid {
    half_extents: Vec3,
}

impl TryFrom<RawCuboid> for Cuboid {
    type Error = ShapeError;
    fn try_from(r: RawCuboid) -> Result<Cuboid, ShapeError> {
        Cuboid::new(r.half_extents)
    }
}

impl Cuboid {
    /// A box with the given half-extents.
    ///
    /// # Errors
    /// [`ShapeError::CuboidHalfExtents`] unless every half-extent is `> 0`.
    pub fn new(half_extents: Vec3) -> Result<Cuboid, ShapeError> {
        if half_extents.min_element().is_positive() {
            Ok(Cuboid { half_extents })
        } else {
            Err(ShapeError::CuboidHalfExtents { half_extents })
        }
    }

    /// The eight corners, in the order of the bits of the index (bit 0 set:
    /// +x, bit 1: +y, bit 2: +z).
    pub fn corners(&self) -> [Vec3; 8] {
        let h = self.half_extents;
        std::array::from_fn(|i| {
            let pick = |bit: usize, c: Scalar| if i & bit != 0 { c } else { -c };
            Vec3::new(pick(1, h.x), pick(2, h.y), pick(4, h.z))
        })
    }

    /// The box `[−h, h]`.
    pub fn local_aabb(&self) -> Aabb {
        Aabb::new(-self.half_extents, self.half_extents)
    }

    /// `8 hx hy hz`, rounded once; saturates with
    /// [`Faults::OVERFLOW`](crate::math::faults::Faults) past the Q32.32 range. Zero
    /// for invalid half-extents.
    pub fn volume(&self) -> Scalar {
        if Cuboid::new(self.half_extents).is_err() {
            return Scalar::ZERO;
        }
        let h = self.half_extents;
        // raw scale 2⁹⁶ → shift 64.
        ratio_to_scalar_saturating(
            &product(&[h.x, h.y, h.z]).mul_i128(8),
            &BigInt::from_i64(1),
            64,
        )
    }

    /// Mass `8 ρ hx hy hz`, centre at the origin, and the diagonal inertia
    /// `m/12 (b² + c²)` with full widths `b, c` (= `m/3 (hy² + hz²)` for
    /// x), each rounded once from the exact integer products: within half an
    /// ulp of the true value. The convex hull of the same eight corners gives
    /// the same bits (it computes the same exact rationals).
    ///
    /// # Errors
    /// [`ShapeError::CuboidHalfExtents`] for a literal with a bad
    /// half-extent; [`ShapeError::InvalidDensity`] unless `density > 0`;
    /// [`ShapeError::MassOutOfRange`] when a value does not fit Q32.32 or
    /// the mass rounds to zero.
    pub fn mass_properties(&self, density: Scalar) -> Result<MassProperties, ShapeError> {
        Cuboid::new(self.half_extents)?;
        if !density.is_positive() {
            return Err(ShapeError::InvalidDensity { density });
        }
        let out_of_range = || ShapeError::MassOutOfRange {
            kind: "box",
            density,
        };
        let h = self.half_extents;
        let m8 = product(&[density, h.x, h.y, h.z]).mul_i128(8);
        let one = BigInt::from_i64(1);
        // mass raw scale 2¹²⁸ → shift 96.
        let mass = ratio_to_scalar(&m8, &one, 96).ok_or_else(out_of_range)?;
        let sq = |a: Scalar, b: Scalar| product(&[a, a]).add(&product(&[b, b]));
        // inertia raw scale 2¹²⁸ · 2⁶⁴ = 2¹⁹² → shift 160.
        let three = BigInt::from_i64(3);
        let i = |a: Scalar, b: Scalar| ratio_to_scalar(&m8.mul(&sq(a, b)), &three, 160);
        let diag = Vec3::new(
            i(h.y, h.z).ok_or_else(out_of_range)?,
            i(h.x, h.z).ok_or_else(out_of_range)?,
            i(h.x, h.y).ok_or_else(out_of_range)?,
        );
        MassProperties::checked(mass, Vec3::ZERO, SymMat3::from_diagonal(diag), out_of_range)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::s;

    const ULP: f64 = 1.0 / 4_294_967_296.0;

    #[test]
    fn box_mass_properties_are_within_half_an_ulp_of_the_closed_form() {
        let mut worst: f64 = 0.0;
        for (h, rho) in [
            ([0.5, 0.5, 0.5], 1000.0),
            ([0.3, 0.7, 1.1], 7.3),
            ([2.0, 0.05, 0.9], 450.0),
        ] {
            let hv = Vec3::new(s(h[0]), s(h[1]), s(h[2]));
            let cuboid = Cuboid::new(hv).unwrap();
            let mp = cuboid.mass_properties(s(rho)).unwrap();
            let (x, y, z, rho) = (hv.x.to_f64(), hv.y.to_f64(), hv.z.to_f64(), s(rho).to_f64());
            let m = rho * 8.0 * x * y * z;
            let (b, c, a) = (2.0 * y, 2.0 * z, 2.0 * x);
            let want = [
                m / 12.0 * (b * b + c * c),
                m / 12.0 * (a * a + c * c),
                m / 12.0 * (a * a + b * b),
            ];
            let em = (mp.mass.to_f64() - m).abs() / ULP;
            assert!(em <= 0.51, "mass {} vs {m}", mp.mass);
            worst = worst.max(em);
            for (got, want) in mp.inertia.diagonal().to_array().iter().zip(want) {
                let e = (got.to_f64() - want).abs() / ULP;
                worst = worst.max(e);
                assert!(e <= 0.51, "inertia {got} vs {want}: {e} ulp");
            }
            assert_eq!(
                (mp.inertia.xy, mp.inertia.xz, mp.inertia.yz),
                (Scalar::ZERO, Scalar::ZERO, Scalar::ZERO)
            );
            let vol = (cuboid.volume().to_f64() - 8.0 * x * y * z).abs() / ULP;
            assert!(vol <= 0.51);
        }
        eprintln!("box: worst error {worst:.3} ulp");
    }

    #[test]
    fn unit_cube_of_density_six_has_inertia_one() {
        // m = 6, I = 6/12 · (1 + 1) = 1.
        let c = Cuboid::new(Vec3::splat(Scalar::HALF)).unwrap();
        let mp = c.mass_properties(Scalar::from_int(6)).unwrap();
        assert_eq!(mp.mass, Scalar::from_int(6));
        assert_eq!(mp.inertia, SymMat3::from_diagonal(Vec3::splat(Scalar::ONE)));
        assert_eq!(c.volume(), Scalar::ONE);
    }

    #[test]
    fn box_rejects_a_non_positive_half_extent() {
        let bad = Vec3::new(Scalar::ONE, Scalar::ZERO, Scalar::ONE);
        let e = Cuboid::new(bad).unwrap_err();
        assert_eq!(e, ShapeError::CuboidHalfExtents { half_extents: bad });
        assert_eq!(
            e.to_string(),
            "box half-extents must all be positive, got (1, 0, 1)"
        );
        assert!(Cuboid::new(Vec3::new(Scalar::ONE, Scalar::ONE, -Scalar::DELTA)).is_err());
        let literal = Cuboid { half_extents: bad };
        assert_eq!(
            literal.mass_properties(Scalar::ONE),
            Err(ShapeError::CuboidHalfExtents { half_extents: bad })
        );
        assert_eq!(literal.volume(), Scalar::ZERO);
    }

    #[test]
    fn corners_follow_the_index_bits() {
        let c = Cuboid::new(Vec3::from_ints(1, 2, 3)).unwrap();
        let k = c.corners();
        assert_eq!(k[0], Vec3::from_ints(-1, -2, -3));
        assert_eq!(k[5], Vec3::from_ints(1, -2, 3));
        assert_eq!(k[7], Vec3::from_ints(1, 2, 3));
    }

    #[test]
    fn tiny_box_mass_rounding_to_zero_is_an_error() {
        let c = Cuboid::new(Vec3::splat(Scalar::from_bits(1 << 16))).unwrap();
        assert!(matches!(
            c.mass_properties(Scalar::ONE),
            Err(ShapeError::MassOutOfRange { kind: "box", .. })
        ));
        assert!(matches!(
            c.mass_properties(Scalar::ZERO),
            Err(ShapeError::InvalidDensity { .. })
        ));
    }
}
