use super::super::{LIMIT, ROWS};
use super::*;
use crate::math::{Scalar, Vec3};
use crate::solver::contact_solver::constraint::NONE;
use crate::solver::contact_solver::params::{Softness, SolverParams};
use crate::solver::contact_solver::quanta::{Quanta, S, flush, quantize};
use crate::solver::contact_solver::rows::BodyArrays;

use crate::testing::Rng;

/// The draws these tests need, from the workspace's test generator.
trait Draws {
    fn next(&mut self) -> u64;
    /// A value in `[-m, m]`.
    fn within(&mut self, m: i64) -> i64;
    fn i32s(&mut self, m: i64) -> [i32; 3];
}

impl Draws for Rng {
    fn next(&mut self) -> u64 {
        self.next_u64()
    }

    fn within(&mut self, m: i64) -> i64 {
        (self.next_u64() % (2 * m as u64 + 1)) as i64 - m
    }

    fn i32s(&mut self, m: i64) -> [i32; 3] {
        [0; 3].map(|_| self.within(m) as i32)
    }
}

fn params() -> SolverParams {
    let h = Scalar::from_ratio(1, 240);
    SolverParams {
        h,
        inv_h: Scalar::from_int(240),
        softness: Softness::new(Scalar::from_int(60), Scalar::from_int(10), h),
        omega: Scalar::ZERO,
        zeta: Scalar::from_int(10),
        omega_max: Scalar::ZERO,
        max_push_out: Scalar::from_int(3),
        restitution_threshold: Scalar::ONE,
        colored: true,
        narrow: true,
    }
}

/// Eight constraints' rows and sixteen bodies' velocities at a scale:
/// `v` the velocities' and `j` the entries' largest magnitude (quanta,
/// and at `2^30`). Lane `l` holds bodies `2l` and `2l + 1`, some of
/// them `NONE` (static) or not written (kinematic).
fn inputs(
    rng: &mut Rng,
    count: usize,
    v: i64,
    j: i64,
) -> ([NarrowRows; LANES], Vec<BodyVel>, Vec<PoseQ>) {
    let rows = std::array::from_fn(|l| {
        let mut r = NarrowRows {
            on: true,
            count: count as u8,
            je: 24 + (rng.next() % 7) as u8,
            ae: 22 + (rng.next() % 9) as u8,
            ge: 20 + (rng.next() % 11) as u8,
            me: (rng.next() % 40) as i8,
            limits_set: !rng.next().is_multiple_of(4),
            ..NarrowRows::default()
        };
        r.a = if l % 3 == 0 { NONE } else { 2 * l as u32 };
        r.b = 2 * l as u32 + 1;
        r.wa = r.a;
        r.wb = if l % 4 == 1 { NONE } else { r.b };
        // Half the lanes' biases are at the visit's poses (7), the
        // others are computed by the visit from the separation terms.
        r.bias_poses = if rng.next().is_multiple_of(2) { 7 } else { 6 };
        r.nq = rng.i32s(1 << 30);
        for i in 0..MAX_MANIFOLD_POINTS {
            r.raq[i] = rng.i32s(1 << 30);
            r.rbq[i] = rng.i32s(1 << 30);
            r.sep0[i] = rng.within(1 << 36);
        }
        r.n = rng.i32s(1 << 30);
        r.t = [rng.i32s(1 << 30), rng.i32s(1 << 30)];
        r.mass_t = [0; 2].map(|_| rng.within(1 << 30).abs() as i32);
        for k in 0..ROWS {
            let row = &mut r.rows[k];
            row.ja = rng.i32s(j);
            row.jb = rng.i32s(j);
            row.ea = rng.i32s(j);
            row.eb = rng.i32s(j);
            row.ca = rng.i32s(j);
            row.cb = rng.i32s(j);
            row.ga = rng.i32s(j);
            row.gb = rng.i32s(j);
            r.mass[k] = Scalar::from_bits(rng.within(1 << 40).abs() + 1);
            r.impulse[k] = rng.within(v.min(LIMIT - 1)) as i32;
            r.mark[k] = rng.within(v.min(LIMIT - 1)) as i32;
        }
        for i in 0..MAX_MANIFOLD_POINTS {
            r.impulse[i] = r.impulse[i].abs();
            r.max_impulse[i] = r.impulse[i];
            r.first_vn[i] = if rng.next().is_multiple_of(2) {
                i32::MAX
            } else {
                rng.within(v) as i32
            };
            r.bias[i] = rng.within((2 * v).min(1 << 30)) as i32;
            r.speculative[i] = rng.next().is_multiple_of(3);
            r.saturated[i] = rng.next().is_multiple_of(16);
        }
        r.disc_limit = rng.within(1 << 62).abs();
        r.twist_limit = rng.within(LIMIT).abs();
        r.friction = Scalar::from_bits(rng.within(1 << 32).abs());
        r.twist_reach = Scalar::from_bits(rng.within(1 << 32).abs());
        r.k_w = Scalar::from_bits(rng.within(1 << 36).abs());
        if rng.next().is_multiple_of(8) {
            // Inactive friction: nothing to bound, nothing held.
            r.disc_limit = 0;
            r.limits_set = true;
            r.impulse[T0..].copy_from_slice(&[0; 3]);
        }
        r
    });
    let q = |x: i64| Scalar::from_bits(x << (32 - S));
    let vels = (0..2 * LANES)
        .map(|_| BodyVel {
            v: Vec3::new(q(rng.within(v)), q(rng.within(v)), q(rng.within(v))),
            w: Vec3::new(q(rng.within(v)), q(rng.within(v)), q(rng.within(v))),
        })
        .collect();
    // Pose changes: one body in sixteen does not fit.
    let pq = (0..2 * LANES)
        .map(|_| PoseQ {
            dp: rng.i32s(1 << 31),
            d: [0; 3].map(|_| rng.i32s(1 << 30)),
            fit: !rng.next().is_multiple_of(16),
        })
        .collect();
    (rows, vels, pq)
}

