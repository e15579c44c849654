//! A stand-in for the Agones SDK sidecar: a gRPC server on 127.0.0.1 that
//! implements the SDK service (`agones.dev.sdk.SDK`) the way the sidecar's
//! local mode does, and records every call, so a test can watch what a game
//! server asks of Agones and play the allocator's part.
//!
//! Its messages are declared here from the SDK's `sdk.proto`, independently
//! of the server's own declarations, so a wrong field number on either side
//! shows up as a failed test.
//!
//! - `Ready`, `Allocate`, `Shutdown` set the game server's state;
//! - `Health` counts the pings of each stream;
//! - `GetGameServer` and `WatchGameServer` return the game server (the
//!   watch: now and after every change);
//! - `SetLabel` / `SetAnnotation` store `agones.dev/sdk-<key>`;
//! - [`StandIn::allocate`] does what a `GameServerAllocation` with metadata
//!   does: adds the annotations and moves the state to `Allocated`.

use std::collections::HashMap;
use std::convert::Infallible;
use std::future::Future;
use std::net::SocketAddr;
use std::pin::Pin;
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll};

use tokio::sync::{mpsc, watch};
use tonic::codegen::http;
use tonic::{Request, Response, Status, Streaming};
use tower::service_fn;

/// `agones.dev.sdk` messages.
pub mod pb {
    use std::collections::HashMap;

    /// `Empty`.
    #[derive(Clone, Copy, PartialEq, Eq, prost::Message)]
    pub struct Empty {}

    /// `KeyValue`.
    #[derive(Clone, PartialEq, Eq, prost::Message)]
    pub struct KeyValue {
        /// `key = 1`.
        #[prost(string, tag = "1")]
        pub key: String,
        /// `value = 2`.
        #[prost(string, tag = "2")]
        pub value: String,
    }

    /// `Duration`.
    #[derive(Clone, Copy, PartialEq, Eq, prost::Message)]
    pub struct Duration {
        /// `seconds = 1`.
        #[prost(int64, tag = "1")]
        pub seconds: i64,
    }

    /// `GameServer`.
    #[derive(Clone, PartialEq, prost::Message)]
    pub struct GameServer {
        /// `object_meta = 1`.
        #[prost(message, optional, tag = "1")]
        pub object_meta: Option<ObjectMeta>,
        /// `spec = 2`.
        #[prost(message, optional, tag = "2")]
        pub spec: Option<Spec>,
        /// `status = 3`.
        #[prost(message, optional, tag = "3")]
        pub status: Option<Status>,
    }

    /// `GameServer.ObjectMeta`.
    #[derive(Clone, PartialEq, prost::Message)]
    pub struct ObjectMeta {
        /// `name = 1`.
        #[prost(string, tag = "1")]
        pub name: String,
        /// `namespace = 2`.
        #[prost(string, tag = "2")]
        pub namespace: String,
        /// `uid = 3`.
        #[prost(string, tag = "3")]
        pub uid: String,
        /// `resource_version = 4`.
        #[prost(string, tag = "4")]
        pub resource_version: String,
        /// `generation = 5`.
        #[prost(int64, tag = "5")]
        pub generation: i64,
        /// `creation_timestamp = 6`.
        #[prost(int64, tag = "6")]
        pub creation_timestamp: i64,
        /// `annotations = 8`.
        #[prost(map = "string, string", tag = "8")]
        pub annotations: HashMap<String, String>,
        /// `labels = 9`.
        #[prost(map = "string, string", tag = "9")]
        pub labels: HashMap<String, String>,
    }

    /// `GameServer.Spec`.
    #[derive(Clone, Copy, PartialEq, Eq, prost::Message)]
    pub struct Spec {
        /// `health = 1`.
        #[prost(message, optional, tag = "1")]
        pub health: Option<Health>,
    }

    /// `GameServer.Spec.Health`.
    #[derive(Clone, Copy, PartialEq, Eq, prost::Message)]
    pub struct Health {
        /// `disabled = 1`.
        #[prost(bool, tag = "1")]
        pub disabled: bool,
        /// `period_seconds = 2`.
        #[prost(int32, tag = "2")]
        pub period_seconds: i32,
        /// `failure_threshold = 3`.
        #[prost(int32, tag = "3")]
        pub failure_threshold: i32,
        /// `initial_delay_seconds = 4`.
        #[prost(int32, tag = "4")]
        pub initial_delay_seconds: i32,
    }

