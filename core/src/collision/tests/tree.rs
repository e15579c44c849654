//! Dynamic tree: invariants, queries against brute force, fat boxes,
//! rebuild, determinism.

use super::rng::{Draw, Rng};
use crate::collision::dynamic_tree::{DynamicTree, LeafId, TreeError};
use crate::math::{Aabb, Scalar, Vec3};
use crate::testing::{s, v};

fn margin() -> Scalar {
    Scalar::from_ratio(1, 10)
}

fn brute_force(tree: &DynamicTree, q: &Aabb) -> Vec<u64> {
    let mut hits = Vec::new();
    tree.for_each_proxy(|_, data, fat| {
        if fat.overlaps(q) {
            hits.push(data);
        }
    });
    hits.sort_unstable();
    hits
}

fn query_sorted(tree: &DynamicTree, q: &Aabb) -> Vec<u64> {
    let mut hits = Vec::new();
    tree.query(q, |_, data| {
        hits.push(data);
        true
    });
    hits.sort_unstable();
    hits
}

#[test]
fn tree_stays_valid_through_6000_random_inserts_moves_and_removes() {
    let mut rng = Rng::new(0x5eed_0001);
    let mut tree = DynamicTree::new(margin());
    let mut live: Vec<(LeafId, Aabb)> = Vec::new();
    let (mut inserts, mut removes, mut moves, mut reinserted) = (0, 0, 0, 0);
    for op in 0..6000 {
        let r = rng.below(10);
        if r < 4 || live.len() < 10 {
            let b = rng.aabb(30, 3);
            let id = tree.create_proxy(b, op);
            live.push((id, b));
            inserts += 1;
        } else if r < 6 {
            let k = rng.below(live.len() as u64) as usize;
            let (id, _) = live.swap_remove(k);
            assert!(tree.destroy_proxy(id).is_ok());
            removes += 1;
        } else {
            let k = rng.below(live.len() as u64) as usize;
            let d = rng.vec(-1, 1);
            let b = Aabb::new(live[k].1.min + d, live[k].1.max + d);
            live[k].1 = b;
            if tree.move_proxy(live[k].0, b, d).unwrap() {
                reinserted += 1;
            }
            moves += 1;
            let fat = tree.fat_aabb(live[k].0).unwrap();
            assert!(fat.contains(&b), "fat box must contain the tight box");
        }
        if op % 1000 == 999 {
            tree.rebuild();
        }
        assert_eq!(tree.validate(), Ok(()), "after op {op}");
        assert_eq!(tree.proxy_count(), live.len());
    }
    println!(
        "inserts {inserts}, removes {removes}, moves {moves} ({reinserted} reinserted), \
         final {} leaves, height {}, {} nodes",
        live.len(),
        tree.height(),
        tree.node_count()
    );
    assert_eq!(inserts + removes + moves, 6000);
    assert!(
        reinserted > moves / 2,
        "moves of up to 1 unit leave a 0.1 margin"
    );
    // Free-list reuse: the pool never holds more than 2·peak − 1 nodes.
    assert!(tree.node_count() < 2 * inserts);
}

#[test]
fn query_matches_brute_force_for_500_random_boxes() {
    let mut rng = Rng::new(42);
    let mut tree = DynamicTree::new(margin());
    for i in 0..2000 {
        tree.create_proxy(rng.aabb(50, 2), i);
    }
    let mut total = 0;
    for _ in 0..500 {
        let q = rng.aabb(55, 12);
        let expected = brute_force(&tree, &q);
        assert_eq!(query_sorted(&tree, &q), expected);
        total += expected.len();
    }
    tree.rebuild();
    let mut total_after = 0;
    let mut rng = Rng::new(43);
    for _ in 0..500 {
        let q = rng.aabb(55, 12);
        let expected = brute_force(&tree, &q);
        assert_eq!(query_sorted(&tree, &q), expected);
        total_after += expected.len();
    }
    println!("hits: {total} before rebuild, {total_after} after (different boxes)");
    assert!(
        total > 1000 && total_after > 1000,
        "queries must hit something"
    );
}

