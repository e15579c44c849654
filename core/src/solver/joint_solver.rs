//! The joint solver: the rows of every joint kind, solved in the soft step
//! beside the contacts (after Box2D v3's joints, in 3D).
//!
//! Per tick, [`JointSolver::prepare`] lists the joints with a moving body,
//! in handle order, with each body's inverse mass, its world inverse inertia
//! at the start of the tick and the anchors relative to the centres of mass
//! (body axes). Per substep, before the contacts of the same pass:
//! [`JointSolver::warm_start`] applies the accumulated impulses again, then
//! [`JointSolver::solve`] runs with the soft bias (a spring at the joint
//! frequency pulls the error out) and, after the positions move, without it
//! (relax: the rows hold rigidly, so the bias adds no velocity that stays).
//!
//! Every row is built at the bodies' current poses (anchors rotated with the
//! current rotations), so errors are measured, not extrapolated. Positions
//! move only between the solve and the relax stages, so each joint is
//! measured once each time they move (anchors, frames, and the anchor
//! block's effective mass, inverted): by the first relax pass of a substep,
//! for the relax passes and for the next substep's warm start and solve
//! passes (which start from those poses), and by the warm start of a tick's
//! first substep. That is `substeps + 1` measurements per tick, not twice
//! the substeps. A row's
//! impulse is `λ = −m·s·(Ċ + b·C) − i·λ_acc` with the effective mass `m`,
//! the softness's mass scale `s`, bias rate `b` and impulse scale `i`
//! (without the bias: `s = 1`, `b = 0`, `i = 0`). Blocks of rows that share
//! bodies (the three rows of an anchor, of a rotation lock, the two of a
//! hinge) are solved together with the block's 3×3 or 2×2 effective mass.
//! Limits are one-sided rows whose accumulated impulse stays ≥ 0 and which
//! are speculative while apart (the gap may close within one substep, no
//! more); motors are rows clamped by the largest force times the substep.
//!
//! Impulses reach a dynamic body as `Δv = P/m`, `ΔL = r × P` and
//! `Δω = I⁻¹_world ΔL` (the tick-start inverse inertia, as the contacts use),
//! so joints change angular momentum exactly as contacts do. Kinematic,
//! static and sleeping bodies only lend their velocity (zero for the last
//! two).
//!
//! Determinism: joints in handle order, rows in a fixed order per kind,
//! fixed-point arithmetic; no allocation once the list is warm.

use crate::arena::Arena;
use crate::body::{BodyHandle, BodyHot, BodyKind, BodySet};
use crate::joint::{Joint, JointKind, Motor};
use crate::math::elem::atan2;
use crate::math::{Mat3, Quat, Scalar, SymMat3, Vec3};

use super::contact_solver::Softness;

/// Damping ratio of the joints' soft constraints (Box2D v3's default).
pub(crate) const JOINT_DAMPING_RATIO: Scalar = Scalar::TWO;

/// The solver's settings for one substep.
#[derive(Clone, Copy, Debug)]
pub(crate) struct JointParams {
    /// The substep, s.
    pub h: Scalar,
    /// 1/h.
    pub inv_h: Scalar,
    /// The joints' soft constraint.
    pub softness: Softness,
}

/// One end of a joint, as the rows see it.
#[derive(Clone, Copy, Debug, Default)]
struct End {
    /// Body slot.
    slot: u32,
    /// Whether impulses move it.
    dynamic: bool,
    /// 1/mass (0 unless dynamic).
    inv_mass: Scalar,
    /// World inverse inertia at the start of the tick (0 unless dynamic).
    inv_inertia: SymMat3,
    /// Whether `inv_inertia` is a multiple of the identity (a sphere, a
    /// cube): the same in every frame, and products with it are one scale.
    isotropic: bool,
    /// The joint frame's origin relative to the centre of mass, body axes.
    anchor: Vec3,
    /// The joint frame's rotation in body axes.
    frame: Quat,
}

/// One joint of this tick.
#[derive(Clone, Copy, Debug, Default)]
struct Row {
    /// The joint's slot in the arena.
    joint: u32,
    a: End,
    b: End,
    /// Whether the rows read the joint frames' rotations (all but a
    /// spherical joint without limits and a distance joint).
    frames: bool,
}

impl End {
    /// `I⁻¹ v`, world axes (the same bits as the full product).
    #[inline]
    fn inv_i(&self, v: Vec3) -> Vec3 {
        if self.isotropic {
            v * self.inv_inertia.xx
        } else {
            self.inv_inertia.mul_vec(v)
        }
    }

