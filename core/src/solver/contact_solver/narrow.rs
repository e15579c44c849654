//! The narrow exact rows: the contact rows on 32-bit operands with exact
//! 64-bit sums. The functions here are the scalar twin: the definition that
//! any lane kernel must reproduce bit for bit.
//!
//! # The format
//!
//! Each accumulated row impulse is kept in velocity units, `Λ = λ·k` with
//! `k = 1/m_eff` (the relative velocity change the impulse causes along its
//! row), so that every row quantity is dimensionless or a lever arm:
//!
//! - velocities (`V`, `Ω`) and impulses (`Λ`) are integers of 2⁻²⁰ m/s
//!   (rad/s) ([`S`]): a quantum of 9.5e-7 m/s, ±512 m/s within the guard;
//! - Jacobian entries (`n`, `t₀`, `t₁`, `r×n`, `r×t`) are integers at
//!   `2^je`, one exponent per constraint (`je ≤ 30`, so `|entry| ≤ 2³⁰`);
//! - response entries (`e = m_eff·m⁻¹·d`, at most 1, and `c =
//!   m_eff·I⁻¹(r×d)`, 1/m) are integers at `2^ae`, one exponent per
//!   constraint; angular-momentum entries (`g = m_eff·(r×d)`, kg·m) at
//!   `2^ge`; the tangent effective masses (the friction disc) at `2^me`.
//!
//! A normal row is then `vn = J·V` (nine products, one rounding),
//! `Λ' = max(ms·(Λ − vn − bias), 0)` (one product and one rounding in the
//! soft pass, `ms` the spring's mass scale in Q1.30; none in the rigid
//! one: `ms + is = 1` turns the soft step's two terms into one), and each
//! body's velocity moves by `d·e` and `d·c` (`d = Λ' − Λ`, each product
//! rounded once). A tangent row is `Λ' = Λ − vt` held in the friction disc
//! `|Λ'·m_t| ≤ μ·total` (an exact integer comparison; a sliding patch is
//! scaled onto the rim), the twist row `Λ' = clamp(Λ − spin, ±limit)`.
//! The warm start applies each `Λ` through the same responses; the angular
//! write-back adds `Σ g·ΔΛ` to each body's angular momentum (one exact sum
//! per body and visit, rounded once to Q32.32).
//!
//! Every product is of two integers below 2³¹ in magnitude (an `i32 × i32
//! → i64`), and every sum is exact in `i64`: the bound is written at each
//! sum, and it holds because a guard checks, at each visit, that every
//! velocity read and written and every impulse stays below 2²⁹ and every
//! row's unclamped value below 2³¹. One rounding rule everywhere: add half,
//! shift right (to nearest, ties toward +∞).
//!
//! # What stays Q32.32
//!
//! The bodies' velocities between passes (a pass works on each body's
//! velocity in quanta, see [`Quanta`], and adds the exact change back at
//! its end, so a body's low bits are never lost) and angular momenta,
//! positions and orientations, the accumulated impulses the pairs store
//! (`λ = Λ·m_eff`, rounded once, written back before restitution),
//! restitution, and the high-mass-ratio contacts (their rows and the shock
//! pass). The points' separations, from which the biases come, are in the
//! narrow kind of arithmetic too (see [`separations`]).
//!
//! # The guard
//!
//! A constraint whose numbers do not fit at `prepare` (a mass ratio above
//! the solver's kept ratio, a lever arm or response beyond the exponents'
//! range, an impulse past the guard) is solved on the Q32.32 rows for the
//! whole tick. A visit whose guard fails writes nothing; the constraint's
//! impulses go back to Q32.32 and the Q32.32 rows solve it from that visit
//! to the end of the tick, alike on every machine. `StepReport` counts
//! both.

use std::sync::atomic::{AtomicU32, Ordering};

use super::constraint::{BodyVel, Constraint, NONE};
use super::params::SolverParams;
use super::quanta::{Quanta, S, TO_Q, from_quanta3, quanta, rsh};
use super::rows::{BodyArrays, mul};
use crate::collision::manifold::MAX_MANIFOLD_POINTS;
use crate::math::lanes::narrow as narrow_q32;
use crate::math::{Mat3, Scalar, Vec3};

pub(super) mod lanes;
mod prepare;

pub(super) use prepare::prepare;

/// The guard on every velocity component and accumulated impulse, in
/// quanta (exclusive): ±512 m/s at [`S`] = 20.
const LIMIT: i64 = 1 << 29;

/// The guard on a row's unclamped value (`Λ − vn − bias`, `Λ − vt`).
const ROW_LIMIT: i64 = 1 << 31;

/// The largest entry exponent: entries at `2^30` hold magnitudes up to 1
/// exactly in 31 bits.
const MAX_EXP: i32 = 30;

