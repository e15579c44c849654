//! Shock propagation for the high-mass-ratio contacts: after the solve and
//! after the relax passes, the contacts of [`ContactSolver::heavy`] are
//! visited once more from the ground up, each with its lower body held
//! still (infinite mass), so that no upper body is left approaching the
//! body under it.
//!
//! Why: Gauss–Seidel passes the weight of a heavy body through a light one
//! under it about R times slower than between equal bodies (R the mass
//! ratio). Each visit of the heavy–light contact can only take from the
//! heavy body the momentum the light body can carry, and the light body's
//! contact with the ground then takes it out again. With a few passes per
//! substep the heavy body keeps most of its downward speed: at 1:1000 it
//! sank into the light box, and the light box into the ground, by several
//! centimetres, and an alternating light/heavy stack collapsed. Stiffer
//! springs alone do not help: the spring sets the depth at rest, not how
//! fast the passes converge.
//!
//! The pass after the regular passes is Guendelman, Bridson and Fedkiw's
//! shock propagation (2003) restricted to those contacts:
//!
//! - each solver body gets a level, its distance in high-ratio contacts
//!   from a static or kinematic body (level 0); bodies that reach none keep
//!   no level, and contacts between bodies of one level are left out;
//! - the contacts are visited in ascending level of their lower body, and
//!   each visit gives the upper body alone the impulse that stops it
//!   approaching the lower one: `vn ≥ 0` at an overlapping point, `vn ≥
//!   −gap/h` at a speculative one. It only ever adds impulse, so it never
//!   holds back a push-out and never pulls;
//! - the impulse goes into the point's accumulated impulse, so the warm
//!   start of the next substep applies it to both bodies: the lower body
//!   and its own support then carry the load, and the regular passes start
//!   from the right impulses. The angular part goes into the upper body's
//!   momentum here, once (the point's mark moves with it).
//!
//! In a scene without a contact above [`RATIO_KEPT`](super::RATIO_KEPT) the
//! list is empty and nothing here runs, so those scenes' results do not
//! depend on it.
//!
//! Determinism: levels from a fixed number of passes over the list in its
//! (constraint) order; the visit order sorted by (level, constraint index),
//! a total key.

use super::ContactSolver;
use super::constraint::{NONE, SeparationFrame, ShockRow};
use super::params::SolverParams;
use super::rows::{angular_along, inverse_or_zero, load, mul, round_wide, scale, store};
use crate::collision::MAX_MANIFOLD_POINTS;
use crate::math::Scalar;

/// A solver body that no high-ratio contact links to a static or
/// kinematic body.
const UNREACHED: u32 = u32::MAX;

/// Sweeps over a manifold's points per visit: only the upper body moves,
/// so the points of one manifold converge among themselves quickly, but one
/// sweep from a fixed point left the body turning.
const SWEEPS: usize = 3;

impl ContactSolver {
    /// Levels of the solver bodies through the high-ratio contacts and the
    /// shock pass's visit order (step 5 of `prepare`). Clears the order
    /// when there is no high-ratio contact.
    pub(super) fn order_shock(&mut self) {
        self.shock.clear();
        if self.heavy.is_empty() {
            return;
        }
        self.level.clear();
        self.level.extend(
            self.bodies
                .iter()
                .map(|b| if b.dynamic { UNREACHED } else { 0 }),
        );
        let level = |levels: &[u32], i: u32| if i == NONE { 0 } else { levels[i as usize] };
        // Each pass settles at least one more level; a chain of n contacts
        // needs n passes, so the list's length bounds them.
        for _ in 0..self.heavy.len() {
            let mut changed = false;
            for &i in &self.heavy {
                let c = &self.constraints[i as usize];
                let (la, lb) = (level(&self.level, c.a), level(&self.level, c.b));
                if la != UNREACHED && c.b != NONE && la + 1 < lb {
                    self.level[c.b as usize] = la + 1;
                    changed = true;
                }
                if lb != UNREACHED && c.a != NONE && lb + 1 < la {
                    self.level[c.a as usize] = lb + 1;
                    changed = true;
                }
            }
            if !changed {
                break;
            }
        }
        for &i in &self.heavy {
            let c = &self.constraints[i as usize];
            let (la, lb) = (level(&self.level, c.a), level(&self.level, c.b));
            if la == lb {
                continue;
            }
            // The upper body has the higher level, so it is a dynamic
            // solver body (static, kinematic and absent bodies are 0).
            self.shock.push(ShockRow {
                level: la.min(lb),
                constraint: i,
                upper_is_b: lb > la,
            });
        }
        self.shock.sort_unstable();
    }

    /// The shock pass (see the module docs); nothing without high-ratio
    /// contacts. After the solve passes (`settle == false`) it only stops
    /// approach; after the relax passes (`settle == true`) it also takes
    /// back the separating speed of a touching point, as far as the point's
    /// accumulated impulse allows (its total push never turns into a pull),
    /// so that a resting stack ends the substep at rest.
    pub(crate) fn shock(&mut self, params: &SolverParams, settle: bool) {
        let vels = &mut self.vels;
        let dls = &mut self.dls;
        let bodies = &self.bodies;
        // Substep k starts at point k (mod count), as the regular passes
        // do, but always forward (they also alternate direction per
        // substep: `constraint::row_order`).
        let rot = self.substeps as usize;
        for row in &self.shock {
            let c = &mut self.constraints[row.constraint as usize];
            let (mut va, mut vb) = load(vels, c.a, c.b);
            let n = c.normal;
            // The current separation, as the regular passes follow it.
            let frame = SeparationFrame::of(c, bodies);
            let count = c.count.min(MAX_MANIFOLD_POINTS);
            let start = if count == 0 { 0 } else { rot % count };
            // What this visit gave each point so far.
            let mut given = [Scalar::ZERO; MAX_MANIFOLD_POINTS];
            for kk in 0..count * SWEEPS {
                let k = (kk + start) % count;
                let cp = c.points[k];
                let s = frame.separation(&cp);
                let vn =
                    round_wide(n.dot_wide(vb.v - va.v)) + angular_along(&va, &vb, cp.ra_n, cp.rb_n);
                // The change of normal speed wanted: up to the approach the
                // gap allows in one substep; after the relax passes, a
                // separating point back to zero.
                let allowed = if s.is_positive() {
                    s * params.inv_h
                } else {
                    Scalar::ZERO
                };
                let want = if vn + allowed < Scalar::ZERO {
                    -(vn + allowed)
                } else if settle && vn.is_positive() {
                    -vn
                } else {
                    Scalar::ZERO
                };
                if want.is_zero() {
                    continue;
                }
                // Only the upper body moves: the effective mass is its own.
                let k_upper = if row.upper_is_b {
                    c.inv_mass_b + round_wide(cp.rb_n.dot_wide(cp.ib_n))
                } else {
                    c.inv_mass_a + round_wide(cp.ra_n.dot_wide(cp.ia_n))
                };
                // Never more pull than the point has pushed.
                let d = mul(want, inverse_or_zero(k_upper)).max(-(cp.normal_impulse + given[k]));
                if d.is_zero() {
                    continue;
                }
                given[k] += d;
                if row.upper_is_b {
                    vb.v += scale(n, mul(d, c.inv_mass_b));
                    vb.w += scale(cp.ib_n, d);
                    dls[c.b as usize] += scale(cp.rb_n, d);
                } else {
                    va.v -= scale(n, mul(d, c.inv_mass_a));
                    va.w -= scale(cp.ia_n, d);
                    dls[c.a as usize] -= scale(cp.ra_n, d);
                }
            }
            store(vels, c.a, c.b, va, vb);
        }
    }
}
