//! Opening rooms: the room configuration the settings describe, the
//! check of the settings at start-up, and the registry of open rooms.

use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::SystemTime;

use lockstep_proto::{Close, CloseReason, MatchLifecycle, Room, RoomConfig};
use tokio::sync::mpsc;

use super::RoomTask;
use crate::peer::{RoomCmd, close_of};
use crate::{ServerConfig, ServerError, Shared};

/// The registry's handle on a room task.
pub(crate) struct RoomHandle {
    tx: mpsc::Sender<RoomCmd>,
    pub(super) seq: u64,
}

/// Builds the room configuration the settings describe.
fn room_config(config: &ServerConfig, name: &str, scene_hash: u64, bodies: u32) -> RoomConfig {
    let s = &config.room;
    let mut c = RoomConfig::new(name, config.scene.as_bytes().to_vec(), scene_hash);
    c.tick_rate = s.tick_rate;
    c.input_delay = s.input_delay;
    c.max_players = s.max_players;
    c.silence_timeout = s.silence_timeout;
    c.verify = config.verifier.is_some();
    // What the server knows of the world: the desync search pulls the
    // hashes of at most twice the scene's bodies (plus room for a game
    // that adds a few) from each player.
    c.max_probe_bodies = bodies.saturating_mul(2).saturating_add(64);
    c.voting = if config.vote {
        lockstep_proto::Voting::TokenHolders
    } else {
        lockstep_proto::Voting::Off
    };
    c.late_join = s.late_join;
    c.rejoin_grace = s.rejoin_grace;
    c.lifecycle = Some(MatchLifecycle {
        start_players: s.start_players,
        lobby_timeout: s.lobby_timeout,
        match_ticks: s.match_ticks,
        final_reports_timeout: s.final_reports_timeout,
    });
    c.rules = Some(config.rules.clone());
    c.seed = s.seed.unwrap_or_else(|| {
        // A fresh seed per room: std's hasher keys are random per process,
        // the room's name and the clock make it per room.
        use std::hash::BuildHasher;
        let now = SystemTime::now()
            .duration_since(SystemTime::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos());
        std::collections::hash_map::RandomState::new().hash_one((name, now))
    });
    c.input_window = c.input_window.max(s.input_delay.saturating_add(16));
    let needed = c.ticks_in(c.hash_timeout).saturating_add(2);
    c.hash_window_ticks = c
        .hash_window_ticks
        .max(u32::try_from(needed).unwrap_or(u32::MAX));
    c
}

/// Checks the settings once at start-up, so a room can never fail to open.
pub(crate) fn check_settings(config: &ServerConfig, scene_hash: u64) -> Result<(), ServerError> {
    room_config(config, "check", scene_hash, 0)
        .validate()
        .map_err(|e| ServerError::Config(e.to_string()))?;
    let s = &config.room;
    if s.start_players == 0 || s.start_players > s.max_players {
        return Err(ServerError::Config(format!(
            "start_players {} must be in 1..=max_players ({})",
            s.start_players, s.max_players
        )));
    }
    if s.match_ticks == Some(0) {
        return Err(ServerError::Config("match_ticks must be positive".into()));
    }
    // A server asked to verify that cannot re-simulate its scene would wait
    // out every tick's hash timeout: it refuses to start instead.
    if let Some(f) = &config.verifier {
        f.new_verifier(config.scene.as_bytes(), scene_hash, 0)
            .map_err(|e| {
                ServerError::Config(format!("verify: cannot re-simulate the scene: {e}"))
            })?;
    }
    Ok(())
}

/// The sender of the open room named `name`, opening it if needed.
pub(crate) fn find_or_open(
    shared: &Arc<Shared>,
    name: &str,
) -> Result<mpsc::Sender<RoomCmd>, Close> {
    if *shared.shutdown.borrow() {
        return Err(close_of(
            CloseReason::RoomClosed,
            "the server is shutting down",
        ));
    }
    let mut rooms = shared.rooms.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(h) = rooms.get(name)
        && !h.tx.is_closed()
    {
        return Ok(h.tx.clone());
    }
    if rooms.len() >= shared.config.max_rooms {
        return Err(close_of(
            CloseReason::RoomFull,
            format!("the server has {} rooms open, its limit", rooms.len()),
        ));
    }
    if name.len() > lockstep_proto::MAX_NAME_BYTES {
        return Err(close_of(CloseReason::WrongRoom, "room name too long"));
    }
    let config = room_config(&shared.config, name, shared.scene_hash, shared.scene_bodies);
    // check_settings validated this configuration at start-up.
    let mut room =
        Room::new(config).map_err(|e| close_of(CloseReason::RoomClosed, e.to_string()))?;
    room.set_rejoin_key(rejoin_key()?);
    let (tx, rx) = mpsc::channel(4096);
    let seq = shared.room_seq.fetch_add(1, Ordering::Relaxed);
    let task = RoomTask::new(shared.clone(), name.to_owned(), room, seq);
    let task = tracing::Instrument::instrument(
        task.run(rx),
        tracing::info_span!(parent: None, "room", room = %name),
    );
    let mut tasks = shared.room_tasks.lock().unwrap_or_else(|e| e.into_inner());
    match &shared.room_threads {
        Some(threads) => tasks.spawn_on(task, threads.handle()),
        None => tasks.spawn(task),
    };
    drop(tasks);
    rooms.insert(
        name.to_owned(),
        RoomHandle {
            tx: tx.clone(),
            seq,
        },
    );
    Ok(tx)
}

/// A fresh secret key for a room's rejoin credentials: 32 bytes from the
/// operating system's random source (through the TLS library's provider).
fn rejoin_key() -> Result<[u8; 32], Close> {
    let mut key = [0u8; 32];
    rustls::crypto::ring::default_provider()
        .secure_random
        .fill(&mut key)
        .map_err(|_| close_of(CloseReason::RoomClosed, "no random source for the room"))?;
    Ok(key)
}
