//! The contact solver: soft-step sequential impulses (after Box2D v3's
//! "soft step").
//!
//! Per tick, `prepare` builds a compact array of solver bodies (awake dynamic
//! and kinematic bodies that appear in a solid contact, in slot order;
//! static and sleeping bodies are an implicit zero-velocity, infinite-mass
//! body) and one constraint per solid pair with points, in pair order. Anchors
//! are taken relative to the body centres at the start of the tick, and the
//! effective masses are computed there once (the iteration loops never
//! divide). Then, per substep:
//!
//! 1. the integrator's velocity stage (outside this module);
//! 2. [`ContactSolver::warm_start`]: last impulses applied again;
//! 3. [`ContactSolver::solve`] with bias: a soft constraint (spring at
//!    `contact_hertz`, damping ratio `contact_damping_ratio`) pushes
//!    overlaps apart at no more than `max_push_out` m/s; speculative points
//!    (a gap) allow the approach that just closes the gap in one substep;
//! 4. the integrator's position stage;
//! 5. [`ContactSolver::solve`] without bias (relax): removes the velocity
//!    the soft push-out added, so resting contacts do not bounce.
//!
//! After the substeps, [`ContactSolver::restitution`] gives points that hit
//! faster than `restitution_threshold` their bounce, and
//! [`ContactSolver::store_impulses`] hands the accumulated impulses back to
//! the contact pairs for warm starting next tick.
//!
//! The current separation of a point during the substeps is its separation
//! at the start of the tick plus the relative displacement of its two
//! anchors along the normal, from each body's change of position and
//! orientation since the start of the tick: no narrow phase per substep.
//!
//! Angular impulses are added to each dynamic body's angular momentum
//! exactly (`ΔL = Σ r × P`), and the solver's angular velocity moves by
//! `I⁻¹_world ΔL`: a body that no contact touches keeps `L` bit for bit, and
//! the world's total angular momentum changes only by rounding of the
//! contact impulses themselves.
//!
//! Determinism: bodies in slot (handle) order, constraints in pair order
//! (ascending collider handles), points in manifold order.

use crate::body::{BodyHot, BodyKind};
use crate::collision::{ContactPair, MAX_MANIFOLD_POINTS, PairKind, PointImpulse};
use crate::math::{Mat3, Quat, Scalar, SymMat3, Vec3};

/// Marks "no solver body": a static or sleeping body.
const NONE: u32 = u32::MAX;

/// The solver's per-body state for one tick (about 200 bytes).
#[derive(Clone, Copy, Debug, Default)]
struct SolverBody {
    /// The body's slot in the body set.
    slot: u32,
    /// Whether impulses move it (dynamic) or it only pushes (kinematic).
    dynamic: bool,
    /// Linear velocity.
    v: Vec3,
    /// Angular velocity, world axes.
    w: Vec3,
    /// Angular impulse applied since the last write-back.
    dl: Vec3,
    /// 1/mass (0 for kinematic).
    inv_mass: Scalar,
    /// World inverse inertia `R I⁻¹ Rᵀ` at the start of the tick.
    inv_inertia: SymMat3,
    /// Centre at the start of the tick.
    center0: Vec3,
    /// Conjugate of the rotation at the start of the tick.
    rotation0_inv: Quat,
    /// Displacement of the centre since the start of the tick.
    dp: Vec3,
    /// Rotation since the start of the tick.
    dq: Quat,
}

