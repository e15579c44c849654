//! `Mat3` (general 3×3, column-major) and `SymMat3` (symmetric 3×3, the form
//! inertia tensors take).
//!
//! Matrix–vector and matrix–matrix products accumulate each entry exactly in
//! `i128` and round once.

use std::ops::{Add, Mul, Sub};

use serde::{Deserialize, Serialize};

use super::faults::{self, Faults};
use super::quat::Quat;
use super::scalar::{Scalar, div_round_i128, narrow, round_shift, wide_sum};
use super::vec3::Vec3;

/// A 3×3 matrix stored as three columns.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Mat3 {
    /// The columns.
    pub cols: [Vec3; 3],
}

impl Mat3 {
    /// The zero matrix.
    pub const ZERO: Mat3 = Mat3 {
        cols: [Vec3::ZERO; 3],
    };
    /// The identity.
    pub const IDENTITY: Mat3 = Mat3 {
        cols: [Vec3::X, Vec3::Y, Vec3::Z],
    };

    /// A matrix from its columns.
    pub const fn from_cols(c0: Vec3, c1: Vec3, c2: Vec3) -> Mat3 {
        Mat3 { cols: [c0, c1, c2] }
    }

    /// A diagonal matrix.
    pub const fn from_diagonal(d: Vec3) -> Mat3 {
        Mat3::from_cols(
            Vec3::new(d.x, Scalar::ZERO, Scalar::ZERO),
            Vec3::new(Scalar::ZERO, d.y, Scalar::ZERO),
            Vec3::new(Scalar::ZERO, Scalar::ZERO, d.z),
        )
    }

    /// Row `i` as a vector.
    #[inline(always)]
    pub fn row(&self, i: usize) -> Vec3 {
        Vec3::new(
            self.cols[0].get(i),
            self.cols[1].get(i),
            self.cols[2].get(i),
        )
    }

    /// The rotation matrix of a unit quaternion.
    pub fn from_quat(q: Quat) -> Mat3 {
        let (x, y, z, w) = (q.x, q.y, q.z, q.w);
        let two = |a: Scalar, b: Scalar, c: Scalar, d: Scalar| {
            // 2(ab ± cd) with one rounding.
            let sum = wide_sum([a.wide_mul(b), c.wide_mul(d)]);
            Scalar::from_wide(wide_sum([sum, sum]))
        };
        let one_minus = |a: Scalar, b: Scalar| {
            let sum = wide_sum([a.wide_mul(a), b.wide_mul(b)]);
            Scalar::from_wide(wide_sum([1i128 << 64, -sum, -sum]))
        };
        Mat3::from_cols(
            Vec3::new(one_minus(y, z), two(x, y, w, z), two(x, z, -w, y)),
            Vec3::new(two(x, y, -w, z), one_minus(x, z), two(y, z, w, x)),
            Vec3::new(two(x, z, w, y), two(y, z, -w, x), one_minus(x, y)),
        )
    }

    /// The transpose.
    pub fn transpose(&self) -> Mat3 {
        Mat3::from_cols(self.row(0), self.row(1), self.row(2))
    }

    /// The determinant (rounded once per cofactor product).
    pub fn determinant(&self) -> Scalar {
        let [a, b, c] = self.cols;
        a.dot(b.cross(c))
    }

    /// The inverse, or `None` when the matrix is singular (or its inverse
    /// overflows).
    pub fn try_inverse(&self) -> Option<Mat3> {
        let [a, b, c] = self.cols;
        let r0 = b.cross(c);
        let r1 = c.cross(a);
        let r2 = a.cross(b);
        let det = a.dot_wide(r0);
        if det == 0 {
            return None;
        }
        // entry = cofactor / det, with det in Q64.64 and cofactor in Q32.32.
        let div = |v: Scalar| -> Option<Scalar> {
            let q = div_round_i128((v.to_bits() as i128) << 64, det);
            i64::try_from(q).ok().map(Scalar::from_bits)
        };
        let row = |r: Vec3| -> Option<Vec3> { Some(Vec3::new(div(r.x)?, div(r.y)?, div(r.z)?)) };
        Some(Mat3::from_cols(row(r0)?, row(r1)?, row(r2)?).transpose())
    }

    /// The inverse; a singular matrix raises `DIV_BY_ZERO` and gives zero.
    pub fn inverse(&self) -> Mat3 {
        self.try_inverse().unwrap_or_else(|| {
            faults::raise(Faults::DIV_BY_ZERO);
            Mat3::ZERO
        })
    }

