//! Headless bots: clients that play and re-simulate every tick, for load
//! tests, the demo, a game's own test matches and the end-to-end tests.
//!
//! Each bot is a full [`Client`]: it builds the world from the welcome,
//! applies every bundle through the game rules, steps, and reports every
//! tick's hash. It plays any game: its rules and its input come from a
//! [`RulesFactory`]: the game's [`BotPolicy`](crate::game::BotPolicy) for
//! its slot when it has one (a bot that sees the world, the rules and its
//! slot), else [`RulesFactory::bot_input`]`(seed, slot, tick)` (a pure
//! function, so a match between such blind bots is reproducible from the
//! seed).

use std::future::Future;
use std::net::SocketAddr;
use std::sync::Arc;

use tokio::sync::watch;

use crate::game::{BotView, Demo, RulesFactory};
use crate::net::{Client, ClientError, ClientEvent, ClientOptions, ClientReport, TrustedCert};

/// What a group of bots should do.
#[derive(Clone)]
pub struct BotOptions {
    /// The server's address.
    pub server: SocketAddr,
    /// Certificate to trust.
    pub cert: TrustedCert,
    /// Room to join.
    pub room: String,
    /// Number of bots (each its own QUIC connection and UDP socket).
    pub count: usize,
    /// Seed of the scripted input.
    pub seed: u64,
    /// Leave after this many ticks (`None`: until the server ends the match).
    pub ticks: Option<u64>,
    /// The game every bot plays (rules and scripted input).
    pub game: Arc<dyn RulesFactory>,
    /// Bots that play with other rules than `game`: (bot index, 0-based in
    /// connection order; its rules). A bot with wrong rules is how a test
    /// makes one peer desync on purpose (see `testing::Diverge` with the
    /// `test-hooks` feature).
    pub game_of_bot: Vec<(usize, Arc<dyn RulesFactory>)>,
    /// Body hashes with every K-th tick's report (0: never); see
    /// [`ClientOptions::body_hashes_every`].
    pub body_hashes_every: u64,
    /// Join tokens, bot `i` presenting `tokens[i]` (none past the list).
    pub tokens: Vec<String>,
    /// Print desync notices and closes to stderr as they happen.
    pub verbose: bool,
    /// Bots predict and roll back ([`ClientOptions::predict`]).
    pub predict: bool,
    /// Where predicting bots count their rollbacks as they happen.
    pub tally: Option<Arc<crate::net::PredictionTally>>,
}

impl std::fmt::Debug for BotOptions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BotOptions")
            .field("server", &self.server)
            .field("room", &self.room)
            .field("count", &self.count)
            .field("seed", &self.seed)
            .field("ticks", &self.ticks)
            .field("game", &self.game.rules_id())
            .finish_non_exhaustive()
    }
}

impl BotOptions {
    /// `count` bots playing the demo ([`Demo`]) in `room` on `server`,
    /// trusting `cert`, seed 1, until the match ends.
    pub fn new(
        server: SocketAddr,
        cert: impl Into<TrustedCert>,
        room: impl Into<String>,
        count: usize,
    ) -> Self {
        Self::for_game(server, cert, room, count, Arc::new(Demo))
    }

    /// `count` bots playing `game` in `room` on `server`, trusting `cert`,
    /// seed 1, until the match ends.
    pub fn for_game(
        server: SocketAddr,
        cert: impl Into<TrustedCert>,
        room: impl Into<String>,
        count: usize,
        game: Arc<dyn RulesFactory>,
    ) -> Self {
        Self {
            server,
            cert: cert.into(),
            room: room.into(),
            count,
            seed: 1,
            ticks: None,
            game,
            game_of_bot: Vec::new(),
            body_hashes_every: 0,
            tokens: Vec::new(),
            verbose: false,
            predict: false,
            tally: None,
        }
    }

    /// The game bot `index` plays.
    pub fn game_of(&self, index: usize) -> Arc<dyn RulesFactory> {
        self.game_of_bot
            .iter()
            .find(|(i, _)| *i == index)
            .map_or_else(|| self.game.clone(), |(_, g)| g.clone())
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
        o.body_hashes_every = self.body_hashes_every;
        o.token = self.tokens.get(index).cloned();
        o.predict = self.predict;
        o
    }
}

/// Connects one bot playing `game` and plays with its scripted input until
/// the match ends, its tick budget is spent, or `stop` fires.
///
/// # Errors
/// [`ClientError`] from connecting or playing.
pub async fn run_bot(
    options: ClientOptions,
    game: Arc<dyn RulesFactory>,
    seed: u64,
    verbose: bool,
    stop: impl Future<Output = ()> + Send,
) -> Result<ClientReport, ClientError> {
    let name = options.player_name.clone();
    let client = Client::connect(options, &*game).await?;
    let slot = client.slot().0;
    client
        .play_seeing(
            bot_brain(game.clone(), seed, slot),
            move |event| {
                if verbose {
                    match event {
                        ClientEvent::Desync { notice, local_hash } => tracing::warn!(
                            player = %name,
                            slot,
                            "{name} (slot {slot}): desync at tick {}: {:?}, mine {:?}",
                            notice.tick,
                            notice.verdict,
                            local_hash
                        ),
                        ClientEvent::Closed(c) => {
                            tracing::info!(player = %name, slot, "{name} (slot {slot}): closed: {:?}: {}", c.reason, c.detail)
                        }
                        ClientEvent::Fault { tick, faults } => {
                            tracing::warn!(player = %name, slot, "{name} (slot {slot}): fault at tick {tick}: {faults}")
                        }
                        ClientEvent::Rollback(_) => {}
                        ClientEvent::DesyncLocated(r) => {
                            tracing::warn!(player = %name, slot, "{name} (slot {slot}): {r}")
                        }
                    }
                }
            },
            stop,
        )
        .await
}

/// A bot's input: the game's [`BotPolicy`](crate::game::BotPolicy) for
/// its slot if it has one, else its scripted
/// [`bot_input`](RulesFactory::bot_input).
fn bot_brain(
    game: Arc<dyn RulesFactory>,
    seed: u64,
    slot: u8,
) -> impl FnMut(&BotView<'_>) -> Vec<u8> + Send + 'static {
    let mut policy = game.bot_policy(seed, slot);
    move |view| match &mut policy {
        Some(p) => p.input(view),
        None => game.bot_input(seed, slot, view.tick),
    }
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
        let tally = options.tally.clone();
        let game = options.game_of(index);
        // Connect in order so bot i gets slot i in an empty room.
        let client = Client::connect(client_options, &*game).await;
        tasks.push(tokio::spawn(async move {
            let client = client?;
            let slot = client.slot().0;
            let stop = async move {
                let _ = rx.wait_for(|s| *s).await;
            };
            let name = format!("bot-{index}");
            client
                .play_seeing(
                    bot_brain(game.clone(), seed, slot),
                    move |event| {
                        if let ClientEvent::Rollback(r) = event {
                            if let Some(t) = &tally {
                                t.add(r);
                            }
                            return;
                        }
                        if verbose {
                            tracing::info!(player = %name, slot, "{name} (slot {slot}): {event:?}");
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
