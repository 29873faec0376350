//! The detectors on scripted readings.

use super::*;

const TS: f32 = 1.0 / 20_000.0;

fn cfg(delay: u8) -> Config {
    crate::control::actuator::Actuator::PRODUCT
        .settings()
        .unwrap()
        .monitors
        .build(&Plant::paper(), &Calibration::board(), TS, delay)
        .unwrap()
}

/// Nominal Tustin step of the paper's coil at gap g.
fn coil_step(g: f32, u: f32, i: f32, r: f32, l_scale: f32) -> f32 {
    let l = crate::control::model::Magnetics::paper().inductance_h(g) * l_scale;
    let k = TS / l;
    i + k * (u - r * i) / (1.0 + 0.5 * r * k)
}

fn run(c: &Config, r_ohm: f32, l_scale: f32, sensor: impl Fn(f32) -> f32) -> Option<Fault> {
    let mut st = State::default();
    let mut i = 2.0_f32;
    let g = 3e-3;
    for k in 0..200 {
        // A square wave of +-6 V around the holding voltage.
        let u = if (k / 20) % 2 == 0 { 6.0 } else { -4.0 };
        let inp = Inputs {
            x_m: g + if k % 2 == 0 { 1e-6 } else { 0.0 },
            i_a: sensor(i),
            r_m: g,
            target_m: 3e-3,
            v_mps: 0.0,
        };
        if let Some(f) = c.check(&mut st, &inp) {
            return Some(f);
        }
        c.record_drive(&mut st, u, true);
        i = coil_step(g, u, i, r_ohm, l_scale);
    }
    None
}

#[test]
fn an_admissible_coil_raises_nothing() {
    let c = cfg(0);
    for (r, l) in [
        (0.4, 1.0),
        (0.32, 0.84),
        (0.48, 1.24),
        (0.32, 1.24),
        (0.48, 0.84),
    ] {
        assert_eq!(run(&c, r, l, |i| i), None, "R {r} L x{l}");
    }
}

#[test]
fn broken_coils_and_sensors_are_named() {
    let c = cfg(0);
    assert_eq!(run(&c, 0.4, 1.0, |_| 2.0), Some(Fault::CurrentStuck));
    assert_eq!(run(&c, 0.4, 1.0, |_| 0.0), Some(Fault::CoilOpen));
    // A coil 70 % more inductive than nominal (the bounds allow 25 %).
    assert_eq!(run(&c, 0.4, 1.7, |i| i), Some(Fault::ModelBounds));
}

/// A reading that lags every admissible coil under a steady drive, in either direction
/// of the drive: frozen, it is a stuck sensor; still moving at more than half the
/// slowest coil's pace, it is a plant outside the bounds. The verdict compares the
/// reading's change with the bank's least admissible change on the side it moves to.
#[test]
fn a_lagging_reading_is_stuck_or_out_of_bounds_in_both_directions() {
    let c = cfg(0);
    let g = 3e-3;
    for (u, i_start) in [(6.0_f32, 2.0_f32), (-6.0, 8.0)] {
        for (pace, expect) in [(0.0, Fault::CurrentStuck), (0.6, Fault::ModelBounds)] {
            let mut st = State::default();
            let mut i = i_start;
            let mut found = None;
            for k in 0..20 {
                let inp = Inputs {
                    x_m: g + (k % 2) as f32 * 1e-6,
                    // The nominal coil's change since the start, scaled by `pace`.
                    i_a: i_start + pace * (i - i_start),
                    r_m: g,
                    target_m: 3e-3,
                    v_mps: 0.0,
                };
                if let Some(f) = c.check(&mut st, &inp) {
                    found = Some((f, k));
                    break;
                }
                c.record_drive(&mut st, u, true);
                i = coil_step(g, u, i, 0.4, 1.0);
            }
            let (f, k) = found.unwrap_or_else(|| panic!("u {u} pace {pace}: nothing"));
            assert_eq!(f, expect, "u {u} pace {pace}");
            assert!(k <= 6, "u {u} pace {pace}: after {k} ticks");
        }
    }
}

/// A shorted coil: the resistance drops to 0.05 ohm while the controller holds
/// 6 A at 3 mm with the voltage a healthy coil needs (2.4 V).
#[test]
fn a_shorted_coil_is_caught_while_holding() {
    let c = cfg(0);
    let mut st = State::default();
    let mut i = 6.0_f32;
    let mut found = None;
    for k in 0..50 {
        let inp = Inputs {
            x_m: 3e-3 + (k % 2) as f32 * 1e-6,
            i_a: i,
            r_m: 3e-3,
            target_m: 3e-3,
            v_mps: 0.0,
        };
        if let Some(f) = c.check(&mut st, &inp) {
            found = Some((f, k));
            break;
        }
        c.record_drive(&mut st, 2.4, true);
        i = coil_step(3e-3, 2.4, i, 0.05, 1.0);
    }
    let (f, k) = found.unwrap();
    assert_eq!(f, Fault::CoilShort);
    assert!(k <= 6, "{k}");
}

