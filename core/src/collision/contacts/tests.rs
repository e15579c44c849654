//! Unit tests of the persistent contact set (impulse carry-over, events,
//! the active-pair list).

use super::*;
use crate::arena::RawHandle;
use crate::collision::manifold::FeatureId;
use crate::math::Vec3;
use crate::workers::Workers;

fn point(at: Vec3, depth: Scalar, id: u32) -> ContactPoint {
    ContactPoint {
        point: at,
        depth,
        id: FeatureId(id),
    }
}

fn ch(i: u32) -> ColliderHandle {
    ColliderHandle(RawHandle {
        index: i,
        generation: 1,
    })
}

fn manifold(points: &[(u32, i32)]) -> Manifold {
    let mut m = Manifold::EMPTY;
    m.normal = Vec3::Y;
    for &(id, depth) in points {
        // Each feature at its own place, a metre apart.
        let at = Vec3::new(Scalar::from_int(id as i32), Scalar::ZERO, Scalar::ZERO);
        m.push(point(at, Scalar::from_ratio(depth as i64, 100), id));
    }
    m
}

#[test]
fn a_point_with_new_features_inherits_the_nearest_old_impulse() {
    let mut p = ContactPair::new(ch(0), ch(1), PairKind::Solid);
    p.update_manifold(&manifold(&[(10, 1), (11, 1)]));
    p.impulses[0].normal = Scalar::from_int(5);
    p.impulses[1].normal = Scalar::from_int(6);
    // Feature 11 renamed 40 but 1 mm from where 11 was; feature 41 is
    // far from everything.
    let mut m = manifold(&[(10, 1)]);
    let near = Vec3::new(Scalar::from_ratio(11_001, 1000), Scalar::ZERO, Scalar::ZERO);
    m.push(point(near, Scalar::ZERO, 40));
    m.push(point(Vec3::from_ints(30, 0, 0), Scalar::ZERO, 41));
    p.update_manifold(&m);
    assert_eq!(p.impulses[0].normal, Scalar::from_int(5));
    assert_eq!(p.impulses[1].normal, Scalar::from_int(6));
    assert_eq!(p.impulses[2], PointImpulse::default());
}

#[test]
fn impulses_follow_points_with_the_same_feature_id() {
    let mut p = ContactPair::new(ch(0), ch(1), PairKind::Solid);
    p.update_manifold(&manifold(&[(10, 1), (11, 1), (12, 1)]));
    p.impulses[0].normal = Scalar::from_int(5);
    p.impulses[1].normal = Scalar::from_int(6);
    p.impulses[2].normal = Scalar::from_int(7);
    let friction = PatchFriction {
        tangent: [Scalar::from_int(8), Scalar::from_int(9)],
        twist: Scalar::from_int(10),
    };
    p.friction = friction;
    // Point 11 disappears, 13 is new, 12 and 10 swap places.
    p.update_manifold(&manifold(&[(12, 2), (13, 1), (10, 2)]));
    assert_eq!(p.impulses[0].normal, Scalar::from_int(7));
    assert_eq!(p.impulses[1], PointImpulse::default());
    assert_eq!(p.impulses[2].normal, Scalar::from_int(5));
    assert_eq!(p.friction, friction, "the patch keeps its friction");
    assert!(p.touching);
    p.update_manifold(&manifold(&[(12, -1)]));
    assert!(!p.touching, "speculative points are not touching");
    assert_eq!(p.friction, friction, "a speculative point keeps it too");
    p.update_manifold(&Manifold::EMPTY);
    assert_eq!(
        p.friction,
        PatchFriction::default(),
        "an empty one drops it"
    );
}

#[test]
fn begin_and_end_events_follow_touching_in_pair_order() {
    let mut set = ContactSet::default();
    let depth = |pairs: &[(u32, u32, i32)]| pairs.to_vec();
    let step = |set: &mut ContactSet, pairs: Vec<(u32, u32, i32)>| {
        let cands: Vec<Candidate> = pairs
            .iter()
            .map(|&(a, b, _)| Candidate {
                a: ch(a),
                b: ch(b),
                kind: if a == 7 {
                    PairKind::Trigger
                } else {
                    PairKind::Solid
                },
            })
            .collect();
        set.update(
            cands.into_iter(),
            |a, b, _, m| {
                let d = pairs
                    .iter()
                    .find(|p| p.0 == a.index() && p.1 == b.index())
                    .unwrap()
                    .2;
                *m = manifold(&[(1, d)]);
                false
            },
            |_| false,
            &Workers::default(),
        );
        set.events()
            .iter()
            .map(|e| (e.kind, e.a.index(), e.b.index()))
            .collect::<Vec<_>>()
    };
    use ContactEventKind::*;
    assert_eq!(
        step(&mut set, depth(&[(0, 1, 1), (0, 2, -1), (7, 9, 3)])),
        vec![(BeginTouch, 0, 1), (TriggerEnter, 7, 9)]
    );
    assert!(
        set.pairs()[2].manifold.is_empty(),
        "triggers keep no points"
    );
    assert_eq!(
        step(&mut set, depth(&[(0, 1, 1), (0, 2, 2)])),
        vec![(BeginTouch, 0, 2), (TriggerExit, 7, 9)]
    );
    assert_eq!(
        step(&mut set, depth(&[(0, 2, -3)])),
        vec![(EndTouch, 0, 1), (EndTouch, 0, 2)]
    );
    assert_eq!(set.pairs().len(), 1);
}