    /// `self * v`.
    #[inline]
    pub fn mul_vec(&self, v: Vec3) -> Vec3 {
        let [a, b, c] = self.cols;
        let e = |i: usize| {
            Scalar::from_wide(wide_sum([
                a.get(i).wide_mul(v.x),
                b.get(i).wide_mul(v.y),
                c.get(i).wide_mul(v.z),
            ]))
        };
        Vec3::new(e(0), e(1), e(2))
    }

    /// `selfᵀ * v`.
    #[inline]
    pub fn transpose_mul_vec(&self, v: Vec3) -> Vec3 {
        Vec3::new(
            self.cols[0].dot(v),
            self.cols[1].dot(v),
            self.cols[2].dot(v),
        )
    }

    /// Every entry times `s`.
    pub fn scale(&self, s: Scalar) -> Mat3 {
        Mat3::from_cols(self.cols[0] * s, self.cols[1] * s, self.cols[2] * s)
    }

    /// The skew-symmetric matrix of `v`, so that `skew(v) * u == v × u`.
    pub fn skew(v: Vec3) -> Mat3 {
        let z = Scalar::ZERO;
        Mat3::from_cols(
            Vec3::new(z, v.z, -v.y),
            Vec3::new(-v.z, z, v.x),
            Vec3::new(v.y, -v.x, z),
        )
    }
}

impl Mul for Mat3 {
    type Output = Mat3;
    fn mul(self, o: Mat3) -> Mat3 {
        Mat3::from_cols(
            self.mul_vec(o.cols[0]),
            self.mul_vec(o.cols[1]),
            self.mul_vec(o.cols[2]),
        )
    }
}

impl Mul<Vec3> for Mat3 {
    type Output = Vec3;
    fn mul(self, v: Vec3) -> Vec3 {
        self.mul_vec(v)
    }
}

impl Add for Mat3 {
    type Output = Mat3;
    fn add(self, o: Mat3) -> Mat3 {
        Mat3::from_cols(
            self.cols[0] + o.cols[0],
            self.cols[1] + o.cols[1],
            self.cols[2] + o.cols[2],
        )
    }
}

impl Sub for Mat3 {
    type Output = Mat3;
    fn sub(self, o: Mat3) -> Mat3 {
        Mat3::from_cols(
            self.cols[0] - o.cols[0],
            self.cols[1] - o.cols[1],
            self.cols[2] - o.cols[2],
        )
    }
}

/// A symmetric 3×3 matrix (six numbers), the form of inertia tensors.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct SymMat3 {
    /// Entry (0,0).
    pub xx: Scalar,
    /// Entry (1,1).
    pub yy: Scalar,
    /// Entry (2,2).
    pub zz: Scalar,
    /// Entries (0,1) and (1,0).
    pub xy: Scalar,
    /// Entries (0,2) and (2,0).
    pub xz: Scalar,
    /// Entries (1,2) and (2,1).
    pub yz: Scalar,
}

impl SymMat3 {
    /// The zero matrix.
    pub const ZERO: SymMat3 = SymMat3::from_diagonal(Vec3::ZERO);

    /// A diagonal matrix.
    pub const fn from_diagonal(d: Vec3) -> SymMat3 {
        SymMat3 {
            xx: d.x,
            yy: d.y,
            zz: d.z,
            xy: Scalar::ZERO,
            xz: Scalar::ZERO,
            yz: Scalar::ZERO,
        }
    }

    /// The diagonal.
    pub fn diagonal(&self) -> Vec3 {
        Vec3::new(self.xx, self.yy, self.zz)
    }

    /// The full matrix.
    pub fn to_mat3(&self) -> Mat3 {
        Mat3::from_cols(
            Vec3::new(self.xx, self.xy, self.xz),
            Vec3::new(self.xy, self.yy, self.yz),
            Vec3::new(self.xz, self.yz, self.zz),
        )
    }

    /// The symmetric part of a general matrix, `(m + mᵀ)/2`.
    pub fn from_mat3_symmetric_part(m: &Mat3) -> SymMat3 {
        let avg = |a: Scalar, b: Scalar| {
            Scalar::from_bits(narrow(
                (a.to_bits() as i128 + b.to_bits() as i128 + 1
                    - ((a.to_bits() as i128 + b.to_bits() as i128) < 0) as i128)
                    >> 1,
            ))
        };
        SymMat3 {
            xx: m.cols[0].x,
            yy: m.cols[1].y,
            zz: m.cols[2].z,
            xy: avg(m.cols[0].y, m.cols[1].x),
            xz: avg(m.cols[0].z, m.cols[2].x),
            yz: avg(m.cols[1].z, m.cols[2].y),
        }
    }

