//! One player's connection: join, build the world, then the lockstep loop.

use std::collections::VecDeque;
use std::future::Future;
use std::net::SocketAddr;
use std::time::{Duration, Instant};

use lockstep_core::World;
use lockstep_proto::{ServerMessage, Session, Slot, Welcome};
use tokio::sync::mpsc;

use lockstep_net::{
    Link, LinkRecv, LinkSend, WEBTRANSPORT_PATH, close_code, read_frame, write_frame,
};

use super::live::{Incoming, Outgoing};
use super::tls::config_for_options;
use super::{
    ClientError, ClientEvent, ClientOptions, ClientReport, InputLatency, LiveClient, Polled,
    Traffic,
};
use crate::game::{BotView, GameRules, RulesFactory, RulesId, start_match};

/// A joined client: the world is built, the match has not been played yet.
/// Either [`play`](Client::play) it in a closed loop (bots, tools) or
/// [`start`](Client::start) it as a [`LiveClient`] that a game's frame loop
/// polls.
pub struct Client {
    endpoint: quinn::Endpoint,
    connection: Link,
    send: LinkSend,
    recv: LinkRecv,
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
    /// Connects (over native QUIC, or WebTransport with
    /// [`ClientOptions::webtransport`]), joins `options.room`, waits for the
    /// welcome, builds the world from its scene (checking the scene hash),
    /// and makes the game's rules for that world with `game`.
    ///
    /// # Errors
    /// [`ClientError`]: certificate, connection, refusal, timeout, a scene
    /// that does not build or hash as announced, or rules that refuse it.
    pub async fn connect(
        options: ClientOptions,
        game: &dyn RulesFactory,
    ) -> Result<Client, ClientError> {
        let config = config_for_options(&options.cert, options.webtransport)?;
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
            let connection = if options.webtransport {
                let session = web_transport_quinn::Session::connect(
                    connection,
                    webtransport_url(&options.server_name, options.server.port())?,
                )
                .await
                .map_err(|e| ClientError::Connect(format!("WebTransport: {e}")))?;
                Link::WebTransport(Box::new(session))
            } else {
                Link::Quic(connection)
            };
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
            connection.close(close_code::REFUSED, b"other game rules");
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
            connection.close(close_code::REFUSED, b"scene hash mismatch");
            return Err(ClientError::SceneHashMismatch { expected, got });
        }
        if welcome.resume.is_none() {
            start_match(&mut world, welcome.seed).map_err(|e| ClientError::Game(e.to_string()))?;
        }
        let rules = match game.rules_for(&world) {
            Ok(r) => r,
            Err(e) => {
                connection.close(close_code::NORMAL, b"rules refused the scene");
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

/// The URL of the server's WebTransport sessions: `server_name` (the name
/// its certificate is checked against, as the URL's host) and `port`.
fn webtransport_url(server_name: &str, port: u16) -> Result<url::Url, ClientError> {
    let host = if server_name.contains(':') {
        format!("[{server_name}]")
    } else {
        server_name.to_owned()
    };
    url::Url::parse(&format!("https://{host}:{port}{WEBTRANSPORT_PATH}"))
        .map_err(|e| ClientError::Connect(format!("WebTransport URL for {server_name:?}: {e}")))
}

async fn read_welcome(recv: &mut LinkRecv) -> Result<Welcome, ClientError> {
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
