//! Property tests of the tick: random sensor frames and sequences, hostile values included.
//!
//! Each case is a sequence of `LEN` frames, run through every law; `CASES` cases for each
//! of three generators: independent converter codes, independent SI measurements, and
//! slow random walks of plausible measurements with sparse hostile injections (run with
//! the detectors that need a physical coil off, since a random walk does not answer the
//! drive): 3 x 250 x 700 x 3 = 1 575 000 frames. The test counts the frames it executed
//! and asserts at least a million, and that the walks mostly drove the bridge (the
//! properties are not checked on fault paths alone).

extern crate std;

use super::{Settings, State, Status};
use crate::bridge::{HBridge, Mode};
use crate::law;
use crate::sense::{Frame, Measurement, ADC_MAX_CODE};
use core::cell::Cell;
use core::convert::Infallible;
use embedded_hal::digital::{ErrorType as PinErrorType, OutputPin};
use embedded_hal::pwm::{ErrorType as PwmErrorType, SetDutyCycle};
use proptest::prelude::*;
use std::rc::Rc;
use std::vec::Vec;

const CASES: u32 = 250;
const LEN: usize = 700;
const MAX_DUTY: u16 = crate::bridge::BOARD_MAX_DUTY;

/// PWM and pins that record what the bridge did, for checking after each tick.
#[derive(Clone, Default)]
struct Hw {
    duty: Rc<Cell<u16>>,
    enable: Rc<Cell<bool>>,
}
struct Pwm(Hw);
impl PwmErrorType for Pwm {
    type Error = Infallible;
}
impl SetDutyCycle for Pwm {
    fn max_duty_cycle(&self) -> u16 {
        MAX_DUTY
    }
    fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Infallible> {
        self.0.duty.set(duty);
        Ok(())
    }
}
struct Pin(Hw, bool);
impl PinErrorType for Pin {
    type Error = Infallible;
}
impl OutputPin for Pin {
    fn set_low(&mut self) -> Result<(), Infallible> {
        if !self.1 {
            self.0.enable.set(false);
        }
        Ok(())
    }
    fn set_high(&mut self) -> Result<(), Infallible> {
        if !self.1 {
            self.0.enable.set(true);
        }
        Ok(())
    }
}

fn settings(which: usize, physical_monitors: bool) -> Settings {
    let mut s = Settings::practical(20_000.0, 24.0).unwrap();
    match which {
        0 => {}
        1 => {
            s = Settings::paper(20_000.0, 24.0);
        }
        _ => {
            s = Settings::paper(20_000.0, 24.0);
            s.law = law::Settings::BoundaryLayer(law::paper::Gains::paper());
            s.delay_ticks = 1;
        }
    }
    if !physical_monitors {
        s.monitors.residual = None;
        s.monitors.stuck = None;
    }
    s
}

/// Hostile floats: NaN, infinities, subnormals, zeros, huge, plausible.
fn hostile_f32(plausible: core::ops::Range<f32>) -> impl Strategy<Value = f32> {
    prop_oneof![
        3 => plausible,
        1 => Just(f32::NAN),
        1 => Just(f32::INFINITY),
        1 => Just(f32::NEG_INFINITY),
        1 => Just(f32::MIN_POSITIVE / 4.0),
        1 => Just(-f32::MIN_POSITIVE / 8.0),
        1 => Just(0.0_f32),
        1 => Just(-0.0_f32),
        1 => Just(f32::MAX),
        1 => any::<f32>(),
    ]
}

/// Codes biased toward the rails and toward plausible values, with wild jumps.
fn code() -> impl Strategy<Value = u16> {
    prop_oneof![
        4 => 41_u16..4055,
        1 => Just(0_u16),
        1 => Just(ADC_MAX_CODE),
        1 => 0_u16..41,
        1 => 4055_u16..=ADC_MAX_CODE,
        1 => any::<u16>(),
    ]
}

/// Slow random walks: plausible measurements that change a little each tick, with a
/// hostile value injected about once in 50 ticks.
fn walk_input() -> impl Strategy<Value = Vec<Input>> {
    let step = (
        -2e-6_f32..2e-6,
        -0.05_f32..0.05,
        -0.05_f32..0.05,
        0_u8..100,
        hostile_f32(-1.0..1.0),
    );
    (
        0.5e-3_f32..3.5e-3,
        0.0_f32..8.0,
        proptest::collection::vec(step, LEN),
    )
        .prop_map(|(x0, i0, steps)| {
            let (mut x, mut i, mut v) = (x0, i0, 24.0_f32);
            steps
                .into_iter()
                .map(|(dx, di, dv, kind, bad)| {
                    x = (x + dx).clamp(0.0, 4e-3);
                    i = (i + di).clamp(-2.0, 12.0);
                    v = (v + dv).clamp(20.0, 28.0);
                    let mut m = Measurement {
                        x_m: x,
                        i_a: i,
                        vbus_v: v,
                    };
                    match kind {
                        0 => m.x_m = bad,
                        1 => m.i_a = bad,
                        2 => m.vbus_v = bad,
                        _ => {}
                    }
                    Input::Si(m, if kind == 3 { bad } else { 2e-3 })
                })
                .collect()
        })
}

#[derive(Clone, Copy, Debug)]
enum Input {
    Codes(Frame, f32),
    Si(Measurement, f32),
}

