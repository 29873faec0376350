//! Control laws: one small interface ([`Law`]), several implementations selected by
//! configuration ([`Config`]), all driven by the same tick.
//!
//! A law maps the estimated state and the reference to a coil voltage command. It never
//! saturates to the supply itself (the supervisor and the bridge do), never fails and never
//! panics; a non-finite output is caught by the supervisor and becomes a fault.

pub mod boundary;
pub mod paper;
pub mod practical;

/// Reference trajectory at the current tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct Reference {
    /// Position `y_r` \[m\].
    pub x_m: f32,
    /// Velocity `y_r'` \[m/s\].
    pub v_mps: f32,
    /// Acceleration `y_r''` \[m/s^2\].
    pub a_mps2: f32,
}

impl Reference {
    /// A constant set point (zero velocity and acceleration).
    #[must_use]
    pub const fn hold(x_m: f32) -> Self {
        Self {
            x_m,
            v_mps: 0.0,
            a_mps2: 0.0,
        }
    }
}

/// What a law sees at one tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct Input {
    /// Position `x1` (estimate) \[m\].
    pub x_m: f32,
    /// Velocity `x2` (estimate) \[m/s\].
    pub v_mps: f32,
    /// Coil current `x3` (measured) \[A\].
    pub i_a: f32,
    /// Bus voltage (measured) \[V\].
    pub vbus_v: f32,
    /// Estimated acceleration disturbance (what the nominal model does not explain)
    /// \[m/s^2\]; 0 when the observer does not estimate one.
    pub disturbance_mps2: f32,
    /// Reference.
    pub reference: Reference,
    /// Average coil voltage the bridge applied over the previous period \[V\] (for the
    /// prediction across the measurement delay).
    pub u_prev_v: f32,
    /// Added to the desired current by the inductance probe ([`crate::control::Probe`])
    /// \[A\]; the practical law follows it, the others ignore it.
    pub probe_a: f32,
}

/// What a law asks for at one tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub struct Output {
    /// Coil voltage command `u` \[V\] (before saturation to the supply).
    pub u_v: f32,
    /// Desired current `x3d` \[A\].
    pub i_d_a: f32,
    /// Sliding variable `S = x3 - x3d` \[A\].
    pub s_a: f32,
}

/// A control law: an immutable, validated configuration that steps its own small state.
pub trait Law {
    /// The law's mutable state.
    type State: Copy + Default;

    /// One control step. Infallible and panic-free.
    fn step(&self, state: &mut Self::State, input: &Input) -> Output;
}

/// Every law, by the name configuration files give it ([`Settings::name`]), in the order
/// the law comparison, the golden traces and the per-law counts list them.
pub const NAMES: [&str; 3] = ["paper", "boundary_layer", "practical"];

/// The law and its gains, before validation.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(
    feature = "serde",
    serde(tag = "law", rename_all = "snake_case", deny_unknown_fields)
)]
pub enum Settings {
    /// The paper's law ([`paper`]).
    #[cfg(feature = "paper")]
    Paper(paper::Gains),
    /// The paper's law with a boundary layer derived from the discrete stability condition
    /// ([`boundary`]).
    #[cfg(feature = "paper")]
    BoundaryLayer(paper::Gains),
    /// The practical law ([`practical`]): discrete-time, the product's.
    Practical(practical::Gains),
}

impl Settings {
    /// Validates the gains against `plant` and builds the law for the sample period `ts_s`
    /// and a measurement delay of `delay_ticks` samples.
    ///
    /// # Errors
    /// The first invalid parameter, by name.
    pub fn build(
        &self,
        plant: &crate::control::model::Plant,
        ts_s: f32,
        delay_ticks: u8,
    ) -> Result<Config, crate::control::config::Error> {
        Ok(match self {
            #[cfg(feature = "paper")]
            Settings::Paper(gains) => Config::Paper(gains.build(plant, ts_s)?),
            #[cfg(feature = "paper")]
            Settings::BoundaryLayer(gains) => {
                Config::BoundaryLayer(boundary::Config::build(gains, plant, ts_s, delay_ticks)?)
            }
            Settings::Practical(gains) => {
                Config::Practical(gains.build(plant, ts_s, delay_ticks)?)
            }
        })
    }

    /// Short name of the law, as in configuration files.
    #[must_use]
    pub const fn name(&self) -> &'static str {
        match self {
            #[cfg(feature = "paper")]
            Settings::Paper(_) => NAMES[0],
            #[cfg(feature = "paper")]
            Settings::BoundaryLayer(_) => NAMES[1],
            Settings::Practical(_) => NAMES[2],
        }
    }
}

/// The law selected by configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub enum Config {
    /// The paper's law exactly as published ([`paper`]).
    #[cfg(feature = "paper")]
    Paper(paper::Config),
    /// The paper's law with a boundary layer ([`boundary`]).
    #[cfg(feature = "paper")]
    BoundaryLayer(boundary::Config),
    /// The practical law ([`practical`]): discrete-time, the product's.
    Practical(practical::Config),
}

/// State of the selected law.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
pub enum State {
    /// State of `Config::Paper` and `Config::BoundaryLayer`.
    #[cfg(feature = "paper")]
    Paper(paper::State),
    /// State of [`Config::Practical`].
    Practical(practical::State),
}

impl Config {
    /// The initial state that goes with this law.
    #[must_use]
    pub fn initial_state(&self) -> State {
        match self {
            #[cfg(feature = "paper")]
            Config::Paper(_) | Config::BoundaryLayer(_) => State::Paper(paper::State::default()),
            Config::Practical(_) => State::Practical(practical::State::default()),
        }
    }

    /// Short name of the law, as in configuration files.
    #[must_use]
    pub const fn name(&self) -> &'static str {
        match self {
            #[cfg(feature = "paper")]
            Config::Paper(_) => NAMES[0],
            #[cfg(feature = "paper")]
            Config::BoundaryLayer(_) => NAMES[1],
            Config::Practical(_) => NAMES[2],
        }
    }
}

impl Default for State {
    #[cfg(feature = "paper")]
    fn default() -> Self {
        State::Paper(paper::State::default())
    }

    #[cfg(not(feature = "paper"))]
    fn default() -> Self {
        State::Practical(practical::State::default())
    }
}

impl Law for Config {
    type State = State;

    #[inline]
    fn step(&self, state: &mut State, input: &Input) -> Output {
        match (self, &mut *state) {
            #[cfg(feature = "paper")]
            (Config::Paper(law), State::Paper(s)) => law.step(s, input),
            #[cfg(feature = "paper")]
            (Config::BoundaryLayer(law), State::Paper(s)) => law.step(s, input),
            (Config::Practical(law), State::Practical(s)) => law.step(s, input),
            // Without the paper's laws the practical law's state is the only one.
            #[cfg(feature = "paper")]
            _ => {
                // A state of another law: start this law from its initial state. The
                // second call matches one of the arms above.
                *state = self.initial_state();
                match (self, state) {
                    #[cfg(feature = "paper")]
                    (Config::Paper(law), State::Paper(s)) => law.step(s, input),
                    #[cfg(feature = "paper")]
                    (Config::BoundaryLayer(law), State::Paper(s)) => law.step(s, input),
                    (Config::Practical(law), State::Practical(s)) => law.step(s, input),
                    _ => Output::default(),
                }
            }
        }
    }
}
