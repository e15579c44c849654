//! Test hooks (feature `test-hooks`): ways to make a peer misbehave on
//! purpose, kept out of the options a game uses.

use std::sync::Arc;

use lockstep_core::{BodyKind, Scalar, Vec3, World};

use crate::game::{GameError, GameRules, GameState, GameStateError, RulesFactory, RulesId};

/// Another game's rules plus one ulp more x velocity on the first dynamic
/// body right before the inputs of `tick`: a peer playing these diverges
/// from the others exactly at `tick`. Claims the wrapped game's id.
#[derive(Clone)]
pub struct Diverge {
    /// The game played otherwise.
    pub inner: Arc<dyn RulesFactory>,
    /// The tick the nudge happens before.
    pub tick: u64,
}

impl std::fmt::Debug for Diverge {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Diverge")
            .field("inner", &self.inner.rules_id())
            .field("tick", &self.tick)
            .finish()
    }
}

struct DivergeRules {
    inner: Box<dyn GameRules>,
    tick: u64,
}

impl GameRules for DivergeRules {
    fn apply_inputs(&mut self, world: &mut World, tick: u64, inputs: &[(u8, &[u8])]) {
        if tick == self.tick {
            nudge_one_body(world);
        }
        self.inner.apply_inputs(world, tick, inputs);
    }
    fn save_state(&self, state: &mut GameState) -> Result<(), GameStateError> {
        self.inner.save_state(state)
    }
    fn load_state(&mut self, state: &GameState) -> Result<(), GameError> {
        self.inner.load_state(state)
    }
    fn player_joined(&mut self, world: &mut World, tick: u64, slot: u8) {
        self.inner.player_joined(world, tick, slot);
    }
    fn player_left(&mut self, world: &mut World, tick: u64, slot: u8) {
        self.inner.player_left(world, tick, slot);
    }
}

impl RulesFactory for Diverge {
    fn rules_id(&self) -> RulesId {
        self.inner.rules_id()
    }
    fn new_rules(&self, world: &World) -> Result<Box<dyn GameRules>, GameError> {
        Ok(Box::new(DivergeRules {
            inner: self.inner.new_rules(world)?,
            tick: self.tick,
        }))
    }
    fn bot_input(&self, seed: u64, slot: u8, tick: u64) -> Vec<u8> {
        self.inner.bot_input(seed, slot, tick)
    }
    fn bot_policy(&self, seed: u64, slot: u8) -> Option<Box<dyn crate::game::BotPolicy>> {
        self.inner.bot_policy(seed, slot)
    }
    fn input_predictor(&self) -> Option<Box<dyn crate::net::InputPredictor>> {
        self.inner.input_predictor()
    }
}

/// One ulp more x velocity on the first dynamic body.
fn nudge_one_body(world: &mut World) {
    let target = world
        .body_handles()
        .find(|&h| world.body(h).is_ok_and(|b| b.kind() == BodyKind::Dynamic));
    if let Some(h) = target
        && let Ok(b) = world.body(h)
    {
        let v = b.linear_velocity();
        let nudged = Vec3::new(v.x + Scalar::DELTA, v.y, v.z);
        let _ = world.set_linear_velocity(h, nudged);
    }
}

/// `reply` as the client's test hooks make it: with
/// [`ClientOptions::corrupt_snapshots`](crate::net::ClientOptions::corrupt_snapshots),
/// every byte of a snapshot piece inverted (a giver that answers a
/// joiner's snapshot probe with garbage).
pub(crate) fn hook_reply(
    mut reply: lockstep_proto::ProbeReply,
    options: &crate::net::ClientOptions,
) -> lockstep_proto::ProbeReply {
    if options.corrupt_snapshots
        && let lockstep_proto::ProbeAnswer::Snapshot { bytes, .. } = &mut reply.answer
    {
        for b in bytes.iter_mut() {
            *b = !*b;
        }
    }
    reply
}
