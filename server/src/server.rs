//! The server's run: the parts it starts, the accept loop, and the
//! graceful shutdown.

use std::collections::HashMap;
use std::future::Future;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use tokio::sync::{Semaphore, watch};
use tokio::task::JoinSet;

use crate::{
    ServerConfig, ServerError, ServerEvent, ServerReport, Shared, agones, clock, conn, metrics,
    room, spectate, tls, webtransport,
};

/// Runs the server until `shutdown` completes, then shuts down gracefully:
/// stops accepting, lets every running room finish its current tick and
/// collect the last hash reports, closes every connection with a reason,
/// flushes the replays, and waits for every task.
///
/// # Example
///
/// A server for a game of one static box on a free port, with its own dev
/// certificate and no replays, stopped as soon as it listens:
///
/// ```
/// use lockstep_server::{RulesId, ServerConfig, ServerEvent, TlsSource, run};
///
/// # #[tokio::main(flavor = "current_thread")]
/// # async fn main() {
/// let dir = std::env::temp_dir().join(format!("lockstep-doc-{}", std::process::id()));
/// let scene = "[[bodies]]\nname = \"ground\"\nkind = \"static\"\n\
///              [[bodies.shapes]]\nkind = \"box\"\nhalf_extents = [10, 1, 10]\n";
/// let listen = "127.0.0.1:0".parse().unwrap();
/// let mut config = ServerConfig::for_game(listen, scene, "ground", RulesId::new("my-game", 1));
/// config.tls = TlsSource::dev(dir.join("cert.pem"));
/// config.replay_dir = None;
/// let (events_tx, mut events) = tokio::sync::mpsc::unbounded_channel();
/// config.events = Some(events_tx);
/// let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
/// let server = tokio::spawn(run(config, async {
///     let _ = stopped.await;
/// }));
/// let Some(ServerEvent::Listening { addr, cert }) = events.recv().await else {
///     panic!("the server did not start");
/// };
/// assert_ne!(addr.port(), 0);
/// assert!(cert.expect("a dev certificate").exists()); // for clients to trust
/// stop.send(()).unwrap();
/// let report = server.await.unwrap().unwrap();
/// assert!(report.matches.is_empty());
/// # }
/// ```
///
/// # Errors
/// [`ServerError`] if the scene does not build, the settings are incoherent,
/// the certificate cannot be made, or a socket (QUIC's, WebTransport's)
/// cannot be bound. Errors of
/// single connections are logged, never returned.
pub async fn run(
    config: ServerConfig,
    shutdown: impl Future<Output = ()>,
) -> Result<ServerReport, ServerError> {
    let scene = load_scene(&config)?;
    check_config(&config, scene.hash)?;
    if let Some(dir) = &config.replay_dir {
        std::fs::create_dir_all(dir).map_err(|e| ServerError::Io(dir.clone(), e))?;
    }
    let (endpoint, addr, cert) = listen(&config, scene.hash)?;
    let webtransport = webtransport::bind(&config)?;
    let view_listener = bind_viewer(&config)?;
    let (shutdown_tx, shutdown_rx) = watch::channel(false);
    let shared = start_shared(config, scene, shutdown_rx)?;
    if let Some(listener) = view_listener {
        serve_viewer(&shared, listener)?;
    }
    let metrics_task = serve_metrics(&shared).await?;
    let mut sdk = match &shared.config.agones {
        Some(a) => Some(agones::start(&shared, a).await?),
        None => None,
    };
    shared.metrics.ready.store(true, Ordering::Relaxed);
    shared.emit(ServerEvent::Listening { addr, cert });
    if let Some(w) = &webtransport {
        shared.emit(w.event());
    }
    // An Agones game server hosts one match.
    let exit_after_match = shared.config.exit_after_match || sdk.is_some();
    let connections = accept(
        &shared,
        &endpoint,
        webtransport.as_ref().map(|w| &w.endpoint),
        shutdown,
        exit_after_match,
    )
    .await;
    crate::log!("shutting down: finishing every room's tick");
    let _ = shutdown_tx.send(true);
    close_rooms_then_connections(&shared, connections).await;
    endpoint.close(
        lockstep_net::close_code::SHUTDOWN.into(),
        b"server shutting down",
    );
    if let Some(w) = &webtransport {
        w.endpoint.close(
            web_transport_quinn::proto::error_to_http3(lockstep_net::close_code::SHUTDOWN)
                .try_into()
                .unwrap_or_default(),
            b"server shutting down",
        );
    }
    let idle = async {
        endpoint.wait_idle().await;
        if let Some(w) = &webtransport {
            w.endpoint.wait_idle().await;
        }
    };
    let _ = tokio::time::timeout(Duration::from_secs(2), idle).await;
    if let Some(t) = metrics_task {
        let _ = t.await;
    }
    // The replays are flushed: Agones may delete the pod now.
    if let Some(sdk) = &mut sdk {
        match sdk.shutdown().await {
            Ok(()) => crate::log!("agones: shutdown requested"),
            Err(e) => crate::log!("agones: {e}"),
        }
    }
    crate::log!("server stopped");
    let report = shared.report.lock().map(|r| r.clone()).unwrap_or_default();
    Ok(report)
}

