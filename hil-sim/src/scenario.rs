//! What to simulate: the controller settings, the true plant, the supply, bridge, sensors,
//! reference and duration. Every type here is serde-(de)serializable with unit-carrying
//! field names, ready for scenario files.

use ema::actuator::Actuator;
use ema::control::Settings;
use ema::law;
use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::hal::{self, Adc, Supply};
use crate::plant::{non_negative, positive, ForceModel, Params, Surface};
use crate::Error;

/// The position reference `y_r(t)` handed to the tick as its set point.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Reference {
    /// `from_m` before `at_s`, `to_m` from `at_s` on.
    Step {
        /// Reference before the step \[m\] (the position the armature starts from).
        from_m: f64,
        /// Reference after the step \[m\].
        to_m: f64,
        /// Time of the step \[s\].
        #[serde(default)]
        at_s: f64,
    },
    /// Linear ramp from `from_m` to `to_m` over `[start_s, start_s + duration_s]`.
    Ramp {
        /// Start value \[m\].
        from_m: f64,
        /// End value \[m\].
        to_m: f64,
        /// Start time \[s\].
        start_s: f64,
        /// Ramp duration \[s\].
        duration_s: f64,
    },
    /// Minimum-jerk (quintic, `10 s^3 - 15 s^4 + 6 s^5`) move from `from_m` to `to_m`
    /// over `[start_s, start_s + duration_s]`: zero velocity and acceleration at both ends.
    Smooth {
        /// Start value \[m\].
        from_m: f64,
        /// End value \[m\].
        to_m: f64,
        /// Start time \[s\].
        start_s: f64,
        /// Move duration \[s\].
        duration_s: f64,
    },
    /// A sequence of steps at increasing times.
    Sequence {
        /// Reference before the first step \[m\].
        initial_m: f64,
        /// The steps, in increasing time.
        steps: Vec<StepAt>,
    },
}

/// One step of a [`Reference::Sequence`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StepAt {
    /// Time of the step \[s\].
    pub at_s: f64,
    /// Reference from then on \[m\].
    pub to_m: f64,
}

/// A part of the run over which metrics are taken: one move of the reference and the time
/// until the next one (or the end).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SegmentSpec {
    /// Start of the move \[s\].
    pub start_s: f64,
    /// End of the segment \[s\].
    pub end_s: f64,
    /// Reference before the move \[m\].
    pub from_m: f64,
    /// Final reference of the segment \[m\].
    pub to_m: f64,
}

impl Reference {
    /// The reference at time `t_s` \[m\].
    #[must_use]
    pub fn position_m(&self, t_s: f64) -> f64 {
        match self {
            Reference::Step { from_m, to_m, at_s } => {
                if t_s >= *at_s {
                    *to_m
                } else {
                    *from_m
                }
            }
            Reference::Ramp {
                from_m,
                to_m,
                start_s,
                duration_s,
            } => {
                let s = ((t_s - start_s) / duration_s).clamp(0.0, 1.0);
                from_m + (to_m - from_m) * s
            }
            Reference::Smooth {
                from_m,
                to_m,
                start_s,
                duration_s,
            } => {
                let s = ((t_s - start_s) / duration_s).clamp(0.0, 1.0);
                let shape = s * s * s * (10.0 + s * (-15.0 + 6.0 * s));
                from_m + (to_m - from_m) * shape
            }
            Reference::Sequence { initial_m, steps } => steps
                .iter()
                .take_while(|s| s.at_s <= t_s)
                .last()
                .map_or(*initial_m, |s| s.to_m),
        }
    }

    /// The reference's value before it first moves \[m\]: `from_m` of a step, ramp or
    /// smooth move, `initial_m` of a sequence.
    #[must_use]
    pub fn start_m(&self) -> f64 {
        match self {
            Reference::Step { from_m, .. }
            | Reference::Ramp { from_m, .. }
            | Reference::Smooth { from_m, .. } => *from_m,
            Reference::Sequence { initial_m, .. } => *initial_m,
        }
    }

    /// The segments of a run of `duration_s`.
    #[must_use]
    pub fn segments(&self, duration_s: f64) -> Vec<SegmentSpec> {
        match self {
            Reference::Step { from_m, to_m, at_s } => vec![SegmentSpec {
                start_s: *at_s,
                end_s: duration_s,
                from_m: *from_m,
                to_m: *to_m,
            }],
            Reference::Ramp {
                from_m,
                to_m,
                start_s,
                ..
            }
            | Reference::Smooth {
                from_m,
                to_m,
                start_s,
                ..
            } => vec![SegmentSpec {
                start_s: *start_s,
                end_s: duration_s,
                from_m: *from_m,
                to_m: *to_m,
            }],
            Reference::Sequence { initial_m, steps } => {
                let mut from = *initial_m;
                let mut out = Vec::with_capacity(steps.len());
                for (k, s) in steps.iter().enumerate() {
                    let end = steps.get(k + 1).map_or(duration_s, |n| n.at_s);
                    out.push(SegmentSpec {
                        start_s: s.at_s,
                        end_s: end.min(duration_s),
                        from_m: from,
                        to_m: s.to_m,
                    });
                    from = s.to_m;
                }
                out
            }
        }
    }

