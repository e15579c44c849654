//! A character controller: a kinematic capsule moved by move-and-slide on
//! the scene queries.
//!
//! Each tick, before [`World::step`], the game calls
//! [`CharacterController::move_character`] with the wished horizontal
//! velocity and an optional jump. The controller works out where the capsule
//! can go this tick and gives the kinematic body the velocity that carries it
//! there during the step:
//!
//! 1. **Depenetration.** If something moved into the capsule (a platform
//!    rising, a box pushed against it), the capsule is pushed out along the
//!    penetration normals, at most [`MAX_DEPENETRATION_PASSES`] passes.
//! 2. **Ground.** A short sweep down ([`CharacterConfig::skin`] long) finds
//!    the ground. A surface is *walkable* when its normal's up component is at
//!    least [`CharacterConfig::max_slope_cos`]; a capsule resting on an edge
//!    (a stair nose) reads the face under the edge with a short ray instead.
//! 3. **Vertical speed.** On the ground it is zero, or the jump speed on a
//!    jump. In the air it is last tick's vertical speed plus gravity's `y`
//!    times `dt` (up is `+y`). Last tick's speed is the body's linear
//!    velocity: the controller keeps no state of its own, so the state hash,
//!    snapshots and late joins cover characters with no extra work.
//! 4. **Move and slide.** The capsule, inflated by the skin, is swept along
//!    the tick's motion; at each hit the rest of the motion loses its part
//!    into the surface (and into the crease of two surfaces), up to
//!    [`CharacterConfig::max_slides`] sweeps. On the ground, a surface too
//!    steep to walk on is first tried as a step (up by
//!    [`CharacterConfig::step_height`], forward, down onto walkable ground)
//!    and otherwise acts as a vertical wall, so steep slopes cannot be
//!    climbed by walking into them.
//! 5. **Ground snap.** A character that was on the ground, did not jump and
//!    has left it this tick (walking down stairs or a slope) is moved down
//!    onto walkable ground within [`CharacterConfig::snap_distance`]; one
//!    that is still on the ground settles onto it, one skin above it (a
//!    slide over a stair nose can leave it up to a skin higher).
//! 6. **Platforms.** A character that stood on a moving body (kinematic or
//!    dynamic) moves with the point of that body under it: exactly along a
//!    kinematic target the game set before this call, or with the body's
//!    velocity. The carry is swept too, so a platform cannot carry the
//!    character through a wall.
//! 7. **Pushing.** Dynamic bodies the capsule ran into get an impulse along
//!    the horizontal push direction that would bring their contact point to
//!    the character's wished speed, capped by
//!    [`CharacterConfig::push_force`] × `dt`: a character pushes a light box
//!    along and leans on a heavy one in vain.
//!
//! The capsule keeps a gap of `skin` (within the sweep tolerance) from what
//! it stands on or touches, so that sliding along a floor or wall starts
//! clear of it. Every step is [`Scalar`] arithmetic on the world's queries,
//! whose results do not depend on tree shape or visit order: two peers with
//! the same world and inputs move their characters to the same bits.
//!
//! The body keeps the velocity it was given after the step, and a kinematic
//! body is not stopped by contacts: call `move_character` every tick for
//! every character (with a zero velocity for one that stands still), or
//! [`CharacterController::stop`] it.

use crate::body::{BodyDesc, BodyHandle, BodyKind};
use crate::collider::{ColliderDesc, ColliderHandle};
use crate::math::{FaultScope, Faults, Quat, Scalar, Transform, Vec3, elem};
use crate::query::{QueryFilter, Ray, SWEEP_TOLERANCE, ShapeHit, sweep_shape};
use crate::shape::{Capsule, Shape};
use crate::world::{BodyRef, World, WorldError};

/// How many times the depenetration step re-checks the capsule.
pub const MAX_DEPENETRATION_PASSES: usize = 4;

/// The most slide sweeps [`CharacterConfig::max_slides`] accepts.
pub const MAX_SLIDES: u32 = 8;

/// A motion shorter than this is treated as none: half the sweep tolerance.
const TINY: Scalar = Scalar::from_bits(SWEEP_TOLERANCE.to_bits() / 2);

/// What a slide leaves along a surface's normal after removing the motion
/// into it, so that the next sweep starts moving away from it (a dot product
/// one ulp below zero would count as moving into it): 2⁻²⁴ m.
const SLIDE_BIAS: Scalar = Scalar::from_bits(1 << 8);

