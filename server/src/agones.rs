//! Agones mode (`--agones`): the server as one Agones `GameServer`.
//!
//! Agones runs a sidecar in the game server's pod that serves the SDK as a
//! gRPC service (`agones.dev.sdk.SDK`, on `localhost:9357` unless
//! `AGONES_SDK_GRPC_HOST` / `AGONES_SDK_GRPC_PORT` say otherwise). The
//! server:
//! - calls `Ready` once it listens;
//! - streams `Health` pings every [`AgonesSettings::health_period`] while
//!   the rooms' tick clocks keep time: a period in which a running room
//!   closed no tick, or closed one more than [`STALL`] late, sends no ping,
//!   so Agones marks a stuck server unhealthy;
//! - watches its `GameServer`: until it is `Allocated`, joins are refused
//!   (players get the address from the allocation); the allocation's
//!   metadata names the one room it hosts ([`ROOM_KEY`], an annotation or a
//!   label) and the secret its join tokens are signed with
//!   ([`TOKEN_SECRET_KEY`], an annotation), which then makes tokens
//!   required;
//! - after the match (its room closed, the replay flushed) calls
//!   `Shutdown` and exits.
//!
//! The messages are declared here with `prost` from the SDK's `sdk.proto`
//! (same package, service, field numbers and types); only the fields the
//! server reads are declared, and protobuf skips the others.

use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Duration;

use tokio::sync::mpsc;
use tonic::codegen::http::uri::PathAndQuery;
use tonic::transport::{Channel, Endpoint};

use crate::Shared;

/// The allocation metadata key naming the room the server hosts (an
/// annotation, or else a label).
pub const ROOM_KEY: &str = "lockstep.dev/room";

/// The allocation annotation holding the join-token secret (its text's
/// bytes, at least 16).
pub const TOKEN_SECRET_KEY: &str = "lockstep.dev/token-secret";

/// A running room that closed a tick this late stops the health pings.
pub const STALL: Duration = Duration::from_secs(1);

/// The SDK's messages (`agones.dev.sdk`), as far as the server uses them.
pub mod pb {
    use std::collections::HashMap;

    /// `Empty`.
    #[derive(Clone, Copy, PartialEq, Eq, prost::Message)]
    pub struct Empty {}

    /// `KeyValue`.
    #[derive(Clone, PartialEq, Eq, prost::Message)]
    pub struct KeyValue {
        /// The key.
        #[prost(string, tag = "1")]
        pub key: String,
        /// The value.
        #[prost(string, tag = "2")]
        pub value: String,
    }

    /// `GameServer`.
    #[derive(Clone, PartialEq, prost::Message)]
    pub struct GameServer {
        /// Its Kubernetes metadata.
        #[prost(message, optional, tag = "1")]
        pub object_meta: Option<ObjectMeta>,
        /// Its status.
        #[prost(message, optional, tag = "3")]
        pub status: Option<Status>,
    }

    /// `GameServer.ObjectMeta`.
    #[derive(Clone, PartialEq, prost::Message)]
    pub struct ObjectMeta {
        /// The game server's name.
        #[prost(string, tag = "1")]
        pub name: String,
        /// Its namespace.
        #[prost(string, tag = "2")]
        pub namespace: String,
        /// Annotations (set by the allocation's `metadata`, among others).
        #[prost(map = "string, string", tag = "8")]
        pub annotations: HashMap<String, String>,
        /// Labels.
        #[prost(map = "string, string", tag = "9")]
        pub labels: HashMap<String, String>,
    }

    /// `GameServer.Status`.
    #[derive(Clone, PartialEq, prost::Message)]
    pub struct Status {
        /// `Scheduled`, `Ready`, `Allocated`, `Shutdown`, ...
        #[prost(string, tag = "1")]
        pub state: String,
        /// The node's address.
        #[prost(string, tag = "2")]
        pub address: String,
    }
}

