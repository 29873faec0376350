//! What a commissioning gives: the [`Report`] of its measurements, or the [`Abort`] that
//! stopped it.

use serde::{Deserialize, Serialize};

/// Why an identification stopped without a result.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Abort {
    /// The current exceeded the rating (the coil is far below its file's resistance, or
    /// shorted).
    OverRated,
    /// The two steps gave the same current: no coil, or an open one.
    NoResponse,
    /// The armature never came to rest (see [`PATIENCE_PERIODS`](super::PATIENCE_PERIODS)).
    NotAtRest,
    /// The armature moved between the two holds at the closed stop: its spring held it
    /// short of the stop, which the rated current cannot reach.
    NoStop,
    /// The reading fell from the open stop to the closed one: the sensor reads backwards.
    Backwards,
    /// Less than [`MIN_TRAVEL_SHARE`](super::MIN_TRAVEL_SHARE) of the stroke between the
    /// stops: the armature is stuck, or no spring brings it back.
    NoTravel,
    /// A current step did not decay geometrically: the armature moved, or something
    /// other than a coil answers.
    NoDecay,
    /// The probe's pull took the armature more than half its stroke off the open stop:
    /// the open stop's inductance cannot be extrapolated from there.
    PulledIn,
    /// A fault latched during the identification.
    Fault,
    /// Ended by an order (disarm, or another command).
    Stopped,
}

impl Abort {
    /// Lower-case name.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Abort::OverRated => "current_above_rating",
            Abort::NoResponse => "no_response",
            Abort::NotAtRest => "not_at_rest",
            Abort::NoStop => "closed_stop_not_reached",
            Abort::Backwards => "position_backwards",
            Abort::NoTravel => "no_travel",
            Abort::NoDecay => "step_response_not_a_coil",
            Abort::PulledIn => "probe_pulled_the_armature_in",
            Abort::Fault => "fault",
            Abort::Stopped => "stopped",
        }
    }
}

/// The coil's resistance as measured.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Resistance {
    /// Resistance \[ohm\].
    pub ohm: f32,
    /// Two standard errors of it from the converter's noise \[ohm\].
    pub uncertainty_ohm: f32,
    /// Mean currents of the two steps \[A\].
    pub i_a: [f32; 2],
    /// Mean applied voltages of the two steps \[V\].
    pub u_v: [f32; 2],
    /// Mean bus voltage over both steps \[V\].
    pub vbus_v: f32,
}

/// The position readings at the two end stops, in the file's calibration.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Ends {
    /// Mean reading at the open stop, the coil off \[m\].
    pub open_m: f32,
    /// Mean reading at the closed stop, at [`FULL_SHARE`](super::FULL_SHARE) of the rated
    /// current \[m\].
    pub closed_m: f32,
    /// Two standard errors of the noisier of the two means \[m\].
    pub uncertainty_m: f32,
}

/// The coil's inductance at the two end stops.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Inductance {
    /// At the open stop (the largest gap) \[H\].
    pub open_h: f32,
    /// At the closed stop (the residual gap) \[H\].
    pub closed_h: f32,
}

/// Everything a commissioning measured.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Report {
    /// The coil's resistance.
    pub resistance: Resistance,
    /// The position sensor's readings at the end stops.
    pub ends: Ends,
    /// The coil's inductance at the end stops.
    pub inductance: Inductance,
}
