//! Actuator files in the simulator: the family kept in the repository
//! (`hil-sim/actuators/*.toml`), loading a file, the scenario an actuator is evaluated on,
//! and tuned files.
//!
//! An actuator file is an [`ema::control::actuator::Actuator`] in TOML: about twenty
//! numbers from a datasheet and a bench (`hil-sim/actuators/valve.toml` is one to copy).
//! Every controller setting follows from it ([`Actuator::settings`]); so does the scenario
//! it is judged on ([`scenario`]): a sequence of four positions across the stroke, timed
//! from its own settling target, with a 12-bit converter of 1.5 codes of noise and one
//! sample of delay on every channel, a supply whose internal resistance is an eighth of the
//! coil's, and the averaged bridge with the PWM resolution a 168 MHz timer gives at its
//! rate.
//!
//! A tuned file is the same file with a `[tuning]` section, which `hil-sim tune` writes
//! ([`tuned_text`]); the firmware build takes either (`EMA_ACTUATOR=path cargo fw`).
//!
//! ```
//! let (name, act) = hil_sim::simulation::actuator::load("valve").unwrap();
//! assert_eq!(name, "valve");
//! let sc = hil_sim::simulation::actuator::scenario(&name, &act).unwrap();
//! // Four positions at 1/8, 7/8, 3/8 and 3/4 of the 1.5 mm stroke.
//! assert_eq!(sc.reference.segments(sc.duration_s).len(), 3);
//! ```

use std::path::Path;

use ema::control::actuator::Actuator;
use ema::control::shaping;
use ema::control::shaping::SETTLING_CLAIM_S;

use crate::simulation::files::LoadError;
use crate::simulation::hal::{Adc, Supply};
use crate::simulation::plant::ForceModel;
use crate::simulation::scenario::Reference;
use crate::simulation::scenario::{
    Bridge, Initial, Integration, Scenario, Sensors, StepAt, TruePlant,
};
use crate::simulation::Error;

#[doc(inline)]
pub use crate::simulation::hal::{pwm_full_scale, TIMER_CLOCK_HZ};

/// An actuator file kept in the repository.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Entry {
    /// Name (the file's stem).
    pub name: &'static str,
    /// The file as written from the datasheet.
    pub text: &'static str,
    /// The same with the gains `hil-sim tune` chose (`<name>.tuned.toml`).
    pub tuned: &'static str,
}

impl Entry {
    /// The first line of the file's leading comment: what the actuator is.
    #[must_use]
    pub fn summary(&self) -> &'static str {
        crate::simulation::files::summary(self.text)
    }
}

macro_rules! entry {
    ($name:literal) => {
        Entry {
            name: $name,
            text: include_str!(concat!("../../actuators/", $name, ".toml")),
            tuned: include_str!(concat!("../../actuators/", $name, ".tuned.toml")),
        }
    };
}

/// The family: actuators of every size the product is validated on, each with its tuned
/// file. Together they span 5 g to 1 kg, 50 to 5000 N/m, 0.2 to 20 ohm, 50 to 2000 turns,
/// 0.5 to 10 mm of stroke, 0.3 to 20 A, 12 to 48 V and 10 to 50 kHz.
///
/// Not every actuator can be tuned: `hil-sim/actuators/magnet-1kg-underdamped.toml` (1.19 kg
/// on a 7370 N/m spring with 0.05 of critical damping, a slow coil, 12.9 kHz) is refused by
/// `tune`, which names the target it misses and where: at the best gains a corner plant
/// overshoots.
pub const FAMILY: [Entry; 7] = [
    entry!("product"),
    entry!("valve"),
    entry!("solenoid-12v"),
    entry!("positioner-48v"),
    entry!("plunger-1kg"),
    entry!("pilot-50khz"),
    entry!("micro-valve"),
];

/// The family member called `name`.
#[must_use]
pub fn member(name: &str) -> Option<&'static Entry> {
    FAMILY.iter().find(|e| e.name == name)
}

/// `true` when `text` looks like an actuator file rather than a scenario file (it has a
/// `[mechanics]` table).
#[must_use]
pub fn is_actuator_text(text: &str) -> bool {
    text.lines()
        .any(|l| l.trim_start().starts_with("[mechanics]"))
}

/// The tables of a board's backup that are the board's, not the actuator's (`bench
/// backup`): an actuator file may carry them, and the actuator is read without them.
pub const BOARD_TABLES: [&str; 2] = ["setpoint", "link"];

