//! One player's connection: join, build the world, then the lockstep loop.

use std::future::Future;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use bytes::Bytes;
use lockstep_core::math::Scalar;
use lockstep_core::{BodyKind, Faults, Vec3, World};
use lockstep_proto::{
    Channel, ClientMessage, Close, CloseReason, DecodeError, DesyncNotice, ServerMessage, Session,
    SessionError, SessionEvent, Slot, Welcome,
};
use thiserror::Error;
use tokio::sync::mpsc;

use super::close_code;
use super::frame::{FrameError, read_frame, write_frame};
use super::tls::{TlsError, client_config, load_certs};
use crate::game::{DemoGame, GameRules};

/// How to reach the server and what to do there.
#[derive(Clone, Debug)]
pub struct ClientOptions {
    /// The server's UDP address.
    pub server: SocketAddr,
    /// The name the server's certificate is checked against (`localhost`
    /// for the dev certificate).
    pub server_name: String,
    /// PEM file of the certificate (or CA) to trust: the dev certificate
    /// the server wrote, or a real one.
    pub cert: PathBuf,
    /// Room to join.
    pub room: String,
    /// Display name.
    pub player_name: String,
    /// Leave after applying this many ticks (`None`: play until the server
    /// closes the match or `stop` fires).
    pub max_ticks: Option<u64>,
    /// Also send every body's hash with each tick's report. Off by default:
    /// 8 bytes per body per tick (about 55 kB/s upstream for 100 bodies at
    /// 60 Hz, twenty times the rest of the traffic) for data the room does
    /// not compare yet; the state hash alone finds the tick of a desync.
    pub body_hashes: bool,
    /// Test hook: at this tick, before stepping, nudge the first dynamic
    /// body's linear velocity by one ulp (`Scalar::DELTA` on x), so this
    /// client diverges from the others exactly there.
    pub diverge_at: Option<u64>,
    /// How long connecting and joining may take.
    pub connect_timeout: Duration,
}

impl ClientOptions {
    /// Options for the server at `server` trusting `cert`, joining `room`
    /// as `player_name`, with the defaults of each field.
    pub fn new(
        server: SocketAddr,
        cert: impl Into<PathBuf>,
        room: impl Into<String>,
        player_name: impl Into<String>,
    ) -> Self {
        Self {
            server,
            server_name: "localhost".into(),
            cert: cert.into(),
            room: room.into(),
            player_name: player_name.into(),
            max_ticks: None,
            body_hashes: false,
            diverge_at: None,
            connect_timeout: Duration::from_secs(10),
        }
    }
}

