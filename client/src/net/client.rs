//! One player's connection: join, build the world, then the lockstep loop.

use std::collections::VecDeque;
use std::future::Future;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use bytes::Bytes;
use lockstep_core::{Faults, World};
use lockstep_proto::{
    Channel, ClientMessage, Close, CloseReason, DecodeError, DesyncNotice, RejoinCredential,
    ServerMessage, Session, SessionError, SessionEvent, Slot, Welcome,
};
use thiserror::Error;
use tokio::sync::mpsc;

use lockstep_net::{
    FrameError, TlsError, close_code, load_certs, parse_certs, read_frame, write_frame,
};

use super::tls::client_config;
use crate::game::{BotView, GameRules, RulesFactory, RulesId, apply_tick, start_match};

/// The certificate (or CA) a client trusts: a PEM file, or PEM text held in
/// memory (a game that ships its server's certificate inside the binary).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum TrustedCert {
    /// A PEM file: the dev certificate the server wrote, or a real one.
    File(PathBuf),
    /// PEM text.
    Pem(Vec<u8>),
}

impl TrustedCert {
    /// The certificates to trust.
    ///
    /// # Errors
    /// [`TlsError::CertFile`] if the file cannot be read or no PEM
    /// certificate is in it.
    pub fn load(&self) -> Result<Vec<rustls::pki_types::CertificateDer<'static>>, TlsError> {
        match self {
            TrustedCert::File(path) => load_certs(path),
            TrustedCert::Pem(bytes) => parse_certs(bytes, "PEM bytes"),
        }
    }
}

impl From<PathBuf> for TrustedCert {
    fn from(p: PathBuf) -> Self {
        TrustedCert::File(p)
    }
}

impl From<&PathBuf> for TrustedCert {
    fn from(p: &PathBuf) -> Self {
        TrustedCert::File(p.clone())
    }
}

impl From<&Path> for TrustedCert {
    fn from(p: &Path) -> Self {
        TrustedCert::File(p.to_path_buf())
    }
}

/// How to reach the server and what to do there.
#[derive(Clone, Debug)]
pub struct ClientOptions {
    /// The server's UDP address.
    pub server: SocketAddr,
    /// The name the server's certificate is checked against (`localhost`
    /// for the dev certificate).
    pub server_name: String,
    /// The certificate (or CA) to trust, as a file or as PEM bytes.
    pub cert: TrustedCert,
    /// Room to join.
    pub room: String,
    /// Display name.
    pub player_name: String,
    /// Leave after applying this many ticks (`None`: play until the server
    /// closes the match or the application leaves).
    pub max_ticks: Option<u64>,
    /// Also send every body's hash with the report of every K-th tick
    /// (0: never, the default). 8 bytes per body per report (about
    /// 55 kB/s upstream for 100 bodies at 60 Hz with K = 1, twenty times the
    /// rest of the traffic). The server writes the agreed body hashes into
    /// the replay, so a replay check can name the bodies that diverge.
    pub body_hashes_every: u64,
    /// How long connecting and joining may take.
    pub connect_timeout: Duration,
    /// Ticks of past states kept to answer the room's probes when a desync
    /// is located (one snapshot per tick: about 27 kB and 30 µs for the
    /// demo's 66 bodies; memory grows with the scene). 0: keep none, and
    /// answer every probe as unavailable. Default 64 (about 1 s at 60 Hz,
    /// longer than a report's round trip).
    pub forensics_ticks: usize,
    /// The join token to present (`lockstep-server token`, or a
    /// matchmaker's), for servers that require one. It seats a player once
    /// per match; to come back, the client presents the rejoin credential
    /// its welcome gave ([`ClientOptions::rejoin`]).
    pub token: Option<String>,
    /// Where this client keeps the rejoin credential of its seat: the
    /// welcome's credential is stored here, and the next connect with
    /// these options (or a clone of them: clones share the store)
    /// presents it, taking the seat back (a token alone is refused once
    /// used). Empty at first.
    pub rejoin: RejoinStore,
    /// Predict (see [`super::predict`]): run a second world ahead of the
    /// confirmed ticks, to the tick of the last input this client chose,
    /// with the other players' inputs guessed; draw
    /// [`LiveClient::predicted_world`]. Default off.
    pub predict: bool,
    /// How many ticks the predicted world may run ahead of the last
    /// confirmed one. Default 8.
    pub max_prediction: u64,
    /// Test hook (feature `test-hooks`): every snapshot this client gives
    /// a player joining the running match has its bytes inverted, so it
    /// does not restore. Default off.
    #[cfg(feature = "test-hooks")]
    pub corrupt_snapshots: bool,
    /// Test hook (feature `test-hooks`): the client simulates every tick
    /// right but reports a wrong hash for every even tick (a liar that
    /// raises a new divergence every other tick). Default off.
    #[cfg(feature = "test-hooks")]
    pub lie_on_even_ticks: bool,
}

