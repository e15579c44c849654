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

use super::{
    Bodies, BodyVel, LIMIT, MAX_MANIFOLD_POINTS, NarrowRows, Outcome, ROW_LIMIT, Row, VisitArgs,
    clamp_to_disc, commit, limits_for, normal_total, update_biases,
};

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
        }
    }
}

/// The constants of eight constraints' narrow rows, as a structure of
/// arrays.
#[derive(Clone, Debug, Default)]
pub(in crate::solver::contact_solver) struct Batch {
    /// Points per constraint (the same in every lane).
    count: usize,
    /// Exponents (shift counts) of the Jacobian and response entries.
    je: L64,
    ae: L64,
    n: [L32; 3],
    t: [[L32; 3]; 2],
    mass_t: [L32; 2],
    points: [LaneRow; MAX_MANIFOLD_POINTS],
    tangent: [LaneRow; 2],
    twist: LaneRow,
}

impl Batch {
    /// Whether `rows` (eight) can go in one batch: all on the narrow rows,
    /// with the same point count.
    pub(in crate::solver::contact_solver) fn fits(rows: &[NarrowRows]) -> bool {
        rows.len() == LANES && rows.iter().all(|r| r.on && r.count == rows[0].count)
    }

    /// Copies the constants of `rows` (eight, see [`Batch::fits`]).
    pub(in crate::solver::contact_solver) fn fill(&mut self, rows: &[NarrowRows]) {
        self.count = rows[0].count as usize;
        for (l, r) in rows.iter().enumerate().take(LANES) {
            self.je[l] = r.je as i64;
            self.ae[l] = r.ae as i64;
            for c in 0..3 {
                self.n[c][l] = r.n[c];
                self.t[0][c][l] = r.t[0][c];
                self.t[1][c][l] = r.t[1][c];
            }
            self.mass_t[0][l] = r.mass_t[0];
            self.mass_t[1][l] = r.mass_t[1];
            for (p, np) in self.points.iter_mut().zip(&r.points[..self.count]) {
                p.set(l, &np.row);
            }
            self.tangent[0].set(l, &r.tangent[0]);
            self.tangent[1].set(l, &r.tangent[1]);
            self.twist.set(l, &r.twist);
        }
    }
}

/// The two bodies' velocities of every lane, quanta.
#[derive(Clone, Copy, Default)]
struct Vels {
    va: [L64; 3],
    wa: [L64; 3],
    vb: [L64; 3],
    wb: [L64; 3],
}

