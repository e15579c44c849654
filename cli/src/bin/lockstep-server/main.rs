//! `lockstep-server`: the match server, with the demo game (`--demo`: the
//! README's main job).

use std::process::ExitCode;

fn main() -> ExitCode {
    lockstep::App::demo().server_main()
}
