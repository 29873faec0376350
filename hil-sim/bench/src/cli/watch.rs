//! The `watch` verb: live values with a progress display.

use std::io::Write;
use std::time::Instant;

use anyhow::anyhow;
use ema::device::protocol::{Command, Mode, Signal};
use hil_sim::analysis::report::sig;

use super::WatchArgs;
use crate::fault_name;
use crate::link::{Link, Port};

pub(super) fn signal_mask(names: &[String]) -> anyhow::Result<(u16, Vec<Signal>)> {
    let mut mask = 0;
    let mut chosen = Vec::new();
    for n in names {
        let s = Signal::ALL
            .into_iter()
            .find(|s| s.name() == n)
            .ok_or_else(|| anyhow!("no signal is called `{n}`"))?;
        mask |= s.bit();
    }
    for s in Signal::ALL {
        if mask & s.bit() != 0 {
            chosen.push(s);
        }
    }
    Ok((mask, chosen))
}

pub(super) fn watch<P: Port>(
    link: &mut Link<P>,
    a: &WatchArgs,
    out: &mut dyn Write,
) -> anyhow::Result<()> {
    let (mask, chosen) = signal_mask(&a.signals)?;
    link.done(Command::Stream {
        signals: mask,
        decimation: a.decimation,
    })?;
    let bar = indicatif::ProgressBar::new((a.seconds * 1000.0) as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{bar:30} {elapsed:>4} {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let start = Instant::now();
    let mut frames = 0u64;
    let mut last = String::new();
    while start.elapsed().as_secs_f64() < a.seconds {
        link.pump()?;
        for t in link.telemetry() {
            frames += 1;
            let values: Vec<String> = chosen
                .iter()
                .zip(t.values.iter())
                .map(|(s, v)| format!("{} {}", s.name(), sig(f64::from(*v), 4)))
                .collect();
            last = format!(
                "{} {}{}",
                Mode::from_code(t.mode).map_or("?", Mode::name),
                values.join("  "),
                if t.fault == 0 {
                    String::new()
                } else {
                    format!("  fault {}", fault_name(t.fault))
                }
            );
            bar.set_message(last.clone());
        }
        bar.set_position(start.elapsed().as_millis() as u64);
    }
    bar.finish_and_clear();
    link.done(Command::Stream {
        signals: 0,
        decimation: 0,
    })?;
    writeln!(out, "{frames} telemetry frames; last: {last}")?;
    Ok(())
}
