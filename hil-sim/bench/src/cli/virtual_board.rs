//! The `virtual` verb: the virtual board on a pseudo-terminal, and the faults a user injects
//! into it.

use std::io::{BufRead, Write};
use std::sync::atomic::AtomicBool;
use std::sync::mpsc;
use std::time::Duration;

use anyhow::{anyhow, Context};
use ema::control::actuator::Actuator;
use serialport::SerialPort;

use super::VirtualArgs;
use crate::board::{Options, Stimulus, VirtualBoard};

/// What the virtual board's standard input takes.
pub(super) const STIMULI: &str = "supply V, position-open, position-ok, analog-v V, analog-ma MA, \
                          cut-save STEP, resistance OHM, surfaces SCALE, \
                          spring N_PER_M PRELOAD_N, \
                          mechanics MASS_KG N_PER_M PRELOAD_N FRICTION_N_S_PER_M, \
                          hang-main, run-main";

/// A line of the virtual board's standard input, as a stimulus on a board whose
/// actuator's file is `file` (a spring keeps its mass and friction).
fn stimulus(line: &str, file: &Actuator) -> Option<Result<Stimulus, String>> {
    let mut words = line.split_whitespace();
    let verb = words.next()?;
    if verb == "mechanics" {
        let v: Vec<f64> = words.map_while(|w| w.parse().ok()).collect();
        return Some(match v[..] {
            [mass_kg, spring_n_per_m, preload_n, friction_n_s_per_m]
                if mass_kg > 0.0 && spring_n_per_m >= 0.0 && friction_n_s_per_m >= 0.0 =>
            {
                Ok(Stimulus::Mechanics {
                    mass_kg,
                    spring_n_per_m,
                    preload_n,
                    friction_n_s_per_m,
                })
            }
            _ => Err(format!(
                "`{line}`: mechanics takes four numbers, the mass above zero, the spring and \
                 the friction not below ({STIMULI})"
            )),
        });
    }
    let arg = words.next().map(str::parse::<f64>);
    let second = words.next().map(str::parse::<f64>);
    if let ("spring", Some(Ok(k)), Some(Ok(f0))) = (verb, &arg, &second) {
        return Some(Ok(Stimulus::Mechanics {
            mass_kg: f64::from(file.mechanics.mass_kg),
            spring_n_per_m: *k,
            preload_n: *f0,
            friction_n_s_per_m: f64::from(file.mechanics.friction_n_s_per_m),
        }));
    }
    Some(match (verb, arg) {
        ("supply", Some(Ok(v))) => Ok(Stimulus::Supply(v)),
        ("position-open", None) => Ok(Stimulus::PositionOpen(true)),
        ("position-ok", None) => Ok(Stimulus::PositionOpen(false)),
        ("analog-v", Some(Ok(v))) => Ok(Stimulus::Analog {
            value: v,
            current: false,
        }),
        ("analog-ma", Some(Ok(v))) => Ok(Stimulus::Analog {
            value: v * 1e-3,
            current: true,
        }),
        ("cut-save", Some(Ok(v))) => Ok(Stimulus::CutSave(v as u64)),
        ("resistance", Some(Ok(v))) => Ok(Stimulus::Resistance(v)),
        ("surfaces", Some(Ok(v))) => Ok(Stimulus::Surfaces(v)),
        ("hang-main", None) => Ok(Stimulus::HangMainLoop(true)),
        ("run-main", None) => Ok(Stimulus::HangMainLoop(false)),
        _ => Err(format!("unknown: `{line}` ({STIMULI})")),
    })
}

pub(super) fn run_virtual(a: &VirtualArgs, out: &mut dyn Write) -> anyhow::Result<()> {
    let actuator = match &a.actuator {
        Some(name) => hil_sim::simulation::actuator::load(name)?.1,
        None => Actuator::PRODUCT,
    };
    // As fast as it can, the board's ticks outrun a host's heartbeat paced in real time:
    // its link timeout is off then (see `Options::link`).
    let link = if a.speed > 0.0 {
        ema::device::liveness::Settings::default()
    } else {
        ema::device::liveness::Settings {
            timeout_s: 0.0,
            ..ema::device::liveness::Settings::default()
        }
    };
    let mut board = VirtualBoard::new(Options {
        actuator,
        noise: a.noise,
        link,
        ..Options::default()
    })?;
    let (mut master, slave) =
        serialport::TTYPort::pair().context("cannot open a pseudo-terminal")?;
    master.set_timeout(Duration::from_millis(1))?;
    let path = slave
        .name()
        .ok_or_else(|| anyhow!("the pseudo-terminal has no name"))?;
    if let Some(link) = &a.link {
        let _ = std::fs::remove_file(link);
        std::os::unix::fs::symlink(&path, link)
            .with_context(|| format!("cannot link {}", link.display()))?;
    }
    writeln!(
        out,
        "virtual board on {path}: {} at {} Hz, {}; stimuli on standard input ({STIMULI})",
        a.actuator.as_deref().unwrap_or("the product's actuator"),
        board.scenario().rate_hz(),
        if a.speed > 0.0 {
            format!(
                "{} x real time, link.timeout_s {} s",
                a.speed, link.timeout_s
            )
        } else {
            "as fast as it can, link.timeout_s off".into()
        }
    )?;
    out.flush()?;
    let (tx, rx) = mpsc::channel::<String>();
    std::thread::spawn(move || {
        for line in std::io::stdin().lock().lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let stop = AtomicBool::new(false);
    let speed = (a.speed > 0.0).then_some(a.speed);
    board.serve(&mut master, speed, &stop, |b| {
        while let Ok(line) = rx.try_recv() {
            match stimulus(&line, &actuator) {
                Some(Ok(i)) => {
                    eprintln!("virtual board: {i:?}");
                    b.inject(i);
                }
                Some(Err(e)) => eprintln!("virtual board: {e}"),
                None => {}
            }
        }
    })?;
    drop(slave);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_virtual_boards_mechanics_stimulus_takes_four_numbers_and_refuses_a_massless_one() {
        let got = stimulus("mechanics 0.085 150 0.06 6", &Actuator::PRODUCT);
        assert_eq!(
            got,
            Some(Ok(Stimulus::Mechanics {
                mass_kg: 0.085,
                spring_n_per_m: 150.0,
                preload_n: 0.06,
                friction_n_s_per_m: 6.0,
            }))
        );
        for bad in [
            "mechanics 0.085 150 0.06",
            "mechanics 0 150 0.06 6",
            "mechanics 0.085 x 150 0.06 6",
        ] {
            let Some(Err(e)) = stimulus(bad, &Actuator::PRODUCT) else {
                panic!("`{bad}` accepted");
            };
            assert!(e.contains("mechanics takes four numbers"), "{e}");
        }
        // `spring` keeps the file's mass and friction.
        let Some(Ok(Stimulus::Mechanics { mass_kg, .. })) =
            stimulus("spring 150 0.06", &Actuator::PRODUCT)
        else {
            panic!("spring refused");
        };
        assert_eq!(mass_kg, f64::from(Actuator::PRODUCT.mechanics.mass_kg));
    }
}
