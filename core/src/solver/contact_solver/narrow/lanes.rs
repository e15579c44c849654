//! The narrow rows on SIMD lanes: eight constraints of one colour (so no
//! two share a moving body) with the same point count, visited together.
//!
//! Every step is the scalar twin's ([`super::visit`]) step, written once as
//! a loop over the eight lanes on plain integers (wrapping products and
//! sums, shifts, comparisons and selects), and compiled three times: for
//! AVX-512, for AVX2 (chosen at run time) and for no vector extension.
//! Integer arithmetic has one result whatever instructions compute it, so
//! each lane ends with the twin's bits; the tests compare them anyway, on
//! random, boundary and guard-failing inputs and on whole worlds.
//!
//! The constants of a batch (Jacobian and response entries, exponents) are
//! copied from the twin's rows into a structure of arrays at `prepare`
//! ([`Batch::fill`]); the impulses and the per-tick bookkeeping stay in the
//! twin's rows, read and written per lane at each visit, so the twin and
//! the lanes share one state. What the lanes do not vectorise is done by
//! the twin's own code per lane: the separations and biases (once per pose
//! change), the friction disc of a patch that may slide (see
//! [`clamp_lanes`]), the commit, the angular write-back and the fused warm
//! start.

// The lane loops index every array by the lane on purpose: one loop per
// step over the eight lanes is what the compiler turns into vector code.
#![allow(clippy::needless_range_loop)]

use super::super::rows::BodyArrays;
use super::{
    Bodies, BodyVel, LIMIT, MAX_MANIFOLD_POINTS, NarrowRows, PoseQ, ROW_LIMIT, ROWS, Row, T0, TW,
    VisitArgs, add_momenta, bias_of, clamp_to_disc, limits_for, limits_of, normal_total_of,
    separations, settled,
};
use crate::math::Scalar;

/// Constraints per batch.
pub(in crate::solver::contact_solver) const LANES: usize = 8;

type L64 = [i64; LANES];
type L32 = [i32; LANES];
type Mask = [bool; LANES];

/// One row's constants, lane by lane.
#[derive(Clone, Copy, Debug, Default)]
struct LaneRow {
    ja: [L32; 3],
    jb: [L32; 3],
    ea: [L32; 3],
    eb: [L32; 3],
    ca: [L32; 3],
    cb: [L32; 3],
    ga: [L32; 3],
    gb: [L32; 3],
}

impl LaneRow {
    fn set(&mut self, l: usize, r: &Row) {
        for c in 0..3 {
            self.ja[c][l] = r.ja[c];
            self.jb[c][l] = r.jb[c];
            self.ea[c][l] = r.ea[c];
            self.eb[c][l] = r.eb[c];
            self.ca[c][l] = r.ca[c];
            self.cb[c][l] = r.cb[c];
            self.ga[c][l] = r.ga[c];
            self.gb[c][l] = r.gb[c];
        }
    }
}

/// The constants of eight constraints' narrow rows, as a structure of
/// arrays, and their state during the passes of a tick (see
/// [`LaneState`]).
#[derive(Clone, Debug, Default)]
pub(in crate::solver::contact_solver) struct Batch {
    /// Points per constraint (the same in every lane).
    count: usize,
    /// Exponents (shift counts) of the Jacobian and response entries.
    je: L64,
    ae: L64,
    /// Solver bodies (or `NONE`) of each lane, the dynamic ones the
    /// passes write, and the angular-momentum entries' exponent.
    a: [u32; LANES],
    b: [u32; LANES],
    wa: [u32; LANES],
    wb: [u32; LANES],
    ge: [u8; LANES],
    /// The separations' terms (the twin's `nq`, `raq`, `rbq`, `sep0`).
    nq: [L32; 3],
    raq: [[L32; 3]; MAX_MANIFOLD_POINTS],
    rbq: [[L32; 3]; MAX_MANIFOLD_POINTS],
    sep0: [L64; MAX_MANIFOLD_POINTS],
    n: [L32; 3],
    t: [[L32; 3]; 2],
    mass_t: [L32; 2],
    /// The rows: the points' normal rows, the two tangents, the twist (as
    /// the twin's `rows`).
    rows: [LaneRow; ROWS],
    /// The index of the batch's first constraint (and row).
    first: usize,
    /// Whether `state` holds the lanes' state (else the twin's rows do).
    loaded: bool,
    state: LaneState,
}