    /// The angular part of the effective mass of a point at arm `r` (the
    /// same bits as the full product).
    #[inline]
    fn arm_mass(&self, r: Vec3) -> SymMat3 {
        if self.isotropic {
            SymMat3::skew_sandwich_scalar(self.inv_inertia.xx, r)
        } else {
            self.inv_inertia.skew_sandwich(r)
        }
    }
}

/// The state of both ends at the current substep, and the joint's geometry
/// there.
#[derive(Clone, Copy, Debug, Default)]
struct Geometry {
    /// Anchors relative to the centres of mass, world axes.
    ra: Vec3,
    rb: Vec3,
    /// Anchor B minus anchor A.
    d: Vec3,
    /// Joint frames in world axes.
    fa: Quat,
    fb: Quat,
}

/// Velocities of both ends (read from the bodies, written back at the end
/// of a joint's visit).
#[derive(Clone, Copy)]
struct Vels {
    va: Vec3,
    wa: Vec3,
    vb: Vec3,
    wb: Vec3,
    /// Angular impulse taken by each end during the visit.
    la: Vec3,
    lb: Vec3,
}

/// A joint at the current poses: its geometry and its anchor block's
/// inverse effective mass (`None` for kinds without the block, or when the
/// block is singular). Positions do not change within a stage, so this is
/// computed once per stage and read by every pass of it.
#[derive(Clone, Copy, Debug, Default)]
struct Posed {
    g: Geometry,
    point_inv: Option<SymMat3>,
}

/// The joints' solver (scratch: rebuilt every tick).
#[derive(Clone, Debug, Default)]
pub(crate) struct JointSolver {
    rows: Vec<Row>,
    /// Per row, the joint at the poses of the stage being solved.
    posed: Vec<Posed>,
}

impl JointSolver {
    /// Lists this tick's joints: those with an awake dynamic body. Returns
    /// whether the list grew (an allocation).
    pub(crate) fn prepare(&mut self, joints: &Arena<Joint>, bodies: &BodySet) -> bool {
        let cap = self.rows.capacity();
        self.rows.clear();
        for (h, j) in joints.iter() {
            let (a, b) = (j.desc.body_a, j.desc.body_b);
            let (Some(ha), Some(hb)) = (bodies.hot(a), bodies.hot(b)) else {
                continue;
            };
            let moving = |b: &BodyHot| b.kind == BodyKind::Dynamic && !b.sleeping;
            if !moving(ha) && !moving(hb) {
                continue;
            }
            let end = |handle: BodyHandle, b: &BodyHot, frame: &crate::math::Transform| {
                let dynamic = moving(b);
                let center = bodies.cold(handle).map_or(Vec3::ZERO, |c| c.local_center);
                End {
                    slot: handle.index(),
                    dynamic,
                    inv_mass: if dynamic { b.inv_mass } else { Scalar::ZERO },
                    // The zero of an end that does not move is isotropic too.
                    isotropic: !dynamic || b.isotropic,
                    inv_inertia: if dynamic && b.isotropic {
                        b.inv_inertia
                    } else if dynamic {
                        b.inv_inertia.rotate(&Mat3::from_quat(b.rotation))
                    } else {
                        SymMat3::ZERO
                    },
                    anchor: frame.translation - center,
                    frame: frame.rotation,
                }
            };
            let frames = match j.desc.kind {
                JointKind::Spherical { cone, twist } => cone.is_some() || twist.is_some(),
                JointKind::Distance { .. } => false,
                _ => true,
            };
            self.rows.push(Row {
                joint: h.index,
                a: end(a, ha, &j.desc.frame_a),
                b: end(b, hb, &j.desc.frame_b),
                frames,
            });
        }
        let posed_cap = self.posed.capacity();
        self.posed.resize(self.rows.len(), Posed::default());
        self.rows.capacity() != cap || self.posed.capacity() != posed_cap
    }