    /// `self * v`, each entry rounded once.
    #[inline]
    pub fn mul_vec(&self, v: Vec3) -> Vec3 {
        Vec3::new(
            Scalar::from_wide(wide_sum([
                self.xx.wide_mul(v.x),
                self.xy.wide_mul(v.y),
                self.xz.wide_mul(v.z),
            ])),
            Scalar::from_wide(wide_sum([
                self.xy.wide_mul(v.x),
                self.yy.wide_mul(v.y),
                self.yz.wide_mul(v.z),
            ])),
            Scalar::from_wide(wide_sum([
                self.xz.wide_mul(v.x),
                self.yz.wide_mul(v.y),
                self.zz.wide_mul(v.z),
            ])),
        )
    }

    /// Every entry times `s`.
    pub fn scale(&self, s: Scalar) -> SymMat3 {
        SymMat3 {
            xx: self.xx * s,
            yy: self.yy * s,
            zz: self.zz * s,
            xy: self.xy * s,
            xz: self.xz * s,
            yz: self.yz * s,
        }
    }

    /// The determinant as an exact-ish Q32.32 (each cofactor rounded once).
    pub fn determinant(&self) -> Scalar {
        self.to_mat3().determinant()
    }

    /// The inverse, or `None` when singular or when it would overflow.
    pub fn try_inverse(&self) -> Option<SymMat3> {
        self.to_mat3()
            .try_inverse()
            .map(|m| SymMat3::from_mat3_symmetric_part(&m))
    }

    /// The inverse with one division: the adjugate times a 64-bit reciprocal
    /// of the determinant. Each entry is within an ulp of the correctly
    /// rounded `cofactor / det` that [`try_inverse`](Self::try_inverse) gives
    /// at nine divisions' cost. `None` when the determinant is zero (or
    /// within a few Q64.64 ulps of it) or an entry does not fit.
    pub fn try_inverse_fast(&self) -> Option<SymMat3> {
        let m = Scalar::mul_sub2;
        let (xx, yy, zz, xy, xz, yz) = (self.xx, self.yy, self.zz, self.xy, self.xz, self.yz);
        let a = m(yy, zz, yz, yz);
        let b = m(xz, yz, xy, zz);
        let c = m(xy, yz, xz, yy);
        let d = m(xx, zz, xz, xz);
        let e = m(xy, xz, xx, yz);
        let f = m(xx, yy, xy, xy);
        let det = wide_sum([xx.wide_mul(a), xy.wide_mul(b), xz.wide_mul(c)]);
        let mag = det.unsigned_abs();
        let bits = 128 - mag.leading_zeros();
        if bits <= 2 {
            return None;
        }
        // det ≈ n · 2^(bits − 64) with n in [2^63, 2^64) (the low bits cut
        // off cost less than 2^−63 relatively); r = ⌊2^126 / n⌋ in
        // (2^62, 2^63]. An entry's bits are cof · 2^64 / det
        // = cof · r / 2^(bits − 2).
        let n = if bits > 64 {
            mag >> (bits - 64)
        } else {
            mag << (64 - bits)
        };
        // r fits 64 bits: as a `u64` each entry below is one 64×64-bit
        // multiply, not a full 128-bit one.
        let r = ((1u128 << 126) / n) as u64;
        let shift = bits - 2;
        let negative = det < 0;
        let entry = |cof: Scalar| -> Option<Scalar> {
            let q = round_shift(cof.to_bits() as i128 * r as i128, shift);
            let q = if negative { -q } else { q };
            i64::try_from(q).ok().map(Scalar::from_bits)
        };
        Some(SymMat3 {
            xx: entry(a)?,
            yy: entry(d)?,
            zz: entry(f)?,
            xy: entry(b)?,
            xz: entry(c)?,
            yz: entry(e)?,
        })
    }

    /// `[r]ₓ S [r]ₓᵀ` (`[r]ₓ` the cross-product matrix of `r`): the
    /// angular part of the effective mass of a point at arm `r` on a body
    /// with inverse inertia `S`. Entry `(j, k)` is `cⱼ · S cₖ` with
    /// `cⱼ = r × eⱼ`; 30 products, each entry rounded twice.
    pub fn skew_sandwich(&self, r: Vec3) -> SymMat3 {
        let m = Scalar::mul_sub2;
        let (xx, yy, zz, xy, xz, yz) = (self.xx, self.yy, self.zz, self.xy, self.xz, self.yz);
        // S cₓ with cₓ = (0, r.z, −r.y), and so on.
        let ux = Vec3::new(
            m(xy, r.z, xz, r.y),
            m(yy, r.z, yz, r.y),
            m(yz, r.z, zz, r.y),
        );
        let uy = Vec3::new(
            m(xz, r.x, xx, r.z),
            m(yz, r.x, xy, r.z),
            m(zz, r.x, xz, r.z),
        );
        let uz = Vec3::new(
            m(xx, r.y, xy, r.x),
            m(xy, r.y, yy, r.x),
            m(xz, r.y, yz, r.x),
        );
        SymMat3 {
            xx: m(r.z, ux.y, r.y, ux.z),
            yy: m(r.x, uy.z, r.z, uy.x),
            zz: m(r.y, uz.x, r.x, uz.y),
            xy: m(r.z, uy.y, r.y, uy.z),
            xz: m(r.z, uz.y, r.y, uz.z),
            yz: m(r.x, uz.z, r.z, uz.x),
        }
    }

