//! An actuator described from its datasheet and a bench, and every controller setting
//! derived from it.
//!
//! A user brings an actuator this product has never seen. What they can write down is
//! short ([`Actuator`], about twenty numbers: the moving mass, the spring, the coil, the
//! magnetic circuit, the stroke, the ratings, the supply, the board's sensor ranges and the
//! interrupt rate); everything the controller needs ([`crate::control::Settings`]) follows
//! from it in [`Actuator::settings`], in one place. Nothing there is a number tuned on one
//! actuator: every gain, threshold and limit is built from the actuator's own time scales
//! ([`TimeScales`]) and the converters' resolution, and each rule says why.
//!
//! The position convention is the physical one ([`Convention::Physical`]): `x` is the
//! stroke from the open end stop, where the spring holds the armature when the coil is
//! off; the airgap is `residual + stroke - x` and the magnet pulls along `+x`, closing it.
//!
//! ## The magnetic circuit, two ways
//!
//! * **Geometry** ([`Magnetics::Geometry`]): a pole face `a x b`, the number of equal
//!   airgaps in series, the paper's fringing growth `S(g) = (a + k g)(b + k g)` and the
//!   iron path's reluctance.
//! * **Two inductances** ([`Magnetics::Inductance`]), as measured on a bench with an LCR
//!   meter at the two end stops: with `L(g) = N^2 / (rho_x g + rho_0)` the two readings give
//!   `rho_x` and `rho_0` exactly; the airgap is then modelled as one gap of constant surface
//!   `S = 1 / (mu0 rho_x)`.
//!
//! Either way the airgap surface is the paper's bounded uncertainty: real actuators have
//! surfaces in `[(1 - s) min S, (1 + s) max S]` over the stroke, `s` the surface
//! tolerance. The controller's lower bound goes further down where it must: the paper
//! builds its force bound with the surface held constant, but the force of a surface that
//! grows with the gap is weaker (`energy_consistent_share`), and `mu_lo` has to hold
//! for it too.
//!
//! ## Physical consistency
//!
//! A design is an actuator a user could have only if its coil holds the armature anywhere
//! on the stroke with a margin, its supply drives the rated current through the hot coil,
//! its iron is not saturated where it is held, and its magnet pulls at every gap of the
//! stroke on every surface the tolerance allows ([`Consistency`],
//! [`Actuator::check_consistency`]). The rules judge a design before gains are chosen for
//! it (the host's `tune` refuses a file that breaks one, with the rule named); the
//! settings themselves do not check them, so that an actuator identified on a bench, which
//! is what it is, still gets a controller when it sits near a margin.
//!
//! ## Derived settings and why
//!
//! | setting | rule |
//! |---|---|
//! | law current limit | the rated current less the ripple allowance (2 % of it): the coil never carries more than its rating |
//! | current trip | the peak current; the current channel must read it with 5 % to spare |
//! | I^2 t | continuous rating = rated current; allowance `(I_peak^2 - I_rated^2) t_peak` |
//! | bus window | 60 % to 125 % of the supply |
//! | position window | the stroke with 10 % on either side |
//! | backstepping `alpha1 = alpha2` | tuned ([`Tuning`]); by default [`DEFAULT_ALPHA_PER_W`] times the mechanical frequency [`TimeScales::mechanical_rad_s`] |
//! | observer bandwidth | tuned; by default [`DEFAULT_OBSERVER_PER_ALPHA`] times `alpha` |
//! | disturbance model | tuned: constant, or following the magnet's force above [`FORCE_SCALED_SHARE`] of the current limit (see [`crate::control::observer`]); by default following |
//! | shaping margin | tuned; by default [`DEFAULT_MARGIN`] |
//! | shaping acceleration cap | the force authority at the rated current ([`TimeScales::authority_mps2`]) |
//! | shortest move | `2.6 / alpha`: the error poles are `-alpha +- j`, and a step of the reference settles to 2 % in about `4 / alpha`; a shorter move would only be rounded off by the loop |
//! | stuck-sensor band and travel | [`NOISE_ALLOWANCE_CODES`] position codes (4 sigma of the difference of two readings) and [`STUCK_TRAVEL_BANDS`] bands of reference travel: the sensor's own resolution and noise ([`stuck_detector`]) |
//! | residual noise, jump, open | [`NOISE_ALLOWANCE_CODES`], [`JUMP_ALLOWANCES`] and [`OPEN_ALLOWANCES`] allowances in current codes: the current channel's own resolution and noise ([`residual_detector`]) |
//! | residual's learned resistance | learned over blocks of [`LEARN_BLOCK_S`] within [`LEARN_TOLERANCE`] plus the current channel's offset class ([`OFFSET_CLASS_CODES`]) over the block's current, for [`LEARN_AGE_S`] |
//! | residual window, confirmation | half the detection deadline ([`DEADLINE_S`]) in interrupt periods; [`RESIDUAL_CONFIRM_TICKS`] ticks, from the converter's noise |
//! | tracking error | 1/8 of the stroke, for a quarter of the settling target |
//! | a move's settling target | 1.5 times the fastest move the limits allow, the coil's current rise included, at least the paper's 0.2 s ([`crate::control::shaping::Config::settling_target_s`]) |
//!
//! ```
//! use ema::control::actuator::Actuator;
//!
//! let product = Actuator::PRODUCT;
//! let settings = product.settings().unwrap();
//! // The physical convention: the airgap at the open stop is the residual gap plus the stroke.
//! let gap = settings.plant.gap_m(0.0);
//! assert!((gap - 4.5e-3).abs() < 1e-9);
//! settings.build().unwrap();
//!
//! // A refusal names the field of the actuator file and its value.
//! let mut bad = Actuator::PRODUCT;
//! bad.coil.peak_current_a = 5.0;
//! let e = bad.settings().unwrap_err();
//! assert_eq!(e.param, "coil.peak_current_a");
//! ```

use crate::control::config::{self, Error, Reason};
use crate::control::law;
use crate::control::math;
use crate::control::model::{self, Bounds, Convention, Fringing, Plant, Tolerance, MU0_H_PER_M};
use crate::control::observer;
use crate::control::sense::{
    Calibration, Channel, PositionCorrection, ADC_MAX_CODE, NOISE_RMS_CODES, RAIL_MARGIN_CODES,
};
use crate::control::shaping;
use crate::control::supervisor::monitor::{Monitors, Residual, Stuck, Thermal, Tracking};
use crate::control::supervisor::{Limits, DEADLINE_S};
use crate::control::Settings;

/// The armature, its spring and its stroke.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Mechanics {
    /// Moving mass \[kg\].
    pub mass_kg: f32,
    /// Spring rate \[N/m\].
    pub spring_n_per_m: f32,
    /// Spring force at the open stop (`x = 0`) \[N\].
    #[serde(default)]
    pub preload_n: f32,
    /// Viscous friction, an estimate \[N s/m\].
    pub friction_n_s_per_m: f32,
    /// Travel between the end stops \[m\].
    pub stroke_m: f32,
    /// Airgap left at the closed stop (`x = stroke`) \[m\].
    pub residual_gap_m: f32,
}

/// The coil and its ratings.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Coil {
    /// Resistance at the operating temperature \[ohm\].
    pub resistance_ohm: f32,
    /// Turns \[-\].
    pub turns: f32,
    /// Continuous current rating \[A\].
    pub rated_current_a: f32,
    /// Largest current the coil and the driver tolerate; the trip level \[A\].
    pub peak_current_a: f32,
    /// How long the coil may carry the peak current from its rating \[s\].
    #[serde(default = "default_peak_time_s")]
    pub peak_time_s: f32,
}

const fn one() -> f32 {
    1.0
}

const fn default_peak_time_s() -> f32 {
    DEFAULT_PEAK_TIME_S
}

/// Default of [`Coil::peak_time_s`] \[s\].
pub const DEFAULT_PEAK_TIME_S: f32 = 0.1;