/// How a character moves. [`CharacterConfig::default`] suits a human-sized
/// capsule in metres.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CharacterConfig {
    /// The gap kept between the capsule and what it touches, m (default
    /// 0.01). Also the distance the ground probe looks down.
    pub skin: Scalar,
    /// Cosine of the steepest walkable slope (default cos 45°, rounded
    /// down). See [`CharacterConfig::with_max_slope`].
    pub max_slope_cos: Scalar,
    /// The highest step climbed by walking into it, m (default 0.3; 0 turns
    /// climbing off).
    pub step_height: Scalar,
    /// How far down the character is pulled onto the ground after walking
    /// off an edge, m (default 0.3; 0 turns snapping off).
    pub snap_distance: Scalar,
    /// The most sweeps in the slide, 1 to [`MAX_SLIDES`] (default 4).
    pub max_slides: u32,
    /// The most force a character puts on a dynamic body it walks into, N
    /// (default 500).
    pub push_force: Scalar,
    /// Query category bits (see [`QueryFilter::category`]); default 1.
    pub category: u32,
    /// Query mask bits: what the character collides with; default all.
    pub mask: u32,
}

impl Default for CharacterConfig {
    fn default() -> Self {
        CharacterConfig {
            skin: Scalar::from_bits(42_949_673), // 0.01 m
            // cos 45° = 0.70710678..., rounded down in Q32.32.
            max_slope_cos: Scalar::from_bits(3_037_000_499),
            step_height: Scalar::from_bits(1_288_490_189), // 0.3 m
            snap_distance: Scalar::from_bits(1_288_490_189),
            max_slides: 4,
            push_force: Scalar::from_int(500),
            category: 1,
            mask: u32::MAX,
        }
    }
}

impl CharacterConfig {
    /// The config with the steepest walkable slope set to `radians` (from
    /// the horizontal), computed with the fixed-point cosine.
    pub fn with_max_slope(mut self, radians: Scalar) -> CharacterConfig {
        self.max_slope_cos = elem::cos(radians);
        self
    }

    fn validate(&self, capsule: &Capsule) -> Result<(), WorldError> {
        let bad = |what: &str| Err(WorldError::InvalidParameter(format!("character: {what}")));
        if self.skin <= Scalar::ZERO || self.skin > capsule.radius {
            return bad("skin must be above 0 and at most the capsule radius");
        }
        if self.max_slope_cos < Scalar::ZERO || self.max_slope_cos > Scalar::ONE {
            return bad("max_slope_cos must be in [0, 1]");
        }
        if self.step_height < Scalar::ZERO || self.snap_distance < Scalar::ZERO {
            return bad("step_height and snap_distance must not be negative");
        }
        if self.max_slides == 0 || self.max_slides > MAX_SLIDES {
            return bad("max_slides must be 1 to 8");
        }
        if self.push_force < Scalar::ZERO {
            return bad("push_force must not be negative");
        }
        Ok(())
    }
}

/// One tick's wish for a character.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CharacterInput {
    /// Wished horizontal velocity, m/s (`y` is ignored).
    pub velocity: Vec3,
    /// Jump: the vertical speed given when the character is on the ground
    /// (0 for no jump).
    pub jump_speed: Scalar,
}

/// What a character stands on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Ground {
    /// The body under the character.
    pub body: BodyHandle,
    /// Its collider.
    pub collider: ColliderHandle,
    /// The contact point on it.
    pub point: Vec3,
    /// The surface normal there (the sweep's, pointing at the character).
    pub normal: Vec3,
}

/// What one [`CharacterController::move_character`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CharacterMove {
    /// Where the character will be after the step, minus where it was.
    pub translation: Vec3,
    /// The body's new linear velocity (`translation / dt`).
    pub velocity: Vec3,
    /// The ground at the start of the tick, if any.
    pub ground_before: Option<Ground>,
    /// The ground under the planned position, if any.
    pub ground: Option<Ground>,
    /// Whether the character jumped this tick.
    pub jumped: bool,
    /// Whether it climbed a step.
    pub climbed_step: bool,
    /// Whether it was snapped down onto the ground.
    pub snapped: bool,
    /// Whether it was pushed out of an overlap first.
    pub depenetrated: bool,
    /// How many surfaces the slide ran into.
    pub hits: u32,
    /// How many dynamic bodies it pushed.
    pub pushed: u32,
    /// Arithmetic faults raised by the controller's own arithmetic (only
    /// with coordinates far beyond a game's range); non-empty means the
    /// move cannot be trusted, as for the world's faults.
    pub faults: Faults,
}

