//! Live rooms in the browser viewer (`--view ADDR`).
//!
//! **Fed by a server-side re-simulation.** While `--view` is on, each room
//! keeps the bundles it closed (the same inputs every player got, a few
//! hundred bytes a tick). Nothing is simulated or encoded until someone
//! asks: the first request for a room builds a re-simulation from the
//! room's scene with the game's rules (the same plugin `--verify` uses),
//! and each request then applies the bundles closed since the last one
//! (and drops them: the re-simulation holds their result), on the viewer's
//! HTTP thread, never on the room's. So a match nobody watches
//! pays only for keeping its inputs, and the viewer's work never delays a
//! tick. Spectators only read: the viewer answers GET alone, has no route
//! that reaches a room, and holds no seat.
//!
//! Routes (docs/viewer.md): `/world` lists the rooms; `/world?room=R`,
//! `/frames?room=R&after=T` (the frames after tick T, waiting up to a
//! second for one) and `/state?room=R&tick=T&body=B`.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use lockstep_proto::TickBundle;
use lockstep_proto::verify::{TickVerifier, VerifierFactory};
use lockstep_view::http::{Query, Response, Routes};
use lockstep_view::{Recorder, ViewKind, encode_frames_from, state_json, world_json};

/// Frames a room's re-simulation keeps for viewers (10 s at 60 Hz).
pub const LIVE_FRAMES: usize = 600;

/// How long a request for new frames waits for one.
const POLL_WAIT: Duration = Duration::from_secs(1);

/// The rooms a viewer can watch.
pub(crate) struct Spectate {
    factory: Arc<dyn VerifierFactory>,
    rooms: Mutex<BTreeMap<String, Arc<RoomFeed>>>,
    /// Ticks re-simulated for viewers, over all rooms.
    pub(crate) ticks_simulated: AtomicU64,
}

/// One room's inputs and, once watched, its re-simulation.
pub(crate) struct RoomFeed {
    name: String,
    scene: Vec<u8>,
    scene_hash: u64,
    seed: u64,
    /// The bundles the room closed that no re-simulation has applied yet,
    /// in tick order (from tick 0 until someone watches).
    history: Mutex<Vec<TickBundle>>,
    /// Ticks the room closed.
    closed: AtomicU64,
    sim: Mutex<Option<LiveSim>>,
}

struct LiveSim {
    verifier: Box<dyn TickVerifier>,
    recorder: Recorder,
}

impl std::fmt::Debug for Spectate {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Spectate").finish_non_exhaustive()
    }
}

impl Spectate {
    pub(crate) fn new(factory: Arc<dyn VerifierFactory>) -> Spectate {
        Spectate {
            factory,
            rooms: Mutex::new(BTreeMap::new()),
            ticks_simulated: AtomicU64::new(0),
        }
    }

    /// A room opened: viewers can find it from now on.
    pub(crate) fn open(
        &self,
        name: &str,
        scene: &[u8],
        scene_hash: u64,
        seed: u64,
    ) -> Arc<RoomFeed> {
        let feed = Arc::new(RoomFeed {
            name: name.to_owned(),
            scene: scene.to_vec(),
            scene_hash,
            seed,
            history: Mutex::new(Vec::new()),
            closed: AtomicU64::new(0),
            sim: Mutex::new(None),
        });
        lock(&self.rooms).insert(name.to_owned(), feed.clone());
        feed
    }

    /// A room closed: it and its re-simulation are dropped.
    pub(crate) fn close(&self, feed: &Arc<RoomFeed>) {
        let mut rooms = lock(&self.rooms);
        if rooms.get(&feed.name).is_some_and(|f| Arc::ptr_eq(f, feed)) {
            rooms.remove(&feed.name);
        }
    }

    fn room(&self, q: Query<'_>) -> Result<Arc<RoomFeed>, Response> {
        let name = q
            .get("room")
            .ok_or_else(|| Response::error(400, "which room? (?room=NAME)"))?;
        lock(&self.rooms)
            .get(&name)
            .cloned()
            .ok_or_else(|| Response::error(404, "no such room (it may have ended)"))
    }