    /// Whether there is a joint to solve this tick.
    pub(crate) fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }

    /// The joints solved this tick.
    pub(crate) fn len(&self) -> usize {
        self.rows.len()
    }

    /// Applies every joint's accumulated impulses again. With `measure`,
    /// each joint is measured at the current poses first (for this pass and
    /// the solve passes after it); without, the last measurement is read:
    /// the caller's promise that no position moved since it (the previous
    /// substep's relax measured at the poses this substep starts from).
    pub(crate) fn warm_start(&mut self, joints: &Arena<Joint>, hot: &mut [BodyHot], measure: bool) {
        for (row, posed) in self.rows.iter().zip(self.posed.iter_mut()) {
            let Some(j) = joints.get_by_index(row.joint) else {
                continue;
            };
            if measure {
                *posed = pose(row, &j.desc.kind, hot);
            }
            let g = &posed.g;
            let mut vel = read(row, hot);
            let imp = j.impulses;
            match j.desc.kind {
                JointKind::Spherical { .. } | JointKind::Revolute { .. } | JointKind::Fixed => {
                    apply_point(row, g, &mut vel, imp.linear);
                }
                JointKind::Prismatic { .. } => {
                    let (p, q) = (g.fa.rotate(Vec3::Y), g.fa.rotate(Vec3::Z));
                    apply_linear(row, g, &mut vel, p, imp.linear.x);
                    apply_linear(row, g, &mut vel, q, imp.linear.y);
                    let axis = g.fa.rotate(Vec3::X);
                    let axial = imp.axial[0] - imp.axial[1] + imp.axial[2];
                    apply_linear(row, g, &mut vel, axis, axial);
                }
                JointKind::Distance { .. } => {
                    if let Some(u) = g.d.try_normalize() {
                        let total = imp.linear.x + imp.axial[0] - imp.axial[1] + imp.axial[3];
                        apply_linear(row, g, &mut vel, u, total);
                    }
                }
            }
            match j.desc.kind {
                JointKind::Fixed | JointKind::Prismatic { .. } => {
                    apply_angular(row, &mut vel, imp.angular);
                }
                JointKind::Revolute { .. } => {
                    let (j1, j2) = hinge_axes(g);
                    apply_angular(row, &mut vel, j1 * imp.angular.x + j2 * imp.angular.y);
                    let axis = g.fa.rotate(Vec3::X);
                    let axial = imp.axial[0] - imp.axial[1] + imp.axial[2];
                    apply_angular(row, &mut vel, axis * axial);
                }
                // A ball joint without limits has no limit rows to warm
                // start (their impulses are zero): skip their axes.
                JointKind::Spherical { cone, twist } => {
                    if cone.is_some()
                        && let Some((n, _)) = cone_axis(g)
                    {
                        apply_angular(row, &mut vel, -n * imp.axial[0]);
                    }
                    if twist.is_some() {
                        let t = twist_axis(g);
                        apply_angular(row, &mut vel, t * (imp.axial[1] - imp.axial[2]));
                    }
                }
                JointKind::Distance { .. } => {}
            }
            write(row, hot, &vel);
        }
    }

    /// One pass over every joint, soft with `use_bias`, rigid without. With
    /// `measure` (the first pass after the positions moved), each joint is
    /// measured at the current poses first; without, the last measurement
    /// is read.
    pub(crate) fn solve(
        &mut self,
        joints: &mut Arena<Joint>,
        hot: &mut [BodyHot],
        params: &JointParams,
        use_bias: bool,
        measure: bool,
    ) {
        for (row, posed) in self.rows.iter().zip(self.posed.iter_mut()) {
            let Some(j) = joints.get_by_index_mut(row.joint) else {
                continue;
            };
            if measure {
                *posed = pose(row, &j.desc.kind, hot);
            }
            let posed = &*posed;
            let g = &posed.g;
            let mut vel = read(row, hot);
            let soft = if use_bias { params.softness } else { RIGID };
            let kind = j.desc.kind;
            let imp = &mut j.impulses;
            // Limits and motors first, the holding rows last (they matter
            // most, and Gauss–Seidel favours the last row visited).
            match kind {
                JointKind::Spherical { cone, twist } => {
                    if let Some(cone) = cone {
                        solve_cone(row, g, &mut vel, cone, &mut imp.axial[0], params, use_bias);
                    }
                    if let Some((lo, hi)) = twist {
                        let t = twist_axis(g);
                        let angle = angle_near(twist_angle(g), lo, hi);
                        let [_, lower, upper, _] = &mut imp.axial;
                        angular_limit(row, &mut vel, t, angle - lo, lower, params, use_bias);
                        angular_limit(row, &mut vel, -t, hi - angle, upper, params, use_bias);
                    }
                    solve_point(row, posed, &mut vel, &mut imp.linear, &soft);
                }
                JointKind::Revolute { limits, motor } => {
                    let axis = g.fa.rotate(Vec3::X);
                    let angle = twist_angle(g);
                    if let Some(m) = motor {
                        let k = angular_mass(row, axis);
                        let cdot = (vel.wb - vel.wa).dot(axis);
                        let x = match m {
                            Motor::Position { target, .. } => angle_near(angle, target, target),
                            Motor::Speed { .. } => angle,
                        };
                        let d = motor_impulse(m, cdot, x, k, &mut imp.axial[2], params, use_bias);
                        apply_angular(row, &mut vel, axis * d);
                    }
                    if let Some((lo, hi)) = limits {
                        let angle = angle_near(angle, lo, hi);
                        let [lower, upper, ..] = &mut imp.axial;
                        angular_limit(row, &mut vel, axis, angle - lo, lower, params, use_bias);
                        angular_limit(row, &mut vel, -axis, hi - angle, upper, params, use_bias);
                    }
                    solve_hinge(row, g, &mut vel, &mut imp.angular, &soft);
                    solve_point(row, posed, &mut vel, &mut imp.linear, &soft);
                }
                JointKind::Prismatic { limits, motor } => {
                    let axis = g.fa.rotate(Vec3::X);
                    let x = axis.dot(g.d);
                    if let Some(m) = motor {
                        let (k, cdot) = linear_row(row, g, &vel, axis);
                        let d = motor_impulse(m, cdot, x, k, &mut imp.axial[2], params, use_bias);
                        apply_linear(row, g, &mut vel, axis, d);
                    }
                    if let Some((lo, hi)) = limits {
                        let [lower, upper, ..] = &mut imp.axial;
                        linear_limit(row, g, &mut vel, axis, x - lo, lower, params, use_bias);
                        linear_limit(row, g, &mut vel, -axis, hi - x, upper, params, use_bias);
                    }
                    solve_lock(row, g, &mut vel, &mut imp.angular, &soft);
                    solve_slide(row, g, &mut vel, &mut imp.linear, &soft);
                }
                JointKind::Fixed => {
                    solve_lock(row, g, &mut vel, &mut imp.angular, &soft);
                    solve_point(row, posed, &mut vel, &mut imp.linear, &soft);
                }
                JointKind::Distance {
                    length,
                    min,
                    max,
                    spring,
                } => {
                    if let Some((u, len)) = g.d.normalize_and_length() {
                        solve_distance(
                            row,
                            g,
                            &mut vel,
                            u,
                            len,
                            (length, min, max),
                            spring,
                            imp,
                            params,
                            use_bias,
                        );
                    }
                }
            }
            write(row, hot, &vel);
        }
    }

    /// The constraint force (N) and torque (N·m) of every listed joint whose
    /// thresholds it passes, in handle order: `(slot, force, torque)`.
    pub(crate) fn over_threshold<'a>(
        &'a self,
        joints: &'a Arena<Joint>,
        inv_h: Scalar,
    ) -> impl Iterator<Item = (u32, Scalar, Scalar)> + 'a {
        self.rows.iter().filter_map(move |row| {
            let j = joints.get_by_index(row.joint)?;
            let d = &j.desc;
            if d.break_force.is_none() && d.break_torque.is_none() {
                return None;
            }
            let (force, torque) = loads(j, inv_h);
            let over = d.break_force.is_some_and(|f| force > f)
                || d.break_torque.is_some_and(|t| torque > t);
            over.then_some((row.joint, force, torque))
        })
    }
}