/// Where the SDK server is and how often to ping it.
#[derive(Clone, Debug)]
pub struct AgonesSettings {
    /// The SDK's gRPC address, e.g. `http://localhost:9357`.
    pub sdk: String,
    /// Between two health pings (keep it under the fleet's
    /// `health.periodSeconds`).
    pub health_period: Duration,
    /// How long to keep trying to reach the SDK at start-up (the sidecar
    /// may start after the server).
    pub connect_timeout: Duration,
}

impl AgonesSettings {
    /// The SDK address from `AGONES_SDK_GRPC_HOST` (default `localhost`)
    /// and `AGONES_SDK_GRPC_PORT` (default 9357), as the sidecar sets them;
    /// a ping every 2 s; 30 s to connect.
    pub fn from_env() -> Self {
        let host = std::env::var("AGONES_SDK_GRPC_HOST").unwrap_or_else(|_| "localhost".into());
        let port = std::env::var("AGONES_SDK_GRPC_PORT")
            .ok()
            .and_then(|p| p.parse::<u16>().ok())
            .unwrap_or(9357);
        Self {
            sdk: format!("http://{host}:{port}"),
            health_period: Duration::from_secs(2),
            connect_timeout: Duration::from_secs(30),
        }
    }
}

/// What the allocation asks of the server.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Allocation {
    /// The only room joins may name (`None`: any).
    pub room: Option<String>,
    /// The join-token secret (then tokens are required).
    pub token_secret: Option<Vec<u8>>,
}

impl Allocation {
    /// The allocation a `GameServer` carries, if its state is `Allocated`.
    pub fn of(gs: &pb::GameServer) -> Option<Allocation> {
        if gs.status.as_ref()?.state != "Allocated" {
            return None;
        }
        let meta = gs.object_meta.clone().unwrap_or_default();
        let room = meta
            .annotations
            .get(ROOM_KEY)
            .or_else(|| meta.labels.get(ROOM_KEY))
            .filter(|r| !r.is_empty())
            .cloned();
        let token_secret = meta
            .annotations
            .get(TOKEN_SECRET_KEY)
            .filter(|s| !s.is_empty())
            .map(|s| s.trim().as_bytes().to_vec());
        Some(Allocation { room, token_secret })
    }
}

/// Where the server stands with Agones, for the join checks.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum AllocationState {
    /// Not in Agones mode: joins as configured.
    Off,
    /// Ready, not allocated: joins are refused.
    Waiting,
    /// Allocated.
    Allocated(Allocation),
    /// Allocated with metadata the server cannot use: joins are refused
    /// with this reason.
    Unusable(String),
}

/// Why the SDK could not be used.
#[derive(Debug, thiserror::Error)]
pub enum AgonesError {
    /// The address does not parse.
    #[error("SDK address {0:?}: {1}")]
    Address(String, String),
    /// The SDK server did not answer in time.
    #[error("SDK at {0}: {1}")]
    Connect(String, String),
    /// A call failed.
    #[error("SDK call {0}: {1}")]
    Call(&'static str, String),
}

/// A client of the Agones SDK service.
#[derive(Clone)]
pub struct Sdk {
    grpc: tonic::client::Grpc<Channel>,
}

fn codec<A, B>() -> tonic_prost::ProstCodec<A, B>
where
    A: prost::Message + Send + 'static,
    B: prost::Message + Default + Send + 'static,
{
    tonic_prost::ProstCodec::default()
}

fn path(method: &'static str) -> PathAndQuery {
    PathAndQuery::from_static(method)
}

const READY: &str = "/agones.dev.sdk.SDK/Ready";
const SHUTDOWN: &str = "/agones.dev.sdk.SDK/Shutdown";
const HEALTH: &str = "/agones.dev.sdk.SDK/Health";
const GET_GAME_SERVER: &str = "/agones.dev.sdk.SDK/GetGameServer";
const WATCH_GAME_SERVER: &str = "/agones.dev.sdk.SDK/WatchGameServer";
const SET_ANNOTATION: &str = "/agones.dev.sdk.SDK/SetAnnotation";

impl Sdk {
    /// Connects to the SDK server at `uri`, retrying for up to `timeout`.
    ///
    /// # Errors
    /// [`AgonesError`] if the address is invalid or nothing answers in
    /// time.
    pub async fn connect(uri: &str, timeout: Duration) -> Result<Sdk, AgonesError> {
        let endpoint = Endpoint::from_shared(uri.to_owned())
            .map_err(|e| AgonesError::Address(uri.to_owned(), e.to_string()))?
            .connect_timeout(Duration::from_secs(2));
        let deadline = tokio::time::Instant::now() + timeout;
        loop {
            match endpoint.connect().await {
                Ok(channel) => {
                    return Ok(Sdk {
                        grpc: tonic::client::Grpc::new(channel),
                    });
                }
                Err(e) if tokio::time::Instant::now() >= deadline => {
                    return Err(AgonesError::Connect(uri.to_owned(), e.to_string()));
                }
                Err(_) => tokio::time::sleep(Duration::from_millis(250)).await,
            }
        }
    }

