//! Broad phase: pair set against brute force, kind rules, determinism,
//! independence from tree shape, allocation.

use super::rng::{Draw, Rng};
use crate::collision::broad_phase::{BroadPhase, PairStats, ProxyId, ProxyKey, ProxyKind};
use crate::math::{Aabb, Scalar, Vec3};

type Pairs = Vec<(ProxyKey, ProxyKey)>;

fn margin() -> Scalar {
    Scalar::from_ratio(1, 10)
}

/// A pure filter standing in for category/mask/group rules: rejects about
/// one pair in five.
fn filter(a: ProxyKey, b: ProxyKey) -> bool {
    !(a.0 ^ b.0.rotate_left(7)).is_multiple_of(5)
}

/// Keys that do not follow creation order (multiplying by an odd constant
/// is a bijection on u64, so they stay unique).
fn key_of(serial: u64) -> ProxyKey {
    ProxyKey(serial.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 8)
}

fn kind_of(r: u64) -> ProxyKind {
    match r % 10 {
        0..=1 => ProxyKind::Static,
        2 => ProxyKind::Kinematic,
        3..=7 => ProxyKind::Dynamic,
        _ => ProxyKind::Sleeping,
    }
}

struct Body {
    id: ProxyId,
    key: ProxyKey,
    aabb: Aabb,
    vel: Vec3,
}

/// Every pair of live proxies whose fat boxes overlap, whose kinds pair and
/// that the filter accepts, sorted: the definition the broad phase must meet.
fn brute_force(bp: &BroadPhase, bodies: &[Body]) -> Pairs {
    let info: Vec<(ProxyKey, ProxyKind, Aabb)> = bodies
        .iter()
        .map(|b| (b.key, bp.kind(b.id).unwrap(), bp.fat_aabb(b.id).unwrap()))
        .collect();
    let mut out = Vec::new();
    for i in 0..info.len() {
        for j in i + 1..info.len() {
            let ((ka, kind_a, fa), (kb, kind_b, fb)) = (&info[i], &info[j]);
            if kind_a.pairs_with(*kind_b) && fa.overlaps(fb) {
                let (a, b) = if ka < kb { (*ka, *kb) } else { (*kb, *ka) };
                if filter(a, b) {
                    out.push((a, b));
                }
            }
        }
    }
    out.sort_unstable();
    out
}

