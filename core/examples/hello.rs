//! Drops a 1 m box from 10 m onto a static ground and prints the height of
//! its centre every 10 ticks until it rests: the engine embedded in a few
//! lines.
//!
//! ```sh
//! cargo run -p lockstep-core --example hello
//! ```

use lockstep_core::{BodyDesc, ColliderDesc, Vec3, World, WorldConfig, WorldError, scalar};

fn main() -> Result<(), WorldError> {
    // 60 ticks per second, gravity −9.81 m/s² along y.
    let mut world = World::new(WorldConfig::default())?;

    // A static ground 40 m × 1 m × 40 m whose top face is y = 0.
    let ground = world.create_body(&BodyDesc::fixed().position(Vec3::new(
        scalar!(0),
        scalar!(-0.5),
        scalar!(0),
    )))?;
    world.add_collider(
        ground,
        ColliderDesc::cuboid(scalar!(20), scalar!(0.5), scalar!(20)),
    )?;

    // A 1 m box (half-extents 0.5 m) whose centre starts 10 m up.
    let cube = world.create_body(&BodyDesc::dynamic().position(Vec3::from_ints(0, 10, 0)))?;
    world.add_collider(
        cube,
        ColliderDesc::cuboid(scalar!(0.5), scalar!(0.5), scalar!(0.5)),
    )?;

    // Step until the box falls asleep (it rests on the ground), at most 10 s.
    while world.tick() < 600 {
        world.step();
        let body = world.body(cube)?;
        if world.tick() % 10 == 0 || body.is_sleeping() {
            // Floats only for printing: the simulation never sees one.
            let [_, y, _] = body.position().to_f64_array();
            let [_, vy, _] = body.linear_velocity().to_f64_array();
            println!(
                "tick {:3}  height {:7.4} m  speed {:6.3} m/s{}",
                world.tick(),
                y,
                vy.abs(),
                if body.is_sleeping() { "  asleep" } else { "" }
            );
        }
        if body.is_sleeping() {
            break;
        }
    }
    // Every machine prints this same hash: the state, bit for bit.
    println!("state hash {:016x}", world.state_hash());
    Ok(())
}
