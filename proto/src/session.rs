//! The client side of lockstep as a state machine: input submission with
//! redundancy, in-order exactly-once delivery of tick bundles, and hash
//! reports.
//!
//! A [`Session`] is created from the server's [`Welcome`]. The caller feeds it
//! decoded server messages with the time they arrived
//! ([`Session::handle_message`]), applies the bundles
//! [`Session::poll_bundle`] yields (strictly in tick order, each once, however
//! the network duplicated, reordered or dropped datagrams), submits an input
//! whenever [`Session::wants_input`] says so, reports the state hash of each
//! applied tick, and sends what [`Session::poll_transmit`] returns. Like the
//! room it reads no clock: the caller passes `now`.
//!
//! Pacing: the input for tick `n + 1 + input_delay` is due once tick `n` is
//! known to be closed. A tick is known closed when its bundle arrived, or —
//! while the downlink is losing datagrams — when the local clock says it
//! should have, extrapolating from the arrival of the newest bundle. So a
//! burst of lost bundles does not stall the inputs that later ticks need.

use std::collections::VecDeque;
use std::time::Duration;

use thiserror::Error;

use crate::limits::{MAX_BODY_HASHES, MAX_INPUTS_PER_DATAGRAM, PROTOCOL_VERSION};
use crate::message::{
    ClientMessage, Close, DesyncNotice, HashReport, InputDatagram, Join, Pong, ServerMessage, Slot,
    TickBundle, Violation, Welcome,
};
use crate::ring::TickRing;

/// Ticks ahead of the next bundle to deliver that the session buffers; a
/// bundle further ahead is dropped and arrives again later (the room resends
/// every unacknowledged bundle).
pub const REORDER_TICKS: usize = 512;

/// Ticks of locally computed hashes remembered, to put next to the room's
/// figures when a desync notice arrives.
pub const LOCAL_HASH_TICKS: usize = 256;

/// Something the client application should react to.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SessionEvent {
    /// The room found a hash mismatch.
    Desync {
        /// The room's notice.
        notice: DesyncNotice,
        /// This client's own hash for that tick, if still remembered.
        local_hash: Option<u64>,
    },
    /// The server ended the session.
    Closed(Close),
    /// The room asks about a past tick to locate a desync: answer with
    /// [`Session::reply_probe`] (clients keep a short ring of past states
    /// for this).
    Probe(crate::forensics::Probe),
    /// The room located a desync: the bodies and fields that differ.
    DesyncLocated(crate::forensics::DesyncReport),
}

/// Why a session call was refused.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum SessionError {
    /// The welcome breaks a protocol bound.
    #[error("invalid welcome: {0}")]
    InvalidWelcome(Violation),
    /// The session was closed by the server or by [`Session::leave`].
    #[error("session is closed")]
    Closed,
    /// An input larger than the room accepts.
    #[error("input of {len} bytes exceeds {max}")]
    InputTooLarge {
        /// Its size.
        len: usize,
        /// The room's limit.
        max: usize,
    },
    /// The input would be for a tick the room does not accept yet; wait for
    /// more bundles ([`Session::wants_input`] says when).
    #[error("input for tick {tick} is beyond the window (limit {limit})")]
    InputWindowFull {
        /// The tick the input would be for.
        tick: u64,
        /// First tick not accepted yet.
        limit: u64,
    },
    /// A hash for a tick whose bundle has not been delivered.
    #[error("hash for tick {tick}, which has not been applied")]
    HashForUnappliedTick {
        /// The tick.
        tick: u64,
    },
    /// Hashes must be reported in increasing tick order.
    #[error("hash for tick {tick} after tick {last}")]
    HashOutOfOrder {
        /// The tick.
        tick: u64,
        /// Last tick reported.
        last: u64,
    },
    /// More per-body hashes than [`MAX_BODY_HASHES`].
    #[error("{0} body hashes exceed the limit")]
    TooManyBodyHashes(usize),
    /// A message that makes no sense in a running session (a second welcome).
    #[error("unexpected {0} message")]
    UnexpectedMessage(&'static str),
}

