//! The example game's one program: its server (`server`, with `--demo`,
//! `--verify` and `--view` on its own rules), its bots (`bots`, the
//! [`ChaseBot`](lockstep_example_game::ChaseBot) policy), and the offline
//! commands (`replay`, `view`, `synctest`, `sim`, `tune`).

use std::process::ExitCode;

use lockstep_example_game::{PaddleGame, SCENE};

fn main() -> ExitCode {
    lockstep::App::new(PaddleGame, SCENE)
        .scene_name("example-game/scene.toml")
        .room("table")
        .name("example-game")
        .main()
}