/// The smallest entry exponent accepted: a constraint whose largest lever
/// arm, response or angular-momentum entry would need less (a lever over
/// 16 km, an angular response over 16,384 /m, an effective mass times
/// lever over 16,384 kg·m) is solved on the Q32.32 rows instead, whose
/// entries keep their precision.
const MIN_EXP: i32 = 16;

/// Row indices: the normal rows of the points first, then the two tangent
/// rows and the twist row of the patch.
const T0: usize = MAX_MANIFOLD_POINTS;
const TW: usize = MAX_MANIFOLD_POINTS + 2;
/// Rows per constraint.
const ROWS: usize = MAX_MANIFOLD_POINTS + 3;

/// One row's constant entries: Jacobian (`ja`, `jb`: `r×d` at `2^je`),
/// responses (`ea`, `eb`, `ca`, `cb` at `2^ae`) and angular-momentum
/// entries (`ga`, `gb` at `2^ge`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Row {
    ja: [i32; 3],
    jb: [i32; 3],
    ea: [i32; 3],
    eb: [i32; 3],
    ca: [i32; 3],
    cb: [i32; 3],
    ga: [i32; 3],
    gb: [i32; 3],
}

/// One constraint's narrow rows: everything its passes read and write but
/// the bodies' poses (see the module docs). The state a visit reads and
/// writes comes first, in the first three cache lines; the constants
/// after it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[repr(C)]
pub(super) struct NarrowRows {
    /// Whether the constraint is solved on these rows this tick (else on
    /// the Q32.32 rows).
    pub(super) on: bool,
    /// Whether `disc_limit`/`twist_limit` hold the bounds of the warm
    /// start's total normal impulse (else each visit takes the current
    /// one).
    limits_set: bool,
    count: u8,
    /// Exponents of the Jacobian, response, angular-momentum entries and
    /// of the tangent masses.
    je: u8,
    ae: u8,
    ge: u8,
    me: i8,
    /// Per point: whether the cached separation is a gap (a rigid,
    /// speculative row), and whether `bias` was saturated.
    speculative: [bool; MAX_MANIFOLD_POINTS],
    saturated: [bool; MAX_MANIFOLD_POINTS],
    /// The lanes' batch this constraint starts (see [`lanes`]), or `NONE`.
    pub(super) batch: u32,
    /// Solver bodies (or `NONE`) and the dynamic ones the passes write.
    a: u32,
    b: u32,
    wa: u32,
    wb: u32,
    /// The pose number (see `ContactSolver::poses`) the points' `bias` was
    /// computed at; 0: never.
    bias_poses: u32,
    /// Accumulated impulses Λ (quanta) of every row, and their values at
    /// the last angular write-back.
    impulse: [i32; ROWS],
    mark: [i32; ROWS],
    /// Per point: the largest Λ this tick (restitution applies only to
    /// points that pushed); the normal velocity at the first push
    /// (`i32::MAX`: none yet); the bias at the cached separation (the
    /// speculative `s/h` for a gap, else the soft push-out, quanta,
    /// saturated at ±2³⁰).
    max_impulse: [i32; MAX_MANIFOLD_POINTS],
    first_vn: [i32; MAX_MANIFOLD_POINTS],
    bias: [i32; MAX_MANIFOLD_POINTS],
    /// The friction disc's radius at `2^(S+me)` and the twist bound in
    /// quanta, from the warm start's total (see `limits_set`).
    disc_limit: i64,
    twist_limit: i64,
    /// The warm start's total normal impulse (Q32.32; zero before one).
    warm_total: Scalar,
    /// The effective masses (Q32.32) of every row: `λ = Λ·m`.
    mass: [Scalar; ROWS],
    /// The friction coefficient, the twist reach and `1/m` of the twist.
    friction: Scalar,
    twist_reach: Scalar,
    k_w: Scalar,
    /// The tangent effective masses at `2^me` (the friction disc).
    mass_t: [i32; 2],
    /// The normal and tangents at `2^je`.
    n: [i32; 3],
    t: [[i32; 3]; 2],
    rows: [Row; ROWS],
    /// The separations' terms (see [`separations`]): the normal at
    /// `2^-N_EXP`, per point the anchors at `2^-R_EXP` m and the
    /// separation at the tick's start (Q32.32 bits).
    nq: [i32; 3],
    raq: [[i32; 3]; MAX_MANIFOLD_POINTS],
    rbq: [[i32; 3]; MAX_MANIFOLD_POINTS],
    sep0: [i64; MAX_MANIFOLD_POINTS],
}

/// Visits whose guard failed since the counts were last taken.
#[derive(Debug, Default)]
pub(crate) struct Fallbacks(AtomicU32);

impl Clone for Fallbacks {
    fn clone(&self) -> Fallbacks {
        Fallbacks(AtomicU32::new(self.0.load(Ordering::Relaxed)))
    }
}