    fn validate(&self, duration_s: f64) -> Result<(), Error> {
        let finite = |name: &str, v: f64| {
            if v.is_finite() {
                Ok(())
            } else {
                Err(Error::param(
                    format!("reference.{name}"),
                    v,
                    "must be finite",
                ))
            }
        };
        match self {
            Reference::Step { from_m, to_m, at_s } => {
                finite("from_m", *from_m)?;
                finite("to_m", *to_m)?;
                non_negative("reference.at_s", *at_s)
            }
            Reference::Ramp {
                from_m,
                to_m,
                start_s,
                duration_s,
            }
            | Reference::Smooth {
                from_m,
                to_m,
                start_s,
                duration_s,
            } => {
                finite("from_m", *from_m)?;
                finite("to_m", *to_m)?;
                non_negative("reference.start_s", *start_s)?;
                positive("reference.duration_s", *duration_s)
            }
            Reference::Sequence { initial_m, steps } => {
                finite("initial_m", *initial_m)?;
                let mut last = -1.0;
                for (k, s) in steps.iter().enumerate() {
                    finite(&format!("steps[{k}].to_m"), s.to_m)?;
                    if !(s.at_s.is_finite() && s.at_s > last && s.at_s < duration_s) {
                        return Err(Error::param(
                            format!("reference.steps[{k}].at_s"),
                            s.at_s,
                            "must increase and lie inside the run",
                        ));
                    }
                    last = s.at_s;
                }
                Ok(())
            }
        }
    }
}

/// Initial state of the true plant.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Initial {
    /// Position \[m\].
    pub x_m: f64,
    /// Velocity \[m/s\].
    #[serde(default)]
    pub v_mps: f64,
    /// Coil current \[A\].
    #[serde(default)]
    pub i_a: f64,
}

/// The uncertainty set plants are drawn from (all draws uniform). A field left out of a
/// scenario file takes its value from [`Uncertainty::default`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Uncertainty {
    /// Relative spread of the coil resistance (`0.2` = +-20 %) \[-\].
    pub resistance_rel: f64,
    /// Relative spread of the spring constant and, drawn on its own, of the preload \[-\].
    pub spring_rel: f64,
    /// Relative spread of the moving mass \[-\].
    pub mass_rel: f64,
    /// Relative spread of the viscous friction \[-\].
    pub friction_rel: f64,
    /// Probability that a drawn plant uses the energy-consistent force model (else the
    /// paper's frozen one) \[-\].
    pub energy_consistent_probability: f64,
    /// Probability that a gap's surface grows with the gap (square pole with fringing,
    /// `S(g) = (a + k g)^2`) rather than being constant \[-\].
    pub rectangular_probability: f64,
}

impl Default for Uncertainty {
    /// R +-20 %, K +-10 %, m +-10 %, lambda +-50 %, both force models and both surface
    /// models equally likely.
    fn default() -> Self {
        Self {
            resistance_rel: 0.2,
            spring_rel: 0.1,
            mass_rel: 0.1,
            friction_rel: 0.5,
            energy_consistent_probability: 0.5,
            rectangular_probability: 0.5,
        }
    }
}

/// Relative margin kept inside the controller's surface bounds when drawing, so that `f32`
/// rounding in the controller's envelope never puts a draw outside \[-\].
const DRAW_MARGIN: f64 = 1e-6;

impl Uncertainty {
    /// The controller's own uncertainty set: the spreads its plant's tolerances state,
    /// both force models and both surface models equally likely.
    #[must_use]
    pub fn of(plant: &ema::model::Plant) -> Self {
        let t = &plant.tolerance;
        Self {
            resistance_rel: f64::from(t.resistance),
            spring_rel: f64::from(t.spring),
            mass_rel: f64::from(t.mass),
            friction_rel: f64::from(t.friction),
            ..Self::default()
        }
    }

    /// Checks the spreads (in `[0, 1)`) and the probabilities (in `[0, 1]`).
    ///
    /// # Errors
    /// The first bad field, by name.
    pub fn validate(&self) -> Result<(), Error> {
        for (name, v) in [
            ("resistance_rel", self.resistance_rel),
            ("spring_rel", self.spring_rel),
            ("mass_rel", self.mass_rel),
            ("friction_rel", self.friction_rel),
        ] {
            if !(v.is_finite() && (0.0..1.0).contains(&v)) {
                return Err(Error::param(
                    format!("plant.uncertainty.{name}"),
                    v,
                    "must be in [0, 1)",
                ));
            }
        }
        for (name, v) in [
            (
                "energy_consistent_probability",
                self.energy_consistent_probability,
            ),
            ("rectangular_probability", self.rectangular_probability),
        ] {
            if !(0.0..=1.0).contains(&v) {
                return Err(Error::param(
                    format!("plant.uncertainty.{name}"),
                    v,
                    "must be in [0, 1]",
                ));
            }
        }
        Ok(())
    }