/// The state the twin keeps in its rows' first cache lines, lane by lane:
/// while a batch is loaded (from its first pass of a tick until its state
/// goes back, see [`Batch::unload`]) the lanes read and write it here, so
/// a visit streams one compact array instead of eight rows.
#[derive(Clone, Copy, Debug, Default)]
struct LaneState {
    impulse: [L32; ROWS],
    mark: [L32; ROWS],
    max_impulse: [L32; MAX_MANIFOLD_POINTS],
    first_vn: [L32; MAX_MANIFOLD_POINTS],
    bias: [L32; MAX_MANIFOLD_POINTS],
    speculative: [Mask; MAX_MANIFOLD_POINTS],
    saturated: [Mask; MAX_MANIFOLD_POINTS],
    bias_poses: [u32; LANES],
    limits_set: Mask,
    disc: L64,
    twist_limit: L64,
    warm_total: [Scalar; LANES],
}

impl Batch {
    /// Whether `rows` (eight) can go in one batch: all on the narrow rows,
    /// with the same point count.
    pub(in crate::solver::contact_solver) fn fits(rows: &[NarrowRows]) -> bool {
        rows.len() == LANES && rows.iter().all(|r| r.on && r.count == rows[0].count)
    }

    /// Copies the constants of `rows` (eight, see [`Batch::fits`], from
    /// constraint `first` on); the state stays in the rows until the first
    /// visit.
    pub(in crate::solver::contact_solver) fn fill(&mut self, rows: &[NarrowRows], first: usize) {
        self.count = rows[0].count as usize;
        self.first = first;
        self.loaded = false;
        for (l, r) in rows.iter().enumerate().take(LANES) {
            self.je[l] = r.je as i64;
            self.ae[l] = r.ae as i64;
            self.a[l] = r.a;
            self.b[l] = r.b;
            self.wa[l] = r.wa;
            self.wb[l] = r.wb;
            self.ge[l] = r.ge;
            for i in 0..self.count {
                for c in 0..3 {
                    self.raq[i][c][l] = r.raq[i][c];
                    self.rbq[i][c][l] = r.rbq[i][c];
                }
                self.sep0[i][l] = r.sep0[i];
            }
            for c in 0..3 {
                self.nq[c][l] = r.nq[c];
                self.n[c][l] = r.n[c];
                self.t[0][c][l] = r.t[0][c];
                self.t[1][c][l] = r.t[1][c];
            }
            self.mass_t[0][l] = r.mass_t[0];
            self.mass_t[1][l] = r.mass_t[1];
            for k in (0..self.count).chain(T0..ROWS) {
                self.rows[k].set(l, &r.rows[k]);
            }
        }
    }

    /// The rows of the batch's constraints, if the lanes hold their state.
    pub(in crate::solver::contact_solver) fn loaded(&self) -> Option<std::ops::Range<usize>> {
        self.loaded.then_some(self.first..self.first + LANES)
    }

    /// Takes the state from the twin's rows (the batch's eight).
    fn load(&mut self, rows: &[NarrowRows]) {
        let st = &mut self.state;
        for (l, r) in rows.iter().enumerate().take(LANES) {
            for k in 0..ROWS {
                st.impulse[k][l] = r.impulse[k];
                st.mark[k][l] = r.mark[k];
            }
            for i in 0..MAX_MANIFOLD_POINTS {
                st.max_impulse[i][l] = r.max_impulse[i];
                st.first_vn[i][l] = r.first_vn[i];
                st.bias[i][l] = r.bias[i];
                st.speculative[i][l] = r.speculative[i];
                st.saturated[i][l] = r.saturated[i];
            }
            st.bias_poses[l] = r.bias_poses;
            st.limits_set[l] = r.limits_set;
            st.disc[l] = r.disc_limit;
            st.twist_limit[l] = r.twist_limit;
            st.warm_total[l] = r.warm_total;
        }
        self.loaded = true;
    }

