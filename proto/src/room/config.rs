//! Room settings, their defaults, and the checks that keep them coherent.

use std::time::Duration;

use thiserror::Error;

use crate::limits::{
    MAX_INPUT_BYTES, MAX_INPUT_WINDOW, MAX_NAME_BYTES, MAX_PLAYERS, MAX_SCENE_BYTES,
};

/// The smallest [`RoomConfig::max_probe_reply_bytes`]: a body-hash piece
/// of [`MAX_BODY_HASHES`](crate::MAX_BODY_HASHES) hashes of 9 bytes, and
/// room for the reply's other fields.
pub const MIN_PROBE_REPLY_BYTES: u32 = 40 << 10;

/// Everything a room needs to know up front. Capacities are fixed here (as in
/// Jolt) so a room's memory does not grow with the length of a match.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RoomConfig {
    /// Name clients put in [`Join::room`](crate::Join::room).
    pub name: String,
    /// Ticks per second. Default 60.
    pub tick_rate: u16,
    /// Ticks between a client sampling an input and the tick it applies to.
    /// The round trip must stay under `(input_delay + 1)` ticks for inputs
    /// to arrive on time. Default 4 (83 ms of round trip at 60 Hz).
    pub input_delay: u16,
    /// How far ahead of the next open tick inputs are accepted; anything
    /// further is a protocol violation. Must exceed `input_delay`. Default 64.
    pub input_window: u16,
    /// Seats in the room, at most [`MAX_PLAYERS`]. Default 8.
    pub max_players: u8,
    /// Largest input accepted, at most [`MAX_INPUT_BYTES`]. Default 64.
    pub max_input_bytes: usize,
    /// Closed bundles kept for resending. A client whose next needed bundle
    /// is older than this is dropped as fallen behind. Default 512 (8.5 s),
    /// longer than the silence timeout, so a client that went silent is
    /// reported as timed out rather than as fallen behind.
    pub history_ticks: u32,
    /// Ticks of hash reports kept for comparison. Must cover `hash_timeout`.
    /// Default 256.
    pub hash_window_ticks: u32,
    /// How long after a tick closes the room waits for every connected
    /// player's hash before comparing the hashes it has. Default 2 s.
    pub hash_timeout: Duration,
    /// A player heard from for this long is dropped. Default 5 s.
    pub silence_timeout: Duration,
    /// Reports are judged over a sliding window: among the last
    /// `report_window` compared ticks a player was in the bundle of, its
    /// state hash may be missing on at most `max_missing_reports`; one
    /// more and it is dropped with
    /// [`CloseReason::NoHashReports`](crate::CloseReason). Reports are not
    /// optional, or a client could avoid being judged, and a report now
    /// and then does not reset the count (as it would a run of misses in a
    /// row). 0: never. Default 240 (4 s at 60 Hz).
    pub max_missing_reports: u32,
    /// The length of that window, in compared ticks (at least 1, at most
    /// 65,536). Default 600 (10 s at 60 Hz): a player must report at least
    /// 360 of every 600 ticks it was sent; one that never reports goes
    /// after 241 ticks plus the 2 s hash timeout, and one that went silent
    /// altogether is dropped as timed out first (after 5 s).
    pub report_window: u32,
    /// A player whose state hash is judged wrong (against the caller's own
    /// hash with [`RoomConfig::verify`], or outside the voters' strict
    /// majority under [`Voting::TokenHolders`] or [`Voting::Everyone`]) on
    /// this many of its reported ticks in a row is dropped with
    /// [`CloseReason::Diverged`](crate::CloseReason): it diverged for good,
    /// or it keeps lying (ticks it stays silent on do not break the run).
    /// Under [`Voting::Off`] without `verify` nobody is judged wrong.
    /// 0: never. Default 180 (3 s at 60 Hz).
    pub max_wrong_ticks: u32,
    /// Interval between pings to each player (RTT and liveness). Default 1 s.
    pub ping_interval: Duration,
    /// How long the search for where a desync lies (body hashes, then field
    /// dumps, and the snapshot for the desync bundle) may wait for answers
    /// before reporting what it has. Zero: no search, notices only.
    /// Default 10 s.
    pub locate_timeout: Duration,
    /// Most bodies whose hashes the search for a desync pulls from one
    /// player (8 bytes each): an answer claiming more ends that player's
    /// part of the search unread, so a liar cannot make the room pull
    /// megabytes. [`Room::set_max_probe_bodies`](crate::Room::set_max_probe_bodies)
    /// changes it while the room runs (a server that re-simulates knows
    /// the world's body count). Default 8,192 (64 KiB a player).
    pub max_probe_bodies: u32,
    /// Most bytes of one probe reply (encoded, without the version
    /// header): a reply over it ends that player's part of the desync
    /// search unread (and, for a joiner's snapshot, counts as a bad
    /// snapshot), so no single answer makes the room hold or process more.
    /// At least [`MIN_PROBE_REPLY_BYTES`] (the largest body-hash and
    /// snapshot pieces fit it). Default 128 KiB: a body-hash piece of 4,096
    /// bodies is 37 KB, a snapshot piece 32 KiB, and the fields of 8 bodies
    /// a few KB to a few tens of KB.
    pub max_probe_reply_bytes: u32,
    /// The caller re-simulates every tick and gives the room its own hash
    /// ([`Room::verify_tick`](crate::Room::verify_tick)): the room then
    /// judges every report against that hash, not by majority, so a
    /// majority of liars cannot outvote honest players. Default false.
    pub verify: bool,
    /// Without `verify`: whose hashes decide which hash is right (see
    /// [`Voting`]). Default [`Voting::Off`]: nobody is judged wrong.
    pub voting: Voting,
    /// Whether players may join a running match (late join). They start
    /// from a snapshot of the last agreed tick, fetched from a player of
    /// the majority and checked by the caller. Default false.
    pub late_join: bool,
    /// How long the seat of a player who joined with a join token and then
    /// dropped stays reserved for its rejoin with the rejoin credential its
    /// welcome gave (rejoins are allowed even without `late_join`).
    /// Default 30 s.
    pub rejoin_grace: Duration,
    /// Scene sent to each player in the welcome, opaque to the room.
    pub scene: Vec<u8>,
    /// Hash of `scene`, sent alongside it.
    pub scene_hash: u64,
    /// The game rules the match is played with, announced in the welcome
    /// so that a client with other rules refuses to play (`None`: not
    /// announced). Default `None`.
    pub rules: Option<crate::RulesId>,
    /// The match's seed, sent in the welcome: every peer's rules read the
    /// same value (a deterministic random source for the game). Default 0.
    pub seed: u64,
    /// The match runs itself: the room starts, ends and closes on its own
    /// ([`MatchLifecycle`]). Default `None`: the caller starts the match
    /// with [`Room::start`](crate::Room::start) and ends it by dropping the
    /// room.
    pub lifecycle: Option<MatchLifecycle>,
}

