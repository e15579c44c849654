//! `lockstep-bot`: N headless bots in one process, each a full client that
//! re-simulates every tick and reports every tick's hash, playing the demo.

use std::process::ExitCode;

fn main() -> ExitCode {
    lockstep::App::demo().bots_main()
}