    /// Draws a true plant around the controller's nominal plant `nominal`: mechanics and
    /// resistance within the relative spreads, each gap's surface anywhere within the
    /// physical surface bounds `[S_lo, S_hi]` over the whole stroke
    /// (`ema::model::Plant::physical_bounds`: the paper's bounds, which the controller's
    /// contain) (constant, or a
    /// square pole `(a + k g)^2` whose surface at the two ends of the gap range is drawn
    /// inside the bounds), and the force model.
    ///
    /// Never panics: spreads and probabilities outside their ranges (see
    /// [`Uncertainty::validate`]) are clamped into them, and degenerate bounds give the
    /// middle surface.
    pub fn draw<R: Rng + ?Sized>(&self, nominal: &ema::model::Plant, rng: &mut R) -> Params {
        let mut p = Params::from_core(nominal, ForceModel::Frozen);
        let physical = nominal.physical_bounds();
        let s_lo = f64::from(physical.s_lo_m2) * (1.0 + DRAW_MARGIN);
        let s_hi = f64::from(physical.s_hi_m2) * (1.0 - DRAW_MARGIN);
        let (s_lo, s_hi) = if s_lo < s_hi {
            (s_lo, s_hi)
        } else {
            let mid = 0.5 * (s_lo + s_hi);
            (mid, mid)
        };
        let probability = |v: f64| if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
        let rel = |v: f64| if v.is_nan() { 0.0 } else { v.clamp(0.0, 0.99) };
        let (g_lo, g_hi) = p.gap_range_m();
        for gap in &mut p.gaps {
            let s1 = rng.random_range(s_lo..=s_hi);
            *gap = if rng.random_bool(probability(self.rectangular_probability)) && g_hi > g_lo {
                let s2 = rng.random_range(s1..=s_hi);
                let (r1, r2) = (s1.sqrt(), s2.sqrt());
                let k = (r2 - r1) / (g_hi - g_lo);
                let a = r1 - k * g_lo;
                if a > 0.0 {
                    Surface::Rectangular {
                        a_m: a,
                        b_m: a,
                        spread: k,
                    }
                } else {
                    Surface::Constant { s_m2: s1 }
                }
            } else {
                Surface::Constant { s_m2: s1 }
            };
        }
        let mut spread = |v: f64, r: f64| v * (1.0 + rng.random_range(-rel(r)..=rel(r)));
        p.resistance_ohm = spread(p.resistance_ohm, self.resistance_rel);
        p.spring_n_per_m = spread(p.spring_n_per_m, self.spring_rel);
        p.preload_n = spread(p.preload_n, self.spring_rel);
        p.mass_kg = spread(p.mass_kg, self.mass_rel);
        p.friction_n_s_per_m = spread(p.friction_n_s_per_m, self.friction_rel);
        p.force = if rng.random_bool(probability(self.energy_consistent_probability)) {
            ForceModel::EnergyConsistent
        } else {
            ForceModel::Frozen
        };
        p
    }
}

/// A fault injected into a run.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Injection {
    /// When it starts \[s\] (it lasts to the end of the run).
    pub at_s: f64,
    /// What goes wrong.
    pub fault: Injected,
}

/// What an [`Injection`] does.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Injected {
    /// The position sensor's output falls to 0 V (open wire): the converter reads its low
    /// rail.
    PositionOpen,
    /// The position sensor's output is shorted to its supply: the converter reads its high
    /// rail.
    PositionShorted,
    /// The position sensor's output freezes at its value at the injection.
    PositionStuck,
    /// The current sensor's output freezes at its value at the injection.
    CurrentStuck,
    /// The current sensor's zero steps by `offset_a`.
    CurrentOffset {
        /// Offset \[A\].
        offset_a: f64,
    },
    /// The coil circuit opens: no current can flow.
    CoilOpen,
    /// Shorted turns: the coil resistance drops to `resistance_ohm`.
    CoilShort {
        /// New resistance \[ohm\].
        resistance_ohm: f64,
    },
    /// The supply's source voltage changes to `voltage_v` (sag or over-voltage).
    Supply {
        /// New source voltage \[V\].
        voltage_v: f64,
    },
    /// The control interrupt misses `ticks` deadlines in a row: no tick runs and the
    /// bridge keeps its last state; when the interrupt runs again the firmware's guard
    /// (`ema::guard`) sees the gap and latches the overrun, and a stall longer than the
    /// window watchdog's early wake-up is ended by the watchdog, which coasts the bridge.
    MissedDeadlines {
        /// Missed periods.
        ticks: u32,
    },
}

impl Injection {
    /// Checks the parameters.
    ///
    /// # Errors
    /// A time that is negative or not finite, a resistance or voltage that is not
    /// positive, zero missed ticks.
    pub fn validate(&self) -> Result<(), Error> {
        non_negative("faults.at_s", self.at_s)?;
        match self.fault {
            Injected::CurrentOffset { offset_a } if !offset_a.is_finite() => {
                return Err(Error::param(
                    "faults.fault.offset_a",
                    offset_a,
                    "must be finite",
                ));
            }
            Injected::CoilShort { resistance_ohm } => {
                positive("faults.fault.resistance_ohm", resistance_ohm)?;
            }
            Injected::Supply { voltage_v } => positive("faults.fault.voltage_v", voltage_v)?,
            Injected::MissedDeadlines { ticks: 0 } => {
                return Err(Error::param(
                    "faults.fault.ticks",
                    0.0,
                    "must be at least 1",
                ));
            }
            _ => {}
        }
        Ok(())
    }
}