/// Why a client stopped with an error.
#[derive(Debug, Error)]
pub enum ClientError {
    /// The certificate or TLS settings are unusable.
    #[error("{0}")]
    Tls(#[from] TlsError),
    /// The UDP socket could not be opened.
    #[error("socket: {0}")]
    Socket(#[source] std::io::Error),
    /// Connecting failed (address, handshake, certificate, ALPN).
    #[error("connect: {0}")]
    Connect(String),
    /// Nothing arrived in time while connecting or joining.
    #[error("timed out {0}")]
    Timeout(&'static str),
    /// The server refused the join.
    #[error("refused by the server: {reason:?}: {detail}")]
    Refused {
        /// The protocol reason.
        reason: CloseReason,
        /// The server's detail.
        detail: String,
    },
    /// The connection failed or the server closed it without a close
    /// message.
    #[error("connection lost: {0}")]
    ConnectionLost(String),
    /// A stream frame could not be read or written.
    #[error("{0}")]
    Frame(#[from] FrameError),
    /// The server sent bytes that are not a valid message.
    #[error("bad message from the server: {0}")]
    Decode(#[from] DecodeError),
    /// The server sent a message that makes no sense here.
    #[error("unexpected {0} from the server")]
    Unexpected(&'static str),
    /// The welcome could not start a session.
    #[error("session: {0}")]
    Session(#[from] SessionError),
    /// The scene in the welcome does not build.
    #[error("scene: {0}")]
    Scene(String),
    /// The scene built, but its hash is not the one the server announced.
    #[error("scene hash {got:016x}, the server announced {expected:016x}")]
    SceneHashMismatch {
        /// Announced.
        expected: u64,
        /// Computed.
        got: u64,
    },
    /// The game rules refused the world.
    #[error("game: {0}")]
    Game(String),
}

/// Something the application should know about while playing.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ClientEvent {
    /// The room found a hash mismatch.
    Desync {
        /// The room's notice (tick, every player's hash, verdict).
        notice: DesyncNotice,
        /// This client's own hash for that tick, if still remembered.
        local_hash: Option<u64>,
    },
    /// A step raised an arithmetic fault (the scene left the fixed-point
    /// range): the hashes from here on still agree between peers, but the
    /// physics is no longer meaningful.
    Fault {
        /// The tick.
        tick: u64,
        /// Which faults.
        faults: Faults,
    },
    /// The server ended the session.
    Closed(Close),
}

/// Bytes and datagrams one connection moved, for bandwidth figures.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Traffic {
    /// UDP payload bytes sent (QUIC overhead, acks and retransmissions
    /// included), from quinn's counters.
    pub udp_bytes_sent: u64,
    /// UDP payload bytes received.
    pub udp_bytes_received: u64,
    /// Protocol datagrams sent.
    pub datagrams_sent: u64,
    /// Their protocol bytes (encoded messages, without QUIC framing).
    pub datagram_bytes_sent: u64,
    /// Largest protocol datagram sent.
    pub max_datagram_sent: usize,
    /// Protocol datagrams received.
    pub datagrams_received: u64,
    /// Their protocol bytes.
    pub datagram_bytes_received: u64,
    /// Largest protocol datagram received.
    pub max_datagram_received: usize,
    /// Stream frames sent, and their bytes (length prefix included).
    pub frames_sent: u64,
    /// Bytes of the frames sent.
    pub frame_bytes_sent: u64,
}

/// What a client did, returned by [`Client::play`].
#[derive(Clone, Debug)]
pub struct ClientReport {
    /// This client's slot.
    pub slot: Slot,
    /// The first tick it took part in.
    pub start_tick: u64,
    /// Ticks applied (bundles stepped).
    pub ticks_applied: u64,
    /// Every state hash reported, in tick order from `start_tick`.
    pub hashes: Vec<u64>,
    /// When each tick's bundle became applicable (in order, so a bundle
    /// waiting for a missing earlier one counts as late too); index is
    /// `tick - start_tick`. Compare with the server's tick deadlines.
    pub delivered_at: Vec<Instant>,
    /// Ticks where this client's own input was substituted by the room.
    pub own_inputs_substituted: u64,
    /// Every event seen, in order.
    pub events: Vec<ClientEvent>,
    /// The server's close message, if the server ended the session.
    pub close: Option<Close>,
    /// quinn's round-trip estimate at the end.
    pub rtt: Duration,
    /// Traffic counters.
    pub traffic: Traffic,
    /// From the welcome to the end of play.
    pub played_for: Duration,
}

impl ClientReport {
    /// The desync notices received, in order.
    pub fn desyncs(&self) -> impl Iterator<Item = &DesyncNotice> {
        self.events.iter().filter_map(|e| match e {
            ClientEvent::Desync { notice, .. } => Some(notice),
            _ => None,
        })
    }
}

/// A joined client, ready to [`play`](Client::play).
pub struct Client {
    endpoint: quinn::Endpoint,
    connection: quinn::Connection,
    send: quinn::SendStream,
    recv: quinn::RecvStream,
    session: Session,
    world: World,
    game: Box<dyn GameRules>,
    options: ClientOptions,
    traffic: Traffic,
}

impl std::fmt::Debug for Client {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Client")
            .field("slot", &self.session.slot())
            .field("remote", &self.connection.remote_address())
            .finish_non_exhaustive()
    }
}

impl Client {
    /// Connects, joins `options.room`, waits for the welcome, and builds the
    /// world from its scene, checking the scene hash.
    ///
    /// # Errors
    /// [`ClientError`]: certificate, connection, refusal, timeout, or a scene
    /// that does not build or hash as announced.
    pub async fn connect(options: ClientOptions) -> Result<Client, ClientError> {
        let roots = load_certs(&options.cert)?;
        let config = client_config(&roots)?;
        let bind: SocketAddr = if options.server.is_ipv6() {
            "[::]:0".parse().expect("literal address")
        } else {
            "0.0.0.0:0".parse().expect("literal address")
        };
        let mut endpoint = quinn::Endpoint::client(bind).map_err(ClientError::Socket)?;
        endpoint.set_default_client_config(config);
        let timeout = options.connect_timeout;
        let joined = tokio::time::timeout(timeout, async {
            let connecting = endpoint
                .connect(options.server, &options.server_name)
                .map_err(|e| ClientError::Connect(e.to_string()))?;
            let connection = connecting
                .await
                .map_err(|e| ClientError::Connect(e.to_string()))?;
            let (mut send, mut recv) = connection
                .open_bi()
                .await
                .map_err(|e| ClientError::ConnectionLost(e.to_string()))?;
            let join = Session::join_message(&options.room, &options.player_name);
            let bytes = join
                .encode()
                .map_err(|e| ClientError::Connect(e.to_string()))?;
            write_frame(&mut send, &bytes).await?;
            let welcome = read_welcome(&mut recv).await?;
            Ok::<_, ClientError>((connection, send, recv, welcome))
        })
        .await;
        let (connection, send, recv, welcome) = match joined {
            Ok(Ok(v)) => v,
            Ok(Err(e)) => {
                endpoint.close(close_code::NORMAL.into(), b"join failed");
                return Err(e);
            }
            Err(_) => {
                endpoint.close(close_code::NORMAL.into(), b"join timed out");
                return Err(ClientError::Timeout("joining"));
            }
        };
        let session = Session::new(&welcome)?;
        let text = std::str::from_utf8(&welcome.scene)
            .map_err(|e| ClientError::Scene(format!("scene is not UTF-8: {e}")))?;
        let world = lockstep_core::scene::load_world(text, "welcome scene")
            .map_err(|e| ClientError::Scene(e.to_string()))?;
        let got = world.state_hash();
        if got != welcome.scene_hash {
            connection.close(close_code::REFUSED.into(), b"scene hash mismatch");
            return Err(ClientError::SceneHashMismatch {
                expected: welcome.scene_hash,
                got,
            });
        }
        let game = DemoGame::new(&world).map_err(|e| ClientError::Game(e.to_string()))?;
        Ok(Client {
            endpoint,
            connection,
            send,
            recv,
            session,
            world,
            game: Box::new(game),
            options,
            traffic: Traffic::default(),
        })
    }

    /// This client's slot.
    pub fn slot(&self) -> Slot {
        self.session.slot()
    }

    /// The world as simulated so far.
    pub fn world(&self) -> &World {
        &self.world
    }

    /// The lockstep session (timing parameters, counters).
    pub fn session(&self) -> &Session {
        &self.session
    }

    /// Plays until the server closes the session, `options.max_ticks` ticks
    /// were applied, or `stop` completes (then the client leaves). `input`
    /// gives the local input for a tick; `on_event` sees every event as it
    /// happens. The connection is closed and the endpoint drained before
    /// returning.
    ///
    /// # Errors
    /// [`ClientError`] if the connection fails or the server sends garbage;
    /// a close by the server is not an error (it is in the report).
    pub async fn play(
        mut self,
        mut input: impl FnMut(u64) -> Vec<u8> + Send,
        mut on_event: impl FnMut(&ClientEvent) + Send,
        stop: impl Future<Output = ()> + Send,
    ) -> Result<ClientReport, ClientError> {
        let base = Instant::now();
        let started = base;
        let mut report = ClientReport {
            slot: self.session.slot(),
            start_tick: self.session.start_tick(),
            ticks_applied: 0,
            hashes: Vec::new(),
            delivered_at: Vec::new(),
            own_inputs_substituted: 0,
            events: Vec::new(),
            close: None,
            rtt: Duration::ZERO,
            traffic: Traffic::default(),
            played_for: Duration::ZERO,
        };
        // The stream is read by its own task so that a frame is never cut in
        // half by the select below.
        let (frames_tx, mut frames_rx) = mpsc::channel::<Result<Vec<u8>, FrameError>>(256);
        let mut recv = self.recv;
        let reader = tokio::spawn(async move {
            loop {
                let r = read_frame(&mut recv).await;
                let end = !matches!(r, Ok(Some(_)));
                let item = match r {
                    Ok(Some(bytes)) => Ok(bytes),
                    Ok(None) => Err(FrameError::Truncated),
                    Err(e) => Err(e),
                };
                if frames_tx.send(item).await.is_err() || end {
                    break;
                }
            }
        });
        let mut ctx = Loop {
            session: self.session,
            world: self.world,
            game: self.game,
            send: self.send,
            connection: self.connection.clone(),
            options: self.options,
            traffic: &mut self.traffic,
        };
        tokio::pin!(stop);
        let mut result: Result<(), ClientError> = Ok(());
        let mut leaving = false;
        loop {
            let now = base.elapsed();
            if let Err(e) = ctx.step_all(now, &mut input, &mut report).await {
                result = Err(e);
                break;
            }
            drain_events(&mut ctx.session, &mut report, &mut on_event);
            if ctx.session.is_closed() {
                break;
            }
            if let Some(max) = ctx.options.max_ticks
                && report.ticks_applied >= max
            {
                leaving = true;
            }
            if leaving {
                ctx.session.leave();
                let _ = ctx.flush().await;
                break;
            }
            let wake = ctx
                .session
                .poll_timeout()
                .map_or(now + Duration::from_millis(100), |t| t);
            let wake = tokio::time::Instant::from_std(base + wake);
            tokio::select! {
                biased;
                () = &mut stop => leaving = true,
                frame = frames_rx.recv() => {
                    let r = match frame {
                        Some(Ok(bytes)) => ctx.on_bytes(base.elapsed(), &bytes, Channel::Reliable),
                        Some(Err(FrameError::Truncated)) | None => {
                            Err(ClientError::ConnectionLost(ctx.lost_reason()))
                        }
                        Some(Err(e)) => Err(e.into()),
                    };
                    if let Err(e) = r {
                        result = Err(e);
                        break;
                    }
                }
                datagram = ctx.connection.read_datagram() => match datagram {
                    Ok(bytes) => {
                        if let Err(e) = ctx.on_bytes(base.elapsed(), &bytes, Channel::Datagram) {
                            result = Err(e);
                            break;
                        }
                    }
                    Err(e) => {
                        // The close message may still be queued in the
                        // stream reader: give it a moment to arrive.
                        result = ctx.drain_close(&mut frames_rx, base, e).await;
                        break;
                    }
                },
                () = tokio::time::sleep_until(wake) => ctx.session.handle_timeout(base.elapsed()),
            }
        }
        // Collect what the session said last (the close arrives as an event).
        drain_events(&mut ctx.session, &mut report, &mut on_event);
        if report.close.is_some() && matches!(result, Err(ClientError::ConnectionLost(_))) {
            result = Ok(());
        }
        let stats = ctx.connection.stats();
        report.rtt = ctx.connection.rtt();
        ctx.traffic.udp_bytes_sent = stats.udp_tx.bytes;
        ctx.traffic.udp_bytes_received = stats.udp_rx.bytes;
        report.traffic = *ctx.traffic;
        report.played_for = started.elapsed();
        let _ = ctx.send.finish();
        ctx.connection
            .close(close_code::NORMAL.into(), b"client done");
        reader.abort();
        let _ = tokio::time::timeout(Duration::from_secs(2), self.endpoint.wait_idle()).await;
        result.map(|()| report)
    }
}

async fn read_welcome(recv: &mut quinn::RecvStream) -> Result<Welcome, ClientError> {
    let Some(bytes) = read_frame(recv).await? else {
        return Err(ClientError::ConnectionLost(
            "the server ended the stream before welcoming".into(),
        ));
    };
    match ServerMessage::decode(&bytes)? {
        ServerMessage::Welcome(w) => Ok(w),
        ServerMessage::Close(c) => Err(ClientError::Refused {
            reason: c.reason,
            detail: c.detail,
        }),
        other => Err(ClientError::Unexpected(other.kind())),
    }
}

/// The state of the play loop, apart from the report.
struct Loop<'a> {
    session: Session,
    world: World,
    game: Box<dyn GameRules>,
    send: quinn::SendStream,
    connection: quinn::Connection,
    options: ClientOptions,
    traffic: &'a mut Traffic,
}

impl Loop<'_> {
    fn lost_reason(&self) -> String {
        match self.connection.close_reason() {
            Some(r) => r.to_string(),
            None => "the server ended the stream".into(),
        }
    }

    /// Waits briefly for a close message after the connection failed.
    async fn drain_close(
        &mut self,
        frames: &mut mpsc::Receiver<Result<Vec<u8>, FrameError>>,
        base: Instant,
        err: quinn::ConnectionError,
    ) -> Result<(), ClientError> {
        let deadline = tokio::time::Instant::now() + Duration::from_millis(200);
        while let Ok(Some(Ok(bytes))) = tokio::time::timeout_at(deadline, frames.recv()).await {
            self.on_bytes(base.elapsed(), &bytes, Channel::Reliable)?;
        }
        if self.session.is_closed() {
            Ok(())
        } else {
            Err(ClientError::ConnectionLost(err.to_string()))
        }
    }

    fn on_bytes(
        &mut self,
        now: Duration,
        bytes: &[u8],
        channel: Channel,
    ) -> Result<(), ClientError> {
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
        self.session.handle_message(now, msg)?;
        Ok(())
    }

    /// Submits due inputs, applies every deliverable bundle, and sends what
    /// the session produced.
    async fn step_all(
        &mut self,
        now: Duration,
        input: &mut (impl FnMut(u64) -> Vec<u8> + Send),
        report: &mut ClientReport,
    ) -> Result<(), ClientError> {
        while self.session.wants_input(now) {
            let tick = self.session.next_input_tick();
            self.session.submit_input(input(tick))?;
        }
        // Inputs first: they are the time-critical part.
        self.flush().await?;
        let slot = self.session.slot();
        while let Some(bundle) = self.session.poll_bundle() {
            report.delivered_at.push(Instant::now());
            if bundle
                .inputs
                .iter()
                .any(|p| p.slot == slot && p.substituted)
            {
                report.own_inputs_substituted += 1;
            }
            if self.options.diverge_at == Some(bundle.tick) {
                nudge_one_body(&mut self.world);
            }
            let inputs: Vec<(u8, &[u8])> = bundle
                .inputs
                .iter()
                .map(|p| (p.slot.0, p.input.as_slice()))
                .collect();
            self.game
                .apply_inputs(&mut self.world, bundle.tick, &inputs);
            let step = self.world.step();
            if !step.faults.is_empty() {
                report.events.push(ClientEvent::Fault {
                    tick: bundle.tick,
                    faults: step.faults,
                });
            }
            let hash = self.world.state_hash();
            let bodies = self.options.body_hashes.then(|| {
                self.world
                    .body_hashes()
                    .into_iter()
                    .map(|(_, h)| h)
                    .collect()
            });
            self.session.report_hash(bundle.tick, hash, bodies)?;
            report.hashes.push(hash);
            report.ticks_applied += 1;
            if self
                .options
                .max_ticks
                .is_some_and(|m| report.ticks_applied >= m)
            {
                break;
            }
        }
        self.flush().await
    }

    /// Sends everything the session queued: stream frames in order,
    /// datagrams as they come.
    async fn flush(&mut self) -> Result<(), ClientError> {
        while let Some(msg) = self.session.poll_transmit() {
            let bytes = match msg.encode() {
                Ok(b) => b,
                // The session never builds an out-of-bounds message.
                Err(e) => return Err(ClientError::Connect(format!("encode: {e}"))),
            };
            match msg.channel() {
                Channel::Reliable => {
                    write_frame(&mut self.send, &bytes).await?;
                    self.traffic.frames_sent += 1;
                    self.traffic.frame_bytes_sent += bytes.len() as u64 + 4;
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
                let _ = self.send.finish();
            }
        }
        Ok(())
    }
}

/// The divergence hook: one ulp more x velocity on the first dynamic body.
fn nudge_one_body(world: &mut World) {
    let target = world
        .body_handles()
        .find(|&h| world.body(h).is_ok_and(|b| b.kind() == BodyKind::Dynamic));
    if let Some(h) = target
        && let Ok(b) = world.body(h)
    {
        let v = b.linear_velocity();
        let nudged = Vec3::new(v.x + Scalar::DELTA, v.y, v.z);
        let _ = world.set_linear_velocity(h, nudged);
    }
}

/// Hands every pending session event to `on_event` and records it in the
/// report (a close also sets `report.close`).
fn drain_events(
    session: &mut Session,
    report: &mut ClientReport,
    on_event: &mut impl FnMut(&ClientEvent),
) {
    while let Some(ev) = session.poll_event() {
        let ev = match ev {
            SessionEvent::Desync { notice, local_hash } => {
                ClientEvent::Desync { notice, local_hash }
            }
            SessionEvent::Closed(c) => {
                report.close = Some(c.clone());
                ClientEvent::Closed(c)
            }
        };
        on_event(&ev);
        report.events.push(ev);
    }
}
