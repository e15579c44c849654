//! Bots that see: a policy chooses a bot's input from the world, the
//! rules (and through them the game's own state) and its slot.

use lockstep_core::World;

use super::GameRules;

/// What a bot sees when it chooses an input: the world after the last
/// tick it applied, the rules it plays with, its slot, and the tick the
/// input is for (a few ticks ahead of the world: the input delay).
pub struct BotView<'a> {
    /// The world after the last applied tick.
    pub world: &'a World,
    /// The rules (read the game's state with
    /// [`downcast_ref`](GameRules::downcast_ref) or from
    /// [`World::game_state`]).
    pub rules: &'a dyn GameRules,
    /// The bot's slot.
    pub slot: u8,
    /// The tick the input will apply to.
    pub tick: u64,
}

/// A bot that plays: asked for an input every tick, with what it sees.
/// Unlike [`RulesFactory::bot_input`](super::RulesFactory::bot_input) it
/// may keep its own memory and read the world; its inputs are still
/// relayed like a player's, so matches stay checked, though they are no
/// longer a pure function of the seed (a bot sees the world as far as it
/// got, which depends on timing).
pub trait BotPolicy: Send {
    /// The input for `view.tick`.
    fn input(&mut self, view: &BotView<'_>) -> Vec<u8>;
}

impl<F: FnMut(&BotView<'_>) -> Vec<u8> + Send> BotPolicy for F {
    fn input(&mut self, view: &BotView<'_>) -> Vec<u8> {
        self(view)
    }
}
