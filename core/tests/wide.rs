//! The solver's exact wide lanes never change a bit: worlds in colour order
//! step to the same state hash, step report (but for the lane counts) and
//! contact events every tick with the lanes off (the default) and turned
//! on, on one worker and on three, on a random pile, on the repository's scene files and on a
//! stack whose masses send batches past the lanes' range guard. On a CPU
//! with the lanes (AVX-512 IFMA), the tests also check that the lanes ran,
//! and that the guard refused the batches it must; elsewhere both runs are
//! the scalar rows and the comparison is trivially equal.
//!
//! The switch is behind lockstep-core's `wide` feature; lockstep-testsupport
//! (a dev-dependency) turns it on, so these tests run in `cargo test`.

#![cfg(feature = "wide")]

use lockstep_core::ContactEvent;
use lockstep_core::scene::{build_world_with_config, parse_scene};
use lockstep_core::{BodyDesc, ColliderDesc, ContactOrder, StepReport, World, WorldConfig};
use lockstep_testsupport::{s, v};

/// What a run left after each tick: the state hash, the step's report (lane
/// counts zeroed) and its contact events.
type Trace = Vec<(u64, StepReport, Vec<ContactEvent>)>;

/// The lane counts a run summed over its ticks: batches on the lanes, and
/// batches the guard refused.
type Lanes = (u64, u64);

fn trace(mut w: World, ticks: u64) -> (Trace, Lanes) {
    let mut lanes = (0, 0);
    let trace = (0..ticks)
        .map(|t| {
            let mut r = w.step();
            assert!(r.faults.is_empty(), "tick {t}: {}", r.faults);
            lanes.0 += u64::from(r.wide_batches);
            lanes.1 += u64::from(r.wide_batches_guarded);
            r.wide_batches = 0;
            r.wide_batches_guarded = 0;
            (w.state_hash(), r, w.contact_events().to_vec())
        })
        .collect();
    (trace, lanes)
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

/// Runs `build()` as it is, with the lanes off (the default: the
/// reference), then with them turned on, on 1 and on 3 workers; every run
/// must match the reference. Returns the lane counts of the runs with the
/// lanes on (the same for both worker counts).
fn compare(build: &dyn Fn() -> World, ticks: u64, what: &str) -> Lanes {
    let off = build();
    assert!(!off.wide(), "off by default");
    let (reference, none) = trace(off, ticks);
    assert_eq!(none, (0, 0), "{what}: no batch with the lanes off");
    let mut counted = None;
    for workers in [1, 3] {
        let mut w = build();
        w.set_workers(workers);
        w.set_wide(true);
        let has = w.wide();
        let (got, lanes) = trace(w, ticks);
        same_trace(
            &reference,
            &got,
            &format!("{what}, lanes on, {workers} workers"),
        );
        if !has {
            assert_eq!(lanes, (0, 0), "{what}: no lanes on this CPU");
        }
        // The batches are cut from each colour's start, whatever the
        // worker count: the same counts.
        assert_eq!(
            *counted.get_or_insert(lanes),
            lanes,
            "{what}: {workers} workers"
        );
    }
    counted.unwrap()
}

fn lanes_on_this_cpu() -> bool {
    let mut w = World::new(WorldConfig::default()).unwrap();
    w.set_wide(true);
    w.wide()
}

/// The shared pit (lockstep_testsupport::pile) in colour order.
fn pile(n: usize, seed: u64) -> World {
    lockstep_testsupport::pile(ContactOrder::Colors, n, seed)
}

#[test]
fn a_random_pile_steps_to_the_same_bits_with_the_lanes_on_and_off() {
    let lanes = compare(&|| pile(180, 7), 150, "random pile");
    if lanes_on_this_cpu() {
        assert!(lanes.0 > 1000, "{lanes:?}: the lanes ran");
    }
}

#[test]
fn the_scene_files_step_to_the_same_bits_with_the_lanes_on_and_off() {
    for name in ["pyramid.toml", "ragdolls.toml", "shapes.toml", "demo.toml"] {
        let path = format!("{}/../scenes/{name}", env!("CARGO_MANIFEST_DIR"));
        let text = std::fs::read_to_string(&path).unwrap();
        let desc = parse_scene(&text, name).unwrap();
        let config = WorldConfig {
            contact_order: ContactOrder::Colors,
            ..desc.world
        };
        let build = || build_world_with_config(&desc, config, name).unwrap();
        compare(&build, 120, name);
    }
}

/// Boxes of 4,000 t on the ground, light ones on them and heavy ones on
/// those: the effective masses of the heavy boxes' rows on the ground are
/// past what the lanes multiply exactly, so the guard sends those batches
/// to the scalar rows, and the results are still the same.
#[test]
fn batches_past_the_range_guard_go_to_the_scalar_rows_to_the_same_bits() {
    let build = || {
        let mut w = World::new(WorldConfig {
            contact_order: ContactOrder::Colors,
            ..WorldConfig::default()
        })
        .unwrap();
        let ground = w
            .create_body(&BodyDesc::fixed().position(v(0.0, -0.5, 0.0)))
            .unwrap();
        w.add_collider(ground, ColliderDesc::cuboid(s(40.0), s(0.5), s(40.0)))
            .unwrap();
        for i in 0..24 {
            let x = -12.0 + i as f64;
            for (layer, mass) in [(0, 4.0e6), (1, 1.0), (2, 4.0e6)] {
                let b = w
                    .create_body(&BodyDesc::dynamic().position(v(
                        x,
                        0.25 + 0.5 * layer as f64,
                        0.0,
                    )))
                    .unwrap();
                w.add_collider(
                    b,
                    ColliderDesc::cuboid(s(0.25), s(0.25), s(0.25)).mass(s(mass)),
                )
                .unwrap();
            }
        }
        w
    };
    let lanes = compare(&build, 60, "heavy rows");
    if lanes_on_this_cpu() {
        assert!(lanes.1 > 0, "{lanes:?}: the guard refused batches");
    }
}

/// The setting is not simulation state: a world with the lanes on hashes
/// as one with them off, its snapshot does not carry the setting, and a
/// restored world (lanes off) goes on to the same hashes.
#[test]
fn the_setting_is_in_neither_the_hash_nor_snapshots() {
    let mut on = pile(72, 3);
    on.set_wide(true);
    let mut off = pile(72, 3);
    assert_eq!(on.state_hash(), off.state_hash());
    for _ in 0..30 {
        on.step();
        off.step();
    }
    assert_eq!(on.snapshot(), off.snapshot());
    let mut restored = World::restore(&on.snapshot()).unwrap();
    assert!(!restored.wide(), "a restored world has the lanes off");
    for t in 0..40 {
        on.step();
        restored.step();
        assert_eq!(on.state_hash(), restored.state_hash(), "tick {t}");
    }
}