impl ClientOptions {
    /// Options for the server at `server` trusting `cert`, joining `room`
    /// as `player_name`, with the defaults of each field.
    pub fn new(
        server: SocketAddr,
        cert: impl Into<TrustedCert>,
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
            body_hashes_every: 0,
            connect_timeout: Duration::from_secs(10),
            forensics_ticks: 64,
            token: None,
            rejoin: RejoinStore::default(),
            predict: false,
            max_prediction: 8,
            #[cfg(feature = "test-hooks")]
            corrupt_snapshots: false,
            #[cfg(feature = "test-hooks")]
            lie_on_even_ticks: false,
        }
    }
}

/// The rejoin credential a client keeps for its seat
/// ([`ClientOptions::rejoin`]); clones share it.
#[derive(Clone, Debug, Default)]
pub struct RejoinStore(Arc<Mutex<Option<RejoinCredential>>>);

impl RejoinStore {
    /// The credential held, if any.
    pub fn get(&self) -> Option<RejoinCredential> {
        *self.0.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Holds `credential` (or forgets the one held).
    pub fn set(&self, credential: Option<RejoinCredential>) {
        *self.0.lock().unwrap_or_else(|e| e.into_inner()) = credential;
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
    /// The server plays other rules than this client's.
    #[error(
        "the server plays {server}, this client {ours}: build the client with the server's game (or point it at a server of its own)"
    )]
    WrongRules {
        /// What the server announced.
        server: RulesId,
        /// This client's.
        ours: RulesId,
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
    /// The room located a desync: the bodies and fields that differ.
    DesyncLocated(lockstep_proto::DesyncReport),
    /// Predicting: a confirmed tick differed from its prediction, and the
    /// predicted world was rolled back and simulated again (passed to the
    /// event callback, not kept in [`ClientReport::events`]).
    Rollback(super::predict::Rollback),
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
    /// The first tick it took part in (its first input and report).
    pub start_tick: u64,
    /// The first tick it applied: `start_tick`, or for a player that joined
    /// a running match the tick after its snapshot. `hashes[i]` is the hash
    /// after tick `first_applied + i`.
    pub first_applied: u64,
    /// Ticks applied (bundles stepped).
    pub ticks_applied: u64,
    /// The state hash after every applied tick, in tick order from
    /// `first_applied` (reported from `start_tick` on).
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
    /// What prediction did ([`ClientOptions::predict`]; zeros without).
    pub prediction: super::predict::PredictionStats,
    /// From choosing an input to the world shown containing its tick: the
    /// confirmed world's (a bundle's round trip), and, predicting, the
    /// predicted world's.
    pub input_latency: InputLatency,
}

/// Input-to-effect latency figures of one client (see
/// [`ClientReport::input_latency`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct InputLatency {
    /// Until the confirmed world applied the input's tick.
    pub confirmed: Latency,
    /// Until the predicted world simulated the input's tick (zero samples
    /// without prediction).
    pub predicted: Latency,
}

/// Samples of one latency: count, sum and largest.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Latency {
    /// Samples.
    pub count: u64,
    /// Their sum.
    pub total: Duration,
    /// The largest.
    pub max: Duration,
}

impl Latency {
    fn add(&mut self, d: Duration) {
        self.count += 1;
        self.total += d;
        self.max = self.max.max(d);
    }