    /// Gives the state back to the twin's rows (the batch's eight), for
    /// what reads it there: the twin's visits after a lane's guard failed,
    /// the twin's warm start, restitution's write-back.
    pub(in crate::solver::contact_solver) fn unload(&mut self, rows: &mut [NarrowRows]) {
        if !self.loaded {
            return;
        }
        let st = &self.state;
        for (l, r) in rows.iter_mut().enumerate().take(LANES) {
            for k in 0..ROWS {
                r.impulse[k] = st.impulse[k][l];
                r.mark[k] = st.mark[k][l];
            }
            for i in 0..MAX_MANIFOLD_POINTS {
                r.max_impulse[i] = st.max_impulse[i][l];
                r.first_vn[i] = st.first_vn[i][l];
                r.bias[i] = st.bias[i][l];
                r.speculative[i] = st.speculative[i][l];
                r.saturated[i] = st.saturated[i][l];
            }
            r.bias_poses = st.bias_poses[l];
            r.limits_set = st.limits_set[l];
            r.disc_limit = st.disc[l];
            r.twist_limit = st.twist_limit[l];
            r.warm_total = st.warm_total[l];
        }
        self.loaded = false;
    }
}

/// The two bodies' velocities of every lane, quanta, as 32-bit integers:
/// exact while the guard passes (every component below 2²⁹), so every
/// product in the rows is a 32 × 32 → 64-bit one, as in the twin; a lane
/// whose guard fails is thrown away whatever its values.
#[derive(Clone, Copy, Default)]
struct Vels {
    va: [L32; 3],
    wa: [L32; 3],
    vb: [L32; 3],
    wb: [L32; 3],
}

/// One visit's state of every lane, gathered from the twin's rows.
#[derive(Clone, Copy, Default)]
struct State {
    /// Whether each lane's velocities fit the guard as gathered.
    ok: Mask,
    v: Vels,
    /// Whether each lane's friction bounds were set by its warm start
    /// (else the kernel sets them from what its normal rows settle).
    limits_set: Mask,
    disc: L64,
    twist_limit: L64,
    impulse_t: [L64; 2],
    impulse_w: L64,
    impulses: [L64; MAX_MANIFOLD_POINTS],
    first_vn: [L64; MAX_MANIFOLD_POINTS],
    bias: [L64; MAX_MANIFOLD_POINTS],
    speculative: [Mask; MAX_MANIFOLD_POINTS],
    saturated: [Mask; MAX_MANIFOLD_POINTS],
}

/// [`super::rsh`] per lane, with a shift count per lane.
#[inline(always)]
fn rsh(x: i64, e: i64) -> i64 {
    x.wrapping_add(1 << (e - 1)) >> e
}

/// A 32 × 32 → 64-bit product.
#[inline(always)]
fn mul(a: i32, b: i32) -> i64 {
    a as i64 * b as i64
}

/// `Bodies::along` per lane (`V_B − V_A` below 2³⁰ while the guard
/// passes, so it is a 32-bit difference).
#[inline(always)]
fn along(d: &[L32; 3], ja: &[L32; 3], jb: &[L32; 3], v: &Vels, je: &L64) -> L64 {
    let mut out = [0i64; LANES];
    for l in 0..LANES {
        let mut s = 0i64;
        for c in 0..3 {
            let dv = v.vb[c][l].wrapping_sub(v.va[c][l]);
            s = s.wrapping_add(mul(d[c][l], dv));
            s = s.wrapping_add(mul(jb[c][l], v.wb[c][l]));
            s = s.wrapping_sub(mul(ja[c][l], v.wa[c][l]));
        }
        out[l] = rsh(s, je[l]);
    }
    out
}

/// `Bodies::apply` per lane, then `Bodies::fit` and-ed into `ok` (on the
/// 64-bit sums, before they are kept in 32 bits). `d` is below 2³¹ in
/// magnitude while the guard passes.
#[inline(always)]
fn apply(d: &L64, row: &LaneRow, ae: &L64, v: &mut Vels, ok: &mut Mask) {
    let mut fits = [true; LANES];
    for c in 0..3 {
        for l in 0..LANES {
            let d = d[l] as i32;
            let p = |e: i32| rsh(mul(d, e), ae[l]);
            let va = (v.va[c][l] as i64).wrapping_sub(p(row.ea[c][l]));
            let wa = (v.wa[c][l] as i64).wrapping_sub(p(row.ca[c][l]));
            let vb = (v.vb[c][l] as i64).wrapping_add(p(row.eb[c][l]));
            let wb = (v.wb[c][l] as i64).wrapping_add(p(row.cb[c][l]));
            fits[l] &= va.abs() < LIMIT && wa.abs() < LIMIT && vb.abs() < LIMIT && wb.abs() < LIMIT;
            (v.va[c][l], v.wa[c][l], v.vb[c][l], v.wb[c][l]) =
                (va as i32, wa as i32, vb as i32, wb as i32);
        }
    }
    for l in 0..LANES {
        ok[l] &= fits[l];
    }
}