/// One contact point's constant terms and accumulated impulses.
#[derive(Clone, Copy, Debug, Default)]
struct ConstraintPoint {
    /// Anchor on A, relative to A's centre at the start of the tick.
    ra: Vec3,
    /// Anchor on B.
    rb: Vec3,
    /// Separation at the start of the tick minus `n·(rb − ra)`: adding the
    /// current anchor offset along `n` gives the current separation.
    adjusted_separation: Scalar,
    /// Normal velocity (B relative to A) at the start of the tick, or at
    /// the first push if the approach was faster then: what restitution
    /// reflects.
    relative_velocity: Scalar,
    /// `1/k` along the normal.
    normal_mass: Scalar,
    /// `1/k` along each tangent.
    tangent_mass: [Scalar; 2],
    /// `ra × n`, `rb × n`, and the same for the two tangents.
    ra_n: Vec3,
    rb_n: Vec3,
    ra_t: [Vec3; 2],
    rb_t: [Vec3; 2],
    /// Accumulated normal impulse (per substep).
    normal_impulse: Scalar,
    /// Accumulated friction impulses.
    tangent_impulse: [Scalar; 2],
    /// The largest normal impulse seen this tick (restitution only applies
    /// to points that pushed).
    max_normal_impulse: Scalar,
}

/// One solid pair's constraint.
#[derive(Clone, Copy, Debug, Default)]
struct Constraint {
    /// Index of the pair in the contact set.
    pair: u32,
    /// Solver body indices (or `NONE`).
    a: u32,
    b: u32,
    normal: Vec3,
    tangent: [Vec3; 2],
    friction: Scalar,
    restitution: Scalar,
    count: usize,
    points: [ConstraintPoint; MAX_MANIFOLD_POINTS],
}

/// Softness of the contact spring for a substep.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Softness {
    /// `ω/(2ζ + hω)`: converts a separation into a velocity bias.
    pub bias_rate: Scalar,
    /// `hω(2ζ + hω)/(1 + hω(2ζ + hω))`: scales the effective mass.
    pub mass_scale: Scalar,
    /// `1/(1 + hω(2ζ + hω))`: how much of the accumulated impulse relaxes.
    pub impulse_scale: Scalar,
}

impl Softness {
    /// A spring of `hertz` with damping ratio `zeta`, stepped at `h`
    /// (Box2D's `b2MakeSoft`). A zero frequency gives a rigid constraint
    /// without bias.
    pub(crate) fn new(hertz: Scalar, zeta: Scalar, h: Scalar) -> Softness {
        if !hertz.is_positive() {
            return Softness {
                bias_rate: Scalar::ZERO,
                mass_scale: Scalar::ONE,
                impulse_scale: Scalar::ZERO,
            };
        }
        let omega = Scalar::TAU * hertz;
        let a1 = Scalar::TWO * zeta + h * omega;
        let a2 = h * omega * a1;
        let a3 = (Scalar::ONE + a2).recip();
        Softness {
            bias_rate: omega.checked_div(a1).unwrap_or(Scalar::ZERO),
            mass_scale: a2 * a3,
            impulse_scale: a3,
        }
    }
}

/// Settings the solver reads each tick.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SolverParams {
    /// `1/h`.
    pub inv_h: Scalar,
    /// The contact spring.
    pub softness: Softness,
    /// Cap on the push-out speed of overlapping shapes, m/s.
    pub max_push_out: Scalar,
    /// Normal approach speed below which there is no bounce, m/s.
    pub restitution_threshold: Scalar,
}

/// Counters from one tick's solve.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct SolverStats {
    /// Constraints (solid pairs with points).
    pub constraints: u32,
    /// Times a buffer grew.
    pub growths: u32,
}

/// The solver's buffers, kept by the world and reused every tick.
#[derive(Clone, Debug, Default)]
pub(crate) struct ContactSolver {
    bodies: Vec<SolverBody>,
    /// Slot → solver body index, or `NONE`.
    body_of_slot: Vec<u32>,
    constraints: Vec<Constraint>,
}

/// What `prepare` needs to know about one pair: the body slots of its two
/// colliders and the combined material.
pub(crate) struct PairInfo {
    /// Slot of collider A's body.
    pub slot_a: u32,
    /// Slot of collider B's body.
    pub slot_b: u32,
    /// Combined friction coefficient.
    pub friction: Scalar,
    /// Combined restitution.
    pub restitution: Scalar,
}