impl Fallbacks {
    /// Counts one.
    pub(super) fn add(&self) {
        self.0.fetch_add(1, Ordering::Relaxed);
    }

    /// The count, reset to zero.
    pub(super) fn take(&self) -> u32 {
        self.0.swap(0, Ordering::Relaxed)
    }
}

/// Whether every component is inside the guard.
#[inline(always)]
fn fits(v: &[i64; 3]) -> bool {
    v[0].abs() < LIMIT && v[1].abs() < LIMIT && v[2].abs() < LIMIT
}

/// `Σ a_i·b_i` over three components, exact (each `|a_i| ≤ 2³⁰`,
/// `|b_i| < 2³⁰`: the sum is below 3·2⁶⁰).
#[inline(always)]
fn dot(a: &[i32; 3], b: &[i64; 3]) -> i64 {
    (a[0] as i64)
        .wrapping_mul(b[0])
        .wrapping_add((a[1] as i64).wrapping_mul(b[1]))
        .wrapping_add((a[2] as i64).wrapping_mul(b[2]))
}

/// `v += d·e` per component (`v −= d·e` for `sub`), each product rounded
/// once at `2^e` (`|d| < 2³²`, `|e| ≤ 2³⁰`: each product below 2⁶²).
#[inline(always)]
fn add_scaled(v: &mut [i64; 3], e: &[i32; 3], d: i64, exp: u32) {
    for i in 0..3 {
        v[i] = v[i].wrapping_add(rsh(d.wrapping_mul(e[i] as i64), exp));
    }
}

#[inline(always)]
fn sub_scaled(v: &mut [i64; 3], e: &[i32; 3], d: i64, exp: u32) {
    for i in 0..3 {
        v[i] = v[i].wrapping_sub(rsh(d.wrapping_mul(e[i] as i64), exp));
    }
}

/// The two bodies' velocities (or velocity changes) in quanta during one
/// visit.
#[derive(Clone, Copy, Default)]
struct Bodies {
    va: [i64; 3],
    wa: [i64; 3],
    vb: [i64; 3],
    wb: [i64; 3],
}

impl Bodies {
    /// Bodies `a` and `b`'s velocities in quanta (zero for `NONE`).
    #[inline(always)]
    fn load(arrays: &BodyArrays, a: u32, b: u32) -> Bodies {
        let (qa, qb) = (arrays.quanta(a), arrays.quanta(b));
        let v = |q: &Quanta, k: usize| [q.q[k] as i64, q.q[k + 1] as i64, q.q[k + 2] as i64];
        Bodies {
            va: v(&qa, 0),
            wa: v(&qa, 4),
            vb: v(&qb, 0),
            wb: v(&qb, 4),
        }
    }

    /// Writes the velocities of the dynamic bodies `wa` and `wb` (`NONE`:
    /// not written); each component is inside the guard, so 32 bits hold
    /// it.
    #[inline(always)]
    fn store(&self, arrays: &BodyArrays, wa: u32, wb: u32) {
        let q = |v: &[i64; 3], w: &[i64; 3]| Quanta {
            q: [
                v[0] as i32,
                v[1] as i32,
                v[2] as i32,
                0,
                w[0] as i32,
                w[1] as i32,
                w[2] as i32,
                0,
            ],
        };
        arrays.set_quanta(wa, q(&self.va, &self.wa));
        arrays.set_quanta(wb, q(&self.vb, &self.wb));
    }

    #[inline(always)]
    fn fit(&self) -> bool {
        fits(&self.va) && fits(&self.wa) && fits(&self.vb) && fits(&self.wb)
    }

    /// The relative velocity of the anchors along a row, quanta: `d·(V_B −
    /// V_A) + jb·Ω_B − ja·Ω_A` at `2^je`, rounded once. With every
    /// component below 2²⁹ (the guard), the linear sum is below 3·2⁶⁰ and
    /// the angular one below 3·2⁶⁰: the whole sum below 2⁶³.
    #[inline(always)]
    fn along(&self, d: &[i32; 3], row: &Row, je: u32) -> i64 {
        let dv = [
            self.vb[0].wrapping_sub(self.va[0]),
            self.vb[1].wrapping_sub(self.va[1]),
            self.vb[2].wrapping_sub(self.va[2]),
        ];
        rsh(
            dot(d, &dv)
                .wrapping_add(dot(&row.jb, &self.wb))
                .wrapping_sub(dot(&row.ja, &self.wa)),
            je,
        )
    }

    /// Applies `d` along a row to both bodies: A loses `d·e_A` and `d·c_A`,
    /// B gains `d·e_B` and `d·c_B`.
    #[inline(always)]
    fn apply(&mut self, d: i64, row: &Row, ae: u32) {
        sub_scaled(&mut self.va, &row.ea, d, ae);
        sub_scaled(&mut self.wa, &row.ca, d, ae);
        add_scaled(&mut self.vb, &row.eb, d, ae);
        add_scaled(&mut self.wb, &row.cb, d, ae);
    }
}