/// A random scene of `n` proxies over `steps` steps: motion with bouncing
/// velocities, teleports, kind changes, creations and removals. Returns the
/// pair list of every step (and checks it against brute force if asked).
fn run_scene(seed: u64, n: usize, steps: usize, check: bool) -> (Vec<Pairs>, PairStats) {
    let mut rng = Rng::new(seed);
    let mut bp = BroadPhase::new(margin());
    let mut bodies: Vec<Body> = Vec::new();
    let mut serial = 0u64;
    let extent = 20;
    let spawn = |bp: &mut BroadPhase, rng: &mut Rng, serial: &mut u64| {
        let aabb = rng.aabb(extent, 2);
        let key = key_of(*serial);
        *serial += 1;
        let kind = kind_of(rng.next_u64());
        let id = bp.create_proxy(aabb, key, kind);
        // Up to 1/16 per step; one body in four rests.
        let vel = if rng.below(4) == 0 {
            Vec3::ZERO
        } else {
            rng.vec(-1, 1) * Scalar::from_ratio(1, 16)
        };
        Body { id, key, aabb, vel }
    };
    for _ in 0..n {
        let b = spawn(&mut bp, &mut rng, &mut serial);
        bodies.push(b);
    }
    let mut lists = Vec::with_capacity(steps);
    let mut totals = PairStats::default();
    let limit = Scalar::from_int(extent + 2);
    for step in 0..steps {
        for b in bodies.iter_mut() {
            match bp.kind(b.id).unwrap() {
                ProxyKind::Dynamic | ProxyKind::Kinematic => {
                    for ax in 0..3 {
                        let c = b.aabb.center().get(ax);
                        let v = b.vel.get(ax);
                        if (c > limit && v.is_positive()) || (c < -limit && v.is_negative()) {
                            b.vel.set(ax, -v);
                        }
                    }
                    b.aabb = Aabb::new(b.aabb.min + b.vel, b.aabb.max + b.vel);
                    bp.move_proxy(b.id, b.aabb, b.vel).unwrap();
                }
                ProxyKind::Static | ProxyKind::Sleeping => {}
            }
        }
        // Churn: teleports (any kind), kind changes, removals, creations.
        for _ in 0..rng.below(4) {
            let k = rng.below(bodies.len() as u64) as usize;
            bodies[k].aabb = rng.aabb(extent, 2);
            bp.move_proxy(bodies[k].id, bodies[k].aabb, Vec3::ZERO)
                .unwrap();
        }
        for _ in 0..rng.below(6) {
            let k = rng.below(bodies.len() as u64) as usize;
            bp.set_kind(bodies[k].id, kind_of(rng.next_u64())).unwrap();
        }
        for _ in 0..rng.below(4) {
            let k = rng.below(bodies.len() as u64) as usize;
            let b = bodies.swap_remove(k);
            bp.destroy_proxy(b.id).unwrap();
        }
        for _ in 0..rng.below(4) {
            let b = spawn(&mut bp, &mut rng, &mut serial);
            bodies.push(b);
        }
        if step % 97 == 50 {
            bp.rebuild_trees();
        }
        let mut out = Vec::new();
        let stats = bp.update_pairs(filter, &mut out);
        totals.moved_proxies += stats.moved_proxies;
        totals.tree_queries += stats.tree_queries;
        totals.pairs_found += stats.pairs_found;
        totals.pairs_filtered += stats.pairs_filtered;
        totals.pairs_kept += stats.pairs_kept;
        totals.pairs_total += stats.pairs_total;
        totals.reinsertions += stats.reinsertions;
        assert_eq!(stats.pairs_total as usize, out.len());
        if check {
            assert_eq!(bp.validate(), Ok(()), "step {step}");
            assert_eq!(out, brute_force(&bp, &bodies), "step {step}");
        }
        lists.push(out);
    }
    (lists, totals)
}

#[test]
fn pair_set_equals_brute_force_fat_overlap_over_300_random_steps_of_1000_proxies() {
    let (lists, t) = run_scene(0xB0AD, 1000, 300, true);
    let sizes: Vec<usize> = lists.iter().map(Vec::len).collect();
    let (min, max) = (sizes.iter().min().unwrap(), sizes.iter().max().unwrap());
    println!(
        "pairs per step {min}..{max}; totals: moved {}, queries {}, found {}, filtered {}, \
         kept {}, reinsertions {}",
        t.moved_proxies,
        t.tree_queries,
        t.pairs_found,
        t.pairs_filtered,
        t.pairs_kept,
        t.reinsertions
    );
    assert!(*min > 100, "the scene must produce pairs");
    assert!(t.pairs_kept > 0 && t.pairs_found > 0 && t.pairs_filtered > 0);
    assert!(t.reinsertions > 0);
    // Pairs that merely persist are kept, not found again by a query.
    assert!(t.pairs_kept as usize > sizes.iter().sum::<usize>() / 4);
}

#[test]
fn same_operations_give_bit_identical_pair_lists() {
    let (a, ta) = run_scene(1234, 600, 120, false);
    let (b, tb) = run_scene(1234, 600, 120, false);
    assert_eq!(a, b);
    assert_eq!(ta, tb);
    let (c, _) = run_scene(1235, 600, 120, false);
    assert_ne!(a, c);
}

