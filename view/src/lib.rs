//! # lockstep-view
//!
//! What the browser viewer shows and how it gets there: a world turned into
//! drawable geometry (each body's shapes once) and frames (every tick's
//! poses and contact points), the frame stream and JSON the page reads, the
//! page itself (a small WebGL2 renderer, embedded in the binary), and a
//! read-only HTTP server for it. `lockstep view FILE` (the client's offline
//! tools) and `lockstep-server --view ADDR` (live rooms) are built on it.
//!
//! Everything here runs after the simulation and only reads the world:
//! positions are converted to `f32` for drawing, and the exact state of a
//! body (the decimal strings of `--dump-state`) is kept and served on
//! request. The formats are documented in docs/viewer.md.

#![warn(missing_docs)]

pub mod http;

use std::collections::BTreeMap;

use lockstep_core::math::{Scalar, Transform};
use lockstep_core::shape::Shape;
use lockstep_core::{BodyHandle, World};
use serde::Serialize;

/// What a view was built from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ViewKind {
    /// A scene file, stepped with no inputs.
    Scene,
    /// A recorded match, re-simulated with its inputs.
    Replay,
    /// A desync bundle: the match up to the desync, and the diverging
    /// player's values at the desync tick.
    Bundle,
    /// A room being played, re-simulated on the server for spectators.
    Live,
}

/// A collider's geometry in its body's frame, for drawing.
#[derive(Clone, Debug, Serialize)]
#[serde(tag = "type", rename_all = "lowercase")]
pub enum Geometry {
    /// A ball.
    Sphere {
        /// Radius.
        radius: f32,
    },
    /// A capsule along local y.
    Capsule {
        /// Half the segment's length.
        half_height: f32,
        /// Radius.
        radius: f32,
    },
    /// A box.
    Box {
        /// Half-extents.
        half_extents: [f32; 3],
    },
    /// Triangles (hulls, meshes and height fields).
    Mesh {
        /// Vertices.
        vertices: Vec<[f32; 3]>,
        /// Counter-clockwise triangles.
        indices: Vec<[u32; 3]>,
    },
}

/// One collider of a body.
#[derive(Clone, Debug, Serialize)]
pub struct ColliderView {
    /// The shape kind's name ("box", "convex_hull", ...).
    pub shape: &'static str,
    /// Whether it is a trigger (drawn translucent).
    pub trigger: bool,
    /// Pose in the body frame: position, then quaternion x, y, z, w.
    pub local: [f32; 7],
    /// The geometry.
    pub geometry: Geometry,
}

/// A body as the page lists it.
#[derive(Clone, Debug, Serialize)]
pub struct BodyView {
    /// Handle index.
    pub handle: u32,
    /// Handle generation.
    pub generation: u32,
    /// The scene's name for it.
    pub name: String,
    /// "static", "dynamic" or "kinematic".
    pub kind: &'static str,
    /// Its colliders.
    pub colliders: Vec<ColliderView>,
}

/// A body's exact state at one tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ExactState {
    /// Body origin.
    pub position: [Scalar; 3],
    /// Rotation x, y, z, w.
    pub rotation: [Scalar; 4],
    /// Linear velocity of the centre of mass.
    pub linear_velocity: [Scalar; 3],
    /// Angular velocity.
    pub angular_velocity: [Scalar; 3],
    /// Whether it sleeps.
    pub asleep: bool,
}

/// A contact point for the overlay: the point and the normal (A to B).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactMark {
    /// World point.
    pub point: [f32; 3],
    /// Unit normal.
    pub normal: [f32; 3],
}

/// One field that differs between the majority and a diverging player.
#[derive(Clone, Debug, Serialize)]
pub struct FieldView {
    /// The engine's name for the field.
    pub name: String,
    /// The majority's value, as exact decimals.
    pub expected: Vec<String>,
    /// The diverging player's value.
    pub got: Vec<String>,
}