/// Parses and checks an actuator file; `origin` names it in errors. Every setting is
/// derived once, so a file that loads is a file the firmware build accepts.
///
/// # Errors
/// TOML that does not parse or has an unknown, missing or mistyped field; a value the
/// derivation refuses, by its name in the file.
pub fn parse(text: &str, origin: &str) -> Result<Actuator, LoadError> {
    let toml_error = |e: &dyn std::fmt::Display| LoadError::Toml {
        origin: origin.to_owned(),
        message: e.to_string(),
    };
    // A board's backup (`bench backup`) adds the board's own tables: the actuator is the
    // rest. (Parsed whole otherwise, so that an error keeps its line.)
    let mut table: toml::Table = toml::from_str(text).map_err(|e| toml_error(&e))?;
    let board = BOARD_TABLES
        .iter()
        .filter(|t| table.remove(**t).is_some())
        .count();
    let act: Actuator = if board > 0 {
        table.try_into().map_err(|e| toml_error(&e))?
    } else {
        toml::from_str(text).map_err(|e| toml_error(&e))?
    };
    act.settings().map_err(|e| LoadError::Invalid {
        origin: origin.to_owned(),
        error: Error::Actuator(e),
    })?;
    Ok(act)
}

/// Loads a family member by name (its tuned file) or an actuator file by path; returns
/// the name (the member's, or the file's stem without `.tuned`) and the actuator.
///
/// # Errors
/// See [`LoadError`].
pub fn load(name_or_path: &str) -> Result<(String, Actuator), LoadError> {
    if let Some(e) = member(name_or_path) {
        return Ok((e.name.to_owned(), parse(e.tuned, e.name)?));
    }
    let path = Path::new(name_or_path);
    let text = std::fs::read_to_string(path).map_err(|e| LoadError::NotFound {
        what: name_or_path.to_owned(),
        io: e.to_string(),
    })?;
    Ok((stem(path), parse(&text, &path.display().to_string())?))
}

/// Loads an actuator as written, without its tuning: a family member's plain file, or a
/// file by path with any `[tuning]` section dropped (what `tune` starts from).
///
/// # Errors
/// See [`LoadError`].
pub fn load_untuned(name_or_path: &str) -> Result<(String, Actuator, String), LoadError> {
    let (name, text, origin) = if let Some(e) = member(name_or_path) {
        (e.name.to_owned(), e.text.to_owned(), e.name.to_owned())
    } else {
        let path = Path::new(name_or_path);
        let text = std::fs::read_to_string(path).map_err(|e| LoadError::NotFound {
            what: name_or_path.to_owned(),
            io: e.to_string(),
        })?;
        (stem(path), text, path.display().to_string())
    };
    let mut act = parse(&text, &origin)?;
    act.tuning = None;
    Ok((name, act, text))
}

/// A file's name without its folder, `.toml` and `.tuned`.
#[must_use]
pub fn stem(path: &Path) -> String {
    let s = path
        .file_stem()
        .map_or_else(|| "actuator".into(), |s| s.to_string_lossy().into_owned());
    s.strip_suffix(".tuned").map_or(s.clone(), str::to_owned)
}

/// Fractions of the stroke the evaluation sequence visits: a long move up, a long move
/// down, a short move up (the product's 0.5, 3.5, 1.5 and 3 mm on its 4 mm stroke).
pub const SEQUENCE: [f64; 4] = [0.125, 0.875, 0.375, 0.75];

/// Length of the steady window at the end of each segment \[s\].
pub const STEADY_WINDOW_S: f64 = 0.05;

/// The minimum-time move between two positions that the settings' limits allow, as the
/// reference shaping computes it (magnet at the current limit on the weakest plant, the
/// spring alone the other way, the coil's current rise included) \[s\]; `None` without
/// reference shaping.
#[must_use]
#[expect(clippy::cast_possible_truncation)]
pub fn minimum_move_s(settings: &ema::control::Settings, from_m: f64, to_m: f64) -> Option<f64> {
    Some(f64::from(
        planner(settings)?.minimum_time_s(from_m as f32, to_m as f32),
    ))
}

/// The settling target of a move ([`ema::control::shaping::Config::settling_target_s`]), or
/// the paper's 0.2 s for settings without reference shaping (the paper's reproduction)
/// \[s\].
#[must_use]
#[expect(clippy::cast_possible_truncation)]
pub fn settling_target_s(settings: &ema::control::Settings, from_m: f64, to_m: f64) -> f64 {
    planner(settings).map_or(f64::from(SETTLING_CLAIM_S), |p| {
        f64::from(p.settling_target_s(from_m as f32, to_m as f32))
    })
}

/// How long each position of the [`SEQUENCE`] over `stroke_m` is held with `controller`:
/// the slowest move's settling target plus twice the steady window, in whole milliseconds
/// (so the step times fall on ticks at any usual rate) \[s\].
#[must_use]
pub fn segment_s(controller: &ema::control::Settings, stroke_m: f64) -> f64 {
    let at = |k: usize| SEQUENCE.get(k).map_or(0.0, |f| f * stroke_m);
    let segment_s = (1..SEQUENCE.len())
        .map(|k| settling_target_s(controller, at(k - 1), at(k)))
        .fold(0.0, f64::max)
        + 2.0 * STEADY_WINDOW_S;
    // (Excess below a microsecond is the f32 rounding of the targets.)
    (segment_s * 1e3 - 1e-3).ceil() / 1e3
}