#[inline]
fn ang_delta(i: &SymMat3, r_x_p: Vec3) -> Vec3 {
    i.mul_vec(r_x_p)
}

impl ContactSolver {
    /// Builds the solver bodies and constraints for this tick from the
    /// contact pairs (at the poses and velocities of the start of the tick).
    ///
    /// Determinism: pairs in contact-set order; bodies in slot order.
    pub(crate) fn prepare(
        &mut self,
        pairs: &[ContactPair],
        hot: &[BodyHot],
        mut info: impl FnMut(&ContactPair) -> Option<PairInfo>,
    ) -> SolverStats {
        let caps = (
            self.bodies.capacity(),
            self.body_of_slot.capacity(),
            self.constraints.capacity(),
        );
        self.bodies.clear();
        self.constraints.clear();
        self.body_of_slot.clear();
        self.body_of_slot.resize(hot.len(), NONE);
        let moves = |slot: u32| {
            let b = &hot[slot as usize];
            b.kind != BodyKind::Static && !b.sleeping
        };
        // 1. Constraints (body indices filled in below) and the set of
        //    bodies they touch.
        for (i, p) in pairs.iter().enumerate() {
            if p.kind != PairKind::Solid || p.manifold.is_empty() {
                continue;
            }
            let Some(pi) = info(p) else { continue };
            if pi.slot_a as usize >= hot.len() || pi.slot_b as usize >= hot.len() {
                continue;
            }
            let (ma, mb) = (moves(pi.slot_a), moves(pi.slot_b));
            let dyn_a = ma && hot[pi.slot_a as usize].kind == BodyKind::Dynamic;
            let dyn_b = mb && hot[pi.slot_b as usize].kind == BodyKind::Dynamic;
            if !dyn_a && !dyn_b {
                continue;
            }
            if ma {
                self.body_of_slot[pi.slot_a as usize] = 0;
            }
            if mb {
                self.body_of_slot[pi.slot_b as usize] = 0;
            }
            self.constraints.push(Constraint {
                pair: i as u32,
                a: if ma { pi.slot_a } else { NONE },
                b: if mb { pi.slot_b } else { NONE },
                friction: pi.friction,
                restitution: pi.restitution,
                ..Constraint::default()
            });
        }
        // 2. Solver bodies in slot order.
        for (slot, idx) in self.body_of_slot.iter_mut().enumerate() {
            if *idx == NONE {
                continue;
            }
            *idx = self.bodies.len() as u32;
            let b = &hot[slot];
            let dynamic = b.kind == BodyKind::Dynamic;
            let inv_inertia = if dynamic {
                b.inv_inertia.rotate(&Mat3::from_quat(b.rotation))
            } else {
                SymMat3::ZERO
            };
            self.bodies.push(SolverBody {
                slot: slot as u32,
                dynamic,
                v: b.linear_velocity,
                w: b.angular_velocity,
                dl: Vec3::ZERO,
                inv_mass: if dynamic { b.inv_mass } else { Scalar::ZERO },
                inv_inertia,
                center0: b.center,
                rotation0_inv: b.rotation.conjugate(),
                dp: Vec3::ZERO,
                dq: Quat::IDENTITY,
            });
        }
        // 3. Constant terms of each point.
        for c in &mut self.constraints {
            let p = &pairs[c.pair as usize];
            c.a = if c.a == NONE {
                NONE
            } else {
                self.body_of_slot[c.a as usize]
            };
            c.b = if c.b == NONE {
                NONE
            } else {
                self.body_of_slot[c.b as usize]
            };
            let zero = SolverBody {
                dq: Quat::IDENTITY,
                rotation0_inv: Quat::IDENTITY,
                ..SolverBody::default()
            };
            let ba = if c.a == NONE {
                zero
            } else {
                self.bodies[c.a as usize]
            };
            let bb = if c.b == NONE {
                zero
            } else {
                self.bodies[c.b as usize]
            };
            let n = p.manifold.normal;
            let t0 = tangent_of(n);
            let t1 = n.cross(t0);
            c.normal = n;
            c.tangent = [t0, t1];
            c.count = p.manifold.points().len();
            let ca = if c.a == NONE { Vec3::ZERO } else { ba.center0 };
            let cb = if c.b == NONE { Vec3::ZERO } else { bb.center0 };
            for (k, (mp, imp)) in p.manifold.points().iter().zip(&p.impulses).enumerate() {
                let cp = &mut c.points[k];
                // Static bodies contribute nothing through their anchor, so
                // any reference point works; the contact point itself keeps
                // the numbers small.
                let ra = if c.a == NONE {
                    Vec3::ZERO
                } else {
                    mp.point - ca
                };
                let rb = if c.b == NONE {
                    Vec3::ZERO
                } else {
                    mp.point - cb
                };
                cp.ra = ra;
                cp.rb = rb;
                cp.adjusted_separation = -mp.depth - n.dot(rb - ra);
                cp.ra_n = ra.cross(n);
                cp.rb_n = rb.cross(n);
                let k_n = effective(&ba, &bb, cp.ra_n, cp.rb_n);
                cp.normal_mass = inverse_or_zero(k_n);
                for j in 0..2 {
                    cp.ra_t[j] = ra.cross(c.tangent[j]);
                    cp.rb_t[j] = rb.cross(c.tangent[j]);
                    cp.tangent_mass[j] =
                        inverse_or_zero(effective(&ba, &bb, cp.ra_t[j], cp.rb_t[j]));
                }
                let dv = (bb.v + bb.w.cross(rb)) - (ba.v + ba.w.cross(ra));
                cp.relative_velocity = n.dot(dv);
                cp.normal_impulse = imp.normal;
                cp.tangent_impulse = imp.tangent;
                cp.max_normal_impulse = Scalar::ZERO;
            }
        }
        let grew = (
            self.bodies.capacity(),
            self.body_of_slot.capacity(),
            self.constraints.capacity(),
        ) != caps;
        SolverStats {
            constraints: self.constraints.len() as u32,
            growths: grew as u32,
        }
    }