/// A body the room found diverging.
#[derive(Clone, Debug, Serialize)]
pub struct DivergingBody {
    /// Its position in [`ViewData::bodies`].
    pub body: usize,
    /// Its name.
    pub name: String,
    /// The differing fields, first first.
    pub fields: Vec<FieldView>,
    /// The diverging player's pose of the body, where its fields say
    /// (position, quaternion x, y, z, w); the majority's otherwise.
    pub minority_pose: [f32; 7],
}

/// A diverging player.
#[derive(Clone, Debug, Serialize)]
pub struct SuspectView {
    /// Its slot.
    pub slot: u8,
    /// How many bodies differ (listed or not).
    pub bodies_differing: u32,
    /// Whether its contact state differs too.
    pub contacts_differ: bool,
    /// The listed bodies.
    pub bodies: Vec<DivergingBody>,
}

/// What a bundle says about its desync.
#[derive(Clone, Debug, Serialize)]
pub struct DesyncView {
    /// The desync tick.
    pub tick: u64,
    /// Its frame.
    pub frame: usize,
    /// The reference slot.
    pub reference: u8,
    /// Whether the reference held the majority hash.
    pub majority: bool,
    /// The diverging players.
    pub suspects: Vec<SuspectView>,
}

/// Everything the viewer serves for one file.
#[derive(Clone, Debug)]
pub struct ViewData {
    /// What it was built from.
    pub kind: ViewKind,
    /// A title (the file name).
    pub title: String,
    /// The scene's tick rate, Hz.
    pub tick_rate: u32,
    /// Every body seen, in the order first seen (handle order per tick).
    pub bodies: Vec<BodyView>,
    /// Tick of each frame: for a scene, the world's tick (as `lockstep sim`
    /// prints it); for a replay, the match tick whose inputs and step made
    /// the frame (as the room and `lockstep replay` name it).
    pub ticks: Vec<u64>,
    /// Per frame, per body: its exact state, or None where absent.
    pub states: Vec<Vec<Option<ExactState>>>,
    /// Per frame: the touching contact points.
    pub contacts: Vec<Vec<ContactMark>>,
    /// For a bundle: the desync.
    pub desync: Option<DesyncView>,
}

fn f(v: Scalar) -> f32 {
    v.to_f64() as f32
}

fn transform7(t: &Transform) -> [f32; 7] {
    let (p, q) = (t.translation, t.rotation);
    [f(p.x), f(p.y), f(p.z), f(q.x), f(q.y), f(q.z), f(q.w)]
}

fn v3(v: lockstep_core::math::Vec3) -> [f32; 3] {
    [f(v.x), f(v.y), f(v.z)]
}

/// A shape's geometry for drawing: spheres, capsules and boxes by their
/// dimensions, the rest as triangles (hull faces fanned, height field
/// cells split as the engine splits them).
pub fn geometry(shape: &Shape) -> Geometry {
    match shape {
        Shape::Sphere(s) => Geometry::Sphere {
            radius: f(s.radius),
        },
        Shape::Capsule(c) => Geometry::Capsule {
            half_height: f(c.half_height),
            radius: f(c.radius),
        },
        Shape::Cuboid(b) => Geometry::Box {
            half_extents: v3(b.half_extents),
        },
        Shape::ConvexHull(h) => {
            let mut indices = Vec::new();
            for face in 0..h.faces().len() {
                let vs = h.face_vertices(face);
                for k in 1..vs.len().saturating_sub(1) {
                    indices.push([vs[0], vs[k], vs[k + 1]]);
                }
            }
            Geometry::Mesh {
                vertices: h.vertices().iter().map(|&v| v3(v)).collect(),
                indices,
            }
        }
        Shape::TriMesh(m) => Geometry::Mesh {
            vertices: m.vertices().iter().map(|&v| v3(v)).collect(),
            indices: m.indices().to_vec(),
        },
        Shape::HeightField(h) => {
            let (rows, cols) = (h.rows(), h.cols());
            let mut vertices = Vec::with_capacity(rows as usize * cols as usize);
            for r in 0..rows {
                for c in 0..cols {
                    vertices.push(h.vertex(r, c).map_or([0.0; 3], v3));
                }
            }
            // The cells' split as `HeightField::cell_triangles` documents it.
            let at = |r: u32, c: u32| r * cols + c;
            let mut indices = Vec::new();
            for r in 0..rows.saturating_sub(1) {
                for c in 0..cols.saturating_sub(1) {
                    let (a, b, cc, d) = (at(r, c), at(r, c + 1), at(r + 1, c), at(r + 1, c + 1));
                    indices.push([a, d, b]);
                    indices.push([a, cc, d]);
                }
            }
            Geometry::Mesh { vertices, indices }
        }
    }
}

