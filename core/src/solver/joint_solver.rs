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
//! The joints that form a chain (see [`chains`]) have their anchor blocks
//! solved together, exactly, after every joint's other rows, and held
//! rigidly (the whole anchor error out in each substep); the rest keep the
//! soft spring.
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
use crate::math::{Mat3, Scalar, SymMat3, Vec3};
use crate::scratch::Capacities;

use super::contact_solver::Softness;

mod chains;
mod kinds;
mod rows;

pub(crate) use kinds::twist_between;
use kinds::{
    HeldAxis, angle_near, angular_limit, angular_mass, cone_axis, friction_axes, hinge_axes,
    linear_limit, motor_impulse, solve_cone, solve_distance, solve_friction, solve_hinge,
    solve_lock, solve_point, solve_slide, twist_angle, twist_axis,
};
pub(crate) use rows::JointParams;
use rows::{
    End, Posed, RIGID, Row, Vels, apply_angular, apply_linear, apply_point, linear_row, pose, read,
    write,
};

/// Damping ratio of the joints' soft constraints (Box2D v3's default).
pub(crate) const JOINT_DAMPING_RATIO: Scalar = Scalar::TWO;

/// The joints' solver (scratch: rebuilt every tick).
#[derive(Clone, Debug, Default)]
pub(crate) struct JointSolver {
    rows: Vec<Row>,
    /// Per row, the joint at the poses of the stage being solved.
    posed: Vec<Posed>,
    /// The chains among the rows.
    chains: chains::Chains,
}