    /// Whether there is anything to solve this tick.
    pub(crate) fn is_empty(&self) -> bool {
        self.constraints.is_empty()
    }

    /// Reads the bodies' current velocities and pose changes (after the
    /// integrator touched them).
    pub(crate) fn gather(&mut self, hot: &[BodyHot]) {
        for sb in &mut self.bodies {
            let b = &hot[sb.slot as usize];
            sb.v = b.linear_velocity;
            sb.w = b.angular_velocity;
            sb.dp = b.center - sb.center0;
            sb.dq = b.rotation * sb.rotation0_inv;
        }
    }

    /// Writes the solved velocities back; the angular impulses go into the
    /// angular momentum exactly.
    pub(crate) fn scatter(&mut self, hot: &mut [BodyHot]) {
        for sb in &mut self.bodies {
            if !sb.dynamic {
                continue;
            }
            let b = &mut hot[sb.slot as usize];
            b.linear_velocity = sb.v;
            b.angular_velocity = sb.w;
            b.angular_momentum += sb.dl;
            sb.dl = Vec3::ZERO;
        }
    }

    /// Applies last substep's (or last tick's) accumulated impulses again.
    pub(crate) fn warm_start(&mut self) {
        let bodies = &mut self.bodies;
        for c in &self.constraints {
            let (mut ba, mut bb) = load(bodies, c.a, c.b);
            for cp in &c.points[..c.count] {
                let p = c.normal * cp.normal_impulse
                    + c.tangent[0] * cp.tangent_impulse[0]
                    + c.tangent[1] * cp.tangent_impulse[1];
                let ang_a = cp.ra.cross(p);
                let ang_b = cp.rb.cross(p);
                apply(&mut ba, -p, -ang_a);
                apply(&mut bb, p, ang_b);
            }
            store(bodies, c.a, c.b, ba, bb);
        }
    }

