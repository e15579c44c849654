//! The rows' shared pieces: a joint's ends and geometry, its
//! measurement, the bodies' velocities during a visit, and how impulses
//! reach them.

use crate::body::{BodyHot, BodyKind};
use crate::joint::JointKind;
use crate::math::{Quat, Scalar, SymMat3, Vec3};
use crate::solver::contact_solver::Softness;

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
pub(super) struct End {
    /// Body slot.
    pub(super) slot: u32,
    /// Whether impulses move it.
    pub(super) dynamic: bool,
    /// 1/mass (0 unless dynamic).
    pub(super) inv_mass: Scalar,
    /// World inverse inertia at the start of the tick (0 unless dynamic).
    pub(super) inv_inertia: SymMat3,
    /// Whether `inv_inertia` is a multiple of the identity (a sphere, a
    /// cube): the same in every frame, and products with it are one scale.
    pub(super) isotropic: bool,
    /// The joint frame's origin relative to the centre of mass, body axes.
    pub(super) anchor: Vec3,
    /// The joint frame's rotation in body axes.
    pub(super) frame: Quat,
}

/// One joint of this tick.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Row {
    /// The joint's slot in the arena.
    pub(super) joint: u32,
    pub(super) a: End,
    pub(super) b: End,
    /// Whether the rows read the joint frames' rotations (all but a
    /// spherical joint without limits and a distance joint).
    pub(super) frames: bool,
    /// Whether it may join a chain: an anchor block and no limit or motor
    /// (see [`chains`]).
    pub(super) chainable: bool,
    /// Whether its anchor block is solved with its chain's (see
    /// [`chains`]).
    pub(super) chained: bool,
    /// Whether its angle limits are rigid and orthogonal to its held rows
    /// (see [`super::kinds::HeldAxis`]), not soft.
    pub(super) rigid_limits: bool,
    /// Its friction torque, N·m (`JointDesc::friction`; zero: none).
    pub(super) friction: Scalar,
}

impl End {
    /// `I⁻¹ v`, world axes (the same bits as the full product).
    #[inline]
    pub(super) fn inv_i(&self, v: Vec3) -> Vec3 {
        if self.isotropic {
            v * self.inv_inertia.xx
        } else {
            self.inv_inertia.mul_vec(v)
        }
    }

    /// The angular part of the effective mass of a point at arm `r` (the
    /// same bits as the full product).
    #[inline]
    pub(super) fn arm_mass(&self, r: Vec3) -> SymMat3 {
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
pub(super) struct Geometry {
    /// Anchors relative to the centres of mass, world axes.
    pub(super) ra: Vec3,
    pub(super) rb: Vec3,
    /// Anchor B minus anchor A.
    pub(super) d: Vec3,
    /// Joint frames in world axes.
    pub(super) fa: Quat,
    pub(super) fb: Quat,
}

/// Velocities of both ends (read from the bodies, written back at the end
/// of a joint's visit).
#[derive(Clone, Copy)]
pub(super) struct Vels {
    pub(super) va: Vec3,
    pub(super) wa: Vec3,
    pub(super) vb: Vec3,
    pub(super) wb: Vec3,
    /// Angular impulse taken by each end during the visit.
    pub(super) la: Vec3,
    pub(super) lb: Vec3,
}

/// A joint at the current poses: its geometry and its anchor block's
/// inverse effective mass (`None` for kinds without the block, or when the
/// block is singular). Positions do not change within a stage, so this is
/// computed once per stage and read by every pass of it.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Posed {
    pub(super) g: Geometry,
    pub(super) point_inv: Option<SymMat3>,
}

/// A limit farther than this (m or rad) from being reached is idle.
pub(super) const LIMIT_REACH: Scalar = Scalar::from_int(1 << 16);

/// A row without softness: rigid, no bias.
pub(super) const RIGID: Softness = Softness::rigid(Scalar::ZERO);

/// Measures a joint at the bodies' current poses, for the passes that
/// follow until the positions move: the geometry, and the anchor block's
/// effective mass, inverted. (Keeping the solve's inverse for the relax
/// passes, one substep's rotation later, left ragdolls jittering awake.)
pub(super) fn pose(row: &Row, kind: &JointKind, hot: &[BodyHot]) -> Posed {
    let g = geometry(row, hot);
    let point_inv = match kind {
        // A chained joint's anchor block is solved with its chain's.
        _ if row.chained => None,
        JointKind::Spherical { .. } | JointKind::Revolute { .. } | JointKind::Fixed => {
            point_mass(row, g.ra, g.rb).try_inverse_fast()
        }
        _ => None,
    };
    Posed { g, point_inv }
}

pub(super) fn geometry(row: &Row, hot: &[BodyHot]) -> Geometry {
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
pub(super) fn point_mass(row: &Row, ra: Vec3, rb: Vec3) -> SymMat3 {
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

pub(super) fn read(row: &Row, hot: &[BodyHot]) -> Vels {
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

pub(super) fn write(row: &Row, hot: &mut [BodyHot], vel: &Vels) {
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
pub(super) fn apply_angular(row: &Row, vel: &mut Vels, p: Vec3) {
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
pub(super) fn apply_point(row: &Row, g: &Geometry, vel: &mut Vels, p: Vec3) {
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
pub(super) fn arms(g: &Geometry, u: Vec3) -> (Vec3, Vec3) {
    ((g.ra + g.d).cross(u), g.rb.cross(u))
}

/// Applies the impulse `lambda` along the linear row `u`.
pub(super) fn apply_linear(row: &Row, g: &Geometry, vel: &mut Vels, u: Vec3, lambda: Scalar) {
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
pub(super) fn linear_row(row: &Row, g: &Geometry, vel: &Vels, u: Vec3) -> (Scalar, Scalar) {
    let (ca, cb) = arms(g, u);
    let k = row.a.inv_mass + row.b.inv_mass + ca.dot(row.a.inv_i(ca)) + cb.dot(row.b.inv_i(cb));
    let cdot = u.dot(vel.vb - vel.va) + cb.dot(vel.wb) - ca.dot(vel.wa);
    (k, cdot)
}