impl JointSolver {
    /// Lists this tick's joints: those with an awake dynamic body. Returns
    /// whether the list grew (an allocation).
    pub(crate) fn prepare(&mut self, joints: &Arena<Joint>, bodies: &BodySet) -> bool {
        let before = self.capacities();
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
                // Limits and motors are solved one joint at a time beside
                // the chain's anchors: with them in chains, a pile of
                // ragdolls kept a dozen of them jittering awake.
                chainable: matches!(
                    j.desc.kind,
                    JointKind::Spherical {
                        cone: None,
                        twist: None
                    } | JointKind::Revolute {
                        limits: None,
                        motor: None
                    } | JointKind::Fixed
                ),
                chained: false,
                rigid_limits: j.desc.rigid_limits,
                friction: j.desc.friction,
            });
        }
        self.posed.resize(self.rows.len(), Posed::default());
        let chains_before = self.chains.capacities();
        self.chains.build(&mut self.rows);
        self.capacities().grew_since(&before) || self.chains.capacities().grew_since(&chains_before)
    }

    /// The buffers [`prepare`](Self::prepare) fills.
    fn capacities(&self) -> Capacities<2> {
        Capacities::of([&self.rows, &self.posed])
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
            let posed = &*posed;
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
                JointKind::Revolute { limits, .. } => {
                    let hinge = hinge_axes(g);
                    let (j1, j2) = hinge;
                    apply_angular(row, &mut vel, j1 * imp.angular.x + j2 * imp.angular.y);
                    let axis = g.fa.rotate(Vec3::X);
                    if row.friction.is_positive() {
                        apply_angular(row, &mut vel, axis * imp.angular.z);
                    }
                    let limit = imp.axial[0] - imp.axial[1];
                    // A rigid limit's impulse went along its held row.
                    let held = limits
                        .filter(|_| row.rigid_limits)
                        .and_then(|_| HeldAxis::new(row, posed, axis, Some(hinge)));
                    match held {
                        Some(held) => {
                            held.apply(row, posed, &mut vel, limit);
                            apply_angular(row, &mut vel, axis * imp.axial[2]);
                        }
                        None => apply_angular(row, &mut vel, axis * (limit + imp.axial[2])),
                    }
                }
                // A ball joint without limits has no limit rows to warm
                // start (their impulses are zero): skip their axes.
                JointKind::Spherical { cone, twist } => {
                    if row.friction.is_positive() {
                        let [x, y, z] = friction_axes(g);
                        let f = imp.angular;
                        apply_angular(row, &mut vel, x * f.x + y * f.y + z * f.z);
                    }
                    // A rigid limit's impulse went along its held row.
                    let held = |axis: Vec3| {
                        row.rigid_limits
                            .then(|| HeldAxis::new(row, posed, axis, None))
                            .flatten()
                    };
                    if cone.is_some()
                        && let Some((n, _)) = cone_axis(g)
                    {
                        match held(n) {
                            Some(held) => held.apply(row, posed, &mut vel, -imp.axial[0]),
                            None => apply_angular(row, &mut vel, -n * imp.axial[0]),
                        }
                    }
                    if twist.is_some() {
                        let t = twist_axis(g);
                        let d = imp.axial[1] - imp.axial[2];
                        match held(t) {
                            Some(held) => held.apply(row, posed, &mut vel, d),
                            None => apply_angular(row, &mut vel, t * d),
                        }
                    }
                }
                JointKind::Distance { .. } => {}
            }
            write(row, hot, &vel);
        }
        if measure {
            self.chains.factor(&self.rows, &mut self.posed);
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
            // Friction first, then soft limits and motors, the holding rows
            // last (they matter most, and Gauss–Seidel favours the last row
            // visited); rigid limits after the rows they are orthogonal to.
            if row.friction.is_positive() {
                match kind {
                    JointKind::Spherical { .. } => {
                        let f = &mut imp.angular;
                        let accs = [&mut f.x, &mut f.y, &mut f.z];
                        for (axis, acc) in friction_axes(g).into_iter().zip(accs) {
                            solve_friction(row, &mut vel, axis, row.friction, acc, params);
                        }
                    }
                    JointKind::Revolute { .. } => {
                        let axis = g.fa.rotate(Vec3::X);
                        let acc = &mut imp.angular.z;
                        solve_friction(row, &mut vel, axis, row.friction, acc, params);
                    }
                    _ => {}
                }
            }
            match kind {
                JointKind::Spherical { cone, twist }
                    if row.rigid_limits && (cone.is_some() || twist.is_some()) =>
                {
                    // The anchor block first, then the limits orthogonal to
                    // it (they leave its rate as it is).
                    solve_point(row, posed, &mut vel, &mut imp.linear, &soft);
                    if let Some(cone) = cone
                        && let Some((n, angle)) = cone_axis(g)
                    {
                        let on = HeldAxis::new(row, posed, n, None);
                        let acc = &mut imp.axial[0];
                        let c = cone - angle;
                        held_side(
                            row,
                            posed,
                            &mut vel,
                            (n, on),
                            true,
                            c,
                            acc,
                            params,
                            use_bias,
                        );
                    }
                    if let Some((lo, hi)) = twist {
                        let t = twist_axis(g);
                        let angle = angle_near(twist_angle(g), lo, hi);
                        let [_, lower, upper, _] = &mut imp.axial;
                        let on = HeldAxis::new(row, posed, t, None);
                        let c = (angle - lo, hi - angle);
                        held_limits(
                            row,
                            posed,
                            &mut vel,
                            (t, on),
                            c,
                            [lower, upper],
                            params,
                            use_bias,
                        );
                    }
                }
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
                    if !row.chained {
                        solve_point(row, posed, &mut vel, &mut imp.linear, &soft);
                    }
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
                    match limits {
                        // Rigid: the held rows first, then the limit
                        // orthogonal to them (it leaves their rates be).
                        Some((lo, hi)) if row.rigid_limits => {
                            solve_hinge(row, g, &mut vel, &mut imp.angular, &soft);
                            solve_point(row, posed, &mut vel, &mut imp.linear, &soft);
                            let angle = angle_near(angle, lo, hi);
                            let on = HeldAxis::new(row, posed, axis, Some(hinge_axes(g)));
                            let [lower, upper, ..] = &mut imp.axial;
                            let c = (angle - lo, hi - angle);
                            let accs = [lower, upper];
                            held_limits(
                                row,
                                posed,
                                &mut vel,
                                (axis, on),
                                c,
                                accs,
                                params,
                                use_bias,
                            );
                        }
                        // Soft: the limit, then the rows that matter most
                        // (Gauss–Seidel favours the last row visited).
                        _ => {
                            if let Some((lo, hi)) = limits {
                                let angle = angle_near(angle, lo, hi);
                                let [lower, upper, ..] = &mut imp.axial;
                                let (c_lo, c_hi) = (angle - lo, hi - angle);
                                angular_limit(row, &mut vel, axis, c_lo, lower, params, use_bias);
                                angular_limit(row, &mut vel, -axis, c_hi, upper, params, use_bias);
                            }
                            solve_hinge(row, g, &mut vel, &mut imp.angular, &soft);
                            if !row.chained {
                                solve_point(row, posed, &mut vel, &mut imp.linear, &soft);
                            }
                        }
                    }
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
                    if !row.chained {
                        solve_point(row, posed, &mut vel, &mut imp.linear, &soft);
                    }
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
        if measure {
            self.chains.factor(&self.rows, &mut self.posed);
        }
        // A chain's anchors are held rigidly: the solve pass takes out the
        // whole anchor error in the substep, the relax pass what that added.
        let push_out = if use_bias { params.inv_h } else { Scalar::ZERO };
        self.chains
            .solve(&self.rows, &self.posed, joints, hot, push_out);
        // A chain whose elimination failed: one joint at a time, as rigid.
        let soft = Softness::rigid(push_out);
        for i in self.chains.unsolved() {
            let (row, posed) = (&self.rows[i], &self.posed[i]);
            let Some(j) = joints.get_by_index_mut(row.joint) else {
                continue;
            };
            let mut vel = read(row, hot);
            solve_point(row, posed, &mut vel, &mut j.impulses.linear, &soft);
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

/// Both sides of a rigid angular limit about `axis` (positions `c_lo`,
/// `c_hi`, ≥ 0 allowed; see [`held_side`]).
#[allow(clippy::too_many_arguments)]
fn held_limits(
    row: &Row,
    posed: &Posed,
    vel: &mut Vels,
    on: (Vec3, Option<HeldAxis>),
    (c_lo, c_hi): (Scalar, Scalar),
    [lower, upper]: [&mut Scalar; 2],
    params: &JointParams,
    use_bias: bool,
) {
    held_side(row, posed, vel, on, false, c_lo, lower, params, use_bias);
    held_side(row, posed, vel, on, true, c_hi, upper, params, use_bias);
}

/// One side of a rigid angular limit about `axis` (`upper`: about the
/// reversed axis) with position `c` (≥ 0 allowed): orthogonal to the held
/// rows (`on`), or a soft row when it cannot be (see [`HeldAxis::new`]).
#[allow(clippy::too_many_arguments)]
fn held_side(
    row: &Row,
    posed: &Posed,
    vel: &mut Vels,
    (axis, on): (Vec3, Option<HeldAxis>),
    upper: bool,
    c: Scalar,
    acc: &mut Scalar,
    params: &JointParams,
    use_bias: bool,
) {
    match on {
        Some(held) => held.limit(row, posed, vel, upper, c, acc, params, use_bias),
        None => {
            let dir = if upper { -axis } else { axis };
            angular_limit(row, vel, dir, c, acc, params, use_bias);
        }
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