/// What the server knows of its scene.
struct Scene {
    /// The state hash of the scene's world.
    hash: u64,
    /// Bodies in the scene's world.
    bodies: u32,
}

/// Builds the scene's world once, for its hash and body count.
fn load_scene(config: &ServerConfig) -> Result<Scene, ServerError> {
    let world =
        lockstep_core::scene::load_world(&config.scene, &config.scene_name).map_err(|e| {
            ServerError::Scene {
                name: config.scene_name.clone(),
                detail: e.to_string(),
            }
        })?;
    Ok(Scene {
        hash: world.state_hash(),
        bodies: u32::try_from(world.body_handles().count()).unwrap_or(u32::MAX),
    })
}

/// Refuses incoherent settings before anything starts.
fn check_config(config: &ServerConfig, scene_hash: u64) -> Result<(), ServerError> {
    room::check_settings(config, scene_hash)?;
    match &config.token_secret {
        Some(s) if s.len() < lockstep_proto::token::MIN_SECRET_BYTES => {
            Err(ServerError::Config(format!(
                "the token secret has {} bytes; at least {} are needed",
                s.len(),
                lockstep_proto::token::MIN_SECRET_BYTES
            )))
        }
        None if config.require_tokens => Err(ServerError::Config(
            "tokens are required but no token secret is set".into(),
        )),
        None if config.vote && config.verifier.is_none() => Err(ServerError::Config(
            "voting counts only token holders' hashes, and no token secret is set".into(),
        )),
        _ => Ok(()),
    }
}

/// Binds the QUIC endpoint; returns it, its address and the dev
/// certificate's file, if one was made.
fn listen(
    config: &ServerConfig,
    scene_hash: u64,
) -> Result<(quinn::Endpoint, SocketAddr, Option<PathBuf>), ServerError> {
    let (server_config, cert) = tls::server_config(&config.tls)?;
    let endpoint = quinn::Endpoint::server(server_config, config.listen)
        .map_err(|e| ServerError::Bind(config.listen, e))?;
    let addr = endpoint
        .local_addr()
        .map_err(|e| ServerError::Bind(config.listen, e))?;
    crate::log!(
        "listening on {addr} (scene {}, hash {scene_hash:016x}){}",
        config.scene_name,
        cert.as_ref()
            .map(|c| format!(", dev certificate in {}", c.display()))
            .unwrap_or_default()
    );
    Ok((endpoint, addr, cert))
}

