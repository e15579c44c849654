//! # lockstep-tools
//!
//! The offline tools behind the `lockstep` CLI, for any game's rules: run a
//! scene file without a server ([`run_sim`]), verify a replay
//! ([`verify_replay_file`]) or reproduce a desync bundle
//! ([`reproduce_bundle`]), the sync test ([`sync_test`]), tune a scene's
//! settings ([`tune`], with its SVG plots), and load a scene, replay or
//! bundle into the browser viewer ([`view`]). They were the client
//! library's `offline` and `view` modules; the client library itself does
//! not need them.

#![warn(missing_docs)]

mod bundle;
mod dump;
mod replay;
mod sim;
mod synctest;
pub mod tune;
pub mod view;

pub use bundle::{BundleCheck, is_bundle, reproduce_bundle};
pub use dump::{BodyDump, StateDump, dump_state};
pub use replay::{
    BodiesAt, BodyDiff, ReplayCheck, ReplayVerifyError, apply_bundle, check_header,
    check_replay_command, exit_status, match_world, recorded_world, verify_replay,
    verify_replay_file,
};
pub use sim::{SimError, SimOptions, SimSummary, load_scene_file, run_sim};
pub use synctest::{SyncCheck, SyncTestError, SyncTestOptions, SyncTestReport, sync_test};