/// The magnetic circuit: from its geometry, or from two inductance readings.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Magnetics {
    /// Pole geometry: `S(g) = c (a + k g)(b + k g)` for each gap.
    Geometry {
        /// Equal airgaps in series \[-\].
        gaps: f32,
        /// Pole side `a` \[m\].
        pole_a_m: f32,
        /// Pole side `b` \[m\].
        pole_b_m: f32,
        /// Fringing coefficient `c >= 1`: the paper's weighting of the pole face \[-\].
        #[serde(default = "one")]
        fringing_coefficient: f32,
        /// Growth of each pole side per metre of gap by fringing, `k` (the paper's
        /// rectangular-pole formula has 1) \[-\].
        #[serde(default = "one")]
        fringing_spread: f32,
        /// Reluctance of the iron path `rho_0` \[1/H\].
        iron_reluctance_per_h: f32,
    },
    /// Inductance measured at the two end stops.
    Inductance {
        /// At the open stop (`x = 0`, largest gap) \[H\].
        open_h: f32,
        /// At the closed stop (`x = stroke`, the residual gap) \[H\].
        closed_h: f32,
    },
}

/// The board: supply, interrupt rate and the sensors' ranges.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Board {
    /// Supply (bus) voltage \[V\].
    pub supply_v: f32,
    /// Control interrupt rate, one tick per PWM period \[Hz\].
    pub rate_hz: f32,
    /// Travel the position sensor maps onto the converter's range, less the room
    /// [`Actuator::calibration`] leaves at either end for the sensor's tolerance \[m\]; at
    /// least the stroke.
    pub position_span_m: f32,
    /// Full scale of the bidirectional current channel, `+-` this \[A\].
    pub current_full_scale_a: f32,
    /// Bus voltage at the converter's full scale \[V\].
    pub vbus_full_scale_v: f32,
}

/// How far the real actuator may be from the file: the controller's uncertainty set.
/// Every field has a default ([`Tolerances::default`]).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Tolerances {
    /// Airgap surface (flux fringing), relative \[-\].
    pub surface: f32,
    /// Moving mass, relative \[-\].
    pub mass: f32,
    /// Spring rate and preload, relative \[-\].
    pub spring: f32,
    /// Friction, relative \[-\].
    pub friction: f32,
    /// Coil resistance (temperature), relative \[-\].
    pub resistance: f32,
}

impl Default for Tolerances {
    /// Surfaces +-20 %, mass +-10 %, spring +-10 %, friction +-50 %, resistance +-20 %.
    fn default() -> Self {
        Self {
            surface: 0.2,
            mass: 0.1,
            spring: 0.1,
            friction: 0.5,
            resistance: 0.2,
        }
    }
}

/// What `hil-sim tune` chose for this actuator (a tuned file carries it).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tuning {
    /// Backstepping gains `alpha1 = alpha2` \[1/s\].
    pub alpha_per_s: f32,
    /// Observer bandwidth \[rad/s\].
    pub observer_rad_s: f32,
    /// Reference-shaping margin, in (0, 1] \[-\].
    pub margin: f32,
    /// The observer's disturbance follows the magnet's force above a tenth of the current
    /// limit ([`FORCE_SCALED_SHARE`], see [`crate::control::observer`]); otherwise it is
    /// constant.
    pub disturbance_follows_force: bool,
}

/// An actuator file: what a user writes from a datasheet and a bench.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Actuator {
    /// Armature, spring, stroke.
    pub mechanics: Mechanics,
    /// Coil and ratings.
    pub coil: Coil,
    /// Magnetic circuit.
    pub magnetics: Magnetics,
    /// Supply, rate and sensors.
    pub board: Board,
    /// Uncertainty the controller must cover.
    #[serde(default)]
    pub tolerance: Tolerances,
    /// Gains chosen by `hil-sim tune` (absent in a hand-written file).
    #[serde(default)]
    pub tuning: Option<Tuning>,
}

/// Time scales of an actuator: what every derived gain and threshold is built from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimeScales {
    /// Mechanical natural frequency `sqrt(K / m)` \[rad/s\].
    pub natural_rad_s: f32,
    /// Force authority: the magnet's pull at the rated current at mid-stroke on the
    /// nominal circuit, per unit mass \[m/s^2\].
    pub authority_mps2: f32,
    /// `sqrt(authority / stroke)`: how fast the magnet can move the armature across its
    /// stroke \[rad/s\].
    pub authority_rad_s: f32,
    /// Coil time constant `L / R` at the open stop (smallest inductance) \[s\].
    pub coil_open_s: f32,
    /// Coil time constant at the closed stop (largest inductance) \[s\].
    pub coil_closed_s: f32,
    /// Interrupt period \[s\].
    pub period_s: f32,
    /// Position resolution: one converter code \[m\].
    pub position_code_m: f32,
}

impl TimeScales {
    /// The frequency the mechanical loop is designed around: the larger of the natural
    /// frequency and the authority frequency \[rad/s\]. A soft spring leaves the magnet's
    /// authority as the scale; a stiff one its own resonance.
    #[must_use]
    pub fn mechanical_rad_s(&self) -> f32 {
        math::max(self.natural_rad_s, self.authority_rad_s)
    }
}

/// Periods between a conversion and the duty computed from it taking effect: the board
/// converts around the top of the count and the duty is applied at the next period
/// boundary \[-\].
pub const DELAY_TICKS: u8 = 1;
/// Default `alpha` per unit of [`TimeScales::mechanical_rad_s`] \[-\].
pub const DEFAULT_ALPHA_PER_W: f32 = 2.0;
/// Default observer bandwidth per unit of `alpha` \[-\].
pub const DEFAULT_OBSERVER_PER_ALPHA: f32 = 1.5;
/// Default reference-shaping margin \[-\].
pub const DEFAULT_MARGIN: f32 = 0.7;
/// Least ratio of the peak (trip) current to the rated current: the trip sits above the
/// law's limit plus the ripple and the current loop's settling \[-\].
pub const PEAK_OVER_RATED: f32 = 1.05;
/// Share of the current limit above which the observer's disturbance follows the magnet
/// force (see [`crate::control::observer`]) \[-\].
pub const FORCE_SCALED_SHARE: f32 = 0.1;
/// Ripple allowance: the targets allow 2 % of the rated current peak to peak at the
/// samples, so the law keeps its desired current that far below the rating \[-\].
pub const RIPPLE_SHARE: f32 = 0.02;

/// Offset and gain error a position sensor may carry, each as a share of its span \[-\]:
/// the calibration leaves room for both at either end of the stroke, so that such a sensor
/// reads within the converter's plausible window until commissioning measures its ends.
pub const POSITION_SENSOR_TOLERANCE: f32 = 0.03;

/// The room [`Actuator::calibration`] leaves for a position sensor's error at either end
/// of the stroke, as a share of its span: an offset and a gain error of
/// [`POSITION_SENSOR_TOLERANCE`] each \[-\]. A commissioning's correction beyond it is
/// refused ([`Actuator::calibration_with`]).
pub const POSITION_CORRECTION_ROOM: f32 = 2.0 * POSITION_SENSOR_TOLERANCE;
/// The board's over-current comparator, per unit of the peak current (the software trip):
/// 20 % above it, for the PWM ripple and the rise within one period that the sampled trip
/// cannot see.
pub const BREAK_PER_PEAK: f32 = 1.2;
/// Largest share of the current channel's full scale the comparator may trip at: 2047
/// codes of the 2048 either side of mid-scale, so that the converter sees what tripped it.
const BREAK_SHARE_OF_FULL_SCALE: f32 = 2047.0 / 2048.0;
/// The bus channel must read this much above the over-voltage trip: a supply at 140 % of
/// its nominal must read as an over-voltage, not as a broken sensor on its rail.
const VBUS_HEADROOM: f32 = 1.15;
/// Bus window around the supply.
const VBUS_MIN_SHARE: f32 = 0.6;
const VBUS_MAX_SHARE: f32 = 1.25;

