//! The board's commissioning routine (`ema::device::commission`) against simulated
//! actuators: the core's identification ticking as the control interrupt runs it (convert,
//! identify, drive the board's bridge on the mock pins), the converter with its typical
//! noise, quantisation and delay, the plant's RK4 with its end stops. The routine starts
//! from the file; the plant is the file's, or one drawn wider than the file (see [`Specimen`]).
//!
//! What is judged against the plant's own values: the resistance, the inductance at both
//! stops (the plant's fringing included), the position readings at both stops (the drawn
//! sensor's gain and offset included), the largest true coil current, the actuator time.
//!
//! The spring, the mass and the friction are measured after the routine, the loop closed
//! ([`mechanics`]): the host tool holds the armature at four positions through the
//! board's link (`bench commission --mechanics`) and captures each move and each hold.
//! At the end of each hold, after its window, inductance probes ([`ema::control::Probe`],
//! [`hold_probe`]; on the board `Command::Probe`, each captured at every tick from its
//! first) step the loop's desired current up and down about the hold's: the armature
//! stays where the loop holds it (between the stops, where the magnet's stiffness
//! exceeds the spring's and no open-loop step could leave it), and the drive and the
//! current readings give the inductance there ([`probe_inductance`],
//! [`hold_inductance`]). With the stops', six inductances along the stroke: the
//! reluctance model, the iron's `rho_0`, the airgap's `rho_x` and how its surface grows
//! with the gap, is fitted to them ([`Circuit::fit`]). The magnet's pull read from the
//! captured current and that circuit gives the spring from the holds ([`fit_spring`])
//! and, with it, the mass and the friction from the moves ([`fit_armature`]): the same
//! fits on the bench and here. The file written carries the fitted circuit. A monitor
//! that ends the holds ends an attempt: they run again with a slower loop
//! ([`HOLD_ATTEMPTS`]), and the actuator time counts every attempt.
//!
//! The actuator file a commissioning writes ([`measured`]) carries, for the spring, the
//! mass and the friction, the tolerance their measurement leaves rather than the
//! datasheet's, narrower or wider: the converters' scale ([`CONVERTER_SCALE`]), each
//! fit's own 99 % interval ([`fitted_tolerance`]) and the uncertainty of the pull they
//! are read against (the circuit's); for the surfaces what the circuit's readings leave
//! (see [`measured`]). A value whose 99 % interval reaches zero is not written: the file
//! keeps its own. No class is set from the errors seen on drawn plants: the
//! `hil-sim commission` table judges each value written against the true one, over its
//! tolerance (its rows "written, error / its tolerance"). `tune` then validates
//! its gains on plants around what was measured, as far off as the measurement may be,
//! and the controller's robust model is built on the same (the test
//! `a_light_lightly_damped_product_is_tuned_with_the_tolerances_its_measurement_leaves`).

mod armature;
mod circuit;
mod holds;
mod measured;
mod probe;
mod run;
mod spring;

pub use armature::{fit_armature, Armature, SETTLED_SHARE, STOP_SHARE};
pub use circuit::{
    open_stop, open_stop_interval, stop_uncertainty, Circuit, GROWTH_MAX, GROWTH_SIGNIFICANCE,
    STOP_INDUCTANCE_CLASS,
};
pub use holds::{
    decimations, hold_tuning, mechanics, Holding, Holds, Mechanics, HOLD_ATTEMPTS,
    HOLD_WINDOW_SHARE, MOVE_CAPTURE_MOVES, REST_SHARE, RETRY_GAIN_SHARE,
};
pub use measured::{coverage_factor, fitted_tolerance, measured, CONVERTER_SCALE, IRON_SHARE};
pub use probe::{
    hold_inductance, hold_probe, probe_capture, probe_inductance, ChannelNoise, HoldInductance,
    ProbeSample, HOLD_PROBE_CYCLES, HOLD_PROBE_HALF_TICKS, HOLD_PROBE_RUNS, HOLD_PROBE_SHARE,
};
pub use run::{
    closed_loop, curve_error, largest_spread, run, run_on, stops_correction, true_plant,
    ClosedLoop, Errors, Factors, Outcome, Specimen, CLOSED_LOOP_VALIDATION, CURVE_POSITIONS,
};
use spring::{corrected, pull};
pub use spring::{fit_spring, Spring};
