//! The board's parameters: the actuator file it was built for, the position sensor's
//! correction a commissioning measured, and the set-point source.
//! Read and changed by name over the link; validated exactly as a build validates an
//! actuator file; stored in flash by [`crate::device::store`].
//!
//! Names are the actuator file's dotted field names (`mechanics.mass_kg`,
//! `coil.rated_current_a`, `board.supply_v`, `tuning.alpha_per_s`, ...), `setpoint.*`
//! for the analog set point ([`crate::device::analog`]), `link.*` for the host's timeout
//! ([`crate::device::liveness`]) and `sensor.position_gain`, `sensor.position_offset_codes`
//! for the position sensor's gain and offset measured at the end stops
//! ([`PositionCorrection`], applied by [`Actuator::calibration_with`]). A change is validated with everything
//! else: the whole set must derive settings ([`Actuator::settings`]) that build, on this
//! board ([`Board`]); a refusal names the field, its value and why, as the build does.
//!
//! Two parameters are fixed by the firmware build and refused over the link:
//! `board.rate_hz` (the PWM timer is set up for it) and `magnetics.kind` (which fields
//! the magnetic circuit has).
//!
//! ```
//! use ema::device::params::{Board, Params};
//! use ema::device::protocol::Value;
//!
//! let board = Board { rate_hz: 20_000.0, current_zero_code: None };
//! let mut p = Params::new(ema::control::actuator::Actuator::PRODUCT);
//! p.set("board.supply_v", Value::Number(12.0)).unwrap();
//! assert_eq!(p.get("board.supply_v"), Ok(Value::Number(12.0)));
//! assert!(p.build(&board).is_ok());
//!
//! // A peak current below 1.05 times the rated current: refused by the build's own check.
//! p.set("coil.peak_current_a", Value::Number(5.0)).unwrap();
//! let e = p.build(&board).unwrap_err();
//! assert_eq!((e.param, e.value), ("coil.peak_current_a", 5.0));
//! ```

use serde::{Deserialize, Serialize};

use crate::control::actuator::{Actuator, Magnetics};
use crate::control::config::{self, Error};
use crate::control::sense::PositionCorrection;
use crate::control::Settings;
use crate::device::analog;
use crate::device::liveness;
use crate::device::protocol::Value;
use crate::device::Install;

/// Every parameter of the board.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Params {
    /// The actuator, as in its file.
    pub actuator: Actuator,
    /// The set point's source and filter.
    pub setpoint: analog::Settings,
    /// The host's timeout.
    pub link: liveness::Settings,
    /// The position sensor's gain and offset a commissioning measured at the end stops
    /// ([`PositionCorrection::NONE`] until one has).
    pub sensor: PositionCorrection,
}

/// What a parameter holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// A number in the unit its name carries.
    Number,
    /// Yes or no.
    Flag,
    /// One of these names.
    Choice(&'static [&'static str]),
}

/// A parameter's description.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Info {
    /// Dotted name.
    pub name: &'static str,
    /// What it holds.
    pub kind: Kind,
    /// `Some(why)` when the link cannot change it.
    pub fixed: Option<&'static str>,
}

const fn number(name: &'static str) -> Info {
    Info {
        name,
        kind: Kind::Number,
        fixed: None,
    }
}

/// Why `board.rate_hz` cannot be changed over the link.
pub const RATE_FIXED: &str = "the PWM timer is set up for the rate at build time";
/// Why `magnetics.kind` cannot be changed over the link.
pub const KIND_FIXED: &str = "the magnetic circuit's form is chosen in the actuator file";
/// The choices of `magnetics.kind`.
pub const MAGNETICS_KINDS: [&str; 2] = ["geometry", "inductance"];

