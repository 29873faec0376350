//! The commissioning routine against a simulated coil and armature.

use super::*;
use crate::control::sense::Measurement;

const RATE: f32 = 20_000.0;
const STROKE: f32 = 2e-3;

/// The file the plans are made from: 2 ohm, 20 mH, 4 A, a 1 kg armature on 4000 N/m
/// (63 rad/s), 2 mm of stroke.
const FILE: Coil = Coil {
    resistance_ohm: 2.0,
    open_inductance_h: 0.02,
    closed_inductance_h: 0.02,
    rated_a: 4.0,
    natural_rad_s: 63.2,
    stroke_m: STROKE,
    spring_n_per_m: 4000.0,
    // The test magnet's pull at the open stop, 1.5 N/A^2.
    open_force_h_per_m: 3.0,
};

/// A test actuator: the coil `L i' = u - R i` (exact exponential per tick) with a
/// constant sensor offset `offset_a` and a bridge drop `drop_v` while it drives, the
/// drive applied one period late; an armature of 1 kg on a spring `k` with `friction` between
/// stops at 0 and [`STROKE`], pulled by `pull(i, x)`; the reading `read(x)`.
struct Rig {
    r: f32,
    l: f32,
    offset_a: f32,
    drop_v: f32,
    k: f32,
    friction: f32,
    pull: fn(f32, f32) -> f32,
    read: fn(f32) -> f32,
    stuck: bool,
    /// The file the plan is made from.
    file: Coil,
}

/// A magnet whose pull grows as the gap (0.5 mm residual) closes: 4 A at the open
/// stop pulls 24 N, 3.8 times what the spring asks at the closed one.
fn magnet(i: f32, x: f32) -> f32 {
    let g = 0.5e-3 + STROKE - x;
    1.5 * i * i * (0.5e-3 + STROKE) * (0.5e-3 + STROKE) / (g * g)
}

impl Rig {
    fn coil(r: f32) -> Self {
        Self {
            r,
            l: 0.02,
            offset_a: 0.05,
            drop_v: 0.3,
            k: 4000.0,
            friction: 40.0,
            pull: magnet,
            read: |x| x,
            stuck: false,
            file: FILE,
        }
    }

    /// Runs a whole identification; its result and the highest current.
    fn run(&self) -> (Result<Report, Abort>, f32) {
        let plan = Plan::new(&self.file, RATE, 0, 1e-5).unwrap();
        let mut id = Identification::new(plan);
        let (mut i, mut pending, mut applied) = (0.0_f32, 0.0_f32, 0.0_f32);
        let (mut x, mut v, mut peak) = (0.0_f32, 0.0_f32, 0.0_f32);
        let decay = libm::expf(-self.r / (self.l * RATE));
        let h = 1.0 / RATE;
        for _ in 0..10 * plan.ticks() {
            // The bridge's drop while it drives; coasting, nothing.
            let u = if applied > 0.0 {
                applied - self.drop_v
            } else {
                applied
            };
            i = u / self.r + (i - u / self.r) * decay;
            peak = peak.max(i);
            if !self.stuck {
                let a = (self.pull)(i, x) - self.k * x - self.friction * v;
                v += a * h;
                x += v * h;
                if x <= 0.0 || x >= STROKE {
                    x = x.clamp(0.0, STROKE);
                    v = 0.0;
                }
            }
            let m = Measurement {
                x_m: (self.read)(x),
                i_a: i + self.offset_a,
                vbus_v: 24.0,
            };
            match id.step(&m, applied) {
                Step::Drive(v) => {
                    applied = pending;
                    pending = v;
                }
                Step::Done(r) => return (r, peak),
            }
        }
        (Err(Abort::Stopped), peak)
    }
}

