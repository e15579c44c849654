//! Rotations in scene files: an axis and an angle in degrees, or a
//! quaternion, converted to a unit [`Quat`] with integer-only math.
//!
//! Degrees are what people write, and decimal degrees such as `30` or
//! `22.5` are exact in the file; the conversion to radians happens here,
//! once, with a 62-fraction-bit π so that the radians are the Q32.32 value
//! nearest to the true angle. The result is the same bits on every machine.

use super::error::SceneErrorKind;
use super::reader::{Field, Result, TableView};
use crate::math::scalar::div_round_i128;
use crate::math::{FaultScope, Quat, Scalar, Vec3};

/// π × 2⁶², rounded to nearest (π = 3.14159265358979323846264338327950288…).
const PI_Q62: i128 = 14_488_038_916_154_245_685;

/// Keys of a rotation table.
const ROTATION_KEYS: &[&str] = &["axis", "angle_deg", "quaternion"];

/// What a rotation table must look like, for messages.
const ROTATION_FORMS: &str =
    "a table { axis = [x, y, z], angle_deg = a } or { quaternion = [w, x, y, z] }";

/// Reads a `rotation` value of table `t` into a unit quaternion.
///
/// # Errors
/// Unknown keys, `quaternion` together with `axis`/`angle_deg`, a missing
/// half of the axis/angle pair, a zero axis or a zero quaternion.
pub(super) fn read_rotation(t: &TableView<'_>, field: &Field<'_>) -> Result<Quat> {
    let r = t.sub_table(field, ROTATION_FORMS)?;
    r.check_keys(ROTATION_KEYS, "a rotation")?;
    if let Some(q) = r.get("quaternion") {
        for other in ["axis", "angle_deg"] {
            if let Some(f) = r.get(other) {
                return Err(r.error(
                    f.at,
                    SceneErrorKind::Conflict,
                    format!(
                        "{} cannot be combined with {} (give either axis and angle_deg, or quaternion)",
                        f.name, q.name
                    ),
                ));
            }
        }
        let [w, x, y, z] = r.scalars::<4>(&q, "[w, x, y, z]")?;
        if [w, x, y, z].iter().all(|c| c.is_zero()) {
            return Err(r.error(
                q.at,
                SceneErrorKind::ZeroRotation,
                format!(
                    "{} must not be zero (expected a non-zero [w, x, y, z]; it is normalised on load)",
                    q.name
                ),
            ));
        }
        return Ok(normalize_quat([w, x, y, z]));
    }
    let axis_field = r.require("axis", "a non-zero [x, y, z] direction")?;
    let angle_field = r.require("angle_deg", "a number of degrees")?;
    let axis = r.vec3(&axis_field)?;
    let degrees = r.scalar(&angle_field)?;
    let Some(unit) = prescale_vec3(axis).try_normalize() else {
        return Err(r.error(
            axis_field.at,
            SceneErrorKind::ZeroRotation,
            format!(
                "{} must not be the zero vector (expected a direction [x, y, z])",
                axis_field.name
            ),
        ));
    };
    Ok(axis_angle_deg(unit, degrees))
}

/// The unit quaternion of the rotation by `degrees` about the unit vector
/// `axis`: degrees are reduced exactly to (−180, 180], converted to radians
/// with one rounding, and the result renormalised.
pub(super) fn axis_angle_deg(axis: Vec3, degrees: Scalar) -> Quat {
    let (q, _faults) = FaultScope::run(|| {
        let radians = degrees_to_radians(degrees);
        Quat::from_axis_angle(axis, radians).normalize()
    });
    q
}

/// `degrees · π / 180`, the nearest Q32.32 value to the exact product,
/// after reducing the angle exactly into (−180°, 180°].
pub(super) fn degrees_to_radians(degrees: Scalar) -> Scalar {
    let full_turn: i128 = 360i128 << 32;
    let half_turn: i128 = 180i128 << 32;
    let mut d = i128::from(degrees.to_bits()).rem_euclid(full_turn);
    if d > half_turn {
        d -= full_turn;
    }
    // |d| ≤ 180·2³² < 2⁴⁰ and PI_Q62 < 2⁶⁴: the product fits in an i128.
    let bits = div_round_i128(d * PI_Q62, 180i128 << 62);
    // |bits| ≤ π·2³² < 2³⁴: always fits.
    Scalar::from_bits(bits as i64)
}

/// A quaternion `[w, x, y, z]` scaled to unit length. Huge components are
/// first halved together (which does not change the direction) so that the
/// exact sum of squares fits the 128-bit accumulator.
fn normalize_quat(wxyz: [Scalar; 4]) -> Quat {
    let mut c = wxyz.map(|s| s.to_bits());
    while c.iter().any(|b| b.unsigned_abs() >= 1 << 60) {
        c = c.map(|b| b >> 1);
    }
    let [w, x, y, z] = c.map(Scalar::from_bits);
    let (q, _faults) = FaultScope::run(|| Quat::from_xyzw(x, y, z, w).normalize());
    q
}

/// `v` halved as often as needed for its exact squared length to be well
/// inside the 128-bit range (direction unchanged).
pub(super) fn prescale_vec3(v: Vec3) -> Vec3 {
    let mut c = v.to_array().map(|s| s.to_bits());
    while c.iter().any(|b| b.unsigned_abs() >= 1 << 60) {
        c = c.map(|b| b >> 1);
    }
    let [x, y, z] = c.map(Scalar::from_bits);
    Vec3::new(x, y, z)
}
