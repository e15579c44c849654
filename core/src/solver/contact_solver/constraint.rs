//! The contact solver's per-body and per-contact data: the solver bodies
//! and their velocities, and the constraints with their points.

use super::arith::{round_wide, scale};
use super::params::Softness;
use crate::collision::MAX_MANIFOLD_POINTS;
use crate::math::scalar::wide_sum;
use crate::math::{Mat3, Quat, Scalar, SymMat3, Vec3};

/// Marks "no solver body": a static or sleeping body.
pub(super) const NONE: u32 = u32::MAX;

/// The solver's per-body velocity state, the only body data the iteration
/// loops read and write (48 bytes).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct BodyVel {
    /// Linear velocity.
    pub(super) v: Vec3,
    /// Angular velocity, world axes.
    pub(super) w: Vec3,
}

/// The solver's per-body constants for the tick and its pose change since
/// the start of the tick (read once per constraint and pass, never written
/// by the iterations).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct SolverBody {
    /// The body's slot in the body set.
    pub(super) slot: u32,
    /// Whether impulses move it (dynamic) or it only pushes (kinematic).
    pub(super) dynamic: bool,
    /// 1/mass (0 for kinematic).
    pub(super) inv_mass: Scalar,
    /// World inverse inertia `R I⁻¹ Rᵀ` at the start of the tick (zero for
    /// kinematic).
    pub(super) inv_inertia: SymMat3,
    /// Whether `inv_inertia` is a multiple of the identity (`xx`).
    pub(super) isotropic: bool,
    /// Centre at the start of the tick.
    pub(super) center0: Vec3,
    /// Conjugate of the rotation at the start of the tick.
    pub(super) rotation0_inv: Quat,
    /// Displacement of the centre since the start of the tick.
    pub(super) dp: Vec3,
    /// Rotation since the start of the tick, as a matrix.
    pub(super) dr: Mat3,
}

impl SolverBody {
    /// `I⁻¹ v` in world axes (one scale for an isotropic body).
    #[inline]
    pub(super) fn inv_inertia_mul(&self, v: Vec3) -> Vec3 {
        if self.isotropic {
            scale(v, self.inv_inertia.xx)
        } else {
            self.inv_inertia.mul_vec(v)
        }
    }
}

/// One contact point's constant terms and accumulated impulses.
///
/// The relative velocity of the anchors along a direction `d` is
/// `d·(vB − vA) + (rB×d)·ωB − (rA×d)·ωA`, and an impulse `λ` along `d`
/// changes `ω` by `λ·I⁻¹(r×d)`: both products are stored here, so an
/// iteration neither forms a cross product nor multiplies by an inertia.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct ConstraintPoint {
    /// The point of A's core behind the contact (the contact point for a
    /// flat-faced shape), relative to A's centre at the start of the tick:
    /// what the separation is followed through. Zero for no body.
    pub(super) ra: Vec3,
    /// The same on B.
    pub(super) rb: Vec3,
    /// `ra × n`, `rb × n`.
    pub(super) ra_n: Vec3,
    pub(super) rb_n: Vec3,
    /// `I⁻¹A (ra × n)`, `I⁻¹B (rb × n)`.
    pub(super) ia_n: Vec3,
    pub(super) ib_n: Vec3,
    /// Separation at the start of the tick minus `n·(rb − ra)`: adding the
    /// current anchor offset along `n` gives the current separation.
    pub(super) adjusted_separation: Scalar,
    /// Normal velocity (B relative to A) at the start of the tick, or at
    /// the first push if the approach was faster then: what restitution
    /// reflects.
    pub(super) relative_velocity: Scalar,
    /// `1/k` along the normal.
    pub(super) normal_mass: Scalar,
    /// Accumulated normal impulse (per substep).
    pub(super) normal_impulse: Scalar,
    /// The normal impulse at the last write-back of angular impulses (zero
    /// after a warm start, which applies it all again).
    pub(super) mark: Scalar,
    /// The largest normal impulse seen this tick (restitution only applies
    /// to points that pushed).
    pub(super) max_normal_impulse: Scalar,
    /// The current separation, as the constraint's cached frame gives it
    /// (see [`Constraint::frame_poses`]).
    pub(super) separation: Scalar,
}

