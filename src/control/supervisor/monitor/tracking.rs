//! Tracking error too large for too long.

use super::{Config, Inputs, State};
use crate::control::supervisor::Fault;

/// Tracking error too large for too long.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct Tracking {
    /// Largest tolerated `|x - r|` \[m\].
    pub error_m: f32,
    /// How long it may be exceeded \[s\].
    pub time_s: f32,
}

impl Config {
    pub(super) fn tracking(&self, st: &mut State, inp: &Inputs) -> Option<Fault> {
        let t = self.monitors.tracking.as_ref()?;
        if (inp.x_m - inp.r_m).abs() > t.error_m {
            st.off_track = st.off_track.saturating_add(1);
        } else {
            st.off_track = 0;
        }
        (st.off_track >= self.tracking_ticks).then_some(Fault::Tracking)
    }
}