/// `Λ·m` in Q32.32 (Λ in quanta, m Q32.32), rounded as [`rsh`] (saturated
/// with the overflow fault past Q32.32).
#[inline(always)]
fn impulse(big: i32, m: Scalar) -> Scalar {
    narrow_q32((big as i128 * m.to_bits() as i128 + (1i128 << (S - 1))) >> S)
}

/// Writes the narrow impulses back to the constraint's Q32.32 impulses
/// (`λ = Λ·m_eff`, rounded once), with the angular write-back's marks at
/// them and restitution's bookkeeping: what restitution, the stored
/// impulses and the Q32.32 rows (after a failed guard) read. The angular
/// impulses of every narrow change up to the last write-back are in the
/// momenta (see [`collect_angular`]).
pub(super) fn write_back(r: &NarrowRows, c: &mut Constraint) {
    let count = c.count.min(MAX_MANIFOLD_POINTS);
    for (i, cp) in c.points[..count].iter_mut().enumerate() {
        let m = r.mass[i];
        cp.normal_impulse = impulse(r.impulse[i], m);
        cp.mark = impulse(r.mark[i], m);
        if r.max_impulse[i] > 0 {
            // At least one ulp: restitution tells a point that pushed by a
            // non-zero largest impulse.
            let max = impulse(r.max_impulse[i], m).max(Scalar::from_bits(1));
            cp.max_normal_impulse = cp.max_normal_impulse.max(max);
        }
        if r.first_vn[i] != i32::MAX {
            let vn = Scalar::from_bits((r.first_vn[i] as i64) << TO_Q);
            cp.relative_velocity = cp.relative_velocity.min(vn);
        }
    }
    let f = &mut c.patch;
    let q32 = |k: usize| {
        (
            impulse(r.impulse[k], r.mass[k]),
            impulse(r.mark[k], r.mass[k]),
        )
    };
    let [(t0, m0), (t1, m1), (w, mw)] = [q32(T0), q32(T0 + 1), q32(TW)];
    f.tangent_impulse = [t0, t1];
    f.twist_impulse = w;
    f.mark = [m0, m1, mw];
    c.warm_total = r.warm_total;
}

/// The total normal impulse (Q32.32) of the points' Λ in `impulses` (the
/// rows' own, or a lanes' batch's copy of them).
fn normal_total_of(r: &NarrowRows, impulses: &[i32; ROWS]) -> Scalar {
    let mut total = Scalar::ZERO;
    for (&big, &m) in impulses.iter().zip(&r.mass).take(r.count as usize) {
        total += impulse(big, m);
    }
    total
}

/// The rows' impulses with the points' Λ as a visit's normal rows settled
/// them, each held in `[0, LIMIT)`: that changes none of an accepted
/// visit (its guard holds them there), and keeps the friction bounds of a
/// refused one in the range of the rows' own.
fn settled(rows: [i32; ROWS], points: &[i32; MAX_MANIFOLD_POINTS]) -> [i32; ROWS] {
    let mut out = rows;
    for (o, &p) in out.iter_mut().zip(points) {
        *o = p.clamp(0, LIMIT as i32 - 1);
    }
    out
}

/// The friction disc's radius (at `2^(S+me)`) and the twist bound (quanta)
/// for a total normal impulse (Q32.32).
fn limits_for(r: &NarrowRows, total: Scalar) -> (i64, i64) {
    let limit = mul(r.friction, total);
    // Saturated at the guard: a bound past it refuses only a visit whose
    // impulse would reach it.
    let twist = quanta(mul(r.twist_reach, total) * r.k_w).min(LIMIT);
    (disc_limit(limit, r.me as i32), twist)
}

/// A Q32.32 bound as an impulse at `2^(S+me)` (the disc's scale),
/// saturated at 2⁶² (no impulse within the guard comes near it).
fn disc_limit(limit: Scalar, me: i32) -> i64 {
    let bits = limit.to_bits().max(0) as i128;
    let e = me + S as i32 - 32;
    let v = if e >= 0 {
        bits.checked_shl(e as u32).unwrap_or(i128::MAX)
    } else {
        let sh = (-e) as u32;
        (bits + (1i128 << (sh - 1))) >> sh
    };
    v.min(1 << 62) as i64
}

