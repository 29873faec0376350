//! What to simulate: the controller settings, the true plant, the supply, bridge, sensors,
//! reference and duration. Every type here is serde-(de)serializable with unit-carrying
//! field names, ready for scenario files.

use ema::control::law;
use ema::control::Settings;
use serde::{Deserialize, Serialize};

use crate::simulation::hal::{self, Supply};
use crate::simulation::plant::{non_negative, positive, ForceModel, Params};
use crate::simulation::Error;

mod hardware;
mod injection;
mod reference;
mod uncertainty;

pub use hardware::*;
pub use injection::*;
pub use reference::*;
pub use uncertainty::*;

/// A complete scenario.
///
/// Deserialised (from a scenario file) with defaults for the sections that have a natural
/// one; serialised in full:
///
/// | field | when left out |
/// |---|---|
/// | `name` | empty (the loader in [`crate::simulation::catalog`] uses the file's name) |
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
    /// Inductance probes started during the run (none by default).
    #[serde(default)]
    pub inductance_probes: Vec<InductanceProbe>,
}

/// An inductance probe ([`ema::control::Probe`]) started during a run: `cycles` times up
/// and down by `amplitude_a` about the law's desired current, `half_ticks` at each level.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InductanceProbe {
    /// When it starts \[s\].
    pub at_s: f64,
    /// Half the step of the desired current \[A\].
    pub amplitude_a: f64,
    /// Ticks at each level.
    pub half_ticks: u16,
    /// Cycles (each up and down).
    pub cycles: u16,
}

impl InductanceProbe {
    /// Ticks it runs.
    #[must_use]
    pub fn ticks(&self) -> usize {
        self.start().ticks_left as usize
    }

    /// The controller's probe, started (as the board starts it on [`Self::command`]).
    #[must_use]
    #[expect(clippy::cast_possible_truncation)]
    pub fn start(&self) -> ema::control::Probe {
        ema::control::Probe::new(self.amplitude_a as f32, self.half_ticks, self.cycles)
    }

    /// The board's command that starts it.
    #[must_use]
    #[expect(clippy::cast_possible_truncation)]
    pub fn command(&self) -> ema::device::protocol::Command<'static> {
        ema::device::protocol::Command::Probe {
            amplitude_a: self.amplitude_a as f32,
            half_ticks: self.half_ticks,
            cycles: self.cycles,
        }
    }
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
    #[serde(default)]
    inductance_probes: Vec<InductanceProbe>,
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
            inductance_probes: f.inductance_probes,
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
    #[expect(clippy::cast_possible_truncation)]
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
            inductance_probes: Vec::new(),
        }
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
    #[expect(clippy::cast_possible_truncation)]
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
        #[expect(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
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
        if let Some(b) = self.bridge.break_current_a {
            // Above the software trip: the comparator backs the sampled trip up.
            let trip = self.controller.limits.current_trip_a;
            if b.is_nan() || b <= trip {
                return Err(Error::param(
                    "bridge.break_current_a",
                    f64::from(b),
                    format!("must be above the current trip, {trip} A"),
                ));
            }
        }
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
        for (k, p) in self.inductance_probes.iter().enumerate() {
            if !(p.at_s.is_finite() && p.at_s >= 0.0 && p.at_s < self.duration_s) {
                return Err(Error::param(
                    format!("inductance_probes[{k}].at_s"),
                    p.at_s,
                    "must lie inside the run",
                ));
            }
            if !(p.amplitude_a.is_finite() && p.amplitude_a >= 0.0) {
                return Err(Error::param(
                    format!("inductance_probes[{k}].amplitude_a"),
                    p.amplitude_a,
                    "must be finite and not negative",
                ));
            }
            if p.half_ticks == 0 {
                return Err(Error::param(
                    format!("inductance_probes[{k}].half_ticks"),
                    0.0,
                    "must be positive",
                ));
            }
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
    use crate::simulation::hal::Adc;
    use crate::simulation::plant::Surface;

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
        let nominal = ema::control::model::Plant::paper();
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
        let mut nominal = ema::control::model::Plant::paper();
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
        board.controller.sense = ema::control::sense::Calibration::board();
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
