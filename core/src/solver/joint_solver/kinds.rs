//! The rows of each joint kind (point, lock, hinge, slide, cone, distance),
//! and the soft, limit and motor impulses they share.

use crate::joint::Motor;
use crate::math::elem::atan2;
use crate::math::{Quat, Scalar, Vec3};

use crate::solver::contact_solver::Softness;

use super::rows::{
    Geometry, JointParams, LIMIT_REACH, Posed, RIGID, Row, Vels, apply_angular, apply_linear,
    apply_point, arms, linear_row,
};

/// `k` of an angular row about `j`.
pub(super) fn angular_mass(row: &Row, j: Vec3) -> Scalar {
    j.dot(row.a.inv_i(j)) + j.dot(row.b.inv_i(j))
}

/// The impulse of a soft equality row: `−(Ċ + b·C)·s/k − i·λ`.
pub(super) fn soft_impulse(
    k: Scalar,
    cdot: Scalar,
    c: Scalar,
    acc: Scalar,
    soft: &Softness,
) -> Scalar {
    let Some(m) = Scalar::ONE.checked_div(k) else {
        return Scalar::ZERO;
    };
    -(m * soft.mass_scale * (cdot + soft.bias_rate * c)) - soft.impulse_scale * acc
}

/// One side of a limit: `c ≥ 0` is allowed, the row's impulse pushes
/// along its direction only (accumulated ≥ 0). Apart, it is speculative:
/// the approach that closes the gap within the substep is allowed.
pub(super) fn limit_impulse(
    k: Scalar,
    cdot: Scalar,
    c: Scalar,
    acc: &mut Scalar,
    params: &JointParams,
    use_bias: bool,
) -> Scalar {
    if c > LIMIT_REACH {
        // Far from the limit: the row is idle (and its bias would not fit).
        let d = -*acc;
        *acc = Scalar::ZERO;
        return d;
    }
    let soft = if c.is_positive() {
        Softness::rigid(params.inv_h)
    } else if use_bias {
        params.softness
    } else {
        RIGID
    };
    let imp = soft_impulse(k, cdot, c, *acc, &soft);
    let new = (*acc + imp).max(Scalar::ZERO);
    let d = new - *acc;
    *acc = new;
    d
}

/// A one-sided angular row about `j` with position `c` (≥ 0 allowed).
pub(super) fn angular_limit(
    row: &Row,
    vel: &mut Vels,
    j: Vec3,
    c: Scalar,
    acc: &mut Scalar,
    params: &JointParams,
    use_bias: bool,
) {
    let k = angular_mass(row, j);
    let cdot = (vel.wb - vel.wa).dot(j);
    let d = limit_impulse(k, cdot, c, acc, params, use_bias);
    apply_angular(row, vel, j * d);
}

/// A one-sided linear row along `u` with position `c` (≥ 0 allowed).
#[allow(clippy::too_many_arguments)]
pub(super) fn linear_limit(
    row: &Row,
    g: &Geometry,
    vel: &mut Vels,
    u: Vec3,
    c: Scalar,
    acc: &mut Scalar,
    params: &JointParams,
    use_bias: bool,
) {
    let (k, cdot) = linear_row(row, g, vel, u);
    let d = limit_impulse(k, cdot, c, acc, params, use_bias);
    apply_linear(row, g, vel, u, d);
}

/// A motor's impulse on a row with rate `cdot` and position `x`, clamped so
/// the accumulated impulse stays within the largest force over the substep.
pub(super) fn motor_impulse(
    m: Motor,
    cdot: Scalar,
    x: Scalar,
    k: Scalar,
    acc: &mut Scalar,
    params: &JointParams,
    use_bias: bool,
) -> Scalar {
    let imp = match m {
        Motor::Speed { speed, .. } => soft_impulse(k, cdot - speed, Scalar::ZERO, *acc, &RIGID),
        Motor::Position { target, .. } => {
            let soft = if use_bias { params.softness } else { RIGID };
            soft_impulse(k, cdot, x - target, *acc, &soft)
        }
    };
    let max = m.max_force().abs() * params.h;
    let new = (*acc + imp).clamp(-max, max);
    let d = new - *acc;
    *acc = new;
    d
}

/// The anchor block: three rows that bring the anchors together.
pub(super) fn solve_point(
    row: &Row,
    posed: &Posed,
    vel: &mut Vels,
    acc: &mut Vec3,
    soft: &Softness,
) {
    let Some(inv) = posed.point_inv else {
        return;
    };
    let g = &posed.g;
    let cdot = vel.vb + vel.wb.cross(g.rb) - vel.va - vel.wa.cross(g.ra);
    let p = if soft.is_rigid() {
        // The same bits as the general form (`x · 1 = x`, `λ · 0 = 0`),
        // without its nine products.
        -inv.mul_vec(cdot)
    } else {
        let rhs = cdot + g.d * soft.bias_rate;
        -(inv.mul_vec(rhs) * soft.mass_scale) - *acc * soft.impulse_scale
    };
    *acc += p;
    apply_point(row, g, vel, p);
}

