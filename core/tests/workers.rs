//! A world's worker threads never change a bit: worlds in either contact
//! order step to the same state hash, step report and contact events every
//! tick with 1, 2, 3, 4 and 8 workers, on the repository's scene files and
//! on a random pile big enough that every colour, the narrow phase's pairs
//! and the integrators' bodies are split over the workers; and the order
//! itself is a world setting (hashed, kept in snapshots).

use lockstep_core::ContactEvent;
use lockstep_core::scene::{build_world_with_config, parse_scene};
use lockstep_core::{ContactOrder, StepReport, World, WorldConfig};
use lockstep_testsupport::{pile, step_pile};

const COUNTS: [usize; 5] = [1, 2, 3, 4, 8];

/// What a run left after each tick: the state hash, the step's report and
/// its contact events.
type Trace = Vec<(u64, StepReport, Vec<ContactEvent>)>;

/// Steps `w` for `ticks` ticks (driving its kinematic "paddle", if it has
/// one) and returns the state hash after each, checking for faults. Also
/// returns the most constraints of any tick, and the most colours.
fn run(w: World, ticks: u64) -> (Vec<u64>, u32, u32) {
    let (trace, most, colors) = trace(w, ticks);
    (trace.into_iter().map(|t| t.0).collect(), most, colors)
}

/// [`run`] with every tick's report and events too.
fn trace(mut w: World, ticks: u64) -> (Trace, u32, u32) {
    let (mut most, mut colors) = (0, 0);
    let trace = (0..ticks)
        .map(|t| {
            let r = step_pile(&mut w, t);
            most = most.max(r.contact_constraints);
            colors = colors.max(r.contact_colors);
            (w.state_hash(), r, w.contact_events().to_vec())
        })
        .collect();
    (trace, most, colors)
}

/// Panics at the first tick where `got` differs from `want`.
fn same_trace(want: &Trace, got: &Trace, what: &str) {
    assert_eq!(want.len(), got.len());
    if let Some(t) = (0..want.len()).find(|&t| want[t] != got[t]) {
        panic!(
            "{what}: tick {t} differs (hash, report, events):\n{:?}\n{:?}",
            want[t], got[t]
        );
    }
}

#[test]
fn a_random_pile_steps_to_the_same_hashes_reports_and_events_with_1_to_8_workers() {
    for order in [ContactOrder::Colors, ContactOrder::Pairs] {
        let (reference, most, colors) = trace(pile(order, 180, 7), 150);
        // Big enough that colours hold many blocks of constraints each, and
        // the narrow phase many blocks of pairs, so every worker count
        // really splits them; with bodies coming to rest and leaving
        // contact on the way (events).
        assert!(most > 300, "{most} constraints");
        if order == ContactOrder::Colors {
            assert!(colors >= 4, "{colors} colours");
        }
        assert!(reference.iter().any(|t| t.1.narrow_tests > 200));
        assert!(reference.iter().any(|t| t.1.end_events > 0));
        for count in COUNTS {
            let mut w = pile(order, 180, 7);
            w.set_workers(count);
            assert_eq!(w.workers(), count);
            let (got, _, _) = trace(w, 150);
            same_trace(&reference, &got, &format!("{order:?}, {count} workers"));
        }
    }
}

#[test]
fn the_scene_files_step_to_the_same_hashes_reports_and_events_with_1_to_8_workers() {
    for name in ["pyramid.toml", "ragdolls.toml", "shapes.toml", "demo.toml"] {
        let path = format!("{}/../scenes/{name}", env!("CARGO_MANIFEST_DIR"));
        let text = std::fs::read_to_string(&path).unwrap();
        let desc = parse_scene(&text, name).unwrap();
        for order in [ContactOrder::Colors, ContactOrder::Pairs] {
            let config = WorldConfig {
                contact_order: order,
                ..desc.world
            };
            let build = || build_world_with_config(&desc, config, name).unwrap();
            let (reference, _, _) = trace(build(), 120);
            for count in COUNTS {
                let mut w = build();
                w.set_workers(count);
                let (got, _, _) = trace(w, 120);
                same_trace(
                    &reference,
                    &got,
                    &format!("{name}, {order:?}, {count} workers"),
                );
            }
        }
    }
}

#[test]
fn pair_order_colours_nothing_and_the_order_is_part_of_the_state() {
    let (_, _, colors) = run(pile(ContactOrder::Pairs, 72, 3), 90);
    assert_eq!(colors, 0, "pair order colours nothing");
    // The two orders are two settings: different hashes from the start
    // (the setting is hashed), and different motion once bodies touch.
    let (mut a, mut b) = (
        pile(ContactOrder::Pairs, 72, 3),
        pile(ContactOrder::Colors, 72, 3),
    );
    assert_ne!(a.state_hash(), b.state_hash(), "the setting is hashed");
    assert_eq!(a.body_hashes(), b.body_hashes(), "the same bodies");
    for _ in 0..90 {
        a.step();
        b.step();
    }
    assert_ne!(
        a.body_hashes(),
        b.body_hashes(),
        "the orders move bodies differently"
    );
}

#[test]
fn a_snapshot_keeps_the_order_and_a_restored_world_takes_any_worker_count() {
    let mut w = pile(ContactOrder::Colors, 72, 11);
    w.set_workers(2);
    for _ in 0..40 {
        w.step();
    }
    let bytes = w.snapshot();
    let mut restored = World::restore(&bytes).unwrap();
    assert_eq!(restored.config().contact_order, ContactOrder::Colors);
    assert_eq!(
        restored.workers(),
        1,
        "the worker count is not in snapshots"
    );
    restored.set_workers(4);
    for t in 0..60 {
        w.step();
        restored.step();
        assert_eq!(
            w.state_hash(),
            restored.state_hash(),
            "tick {t} after restore"
        );
    }
}