/// Binds the viewer's HTTP listener (`--view`).
fn bind_viewer(
    config: &ServerConfig,
) -> Result<Option<(std::net::TcpListener, SocketAddr)>, ServerError> {
    let Some(v) = &config.view else {
        return Ok(None);
    };
    let l = std::net::TcpListener::bind(v.listen).map_err(|e| ServerError::Bind(v.listen, e))?;
    let local = l.local_addr().map_err(|e| ServerError::Bind(v.listen, e))?;
    Ok(Some((l, local)))
}

/// Starts the room threads and the precise clock, and builds the state
/// every task shares.
fn start_shared(
    config: ServerConfig,
    scene: Scene,
    shutdown: watch::Receiver<bool>,
) -> Result<Arc<Shared>, ServerError> {
    let priority = clock::Priority {
        realtime: config.realtime_clock,
    };
    // At real-time priority: relaying rooms cost microseconds a tick, so
    // one thread holds hundreds and a second one only adds wake-ups;
    // verifying rooms re-simulate, so they get one thread per core.
    let room_threads = if config.verifier.is_some() {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        1
    };
    let room_threads =
        clock::RoomThreads::start(room_threads, priority).map_err(ServerError::Thread)?;
    let clock = clock::Clock::start(priority).map_err(ServerError::Thread)?;
    let spectate = config
        .view
        .as_ref()
        .map(|v| Arc::new(spectate::Spectate::new(v.sim.clone())));
    let allocation = if config.agones.is_some() {
        agones::AllocationState::Waiting
    } else {
        agones::AllocationState::Off
    };
    Ok(Arc::new(Shared {
        config,
        scene_hash: scene.hash,
        scene_bodies: scene.bodies,
        rooms: Mutex::new(HashMap::new()),
        shutdown,
        report: Mutex::new(ServerReport::default()),
        room_tasks: Mutex::new(JoinSet::new()),
        room_seq: std::sync::atomic::AtomicU64::new(0),
        metrics: metrics::Metrics::default(),
        match_ended: tokio::sync::Notify::new(),
        clock,
        room_threads,
        allocation: std::sync::RwLock::new(allocation),
        spectate,
        per_address: Mutex::new(HashMap::new()),
    }))
}

/// Serves the live viewer on its own thread.
fn serve_viewer(
    shared: &Arc<Shared>,
    (listener, local): (std::net::TcpListener, SocketAddr),
) -> Result<(), ServerError> {
    let Some(spectate) = &shared.spectate else {
        return Ok(());
    };
    crate::log!("viewer on http://{local}/ (live rooms, read-only)");
    shared.emit(ServerEvent::ViewListening { addr: local });
    let routes = Arc::new(spectate::LiveRoutes(spectate.clone()));
    std::thread::Builder::new()
        .name("lockstep-view".into())
        .spawn(move || lockstep_view::http::serve(listener, routes))
        .map_err(ServerError::Thread)?;
    Ok(())
}

/// Serves the metrics (`--metrics`), if asked.
async fn serve_metrics(
    shared: &Arc<Shared>,
) -> Result<Option<tokio::task::JoinHandle<()>>, ServerError> {
    let Some(a) = shared.config.metrics else {
        return Ok(None);
    };
    let listener = metrics::bind(a)
        .await
        .map_err(|e| ServerError::Bind(a, e))?;
    let local = listener.local_addr().map_err(|e| ServerError::Bind(a, e))?;
    crate::log!("metrics on http://{local}/metrics (and /healthz, /readyz)");
    shared.emit(ServerEvent::MetricsListening { addr: local });
    Ok(Some(tokio::spawn(metrics::serve(shared.clone(), listener))))
}