/// The same final set of proxies reached by three different histories.
#[test]
fn pair_list_does_not_depend_on_tree_shape_or_insertion_history() {
    let mut rng = Rng::new(31337);
    let protos: Vec<(Aabb, ProxyKey, ProxyKind)> = (0..800)
        .map(|i| (rng.aabb(15, 2), key_of(i), kind_of(rng.next_u64())))
        .collect();

    // History 1: forward order.
    let mut a = BroadPhase::new(margin());
    for &(b, k, kind) in &protos {
        a.create_proxy(b, k, kind);
    }
    // History 2: reverse order, with decoys created and destroyed in between,
    // then every proxy starts with another kind and is switched back.
    let mut b = BroadPhase::new(margin());
    let mut ids = Vec::new();
    for (i, &(bx, k, kind)) in protos.iter().enumerate().rev() {
        let decoy = b.create_proxy(rng.aabb(15, 2), ProxyKey(u64::MAX - i as u64), kind);
        let flipped = if kind.is_moving() {
            ProxyKind::Sleeping
        } else {
            ProxyKind::Dynamic
        };
        ids.push((b.create_proxy(bx, k, flipped), kind));
        b.destroy_proxy(decoy).unwrap();
    }
    let mut scratch = Vec::new();
    b.update_pairs(filter, &mut scratch);
    for &(id, kind) in &ids {
        b.set_kind(id, kind).unwrap();
    }
    // History 3: forward order, then both trees rebuilt.
    let mut c = BroadPhase::new(margin());
    for &(bx, k, kind) in &protos {
        c.create_proxy(bx, k, kind);
    }
    c.rebuild_trees();

    let areas = [&a, &b, &c].map(|bp| bp.moving_tree().internal_area());
    assert!(
        areas[0] != areas[1] && areas[0] != areas[2],
        "shapes must differ"
    );
    let (mut pa, mut pb, mut pc) = (Vec::new(), Vec::new(), Vec::new());
    a.update_pairs(filter, &mut pa);
    b.update_pairs(filter, &mut pb);
    c.update_pairs(filter, &mut pc);
    println!("{} pairs from three histories", pa.len());
    assert!(pa.len() > 200);
    assert_eq!(pa, pb);
    assert_eq!(pa, pc);
    assert!(pa.windows(2).all(|w| w[0] < w[1]) && pa.iter().all(|(x, y)| x < y));
}

#[test]
fn kinds_pair_only_when_a_dynamic_body_or_a_kinematic_and_a_sleeper_meet() {
    let mut bp = BroadPhase::new(margin());
    let unit = Aabb::new(Vec3::ZERO, Vec3::splat(Scalar::ONE));
    let s = bp.create_proxy(unit, ProxyKey(1), ProxyKind::Static);
    let _s2 = bp.create_proxy(unit, ProxyKey(2), ProxyKind::Static);
    let k = bp.create_proxy(unit, ProxyKey(3), ProxyKind::Kinematic);
    let _k2 = bp.create_proxy(unit, ProxyKey(4), ProxyKind::Kinematic);
    let d = bp.create_proxy(unit, ProxyKey(5), ProxyKind::Dynamic);
    let z = bp.create_proxy(unit, ProxyKey(6), ProxyKind::Sleeping);
    let _z2 = bp.create_proxy(unit, ProxyKey(7), ProxyKind::Sleeping);
    let p = |a, b| (ProxyKey(a), ProxyKey(b));
    let mut out = Vec::new();
    bp.update_pairs(|_, _| true, &mut out);
    // D with everyone; K with the sleepers.
    assert_eq!(
        out,
        vec![
            p(1, 5),
            p(2, 5),
            p(3, 5),
            p(3, 6),
            p(3, 7),
            p(4, 5),
            p(4, 6),
            p(4, 7),
            p(5, 6),
            p(5, 7)
        ]
    );
    // The sleeper wakes up; the dynamic one falls asleep.
    bp.set_kind(z, ProxyKind::Dynamic).unwrap();
    bp.set_kind(d, ProxyKind::Sleeping).unwrap();
    let stats = bp.update_pairs(|_, _| true, &mut out);
    assert_eq!(
        out,
        vec![
            p(1, 6),
            p(2, 6),
            p(3, 5),
            p(3, 6),
            p(3, 7),
            p(4, 5),
            p(4, 6),
            p(4, 7),
            p(5, 6),
            p(6, 7)
        ]
    );
    assert_eq!(stats.reinsertions, 2, "both switched trees");
    assert_eq!(stats.pairs_kept, 2, "3-7 and 4-7 involve neither");
    // Static and kinematic proxies never pair with each other.
    bp.set_kind(k, ProxyKind::Static).unwrap();
    bp.set_kind(s, ProxyKind::Kinematic).unwrap();
    bp.update_pairs(|_, _| true, &mut out);
    assert!(out.contains(&p(1, 5)) && !out.contains(&p(3, 5)) && out.contains(&p(3, 6)));
    assert_eq!(bp.validate(), Ok(()));
}