    /// Brings the room's re-simulation up to its newest closed tick.
    fn advance(&self, feed: &RoomFeed, sim: &mut Option<LiveSim>) -> Result<(), Response> {
        if sim.is_none() {
            let verifier = self
                .factory
                .new_verifier(&feed.scene, feed.scene_hash, feed.seed)
                .map_err(|e| Response::error(503, &format!("cannot re-simulate: {e}")))?;
            let world = restore(&*verifier)?;
            let title = format!("room {}", feed.name);
            let mut recorder = Recorder::new(ViewKind::Live, title, &world);
            recorder.add_bodies(&world);
            *sim = Some(LiveSim { verifier, recorder });
        }
        let Some(s) = sim.as_mut() else {
            return Ok(());
        };
        // The re-simulation holds the state the applied bundles made, so
        // they are taken out of the history: a watched room keeps only the
        // bundles closed since the last request.
        let new: Vec<TickBundle> = std::mem::take(&mut *lock(&feed.history));
        let total = new.len();
        for (i, bundle) in new.iter().enumerate() {
            s.verifier.apply(bundle);
            // Only the frames a viewer can still get are drawn.
            if total - i <= LIVE_FRAMES {
                let world = restore(&*s.verifier)?;
                s.recorder.record(&world, bundle.tick);
            }
        }
        s.recorder.keep_last(LIVE_FRAMES);
        self.ticks_simulated
            .fetch_add(total as u64, Ordering::Relaxed);
        Ok(())
    }

    fn frames(&self, q: Query<'_>) -> Result<Response, Response> {
        let feed = self.room(q)?;
        let after = q.number("after");
        let deadline = Instant::now() + POLL_WAIT;
        loop {
            {
                let mut sim = lock(&feed.sim);
                self.advance(&feed, &mut sim)?;
                let data = sim.as_ref().map(|s| s.recorder.data());
                if let Some(data) = data {
                    let first = match after {
                        Some(t) => data.ticks.partition_point(|&x| x <= t),
                        None => 0,
                    };
                    if first < data.ticks.len() || Instant::now() >= deadline {
                        return Ok(Response::binary(encode_frames_from(data, first)));
                    }
                }
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    fn world(&self, q: Query<'_>) -> Result<Response, Response> {
        if q.get("room").is_none() {
            let rooms: Vec<serde_json::Value> = lock(&self.rooms)
                .values()
                .map(|f| {
                    serde_json::json!({
                        "name": f.name,
                        "ticks": f.closed.load(Ordering::Relaxed),
                    })
                })
                .collect();
            let body = serde_json::json!({ "kind": "rooms", "rooms": rooms });
            return Ok(Response::json(body.to_string().into_bytes()));
        }
        let feed = self.room(q)?;
        let mut sim = lock(&feed.sim);
        self.advance(&feed, &mut sim)?;
        let data = sim.as_ref().map(|s| s.recorder.data());
        Ok(Response::json(
            data.map(world_json).unwrap_or_default().into_bytes(),
        ))
    }

    fn state(&self, q: Query<'_>) -> Result<Response, Response> {
        let feed = self.room(q)?;
        let (tick, body) = q
            .number("tick")
            .zip(q.number("body"))
            .ok_or_else(|| Response::error(400, "state needs tick and body"))?;
        let sim = lock(&feed.sim);
        let data = sim.as_ref().map(|s| s.recorder.data());
        data.and_then(|d| {
            let frame = d.ticks.binary_search(&tick).ok()?;
            state_json(d, frame, usize::try_from(body).ok()?)
        })
        .map(|j| Response::json(j.into_bytes()))
        .ok_or_else(|| Response::error(404, "that tick is no longer kept, or no such body"))
    }
}

impl RoomFeed {
    /// The room closed a tick.
    pub(crate) fn push(&self, bundle: &TickBundle) {
        lock(&self.history).push(bundle.clone());
        self.closed.fetch_add(1, Ordering::Relaxed);
    }
}

/// The viewer's routes for live rooms.
pub(crate) struct LiveRoutes(pub(crate) Arc<Spectate>);

impl Routes for LiveRoutes {
    fn get(&self, path: &str, query: Query<'_>) -> Option<Response> {
        let r = match path {
            "/world" => self.0.world(query),
            "/frames" => self.0.frames(query),
            "/state" => self.0.state(query),
            _ => return None,
        };
        Some(r.unwrap_or_else(|e| e))
    }
}

fn restore(v: &dyn TickVerifier) -> Result<lockstep_core::World, Response> {
    let bytes = v
        .snapshot()
        .ok_or_else(|| Response::error(503, "the re-simulation gives no snapshots"))?;
    lockstep_core::World::restore(&bytes)
        .map_err(|e| Response::error(503, &format!("re-simulation snapshot: {e}")))
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}