    /// The mean (zero without samples).
    pub fn mean(&self) -> Duration {
        if self.count == 0 {
            Duration::ZERO
        } else {
            self.total / u32::try_from(self.count).unwrap_or(u32::MAX)
        }
    }
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

/// A joined client: the world is built, the match has not been played yet.
/// Either [`play`](Client::play) it in a closed loop (bots, tools) or
/// [`start`](Client::start) it as a [`LiveClient`] that a game's frame loop
/// polls.
pub struct Client {
    endpoint: quinn::Endpoint,
    connection: quinn::Connection,
    send: quinn::SendStream,
    recv: quinn::RecvStream,
    session: Session,
    world: World,
    rules: Box<dyn GameRules>,
    /// The predicted world's rules and the game's input predictor (with
    /// [`ClientOptions::predict`]).
    predicted_rules: Option<Box<dyn GameRules>>,
    input_predictor: Option<Box<dyn super::predict::InputPredictor>>,
    rules_id: RulesId,
    options: ClientOptions,
}

impl std::fmt::Debug for Client {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Client")
            .field("slot", &self.session.slot())
            .field("remote", &self.connection.remote_address())
            .field("rules", &self.rules_id)
            .finish_non_exhaustive()
    }
}

impl Client {
    /// Connects, joins `options.room`, waits for the welcome, builds the
    /// world from its scene (checking the scene hash), and makes the game's
    /// rules for that world with `game`.
    ///
    /// # Errors
    /// [`ClientError`]: certificate, connection, refusal, timeout, a scene
    /// that does not build or hash as announced, or rules that refuse it.
    pub async fn connect(
        options: ClientOptions,
        game: &dyn RulesFactory,
    ) -> Result<Client, ClientError> {
        let roots = options.cert.load()?;
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
            let join = Session::rejoin_message(
                &options.room,
                &options.player_name,
                options.token.clone(),
                options.rejoin.get(),
            );
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
        if welcome.rejoin.is_some() {
            options.rejoin.set(welcome.rejoin);
        }
        if let Some(server) = &welcome.rules
            && *server != game.rules_id()
        {
            connection.close(close_code::REFUSED.into(), b"other game rules");
            return Err(ClientError::WrongRules {
                server: server.clone(),
                ours: game.rules_id(),
            });
        }
        let session = Session::new(&welcome)?;
        let (mut world, expected) = match &welcome.resume {
            // Joining a running match: the agreed state of a past tick.
            Some(r) => {
                let world = World::restore(&r.snapshot)
                    .map_err(|e| ClientError::Scene(format!("resume snapshot: {e}")))?;
                (world, r.hash)
            }
            None => {
                let text = std::str::from_utf8(&welcome.scene)
                    .map_err(|e| ClientError::Scene(format!("scene is not UTF-8: {e}")))?;
                let world = lockstep_core::scene::load_world(text, "welcome scene")
                    .map_err(|e| ClientError::Scene(e.to_string()))?;
                (world, welcome.scene_hash)
            }
        };
        let got = world.state_hash();
        if got != expected {
            connection.close(close_code::REFUSED.into(), b"scene hash mismatch");
            return Err(ClientError::SceneHashMismatch { expected, got });
        }
        if welcome.resume.is_none() {
            start_match(&mut world, welcome.seed).map_err(|e| ClientError::Game(e.to_string()))?;
        }
        let rules = match game.rules_for(&world) {
            Ok(r) => r,
            Err(e) => {
                connection.close(close_code::NORMAL.into(), b"rules refused the scene");
                return Err(ClientError::Game(e.to_string()));
            }
        };
        let predicted_rules = if options.predict {
            Some(
                game.rules_for(&world)
                    .map_err(|e| ClientError::Game(e.to_string()))?,
            )
        } else {
            None
        };
        Ok(Client {
            endpoint,
            connection,
            send,
            recv,
            session,
            world,
            rules,
            predicted_rules,
            input_predictor: if options.predict {
                game.input_predictor()
            } else {
                None
            },
            rules_id: game.rules_id(),
            options,
        })
    }

    /// This client's slot.
    pub fn slot(&self) -> Slot {
        self.session.slot()
    }

    /// The world as built from the welcome.
    pub fn world(&self) -> &World {
        &self.world
    }

    /// The lockstep session (timing parameters, counters).
    pub fn session(&self) -> &Session {
        &self.session
    }

    /// The rules, as built for the welcome's world.
    pub fn rules(&self) -> &dyn GameRules {
        &*self.rules
    }

    /// The rules this client plays with.
    pub fn rules_id(&self) -> &RulesId {
        &self.rules_id
    }