    /// [`skew_sandwich`](Self::skew_sandwich) of `s` times the identity, with
    /// the same bits in 9 products: `s (|r|² 1 − r rᵀ)`.
    pub fn skew_sandwich_scalar(s: Scalar, r: Vec3) -> SymMat3 {
        let (sx, sy, sz) = (s * r.x, s * r.y, s * r.z);
        SymMat3 {
            xx: Scalar::mul_add2(r.z, sz, r.y, sy),
            yy: Scalar::mul_add2(r.x, sx, r.z, sz),
            zz: Scalar::mul_add2(r.y, sy, r.x, sx),
            xy: -(r.y * sx),
            xz: -(r.z * sx),
            yz: -(r.z * sy),
        }
    }

    /// `R S Rᵀ` for a rotation `R`: the tensor expressed in the rotated frame
    /// (body inertia to world inertia).
    pub fn rotate(&self, r: &Mat3) -> SymMat3 {
        let rs = *r * self.to_mat3();
        SymMat3::from_mat3_symmetric_part(&(rs * r.transpose()))
    }

    /// The inertia tensor of a point mass `m` at offset `d` from the
    /// reference point: `m (|d|² 1 − d dᵀ)` (the parallel-axis term).
    pub fn point_mass_inertia(m: Scalar, d: Vec3) -> SymMat3 {
        let xx = d.x.wide_mul(d.x);
        let yy = d.y.wide_mul(d.y);
        let zz = d.z.wide_mul(d.z);
        let mm = |v: i128| Scalar::from_wide(v) * m;
        SymMat3 {
            xx: mm(wide_sum([yy, zz])),
            yy: mm(wide_sum([xx, zz])),
            zz: mm(wide_sum([xx, yy])),
            xy: -mm(d.x.wide_mul(d.y)),
            xz: -mm(d.x.wide_mul(d.z)),
            yz: -mm(d.y.wide_mul(d.z)),
        }
    }
}

impl Add for SymMat3 {
    type Output = SymMat3;
    fn add(self, o: SymMat3) -> SymMat3 {
        SymMat3 {
            xx: self.xx + o.xx,
            yy: self.yy + o.yy,
            zz: self.zz + o.zz,
            xy: self.xy + o.xy,
            xz: self.xz + o.xz,
            yz: self.yz + o.yz,
        }
    }
}

