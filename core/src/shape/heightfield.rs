//! `HeightField`: a static terrain grid of heights.

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use super::ShapeError;
use crate::math::scalar::{round_shift, round_shift32};
use crate::math::{Aabb, Scalar, Vec3};

/// A regular grid of heights: terrain.
///
/// Layout (the one the scene format documents): the grid is **centred on the
/// local origin** in x and z. The sample in row `r` and column `c`
/// (row-major: `heights[r * cols + c]`) sits at
/// `((c − (cols − 1)/2) · scale.x, heights[r * cols + c] · scale.y,
/// (r − (rows − 1)/2) · scale.z)`; columns run along +x, rows along +z,
/// heights along +y. Each coordinate is computed as
/// `(2c − (cols − 1)) · scale.x / 2` with a single rounding (ties away from
/// zero), so the grid is exactly symmetric about the origin. Each cell is
/// split into two triangles along the diagonal from `(r, c)` to
/// `(r + 1, c + 1)`, both facing +y (see [`cell_triangles`](Self::cell_triangles)).
///
/// Static-only: it has no volume or mass.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct HeightField {
    rows: u32,
    cols: u32,
    heights: Vec<Scalar>,
    scale: Vec3,
    local_aabb: Aabb,
}

/// `a · b` rounded to nearest, or `None` if it does not fit Q32.32.
fn mul_checked(a: Scalar, b: Scalar) -> Option<Scalar> {
    i64::try_from(round_shift32(a.wide_mul(b)))
        .ok()
        .map(Scalar::from_bits)
}

/// `(2i − (n − 1)) · step / 2`, rounded once (ties away from zero), or `None`
/// if it does not fit: the centred grid coordinate of sample `i` of `n`.
fn grid_coordinate(i: u32, n: u32, step: Scalar) -> Option<Scalar> {
    let k = 2 * i as i128 - (n as i128 - 1);
    i64::try_from(round_shift(k * step.to_bits() as i128, 1))
        .ok()
        .map(Scalar::from_bits)
}

impl HeightField {
    /// A `rows × cols` grid of `heights` (row-major), scaled by `scale`.
    ///
    /// # Errors
    /// * [`ShapeError::HeightFieldTooSmall`] unless `rows ≥ 2` and
    ///   `cols ≥ 2`;
    /// * [`ShapeError::HeightFieldSizeMismatch`] unless
    ///   `heights.len() == rows · cols`;
    /// * [`ShapeError::HeightFieldScale`] unless every scale component is
    ///   `> 0`;
    /// * [`ShapeError::HeightFieldOutOfRange`] when the grid's extent
    ///   (`(cols − 1) · scale.x`, `(rows − 1) · scale.z`) or a scaled height
    ///   does not fit Q32.32.
    pub fn new(
        rows: u32,
        cols: u32,
        heights: Vec<Scalar>,
        scale: Vec3,
    ) -> Result<HeightField, ShapeError> {
        if rows < 2 || cols < 2 {
            return Err(ShapeError::HeightFieldTooSmall { rows, cols });
        }
        let expected = rows as u64 * cols as u64;
        if heights.len() as u64 != expected {
            return Err(ShapeError::HeightFieldSizeMismatch {
                rows,
                cols,
                expected,
                got: heights.len(),
            });
        }
        if !scale.min_element().is_positive() {
            return Err(ShapeError::HeightFieldScale { scale });
        }
        let out = ShapeError::HeightFieldOutOfRange;
        // The full width must fit too: bounding boxes subtract their corners.
        let width = |n: u32, s: Scalar| i64::try_from((n as i128 - 1) * s.to_bits() as i128).ok();
        width(cols, scale.x).ok_or(out.clone())?;
        width(rows, scale.z).ok_or(out.clone())?;
        let max_x = grid_coordinate(cols - 1, cols, scale.x).ok_or(out.clone())?;
        let max_z = grid_coordinate(rows - 1, rows, scale.z).ok_or(out.clone())?;
        let (mut lo, mut hi) = (Scalar::MAX, Scalar::MIN);
        for &h in &heights {
            let y = mul_checked(h, scale.y).ok_or(out.clone())?;
            lo = lo.min(y);
            hi = hi.max(y);
        }
        let local_aabb = Aabb::new(Vec3::new(-max_x, lo, -max_z), Vec3::new(max_x, hi, max_z));
        Ok(HeightField {
            rows,
            cols,
            heights,
            scale,
            local_aabb,
        })
    }