/// How a constraint follows its points' current separation through the
/// substeps: a point's is its adjusted separation plus `n·(Δp_B − Δp_A) +
/// n·(ΔR_B r_B) − n·(ΔR_A r_A)`, and `n·(ΔR r) = (ΔRᵀ n)·r`, so the two
/// rotated normals and the displacement term are formed once per
/// constraint and visit, not two rotated anchors per point.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct SeparationFrame {
    /// `ΔR_Aᵀ n` and `ΔR_Bᵀ n` (zero for no body).
    pub(super) na: Vec3,
    pub(super) nb: Vec3,
    /// `n·(Δp_B − Δp_A)`, unrounded.
    pub(super) base: i128,
}

impl SeparationFrame {
    /// The frame of `c` at its bodies' current pose changes.
    #[inline(always)]
    pub(super) fn of(c: &Constraint, bodies: &[SolverBody]) -> SeparationFrame {
        SeparationFrame::at(c.normal, c.a, c.b, bodies)
    }

    /// The frame of normal `n` between solver bodies `a` and `b` (or
    /// `NONE`) at their current pose changes.
    #[inline(always)]
    pub(super) fn at(n: Vec3, a: u32, b: u32, bodies: &[SolverBody]) -> SeparationFrame {
        let (na, dpa) = if a == NONE {
            (Vec3::ZERO, Vec3::ZERO)
        } else {
            let b = &bodies[a as usize];
            (b.dr.transpose_mul_vec(n), b.dp)
        };
        let (nb, dpb) = if b == NONE {
            (Vec3::ZERO, Vec3::ZERO)
        } else {
            let b = &bodies[b as usize];
            (b.dr.transpose_mul_vec(n), b.dp)
        };
        SeparationFrame {
            na,
            nb,
            base: n.dot_wide(dpb - dpa),
        }
    }

    /// The current separation of point `cp` of the constraint.
    #[inline(always)]
    pub(super) fn separation(&self, cp: &ConstraintPoint) -> Scalar {
        self.separation_at(cp.ra, cp.rb, cp.adjusted_separation)
    }

    /// The current separation of a point with anchors `ra`, `rb` and
    /// adjusted separation `adjusted` (see [`ConstraintPoint`]).
    #[inline(always)]
    pub(super) fn separation_at(&self, ra: Vec3, rb: Vec3, adjusted: Scalar) -> Scalar {
        round_wide(wide_sum([
            self.base,
            self.nb.dot_wide(rb),
            -self.na.dot_wide(ra),
        ])) + adjusted
    }
}

/// One solid pair's constraint.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Constraint {
    /// Index of the pair in the contact set.
    pub(super) pair: u32,
    /// Solver body indices (or `NONE`).
    pub(super) a: u32,
    pub(super) b: u32,
    /// The same for the bodies the passes write: `a` and `b` if dynamic,
    /// `NONE` for a kinematic body (whose velocity no impulse changes, and
    /// which two constraints of one colour may share).
    pub(super) wa: u32,
    pub(super) wb: u32,
    pub(super) normal: Vec3,
    pub(super) tangent: [Vec3; 2],
    /// `1/mass` of A and of B (zero for none, static or kinematic).
    pub(super) inv_mass_a: Scalar,
    pub(super) inv_mass_b: Scalar,
    /// Their sum: how fast the relative velocity along a unit direction
    /// changes per unit impulse along it, linear part.
    pub(super) inv_mass_sum: Scalar,
    /// The contact spring of this constraint's soft pass: the world's, or
    /// a stiffer one for a high mass ratio (see [`RATIO_KEPT`]).
    pub(super) softness: Softness,
    pub(super) friction: Scalar,
    pub(super) restitution: Scalar,
    /// How far A's and B's surfaces lie out from their cores (see
    /// [`PairInfo::rounding`]); read by `prepare` only.
    pub(super) rounding: [Scalar; 2],
    /// The manifold's total normal impulse at this substep's warm start
    /// (the last substep's, or last tick's): what bounds friction through
    /// the substep's soft passes (see [`Pass::friction`](super::pass::Pass::friction)).
    pub(super) warm_total: Scalar,
    /// The friction rows, acting at the centre of the patch.
    pub(super) patch: Patch,
    pub(super) count: usize,
    pub(super) points: [ConstraintPoint; MAX_MANIFOLD_POINTS],
    /// The separation frame at the bodies' poses numbered `frame_poses`
    /// (see [`ContactSolver::poses`]), and each point's separation from it:
    /// the poses change once per substep (before the relax pass), but the
    /// next substep's solve pass, and every extra pass or visit at the same
    /// poses, would compute the same frame again. Set by a visit's first
    /// pass at new poses; 0 (never a pose number) after `prepare`.
    pub(super) frame: SeparationFrame,
    pub(super) frame_poses: u32,
    /// Whether this constraint takes a hit this tick (see
    /// [`ContactSolver::impact`](super::ContactSolver)): its visits start
    /// with [`Pass::hit_row`](super::pass::Pass::hit_row).
    pub(super) hit: bool,
}

