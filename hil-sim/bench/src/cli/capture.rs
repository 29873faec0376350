//! The `capture` verb: a step response captured on the board, its CSV and figure, the
//! simulator's metrics and prediction beside it.

use std::io::Write;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail};
use ema::device::protocol::{CaptureState, Command, Message, Reply, Trigger, CHUNK_SAMPLES};
use hil_sim::analysis::report::{self, sig, Figure, Panel, Series, Table};

use super::{read_params, status, CaptureArgs};
use crate::link::{Link, Port};
use crate::Capture;

/// What `capture` measured and wrote.
#[derive(Clone, Debug)]
pub struct CaptureOutcome {
    /// The capture.
    pub capture: Capture,
    /// The simulator's metrics of the capture.
    pub board: hil_sim::Metrics,
    /// The simulator's metrics of its prediction, on the same samples.
    pub simulator: hil_sim::Metrics,
    /// Files written.
    pub files: Vec<PathBuf>,
}

/// Captures `samples` readings, one every `decimation` ticks, of a move to `position_m`
/// (the board armed; `time_s` the move's duration, the board's shaping if `None`), or
/// from now without a move (`to` is `None`), and reads the capture back.
///
/// # Errors
/// A refusal, no reply, a capture that does not finish.
pub(super) fn capture_move<P: Port>(
    link: &mut Link<P>,
    samples: u16,
    decimation: u16,
    to: Option<(f32, Option<f32>)>,
    rate_hz: f64,
) -> anyhow::Result<Capture> {
    link.done(Command::Capture {
        samples,
        decimation,
        trigger: if to.is_some() {
            Trigger::Move
        } else {
            Trigger::Now
        },
    })?;
    if let Some((position_m, time_s)) = to {
        link.done(Command::Move { position_m, time_s })?;
    }
    read_capture(link, samples, decimation, rate_hz)
}

/// Waits for the capture started (`samples` every `decimation` ticks) to finish and reads
/// it back.
///
/// # Errors
/// A refusal, no reply, a capture that does not finish.
pub(super) fn read_capture<P: Port>(
    link: &mut Link<P>,
    samples: u16,
    decimation: u16,
    rate_hz: f64,
) -> anyhow::Result<Capture> {
    let span_s = f64::from(samples) * f64::from(decimation) / rate_hz;
    let deadline = Instant::now() + Duration::from_secs_f64(10.0 * span_s + 5.0);
    let total = loop {
        match status(link)?.capture {
            CaptureState::Done(n) => break n,
            _ if Instant::now() > deadline => bail!("the capture did not finish"),
            _ => std::thread::sleep(Duration::from_millis(20)),
        }
    };
    let mut chunks = Vec::new();
    let mut offset = 0u16;
    while offset < total {
        let f = link.request(Command::ReadCapture { offset })?;
        let mut scratch = Vec::new();
        match f.message(&mut scratch)? {
            Message::Reply {
                reply: Reply::Capture(c),
                ..
            } => chunks.push(c),
            Message::Reply {
                reply: Reply::Refused(r),
                ..
            } => bail!("refused: {}", crate::refusal(&r)),
            other => bail!("unexpected reply: {other:?}"),
        }
        offset = offset.saturating_add(CHUNK_SAMPLES as u16);
    }
    Capture::from_chunks(&chunks).ok_or_else(|| anyhow!("empty capture"))
}