    /// Number of rows (samples along z).
    pub fn rows(&self) -> u32 {
        self.rows
    }

    /// Number of columns (samples along x).
    pub fn cols(&self) -> u32 {
        self.cols
    }

    /// The unscaled heights, row-major, as given.
    pub fn heights(&self) -> &[Scalar] {
        &self.heights
    }

    /// Cell size in x and z, and the height multiplier in y.
    pub fn scale(&self) -> Vec3 {
        self.scale
    }

    /// The local position of sample `(row, col)`, or `None` outside the grid.
    pub fn vertex(&self, row: u32, col: u32) -> Option<Vec3> {
        if row >= self.rows || col >= self.cols {
            return None;
        }
        let h = self.heights[row as usize * self.cols as usize + col as usize];
        // Cannot overflow: `new` checked the extents and every scaled height.
        Some(Vec3::new(
            grid_coordinate(col, self.cols, self.scale.x)?,
            h * self.scale.y,
            grid_coordinate(row, self.rows, self.scale.z)?,
        ))
    }

    /// The two triangles of cell `(row, col)` (`row < rows − 1`,
    /// `col < cols − 1`), counter-clockwise seen from above (+y), split
    /// along the diagonal from `(row, col)` to `(row + 1, col + 1)`:
    /// `[a, d, b]` and `[a, c, d]` with `a = (row, col)`, `b = (row, col + 1)`,
    /// `c = (row + 1, col)`, `d = (row + 1, col + 1)`. `None` outside.
    pub fn cell_triangles(&self, row: u32, col: u32) -> Option<[[Vec3; 3]; 2]> {
        if row >= self.rows - 1 || col >= self.cols - 1 {
            return None;
        }
        let a = self.vertex(row, col)?;
        let b = self.vertex(row, col + 1)?;
        let c = self.vertex(row + 1, col)?;
        let d = self.vertex(row + 1, col + 1)?;
        Some([[a, d, b], [a, c, d]])
    }

    /// The grid's footprint (symmetric about the origin in x and z), spanning
    /// the lowest and highest scaled heights.
    pub fn local_aabb(&self) -> Aabb {
        self.local_aabb
    }
}

#[derive(Serialize)]
struct HeightFieldRef<'a> {
    rows: u32,
    cols: u32,
    heights: &'a [Scalar],
    scale: Vec3,
}

#[derive(Deserialize)]
struct HeightFieldData {
    rows: u32,
    cols: u32,
    heights: Vec<Scalar>,
    scale: Vec3,
}

impl Serialize for HeightField {
    /// The constructor's arguments; the bounds are derived.
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        HeightFieldRef {
            rows: self.rows,
            cols: self.cols,
            heights: &self.heights,
            scale: self.scale,
        }
        .serialize(s)
    }
}

