//! A server in the test's runtime, and checks of bot reports, for the
//! end-to-end tests.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

use lockstep_client::game::{Demo, DemoGame, RulesFactory};
use lockstep_client::net::ClientReport;
use lockstep_server::{ServerConfig, ServerError, ServerEvent, ServerReport, TlsSource, run};
use tokio::sync::{mpsc, oneshot};
use tokio::task::JoinHandle;

/// A server running in the test's runtime.
pub struct TestServer {
    /// The server's UDP address.
    pub addr: SocketAddr,
    /// The metrics listener, if configured.
    pub metrics: Option<SocketAddr>,
    /// Its dev certificate, for clients to trust.
    pub cert: PathBuf,
    /// What it reports.
    pub events: mpsc::UnboundedReceiver<ServerEvent>,
    /// Completing it stops the server.
    pub stop: Option<oneshot::Sender<()>>,
    /// The server's task.
    pub task: JoinHandle<Result<ServerReport, ServerError>>,
}

impl TestServer {
    /// Starts a demo-game server on a free port of 127.0.0.1 with its
    /// certificate and replays in `dir` (emptied first), after `tweak`.
    pub async fn start(dir: PathBuf, tweak: impl FnOnce(&mut ServerConfig)) -> TestServer {
        let _ = std::fs::remove_dir_all(&dir);
        let mut config = ServerConfig::for_game(
            SocketAddr::from(([127, 0, 0, 1], 0)),
            DemoGame::SCENE,
            "demo",
            Demo.rules_id(),
        );
        config.tls = TlsSource::dev(dir.join("cert.pem"));
        config.replay_dir = Some(dir.join("replays"));
        let (tx, mut events) = mpsc::unbounded_channel();
        config.events = Some(tx);
        tweak(&mut config);
        let (stop, stop_rx) = oneshot::channel::<()>();
        let task = tokio::spawn(run(config, async {
            let _ = stop_rx.await;
        }));
        let mut metrics = None;
        let (addr, cert) = loop {
            match events.recv().await.expect("server stopped at start-up") {
                ServerEvent::Listening { addr, cert } => break (addr, cert.expect("dev cert")),
                ServerEvent::MetricsListening { addr } => metrics = Some(addr),
                _ => continue,
            }
        };
        TestServer {
            addr,
            metrics,
            cert,
            events,
            stop: Some(stop),
            task,
        }
    }

    /// As [`start`](Self::start), with a WebTransport endpoint on a free
    /// port of 127.0.0.1 beside the QUIC one; returns the server with that
    /// endpoint's address and certificate hash
    /// ([`ServerEvent::WebTransportListening`]).
    pub async fn start_webtransport(
        dir: PathBuf,
        tweak: impl FnOnce(&mut ServerConfig),
    ) -> (TestServer, SocketAddr, [u8; 32]) {
        let mut server = TestServer::start(dir, |c| {
            c.webtransport = Some(SocketAddr::from(([127, 0, 0, 1], 0)));
            tweak(c);
        })
        .await;
        let (addr, hash) = server
            .wait_for(Duration::from_secs(5), |e| match e {
                ServerEvent::WebTransportListening { addr, cert_sha256 } => {
                    Some((*addr, *cert_sha256))
                }
                _ => None,
            })
            .await;
        assert_ne!(addr.port(), 0);
        assert_ne!(addr, server.addr, "its own port, beside the QUIC one");
        (server, addr, hash)
    }

    /// Waits for an event matching `pick`, up to `timeout`.
    pub async fn wait_for<T>(
        &mut self,
        timeout: Duration,
        mut pick: impl FnMut(&ServerEvent) -> Option<T>,
    ) -> T {
        tokio::time::timeout(timeout, async {
            loop {
                let e = self.events.recv().await.expect("server events ended");
                if let Some(t) = pick(&e) {
                    return t;
                }
            }
        })
        .await
        .expect("timed out waiting for a server event")
    }

    /// Waits up to `timeout` for the next match's end and returns its
    /// report.
    pub async fn match_end(&mut self, timeout: Duration) -> lockstep_server::RoomReport {
        self.wait_for(timeout, |e| match e {
            ServerEvent::MatchEnded(r) => Some(r.clone()),
            _ => None,
        })
        .await
    }

    /// Stops the server and returns its report.
    pub async fn shutdown(mut self) -> ServerReport {
        if let Some(s) = self.stop.take() {
            let _ = s.send(());
        }
        tokio::time::timeout(Duration::from_secs(15), self.task)
            .await
            .expect("server did not shut down in 15 s")
            .expect("server task")
            .expect("server run")
    }
}

/// The bots' reports, panicking on the first that failed.
pub fn bots_ok(
    results: Vec<Result<ClientReport, lockstep_client::net::ClientError>>,
) -> Vec<ClientReport> {
    results
        .into_iter()
        .enumerate()
        .map(|(i, r)| r.unwrap_or_else(|e| panic!("bot {i}: {e}")))
        .collect()
}

/// Every bot reported the same hash for every tick it applied.
pub fn assert_same_hashes(bots: &[ClientReport], ticks: usize) {
    for b in bots {
        assert_eq!(
            b.hashes.len(),
            ticks,
            "slot {} applied {} ticks",
            b.slot.0,
            b.hashes.len()
        );
    }
    for t in 0..ticks {
        let h = bots[0].hashes[t];
        for b in &bots[1..] {
            assert_eq!(
                b.hashes[t], h,
                "tick {t}: slot {} differs from slot 0",
                b.slot.0
            );
        }
    }
}