    /// Starts the network tasks and hands the match to the caller's loop:
    /// call [`LiveClient::poll`] every frame, then read
    /// [`LiveClient::world`] (or, predicting,
    /// [`LiveClient::predicted_world`]) to render. Must be called inside a
    /// tokio runtime (the tasks run on it).
    ///
    /// # Panics
    /// Never; a predicting client whose rules refuse their own state starts
    /// without prediction (the same rules accepted it at connect).
    pub fn start(self) -> LiveClient {
        let (in_tx, incoming) = mpsc::unbounded_channel::<Incoming>();
        let (outgoing, mut out_rx) = mpsc::unbounded_channel::<Outgoing>();
        let mut recv = self.recv;
        let frames_tx = in_tx.clone();
        // The stream is read by its own task so that a frame is never cut
        // in half; its end (or failure) comes after every frame before it,
        // so a close message is always seen before the connection's loss.
        let reader = tokio::spawn(async move {
            loop {
                match read_frame(&mut recv).await {
                    Ok(Some(bytes)) => {
                        if frames_tx.send(Incoming::Frame(bytes)).is_err() {
                            break;
                        }
                    }
                    Ok(None) => {
                        let _ = frames_tx.send(Incoming::StreamEnded(None));
                        break;
                    }
                    Err(e) => {
                        let _ = frames_tx.send(Incoming::StreamEnded(Some(e)));
                        break;
                    }
                }
            }
        });
        let conn = self.connection.clone();
        let datagrams = tokio::spawn(async move {
            while let Ok(bytes) = conn.read_datagram().await {
                if in_tx.send(Incoming::Datagram(bytes.to_vec())).is_err() {
                    break;
                }
            }
        });
        let mut send = self.send;
        let writer = tokio::spawn(async move {
            while let Some(out) = out_rx.recv().await {
                match out {
                    Outgoing::Frame(bytes) => {
                        write_frame(&mut send, &bytes).await?;
                    }
                    Outgoing::Finish => {
                        let _ = send.finish();
                        break;
                    }
                }
            }
            Ok(())
        });
        let start_tick = self.session.first_bundle();
        let history = super::forensics::History::new(self.options.forensics_ticks);
        let predictor = self.predicted_rules.and_then(|rules| {
            super::predict::Predictor::new(
                &self.world,
                start_tick,
                rules,
                self.session.slot().0,
                self.options.max_prediction,
                self.input_predictor,
            )
            .ok()
        });
        LiveClient {
            predictor,
            chosen_at: VecDeque::new(),
            latency: InputLatency::default(),
            history,
            endpoint: self.endpoint,
            connection: self.connection,
            session: self.session,
            world: self.world,
            rules: self.rules,
            options: self.options,
            base: Instant::now(),
            incoming,
            buffered: VecDeque::new(),
            outgoing,
            tasks: vec![reader, datagrams],
            writer: Some(writer),
            traffic: Traffic::default(),
            ticks_applied: 0,
            next_tick: start_tick,
            stream_ended: None,
            left: false,
        }
    }

    /// Plays until the server closes the session, `options.max_ticks` ticks
    /// were applied, or `stop` completes (then the client leaves). `input`
    /// gives the local input for a tick; `on_event` sees every event as it
    /// happens. The connection is closed and the endpoint drained before
    /// returning. A closed loop over [`Client::start`] and
    /// [`LiveClient::poll`].
    ///
    /// # Errors
    /// [`ClientError`] if the connection fails or the server sends garbage;
    /// a close by the server is not an error (it is in the report).
    pub async fn play(
        self,
        mut input: impl FnMut(u64) -> Vec<u8> + Send,
        on_event: impl FnMut(&ClientEvent) + Send,
        stop: impl Future<Output = ()> + Send,
    ) -> Result<ClientReport, ClientError> {
        self.play_seeing(move |view| input(view.tick), on_event, stop)
            .await
    }