/// A joint's constraint force and torque from its accumulated impulses (per
/// substep).
pub(crate) fn loads(j: &Joint, inv_h: Scalar) -> (Scalar, Scalar) {
    let imp = &j.impulses;
    let axial = imp.axial[0].abs() + imp.axial[1].abs() + imp.axial[2].abs() + imp.axial[3].abs();
    let (mut lin, mut ang) = (imp.linear.length(), imp.angular.length());
    match j.desc.kind {
        JointKind::Prismatic { .. } | JointKind::Distance { .. } => lin += axial,
        _ => ang += axial,
    }
    (lin * inv_h, ang * inv_h)
}

/// A limit farther than this (m or rad) from being reached is idle.
const LIMIT_REACH: Scalar = Scalar::from_int(1 << 16);

/// A row without softness: rigid, no bias.
const RIGID: Softness = Softness {
    bias_rate: Scalar::ZERO,
    mass_scale: Scalar::ONE,
    impulse_scale: Scalar::ZERO,
};

/// Measures a joint at the bodies' current poses, for the passes that
/// follow until the positions move: the geometry, and the anchor block's
/// effective mass, inverted. (Keeping the solve's inverse for the relax
/// passes, one substep's rotation later, left ragdolls jittering awake.)
fn pose(row: &Row, kind: &JointKind, hot: &[BodyHot]) -> Posed {
    let g = geometry(row, hot);
    let point_inv = match kind {
        JointKind::Spherical { .. } | JointKind::Revolute { .. } | JointKind::Fixed => {
            point_mass(row, g.ra, g.rb).try_inverse_fast()
        }
        _ => None,
    };
    Posed { g, point_inv }
}

