//! Commissioning on the virtual board, through the host tool's own serial path: the
//! board's identification (`ema::commission`, run by the board's interrupt half) against
//! the simulated coil with the converter's typical noise, its delay and quantisation.
//!
//! Coils drawn up to 30 % either side of the file's resistance (a fixed, printed seed) are
//! measured within 2 %; a coil far below its file stops above the rating, by name; a
//! disarm stops a commissioning; an armed board refuses one.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc};
use std::thread;
use std::time::Duration;

use ema::actuator::Actuator;
use ema::protocol::{Command, Commissioned, Message, Mode, Refusal, Reply};
use hil_sim::bench::board::{Injection, Options, VirtualBoard};
use hil_sim::bench::cli::{self, CommissionArgs};
use hil_sim::bench::link::Link;
use rand::{Rng, SeedableRng};

/// Seed of the drawn coils.
const SEED: u64 = 0x00e3_a5ee_d000_0004;
/// Coils measured.
const COILS: usize = 12;

struct Rig {
    link: Link<serialport::TTYPort>,
    inject: mpsc::Sender<Injection>,
    stop: Arc<AtomicBool>,
    board: Option<thread::JoinHandle<()>>,
    _slave: serialport::TTYPort,
}

impl Rig {
    /// A virtual board with converter noise, served as fast as it can.
    fn new() -> Self {
        let (master, slave) = serialport::TTYPort::pair().unwrap();
        let path = serialport::SerialPort::name(&slave).unwrap();
        let (tx, rx) = mpsc::channel::<Injection>();
        let stop = Arc::new(AtomicBool::new(false));
        let stop2 = stop.clone();
        let board = thread::spawn(move || {
            let mut master = master;
            serialport::SerialPort::set_timeout(&mut master, Duration::from_millis(1)).unwrap();
            let options = Options {
                noise: true,
                ..Options::default()
            };
            let mut b = VirtualBoard::new(options).unwrap();
            b.serve(&mut master, None, &stop2, |b| {
                while let Ok(i) = rx.try_recv() {
                    b.inject(i);
                }
            })
            .unwrap();
        });
        let mut link = cli::open(path.as_ref(), Duration::from_secs(5)).unwrap();
        link.wait_started(Duration::from_secs(5)).unwrap();
        Self {
            link,
            inject: tx,
            stop,
            board: Some(board),
            _slave: slave,
        }
    }

    /// Sets the coil's resistance and waits until the board has taken it (a status round
    /// trip after the injection).
    fn coil(&mut self, r_ohm: f64) {
        self.inject.send(Injection::Resistance(r_ohm)).unwrap();
        cli::status(&mut self.link).unwrap();
        cli::status(&mut self.link).unwrap();
    }

    fn commission(&mut self) -> anyhow::Result<ema::commission::Resistance> {
        let args = CommissionArgs {
            apply: false,
            timeout_s: 60.0,
        };
        cli::commission(&mut self.link, &args, &mut std::io::sink())
    }

    fn commissioned(&mut self) -> Commissioned {
        let f = self.link.request(Command::Commissioned).unwrap();
        let mut scratch = Vec::new();
        match f.message(&mut scratch).unwrap() {
            Message::Reply {
                reply: Reply::Commissioned(c),
                ..
            } => c,
            other => panic!("unexpected: {other:?}"),
        }
    }
}

impl Drop for Rig {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(b) = self.board.take() {
            let _ = b.join();
        }
    }
}

#[test]
fn coils_thirty_percent_off_their_file_are_measured_within_two_percent() {
    let file = f64::from(Actuator::PRODUCT.coil.resistance_ohm);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(SEED);
    let mut rig = Rig::new();
    let mut worst: f64 = 0.0;
    let mut draws = vec![0.7 * file, 1.3 * file];
    draws.extend((2..COILS).map(|_| file * rng.random_range(0.7..1.3)));
    for r in draws {
        rig.coil(r);
        let got = rig.commission().unwrap();
        let error = f64::from(got.ohm) / r - 1.0;
        worst = worst.max(error.abs());
        assert!(error.abs() < 0.02, "{r} ohm measured {} ohm", got.ohm);
        assert_eq!(cli::status(&mut rig.link).unwrap().mode, Mode::Disarmed);
    }
    eprintln!(
        "seed {SEED:#x}: {COILS} coils within 0.7-1.3 x {file} ohm, worst error {:.3} %",
        100.0 * worst
    );
}

#[test]
fn a_coil_far_below_its_file_stops_above_the_rating_and_a_disarm_stops_it() {
    let file = f64::from(Actuator::PRODUCT.coil.resistance_ohm);
    let mut rig = Rig::new();
    assert_eq!(rig.commissioned(), Commissioned::Never);
    rig.coil(0.4 * file);
    let e = rig.commission().unwrap_err();
    assert!(e.to_string().contains("current_above_rating"), "{e}");
    assert_eq!(cli::status(&mut rig.link).unwrap().mode, Mode::Disarmed);

    rig.coil(file);
    rig.link.done(Command::Commission).unwrap();
    assert_eq!(
        cli::status(&mut rig.link).unwrap().mode,
        Mode::Commissioning
    );
    rig.link.done(Command::Disarm).unwrap();
    assert_eq!(
        rig.commissioned(),
        Commissioned::Aborted(ema::commission::Abort::Stopped)
    );
    assert_eq!(cli::status(&mut rig.link).unwrap().mode, Mode::Disarmed);

    // Armed: refused, and nothing changes.
    rig.link.done(Command::Arm).unwrap();
    let f = rig.link.request(Command::Commission).unwrap();
    let mut scratch = Vec::new();
    match f.message(&mut scratch).unwrap() {
        Message::Reply {
            reply: Reply::Refused(r),
            ..
        } => assert_eq!(r, Refusal::Armed),
        other => panic!("not refused: {other:?}"),
    }
    assert!(cli::status(&mut rig.link).unwrap().mode.armed());
}