impl Actuator {
    /// The product's default actuator: the paper's (Table I: `m = 0.1 kg`,
    /// `K = 120 N/m`, `lambda = 5 N s/m`, `R = 0.4 ohm`, `N = 70`, `rho_0 = 630 1/H`, two
    /// airgaps whose 7 mm x 7 mm pole with a fringing coefficient of 1.16 gives
    /// `rho_x = 2.8e10 1/(H m)`) in the physical convention: 4 mm of stroke closing onto a
    /// 0.5 mm residual gap; 12 A rated, 13.2 A peak; 24 V; 20 kHz; the reference board's
    /// sensors (4 mm position span, +-16.5 A, 72.6 V); the gains `hil-sim tune` chose
    /// (`hil-sim/actuators/product.tuned.toml`, which a test keeps equal to this).
    ///
    /// The surface is constant over the stroke (the paper's weighting coefficient, no
    /// fringing spread), as in the paper's example.
    pub const PRODUCT: Actuator = Actuator {
        mechanics: Mechanics {
            mass_kg: 0.1,
            spring_n_per_m: 120.0,
            preload_n: 0.0,
            friction_n_s_per_m: 5.0,
            stroke_m: 4.0e-3,
            residual_gap_m: 0.5e-3,
        },
        coil: Coil {
            resistance_ohm: 0.4,
            turns: 70.0,
            rated_current_a: 12.0,
            peak_current_a: 13.2,
            peak_time_s: DEFAULT_PEAK_TIME_S,
        },
        magnetics: Magnetics::Geometry {
            gaps: 2.0,
            pole_a_m: 7.0e-3,
            pole_b_m: 7.0e-3,
            fringing_coefficient: 1.16,
            fringing_spread: 0.0,
            iron_reluctance_per_h: 630.0,
        },
        board: Board {
            supply_v: 24.0,
            rate_hz: 20_000.0,
            position_span_m: 4.0e-3,
            current_full_scale_a: 16.5,
            vbus_full_scale_v: 72.6,
        },
        tolerance: Tolerances {
            surface: 0.2,
            mass: 0.1,
            spring: 0.1,
            friction: 0.5,
            resistance: 0.2,
        },
        tuning: Some(Tuning {
            alpha_per_s: 139.0,
            observer_rad_s: 139.0,
            margin: 0.7,
            disturbance_follows_force: false,
        }),
    };

    /// The same actuator at another interrupt rate \[Hz\], with the same gains and
    /// observer bandwidth (in rad/s). (Scaling the bandwidth with the rate, as
    /// `(f / f0)^(1/5)` to hold the disturbance estimate's noise variance, `Ts w^5`,
    /// constant, made the product's current ripple worse at the higher rates: the ripple
    /// at the samples follows the velocity estimate as much as the disturbance.)
    #[must_use]
    pub fn with_rate_hz(mut self, rate_hz: f32) -> Self {
        self.board.rate_hz = rate_hz;
        self
    }

    /// The same actuator on another supply \[V\]; the bus channel's full scale grows to
    /// twice the supply where the board's would clip an over-voltage.
    #[must_use]
    pub fn with_supply_v(mut self, supply_v: f32) -> Self {
        self.board.supply_v = supply_v;
        self.board.vbus_full_scale_v = math::max(self.board.vbus_full_scale_v, 2.0 * supply_v);
        self
    }

    /// Checks every field of the file.
    ///
    /// # Errors
    /// The first field that is missing a physical value, by its name in the file.
    pub fn validate(&self) -> Result<(), Error> {
        let m = &self.mechanics;
        config::positive("mechanics.mass_kg", m.mass_kg)?;
        config::at_least("mechanics.spring_n_per_m", m.spring_n_per_m, 0.0)?;
        config::at_least("mechanics.preload_n", m.preload_n, 0.0)?;
        config::at_least("mechanics.friction_n_s_per_m", m.friction_n_s_per_m, 0.0)?;
        config::positive("mechanics.stroke_m", m.stroke_m)?;
        config::positive("mechanics.residual_gap_m", m.residual_gap_m)?;
        let c = &self.coil;
        config::positive("coil.resistance_ohm", c.resistance_ohm)?;
        config::at_least("coil.turns", c.turns, 1.0)?;
        config::positive("coil.rated_current_a", c.rated_current_a)?;
        config::at_least(
            "coil.peak_current_a",
            c.peak_current_a,
            PEAK_OVER_RATED * c.rated_current_a,
        )?;
        config::positive("coil.peak_time_s", c.peak_time_s)?;
        match self.magnetics {
            Magnetics::Geometry {
                gaps,
                pole_a_m,
                pole_b_m,
                fringing_coefficient,
                fringing_spread,
                iron_reluctance_per_h,
            } => {
                config::at_least("magnetics.geometry.gaps", gaps, 1.0)?;
                config::positive("magnetics.geometry.pole_a_m", pole_a_m)?;
                config::positive("magnetics.geometry.pole_b_m", pole_b_m)?;
                config::at_least(
                    "magnetics.geometry.fringing_coefficient",
                    fringing_coefficient,
                    1.0,
                )?;
                config::at_least("magnetics.geometry.fringing_spread", fringing_spread, 0.0)?;
                config::positive(
                    "magnetics.geometry.iron_reluctance_per_h",
                    iron_reluctance_per_h,
                )?;
            }
            Magnetics::Inductance { open_h, closed_h } => {
                config::positive("magnetics.inductance.open_h", open_h)?;
                config::positive("magnetics.inductance.closed_h", closed_h)?;
                config::ordered(
                    "magnetics.inductance.open_h",
                    open_h,
                    "magnetics.inductance.closed_h",
                    closed_h,
                )?;
            }
        }
        let b = &self.board;
        config::positive("board.supply_v", b.supply_v)?;
        config::positive("board.rate_hz", b.rate_hz)?;
        config::at_least("board.position_span_m", b.position_span_m, m.stroke_m)?;
        // The board's comparator trips inside the channel's full scale.
        let least_fs = BREAK_PER_PEAK * c.peak_current_a / BREAK_SHARE_OF_FULL_SCALE;
        config::at_least(
            "board.current_full_scale_a",
            b.current_full_scale_a,
            least_fs,
        )?;
        let least_vbus = VBUS_HEADROOM * VBUS_MAX_SHARE * b.supply_v;
        config::at_least("board.vbus_full_scale_v", b.vbus_full_scale_v, least_vbus)?;
        let t = &self.tolerance;
        let below_one = 1.0 - f32::EPSILON;
        config::within("tolerance.surface", t.surface, 0.0, below_one)?;
        config::within("tolerance.mass", t.mass, 0.0, below_one)?;
        config::within("tolerance.spring", t.spring, 0.0, below_one)?;
        config::within("tolerance.friction", t.friction, 0.0, below_one)?;
        config::within("tolerance.resistance", t.resistance, 0.0, below_one)?;
        if let Some(t) = &self.tuning {
            config::positive("tuning.alpha_per_s", t.alpha_per_s)?;
            config::positive("tuning.observer_rad_s", t.observer_rad_s)?;
            config::within("tuning.margin", t.margin, f32::MIN_POSITIVE, 1.0)?;
        }
        Ok(())
    }