#[test]
fn pairs_end_when_fat_boxes_part_and_slot_reuse_leaves_no_stale_pair() {
    let mut bp = BroadPhase::new(margin());
    let unit = Aabb::new(Vec3::ZERO, Vec3::splat(Scalar::ONE));
    let a = bp.create_proxy(unit, ProxyKey(10), ProxyKind::Dynamic);
    let b = bp.create_proxy(unit, ProxyKey(20), ProxyKind::Dynamic);
    let mut out = Vec::new();
    bp.update_pairs(|_, _| true, &mut out);
    assert_eq!(out, vec![(ProxyKey(10), ProxyKey(20))]);

    // Nothing moves: the pair is kept without a query.
    let st = bp.update_pairs(|_, _| true, &mut out);
    assert_eq!((st.pairs_kept, st.tree_queries, out.len()), (1, 0, 1));

    // 1.15 apart along x: the fat boxes (margin 0.1 each) no longer touch.
    let d = Vec3::new(
        Scalar::from_ratio(23, 20) + Scalar::ONE,
        Scalar::ZERO,
        Scalar::ZERO,
    );
    let moved = Aabb::new(unit.min + d, unit.max + d);
    assert_eq!(bp.move_proxy(b, moved, Vec3::ZERO), Ok(true));
    let st = bp.update_pairs(|_, _| true, &mut out);
    assert!(out.is_empty());
    assert_eq!(
        (st.moved_proxies, st.tree_queries, st.reinsertions),
        (1, 2, 1)
    );

    // Destroy `a` and create `c` in its slot in the same step: the pair
    // a–b must not survive under c's name.
    bp.move_proxy(b, unit, Vec3::ZERO).unwrap();
    bp.update_pairs(|_, _| true, &mut out);
    assert_eq!(out, vec![(ProxyKey(10), ProxyKey(20))]);
    bp.destroy_proxy(a).unwrap();
    let far = Aabb::new(Vec3::from_ints(50, 0, 0), Vec3::from_ints(51, 1, 1));
    let c = bp.create_proxy(far, ProxyKey(5), ProxyKind::Dynamic);
    assert_eq!(c, a, "slots are reused LIFO");
    bp.update_pairs(|_, _| true, &mut out);
    assert!(out.is_empty());
    assert!(bp.destroy_proxy(ProxyId::from_index(99)).is_err());
    assert_eq!(bp.validate(), Ok(()));
}

#[test]
fn touch_proxy_reapplies_the_filter_to_kept_pairs() {
    let mut bp = BroadPhase::new(margin());
    let unit = Aabb::new(Vec3::ZERO, Vec3::splat(Scalar::ONE));
    let a = bp.create_proxy(unit, ProxyKey(1), ProxyKind::Dynamic);
    bp.create_proxy(unit, ProxyKey(2), ProxyKind::Dynamic);
    let mut out = Vec::new();
    bp.update_pairs(|_, _| true, &mut out);
    assert_eq!(out.len(), 1);
    // Kept pairs are not filtered again...
    bp.update_pairs(|_, _| false, &mut out);
    assert_eq!(out.len(), 1);
    // ...until the caller says the filter inputs changed.
    bp.touch_proxy(a).unwrap();
    let st = bp.update_pairs(|_, _| false, &mut out);
    assert_eq!((out.len(), st.pairs_found, st.pairs_filtered), (0, 1, 1));
}

/// A 40 × 50 grid of boxes, neighbours 2 apart with half-extent 0.75.
fn grid(bp: &mut BroadPhase) -> Vec<(ProxyId, Aabb)> {
    let mut ids = Vec::new();
    for i in 0..40i32 {
        for j in 0..50i32 {
            let c = Vec3::from_ints(i * 2, 0, j * 2);
            let b = Aabb::from_center_half_extents(c, Vec3::splat(Scalar::from_ratio(3, 4)));
            let key = ProxyKey((i * 50 + j) as u64);
            ids.push((bp.create_proxy(b, key, ProxyKind::Dynamic), b));
        }
    }
    ids
}