#[test]
fn sleeping_pairs_are_kept_without_events() {
    let mut set = ContactSet::default();
    set.update(
        [Candidate {
            a: ch(3),
            b: ch(4),
            kind: PairKind::Solid,
        }]
        .into_iter(),
        |_, _, _, m| {
            *m = manifold(&[(1, 1)]);
            false
        },
        |_| false,
        &Workers::default(),
    );
    assert_eq!(set.events().len(), 1);
    set.update(
        std::iter::empty(),
        |_, _, _, _| false,
        |_| true,
        &Workers::default(),
    );
    assert!(set.events().is_empty());
    assert_eq!(set.pairs().len(), 1);
    assert!(set.pairs()[0].touching);
}

/// Rounds of random candidate sets (pairs appearing, leaving, kept asleep,
/// triggers, touching and not) give the same pairs, events and counters
/// whether the narrow phase runs on one worker or is split over three.
#[test]
fn updates_are_the_same_on_any_worker_count() {
    // A keyed draw: the first number of the test generator seeded by `x`.
    fn mix(x: u64) -> u64 {
        crate::testing::Rng::new(x).next_u64()
    }
    let run = |workers: &Workers| {
        let mut set = ContactSet::default();
        let mut log = Vec::new();
        for round in 0..40u64 {
            // Pairs among 30 colliders; collider 7 is a trigger. Every
            // third round a new set, with the active list invalidated (as a
            // body waking does) and pairs that left kept asleep or not; in
            // between, the active path, with pairs leaving and coming back
            // (a pair kept asleep is never a candidate before the next
            // invalidation, as in a world).
            let fresh = round % 3 == 0;
            let mut cands = Vec::new();
            for a in 0..30u32 {
                for b in a + 1..30 {
                    let pair = u64::from(a * 31 + b);
                    let listed = mix(round / 3 * 1000 + pair).is_multiple_of(5);
                    let dropped = !fresh && mix(round * 5000 + pair).is_multiple_of(4);
                    if listed && !dropped {
                        cands.push((a, b));
                    }
                }
            }
            let candidates = cands.iter().map(|&(a, b)| Candidate {
                a: ch(a),
                b: ch(b),
                kind: if a == 7 || b == 7 {
                    PairKind::Trigger
                } else {
                    PairKind::Solid
                },
            });
            let asleep =
                |p: &ContactPair| fresh && mix(round + u64::from(p.a.index())).is_multiple_of(3);
            if fresh {
                set.invalidate_active();
            }
            let stats = set.update(
                candidates,
                |a, b, _, m| {
                    let h = mix(round * 7919 + u64::from(a.index() * 31 + b.index()));
                    let depth = (h % 7) as i32 - 3;
                    *m = manifold(&[(1, depth), (2, depth - 1)]);
                    false
                },
                asleep,
                workers,
            );
            log.push((stats, set.events().to_vec(), set.pairs().to_vec()));
        }
        log
    };
    let one = run(&Workers::new(1));
    let three = run(&Workers::new(3));
    assert!(one.iter().any(|(s, _, _)| s.narrow_tests > 40));
    assert!(
        one.iter()
            .any(|(s, _, _)| s.begin_events > 0 && s.end_events > 0)
    );
    assert!(one.iter().any(|(s, _, _)| s.kept_asleep > 0));
    for (round, (a, b)) in one.iter().zip(&three).enumerate() {
        assert_eq!(a, b, "round {round}");
        // Events in pair order, the retired pairs' among the tested ones'.
        let keys: Vec<_> = a.1.iter().map(|e| (e.a.index(), e.b.index())).collect();
        assert!(
            keys.windows(2).all(|w| w[0] < w[1]),
            "round {round}: {keys:?}"
        );
    }
}