    /// The actuator as the controller's model knows it (physical convention, nominal
    /// values, surface bounds, tolerances).
    ///
    /// # Errors
    /// As [`Actuator::validate`], and a circuit whose two inductances imply a negative
    /// iron reluctance (named `magnetics.inductance.closed_h`).
    pub fn plant(&self) -> Result<Plant, Error> {
        self.validate()?;
        let m = &self.mechanics;
        let convention = Convention::Physical {
            gap_at_zero_m: m.residual_gap_m + m.stroke_m,
        };
        let magnetics = match self.magnetics {
            Magnetics::Geometry {
                gaps,
                pole_a_m,
                pole_b_m,
                fringing_coefficient,
                fringing_spread,
                iron_reluctance_per_h,
            } => model::Magnetics {
                turns: self.coil.turns,
                rho0_per_h: iron_reluctance_per_h,
                gaps,
                fringing: if fringing_spread == 0.0 {
                    Fringing::Coefficient {
                        alpha: fringing_coefficient,
                        pole_m2: pole_a_m * pole_b_m,
                    }
                } else {
                    // c (a + k g)(b + k g) = (a' + k' g)(b' + k' g) with every length
                    // scaled by sqrt(c).
                    let r = math::sqrt(fringing_coefficient);
                    Fringing::Rectangular {
                        a_m: r * pole_a_m,
                        b_m: r * pole_b_m,
                        spread: r * fringing_spread,
                    }
                },
            },
            Magnetics::Inductance { open_h, closed_h } => {
                // 1/L = (rho_x g + rho_0) / N^2 at the two gaps.
                let n2 = self.coil.turns * self.coil.turns;
                let (g_open, g_closed) = (m.residual_gap_m + m.stroke_m, m.residual_gap_m);
                let rho_x = n2 * (1.0 / open_h - 1.0 / closed_h) / (g_open - g_closed);
                let rho0 = n2 / closed_h - rho_x * g_closed;
                if rho0.partial_cmp(&0.0) != Some(core::cmp::Ordering::Greater) {
                    return Err(refused(
                        "magnetics.inductance.closed_h",
                        closed_h,
                        "iron reluctance rho_0 [1/H]",
                        rho0,
                    ));
                }
                model::Magnetics {
                    turns: self.coil.turns,
                    rho0_per_h: rho0,
                    gaps: 1.0,
                    fringing: Fringing::Coefficient {
                        alpha: 1.0,
                        pole_m2: 1.0 / (MU0_H_PER_M * rho_x),
                    },
                }
            }
        };
        let t = &self.tolerance;
        let convention_gaps = convention.gap_range_m(m.stroke_m);
        let physical = Bounds::around(&magnetics.fringing, convention_gaps, t.surface, t.surface);
        let plant = Plant {
            mass_kg: m.mass_kg,
            spring_n_per_m: m.spring_n_per_m,
            preload_n: m.preload_n,
            friction_n_s_per_m: m.friction_n_s_per_m,
            resistance_ohm: self.coil.resistance_ohm,
            magnetics,
            bounds: Bounds {
                s_lo_m2: physical.s_lo_m2
                    * energy_consistent_share(&magnetics, &physical, convention_gaps),
                s_hi_m2: physical.s_hi_m2,
            },
            convention,
            stroke_m: m.stroke_m,
            tolerance: Tolerance {
                surface: t.surface,
                mass: t.mass,
                spring: t.spring,
                friction: t.friction,
                resistance: t.resistance,
            },
        };
        plant.validate()?;
        Ok(plant)
    }

    /// The converters' calibration: the position sensor's zero and span placed so that a
    /// sensor off by [`POSITION_SENSOR_TOLERANCE`] in offset and in gain still reads inside
    /// the plausible window at both stops, noise included; the current channel
    /// bidirectional about mid-scale, the bus from zero; codes within 1 % of a rail read as
    /// a broken sensor.
    #[must_use]
    pub fn calibration(&self) -> Calibration {
        let full = f32::from(ADC_MAX_CODE) + 1.0;
        let b = &self.board;
        let window_lo = RAIL_MARGIN_CODES;
        let window_hi = ADC_MAX_CODE - RAIL_MARGIN_CODES;
        // Below the zero and above the span's end, room for an offset and a gain error of
        // the tolerance each (2 T of the span) and the noise's reach, inside the window.
        let room = POSITION_CORRECTION_ROOM;
        let reach = NOISE_SIGMAS * NOISE_RMS_CODES;
        let inside = f32::from(window_hi) - f32::from(window_lo) - 2.0 * reach;
        let span_codes = inside / (1.0 + 2.0 * room);
        Calibration {
            position: Channel {
                offset_code: f32::from(window_lo) + reach + room * span_codes,
                scale: b.position_span_m / span_codes,
                min_code: window_lo,
                max_code: window_hi,
            },
            current: Channel {
                offset_code: 0.5 * full,
                scale: b.current_full_scale_a / (0.5 * full),
                min_code: window_lo,
                max_code: window_hi,
            },
            vbus: Channel {
                offset_code: 0.0,
                scale: b.vbus_full_scale_v / full,
                min_code: 0,
                max_code: window_hi,
            },
        }
    }

    /// The converters' calibration with the position sensor's measured gain and offset
    /// taken out ([`PositionCorrection`], from a commissioning's end stops).
    ///
    /// A correction is refused beyond the room [`Actuator::calibration`] leaves at either
    /// end of the stroke, [`POSITION_CORRECTION_ROOM`]: a sensor off by more would read
    /// outside the plausible window at a stop, so a larger measured error is not the
    /// sensor's but a stroke or span in the file that the actuator does not have.
    ///
    /// # Errors
    /// `sensor.position_gain` or `sensor.position_offset_codes` not finite or beyond the
    /// room.
    pub fn calibration_with(&self, c: &PositionCorrection) -> Result<Calibration, Error> {
        let mut cal = self.calibration();
        let room = POSITION_CORRECTION_ROOM;
        config::within("sensor.position_gain", c.gain, 1.0 - room, 1.0 + room)?;
        let span_codes = self.board.position_span_m / cal.position.scale;
        let reach = room * span_codes.abs();
        config::within(
            "sensor.position_offset_codes",
            c.offset_codes,
            -reach,
            reach,
        )?;
        cal.position = cal.position.corrected(c);
        Ok(cal)
    }

    /// The actuator's time scales.
    ///
    /// # Errors
    /// As [`Actuator::plant`].
    pub fn time_scales(&self) -> Result<TimeScales, Error> {
        let plant = self.plant()?;
        let m = &self.mechanics;
        let nominal = plant.envelope()?.nominal();
        let g_mid = plant.gap_m(0.5 * m.stroke_m);
        let i = self.coil.rated_current_a;
        let authority = 0.5 * nominal.force_coefficient_h_per_m(g_mid) * i * i / m.mass_kg;
        let r = self.coil.resistance_ohm;
        Ok(TimeScales {
            natural_rad_s: math::sqrt(m.spring_n_per_m / m.mass_kg),
            authority_mps2: authority,
            authority_rad_s: math::sqrt(authority / m.stroke_m),
            coil_open_s: nominal.inductance_h(plant.gap_m(0.0)) / r,
            coil_closed_s: nominal.inductance_h(plant.gap_m(m.stroke_m)) / r,
            period_s: 1.0 / self.board.rate_hz,
            position_code_m: self.calibration().position.scale,
        })
    }

    /// The gains in use: the tuned ones, or the defaults derived from the time scales.
    ///
    /// # Errors
    /// As [`Actuator::plant`].
    #[inline(never)]
    pub fn tuning_or_default(&self) -> Result<Tuning, Error> {
        if let Some(t) = self.tuning {
            self.validate()?;
            return Ok(t);
        }
        let alpha = DEFAULT_ALPHA_PER_W * self.time_scales()?.mechanical_rad_s();
        Ok(Tuning {
            alpha_per_s: alpha,
            observer_rad_s: DEFAULT_OBSERVER_PER_ALPHA * alpha,
            margin: DEFAULT_MARGIN,
            disturbance_follows_force: true,
        })
    }

    /// The level the board's over-current comparator trips at, either direction
    /// ([`BREAK_PER_PEAK`] times the peak current) \[A\]: it switches the bridge off without
    /// software, within the period the sampled trip cannot see into.
    #[must_use]
    pub const fn break_current_a(&self) -> f32 {
        BREAK_PER_PEAK * self.coil.peak_current_a
    }

    /// The law's limit on the desired current: the rating less the ripple allowance \[A\].
    #[must_use]
    pub fn current_limit_a(&self) -> f32 {
        (1.0 - RIPPLE_SHARE) * self.coil.rated_current_a
    }

    /// The largest voltage the bridge puts across the coil from the supply at the board's
    /// rate \[V\].
    fn drive_v(&self) -> f32 {
        self.board.supply_v * crate::control::bridge::max_modulation(self.board.rate_hz)
    }

    /// Time the coil's current takes from zero to `current_a` at full drive through its
    /// closed-stop inductance \[s\]: `tau ln(U / (U - R i))` with `tau = L / R` (the
    /// first-order rise toward `U / R`), on the nominal coil, as the settling target
    /// describes the nominal actuator.
    ///
    /// # Errors
    /// A drive that cannot reach `current_a` even through the nominal coil, as the drive
    /// rule ([`Consistency::drive_ratio`]) names it.
    fn current_rise_s(&self, scales: &TimeScales, current_a: f32) -> Result<f32, Error> {
        let drop_v = self.coil.resistance_ohm * current_a;
        let drive_v = self.drive_v();
        if (drive_v - drop_v).partial_cmp(&0.0) != Some(core::cmp::Ordering::Greater) {
            return Err(refused(
                "board.supply_v",
                self.board.supply_v,
                RULE_DRIVE,
                drive_v / drop_v,
            ));
        }
        Ok(scales.coil_closed_s * math::ln(drive_v / (drive_v - drop_v)))
    }