/// The friction disc: `want` (quanta) held so that `|want_j·m_j|` (the
/// impulses, at `2^(S+me)`) lies within `limit` (at that scale, ≥ 0).
/// Exact in integers, as the Q32.32 rows' disc: inside, kept; outside,
/// scaled by `limit/⌈|λ|⌉` (Q0.64, below one), each component truncated
/// toward zero, so the result never leaves the disc.
#[inline(always)]
fn clamp_to_disc(want: [i64; 2], mass: &[i32; 2], limit: i64) -> [i64; 2] {
    // |want| < 2³¹ (guarded), |mass| ≤ 2³⁰: each λ below 2⁶¹, each square
    // below 2¹²², their sum below 2¹²³ (and below 2¹²⁸ whatever the input).
    let l0 = (want[0].wrapping_mul(mass[0] as i64)).unsigned_abs() as u128;
    let l1 = (want[1].wrapping_mul(mass[1] as i64)).unsigned_abs() as u128;
    let len2 = l0 * l0 + l1 * l1;
    let lim = limit as u128;
    if len2 <= lim * lim {
        return want;
    }
    let root = crate::math::elem::isqrt_u128(len2) as u128;
    let len = if root * root < len2 { root + 1 } else { root };
    // limit < len ≤ 2⁶⁴: the factor is below 2⁶⁴, limit·2⁶⁴ below 2¹²⁶.
    let factor = (lim << 64) / len;
    let scaled = |w: i64| {
        let m = ((w.unsigned_abs() as u128 * factor) >> 64) as i64;
        if w < 0 { -m } else { m }
    };
    [scaled(want[0]), scaled(want[1])]
}

/// The exponents of the separations' terms: a body's displacement since
/// the tick's start at `2^-DP_EXP` m (within ±8 m), its rotation since then
/// minus the identity (`D = ΔR − I`, entries within ±2) at `2^-D_EXP`, the
/// normal at `2^-N_EXP`, the anchors at `2^-R_EXP` m (within ±128 m).
const DP_EXP: u32 = 28;
const D_EXP: u32 = 29;
pub(super) const N_EXP: u32 = 30;
pub(super) const R_EXP: u32 = 24;

/// The largest separation at the tick's start a narrow constraint takes
/// (Q32.32 bits: 256 m), so that every separation stays far inside 64 bits.
pub(super) const SEP0_LIMIT: i64 = 1 << 40;

/// A solver body's pose change since the tick's start, as the narrow
/// separations read it: `dp` at `2^-DP_EXP` m, `D = ΔR − I` by columns
/// (as `Mat3`) at `2^-D_EXP`, each rounded once from Q32.32; `fit` when
/// every entry is inside 32 bits (a body that moved 8 m or more in a tick
/// does not fit, and its constraints go to the Q32.32 rows).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct PoseQ {
    dp: [i32; 3],
    d: [[i32; 3]; 3],
    fit: bool,
}

impl Default for PoseQ {
    fn default() -> PoseQ {
        PoseQ::ZERO
    }
}

impl PoseQ {
    /// No change: the tick's start, and a static body.
    pub(super) const ZERO: PoseQ = PoseQ {
        dp: [0; 3],
        d: [[0; 3]; 3],
        fit: true,
    };

    /// Solver body `i`'s pose change in `pq` (no change for `NONE`).
    #[inline(always)]
    pub(super) fn of_body(pq: &[PoseQ], i: u32) -> PoseQ {
        if i == NONE {
            PoseQ::ZERO
        } else {
            pq[i as usize]
        }
    }

    /// The narrow form of displacement `dp` and rotation `dr`.
    pub(super) fn of(dp: Vec3, dr: &Mat3) -> PoseQ {
        let mut fit = true;
        let mut at = |x: i64, sh: u32| {
            let v = rsh(x, sh);
            fit &= v.abs() < 1 << 31;
            v as i32
        };
        let dp = [
            at(dp.x.to_bits(), 32 - DP_EXP),
            at(dp.y.to_bits(), 32 - DP_EXP),
            at(dp.z.to_bits(), 32 - DP_EXP),
        ];
        let mut d = [[0; 3]; 3];
        for (j, col) in dr.cols.iter().enumerate() {
            for (k, e) in d[j].iter_mut().enumerate() {
                let one = if j == k { 1i64 << 32 } else { 0 };
                *e = at(col.get(k).to_bits().wrapping_sub(one), 32 - D_EXP);
            }
        }
        PoseQ { dp, d, fit }
    }

    /// `Dᵀn` at `2^-D_EXP` (`n` at `2^-N_EXP`): each component a sum of
    /// three products below `|D col|·|n| ≤ 2·2^(D_EXP+N_EXP)` = 2⁶⁰ in
    /// every partial sum, rounded once.
    #[inline(always)]
    fn turned(&self, n: &[i32; 3]) -> [i64; 3] {
        std::array::from_fn(|j| {
            let c = &self.d[j];
            rsh(
                (c[0] as i64 * n[0] as i64)
                    .wrapping_add(c[1] as i64 * n[1] as i64)
                    .wrapping_add(c[2] as i64 * n[2] as i64),
                N_EXP,
            )
        })
    }
}

