//! A client in a match, driven by the caller's loop ([`LiveClient::poll`]).

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use bytes::Bytes;
use lockstep_core::{Faults, World};
use lockstep_proto::{Channel, ClientMessage, ServerMessage, Session, SessionEvent, Slot};
use tokio::sync::mpsc;

use lockstep_net::{FrameError, Link, close_code};

use super::{ClientError, ClientEvent, ClientOptions, InputLatency, Traffic};
use crate::game::{BotView, GameRules, apply_tick};

/// What the network tasks hand to the poll.
pub(super) enum Incoming {
    Frame(Vec<u8>),
    Datagram(Vec<u8>),
    /// The stream ended cleanly (`None`) or failed.
    StreamEnded(Option<FrameError>),
}

/// What the poll hands to the writer task.
pub(super) enum Outgoing {
    Frame(Vec<u8>),
    Finish,
}

/// One tick a poll applied.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AppliedTick {
    /// The tick.
    pub tick: u64,
    /// The state hash after it (reported to the server).
    pub hash: u64,
    /// Whether the room substituted this client's own input.
    pub own_input_substituted: bool,
    /// Faults the step raised.
    pub faults: Faults,
    /// When it was applied.
    pub applied_at: Instant,
}

/// What one [`LiveClient::poll`] did.
#[derive(Clone, Debug, Default)]
pub struct Polled {
    /// The confirmed ticks applied, in order (none if no bundle was
    /// ready).
    pub ticks: Vec<AppliedTick>,
    /// Room events seen (desync notices, the close).
    pub events: Vec<ClientEvent>,
    /// Predicting: the predicted ticks this poll threw away and simulated
    /// again because a confirmed tick differed from its prediction.
    pub rollback: Option<super::predict::Rollback>,
    /// Predicting: the tick the predicted world is at (its state is the
    /// one after this tick).
    pub predicted_tick: Option<u64>,
}

/// A client in a match, driven by the caller's loop: [`poll`](Self::poll)
/// does everything due now without blocking (reads what arrived, submits
/// the local input, applies the ready bundles through the rules, steps,
/// reports hashes) and returns; [`world`](Self::world) is then the world to
/// render. Network I/O runs on tokio tasks started by [`Client::start`](super::Client::start).
pub struct LiveClient {
    pub(super) endpoint: quinn::Endpoint,
    pub(super) connection: Link,
    pub(super) session: Session,
    pub(super) world: World,
    pub(super) rules: Box<dyn GameRules>,
    pub(super) options: ClientOptions,
    pub(super) base: Instant,
    pub(super) incoming: mpsc::UnboundedReceiver<Incoming>,
    pub(super) buffered: VecDeque<Incoming>,
    pub(super) outgoing: mpsc::UnboundedSender<Outgoing>,
    pub(super) tasks: Vec<tokio::task::JoinHandle<()>>,
    pub(super) writer: Option<tokio::task::JoinHandle<Result<(), FrameError>>>,
    pub(super) traffic: Traffic,
    pub(super) ticks_applied: u64,
    pub(super) next_tick: u64,
    pub(super) stream_ended: Option<String>,
    pub(super) left: bool,
    pub(super) history: super::forensics::History,
    pub(super) predictor: Option<super::predict::Predictor>,
    /// Own inputs chosen, by tick, with when: for the latency figures.
    pub(super) chosen_at: VecDeque<(u64, Instant, bool)>,
    pub(super) latency: InputLatency,
}

impl std::fmt::Debug for LiveClient {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LiveClient")
            .field("slot", &self.session.slot())
            .field("next_tick", &self.next_tick)
            .finish_non_exhaustive()
    }
}

impl LiveClient {
    /// This client's slot.
    pub fn slot(&self) -> Slot {
        self.session.slot()
    }

    /// The world after the last applied tick: read it to render.
    pub fn world(&self) -> &World {
        &self.world
    }

    /// The lockstep session (timing parameters, counters).
    pub fn session(&self) -> &Session {
        &self.session
    }

    /// The rules after the last applied tick: a frame loop reads the
    /// game's own state from them, typed, with
    /// `live.rules().downcast_ref::<MyRules>()` (or from
    /// [`World::game_state`]).
    pub fn rules(&self) -> &dyn GameRules {
        &*self.rules
    }