/// A dynamic body the slide ran into.
#[derive(Clone, Copy, Debug)]
struct Bump {
    body: BodyHandle,
    point: Vec3,
    normal: Vec3,
}

/// The plan of one move, before it is applied to the world.
struct Plan {
    start: Vec3,
    end: Vec3,
    ground_before: Option<Ground>,
    ground: Option<Ground>,
    jumped: bool,
    climbed_step: bool,
    snapped: bool,
    depenetrated: bool,
    hits: u32,
    bumps: [Option<Bump>; MAX_SLIDES as usize],
}

/// A kinematic capsule body and how it moves (see the module docs).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CharacterController {
    body: BodyHandle,
    capsule: Capsule,
    /// The capsule the queries sweep: the body's capsule inflated by the skin.
    probe: Shape,
    config: CharacterConfig,
}

impl CharacterController {
    /// Creates a kinematic body called `name` at `position` with an upright
    /// capsule (`half_height` of the core segment, `radius`), and its
    /// controller.
    ///
    /// # Errors
    /// [`WorldError::Shape`] for a bad capsule, [`WorldError::InvalidParameter`]
    /// for a bad config; the world's errors for the body.
    pub fn create(
        world: &mut World,
        name: &str,
        position: Vec3,
        half_height: Scalar,
        radius: Scalar,
        config: CharacterConfig,
    ) -> Result<CharacterController, WorldError> {
        let capsule = Capsule::new(half_height, radius)?;
        config.validate(&capsule)?;
        let body = world.create_body(&BodyDesc::kinematic().name(name).position(position))?;
        world.add_collider(body, ColliderDesc::capsule(half_height, radius))?;
        CharacterController::attach(world, body, config)
    }

    /// A controller for an existing body: kinematic, upright (identity
    /// rotation), with exactly one capsule collider at its origin.
    ///
    /// # Errors
    /// [`WorldError::InvalidBody`]; [`WorldError::InvalidParameter`] naming
    /// what is not as expected, or a bad config.
    pub fn attach(
        world: &World,
        body: BodyHandle,
        config: CharacterConfig,
    ) -> Result<CharacterController, WorldError> {
        let b = world.body(body)?;
        let bad = |what: &str| {
            Err(WorldError::InvalidParameter(format!(
                "character body {:?}: {what}",
                b.name()
            )))
        };
        if b.kind() != BodyKind::Kinematic {
            return bad("must be kinematic");
        }
        if b.rotation() != Quat::IDENTITY {
            return bad("must be upright (identity rotation)");
        }
        let [c] = b.colliders() else {
            return bad("must have exactly one collider");
        };
        let collider = world.collider(*c)?;
        let Shape::Capsule(capsule) = collider.shape else {
            return bad("its collider must be a capsule");
        };
        if collider.local_pose != Transform::IDENTITY {
            return bad("its capsule must sit at the body origin, unrotated");
        }
        config.validate(&capsule)?;
        let probe = Shape::Capsule(Capsule::new(
            capsule.half_height,
            capsule.radius + config.skin,
        )?);
        Ok(CharacterController {
            body,
            capsule,
            probe,
            config,
        })
    }

    /// The character's body.
    pub fn body(&self) -> BodyHandle {
        self.body
    }

    /// The body's capsule.
    pub fn capsule(&self) -> Capsule {
        self.capsule
    }

    /// How it moves.
    pub fn config(&self) -> &CharacterConfig {
        &self.config
    }

    /// Stops the character where it is (its velocity becomes zero).
    ///
    /// # Errors
    /// [`WorldError::InvalidBody`] if the body was removed.
    pub fn stop(&self, world: &mut World) -> Result<(), WorldError> {
        world.set_linear_velocity(self.body, Vec3::ZERO)
    }

