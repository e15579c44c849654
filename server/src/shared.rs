//! The state the accept loop, the connection tasks and the room tasks
//! share.

use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};

use tokio::sync::watch;
use tokio::task::JoinSet;

use crate::{ServerConfig, ServerEvent, ServerReport, agones, clock, metrics, room, spectate};

/// State shared by the accept loop, the connection tasks and the rooms.
pub(crate) struct Shared {
    pub(crate) config: ServerConfig,
    pub(crate) scene_hash: u64,
    /// Bodies in the scene's world.
    pub(crate) scene_bodies: u32,
    pub(crate) rooms: Mutex<HashMap<String, room::RoomHandle>>,
    pub(crate) shutdown: watch::Receiver<bool>,
    pub(crate) report: Mutex<ServerReport>,
    pub(crate) room_tasks: Mutex<JoinSet<()>>,
    pub(crate) room_seq: std::sync::atomic::AtomicU64,
    pub(crate) metrics: metrics::Metrics,
    /// Notified when a match ends (for `exit_after_match`).
    pub(crate) match_ended: tokio::sync::Notify,
    /// Precise wake-ups for the rooms' tick clocks.
    pub(crate) clock: clock::Clock,
    /// The real-time threads room tasks run on (`None`: the server's
    /// runtime).
    pub(crate) room_threads: Option<clock::RoomThreads>,
    /// Agones mode: whether and how the server is allocated.
    pub(crate) allocation: std::sync::RwLock<agones::AllocationState>,
    /// The live viewer's rooms (`--view`).
    pub(crate) spectate: Option<Arc<spectate::Spectate>>,
    /// Open connections per IP address.
    pub(crate) per_address: Mutex<HashMap<std::net::IpAddr, usize>>,
}

/// One connection counted against its address while it lives.
pub(crate) struct AddressSlot {
    shared: Arc<Shared>,
    ip: std::net::IpAddr,
}

impl Drop for AddressSlot {
    fn drop(&mut self) {
        let mut map = self
            .shared
            .per_address
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        if let Some(n) = map.get_mut(&self.ip) {
            *n -= 1;
            if *n == 0 {
                map.remove(&self.ip);
            }
        }
    }
}

impl Shared {
    pub(crate) fn emit(&self, event: ServerEvent) {
        if let Some(tx) = &self.config.events {
            let _ = tx.send(event);
        }
    }

    /// Counts one more connection from `ip`, unless it already has
    /// `max_connections_per_address`.
    pub(crate) fn address_slot(self: &Arc<Self>, ip: std::net::IpAddr) -> Option<AddressSlot> {
        let mut map = self.per_address.lock().unwrap_or_else(|e| e.into_inner());
        let n = map.entry(ip).or_insert(0);
        if self
            .config
            .max_connections_per_address
            .is_some_and(|max| *n >= max)
        {
            return None;
        }
        *n += 1;
        Some(AddressSlot {
            shared: self.clone(),
            ip,
        })
    }

    pub(crate) fn refused(&self, remote: SocketAddr, reason: String) {
        crate::log!("refused {remote}: {reason}");
        self.metrics.refused(&reason);
        if let Ok(mut r) = self.report.lock() {
            r.add_refusal(remote, reason.clone());
        }
        self.emit(ServerEvent::Refused { remote, reason });
    }
}