#[test]
fn query_stops_when_the_callback_says_so() {
    let mut tree = DynamicTree::new(Scalar::ZERO);
    let b = Aabb::new(Vec3::ZERO, Vec3::splat(Scalar::ONE));
    for i in 0..10 {
        tree.create_proxy(b, i);
    }
    let mut seen = 0;
    tree.query(&b, |_, _| {
        seen += 1;
        seen < 3
    });
    assert_eq!(seen, 3);
    assert_eq!(query_sorted(&tree, &b).len(), 10);
}

#[test]
fn small_moves_stay_in_the_fat_box_and_large_moves_stretch_it_forward() {
    let m = margin();
    let mut tree = DynamicTree::new(m);
    let b = Aabb::new(Vec3::ZERO, Vec3::splat(Scalar::ONE));
    let id = tree.create_proxy(b, 7);
    assert_eq!(tree.fat_aabb(id), Ok(b.expanded(m)));

    // 0.05 along x: still inside the fat box.
    let small = Vec3::new(Scalar::from_ratio(1, 20), Scalar::ZERO, Scalar::ZERO);
    let b2 = Aabb::new(b.min + small, b.max + small);
    assert_eq!(tree.move_proxy(id, b2, small), Ok(false));
    assert_eq!(tree.fat_aabb(id), Ok(b.expanded(m)));

    // 0.5 along +x, -0.25 along y: reinserted, stretched on the side it goes.
    let d = Vec3::new(Scalar::HALF, -Scalar::from_ratio(1, 4), Scalar::ZERO);
    let b3 = Aabb::new(b.min + d, b.max + d);
    assert_eq!(tree.move_proxy(id, b3, d), Ok(true));
    let fat = tree.fat_aabb(id).unwrap();
    let expect = b3.expanded(m);
    assert_eq!(fat.min.x, expect.min.x);
    assert_eq!(fat.max.x, expect.max.x + Scalar::HALF);
    assert_eq!(fat.min.y, expect.min.y - Scalar::from_ratio(1, 4));
    assert_eq!(fat.max.y, expect.max.y);
    assert_eq!((fat.min.z, fat.max.z), (expect.min.z, expect.max.z));

    // It stops: the box stretched 0.5 ahead is more than the new fat box
    // plus four margins (0.4), so it is shrunk back.
    assert_eq!(tree.move_proxy(id, b3, Vec3::ZERO), Ok(true));
    assert_eq!(tree.fat_aabb(id), Ok(b3.expanded(m)));
    // A move of 0.3 leaves the fat box; stopping then keeps the 0.3 stretch.
    let d = Vec3::new(Scalar::from_ratio(3, 10), Scalar::ZERO, Scalar::ZERO);
    let b4 = Aabb::new(b3.min + d, b3.max + d);
    assert_eq!(tree.move_proxy(id, b4, d), Ok(true));
    assert_eq!(tree.move_proxy(id, b4, Vec3::ZERO), Ok(false));
    assert_eq!(tree.fat_aabb(id).unwrap().max.x, b4.max.x + m + d.x);
    assert_eq!(tree.validate(), Ok(()));
}

#[test]
fn stale_leaf_ids_are_rejected_with_an_error() {
    let mut tree = DynamicTree::new(margin());
    let a = tree.create_proxy(Aabb::default(), 1);
    let b = tree.create_proxy(Aabb::default(), 2);
    assert_eq!(tree.destroy_proxy(a), Ok(1));
    assert_eq!(tree.destroy_proxy(a), Err(TreeError::InvalidLeaf(a)));
    assert_eq!(
        tree.move_proxy(a, Aabb::default(), Vec3::ZERO),
        Err(TreeError::InvalidLeaf(a))
    );
    // The internal node freed with `a` is not a leaf either.
    let internal = LeafId::from_raw(2);
    assert!(tree.fat_aabb(internal).is_err());
    assert_eq!(tree.user_data(b), Ok(2));
    assert_eq!(tree.validate(), Ok(()));
}