/// The friction disc per lane (see `clamp_to_disc`): a lane whose two
/// impulses are inside the disc by the cheap test `|λ₀| + |λ₁| ≤ limit`
/// (which implies `λ₀² + λ₁² ≤ limit²`) keeps them, as the twin does; any
/// other active lane goes through the twin's exact function.
#[inline(always)]
fn clamp_lanes(want: &[L64; 2], mass: &[L32; 2], disc: &L64, active: &Mask) -> [L64; 2] {
    let mut inside = [true; LANES];
    for l in 0..LANES {
        let l0 = want[0][l].wrapping_mul(mass[0][l] as i64).unsigned_abs();
        let l1 = want[1][l].wrapping_mul(mass[1][l] as i64).unsigned_abs();
        inside[l] = l0.saturating_add(l1) <= disc[l] as u64;
    }
    let mut out = *want;
    for l in 0..LANES {
        if active[l] && !inside[l] {
            let m = [mass[0][l], mass[1][l]];
            let q = clamp_to_disc([want[0][l], want[1][l]], &m, disc[l]);
            out[0][l] = q[0];
            out[1][l] = q[1];
        }
    }
    out
}

/// The rows of one batch on the lanes: the twin's normal and friction
/// rows, step by step. Returns each lane's guard.
#[inline(always)]
fn kernel(
    b: &Batch,
    rows: &[NarrowRows],
    st: &mut State,
    ms: i64,
    use_bias: bool,
    rot: usize,
) -> Mask {
    // The velocities were checked as they were gathered (`st.ok`).
    let mut ok = st.ok;
    // The normal rows in the substep's order.
    let count = b.count;
    for kk in 0..count {
        let i = super::super::constraint::row_order(kk, count, rot);
        let p = &b.rows[i];
        let vn = along(&b.n, &p.ja, &p.jb, &st.v, &b.je);
        let mut d = [0i64; LANES];
        for l in 0..LANES {
            let spec = st.speculative[i][l];
            let bias = if spec || use_bias { st.bias[i][l] } else { 0 };
            let soft = !spec && use_bias;
            let old = st.impulses[i][l];
            let x = old.wrapping_sub(vn[l]).wrapping_sub(bias);
            ok[l] &= x.abs() < ROW_LIMIT && !(st.saturated[i][l] && x > 0);
            // |x| < 2³¹ while the guard passes: a 32-bit operand.
            let new = if soft {
                rsh(mul(ms as i32, x as i32), 30)
            } else {
                x
            }
            .max(0);
            ok[l] &= new < LIMIT;
            d[l] = new.wrapping_sub(old);
            if st.first_vn[i][l] == i32::MAX as i64 && new > 0 {
                st.first_vn[i][l] = vn[l].clamp(i32::MIN as i64, i32::MAX as i64 - 1);
            }
            st.impulses[i][l] = new as i32 as i64;
        }
        apply(&d, p, &b.ae, &mut st.v, &mut ok);
    }
    // Friction at the patch centre, after the normal rows, bounded in a
    // soft pass by the warm start's total normal impulse or (a relax pass,
    // or a contact new this substep) the one its normal rows just settled,
    // as the twin: both tangents from the same velocities, held in the
    // disc, then the twist.
    for (l, r) in rows.iter().enumerate().take(LANES) {
        if !st.limits_set[l] || !use_bias {
            let points = std::array::from_fn(|i| st.impulses[i][l] as i32);
            (st.disc[l], st.twist_limit[l]) =
                limits_for(r, normal_total_of(r, &settled([0; ROWS], &points)));
        }
    }
    let mut active = [false; LANES];
    for l in 0..LANES {
        active[l] = !(st.disc[l] == 0
            && st.impulse_t[0][l] == 0
            && st.impulse_t[1][l] == 0
            && st.impulse_w[l] == 0);
    }
    let (t0, t1) = (&b.rows[T0], &b.rows[T0 + 1]);
    let vt0 = along(&b.t[0], &t0.ja, &t0.jb, &st.v, &b.je);
    let vt1 = along(&b.t[1], &t1.ja, &t1.jb, &st.v, &b.je);
    let mut want = [[0i64; LANES]; 2];
    for l in 0..LANES {
        want[0][l] = st.impulse_t[0][l].wrapping_sub(vt0[l]);
        want[1][l] = st.impulse_t[1][l].wrapping_sub(vt1[l]);
        ok[l] &= !active[l] || (want[0][l].abs() < ROW_LIMIT && want[1][l].abs() < ROW_LIMIT);
    }
    let new = clamp_lanes(&want, &b.mass_t, &st.disc, &active);
    for j in 0..2 {
        let mut d = [0i64; LANES];
        for l in 0..LANES {
            let n = if active[l] {
                new[j][l]
            } else {
                st.impulse_t[j][l]
            };
            ok[l] &= !active[l] || n.abs() < LIMIT;
            d[l] = n.wrapping_sub(st.impulse_t[j][l]);
            st.impulse_t[j][l] = n as i32 as i64;
        }
        apply(&d, &b.rows[T0 + j], &b.ae, &mut st.v, &mut ok);
    }
    // The twist, not in a soft pass with a warm start, as the twin.
    let mut d = [0i64; LANES];
    for l in 0..LANES {
        let mut s = 0i64;
        for c in 0..3 {
            s = s.wrapping_add(mul(b.n[c][l], st.v.wb[c][l]));
            s = s.wrapping_sub(mul(b.n[c][l], st.v.wa[c][l]));
        }
        let spin = rsh(s, b.je[l]);
        let want = st.impulse_w[l].wrapping_sub(spin);
        let tl = st.twist_limit[l];
        let solve = active[l] && !(st.limits_set[l] && use_bias);
        let n = if solve {
            want.clamp(-tl, tl)
        } else {
            st.impulse_w[l]
        };
        ok[l] &= !solve || (want.abs() < ROW_LIMIT && n.abs() < LIMIT);
        d[l] = n.wrapping_sub(st.impulse_w[l]);
        st.impulse_w[l] = n as i32 as i64;
    }
    apply(&d, &b.rows[TW], &b.ae, &mut st.v, &mut ok);
    ok
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512dq,avx512vl,avx512bw")]
fn kernel_avx512(
    b: &Batch,
    rows: &[NarrowRows],
    st: &mut State,
    ms: i64,
    use_bias: bool,
    rot: usize,
) -> Mask {
    kernel(b, rows, st, ms, use_bias, rot)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn kernel_avx2(
    b: &Batch,
    rows: &[NarrowRows],
    st: &mut State,
    ms: i64,
    use_bias: bool,
    rot: usize,
) -> Mask {
    kernel(b, rows, st, ms, use_bias, rot)
}

#[inline(never)]
fn kernel_plain(
    b: &Batch,
    rows: &[NarrowRows],
    st: &mut State,
    ms: i64,
    use_bias: bool,
    rot: usize,
) -> Mask {
    kernel(b, rows, st, ms, use_bias, rot)
}

/// Which build of the lane kernel runs (the results are the same bits).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
// Only x86_64 builds construct the vector variants.
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
pub enum Kernel {
    /// AVX-512 (F, DQ, VL, BW).
    Avx512,
    /// AVX2.
    Avx2,
    /// No vector extension (the lanes one after another).
    Plain,
}

impl Kernel {
    /// The widest build this CPU runs, found once.
    pub fn best() -> Kernel {
        #[cfg(target_arch = "x86_64")]
        {
            static BEST: std::sync::OnceLock<Kernel> = std::sync::OnceLock::new();
            *BEST.get_or_init(|| {
                if std::arch::is_x86_feature_detected!("avx512f")
                    && std::arch::is_x86_feature_detected!("avx512dq")
                    && std::arch::is_x86_feature_detected!("avx512vl")
                    && std::arch::is_x86_feature_detected!("avx512bw")
                {
                    Kernel::Avx512
                } else if std::arch::is_x86_feature_detected!("avx2") {
                    Kernel::Avx2
                } else {
                    Kernel::Plain
                }
            })
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            Kernel::Plain
        }
    }

    /// Its name, for reports.
    pub fn name(self) -> &'static str {
        match self {
            Kernel::Avx512 => "AVX-512",
            Kernel::Avx2 => "AVX2",
            Kernel::Plain => "plain",
        }
    }

    fn run(
        self,
        b: &Batch,
        rows: &[NarrowRows],
        st: &mut State,
        ms: i64,
        use_bias: bool,
        rot: usize,
    ) -> Mask {
        match self {
            // SAFETY: `best` found these features on this CPU (a caller
            // that names a kernel explicitly, as the tests do, checks
            // `best` first).
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx512 => unsafe { kernel_avx512(b, rows, st, ms, use_bias, rot) },
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx2 => unsafe { kernel_avx2(b, rows, st, ms, use_bias, rot) },
            _ => kernel_plain(b, rows, st, ms, use_bias, rot),
        }
    }
}

/// One visit of eight constraints (`rows`, one batch, all on the narrow
/// rows) on the lanes of `kernel`, with their state in the batch (taken
/// from the rows at the tick's first visit). Each accepted lane is written
/// as the twin writes it. Returns the mask of lanes whose guard failed
/// (nothing of theirs written but their biases): then the whole batch's
/// state has gone back to the rows, for the caller to solve the refused
/// constraints on the Q32.32 rows and the others with the twin from then
/// on.
pub(in crate::solver::contact_solver) fn visit(
    args: &VisitArgs<'_>,
    batch: &mut Batch,
    rows: &mut [NarrowRows],
    kernel: Kernel,
) -> Mask {
    if !batch.loaded {
        batch.load(rows);
    }
    let mut st = State::default();
    for l in 0..LANES {
        let b = Bodies::load(args.arrays, batch.a[l], batch.b[l]);
        st.ok[l] = b.fit();
        for c in 0..3 {
            st.v.va[c][l] = b.va[c] as i32;
            st.v.wa[c][l] = b.wa[c] as i32;
            st.v.vb[c][l] = b.vb[c] as i32;
            st.v.wb[c][l] = b.wb[c] as i32;
        }
    }
    let count = batch.count;
    let bs = &mut batch.state;
    for l in 0..LANES {
        if bs.bias_poses[l] != args.poses {
            // The twin's functions on the batch's copy of the separation
            // terms; a pose change that does not fit refuses the lane.
            let n = [batch.nq[0][l], batch.nq[1][l], batch.nq[2][l]];
            let ra = std::array::from_fn(|i| std::array::from_fn(|c| batch.raq[i][c][l]));
            let rb = std::array::from_fn(|i| std::array::from_fn(|c| batch.rbq[i][c][l]));
            let sep0 = std::array::from_fn(|i| batch.sep0[i][l]);
            let (pa, pb) = (
                PoseQ::of_body(args.pq, batch.a[l]),
                PoseQ::of_body(args.pq, batch.b[l]),
            );
            match separations(&n, &pa, &pb, &ra, &rb, &sep0, count) {
                Some(s) => {
                    bs.bias_poses[l] = args.poses;
                    for i in 0..count {
                        (bs.bias[i][l], bs.speculative[i][l], bs.saturated[i][l]) =
                            bias_of(s[i], args.params);
                    }
                }
                None => st.ok[l] = false,
            }
        }
    }
    for l in 0..LANES {
        st.limits_set[l] = bs.limits_set[l];
        (st.disc[l], st.twist_limit[l]) = (bs.disc[l], bs.twist_limit[l]);
    }
    for l in 0..LANES {
        st.impulse_t[0][l] = bs.impulse[T0][l] as i64;
        st.impulse_t[1][l] = bs.impulse[T0 + 1][l] as i64;
        st.impulse_w[l] = bs.impulse[TW][l] as i64;
    }
    for i in 0..batch.count {
        for l in 0..LANES {
            st.impulses[i][l] = bs.impulse[i][l] as i64;
            st.first_vn[i][l] = bs.first_vn[i][l] as i64;
            st.bias[i][l] = bs.bias[i][l] as i64;
            st.speculative[i][l] = bs.speculative[i][l];
            st.saturated[i][l] = bs.saturated[i][l];
        }
    }
    let ms = super::rsh(args.params.softness.mass_scale.to_bits(), 2);
    let ok = kernel.run(batch, rows, &mut st, ms, args.use_bias, args.rot);
    let bs = &mut batch.state;
    let mut refused = [false; LANES];
    for l in 0..LANES {
        if !ok[l] {
            refused[l] = true;
            continue;
        }
        bs.impulse[T0][l] = st.impulse_t[0][l] as i32;
        bs.impulse[T0 + 1][l] = st.impulse_t[1][l] as i32;
        bs.impulse[TW][l] = st.impulse_w[l] as i32;
        for i in 0..batch.count {
            let new = st.impulses[i][l] as i32;
            bs.impulse[i][l] = new;
            bs.max_impulse[i][l] = bs.max_impulse[i][l].max(new);
            bs.first_vn[i][l] = st.first_vn[i][l] as i32;
        }
        let v = |x: &[L32; 3]| [x[0][l] as i64, x[1][l] as i64, x[2][l] as i64];
        let b = Bodies {
            va: v(&st.v.va),
            wa: v(&st.v.wa),
            vb: v(&st.v.vb),
            wb: v(&st.v.wb),
        };
        b.store(args.arrays, batch.wa[l], batch.wb[l]);
    }
    if !args.use_bias {
        collect_angular(batch, &refused, args.arrays);
    }
    if refused.contains(&true) {
        batch.unload(rows);
    }
    refused
}

/// The twin's `collect_angular` for the accepted lanes: `Σ g·ΔΛ` per body
/// since the marks (each lane's sum exact in `i64`, as the twin's), then
/// the marks moved and the sums added to the bodies' write-back.
fn collect_angular(batch: &mut Batch, refused: &Mask, arrays: &BodyArrays) {
    let mut la = [[0i64; LANES]; 3];
    let mut lb = [[0i64; LANES]; 3];
    let mut any = [false; LANES];
    let st = &mut batch.state;
    for k in (0..batch.count).chain(T0..ROWS) {
        let mut d = [0i64; LANES];
        for l in 0..LANES {
            if refused[l] {
                continue;
            }
            d[l] = (st.impulse[k][l] - st.mark[k][l]) as i64;
            st.mark[k][l] = st.impulse[k][l];
            any[l] |= d[l] != 0;
        }
        let g = &batch.rows[k];
        for c in 0..3 {
            for l in 0..LANES {
                la[c][l] += d[l] * g.ga[c][l] as i64;
                lb[c][l] += d[l] * g.gb[c][l] as i64;
            }
        }
    }
    for l in 0..LANES {
        if any[l] {
            let a = [la[0][l], la[1][l], la[2][l]];
            let b = [lb[0][l], lb[1][l], lb[2][l]];
            add_momenta(arrays, (batch.ge[l], batch.wa[l], batch.wb[l]), &a, &b);
        }
    }
}

/// The twin's `warm_start` of eight constraints (one loaded batch): each
/// lane's velocity changes of A and B, with the marks cleared and the
/// friction bounds set in the batch's state (`rows`: the batch's eight,
/// for their constants).
pub(in crate::solver::contact_solver) fn warm_start(
    batch: &mut Batch,
    rows: &[NarrowRows],
) -> [(BodyVel, BodyVel); LANES] {
    let mut v = Vels64::default();
    let st = &mut batch.state;
    for k in (0..batch.count).chain(T0..ROWS) {
        let d = st.impulse[k];
        let g = &batch.rows[k];
        for c in 0..3 {
            for l in 0..LANES {
                let p = |e: i32| rsh(mul(d[l], e), batch.ae[l]);
                v.va[c][l] = v.va[c][l].wrapping_sub(p(g.ea[c][l]));
                v.wa[c][l] = v.wa[c][l].wrapping_sub(p(g.ca[c][l]));
                v.vb[c][l] = v.vb[c][l].wrapping_add(p(g.eb[c][l]));
                v.wb[c][l] = v.wb[c][l].wrapping_add(p(g.cb[c][l]));
            }
        }
    }
    st.mark = [[0; LANES]; ROWS];
    for (l, r) in rows.iter().enumerate().take(LANES) {
        let imp: [i32; ROWS] = std::array::from_fn(|k| st.impulse[k][l]);
        (
            st.warm_total[l],
            st.limits_set[l],
            st.disc[l],
            st.twist_limit[l],
        ) = limits_of(r, &imp, st.disc[l], st.twist_limit[l]);
    }
    std::array::from_fn(|l| {
        let b = Bodies {
            va: [v.va[0][l], v.va[1][l], v.va[2][l]],
            wa: [v.wa[0][l], v.wa[1][l], v.wa[2][l]],
            vb: [v.vb[0][l], v.vb[1][l], v.vb[2][l]],
            wb: [v.wb[0][l], v.wb[1][l], v.wb[2][l]],
        };
        b.as_changes()
    })
}

/// Velocity changes of every lane, quanta, summed from zero.
#[derive(Clone, Copy, Default)]
struct Vels64 {
    va: [L64; 3],
    wa: [L64; 3],
    vb: [L64; 3],
    wb: [L64; 3],
}

#[cfg(test)]
mod tests;