/// The rotation lock: three rows that bring B's frame onto A's.
pub(super) fn solve_lock(row: &Row, g: &Geometry, vel: &mut Vels, acc: &mut Vec3, soft: &Softness) {
    let k = row.a.inv_inertia + row.b.inv_inertia;
    let Some(inv) = k.try_inverse() else {
        return;
    };
    // The small rotation taking A's frame to B's, as a rotation vector.
    let e = (g.fb * g.fa.conjugate()).canonical().xyz() * Scalar::TWO;
    let cdot = vel.wb - vel.wa;
    let p = -(inv.mul_vec(cdot + e * soft.bias_rate) * soft.mass_scale) - *acc * soft.impulse_scale;
    *acc += p;
    apply_angular(row, vel, p);
}

/// The two angular rows of a hinge, about `hB × p` and `hB × q` (`p`, `q`
/// across A's axis): they keep B's axis on A's.
pub(super) fn hinge_axes(g: &Geometry) -> (Vec3, Vec3) {
    let hb = g.fb.rotate(Vec3::X);
    (
        hb.cross(g.fa.rotate(Vec3::Y)),
        hb.cross(g.fa.rotate(Vec3::Z)),
    )
}

pub(super) fn solve_hinge(
    row: &Row,
    g: &Geometry,
    vel: &mut Vels,
    acc: &mut Vec3,
    soft: &Softness,
) {
    let hb = g.fb.rotate(Vec3::X);
    let (p, q) = (g.fa.rotate(Vec3::Y), g.fa.rotate(Vec3::Z));
    let (j1, j2) = (hb.cross(p), hb.cross(q));
    let i = |v: Vec3| row.a.inv_i(v) + row.b.inv_i(v);
    let (i1, i2) = (i(j1), i(j2));
    let (k11, k12, k22) = (j1.dot(i1), j1.dot(i2), j2.dot(i2));
    let det = k11 * k22 - k12 * k12;
    if !det.is_positive() {
        return;
    }
    let w = vel.wb - vel.wa;
    let r1 = w.dot(j1) + soft.bias_rate * p.dot(hb);
    let r2 = w.dot(j2) + soft.bias_rate * q.dot(hb);
    let Some((l1, l2)) = block2([k11, k12, k22], det, [r1, r2], acc, soft) else {
        return;
    };
    apply_angular(row, vel, j1 * l1 + j2 * l2);
}

/// The impulses of a soft 2×2 block with `K = [[k11, k12], [k12, k22]]`
/// (determinant `det` > 0) and right-hand side `r = Ċ + b·C`: `K⁻¹r` by
/// Cramer's rule, scaled, minus the relaxed accumulated impulses (`acc.x`,
/// `acc.y`), which take the result.
pub(super) fn block2(
    [k11, k12, k22]: [Scalar; 3],
    det: Scalar,
    [r1, r2]: [Scalar; 2],
    acc: &mut Vec3,
    soft: &Softness,
) -> Option<(Scalar, Scalar)> {
    let x1 = (k22 * r1 - k12 * r2).checked_div(det)?;
    let x2 = (k11 * r2 - k12 * r1).checked_div(det)?;
    let l1 = -(x1 * soft.mass_scale) - acc.x * soft.impulse_scale;
    let l2 = -(x2 * soft.mass_scale) - acc.y * soft.impulse_scale;
    acc.x += l1;
    acc.y += l2;
    Some((l1, l2))
}

/// The two linear rows of a slider, across A's axis: they keep B's anchor
/// on A's axis.
pub(super) fn solve_slide(
    row: &Row,
    g: &Geometry,
    vel: &mut Vels,
    acc: &mut Vec3,
    soft: &Softness,
) {
    let (p, q) = (g.fa.rotate(Vec3::Y), g.fa.rotate(Vec3::Z));
    let (pa, pb) = arms(g, p);
    let (qa, qb) = (arms(g, q).0, arms(g, q).1);
    let ms = row.a.inv_mass + row.b.inv_mass;
    let ia = |v: Vec3| row.a.inv_i(v);
    let ib = |v: Vec3| row.b.inv_i(v);
    let k11 = ms + pa.dot(ia(pa)) + pb.dot(ib(pb));
    let k22 = ms + qa.dot(ia(qa)) + qb.dot(ib(qb));
    let k12 = pa.dot(ia(qa)) + pb.dot(ib(qb));
    let det = k11 * k22 - k12 * k12;
    if !det.is_positive() {
        return;
    }
    let dv = vel.vb - vel.va;
    let r1 = p.dot(dv) + pb.dot(vel.wb) - pa.dot(vel.wa) + soft.bias_rate * p.dot(g.d);
    let r2 = q.dot(dv) + qb.dot(vel.wb) - qa.dot(vel.wa) + soft.bias_rate * q.dot(g.d);
    let Some((l1, l2)) = block2([k11, k12, k22], det, [r1, r2], acc, soft) else {
        return;
    };
    apply_linear(row, g, vel, p, l1);
    apply_linear(row, g, vel, q, l2);
}

