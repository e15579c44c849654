//! A browser-style build of the core: one `World` behind plain C-ABI
//! exports, no JS glue and no wasm-bindgen, the shape of what a game's own
//! browser module does (docs/own-game.md, "In the browser").
//!
//! ```text
//! cargo build --release -p lockstep-core --example plain_exports --target wasm32-unknown-unknown
//! node scripts/plain-exports-run.mjs target/wasm32-unknown-unknown/release/examples/plain_exports.wasm \
//!     --scene scenes/demo.toml --ticks 100
//! ```
//!
//! A game's own module is a `cdylib` crate; this example is an ordinary
//! (binary) example, whose wasm build exports the `#[unsafe(no_mangle)]`
//! functions just the same (and a `main` that nothing calls), because the
//! cross-architecture check also builds the core's examples for i686 and
//! aarch64 statically linked, where a cdylib cannot be made. Natively, `main`
//! only says how to build it.
//!
//! The module imports nothing (the runner checks): it cannot reach threads,
//! files or clocks. JS passes a scene's text in through linear memory:
//! `lockstep_input(len)` returns where to write `len` bytes, then
//! `lockstep_load_scene(len)` builds the world from them. Each
//! `lockstep_step()` steps one tick and returns the state hash (a `BigInt`
//! in JS); the cross-architecture check compares those with native ones.
//!
//! The exports are not a stable API of the project: a game writes its own,
//! with its inputs and what its renderer needs to read back.

use std::cell::RefCell;

#[path = "support/random_scene.rs"]
mod random_scene;

/// Natively there is nothing to run.
fn main() {
    eprintln!(
        "plain_exports is a wasm module: cargo build --release -p lockstep-core \
         --example plain_exports --target wasm32-unknown-unknown"
    );
}

/// The module's state: one world, the input buffer JS writes into, and the
/// last error message.
#[derive(Default)]
struct State {
    world: Option<lockstep_core::World>,
    input: Vec<u8>,
    error: String,
    faults: u8,
}

thread_local! {
    static STATE: RefCell<State> = RefCell::new(State::default());
}

fn with<R>(f: impl FnOnce(&mut State) -> R) -> R {
    STATE.with(|s| f(&mut s.borrow_mut()))
}

/// Makes the input buffer `len` bytes long (zeroed) and returns where it
/// starts in linear memory; JS writes the scene text there.
#[unsafe(no_mangle)]
pub extern "C" fn lockstep_input(len: usize) -> *mut u8 {
    with(|s| {
        s.input.clear();
        s.input.resize(len, 0);
        s.input.as_mut_ptr()
    })
}

/// Builds the world from the first `len` bytes of the input buffer (a scene
/// file's text). Returns 0, or 1 with a message (`lockstep_error_*`).
#[unsafe(no_mangle)]
pub extern "C" fn lockstep_load_scene(len: usize) -> u32 {
    with(|s| {
        let built = std::str::from_utf8(&s.input[..len.min(s.input.len())])
            .map_err(|e| format!("scene text: {e}"))
            .and_then(|text| {
                lockstep_core::scene::load_world(text, "scene").map_err(|e| e.to_string())
            });
        s.set(built)
    })
}

/// Builds the seeded random scene of the `scene_hashes` example. Returns 0,
/// or 1 with a message.
#[unsafe(no_mangle)]
pub extern "C" fn lockstep_load_random(seed: u64) -> u32 {
    with(|s| {
        let built = random_scene::random_world(seed).map_err(|e| format!("random scene: {e}"));
        s.set(built)
    })
}

impl State {
    fn set(&mut self, built: Result<lockstep_core::World, String>) -> u32 {
        self.faults = 0;
        match built {
            Ok(w) => {
                self.world = Some(w);
                self.error.clear();
                0
            }
            Err(e) => {
                self.world = None;
                self.error = e;
                1
            }
        }
    }
}

/// Steps one tick and returns the state hash after it; 0 if no world is
/// loaded. The step's arithmetic faults are in `lockstep_faults`.
#[unsafe(no_mangle)]
pub extern "C" fn lockstep_step() -> u64 {
    with(|s| match &mut s.world {
        Some(w) => {
            s.faults = w.step().faults.bits();
            w.state_hash()
        }
        None => 0,
    })
}

/// The world's tick (0 before the first step, or if no world is loaded).
#[unsafe(no_mangle)]
pub extern "C" fn lockstep_tick() -> u64 {
    with(|s| s.world.as_ref().map_or(0, |w| w.tick()))
}

/// The arithmetic faults of the last step, as `Faults::bits` (0: none).
#[unsafe(no_mangle)]
pub extern "C" fn lockstep_faults() -> u32 {
    with(|s| u32::from(s.faults))
}

/// Where the last error message (UTF-8) starts in linear memory.
#[unsafe(no_mangle)]
pub extern "C" fn lockstep_error_ptr() -> *const u8 {
    with(|s| s.error.as_ptr())
}

/// The last error message's length in bytes (0: none).
#[unsafe(no_mangle)]
pub extern "C" fn lockstep_error_len() -> usize {
    with(|s| s.error.len())
}