impl<'de> Deserialize<'de> for HeightField {
    /// Rebuilds (and so re-validates) the field.
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<HeightField, D::Error> {
        let f = HeightFieldData::deserialize(d)?;
        HeightField::new(f.rows, f.cols, f.heights, f.scale).map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ints(v: &[i32]) -> Vec<Scalar> {
        v.iter().map(|&x| Scalar::from_int(x)).collect()
    }

    fn scale() -> Vec3 {
        Vec3::new(Scalar::TWO, Scalar::HALF, Scalar::from_int(3))
    }

    #[test]
    fn grid_is_centred_on_the_origin_with_rows_along_z() {
        // 2 rows × 3 columns, cell 2 × 3: x ∈ {−2, 0, 2}, z ∈ {−1.5, 1.5}.
        let f = HeightField::new(2, 3, ints(&[0, 2, 4, -2, 6, 8]), scale()).unwrap();
        let z = Scalar::from_ratio(3, 2);
        assert_eq!(
            f.vertex(0, 0),
            Some(Vec3::new(-Scalar::TWO, Scalar::ZERO, -z))
        );
        assert_eq!(
            f.vertex(0, 2),
            Some(Vec3::new(Scalar::TWO, Scalar::TWO, -z))
        );
        assert_eq!(
            f.vertex(1, 0),
            Some(Vec3::new(-Scalar::TWO, -Scalar::ONE, z))
        );
        assert_eq!(
            f.vertex(1, 1),
            Some(Vec3::new(Scalar::ZERO, Scalar::from_int(3), z))
        );
        assert_eq!(
            f.vertex(1, 2),
            Some(Vec3::new(Scalar::TWO, Scalar::from_int(4), z))
        );
        assert_eq!(f.vertex(2, 0), None);
        assert_eq!(
            f.local_aabb(),
            Aabb::new(
                Vec3::new(-Scalar::TWO, -Scalar::ONE, -z),
                Vec3::new(Scalar::TWO, Scalar::from_int(4), z)
            )
        );
    }

    #[test]
    fn odd_spacing_rounds_symmetrically() {
        // Spacing of 3 raw units over 2 columns: ±1.5 ulp rounds away from
        // zero on both sides.
        let step = Scalar::from_bits(3);
        let f = HeightField::new(2, 2, ints(&[0; 4]), Vec3::new(step, Scalar::ONE, step)).unwrap();
        let a = f.vertex(0, 0).unwrap();
        let b = f.vertex(1, 1).unwrap();
        assert_eq!((a.x.to_bits(), b.x.to_bits()), (-2, 2));
        assert_eq!(a.z, -b.z);
    }

    #[test]
    fn cell_triangles_face_up() {
        let f = HeightField::new(2, 2, ints(&[0, 0, 0, 0]), scale()).unwrap();
        for tri in f.cell_triangles(0, 0).unwrap() {
            let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
            assert!(n.y.is_positive() && n.x.is_zero() && n.z.is_zero(), "{n:?}");
            assert_eq!(n.y, Scalar::from_int(6));
        }
        assert_eq!(f.cell_triangles(1, 0), None);
    }

    #[test]
    fn height_field_validation_errors_say_what_is_wrong() {
        let e = HeightField::new(1, 5, ints(&[0; 5]), scale()).unwrap_err();
        assert_eq!(e, ShapeError::HeightFieldTooSmall { rows: 1, cols: 5 });
        assert_eq!(
            e.to_string(),
            "height field needs at least 2 rows and 2 columns, got 1×5"
        );
        let e = HeightField::new(3, 3, ints(&[0; 8]), scale()).unwrap_err();
        assert_eq!(e.to_string(), "height field of 3×3 needs 9 heights, got 8");
        let bad = Vec3::new(Scalar::ONE, Scalar::ZERO, Scalar::ONE);
        assert_eq!(
            HeightField::new(2, 2, ints(&[0; 4]), bad),
            Err(ShapeError::HeightFieldScale { scale: bad })
        );
        let wide = Vec3::new(Scalar::from_int(1 << 20), Scalar::ONE, Scalar::ONE);
        assert_eq!(
            HeightField::new(2, 5000, ints(&[0; 10_000]), wide),
            Err(ShapeError::HeightFieldOutOfRange)
        );
        let tall = Vec3::new(Scalar::ONE, Scalar::from_int(1 << 16), Scalar::ONE);
        assert_eq!(
            HeightField::new(2, 2, ints(&[0, 0, 0, 1 << 16]), tall),
            Err(ShapeError::HeightFieldOutOfRange)
        );
    }

    #[test]
    fn height_field_survives_a_serde_round_trip() {
        let f = HeightField::new(2, 3, ints(&[0, 2, 4, -2, 6, 8]), scale()).unwrap();
        let cfg = bincode::config::standard();
        let bytes = bincode::serde::encode_to_vec(&f, cfg).unwrap();
        let (back, _): (HeightField, usize) =
            bincode::serde::decode_from_slice(&bytes, cfg).unwrap();
        assert_eq!(back, f);
    }
}
