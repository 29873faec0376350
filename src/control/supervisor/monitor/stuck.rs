//! Stuck position sensor (see [`Stuck`]).

use super::{Config, Inputs, State};
use crate::control::supervisor::Fault;

/// How much farther the reference may travel than the reading while the reading crosses
/// its last two bands, for the reading to count as moving with it \[-\] (see [`Stuck`]).
pub const MOVING_RATIO: f32 = 1.5;

/// Stuck position sensor: the reading stops within its noise band mid-move while the
/// reference runs on.
///
/// A frozen sensor output still reaches the tick through the converter, with the
/// converter's noise: the evidence is a reading that stays within `band_codes` of where
/// it last left its band (an anchor, renewed at every exit) while the armature, by the
/// observer's velocity estimate (which runs on the coil current and the force model as
/// much as on the reading), has travelled `reference_m` the way the reading was going.
/// A healthy reading leaves the band before: `reference_m` is the band plus the
/// converter's worst noise excursions of the anchor and of the newest reading. (Counting
/// the reading's own crossing times instead, "in one band longer than the last crossings
/// took", names a healthy armature that slows down while its noise stretches one
/// crossing and shortens the one before.)
///
/// Four conditions keep healthy motion out:
///
/// * **the reading was moving with the reference**: it left its last two bands the same
///   way, and while it crossed the last one the reference travelled at most
///   [`MOVING_RATIO`] times as far as the reading. An armature at rest that a move sets
///   off lags its reference by the time the coil needs to build the current that
///   overcomes the spring and its preload (milliseconds on a valve): during that lag the
///   reference runs away from a static reading, and its first band crossings are slow
///   beside the reference: it is healthy, and not yet moving;
/// * **the reading crossed its last two bands within the deadline**
///   ([`crate::control::supervisor::DEADLINE_S`], in interrupt periods), at least two bands
///   per deadline: a slower reading could not be named within the deadline anyway, and a
///   creep that slow (an armature that the start-up left ahead of a slow reference, at a
///   fraction of a code per period) crosses its bands as much by the converter's noise as
///   by its motion, which can make it look as if it moved with the reference;
/// * **the reference runs on the same way**, by `reference_m` since the anchor: a reading
///   that waits while the reference comes back toward it is healthy;
/// * **the reading is short of the target** (the set point the move goes to) by more
///   than `reference_m`: a healthy armature that leads its reference stops at the target
///   and waits there for the reference to arrive; it does not stop halfway.
///
/// A sensor that freezes mid-move, with the armature at speed `v`, is found once the
/// estimate and the reference have both run `reference_m` past the last exit: about
/// `reference_m / v`, under the deadline whenever the reading moved at least two bands
/// per deadline (`reference_m` is `1 + sqrt 2` bands). One that
/// freezes at rest, or within `reference_m` of the target, looks exactly like an armature
/// that is where it should be, and is left to the tracking detector.
///
/// "No change while the current changes" is not usable as evidence: in closed loop the
/// controller changes the current precisely to hold the position against a changing
/// disturbance, and over a millisecond the armature's mass turns even an ampere of change
/// into much less than one converter step of motion.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(all(target_os = "none", feature = "defmt"), derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct Stuck {
    /// Half-width of the band, in steps of the position converter \[code\].
    pub band_codes: f32,
    /// Reference travel since the anchor that must have moved the reading \[m\].
    pub reference_m: f32,
}

impl Config {
    pub(super) fn stuck(&self, st: &mut State, inp: &Inputs) -> Option<Fault> {
        let s = self.monitors.stuck.as_ref()?;
        let step = inp.x_m - st.x_last;
        st.x_ticks = st.x_ticks.saturating_add(1);
        if step.abs() > self.band_m {
            let dir: i8 = if step > 0.0 { 1 } else { -1 };
            let d = f32::from(dir);
            // Over the reading's last two crossings, both the same way: how far the
            // reading and the reference went.
            let (x_run, r_run) = ((inp.x_m - st.x_prev) * d, (inp.r_m - st.r_prev) * d);
            st.x_moving = dir == st.x_dir
                && r_run > 0.0
                && r_run <= MOVING_RATIO * x_run
                && st.x_ticks.saturating_add(st.x_prev_ticks) <= self.moving_ticks;
            st.x_prev_ticks = st.x_ticks;
            st.x_ticks = 0;
            st.x_travel = 0.0;
            st.x_dir = dir;
            st.x_prev = st.x_last;
            st.r_prev = st.r_at_change;
            st.x_last = inp.x_m;
            st.r_at_change = inp.r_m;
            return None;
        }
        let dir = f32::from(st.x_dir);
        // Stopped: still in one band while the velocity estimate has travelled the
        // reference travel since the exit, and the reference ran on; short of the target.
        st.x_travel += inp.v_mps * dir * self.ts_s;
        let stopped = st.x_travel >= s.reference_m;
        let ran_on = (inp.r_m - st.r_at_change) * dir >= s.reference_m;
        let short = (inp.target_m - st.x_last) * dir > s.reference_m;
        (st.x_moving && stopped && ran_on && short).then_some(Fault::PositionStuck)
    }
}