fn geometry(row: &Row, hot: &[BodyHot]) -> Geometry {
    let a = &hot[row.a.slot as usize];
    let b = &hot[row.b.slot as usize];
    let ra = a.rotation.rotate(row.a.anchor);
    let rb = b.rotation.rotate(row.b.anchor);
    let (fa, fb) = if row.frames {
        (a.rotation * row.a.frame, b.rotation * row.b.frame)
    } else {
        (a.rotation, b.rotation)
    };
    Geometry {
        ra,
        rb,
        d: (b.center + rb) - (a.center + ra),
        fa,
        fb,
    }
}

/// The anchor block's `K` for anchors `ra`, `rb` (relative to the centres
/// of mass, world axes), built at the current anchors in every stage.
/// (Inverting it once per tick at the start anchors, as Box2D does, let a
/// pendulum with a small bob gain energy: the bob's `K` is strongly
/// anisotropic and turns with it.)
fn point_mass(row: &Row, ra: Vec3, rb: Vec3) -> SymMat3 {
    let ms = row.a.inv_mass + row.b.inv_mass;
    let mut k = SymMat3::from_diagonal(Vec3::new(ms, ms, ms));
    if row.a.dynamic {
        k = k + row.a.arm_mass(ra);
    }
    if row.b.dynamic {
        k = k + row.b.arm_mass(rb);
    }
    k
}

fn read(row: &Row, hot: &[BodyHot]) -> Vels {
    let a = &hot[row.a.slot as usize];
    let b = &hot[row.b.slot as usize];
    let vel = |b: &BodyHot| {
        if b.kind == BodyKind::Static || b.sleeping {
            (Vec3::ZERO, Vec3::ZERO)
        } else {
            (b.linear_velocity, b.angular_velocity)
        }
    };
    let ((va, wa), (vb, wb)) = (vel(a), vel(b));
    Vels {
        va,
        wa,
        vb,
        wb,
        la: Vec3::ZERO,
        lb: Vec3::ZERO,
    }
}

fn write(row: &Row, hot: &mut [BodyHot], vel: &Vels) {
    if row.a.dynamic {
        let a = &mut hot[row.a.slot as usize];
        a.linear_velocity = vel.va;
        a.angular_velocity = vel.wa;
        a.angular_momentum += vel.la;
    }
    if row.b.dynamic {
        let b = &mut hot[row.b.slot as usize];
        b.linear_velocity = vel.vb;
        b.angular_velocity = vel.wb;
        b.angular_momentum += vel.lb;
    }
}

/// Applies the angular impulse `p` to B and `−p` to A.
fn apply_angular(row: &Row, vel: &mut Vels, p: Vec3) {
    if p.is_zero() {
        return;
    }
    if row.a.dynamic {
        vel.la -= p;
        vel.wa -= row.a.inv_i(p);
    }
    if row.b.dynamic {
        vel.lb += p;
        vel.wb += row.b.inv_i(p);
    }
}

/// Applies the impulse `p` at B's anchor and `−p` at A's.
fn apply_point(row: &Row, g: &Geometry, vel: &mut Vels, p: Vec3) {
    if p.is_zero() {
        return;
    }
    if row.a.dynamic {
        vel.va -= p * row.a.inv_mass;
        let l = g.ra.cross(p);
        vel.la -= l;
        vel.wa -= row.a.inv_i(l);
    }
    if row.b.dynamic {
        vel.vb += p * row.b.inv_mass;
        let l = g.rb.cross(p);
        vel.lb += l;
        vel.wb += row.b.inv_i(l);
    }
}