/// Every parameter, in the order of the actuator file, then the board's own.
pub const TABLE: [Info; 36] = [
    number("mechanics.mass_kg"),
    number("mechanics.spring_n_per_m"),
    number("mechanics.preload_n"),
    number("mechanics.friction_n_s_per_m"),
    number("mechanics.stroke_m"),
    number("mechanics.residual_gap_m"),
    number("coil.resistance_ohm"),
    number("coil.turns"),
    number("coil.rated_current_a"),
    number("coil.peak_current_a"),
    number("coil.peak_time_s"),
    Info {
        name: "magnetics.kind",
        kind: Kind::Choice(&MAGNETICS_KINDS),
        fixed: Some(KIND_FIXED),
    },
    number("magnetics.geometry.gaps"),
    number("magnetics.geometry.pole_a_m"),
    number("magnetics.geometry.pole_b_m"),
    number("magnetics.geometry.fringing_coefficient"),
    number("magnetics.geometry.fringing_spread"),
    number("magnetics.geometry.iron_reluctance_per_h"),
    number("magnetics.inductance.open_h"),
    number("magnetics.inductance.closed_h"),
    number("board.supply_v"),
    Info {
        name: "board.rate_hz",
        kind: Kind::Number,
        fixed: Some(RATE_FIXED),
    },
    number("board.position_span_m"),
    number("board.current_full_scale_a"),
    number("board.vbus_full_scale_v"),
    number("tolerance.surface"),
    number("tolerance.mass"),
    number("tolerance.spring"),
    number("tolerance.friction"),
    number("tolerance.resistance"),
    number("sensor.position_gain"),
    number("sensor.position_offset_codes"),
    Info {
        name: "setpoint.source",
        kind: Kind::Choice(&analog::Source::NAMES),
        fixed: None,
    },
    number("setpoint.filter_s"),
    number("link.timeout_s"),
    Info {
        name: "link.on_timeout",
        kind: Kind::Choice(&liveness::OnTimeout::NAMES),
        fixed: None,
    },
];

/// The `tuning.*` parameters (the gains `hil-sim tune` chose, or the derived defaults).
pub const TUNING: [Info; 4] = [
    number("tuning.alpha_per_s"),
    number("tuning.observer_rad_s"),
    number("tuning.margin"),
    Info {
        name: "tuning.disturbance_follows_force",
        kind: Kind::Flag,
        fixed: None,
    },
];

/// Every parameter's description, tuning included.
pub fn all() -> impl Iterator<Item = &'static Info> {
    TABLE.iter().chain(TUNING.iter())
}

/// The description of the parameter called `name`.
#[must_use]
pub fn info(name: &str) -> Option<&'static Info> {
    all().find(|i| i.name == name)
}

/// Why a get or a set was refused (before validation of the whole set).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Refused {
    /// No parameter has this name.
    Unknown,
    /// Fixed by the firmware build.
    Fixed(&'static str),
    /// A value of another kind.
    WrongKind,
    /// A field of the other form of magnetic circuit than the actuator's.
    Unused,
    /// The value itself is refused (a choice index out of range, a non-finite tuning).
    Invalid(Error),
}

/// Facts of the board the parameters run on, fixed at build or measured at start.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Board {
    /// The control rate the firmware's timer runs \[Hz\].
    pub rate_hz: f32,
    /// The current sensor's zero measured at start \[code\] (`None`: nominal).
    pub current_zero_code: Option<f32>,
}