    /// One pass over every constraint: friction, then the normal impulses
    /// (soft with `use_bias`, rigid without).
    pub(crate) fn solve(&mut self, params: &SolverParams, use_bias: bool) {
        let bodies = &mut self.bodies;
        for c in &mut self.constraints {
            let (mut ba, mut bb) = load(bodies, c.a, c.b);
            let n = c.normal;
            // Friction, bounded by μ times the current normal impulse.
            for cp in &mut c.points[..c.count] {
                let limit = c.friction * cp.normal_impulse;
                for j in 0..2 {
                    let t = c.tangent[j];
                    let dv = relative_velocity(&ba, &bb, cp.ra, cp.rb);
                    let vt = t.dot(dv);
                    let lambda = -(cp.tangent_mass[j] * vt);
                    let old = cp.tangent_impulse[j];
                    let new = (old + lambda).clamp(-limit, limit);
                    let d = new - old;
                    cp.tangent_impulse[j] = new;
                    let p = t * d;
                    apply(&mut ba, -p, -(cp.ra_t[j] * d));
                    apply(&mut bb, p, cp.rb_t[j] * d);
                }
            }
            // Non-penetration.
            for cp in &mut c.points[..c.count] {
                let d = (bb.dp - ba.dp) + (bb.dq.rotate(cp.rb) - ba.dq.rotate(cp.ra));
                let s = n.dot(d) + cp.adjusted_separation;
                let (bias, mass_scale, impulse_scale) = if s.is_positive() {
                    (s * params.inv_h, Scalar::ONE, Scalar::ZERO)
                } else if use_bias {
                    (
                        (params.softness.bias_rate * s).max(-params.max_push_out),
                        params.softness.mass_scale,
                        params.softness.impulse_scale,
                    )
                } else {
                    (Scalar::ZERO, Scalar::ONE, Scalar::ZERO)
                };
                let dv = relative_velocity(&ba, &bb, cp.ra, cp.rb);
                let vn = n.dot(dv);
                let lambda = -(cp.normal_mass * mass_scale * (vn + bias))
                    - impulse_scale * cp.normal_impulse;
                let old = cp.normal_impulse;
                let new = (old + lambda).max(Scalar::ZERO);
                let d = new - old;
                if cp.max_normal_impulse.is_zero() && new.is_positive() {
                    // First push this tick (in a solve or a relax pass):
                    // the approach speed at impact, gravity included up to
                    // this substep, is what restitution reflects, not the
                    // speed at the start of the tick.
                    cp.relative_velocity = cp.relative_velocity.min(vn);
                }
                cp.normal_impulse = new;
                cp.max_normal_impulse = cp.max_normal_impulse.max(new);
                let p = n * d;
                apply(&mut ba, -p, -(cp.ra_n * d));
                apply(&mut bb, p, cp.rb_n * d);
            }
            store(bodies, c.a, c.b, ba, bb);
        }
    }

    /// After the substeps: points that approached faster than the threshold
    /// and pushed get the normal velocity `−e·v_before`.
    pub(crate) fn restitution(&mut self, params: &SolverParams) {
        let bodies = &mut self.bodies;
        let threshold = -params.restitution_threshold;
        for c in &mut self.constraints {
            if c.restitution.is_zero() {
                continue;
            }
            let (mut ba, mut bb) = load(bodies, c.a, c.b);
            let n = c.normal;
            for cp in &mut c.points[..c.count] {
                if cp.relative_velocity > threshold || cp.max_normal_impulse.is_zero() {
                    continue;
                }
                let dv = relative_velocity(&ba, &bb, cp.ra, cp.rb);
                let vn = n.dot(dv);
                let lambda = -(cp.normal_mass * (vn + c.restitution * cp.relative_velocity));
                let old = cp.normal_impulse;
                let new = (old + lambda).max(Scalar::ZERO);
                let d = new - old;
                cp.normal_impulse = new;
                cp.max_normal_impulse = cp.max_normal_impulse.max(new);
                let p = n * d;
                apply(&mut ba, -p, -(cp.ra_n * d));
                apply(&mut bb, p, cp.rb_n * d);
            }
            store(bodies, c.a, c.b, ba, bb);
        }
    }