fn frame_input() -> impl Strategy<Value = Input> {
    (code(), code(), code(), hostile_f32(0.0..4e-3)).prop_map(|(p, i, v, sp)| {
        Input::Codes(
            Frame {
                position: p,
                current: i,
                vbus: v,
            },
            sp,
        )
    })
}

fn si_input() -> impl Strategy<Value = Input> {
    (
        hostile_f32(-1e-3..5e-3),
        hostile_f32(-20.0..20.0),
        hostile_f32(0.0..40.0),
        hostile_f32(0.0..4e-3),
    )
        .prop_map(|(x_m, i_a, vbus_v, sp)| Input::Si(Measurement { x_m, i_a, vbus_v }, sp))
}

/// Checks one tick's outcome against the product's promises.
fn check(status: &Status, hw: &Hw, input: &Input, state: &State) -> Result<(), TestCaseError> {
    let duty = hw.duty.get();
    prop_assert!(duty <= MAX_DUTY, "duty {duty}");
    prop_assert!(status.drive.duty <= MAX_DUTY);
    prop_assert!(status.drive.u_v.is_finite(), "applied {}", status.drive.u_v);
    // The command the bridge applied never exceeds the measured bus.
    if let Some(vbus) = match input {
        Input::Si(m, _) => Some(m.vbus_v),
        Input::Codes(..) => Some(status.measurement.vbus_v),
    } {
        if vbus.is_finite() && vbus > 0.0 {
            prop_assert!(status.drive.u_v.abs() <= vbus * (1.0 + 1e-6));
        }
    }
    // Every command is finite, or the tick is in the safe state.
    prop_assert!(status.output.u_v.is_finite() || status.fault.is_some());
    // Invalid inputs always end in the safe state with a fault.
    let invalid = match input {
        Input::Si(m, sp) => {
            !(m.x_m.is_finite() && m.i_a.is_finite() && m.vbus_v.is_finite() && sp.is_finite())
        }
        Input::Codes(f, sp) => {
            f.position < 41
                || f.position > 4054
                || f.current < 41
                || f.current > 4054
                || f.vbus > 4054
                || !sp.is_finite()
        }
    };
    if invalid || status.fault.is_some() {
        prop_assert!(
            status.fault.is_some(),
            "invalid input without a fault: {input:?}"
        );
        prop_assert_eq!(status.drive.mode, Mode::Coast);
        prop_assert!(!hw.enable.get(), "bridge enabled in the safe state");
        prop_assert_eq!(duty, 0);
    }
    prop_assert_eq!(state.supervisor.latched(), status.fault);
    Ok(())
}

/// Runs `inputs` through the law `which`; returns the number of frames executed and how
/// many of them drove the bridge.
fn run(
    which: usize,
    physical_monitors: bool,
    inputs: &[Input],
    rearm_every: usize,
) -> Result<(u64, u64), TestCaseError> {
    let cfg = settings(which, physical_monitors).build().unwrap();
    let hw = Hw::default();
    let mut bridge = HBridge::new(
        Pwm(hw.clone()),
        Pin(hw.clone(), true),
        Pin(hw.clone(), false),
    )
    .unwrap();
    let mut state = cfg.initial_state();
    let mut driven = 0;
    for (k, input) in inputs.iter().enumerate() {
        if rearm_every > 0 && k % rearm_every == 0 {
            cfg.rearm(&mut state);
        }
        let status = match input {
            Input::Codes(frame, sp) => cfg.tick(&mut state, &mut bridge, frame, *sp),
            Input::Si(m, sp) => cfg.tick_measured(&mut state, &mut bridge, m, *sp),
        };
        check(&status, &hw, input, &state)?;
        if hw.enable.get() {
            driven += 1;
        }
    }
    Ok((inputs.len() as u64, driven))
}

/// Runs `CASES` random sequences from `sequences` through every law; the frame count and
/// how many frames drove the bridge.
fn property(sequences: impl Strategy<Value = Vec<Input>>, physical_monitors: bool) -> (u64, u64) {
    let config = ProptestConfig {
        cases: CASES,
        failure_persistence: None,
        ..ProptestConfig::default()
    };
    let mut runner = proptest::test_runner::TestRunner::new(config);
    let frames = Cell::new(0_u64);
    let driven = Cell::new(0_u64);
    let cases = (sequences, 0_usize..50);
    let result = runner.run(&cases, |(inputs, rearm)| {
        for which in 0..3 {
            let (f, d) = run(which, physical_monitors, &inputs, rearm)?;
            frames.set(frames.get() + f);
            driven.set(driven.get() + d);
        }
        Ok(())
    });
    if let Err(e) = result {
        panic!("{e}");
    }
    (frames.get(), driven.get())
}

#[test]
fn a_million_hostile_frames_never_panic_and_always_end_safe() {
    let (f1, _) = property(proptest::collection::vec(frame_input(), LEN), true);
    let (f2, _) = property(proptest::collection::vec(si_input(), LEN), true);
    let (f3, d3) = property(walk_input(), false);
    let frames = f1 + f2 + f3;
    std::eprintln!("{frames} frames; the walks drove the bridge in {d3} of {f3}");
    assert!(frames >= 1_000_000, "only {frames} frames");
    // Not vacuous: the walks drove the bridge most of the time.
    assert!(2 * d3 >= f3, "only {d3} of {f3} walk frames drove");
}