    /// The world to draw: predicting, the predicted present (after
    /// [`Polled::predicted_tick`]); otherwise the confirmed world
    /// ([`LiveClient::world`]).
    pub fn predicted_world(&self) -> &World {
        self.predictor.as_ref().map_or(&self.world, |p| p.world())
    }

    /// The predicted world's rules (the confirmed ones when not
    /// predicting).
    pub fn predicted_rules(&self) -> &dyn GameRules {
        self.predictor.as_ref().map_or(&*self.rules, |p| p.rules())
    }

    /// Whether this client predicts.
    pub fn is_predicting(&self) -> bool {
        self.predictor.is_some()
    }

    /// What prediction did so far (zeros when not predicting).
    pub fn prediction_stats(&self) -> super::predict::PredictionStats {
        self.predictor
            .as_ref()
            .map_or_else(Default::default, |p| p.stats())
    }

    /// The next tick to apply.
    pub fn next_tick(&self) -> u64 {
        self.next_tick
    }

    /// Ticks applied so far.
    pub fn ticks_applied(&self) -> u64 {
        self.ticks_applied
    }

    /// Whether the server ended the session.
    pub fn is_closed(&self) -> bool {
        self.session.is_closed()
    }

    /// Whether this client left (by [`leave`](Self::leave) or
    /// `max_ticks`).
    pub fn has_left(&self) -> bool {
        self.left
    }

    /// Traffic counters so far (UDP totals from quinn).
    pub fn traffic(&self) -> Traffic {
        let stats = self.connection.stats();
        Traffic {
            udp_bytes_sent: stats.udp_tx.bytes,
            udp_bytes_received: stats.udp_rx.bytes,
            ..self.traffic
        }
    }

    /// When the session next needs a poll even if nothing arrives (time
    /// since [`Client::start`](super::Client::start)).
    pub fn poll_timeout(&self) -> Option<Duration> {
        self.session.poll_timeout()
    }

    /// Does everything due now, without blocking: handles what arrived,
    /// submits the local input (`input(tick)`) for every tick due, applies
    /// every bundle ready through the rules, steps, reports the hashes, and
    /// returns the ticks applied and the events seen.
    ///
    /// # Errors
    /// [`ClientError`] if the server sent garbage or the connection is
    /// lost (a close by the server is an event, not an error).
    pub fn poll(&mut self, mut input: impl FnMut(u64) -> Vec<u8>) -> Result<Polled, ClientError> {
        self.poll_seeing(|view| input(view.tick))
    }

