//! What the room hands back to its caller: transmits, events, counters, and
//! the player handle they are addressed with.

use crate::forensics::DesyncReport;
use crate::message::{Channel, DesyncNotice, ServerMessage, Slot, TickBundle};

/// Handle of a seated player: the slot plus a generation, so a message or
/// transmit meant for a player who left is never confused with the next
/// occupant of the same slot.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct PlayerId {
    /// The seat.
    pub slot: Slot,
    /// How many times the seat had been taken before this player.
    pub generation: u32,
}

/// A message the caller must send to one player.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Transmit {
    /// Recipient.
    pub to: PlayerId,
    /// The message; encode it with [`ServerMessage::encode`].
    pub message: ServerMessage,
}

impl Transmit {
    /// Channel to send it on.
    pub fn channel(&self) -> Channel {
        self.message.channel()
    }
}

/// Why a player is no longer in the room.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LeaveReason {
    /// The client sent [`ClientMessage::Leave`](crate::ClientMessage::Leave).
    Left,
    /// The caller reported the connection lost ([`Room::disconnect`](super::Room::disconnect)).
    Disconnected,
    /// Nothing was heard for [`RoomConfig::silence_timeout`](super::RoomConfig::silence_timeout).
    TimedOut,
    /// The client stopped acknowledging bundles until the ones it needs were
    /// dropped from the history.
    FellBehind,
    /// The caller removed the player ([`Room::kick`](super::Room::kick)).
    Kicked,
    /// The room closed (the match ended, or the server shut down): a
    /// normal end, [`Room::kick`](super::Room::kick) with
    /// [`CloseReason::RoomClosed`](crate::CloseReason::RoomClosed).
    RoomClosed,
    /// Its state hash stayed outside the majority for
    /// [`RoomConfig::max_wrong_ticks`](super::RoomConfig::max_wrong_ticks)
    /// reported ticks in a row.
    Diverged,
    /// Its state hash was missing on more than
    /// [`RoomConfig::max_missing_reports`](super::RoomConfig::max_missing_reports)
    /// of its last [`RoomConfig::report_window`](super::RoomConfig::report_window)
    /// compared ticks.
    NoHashReports,
    /// It was joining the running match (or rejoining its seat) and no
    /// agreed state could be had for it: refused with
    /// [`CloseReason::MatchInProgress`](crate::CloseReason::MatchInProgress)
    /// and the reason (a rejoiner keeps its seat's reservation).
    JoinRefused,
}

/// Something the caller may want to log, record or act on.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum RoomEvent {
    /// A player took a seat.
    PlayerJoined {
        /// Their handle.
        id: PlayerId,
        /// Their display name.
        name: String,
    },
    /// A player left; bundles from `from_tick` on no longer include them.
    PlayerLeft {
        /// Their handle.
        id: PlayerId,
        /// Why.
        reason: LeaveReason,
        /// First tick without them.
        from_tick: u64,
    },
    /// A tick closed; this is exactly what every client will apply, so a
    /// server recording a replay stores these.
    TickClosed(TickBundle),
    /// An input arrived after its tick had closed with a substitute.
    LateInput {
        /// Whose.
        id: PlayerId,
        /// For which tick.
        tick: u64,
    },
    /// Players' hashes differ; the same notice was queued to every player.
    Desync(DesyncNotice),
    /// A compared tick has a right hash the room stands behind: the
    /// caller's own ([`RoomConfig::verify`](super::RoomConfig::verify)),
    /// the voters' strict majority, or, without voting, the hash every
    /// reporter held. A tick without one gets no event. What a replay
    /// records as the tick's hash ([`ReplayRecorder::follow_room`](crate::ReplayRecorder::follow_room)).
    TickAgreed {
        /// The tick.
        tick: u64,
        /// Its right hash.
        hash: u64,
    },
    /// The agreed snapshot for a player joining the running match arrived:
    /// check it restores and hashes to `agreed_hash`, then call
    /// [`Room::admit`](super::Room::admit) (or
    /// [`Room::refuse_join`](super::Room::refuse_join)).
    JoinSnapshot {
        /// The joiner.
        id: PlayerId,
        /// The tick it is the state after.
        tick: u64,
        /// The agreed hash of that tick.
        agreed_hash: u64,
        /// The player that gave it.
        from: Option<Slot>,
        /// The snapshot.
        bytes: Vec<u8>,
    },
    /// A player joins the running match from the caller's own state
    /// ([`Room::offer_own_snapshots`](super::Room::offer_own_snapshots)):
    /// take the snapshot of the state after `tick` and check it hashes to
    /// `agreed_hash`, then call [`Room::admit`](super::Room::admit) (or
    /// [`Room::refuse_join`](super::Room::refuse_join)).
    JoinFromOwnState {
        /// The joiner.
        id: PlayerId,
        /// The newest verified tick.
        tick: u64,
        /// The caller's hash of it.
        agreed_hash: u64,
    },
    /// The search started by a desync notice is over: the bodies and
    /// fields that differ (the same report was queued to every player).
    DesyncLocated(DesyncReport),
    /// The snapshot of the last agreed tick before a desync, from a player
    /// of the majority, for the desync bundle. Check it against
    /// `agreed_hash` before trusting it: the room cannot read it.
    DesyncSnapshot {
        /// Its tick.
        tick: u64,
        /// The hash the players agreed on for that tick, if known.
        agreed_hash: Option<u64>,
        /// Who sent it.
        from: Slot,
        /// The engine's snapshot bytes.
        bytes: Vec<u8>,
    },
    /// The room started its match ([`RoomConfig::lifecycle`](super::RoomConfig::lifecycle)):
    /// tick 0 closes one tick period after [`Room::started_at`](super::Room::started_at).
    MatchStarted {
        /// Players seated at the start.
        players: usize,
    },
    /// The last tick closed ([`RoomConfig::lifecycle`](super::RoomConfig::lifecycle)):
    /// the room collects the last hash reports, then closes everyone.
    MatchEnding {
        /// Why the match ends.
        reason: String,
    },
    /// The match is over and the room has nothing more to do
    /// ([`RoomConfig::lifecycle`](super::RoomConfig::lifecycle)): the
    /// players still seated were closed just before (or, in a lobby where
    /// nobody was ready, are closed just after).
    MatchOver {
        /// Why the match ended.
        reason: String,
        /// Whether every player still seated had reported its hash of the
        /// last tick.
        all_reported: bool,
    },
}

/// Room-wide counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RoomStats {
    /// Ticks closed so far.
    pub ticks_closed: u64,
    /// Ticks whose hashes were compared.
    pub ticks_compared: u64,
    /// Compared ticks whose hashes differed.
    pub mismatched_ticks: u64,
    /// Desync notices raised (one per divergence, not per tick).
    pub desync_notices: u64,
    /// Searches started for where a desync lies (one runs at a time; a
    /// notice raised during a search is not searched).
    pub desync_searches: u64,
    /// Searches that ended with a report.
    pub desyncs_located: u64,
    /// Snapshots players gave a player joining the running match that did
    /// not check out or came in pieces that do not fit (each counts against
    /// its giver, [`PlayerStats::bad_snapshots`](super::PlayerStats::bad_snapshots)).
    pub bad_snapshots: u64,
}