#[test]
fn rebuild_keeps_every_leaf_and_lowers_the_sah_cost_of_a_sorted_insertion() {
    // Boxes inserted in sweep order: the worst case for incremental insertion.
    let mut tree = DynamicTree::new(margin());
    let mut ids = Vec::new();
    for i in 0..40i32 {
        for j in 0..40i32 {
            let c = Vec3::from_ints(i * 2, 0, j * 2);
            let b = Aabb::from_center_half_extents(c, Vec3::splat(Scalar::HALF));
            ids.push((tree.create_proxy(b, (i * 40 + j) as u64), b));
        }
    }
    let (cost_before, height_before) = (tree.internal_area(), tree.height());
    let q = Aabb::new(Vec3::from_ints(10, -1, 10), Vec3::from_ints(30, 1, 20));
    let hits_before = query_sorted(&tree, &q);
    tree.rebuild();
    assert_eq!(tree.validate(), Ok(()));
    let (cost_after, height_after) = (tree.internal_area(), tree.height());
    let ratio = cost_after as f64 / cost_before as f64;
    println!(
        "1600 sorted boxes: height {height_before} -> {height_after}, SAH cost ratio {ratio:.3}"
    );
    assert!(cost_after < cost_before);
    assert_eq!(query_sorted(&tree, &q), hits_before);
    assert_eq!(hits_before.len(), 11 * 6);
    for (id, b) in ids {
        assert_eq!(tree.fat_aabb(id), Ok(b.expanded(margin())));
    }
    // Moves after a rebuild keep working.
    let mut rng = Rng::new(9);
    for k in 0..200u32 {
        let d = rng.vec(-2, 2);
        let b = Aabb::from_center_half_extents(d, Vec3::splat(Scalar::ONE));
        let _ = tree.move_proxy(LeafId::from_raw(k * 2 % 1600), b, d);
    }
    assert_eq!(tree.validate(), Ok(()));
}

#[test]
fn heights_stay_logarithmic_for_10000_random_inserts() {
    let mut rng = Rng::new(77);
    let mut tree = DynamicTree::new(margin());
    for i in 0..10_000 {
        tree.create_proxy(rng.aabb(100, 2), i);
    }
    let h_incremental = tree.height();
    tree.rebuild();
    let h_rebuilt = tree.height();
    println!("10000 random boxes: height {h_incremental} incremental, {h_rebuilt} rebuilt");
    // log2(10000) = 13.3; a balanced-enough SAH tree stays within ~3x.
    assert!(h_incremental <= 40, "height {h_incremental}");
    assert!(h_rebuilt <= 40, "height {h_rebuilt}");
    assert_eq!(tree.validate(), Ok(()));
}

fn scripted_tree(seed: u64) -> DynamicTree {
    let mut rng = Rng::new(seed);
    let mut tree = DynamicTree::new(margin());
    let mut live = Vec::new();
    for op in 0..3000 {
        match rng.below(4) {
            0 | 1 => live.push(tree.create_proxy(rng.aabb(20, 2), op)),
            2 if !live.is_empty() => {
                let k = rng.below(live.len() as u64) as usize;
                tree.destroy_proxy(live.swap_remove(k)).unwrap();
            }
            _ if !live.is_empty() => {
                let k = rng.below(live.len() as u64) as usize;
                let d = rng.vec(-1, 1);
                tree.move_proxy(live[k], rng.aabb(20, 2), d).unwrap();
            }
            _ => {}
        }
        if op == 1500 {
            tree.rebuild();
        }
    }
    tree
}

#[test]
fn same_operations_give_bit_identical_trees() {
    let cfg = bincode::config::standard();
    let a = bincode::serde::encode_to_vec(scripted_tree(5), cfg).unwrap();
    let b = bincode::serde::encode_to_vec(scripted_tree(5), cfg).unwrap();
    let c = bincode::serde::encode_to_vec(scripted_tree(6), cfg).unwrap();
    assert_eq!(a, b);
    assert_ne!(a, c);
    let (back, _): (DynamicTree, usize) = bincode::serde::decode_from_slice(&a, cfg).unwrap();
    assert_eq!(back.validate(), Ok(()));
    assert_eq!(back.internal_area(), scripted_tree(5).internal_area());
}