/// The true plant of a scenario.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum TruePlant {
    /// Exactly the controller's nominal plant (its `f32` values widened), with a force
    /// model.
    Nominal {
        /// Force model.
        #[serde(default)]
        force: ForceModel,
    },
    /// Given explicitly.
    Given(Params),
    /// Drawn from the uncertainty set around the controller's nominal plant
    /// ([`Uncertainty::draw`]) with a PCG64 generator seeded by `seed`.
    Drawn {
        /// Seed of the draw.
        seed: u64,
        /// The uncertainty set.
        #[serde(default)]
        uncertainty: Uncertainty,
    },
}

impl TruePlant {
    /// The plant parameters this describes for a controller whose nominal plant is
    /// `nominal`.
    #[must_use]
    pub fn resolve(&self, nominal: &ema::model::Plant) -> Params {
        match self {
            TruePlant::Nominal { force } => Params::from_core(nominal, *force),
            TruePlant::Given(p) => p.clone(),
            TruePlant::Drawn { seed, uncertainty } => {
                use rand::SeedableRng;
                let mut rng = rand_pcg::Pcg64::seed_from_u64(*seed);
                uncertainty.draw(nominal, &mut rng)
            }
        }
    }
}

/// How the sampled measurement reaches the tick.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Sensors {
    /// Exact values at the sample instant, rounded to `f32`, through
    /// `Config::tick_measured` (no converter, no delay). The default in scenario files.
    #[default]
    Ideal,
    /// Raw codes from the converter model through `Config::tick`.
    Adc(Adc),
}

/// How the bridge's output reaches the coil.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BridgeMode {
    /// The coil sees the period average, `duty x Vbus` in the pins' direction.
    #[default]
    Averaged,
    /// The coil sees the pulses of a centre-aligned PWM at the ISR rate: off for
    /// `(1 - d) T / 2`, on (`+-Vbus`) for `d T`, off for `(1 - d) T / 2`; the samples fall in
    /// the middle of the off-time, where the current equals its period average to first order.
    Switching,
}

/// The power stage. Every field has a default in scenario files ([`Bridge::default`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Bridge {
    /// Averaged or switching-level.
    pub mode: BridgeMode,
    /// PWM full-scale compare value (4201 at 20 kHz: half a period of a 168 MHz timer, plus
    /// one for 100 %).
    pub max_duty: u16,
    /// Forward drop of one freewheeling diode \[V\].
    pub diode_drop_v: f64,
}

impl Default for Bridge {
    /// Averaged, the firmware's PWM resolution at 20 kHz (4201 counts,
    /// [`crate::actuator::pwm_full_scale`]), 0.7 V diodes.
    fn default() -> Self {
        Self {
            mode: BridgeMode::Averaged,
            max_duty: crate::actuator::pwm_full_scale(20e3),
            diode_drop_v: 0.7,
        }
    }
}

/// Integration settings.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Integration {
    /// RK4 substeps per ISR period. In the switching-level model each PWM phase gets
    /// `ceil(substeps x its share of the period)` (at least one), so no substep is longer
    /// than `T / substeps` and every substep sees a constant bridge state.
    pub substeps: u32,
}

/// Longest RK4 substep [`Integration::for_rate`] allows \[s\].
pub const MAX_SUBSTEP_S: f64 = 5.0e-6;

impl Integration {
    /// Enough substeps that none is longer than [`MAX_SUBSTEP_S`] (10 at 20 kHz, 1 at
    /// 1 MHz).
    #[must_use]
    pub fn for_rate(rate_hz: f64) -> Self {
        let n = (1.0 / (rate_hz * MAX_SUBSTEP_S)).ceil();
        // Bounded to [1, 1e6] before the cast.
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let substeps = if n.is_finite() {
            n.clamp(1.0, 1e6) as u32
        } else {
            1
        };
        Self { substeps }
    }
}