/// Accepts connections on the QUIC endpoint and the WebTransport one (if
/// any), each served by its own task, until `shutdown` completes (or the
/// match ended, with `exit_after_match`); returns the connection tasks.
/// Both endpoints share the connection limits.
async fn accept(
    shared: &Arc<Shared>,
    endpoint: &quinn::Endpoint,
    webtransport: Option<&quinn::Endpoint>,
    shutdown: impl Future<Output = ()>,
    exit_after_match: bool,
) -> JoinSet<()> {
    let mut admit = Admission {
        shared: shared.clone(),
        limit: Arc::new(Semaphore::new(shared.config.max_connections)),
        // Handshakes spent on telling refused connections why, at once.
        refusals: Arc::new(Semaphore::new(32)),
        connections: JoinSet::new(),
    };
    let mut webtransport = webtransport;
    tokio::pin!(shutdown);
    loop {
        tokio::select! {
            () = &mut shutdown => break,
            () = shared.match_ended.notified(), if exit_after_match => {
                crate::log!("the match ended; exiting (--exit-after-match)");
                break;
            }
            incoming = endpoint.accept() => {
                let Some(incoming) = incoming else { break };
                admit.admit(incoming, conn::Via::Quic);
            }
            incoming = async move { webtransport?.accept().await }, if webtransport.is_some() => {
                match incoming {
                    Some(incoming) => admit.admit(incoming, conn::Via::WebTransport),
                    None => webtransport = None,
                }
            }
            Some(_) = admit.connections.join_next(), if !admit.connections.is_empty() => {}
        }
    }
    admit.connections
}

/// The accept loop's limits and connection tasks.
struct Admission {
    shared: Arc<Shared>,
    limit: Arc<Semaphore>,
    refusals: Arc<Semaphore>,
    connections: JoinSet<()>,
}

impl Admission {
    /// Serves an incoming connection if the limits allow it, or refuses it
    /// with the reason.
    fn admit(&mut self, incoming: quinn::Incoming, via: conn::Via) {
        let shared = &self.shared;
        let remote = incoming.remote_address();
        let admitted = match (
            shared.address_slot(remote.ip()),
            self.limit.clone().try_acquire_owned(),
        ) {
            (Some(slot), Ok(permit)) => Ok((slot, permit)),
            (None, _) => Err(format!(
                "too many connections from {} (at most {} per address)",
                remote.ip(),
                shared
                    .config
                    .max_connections_per_address
                    .unwrap_or_default()
            )),
            (Some(_), Err(_)) => Err(format!(
                "too many connections (at most {} on this server)",
                shared.config.max_connections
            )),
        };
        match admitted {
            Ok((slot, permit)) => {
                let shared = shared.clone();
                let span = tracing::info_span!(
                    "conn",
                    remote = %remote,
                    via = via.name(),
                    slot = tracing::field::Empty
                );
                self.connections.spawn(tracing::Instrument::instrument(
                    async move {
                        conn::serve(shared, incoming, via).await;
                        drop(permit);
                        drop(slot);
                    },
                    span,
                ));
            }
            Err(reason) => {
                shared.refused(remote, reason.clone());
                // Told why (code 5 and the reason) when a handshake can be
                // spared; a flood past that gets a bare refusal.
                match self.refusals.clone().try_acquire_owned() {
                    Ok(permit) => {
                        self.connections.spawn(async move {
                            conn::refuse(incoming, &reason, via).await;
                            drop(permit);
                        });
                    }
                    Err(_) => incoming.refuse(),
                }
            }
        }
    }
}

/// Waits for the rooms (they finish their tick, close their players with
/// a reason and flush their replays), then for the connection tasks,
/// which end once their room closed them.
async fn close_rooms_then_connections(shared: &Shared, mut connections: JoinSet<()>) {
    let mut rooms =
        std::mem::take(&mut *shared.room_tasks.lock().unwrap_or_else(|e| e.into_inner()));
    while rooms.join_next().await.is_some() {}
    let drained = tokio::time::timeout(Duration::from_secs(3), async {
        while connections.join_next().await.is_some() {}
    })
    .await;
    if drained.is_err() {
        crate::log!(
            "{} connection tasks did not end in 3 s; aborting them",
            connections.len()
        );
        connections.shutdown().await;
    }
}