/// Counters describing what the network did to the bundle stream.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SessionStats {
    /// Bundles received that were already received or delivered.
    pub duplicate_bundles: u64,
    /// Bundles too far ahead to buffer, dropped (they come again).
    pub bundles_beyond_window: u64,
    /// Bundles that arrived before an earlier missing one.
    pub out_of_order_bundles: u64,
    /// Input datagrams produced.
    pub input_datagrams: u64,
}

/// A client's lockstep session; see the module documentation, and the
/// example on [`Room`](crate::Room), which drives one through a tick.
#[derive(Debug)]
pub struct Session {
    slot: Slot,
    tick_rate: u16,
    input_delay: u16,
    /// Ticks ahead of the room's clock inputs are sent (the input delay
    /// unless a predicting client asks for more, [`Session::set_input_lead`]).
    input_lead: u16,
    input_window: u16,
    max_input_bytes: usize,
    start_tick: u64,
    /// The first bundle to apply (before `start_tick` for a player joining
    /// a running match).
    first_bundle: u64,
    scene_hash: u64,
    next_input_tick: u64,
    inputs: TickRing<Vec<u8>>,
    input_ack: Option<u64>,
    input_dirty: bool,
    /// Newest bundle tick seen and the local time it arrived: the anchor
    /// from which the room's clock is extrapolated.
    clock_anchor: Option<(u64, Duration)>,
    /// Whether an input datagram was built since the last resend timer.
    sent_since_timer: bool,
    next_resend_at: Option<Duration>,
    next_deliver: u64,
    /// Every bundle up to this tick has been received (delivered or buffered).
    received_through: Option<u64>,
    reorder: TickRing<TickBundle>,
    local_hashes: TickRing<u64>,
    last_reported: Option<u64>,
    reliable: VecDeque<ClientMessage>,
    pong: Option<Pong>,
    events: VecDeque<SessionEvent>,
    closed: bool,
    stats: SessionStats,
}

impl Session {
    /// The join message for `room`, to send before any session exists.
    pub fn join_message(room: &str, player_name: &str) -> ClientMessage {
        Self::join_message_with_token(room, player_name, None)
    }

    /// The join message carrying a join token.
    pub fn join_message_with_token(
        room: &str,
        player_name: &str,
        token: Option<String>,
    ) -> ClientMessage {
        Self::rejoin_message(room, player_name, token, None)
    }

    /// The join message carrying a join token and the rejoin credential of
    /// an earlier welcome of the same match ([`Welcome::rejoin`]), which
    /// takes the player back to its seat.
    pub fn rejoin_message(
        room: &str,
        player_name: &str,
        token: Option<String>,
        rejoin: Option<crate::message::RejoinCredential>,
    ) -> ClientMessage {
        ClientMessage::Join(Join {
            protocol_version: PROTOCOL_VERSION,
            room: room.to_owned(),
            player_name: player_name.to_owned(),
            token,
            rejoin,
        })
    }

    /// Starts a session from the server's welcome. The caller keeps the
    /// scene bytes; the session only needs the timing parameters.
    ///
    /// # Errors
    /// [`SessionError::InvalidWelcome`] if the welcome breaks a bound.
    pub fn new(welcome: &Welcome) -> Result<Self, SessionError> {
        welcome.validate().map_err(SessionError::InvalidWelcome)?;
        let first_bundle = welcome
            .resume
            .as_ref()
            .map_or(welcome.start_tick, |r| r.tick + 1);
        Ok(Self {
            slot: welcome.slot,
            tick_rate: welcome.tick_rate,
            input_delay: welcome.input_delay,
            input_lead: welcome.input_delay,
            input_window: welcome.input_window,
            max_input_bytes: usize::from(welcome.max_input_bytes),
            start_tick: welcome.start_tick,
            first_bundle,
            scene_hash: welcome.scene_hash,
            next_input_tick: welcome.start_tick,
            inputs: TickRing::new(usize::from(welcome.input_window)),
            input_ack: None,
            input_dirty: false,
            clock_anchor: None,
            sent_since_timer: false,
            next_resend_at: None,
            next_deliver: first_bundle,
            received_through: first_bundle.checked_sub(1),
            reorder: TickRing::new(REORDER_TICKS),
            local_hashes: TickRing::new(LOCAL_HASH_TICKS),
            last_reported: None,
            reliable: VecDeque::new(),
            pong: None,
            events: VecDeque::new(),
            closed: false,
            stats: SessionStats::default(),
        })
    }