/// Moves the grid's boxes diagonally, alternate boxes in opposite
/// directions, on a triangle wave of period 16 steps and amplitude 0.5: the
/// pair count is periodic, so the capacities reached in one period suffice.
fn oscillate(
    bp: &mut BroadPhase,
    grid: &[(ProxyId, Aabb)],
    steps: std::ops::Range<usize>,
    out: &mut Pairs,
) -> Vec<PairStats> {
    let amp = Scalar::from_ratio(1, 8);
    let mut stats = Vec::new();
    for step in steps {
        let phase = (step % 16) as i64;
        let s = if phase < 8 { phase - 4 } else { 12 - phase };
        for (n, (id, b)) in grid.iter().enumerate() {
            let dir = if n % 2 == 0 { 1 } else { -1 };
            let off = Vec3::new(amp.mul_int(s * dir), Scalar::ZERO, amp.mul_int(s * dir));
            let vel = Vec3::new(amp.mul_int(dir), Scalar::ZERO, amp.mul_int(dir));
            bp.move_proxy(*id, Aabb::new(b.min + off, b.max + off), vel)
                .unwrap();
        }
        stats.push(bp.update_pairs(filter, out));
    }
    stats
}

#[test]
fn warm_update_pairs_does_not_allocate() {
    // Pre-sized: no growth from the first step on.
    let mut bp = BroadPhase::with_capacity(margin(), 2000, 20_000);
    let mut out = Vec::with_capacity(20_000);
    let before = (bp.buffer_capacity(), out.capacity());
    let g = grid(&mut bp);
    let stats = oscillate(&mut bp, &g, 0..64, &mut out);
    assert_eq!((bp.buffer_capacity(), out.capacity()), before);
    assert!(stats.iter().all(|s| s.buffer_growths == 0));
    let reinserted: u32 = stats.iter().map(|s| s.reinsertions).sum();
    println!(
        "pre-sized: {} pairs, {reinserted} reinsertions in 64 steps",
        out.len()
    );
    assert!(reinserted > 1000 && !out.is_empty());

    // Not pre-sized: growth is reported while warming up, then stops.
    let mut bp = BroadPhase::new(margin());
    let mut out = Vec::new();
    let g = grid(&mut bp);
    let stats = oscillate(&mut bp, &g, 0..32, &mut out);
    let growths: Vec<u32> = stats.iter().map(|s| s.buffer_growths).collect();
    println!("growths per step (not pre-sized): {growths:?}");
    assert!(growths[0] > 0);
    assert!(growths[16..].iter().all(|&g| g == 0));
    let warm = (bp.buffer_capacity(), out.capacity());
    let stats = oscillate(&mut bp, &g, 32..96, &mut out);
    assert!(stats.iter().all(|s| s.buffer_growths == 0));
    assert_eq!((bp.buffer_capacity(), out.capacity()), warm);
}

#[test]
fn a_restored_snapshot_continues_with_the_same_pairs() {
    let cfg = bincode::config::standard();
    let mut bp = BroadPhase::new(margin());
    let g = grid(&mut bp);
    let mut out = Vec::new();
    oscillate(&mut bp, &g, 0..11, &mut out);
    let bytes = bincode::serde::encode_to_vec(&bp, cfg).unwrap();
    let (mut restored, _): (BroadPhase, usize) =
        bincode::serde::decode_from_slice(&bytes, cfg).unwrap();
    assert_eq!(restored.validate(), Ok(()));
    let mut out2 = Vec::new();
    for k in 11..40 {
        let a = oscillate(&mut bp, &g, k..k + 1, &mut out);
        let b = oscillate(&mut restored, &g, k..k + 1, &mut out2);
        assert_eq!(out, out2, "step {k}");
        assert_eq!(a[0].reinsertions, b[0].reinsertions);
        assert_eq!(a[0].tree_queries, b[0].tree_queries);
    }
    assert!(!out.is_empty());
    assert_eq!(bincode::serde::encode_to_vec(&restored, cfg).unwrap(), {
        bincode::serde::encode_to_vec(&bp, cfg).unwrap()
    });
}
