//! The board's status: read (`status`) and shown as text.

use anyhow::anyhow;
use ema::device::protocol::{Build, CaptureState, Command, Message, Reply, Status};
use hil_sim::analysis::report::{sig, Table};

use crate::fault_name;
use crate::link::{Link, Port};

/// The board's status.
///
/// # Errors
/// No reply, or an unexpected one.
pub fn status<P: Port>(link: &mut Link<P>) -> anyhow::Result<Status<'static>> {
    let f = link.request(Command::Status)?;
    let mut scratch = Vec::new();
    match f.message(&mut scratch)? {
        Message::Reply {
            reply: Reply::Status(s),
            ..
        } => {
            let leak = |t: &str| -> &'static str { Box::leak(t.to_owned().into_boxed_str()) };
            Ok(Status {
                params: crate::owned_source(&s.params),
                build: Build {
                    version: leak(s.build.version),
                    id: leak(s.build.id),
                },
                ..s
            })
        }
        other => Err(anyhow!("unexpected reply: {other:?}")),
    }
}

/// A status as the `status` command prints it.
#[must_use]
pub fn status_text(s: &Status<'_>) -> String {
    let mut t = Table::new(["", ""]);
    let row = |t: &mut Table, k: &str, v: String| t.push([k.to_owned(), v]);
    row(
        &mut t,
        "firmware",
        format!("ema {} ({})", s.build.version, s.build.id),
    );
    row(&mut t, "state", s.mode.name().into());
    row(
        &mut t,
        "latched fault",
        s.fault.map_or("none".into(), fault_name),
    );
    row(
        &mut t,
        "arming",
        s.not_ready
            .map_or("possible".into(), |f| format!("refused: {}", fault_name(f))),
    );
    let counts: Vec<String> = s
        .fault_counts
        .iter()
        .enumerate()
        .filter(|(_, &n)| n > 0)
        .map(|(k, n)| format!("{} x{n}", fault_name(u8::try_from(k + 1).unwrap_or(0))))
        .collect();
    row(
        &mut t,
        "faults since start",
        if counts.is_empty() {
            "none".into()
        } else {
            counts.join(", ")
        },
    );
    row(
        &mut t,
        "position",
        format!("{} mm", sig(f64::from(s.x_m) * 1e3, 4)),
    );
    row(
        &mut t,
        "set point",
        format!("{} mm", sig(f64::from(s.setpoint_m) * 1e3, 4)),
    );
    row(
        &mut t,
        "coil current",
        format!("{} A", sig(f64::from(s.i_a), 3)),
    );
    row(
        &mut t,
        "bus voltage",
        format!("{} V", sig(f64::from(s.vbus_v), 4)),
    );
    row(
        &mut t,
        "cycles per tick",
        if s.isr_cycles_max == 0 {
            "not measured (virtual board)".into()
        } else {
            format!("mean {} max {}", s.isr_cycles_mean, s.isr_cycles_max)
        },
    );
    row(&mut t, "overruns", s.overruns.to_string());
    row(&mut t, "ticks", s.ticks.to_string());
    row(
        &mut t,
        "parameters",
        format!(
            "{}{}",
            crate::source(&s.params),
            if s.unsaved {
                ", changed since (unsaved)"
            } else {
                ""
            }
        ),
    );
    row(
        &mut t,
        "capture",
        match s.capture {
            CaptureState::Idle => "none".into(),
            CaptureState::Waiting => "waiting for a move".into(),
            CaptureState::Running(n) => format!("recording ({n} samples)"),
            CaptureState::Done(n) => format!("{n} samples ready"),
        },
    );
    row(
        &mut t,
        "link",
        format!(
            "{} frames rejected, {} telemetry samples dropped",
            s.frames_rejected, s.telemetry_dropped
        ),
    );
    t.to_text()
}