/// How a room that runs its own match ([`RoomConfig::lifecycle`]) starts
/// and ends it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MatchLifecycle {
    /// The match starts once this many players are seated and every one
    /// sent its first input.
    pub start_players: u8,
    /// How long the lobby waits after its first join: then the players
    /// without their first input are dropped and the ready ones start. The
    /// room closes if none is ready. `None` waits for ever.
    pub lobby_timeout: Option<Duration>,
    /// The match's length in ticks, `None` for no limit.
    pub match_ticks: Option<u64>,
    /// After the last tick, how long the room waits for the last hash
    /// reports (repeating the bundles a player has not acknowledged once
    /// per tick period) before it closes.
    pub final_reports_timeout: Duration,
}

/// Who decides a tick's right hash in a room that does not verify
/// ([`RoomConfig::verify`] false). A verifying room ignores it: its own
/// hash decides.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Voting {
    /// Nobody: the room cannot tell who is right, so it drops nobody for
    /// its hash. Mismatches are announced with
    /// [`Verdict::Undecided`](crate::Verdict), and a tick's hash is agreed
    /// (for the replay and for joins to the running match) only when every
    /// reporter holds it. The default: connections that do not simulate
    /// cannot outvote, drop or impersonate honest players.
    #[default]
    Off,
    /// The players seated with a join token
    /// ([`Room::join_with_ticket`](crate::Room::join_with_ticket)) vote:
    /// the hash a strict majority of the token holders who reported hold
    /// is right, and every reporter (with a token or not) that reported
    /// another one is judged wrong. A tick no token holder reported has no
    /// agreed hash.
    TokenHolders,
    /// Every player votes, as [`Voting::TokenHolders`] with everyone
    /// holding a token: only for clients the operator trusts (a stranger
    /// can open as many connections as it likes).
    Everyone,
}