/// The current separations (Q32.32 bits) of a constraint's points from its
/// narrow terms (normal `n`, anchors `ra`, `rb`, separations at the tick's
/// start `sep0`) and its bodies' pose changes: `sep0 + n·(dp_B − dp_A) +
/// (D_Bᵀn)·r_B − (D_Aᵀn)·r_A`. Each dot product is exact in `i64` and
/// rounded once to Q32.32: `n·Δdp` below `|n||Δdp|` < 2³⁰·2^32.8 (every
/// partial sum too, by Cauchy–Schwarz), `(Dᵀn)·r` below (2³⁰ + 2)·2^31.8;
/// the sum below 2⁴² (`|sep0|` < [`SEP0_LIMIT`]). `None` when a pose does
/// not fit.
#[inline(always)]
pub(super) fn separations(
    n: &[i32; 3],
    pa: &PoseQ,
    pb: &PoseQ,
    ra: &[[i32; 3]; MAX_MANIFOLD_POINTS],
    rb: &[[i32; 3]; MAX_MANIFOLD_POINTS],
    sep0: &[i64; MAX_MANIFOLD_POINTS],
    count: usize,
) -> Option<[i64; MAX_MANIFOLD_POINTS]> {
    if !(pa.fit && pb.fit) {
        return None;
    }
    let mut base = 0i64;
    for ((&n, &b), &a) in n.iter().zip(&pb.dp).zip(&pa.dp) {
        base = base.wrapping_add((n as i64).wrapping_mul(b as i64 - a as i64));
    }
    let base = rsh(base, N_EXP + DP_EXP - 32);
    let (ma, mb) = (pa.turned(n), pb.turned(n));
    let dot = |m: &[i64; 3], r: &[i32; 3]| {
        rsh(
            m[0].wrapping_mul(r[0] as i64)
                .wrapping_add(m[1].wrapping_mul(r[1] as i64))
                .wrapping_add(m[2].wrapping_mul(r[2] as i64)),
            D_EXP + R_EXP - 32,
        )
    };
    let mut out = [0i64; MAX_MANIFOLD_POINTS];
    for i in 0..count.min(MAX_MANIFOLD_POINTS) {
        out[i] = sep0[i] + base + dot(&mb, &rb[i]) - dot(&ma, &ra[i]);
    }
    Some(out)
}

/// A point's bias from its separation `s` (Q32.32 bits): the speculative
/// `s/h` for a gap, else the soft push-out, in quanta saturated at ±2³⁰;
/// with whether it is a gap and whether it saturated.
#[inline(always)]
pub(super) fn bias_of(s: i64, params: &SolverParams) -> (i32, bool, bool) {
    let s = Scalar::from_bits(s);
    let speculative = s.is_positive();
    let bias = if speculative {
        s * params.inv_h
    } else {
        (params.softness.bias_rate * s).max(-params.max_push_out)
    };
    let q = quanta(bias);
    (
        q.clamp(-(1 << 30), 1 << 30) as i32,
        speculative,
        q.abs() > 1 << 30,
    )
}

/// The points' separations at the current poses and their biases in
/// quanta, from the rows' own narrow separation terms (the Q32.32
/// constraint is not read). `false`, with nothing written, when a body's
/// pose change does not fit.
#[inline(always)]
fn update_biases(r: &mut NarrowRows, pq: &[PoseQ], params: &SolverParams, poses: u32) -> bool {
    let count = r.count as usize;
    let (pa, pb) = (PoseQ::of_body(pq, r.a), PoseQ::of_body(pq, r.b));
    let Some(s) = separations(&r.nq, &pa, &pb, &r.raq, &r.rbq, &r.sep0, count) else {
        return false;
    };
    r.bias_poses = poses;
    for (i, &s) in s.iter().enumerate().take(count) {
        (r.bias[i], r.speculative[i], r.saturated[i]) = bias_of(s, params);
    }
    true
}

/// What one visit needs beside the constraint.
pub(super) struct VisitArgs<'a> {
    pub params: &'a SolverParams,
    pub pq: &'a [PoseQ],
    pub arrays: &'a BodyArrays,
    pub use_bias: bool,
    pub rot: usize,
    pub poses: u32,
}

