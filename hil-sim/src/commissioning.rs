//! The board's commissioning routine (`ema::commission`) against simulated actuators: the
//! core's identification ticking as the control interrupt runs it (convert, identify,
//! drive the board's bridge on the mock pins), the converter with its typical noise,
//! quantisation and delay, the plant's RK4 with its end stops. The routine starts from the
//! file; the plant is the file's, or one drawn wider than the file (see [`Draw`]).
//!
//! What is judged against the plant's own values: the resistance, the inductance at both
//! stops (the plant's fringing included), the position readings at both stops (the drawn
//! sensor's gain and offset included), the largest true coil current, the actuator time.

use ema::actuator::Actuator;
use ema::bridge::HBridge;
use ema::commission::{Abort, Identification, Plan, Report, Step};
use rand::Rng;

use crate::bench::board::scenario;
use crate::hal::{self, Adc};
use crate::plant::Params;
use crate::scenario::Sensors;
use crate::sim::Stepper;
use crate::Error;

/// An actuator drawn off its file, as a user's is: the airgap surfaces, the coil's
/// resistance, the spring rate, the mass each within +-30 %, an unknown preload up to a
/// fifth of the spring's force over the stroke, the friction within +-50 %, and a
/// position sensor whose offset and gain are each within +-3 % (of the stroke, of the
/// span).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Draw {
    /// Surfaces, resistance, spring rate, mass, friction: factors on the file's \[-\].
    pub factors: [f64; 5],
    /// Preload as a share of the spring's force over the stroke \[-\].
    pub preload_share: f64,
    /// The position sensor's gain error \[-\].
    pub gain_error: f64,
    /// Its offset as a share of the stroke \[-\].
    pub offset_share: f64,
}

impl Draw {
    /// One draw.
    pub fn new<R: Rng + ?Sized>(rng: &mut R) -> Self {
        let mut f = |s: f64| rng.random_range(1.0 - s..1.0 + s);
        let factors = [f(0.3), f(0.3), f(0.3), f(0.3), f(0.5)];
        Self {
            factors,
            preload_share: rng.random_range(0.0..0.2),
            gain_error: rng.random_range(-0.03..0.03),
            offset_share: rng.random_range(-0.03..0.03),
        }
    }

    /// `plant` (the file's) drawn.
    #[must_use]
    pub fn apply(&self, plant: &Params) -> Params {
        let [surfaces, r, k, m, friction] = self.factors;
        let mut p = plant.clone();
        p.scale_surfaces(surfaces);
        p.resistance_ohm *= r;
        p.spring_n_per_m *= k;
        p.mass_kg *= m;
        p.friction_n_s_per_m *= friction;
        p.preload_n = self.preload_share * p.spring_n_per_m * p.stroke_m;
        p
    }
}

/// One commissioning and what it is judged against.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Outcome {
    /// The routine's result.
    pub report: Result<Report, Abort>,
    /// Actuator time it took \[s\].
    pub took_s: f64,
    /// Largest true coil current \[A\].
    pub peak_a: f64,
    /// The plant's resistance \[ohm\].
    pub resistance_ohm: f64,
    /// The plant's inductance at the open and the closed stop \[H\].
    pub inductance_h: [f64; 2],
    /// What the file's calibration reads with the armature at each stop, noise and
    /// quantisation aside \[m\].
    pub ends_m: [f64; 2],
    /// One position code \[m\].
    pub code_m: f64,
}

impl Outcome {
    /// Relative errors of the resistance and the two inductances, and the end stops'
    /// errors in position codes; `None` for a commissioning that stopped.
    #[must_use]
    pub fn errors(&self) -> Option<[f64; 5]> {
        let r = self.report.ok()?;
        let rel = |got: f32, want: f64| f64::from(got) / want - 1.0;
        let codes = |got: f32, want: f64| (f64::from(got) - want).abs() / self.code_m;
        Some([
            rel(r.resistance.ohm, self.resistance_ohm),
            rel(r.inductance.open_h, self.inductance_h[0]),
            rel(r.inductance.closed_h, self.inductance_h[1]),
            codes(r.ends.open_m, self.ends_m[0]),
            codes(r.ends.closed_m, self.ends_m[1]),
        ])
    }
}

/// Commissions actuator `a` (its file), the plant the file's or `draw`n from it.
///
/// # Errors
/// An actuator whose settings do not derive.
pub fn run(a: &Actuator, draw: Option<&Draw>) -> Result<Outcome, Error> {
    let sc = scenario(a, true)?;
    let file_plant = sc.plant.resolve(&sc.controller.plant);
    let plant = draw.map_or_else(|| file_plant.clone(), |d| d.apply(&file_plant));
    let mut stepper = Stepper::for_scenario(&sc, plant.clone(), sc.integration.substeps)?;
    let mut converter = match &sc.sensors {
        Sensors::Adc(adc) => adc.start(&sc.controller.sense),
        Sensors::Ideal => Adc::default().start(&sc.controller.sense),
    };
    let position = sc.controller.sense.position;
    let code_m = f64::from(position.scale);
    let (gain, offset_code) = draw.map_or((0.0, 0.0), |d| {
        (d.gain_error, d.offset_share * plant.stroke_m / code_m)
    });
    converter.set_position_error(gain, offset_code);
    let (pwm, dir, en, lines) = hal::bridge_io(sc.bridge.max_duty);
    let Ok(mut bridge) = HBridge::new(pwm, dir, en);
    let cfg = sc.controller.build().map_err(Error::Controller)?;
    // As the board's dispatcher plans it (`ema::device`).
    let plan = Plan::for_actuator(a, a.board.rate_hz).map_err(Error::Actuator)?;
    let mut id = Identification::new(plan);
    let (mut applied, mut peak_a) = (0.0_f32, 0.0_f64);
    let rate = f64::from(a.board.rate_hz);
    let mut report = Err(Abort::Stopped);
    let mut ticks = 0_u64;
    // Ten times the plan without restarts: more is a routine that does not end.
    while ticks < 10 * plan.ticks() {
        ticks += 1;
        let truth = stepper.sample();
        peak_a = peak_a.max(truth.i_a.abs());
        let frame = converter.sample(truth.x_m, truth.i_a, truth.vbus_v);
        let Ok(m) = cfg.sense().convert(&frame) else {
            // A reading the board would latch as a fault.
            report = Err(Abort::Fault);
            break;
        };
        match id.step(&m, applied) {
            Step::Drive(u) => {
                // The mock pins cannot fail.
                applied = bridge.apply(u, m.vbus_v).map_or(0.0, |d| d.u_v);
            }
            Step::Done(r) => {
                report = r;
                break;
            }
        }
        stepper.advance(lines.switches(), sc.bridge.mode);
    }
    let ends_m = [0.0, plant.stroke_m].map(|x| x * (1.0 + gain) + offset_code * code_m);
    Ok(Outcome {
        report,
        took_s: ticks as f64 / rate,
        peak_a,
        resistance_ohm: plant.resistance_ohm,
        inductance_h: [0.0, plant.stroke_m].map(|x| plant.inductance_h(plant.gap_m(x))),
        ends_m,
        code_m,
    })
}
