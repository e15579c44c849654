//! `lockstep view FILE`: a scene, a replay or a desync bundle loaded into
//! the viewer's [`ViewData`] (lockstep-view draws and serves it).
//!
//! The world is stepped exactly as `lockstep sim` or `lockstep replay` step
//! it; only the results are converted for drawing. A bundle adds what the
//! room found: the diverging bodies, their first differing field, and the
//! diverging player's pose of each.

use std::path::Path;

use lockstep_core::World;
use lockstep_core::math::Scalar;
use lockstep_proto::{FieldKind, Replay};
pub use lockstep_view::{
    BodyView, ColliderView, ContactMark, DesyncView, DivergingBody, ExactState, FieldView,
    Geometry, Recorder, SuspectView, ViewData, ViewKind, encode_frames, geometry, http, state_json,
    world_json,
};

use crate::{apply_bundle, check_header, is_bundle, match_world};
use lockstep_client::game::RulesFactory;

/// Why a file could not be viewed.
#[derive(Debug, thiserror::Error)]
pub enum ViewError {
    /// The file could not be read.
    #[error("reading {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The cause.
        source: std::io::Error,
    },
    /// Not a scene (TOML), a replay or a bundle.
    #[error("{0}")]
    Format(String),
    /// The replay's rules, scene or snapshot did not check out.
    #[error("{0}")]
    Replay(String),
    /// The simulation raised a fault.
    #[error("tick {tick}: the simulation reported {faults}")]
    Fault {
        /// The tick.
        tick: u64,
        /// What it reported.
        faults: String,
    },
}

/// Ticks a scene file is stepped by default.
pub const SCENE_TICKS: u64 = 600;
/// Frames a replay or bundle shows by default (a minute at 60 Hz): a long
/// match is viewed a window at a time, since every frame is kept in memory
/// and sent to the browser.
pub const REPLAY_TICKS: u64 = 3600;

/// Which ticks a view shows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Window {
    /// The first tick shown. Default: 0; for a bundle, the last
    /// `ticks` before and including the desync tick.
    pub from: Option<u64>,
    /// How many ticks: a scene is stepped to `from + ticks` (default
    /// [`SCENE_TICKS`]); a replay shows `ticks` from `from` (default
    /// [`REPLAY_TICKS`]). A bundle always ends at its desync tick.
    pub ticks: Option<u64>,
}

/// Builds the view of `path`: a replay or bundle when it parses as one
/// (re-simulated with `game`'s rules), a scene file otherwise (stepped with
/// no inputs), over `window`.
///
/// # Errors
/// [`ViewError`].
pub fn load_view(
    path: &Path,
    game: &dyn RulesFactory,
    window: Window,
) -> Result<ViewData, ViewError> {
    let bytes = std::fs::read(path).map_err(|source| ViewError::Io {
        path: path.display().to_string(),
        source,
    })?;
    let title = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    match Replay::parse(&bytes) {
        Ok(replay) => view_replay(&replay, game, title, window),
        Err(replay_err) => {
            let text = std::str::from_utf8(&bytes).map_err(|_| {
                ViewError::Format(format!(
                    "{}: neither a scene file (not UTF-8 text) nor a replay ({replay_err})",
                    path.display()
                ))
            })?;
            let world = lockstep_core::scene::load_world(text, &path.display().to_string())
                .map_err(|e| ViewError::Format(e.to_string()))?;
            view_scene(world, window, title)
        }
    }
}

/// Steps a scene world with no inputs to the end of `window` and records
/// the ticks in it.
///
/// # Errors
/// [`ViewError::Fault`] if a step reports a fault.
pub fn view_scene(mut world: World, window: Window, title: String) -> Result<ViewData, ViewError> {
    let from = window.from.unwrap_or(0);
    let end = from.saturating_add(window.ticks.unwrap_or(SCENE_TICKS));
    let mut rec = Recorder::new(ViewKind::Scene, title, &world);
    if from == 0 {
        rec.record(&world, 0);
    }
    for _ in 0..end {
        let report = world.step();
        if !report.faults.is_empty() {
            return Err(ViewError::Fault {
                tick: report.tick,
                faults: format!("{:?}", report.faults),
            });
        }
        if report.tick >= from {
            rec.record(&world, report.tick);
        }
    }
    Ok(rec.finish())
}

