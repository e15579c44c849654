//! # lockstep (the programs)
//!
//! Every program lockstep ships, for any game: a game's `main` is
//!
//! ```no_run
//! use std::process::ExitCode;
//!
//! fn main() -> ExitCode {
//!     // Your RulesFactory and your scene; here the demo's.
//!     lockstep::App::new(lockstep_client::game::Demo, lockstep_client::game::DemoGame::SCENE)
//!         .scene_name("scenes/demo.toml")
//!         .room("demo")
//!         .main()
//! }
//! ```
//!
//! and the binary then has the commands `server` (the match server, with
//! `--demo` for a local match of bots, `--verify` and `--view` with the
//! game's rules), `bots` (headless bots: the game's
//! [`BotPolicy`](lockstep_client::game::BotPolicy) if it has one, else its
//! scripted input), `replay FILE` (a replay or desync bundle re-simulated
//! with the game's rules), `view FILE`, `synctest` (the game's determinism
//! on one machine), `sim` and `tune`. The shipped `lockstep-server`,
//! `lockstep-bot` and `lockstep` binaries are this, with the demo game
//! ([`App::demo`]), one program each.

#![warn(missing_docs)]

pub mod bots;
pub mod demo;
pub mod server;
pub mod tool;
pub mod web;

use std::process::ExitCode;
use std::sync::Arc;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};
use lockstep_client::game::{Demo, DemoGame, RulesFactory};

/// A game's programs (see the crate docs).
#[derive(Clone)]
pub struct App {
    /// The game.
    pub game: Arc<dyn RulesFactory>,
    /// The scene the server sends (TOML).
    pub scene: String,
    /// The scene's name in messages.
    pub scene_name: String,
    /// The room bots join by default.
    pub room: String,
    /// The program's name in its help.
    pub name: String,
    /// How a user runs this program's offline commands, for the hints it
    /// prints (`replay FILE` is appended): the name by default.
    pub tool: String,
    /// The game's browser module, for `server --demo --webtransport ADDR`
    /// to serve beside the page (docs/browser.md): the demo's
    /// `lockstep-web-demo` for [`App::demo`], none by default
    /// ([`App::web_module`]).
    pub web_module: Option<web::ModuleSource>,
}

impl std::fmt::Debug for App {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("App")
            .field("game", &self.game.rules_id())
            .field("scene_name", &self.scene_name)
            .field("room", &self.room)
            .field("name", &self.name)
            .finish_non_exhaustive()
    }
}

/// A game's one program: `NAME <command> ...`.
#[derive(Parser, Debug)]
#[command(version)]
struct GameCli {
    #[command(subcommand)]
    command: GameCommand,
}

#[derive(Subcommand, Debug)]
enum GameCommand {
    /// Run the match server (`--demo`: a local match of the game's bots).
    Server(Box<server::ServerArgs>),
    /// Run headless bots against a server.
    Bots(bots::BotArgs),
    #[command(flatten)]
    Tool(tool::ToolCommand),
}

impl App {
    /// The programs of `game`, whose server sends `scene`; the scene is
    /// named `scene.toml` and bots join room `game` until said otherwise.
    pub fn new(game: impl RulesFactory + 'static, scene: impl Into<String>) -> App {
        let id = game.rules_id().id;
        App {
            game: Arc::new(game),
            scene: scene.into(),
            scene_name: "scene.toml".into(),
            room: "game".into(),
            name: id.clone(),
            tool: id,
            web_module: None,
        }
    }

    /// The demo game's programs (what the shipped binaries run).
    pub fn demo() -> App {
        let mut app = App::new(Demo, DemoGame::SCENE)
            .scene_name("demo")
            .room("demo")
            .name("lockstep");
        app.tool = "cargo run --release -p lockstep --bin lockstep --".into();
        app.web_module = Some(web::ModuleSource::Build(
            lockstep_web::site::ModuleBuild::demo(),
        ));
        app
    }

    /// The game's browser module (a `cdylib` crate whose source is
    /// `lockstep_web::export_client!(MyGame);`, docs/browser.md), built
    /// with cargo when `server --demo --webtransport ADDR` starts and
    /// served with the page.
    pub fn web_module(mut self, build: lockstep_web::site::ModuleBuild) -> App {
        self.web_module = Some(web::ModuleSource::Build(build));
        self
    }

    /// The scene's name in messages and replays.
    pub fn scene_name(mut self, name: impl Into<String>) -> App {
        self.scene_name = name.into();
        self
    }

    /// The room bots join by default.
    pub fn room(mut self, room: impl Into<String>) -> App {
        self.room = room.into();
        self
    }

    /// The program's name in its help and hints.
    pub fn name(mut self, name: impl Into<String>) -> App {
        self.name = name.into();
        self.tool.clone_from(&self.name);
        self
    }

    /// Parses the command line as `NAME <command> ...` and runs the command.
    pub fn main(self) -> ExitCode {
        let name: &'static str = Box::leak(self.name.clone().into_boxed_str());
        let matches = GameCli::command().name(name).get_matches();
        let cli = match GameCli::from_arg_matches(&matches) {
            Ok(c) => c,
            Err(e) => e.exit(),
        };
        match cli.command {
            GameCommand::Server(args) => self.run_server(*args),
            GameCommand::Bots(args) => self.run_bots(args),
            GameCommand::Tool(command) => tool::run_tool(&self, command),
        }
    }

    /// `lockstep-server`'s command line: the server alone.
    pub fn server_main(self) -> ExitCode {
        let args = server::ServerArgs::parse();
        self.run_server(args)
    }

    /// The server configuration `lockstep-server` would run with for
    /// these command-line arguments (the program's name first), without
    /// running it: what the flags and their defaults mean, for tests and
    /// for programs that run the server library themselves.
    ///
    /// # Errors
    /// The flags do not parse, or name a file that cannot be read or a
    /// scene the game's rules refuse.
    pub fn server_config<I, T>(&self, args: I) -> Result<lockstep_server::ServerConfig, String>
    where
        I: IntoIterator<Item = T>,
        T: Into<std::ffi::OsString> + Clone,
    {
        let args = server::ServerArgs::try_parse_from(args).map_err(|e| e.to_string())?;
        server::build_config(self, &args)
    }

    /// `lockstep-bot`'s command line: the bots alone.
    pub fn bots_main(self) -> ExitCode {
        let args = bots::BotArgs::parse();
        self.run_bots(args)
    }

    /// `lockstep`'s command line: the offline tools.
    pub fn tool_main(self) -> ExitCode {
        #[derive(Parser, Debug)]
        #[command(name = "lockstep", version)]
        struct ToolCli {
            #[command(subcommand)]
            command: tool::ToolCommand,
        }
        let cli = ToolCli::parse();
        tool::run_tool(&self, cli.command)
    }

    fn runtime() -> Result<tokio::runtime::Runtime, ExitCode> {
        tokio::runtime::Builder::new_multi_thread()
            .enable_all()
            .build()
            .map_err(|e| {
                eprintln!("cannot start the async runtime: {e}");
                ExitCode::from(2)
            })
    }

    fn run_server(&self, args: server::ServerArgs) -> ExitCode {
        server::init_logging();
        match App::runtime() {
            Ok(rt) => rt.block_on(server::run_server(self, args)),
            Err(code) => code,
        }
    }

    fn run_bots(&self, args: bots::BotArgs) -> ExitCode {
        server::init_logging();
        match App::runtime() {
            Ok(rt) => rt.block_on(bots::run_bot_command(self, args)),
            Err(code) => code,
        }
    }
}