    fn period(&self) -> Duration {
        Duration::from_nanos(1_000_000_000 / u64::from(self.tick_rate.max(1)))
    }

    /// The newest tick the room has presumably closed by `now`: the newest
    /// bundle seen plus the whole tick periods elapsed since it arrived.
    pub fn estimated_room_tick(&self, now: Duration) -> Option<u64> {
        let (tick, at) = self.clock_anchor?;
        let elapsed = now.saturating_sub(at).as_nanos() / self.period().as_nanos().max(1);
        Some(tick.saturating_add(u64::try_from(elapsed).unwrap_or(u64::MAX)))
    }

    /// First tick not yet known (or estimated) to be closed.
    fn pacing_base(&self, now: Duration) -> u64 {
        let estimated = self.estimated_room_tick(now).map_or(0, |t| t + 1);
        self.next_deliver.max(estimated)
    }

    /// Whether the application should submit its next input now: the next
    /// input tick is at most `input_delay` ticks past the first tick not
    /// known to be closed, and inside the room's window. Inputs then arrive
    /// on time whenever the round trip is below `input_delay + 1` ticks.
    pub fn wants_input(&self, now: Duration) -> bool {
        !self.closed
            && self.next_input_tick <= self.pacing_base(now) + u64::from(self.input_lead)
            && self.next_input_tick < self.next_deliver + u64::from(self.input_window)
    }

    /// Queues `input` for the next input tick and returns that tick. The
    /// input is repeated in every input datagram until the server
    /// acknowledges it.
    ///
    /// # Errors
    /// [`SessionError::Closed`], [`SessionError::InputTooLarge`], or
    /// [`SessionError::InputWindowFull`] when submitting further ahead than
    /// the room accepts.
    pub fn submit_input(&mut self, input: Vec<u8>) -> Result<u64, SessionError> {
        if self.closed {
            return Err(SessionError::Closed);
        }
        if input.len() > self.max_input_bytes {
            return Err(SessionError::InputTooLarge {
                len: input.len(),
                max: self.max_input_bytes,
            });
        }
        let tick = self.next_input_tick;
        // next_deliver never exceeds the room's next open tick, so this
        // keeps every input inside the room's acceptance window.
        let limit = self.next_deliver + u64::from(self.input_window);
        if tick >= limit {
            return Err(SessionError::InputWindowFull { tick, limit });
        }
        self.inputs.insert(tick, input);
        self.next_input_tick += 1;
        self.input_dirty = true;
        Ok(tick)
    }

    /// Applies one decoded server message that arrived at `now`.
    ///
    /// # Errors
    /// [`SessionError::UnexpectedMessage`] for a second welcome.
    pub fn handle_message(
        &mut self,
        now: Duration,
        message: ServerMessage,
    ) -> Result<(), SessionError> {
        match message {
            ServerMessage::Welcome(_) => return Err(SessionError::UnexpectedMessage("welcome")),
            ServerMessage::Bundles(d) => {
                self.input_ack = self.input_ack.max(d.ack_input);
                if let Some(newest) = d.bundles.last().map(|b| b.tick)
                    && self.clock_anchor.is_none_or(|(t, _)| newest > t)
                {
                    self.clock_anchor = Some((newest, now));
                }
                for b in d.bundles {
                    self.accept_bundle(b);
                }
                // Answer every bundle datagram: the reply carries the bundle
                // ack, and repeats unacknowledged inputs even while the
                // application is not submitting.
                self.input_dirty = true;
            }
            ServerMessage::Desync(notice) => {
                let local_hash = self.local_hashes.get(notice.tick).copied();
                self.events
                    .push_back(SessionEvent::Desync { notice, local_hash });
            }
            ServerMessage::Ping(p) => {
                self.pong = Some(Pong { nonce: p.nonce });
                // Before the match starts no bundles flow; pings are then
                // what makes lost inputs for the first ticks go out again.
                if self.has_unacked_inputs() {
                    self.input_dirty = true;
                }
            }
            ServerMessage::Close(c) => {
                self.closed = true;
                self.events.push_back(SessionEvent::Closed(c));
            }
            ServerMessage::Probe(p) => self.events.push_back(SessionEvent::Probe(p)),
            ServerMessage::DesyncReport(r) => {
                self.events.push_back(SessionEvent::DesyncLocated(r));
            }
        }
        Ok(())
    }

