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

/// One side of a soft limit: `c ≥ 0` is allowed, the row's impulse pushes
/// along its direction only (accumulated ≥ 0). Apart, it is speculative:
/// the approach that closes the gap within the substep is allowed.
/// Reached, it is a row on the joints' soft spring.
pub(super) fn limit_impulse(
    k: Scalar,
    cdot: Scalar,
    c: Scalar,
    acc: &mut Scalar,
    params: &JointParams,
    use_bias: bool,
) -> Scalar {
    one_sided(k, cdot, c, acc, params, &reached(params, use_bias, false))
}

/// A limit's row once reached: on the joints' soft spring or, `rigid`,
/// without softness (the solve pass pushes the whole error out in the
/// substep, the relax pass lets nothing through; a steady load then holds
/// it at the limit, not a spring's stretch past it).
fn reached(params: &JointParams, use_bias: bool, rigid: bool) -> Softness {
    match (use_bias, rigid) {
        (false, _) => RIGID,
        (true, false) => params.softness,
        (true, true) => Softness::rigid(params.inv_h),
    }
}

/// The impulse of a one-sided row at position `c` (≥ 0 allowed),
/// speculative while apart and `reached` once reached.
fn one_sided(
    k: Scalar,
    cdot: Scalar,
    c: Scalar,
    acc: &mut Scalar,
    params: &JointParams,
    reached: &Softness,
) -> Scalar {
    if c > LIMIT_REACH {
        // Far from the limit: the row is idle (and its bias would not fit).
        let d = -*acc;
        *acc = Scalar::ZERO;
        return d;
    }
    let spec = Softness::rigid(params.inv_h);
    let soft = if c.is_positive() { &spec } else { reached };
    let imp = soft_impulse(k, cdot, c, *acc, soft);
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

/// The axes a spherical joint's friction acts about: A's joint frame's.
pub(super) fn friction_axes(g: &Geometry) -> [Vec3; 3] {
    [Vec3::X, Vec3::Y, Vec3::Z].map(|a| g.fa.rotate(a))
}

/// Joint friction about `axis`: a row that stops the bodies' relative
/// rotation about it, its accumulated impulse held within `torque`·h (a
/// speed motor at speed 0, in the solve and relax passes alike).
pub(super) fn solve_friction(
    row: &Row,
    vel: &mut Vels,
    axis: Vec3,
    torque: Scalar,
    acc: &mut Scalar,
    params: &JointParams,
) {
    let k = angular_mass(row, axis);
    let cdot = (vel.wb - vel.wa).dot(axis);
    let hold = Motor::Speed {
        speed: Scalar::ZERO,
        max_force: torque,
    };
    let d = motor_impulse(hold, cdot, Scalar::ZERO, k, acc, params, false);
    apply_angular(row, vel, axis * d);
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

/// An angular limit made orthogonal, in the mass metric, to the rows its
/// joint holds (the anchor block and, for a hinge, the two rows that keep
/// the axes aligned), as Rapier orthogonalises a joint's limit rows against
/// its locked ones: the rigid limits (`JointDesc::rigid_limits`). The
/// limit's impulse `λ` goes about its axis and `−λ·w` along the held rows
/// (`w = K_held⁻¹·k_held,limit`), so it changes none of their rates, and
/// theirs none of its. Alone, a hinge's limit row sees only the body's
/// inertia about its centre (a door hinged 1 m from its centre: a seventh
/// of its inertia about the hinge); the anchor rows then undo most of its
/// impulse, Gauss–Seidel closes the gap by that ratio per pass, and the
/// door passes its limit.
#[derive(Clone, Copy, Debug)]
pub(super) struct HeldAxis {
    /// The limit's axis (world).
    axis: Vec3,
    /// A hinge's two held angular rows (`None` for a ball joint).
    hinge: Option<(Vec3, Vec3)>,
    /// The held rows' impulses per unit of the limit's: the anchor block's,
    /// and the hinge rows'.
    w_point: Vec3,
    w_hinge: [Scalar; 2],
    /// The inverse effective mass of the limit with the held rows held (the
    /// Schur complement `k − k_held,limit·w`), > 0.
    k: Scalar,
}

/// The anchor block's rate change per unit of angular impulse about `j`:
/// `I_B⁻¹j × r_B + I_A⁻¹j × r_A`.
fn point_by_angular(row: &Row, g: &Geometry, j: Vec3) -> Vec3 {
    row.b.inv_i(j).cross(g.rb) + row.a.inv_i(j).cross(g.ra)
}

/// `j·(I_A⁻¹ + I_B⁻¹)·k`.
fn angular_by_angular(row: &Row, j: Vec3, k: Vec3) -> Scalar {
    j.dot(row.a.inv_i(k) + row.b.inv_i(k))
}

impl HeldAxis {
    /// The limit about `axis` of a joint whose anchor block is held and,
    /// with `hinge`, its two hinge rows: `None` when this joint does not
    /// solve the anchor block (chained, or singular) or the limit has no
    /// mass left once the held rows hold.
    ///
    /// Bounds: every product is of terms the anchor block and the hinge
    /// rows already form (inverse masses and inertias times arms, and the
    /// block's inverse), so it overflows where they would; like theirs, an
    /// overflow saturates and raises the world's fault flag. A 2×2
    /// complement that is not positive leaves the hinge rows out of `w`
    /// (the anchor block alone), and a failed division gives `None`: the
    /// limit is then solved as a soft row, the same on every machine.
    pub(super) fn new(
        row: &Row,
        posed: &Posed,
        axis: Vec3,
        hinge: Option<(Vec3, Vec3)>,
    ) -> Option<HeldAxis> {
        let p = posed.point_inv?;
        let g = &posed.g;
        let k_p = point_by_angular(row, g, axis);
        let pk = p.mul_vec(k_p);
        let mut held = HeldAxis {
            axis,
            hinge,
            w_point: pk,
            w_hinge: [Scalar::ZERO; 2],
            k: angular_mass(row, axis) - k_p.dot(pk),
        };
        if let Some((j1, j2)) = hinge {
            // The held block is [[K_pp, K_ph], [K_hp, K_hh]]; with
            // P = K_pp⁻¹, its Schur complement S = K_hh − K_hp·P·K_ph (2×2)
            // gives the hinge rows' share, and the anchor block's follows.
            let (c1, c2) = (point_by_angular(row, g, j1), point_by_angular(row, g, j2));
            let (p1, p2) = (p.mul_vec(c1), p.mul_vec(c2));
            let s11 = angular_by_angular(row, j1, j1) - c1.dot(p1);
            let s12 = angular_by_angular(row, j1, j2) - c1.dot(p2);
            let s22 = angular_by_angular(row, j2, j2) - c2.dot(p2);
            let r1 = angular_by_angular(row, j1, axis) - c1.dot(pk);
            let r2 = angular_by_angular(row, j2, axis) - c2.dot(pk);
            let det = s11 * s22 - s12 * s12;
            if det.is_positive() {
                let w1 = (s22 * r1 - s12 * r2).checked_div(det)?;
                let w2 = (s11 * r2 - s12 * r1).checked_div(det)?;
                held.w_hinge = [w1, w2];
                held.w_point = pk - p1 * w1 - p2 * w2;
                held.k = held.k - r1 * w1 - r2 * w2;
            }
        }
        held.k.is_positive().then_some(held)
    }

    /// One side of the limit, rigid: about the axis with position `c`
    /// (≥ 0 allowed; `upper`: about the reversed axis).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn limit(
        &self,
        row: &Row,
        posed: &Posed,
        vel: &mut Vels,
        upper: bool,
        c: Scalar,
        acc: &mut Scalar,
        params: &JointParams,
        use_bias: bool,
    ) {
        // The raw rate: the held rows were solved just before, and the
        // limit's impulse leaves them be, so this is the rate the positions
        // will move at (the orthogonal row's own rate differs by the held
        // rows' soft push-out, and let the door overshoot).
        let rate = (vel.wb - vel.wa).dot(self.axis);
        let rigid = reached(params, use_bias, true);
        let d = if upper {
            -one_sided(self.k, -rate, c, acc, params, &rigid)
        } else {
            one_sided(self.k, rate, c, acc, params, &rigid)
        };
        self.apply(row, posed, vel, d);
    }

    /// Applies the limit's impulse `d` about the axis, and `−d·w` along the
    /// held rows.
    pub(super) fn apply(&self, row: &Row, posed: &Posed, vel: &mut Vels, d: Scalar) {
        if d.is_zero() {
            return;
        }
        apply_point(row, &posed.g, vel, -(self.w_point * d));
        let mut ang = self.axis * d;
        if let Some((j1, j2)) = self.hinge {
            ang = ang - j1 * (self.w_hinge[0] * d) - j2 * (self.w_hinge[1] * d);
        }
        apply_angular(row, vel, ang);
    }
}
