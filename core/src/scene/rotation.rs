//! Rotations in scene files: an axis and an angle in degrees, a unit
//! quaternion with its component order in the key, or Euler angles in
//! degrees, converted to a unit [`Quat`] with integer-only math.
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
const ROTATION_KEYS: &[&str] = &[
    "axis",
    "angle_deg",
    "quat_xyzw",
    "quat_wxyz",
    "quaternion",
    "euler_deg",
    "euler_order",
];

/// What a rotation table must look like, for messages.
const ROTATION_FORMS: &str = "a table { axis = [x, y, z], angle_deg = a }, { quat_xyzw = [x, y, z, w] }, \
     { quat_wxyz = [w, x, y, z] } or { euler_deg = [x, y, z] } (optionally with euler_order)";

/// How far a quaternion's squared length may be from 1 and still be read as
/// a unit quaternion (normalised on load): 10⁻⁶, what seven significant
/// digits per component give. As a Q64.64 value, ⌈2⁶⁴/10⁶⌉.
const UNIT_TOLERANCE_Q64: i128 = 18_446_744_073_710;

/// Reads a `rotation` value of table `t` into a unit quaternion.
///
/// The forms: an axis and an angle in degrees; a quaternion with its
/// component order in the key (`quat_xyzw` as glTF, Bevy and Unity write
/// them; `quat_wxyz`, and `quaternion` for the same order, as earlier
/// files do); or Euler angles in degrees about the parent's x, y and z
/// axes, applied in `euler_order` (default `"xyz"`: x first).
///
/// # Errors
/// Unknown keys, two forms at once, a missing half of the axis/angle pair,
/// a zero axis, a zero quaternion, a quaternion whose length is not 1
/// (the message shows the normalised value to write instead), an
/// `euler_order` that is not a permutation of `xyz`.
pub(super) fn read_rotation(t: &TableView<'_>, field: &Field<'_>) -> Result<Quat> {
    let r = t.sub_table(field, ROTATION_FORMS)?;
    r.check_keys(ROTATION_KEYS, "a rotation")?;
    // Exactly one form.
    let mut forms: Vec<_> = ["axis", "quat_xyzw", "quat_wxyz", "quaternion", "euler_deg"]
        .iter()
        .filter_map(|k| r.get(k))
        .collect();
    // Reported at the second one written.
    forms.sort_by_key(|f| f.at);
    if let [first, second, ..] = forms.as_slice() {
        return Err(r.error(
            second.at,
            SceneErrorKind::Conflict,
            format!(
                "{} cannot be combined with {} (give one rotation: axis and angle_deg, a quaternion, or euler_deg)",
                second.name, first.name
            ),
        ));
    }
    for (key, needs) in [("angle_deg", "axis"), ("euler_order", "euler_deg")] {
        if let (Some(f), None) = (r.get(key), r.get(needs)) {
            if forms.is_empty() && key == "angle_deg" {
                break; // reported below as the missing axis
            }
            return Err(r.error(
                f.at,
                SceneErrorKind::Conflict,
                format!("{} goes with {needs} only", f.name),
            ));
        }
    }
    if let Some(q) = r.get("quat_xyzw") {
        let [x, y, z, w] = r.scalars::<4>(&q, "[x, y, z, w]")?;
        return unit_quat(&r, &q, [w, x, y, z], false);
    }
    for key in ["quat_wxyz", "quaternion"] {
        if let Some(q) = r.get(key) {
            let wxyz = r.scalars::<4>(&q, "[w, x, y, z]")?;
            return unit_quat(&r, &q, wxyz, true);
        }
    }
    if let Some(e) = r.get("euler_deg") {
        let [x, y, z] = r.scalars::<3>(&e, "[x, y, z] in degrees")?;
        let order = match r.get("euler_order") {
            Some(f) => {
                let text = r.string(&f)?;
                euler_order(text).ok_or_else(|| {
                    r.error(
                        f.at,
                        SceneErrorKind::OutOfRange,
                        format!(
                            "{} \"{text}\" is not an order of the three axes (expected one of: xyz, xzy, yxz, yzx, zxy, zyx; the first is applied first)",
                            f.name
                        ),
                    )
                })?
            }
            None => [0, 1, 2],
        };
        return Ok(euler_deg([x, y, z], order));
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

/// A quaternion read from the file as `[w, x, y, z]`: refused when zero or
/// when its squared length is further than 10⁻⁶ from 1 (the message gives
/// the normalised value in the key's own order), else normalised.
fn unit_quat(r: &TableView<'_>, q: &Field<'_>, wxyz: [Scalar; 4], w_first: bool) -> Result<Quat> {
    if wxyz.iter().all(|c| c.is_zero()) {
        return Err(r.error(
            q.at,
            SceneErrorKind::ZeroRotation,
            format!("{} must not be zero (expected a unit quaternion)", q.name),
        ));
    }
    let unit = normalize_quat(wxyz);
    // The exact squared length, Q64.64 (a component beyond ±2³⁰ is far from
    // unit anyway: its square alone is caught without overflow by capping).
    let len2: i128 = wxyz
        .iter()
        .map(|c| {
            let b = i128::from(c.to_bits()).clamp(-(1 << 62), 1 << 62);
            b * b
        })
        .fold(0i128, i128::saturating_add);
    if (len2 - (1i128 << 64)).abs() > UNIT_TOLERANCE_Q64 {
        let [w, x, y, z] = [unit.w, unit.x, unit.y, unit.z].map(|c| format!("{:.7}", c.to_f64()));
        let shown = if w_first {
            format!("[{w}, {x}, {y}, {z}]")
        } else {
            format!("[{x}, {y}, {z}, {w}]")
        };
        let length = (len2 as f64 / 2f64.powi(64)).sqrt();
        return Err(r.error(
            q.at,
            SceneErrorKind::OutOfRange,
            format!(
                "{} is not a unit quaternion (its length is {length:.7}); write the normalised {shown}",
                q.name
            ),
        ));
    }
    Ok(unit)
}

/// The axis order of an `euler_order` string: indices 0 (x), 1 (y), 2 (z)
/// in the order they are applied; `None` unless a permutation of `xyz`.
fn euler_order(text: &str) -> Option<[usize; 3]> {
    let b = text.as_bytes();
    if b.len() != 3 {
        return None;
    }
    let mut order = [0usize; 3];
    for (slot, c) in order.iter_mut().zip(b) {
        *slot = match c.to_ascii_lowercase() {
            b'x' => 0,
            b'y' => 1,
            b'z' => 2,
            _ => return None,
        };
    }
    let distinct = order[0] != order[1] && order[1] != order[2] && order[0] != order[2];
    distinct.then_some(order)
}

/// The rotation by `degrees[i]` about the parent's unit axis `i`, applied in
/// `order` (the first index first): `q = q₃ · q₂ · q₁`, normalised.
pub(super) fn euler_deg(degrees: [Scalar; 3], order: [usize; 3]) -> Quat {
    let axes = [Vec3::X, Vec3::Y, Vec3::Z];
    let (q, _faults) = FaultScope::run(|| {
        let mut q = Quat::IDENTITY;
        for i in order {
            q = axis_angle_deg(axes[i], degrees[i]) * q;
        }
        q.normalize()
    });
    q
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