    fn first_unacked_input(&self) -> u64 {
        self.input_ack
            .map_or(self.start_tick, |a| (a + 1).max(self.start_tick))
    }

    /// Inputs the room has not acknowledged, for ticks not known closed.
    fn has_unacked_inputs(&self) -> bool {
        self.first_unacked_input().max(self.next_deliver) < self.next_input_tick
    }

    fn accept_bundle(&mut self, b: TickBundle) {
        let tick = b.tick;
        if tick < self.next_deliver || self.reorder.contains(tick) {
            self.stats.duplicate_bundles += 1;
            return;
        }
        if tick >= self.next_deliver + REORDER_TICKS as u64 {
            self.stats.bundles_beyond_window += 1;
            return;
        }
        let expected = self.received_through.map_or(self.first_bundle, |t| t + 1);
        if tick > expected {
            self.stats.out_of_order_bundles += 1;
        }
        self.reorder.insert(tick, b);
        let mut next = expected;
        while self.reorder.contains(next) {
            self.received_through = Some(next);
            next += 1;
        }
    }

    /// Tells the session the time. Inputs are normally repeated whenever a
    /// bundle datagram arrives; if a whole tick period passed without any
    /// input datagram while inputs are unacknowledged (the downlink is
    /// losing everything), this makes the next [`Session::poll_transmit`]
    /// repeat them anyway, so a lost uplink datagram is not left
    /// unrepeated until its deadline.
    pub fn handle_timeout(&mut self, now: Duration) {
        match self.next_resend_at {
            Some(at) if now < at => return,
            Some(_) if !self.sent_since_timer && self.has_unacked_inputs() => {
                self.input_dirty = true;
            }
            _ => {}
        }
        self.sent_since_timer = false;
        self.next_resend_at = Some(now.saturating_add(self.period()));
    }

    /// The next time the session has something to do on its own: the resend
    /// timer, or the moment the estimated room clock makes the next input
    /// due. `None` once closed.
    pub fn poll_timeout(&self) -> Option<Duration> {
        if self.closed {
            return None;
        }
        let resend = self.next_resend_at.unwrap_or(Duration::ZERO);
        // The input for tick i is due when the estimate reaches
        // i - input_delay - 1, i.e. (that - anchor) periods after the anchor.
        let due = self.clock_anchor.and_then(|(tick, at)| {
            let needed = self
                .next_input_tick
                .checked_sub(u64::from(self.input_lead) + 1)?;
            let periods = u32::try_from(needed.checked_sub(tick)?).ok()?;
            Some(at.saturating_add(self.period().saturating_mul(periods)))
        });
        Some(due.map_or(resend, |d| d.min(resend)))
    }

    /// The next bundle in tick order, once; `None` until it has arrived.
    pub fn poll_bundle(&mut self) -> Option<TickBundle> {
        let b = self.reorder.remove(self.next_deliver)?;
        self.next_deliver += 1;
        Some(b)
    }

    /// Records the state hash after applying the bundle of `tick` and queues
    /// a report to the room (reliable stream). Optional per-body hashes help
    /// locate a divergence.
    ///
    /// # Errors
    /// [`SessionError::Closed`]; [`SessionError::HashForUnappliedTick`] if
    /// that bundle was not delivered yet; [`SessionError::HashOutOfOrder`]
    /// unless ticks increase; [`SessionError::TooManyBodyHashes`].
    pub fn report_hash(
        &mut self,
        tick: u64,
        hash: u64,
        body_hashes: Option<Vec<u64>>,
    ) -> Result<(), SessionError> {
        if self.closed {
            return Err(SessionError::Closed);
        }
        if tick >= self.next_deliver || tick < self.start_tick {
            return Err(SessionError::HashForUnappliedTick { tick });
        }
        if let Some(last) = self.last_reported
            && tick <= last
        {
            return Err(SessionError::HashOutOfOrder { tick, last });
        }
        if let Some(b) = &body_hashes
            && b.len() > MAX_BODY_HASHES
        {
            return Err(SessionError::TooManyBodyHashes(b.len()));
        }
        self.last_reported = Some(tick);
        self.local_hashes.insert(tick, hash);
        self.reliable
            .push_back(ClientMessage::HashReport(HashReport {
                tick,
                hash,
                body_hashes,
            }));
        Ok(())
    }