    /// Every controller setting, derived (see the module documentation for each rule).
    /// The result is validated by building it once.
    ///
    /// # Errors
    /// The first bad field of the file by its name, or a derived setting that does not
    /// build (named as in the settings).
    pub fn settings(&self) -> Result<Settings, Error> {
        let plant = self.plant()?;
        let tuning = self.tuning_or_default()?;
        let scales = self.time_scales()?;
        let sense = self.calibration();
        let b = &self.board;
        let c = &self.coil;
        let current_max_a = self.current_limit_a();
        let gains = law::practical::Gains::new(tuning.alpha_per_s, current_max_a);
        let shaping = shaping::Settings {
            accel_max_mps2: scales.authority_mps2,
            current_max_a,
            margin: tuning.margin,
            duration_min_s: 2.6 / tuning.alpha_per_s,
            current_rise_s: self.current_rise_s(&scales, current_max_a)?,
        };
        let settings = Settings {
            rate_hz: b.rate_hz,
            plant,
            sense,
            observer: observer::Settings {
                bandwidth_rad_s: tuning.observer_rad_s,
                disturbance: true,
                model: observer::Model::Robust,
                force_scaled_above_a: if tuning.disturbance_follows_force {
                    FORCE_SCALED_SHARE * current_max_a
                } else {
                    0.0
                },
            },
            law: law::Settings::Practical(gains),
            limits: Limits::for_stroke(
                plant.stroke_m,
                c.peak_current_a,
                VBUS_MIN_SHARE * b.supply_v,
                VBUS_MAX_SHARE * b.supply_v,
            ),
            delay_ticks: DELAY_TICKS,
            shaping: Some(shaping),
            monitors: self.monitors(&sense, &plant, &shaping)?,
        };
        settings.build()?;
        Ok(settings)
    }

    /// What the physical-consistency rules measure on this actuator (see
    /// [`Consistency`]).
    ///
    /// # Errors
    /// As [`Actuator::plant`].
    pub fn consistency(&self) -> Result<Consistency, Error> {
        let plant = self.plant()?;
        let envelope = plant.envelope()?;
        let m = &self.mechanics;
        let c = &self.coil;
        let t = &self.tolerance;
        // The current that holds each point of the stroke against the stiffest spring on
        // the weakest magnet, the largest over the stroke (both stops included); and the
        // flux density in an airgap where the nominal magnet holds it (N i / rho(g) over
        // the gap's surface).
        let mut hold_a: f32 = 0.0;
        let mut flux_density_t: f32 = 0.0;
        for k in 0..=CONSISTENCY_POINTS {
            let x = m.stroke_m * f32::from(k) / f32::from(CONSISTENCY_POINTS);
            let g = plant.gap_m(x);
            let spring_n = math::max((1.0 + t.spring) * plant.spring_force_n(x), 0.0);
            hold_a = math::max(hold_a, math::sqrt(2.0 * spring_n / envelope.mu_lo(g)));
            let nominal_a =
                math::sqrt(2.0 * spring_n / plant.magnetics.force_coefficient_h_per_m(g));
            let flux_wb = c.turns * nominal_a / plant.magnetics.reluctance_per_h(g);
            flux_density_t = math::max(
                flux_density_t,
                flux_wb / plant.magnetics.fringing.surface_m2(g),
            );
        }
        let drive_v = self.drive_v();
        let hot_v = (1.0 + t.resistance) * c.resistance_ohm * c.rated_current_a;
        let physical = plant.physical_bounds();
        let pull_ratio = WeakestPull::of(
            &plant.magnetics,
            &physical,
            plant.convention.gap_range_m(m.stroke_m),
        )
        .map_or(1.0, |w| w.ratio_to(physical.s_lo_m2));
        Ok(Consistency {
            hold_ratio: self.current_limit_a() / hold_a,
            drive_ratio: drive_v / hot_v,
            flux_density_t,
            pull_ratio,
        })
    }

    /// The physical-consistency rules ([`Consistency`]): the first one broken, named.
    ///
    /// # Errors
    /// The field the rule bounds, with the rule's text as the reason.
    pub fn check_consistency(&self) -> Result<Consistency, Error> {
        let k = self.consistency()?;
        // First: without a pull the force bound, and so the hold, means nothing.
        if k.pull_ratio.partial_cmp(&0.0) != Some(core::cmp::Ordering::Greater) {
            let (param, value) = match self.magnetics {
                Magnetics::Geometry {
                    fringing_spread, ..
                } if fringing_spread > 0.0 => {
                    ("magnetics.geometry.fringing_spread", fringing_spread)
                }
                _ => ("mechanics.stroke_m", self.mechanics.stroke_m),
            };
            return Err(refused(param, value, RULE_PULL, k.pull_ratio));
        }
        if k.hold_ratio.partial_cmp(&1.0) == Some(core::cmp::Ordering::Less) {
            return Err(refused(
                "coil.rated_current_a",
                self.coil.rated_current_a,
                RULE_HOLD,
                k.hold_ratio,
            ));
        }
        if k.drive_ratio.partial_cmp(&1.0) == Some(core::cmp::Ordering::Less) {
            return Err(refused(
                "board.supply_v",
                self.board.supply_v,
                RULE_DRIVE,
                k.drive_ratio,
            ));
        }
        if k.flux_density_t.partial_cmp(&SATURATION_T) == Some(core::cmp::Ordering::Greater) {
            return Err(refused(
                "coil.turns",
                self.coil.turns,
                RULE_SATURATION,
                k.flux_density_t,
            ));
        }
        if !(k.hold_ratio.is_finite() && k.drive_ratio.is_finite() && k.flux_density_t.is_finite())
        {
            return Err(refused(
                "coil.rated_current_a",
                self.coil.rated_current_a,
                RULE_HOLD,
                k.hold_ratio,
            ));
        }
        Ok(k)
    }

    /// The fault detectors, from the ratings, the converters' resolution and the
    /// settling target.
    fn monitors(
        &self,
        sense: &Calibration,
        plant: &Plant,
        shaping: &shaping::Settings,
    ) -> Result<Monitors, Error> {
        let c = &self.coil;
        let planner = shaping.build(plant, 1.0 / self.board.rate_hz)?;
        let stroke = plant.stroke_m;
        // The magnet at the current limit must lift the weakest admissible armature off the
        // open stop against its spring, or no move up can be planned.
        let (lift_n, _) = planner.force_budget_n(0.0, stroke);
        if lift_n.partial_cmp(&0.0) != Some(core::cmp::Ordering::Greater) {
            return Err(refused(
                "coil.rated_current_a",
                c.rated_current_a,
                "the magnet's pull at the current limit less the spring, at the open stop on \
                 the weakest plant the surfaces allow [N]",
                lift_n,
            ));
        }
        let settling_s = planner.settling_target_s(0.0, stroke);
        Ok(Monitors {
            thermal: Some(Thermal {
                continuous_a: c.rated_current_a,
                allowance_a2s: (c.peak_current_a * c.peak_current_a
                    - c.rated_current_a * c.rated_current_a)
                    * c.peak_time_s,
            }),
            stuck: Some(stuck_detector(&sense.position)),
            residual: Some(residual_detector(&sense.current, self.board.rate_hz)),
            tracking: Some(Tracking {
                error_m: 0.125 * stroke,
                time_s: 0.25 * settling_s,
            }),
        })
    }
}

/// The refusal of a file whose field `param` (at `value`) gives a quantity out of its
/// bounds: `what` says which quantity (or which physical rule it breaks), `derived` its
/// value.
const fn refused(param: &'static str, value: f32, what: &'static str, derived: f32) -> Error {
    Error {
        param,
        value,
        reason: Reason::Derived { what, derived },
    }
}