/// One visit of a constraint on the narrow rows: the normal rows in the
/// substep's order ([`row_order`](super::constraint::row_order)), then
/// friction at the patch centre, as the Q32.32 visit does. Returns
/// `false`, having written nothing but the biases at the current poses,
/// when the guard fails. With `!use_bias` (relax) it also adds the angular
/// impulses since the last write-back to the bodies' momenta.
#[inline(always)]
pub(super) fn visit(args: &VisitArgs<'_>, r: &mut NarrowRows) -> bool {
    if r.bias_poses != args.poses && !update_biases(r, args.pq, args.params, args.poses) {
        return false;
    }
    let mut b = Bodies::load(args.arrays, r.a, r.b);
    if !b.fit() {
        return false;
    }
    let (je, ae) = (r.je as u32, r.ae as u32);
    let count = r.count as usize;
    let mut ok = true;
    // The normal rows. Soft: Λ' = ms·(Λ − vn − bias), ms in Q1.30.
    let ms = rsh(args.params.softness.mass_scale.to_bits(), 2);
    let mut impulses = [0i32; MAX_MANIFOLD_POINTS];
    impulses[..count].copy_from_slice(&r.impulse[..count]);
    let mut first_vn = r.first_vn;
    for kk in 0..count {
        let i = super::constraint::row_order(kk, count, args.rot);
        let vn = b.along(&r.n, &r.rows[i], je);
        let old = impulses[i] as i64;
        let (bias, soft) = if r.speculative[i] {
            (r.bias[i] as i64, false)
        } else if args.use_bias {
            (r.bias[i] as i64, true)
        } else {
            (0, false)
        };
        // |old| < 2²⁹, |bias| ≤ 2³⁰ and |vn| < 2⁶³/2¹⁶: no wrap.
        let x = old.wrapping_sub(vn).wrapping_sub(bias);
        ok &= x.abs() < ROW_LIMIT;
        // A saturated bias is exact only where it clamps to zero anyway.
        ok &= !(r.saturated[i] && x > 0);
        // |ms| ≤ 2³⁰, |x| < 2³¹: the product is below 2⁶¹.
        let new = if soft { rsh(ms.wrapping_mul(x), 30) } else { x }.max(0);
        ok &= new < LIMIT;
        let d = new.wrapping_sub(old);
        if first_vn[i] == i32::MAX && new > 0 {
            // First push this tick: the approach speed restitution
            // reflects (|vn| < 2³² here when the guard passes).
            first_vn[i] = vn.clamp(i32::MIN as i64, i32::MAX as i64 - 1) as i32;
        }
        impulses[i] = new as i32;
        if d != 0 {
            b.apply(d, &r.rows[i], ae);
            ok &= b.fit();
        }
    }
    let mut impulse_t = [r.impulse[T0], r.impulse[T0 + 1]];
    let mut impulse_w = r.impulse[TW];
    // Friction at the patch centre, after the normal rows (see
    // `patch::solve_patch`), bounded in a soft pass by the warm start's
    // total normal impulse, or (a relax pass, or a contact new this
    // substep) the one its normal rows just settled (as `Pass::friction`,
    // which says why).
    let (disc, twist_limit) = if r.limits_set && args.use_bias {
        (r.disc_limit, r.twist_limit)
    } else {
        limits_for(r, normal_total_of(r, &settled(r.impulse, &impulses)))
    };
    if !(disc == 0 && impulse_t == [0; 2] && impulse_w == 0) {
        let vt0 = b.along(&r.t[0], &r.rows[T0], je);
        let vt1 = b.along(&r.t[1], &r.rows[T0 + 1], je);
        let want = [
            (impulse_t[0] as i64).wrapping_sub(vt0),
            (impulse_t[1] as i64).wrapping_sub(vt1),
        ];
        ok &= want[0].abs() < ROW_LIMIT && want[1].abs() < ROW_LIMIT;
        let new = clamp_to_disc(want, &r.mass_t, disc);
        for j in 0..2 {
            ok &= new[j].abs() < LIMIT;
            let d = new[j].wrapping_sub(impulse_t[j] as i64);
            impulse_t[j] = new[j] as i32;
            if d != 0 {
                b.apply(d, &r.rows[T0 + j], ae);
                ok &= b.fit();
            }
        }
        // Twist: the relative spin about the normal, not in a soft pass
        // with a warm start (as `patch::solve_patch`, which says why).
        if !(r.limits_set && args.use_bias) {
            let spin = rsh(dot(&r.n, &b.wb).wrapping_sub(dot(&r.n, &b.wa)), je);
            let want = (impulse_w as i64).wrapping_sub(spin);
            ok &= want.abs() < ROW_LIMIT;
            let new = want.clamp(-twist_limit, twist_limit);
            ok &= new.abs() < LIMIT;
            let d = new.wrapping_sub(impulse_w as i64);
            impulse_w = new as i32;
            if d != 0 {
                b.apply(d, &r.rows[TW], ae);
                ok &= b.fit();
            }
        }
    }
    if !ok {
        return false;
    }
    let out = Outcome {
        impulse_t,
        impulse_w,
        impulses,
        first_vn,
    };
    commit(r, &out);
    b.store(args.arrays, r.wa, r.wb);
    if !args.use_bias {
        collect_angular(r, args.arrays);
    }
    true
}

/// What one accepted visit computed: the new impulses and restitution's
/// bookkeeping.
#[derive(Clone, Copy, Default)]
struct Outcome {
    impulse_t: [i32; 2],
    impulse_w: i32,
    impulses: [i32; MAX_MANIFOLD_POINTS],
    first_vn: [i32; MAX_MANIFOLD_POINTS],
}