/// The f64 slab test (the parameter interval of the segment `o + t·d`
/// inside `[lo, hi]`), for cross-checking the exact one away from ties.
fn slab_f64(o: [f64; 3], d: [f64; 3], lo: [f64; 3], hi: [f64; 3]) -> Option<(f64, f64)> {
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for k in 0..3 {
        if d[k] == 0.0 {
            if o[k] < lo[k] || o[k] > hi[k] {
                return None;
            }
            continue;
        }
        let (a, b) = ((lo[k] - o[k]) / d[k], (hi[k] - o[k]) / d[k]);
        t0 = t0.max(a.min(b));
        t1 = t1.min(a.max(b));
    }
    (t0 <= t1).then_some((t0, t1))
}

#[test]
fn tree_ray_traversal_visits_exactly_the_boxes_the_segment_touches() {
    let mut st = Rng::new(17);
    let mut tree = DynamicTree::new(s(0.1));
    for i in 0..400u64 {
        let c = [
            st.unit() * 100.0 - 50.0,
            st.unit() * 20.0,
            st.unit() * 100.0 - 50.0,
        ];
        let h = [st.unit() * 3.0, st.unit() * 3.0, st.unit() * 3.0];
        tree.create_proxy(
            Aabb::new(
                v(c[0] - h[0], c[1] - h[1], c[2] - h[2]),
                v(c[0] + h[0], c[1] + h[1], c[2] + h[2]),
            ),
            i,
        );
    }
    let (mut checked, mut visited_total) = (0, 0);
    for _ in 0..300 {
        let mut p = || {
            v(
                st.unit() * 120.0 - 60.0,
                st.unit() * 30.0 - 5.0,
                st.unit() * 120.0 - 60.0,
            )
        };
        let (o, e) = (p(), p());
        let d = e - o;
        let mut visited = Vec::new();
        tree.ray_cast(o, d, Scalar::ONE, |_, data, max| {
            visited.push(data);
            Some(max)
        });
        visited.sort_unstable();
        let mut want = Vec::new();
        tree.for_each_proxy(|_, data, fat| {
            if DynamicTree::segment_touches(o, d, Scalar::ONE, fat) {
                want.push(data);
            }
            // The exact test agrees with f64 wherever f64 is not near a tie.
            let f = |x: Vec3| [x.x.to_f64(), x.y.to_f64(), x.z.to_f64()];
            let r = slab_f64(f(o), f(d), f(fat.min), f(fat.max));
            let margin = r.is_none_or(|(t0, t1)| t1 - t0 > 1e-9);
            if margin {
                checked += 1;
                assert_eq!(
                    r.is_some(),
                    DynamicTree::segment_touches(o, d, Scalar::ONE, fat)
                );
            }
        });
        want.sort_unstable();
        assert_eq!(visited, want);
        visited_total += visited.len();
        // Clipping at the nearest box entry still finds every box entered
        // there and none beyond.
        let entry = |data: u64| {
            let mut t = None;
            tree.for_each_proxy(|_, d2, fat| {
                if d2 == data {
                    let f = |x: Vec3| [x.x.to_f64(), x.y.to_f64(), x.z.to_f64()];
                    t = slab_f64(f(o), f(d), f(fat.min), f(fat.max)).map(|r| r.0);
                }
            });
            t.unwrap_or(2.0)
        };
        let nearest = want.iter().map(|&x| entry(x)).fold(2.0, f64::min);
        let mut clipped = Vec::new();
        tree.ray_cast(o, d, Scalar::ONE, |_, data, max| {
            clipped.push(data);
            Some(max.min(s(entry(data)).max(Scalar::ZERO)))
        });
        if nearest <= 1.0 {
            assert!(clipped.iter().any(|&x| (entry(x) - nearest).abs() < 1e-9));
        }
        assert!(clipped.len() <= want.len());
    }
    assert!(
        visited_total > 300 && checked > 100_000,
        "{visited_total} {checked}"
    );
}