#[test]
fn an_offset_step_is_caught_in_one_tick() {
    let c = cfg(0);
    let mut st = State::default();
    let inp = |i_a| Inputs {
        x_m: 3e-3,
        i_a,
        r_m: 3e-3,
        target_m: 3e-3,
        v_mps: 0.0,
    };
    // Holding 6 A at 2.4 V; the reading steps by +2.5 A and stays offset.
    assert_eq!(c.check(&mut st, &inp(6.0)), None);
    c.record_drive(&mut st, 2.4, true);
    assert_eq!(c.check(&mut st, &inp(6.0)), None);
    c.record_drive(&mut st, 2.4, true);
    assert_eq!(c.check(&mut st, &inp(8.5)), None);
    c.record_drive(&mut st, 2.4, true);
    assert_eq!(c.check(&mut st, &inp(8.5)), Some(Fault::CurrentOffset));
}

#[test]
fn a_frozen_position_during_a_move_is_stuck() {
    let c = cfg(0);
    let mut st = State::default();
    let mut found = None;
    let reference = |k: i32| 2e-3 + k as f32 * 2e-6; // moving at 4 cm/s
    for k in 0..60 {
        // Following the reference for 20 ticks, then frozen at 40 um with +-2 codes of
        // converter noise.
        let x_m = if k < 20 {
            reference(k)
        } else {
            reference(20) + ((k * 7) % 5) as f32 * 1.085e-6 - 2.17e-6
        };
        let inp = Inputs {
            x_m,
            i_a: 5.0,
            r_m: reference(k),
            target_m: 3e-3,
            v_mps: 0.04,
        };
        if let Some(f) = c.check(&mut st, &inp) {
            found = Some((f, k));
            break;
        }
        c.record_drive(&mut st, 2.0, false);
    }
    // The 12th tick after the last exit: the velocity estimate (2 um per tick) has then
    // travelled the 22.2 um of reference travel (1 + sqrt 2 bands of 9.2 um), and so
    // has the reference. The last exit is one of the first frozen readings (the last
    // step, 10 um, plus noise): at most 2 ticks after the freeze.
    let (fault, k) = found.unwrap();
    assert_eq!(fault, Fault::PositionStuck);
    assert!((20 + 12..=20 + 12 + 2).contains(&k), "{k}");

    // The same frozen reading from rest (an armature that a move sets off lags while
    // the coil builds its current): healthy, no fault; also when the converter's noise
    // takes two readings out of each other's band, one up, then one down.
    let mut st = State::default();
    for k in 0..60 {
        let noise_codes = match k {
            3 => 4.5,
            5 => -4.5,
            _ => ((k * 7) % 5) as f32 - 2.0,
        };
        let inp = Inputs {
            x_m: 2e-3 + noise_codes * 1.085e-6,
            i_a: 5.0,
            r_m: reference(k),
            target_m: 3e-3,
            v_mps: 0.0,
        };
        assert_eq!(c.check(&mut st, &inp), None, "tick {k}");
        c.record_drive(&mut st, 2.0, false);
    }
    // At rest nothing is expected to move: no fault.
    let mut st = State::default();
    for _ in 0..1000 {
        let inp = Inputs {
            x_m: 2e-3,
            i_a: 5.0,
            r_m: 2e-3,
            target_m: 3e-3,
            v_mps: 0.0,
        };
        assert_eq!(c.check(&mut st, &inp), None);
        c.record_drive(&mut st, 2.0, false);
    }
}

#[test]
fn i2t_allows_the_rating_and_trips_the_peak_after_its_time() {
    let c = cfg(0);
    let thermal = c.monitors.thermal.unwrap();
    // The product's coil: rated 12 A, 13.2 A for 0.1 s.
    assert_eq!(thermal.continuous_a, 12.0);
    let mut st = State::default();
    let at = |i_a| Inputs {
        x_m: 2e-3,
        i_a,
        r_m: 2e-3,
        target_m: 3e-3,
        v_mps: 0.0,
    };
    // At the peak current the allowance (13.2^2 - 12^2) 0.1 s lasts 0.1 s: 2000 ticks.
    let mut tripped = None;
    for k in 0..4000 {
        if let Some(f) = c.check(&mut st, &at(13.2)) {
            tripped = Some((f, k));
            break;
        }
    }
    let (f, k) = tripped.unwrap();
    assert_eq!(f, Fault::OverCurrentI2t);
    assert!((1995..=2005).contains(&k), "{k}");
    // At the rating it never trips; below it, it cools down to zero.
    let mut st = State::default();
    for _ in 0..100 {
        c.check(&mut st, &at(13.0));
    }
    assert!(st.i2t_a2s > 0.0);
    for _ in 0..100_000 {
        assert_eq!(c.check(&mut st, &at(12.0)), None);
    }
    for _ in 0..100_000 {
        assert_eq!(c.check(&mut st, &at(11.0)), None);
    }
    assert_eq!(st.i2t_a2s, 0.0);
}