/// Re-simulates a replay or a bundle with `game`'s rules and records the
/// ticks in `window`.
///
/// # Errors
/// [`ViewError::Replay`] when the rules, the scene or the hash layout do
/// not match.
pub fn view_replay(
    replay: &Replay,
    game: &dyn RulesFactory,
    title: String,
    window: Window,
) -> Result<ViewData, ViewError> {
    check_header(replay, game).map_err(|e| ViewError::Replay(e.to_string()))?;
    let mut world =
        match_world(replay, "recorded scene").map_err(|e| ViewError::Replay(e.to_string()))?;
    let mut rules = game
        .rules_for(&world)
        .map_err(|e| ViewError::Replay(e.to_string()))?;
    let bundle = is_bundle(replay);
    let kind = if bundle {
        ViewKind::Bundle
    } else {
        ViewKind::Replay
    };
    let located = if bundle {
        replay.located.last().cloned()
    } else {
        None
    };
    let end = located.as_ref().map_or(replay.ticks.len(), |d| {
        (d.tick as usize + 1).min(replay.ticks.len())
    });
    let n = window.ticks.unwrap_or(REPLAY_TICKS).max(1);
    let (from, last) = match &located {
        // A bundle ends at its desync tick.
        Some(d) => (
            window
                .from
                .unwrap_or(d.tick.saturating_sub(n - 1))
                .min(d.tick),
            d.tick,
        ),
        None => {
            let from = window.from.unwrap_or(0);
            (from, from.saturating_add(n - 1))
        }
    };
    // One frame per match tick, after its inputs and step: the state whose
    // hash the room compared for that tick, labelled as the room labels it.
    let mut rec = Recorder::new(kind, title, &world);
    for t in &replay.ticks[..end] {
        if t.tick > last {
            break;
        }
        apply_bundle(&mut world, &mut *rules, t).map_err(|e| ViewError::Replay(e.to_string()))?;
        if t.tick >= from {
            rec.record(&world, t.tick);
        }
    }
    if rec.data().ticks.is_empty() {
        // A window past the end, or a match that ended before its first
        // tick: the last state reached.
        let tick = replay.ticks[..end].last().map_or(0, |t| t.tick);
        rec.record(&world, tick);
    }
    let mut data = rec.finish();
    if let Some(report) = located {
        data.desync = Some(desync_view(&data, &world, &report));
    }
    Ok(data)
}

fn desync_view(
    data: &ViewData,
    world: &World,
    report: &lockstep_proto::DesyncReport,
) -> DesyncView {
    let frame = data.ticks.len().saturating_sub(1);
    let slot_of = |h: u32, g: u32| {
        data.bodies
            .iter()
            .position(|b| b.handle == h && b.generation == g)
    };
    let suspects = report
        .suspects
        .iter()
        .map(|s| SuspectView {
            slot: s.slot.0,
            bodies_differing: s.bodies_differing,
            contacts_differ: s.contacts_differ,
            bodies: s
                .bodies
                .iter()
                .filter_map(|b| {
                    let body = slot_of(b.handle, b.generation)?;
                    let state = data.states[frame][body]?;
                    let handle = world
                        .body_handles()
                        .find(|h| h.index() == b.handle && h.generation() == b.generation);
                    let center = handle
                        .and_then(|h| world.body(h).ok())
                        .map(|r| r.center_of_mass());
                    Some(DivergingBody {
                        body,
                        name: b.name.clone(),
                        fields: b
                            .fields
                            .iter()
                            .map(|f| FieldView {
                                name: f.name.clone(),
                                expected: words(f.kind, &f.expected),
                                got: words(f.kind, &f.got),
                            })
                            .collect(),
                        minority_pose: minority_pose(&state, center, &b.fields),
                    })
                })
                .collect(),
        })
        .collect();
    DesyncView {
        tick: report.tick,
        frame,
        reference: report.reference.0,
        majority: report.majority,
        suspects,
    }
}

fn words(kind: FieldKind, w: &[u64]) -> Vec<String> {
    w.iter()
        .map(|&x| match kind {
            FieldKind::Word => x.to_string(),
            FieldKind::Int => (x as i64).to_string(),
            FieldKind::Scalar => Scalar::from_bits(x as i64).to_string(),
        })
        .collect()
}

fn q_rotate(q: [f64; 4], v: [f64; 3]) -> [f64; 3] {
    // v + 2w (u × v) + 2 u × (u × v), u = (x, y, z).
    let (u, w) = ([q[0], q[1], q[2]], q[3]);
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let t = cross(u, v);
    let t2 = cross(u, t);
    [0, 1, 2].map(|k| v[k] + 2.0 * w * t[k] + 2.0 * t2[k])
}