/// The scenario an actuator is judged on (see the module documentation): rest at the
/// open stop, then the [`SEQUENCE`] of positions, each held for its settling target plus
/// the steady window and 50 ms.
///
/// # Errors
/// A file whose settings do not derive, by name.
pub fn scenario(name: &str, act: &Actuator) -> Result<Scenario, Error> {
    let controller = act.settings().map_err(Error::Actuator)?;
    let stroke = f64::from(act.mechanics.stroke_m);
    let at = |k: usize| SEQUENCE.get(k).map_or(0.0, |f| f * stroke);
    let segment_s = segment_s(&controller, stroke);
    #[expect(clippy::cast_precision_loss)]
    let steps = (1..SEQUENCE.len())
        .map(|k| StepAt {
            at_s: segment_s * k as f64,
            to_m: at(k),
        })
        .collect();
    let rate_hz = f64::from(act.board.rate_hz);
    #[expect(clippy::cast_precision_loss)]
    let duration_s = segment_s * SEQUENCE.len() as f64;
    Ok(Scenario {
        name: name.to_owned(),
        duration_s,
        supply: Supply {
            voltage_v: f64::from(act.board.supply_v),
            internal_resistance_ohm: f64::from(act.coil.resistance_ohm) / 8.0,
        },
        reference: Reference::Sequence {
            initial_m: at(0),
            steps,
        },
        initial: Initial::default(),
        plant: TruePlant::Nominal {
            force: ForceModel::default(),
        },
        controller,
        sensors: Sensors::Adc(Adc::typical()),
        bridge: Bridge {
            max_duty: pwm_full_scale(rate_hz),
            break_current_a: Some(act.break_current_a()),
            ..Bridge::default()
        },
        integration: Integration::for_rate(rate_hz),
        probes_s: Vec::new(),
        steady_window_s: STEADY_WINDOW_S,
        faults: Vec::new(),
        inductance_probes: Vec::new(),
    })
}

/// The tuned file: `text` (an actuator file as written) without any `[tuning]` section,
/// followed by one holding `tuning`.
#[must_use]
pub fn tuned_text(text: &str, tuning: &ema::control::actuator::Tuning, note: &str) -> String {
    let mut out = String::new();
    let mut skipping = false;
    for line in text.lines() {
        let trimmed = line.trim_start();
        if trimmed.starts_with('[') {
            skipping = trimmed.starts_with("[tuning]");
        }
        if !skipping {
            out.push_str(line);
            out.push('\n');
        }
    }
    while out.ends_with("\n\n") {
        out.pop();
    }
    out.push_str(&format!(
        "\n[tuning]                    # {note}\nalpha_per_s = {:?}\nobserver_rad_s = {:?}\nmargin = {:?}\ndisturbance_follows_force = {}\n",
        tuning.alpha_per_s, tuning.observer_rad_s, tuning.margin, tuning.disturbance_follows_force
    ));
    out
}

/// The shaping planner of `settings`, if any.
#[must_use]
pub fn planner(settings: &ema::control::Settings) -> Option<shaping::Config> {
    settings
        .shaping?
        .build(&settings.plant, 1.0 / settings.rate_hz)
        .ok()
}

// The product's scenarios are an actuator's judging scenario ([`scenario`]): defined
// here, above `scenario`.
impl Scenario {
    /// The product's realistic default at an ISR rate of `rate_hz` on a `supply_v`
    /// supply: the product's actuator ([`ema::control::actuator::Actuator::PRODUCT`], the
    /// physical convention) with every setting derived from it (the practical law,
    /// extended-state observer, one sample of measurement delay, reference shaping, every
    /// fault detector), judged as [`crate::simulation::actuator::scenario`] judges any actuator
    /// (converter noise and delay, supply resistance, averaged bridge, nominal plant with
    /// frozen fringing), on the paper's step from 1 mm to 3 mm from rest without current,
    /// 0.4 s.
    ///
    /// # Errors
    /// A rate or supply the derivation refuses, by name.
    #[expect(clippy::cast_possible_truncation)]
    pub fn product(rate_hz: f64, supply_v: f64) -> Result<Self, Error> {
        let act = Actuator::PRODUCT
            .with_rate_hz(rate_hz as f32)
            .with_supply_v(supply_v as f32);
        let sc = crate::simulation::actuator::scenario(
            &format!("product-{rate_hz}hz-{supply_v}v"),
            &act,
        )?;
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
    /// ([`crate::simulation::actuator::scenario`]: from rest at the open stop, 0.5 mm, then
    /// 3.5 mm at 0.3 s, 1.5 mm at 0.6 s and 3 mm at 0.9 s; 1.2 s in all).
    ///
    /// # Errors
    /// A rate or supply the derivation refuses, by name.
    #[expect(clippy::cast_possible_truncation)]
    pub fn product_sequence(rate_hz: f64, supply_v: f64) -> Result<Self, Error> {
        let act = Actuator::PRODUCT
            .with_rate_hz(rate_hz as f32)
            .with_supply_v(supply_v as f32);
        crate::simulation::actuator::scenario(
            &format!("product-sequence-{rate_hz}hz-{supply_v}v"),
            &act,
        )
    }
}
