//! Offline tools: run a scene file without a server.

mod dump;
mod sim;

pub use dump::{BodyDump, StateDump, dump_state};
pub use sim::{SimError, SimOptions, SimSummary, load_scene_file, run_sim};