/// A complete scenario.
///
/// Deserialised (from a scenario file) with defaults for the sections that have a natural
/// one; serialised in full:
///
/// | field | when left out |
/// |---|---|
/// | `name` | empty (the loader in [`crate::catalog`] uses the file's name) |
/// | `initial` | at rest, no current, at the reference's starting value ([`Reference::start_m`]) |
/// | `plant` | the controller's nominal plant, frozen fringing (`kind = "nominal"`) |
/// | `sensors` | ideal (`kind = "ideal"`) |
/// | `bridge` | [`Bridge::default`]: averaged, 4201 counts, 0.7 V diodes (each field alone too) |
/// | `integration` | [`Integration::for_rate`] of `controller.rate_hz` |
/// | `probes_s` | none |
/// | `steady_window_s` | 0.05 s |
///
/// `duration_s`, `supply`, `reference` and `controller` are required.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(from = "File")]
pub struct Scenario {
    /// Free-form name.
    #[serde(default)]
    pub name: String,
    /// Simulated time \[s\]; the run has `round(duration_s * rate_hz)` ISR periods.
    pub duration_s: f64,
    /// Supply.
    pub supply: Supply,
    /// Position reference.
    pub reference: Reference,
    /// Initial state of the true plant.
    pub initial: Initial,
    /// The true plant.
    pub plant: TruePlant,
    /// The controller, exactly as the firmware would be configured; its `rate_hz` is the
    /// ISR rate of the simulation.
    pub controller: Settings,
    /// Sensors.
    pub sensors: Sensors,
    /// Power stage.
    pub bridge: Bridge,
    /// Integration.
    pub integration: Integration,
    /// Times at which to report the position error \[s\].
    #[serde(default)]
    pub probes_s: Vec<f64>,
    /// Length of the steady-state window at the end of each segment \[s\].
    #[serde(default = "default_window")]
    pub steady_window_s: f64,
    /// Faults injected during the run (none by default).
    #[serde(default)]
    pub faults: Vec<Injection>,
}

fn default_window() -> f64 {
    0.05
}

/// A scenario as a file states it: [`Scenario`] with the optional sections optional.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    #[serde(default)]
    name: String,
    duration_s: f64,
    supply: Supply,
    reference: Reference,
    #[serde(default)]
    initial: Option<Initial>,
    #[serde(default = "nominal_plant")]
    plant: TruePlant,
    controller: Settings,
    #[serde(default)]
    sensors: Sensors,
    #[serde(default)]
    bridge: Bridge,
    #[serde(default)]
    integration: Option<Integration>,
    #[serde(default)]
    probes_s: Vec<f64>,
    #[serde(default = "default_window")]
    steady_window_s: f64,
    #[serde(default)]
    faults: Vec<Injection>,
}

fn nominal_plant() -> TruePlant {
    TruePlant::Nominal {
        force: ForceModel::default(),
    }
}

impl From<File> for Scenario {
    fn from(f: File) -> Self {
        let initial = f.initial.unwrap_or(Initial {
            x_m: f.reference.start_m(),
            v_mps: 0.0,
            i_a: 0.0,
        });
        let integration = f
            .integration
            .unwrap_or_else(|| Integration::for_rate(f64::from(f.controller.rate_hz)));
        Self {
            name: f.name,
            duration_s: f.duration_s,
            supply: f.supply,
            reference: f.reference,
            initial,
            plant: f.plant,
            controller: f.controller,
            sensors: f.sensors,
            bridge: f.bridge,
            integration,
            probes_s: f.probes_s,
            steady_window_s: f.steady_window_s,
            faults: f.faults,
        }
    }
}

/// PWM full scale of the paper's reproduction (a 4200-count timer period).
pub const PAPER_MAX_DUTY: u16 = 4200;

/// Supply voltage of the paper's example \[V\].
pub const PAPER_SUPPLY_V: f64 = 150.0;

impl Scenario {
    /// The paper's example at an ISR rate of `rate_hz`: the nominal actuator
    /// ([`Params::paper`], frozen fringing) under the paper's law with the core's
    /// `Settings::paper` (surface bounds +-20 %, alpha1 = 10, alpha2 = 20000, eps1 = 10 V),
    /// a 150 V ideal supply, a calibration covering 225 V and +-40 A, ideal sensors, the
    /// averaged bridge, a step from `x0 = (1 mm, 0, 0)` to 3 mm at `t = 0`, 1 s (the law
    /// creeps: at 0.6 s the error is still 0.7 %, at 1 s it has reached its 0.49 %), the
    /// error probed at 0.5 s, a current trip of 30 A (the law asks for 22 A at start-up).
    #[must_use]
    #[allow(clippy::cast_possible_truncation)]
    pub fn paper(rate_hz: f64) -> Self {
        let mut controller = Settings::paper(rate_hz as f32, PAPER_SUPPLY_V as f32);
        controller.sense = hal::calibration(1.5 * PAPER_SUPPLY_V, 40.0);
        controller.limits.current_trip_a = 30.0;
        Self {
            name: format!("paper-{rate_hz}hz"),
            duration_s: 1.0,
            supply: Supply::ideal(PAPER_SUPPLY_V),
            reference: Reference::Step {
                from_m: 1e-3,
                to_m: 3e-3,
                at_s: 0.0,
            },
            initial: Initial {
                x_m: 1e-3,
                v_mps: 0.0,
                i_a: 0.0,
            },
            plant: TruePlant::Given(Params::paper()),
            controller,
            sensors: Sensors::Ideal,
            bridge: Bridge {
                // The reproduction keeps the PWM resolution its claims table was first
                // measured with (the chattering sampled law is sensitive to the last count).
                max_duty: PAPER_MAX_DUTY,
                ..Bridge::default()
            },
            integration: Integration::for_rate(rate_hz),
            probes_s: vec![0.5],
            steady_window_s: default_window(),
            faults: Vec::new(),
        }
    }

