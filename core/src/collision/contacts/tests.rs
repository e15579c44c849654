//! Unit tests of the persistent contact set (impulse carry-over, events,
//! the active-pair list).

use super::*;
use crate::arena::RawHandle;
use crate::collision::manifold::FeatureId;
use crate::math::Vec3;

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
    );
    assert_eq!(set.events().len(), 1);
    set.update(std::iter::empty(), |_, _, _, _| false, |_| true);
    assert!(set.events().is_empty());
    assert_eq!(set.pairs().len(), 1);
    assert!(set.pairs()[0].touching);
}
