//! `HeightField`: a static terrain grid of heights.

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use super::error::ShapeError;
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

    /// Number of triangles: two per cell, numbered
    /// `2 · (row · (cols − 1) + col) + k` with `k` as in
    /// [`cell_triangles`](Self::cell_triangles). The narrow phase visits
    /// triangles in this order.
    pub fn triangle_count(&self) -> u64 {
        2 * (self.rows as u64 - 1) * (self.cols as u64 - 1)
    }

    /// Triangle `index` (numbered as in
    /// [`triangle_count`](Self::triangle_count)), or `None` past the end.
    pub fn triangle(&self, index: u64) -> Option<[Vec3; 3]> {
        let cell = index / 2;
        let w = self.cols as u64 - 1;
        let (row, col) = (cell / w, cell % w);
        let row = u32::try_from(row).ok()?;
        let tris = self.cell_triangles(row, col as u32)?;
        Some(tris[(index % 2) as usize])
    }

    /// The cells whose footprint overlaps `aabb` in x and z:
    /// `(rows, cols)` as inclusive ranges `([row_lo, row_hi], [col_lo,
    /// col_hi])`, clamped to the grid, or `None` when the box misses the
    /// grid (in x, z, or in y against the height range). Computed in
    /// integers from the box's corners, so a box of any size costs the same;
    /// one raw unit of slack covers the grid coordinates' rounding.
    pub fn cell_range(&self, aabb: &Aabb) -> Option<([u32; 2], [u32; 2])> {
        let b = self.local_aabb;
        if aabb.max.y < b.min.y || aabb.min.y > b.max.y {
            return None;
        }
        let cols = self.cell_span(aabb.min.x, aabb.max.x, self.cols, self.scale.x)?;
        let rows = self.cell_span(aabb.min.z, aabb.max.z, self.rows, self.scale.z)?;
        Some((rows, cols))
    }

    /// The inclusive range of cells (of `n − 1`, spacing `step`) overlapped
    /// by `[lo, hi]` on one axis.
    fn cell_span(&self, lo: Scalar, hi: Scalar, n: u32, step: Scalar) -> Option<[u32; 2]> {
        let s2 = 2 * step.to_bits() as i128;
        let shift = (n as i128 - 1) * step.to_bits() as i128;
        // Cell index c has its left sample at (2c − (n − 1))·step/2.
        let cell =
            |x: Scalar, slack: i128| (2 * (x.to_bits() as i128 + slack) + shift).div_euclid(s2);
        let first = cell(lo, -1);
        let last = cell(hi, 1);
        let top = n as i128 - 2;
        if last < 0 || first > top {
            return None;
        }
        Some([first.max(0) as u32, last.min(top) as u32])
    }

    /// Whether edge `k` (corner `k` to corner `(k + 1) % 3`) of triangle
    /// `index` is a convex crease a body can hit; computed on the fly from
    /// the neighbouring triangle in the grid with the same rule as
    /// [`TriMesh::edge_active`](super::trimesh::TriMesh::edge_active). Edges on the
    /// grid's border are active. `false` past the end.
    pub fn edge_active(&self, index: u64, k: usize) -> bool {
        if index >= self.triangle_count() || k > 2 {
            return false;
        }
        let cell = index / 2;
        let w = self.cols as u64 - 1;
        let (r, c) = ((cell / w) as i64, (cell % w) as i64);
        // The neighbour across edge k, as (row, col, k') of its cell, and
        // the neighbour's vertex off the shared edge as a grid sample.
        let (nb, far): ((i64, i64, u64), (i64, i64)) = match (index % 2, k) {
            (0, 0) => ((r, c, 1), (r + 1, c)),
            (0, 1) => ((r, c + 1, 1), (r + 1, c + 2)),
            (0, _) => ((r - 1, c, 1), (r - 1, c)),
            (_, 0) => ((r, c - 1, 0), (r, c - 1)),
            (_, 1) => ((r + 1, c, 0), (r + 2, c + 1)),
            (_, _) => ((r, c, 0), (r, c + 1)),
        };
        let inside = |row: i64, col: i64, rows: u32, cols: u32| {
            row >= 0 && col >= 0 && row < rows as i64 && col < cols as i64
        };
        if !inside(nb.0, nb.1, self.rows - 1, self.cols - 1) {
            return true;
        }
        let (Some(tri), Some(nbt), Some(w)) = (
            self.triangle(index),
            self.cell_triangles(nb.0 as u32, nb.1 as u32),
            self.vertex(far.0 as u32, far.1 as u32),
        ) else {
            return true;
        };
        let nbt = nbt[nb.2 as usize];
        match (
            super::trimesh::TriMesh::triangle_normal(tri[0], tri[1], tri[2]),
            super::trimesh::TriMesh::triangle_normal(nbt[0], nbt[1], nbt[2]),
        ) {
            (Some(n1), Some(n2)) => super::trimesh::TriMesh::crease_is_active(n1, n2, tri[k], w),
            _ => true,
        }
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