    /// The product's realistic default at an ISR rate of `rate_hz` on a `supply_v`
    /// supply: the product's actuator ([`ema::actuator::Actuator::PRODUCT`], the physical
    /// convention) with every setting derived from it (the practical law, extended-state
    /// observer, one sample of measurement delay, reference shaping, every fault
    /// detector), judged as [`crate::actuator::scenario`] judges any actuator (converter
    /// noise and delay, supply resistance, averaged bridge, nominal plant with frozen
    /// fringing), on the paper's step from 1 mm to 3 mm from rest without current, 0.4 s.
    ///
    /// # Errors
    /// A rate or supply the derivation refuses, by name.
    #[allow(clippy::cast_possible_truncation)]
    pub fn product(rate_hz: f64, supply_v: f64) -> Result<Self, Error> {
        let act = Actuator::PRODUCT
            .with_rate_hz(rate_hz as f32)
            .with_supply_v(supply_v as f32);
        let sc = crate::actuator::scenario(&format!("product-{rate_hz}hz-{supply_v}v"), &act)?;
        Ok(sc
            .with_reference(Reference::Step {
                from_m: 1e-3,
                to_m: 3e-3,
                at_s: 0.0,
            })
            .with_initial(Initial {
                x_m: 1e-3,
                v_mps: 0.0,
                i_a: 0.0,
            })
            .with_duration_s(0.4))
    }

    /// The product's actuator at `rate_hz` on `supply_v` on its evaluation sequence
    /// ([`crate::actuator::scenario`]: from rest at the open stop, 0.5 mm, then 3.5 mm at
    /// 0.3 s, 1.5 mm at 0.6 s and 3 mm at 0.9 s; 1.2 s in all).
    ///
    /// # Errors
    /// A rate or supply the derivation refuses, by name.
    #[allow(clippy::cast_possible_truncation)]
    pub fn product_sequence(rate_hz: f64, supply_v: f64) -> Result<Self, Error> {
        let act = Actuator::PRODUCT
            .with_rate_hz(rate_hz as f32)
            .with_supply_v(supply_v as f32);
        crate::actuator::scenario(&format!("product-sequence-{rate_hz}hz-{supply_v}v"), &act)
    }

    /// ISR rate \[Hz\] (the controller's).
    #[must_use]
    pub fn rate_hz(&self) -> f64 {
        f64::from(self.controller.rate_hz)
    }

    /// Sets the duration \[s\] and drops the probe times and the steps of a sequence
    /// that fall outside it.
    #[must_use]
    pub fn with_duration_s(mut self, duration_s: f64) -> Self {
        self.duration_s = duration_s;
        self.probes_s.retain(|t| *t < duration_s);
        if let Reference::Sequence { steps, .. } = &mut self.reference {
            steps.retain(|s| s.at_s < duration_s);
        }
        self
    }

    /// Sets the reference.
    #[must_use]
    pub fn with_reference(mut self, reference: Reference) -> Self {
        self.reference = reference;
        self
    }

    /// Sets the initial state.
    #[must_use]
    pub fn with_initial(mut self, initial: Initial) -> Self {
        self.initial = initial;
        self
    }

    /// Sets the true plant.
    #[must_use]
    pub fn with_plant(mut self, plant: TruePlant) -> Self {
        self.plant = plant;
        self
    }

    /// Sets the controller settings (its `rate_hz` becomes the ISR rate).
    #[must_use]
    pub fn with_controller(mut self, controller: Settings) -> Self {
        self.controller = controller;
        self
    }

    /// Sets the control law, keeping everything else of the controller.
    #[must_use]
    pub fn with_law(mut self, law: law::Settings) -> Self {
        self.controller.law = law;
        self
    }

    /// Sets the instantaneous over-current trip of the controller \[A\].
    #[must_use]
    #[allow(clippy::cast_possible_truncation)]
    pub fn with_current_trip_a(mut self, trip_a: f64) -> Self {
        self.controller.limits.current_trip_a = trip_a as f32;
        self
    }

    /// Sets the sensors.
    #[must_use]
    pub fn with_sensors(mut self, sensors: Sensors) -> Self {
        self.sensors = sensors;
        self
    }

    /// Sets the bridge model.
    #[must_use]
    pub fn with_bridge(mut self, bridge: Bridge) -> Self {
        self.bridge = bridge;
        self
    }

    /// Sets the bridge mode only.
    #[must_use]
    pub fn with_bridge_mode(mut self, mode: BridgeMode) -> Self {
        self.bridge.mode = mode;
        self
    }

    /// Sets the supply.
    #[must_use]
    pub fn with_supply(mut self, supply: Supply) -> Self {
        self.supply = supply;
        self
    }

    /// Sets the RK4 substeps per ISR period.
    #[must_use]
    pub fn with_substeps(mut self, substeps: u32) -> Self {
        self.integration.substeps = substeps;
        self
    }

    /// Sets the times at which the error is probed \[s\].
    #[must_use]
    pub fn with_probes_s(mut self, probes_s: Vec<f64>) -> Self {
        self.probes_s = probes_s;
        self
    }