#[test]
fn the_plan_follows_the_coil_and_the_armature() {
    let p = Plan::new(&FILE, RATE, 0, 1e-5).unwrap();
    // Slowest coil: 0.02 * 1.5 / (2 * 0.5) = 30 ms; six of them, 180 ms = 3600 ticks;
    // two averaged, 1200.
    assert_eq!(p.settle_ticks, 3600);
    assert_eq!(p.average_ticks, 1200);
    assert_eq!(p.u_v, [0.3 * 4.0 * 2.0, 0.6 * 4.0 * 2.0]);
    assert_eq!(p.abort_a, 4.0);
    // Slowest armature: 63.2 * sqrt(0.5 / 1.5) = 36.49 rad/s, a period of 172.2 ms;
    // half of it, 1722 ticks; the release a quarter of it, 861, after the coil's 180 ms.
    assert_eq!(p.ramp_ticks, 1722);
    assert_eq!(p.release_ticks, 4461);
    // The probe's pull at the open stop: a tenth of the weakest spring's 4 N over the
    // stroke (2000 N/m, 2 mm) against the strongest magnet (4.5 N/A^2) is 0.42 A,
    // under a fifth of the rating (0.8 A).
    let pull_a = (2.0_f32 * 0.1 * 2000.0 * STROKE / 4.5).sqrt();
    assert!((p.probe_a[1] / pull_a - 1.0).abs() < 1e-6, "{p:?}");
    assert!((p.probe_a[0] / (0.25 * pull_a) - 1.0).abs() < 1e-6, "{p:?}");
    // A stiff spring leaves the rating's fifth.
    let stiff = Plan::new(
        &Coil {
            spring_n_per_m: 40_000.0,
            ..FILE
        },
        RATE,
        0,
        1e-5,
    )
    .unwrap();
    assert_eq!(stiff.probe_a, [0.2, 0.8]);
    // A fast coil averages at least 20 ms.
    let fast = Plan::new(
        &Coil {
            resistance_ohm: 20.0,
            open_inductance_h: 0.002,
            closed_inductance_h: 0.002,
            rated_a: 0.3,
            ..FILE
        },
        50_000.0,
        0,
        1e-5,
    )
    .unwrap();
    assert_eq!(fast.average_ticks, 1000);
    for bad in [
        Coil {
            resistance_ohm: 0.0,
            ..FILE
        },
        Coil {
            closed_inductance_h: f32::NAN,
            ..FILE
        },
        Coil {
            natural_rad_s: 0.0,
            ..FILE
        },
        Coil {
            stroke_m: -1.0,
            ..FILE
        },
        Coil {
            open_force_h_per_m: 0.0,
            ..FILE
        },
    ] {
        assert!(Plan::new(&bad, RATE, 0, 1e-5).is_none(), "{bad:?}");
    }
}

#[test]
fn the_resistance_and_the_stops_are_found_through_offsets_and_a_drop() {
    for r in [1.4_f32, 2.0, 2.6] {
        let mut rig = Rig::coil(r);
        // A sensor 3 % of the stroke off and 3 % steep.
        rig.read = |x| 0.03 * STROKE + 1.03 * x;
        let (got, peak) = rig.run();
        let got = got.unwrap();
        assert!((got.resistance.ohm / r - 1.0).abs() < 1e-3, "{r}: {got:?}");
        assert!((got.ends.open_m - 0.03 * STROKE).abs() < 1e-9, "{got:?}");
        assert!((got.ends.closed_m - 1.06 * STROKE).abs() < 1e-9, "{got:?}");
        // The test coil's inductance does not depend on the gap. Its time constant
        // spans 200 to 290 periods: the fit's sums over as many readings in f32
        // leave a few parts in ten thousand.
        for h in [got.inductance.open_h, got.inductance.closed_h] {
            assert!((h / 0.02 - 1.0).abs() < 3e-3, "{r}: {got:?}");
        }
        // The holds at the closed stop stay below the rating, whatever the file said.
        assert!(peak < 0.96 * 4.0, "{r}: {peak} A");
    }
}

#[test]
fn a_ringing_armature_is_measured_at_the_stops() {
    // 1 N s/m: a damping ratio of 0.008; the armature floating about the first two
    // steps' equilibria rings for seconds. The resistance comes from the closed stop.
    let mut ringing = Rig::coil(2.0);
    ringing.friction = 1.0;
    // A pull that grows gently as the gap closes: at the first step (1.2 A) the
    // armature floats about 0.24 mm, at the second (2.4 A) about 1.3 mm; from 3 A on
    // it is pressed against the closed stop.
    ringing.pull = |i, x| 0.6 * i * i * (1.0 + 400.0 * x);
    let (got, peak) = ringing.run();
    let got = got.unwrap();
    assert!((got.resistance.ohm / 2.0 - 1.0).abs() < 1e-3, "{got:?}");
    for h in [got.inductance.open_h, got.inductance.closed_h] {
        assert!((h / 0.02 - 1.0).abs() < 3e-3, "{got:?}");
    }
    assert!(peak < 0.96 * 4.0, "{peak} A");
}