impl RoomConfig {
    /// A configuration with the defaults documented on each field.
    pub fn new(name: impl Into<String>, scene: Vec<u8>, scene_hash: u64) -> Self {
        Self {
            name: name.into(),
            tick_rate: 60,
            input_delay: 4,
            input_window: 64,
            max_players: 8,
            max_input_bytes: MAX_INPUT_BYTES,
            history_ticks: 512,
            hash_window_ticks: 256,
            hash_timeout: Duration::from_secs(2),
            silence_timeout: Duration::from_secs(5),
            max_missing_reports: 240,
            report_window: 600,
            max_wrong_ticks: 180,
            ping_interval: Duration::from_secs(1),
            locate_timeout: Duration::from_secs(10),
            max_probe_bodies: 8192,
            max_probe_reply_bytes: 128 << 10,
            rules: None,
            seed: 0,
            verify: false,
            voting: Voting::Off,
            late_join: false,
            rejoin_grace: Duration::from_secs(30),
            scene,
            scene_hash,
            lifecycle: None,
        }
    }

    /// Checks every field against the protocol bounds and the others.
    ///
    /// # Errors
    /// The first inconsistency found, as a [`ConfigError`].
    pub fn validate(&self) -> Result<(), ConfigError> {
        if self.name.len() > MAX_NAME_BYTES {
            return Err(ConfigError::NameTooLong(self.name.len()));
        }
        if self.tick_rate == 0 {
            return Err(ConfigError::ZeroTickRate);
        }
        if self.max_players == 0 || usize::from(self.max_players) > MAX_PLAYERS {
            return Err(ConfigError::MaxPlayers(self.max_players));
        }
        if self.max_input_bytes > MAX_INPUT_BYTES {
            return Err(ConfigError::MaxInputBytes(self.max_input_bytes));
        }
        if self.input_window <= self.input_delay || self.input_window > MAX_INPUT_WINDOW {
            return Err(ConfigError::InputWindow {
                window: self.input_window,
                delay: self.input_delay,
            });
        }
        if self.history_ticks < 2 {
            return Err(ConfigError::HistoryTooShort(self.history_ticks));
        }
        let needed = self.ticks_in(self.hash_timeout).saturating_add(2);
        if u64::from(self.hash_window_ticks) < needed {
            return Err(ConfigError::HashWindowTooShort {
                window: self.hash_window_ticks,
                needed,
            });
        }
        if self.report_window == 0 || self.report_window > 65_536 {
            return Err(ConfigError::ReportWindow(self.report_window));
        }
        if self.silence_timeout.is_zero() || self.ping_interval.is_zero() {
            return Err(ConfigError::ZeroInterval);
        }
        if self.scene.len() > MAX_SCENE_BYTES {
            return Err(ConfigError::SceneTooLarge(self.scene.len()));
        }
        if self.max_probe_reply_bytes < MIN_PROBE_REPLY_BYTES {
            return Err(ConfigError::ProbeReplyBudget(self.max_probe_reply_bytes));
        }
        Ok(())
    }

    /// Time from the start of the match to the deadline of `tick`, when the
    /// room closes it: `(tick + 1) / tick_rate` seconds, computed in integer
    /// nanoseconds from the start so it never drifts.
    pub fn deadline_offset(&self, tick: u64) -> Duration {
        let nanos = (u128::from(tick) + 1) * 1_000_000_000 / u128::from(self.tick_rate.max(1));
        Duration::from_nanos(u64::try_from(nanos).unwrap_or(u64::MAX))
    }