    /// [`poll`](Self::poll) with an input that sees the world, the rules
    /// and the slot ([`BotView`]): what a bot that plays, or a game's
    /// assist, needs.
    ///
    /// # Errors
    /// As [`poll`](Self::poll).
    pub fn poll_seeing(
        &mut self,
        mut input: impl FnMut(&BotView<'_>) -> Vec<u8>,
    ) -> Result<Polled, ClientError> {
        let mut out = Polled::default();
        let result = self.poll_inner(&mut input, &mut out);
        let mut answered = false;
        while let Some(ev) = self.session.poll_event() {
            out.events.push(match ev {
                SessionEvent::Desync { notice, local_hash } => {
                    ClientEvent::Desync { notice, local_hash }
                }
                SessionEvent::Closed(c) => ClientEvent::Closed(c),
                SessionEvent::DesyncLocated(r) => ClientEvent::DesyncLocated(r),
                SessionEvent::Probe(p) => {
                    let reply = self.history.answer(&p);
                    #[cfg(feature = "test-hooks")]
                    let reply = crate::testing::hook_reply(reply, &self.options);
                    answered |= self.session.reply_probe(reply).is_ok();
                    continue;
                }
            });
        }
        let result = match result {
            Ok(()) if answered => self.flush(),
            r => r,
        };
        result.map(|()| out)
    }

    fn poll_inner(
        &mut self,
        input: &mut impl FnMut(&BotView<'_>) -> Vec<u8>,
        out: &mut Polled,
    ) -> Result<(), ClientError> {
        while let Some(item) = self
            .buffered
            .pop_front()
            .or_else(|| self.incoming.try_recv().ok())
        {
            match item {
                Incoming::Frame(bytes) => self.on_bytes(&bytes, Channel::Reliable)?,
                Incoming::Datagram(bytes) => self.on_bytes(&bytes, Channel::Datagram)?,
                Incoming::StreamEnded(e) => {
                    self.stream_ended = Some(match (e, self.connection.close_reason()) {
                        (_, Some(r)) => r,
                        (Some(e), None) => e.to_string(),
                        (None, None) => "the server ended the stream".into(),
                    });
                }
            }
        }
        if self.session.is_closed() || self.left {
            return Ok(());
        }
        if let Some(reason) = &self.stream_ended {
            return Err(ClientError::ConnectionLost(reason.clone()));
        }
        let now = self.base.elapsed();
        if self.session.poll_timeout().is_some_and(|t| t <= now) {
            self.session.handle_timeout(now);
        }
        if self.predictor.is_some() {
            // Inputs must reach the room before their ticks close: lead
            // its clock (estimated from the bundles, a one-way trip late)
            // by the round trip and two ticks more.
            let period = 1.0 / f64::from(self.session.tick_rate().max(1));
            let rtt = self.connection.rtt().as_secs_f64();
            let lead = (rtt / period).ceil() as u64 + 2;
            self.session
                .set_input_lead(u16::try_from(lead).unwrap_or(u16::MAX));
        }
        while self.session.wants_input(now) {
            let tick = self.session.next_input_tick();
            // A predicting client chooses from the predicted present.
            let (world, rules) = match &self.predictor {
                Some(p) => (p.world(), p.rules()),
                None => (&self.world, &*self.rules),
            };
            let view = BotView {
                world,
                rules,
                slot: self.session.slot().0,
                tick,
            };
            let bytes = input(&view);
            if let Some(p) = &mut self.predictor {
                p.own_input(tick, &bytes);
            }
            self.chosen_at.push_back((tick, Instant::now(), false));
            self.session.submit_input(bytes)?;
        }
        // Inputs first: they are the time-critical part.
        self.flush()?;
        let slot = self.session.slot();
        while self
            .options
            .max_ticks
            .is_none_or(|m| self.ticks_applied < m)
        {
            let Some(bundle) = self.session.poll_bundle() else {
                break;
            };
            let applied_at = Instant::now();
            let own_input_substituted = bundle
                .inputs
                .iter()
                .any(|p| p.slot == slot && p.substituted);
            let inputs: Vec<(u8, &[u8])> = bundle
                .inputs
                .iter()
                .map(|p| (p.slot.0, p.input.as_slice()))
                .collect();
            let step = apply_tick(&mut self.world, &mut *self.rules, bundle.tick, &inputs)
                .map_err(|e| ClientError::Game(e.to_string()))?;
            let hash = self.world.state_hash();
            if let Some(p) = &mut self.predictor {
                p.confirmed(&bundle, hash);
            }
            while self.chosen_at.front().is_some_and(|c| c.0 <= bundle.tick) {
                if let Some((t, at, _)) = self.chosen_at.pop_front()
                    && t == bundle.tick
                {
                    self.latency
                        .confirmed
                        .add(applied_at.saturating_duration_since(at));
                }
            }
            self.history.record(bundle.tick, &self.world);
            let every = self.options.body_hashes_every;
            let bodies = (every > 0 && bundle.tick.is_multiple_of(every)).then(|| {
                self.world
                    .body_hashes()
                    .into_iter()
                    .map(|(_, h)| h)
                    .collect()
            });
            // A player that joined a running match catches up on the ticks
            // before its start without reporting them (it was not in them).
            if bundle.tick >= self.session.start_tick() {
                #[cfg(feature = "test-hooks")]
                let hash = hash ^ u64::from(self.options.lie_on_even_ticks && bundle.tick % 2 == 0);
                self.session.report_hash(bundle.tick, hash, bodies)?;
            }
            self.ticks_applied += 1;
            self.next_tick = bundle.tick + 1;
            out.ticks.push(AppliedTick {
                tick: bundle.tick,
                hash,
                own_input_substituted,
                faults: step.faults,
                applied_at,
            });
        }
        if let Some(p) = &mut self.predictor {
            // To the tick of the last input chosen, which the room has not
            // closed yet (with an input delay, a few ticks past its clock).
            let target = self.session.next_input_tick().saturating_sub(1);
            out.rollback = p
                .advance(&self.world, self.next_tick, target)
                .map_err(|e| ClientError::Game(e.to_string()))?;
            out.predicted_tick = p.next().checked_sub(1);
            let shown = Instant::now();
            for c in self.chosen_at.iter_mut().filter(|c| !c.2 && c.0 < p.next()) {
                c.2 = true;
                self.latency
                    .predicted
                    .add(shown.saturating_duration_since(c.1));
            }
        }
        if self
            .options
            .max_ticks
            .is_some_and(|m| self.ticks_applied >= m)
        {
            self.leave();
        }
        self.flush()
    }

    /// Leaves the match (tells the server, ends the stream). Later polls
    /// do nothing.
    pub fn leave(&mut self) {
        if self.left {
            return;
        }
        self.left = true;
        self.session.leave();
        let _ = self.flush();
    }

    /// Waits until something arrives or the session's next timeout, for a
    /// loop that has nothing else to do between polls.
    pub async fn wait(&mut self) {
        let wake = self
            .session
            .poll_timeout()
            .unwrap_or_else(|| self.base.elapsed() + Duration::from_millis(100));
        let wake = tokio::time::Instant::from_std(self.base + wake);
        if self.stream_ended.is_some() && self.buffered.is_empty() {
            tokio::time::sleep_until(wake).await;
            return;
        }
        tokio::select! {
            item = self.incoming.recv() => match item {
                Some(i) => self.buffered.push_back(i),
                None => tokio::time::sleep_until(wake).await,
            },
            () = tokio::time::sleep_until(wake) => {}
        }
    }

    /// Ends the stream, closes the connection and waits (at most 2 s) for
    /// the endpoint to drain.
    pub async fn shutdown(mut self) {
        let _ = self.outgoing.send(Outgoing::Finish);
        if let Some(w) = self.writer.take() {
            let _ = tokio::time::timeout(Duration::from_secs(1), w).await;
        }
        let endpoint = self.endpoint.clone();
        drop(self);
        let _ = tokio::time::timeout(Duration::from_secs(2), endpoint.wait_idle()).await;
    }

    fn on_bytes(&mut self, bytes: &[u8], channel: Channel) -> Result<(), ClientError> {
        let msg = ServerMessage::decode(bytes)?;
        if msg.channel() != channel {
            return Err(ClientError::Unexpected(msg.kind()));
        }
        if channel == Channel::Datagram {
            self.traffic.datagrams_received += 1;
            self.traffic.datagram_bytes_received += bytes.len() as u64;
            self.traffic.max_datagram_received =
                self.traffic.max_datagram_received.max(bytes.len());
        }
        self.session.handle_message(self.base.elapsed(), msg)?;
        Ok(())
    }

    /// Sends everything the session queued: stream frames in order (through
    /// the writer task), datagrams at once.
    fn flush(&mut self) -> Result<(), ClientError> {
        while let Some(msg) = self.session.poll_transmit() {
            let bytes = match msg.encode() {
                Ok(b) => b,
                // The session never builds an out-of-bounds message.
                Err(e) => return Err(ClientError::Connect(format!("encode: {e}"))),
            };
            match msg.channel() {
                Channel::Reliable => {
                    self.traffic.frames_sent += 1;
                    self.traffic.frame_bytes_sent += bytes.len() as u64 + 4;
                    if self.outgoing.send(Outgoing::Frame(bytes)).is_err() {
                        return Err(ClientError::ConnectionLost(
                            "the stream writer stopped".into(),
                        ));
                    }
                }
                Channel::Datagram => {
                    self.traffic.datagrams_sent += 1;
                    self.traffic.datagram_bytes_sent += bytes.len() as u64;
                    self.traffic.max_datagram_sent =
                        self.traffic.max_datagram_sent.max(bytes.len());
                    if let Err(e) = self.connection.send_datagram(Bytes::from(bytes)) {
                        return Err(ClientError::ConnectionLost(e.to_string()));
                    }
                }
            }
            if matches!(msg, ClientMessage::Leave) {
                let _ = self.outgoing.send(Outgoing::Finish);
            }
        }
        Ok(())
    }
}

impl Drop for LiveClient {
    fn drop(&mut self) {
        self.connection.close(close_code::NORMAL, b"client done");
        for t in &self.tasks {
            t.abort();
        }
        if let Some(w) = &self.writer {
            w.abort();
        }
    }
}
