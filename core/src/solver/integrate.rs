//! Integration of velocities and positions.
//!
//! # Linear motion
//! Semi-implicit (symplectic) Euler per substep of length `h`:
//! `v += (g + F/m)·h; x += v·h`. For a constant acceleration this leaves a
//! position error of exactly `½·a·h·t` against the closed form (tested); the
//! contact solver that runs between the two updates relies on this form.
//!
//! # Rotation
//! A dynamic body's rotational state is its angular momentum `L` in world
//! axes; its angular velocity is derived, `ω = R I⁻¹ Rᵀ L`. Torques change
//! `L` directly, so a torque-free body keeps `L` bit for bit: |L| cannot
//! drift. The gyroscopic effect (a spinning, anisotropic body precessing,
//! the intermediate-axis flip) comes from the orientation update, which uses
//! the *implicit midpoint* angular velocity of Euler's equations in body
//! axes: `ω_m = I⁻¹ (L_b + L_b')/2` with `L_b' = cay(−h ω_m) L_b`, solved by
//! fixed-point iteration (it converges by a factor of about `h|ω|` per
//! round, and stops as soon as the integer result repeats). The orientation
//! then turns by `cay(h ω_m)`, which is exactly what the quaternion update
//! `normalize(q + ½ h ω_m ⊗ q)` computes. Implicit midpoint preserves every
//! quadratic invariant, so the kinetic energy `½ L·ω` is conserved up to
//! rounding instead of growing as it does with an explicit gyroscopic term
//! (Catto, "Numerical Methods", GDC 2015, shows that blow-up). Bodies whose
//! inertia is a multiple of the identity (spheres, cubes) have no gyroscopic
//! term and skip all of this.

use std::sync::atomic::{AtomicU32, Ordering};

use crate::body::{BodyHot, BodyKind};
use crate::math::{Quat, Scalar, SymMat3, Vec3};

use crate::workers::{SharedMut, Workers};

/// Awake slots a worker claims at a time.
const BLOCK: usize = 128;

/// Runs `update` on every body of `awake` (distinct slots of `hot`), in
/// blocks over the workers: each body's update reads and writes only that
/// body, so the results are the same for any worker count. Returns the sum
/// of what the updates counted: each block sums its own, then adds it to
/// the totals once (integers: the same sum in any order).
fn for_each_awake(
    hot: &mut [BodyHot],
    awake: &[u32],
    workers: &Workers,
    update: impl Fn(&mut BodyHot) -> VelocityCounters + Sync,
) -> VelocityCounters {
    let totals = [AtomicU32::new(0), AtomicU32::new(0), AtomicU32::new(0)];
    let hot = SharedMut::new(hot);
    workers.for_each_block(awake.len(), BLOCK, |r| {
        let mut sum = [0u32; 3];
        for &slot in &awake[r] {
            // SAFETY: the awake slots are distinct, and each block goes to
            // one worker alone.
            let c = update(unsafe { hot.get(slot as usize) });
            sum[0] += c.integrated;
            sum[1] += c.gyroscopic;
            sum[2] += c.clamped;
        }
        for (total, n) in totals.iter().zip(sum) {
            if n != 0 {
                total.fetch_add(n, Ordering::Relaxed);
            }
        }
    });
    let [integrated, gyroscopic, clamped] = totals.map(AtomicU32::into_inner);
    VelocityCounters {
        integrated,
        gyroscopic,
        clamped,
    }
}

/// At most this many fixed-point rounds for the midpoint angular velocity.
/// Four reach the last bit for `h|ω|` up to about 0.05 (ω ≈ 12 rad/s at
/// 240 Hz); the rest only run for very fast spins.
pub const GYRO_MAX_ITERATIONS: u32 = 8;

/// `1 / (1 + h·c)`: the per-substep damping factor for rate `c` (≥ 0).
#[inline]
pub(crate) fn damping_factor(h: Scalar, c: Scalar) -> Scalar {
    (Scalar::ONE + h * c).recip()
}

/// World angular velocity from world angular momentum: `R I⁻¹ Rᵀ L`.
#[inline]
pub(crate) fn omega_from_momentum(q: Quat, inv_inertia: &SymMat3, l: Vec3) -> Vec3 {
    q.rotate(inv_inertia.mul_vec(q.inverse_rotate(l)))
}

/// World angular momentum from world angular velocity: `R I Rᵀ ω`.
#[inline]
pub(crate) fn momentum_from_omega(q: Quat, inertia: &SymMat3, w: Vec3) -> Vec3 {
    q.rotate(inertia.mul_vec(q.inverse_rotate(w)))
}

/// Rotates `v` by the Cayley transform of `2·skew(u)`: a rotation about `u`
/// by `2·atan(|u|)`, exactly orthogonal in exact arithmetic.
#[inline]
fn cayley_rotate(u: Vec3, v: Vec3) -> Vec3 {
    let uv = u.cross(v);
    let uuv = u.cross(uv);
    let k = Scalar::TWO / (Scalar::ONE + u.length_squared());
    v + (uv + uuv) * k
}

/// The implicit-midpoint angular velocity (world axes) for a substep `h`,
/// and the number of fixed-point rounds used.
pub(crate) fn midpoint_omega(
    q: Quat,
    inertia_inv: &SymMat3,
    l_world: Vec3,
    h: Scalar,
) -> (Vec3, u32) {
    let lb = q.inverse_rotate(l_world);
    let mut wm = inertia_inv.mul_vec(lb);
    let hh = h.half();
    let mut rounds = 0;
    while rounds < GYRO_MAX_ITERATIONS {
        rounds += 1;
        let lb_new = cayley_rotate(-(wm * hh), lb);
        let next = inertia_inv.mul_vec((lb + lb_new).half());
        if next == wm {
            break;
        }
        wm = next;
    }
    (q.rotate(wm), rounds)
}

