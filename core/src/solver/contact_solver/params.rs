//! The solver's settings for a tick: the soft constraint (`Softness`,
//! shared with the joints), the mass-ratio springs, and the counts.

use crate::math::Scalar;

/// The stiffest spring [`Softness::new`] builds, Hz (2²⁴, about 16.8 MHz):
/// rigid at any substep rate.
pub(crate) const MAX_HERTZ: Scalar = Scalar::from_int(1 << 24);

/// The largest damping ratio [`Softness::new`] builds (2²⁴).
pub(crate) const MAX_DAMPING_RATIO: Scalar = Scalar::from_int(1 << 24);

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
    /// No softness: the whole effective mass, nothing relaxed, and the
    /// error pushed out at `bias_rate` (zero: no push-out at all; `1/h`:
    /// the whole error in the substep).
    #[inline]
    pub(crate) const fn rigid(bias_rate: Scalar) -> Softness {
        Softness {
            bias_rate,
            mass_scale: Scalar::ONE,
            impulse_scale: Scalar::ZERO,
        }
    }

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
    ///
    /// A frequency above [`MAX_HERTZ`] or a damping ratio above
    /// [`MAX_DAMPING_RATIO`] (a user's spring may ask for either) is taken
    /// at that bound, so `2πf` and `2ζ` stay in range; such a spring is
    /// rigid at any substep (see [`from_omega`](Self::from_omega)).
    pub(crate) fn new(hertz: Scalar, zeta: Scalar, h: Scalar) -> Softness {
        if !hertz.is_positive() {
            return Softness::rigid(Scalar::ZERO);
        }
        let hertz = hertz.min(MAX_HERTZ);
        let zeta = zeta.min(MAX_DAMPING_RATIO);
        Softness::from_omega(Scalar::TAU * hertz, zeta, h)
    }

    /// A spring of angular frequency `omega` (> 0, at most `2π·MAX_HERTZ`),
    /// damping ratio `zeta` (at most [`MAX_DAMPING_RATIO`]), stepped at `h`
    /// (at most 1 s).
    ///
    /// Bounds: `2ζ ≤ 2²⁵` and `hω ≤ 2π·2²⁴`, so `a1 = 2ζ + hω < 2²⁷`,
    /// but `a2 = hω·a1` can pass Q32.32's range (2³¹) for a spring far
    /// stiffer than the substep (a user's 10⁶ Hz spring at 30 Hz: `a2` ≈
    /// 4·10¹⁰). So `a2` is formed exactly first. From `a2 ≥ 2¹⁶` on, the
    /// spring takes its rigid limit: the whole effective mass, nothing
    /// relaxed, the bias rate `ω/a1` as always. There the limit's own
    /// error, `1/(1 + a2)` on the mass scale, is under 2⁻¹⁶, while the
    /// formula's `a2·round(1/(1 + a2))` would be off by up to `a2·2⁻³³` and
    /// only grows from there (0.05 at `a2` = 2³⁰). Both are under 1.6·10⁻⁵
    /// at the switch. Every contact and joint spring of the world (`hω` ≤
    /// 8, `a2` ≤ 224) is far below it. The same on every machine; no
    /// overflow.
    pub(crate) fn from_omega(omega: Scalar, zeta: Scalar, h: Scalar) -> Softness {
        let a1 = Scalar::TWO * zeta + h * omega;
        // `hω·a1` exactly, in units of 2⁻⁶⁴: 2¹⁶ is 2⁸⁰ of them.
        if (h * omega).wide_mul(a1) >= 1 << 80 {
            return Softness::rigid(omega.checked_div(a1).unwrap_or(Scalar::ZERO));
        }
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

/// Extra visits per relax pass of the contacts that take a hit this tick
/// (see [`ContactSolver::impact`](super::ContactSolver)): one relax visit
/// leaves a hit unconverged, and what it leaves is a spin. A box landing
/// flat while it slides stops its first corner, then friction at the
/// patch centre pitches it over its leading edge before the other rows
/// have taken their share; the next substep's rows then push the leading
/// edge up and the box tips over it, though the hit is fully inelastic.
/// With three more visits (and the relax pass's friction bounded by the
/// load it settles, see `Pass::friction`) the landing converges: a box
/// thrown flat comes to rest along the throw 9.8 mm apart at 480 and
/// 3840 Hz × 1 and 2 mm apart × 4, within 1.7 cm of the rigid closed form
/// at every rate from 60 Hz × 4. With the hit's rows solved as a block
/// (`Pass::hit_row`) it also slides straight: 5 mm at most to the side of
/// the throw at any rate, where it was up to 1.5 cm (docs/stress.md).
pub(super) const IMPACT_RELAX_PASSES: u32 = 3;

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::faults;

    /// The spring formula as written, for a spring whose `hω(2ζ + hω)`
    /// fits: the guard must not change a bit of it.
    fn formula(omega: Scalar, zeta: Scalar, h: Scalar) -> (Scalar, Scalar, Scalar) {
        let a1 = Scalar::TWO * zeta + h * omega;
        let a2 = h * omega * a1;
        let a3 = (Scalar::ONE + a2).recip();
        (omega.checked_div(a1).unwrap(), a2 * a3, a3)
    }

    #[test]
    fn springs_in_range_are_the_formula_bit_for_bit() {
        faults::take();
        for rate in [30, 60, 120, 240, 480, 960, 1920] {
            let h = Scalar::ONE.div_int(rate);
            for hertz in [1, 2, 30, 60, 120, 240, 1000, 5000] {
                for zeta in [Scalar::ZERO, Scalar::ONE, Scalar::TWO, Scalar::from_int(10)] {
                    let hw = std::f64::consts::TAU * hertz as f64 / rate as f64;
                    if hw * (2.0 * zeta.to_f64() + hw) >= 65_000.0 {
                        continue;
                    }
                    let s = Softness::new(Scalar::from_int(hertz), zeta, h);
                    let (b, m, i) = formula(Scalar::TAU * Scalar::from_int(hertz), zeta, h);
                    assert_eq!(
                        (s.bias_rate, s.mass_scale, s.impulse_scale),
                        (b, m, i),
                        "{hertz} Hz, ζ {zeta}, {rate} Hz substeps"
                    );
                }
            }
        }
        assert!(faults::take().is_empty());
    }

    #[test]
    fn a_spring_past_the_range_takes_its_rigid_limit_without_overflow() {
        faults::take();
        let h = Scalar::ONE.div_int(30);
        // hω·(2 + hω) crosses 2³⁰ near hω = 32,767: just below, the formula;
        // from there on, the rigid limit, a few ulps away.
        let below = Softness::from_omega(Scalar::from_int(32_000 * 30), Scalar::ONE, h);
        assert!(below.impulse_scale.to_bits() <= 4, "{below:?}");
        assert!(
            Scalar::ONE.to_bits() - below.mass_scale.to_bits() <= 4,
            "{below:?}"
        );
        for hertz in [1.0e5, 1.0e6, 1.0e9, 2.0e9] {
            for zeta in [0.0, 1.0, 1.0e6, 2.0e9] {
                let s = Softness::new(
                    Scalar::from_f64_lossy(hertz),
                    Scalar::from_f64_lossy(zeta),
                    h,
                );
                assert_eq!(s.mass_scale, Scalar::ONE, "{hertz} Hz, ζ {zeta}");
                assert_eq!(s.impulse_scale, Scalar::ZERO, "{hertz} Hz, ζ {zeta}");
                // ω/(2ζ + hω): at most 1/h, and close to it unless ζ is
                // far above hω.
                assert!(s.bias_rate <= Scalar::from_int(30), "{hertz} Hz, ζ {zeta}");
                assert!(s.bias_rate.is_positive(), "{hertz} Hz, ζ {zeta}");
            }
        }
        let stiff = Softness::new(Scalar::from_int(1_000_000), Scalar::ONE, h);
        assert!((stiff.bias_rate.to_f64() - 30.0).abs() < 0.001, "{stiff:?}");
        assert!(faults::take().is_empty());
    }
}