    /// Plans this tick's move and applies it: the body's velocity for the
    /// coming step, and impulses on the dynamic bodies it pushes. Call once
    /// per tick, before [`World::step`], after moving platforms have been
    /// given their kinematic targets or velocities for the tick.
    ///
    /// # Errors
    /// [`WorldError::InvalidBody`] if the body was removed.
    pub fn move_character(
        &self,
        world: &mut World,
        input: &CharacterInput,
    ) -> Result<CharacterMove, WorldError> {
        let (result, faults) = FaultScope::run(|| -> Result<CharacterMove, WorldError> {
            let plan = self.plan(world, input)?;
            let pushed = self.push(world, input, &plan)?;
            let translation = plan.end - plan.start;
            let velocity = translation.mul_int(i64::from(world.config().tick_rate));
            world.set_linear_velocity(self.body, velocity)?;
            Ok(CharacterMove {
                translation,
                velocity,
                ground_before: plan.ground_before,
                ground: plan.ground,
                jumped: plan.jumped,
                climbed_step: plan.climbed_step,
                snapped: plan.snapped,
                depenetrated: plan.depenetrated,
                hits: plan.hits,
                pushed,
                faults: Faults::NONE,
            })
        });
        let mut m = result?;
        m.faults = faults;
        Ok(m)
    }

    /// The velocity the ground under the character now would carry it
    /// with (step 6): the velocity of the ground body's point at the
    /// character's position, zero on static ground or in the air.
    ///
    /// The body's linear velocity after a step is the whole move of the
    /// tick, its own walk and the carry together. A game that keeps
    /// momentum in that velocity (walking that accelerates towards a wished
    /// speed) must take this away first to get the walk relative to the
    /// ground, and pass only that as [`CharacterInput::velocity`]: the
    /// controller adds the carry again. Fed back whole, the carry is
    /// counted once more every tick, and a character pushing the crate it
    /// stands on doubles its own speed each tick.
    ///
    /// Arithmetic faults are raised in the caller's [`FaultScope`], as for
    /// the game's own arithmetic.
    ///
    /// # Errors
    /// [`WorldError::InvalidBody`] if the body was removed.
    pub fn ground_velocity(&self, world: &World) -> Result<Vec3, WorldError> {
        let pos = world.body(self.body)?.position();
        let Some(ground) = self.ground_at(world, pos) else {
            return Ok(Vec3::ZERO);
        };
        let g = world.body(ground.body)?;
        if g.kind() == BodyKind::Static {
            return Ok(Vec3::ZERO);
        }
        // The same point as the carry's (step 6).
        Ok(velocity_at(&g, pos))
    }

    /// The ground under the character now (the probe of step 2), without
    /// moving it.
    ///
    /// # Errors
    /// [`WorldError::InvalidBody`] if the body was removed.
    pub fn ground(&self, world: &World) -> Result<Option<Ground>, WorldError> {
        let pos = world.body(self.body)?.position();
        Ok(FaultScope::run(|| self.ground_at(world, pos)).0)
    }

    /// The probe of step 2 from `pos`, its faults raised in the caller's
    /// scope.
    fn ground_at(&self, world: &World, pos: Vec3) -> Option<Ground> {
        let exclude = [self.body];
        let filter = self.filter(&exclude);
        self.probe_ground(world, pos, &filter, self.config.skin)
    }