    /// Whole ticks (rounded up) spanned by `d`.
    pub fn ticks_in(&self, d: Duration) -> u64 {
        let ticks = (d.as_nanos() * u128::from(self.tick_rate)).div_ceil(1_000_000_000);
        u64::try_from(ticks).unwrap_or(u64::MAX)
    }
}

/// A [`RoomConfig`] that cannot work.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum ConfigError {
    /// The room name is longer than [`MAX_NAME_BYTES`].
    #[error("room name of {0} bytes is too long")]
    NameTooLong(usize),
    /// A tick rate of zero never closes a tick.
    #[error("tick rate must be positive")]
    ZeroTickRate,
    /// `max_players` is zero or above [`MAX_PLAYERS`].
    #[error("max_players {0} is outside 1..=MAX_PLAYERS")]
    MaxPlayers(u8),
    /// `max_input_bytes` is above [`MAX_INPUT_BYTES`].
    #[error("max_input_bytes {0} exceeds MAX_INPUT_BYTES")]
    MaxInputBytes(usize),
    /// The input window does not exceed the input delay, or is too large.
    #[error(
        "input window {window} must exceed input delay {delay} and be at most MAX_INPUT_WINDOW"
    )]
    InputWindow {
        /// Configured window.
        window: u16,
        /// Configured delay.
        delay: u16,
    },
    /// The history cannot hold even two bundles.
    #[error("history of {0} ticks is too short")]
    HistoryTooShort(u32),
    /// The hash window is shorter than the hash timeout, so reports would be
    /// evicted before the room waited for them.
    #[error("hash window of {window} ticks is shorter than the {needed} the timeout needs")]
    HashWindowTooShort {
        /// Configured window.
        window: u32,
        /// Ticks the timeout spans, plus margin.
        needed: u64,
    },
    /// The report window is empty or longer than 65,536 ticks.
    #[error("report window of {0} ticks is outside 1..=65536")]
    ReportWindow(u32),
    /// A zero silence timeout or ping interval.
    #[error("silence timeout and ping interval must be positive")]
    ZeroInterval,
    /// `max_probe_reply_bytes` is below [`MIN_PROBE_REPLY_BYTES`].
    #[error(
        "max_probe_reply_bytes {0} is below {MIN_PROBE_REPLY_BYTES}, the largest body-hash piece"
    )]
    ProbeReplyBudget(u32),
    /// The scene is larger than [`MAX_SCENE_BYTES`].
    #[error("scene of {0} bytes is too large")]
    SceneTooLarge(usize),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_deadlines_do_not_drift() {
        let c = RoomConfig::new("r", vec![], 0);
        assert_eq!(c.validate(), Ok(()));
        assert_eq!(c.deadline_offset(0), Duration::from_nanos(16_666_666));
        assert_eq!(c.deadline_offset(59), Duration::from_secs(1));
        assert_eq!(c.deadline_offset(215_999), Duration::from_secs(3600));
        assert_eq!(c.ticks_in(Duration::from_secs(2)), 120);
        assert_eq!(c.ticks_in(Duration::from_millis(17)), 2);
    }

    #[test]
    fn incoherent_configs_are_refused() {
        let mut c = RoomConfig::new("r", vec![], 0);
        c.input_window = 4;
        assert_eq!(
            c.validate(),
            Err(ConfigError::InputWindow {
                window: 4,
                delay: 4
            })
        );
        let mut c = RoomConfig::new("r", vec![], 0);
        c.hash_window_ticks = 100;
        assert_eq!(
            c.validate(),
            Err(ConfigError::HashWindowTooShort {
                window: 100,
                needed: 122
            })
        );
        let mut c = RoomConfig::new("r", vec![], 0);
        c.max_players = 17;
        assert_eq!(c.validate(), Err(ConfigError::MaxPlayers(17)));
    }
}