/// Builds a [`ViewData`] one frame at a time from a world.
pub struct Recorder {
    data: ViewData,
    slots: BTreeMap<(u32, u32), usize>,
}

impl Recorder {
    /// Starts a view of `world`'s kind of data (no frames yet).
    pub fn new(kind: ViewKind, title: String, world: &World) -> Recorder {
        Recorder {
            data: ViewData {
                kind,
                title,
                tick_rate: world.config().tick_rate,
                bodies: Vec::new(),
                ticks: Vec::new(),
                states: Vec::new(),
                contacts: Vec::new(),
                desync: None,
            },
            slots: BTreeMap::new(),
        }
    }

    fn slot(&mut self, world: &World, h: BodyHandle) -> Option<usize> {
        let key = (h.index(), h.generation());
        if let Some(&s) = self.slots.get(&key) {
            return Some(s);
        }
        let b = world.body(h).ok()?;
        let colliders = b
            .colliders()
            .iter()
            .filter_map(|&c| world.collider(c).ok())
            .map(|c| ColliderView {
                shape: c.shape.kind().name(),
                trigger: c.is_trigger,
                local: transform7(&c.local_pose),
                geometry: geometry(&c.shape),
            })
            .collect();
        self.data.bodies.push(BodyView {
            handle: h.index(),
            generation: h.generation(),
            name: b.name().to_owned(),
            kind: b.kind().name(),
            colliders,
        });
        let s = self.data.bodies.len() - 1;
        self.slots.insert(key, s);
        Some(s)
    }

    /// Adds a frame: every body's state and the touching contacts, labelled
    /// `tick`. A body seen for the first time is added to the body list.
    pub fn record(&mut self, world: &World, tick: u64) {
        let handles: Vec<BodyHandle> = world.body_handles().collect();
        let mut frame = vec![None; self.data.bodies.len()];
        for h in handles {
            let Some(s) = self.slot(world, h) else {
                continue;
            };
            if frame.len() <= s {
                frame.resize(s + 1, None);
            }
            let Ok(b) = world.body(h) else { continue };
            let (p, q, v, w) = (
                b.position(),
                b.rotation(),
                b.linear_velocity(),
                b.angular_velocity(),
            );
            frame[s] = Some(ExactState {
                position: [p.x, p.y, p.z],
                rotation: [q.x, q.y, q.z, q.w],
                linear_velocity: [v.x, v.y, v.z],
                angular_velocity: [w.x, w.y, w.z],
                asleep: b.is_sleeping(),
            });
        }
        let contacts = world
            .contact_pairs()
            .iter()
            .filter(|p| p.touching)
            .flat_map(|p| {
                let n = v3(p.manifold.normal);
                p.manifold.points().iter().map(move |c| ContactMark {
                    point: v3(c.point),
                    normal: n,
                })
            })
            .collect();
        self.data.ticks.push(tick);
        self.data.states.push(frame);
        self.data.contacts.push(contacts);
    }

    /// The frames so far (frames recorded before a body was first seen are
    /// shorter than the body list; [`finish`](Self::finish) pads them).
    pub fn data(&self) -> &ViewData {
        &self.data
    }

    /// Adds `world`'s bodies to the body list without a frame (so that a
    /// viewer has their geometry before the first frame).
    pub fn add_bodies(&mut self, world: &World) {
        let handles: Vec<BodyHandle> = world.body_handles().collect();
        for h in handles {
            self.slot(world, h);
        }
    }

    /// Drops the oldest frames beyond the newest `max`.
    pub fn keep_last(&mut self, max: usize) {
        let excess = self.data.ticks.len().saturating_sub(max);
        if excess > 0 {
            self.data.ticks.drain(..excess);
            self.data.states.drain(..excess);
            self.data.contacts.drain(..excess);
        }
    }