/// What the physical-consistency rules measure: an actuator that breaks one is not one a
/// user could have (its coil cannot hold its armature, its supply cannot drive its coil,
/// its iron saturates where the model says it does not, or its magnet would push), and
/// [`Actuator::check_consistency`] refuses it with the rule's text.
///
/// | rule | measure | limit |
/// |---|---|---|
/// | the law's current limit holds the armature anywhere on the stroke, on every plant of the uncertainty set | [`Consistency::hold_ratio`] | at least 1 |
/// | the supply drives the rated current through the hot coil | [`Consistency::drive_ratio`] | at least 1 |
/// | the iron is not saturated where the armature is held | [`Consistency::flux_density_t`] | at most [`SATURATION_T`] |
/// | the magnet pulls at every gap of the stroke, on every surface the tolerance allows | [`Consistency::pull_ratio`] | above 0 |
///
/// Each limit is what the physics needs, not a design margin: a coil that holds its
/// stroke with a tenth to spare is a better design than one with 1 %, but both are
/// actuators, and `tune` finds out by simulation whether the loop can work with the room
/// left. The iron may saturate above the holding current (a valve's closed stop at its
/// rated current often does): that is a transient whose force the model overstates;
/// where the armature rests, the model must be right.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Consistency {
    /// The law's current limit over the largest current that holds a point of the stroke
    /// (stops included) against the spring at the stiff end of its tolerance, on the
    /// weakest magnet the surface bounds allow \[-\].
    pub hold_ratio: f32,
    /// The largest voltage the bridge applies from the supply (at the rate's
    /// [`crate::control::bridge::max_modulation`]) over the voltage the coil drops at the
    /// rated current with its resistance at the hot end of its tolerance \[-\].
    pub drive_ratio: f32,
    /// The largest flux density in an airgap where the nominal magnet holds the armature
    /// against the stiffest spring, over the stroke \[T\].
    pub flux_density_t: f32,
    /// The weakest reluctance force coefficient (`-dL/dg`) of a surface that grows inside
    /// the tolerance, over the frozen one of the smallest surface, at the worst gap of the
    /// stroke \[-\]. A surface that grows with the gap as fast as the gap itself
    /// (`g S'(g) / S(g)` reaching 1) makes the inductance rise as the gap opens: the
    /// magnet would push the armature open, which no actuator does, and the force bound of
    /// the controller cannot exist. It happens when the fringe is wide against the pole
    /// (a pole side below the gap times the fringing spread), where the fringing model
    /// itself no longer holds.
    pub pull_ratio: f32,
}

/// Largest [`Consistency::flux_density_t`]: soft magnetic steels of solenoid valves and
/// positioners (ferritic stainless 430F, 1.5-1.7 T; pure iron 2.1 T) leave their linear
/// range about there, and the model's reluctance has no saturation, so above it the model
/// overstates the force \[T\].
pub const SATURATION_T: f32 = 1.6;
/// Points of the stroke (plus one) at which the hold is checked: within a 3 % step of the
/// stroke, the holding current changes by well under the hold margin \[-\].
const CONSISTENCY_POINTS: u16 = 32;
const RULE_HOLD: &str = "the law's current limit over the current that holds the armature \
                         anywhere on the stroke against the stiffest spring on the weakest \
                         magnet (rule: at least 1)";
const RULE_DRIVE: &str = "the bridge's largest voltage from the supply over the hot coil's \
                          drop at the rated current (rule: at least 1)";
const RULE_PULL: &str = "the weakest pull of a surface growing within the tolerance over the \
                         frozen pull of the smallest surface, at the worst gap (rule: above \
                         0, or the magnet pushes the armature open)";
const RULE_SATURATION: &str = "the flux density in the airgap where the magnet holds the \
                               armature [T] (rule: at most 1.6, where soft steels saturate)";

/// Standard deviations of the difference of two converter readings that a noise
/// allowance spans \[-\]: a healthy comparison falls outside it with a probability of
/// about 6e-5.
pub const NOISE_SIGMAS: f32 = 4.0;

/// The noise allowance of a comparison between two readings of one channel \[code\]:
/// [`NOISE_SIGMAS`] standard deviations of their difference, `sqrt(2)` times the
/// converter's [`NOISE_RMS_CODES`] (8.5 codes for the board's 1.5).
pub const NOISE_ALLOWANCE_CODES: f32 = NOISE_SIGMAS * core::f32::consts::SQRT_2 * NOISE_RMS_CODES;

/// Reference travel, in bands, that must have moved a healthy reading out of its band
/// \[-\]: the band, plus the two readings' worst noise (each up to [`NOISE_SIGMAS`]
/// standard deviations, together `sqrt(2)` bands), `1 + sqrt(2)`.
pub const STUCK_TRAVEL_BANDS: f32 = 1.0 + core::f32::consts::SQRT_2;

/// The stuck-position detector for a position channel (see
/// [`crate::control::supervisor::monitor::Stuck`]): a band of [`NOISE_ALLOWANCE_CODES`]
/// position codes, so that a frozen reading stays in it, and [`STUCK_TRAVEL_BANDS`] bands
/// of reference travel, so that a healthy one leaves it first. Both follow the sensor's
/// resolution and noise only: the detection time is that travel over the armature's speed
/// when the sensor freezes.
#[must_use]
pub fn stuck_detector(position: &Channel) -> Stuck {
    Stuck {
        band_codes: NOISE_ALLOWANCE_CODES,
        reference_m: STUCK_TRAVEL_BANDS * NOISE_ALLOWANCE_CODES * position.scale.abs(),
    }
}

/// Relative widening of the electrical residual's admissible change \[-\]: what the
/// Tustin step, the sampled voltage and the unmodelled iron leave out of the coil model.
pub const RESIDUAL_MARGIN: f32 = 0.1;
/// Consecutive ticks a reading must stay outside the corner bank's envelope \[tick\]:
/// with the anchor's own noise at two standard deviations, three readings beyond the
/// [`NOISE_ALLOWANCE_CODES`] allowance by noise alone have a probability of about 2e-12.
pub const RESIDUAL_CONFIRM_TICKS: u16 = 3;
/// A one-step jump of the current reading, in noise allowances \[-\]: a step this far
/// beyond every admissible change is the reading stepping, not noise.
pub const JUMP_ALLOWANCES: f32 = 8.0;
/// Current below which the coil counts as open, in noise allowances \[-\].
pub const OPEN_ALLOWANCES: f32 = 3.0;
/// Factor between a coil outside its bounds and a broken one (or a frozen reading)
/// \[-\].
pub const GROSS: f32 = 2.0;

/// Relative half-width of the resistance the electrical residual learns, before the
/// converter's offset ([`OFFSET_CLASS_CODES`]) is added to it \[-\]: half of it for what
/// a block cannot know (the inductance within its bounds, the back-EMF's allowance; a
/// block with more is not used), half for a coil that warms while it holds (copper
/// gains 0.39 % per kelvin: 2.6 K in [`LEARN_AGE_S`]) and for the Tustin step's and the
/// sampled voltage's approximation. The narrower it is, the sooner a frozen reading is
/// named, and the fewer blocks qualify.
pub const LEARN_TOLERANCE: f32 = 0.02;
/// Offset class of the board's converters \[code\]: the most a healthy channel's zero
/// is off.
pub const OFFSET_CLASS_CODES: f32 = 2.0;
/// Length of a block that teaches the residual the coil's resistance \[s\]: 40 to 250
/// steps at the interrupt rates, so that the converter's noise on the inductive sum (the
/// block's first and last readings) is spread over as many steps, and short beside a
/// hold.
pub const LEARN_BLOCK_S: f32 = 5e-3;
/// How long a learned resistance holds without a block that confirms it \[s\].
pub const LEARN_AGE_S: f32 = 0.25;