/// A's and B's angular arms of a linear row along `u`: the row is
/// `u·(vB − vA) + cb·ωB − ca·ωA` with `ca = (rA + d) × u` (A's frame carries
/// the direction) and `cb = rB × u`.
fn arms(g: &Geometry, u: Vec3) -> (Vec3, Vec3) {
    ((g.ra + g.d).cross(u), g.rb.cross(u))
}

/// Applies the impulse `lambda` along the linear row `u`.
fn apply_linear(row: &Row, g: &Geometry, vel: &mut Vels, u: Vec3, lambda: Scalar) {
    if lambda.is_zero() {
        return;
    }
    let (ca, cb) = arms(g, u);
    if row.a.dynamic {
        vel.va -= u * (row.a.inv_mass * lambda);
        vel.la -= ca * lambda;
        vel.wa -= row.a.inv_i(ca * lambda);
    }
    if row.b.dynamic {
        vel.vb += u * (row.b.inv_mass * lambda);
        vel.lb += cb * lambda;
        vel.wb += row.b.inv_i(cb * lambda);
    }
}

/// The effective mass's inverse (`k`) and the current rate of the linear
/// row along `u`.
fn linear_row(row: &Row, g: &Geometry, vel: &Vels, u: Vec3) -> (Scalar, Scalar) {
    let (ca, cb) = arms(g, u);
    let k = row.a.inv_mass + row.b.inv_mass + ca.dot(row.a.inv_i(ca)) + cb.dot(row.b.inv_i(cb));
    let cdot = u.dot(vel.vb - vel.va) + cb.dot(vel.wb) - ca.dot(vel.wa);
    (k, cdot)
}

/// `k` of an angular row about `j`.
fn angular_mass(row: &Row, j: Vec3) -> Scalar {
    j.dot(row.a.inv_i(j)) + j.dot(row.b.inv_i(j))
}

/// The impulse of a soft equality row: `−(Ċ + b·C)·s/k − i·λ`.
fn soft_impulse(k: Scalar, cdot: Scalar, c: Scalar, acc: Scalar, soft: &Softness) -> Scalar {
    let Some(m) = Scalar::ONE.checked_div(k) else {
        return Scalar::ZERO;
    };
    -(m * soft.mass_scale * (cdot + soft.bias_rate * c)) - soft.impulse_scale * acc
}

/// One side of a limit: `c ≥ 0` is allowed, the row's impulse pushes
/// along its direction only (accumulated ≥ 0). Apart, it is speculative:
/// the approach that closes the gap within the substep is allowed.
fn limit_impulse(
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
        Softness {
            bias_rate: params.inv_h,
            mass_scale: Scalar::ONE,
            impulse_scale: Scalar::ZERO,
        }
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
fn angular_limit(
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
fn linear_limit(
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
fn motor_impulse(
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
fn solve_point(row: &Row, posed: &Posed, vel: &mut Vels, acc: &mut Vec3, soft: &Softness) {
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
fn solve_lock(row: &Row, g: &Geometry, vel: &mut Vels, acc: &mut Vec3, soft: &Softness) {
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
fn hinge_axes(g: &Geometry) -> (Vec3, Vec3) {
    let hb = g.fb.rotate(Vec3::X);
    (
        hb.cross(g.fa.rotate(Vec3::Y)),
        hb.cross(g.fa.rotate(Vec3::Z)),
    )
}

fn solve_hinge(row: &Row, g: &Geometry, vel: &mut Vels, acc: &mut Vec3, soft: &Softness) {
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
fn block2(
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
fn solve_slide(row: &Row, g: &Geometry, vel: &mut Vels, acc: &mut Vec3, soft: &Softness) {
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
fn twist_axis(g: &Geometry) -> Vec3 {
    let t = g.fa.rotate(Vec3::X) + g.fb.rotate(Vec3::X);
    t.try_normalize().unwrap_or_else(|| g.fa.rotate(Vec3::X))
}

/// The angle of B's frame about A's x axis: the twist of the swing–twist
/// split of B's frame relative to A's, in (−π, π].
fn twist_angle(g: &Geometry) -> Scalar {
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
fn cone_axis(g: &Geometry) -> Option<(Vec3, Scalar)> {
    let (ta, tb) = (g.fa.rotate(Vec3::X), g.fb.rotate(Vec3::X));
    let (n, s) = ta.cross(tb).normalize_and_length()?;
    Some((n, atan2(s, ta.dot(tb))))
}

fn solve_cone(
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
fn solve_distance(
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