    /// The frames so far (every frame padded to the full body list).
    pub fn finish(mut self) -> ViewData {
        let n = self.data.bodies.len();
        for f in &mut self.data.states {
            f.resize(n, None);
        }
        self.data
    }
}

/// The `/frames` body: every frame's poses and contacts, little-endian
/// (docs/viewer.md): "LSVF", version 1, frame count, body count (u32
/// each); per frame the tick (u64), per body a flags byte (1 present, 2
/// asleep) and position and quaternion x, y, z, w (7 × f32), then the
/// contact count (u32) and per contact point and normal (6 × f32).
pub fn encode_frames(data: &ViewData) -> Vec<u8> {
    encode_frames_from(data, 0)
}

/// The frame stream of the frames from index `first` on (none past the
/// end): what a live viewer polls for.
pub fn encode_frames_from(data: &ViewData, first: usize) -> Vec<u8> {
    let nb = data.bodies.len();
    let first = first.min(data.ticks.len());
    let count = data.ticks.len() - first;
    let mut out = Vec::with_capacity(16 + count * (8 + nb * 29 + 4));
    out.extend_from_slice(b"LSVF");
    out.extend_from_slice(&1u32.to_le_bytes());
    out.extend_from_slice(&(count as u32).to_le_bytes());
    out.extend_from_slice(&(nb as u32).to_le_bytes());
    for (i, &tick) in data.ticks.iter().enumerate().skip(first) {
        out.extend_from_slice(&tick.to_le_bytes());
        for b in 0..nb {
            // A frame recorded before a body existed is shorter: absent.
            let s = data.states[i].get(b).copied().flatten();
            let (flags, vals) = match s {
                Some(s) => (
                    1u8 | if s.asleep { 2 } else { 0 },
                    [
                        f(s.position[0]),
                        f(s.position[1]),
                        f(s.position[2]),
                        f(s.rotation[0]),
                        f(s.rotation[1]),
                        f(s.rotation[2]),
                        f(s.rotation[3]),
                    ],
                ),
                None => (0, [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]),
            };
            out.push(flags);
            for v in vals {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
        out.extend_from_slice(&(data.contacts[i].len() as u32).to_le_bytes());
        for c in &data.contacts[i] {
            for v in c.point.iter().chain(&c.normal) {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
    }
    out
}

/// The `/world` JSON: kind, title, tick rate, frame count, bodies with
/// their geometry, and the desync of a bundle.
pub fn world_json(data: &ViewData) -> String {
    #[derive(Serialize)]
    struct World<'a> {
        kind: ViewKind,
        title: &'a str,
        tick_rate: u32,
        frames: usize,
        first_tick: u64,
        bodies: &'a [BodyView],
        desync: &'a Option<DesyncView>,
    }
    serde_json::to_string(&World {
        kind: data.kind,
        title: &data.title,
        tick_rate: data.tick_rate,
        frames: data.ticks.len(),
        first_tick: data.ticks.first().copied().unwrap_or(0),
        bodies: &data.bodies,
        desync: &data.desync,
    })
    .unwrap_or_else(|_| "{}".into())
}

/// The `/state` JSON: a body's exact state at a frame, as the decimal
/// strings of `--dump-state`, or None for a frame or body out of range.
pub fn state_json(data: &ViewData, frame: usize, body: usize) -> Option<String> {
    let s = (*data.states.get(frame)?.get(body)?)?;
    let b = data.bodies.get(body)?;
    let d = |v: &[Scalar]| v.iter().map(|x| x.to_string()).collect::<Vec<_>>();
    let v = serde_json::json!({
        "frame": frame,
        "tick": data.ticks[frame],
        "handle": format!("{}:{}", b.handle, b.generation),
        "name": b.name,
        "kind": b.kind,
        "position": d(&s.position),
        "rotation (x, y, z, w)": d(&s.rotation),
        "linear_velocity": d(&s.linear_velocity),
        "angular_velocity": d(&s.angular_velocity),
        "asleep": s.asleep,
    });
    Some(v.to_string())
}