    /// `GameServer.Status`.
    #[derive(Clone, PartialEq, prost::Message)]
    pub struct Status {
        /// `state = 1`.
        #[prost(string, tag = "1")]
        pub state: String,
        /// `address = 2`.
        #[prost(string, tag = "2")]
        pub address: String,
    }
}

/// What the game server asked, in order.
#[derive(Clone, Debug, Default)]
pub struct Calls {
    /// Method names, in the order they arrived (`Health` once per stream).
    pub methods: Vec<String>,
    /// Health pings received, over all streams.
    pub health_pings: u64,
}

impl Calls {
    /// How many times `method` was called.
    pub fn count(&self, method: &str) -> usize {
        self.methods.iter().filter(|m| *m == method).count()
    }
}

struct Inner {
    calls: Mutex<Calls>,
    game_server: watch::Sender<pb::GameServer>,
}

/// The stand-in SDK server.
#[derive(Clone)]
pub struct StandIn {
    inner: Arc<Inner>,
}

impl StandIn {
    /// Starts one on a free port of 127.0.0.1; it runs until the runtime
    /// ends. Returns it and its address (`http://127.0.0.1:PORT` for the
    /// client).
    ///
    /// # Panics
    /// If no port can be bound.
    pub async fn start() -> (StandIn, SocketAddr) {
        let gs = pb::GameServer {
            object_meta: Some(pb::ObjectMeta {
                name: "lockstep-standin".into(),
                namespace: "default".into(),
                generation: 1,
                ..Default::default()
            }),
            spec: Some(pb::Spec {
                health: Some(pb::Health {
                    disabled: false,
                    period_seconds: 5,
                    failure_threshold: 3,
                    initial_delay_seconds: 5,
                }),
            }),
            status: Some(pb::Status {
                state: "Scheduled".into(),
                address: "127.0.0.1".into(),
            }),
        };
        let me = StandIn {
            inner: Arc::new(Inner {
                calls: Mutex::new(Calls::default()),
                game_server: watch::channel(gs).0,
            }),
        };
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0")
            .await
            .expect("bind the stand-in");
        let addr = listener.local_addr().expect("its address");
        let incoming = tonic::transport::server::TcpIncoming::from(listener);
        let svc = me.clone();
        tokio::spawn(async move {
            let _ = tonic::transport::Server::builder()
                .serve_with_incoming(svc, incoming)
                .await;
        });
        (me, addr)
    }

    /// Everything asked so far.
    pub fn calls(&self) -> Calls {
        self.inner
            .calls
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }

    /// The game server as it stands.
    pub fn game_server(&self) -> pb::GameServer {
        self.inner.game_server.borrow().clone()
    }

    /// Its state (`Scheduled`, `Ready`, `Allocated`, `Shutdown`).
    pub fn state(&self) -> String {
        self.game_server()
            .status
            .map(|s| s.state)
            .unwrap_or_default()
    }

    /// Allocates the game server with these annotations, as a
    /// `GameServerAllocation` with `metadata.annotations` does.
    pub fn allocate(&self, annotations: &[(&str, &str)]) {
        self.inner.game_server.send_modify(|gs| {
            let meta = gs.object_meta.get_or_insert_with(Default::default);
            for (k, v) in annotations {
                meta.annotations.insert((*k).to_owned(), (*v).to_owned());
            }
            set_state(gs, "Allocated");
        });
    }

    fn record(&self, method: &str) {
        self.inner
            .calls
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .methods
            .push(method.to_owned());
    }

    fn set_state(&self, state: &str) {
        self.inner
            .game_server
            .send_modify(|gs| set_state(gs, state));
    }

    fn set_meta(&self, label: bool, kv: pb::KeyValue) {
        self.inner.game_server.send_modify(|gs| {
            let meta = gs.object_meta.get_or_insert_with(Default::default);
            let map: &mut HashMap<String, String> = if label {
                &mut meta.labels
            } else {
                &mut meta.annotations
            };
            map.insert(format!("agones.dev/sdk-{}", kv.key), kv.value);
        });
    }

