//! What a run records ([`crate::simulation::sim`]), below what judges it
//! ([`crate::simulation::metrics`]): one sample per ISR period, the end-stop impacts, and
//! the serde names of a bridge mode and a fault. Re-exported by [`crate::simulation::sim`],
//! where they are documented.

use ema::control::bridge::Mode;
use ema::control::supervisor::Fault;
use serde::{Deserialize, Serialize};

use crate::simulation::plant::Impact;

/// One ISR period: the state at the sample instant `t_s`, what the tick did, and what the
/// coil saw over the period that follows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Sample {
    /// Sample instant \[s\].
    pub t_s: f64,
    /// Reference handed to the tick \[m\].
    pub r_m: f64,
    /// True position \[m\].
    pub x_m: f64,
    /// True velocity \[m/s\].
    pub v_mps: f64,
    /// True coil current \[A\].
    pub i_a: f64,
    /// Flux linkage \[Wb\] (`L(g) i` for the frozen model).
    pub psi_wb: f64,
    /// True bus voltage at the sample instant \[V\].
    pub vbus_v: f64,
    /// Position as the tick measured it (converter code or ideal value, 0 when the
    /// frame was implausible) \[m\].
    pub x_meas_m: f64,
    /// Coil current as the tick measured it \[A\].
    pub i_meas_a: f64,
    /// Average coil voltage the bridge was set to \[V\] (0 in coast).
    pub u_drive_v: f64,
    /// Bus voltage as the tick measured it \[V\].
    pub vbus_meas_v: f64,
    /// Observer position estimate \[m\].
    pub x_est_m: f64,
    /// Observer velocity estimate \[m/s\].
    pub v_est_mps: f64,
    /// Observer's disturbance estimate (what the model does not explain) \[m/s^2\].
    pub d_est_mps2: f64,
    /// The shaped reference the law followed at this tick \[m\].
    pub r_shaped_m: f64,
    /// Law voltage command before saturation \[V\].
    pub u_cmd_v: f64,
    /// Law desired current \[A\].
    pub i_d_a: f64,
    /// PWM compare value written.
    pub duty: u16,
    /// Bridge mode after the tick.
    #[serde(with = "mode_name")]
    pub mode: Mode,
    /// Latched fault after the tick.
    #[serde(with = "fault_name")]
    pub fault: Option<Fault>,
    /// Mean coil voltage over the period \[V\].
    pub u_mean_v: f64,
    /// RMS coil voltage over the period \[V\].
    pub u_rms_v: f64,
    /// Largest `|u|` over the period (at the substep boundaries) \[V\].
    pub u_abs_max_v: f64,
    /// Largest `|i|` over the period (at the substep boundaries) \[A\].
    pub i_abs_max_a: f64,
    /// Energy drawn from the supply's source over the period (negative when the coil
    /// returns energy) \[J\].
    pub energy_j: f64,
}

/// An end-stop impact during a run.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ImpactAt {
    /// End of the substep in which it happened \[s\].
    pub t_s: f64,
    /// The impact.
    pub impact: Impact,
}

/// Serialises a bridge mode as `coast`, `forward` or `reverse`.
pub mod mode_name {
    use ema::control::bridge::Mode;
    use serde::{Deserialize, Deserializer, Serializer};

    /// Serde serialiser.
    ///
    /// # Errors
    /// The serializer's.
    pub fn serialize<S: Serializer>(mode: &Mode, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(mode.name())
    }

    /// Serde deserialiser.
    ///
    /// # Errors
    /// An unknown name.
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Mode, D::Error> {
        let s = String::deserialize(d)?;
        Mode::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| serde::de::Error::custom(format!("unknown bridge mode `{s}`")))
    }
}

/// Serialises an optional fault as its name (`over_current`), or an empty string.
pub mod fault_name {
    use ema::control::supervisor::Fault;
    use serde::{Deserialize, Deserializer, Serializer};

    /// Serde serialiser.
    ///
    /// # Errors
    /// The serializer's.
    pub fn serialize<S: Serializer>(fault: &Option<Fault>, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(fault.map_or("", Fault::name))
    }

    /// Serde deserialiser.
    ///
    /// # Errors
    /// An unknown name.
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Fault>, D::Error> {
        let s = String::deserialize(d)?;
        if s.is_empty() {
            return Ok(None);
        }
        Fault::ALL
            .into_iter()
            .find(|f| f.name() == s)
            .map(Some)
            .ok_or_else(|| serde::de::Error::custom(format!("unknown fault `{s}`")))
    }
}