    /// Queues the answer to a [`SessionEvent::Probe`] (reliable).
    ///
    /// # Errors
    /// [`SessionError::Closed`] after the session closed.
    pub fn reply_probe(&mut self, reply: crate::forensics::ProbeReply) -> Result<(), SessionError> {
        if self.closed {
            return Err(SessionError::Closed);
        }
        self.reliable.push_back(ClientMessage::ProbeReply(reply));
        Ok(())
    }

    /// Leaves the room: queues a leave message and closes the session.
    pub fn leave(&mut self) {
        if !self.closed {
            self.reliable.push_back(ClientMessage::Leave);
            self.closed = true;
        }
    }

    /// Next message to send: reliable messages first, then a pong, then one
    /// input datagram holding the unacknowledged inputs for ticks not known
    /// to be closed (at most [`MAX_INPUTS_PER_DATAGRAM`], oldest first) and
    /// the bundle ack.
    ///
    /// An input datagram is due after a submission, after each bundle
    /// datagram received (so acks flow and inputs are repeated even when the
    /// application pauses), and after a ping while inputs are unacknowledged
    /// (the lobby, where no bundles flow). It is built here, at send time, so
    /// it carries the freshest acks, and everything due between two polls
    /// coalesces into one datagram.
    pub fn poll_transmit(&mut self) -> Option<ClientMessage> {
        if let Some(m) = self.reliable.pop_front() {
            return Some(m);
        }
        if let Some(p) = self.pong.take() {
            return Some(ClientMessage::Pong(p));
        }
        if !self.input_dirty || self.closed {
            return None;
        }
        self.input_dirty = false;
        self.sent_since_timer = true;
        // Inputs for ticks whose bundle was delivered are closed: useless.
        // Of the rest, the oldest are the most urgent (nearest deadline);
        // newer ones follow as the acks advance.
        let first = self.first_unacked_input().max(self.next_deliver);
        let end = self
            .next_input_tick
            .min(first + MAX_INPUTS_PER_DATAGRAM as u64);
        let inputs: Vec<Vec<u8>> = (first..end)
            .map_while(|t| self.inputs.get(t).cloned())
            .collect();
        self.stats.input_datagrams += 1;
        Some(ClientMessage::Input(InputDatagram {
            slot: self.slot,
            ack_bundle: self.received_through,
            first_tick: first,
            inputs,
        }))
    }

    /// Next event for the application.
    pub fn poll_event(&mut self) -> Option<SessionEvent> {
        self.events.pop_front()
    }

    /// This client's slot.
    pub fn slot(&self) -> Slot {
        self.slot
    }

    /// The room's ticks per second.
    pub fn tick_rate(&self) -> u16 {
        self.tick_rate
    }

    /// The room's input delay in ticks.
    pub fn input_delay(&self) -> u16 {
        self.input_delay
    }

    /// Sends inputs `lead` ticks ahead of the room's clock instead of the
    /// room's input delay: a predicting client runs ahead by about a round
    /// trip, so that its inputs arrive before their ticks close while it
    /// shows their effect at once. Held between the input delay and the
    /// room's input window (less one); returns the lead kept.
    pub fn set_input_lead(&mut self, lead: u16) -> u16 {
        let max = self.input_window.saturating_sub(2).max(self.input_delay);
        self.input_lead = lead.clamp(self.input_delay, max);
        self.input_lead
    }

    /// Ticks ahead of the room's clock inputs are sent.
    pub fn input_lead(&self) -> u16 {
        self.input_lead
    }

    /// First tick this client takes part in.
    pub fn start_tick(&self) -> u64 {
        self.start_tick
    }