/// The twist axis: the mean of the two x axes.
pub(super) fn twist_axis(g: &Geometry) -> Vec3 {
    let t = g.fa.rotate(Vec3::X) + g.fb.rotate(Vec3::X);
    t.try_normalize().unwrap_or_else(|| g.fa.rotate(Vec3::X))
}

/// The angle of B's frame about A's x axis: the twist of the swing–twist
/// split of B's frame relative to A's, in (−π, π].
pub(super) fn twist_angle(g: &Geometry) -> Scalar {
    twist_between(g.fa, g.fb)
}

/// `angle` (in (−π, π]) moved by a whole turn, if need be, to within half a
/// turn of the middle of `[lo, hi]`. A limited angle is then always judged
/// against the nearer end of its range: a knee limited to [0°, 140°] that a
/// hit bends to 185° is 45° past its upper limit, not 175° short of its
/// lower one (which would drive it on round the wrong way, turn after turn).
/// The cut is at the middle of the range's complement, the farthest point
/// from both limits.
pub(crate) fn angle_near(angle: Scalar, lo: Scalar, hi: Scalar) -> Scalar {
    let mid = lo + (hi - lo).half();
    let offset = angle - mid;
    if offset > Scalar::PI {
        angle - Scalar::TAU
    } else if offset <= -Scalar::PI {
        angle + Scalar::TAU
    } else {
        angle
    }
}

/// The twist about A's x axis of frame `fb` relative to frame `fa` (world
/// rotations), in (−π, π].
pub(crate) fn twist_between(fa: Quat, fb: Quat) -> Scalar {
    let mut rel = fa.conjugate() * fb;
    if rel.w.is_negative() {
        rel = Quat::from_xyzw(-rel.x, -rel.y, -rel.z, -rel.w);
    }
    atan2(rel.x, rel.w) * Scalar::TWO
}

/// The swing axis (unit, `x_A × x_B`) and the swing angle between the two x
/// axes; `None` when they are (nearly) aligned.
pub(super) fn cone_axis(g: &Geometry) -> Option<(Vec3, Scalar)> {
    let (ta, tb) = (g.fa.rotate(Vec3::X), g.fb.rotate(Vec3::X));
    let (n, s) = ta.cross(tb).normalize_and_length()?;
    Some((n, atan2(s, ta.dot(tb))))
}

pub(super) fn solve_cone(
    row: &Row,
    g: &Geometry,
    vel: &mut Vels,
    cone: Scalar,
    acc: &mut Scalar,
    params: &JointParams,
    use_bias: bool,
) {
    let Some((n, angle)) = cone_axis(g) else {
        return;
    };
    angular_limit(row, vel, -n, cone - angle, acc, params, use_bias);
}

/// The rows of a distance joint along the unit `u` at length `len`: a rigid
/// rod, or a spring with its limits.
#[allow(clippy::too_many_arguments)]
pub(super) fn solve_distance(
    row: &Row,
    g: &Geometry,
    vel: &mut Vels,
    u: Vec3,
    len: Scalar,
    (length, min, max): (Scalar, Scalar, Scalar),
    spring: Option<crate::joint::Spring>,
    imp: &mut crate::joint::JointImpulses,
    params: &JointParams,
    use_bias: bool,
) {
    match spring {
        None => {
            let soft = if use_bias { params.softness } else { RIGID };
            let (k, cdot) = linear_row(row, g, vel, u);
            let d = soft_impulse(k, cdot, len - length, imp.linear.x, &soft);
            imp.linear.x += d;
            apply_linear(row, g, vel, u, d);
        }
        Some(s) => {
            if s.hertz.is_positive() {
                // A physical spring: in every pass.
                let soft = Softness::new(s.hertz, s.damping_ratio, params.h);
                let (k, cdot) = linear_row(row, g, vel, u);
                let d = soft_impulse(k, cdot, len - length, imp.axial[3], &soft);
                imp.axial[3] += d;
                apply_linear(row, g, vel, u, d);
            }
            if min < max {
                let [lower, upper, ..] = &mut imp.axial;
                linear_limit(row, g, vel, u, len - min, lower, params, use_bias);
                linear_limit(row, g, vel, -u, max - len, upper, params, use_bias);
            }
        }
    }
}
