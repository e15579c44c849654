//! The solver's settings for a tick: the soft constraint (`Softness`,
//! shared with the joints), the mass-ratio springs, and the counts.

use crate::math::Scalar;

/// Softness of the contact spring for a substep.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Softness {
    /// `ω/(2ζ + hω)`: converts a separation into a velocity bias.
    pub bias_rate: Scalar,
    /// `hω(2ζ + hω)/(1 + hω(2ζ + hω))`: scales the effective mass.
    pub mass_scale: Scalar,
    /// `1/(1 + hω(2ζ + hω))`: how much of the accumulated impulse relaxes.
    pub impulse_scale: Scalar,
}

impl Softness {
    /// Whether this is no softness at all: no bias, the whole effective
    /// mass, nothing relaxed.
    #[inline]
    pub(crate) fn is_rigid(&self) -> bool {
        self.bias_rate.is_zero() && self.mass_scale == Scalar::ONE && self.impulse_scale.is_zero()
    }

    /// The spring of a contact whose lighter body has inverse mass `hi` and
    /// touches (through it or its partner) a body of inverse mass `lo`, and
    /// whether that ratio counts as high. See [`RATIO_KEPT`].
    pub(crate) fn for_ratio(params: &SolverParams, lo: Scalar, hi: Scalar) -> (Softness, bool) {
        if !lo.is_positive() || !params.omega.is_positive() {
            return (params.softness, false);
        }
        // R = m_heavy/m_light = hi/lo.
        let Some(ratio) = hi.checked_div(lo) else {
            return (params.softness, false);
        };
        if ratio <= Scalar::from_int(RATIO_KEPT) {
            return (params.softness, false);
        }
        let f = (ratio + Scalar::ONE).div_int(RATIO_KEPT as i64 + 1);
        let omega = (params.omega * crate::math::elem::sqrt(f)).min(params.omega_max);
        (Softness::from_omega(omega, params.zeta, params.h), true)
    }

    /// A spring of `hertz` with damping ratio `zeta`, stepped at `h`
    /// (Box2D's `b2MakeSoft`). A zero frequency gives a rigid constraint
    /// without bias.
    pub(crate) fn new(hertz: Scalar, zeta: Scalar, h: Scalar) -> Softness {
        if !hertz.is_positive() {
            return Softness {
                bias_rate: Scalar::ZERO,
                mass_scale: Scalar::ONE,
                impulse_scale: Scalar::ZERO,
            };
        }
        Softness::from_omega(Scalar::TAU * hertz, zeta, h)
    }

    /// A spring of angular frequency `omega` (> 0), damping ratio `zeta`,
    /// stepped at `h`.
    pub(crate) fn from_omega(omega: Scalar, zeta: Scalar, h: Scalar) -> Softness {
        let a1 = Scalar::TWO * zeta + h * omega;
        let a2 = h * omega * a1;
        let a3 = (Scalar::ONE + a2).recip();
        Softness {
            bias_rate: omega.checked_div(a1).unwrap_or(Scalar::ZERO),
            mass_scale: a2 * a3,
            impulse_scale: a3,
        }
    }
}

/// The mass ratio up to which a contact keeps the world's spring: there
/// its static depth, (1 + R)·g/ω² for a light body under a heavy one (the
/// effective mass is about the light body's, the load the heavy one's), is
/// at most 4.5 mm at 60 Hz. Above it the spring's ω is raised by
/// `√((1 + R)/(1 + RATIO_KEPT))` (up to `omega_max`) so the depth stays
/// there, and the pass visits the contact [`HIGH_RATIO_PASSES`] more times:
/// Gauss–Seidel between a light and a heavy body converges about R times
/// slower, and with a single visit the stiffer spring let a box 1,000
/// times heavier through the light one.
pub(super) const RATIO_KEPT: i32 = 64;

/// Extra visits per pass of the high-ratio contacts (see [`RATIO_KEPT`]).
pub(super) const HIGH_RATIO_PASSES: u32 = 3;

/// Settings the solver reads each tick.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SolverParams {
    /// The substep `h` and `1/h`.
    pub h: Scalar,
    pub inv_h: Scalar,
    /// The contact spring.
    pub softness: Softness,
    /// Its angular frequency and its damping ratio.
    pub omega: Scalar,
    pub zeta: Scalar,
    /// The stiffest spring a high-ratio contact may get (see
    /// [`RATIO_KEPT`]).
    pub omega_max: Scalar,
    /// Cap on the push-out speed of overlapping shapes, m/s.
    pub max_push_out: Scalar,
    /// Normal approach speed below which there is no bounce, m/s.
    pub restitution_threshold: Scalar,
    /// Whether the constraints are solved in colour order (see [`color`])
    /// rather than pair order.
    pub colored: bool,
    /// Whether the passes solve the contacts on the narrow rows (see
    /// [`narrow`]) where they fit, rather than on the Q32.32 rows.
    pub narrow: bool,
}

/// Counters from one tick's solve.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct SolverStats {
    /// Constraints (solid pairs with points).
    pub constraints: u32,
    /// Colours with at least one constraint (see [`color`]).
    pub colors: u32,
    /// Constraints that found no free colour (solved after the colours).
    pub overflow: u32,
    /// Times a buffer grew.
    pub growths: u32,
    /// Constraints that start the tick on the narrow rows.
    pub narrow: u32,
    /// Batches of eight of them that the lanes may visit together.
    pub lane_batches: u32,
}
