//! What a game adds for its browser client: how the keys a player holds
//! become its input bytes ([`WebGame`]), and which body is the player's.

use lockstep_client::game::{BotView, Demo, DemoInput, RulesFactory};
use lockstep_core::{BodyHandle, World};

/// The keys a player holds, as the page reports them: one bit per game key,
/// each bound to two keyboard keys (`web/page/client.js`, `KEYS`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Keys(pub u32);

impl Keys {
    /// Arrow up or W.
    pub const UP: u32 = 1;
    /// Arrow down or S.
    pub const DOWN: u32 = 1 << 1;
    /// Arrow left or A.
    pub const LEFT: u32 = 1 << 2;
    /// Arrow right or D.
    pub const RIGHT: u32 = 1 << 3;
    /// Space.
    pub const JUMP: u32 = 1 << 4;
    /// Enter or E.
    pub const ACTION: u32 = 1 << 5;
    /// Either Shift.
    pub const ALT: u32 = 1 << 6;

    /// Whether `key` (one of the constants) is held.
    pub fn held(self, key: u32) -> bool {
        self.0 & key != 0
    }

    /// −1, 0 or 1 along an axis whose ends are `negative` and `positive`
    /// (0 when both or neither are held).
    pub fn axis(self, negative: u32, positive: u32) -> i8 {
        i8::from(self.held(positive)) - i8::from(self.held(negative))
    }
}

/// A game as its browser client sees it: its rules (the [`RulesFactory`]
/// every peer uses, so the browser simulates exactly what the native
/// clients do) and what only a page with a keyboard needs.
///
/// The input must be a pure function of what it is given (the keys and
/// the view): it is chosen in the browser and relayed to every peer as
/// bytes, like a native client's.
pub trait WebGame: RulesFactory {
    /// The input bytes for the tick `view.tick` while `keys` are held.
    fn keys_input(&self, keys: Keys, view: &BotView<'_>) -> Vec<u8>;

    /// The body of the player in `slot`, if the game has one per player:
    /// the page marks it. Default: none.
    fn player_body(&self, world: &World, slot: u8) -> Option<BodyHandle> {
        let _ = (world, slot);
        None
    }
}

/// The demo: the arrows (or WASD) walk along the world's axes at full
/// speed (up is −z, away from the page's camera; diagonals at 71 %, so
/// no direction is faster), space jumps.
impl WebGame for Demo {
    fn keys_input(&self, keys: Keys, _view: &BotView<'_>) -> Vec<u8> {
        let x = keys.axis(Keys::LEFT, Keys::RIGHT);
        let z = keys.axis(Keys::UP, Keys::DOWN);
        let speed = if x != 0 && z != 0 { 71 } else { 100 };
        DemoInput {
            move_x: x * speed,
            move_z: z * speed,
            jump: keys.held(Keys::JUMP),
        }
        .encode()
    }

    fn player_body(&self, world: &World, slot: u8) -> Option<BodyHandle> {
        world.find_body(&format!("player{slot}"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lockstep_client::game::DemoGame;

    #[test]
    fn the_demo_walks_with_the_arrows_and_jumps_with_space() {
        let world = DemoGame::world().unwrap();
        let rules = Demo.new_rules(&world).unwrap();
        let view = BotView {
            world: &world,
            rules: &*rules,
            slot: 1,
            tick: 0,
        };
        let input = |bits| DemoInput::decode(&Demo.keys_input(Keys(bits), &view)).unwrap();
        assert_eq!(input(0), DemoInput::default());
        assert_eq!(
            input(Keys::RIGHT),
            DemoInput {
                move_x: 100,
                move_z: 0,
                jump: false
            }
        );
        assert_eq!(
            input(Keys::UP | Keys::LEFT | Keys::JUMP),
            DemoInput {
                move_x: -71,
                move_z: -71,
                jump: true
            }
        );
        // Opposite keys cancel.
        assert_eq!(input(Keys::UP | Keys::DOWN).move_z, 0);
        assert_eq!(
            Demo.player_body(&world, 1),
            world.find_body("player1"),
            "slot 1 walks player1"
        );
    }
}