    /// Hands the accumulated impulses back to the pairs (warm starting next
    /// tick).
    pub(crate) fn store_impulses(&self, pairs: &mut [ContactPair]) {
        for c in &self.constraints {
            let p = &mut pairs[c.pair as usize];
            for (k, cp) in c.points[..c.count].iter().enumerate() {
                p.impulses[k] = PointImpulse {
                    normal: cp.normal_impulse,
                    tangent: cp.tangent_impulse,
                };
            }
        }
    }
}

/// A unit tangent for normal `n`, continuous for normals within about 54°
/// of the y or z axis and of the x axis: the switch between the two
/// formulas (at |n.x| = 0.577) is far from the axis-aligned normals of
/// resting contacts, so the friction impulses carried from last tick keep
/// their directions while a normal wobbles.
fn tangent_of(n: Vec3) -> Vec3 {
    // 0.57735 ≈ 1/√3 (bits of 0.57735·2³²): every unit vector has a
    // component at least this big.
    const SWITCH: Scalar = Scalar::from_bits(2_479_700_526);
    if n.x.abs() >= SWITCH {
        Vec3::new(n.y, -n.x, Scalar::ZERO).normalize_or_zero()
    } else {
        Vec3::new(Scalar::ZERO, n.z, -n.y).normalize_or_zero()
    }
}

/// `1/k`, or zero when `k` is zero (two infinite masses never reach here,
/// but a degenerate inertia must not divide by zero).
fn inverse_or_zero(k: Scalar) -> Scalar {
    if k.is_positive() {
        k.recip()
    } else {
        Scalar::ZERO
    }
}

/// `k = 1/mA + 1/mB + (rA×d)·I⁻¹A(rA×d) + (rB×d)·I⁻¹B(rB×d)`.
fn effective(a: &SolverBody, b: &SolverBody, ra_d: Vec3, rb_d: Vec3) -> Scalar {
    let wide = a.inv_mass.to_bits() as i128 * (1i128 << 32)
        + b.inv_mass.to_bits() as i128 * (1i128 << 32)
        + ra_d.dot_wide(a.inv_inertia.mul_vec(ra_d))
        + rb_d.dot_wide(b.inv_inertia.mul_vec(rb_d));
    Scalar::from_wide(wide)
}

/// Velocity of B's anchor relative to A's.
#[inline]
fn relative_velocity(a: &SolverBody, b: &SolverBody, ra: Vec3, rb: Vec3) -> Vec3 {
    (b.v + b.w.cross(rb)) - (a.v + a.w.cross(ra))
}

/// Applies a linear impulse `p` and angular impulse `r × p` to a body.
#[inline]
fn apply(b: &mut SolverBody, p: Vec3, ang: Vec3) {
    if !b.dynamic {
        return;
    }
    b.v += p * b.inv_mass;
    b.w += ang_delta(&b.inv_inertia, ang);
    b.dl += ang;
}

fn load(bodies: &[SolverBody], a: u32, b: u32) -> (SolverBody, SolverBody) {
    let get = |i: u32| {
        if i == NONE {
            SolverBody {
                dq: Quat::IDENTITY,
                rotation0_inv: Quat::IDENTITY,
                ..SolverBody::default()
            }
        } else {
            bodies[i as usize]
        }
    };
    (get(a), get(b))
}

fn store(bodies: &mut [SolverBody], a: u32, b: u32, ba: SolverBody, bb: SolverBody) {
    if a != NONE {
        bodies[a as usize] = ba;
    }
    if b != NONE {
        bodies[b as usize] = bb;
    }
}