enum Field<'a> {
    Number(&'a mut f32),
    Flag(&'a mut bool),
    Source(&'a mut analog::Source),
    OnTimeout(&'a mut liveness::OnTimeout),
    Kind(u8),
}

impl Params {
    /// The actuator's parameters with the set point from the link.
    #[must_use]
    pub fn new(actuator: Actuator) -> Self {
        Self {
            actuator,
            setpoint: analog::Settings::default(),
            link: liveness::Settings::default(),
            sensor: PositionCorrection::NONE,
        }
    }

    fn field(&mut self, name: &str) -> Result<Field<'_>, Refused> {
        fn number(x: &mut f32) -> Result<Field<'_>, Refused> {
            Ok(Field::Number(x))
        }
        let a = &mut self.actuator;
        if name.starts_with("tuning.") && a.tuning.is_none() {
            // The defaults derived from the actuator become explicit values.
            a.tuning = Some(a.tuning_or_default().map_err(Refused::Invalid)?);
        }
        // One search of the table, then a jump by position ([`TABLE`] then [`TUNING`]): a
        // match on the names compiles to one comparison per name (1.9 KiB of flash). The
        // test `field_follows_the_table` holds the positions to the names.
        let Some(k) = all().position(|i| i.name == name) else {
            return Err(Refused::Unknown);
        };
        match k {
            0 => number(&mut a.mechanics.mass_kg),
            1 => number(&mut a.mechanics.spring_n_per_m),
            2 => number(&mut a.mechanics.preload_n),
            3 => number(&mut a.mechanics.friction_n_s_per_m),
            4 => number(&mut a.mechanics.stroke_m),
            5 => number(&mut a.mechanics.residual_gap_m),
            6 => number(&mut a.coil.resistance_ohm),
            7 => number(&mut a.coil.turns),
            8 => number(&mut a.coil.rated_current_a),
            9 => number(&mut a.coil.peak_current_a),
            10 => number(&mut a.coil.peak_time_s),
            11 => Ok(Field::Kind(match a.magnetics {
                Magnetics::Geometry { .. } => 0,
                Magnetics::Inductance { .. } => 1,
            })),
            12..=17 => match &mut a.magnetics {
                Magnetics::Geometry {
                    gaps,
                    pole_a_m,
                    pole_b_m,
                    fringing_coefficient,
                    fringing_spread,
                    iron_reluctance_per_h,
                } => number(match k {
                    12 => gaps,
                    13 => pole_a_m,
                    14 => pole_b_m,
                    15 => fringing_coefficient,
                    16 => fringing_spread,
                    _ => iron_reluctance_per_h,
                }),
                Magnetics::Inductance { .. } => Err(Refused::Unused),
            },
            18 | 19 => match &mut a.magnetics {
                Magnetics::Inductance { open_h, closed_h } => {
                    number(if k == 18 { open_h } else { closed_h })
                }
                Magnetics::Geometry { .. } => Err(Refused::Unused),
            },
            20 => number(&mut a.board.supply_v),
            21 => number(&mut a.board.rate_hz),
            22 => number(&mut a.board.position_span_m),
            23 => number(&mut a.board.current_full_scale_a),
            24 => number(&mut a.board.vbus_full_scale_v),
            25 => number(&mut a.tolerance.surface),
            26 => number(&mut a.tolerance.mass),
            27 => number(&mut a.tolerance.spring),
            28 => number(&mut a.tolerance.friction),
            29 => number(&mut a.tolerance.resistance),
            30 => number(&mut self.sensor.gain),
            31 => number(&mut self.sensor.offset_codes),
            32 => Ok(Field::Source(&mut self.setpoint.source)),
            33 => number(&mut self.setpoint.filter_s),
            34 => number(&mut self.link.timeout_s),
            35 => Ok(Field::OnTimeout(&mut self.link.on_timeout)),
            36..=39 => match &mut a.tuning {
                Some(t) => match k {
                    36 => number(&mut t.alpha_per_s),
                    37 => number(&mut t.observer_rad_s),
                    38 => number(&mut t.margin),
                    _ => Ok(Field::Flag(&mut t.disturbance_follows_force)),
                },
                None => Err(Refused::Unknown),
            },
            _ => Err(Refused::Unknown),
        }
    }

    /// The value of the parameter called `name` (for `tuning.*` on an actuator without
    /// tuning: the derived default in use).
    ///
    /// # Errors
    /// An unknown name, or a field of the other form of magnetic circuit.
    pub fn get(&self, name: &str) -> Result<Value, Refused> {
        let mut copy = *self;
        Ok(match copy.field(name)? {
            Field::Number(x) => Value::Number(*x),
            Field::Flag(b) => Value::Flag(*b),
            Field::Source(s) => Value::Choice(s.index()),
            Field::OnTimeout(o) => Value::Choice(o.index()),
            Field::Kind(k) => Value::Choice(k),
        })
    }

    /// Sets the parameter called `name`. Only the value's kind is checked here: validate
    /// the whole set with [`Params::build`] before using it.
    ///
    /// # Errors
    /// An unknown or fixed name, a value of another kind, a field of the other form of
    /// magnetic circuit, a choice out of range.
    pub fn set(&mut self, name: &str, value: Value) -> Result<(), Refused> {
        if let Some(why) = info(name).and_then(|i| i.fixed) {
            return Err(Refused::Fixed(why));
        }
        match (self.field(name)?, value) {
            (Field::Number(x), Value::Number(v)) => *x = v,
            (Field::Flag(b), Value::Flag(v)) => *b = v,
            (Field::Source(s), Value::Choice(c)) => {
                *s = analog::Source::from_index(c).ok_or(Refused::Invalid(Error {
                    param: "setpoint.source",
                    value: f32::from(c),
                    reason: config::Reason::AboveMax { max: 2.0 },
                }))?;
            }
            (Field::OnTimeout(o), Value::Choice(c)) => {
                *o = liveness::OnTimeout::from_index(c).ok_or(Refused::Invalid(Error {
                    param: "link.on_timeout",
                    value: f32::from(c),
                    reason: config::Reason::AboveMax { max: 1.0 },
                }))?;
            }
            _ => return Err(Refused::WrongKind),
        }
        Ok(())
    }

    /// Validates the whole set for `board` and derives the controller's settings, exactly
    /// as a firmware build does for its actuator file, plus the board's own facts: the
    /// rate its timer runs and the current zero it measured.
    ///
    /// # Errors
    /// The first bad field, by name, with its value and the reason.
    pub fn settings(&self, board: &Board) -> Result<Settings, Error> {
        if self.actuator.board.rate_hz != board.rate_hz {
            return Err(Error {
                param: "board.rate_hz",
                value: self.actuator.board.rate_hz,
                reason: config::Reason::Derived {
                    what: "the control rate this firmware's timer runs [Hz]",
                    derived: board.rate_hz,
                },
            });
        }
        let mut s = self.actuator.settings()?;
        s.sense = self.actuator.calibration_with(&self.sensor)?;
        if let Some(code) = board.current_zero_code {
            s.sense = s.sense.with_current_zero(code)?;
        }
        Ok(s)
    }

    /// Validates and builds what the interrupt runs: the controller, the analog input and
    /// the link's timeout.
    ///
    /// # Errors
    /// As [`Params::settings`], and a bad `setpoint.*` or `link.*`.
    pub fn build(&self, board: &Board) -> Result<Install, Error> {
        let s = self.settings(board)?;
        let control = s.build()?;
        let analog = self.setpoint.build(s.plant.stroke_m, control.ts_s())?;
        let link = self.link.build(board.rate_hz)?;
        Ok(Install {
            control,
            analog,
            link,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::actuator::Actuator;

    const BOARD: Board = Board {
        rate_hz: 20_000.0,
        current_zero_code: None,
    };

    /// The match on the names `Params::field` had: the reference for its positions.
    fn field_by_name<'p>(p: &'p mut Params, name: &str) -> Result<Field<'p>, Refused> {
        fn number(x: &mut f32) -> Result<Field<'_>, Refused> {
            Ok(Field::Number(x))
        }
        let a = &mut p.actuator;
        match name {
            "mechanics.mass_kg" => number(&mut a.mechanics.mass_kg),
            "mechanics.spring_n_per_m" => number(&mut a.mechanics.spring_n_per_m),
            "mechanics.preload_n" => number(&mut a.mechanics.preload_n),
            "mechanics.friction_n_s_per_m" => number(&mut a.mechanics.friction_n_s_per_m),
            "mechanics.stroke_m" => number(&mut a.mechanics.stroke_m),
            "mechanics.residual_gap_m" => number(&mut a.mechanics.residual_gap_m),
            "coil.resistance_ohm" => number(&mut a.coil.resistance_ohm),
            "coil.turns" => number(&mut a.coil.turns),
            "coil.rated_current_a" => number(&mut a.coil.rated_current_a),
            "coil.peak_current_a" => number(&mut a.coil.peak_current_a),
            "coil.peak_time_s" => number(&mut a.coil.peak_time_s),
            "magnetics.kind" => Ok(Field::Kind(match a.magnetics {
                Magnetics::Geometry { .. } => 0,
                Magnetics::Inductance { .. } => 1,
            })),
            "board.supply_v" => number(&mut a.board.supply_v),
            "board.rate_hz" => number(&mut a.board.rate_hz),
            "board.position_span_m" => number(&mut a.board.position_span_m),
            "board.current_full_scale_a" => number(&mut a.board.current_full_scale_a),
            "board.vbus_full_scale_v" => number(&mut a.board.vbus_full_scale_v),
            "tolerance.surface" => number(&mut a.tolerance.surface),
            "tolerance.mass" => number(&mut a.tolerance.mass),
            "tolerance.spring" => number(&mut a.tolerance.spring),
            "tolerance.friction" => number(&mut a.tolerance.friction),
            "tolerance.resistance" => number(&mut a.tolerance.resistance),
            "sensor.position_gain" => number(&mut p.sensor.gain),
            "sensor.position_offset_codes" => number(&mut p.sensor.offset_codes),
            "setpoint.source" => Ok(Field::Source(&mut p.setpoint.source)),
            "setpoint.filter_s" => number(&mut p.setpoint.filter_s),
            "link.timeout_s" => number(&mut p.link.timeout_s),
            "link.on_timeout" => Ok(Field::OnTimeout(&mut p.link.on_timeout)),
            _ if name.starts_with("magnetics.geometry.") => match &mut a.magnetics {
                Magnetics::Geometry {
                    gaps,
                    pole_a_m,
                    pole_b_m,
                    fringing_coefficient,
                    fringing_spread,
                    iron_reluctance_per_h,
                } => match name {
                    "magnetics.geometry.gaps" => number(gaps),
                    "magnetics.geometry.pole_a_m" => number(pole_a_m),
                    "magnetics.geometry.pole_b_m" => number(pole_b_m),
                    "magnetics.geometry.fringing_coefficient" => number(fringing_coefficient),
                    "magnetics.geometry.fringing_spread" => number(fringing_spread),
                    "magnetics.geometry.iron_reluctance_per_h" => number(iron_reluctance_per_h),
                    _ => Err(Refused::Unknown),
                },
                Magnetics::Inductance { .. } => {
                    info(name).map_or(Err(Refused::Unknown), |_| Err(Refused::Unused))
                }
            },
            _ if name.starts_with("magnetics.inductance.") => match &mut a.magnetics {
                Magnetics::Inductance { open_h, closed_h } => match name {
                    "magnetics.inductance.open_h" => number(open_h),
                    "magnetics.inductance.closed_h" => number(closed_h),
                    _ => Err(Refused::Unknown),
                },
                Magnetics::Geometry { .. } => {
                    info(name).map_or(Err(Refused::Unknown), |_| Err(Refused::Unused))
                }
            },
            _ if name.starts_with("tuning.") => {
                if a.tuning.is_none() {
                    // The defaults derived from the actuator become explicit values.
                    a.tuning = Some(a.tuning_or_default().map_err(Refused::Invalid)?);
                }
                match &mut a.tuning {
                    Some(t) => match name {
                        "tuning.alpha_per_s" => number(&mut t.alpha_per_s),
                        "tuning.observer_rad_s" => number(&mut t.observer_rad_s),
                        "tuning.margin" => number(&mut t.margin),
                        "tuning.disturbance_follows_force" => {
                            Ok(Field::Flag(&mut t.disturbance_follows_force))
                        }
                        _ => Err(Refused::Unknown),
                    },
                    None => Err(Refused::Unknown),
                }
            }
            _ => Err(Refused::Unknown),
        }
    }

    /// What a field lookup gave: the field's kind and address relative to the set, or the
    /// refusal.
    fn seen(base: *const Params, r: Result<Field<'_>, Refused>) -> Result<(u8, isize), Refused> {
        let at = |x: *const u8| x as isize - base as isize;
        r.map(|f| match f {
            Field::Number(x) => (0, at(core::ptr::from_mut(x).cast())),
            Field::Flag(x) => (1, at(core::ptr::from_mut(x).cast())),
            Field::Source(x) => (2, at(core::ptr::from_mut(x).cast())),
            Field::OnTimeout(x) => (4, at(core::ptr::from_mut(x).cast())),
            Field::Kind(k) => (3, isize::from(k)),
        })
    }

    #[test]
    fn field_follows_the_table() {
        let mut inductance = Actuator::PRODUCT;
        inductance.magnetics = Magnetics::Inductance {
            open_h: 1e-3,
            closed_h: 2e-3,
        };
        let mut untuned = Actuator::PRODUCT;
        untuned.tuning = None;
        let mut both = inductance;
        both.tuning = None;
        let names = all().map(|i| i.name).chain([
            "coil.colour",
            "",
            "tuning.bogus",
            "magnetics.geometry.bogus",
            "magnetics.inductance.bogus",
            "setpoint",
        ]);
        for name in names {
            for a in [Actuator::PRODUCT, inductance, untuned, both] {
                let (mut p, mut q) = (Params::new(a), Params::new(a));
                let (pb, qb) = (core::ptr::from_ref(&p), core::ptr::from_ref(&q));
                let got = seen(pb, p.field(name));
                let want = seen(qb, field_by_name(&mut q, name));
                assert_eq!(got, want, "{name}");
                assert_eq!(p, q, "{name}");
            }
        }
    }

    #[test]
    fn every_listed_parameter_reads_and_writes_back() {
        let p = Params::new(Actuator::PRODUCT);
        for info in all() {
            let v = p.get(info.name);
            let v = match v {
                Ok(v) => v,
                // The product's circuit is given by geometry.
                Err(Refused::Unused) => {
                    assert!(
                        info.name.starts_with("magnetics.inductance."),
                        "{}",
                        info.name
                    );
                    continue;
                }
                Err(e) => panic!("{}: {e:?}", info.name),
            };
            match (info.kind, v) {
                (Kind::Number, Value::Number(x)) => assert!(x.is_finite(), "{}", info.name),
                (Kind::Flag, Value::Flag(_)) | (Kind::Choice(_), Value::Choice(_)) => {}
                other => panic!("{}: {other:?}", info.name),
            }
            let mut q = p;
            match info.fixed {
                Some(why) => assert_eq!(q.set(info.name, v), Err(Refused::Fixed(why))),
                None => {
                    q.set(info.name, v).unwrap();
                    assert_eq!(q.get(info.name), Ok(v));
                }
            }
        }
    }

    #[test]
    fn refusals_name_what_is_wrong() {
        let mut p = Params::new(Actuator::PRODUCT);
        assert_eq!(p.get("coil.colour"), Err(Refused::Unknown));
        assert_eq!(
            p.set("board.rate_hz", Value::Number(10_000.0)),
            Err(Refused::Fixed(RATE_FIXED))
        );
        assert_eq!(
            p.set("coil.turns", Value::Flag(true)),
            Err(Refused::WrongKind)
        );
        assert_eq!(
            p.set("magnetics.inductance.open_h", Value::Number(1e-4)),
            Err(Refused::Unused)
        );
        assert!(matches!(
            p.set("setpoint.source", Value::Choice(3)),
            Err(Refused::Invalid(e)) if e.param == "setpoint.source"
        ));
        // A value that derives no controller: the build's own message.
        p.set("mechanics.mass_kg", Value::Number(-0.1)).unwrap();
        let e = p.build(&BOARD).unwrap_err();
        assert_eq!((e.param, e.value), ("mechanics.mass_kg", -0.1));
        // A stored set made for another rate.
        let mut q = Params::new(Actuator::PRODUCT.with_rate_hz(10_000.0));
        q.setpoint.filter_s = 0.0;
        assert_eq!(q.build(&BOARD).unwrap_err().param, "board.rate_hz");
        let mut q = Params::new(Actuator::PRODUCT);
        q.setpoint.filter_s = 2.0;
        assert_eq!(q.build(&BOARD).unwrap_err().param, "setpoint.filter_s");
        let mut q = Params::new(Actuator::PRODUCT);
        q.set("link.timeout_s", Value::Number(0.01)).unwrap();
        assert_eq!(q.build(&BOARD).unwrap_err().param, "link.timeout_s");
        assert!(matches!(
            q.set("link.on_timeout", Value::Choice(2)),
            Err(Refused::Invalid(e)) if e.param == "link.on_timeout"
        ));
    }

    #[test]
    fn the_defaults_build_as_the_firmware_builds_them() {
        let p = Params::new(Actuator::PRODUCT);
        let c = p.build(&BOARD).unwrap().control;
        let direct = Actuator::PRODUCT.settings().unwrap().build().unwrap();
        assert_eq!(c, direct);
        // Tuning written explicitly from an actuator without tuning gives the same gains.
        let mut a = Actuator::PRODUCT;
        a.tuning = None;
        let mut p = Params::new(a);
        let alpha = p.get("tuning.alpha_per_s").unwrap();
        p.set("tuning.alpha_per_s", alpha).unwrap();
        assert_eq!(
            p.build(&BOARD).unwrap().control,
            a.settings().unwrap().build().unwrap()
        );
    }
}
