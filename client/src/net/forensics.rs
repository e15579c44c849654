//! The client's side of locating a desync: a ring of the world's recent
//! states (snapshots, one per applied tick) and the answers to the room's
//! probes, computed from them.
//!
//! Nothing is sent in steady state: the room asks only after a tick's
//! hashes disagree, and the answer comes from the state the client had
//! then, so a fault that happened once (a cosmic-ray bit flip, a nudge by
//! a bug outside the simulation) is still seen as it was.

use std::collections::VecDeque;

use lockstep_core::World;
use lockstep_core::world::FieldKind as CoreKind;
use lockstep_proto::{
    BodyDump, FieldDump, FieldKind, MAX_BODY_HASHES, MAX_DUMP_FIELDS, MAX_FIELD_NAME_BYTES,
    MAX_FIELD_WORDS, MAX_NAME_BYTES, MAX_PROBE_BODIES, MAX_SNAPSHOT_CHUNK_BYTES, Probe,
    ProbeAnswer, ProbeAsk, ProbeReply,
};

/// The last `depth` ticks' states, and the world restored from one of them
/// while a probe reads it: what a client keeps to answer the room's probes
/// after a desync ([`SessionEvent::Probe`](lockstep_proto::SessionEvent)).
/// Record the world after every applied tick; answer each probe with
/// [`History::answer`] and hand the reply to `Session::reply_probe`.
pub struct History {
    depth: usize,
    states: VecDeque<(u64, Vec<u8>)>,
    restored: Option<(u64, World)>,
}

impl History {
    /// Keeps the states of the last `depth` ticks (0: none; every probe is
    /// then answered "unavailable").
    pub fn new(depth: usize) -> Self {
        Self {
            depth,
            states: VecDeque::with_capacity(depth),
            restored: None,
        }
    }

    /// Keeps the state after `tick`.
    pub fn record(&mut self, tick: u64, world: &World) {
        if self.depth == 0 {
            return;
        }
        if self.states.len() == self.depth {
            self.states.pop_front();
        }
        self.states.push_back((tick, world.snapshot()));
    }

    fn snapshot(&self, tick: u64) -> Option<&[u8]> {
        self.states
            .iter()
            .find(|(t, _)| *t == tick)
            .map(|(_, b)| b.as_slice())
    }

    fn world(&mut self, tick: u64) -> Option<&World> {
        if self.restored.as_ref().is_none_or(|(t, _)| *t != tick) {
            let world = World::restore(self.snapshot(tick)?).ok()?;
            self.restored = Some((tick, world));
        }
        self.restored.as_ref().map(|(_, w)| w)
    }

    /// The answer to `probe`, from the recorded state of its tick.
    pub fn answer(&mut self, probe: &Probe) -> ProbeReply {
        let answer = self.try_answer(probe).unwrap_or(ProbeAnswer::Unavailable);
        ProbeReply {
            tick: probe.tick,
            answer,
        }
    }

    fn try_answer(&mut self, probe: &Probe) -> Option<ProbeAnswer> {
        match &probe.ask {
            ProbeAsk::Snapshot { offset } => {
                let bytes = self.snapshot(probe.tick)?;
                let start = (*offset as usize).min(bytes.len());
                let end = (start + MAX_SNAPSHOT_CHUNK_BYTES).min(bytes.len());
                Some(ProbeAnswer::Snapshot {
                    total: u32::try_from(bytes.len()).ok()?,
                    offset: start as u32,
                    bytes: bytes[start..end].to_vec(),
                })
            }
            ProbeAsk::BodyHashes { from } => {
                let world = self.world(probe.tick)?;
                let all = world.body_hashes();
                let start = (*from as usize).min(all.len());
                let end = (start + MAX_BODY_HASHES).min(all.len());
                Some(ProbeAnswer::BodyHashes {
                    total: all.len() as u32,
                    from: start as u32,
                    contacts: world.contacts_hash(),
                    game: world.game_state().hash(),
                    hashes: all[start..end].iter().map(|&(_, h)| h).collect(),
                })
            }
            ProbeAsk::Fields { bodies } => {
                let world = self.world(probe.tick)?;
                let handles = world.body_hashes();
                let mut wanted: Vec<u32> = bodies.clone();
                wanted.sort_unstable();
                wanted.dedup();
                wanted.truncate(MAX_PROBE_BODIES);
                let dumps = wanted
                    .into_iter()
                    .filter_map(|index| {
                        let &(handle, _) = handles.get(index as usize)?;
                        dump(world, index, handle)
                    })
                    .collect();
                Some(ProbeAnswer::Fields {
                    bodies: dumps,
                    game: dump_game(world),
                })
            }
        }
    }
}

fn cut(s: &str, max: usize) -> String {
    let mut end = s.len().min(max);
    while !s.is_char_boundary(end) {
        end -= 1;
    }
    s[..end].to_owned()
}

fn dump(world: &World, index: u32, handle: lockstep_core::BodyHandle) -> Option<BodyDump> {
    let name = world.body(handle).ok()?.name().to_owned();
    let fields = world
        .body_fields(handle)
        .ok()?
        .into_iter()
        .take(MAX_DUMP_FIELDS)
        .map(|f| FieldDump {
            name: cut(&f.name, MAX_FIELD_NAME_BYTES),
            kind: kind(f.kind),
            words: f.words.into_iter().take(MAX_FIELD_WORDS).collect(),
        })
        .collect();
    Some(BodyDump {
        index,
        handle: handle.index(),
        generation: handle.generation(),
        name: cut(&name, MAX_NAME_BYTES),
        fields,
    })
}

/// Every field of the world's game state, as a client dumps them.
pub fn dump_game(world: &World) -> Vec<FieldDump> {
    world
        .game_state()
        .fields()
        .iter()
        .take(MAX_DUMP_FIELDS)
        .map(|f| FieldDump {
            name: cut(f.name(), MAX_FIELD_NAME_BYTES),
            kind: kind(f.kind()),
            words: f.words().iter().take(MAX_FIELD_WORDS).copied().collect(),
        })
        .collect()
}

fn kind(k: CoreKind) -> FieldKind {
    match k {
        CoreKind::Word => FieldKind::Word,
        CoreKind::Int => FieldKind::Int,
        CoreKind::Scalar => FieldKind::Scalar,
    }
}

/// Every hashed field of every body of `world` whose index is in `bodies`,
/// as a client would dump them: for offline checks of a desync bundle.
pub fn dump_bodies(world: &World, bodies: &[u32]) -> Vec<BodyDump> {
    let handles = world.body_hashes();
    bodies
        .iter()
        .filter_map(|&index| {
            let &(handle, _) = handles.get(index as usize)?;
            dump(world, index, handle)
        })
        .collect()
}
