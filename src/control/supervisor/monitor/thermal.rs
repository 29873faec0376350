//! I^2 t protection of the coil.

use super::{Config, Inputs, State};
use crate::control::math;
use crate::control::supervisor::Fault;

/// I^2 t protection of the coil.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct Thermal {
    /// Continuous current rating \[A\].
    pub continuous_a: f32,
    /// Allowance above the continuous rating, `integral of (i^2 - I_c^2) dt` \[A^2 s\].
    pub allowance_a2s: f32,
}

impl Config {
    pub(super) fn thermal(&self, st: &mut State, inp: &Inputs) -> Option<Fault> {
        let t = self.monitors.thermal.as_ref()?;
        let excess = inp.i_a * inp.i_a - t.continuous_a * t.continuous_a;
        st.i2t_a2s = math::max(st.i2t_a2s + excess * self.ts_s, 0.0);
        (st.i2t_a2s > t.allowance_a2s).then_some(Fault::OverCurrentI2t)
    }
}