/// The diverging player's pose of a body: its centre of mass and rotation
/// where its fields differ, the majority's otherwise; the origin follows
/// from the centre and the body-frame offset between them. For drawing only.
fn minority_pose(
    state: &ExactState,
    center: Option<lockstep_core::math::Vec3>,
    fields: &[lockstep_proto::FieldDiff],
) -> [f32; 7] {
    let p = state.position.map(|s| s.to_f64());
    let q = state.rotation.map(|s| s.to_f64());
    let c = center.map_or(p, |c| [c.x, c.y, c.z].map(|s| s.to_f64()));
    let scalars = |name: &str, n: usize| {
        fields
            .iter()
            .find(|f| f.name == name && f.got.len() == n)
            .map(|f| {
                f.got
                    .iter()
                    .map(|&w| Scalar::from_bits(w as i64).to_f64())
                    .collect::<Vec<_>>()
            })
    };
    let c_min = scalars("center_of_mass", 3).map_or(c, |v| [v[0], v[1], v[2]]);
    let q_min = scalars("rotation (x, y, z, w)", 4).map_or(q, |v| [v[0], v[1], v[2], v[3]]);
    // Offset from origin to centre in the body frame (rotate by q⁻¹).
    let d = [c[0] - p[0], c[1] - p[1], c[2] - p[2]];
    let local = q_rotate([-q[0], -q[1], -q[2], q[3]], d);
    let off = q_rotate(q_min, local);
    [
        (c_min[0] - off[0]) as f32,
        (c_min[1] - off[1]) as f32,
        (c_min[2] - off[2]) as f32,
        q_min[0] as f32,
        q_min[1] as f32,
        q_min[2] as f32,
        q_min[3] as f32,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shapes() -> ViewData {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/shapes.toml");
        load_view(
            &path,
            &lockstep_client::game::Demo,
            Window {
                from: None,
                ticks: Some(30),
            },
        )
        .unwrap()
    }

    #[test]
    fn a_scene_gives_one_frame_per_tick_with_every_body_and_shape() {
        let v = shapes();
        assert_eq!(v.kind, ViewKind::Scene);
        assert_eq!(v.ticks, (0..=30).collect::<Vec<_>>());
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/shapes.toml");
        let world = crate::load_scene_file(&path).unwrap();
        assert_eq!(v.bodies.len(), world.body_handles().count());
        let mut kinds: Vec<&str> = v
            .bodies
            .iter()
            .flat_map(|b| b.colliders.iter().map(|c| c.shape))
            .collect();
        kinds.sort_unstable();
        kinds.dedup();
        assert_eq!(
            kinds,
            [
                "box",
                "capsule",
                "convex_hull",
                "heightfield",
                "sphere",
                "trimesh"
            ]
        );
        // Every mesh index points at a vertex.
        for c in v.bodies.iter().flat_map(|b| &b.colliders) {
            if let Geometry::Mesh { vertices, indices } = &c.geometry {
                assert!(!indices.is_empty());
                assert!(
                    indices
                        .iter()
                        .flatten()
                        .all(|&i| (i as usize) < vertices.len())
                );
            }
        }
        assert!(
            v.states
                .iter()
                .all(|f| f.len() == v.bodies.len() && f.iter().all(Option::is_some))
        );
        assert!(
            v.contacts.last().is_some_and(|c| !c.is_empty()),
            "things rest on the floor"
        );
    }

    #[test]
    fn a_window_of_a_scene_starts_where_asked() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/shapes.toml");
        let window = Window {
            from: Some(100),
            ticks: Some(20),
        };
        let v = load_view(&path, &lockstep_client::game::Demo, window).unwrap();
        assert_eq!(v.ticks, (100..=120).collect::<Vec<_>>());
        let full = shapes_to(120);
        assert_eq!(v.states[0], full.states[100]);
        assert_eq!(v.states[20], full.states[120]);
    }

    fn shapes_to(ticks: u64) -> ViewData {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/shapes.toml");
        let window = Window {
            from: None,
            ticks: Some(ticks),
        };
        load_view(&path, &lockstep_client::game::Demo, window).unwrap()
    }

    #[test]
    fn the_exact_state_is_the_dump_of_that_tick() {
        let v = shapes();
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/shapes.toml");
        let mut world = crate::load_scene_file(&path).unwrap();
        for _ in 0..30 {
            world.step();
        }
        let dump = crate::dump_state(&world);
        for (i, b) in dump.bodies.iter().enumerate() {
            let s: serde_json::Value =
                serde_json::from_str(&state_json(&v, 30, i).unwrap()).unwrap();
            assert_eq!(s["handle"], b.handle.as_str());
            assert_eq!(s["position"], serde_json::json!(b.position));
            let [w, x, y, z] = b.rotation.clone();
            assert_eq!(s["rotation (x, y, z, w)"], serde_json::json!([x, y, z, w]));
            assert_eq!(s["linear_velocity"], serde_json::json!(b.linear_velocity));
            assert_eq!(s["asleep"], b.asleep);
        }
        assert!(state_json(&v, 31, 0).is_none());
        assert!(state_json(&v, 0, v.bodies.len()).is_none());
    }

    #[test]
    fn the_frame_stream_has_its_documented_layout() {
        let v = shapes();
        let bytes = encode_frames(&v);
        assert_eq!(&bytes[..4], b"LSVF");
        let word = |o: usize| u32::from_le_bytes(bytes[o..o + 4].try_into().unwrap());
        assert_eq!(word(4), 1);
        assert_eq!(word(8) as usize, v.ticks.len());
        assert_eq!(word(12) as usize, v.bodies.len());
        // Walk every frame as the page does.
        let mut o = 16;
        for (i, &tick) in v.ticks.iter().enumerate() {
            assert_eq!(
                u64::from_le_bytes(bytes[o..o + 8].try_into().unwrap()),
                tick
            );
            o += 8;
            for (b, s) in v.states[i].iter().enumerate() {
                let s = s.unwrap();
                assert_eq!(bytes[o] & 1, 1, "present");
                assert_eq!(bytes[o] & 2 != 0, s.asleep);
                let x = f32::from_le_bytes(bytes[o + 1..o + 5].try_into().unwrap());
                assert_eq!(x, s.position[0].to_f64() as f32, "body {b}");
                o += 29;
            }
            let n = word(o) as usize;
            assert_eq!(n, v.contacts[i].len());
            o += 4 + n * 24;
        }
        assert_eq!(o, bytes.len());
    }

    #[test]
    fn a_file_that_is_neither_is_a_clear_error() {
        let dir = std::env::temp_dir().join(format!("lockstep-view-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let bad = dir.join("bad.toml");
        std::fs::write(&bad, "[[body]]\nshape = 3\n").unwrap();
        let e = load_view(&bad, &lockstep_client::game::Demo, Window::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("bad.toml"), "{e}");
        let bin = dir.join("junk.replay");
        std::fs::write(&bin, [0xff, 0xfe, 0x00, 0x01]).unwrap();
        let e = load_view(&bin, &lockstep_client::game::Demo, Window::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("neither a scene file"), "{e}");
        let e = load_view(
            &dir.join("missing"),
            &lockstep_client::game::Demo,
            Window::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.starts_with("reading "), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn the_minority_pose_follows_its_centre_and_rotation() {
        let s = Scalar::from_f64_lossy;
        let state = ExactState {
            position: [s(1.0), s(2.0), s(3.0)],
            rotation: [s(0.0), s(0.0), s(0.0), s(1.0)],
            linear_velocity: [Scalar::ZERO; 3],
            angular_velocity: [Scalar::ZERO; 3],
            asleep: false,
        };
        // Centre 0.5 m along x from the origin; the diverging player has the
        // centre 1 m higher and the body turned 180° about y.
        let centre = lockstep_core::math::Vec3::new(s(1.5), s(2.0), s(3.0));
        let bits = |v: f64| s(v).to_bits() as u64;
        let fields = vec![
            lockstep_proto::FieldDiff {
                name: "center_of_mass".into(),
                kind: FieldKind::Scalar,
                expected: vec![bits(1.5), bits(2.0), bits(3.0)],
                got: vec![bits(1.5), bits(3.0), bits(3.0)],
            },
            lockstep_proto::FieldDiff {
                name: "rotation (x, y, z, w)".into(),
                kind: FieldKind::Scalar,
                expected: vec![0, 0, 0, bits(1.0)],
                got: vec![0, bits(1.0), 0, 0],
            },
        ];
        let p = minority_pose(&state, Some(centre), &fields);
        assert_eq!(p, [2.0, 3.0, 3.0, 0.0, 1.0, 0.0, 0.0]);
        assert_eq!(
            minority_pose(&state, Some(centre), &[]),
            [1.0, 2.0, 3.0, 0.0, 0.0, 0.0, 1.0]
        );
    }
}
