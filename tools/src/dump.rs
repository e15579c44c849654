//! The `--dump-state` JSON: every body's state as exact decimal strings.

use lockstep_core::{World, math::Scalar};
use serde::Serialize;

/// One body in a state dump. Numbers are decimal strings exact to the last
/// bit of the Q32.32 value (parsing them back gives the same bits), so two
/// dumps can be diffed with any text tool and a one-ulp divergence shows.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct BodyDump {
    /// Handle as `index:generation`.
    pub handle: String,
    /// The body's name from the scene.
    pub name: String,
    /// "static", "dynamic" or "kinematic".
    pub kind: String,
    /// Position of the body origin, [x, y, z].
    pub position: [String; 3],
    /// Orientation quaternion, [w, x, y, z].
    pub rotation: [String; 4],
    /// Linear velocity of the centre of mass, [x, y, z].
    pub linear_velocity: [String; 3],
    /// Angular velocity in world axes, [x, y, z].
    pub angular_velocity: [String; 3],
    /// Whether the body sleeps.
    pub asleep: bool,
    /// The body's own hash, 16 hex digits.
    pub hash: String,
}

/// A whole-world dump.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct StateDump {
    /// The world's tick.
    pub tick: u64,
    /// The world's state hash, 16 hex digits.
    pub state_hash: String,
    /// Every body in handle order.
    pub bodies: Vec<BodyDump>,
}

fn d(v: Scalar) -> String {
    v.to_string()
}

/// Dumps every body of `world`, in handle order.
pub fn dump_state(world: &World) -> StateDump {
    let hashes = world.body_hashes();
    let bodies = hashes
        .iter()
        .filter_map(|&(h, hash)| {
            let b = world.body(h).ok()?;
            let p = b.position();
            let q = b.rotation();
            let v = b.linear_velocity();
            let w = b.angular_velocity();
            Some(BodyDump {
                handle: format!("{}:{}", h.index(), h.generation()),
                name: b.name().to_string(),
                kind: b.kind().name().to_string(),
                position: [d(p.x), d(p.y), d(p.z)],
                rotation: [d(q.w), d(q.x), d(q.y), d(q.z)],
                linear_velocity: [d(v.x), d(v.y), d(v.z)],
                angular_velocity: [d(w.x), d(w.y), d(w.z)],
                asleep: b.is_sleeping(),
                hash: format!("{hash:016x}"),
            })
        })
        .collect();
    StateDump {
        tick: world.tick(),
        state_hash: format!("{:016x}", world.state_hash()),
        bodies,
    }
}
