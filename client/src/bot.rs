//! Headless bots: clients that play scripted input and re-simulate every
//! tick, for load tests, the demo and the end-to-end tests.
//!
//! Each bot is a full [`Client`]: it builds the world from the welcome,
//! applies every bundle through the game rules, steps, and reports every
//! tick's hash. Its input is [`bot_input`]`(seed, slot, tick)`, a pure
//! function, so a match between bots is reproducible from the seed.

use std::future::Future;
use std::net::SocketAddr;
use std::path::PathBuf;

use tokio::sync::watch;

use crate::game::bot_input;
use crate::net::{Client, ClientError, ClientEvent, ClientOptions, ClientReport};

/// What a group of bots should do.
#[derive(Clone, Debug)]
pub struct BotOptions {
    /// The server's address.
    pub server: SocketAddr,
    /// Certificate file to trust.
    pub cert: PathBuf,
    /// Room to join.
    pub room: String,
    /// Number of bots (each its own QUIC connection and UDP socket).
    pub count: usize,
    /// Seed of the scripted input.
    pub seed: u64,
    /// Leave after this many ticks (`None`: until the server ends the match).
    pub ticks: Option<u64>,
    /// Test hook: bot `index` (0-based, in connection order) diverges at
    /// `tick` (see [`ClientOptions::diverge_at`]).
    pub diverge: Option<(usize, u64)>,
    /// Print desync notices and closes to stderr as they happen.
    pub verbose: bool,
}

impl BotOptions {
    /// `count` bots for `room` on `server`, trusting `cert`, seed 1, playing
    /// until the match ends.
    pub fn new(
        server: SocketAddr,
        cert: impl Into<PathBuf>,
        room: impl Into<String>,
        count: usize,
    ) -> Self {
        Self {
            server,
            cert: cert.into(),
            room: room.into(),
            count,
            seed: 1,
            ticks: None,
            diverge: None,
            verbose: false,
        }
    }

    /// The client options of bot `index`.
    pub fn client_options(&self, index: usize) -> ClientOptions {
        let mut o = ClientOptions::new(
            self.server,
            self.cert.clone(),
            self.room.clone(),
            format!("bot-{index}"),
        );
        o.max_ticks = self.ticks;
        o.diverge_at = self
            .diverge
            .and_then(|(i, tick)| (i == index).then_some(tick));
        o
    }
}

/// Connects one bot and plays with scripted input until the match ends, its
/// tick budget is spent, or `stop` fires.
///
/// # Errors
/// [`ClientError`] from connecting or playing.
pub async fn run_bot(
    options: ClientOptions,
    seed: u64,
    verbose: bool,
    stop: impl Future<Output = ()> + Send,
) -> Result<ClientReport, ClientError> {
    let name = options.player_name.clone();
    let client = Client::connect(options).await?;
    let slot = client.slot().0;
    client
        .play(
            move |tick| bot_input(seed, slot, tick).encode(),
            move |event| {
                if verbose {
                    match event {
                        ClientEvent::Desync { notice, local_hash } => eprintln!(
                            "{name} (slot {slot}): desync at tick {}: {:?}, mine {:?}",
                            notice.tick, notice.verdict, local_hash
                        ),
                        ClientEvent::Closed(c) => {
                            eprintln!("{name} (slot {slot}): closed: {:?}: {}", c.reason, c.detail)
                        }
                        ClientEvent::Fault { tick, faults } => {
                            eprintln!("{name} (slot {slot}): fault at tick {tick}: {faults}")
                        }
                    }
                }
            },
            stop,
        )
        .await
}

/// Runs `options.count` bots concurrently (connecting one after the other,
/// so slots follow the index) until each one ends; `stop` makes them all
/// leave. Returns each bot's outcome in index order.
pub async fn run_bots(
    options: &BotOptions,
    stop: impl Future<Output = ()> + Send,
) -> Vec<Result<ClientReport, ClientError>> {
    let (stop_tx, stop_rx) = watch::channel(false);
    let mut tasks = Vec::with_capacity(options.count);
    for index in 0..options.count {
        let client_options = options.client_options(index);
        let mut rx = stop_rx.clone();
        let (seed, verbose) = (options.seed, options.verbose);
        // Connect in order so bot i gets slot i in an empty room.
        let client = Client::connect(client_options).await;
        tasks.push(tokio::spawn(async move {
            let client = client?;
            let slot = client.slot().0;
            let stop = async move {
                let _ = rx.wait_for(|s| *s).await;
            };
            let name = format!("bot-{index}");
            client
                .play(
                    move |tick| bot_input(seed, slot, tick).encode(),
                    move |event| {
                        if verbose {
                            eprintln!("{name} (slot {slot}): {event:?}");
                        }
                    },
                    stop,
                )
                .await
        }));
    }
    let all = async {
        let mut out = Vec::with_capacity(tasks.len());
        for t in tasks {
            out.push(match t.await {
                Ok(r) => r,
                Err(e) => Err(ClientError::ConnectionLost(format!("bot task failed: {e}"))),
            });
        }
        out
    };
    tokio::pin!(all);
    tokio::pin!(stop);
    tokio::select! {
        out = &mut all => out,
        () = &mut stop => {
            let _ = stop_tx.send(true);
            all.await
        }
    }
}