/// The electrical residual for a current channel at an interrupt rate \[Hz\], in the
/// channel's own codes (see [`crate::control::supervisor::monitor`]): the noise allowance
/// [`NOISE_ALLOWANCE_CODES`], a [`RESIDUAL_MARGIN`], [`RESIDUAL_CONFIRM_TICKS`] ticks of
/// evidence, a jump of [`JUMP_ALLOWANCES`] and an open coil below [`OPEN_ALLOWANCES`]
/// allowances, a [`GROSS`] factor, and a corner bank as long as half the detection
/// deadline ([`DEADLINE_S`]): evidence that starts anywhere in a window is confirmed
/// within the deadline, and a longer window only widens the envelope by the resistance
/// and inductance tolerance.
#[must_use]
pub fn residual_detector(current: &Channel, rate_hz: f32) -> Residual {
    let noise_a = NOISE_ALLOWANCE_CODES * current.scale.abs();
    let half_deadline = libm::roundf(0.5 * DEADLINE_S * rate_hz);
    let least = f32::from(2 * RESIDUAL_CONFIRM_TICKS);
    // At least twice the confirmation; far below u16::MAX at any plausible rate.
    #[expect(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    let window = math::clamp(half_deadline, least, f32::from(u16::MAX)) as u16;
    let ticks = |s: f32| {
        // Clamped to [2, u16::MAX]: the truncation is the intended rounding.
        #[expect(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let n = math::clamp(libm::roundf(s * rate_hz), 2.0, f32::from(u16::MAX)) as u16;
        n
    };
    Residual {
        noise_codes: NOISE_ALLOWANCE_CODES,
        margin: RESIDUAL_MARGIN,
        confirm_ticks: RESIDUAL_CONFIRM_TICKS,
        jump_a: JUMP_ALLOWANCES * noise_a,
        open_a: OPEN_ALLOWANCES * noise_a,
        gross: GROSS,
        window,
        learn_ticks: ticks(LEARN_BLOCK_S),
        learn_tol: LEARN_TOLERANCE,
        offset_a: OFFSET_CLASS_CODES * current.scale.abs(),
        learn_age_ticks: ticks(LEARN_AGE_S),
    }
}

/// Steps of the grids [`energy_consistent_share`] searches.
const GROWTH_GRID: u16 = 16;