#[test]
fn tracking_error_must_last() {
    let c = cfg(0);
    let mut st = State::default();
    let off = Inputs {
        x_m: 1e-3,
        i_a: 1.0,
        r_m: 3e-3,
        target_m: 3e-3,
        v_mps: 0.0,
    };
    c.check(&mut st, &off);
    let mut n = 0;
    while c
        .check(
            &mut st,
            &Inputs {
                x_m: 1e-3 + (n % 2) as f32 * 1e-6,
                ..off
            },
        )
        .is_none()
    {
        n += 1;
        assert!(n < 5000);
    }
    // 50 ms at 20 kHz.
    assert_eq!(n + 1, 1000);
}

#[test]
fn bad_monitor_settings_are_named() {
    let mut m = crate::control::actuator::Actuator::PRODUCT
        .settings()
        .unwrap()
        .monitors;
    m.residual.as_mut().unwrap().gross = 0.5;
    let e = m
        .build(&Plant::paper(), &Calibration::board(), TS, 0)
        .unwrap_err();
    assert_eq!(e.param, "monitors.residual.gross");
    let mut m = crate::control::actuator::Actuator::PRODUCT
        .settings()
        .unwrap()
        .monitors;
    // Shorter than one period: refused in the file's unit, seconds.
    m.tracking.as_mut().unwrap().time_s = 1e-5;
    let e = m
        .build(&Plant::paper(), &Calibration::board(), TS, 0)
        .unwrap_err();
    assert_eq!(e.param, "monitors.tracking.time_s");
    assert_eq!(e.value, 1e-5);
    assert_eq!(e.reason, config::Reason::BelowMin { min: TS });
}

/// The detectors' inputs for an armature held at gap `g` (its reading toggling by 1 um
/// with tick `k`, the reference and the target there) and the current reading `i_a`.
fn held(g: f32, k: u32, i_a: f32) -> Inputs {
    Inputs {
        x_m: g + (k % 2) as f32 * 1e-6,
        i_a,
        r_m: g,
        target_m: g,
        v_mps: 0.0,
    }
}

/// Holds `i0` at gap `g` on the voltage a nominal coil needs, the true coil stepping
/// as `coil` (resistance, from tick `at`), the reading the true current plus `offset`
/// from tick `at`; the fault found and the tick, from `at`.
fn hold_then(
    g: f32,
    i0: f32,
    at: u32,
    resistance_after: f32,
    offset_after: f32,
) -> Option<(Fault, u32)> {
    let c = cfg(0);
    let mut st = State::default();
    let u = 0.4 * i0;
    let mut i = i0;
    for k in 0..at + 40 {
        let after = k >= at;
        let inp = held(g, k, i + if after { offset_after } else { 0.0 });
        if let Some(f) = c.check(&mut st, &inp) {
            return Some((f, k.saturating_sub(at)));
        }
        c.record_drive(&mut st, u, true);
        let r = if k + 1 >= at { resistance_after } else { 0.4 };
        i = coil_step(g, u, i, r, 1.0);
    }
    None
}

/// At 4 mm the paper's coil has a time constant of two periods, so a reading that
/// stepped shifts the next admissible step by half the step: the one-step check takes
/// the coil's current as the reading less the step, and names the offset one tick
/// after it, wherever in the bank's window it falls.
#[test]
fn an_offset_on_a_fast_coil_is_named_from_the_current_under_it() {
    for at in [3, 7, 12] {
        assert_eq!(
            hold_then(4e-3, 4.0, at, 0.4, 2.0),
            Some((Fault::CurrentOffset, 1)),
            "step at tick {at}"
        );
    }
}

/// A short late in the bank's window is named a short: the fit covers the excursion
/// only, not the healthy steps before it (over the whole window it read a resistance
/// within the bounds). Holding 8 A on the fast coil, the reading jumps twice and the
/// short is named on the second jump, a tick before the bank's confirmation; on a
/// slower coil the bank confirms it.
#[test]
fn a_short_late_in_the_window_is_named_a_short() {
    for at in [3, 7, 12] {
        assert_eq!(
            hold_then(4e-3, 8.0, at, 0.05, 0.0),
            Some((Fault::CoilShort, 1)),
            "fast coil, short at tick {at}"
        );
        let found = hold_then(1e-3, 6.0, at, 0.05, 0.0);
        assert!(
            matches!(found, Some((Fault::CoilShort, k)) if k <= 4),
            "slower coil, short at tick {at}: {found:?}"
        );
    }
}