    /// [`play`](Self::play) with an input that sees the world, the rules
    /// and the slot ([`BotView`]): how a bot with a
    /// [`BotPolicy`](crate::game::BotPolicy) plays.
    ///
    /// # Errors
    /// As [`play`](Self::play).
    pub async fn play_seeing(
        self,
        mut input: impl FnMut(&BotView<'_>) -> Vec<u8> + Send,
        mut on_event: impl FnMut(&ClientEvent) + Send,
        stop: impl Future<Output = ()> + Send,
    ) -> Result<ClientReport, ClientError> {
        let started = Instant::now();
        let mut live = self.start();
        let mut report = ClientReport {
            slot: live.slot(),
            start_tick: live.session.start_tick(),
            first_applied: live.session.first_bundle(),
            ticks_applied: 0,
            hashes: Vec::new(),
            delivered_at: Vec::new(),
            own_inputs_substituted: 0,
            events: Vec::new(),
            close: None,
            rtt: Duration::ZERO,
            traffic: Traffic::default(),
            played_for: Duration::ZERO,
            prediction: Default::default(),
            input_latency: Default::default(),
        };
        tokio::pin!(stop);
        let mut stopped = false;
        let result = loop {
            let polled = live.poll_seeing(&mut input);
            let failed = match polled {
                Ok(p) => {
                    record(&mut report, &p, &mut on_event);
                    None
                }
                Err(e) => Some(e),
            };
            if let Some(e) = failed {
                break Err(e);
            }
            if live.is_closed() || live.has_left() {
                break Ok(());
            }
            if stopped {
                live.leave();
                break Ok(());
            }
            tokio::select! {
                biased;
                () = &mut stop => stopped = true,
                () = live.wait() => {}
            }
        };
        // The close may arrive as the last event.
        if let Ok(p) = live.poll(|_| Vec::new()) {
            record(&mut report, &p, &mut on_event);
        }
        let result = match result {
            Err(ClientError::ConnectionLost(_)) if report.close.is_some() => Ok(()),
            r => r,
        };
        report.rtt = live.connection.rtt();
        report.traffic = live.traffic();
        report.played_for = started.elapsed();
        report.prediction = live.prediction_stats();
        report.input_latency = live.latency;
        live.shutdown().await;
        result.map(|()| report)
    }
}

/// Adds what one poll did to a closed loop's report.
fn record(report: &mut ClientReport, p: &Polled, on_event: &mut impl FnMut(&ClientEvent)) {
    for t in &p.ticks {
        report.delivered_at.push(t.applied_at);
        report.own_inputs_substituted += u64::from(t.own_input_substituted);
        report.hashes.push(t.hash);
        report.ticks_applied += 1;
        if !t.faults.is_empty() {
            report.events.push(ClientEvent::Fault {
                tick: t.tick,
                faults: t.faults,
            });
        }
    }
    for ev in &p.events {
        if let ClientEvent::Closed(c) = ev {
            report.close = Some(c.clone());
        }
        on_event(ev);
        report.events.push(ev.clone());
    }
    if let Some(r) = p.rollback {
        on_event(&ClientEvent::Rollback(r));
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

/// What the network tasks hand to the poll.
enum Incoming {
    Frame(Vec<u8>),
    Datagram(Vec<u8>),
    /// The stream ended cleanly (`None`) or failed.
    StreamEnded(Option<FrameError>),
}

/// What the poll hands to the writer task.
enum Outgoing {
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
/// render. Network I/O runs on tokio tasks started by [`Client::start`].
pub struct LiveClient {
    endpoint: quinn::Endpoint,
    connection: quinn::Connection,
    session: Session,
    world: World,
    rules: Box<dyn GameRules>,
    options: ClientOptions,
    base: Instant,
    incoming: mpsc::UnboundedReceiver<Incoming>,
    buffered: VecDeque<Incoming>,
    outgoing: mpsc::UnboundedSender<Outgoing>,
    tasks: Vec<tokio::task::JoinHandle<()>>,
    writer: Option<tokio::task::JoinHandle<Result<(), FrameError>>>,
    traffic: Traffic,
    ticks_applied: u64,
    next_tick: u64,
    stream_ended: Option<String>,
    left: bool,
    history: super::forensics::History,
    predictor: Option<super::predict::Predictor>,
    /// Own inputs chosen, by tick, with when: for the latency figures.
    chosen_at: VecDeque<(u64, Instant, bool)>,
    latency: InputLatency,
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
    /// since [`Client::start`]).
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
                        (_, Some(r)) => r.to_string(),
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
        self.connection
            .close(close_code::NORMAL.into(), b"client done");
        for t in &self.tasks {
            t.abort();
        }
        if let Some(w) = &self.writer {
            w.abort();
        }
    }
}
