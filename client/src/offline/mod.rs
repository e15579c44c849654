//! Offline tools: run a scene file without a server, verify a replay, tune
//! a scene's settings.

mod bundle;
mod dump;
mod replay;
mod sim;
mod synctest;
pub mod tune;

pub use bundle::{BundleCheck, is_bundle, reproduce_bundle};
pub use dump::{BodyDump, StateDump, dump_state};
pub use replay::{
    BodiesAt, BodyDiff, ReplayCheck, ReplayVerifyError, apply_bundle, check_header,
    check_replay_command, exit_status, match_world, recorded_world, verify_replay,
    verify_replay_file,
};
pub use sim::{SimError, SimOptions, SimSummary, load_scene_file, run_sim};
pub use synctest::{SyncCheck, SyncTestError, SyncTestOptions, SyncTestReport, sync_test};