    /// Number of ISR periods simulated.
    #[must_use]
    pub fn ticks(&self) -> usize {
        let n = (self.duration_s * self.rate_hz()).round();
        // Validated finite and bounded before use; negative or NaN gives 0.
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let n = if n.is_finite() && n > 0.0 {
            n as usize
        } else {
            0
        };
        n
    }

    /// Checks everything that can be checked before running (the controller settings are
    /// checked by the core when the run builds them).
    ///
    /// # Errors
    /// The first bad field, by name, with its value and why.
    pub fn validate(&self) -> Result<(), Error> {
        positive("duration_s", self.duration_s)?;
        positive("controller.rate_hz", self.rate_hz())?;
        if self.duration_s * self.rate_hz() > 1e9 {
            return Err(Error::param(
                "duration_s",
                self.duration_s,
                "more than 1e9 ISR periods",
            ));
        }
        self.supply.validate()?;
        self.reference.validate(self.duration_s)?;
        for (name, v) in [
            ("initial.x_m", self.initial.x_m),
            ("initial.v_mps", self.initial.v_mps),
            ("initial.i_a", self.initial.i_a),
        ] {
            if !v.is_finite() {
                return Err(Error::param(name, v, "must be finite"));
            }
        }
        if let TruePlant::Drawn { uncertainty, .. } = &self.plant {
            uncertainty.validate()?;
        }
        if let Sensors::Adc(adc) = &self.sensors {
            adc.validate()?;
            if adc.delay_samples != u32::from(self.controller.delay_ticks) {
                return Err(Error::param(
                    "controller.delay_ticks",
                    f64::from(self.controller.delay_ticks),
                    format!(
                        "the converter delivers its frames {} period(s) late \
                         (sensors.delay_samples): the controller must be told the same, or \
                         its observer, current predictor and fault detectors pair samples \
                         with the wrong voltages",
                        adc.delay_samples
                    ),
                ));
            }
            let cal = &self.controller.sense;
            let (_, vbus_max) = hal::channel_span(&cal.vbus);
            if vbus_max <= self.supply.voltage_v {
                return Err(Error::param(
                    "controller.sense.vbus.scale",
                    f64::from(cal.vbus.scale),
                    format!(
                        "the bus channel reads at most {vbus_max:.1} V, below the {} V supply \
                         (use hal::calibration with a full scale of about 1.5 x supply)",
                        self.supply.voltage_v
                    ),
                ));
            }
            let (i_min, i_max) = hal::channel_span(&cal.current);
            let trip = f64::from(self.controller.limits.current_trip_a);
            if trip > i_max || -trip < i_min {
                return Err(Error::param(
                    "controller.sense.current.scale",
                    f64::from(cal.current.scale),
                    format!(
                        "the current channel reads {i_min:.1}..{i_max:.1} A, short of the \
                         {trip} A trip level"
                    ),
                ));
            }
        }
        if self.bridge.max_duty == 0 {
            return Err(Error::param("bridge.max_duty", 0.0, "must be positive"));
        }
        non_negative("bridge.diode_drop_v", self.bridge.diode_drop_v)?;
        if !(1..=1_000_000).contains(&self.integration.substeps) {
            return Err(Error::param(
                "integration.substeps",
                f64::from(self.integration.substeps),
                "must be 1 to 1e6",
            ));
        }
        for (k, t) in self.probes_s.iter().enumerate() {
            if !(t.is_finite() && *t >= 0.0 && *t < self.duration_s) {
                return Err(Error::param(
                    format!("probes_s[{k}]"),
                    *t,
                    "must lie inside the run",
                ));
            }
        }
        for f in &self.faults {
            f.validate()?;
        }
        positive("steady_window_s", self.steady_window_s)
    }

