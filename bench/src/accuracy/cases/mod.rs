//! The accuracy cases: each builds one scene (or a series of shots), steps
//! it through a [`Runner`] and measures its error against a closed form or
//! an exact invariant from [`closed`](super::closed).
//!
//! docs/accuracy.md describes every case; keep the two in step.

mod contact;
mod free;
mod joints;
mod piles;

use super::closed::G;
use super::run::{Outcome, Runner};
use super::sim::{BodySpec, ShapeSpec};

/// One case of the suite.
pub struct Case {
    /// Short name (file names, CSV, `--scenes`).
    pub name: &'static str,
    /// What is simulated.
    pub title: &'static str,
    /// What the error is, with its unit (the plot's y axis).
    pub metric: &'static str,
    /// The reference the error is measured against.
    pub reference: &'static str,
    /// The lowest a zero error is drawn, for errors that come in steps (a
    /// fraction of shots): `None` lets the data decide.
    pub zero_floor: Option<f64>,
    /// Runs the case (`quick`: the smoke-run size).
    pub run: fn(&mut Runner, bool) -> Outcome,
}

/// Every case, in the order they are run and listed.
pub const CASES: &[Case] = &[
    free::PROJECTILE,
    free::FAR_PROJECTILE,
    free::SPIN_SYMMETRIC,
    free::SPIN_INTERMEDIATE,
    free::ELASTIC_SPHERES,
    free::ISOLATED_COLLISION,
    contact::BOUNCE_05,
    contact::BOUNCE_09,
    contact::DROP_TIME,
    contact::SLIDE,
    contact::SLIDE_45,
    contact::FAR_SLIDE,
    contact::RAMP_STICK,
    contact::RAMP_SLIDE,
    contact::ROLL,
    contact::SLIDE_TO_ROLL,
    piles::STACK,
    piles::PYRAMID,
    piles::MASS_RATIO,
    piles::OVERLAP,
    free::TUNNELLING,
    joints::PENDULUM_PERIOD,
    joints::PENDULUM_ENERGY,
    joints::CHAIN,
    joints::HINGE_MOTOR,
    joints::HINGE_LIMIT,
    joints::HEAVY_CHAIN,
];

/// A static ground box whose top face is `y = 0`, centred at `(x, z)`,
/// `half` m across.
fn ground_at(x: f64, z: f64, half: f64, friction: f64, restitution: f64) -> BodySpec {
    BodySpec::fixed(ShapeSpec::Cuboid([half, 1.0, half]), [x, -1.0, z])
        .material(friction, restitution)
}

/// The ground around the origin (400 m across).
fn ground(friction: f64, restitution: f64) -> BodySpec {
    ground_at(0.0, 0.0, 200.0, friction, restitution)
}

/// A unit box (half-extent 0.5, density 1000) at `pos`.
fn unit_box(pos: [f64; 3], friction: f64) -> BodySpec {
    BodySpec::dynamic(ShapeSpec::Cuboid([0.5; 3]), pos).material(friction, 0.0)
}

/// Gravity tilted by `theta_deg` about z: the same physics as a ramp at
/// that angle (down-slope is +x), without a rotated ground in the way.
fn slope_gravity(theta_deg: f64) -> [f64; 3] {
    let t = theta_deg.to_radians();
    [G * t.sin(), -G * t.cos(), 0.0]
}

/// The horizontal (x–z) distance between two points.
fn horizontal(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn case_names_are_unique_and_file_safe() {
        for (i, c) in CASES.iter().enumerate() {
            assert!(
                CASES[i + 1..].iter().all(|d| d.name != c.name),
                "{}",
                c.name
            );
            assert!(
                c.name
                    .chars()
                    .all(|ch| ch.is_ascii_alphanumeric() || ch == '_'),
                "{}",
                c.name
            );
        }
        assert!(CASES.len() >= 27);
    }

    #[test]
    fn slope_gravity_has_g_along_the_slope_and_across_it() {
        let g = slope_gravity(30.0);
        assert!((g[0] - G / 2.0).abs() < 1e-12);
        assert!((g[0].hypot(g[1]) - G).abs() < 1e-12);
    }
}
