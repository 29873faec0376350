//! The host tool against the virtual board, over a pseudo-terminal opened by its path, as
//! a user would drive a board on a bench: status, arm, move, capture (its metrics equal to
//! the simulator's for the same scenario), a fault (named), clear, set while armed
//! (refused), save then restart (kept), a power cut during a save (old or new set).

#[path = "common/rig.rs"]
mod rig;

use std::thread;
use std::time::Duration;

use ema::protocol::{Command, Message, Mode, Refusal, Reply, Source, Value};
use ema::supervisor::Fault;
use hil_sim::bench::board::{Injection, Options};
use hil_sim::bench::cli::{self, CaptureArgs};
use rig::Rig;

fn wait_for(rig: &mut Rig, what: &str, f: impl Fn(&ema::protocol::Status<'_>) -> bool) {
    for _ in 0..500 {
        if f(&rig.status()) {
            return;
        }
        thread::sleep(Duration::from_millis(10));
    }
    panic!("never: {what}");
}

#[test]
fn the_host_tool_drives_the_virtual_board_through_a_session() {
    let mut rig = Rig::new(Options::default());

    // Boots disarmed, on its built-in parameters, ready to arm.
    let s = rig.status();
    assert_eq!(s.mode, Mode::Disarmed);
    assert_eq!(s.fault, None);
    assert_eq!(s.not_ready, None);
    assert_eq!(s.params, Source::Defaults);
    assert!((s.vbus_v - 24.0).abs() < 0.1, "{}", s.vbus_v);
    // A move before arming is refused.
    let r = rig.refusal(Command::Move {
        position_m: 3e-3,
        time_s: None,
    });
    assert_eq!(r, format!("{:?}", Refusal::NotArmed));

    // Arm: closed loop, holding the open stop it rests on.
    rig.link.done(Command::Arm).unwrap();
    let s = rig.status();
    assert_eq!(s.mode, Mode::Armed);
    assert!(s.setpoint_m.abs() < 2e-6, "{}", s.setpoint_m);

    // Set while armed: refused, nothing changed.
    let r = rig.refusal(Command::Set {
        name: "tuning.margin",
        value: Value::Number(0.6),
    });
    assert_eq!(r, format!("{:?}", Refusal::Armed));
    assert_eq!(
        cli::get(&mut rig.link, "tuning.margin").unwrap(),
        Value::Number(0.7)
    );

    // Capture the move to 3 mm: the simulator's metrics of the capture equal those of its
    // prediction for the same scenario, sample for sample.
    let dir = std::env::temp_dir().join(format!("ema-bench-e2e-{}", std::process::id()));
    let mut sink = Vec::new();
    let c = cli::capture(
        &mut rig.link,
        &CaptureArgs {
            position_mm: 3.0,
            time_s: None,
            samples: 256,
            decimation: 20,
            noise: false,
            out: dir.clone(),
        },
        &mut sink,
    )
    .unwrap();
    assert_eq!(c.capture.samples.len(), 256);
    assert_eq!(c.board.segments, c.simulator.segments);
    // The board measures no supply current: no energy in what it prints.
    let printed = String::from_utf8(sink).unwrap();
    assert!(printed.contains("settling 2 % [s]") && !printed.contains("energy"));
    let seg = c.board.first().unwrap();
    assert!(seg.settling_time_s.unwrap() < 0.2, "{seg:?}");
    assert!(seg.overshoot_pct < 0.5, "{seg:?}");
    assert!(seg.steady_error_pct.abs() < 0.1, "{seg:?}");
    for f in &c.files {
        assert!(std::fs::metadata(f).unwrap().len() > 100, "{}", f.display());
    }
    wait_for(&mut rig, "at 3 mm", |s| (s.x_m - 3e-3).abs() < 20e-6);

    // A supply sag: bus_under_voltage, named; the bridge coasts.
    rig.inject.send(Injection::Supply(10.0)).unwrap();
    wait_for(&mut rig, "a fault", |s| s.mode == Mode::Fault);
    let s = rig.status();
    assert_eq!(s.fault, Some(Fault::BusUnderVoltage.code()));
    assert_eq!(
        hil_sim::bench::fault_name(s.fault.unwrap()),
        "bus_under_voltage (code 8)"
    );
    assert_eq!(
        s.fault_counts[usize::from(Fault::BusUnderVoltage.code() - 1)],
        1
    );
    // Arming and clearing while the supply is still low: refused, with the reason.
    let r = rig.refusal(Command::Arm);
    assert_eq!(
        r,
        format!(
            "{:?}",
            Refusal::Faulted {
                fault: Fault::BusUnderVoltage.code()
            }
        )
    );
    let r = rig.refusal(Command::Clear);
    assert_eq!(
        r,
        format!(
            "{:?}",
            Refusal::CauseActive {
                fault: Fault::BusUnderVoltage.code()
            }
        )
    );
    // The supply back: clear, disarmed, arm again.
    rig.inject.send(Injection::Supply(24.0)).unwrap();
    wait_for(&mut rig, "the bus back", |s| s.not_ready.is_none());
    rig.link.done(Command::Clear).unwrap();
    assert_eq!(rig.status().mode, Mode::Disarmed);
    rig.link.done(Command::Arm).unwrap();
    rig.link.done(Command::Disarm).unwrap();

    // A refused value names the field, its value and why, as the build does.
    let f = rig
        .link
        .request(Command::Set {
            name: "coil.peak_current_a",
            value: Value::Number(5.0),
        })
        .unwrap();
    let mut scratch = Vec::new();
    let Message::Reply {
        reply: Reply::Refused(Refusal::Invalid(i)),
        ..
    } = f.message(&mut scratch).unwrap()
    else {
        panic!("not refused");
    };
    assert_eq!(
        i.to_string(),
        "coil.peak_current_a = 5: must be at least 12.599999"
    );

    // Set, save, restart: kept.
    rig.link
        .done(Command::Set {
            name: "tuning.margin",
            value: Value::Number(0.6),
        })
        .unwrap();
    assert!(rig.status().unsaved);
    rig.link.forget_started();
    rig.link.done(Command::Save).unwrap();
    let started = rig.link.wait_started(Duration::from_secs(5)).unwrap();
    assert_eq!(started.saved, Some(Ok(())));
    assert_eq!(started.params, Source::Stored);
    assert_eq!(
        cli::get(&mut rig.link, "tuning.margin").unwrap(),
        Value::Number(0.6)
    );
    rig.link.forget_started();
    rig.link.done(Command::Restart).unwrap();
    rig.link.wait_started(Duration::from_secs(5)).unwrap();
    let s = rig.status();
    assert_eq!(
        (s.mode, s.params, s.unsaved),
        (Mode::Disarmed, Source::Stored, false)
    );
    assert_eq!(
        cli::get(&mut rig.link, "tuning.margin").unwrap(),
        Value::Number(0.6)
    );

    // A power cut in the middle of a save: the board comes back with the old set or the
    // new one, never a mix (every single step is cut in tests/power_cut.rs).
    let mut seen = Vec::new();
    for (k, step) in [0u64, 7, 60, 100].into_iter().enumerate() {
        let new = 0.5 - 0.01 * k as f32;
        let old = cli::get(&mut rig.link, "tuning.margin").unwrap();
        rig.link
            .done(Command::Set {
                name: "tuning.margin",
                value: Value::Number(new),
            })
            .unwrap();
        rig.inject.send(Injection::CutSave(step)).unwrap();
        rig.link.forget_started();
        rig.link.done(Command::Save).unwrap();
        let started = rig.link.wait_started(Duration::from_secs(5)).unwrap();
        // The power went during the save: the start that follows made none.
        assert_eq!(started.saved, None, "cut at {step}");
        assert_eq!(started.params, Source::Stored, "cut at {step}");
        let now = cli::get(&mut rig.link, "tuning.margin").unwrap();
        assert!(
            now == old || now == Value::Number(new),
            "cut at {step}: {now:?}"
        );
        seen.push(now == old);
    }
    // A cut before the record's last byte keeps the old set.
    assert_eq!(seen, [true, true, true, true]);

    let (starts, cut) = rig.finish();
    assert_eq!(cut, 4);
    // Power-on, a save and a restart, four cut saves: a start whose save the power cut
    // never ran the application; the start after the power came back did.
    assert_eq!(starts, 1 + 1 + 1 + 4);
    let _ = std::fs::remove_dir_all(dir);
}

/// The bridge driver's fault output pulls the timer's break input: the outputs go off
/// without the tick, the next tick latches `hardware_trip`, and the armature falls back
/// to its open stop. Clearing is refused while the input is still active; once it is
/// gone, a clear re-enables the outputs and the board arms and moves again.
#[test]
fn a_driver_fault_on_the_break_input_holds_the_bridge_off_until_it_is_gone_and_cleared() {
    let mut rig = Rig::new(Options::default());
    rig.link.done(Command::Arm).unwrap();
    rig.link
        .done(Command::Move {
            position_m: 3e-3,
            time_s: None,
        })
        .unwrap();
    wait_for(&mut rig, "at 3 mm", |s| (s.x_m - 3e-3).abs() < 20e-6);

    rig.inject.send(Injection::DriverFault(true)).unwrap();
    wait_for(&mut rig, "a fault", |s| s.mode == Mode::Fault);
    assert_eq!(rig.status().fault, Some(Fault::HardwareTrip.code()));
    wait_for(&mut rig, "back at the open stop", |s| s.x_m < 0.1e-3);
    let r = rig.refusal(Command::Clear);
    assert_eq!(
        r,
        format!(
            "{:?}",
            Refusal::CauseActive {
                fault: Fault::HardwareTrip.code()
            }
        )
    );

    rig.inject.send(Injection::DriverFault(false)).unwrap();
    rig.link.done(Command::Clear).unwrap();
    assert_eq!(rig.status().mode, Mode::Disarmed);
    rig.link.done(Command::Arm).unwrap();
    rig.link
        .done(Command::Move {
            position_m: 2e-3,
            time_s: None,
        })
        .unwrap();
    wait_for(&mut rig, "at 2 mm", |s| (s.x_m - 2e-3).abs() < 20e-6);
    assert_eq!(rig.status().fault, None);
    rig.link.done(Command::Disarm).unwrap();
}