/// Runs the twin on each row, then every lane kernel this CPU has on
/// the same inputs, and compares rows, velocities, momenta and
/// refusals.
fn compare(
    (rows, vels, pq): ([NarrowRows; LANES], Vec<BodyVel>, Vec<PoseQ>),
    use_bias: bool,
    rot: usize,
) -> usize {
    let params = params();
    let n = vels.len();
    let run = |visit: &dyn Fn(&VisitArgs<'_>, &mut [NarrowRows]) -> Mask| {
        let (mut rows, mut vels) = (rows, vels.clone());
        let (mut dls, mut warm) = (vec![Vec3::ZERO; n], vec![BodyVel::default(); n]);
        let (mut q, mut q0) = (vec![Quanta::default(); n], vec![Quanta::default(); n]);
        quantize(&vels, &mut q, &mut q0);
        // SAFETY: one thread; the vectors outlive the arrays.
        let arrays =
            unsafe { BodyArrays::new(&mut vels, &mut dls, &mut warm).with_quanta(&mut q, &mut q0) };
        let args = VisitArgs {
            params: &params,
            pq: &pq,
            arrays: &arrays,
            use_bias,
            rot,
            poses: 7,
        };
        let refused = visit(&args, &mut rows);
        flush(&mut vels, &q, &mut q0);
        (refused, rows, vels, dls)
    };
    let twin = run(&|args, rows| std::array::from_fn(|l| !super::super::visit(args, &mut rows[l])));
    let mut batch = Batch::default();
    batch.fill(&rows, 0);
    #[cfg(target_arch = "x86_64")]
    let avx2 = std::arch::is_x86_feature_detected!("avx2");
    #[cfg(not(target_arch = "x86_64"))]
    let avx2 = false;
    let kernels = [
        Some(Kernel::Plain),
        avx2.then_some(Kernel::Avx2),
        (Kernel::best() == Kernel::Avx512).then_some(Kernel::Avx512),
    ];
    for kernel in kernels.into_iter().flatten() {
        let lanes = run(&|args, rows| {
            let mut batch = batch.clone();
            let refused = visit(args, &mut batch, rows, kernel);
            batch.unload(rows);
            refused
        });
        assert_eq!(lanes.0, twin.0, "{kernel:?}: refusals");
        for l in 0..LANES {
            assert_eq!(lanes.1[l], twin.1[l], "{kernel:?}: lane {l}'s rows");
        }
        assert_eq!(lanes.2, twin.2, "{kernel:?}: velocities");
        assert_eq!(lanes.3, twin.3, "{kernel:?}: momenta");
    }
    twin.0.iter().filter(|&&r| !r).count()
}

#[test]
fn every_lane_kernel_gives_the_twins_bits_and_refusals() {
    let mut rng = Rng::new(17);
    let (mut accepted, mut refused) = (0, 0);
    for round in 0..600 {
        let count = 1 + round % MAX_MANIFOLD_POINTS;
        // Small values (accepted), values near the guard, and values
        // past it (refused).
        let (v, j) = match round % 4 {
            0 | 1 => (1 << 18, 1 << 28),
            2 => (1 << 27, 1 << 30),
            _ => (1 << 30, 1 << 30),
        };
        let ok = compare(inputs(&mut rng, count, v, j), round % 2 == 0, round);
        accepted += ok;
        refused += LANES - ok;
    }
    assert!(
        accepted > 1000 && refused > 1000,
        "{accepted} accepted, {refused} refused"
    );
}

#[test]
fn the_lanes_warm_start_is_the_twins() {
    let mut rng = Rng::new(5);
    for round in 0..200 {
        let (rows, _, _) = inputs(&mut rng, 1 + round % MAX_MANIFOLD_POINTS, 1 << 20, 1 << 30);
        let mut batch = Batch::default();
        batch.fill(&rows, 0);
        let (mut a, mut b) = (rows, rows);
        batch.load(&a);
        let lanes = warm_start(&mut batch, &a);
        batch.unload(&mut a);
        for l in 0..LANES {
            assert_eq!(lanes[l], super::super::warm_start(&mut b[l]), "lane {l}");
            assert_eq!(a[l], b[l], "lane {l}'s rows");
        }
    }
}