    async fn unary<M, R>(
        &mut self,
        name: &'static str,
        method: &'static str,
        m: M,
    ) -> Result<R, AgonesError>
    where
        M: prost::Message + Send + Sync + 'static,
        R: prost::Message + Default + Send + Sync + 'static,
    {
        let call = |e: String| AgonesError::Call(name, e);
        self.grpc.ready().await.map_err(|e| call(e.to_string()))?;
        self.grpc
            .unary(tonic::Request::new(m), path(method), codec())
            .await
            .map(tonic::Response::into_inner)
            .map_err(|s| call(s.message().to_owned()))
    }

    /// `Ready`: the server can take an allocation.
    ///
    /// # Errors
    /// [`AgonesError::Call`].
    pub async fn ready(&mut self) -> Result<(), AgonesError> {
        self.unary::<_, pb::Empty>("Ready", READY, pb::Empty {})
            .await
            .map(drop)
    }

    /// `Shutdown`: the match is over; Agones deletes the pod.
    ///
    /// # Errors
    /// [`AgonesError::Call`].
    pub async fn shutdown(&mut self) -> Result<(), AgonesError> {
        self.unary::<_, pb::Empty>("Shutdown", SHUTDOWN, pb::Empty {})
            .await
            .map(drop)
    }

    /// `GetGameServer`.
    ///
    /// # Errors
    /// [`AgonesError::Call`].
    pub async fn game_server(&mut self) -> Result<pb::GameServer, AgonesError> {
        self.unary("GetGameServer", GET_GAME_SERVER, pb::Empty {})
            .await
    }

    /// `SetAnnotation` (Agones prefixes the key with `agones.dev/sdk-`).
    ///
    /// # Errors
    /// [`AgonesError::Call`].
    pub async fn set_annotation(&mut self, key: &str, value: &str) -> Result<(), AgonesError> {
        let kv = pb::KeyValue {
            key: key.to_owned(),
            value: value.to_owned(),
        };
        self.unary::<_, pb::Empty>("SetAnnotation", SET_ANNOTATION, kv)
            .await
            .map(drop)
    }

    /// `WatchGameServer`: the game server now and after every change.
    ///
    /// # Errors
    /// [`AgonesError::Call`].
    pub async fn watch(&mut self) -> Result<tonic::Streaming<pb::GameServer>, AgonesError> {
        let call = |e: String| AgonesError::Call("WatchGameServer", e);
        self.grpc.ready().await.map_err(|e| call(e.to_string()))?;
        self.grpc
            .server_streaming(
                tonic::Request::new(pb::Empty {}),
                path(WATCH_GAME_SERVER),
                codec(),
            )
            .await
            .map(tonic::Response::into_inner)
            .map_err(|s| call(s.message().to_owned()))
    }