#[test]
fn an_armature_creeping_back_onto_the_open_stop_is_read_once_there() {
    // 200 to 400 N s/m: damping ratios of 1.6 to 3.2, the slow mode creeping back with
    // a time constant of 44 to 98 ms onto a stop where the spring no longer pulls.
    // Released from the first two steps' pull, the armature is still 5 to 11 um off
    // the stop when the reading's peak-to-peak first stays within the noise's (10 um here).
    let open_m = [200.0, 300.0, 400.0, 600.0].map(|friction| {
        let mut creeping = Rig::coil(2.0);
        creeping.friction = friction;
        creeping.run().0.map(|got| got.ends.open_m)
    });
    let [a, b, c, slowest] = open_m;
    assert!(
        [a, b, c].iter().all(|x| x.is_ok_and(|x| x.abs() < 1e-6)),
        "{open_m:?}"
    );
    // A creep slower than the patience is named, not read short of the stop.
    assert_eq!(slowest, Err(Abort::NotAtRest), "{open_m:?}");
}

#[test]
fn a_coil_slower_than_its_armature_is_averaged_again_once_the_armature_is_back() {
    // 250 mH: a 125 ms coil (375 ms at the slowest the file admits) under an armature
    // whose slowest period is 172 ms. Each window (750 ms) is longer than four periods,
    // and the armature leaves the closed stop only as the coil's current decays, inside
    // the settling part of the open stop's wait, which the window covers.
    let slow = Coil {
        open_inductance_h: 0.25,
        closed_inductance_h: 0.25,
        ..FILE
    };
    let plan = Plan::new(&slow, RATE, 0, 1e-5).unwrap();
    // The patience the armature alone would be given: PATIENCE_PERIODS slowest periods,
    // the ramp being RAMP_PERIODS of one.
    #[expect(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    let periods = plan.ramp_ticks * (PATIENCE_PERIODS / RAMP_PERIODS) as u32;
    assert!(plan.average_ticks > periods, "{plan:?}");
    let mut rig = Rig::coil(2.0);
    rig.l = 0.25;
    rig.file = slow;
    let got = rig.run().0.unwrap();
    assert!(got.ends.open_m.abs() < 1e-6, "{got:?}");
    assert!((got.ends.closed_m / STROKE - 1.0).abs() < 1e-3, "{got:?}");
    assert!((got.resistance.ohm / 2.0 - 1.0).abs() < 1e-2, "{got:?}");
}

#[test]
fn a_low_resistance_stops_above_the_rating_and_an_open_coil_is_named() {
    // 2 ohm in the file, 1.1 ohm in the coil: the second step drives 4.8 V, 4.4 A.
    assert_eq!(Rig::coil(1.1).run().0, Err(Abort::OverRated));
    assert_eq!(Rig::coil(1e6).run().0, Err(Abort::NoResponse));
}

#[test]
fn a_backwards_sensor_a_stuck_armature_and_a_short_pull_are_named() {
    let mut backwards = Rig::coil(2.0);
    backwards.read = |x| STROKE - x;
    assert_eq!(backwards.run().0, Err(Abort::Backwards));
    let mut stuck = Rig::coil(2.0);
    stuck.stuck = true;
    assert_eq!(stuck.run().0, Err(Abort::NoTravel));
    // A pull that does not grow as the gap closes (14.4 N at 4 A): the spring holds
    // the armature at 2.0 mm * 0.56 at 75 % of the rating and 0.9 at 95 %.
    let mut short = Rig::coil(2.0);
    short.pull = |i, _| 0.9 * i * i;
    assert_eq!(short.run().0, Err(Abort::NoStop));
}