/// One visit's state of every lane, gathered from the twin's rows.
#[derive(Clone, Copy, Default)]
struct State {
    v: Vels,
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

/// `Bodies::along` per lane.
#[inline(always)]
fn along(d: &[L32; 3], ja: &[L32; 3], jb: &[L32; 3], v: &Vels, je: &L64) -> L64 {
    let mut out = [0i64; LANES];
    for l in 0..LANES {
        let mut s = 0i64;
        for c in 0..3 {
            let dv = v.vb[c][l].wrapping_sub(v.va[c][l]);
            s = s.wrapping_add((d[c][l] as i64).wrapping_mul(dv));
            s = s.wrapping_add((jb[c][l] as i64).wrapping_mul(v.wb[c][l]));
            s = s.wrapping_sub((ja[c][l] as i64).wrapping_mul(v.wa[c][l]));
        }
        out[l] = rsh(s, je[l]);
    }
    out
}

/// `Bodies::apply` per lane.
#[inline(always)]
fn apply(d: &L64, row: &LaneRow, ae: &L64, v: &mut Vels) {
    for c in 0..3 {
        for l in 0..LANES {
            let p = |e: i32| rsh(d[l].wrapping_mul(e as i64), ae[l]);
            v.va[c][l] = v.va[c][l].wrapping_sub(p(row.ea[c][l]));
            v.wa[c][l] = v.wa[c][l].wrapping_sub(p(row.ca[c][l]));
            v.vb[c][l] = v.vb[c][l].wrapping_add(p(row.eb[c][l]));
            v.wb[c][l] = v.wb[c][l].wrapping_add(p(row.cb[c][l]));
        }
    }
}

/// `Bodies::fit` per lane, and-ed into `ok`.
#[inline(always)]
fn fit(v: &Vels, ok: &mut Mask) {
    for l in 0..LANES {
        let mut f = true;
        for c in 0..3 {
            f &= v.va[c][l].abs() < LIMIT
                && v.wa[c][l].abs() < LIMIT
                && v.vb[c][l].abs() < LIMIT
                && v.wb[c][l].abs() < LIMIT;
        }
        ok[l] &= f;
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

/// The rows of one batch on the lanes: the twin's friction and normal
/// rows, step by step. Returns each lane's guard.
#[inline(always)]
fn kernel(b: &Batch, st: &mut State, ms: i64, use_bias: bool, first: usize) -> Mask {
    let mut ok = [true; LANES];
    fit(&st.v, &mut ok);
    let mut active = [false; LANES];
    for l in 0..LANES {
        active[l] = !(st.disc[l] == 0
            && st.impulse_t[0][l] == 0
            && st.impulse_t[1][l] == 0
            && st.impulse_w[l] == 0);
    }
    // Friction at the patch centre: both tangents from the same
    // velocities, held in the disc, then the twist.
    let vt0 = along(&b.t[0], &b.tangent[0].ja, &b.tangent[0].jb, &st.v, &b.je);
    let vt1 = along(&b.t[1], &b.tangent[1].ja, &b.tangent[1].jb, &st.v, &b.je);
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
        apply(&d, &b.tangent[j], &b.ae, &mut st.v);
        fit(&st.v, &mut ok);
    }
    let mut d = [0i64; LANES];
    for l in 0..LANES {
        let mut s = 0i64;
        for c in 0..3 {
            s = s.wrapping_add((b.n[c][l] as i64).wrapping_mul(st.v.wb[c][l]));
            s = s.wrapping_sub((b.n[c][l] as i64).wrapping_mul(st.v.wa[c][l]));
        }
        let spin = rsh(s, b.je[l]);
        let want = st.impulse_w[l].wrapping_sub(spin);
        let tl = st.twist_limit[l];
        let n = if active[l] {
            want.clamp(-tl, tl)
        } else {
            st.impulse_w[l]
        };
        ok[l] &= !active[l] || (want.abs() < ROW_LIMIT && n.abs() < LIMIT);
        d[l] = n.wrapping_sub(st.impulse_w[l]);
        st.impulse_w[l] = n as i32 as i64;
    }
    apply(&d, &b.twist, &b.ae, &mut st.v);
    fit(&st.v, &mut ok);
    // The normal rows from point `first`.
    let count = b.count;
    for kk in 0..count {
        let i = if kk + first >= count {
            kk + first - count
        } else {
            kk + first
        };
        let p = &b.points[i];
        let vn = along(&b.n, &p.ja, &p.jb, &st.v, &b.je);
        let mut d = [0i64; LANES];
        for l in 0..LANES {
            let spec = st.speculative[i][l];
            let bias = if spec || use_bias { st.bias[i][l] } else { 0 };
            let soft = !spec && use_bias;
            let old = st.impulses[i][l];
            let x = old.wrapping_sub(vn[l]).wrapping_sub(bias);
            ok[l] &= x.abs() < ROW_LIMIT && !(st.saturated[i][l] && x > 0);
            let new = if soft { rsh(ms.wrapping_mul(x), 30) } else { x }.max(0);
            ok[l] &= new < LIMIT;
            d[l] = new.wrapping_sub(old);
            if st.first_vn[i][l] == i32::MAX as i64 && new > 0 {
                st.first_vn[i][l] = vn[l].clamp(i32::MIN as i64, i32::MAX as i64 - 1);
            }
            st.impulses[i][l] = new as i32 as i64;
        }
        apply(&d, p, &b.ae, &mut st.v);
        fit(&st.v, &mut ok);
    }
    ok
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512dq,avx512vl,avx512bw")]
fn kernel_avx512(b: &Batch, st: &mut State, ms: i64, use_bias: bool, first: usize) -> Mask {
    kernel(b, st, ms, use_bias, first)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn kernel_avx2(b: &Batch, st: &mut State, ms: i64, use_bias: bool, first: usize) -> Mask {
    kernel(b, st, ms, use_bias, first)
}

#[inline(never)]
fn kernel_plain(b: &Batch, st: &mut State, ms: i64, use_bias: bool, first: usize) -> Mask {
    kernel(b, st, ms, use_bias, first)
}

/// Which build of the lane kernel runs (the results are the same bits).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
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

    fn run(self, b: &Batch, st: &mut State, ms: i64, use_bias: bool, first: usize) -> Mask {
        match self {
            // SAFETY: `best` found these features on this CPU (a caller
            // that names a kernel explicitly, as the tests do, checks
            // `best` first).
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx512 => unsafe { kernel_avx512(b, st, ms, use_bias, first) },
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx2 => unsafe { kernel_avx2(b, st, ms, use_bias, first) },
            _ => kernel_plain(b, st, ms, use_bias, first),
        }
    }
}

/// One visit of eight constraints (`rows`, one batch, all on the narrow
/// rows) on the lanes of `kernel`: each accepted lane is committed as the
/// twin commits it. Returns the mask of lanes whose guard failed (nothing
/// of theirs written but their biases), for the caller to solve on the
/// Q32.32 rows.
pub(in crate::solver::contact_solver) fn visit(
    args: &VisitArgs<'_>,
    batch: &Batch,
    rows: &mut [NarrowRows],
    kernel: Kernel,
) -> Mask {
    let mut st = State::default();
    let mut begin = [[BodyVel::default(); 2]; LANES];
    let first = if batch.count == 0 {
        0
    } else {
        args.rot % batch.count
    };
    for (l, r) in rows.iter_mut().enumerate().take(LANES) {
        if r.bias_poses != args.poses {
            update_biases(r, args.bodies, args.params, args.poses);
        }
        let (va0, vb0) = args.arrays.load(r.a, r.b);
        let b = Bodies::of(&va0, &vb0);
        begin[l] = [va0, vb0];
        for c in 0..3 {
            st.v.va[c][l] = b.va[c];
            st.v.wa[c][l] = b.wa[c];
            st.v.vb[c][l] = b.vb[c];
            st.v.wb[c][l] = b.wb[c];
        }
        (st.disc[l], st.twist_limit[l]) = if r.limits_set {
            (r.disc_limit, r.twist_limit)
        } else {
            limits_for(r, normal_total(r))
        };
        st.impulse_t[0][l] = r.tangent[0].impulse as i64;
        st.impulse_t[1][l] = r.tangent[1].impulse as i64;
        st.impulse_w[l] = r.twist.impulse as i64;
        for (i, np) in r.points[..batch.count].iter().enumerate() {
            st.impulses[i][l] = np.row.impulse as i64;
            st.first_vn[i][l] = np.first_vn as i64;
            st.bias[i][l] = np.bias as i64;
            st.speculative[i][l] = np.speculative;
            st.saturated[i][l] = np.bias_saturated;
        }
    }
    let start = st.v;
    let ms = super::rsh(args.params.softness.mass_scale.to_bits(), 2);
    let ok = kernel.run(batch, &mut st, ms, args.use_bias, first);
    let mut refused = [false; LANES];
    for (l, r) in rows.iter_mut().enumerate().take(LANES) {
        if !ok[l] {
            refused[l] = true;
            continue;
        }
        let mut out = Outcome {
            impulse_t: [st.impulse_t[0][l] as i32, st.impulse_t[1][l] as i32],
            impulse_w: st.impulse_w[l] as i32,
            ..Outcome::default()
        };
        for i in 0..batch.count {
            out.impulses[i] = st.impulses[i][l] as i32;
            out.first_vn[i] = st.first_vn[i][l] as i32;
        }
        for c in 0..3 {
            out.moved[0][c] = st.v.va[c][l] - start.va[c][l];
            out.moved[1][c] = st.v.wa[c][l] - start.wa[c][l];
            out.moved[2][c] = st.v.vb[c][l] - start.vb[c][l];
            out.moved[3][c] = st.v.wb[c][l] - start.wb[c][l];
        }
        let [va0, vb0] = &begin[l];
        commit(args, r, &out, va0, vb0);
    }
    refused
}