/// Holds the paper's coil (true resistance `r_true`) at `i0` for `learn` ticks on the
/// voltage that holds it, the reading the true current with a code of noise either way;
/// then raises the voltage by 1 % of the holding voltage every 10 ticks for 400 ticks
/// (to 1.4 times it), the reading frozen from then on if `freeze` (a law winding up
/// against a reading that no longer follows). The fault found and the tick, from the
/// end of the hold.
fn ramp_after_hold(
    c: &Config,
    r_true: f32,
    i0: f32,
    learn: u32,
    freeze: bool,
) -> Option<(Fault, u32)> {
    let g = 2e-3;
    let mut st = State::default();
    let hold = r_true * i0;
    let mut i = i0;
    let code = Calibration::board().current.scale.abs();
    for k in 0..learn + 400 {
        let ramp = k >= learn;
        let frozen = ramp && freeze;
        let u = if ramp {
            hold * (1.0 + 0.001 * (k - learn) as f32)
        } else {
            hold
        };
        let reading = if frozen {
            i0
        } else {
            i + if k % 2 == 0 { code } else { -code }
        };
        let inp = held(g, k, reading);
        if let Some(f) = c.check(&mut st, &inp) {
            return Some((f, k.saturating_sub(learn)));
        }
        c.record_drive(&mut st, u, true);
        i = coil_step(g, u, i, r_true, 1.0);
    }
    None
}

/// A coil 8 % above its nominal resistance, held at 4 A: the resistance bounds (+-20 %)
/// let the frozen reading pass until the law's voltage is 11 % above what holds the coil
/// and the noise allowance is crossed (254 ticks); the resistance learned over the hold
/// narrows them to +-2 % and the channel's offset (+-0.4 % at 4 A), and the reading is
/// named stuck in under 100 (77). A reading that follows the coil through the same ramp
/// raises nothing, learned or not: the coil's current stays within a factor 2 of the
/// one it was learned at.
#[test]
fn a_learned_resistance_names_a_frozen_reading_sooner() {
    let learning = cfg(0);
    let mut m = crate::control::actuator::Actuator::PRODUCT
        .settings()
        .unwrap()
        .monitors;
    m.residual.as_mut().unwrap().learn_ticks = 0;
    let bounds = m
        .build(&Plant::paper(), &Calibration::board(), TS, 0)
        .unwrap();
    for c in [&learning, &bounds] {
        assert_eq!(ramp_after_hold(c, 0.432, 4.0, 400, false), None);
    }
    let learned = ramp_after_hold(&learning, 0.432, 4.0, 400, true);
    assert!(
        matches!(learned, Some((Fault::CurrentStuck, k)) if k < 100),
        "learned: {learned:?}"
    );
    let unlearned = ramp_after_hold(&bounds, 0.432, 4.0, 400, true);
    assert!(
        matches!(unlearned, Some((Fault::CurrentStuck, k)) if k > 200),
        "bounds: {unlearned:?}"
    );
}

/// A law that chatters about the holding voltage (+-1.5 V every period, after a hold
/// that taught the resistance) on a coil whose drive loses `loss` of each swing (a
/// supply's internal resistance seen through the switching, the bridge's dead time):
/// the coil sees less mean voltage than the bank is told, a little every period. The
/// fault found, if any, over 400 periods.
fn chatter_after_hold(loss: f32) -> Option<Fault> {
    let c = cfg(0);
    let g = 2e-3;
    let (r, i0) = (0.432_f32, 4.0_f32);
    let hold = r * i0;
    let mut st = State::default();
    let mut i = i0;
    let code = Calibration::board().current.scale.abs();
    for k in 0..800_u32 {
        let swing = if k < 400 {
            0.0
        } else if k % 2 == 0 {
            1.5
        } else {
            -1.5
        };
        let u = hold + swing;
        let inp = held(g, k, i + if k % 3 == 0 { code } else { -code });
        if let Some(f) = c.check(&mut st, &inp) {
            return Some(f);
        }
        c.record_drive(&mut st, u, true);
        i = coil_step(g, u - loss * swing.abs(), i, r, 1.0);
    }
    None
}

/// The bank pays its margin on every period's change: a chattering drive whose swings
/// lose a tenth in the bridge raises nothing against the learned resistance. (With the
/// margin on the net excursion from the anchor, a few milliamperes, the same coil is
/// named a frozen reading; that is how a healthy plant in a thousand was named in the
/// simulator, where the chatter's loss was larger still.) Half of every swing lost is a
/// coil outside its model, and is named so.
#[test]
fn a_chattering_drive_with_a_lossy_bridge_raises_nothing() {
    assert_eq!(chatter_after_hold(0.1), None);
    assert_eq!(chatter_after_hold(0.5), Some(Fault::ModelBounds));
}