/// Captures a move (the board must be armed) and compares it with the prediction.
///
/// # Errors
/// A refusal, no reply, a capture that does not finish, files that cannot be written.
pub fn capture<P: Port>(
    link: &mut Link<P>,
    a: &CaptureArgs,
    out: &mut dyn Write,
) -> anyhow::Result<CaptureOutcome> {
    let s = status(link)?;
    if !s.mode.armed() {
        bail!("the board is {}: arm it first", s.mode.name());
    }
    let params = read_params(link)?;
    let rate = f64::from(params.actuator.board.rate_hz);
    let span_s = f64::from(a.samples) * f64::from(a.decimation) / rate;
    let capture = capture_move(
        link,
        a.samples,
        a.decimation,
        Some(((a.position_mm * 1e-3) as f32, a.time_s.map(|t| t as f32))),
        rate,
    )?;
    let (sc, run) = crate::prediction(&params, &capture, a.noise)?;
    let board = crate::capture_metrics(&sc, &capture);
    let simulator = crate::prediction_metrics(&sc, &run, &capture);
    let at_s = match sc.reference {
        hil_sim::simulation::scenario::Reference::Step { at_s, .. } => at_s,
        _ => 0.0,
    };
    let predicted = crate::prediction_samples(&run, &capture, at_s, rate);

    report::create_dir(&a.out)?;
    let csv = a.out.join("capture.csv");
    let mut t = Table::new([
        "t_s", "r_m", "x_m", "v_mps", "i_a", "u_v", "duty", "fault", "sim_x_m", "sim_i_a",
        "sim_u_v",
    ]);
    for (k, s) in capture.samples.iter().enumerate() {
        let p = predicted.get(k).copied().unwrap_or_default();
        t.push([
            format!("{}", capture.t_s(k, rate)),
            s.r_m.to_string(),
            s.x_m.to_string(),
            s.v_mps.to_string(),
            s.i_a.to_string(),
            s.u_v.to_string(),
            s.duty.to_string(),
            s.fault.to_string(),
            p.x_m.to_string(),
            p.i_a.to_string(),
            p.u_v.to_string(),
        ]);
    }
    t.write_csv(&csv)?;
    // The board does not measure the supply's current: the energy is not reported.
    let metrics = report::metrics_table(&[("board", &board), ("simulator", &simulator)])
        .without("energy [J]");
    let metrics_csv = a.out.join("metrics.csv");
    metrics.write_csv(&metrics_csv)?;
    let pts = |f: &dyn Fn(&ema::device::protocol::Sample) -> f64,
               v: &[ema::device::protocol::Sample]| {
        v.iter()
            .enumerate()
            .map(|(k, s)| (capture.t_s(k, rate), f(s)))
            .collect::<Vec<_>>()
    };
    let png = a.out.join("capture.png");
    Figure::new(format!(
        "step response {} -> {} mm: board and simulator",
        sig(f64::from(capture.from_m) * 1e3, 4),
        sig(f64::from(capture.to_m) * 1e3, 4)
    ))
    .panel(
        Panel::new("time from the move [s]", "position [mm]")
            .series(
                Series::line(
                    "x, board",
                    pts(&|s| f64::from(s.x_m) * 1e3, &capture.samples),
                )
                .color(0),
            )
            .series(
                Series::dashed("x, simulator", pts(&|s| f64::from(s.x_m) * 1e3, &predicted))
                    .color(1),
            )
            .series(
                Series::dashed(
                    "reference",
                    pts(&|s| f64::from(s.r_m) * 1e3, &capture.samples),
                )
                .color(7),
            ),
    )
    .panel(
        Panel::new("time from the move [s]", "coil current [A]")
            .series(Series::line("i, board", pts(&|s| f64::from(s.i_a), &capture.samples)).color(0))
            .series(
                Series::dashed("i, simulator", pts(&|s| f64::from(s.i_a), &predicted)).color(1),
            ),
    )
    .panel(
        Panel::new("time from the move [s]", "coil voltage [V]")
            .series(Series::line("u, board", pts(&|s| f64::from(s.u_v), &capture.samples)).color(0))
            .series(
                Series::dashed("u, simulator", pts(&|s| f64::from(s.u_v), &predicted)).color(1),
            ),
    )
    .write_png(&png)?;
    writeln!(
        out,
        "captured {} samples, one every {} ticks ({} s), move {} -> {} mm planned over {} s",
        capture.samples.len(),
        capture.decimation,
        sig(span_s, 4),
        sig(f64::from(capture.from_m) * 1e3, 4),
        sig(f64::from(capture.to_m) * 1e3, 4),
        sig(f64::from(capture.move_s), 4)
    )?;
    write!(out, "{}", metrics.transposed().to_text())?;
    let files = vec![csv, metrics_csv, png];
    writeln!(out, "\nwrote:")?;
    for f in &files {
        writeln!(out, "  {}", f.display())?;
    }
    Ok(CaptureOutcome {
        capture,
        board,
        simulator,
        files,
    })
}