    /// The first bundle this session applies: `start_tick`, or for a player
    /// joining a running match the tick after its snapshot (bundles before
    /// `start_tick` are applied to catch up, and not reported).
    pub fn first_bundle(&self) -> u64 {
        self.first_bundle
    }

    /// Hash of the scene announced in the welcome.
    pub fn scene_hash(&self) -> u64 {
        self.scene_hash
    }

    /// Tick the next submitted input will be for.
    pub fn next_input_tick(&self) -> u64 {
        self.next_input_tick
    }

    /// Tick of the next bundle [`Session::poll_bundle`] will yield.
    pub fn next_bundle_tick(&self) -> u64 {
        self.next_deliver
    }

    /// Last tick the room acknowledged input for.
    pub fn input_ack(&self) -> Option<u64> {
        self.input_ack
    }

    /// Last tick up to which every bundle has been received.
    pub fn bundle_ack(&self) -> Option<u64> {
        self.received_through
    }

    /// The hash this client reported for `tick`, if still remembered.
    pub fn local_hash(&self, tick: u64) -> Option<u64> {
        self.local_hashes.get(tick).copied()
    }

    /// Whether the session has ended.
    pub fn is_closed(&self) -> bool {
        self.closed
    }

    /// Network counters.
    pub fn stats(&self) -> &SessionStats {
        &self.stats
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::message::{BundleDatagram, Ping, PlayerInput};

    fn welcome() -> Welcome {
        Welcome {
            slot: Slot(2),
            tick_rate: 60,
            input_delay: 3,
            input_window: 8,
            max_input_bytes: 16,
            start_tick: 0,
            scene_hash: 77,
            scene: vec![1, 2, 3],
            resume: None,
            rules: None,
            seed: 0,
            rejoin: None,
        }
    }

    fn bundle(tick: u64) -> TickBundle {
        TickBundle {
            tick,
            inputs: vec![PlayerInput {
                slot: Slot(2),
                input: vec![tick as u8],
                substituted: false,
            }],
        }
    }

    fn deliver(s: &mut Session, ticks: &[u64], ack_input: Option<u64>) {
        s.handle_message(
            Duration::ZERO,
            ServerMessage::Bundles(BundleDatagram {
                ack_input,
                bundles: ticks.iter().map(|&t| bundle(t)).collect(),
            }),
        )
        .unwrap();
    }

    #[test]
    fn pacing_allows_delay_plus_one_inputs_ahead_of_delivery() {
        let mut s = Session::new(&welcome()).unwrap();
        let mut ticks = Vec::new();
        while s.wants_input(Duration::ZERO) {
            ticks.push(s.submit_input(vec![0]).unwrap());
        }
        assert_eq!(ticks, vec![0, 1, 2, 3]);
        // Forcing past the pacing is allowed up to the room's window...
        for t in 4..8 {
            assert_eq!(s.submit_input(vec![0]), Ok(t));
        }
        // ...and no further.
        assert_eq!(
            s.submit_input(vec![0]),
            Err(SessionError::InputWindowFull { tick: 8, limit: 8 })
        );
        assert_eq!(
            s.submit_input(vec![0; 17]),
            Err(SessionError::InputTooLarge { len: 17, max: 16 })
        );
    }

    #[test]
    fn while_bundles_are_lost_the_local_clock_keeps_inputs_flowing() {
        let ms = Duration::from_millis;
        let mut s = Session::new(&welcome()).unwrap();
        deliver(&mut s, &[0], None);
        assert_eq!(s.poll_bundle().map(|b| b.tick), Some(0));
        let mut submitted = Vec::new();
        while s.wants_input(ms(0)) {
            submitted.push(s.submit_input(vec![0]).unwrap());
        }
        assert_eq!(submitted, vec![0, 1, 2, 3, 4]);
        // 50 ms later no bundle came, but three more ticks have closed.
        assert_eq!(s.estimated_room_tick(ms(50)), Some(3));
        while s.wants_input(ms(50)) {
            submitted.push(s.submit_input(vec![0]).unwrap());
        }
        assert_eq!(submitted, (0..8).collect::<Vec<_>>());
        // The next input (tick 8) is due when tick 4 closes: 4 periods in.
        s.handle_timeout(ms(60));
        assert_eq!(s.poll_timeout(), Some(Duration::from_nanos(66_666_664)));
        // Never beyond the room's window, however long the silence.
        while s.wants_input(ms(10_000)) {
            submitted.push(s.submit_input(vec![0]).unwrap());
        }
        assert_eq!(submitted.last(), Some(&8), "window: next bundle 1 + 8");
    }

    #[test]
    fn input_datagram_repeats_unacked_inputs_and_carries_the_bundle_ack() {
        let mut s = Session::new(&welcome()).unwrap();
        for i in 0..4u8 {
            s.submit_input(vec![i]).unwrap();
        }
        let Some(ClientMessage::Input(d)) = s.poll_transmit() else {
            panic!("expected an input datagram");
        };
        assert_eq!((d.first_tick, d.inputs.len(), d.ack_bundle), (0, 4, None));
        assert_eq!(s.poll_transmit(), None, "submissions coalesce");
        deliver(&mut s, &[0, 1], Some(1));
        s.submit_input(vec![4]).unwrap();
        let Some(ClientMessage::Input(d)) = s.poll_transmit() else {
            panic!("expected an input datagram");
        };
        assert_eq!(d.first_tick, 2);
        assert_eq!(d.inputs, vec![vec![2], vec![3], vec![4]]);
        assert_eq!(d.ack_bundle, Some(1));
    }

    #[test]
    fn bundles_are_delivered_in_order_once_despite_gaps_and_duplicates() {
        let mut s = Session::new(&welcome()).unwrap();
        deliver(&mut s, &[2, 3], None);
        assert_eq!(s.poll_bundle(), None);
        assert_eq!(s.bundle_ack(), None);
        deliver(&mut s, &[0, 2], None);
        assert_eq!(s.bundle_ack(), Some(0));
        assert_eq!(s.poll_bundle().map(|b| b.tick), Some(0));
        assert_eq!(s.poll_bundle(), None);
        deliver(&mut s, &[0, 1], None);
        assert_eq!(s.bundle_ack(), Some(3));
        let got: Vec<u64> = std::iter::from_fn(|| s.poll_bundle().map(|b| b.tick)).collect();
        assert_eq!(got, vec![1, 2, 3]);
        assert_eq!(s.stats().duplicate_bundles, 2);
        assert_eq!(s.stats().out_of_order_bundles, 2);
    }

    #[test]
    fn hash_reports_follow_delivery_and_increase() {
        let mut s = Session::new(&welcome()).unwrap();
        assert_eq!(
            s.report_hash(0, 9, None),
            Err(SessionError::HashForUnappliedTick { tick: 0 })
        );
        deliver(&mut s, &[0, 1], None);
        s.poll_bundle();
        s.poll_bundle();
        s.report_hash(1, 9, None).unwrap();
        assert_eq!(
            s.report_hash(0, 9, None),
            Err(SessionError::HashOutOfOrder { tick: 0, last: 1 })
        );
        assert_eq!(s.local_hash(1), Some(9));
        assert!(matches!(
            s.poll_transmit(),
            Some(ClientMessage::HashReport(HashReport {
                tick: 1,
                hash: 9,
                ..
            }))
        ));
    }

    #[test]
    fn ping_is_answered_and_close_ends_the_session() {
        let mut s = Session::new(&welcome()).unwrap();
        s.handle_message(Duration::ZERO, ServerMessage::Ping(Ping { nonce: 41 }))
            .unwrap();
        assert_eq!(
            s.poll_transmit(),
            Some(ClientMessage::Pong(Pong { nonce: 41 }))
        );
        let c = Close {
            reason: crate::message::CloseReason::Kicked,
            detail: String::new(),
        };
        s.handle_message(Duration::ZERO, ServerMessage::Close(c.clone()))
            .unwrap();
        assert_eq!(s.poll_event(), Some(SessionEvent::Closed(c)));
        assert!(!s.wants_input(Duration::ZERO));
        assert_eq!(s.submit_input(vec![]), Err(SessionError::Closed));
    }
}