    /// Adds a fault injected at `at_s`.
    #[must_use]
    pub fn with_fault(mut self, at_s: f64, fault: Injected) -> Self {
        self.faults.push(Injection { at_s, fault });
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_converter_delay_the_controller_does_not_know_is_refused() {
        let mut sc = Scenario::product(20e3, 24.0).unwrap();
        sc.controller.delay_ticks = 0;
        let e = sc.validate().unwrap_err();
        assert!(e.to_string().contains("controller.delay_ticks"), "{e}");
        assert!(Scenario::product(20e3, 24.0).unwrap().validate().is_ok());
    }

    #[test]
    fn references_and_segments() {
        let s = Reference::Sequence {
            initial_m: 1e-3,
            steps: vec![
                StepAt {
                    at_s: 0.0,
                    to_m: 3e-3,
                },
                StepAt {
                    at_s: 0.5,
                    to_m: 2e-3,
                },
            ],
        };
        assert_eq!(s.position_m(0.2), 3e-3);
        assert_eq!(s.position_m(0.5), 2e-3);
        let seg = s.segments(0.8);
        assert_eq!(seg.len(), 2);
        assert_eq!((seg[1].start_s, seg[1].end_s), (0.5, 0.8));
        assert_eq!((seg[1].from_m, seg[1].to_m), (3e-3, 2e-3));
        let m = Reference::Smooth {
            from_m: 1e-3,
            to_m: 3e-3,
            start_s: 0.1,
            duration_s: 0.2,
        };
        assert_eq!(m.position_m(0.0), 1e-3);
        assert!((m.position_m(0.2) - 2e-3).abs() < 1e-15);
        assert_eq!(m.position_m(0.4), 3e-3);
        let r = Reference::Ramp {
            from_m: 0.0,
            to_m: 2e-3,
            start_s: 0.0,
            duration_s: 0.1,
        };
        assert!((r.position_m(0.025) - 0.5e-3).abs() < 1e-15);
    }

    #[test]
    fn draws_stay_within_the_controller_bounds() {
        use rand::SeedableRng;
        let nominal = ema::model::Plant::paper();
        let env = nominal.envelope().unwrap();
        let u = Uncertainty::default();
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        let (mut rect, mut ec) = (0, 0);
        for _ in 0..200 {
            let p = u.draw(&nominal, &mut rng);
            p.validate().unwrap();
            let (g_lo, g_hi) = p.gap_range_m();
            for s in &p.gaps {
                if matches!(s, Surface::Rectangular { .. }) {
                    rect += 1;
                }
                for k in 0..=20 {
                    let g = g_lo + (g_hi - g_lo) * f64::from(k) / 20.0;
                    let a = s.area_m2(g);
                    assert!(a >= f64::from(nominal.bounds.s_lo_m2));
                    assert!(a <= f64::from(nominal.bounds.s_hi_m2));
                }
                // The frozen mu therefore lies inside the controller's envelope.
                let g = 2e-3;
                let mu = p.mu_frozen_h_per_m(g);
                assert!(mu >= f64::from(env.mu_lo(g as f32)) * (1.0 - 1e-5));
                assert!(mu <= f64::from(env.mu_hi(g as f32)) * (1.0 + 1e-5));
            }
            if p.force == ForceModel::EnergyConsistent {
                ec += 1;
            }
            assert!((p.resistance_ohm / 0.4 - 1.0).abs() <= 0.2 + 1e-6);
            assert!((p.friction_n_s_per_m / 5.0 - 1.0).abs() <= 0.5 + 1e-6);
        }
        assert!(rect > 100 && rect < 300, "{rect}");
        assert!(ec > 60 && ec < 140, "{ec}");
    }

    #[test]
    fn draws_never_panic_on_bad_settings() {
        use rand::SeedableRng;
        let bad = Uncertainty {
            resistance_rel: f64::NAN,
            spring_rel: 3.0,
            mass_rel: -1.0,
            friction_rel: 0.5,
            energy_consistent_probability: 1.5,
            rectangular_probability: f64::NAN,
        };
        assert!(bad.validate().is_err());
        let mut nominal = ema::model::Plant::paper();
        nominal.bounds.s_hi_m2 = nominal.bounds.s_lo_m2;
        let mut rng = rand_pcg::Pcg64::seed_from_u64(0);
        let p = bad.draw(&nominal, &mut rng);
        assert_eq!(p.force, ForceModel::EnergyConsistent);
        assert_eq!(p.resistance_ohm, f64::from(nominal.resistance_ohm));
        assert!(p.spring_n_per_m >= 0.0);
    }

    #[test]
    fn the_adc_must_cover_the_supply_and_the_trip() {
        let sc = Scenario::paper(20_000.0).with_sensors(Sensors::Adc(Adc::default()));
        sc.validate().unwrap();
        let mut board = sc.clone();
        board.controller.sense = ema::sense::Calibration::board();
        assert_eq!(
            board.validate().unwrap_err().name(),
            "controller.sense.vbus.scale"
        );
        let mut low = sc.clone().with_current_trip_a(45.0);
        assert_eq!(
            low.validate().unwrap_err().name(),
            "controller.sense.current.scale"
        );
        low.controller.sense = hal::calibration(225.0, 50.0);
        low.validate().unwrap();
    }

    #[test]
    fn scenarios_round_trip_through_toml() {
        let mut sc = Scenario::paper(20_000.0)
            .with_sensors(Sensors::Adc(Adc::typical()))
            .with_plant(TruePlant::Drawn {
                seed: 5,
                uncertainty: Uncertainty::default(),
            });
        sc.reference = Reference::Sequence {
            initial_m: 1e-3,
            steps: vec![StepAt {
                at_s: 0.0,
                to_m: 3e-3,
            }],
        };
        let text = toml::to_string(&sc).unwrap();
        assert!(text.contains("duration_s"), "{text}");
        let back: Scenario = toml::from_str(&text).unwrap();
        assert_eq!(back, sc);
        let given = Scenario::paper(1e6);
        let back: Scenario = toml::from_str(&toml::to_string(&given).unwrap()).unwrap();
        assert_eq!(back, given);
        // Unknown fields are refused, by name.
        let bad = text.replace("duration_s", "duration_ms");
        let err = toml::from_str::<Scenario>(&bad).unwrap_err().to_string();
        assert!(err.contains("duration_ms"), "{err}");
    }
}
