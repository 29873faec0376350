//! Commissioning on the virtual board, through the host tool's own serial path: the
//! board's identification (`ema::commission`, run by the board's interrupt half) against
//! the simulated coil with the converter's typical noise, its delay and quantisation.
//!
//! Coils drawn up to 30 % either side of the file's resistance (a fixed, printed seed) are
//! measured within 2 %; a coil far below its file stops above the rating, by name; a
//! disarm stops a commissioning; an armed board refuses one.

#[path = "common/rig.rs"]
mod rig;

use ema::actuator::Actuator;
use ema::protocol::{Command, Commissioned, Message, Mode, Refusal, Reply};
use hil_sim::bench::board::{Injection, Options};
use hil_sim::bench::cli::{self, CommissionArgs};
use rand::{Rng, SeedableRng};
use rig::Rig;

/// Seed of the drawn coils.
const SEED: u64 = 0x00e3_a5ee_d000_0004;
/// Coils measured.
const COILS: usize = 12;

/// What this test adds to the shared rig.
trait Commissioning {
    fn coil(&mut self, r_ohm: f64);
    fn commission(&mut self) -> anyhow::Result<ema::commission::Resistance>;
    fn commissioned(&mut self) -> Commissioned;
}

impl Commissioning for Rig {
    /// Sets the coil's resistance and waits until the board has taken it (a status round
    /// trip after the injection).
    fn coil(&mut self, r_ohm: f64) {
        self.inject.send(Injection::Resistance(r_ohm)).unwrap();
        self.status();
        self.status();
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

#[test]
fn coils_thirty_percent_off_their_file_are_measured_within_two_percent() {
    let file = f64::from(Actuator::PRODUCT.coil.resistance_ohm);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(SEED);
    let mut rig = Rig::new(Options {
        noise: true,
        ..Options::default()
    });
    let mut worst: f64 = 0.0;
    let mut draws = vec![0.7 * file, 1.3 * file];
    draws.extend((2..COILS).map(|_| file * rng.random_range(0.7..1.3)));
    for r in draws {
        rig.coil(r);
        let got = rig.commission().unwrap();
        let error = f64::from(got.ohm) / r - 1.0;
        worst = worst.max(error.abs());
        assert!(error.abs() < 0.02, "{r} ohm measured {} ohm", got.ohm);
        assert_eq!(rig.status().mode, Mode::Disarmed);
    }
    eprintln!(
        "seed {SEED:#x}: {COILS} coils within 0.7-1.3 x {file} ohm, worst error {:.3} %",
        100.0 * worst
    );
}

#[test]
fn a_coil_far_below_its_file_stops_above_the_rating_and_a_disarm_stops_it() {
    let file = f64::from(Actuator::PRODUCT.coil.resistance_ohm);
    let mut rig = Rig::new(Options {
        noise: true,
        ..Options::default()
    });
    assert_eq!(rig.commissioned(), Commissioned::Never);
    rig.coil(0.4 * file);
    let e = rig.commission().unwrap_err();
    assert!(e.to_string().contains("current_above_rating"), "{e}");
    assert_eq!(rig.status().mode, Mode::Disarmed);

    rig.coil(file);
    rig.link.done(Command::Commission).unwrap();
    assert_eq!(rig.status().mode, Mode::Commissioning);
    rig.link.done(Command::Disarm).unwrap();
    assert_eq!(
        rig.commissioned(),
        Commissioned::Aborted(ema::commission::Abort::Stopped)
    );
    assert_eq!(rig.status().mode, Mode::Disarmed);

    // Armed: refused, and nothing changes.
    rig.link.done(Command::Arm).unwrap();
    assert_eq!(
        rig.refusal(Command::Commission),
        format!("{:?}", Refusal::Armed)
    );
    assert!(rig.status().mode.armed());
    // No restart on the way.
    assert_eq!(rig.finish(), (1, 0));
}