impl Sub for SymMat3 {
    type Output = SymMat3;
    fn sub(self, o: SymMat3) -> SymMat3 {
        SymMat3 {
            xx: self.xx - o.xx,
            yy: self.yy - o.yy,
            zz: self.zz - o.zz,
            xy: self.xy - o.xy,
            xz: self.xz - o.xz,
            yz: self.yz - o.yz,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{Rng, s};

    fn close(a: &Mat3, b: &Mat3, ulps: i64) -> bool {
        (0..3).all(|c| (a.cols[c] - b.cols[c]).abs().max_element() <= Scalar::from_bits(ulps))
    }

    #[test]
    fn rotation_matrix_agrees_with_quaternion_rotation() {
        let q = Quat::from_axis_angle(Vec3::new(s(0.48), s(0.6), s(0.64)), s(2.1));
        let m = Mat3::from_quat(q);
        let v = Vec3::new(s(3.0), s(-1.25), s(0.5));
        assert!((m * v - q.rotate(v)).abs().max_element() <= Scalar::from_bits(16));
        assert!(close(&(m * m.transpose()), &Mat3::IDENTITY, 16));
    }

    #[test]
    fn fast_symmetric_inverse_is_within_an_ulp_of_the_exact_one() {
        let mut st = Rng::new(7);
        let mut checked = 0;
        for case in 0..2000 {
            // Scales from 1e-4 to 1e3, as effective masses of joints span.
            let scale = 10f64.powf(-4.0 + 7.0 * st.unit());
            let mut e = || s((st.unit() - 0.5) * scale);
            let (xy, xz, yz) = (e(), e(), e());
            // Diagonally dominant (positive definite) for most cases, and
            // indefinite for every fifth.
            let dom = |off: Scalar, st: &mut Rng| {
                let extra = s(st.unit() * scale);
                if case % 5 == 0 {
                    -extra
                } else {
                    off.abs() * Scalar::TWO + extra
                }
            };
            let m = SymMat3 {
                xx: dom(xy + xz, &mut st),
                yy: dom(xy + yz, &mut st),
                zz: dom(xz + yz, &mut st),
                xy,
                xz,
                yz,
            };
            let exact = m.to_mat3().try_inverse();
            let fast = m.try_inverse_fast();
            match (exact, fast) {
                (Some(x), Some(f)) => {
                    assert!(close(&x, &f.to_mat3(), 1), "case {case}: {x:?} vs {f:?}");
                    checked += 1;
                }
                (None, None) => {}
                (x, f) => {
                    // Only at the edge of what fits may the two disagree.
                    let big = |v: &Mat3| {
                        (0..3).any(|c| v.cols[c].abs().max_element() > Scalar::from_int(1 << 30))
                    };
                    assert!(x.is_none_or(|x| big(&x)) && f.is_none_or(|f| big(&f.to_mat3())));
                }
            }
        }
        assert!(checked > 1900);
        assert_eq!(SymMat3::ZERO.try_inverse_fast(), None);
        let singular = SymMat3 {
            xx: s(1.0),
            yy: s(1.0),
            zz: s(2.0),
            xy: s(1.0),
            xz: s(1.0),
            yz: s(1.0),
        };
        assert_eq!(singular.try_inverse_fast(), None);
    }

    #[test]
    fn skew_sandwich_matches_the_matrix_product() {
        let mut st = Rng::new(11);
        for _ in 0..500 {
            let mut e = || s((st.unit() - 0.5) * 4.0);
            let sym = SymMat3 {
                xx: e(),
                yy: e(),
                zz: e(),
                xy: e(),
                xz: e(),
                yz: e(),
            };
            let r = Vec3::new(e(), e(), e());
            let skew = Mat3::from_cols(
                Vec3::new(Scalar::ZERO, r.z, -r.y),
                Vec3::new(-r.z, Scalar::ZERO, r.x),
                Vec3::new(r.y, -r.x, Scalar::ZERO),
            );
            let product = skew * sym.to_mat3() * skew.transpose();
            assert!(close(&product, &sym.skew_sandwich(r).to_mat3(), 8));
        }
    }

    #[test]
    fn scalar_skew_sandwich_has_the_general_bits() {
        let mut st = Rng::new(13);
        for _ in 0..2000 {
            let mut e = || Scalar::from_bits((st.unit() * 2f64.powi(40)) as i64 - (1 << 39));
            let k = e().abs();
            let r = Vec3::new(e(), e(), e());
            let general = SymMat3::from_diagonal(Vec3::new(k, k, k)).skew_sandwich(r);
            assert_eq!(SymMat3::skew_sandwich_scalar(k, r), general);
        }
    }

    #[test]
    fn inverse_times_matrix_is_identity() {
        let m = Mat3::from_cols(
            Vec3::new(s(2.0), s(0.5), s(-1.0)),
            Vec3::new(s(0.25), s(3.0), s(0.75)),
            Vec3::new(s(-1.5), s(0.1), s(4.0)),
        );
        let inv = m.try_inverse().unwrap();
        assert!(close(&(m * inv), &Mat3::IDENTITY, 16));
        assert_eq!(Mat3::ZERO.try_inverse(), None);
        let sym = SymMat3 {
            xx: s(2.0),
            yy: s(3.0),
            zz: s(4.0),
            xy: s(0.5),
            xz: s(-0.25),
            yz: s(0.1),
        };
        let si = sym.try_inverse().unwrap();
        assert!(close(&(sym.to_mat3() * si.to_mat3()), &Mat3::IDENTITY, 16));
    }

    #[test]
    fn rotating_a_tensor_preserves_its_trace() {
        let i = SymMat3::from_diagonal(Vec3::new(s(1.0), s(2.0), s(5.0)));
        let r = Mat3::from_quat(Quat::from_axis_angle(
            Vec3::new(s(0.0), s(0.6), s(0.8)),
            s(0.9),
        ));
        let w = i.rotate(&r);
        let trace = w.xx + w.yy + w.zz;
        assert!((trace - s(8.0)).abs() <= Scalar::from_bits(16));
    }
}