    async fn handle(
        self,
        method: &str,
        req: http::Request<tonic::body::Body>,
    ) -> http::Response<tonic::body::Body> {
        self.record(method);
        let ok = || Ok::<_, Status>(Response::new(pb::Empty {}));
        match method {
            "Ready" | "Allocate" | "Shutdown" => {
                let state = match method {
                    "Ready" => "Ready",
                    "Allocate" => "Allocated",
                    _ => "Shutdown",
                };
                let me = self.clone();
                let svc = service_fn(move |_: Request<pb::Empty>| {
                    me.set_state(state);
                    std::future::ready(ok())
                });
                grpc::<pb::Empty, pb::Empty>().unary(svc, req).await
            }
            "Health" => {
                let me = self.clone();
                let svc = service_fn(move |r: Request<Streaming<pb::Empty>>| {
                    let me = me.clone();
                    async move {
                        let mut pings = r.into_inner();
                        while let Ok(Some(_)) = pings.message().await {
                            me.inner
                                .calls
                                .lock()
                                .unwrap_or_else(|e| e.into_inner())
                                .health_pings += 1;
                        }
                        ok()
                    }
                });
                grpc::<pb::Empty, pb::Empty>()
                    .client_streaming(svc, req)
                    .await
            }
            "GetGameServer" => {
                let gs = self.game_server();
                let svc = service_fn(move |_: Request<pb::Empty>| {
                    std::future::ready(Ok::<_, Status>(Response::new(gs.clone())))
                });
                grpc::<pb::GameServer, pb::Empty>().unary(svc, req).await
            }
            "WatchGameServer" => {
                let rx = self.inner.game_server.subscribe();
                let svc = service_fn(move |_: Request<pb::Empty>| {
                    let (tx, out) = mpsc::channel(16);
                    let mut rx = rx.clone();
                    tokio::spawn(async move {
                        loop {
                            let gs = rx.borrow_and_update().clone();
                            if tx.send(Ok::<_, Status>(gs)).await.is_err()
                                || rx.changed().await.is_err()
                            {
                                break;
                            }
                        }
                    });
                    std::future::ready(Ok::<_, Status>(Response::new(
                        tokio_stream::wrappers::ReceiverStream::new(out),
                    )))
                });
                grpc::<pb::GameServer, pb::Empty>()
                    .server_streaming(svc, req)
                    .await
            }
            "SetLabel" | "SetAnnotation" => {
                let me = self.clone();
                let label = method == "SetLabel";
                let svc = service_fn(move |r: Request<pb::KeyValue>| {
                    me.set_meta(label, r.into_inner());
                    std::future::ready(ok())
                });
                grpc::<pb::Empty, pb::KeyValue>().unary(svc, req).await
            }
            "Reserve" => {
                let svc = service_fn(move |_: Request<pb::Duration>| std::future::ready(ok()));
                grpc::<pb::Empty, pb::Duration>().unary(svc, req).await
            }
            other => Status::unimplemented(format!("the stand-in has no {other}")).into_http(),
        }
    }
}

fn set_state(gs: &mut pb::GameServer, state: &str) {
    gs.status.get_or_insert_with(Default::default).state = state.to_owned();
}

/// A server-side gRPC codec sending `E` and receiving `D`.
fn grpc<E, D>() -> tonic::server::Grpc<tonic_prost::ProstCodec<E, D>>
where
    E: prost::Message + Send + 'static,
    D: prost::Message + Default + Send + 'static,
{
    tonic::server::Grpc::new(tonic_prost::ProstCodec::default())
}

impl tower::Service<http::Request<tonic::body::Body>> for StandIn {
    type Response = http::Response<tonic::body::Body>;
    type Error = Infallible;
    type Future = Pin<Box<dyn Future<Output = Result<Self::Response, Infallible>> + Send>>;

    fn poll_ready(&mut self, _: &mut Context<'_>) -> Poll<Result<(), Infallible>> {
        Poll::Ready(Ok(()))
    }

    fn call(&mut self, req: http::Request<tonic::body::Body>) -> Self::Future {
        let me = self.clone();
        Box::pin(async move {
            let method = req
                .uri()
                .path()
                .strip_prefix("/agones.dev.sdk.SDK/")
                .unwrap_or("?")
                .to_owned();
            Ok(me.handle(&method, req).await)
        })
    }
}

impl tonic::server::NamedService for StandIn {
    const NAME: &'static str = "agones.dev.sdk.SDK";
}