    fn filter<'a>(&self, exclude: &'a [BodyHandle]) -> QueryFilter<'a> {
        QueryFilter {
            category: self.config.category,
            mask: self.config.mask,
            exclude_bodies: exclude,
            include_triggers: false,
            predicate: None,
        }
    }

    /// Sweeps the inflated capsule from `pos` along `motion`.
    fn sweep(
        &self,
        world: &World,
        pos: Vec3,
        motion: Vec3,
        filter: &QueryFilter<'_>,
    ) -> Option<ShapeHit> {
        if motion.is_zero() {
            return None;
        }
        // The probe is a capsule, always convex: the query cannot refuse it.
        world
            .cast_shape(
                &self.probe,
                &Transform::new(pos, Quat::IDENTITY),
                motion,
                filter,
            )
            .ok()
            .flatten()
    }

    fn plan(&self, world: &World, input: &CharacterInput) -> Result<Plan, WorldError> {
        let body = world.body(self.body)?;
        let start = body.position();
        let last_velocity = body.linear_velocity();
        let dt = world.dt();
        let exclude = [self.body];
        let filter = self.filter(&exclude);
        let cfg = &self.config;

        let mut pos = start;
        let depenetrated = self.depenetrate(world, &mut pos, &filter);

        let ground_before = self.probe_ground(world, pos, &filter, cfg.skin);
        let jumped = ground_before.is_some() && input.jump_speed > Scalar::ZERO;
        let on_ground = ground_before.is_some() && !jumped;
        let vy = if jumped {
            input.jump_speed
        } else if on_ground {
            Scalar::ZERO
        } else {
            last_velocity.y + world.config().gravity.y * dt
        };
        let motion = Vec3::new(input.velocity.x * dt, vy * dt, input.velocity.z * dt);

        let mut plan = Plan {
            start,
            end: pos,
            ground_before,
            ground: None,
            jumped,
            climbed_step: false,
            snapped: false,
            depenetrated,
            hits: 0,
            bumps: [None; MAX_SLIDES as usize],
        };
        self.slide(world, &mut pos, motion, on_ground, &filter, &mut plan);

        // The ground is read before the carry, against the poses the
        // ground body has now: the carry moves the character with it.
        let below = self.walkable_below(world, pos, &filter, cfg.skin);
        plan.ground = below.as_ref().map(ground_of);
        if on_ground && let Some(hit) = below {
            // Still on the ground: settle onto it, one skin from it. The
            // probe finds ground up to two skins below the capsule, and a
            // character on the ground gets no vertical speed, so a slide
            // over a stair nose or a step landing that left it higher
            // would otherwise walk on that high for good. (The probe's own
            // sweep, down by a skin, says how far.)
            if !hit.initially_overlapping {
                pos += Vec3::new(Scalar::ZERO, -cfg.skin, Scalar::ZERO) * hit.fraction;
            }
        } else if on_ground && cfg.snap_distance > Scalar::ZERO {
            let down = Vec3::new(Scalar::ZERO, -cfg.snap_distance, Scalar::ZERO);
            if let Some(hit) = self.walkable_below(world, pos, &filter, cfg.snap_distance)
                && !hit.initially_overlapping
            {
                pos += down * hit.fraction;
                plan.snapped = true;
                plan.ground = self.probe_ground(world, pos, &filter, cfg.skin);
            }
        }
        if let Some(g) = ground_before {
            pos = self.carry(world, pos, g.body, dt)?;
        }
        plan.end = pos;
        Ok(plan)
    }

    /// Step 1: pushes the capsule out of whatever it overlaps.
    fn depenetrate(&self, world: &World, pos: &mut Vec3, filter: &QueryFilter<'_>) -> bool {
        let mut moved = false;
        let mut hits = Vec::new();
        let r = self.capsule.radius + self.config.skin;
        let probe_motion = Vec3::new(Scalar::ZERO, -self.config.skin, Scalar::ZERO);
        for _ in 0..MAX_DEPENETRATION_PASSES {
            let pose = Transform::new(*pos, Quat::IDENTITY);
            if world
                .overlap_shape(&self.probe, &pose, filter, &mut hits)
                .is_err()
            {
                return moved;
            }
            let mut pushed = false;
            for h in &hits {
                let Ok(c) = world.collider(h.collider) else {
                    continue;
                };
                let Ok(owner) = world.body(c.body) else {
                    continue;
                };
                let cpose = c.world_pose(&owner.pose());
                let here = Transform::new(*pos, Quat::IDENTITY);
                let Ok(Some(x)) = sweep_shape(
                    &self.probe,
                    &here,
                    probe_motion,
                    &c.shape,
                    &cpose,
                    Scalar::ONE,
                ) else {
                    continue;
                };
                if !x.initially_overlapping {
                    continue;
                }
                // The capsule's deepest point against the surface plane
                // through `x.point` with normal `x.normal`.
                let n = x.normal;
                let [lo, hi] = self.capsule.segment();
                let lowest = (*pos + lo).dot(n).min((*pos + hi).dot(n)) - r;
                // Touching counts: the sweeps would report it at 0.
                let depth = (x.point.dot(n) - lowest).max(Scalar::ZERO);
                *pos += n * (depth + TINY);
                pushed = true;
                moved = true;
            }
            if !pushed {
                break;
            }
        }
        moved
    }

    /// Step 2: walkable ground within `distance` below `pos`.
    fn probe_ground(
        &self,
        world: &World,
        pos: Vec3,
        filter: &QueryFilter<'_>,
        distance: Scalar,
    ) -> Option<Ground> {
        self.walkable_below(world, pos, filter, distance)
            .as_ref()
            .map(ground_of)
    }

    /// The sweep of the capsule straight down by `distance` from `pos`,
    /// if it hits walkable ground.
    fn walkable_below(
        &self,
        world: &World,
        pos: Vec3,
        filter: &QueryFilter<'_>,
        distance: Scalar,
    ) -> Option<ShapeHit> {
        let down = Vec3::new(Scalar::ZERO, -distance, Scalar::ZERO);
        let hit = self.sweep(world, pos, down, filter)?;
        self.walkable(world, &hit, filter).then_some(hit)
    }

    /// Whether a hit is ground the character can stand on: the normal is
    /// flat enough, or the hit is on an edge whose face just beside it (read
    /// by a short ray down, on the side away from the character) is.
    fn walkable(&self, world: &World, hit: &ShapeHit, filter: &QueryFilter<'_>) -> bool {
        let cos = self.config.max_slope_cos;
        if hit.normal.y >= cos {
            return true;
        }
        if hit.normal.y <= Scalar::ZERO {
            return false;
        }
        let Some(away) = Vec3::new(-hit.normal.x, Scalar::ZERO, -hit.normal.z).try_normalize()
        else {
            return false;
        };
        let e = self.config.skin;
        let origin = hit.point + away * e + Vec3::new(Scalar::ZERO, e.mul_int(2), Scalar::ZERO);
        let ray = Ray::new(origin, Vec3::new(Scalar::ZERO, -e.mul_int(4), Scalar::ZERO));
        // A ray that starts inside the face is on a slope steeper than
        // atan 2: not walkable.
        world
            .cast_ray_closest(&ray, filter)
            .is_some_and(|r| r.fraction > Scalar::ZERO && r.normal.y >= cos)
    }

    /// Step 4: move and slide from `pos` along `motion`.
    fn slide(
        &self,
        world: &World,
        pos: &mut Vec3,
        motion: Vec3,
        on_ground: bool,
        filter: &QueryFilter<'_>,
        plan: &mut Plan,
    ) {
        let mut planes = [Vec3::ZERO; MAX_SLIDES as usize];
        let mut n_planes = 0;
        let mut remaining = motion;
        for _ in 0..self.config.max_slides {
            if short(remaining) {
                break;
            }
            let Some(hit) = self.sweep(world, *pos, remaining, filter) else {
                *pos += remaining;
                break;
            };
            let moved = remaining * hit.fraction;
            *pos += moved;
            let mut left = remaining - moved;
            if let Ok(b) = world.body(hit.body)
                && b.kind() == BodyKind::Dynamic
                && let Some(slot) = plan.bumps.iter_mut().find(|s| s.is_none())
            {
                *slot = Some(Bump {
                    body: hit.body,
                    point: hit.point,
                    normal: hit.normal,
                });
            }
            plan.hits += 1;
            let mut n = hit.normal;
            // On the ground, a surface whose own normal is too steep is a
            // step or a wall; an edge with walkable ground beyond it too (it
            // is climbed as a step, not rolled over).
            if on_ground && hit.normal.y < self.config.max_slope_cos {
                if let Some((p, rest)) = self.try_step(world, *pos, left, filter) {
                    *pos = p;
                    remaining = rest;
                    plan.climbed_step = true;
                    continue;
                }
                // Too steep to walk up and not a step: a wall.
                if let Some(h) = Vec3::new(n.x, Scalar::ZERO, n.z).try_normalize() {
                    n = h;
                }
            }
            left = clip(left, n);
            for &p in &planes[..n_planes] {
                if left.dot(p) < Scalar::ZERO {
                    // Into an earlier surface too: along the crease, or stop.
                    left = match n.cross(p).try_normalize() {
                        Some(c) => c * left.dot(c),
                        None => Vec3::ZERO,
                    };
                }
            }
            if planes[..n_planes]
                .iter()
                .any(|&p| left.dot(p) < -SLIDE_BIAS)
            {
                left = Vec3::ZERO;
            }
            if n_planes < planes.len() {
                planes[n_planes] = n;
                n_planes += 1;
            }
            remaining = left;
        }
    }

    /// A step up: lift by up to `step_height`, move the horizontal part of
    /// `left` forward, and land on walkable ground higher than `pos`.
    /// Returns the landing position and the horizontal motion still to do.
    fn try_step(
        &self,
        world: &World,
        pos: Vec3,
        left: Vec3,
        filter: &QueryFilter<'_>,
    ) -> Option<(Vec3, Vec3)> {
        let height = self.config.step_height;
        let forward = Vec3::new(left.x, Scalar::ZERO, left.z);
        if height <= Scalar::ZERO || short(forward) {
            return None;
        }
        let up = Vec3::new(Scalar::ZERO, height, Scalar::ZERO);
        let lift = match self.sweep(world, pos, up, filter) {
            Some(h) => height * h.fraction,
            None => height,
        };
        if lift <= self.config.skin {
            return None;
        }
        let raised = pos + Vec3::new(Scalar::ZERO, lift, Scalar::ZERO);
        let ahead = match self.sweep(world, raised, forward, filter) {
            Some(h) if h.initially_overlapping => return None,
            Some(h) => h.fraction,
            None => Scalar::ONE,
        };
        let went = forward * ahead;
        if short(went) {
            return None;
        }
        let over = raised + went;
        let fall = lift + self.config.skin;
        let down = Vec3::new(Scalar::ZERO, -fall, Scalar::ZERO);
        let land = self.sweep(world, over, down, filter)?;
        if land.initially_overlapping || !self.walkable(world, &land, filter) {
            return None;
        }
        let landed = over + down * land.fraction;
        // The round bottom would ride over an edge somewhat higher than the
        // lift: the step is measured from the foot to where it lands.
        let foot = pos.y - self.capsule.half_height - self.capsule.radius - self.config.skin;
        if landed.y <= pos.y + TINY || land.point.y - foot > height {
            return None;
        }
        Some((landed, forward - went))
    }

    /// Step 6: the motion of the ground body's point under the character
    /// during the coming step, swept without the ground body.
    fn carry(
        &self,
        world: &World,
        pos: Vec3,
        ground: BodyHandle,
        dt: Scalar,
    ) -> Result<Vec3, WorldError> {
        let g = world.body(ground)?;
        let shift = match (g.kind(), g.kinematic_target()) {
            (BodyKind::Static, _) => return Ok(pos),
            (BodyKind::Kinematic, Some(target)) => {
                target.transform_point(g.pose().inverse_transform_point(pos)) - pos
            }
            _ => velocity_at(&g, pos) * dt,
        };
        if short(shift) {
            return Ok(pos);
        }
        let exclude = [self.body, ground];
        let filter = self.filter(&exclude);
        Ok(match self.sweep(world, pos, shift, &filter) {
            Some(h) => pos + shift * h.fraction,
            None => pos + shift,
        })
    }

    /// Step 7: impulses on the dynamic bodies the slide ran into, each body
    /// once (its first hit). Returns how many were pushed.
    fn push(
        &self,
        world: &mut World,
        input: &CharacterInput,
        plan: &Plan,
    ) -> Result<u32, WorldError> {
        let cap = self.config.push_force * world.dt();
        let mut pushed = 0;
        let mut seen = [None; MAX_SLIDES as usize];
        for (i, bump) in plan.bumps.iter().enumerate() {
            let Some(b) = bump else { break };
            if seen[..i].contains(&Some(b.body)) {
                continue;
            }
            seen[i] = Some(b.body);
            let Some(dir) = Vec3::new(-b.normal.x, Scalar::ZERO, -b.normal.z).try_normalize()
            else {
                continue;
            };
            let body = world.body(b.body)?;
            let at_point = velocity_at(&body, b.point);
            let wished = Vec3::new(input.velocity.x, Scalar::ZERO, input.velocity.z);
            let closing = (wished - at_point).dot(dir);
            if closing <= Scalar::ZERO {
                continue;
            }
            let j = (closing * body.mass()).min(cap);
            if j > Scalar::ZERO {
                world.apply_impulse_at_point(b.body, dir * j, b.point)?;
                pushed += 1;
            }
        }
        Ok(pushed)
    }
}

/// The velocity of `body`'s material point at world position `p`.
fn velocity_at(body: &BodyRef<'_>, p: Vec3) -> Vec3 {
    body.linear_velocity() + body.angular_velocity().cross(p - body.center_of_mass())
}

/// The ground a walkable hit found.
fn ground_of(hit: &ShapeHit) -> Ground {
    Ground {
        body: hit.body,
        collider: hit.collider,
        point: hit.point,
        normal: hit.normal,
    }
}

/// Whether a motion is too short to sweep.
fn short(v: Vec3) -> bool {
    v.length_squared_wide() <= TINY.wide_mul(TINY) as u128
}

/// `v` without its part into the plane of normal `n`, left moving a hair
/// away from it.
fn clip(v: Vec3, n: Vec3) -> Vec3 {
    let into = v.dot(n);
    if into < Scalar::ZERO {
        v - n * into + n * SLIDE_BIAS
    } else {
        v
    }
}