/// How far below the physical lower bound the controller's lower surface bound must go so
/// that its force bound `mu_lo` still holds for every actuator the physical bounds allow,
/// with the energy-consistent force \[-\] (1 when nothing needs to move).
///
/// The paper bounds the airgap surface, `S_lo <= S(g) <= S_hi`, and builds `mu_lo` from
/// `S_lo` with the surface held constant when differentiating the inductance. A real
/// reluctance force is `-dL/dg`: for a surface that grows with the gap,
/// `S(g) = (a + k g)^2`, it is the frozen one times `1 - g S'(g) / S(g)`, which falls below
/// the paper's `mu_lo` wherever the surface grows fast across a large gap. Over every such
/// surface inside the physical bounds (its ends anywhere in them, the upper one above the
/// lower) and every gap of the stroke, this finds the largest `r <= 1` for which the
/// frozen force of the constant surface `r S_lo` stays below the energy-consistent force;
/// the controller's `S_lo` is then `r S_lo`.
fn energy_consistent_share(
    magnetics: &model::Magnetics,
    physical: &Bounds,
    gaps_m: (f32, f32),
) -> f32 {
    let Some(weakest) = WeakestPull::of(magnetics, physical, gaps_m) else {
        return 1.0;
    };
    // The largest share whose frozen force stays below that floor at every gap: the
    // frozen force grows with the surface, so bisect.
    let below = |r: f32| weakest.all(|g, least| weakest.frozen(r * physical.s_lo_m2, g) <= least);
    if below(1.0) {
        return 1.0;
    }
    let (mut lo, mut hi) = (SHARE_FLOOR, 1.0_f32);
    if !below(lo) {
        return lo;
    }
    for _ in 0..24 {
        let mid = 0.5 * (lo + hi);
        if below(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// The share [`energy_consistent_share`] returns for a design whose weakest pull it cannot
/// bound from below: one that breaks the pull rule ([`Consistency::pull_ratio`]), which
/// `check_consistency` refuses; the settings of such a file still derive, with the force
/// bound this far below the physical one \[-\].
const SHARE_FLOOR: f32 = 0.1;

/// The weakest energy-consistent force coefficient over the surfaces that grow inside the
/// physical bounds (see [`energy_consistent_share`]), on a grid of the stroke's airgaps.
struct WeakestPull {
    n2: f32,
    gaps: f32,
    rho0: f32,
    g_lo: f32,
    span: f32,
    floor: [f32; GROWTH_GRID as usize + 1],
}

impl WeakestPull {
    /// `None` for a stroke without length.
    fn of(
        magnetics: &model::Magnetics,
        physical: &Bounds,
        (g_lo, g_hi): (f32, f32),
    ) -> Option<Self> {
        let span = g_hi - g_lo;
        if span.partial_cmp(&0.0) != Some(core::cmp::Ordering::Greater) {
            return None;
        }
        let mut w = Self {
            n2: magnetics.turns_sq(),
            gaps: magnetics.gaps,
            rho0: magnetics.rho0_per_h,
            g_lo,
            span,
            floor: [f32::INFINITY; GROWTH_GRID as usize + 1],
        };
        let (r_lo, r_hi) = (math::sqrt(physical.s_lo_m2), math::sqrt(physical.s_hi_m2));
        let steps = f32::from(GROWTH_GRID);
        let mut floor = w.floor;
        for i in 0..=GROWTH_GRID {
            // sqrt of the surface at the smallest gap, then at the largest.
            let r1 = r_lo + (r_hi - r_lo) * f32::from(i) / steps;
            for j in i..=GROWTH_GRID {
                let r2 = r_lo + (r_hi - r_lo) * f32::from(j) / steps;
                let k = (r2 - r1) / span;
                for (q, least) in (0..=GROWTH_GRID).zip(floor.iter_mut()) {
                    let g = w.gap(q);
                    let side = r1 + k * (g - g_lo);
                    // -dL/dg with S(g) = side^2: the frozen value times 1 - 2 g k / side.
                    let energy = w.frozen(side * side, g) * (1.0 - 2.0 * g * k / side);
                    *least = math::min(*least, energy);
                }
            }
        }
        w.floor = floor;
        Some(w)
    }

    /// Gap `q` of the grid \[m\].
    fn gap(&self, q: u16) -> f32 {
        self.g_lo + self.span * f32::from(q) / f32::from(GROWTH_GRID)
    }

    /// The frozen force coefficient of a constant surface `s` at gap `g` \[H/m\].
    fn frozen(&self, s: f32, g: f32) -> f32 {
        let rho_x = self.gaps / (MU0_H_PER_M * s);
        let rho = rho_x * g + self.rho0;
        self.n2 * rho_x / (rho * rho)
    }

    /// Whether `f(gap, weakest force coefficient there)` holds at every gap of the grid.
    fn all(&self, f: impl Fn(f32, f32) -> bool) -> bool {
        (0..=GROWTH_GRID)
            .zip(self.floor.iter())
            .all(|(q, least)| f(self.gap(q), *least))
    }

    /// The smallest ratio over the grid of the weakest force to the frozen force of the
    /// constant surface `s_lo` \[-\].
    fn ratio_to(&self, s_lo: f32) -> f32 {
        (0..=GROWTH_GRID)
            .zip(self.floor.iter())
            .map(|(q, least)| least / self.frozen(s_lo, self.gap(q)))
            .fold(f32::INFINITY, math::min)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rule's text of a refusal, or `None` when the actuator is accepted. Settings
    /// derive for any actuator but one whose drive cannot reach the current limit through
    /// the nominal coil, which they refuse by the drive rule too.
    fn refused_by(a: &Actuator) -> Option<(&'static str, &'static str)> {
        let rule = |r: Result<_, Error>| match r {
            Ok(_) => None,
            Err(Error {
                param,
                reason: Reason::Derived { what, .. },
                ..
            }) => Some((param, what)),
            Err(e) => panic!("refused for another reason: {e}"),
        };
        let settings = rule(a.settings().map(|_| ()));
        assert!(settings.is_none() || settings == Some(("board.supply_v", RULE_DRIVE)));
        rule(a.check_consistency().map(|_| ()))
    }

    /// The settling target waits for the coil: its current rises from zero to the limit
    /// at full drive through the closed-stop inductance, `tau ln(U / (U - R i))`.
    #[test]
    fn the_current_rise_is_the_first_order_rise_of_the_nominal_coil_at_full_drive() {
        let a = Actuator::PRODUCT;
        let rise = a.settings().unwrap().shaping.unwrap().current_rise_s;
        let tau = a.time_scales().unwrap().coil_closed_s;
        let u = a.board.supply_v * crate::control::bridge::max_modulation(a.board.rate_hz);
        let drop = a.coil.resistance_ohm * a.current_limit_a();
        let expect = tau * libm::logf(u / (u - drop));
        assert!((rise - expect).abs() < 1e-9, "{rise} vs {expect}");
        // The product's drive is 4.6 times the coil's drop: the rise is a quarter of tau.
        assert!(rise > 0.2 * tau && rise < 0.3 * tau, "{rise} {tau}");
        // A lower supply, nearer the drop, waits longer; one below it is refused.
        let mut weak = a;
        weak.board.supply_v = 8.0;
        let slower = weak.settings().unwrap().shaping.unwrap().current_rise_s;
        assert!(slower > 2.0 * rise, "{slower} {rise}");
    }

    #[test]
    fn the_product_meets_every_consistency_rule_with_room() {
        let k = Actuator::PRODUCT.check_consistency().unwrap();
        // 12 A rated against about 5.4 A to hold the open end of the stroke on the weakest
        // magnet; 24 V against 5.8 V on the hot coil; 0.11 T where it is held.
        assert!(k.hold_ratio > 2.0 && k.hold_ratio < 2.4, "{k:?}");
        assert!(k.drive_ratio > 3.5 && k.drive_ratio < 4.0, "{k:?}");
        assert!(k.flux_density_t > 0.05 && k.flux_density_t < 0.2, "{k:?}");
    }

    #[test]
    fn a_coil_too_weak_to_hold_the_stroke_is_refused_by_the_hold_rule() {
        let mut a = Actuator::PRODUCT;
        // The hold needs 5.38 A on the weakest plant; the law's limit is 98 % of the rating.
        a.coil.rated_current_a = 5.4;
        a.coil.peak_current_a = 6.0;
        assert_eq!(refused_by(&a), Some(("coil.rated_current_a", RULE_HOLD)));
        a.coil.rated_current_a = 5.6;
        assert_eq!(refused_by(&a), None);
    }

    #[test]
    fn a_supply_that_cannot_drive_the_rated_current_is_refused_by_the_drive_rule() {
        let mut a = Actuator::PRODUCT;
        // The hot coil drops 1.2 x 0.4 x 12 = 5.76 V; the bridge gives about 0.91 of the
        // supply at 20 kHz.
        a.board.supply_v = 6.0;
        assert_eq!(refused_by(&a), Some(("board.supply_v", RULE_DRIVE)));
        a.board.supply_v = 6.5;
        assert_ne!(refused_by(&a).map(|r| r.1), Some(RULE_DRIVE));
    }

    #[test]
    fn a_surface_that_grows_as_fast_as_the_gap_is_refused_by_the_pull_rule() {
        let spread = |k: f32| {
            let mut a = Actuator::PRODUCT;
            if let Magnetics::Geometry {
                ref mut fringing_spread,
                ..
            } = a.magnetics
            {
                *fringing_spread = k;
            }
            a
        };
        // The product's 7 mm pole across gaps of 0.5-4.5 mm: a fringe growing half a gap
        // per side keeps the weakest pull at 0.46 of the frozen one; the paper's `(a + g)(b
        // + g)` lets a surface inside the 20 % tolerance grow faster than the gap at the
        // open stop, where its magnet would push.
        let k = spread(0.5).check_consistency().unwrap();
        assert!(k.pull_ratio > 0.4 && k.pull_ratio < 0.5, "{k:?}");
        let k = spread(1.0).consistency().unwrap();
        assert!(k.pull_ratio < -0.1, "{k:?}");
        // (Its settings do not derive either: at the share's floor the weakest magnet
        // cannot lift the armature.)
        let e = spread(1.0).check_consistency().unwrap_err();
        assert_eq!(e.param, "magnetics.geometry.fringing_spread");
        assert!(matches!(e.reason, Reason::Derived { what, .. } if what == RULE_PULL));
        // A constant surface pulls everywhere.
        let k = Actuator::PRODUCT.consistency().unwrap();
        assert!(k.pull_ratio > 0.8 && k.pull_ratio < 0.9, "{k:?}");
    }

    #[test]
    fn iron_saturated_where_the_armature_is_held_is_refused() {
        let mut a = Actuator::PRODUCT;
        // A pole face a tenth as wide on each side: a hundredth of the surface, the same
        // force needs ten times the flux density (about 1.1 T -> still inside), so also a
        // spring twice as stiff.
        if let Magnetics::Geometry {
            ref mut pole_a_m,
            ref mut pole_b_m,
            ..
        } = a.magnetics
        {
            *pole_a_m *= 0.1;
            *pole_b_m *= 0.1;
        }
        a.coil.turns *= 10.0;
        let k = a.consistency().unwrap();
        assert!(
            k.flux_density_t > 1.0 && k.flux_density_t < SATURATION_T,
            "{k:?}"
        );
        a.mechanics.spring_n_per_m *= 3.0;
        let k = a.consistency().unwrap();
        assert!(k.flux_density_t > SATURATION_T, "{k:?}");
        assert_eq!(refused_by(&a).map(|r| r.1), Some(RULE_SATURATION));
    }

    /// A sensor 2.5 % long and 40 codes high, read at the stops through the file's
    /// calibration: the correction from those two readings reads the true position
    /// everywhere on the stroke, to a tenth of a code.
    #[test]
    fn the_stops_take_a_sensors_gain_and_offset_out() {
        let a = Actuator::PRODUCT;
        let file = a.calibration().position;
        let stroke = a.mechanics.stroke_m;
        let (gain, offset) = (1.025_f32, 40.0_f32);
        // The code such a sensor gives at true position x, and what the file reads of it.
        let code = |x: f32| x * gain / file.scale + file.offset_code + offset;
        let read = |x: f32| (code(x) - file.offset_code) * file.scale;
        let c = PositionCorrection::from_stops(read(0.0), read(stroke), stroke, file.scale);
        assert!((c.gain - gain).abs() < 1e-5, "{c:?}");
        assert!((c.offset_codes - offset).abs() < 1e-3, "{c:?}");
        let fixed = a.calibration_with(&c).unwrap().position;
        for k in 0..=8 {
            let x = stroke * k as f32 / 8.0;
            let got = (code(x) - fixed.offset_code) * fixed.scale;
            assert!((got - x).abs() < 0.1 * file.scale, "x {x}: {got}");
        }
        // Uncorrected, the same sensor is off by 2.5 % of the position plus 40 codes.
        assert!((read(stroke) - stroke).abs() > 0.02 * stroke);
    }

    /// Beyond the room the calibration leaves, a correction is refused by name.
    #[test]
    fn a_correction_beyond_the_room_is_refused_by_name() {
        let a = Actuator::PRODUCT;
        let room = POSITION_CORRECTION_ROOM;
        let span_codes = a.board.position_span_m / a.calibration().position.scale;
        for (c, param) in [
            (
                PositionCorrection {
                    gain: 1.0 + 1.01 * room,
                    offset_codes: 0.0,
                },
                "sensor.position_gain",
            ),
            (
                PositionCorrection {
                    gain: f32::NAN,
                    offset_codes: 0.0,
                },
                "sensor.position_gain",
            ),
            (
                PositionCorrection {
                    gain: 1.0,
                    offset_codes: -1.01 * room * span_codes,
                },
                "sensor.position_offset_codes",
            ),
        ] {
            assert_eq!(a.calibration_with(&c).unwrap_err().param, param, "{c:?}");
        }
        let inside = PositionCorrection {
            gain: 1.0 - 0.99 * room,
            offset_codes: 0.99 * room * span_codes,
        };
        assert!(a.calibration_with(&inside).is_ok());
        assert_eq!(
            a.calibration_with(&PositionCorrection::NONE),
            Ok(a.calibration())
        );
    }
}