/// Writes an accepted visit's impulses and restitution's bookkeeping (its
/// velocities are written by the caller, in quanta).
#[inline(always)]
fn commit(r: &mut NarrowRows, out: &Outcome) {
    r.impulse[T0] = out.impulse_t[0];
    r.impulse[T0 + 1] = out.impulse_t[1];
    r.impulse[TW] = out.impulse_w;
    let count = r.count as usize;
    for i in 0..count {
        r.impulse[i] = out.impulses[i];
        r.max_impulse[i] = r.max_impulse[i].max(out.impulses[i]);
        r.first_vn[i] = out.first_vn[i];
    }
}

/// Adds the angular impulse of every impulse change since its mark to the
/// write-back sums of A (negated) and B: `Σ g·ΔΛ` over the rows, one
/// exact sum per body (each `|g| ≤ 2³⁰`, `|ΔΛ| < 2³⁰`, seven rows: below
/// 7·2⁶⁰), rounded once to Q32.32; and moves the marks.
#[inline(always)]
fn collect_angular(r: &mut NarrowRows, arrays: &BodyArrays) {
    let mut la = [0i64; 3];
    let mut lb = [0i64; 3];
    let mut any = false;
    let count = r.count as usize;
    for k in (0..count).chain(T0..ROWS) {
        let d = (r.impulse[k] - r.mark[k]) as i64;
        if d == 0 {
            continue;
        }
        r.mark[k] = r.impulse[k];
        any = true;
        let row = &r.rows[k];
        for i in 0..3 {
            la[i] += d * row.ga[i] as i64;
            lb[i] += d * row.gb[i] as i64;
        }
    }
    if any {
        add_momenta(arrays, (r.ge, r.wa, r.wb), &la, &lb);
    }
}

/// Adds `−la` and `lb` (at `2^-(S+ge)`) to the write-back sums of A and B,
/// rounded once to Q32.32 (`S + ge ≥ 36`: a right shift).
#[inline(always)]
fn add_momenta(arrays: &BodyArrays, (ge, wa, wb): (u8, u32, u32), la: &[i64; 3], lb: &[i64; 3]) {
    let sh = S + ge as u32 - 32;
    let q32 = |x: &[i64; 3]| {
        Vec3::new(
            Scalar::from_bits(rsh(x[0], sh)),
            Scalar::from_bits(rsh(x[1], sh)),
            Scalar::from_bits(rsh(x[2], sh)),
        )
    };
    if wa != NONE {
        arrays.add_dl(wa, -q32(la));
    }
    if wb != NONE {
        arrays.add_dl(wb, q32(lb));
    }
}

/// The warm start of a constraint on the narrow rows: every accumulated Λ
/// applied through its responses (the changes do not depend on the
/// velocities, so they are summed from zero), returned as Q32.32 velocity
/// changes of A and B; the marks go to zero (the angular write-back takes
/// the whole impulses again) and the friction bounds are set from the total
/// normal impulse.
#[inline(always)]
pub(super) fn warm_start(r: &mut NarrowRows) -> (BodyVel, BodyVel) {
    let mut b = Bodies::default();
    let (ae, count) = (r.ae as u32, r.count as usize);
    r.mark = [0; ROWS];
    for k in (0..count).chain(T0..ROWS) {
        let d = r.impulse[k] as i64;
        if d != 0 {
            b.apply(d, &r.rows[k], ae);
        }
    }
    set_limits(r);
    b.as_changes()
}

/// The friction bounds from the total normal impulse of the warm start.
#[inline(always)]
fn set_limits(r: &mut NarrowRows) {
    (r.warm_total, r.limits_set, r.disc_limit, r.twist_limit) =
        limits_of(r, &r.impulse, r.disc_limit, r.twist_limit);
}

/// What [`set_limits`] writes, for the points' Λ in `impulses`: the warm
/// start's total, whether it bounds friction, and the bounds (unchanged
/// `disc`, `twist` when it does not).
#[inline(always)]
fn limits_of(
    r: &NarrowRows,
    impulses: &[i32; ROWS],
    disc: i64,
    twist: i64,
) -> (Scalar, bool, i64, i64) {
    let total = normal_total_of(r, impulses);
    if total.is_positive() {
        let (d, t) = limits_for(r, total);
        (total, true, d, t)
    } else {
        (total, false, disc, twist)
    }
}

impl Bodies {
    /// These quanta as Q32.32 velocity changes of A and B.
    fn as_changes(&self) -> (BodyVel, BodyVel) {
        (
            BodyVel {
                v: from_quanta3(&self.va),
                w: from_quanta3(&self.wa),
            },
            BodyVel {
                v: from_quanta3(&self.vb),
                w: from_quanta3(&self.wb),
            },
        )
    }
}

#[cfg(test)]
mod tests;