    /// Opens a `Health` stream: each message sent on the returned channel
    /// is one ping. The stream ends (and the channel closes) when the call
    /// fails.
    pub fn health_stream(&self) -> mpsc::Sender<pb::Empty> {
        let (tx, rx) = mpsc::channel(4);
        let mut grpc = self.grpc.clone();
        tokio::spawn(async move {
            if grpc.ready().await.is_err() {
                return;
            }
            let pings = tokio_stream::wrappers::ReceiverStream::new(rx);
            let r = grpc
                .client_streaming::<_, _, pb::Empty, _>(
                    tonic::Request::new(pings),
                    path(HEALTH),
                    codec(),
                )
                .await;
            if let Err(s) = r {
                tracing::warn!("agones: the health stream ended: {}", s.message());
            }
        });
        tx
    }
}

/// Whether the rooms' clocks kept time since the last look: no running
/// room went a whole period without closing a tick, and none closed a tick
/// [`STALL`] late.
pub(crate) fn clocks_healthy(
    running: bool,
    ticks_before: u64,
    ticks_now: u64,
    worst_late: Duration,
) -> bool {
    !(running && ticks_now == ticks_before) && worst_late < STALL
}

/// Connects, calls `Ready`, and starts the health pings and the watch on
/// the allocation. Returns the client, for `Shutdown`.
pub(crate) async fn start(
    shared: &Arc<Shared>,
    settings: &AgonesSettings,
) -> Result<Sdk, AgonesError> {
    let mut sdk = Sdk::connect(&settings.sdk, settings.connect_timeout).await?;
    let watch = sdk.watch().await?;
    tokio::spawn(watch_allocation(shared.clone(), watch));
    sdk.ready().await?;
    tracing::info!("agones: ready (SDK at {})", settings.sdk);
    tokio::spawn(health(shared.clone(), sdk.clone(), settings.health_period));
    Ok(sdk)
}

async fn watch_allocation(shared: Arc<Shared>, mut watch: tonic::Streaming<pb::GameServer>) {
    loop {
        match watch.message().await {
            Ok(Some(gs)) => {
                let Some(alloc) = Allocation::of(&gs) else {
                    continue;
                };
                let mut state = shared.allocation.write().unwrap_or_else(|e| e.into_inner());
                if *state != AllocationState::Waiting {
                    continue;
                }
                let min = lockstep_proto::token::MIN_SECRET_BYTES;
                if let Some(s) = alloc.token_secret.as_ref().filter(|s| s.len() < min) {
                    let why = format!(
                        "the allocation's token secret has {} bytes; at least {min} are needed",
                        s.len()
                    );
                    tracing::error!("agones: {why}; every join is refused");
                    *state = AllocationState::Unusable(why);
                } else {
                    tracing::info!(
                        room = alloc.room.as_deref().unwrap_or("(any)"),
                        tokens = alloc.token_secret.is_some(),
                        "agones: allocated"
                    );
                    *state = AllocationState::Allocated(alloc);
                }
            }
            Ok(None) => break,
            Err(s) => {
                tracing::warn!("agones: the game server watch ended: {}", s.message());
                break;
            }
        }
    }
}

async fn health(shared: Arc<Shared>, sdk: Sdk, period: Duration) {
    let mut ticker = tokio::time::interval(period);
    ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut stream = sdk.health_stream();
    let mut ticks_before = shared.metrics.ticks_closed.load(Ordering::Relaxed);
    let mut shutdown = shared.shutdown.clone();
    loop {
        tokio::select! {
            _ = ticker.tick() => {}
            _ = shutdown.changed() => return,
        }
        let m = &shared.metrics;
        let running = m.matches_running.load(Ordering::Relaxed) > 0;
        let ticks_now = m.ticks_closed.load(Ordering::Relaxed);
        let worst = Duration::from_nanos(m.worst_late_ns.swap(0, Ordering::Relaxed));
        let healthy = clocks_healthy(running, ticks_before, ticks_now, worst);
        ticks_before = ticks_now;
        if !healthy {
            tracing::warn!(
                worst_late_ms = worst.as_secs_f64() * 1000.0,
                "agones: a room's tick clock stalled; no health ping"
            );
            continue;
        }
        if stream.send(pb::Empty {}).await.is_err() {
            // The call ended (the sidecar restarted?): open a new one.
            stream = sdk.health_stream();
            let _ = stream.send(pb::Empty {}).await;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gs(state: &str, ann: &[(&str, &str)], labels: &[(&str, &str)]) -> pb::GameServer {
        let map = |kv: &[(&str, &str)]| {
            kv.iter()
                .map(|(k, v)| ((*k).to_owned(), (*v).to_owned()))
                .collect()
        };
        pb::GameServer {
            object_meta: Some(pb::ObjectMeta {
                name: "gs-1".into(),
                namespace: "default".into(),
                annotations: map(ann),
                labels: map(labels),
            }),
            status: Some(pb::Status {
                state: state.into(),
                address: "10.0.0.1".into(),
            }),
        }
    }

    #[test]
    fn only_an_allocated_game_server_carries_an_allocation() {
        assert_eq!(Allocation::of(&gs("Ready", &[(ROOM_KEY, "a")], &[])), None);
        assert_eq!(Allocation::of(&pb::GameServer::default()), None);
        assert_eq!(
            Allocation::of(&gs("Allocated", &[], &[])),
            Some(Allocation::default())
        );
    }

    #[test]
    fn the_room_comes_from_an_annotation_or_else_a_label_and_the_secret_only_from_an_annotation() {
        let a = Allocation::of(&gs(
            "Allocated",
            &[
                (ROOM_KEY, "match-7"),
                (TOKEN_SECRET_KEY, " 0123456789abcdef0123\n"),
            ],
            &[(ROOM_KEY, "other")],
        ))
        .unwrap();
        assert_eq!(a.room.as_deref(), Some("match-7"));
        assert_eq!(
            a.token_secret.as_deref(),
            Some(&b"0123456789abcdef0123"[..])
        );
        let b = Allocation::of(&gs(
            "Allocated",
            &[],
            &[
                (ROOM_KEY, "from-label"),
                (TOKEN_SECRET_KEY, "not-read-from-labels"),
            ],
        ))
        .unwrap();
        assert_eq!(b.room.as_deref(), Some("from-label"));
        assert_eq!(b.token_secret, None);
    }

    #[test]
    fn a_stalled_or_very_late_clock_is_unhealthy_and_an_idle_server_is_healthy() {
        let ms = Duration::from_millis;
        assert!(clocks_healthy(false, 5, 5, ms(0)), "no match running");
        assert!(clocks_healthy(true, 5, 125, ms(2)), "ticking on time");
        assert!(
            !clocks_healthy(true, 5, 5, ms(0)),
            "a running room closed no tick"
        );
        assert!(
            !clocks_healthy(true, 5, 125, STALL),
            "a tick closed a second late"
        );
        assert!(clocks_healthy(true, 5, 125, STALL - ms(1)));
    }

    #[test]
    fn the_messages_encode_as_the_sdk_proto_says() {
        use prost::Message;
        // KeyValue{key = "k", value = "v"}: field 1 and 2, length-delimited.
        let kv = pb::KeyValue {
            key: "k".into(),
            value: "v".into(),
        };
        assert_eq!(kv.encode_to_vec(), [0x0a, 1, b'k', 0x12, 1, b'v']);
        // GameServer{status{state = "Allocated"}}: field 3 holding field 1.
        let g = pb::GameServer {
            object_meta: None,
            status: Some(pb::Status {
                state: "Allocated".into(),
                address: String::new(),
            }),
        };
        let mut want = vec![0x1a, 11, 0x0a, 9];
        want.extend_from_slice(b"Allocated");
        assert_eq!(g.encode_to_vec(), want);
        // Fields the server does not declare (spec = 2, generation = 5)
        // are skipped when decoding.
        let mut with_spec = vec![0x12, 2, 0x0a, 0];
        with_spec.extend_from_slice(&want);
        with_spec.extend_from_slice(&[0x0a, 2, 0x28, 7]);
        let d = pb::GameServer::decode(&with_spec[..]).unwrap();
        assert_eq!(d.status.unwrap().state, "Allocated");
        assert_eq!(d.object_meta.unwrap(), pb::ObjectMeta::default());
    }
}
