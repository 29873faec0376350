//! The host tool against the virtual board, over a pseudo-terminal opened by its path, as
//! a user would drive a board on a bench: status, arm, move, capture (its metrics equal to
//! the simulator's for the same scenario), a fault (named), clear, set while armed
//! (refused), save then restart (kept), a power cut during a save (old or new set).

#[path = "common/rig.rs"]
mod rig;

use std::thread;
use std::time::Duration;

use bench::board::{Options, Stimulus};
use bench::cli::{self, CaptureArgs};
use ema::control::supervisor::Fault;
use ema::device::protocol::{Command, Message, Mode, Refusal, Reply, Source, Value};
use rig::Rig;

fn wait_for(rig: &mut Rig, what: &str, f: impl Fn(&ema::device::protocol::Status<'_>) -> bool) {
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
    // It says which firmware it runs: the package's version and the commit.
    assert_eq!(s.build, ema::device::protocol::Build::THIS);
    assert_eq!(s.build.version, "0.1.0");
    let id = s.build.id;
    assert!(
        id == "unknown" || (id.len() == 12 && id.chars().all(|c| c.is_ascii_hexdigit())),
        "{id}"
    );
    assert!(cli::status_text(&s).contains(&format!("ema 0.1.0 ({id})")));
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
    rig.inject.send(Stimulus::Supply(10.0)).unwrap();
    wait_for(&mut rig, "a fault", |s| s.mode == Mode::Fault);
    let s = rig.status();
    assert_eq!(s.fault, Some(Fault::BusUnderVoltage.code()));
    assert_eq!(
        bench::fault_name(s.fault.unwrap()),
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
    rig.inject.send(Stimulus::Supply(24.0)).unwrap();
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
        rig.inject.send(Stimulus::CutSave(step)).unwrap();
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

    rig.inject.send(Stimulus::DriverFault(true)).unwrap();
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

    rig.inject.send(Stimulus::DriverFault(false)).unwrap();
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

/// Ticks of the product's board in `s` seconds.
fn ticks_in(s: f64) -> u64 {
    (s * f64::from(ema::control::actuator::Actuator::PRODUCT.board.rate_hz)) as u64
}

/// In real time, with the link's default timeout (0.5 s): the host tool's heartbeat keeps
/// an armed board armed while the host asks nothing; a host that falls silent leaves it
/// armed for less than the timeout and disarmed, `link_timeout` latched, after it; with
/// `link.on_timeout = hold` the board holds its set point and counts the timeout.
#[test]
fn an_armed_board_disarms_when_its_host_falls_silent_and_not_before() {
    let mut rig = Rig::with_speed(Options::default(), Some(1.0));
    assert_eq!(
        cli::get(&mut rig.link, "link.timeout_s").unwrap(),
        Value::Number(ema::device::liveness::DEFAULT_TIMEOUT_S)
    );
    rig.link.done(Command::Arm).unwrap();
    // A second and a half with nothing asked: the heartbeat alone keeps it armed.
    rig.wait_ticks(ticks_in(1.5));
    assert_eq!(rig.status().mode, Mode::Armed);
    // Silent for 0.4 s: still armed.
    rig.host_away(|rig| rig.wait_ticks(ticks_in(0.4)));
    let s = rig.status();
    assert_eq!((s.mode, s.fault), (Mode::Armed, None));
    // Silent for 0.6 s: disarmed, the fault named.
    rig.host_away(|rig| rig.wait_ticks(ticks_in(0.6)));
    let s = rig.status();
    assert_eq!(
        (s.mode, s.fault),
        (Mode::Fault, Some(Fault::LinkTimeout.code()))
    );
    assert_eq!(
        bench::fault_name(s.fault.unwrap()),
        "link_timeout (code 22)"
    );
    rig.link.done(Command::Clear).unwrap();

    // Holding instead: the set point kept, the timeout counted, nothing latched.
    rig.link
        .done(Command::Set {
            name: "link.on_timeout",
            value: Value::Choice(ema::device::liveness::OnTimeout::Hold.index()),
        })
        .unwrap();
    rig.link.done(Command::Arm).unwrap();
    rig.link
        .done(Command::Move {
            position_m: 2e-3,
            time_s: None,
        })
        .unwrap();
    rig.host_away(|rig| rig.wait_ticks(ticks_in(0.8)));
    let s = rig.status();
    assert_eq!((s.mode, s.fault), (Mode::Armed, None));
    assert!((s.x_m - 2e-3).abs() < 20e-6, "{}", s.x_m);
    assert_eq!(
        s.fault_counts[usize::from(Fault::LinkTimeout.code() - 1)],
        2
    );
    rig.link.done(Command::Disarm).unwrap();
}

/// The main loop hangs on the virtual board while armed: the ticks go on, latch
/// `main_loop_stalled` and stop feeding the watchdogs; the watchdog restarts the board,
/// which comes back disarmed with the fault latched and named.
#[test]
fn a_hung_main_loop_ends_in_the_safe_state_and_is_named_after_the_restart() {
    let mut rig = Rig::new(Options::default());
    rig.link.done(Command::Arm).unwrap();
    rig.link
        .done(Command::Move {
            position_m: 3e-3,
            time_s: None,
        })
        .unwrap();
    wait_for(&mut rig, "at 3 mm", |s| (s.x_m - 3e-3).abs() < 20e-6);
    rig.link.forget_started();
    rig.inject.send(Stimulus::HangMainLoop(true)).unwrap();
    let started = rig.link.wait_started(Duration::from_secs(5)).unwrap();
    assert_eq!(started.params, Source::Defaults);
    let s = rig.status();
    assert_eq!(
        (s.mode, s.fault),
        (Mode::Fault, Some(Fault::MainLoopStalled.code()))
    );
    // The bridge coasted: the armature back at its open stop.
    wait_for(&mut rig, "back at the open stop", |s| s.x_m < 0.1e-3);
    let r = rig.refusal(Command::Arm);
    assert_eq!(
        r,
        format!(
            "{:?}",
            Refusal::Faulted {
                fault: Fault::MainLoopStalled.code()
            }
        )
    );
    rig.link.done(Command::Clear).unwrap();
    rig.link.done(Command::Arm).unwrap();
    rig.link.done(Command::Disarm).unwrap();
}

/// Two megabytes of random bytes written to the board while nobody reads what it sends:
/// the board takes them at the link's rate, drops what the host does not read (counted,
/// as a UART would lose it), and then answers a request.
#[test]
fn two_megabytes_of_noise_with_nobody_reading_leave_the_board_answering() {
    use rand::{Rng, SeedableRng};
    const SEED: u64 = 0x00E3_A5EE_D000_0002;
    println!("seed {SEED:#x}");
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(SEED);
    let noise: Vec<u8> = (0..2 << 20).map(|_| rng.random()).collect();
    let mut rig = Rig::new(Options::default());
    let t0 = rig.ticks();
    rig.link.send_raw(&noise).unwrap();
    // The board has taken all of it (the port held what the line had not carried yet).
    rig.wait_ticks(ticks_in(0.05));
    let seconds = (rig.ticks() - t0) as f64 / ticks_in(1.0) as f64;
    let s = rig.status();
    let dropped = rig.dropped();
    println!(
        "{} bytes in {seconds:.1} s of board time: {} frames rejected, {} bytes the host did not read dropped, {} received bytes dropped; then a status: {:?}",
        noise.len(),
        s.frames_rejected,
        dropped.sent,
        dropped.received,
        s.mode
    );
    assert_eq!(s.mode, Mode::Disarmed);
    assert!(s.frames_rejected > 7_000, "{}", s.frames_rejected);
    assert!(dropped.sent > 0, "{dropped:?}");
    assert_eq!(
        cli::get(&mut rig.link, "tuning.margin").unwrap(),
        Value::Number(0.7)
    );
}

/// Every parameter of a board, backed up to a file (an actuator file with the board's
/// tables, which `hil-sim` reads as the actuator), restored on a fresh board and saved:
/// the fresh board then has every one of them, from its store.
#[test]
fn a_backup_restores_every_parameter_on_a_fresh_board() {
    let file = std::env::temp_dir().join(format!("ema-backup-{}.toml", std::process::id()));
    let changed: [(&str, Value); 5] = [
        ("tuning.margin", Value::Number(0.6)),
        ("coil.resistance_ohm", Value::Number(0.43)),
        ("setpoint.filter_s", Value::Number(0.01)),
        ("link.timeout_s", Value::Number(2.0)),
        ("link.on_timeout", Value::Choice(1)),
    ];
    let mut old = Rig::new(Options::default());
    for (name, value) in changed {
        old.link.done(Command::Set { name, value }).unwrap();
    }
    let mut out = Vec::new();
    cli::run(
        &mut old.link,
        cli::Verb::Backup { file: file.clone() },
        &mut out,
    )
    .unwrap();
    let text = std::fs::read_to_string(&file).unwrap();
    assert!(text.contains("on_timeout = \"hold\""), "{text}");
    let actuator = hil_sim::simulation::actuator::parse(&text, "backup").unwrap();
    assert_eq!(actuator.coil.resistance_ohm, 0.43);
    let backed_up = cli::read_params(&mut old.link).unwrap();

    let mut fresh = Rig::new(Options::default());
    assert_eq!(fresh.status().params, Source::Defaults);
    cli::run(
        &mut fresh.link,
        cli::Verb::Restore { file: file.clone() },
        &mut out,
    )
    .unwrap();
    assert_eq!(fresh.status().params, Source::Stored);
    for (name, value) in changed {
        assert_eq!(cli::get(&mut fresh.link, name).unwrap(), value, "{name}");
    }
    assert_eq!(cli::read_params(&mut fresh.link).unwrap(), backed_up);
    let _ = std::fs::remove_file(file);
}

/// The console: commands one per line over one link, a bad line reported and the next
/// run, and the board disarmed at the end of the input.
#[test]
fn the_console_runs_line_after_line_and_disarms_at_the_end() {
    let mut rig = Rig::new(Options::default());
    let input = "arm\nmove 3\n# a comment\nbogus 1\nstatus\n";
    let mut out = Vec::new();
    cli::console(&mut rig.link, input.as_bytes(), &mut out).unwrap();
    let out = String::from_utf8(out).unwrap();
    assert!(out.contains("armed: holding"), "{out}");
    assert!(out.contains("moving to 3 mm"), "{out}");
    assert!(out.contains("unrecognized subcommand 'bogus'"), "{out}");
    assert!(
        out.lines()
            .last()
            .unwrap()
            .contains("end of input: disarmed"),
        "{out}"
    );
    assert_eq!(rig.status().mode, Mode::Disarmed);
}

/// A save over a stored set this firmware cannot read (a later format) needs `--replace`.
#[test]
fn a_save_over_a_set_of_a_later_format_is_refused_by_name() {
    use ema::device::protocol::LoadError;
    let later = Source::Fallback(LoadError::Version {
        found: 3,
        expected: ema::device::store::FORMAT,
    });
    let why = cli::save_would_replace(&later).unwrap();
    assert!(
        why.contains("format 3") && why.contains("--replace"),
        "{why}"
    );
    assert_eq!(cli::save_would_replace(&Source::Stored), None);
    assert_eq!(
        cli::save_would_replace(&Source::Fallback(LoadError::Crc)),
        None
    );
}