/// Friction of one manifold, solved at the centre of its contact patch
/// (the mean of its points) rather than at every point: two tangent rows
/// whose impulse is held in a disc of radius μ times the manifold's total
/// normal impulse, and a twist row
/// about the normal bounded by μ times that total times the points' mean
/// distance from the centre. For a patch whose points share the load, the
/// friction force and its moment about the centre are the same as
/// per-point friction's, with three rows per manifold instead of two per
/// point (eight for a box face).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Patch {
    /// `ra × t_j`, `rb × t_j` for the anchor at the patch centre.
    pub(super) ra_t: [Vec3; 2],
    pub(super) rb_t: [Vec3; 2],
    /// `I⁻¹A (ra × t_j)`, `I⁻¹B (rb × t_j)`.
    pub(super) ia_t: [Vec3; 2],
    pub(super) ib_t: [Vec3; 2],
    /// `1/k` along each tangent.
    pub(super) tangent_mass: [Scalar; 2],
    /// `I⁻¹A n`, `I⁻¹B n`: the spin change per unit twist impulse.
    pub(super) ia_w: Vec3,
    pub(super) ib_w: Vec3,
    /// `1/k` of the twist row.
    pub(super) twist_mass: Scalar,
    /// μ times the points' mean distance from the centre: the twist bound
    /// per unit of total normal impulse.
    pub(super) twist_reach: Scalar,
    /// `1/m_eff` of the two tangent rows and of the twist row (what the
    /// narrow rows' impulses are scaled by, see `narrow`).
    pub(super) k: [Scalar; 3],
    /// Accumulated tangent and twist impulses.
    pub(super) tangent_impulse: [Scalar; 2],
    pub(super) twist_impulse: Scalar,
    /// The two tangent and the twist impulses at the last write-back of
    /// angular impulses.
    pub(super) mark: [Scalar; 3],
}

/// What `prepare`'s first scan found for one candidate pair, before its
/// constraint's place in colour order is known.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Pending {
    /// Whether the pair makes a constraint this tick (solid, with points,
    /// and a moving dynamic body); if not, the rest is unset.
    pub(super) used: bool,
    pub(super) pair: u32,
    /// Slots of the moving bodies (`NONE` for a static or sleeping one).
    pub(super) a: u32,
    pub(super) b: u32,
    /// Slots of the moving dynamic bodies, the ones a colour takes (`NONE`
    /// for any other).
    pub(super) dyn_a: u32,
    pub(super) dyn_b: u32,
    pub(super) friction: Scalar,
    pub(super) restitution: Scalar,
    pub(super) rounding: [Scalar; 2],
}

/// One visit of the shock pass: a constraint and which of its bodies is
/// the upper one (the one that moves).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord)]
pub(super) struct ShockRow {
    /// The lower body's level (sort key first).
    pub(super) level: u32,
    /// Index of the constraint (second key: unique, so the order is total).
    pub(super) constraint: u32,
    /// Whether the upper body is B (else A).
    pub(super) upper_is_b: bool,
}

/// The `kk`-th normal row visited, of a manifold's `count` (≥ 1), in the
/// passes of substep `rot` (the solver's substep counter): the rows start at
/// point `rot mod count` and go round, forward in even substeps and backward
/// in odd ones (`rot mod count`, then one less, …). Always the same start
/// lets a manifold's first point take more than its share of the load (a
/// stack of 20 without sleeping rocked by 8 cm; rotating the start keeps it
/// within a millimetre). Always the same direction goes round a face's
/// corners the same way every substep, and the last row visited sees every
/// other row's push: in a stack or pyramid of equal boxes that bias tilted
/// every box the same way while they sagged and rebounded, and seeded the
/// column's bending mode. Alternating the direction costs no extra visit.
/// Every row path (the Q32.32 rows and their lanes, the narrow rows and
/// their lanes) visits in this order.
#[inline(always)]
pub(super) fn row_order(kk: usize, count: usize, rot: usize) -> usize {
    debug_assert!(kk < count);
    let start = rot % count;
    // Both sums are below 2·count: one subtraction brings them into range.
    let k = if rot & 1 == 0 {
        start + kk
    } else {
        start + count - kk
    };
    if k >= count { k - count } else { k }
}