/// Counters from one velocity stage.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct VelocityCounters {
    /// Bodies whose velocity was integrated.
    pub integrated: u32,
    /// Bodies that needed the gyroscopic midpoint solve.
    pub gyroscopic: u32,
    /// Bodies whose spin was capped at [`max_angular_speed`].
    pub clamped: u32,
}

/// Velocity stage for one substep: gravity, accumulated forces and torques,
/// damping; sets each dynamic body's angular velocity for the substep.
///
/// `awake` lists the slots to visit (the awake dynamic and kinematic
/// bodies, ascending): sleeping and static bodies cost nothing here.
///
/// Determinism: each body's update reads only its own state (so the
/// workers may share the bodies out in any order).
pub(crate) fn integrate_velocities(
    hot: &mut [BodyHot],
    awake: &[u32],
    gravity: Vec3,
    h: Scalar,
    workers: &Workers,
) -> VelocityCounters {
    let max_w = max_angular_speed(h);
    let max_w2 = max_w.wide_mul(max_w) as u128;
    for_each_awake(hot, awake, workers, |b| {
        let mut counted = VelocityCounters::default();
        if b.kind != BodyKind::Dynamic || b.sleeping {
            return counted;
        }
        counted.integrated = 1;
        if b.angular_velocity.length_squared_wide() > max_w2 {
            // ω and L are proportional (ω = I⁻¹L): scaling L scales ω.
            let k = max_w / b.angular_velocity.length();
            b.angular_momentum *= k;
            b.angular_velocity *= k;
            counted.clamped = 1;
        }
        let accel = gravity * b.gravity_scale + b.force * b.inv_mass;
        b.linear_velocity += accel * h;
        if !b.linear_damping.is_zero() {
            b.linear_velocity *= damping_factor(h, b.linear_damping);
        }
        if !b.torque.is_zero() {
            b.angular_momentum += b.torque * h;
        }
        if !b.angular_damping.is_zero() {
            b.angular_momentum *= damping_factor(h, b.angular_damping);
        }
        if b.angular_momentum.is_zero() {
            b.angular_velocity = Vec3::ZERO;
        } else if b.isotropic {
            b.angular_velocity = b.angular_momentum * b.inv_inertia.xx;
        } else {
            let (w, _) = midpoint_omega(b.rotation, &b.inv_inertia, b.angular_momentum, h);
            b.angular_velocity = w;
            counted.gyroscopic = 1;
        }
        counted
    })
}

/// The most a body may turn in one substep, rad: a quarter turn's half
/// (π/4, as Box2D and Jolt). Faster spin than `π/4 / h` is not resolved by
/// the substeps anyway, and a cap keeps the gyroscopic products far inside
/// Q32.32's range (a 2 cm box hit at 500 m/s can otherwise be spun past
/// 40,000 rad/s, where they overflow).
pub const MAX_ROTATION_PER_SUBSTEP: Scalar = Scalar::from_bits(3_373_259_426);

/// `MAX_ROTATION_PER_SUBSTEP / h`: the fastest a body spins, rad/s (188.5 at
/// 60 Hz with 4 substeps).
pub fn max_angular_speed(h: Scalar) -> Scalar {
    MAX_ROTATION_PER_SUBSTEP / h
}

/// Position stage for one substep: `x += v·h`, `q ← normalize(q + ½h ω⊗q)`
/// for every moving dynamic and kinematic body (the slots in `awake`).
pub(crate) fn integrate_positions(
    hot: &mut [BodyHot],
    awake: &[u32],
    h: Scalar,
    workers: &Workers,
) {
    for_each_awake(hot, awake, workers, |b| {
        if b.is_moving() {
            b.center += b.linear_velocity * h;
            if !b.angular_velocity.is_zero() {
                b.rotation = b.rotation.integrate(b.angular_velocity, h);
            }
        }
        VelocityCounters::default()
    });
}

/// After the last substep: each anisotropic dynamic body's angular velocity
/// becomes the one its momentum gives at the new orientation (the midpoint
/// value was only for the substep). Visits the slots in `awake`.
pub(crate) fn finish_angular_velocities(hot: &mut [BodyHot], awake: &[u32], workers: &Workers) {
    for_each_awake(hot, awake, workers, |b| {
        if b.kind == BodyKind::Dynamic && !b.sleeping && !b.isotropic {
            b.angular_velocity =
                omega_from_momentum(b.rotation, &b.inv_inertia, b.angular_momentum);
        }
        VelocityCounters::default()
    });
}

/// The quaternion rotation vector (axis × angle, angle in [0, π]) taking
/// orientation `from` to `to`.
pub(crate) fn rotation_delta(from: Quat, to: Quat) -> Vec3 {
    let d = (to * from.conjugate()).canonical();
    match d.xyz().normalize_and_length() {
        Some((axis, s)) => {
            let angle = crate::math::elem::atan2(s, d.w) * Scalar::TWO;
            axis * angle
        }
        None => Vec3::ZERO,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cayley_rotation_keeps_length_and_turns_by_two_atan() {
        let u = Vec3::new(Scalar::ZERO, Scalar::ZERO, Scalar::from_ratio(1, 10));
        let v = Vec3::X * Scalar::from_int(3);
        let r = cayley_rotate(u, v);
        let angle = 2.0 * 0.1f64.atan();
        assert!((r.x.to_f64() - 3.0 * angle.cos()).abs() < 1e-8);
        assert!((r.y.to_f64() - 3.0 * angle.sin()).abs() < 1e-8);
        assert!((r.length().to_f64() - 3.0).abs() < 1e-8);
    }
}
