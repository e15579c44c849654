//! `lockstep`: the offline command-line tool, with the demo game.

use std::process::ExitCode;

fn main() -> ExitCode {
    lockstep::App::demo().tool_main()
}
