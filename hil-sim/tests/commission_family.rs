//! The board's commissioning routine (`ema::device::commission`) on every actuator of the
//! family, against its simulated plant ([`hil_sim::identification::commissioning`]): the
//! file's plant here (the drawn plants are in `tests/commission.rs`, through the host tool
//! and the virtual board, and in `hil-sim commission`).
//!
//! Each member: the resistance within 2 %, the inductance at both stops and the curve the
//! written file models over the stroke within 5 % of the plant's, the position readings at both stops within 2 codes of the true positions',
//! the true coil current never above the rating, the board's routine within 10 s of
//! actuator time (`hil-sim commission NAME` adds the holds' time to it). A product
//! drawn wider than its file, commissioned and tuned, meets every target in closed loop on
//! its true plant (`hil-sim commission NAME --tune` gives the rate over many draws).
//! Beyond the family, every actuator of the development seed's draw is commissioned on
//! its file's plant.

use hil_sim::identification::commissioning::Errors;

#[test]
fn every_member_is_commissioned_within_its_targets() {
    for e in &hil_sim::simulation::actuator::FAMILY {
        let (name, a) = hil_sim::simulation::actuator::load(e.name).unwrap();
        let o = hil_sim::identification::commissioning::run(&a, None).unwrap();
        let Some(Errors {
            resistance: r,
            inductance_open: l_open,
            inductance_closed: l_closed,
            curve,
            open_codes: open,
            closed_codes: closed,
        }) = o.errors()
        else {
            panic!("{name}: commissioning stopped: {:?}", o.report)
        };
        let share = o.peak_a / f64::from(a.coil.rated_current_a);
        eprintln!(
            "{name:15} R {:+.3} %, L open {:+.2} % closed {:+.2} % over the stroke {:.2} %, stops {open:.2} and {closed:.2} codes, peak {:.1} % of the rating, {:.2} s",
            100.0 * r,
            100.0 * l_open,
            100.0 * l_closed,
            100.0 * curve,
            100.0 * share,
            o.took_s
        );
        assert!(r.abs() < 0.02, "{name}: {o:?}");
        assert!(
            l_open.abs() < 0.05 && l_closed.abs() < 0.05 && curve < 0.05,
            "{name}: {o:?}"
        );
        assert!(open < 2.0 && closed < 2.0, "{name}: {o:?}");
        assert!(share <= 1.0, "{name}: {o:?}");
        assert!(o.took_s <= 10.0, "{name}: {o:?}");
    }
}

/// Seed of the drawn plungers and pilot valves whose inductances are measured.
const INDUCTANCE_SEED: u64 = 0x1d0c_0000_0000_0017;

/// The inductance at both stops within 5 % on 16 drawn plungers and 16 drawn pilot
/// valves, each plant with its own converter noise, and the curve the file written from
/// the stops models over the stroke within 5 % on those whose surface is constant (the
/// two-inductance form models no growth; the holds' fit does). Their probes are one step of 48 and
/// 127 current codes: an estimate that one reading's noise can move (as the instrument
/// `sum w y(k+1) / sum w y(k)` can) misses on most of them.
#[test]
fn small_probe_steps_give_the_inductance_within_five_percent_on_drawn_plants() {
    use rand::SeedableRng;
    let mut rng = rand_pcg::Pcg64::seed_from_u64(INDUCTANCE_SEED);
    eprintln!("seed {INDUCTANCE_SEED:#x}");
    for name in ["plunger-1kg", "pilot-50khz"] {
        let (_, a) = hil_sim::simulation::actuator::load(name).unwrap();
        let mut worst = [0.0_f64; 3];
        for _ in 0..16 {
            let draw = hil_sim::identification::commissioning::Specimen::new(&mut rng);
            let o = hil_sim::identification::commissioning::run(&a, Some(&draw)).unwrap();
            let Some(Errors {
                inductance_open: open,
                inductance_closed: closed,
                curve,
                ..
            }) = o.errors()
            else {
                panic!("{name}: commissioning stopped: {:?}; {draw:?}", o.report)
            };
            // The stops' line models a constant surface only: a growing one's curve is
            // the holds' fit's.
            let curve = if draw.growth_share > 0.0 { 0.0 } else { curve };
            worst = [
                worst[0].max(open.abs()),
                worst[1].max(closed.abs()),
                // NaN (a curve that could not be read) fails below.
                if curve > worst[2] || curve.is_nan() {
                    curve
                } else {
                    worst[2]
                },
            ];
        }
        eprintln!(
            "{name}: worst inductance error, open stop {:.2} %, closed stop {:.2} %, over the stroke {:.2} %",
            100.0 * worst[0],
            100.0 * worst[1],
            100.0 * worst[2]
        );
        assert!(
            worst[0] < 0.05 && worst[1] < 0.05 && worst[2] < 0.05,
            "{name}: {worst:?}"
        );
    }
}

/// Seeds of three drawn valves whose armature, at the second resistance step, creeps off
/// the open stop and snaps onto the closed one at the end of the step's wait.
const SNAP_SEEDS: [u64; 3] = [62, 78, 82];

/// Valves drawn with their file's preload whose armature snaps onto the closed stop at
/// the end of the second resistance step's wait: the coil's current, kicked by the
/// back-EMF, recovers over the window that follows, which then reads the resistance up
/// to 15 % high and sets the later holds' voltages too high. The motion in the wait's
/// last part restarts the window after the coil has settled: each is commissioned, its
/// resistance within 2 %, its current never above the approach's share of the rating
/// (read too high, the hold at the closed stop reached the rating and ended the routine).
#[test]
fn a_valve_that_snaps_onto_its_stop_in_a_step_s_wait_is_driven_within_its_rating() {
    use rand::SeedableRng;
    let (_, a) = hil_sim::simulation::actuator::load("valve").unwrap();
    let rated = f64::from(a.coil.rated_current_a);
    for seed in SNAP_SEEDS {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        let draw = hil_sim::identification::commissioning::Specimen::new(&mut rng);
        let o = hil_sim::identification::commissioning::run(&a, Some(&draw)).unwrap();
        eprintln!(
            "seed {seed}: peak {:.4} A (rated {rated} A), {:?}",
            o.peak_a, o.report
        );
        let Some(Errors { resistance: r, .. }) = o.errors() else {
            panic!("seed {seed}: commissioning stopped: {:?}", o.report)
        };
        assert!(r.abs() < 0.02, "seed {seed}: {o:?}");
        let full = f64::from(ema::device::commission::FULL_SHARE) + 0.01;
        assert!(o.peak_a <= full * rated, "seed {seed}: {o:?}");
    }
}

/// Seed of the drawn product.
const PRODUCT_SEED: u64 = 0x00e3_a5ee_d000_0006;

#[test]
fn a_drawn_product_commissioned_and_tuned_meets_every_target_in_closed_loop() {
    use rand::SeedableRng;
    let (_, a) = hil_sim::simulation::actuator::load("product").unwrap();
    let mut rng = rand_pcg::Pcg64::seed_from_u64(PRODUCT_SEED);
    let draw = hil_sim::identification::commissioning::Specimen::new(&mut rng);
    let o = hil_sim::identification::commissioning::run(&a, Some(&draw)).unwrap();
    let report = o.report.unwrap();
    let plant = hil_sim::identification::commissioning::true_plant(&a, Some(&draw)).unwrap();
    let c =
        hil_sim::identification::commissioning::closed_loop(&a, &report, None, &plant, Some(&draw))
            .unwrap();
    eprintln!("seed {PRODUCT_SEED:#x}: {draw:?}\n{c:?}");
    assert_eq!(c.misses(), Vec::<&str>::new(), "{c:?}");
}

/// A position sensor at the corners of its tolerance
/// ([`ema::control::actuator::POSITION_SENSOR_TOLERANCE`] in offset and in gain, the same
/// way) reads inside the converter's plausible window at both stops on every member, the
/// noise's reach ([`ema::control::actuator::NOISE_SIGMAS`] deviations) included; and the
/// product with such a sensor is commissioned, its stops read within 2 codes.
#[test]
fn a_sensor_at_its_tolerance_s_corners_reads_inside_the_window_and_is_commissioned() {
    let t = ema::control::actuator::POSITION_SENSOR_TOLERANCE;
    let reach = ema::control::actuator::NOISE_SIGMAS * ema::control::sense::NOISE_RMS_CODES;
    for e in &hil_sim::simulation::actuator::FAMILY {
        let (name, a) = hil_sim::simulation::actuator::load(e.name).unwrap();
        let ch = a.calibration().position;
        let stroke = a.mechanics.stroke_m;
        for sign in [-1.0_f32, 1.0] {
            let (gain, offset_m) = (sign * t, sign * t * stroke);
            for x in [0.0, stroke] {
                let code = ch.offset_code + (x * (1.0 + gain) + offset_m) / ch.scale;
                // The corners land on the window's edges: a thousandth of a code for f32.
                assert!(
                    code - reach >= f32::from(ch.min_code) - 1e-3
                        && code + reach <= f32::from(ch.max_code) + 1e-3,
                    "{name}: {code} at {x} m, window {ch:?}"
                );
            }
        }
    }
    let (_, a) = hil_sim::simulation::actuator::load("product").unwrap();
    let corner = hil_sim::identification::commissioning::Specimen {
        factors: hil_sim::identification::commissioning::Factors::NONE,
        preload_share: 0.0,
        gain_error: f64::from(t),
        offset_share: f64::from(t),
        noise_seed: hil_sim::simulation::hal::Adc::typical().seed,
        current: hil_sim::simulation::hal::ChannelError::default(),
        vbus: hil_sim::simulation::hal::ChannelError::default(),
        growth_share: 0.0,
    };
    let o = hil_sim::identification::commissioning::run(&a, Some(&corner)).unwrap();
    let Some(Errors {
        open_codes: open,
        closed_codes: closed,
        ..
    }) = o.errors()
    else {
        panic!("commissioning stopped: {:?}", o.report)
    };
    assert!(open < 2.0 && closed < 2.0, "{o:?}");
}

/// A plant drawn off actuator `a`, commissioned, then held in closed loop: the draw, the
/// true plant, the commissioning's report, what the holds measured (none: every attempt
/// ended by a fault) and the faults that ended attempts.
struct Drawn {
    draw: hil_sim::identification::commissioning::Specimen,
    plant: hil_sim::simulation::plant::Params,
    report: ema::device::commission::Report,
    mechanics: Option<hil_sim::identification::commissioning::Mechanics>,
    faults: Vec<&'static str>,
}

/// A plant drawn off actuator `a` with `rng`, commissioned and held ([`Drawn`]).
fn holds_on_a_drawn_plant(
    a: &ema::control::actuator::Actuator,
    rng: &mut rand_pcg::Pcg64,
) -> Drawn {
    let draw = hil_sim::identification::commissioning::Specimen::new(rng);
    let o = hil_sim::identification::commissioning::run(a, Some(&draw)).unwrap();
    let report = o.report.unwrap();
    let plant = hil_sim::identification::commissioning::true_plant(a, Some(&draw)).unwrap();
    let holding =
        hil_sim::identification::commissioning::mechanics(a, &report, &plant, Some(&draw)).unwrap();
    Drawn {
        draw,
        plant,
        report,
        mechanics: holding.mechanics,
        faults: holding.faults,
    }
}

/// The product drawn with `seed` ([`holds_on_a_drawn_plant`]), its holds measured.
fn drawn_product(
    seed: u64,
) -> (
    ema::control::actuator::Actuator,
    Drawn,
    hil_sim::identification::commissioning::Mechanics,
) {
    use rand::SeedableRng;
    let (_, a) = hil_sim::simulation::actuator::load("product").unwrap();
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    eprintln!("seed {seed}");
    let d = holds_on_a_drawn_plant(&a, &mut rng);
    let m = d.mechanics.unwrap();
    (a, d, m)
}

/// Seed of the plants whose spring, mass and friction are measured.
const SPRING_SEED: u64 = 0x5b71_0000_0000_0013;

/// The spring's rate within 5 % and its preload within 2 % of the spring's force over the
/// stroke, the spring, the mass and the friction within the tolerances the file written
/// with them carries ([`hil_sim::identification::commissioning::measured`]: the
/// converters' scale and each fit's own 99 % interval), measured from the
/// closed-loop holds and the moves between them
/// ([`hil_sim::identification::commissioning::mechanics`]) on drawn products and valves
/// (sensor offset and gain errors included, corrected by the measured end stops), every
/// hold run to its end: no monitor ends them (holds that one ends measure nothing; `hil-sim
/// commission NAME --n 1000` counts them).
#[test]
fn the_spring_its_preload_and_the_mass_are_measured_from_closed_loop_holds() {
    use rand::SeedableRng;
    let mut rng = rand_pcg::Pcg64::seed_from_u64(SPRING_SEED);
    eprintln!("seed {SPRING_SEED:#x}");
    for name in ["product", "valve"] {
        let (_, a) = hil_sim::simulation::actuator::load(name).unwrap();
        for _ in 0..6 {
            let Drawn {
                draw,
                plant,
                mechanics,
                faults,
                report,
            } = holds_on_a_drawn_plant(&a, &mut rng);
            let (file, _) =
                hil_sim::identification::commissioning::measured(&a, &report, mechanics.as_ref())
                    .unwrap();
            let t = file.tolerance;
            assert!(
                faults.is_empty(),
                "{name}: attempts ended by {faults:?}; {draw:?}"
            );
            let (s, arm) = match mechanics {
                Some(m) => {
                    let errors = m.inductance_errors(&plant);
                    for (k, (probe, e)) in m.inductances.iter().zip(errors).enumerate() {
                        let Some(hil_sim::identification::commissioning::HoldInductance {
                            x_m: x,
                            inductance_h: l,
                            uncertainty_h: uncertainty,
                        }) = *probe
                        else {
                            panic!("{name}: no inductance at hold {k}; {draw:?}")
                        };
                        eprintln!(
                            "{name}: hold {k} at {:.3} mm: L {l:.4e} H ({:+.2} %, +- {:.2} %)",
                            x * 1e3,
                            100.0 * e,
                            100.0 * uncertainty / l
                        );
                        assert!(e.abs() < 0.025, "{name}: hold {k}: {e}; {draw:?}");
                    }
                    (m.spring, m.armature)
                }
                None => panic!("{name}: holds ended by {faults:?}; {draw:?}"),
            };
            let k = s.n_per_m / plant.spring_n_per_m - 1.0;
            let f0 = (s.preload_n - plant.preload_n) / (plant.spring_n_per_m * plant.stroke_m);
            eprintln!(
                "{name}: K {:.2} N/m ({:+.2} %, +- {:.2}), preload {:.4} N ({:+.2} % of K x stroke); {draw:?}",
                s.n_per_m,
                100.0 * k,
                s.uncertainty_n_per_m,
                s.preload_n,
                100.0 * f0
            );
            assert!(k.abs() < 0.05, "{name}: {s:?}, plant {plant:?}");
            assert!(k.abs() <= f64::from(t.spring), "{name}: {s:?}, {t:?}");
            assert!(f0.abs() < 0.02, "{name}: {s:?}, plant {plant:?}");
            let Some(arm) = arm else {
                panic!("{name}: no move fitted; {draw:?}")
            };
            let m = arm.mass_kg / plant.mass_kg - 1.0;
            let c = arm.friction_n_s_per_m / plant.friction_n_s_per_m - 1.0;
            eprintln!(
                "{name}: mass {:.4} kg ({:+.2} %, tolerance {:.2} %), friction {:.3} N s/m ({:+.2} %, tolerance {:.2} %); {t:?}",
                arm.mass_kg,
                100.0 * m,
                100.0 * t.mass,
                arm.friction_n_s_per_m,
                100.0 * c,
                100.0 * t.friction,
            );
            // Each within its tolerance (the mass's may be the file's: three moves leave
            // the jackknife two degrees of freedom, a wide 99 % interval).
            assert!(m.abs() <= f64::from(t.mass), "{name}: {arm:?}, {t:?}");
            assert!(c.abs() <= f64::from(t.friction), "{name}: {arm:?}, {t:?}");
        }
    }
}

/// A hold's inductance on a coil as fast as the period (its time constant 0.8 of it), its
/// current read one period late with noise, under a loop that steps it between two levels:
/// each of 300 noise realisations is read, and the uncertainty the converters' noise leaves
/// the estimate, carried through it, is what the realisations scatter. Stated for four
/// times the noise the readings carry (so that it, not the cycles' scatter, is the
/// uncertainty), it is four times their standard deviation within 15 %.
#[test]
fn a_fast_coil_s_hold_is_read_with_the_uncertainty_its_noise_leaves() {
    use hil_sim::identification::commissioning as c;
    use rand::SeedableRng;
    use rand_distr::Distribution;
    let seed = 0x4e_u64;
    eprintln!("seed {seed:#x}");
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let sigma = 0.004;
    let noise = rand_distr::Normal::new(0.0, sigma).unwrap();
    let (ts, r) = (1e-4_f64, 2.0_f64);
    let l = 0.8 * ts * r;
    let a = (-ts * r / l).exp();
    let probe = hil_sim::simulation::scenario::InductanceProbe {
        at_s: 0.0,
        amplitude_a: 0.1,
        half_ticks: c::HOLD_PROBE_HALF_TICKS,
        cycles: c::HOLD_PROBE_CYCLES,
    };
    let half = usize::from(probe.half_ticks);
    let span = c::probe_capture(probe.ticks(), 1);
    let (_, file) = hil_sim::simulation::actuator::load("product").unwrap();
    // Both stops at the coil's inductance: no flux gradient, no motion to take out.
    let report = ema::device::commission::Report {
        resistance: ema::device::commission::Resistance {
            ohm: r as f32,
            ..Default::default()
        },
        ends: ema::device::commission::Ends {
            open_m: 0.0,
            closed_m: file.mechanics.stroke_m,
            uncertainty_m: 0.0,
        },
        inductance: ema::device::commission::Inductance {
            open_h: l as f32,
            closed_h: l as f32,
        },
    };
    let line = c::Circuit::through_stops(&report, &file);
    let stated = c::ChannelNoise {
        current_a: 4.0 * sigma,
        position_m: 0.0,
        vbus_v: 0.0,
    };
    let mut capture = || -> Vec<c::ProbeSample> {
        // `cur[k]`: the true current at tick k; `read`: the reading tick k gets, that of
        // tick k - 1, with noise.
        let (mut cur, mut read) = (2.0_f64, 2.0_f64);
        (0..span)
            .map(|k| {
                let up = (k / half) % 2 == 0;
                let target = if up { 2.1 } else { 1.9 };
                let drive = r * target + 0.5 * (target - read) * l / ts;
                let q = c::ProbeSample {
                    y_m: 0.5 * f64::from(file.mechanics.stroke_m),
                    u_v: drive,
                    i_a: read,
                    vbus_v: 24.0,
                };
                read = cur + noise.sample(&mut rng);
                cur = a * cur + (1.0 - a) * drive / r;
                q
            })
            .collect()
    };
    let reads: Vec<c::HoldInductance> = (0..300)
        .map(|_| {
            let runs: Vec<Vec<c::ProbeSample>> =
                (0..c::HOLD_PROBE_RUNS).map(|_| capture()).collect();
            c::hold_inductance(&runs, &probe, 1, ts, &report, line, stated)
                .expect("a fast coil's hold is read")
        })
        .collect();
    #[expect(clippy::cast_precision_loss)]
    let n = reads.len() as f64;
    let mean = reads.iter().map(|h| h.inductance_h).sum::<f64>() / n;
    let sd = (reads
        .iter()
        .map(|h| (h.inductance_h - mean).powi(2))
        .sum::<f64>()
        / (n - 1.0))
        .sqrt();
    let stated_se = reads.iter().map(|h| 0.5 * h.uncertainty_h).sum::<f64>() / n;
    eprintln!(
        "mean {:+.2} % off, spread {:.2} %, stated for 4x the noise {:.2} % (ratio {:.3})",
        100.0 * (mean / l - 1.0),
        100.0 * sd / l,
        100.0 * stated_se / l,
        stated_se / (4.0 * sd)
    );
    assert!((mean / l - 1.0).abs() < 0.01, "{mean} against {l}");
    assert!(
        (stated_se / (4.0 * sd) - 1.0).abs() < 0.15,
        "stated {stated_se} against 4 x {sd}"
    );
}

/// The inductance probe's estimate on a coil whose every period is known exactly
/// (`i(k+1) = a i(k) + (1 - a) u(k) / R`), its current read one period late with noise,
/// under a loop that steps it between two levels without settling, the bridge dropping
/// 0.3 V the board does not see, an armature moving against the steps: within 0.5 % of
/// the true inductance for a coil whose time constant spans 2 and 200 periods, the
/// motion's flux taken out; a resistance 2 % off costs at most 2 % times a level's length
/// over twice the time constant; the motion left in reads it more than 2 % low.
#[test]
fn the_inductance_probe_reads_a_coil_within_half_a_percent() {
    use rand::SeedableRng;
    use rand_distr::Distribution;
    let seed = 0x1d_u64;
    eprintln!("seed {seed:#x}");
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let noise = rand_distr::Normal::new(0.0, 0.004).unwrap();
    let (ts, r, half) = (5e-5_f64, 0.5_f64, 16_usize);
    for periods in [2.0, 20.0, 200.0] {
        let l = periods * ts * r;
        let a = (-ts * r / l).exp();
        // An armature that moves 10 um against the current's steps, through a flux
        // gradient `i L'` of 2 A times L per millimetre: its flux is a tenth of the steps'.
        let kappa = 2.0 * l / 1e-3;
        // `cur[k]`, `x[k]`: the true current and position at tick k; `read[k]`,
        // `x_read[k]`: the readings tick k gets, those of tick k - 1, the current's with
        // noise.
        let (mut cur, mut read, mut u) = (vec![2.0_f64], vec![2.0_f64], Vec::new());
        let (mut x, mut x_read) = (vec![0.0_f64], vec![0.0_f64]);
        for k in 0..40 * half {
            let up = (k / half) % 2 == 0;
            let target = if up { 2.2 } else { 1.8 };
            // A loop on the late reading: half the error per period, plus the drop.
            let drive = r * target + 0.5 * (target - read[k]) * l / ts;
            u.push(drive);
            let to = if up { -1e-5 } else { 1e-5 };
            x.push(x[k] + 0.25 * (to - x[k]));
            let back_emf = kappa * (x[k + 1] - x[k]) / ts;
            cur.push(a * cur[k] + (1.0 - a) * (drive - 0.3 - back_emf) / r);
            read.push(cur[k] + noise.sample(&mut rng));
            x_read.push(x[k]);
        }
        // Read as two probes' captures, split between levels.
        let cut = 20 * half;
        let runs: [(&[f64], &[f64], &[f64]); 2] = [
            (&u[..cut], &read[..=cut], &x_read[..=cut]),
            (&u[cut..], &read[cut..], &x_read[cut..]),
        ];
        let read_with = |motion: f64, r_ohm: f64| {
            hil_sim::identification::commissioning::probe_inductance(
                &runs, motion, half, 1, ts, r_ohm,
            )
            .unwrap()
        };
        let (got, uncertainty) = read_with(kappa / r, r);
        eprintln!(
            "{periods} periods: {:+.3} % (+- {:.3} %)",
            100.0 * (got / l - 1.0),
            100.0 * uncertainty / l
        );
        assert!(
            (got / l - 1.0).abs() < 0.005,
            "{periods}: {got} against {l}"
        );
        assert!(
            uncertainty / l < 0.01,
            "{periods}: uncertainty {uncertainty}"
        );
        let (off, _) = read_with(kappa / r, 1.02 * r);
        let bound = 0.02 * half as f64 / (2.0 * periods) + 0.005;
        assert!(
            (off / l - 1.0).abs() < bound,
            "{periods}: {off} against {l}"
        );
        // The motion left in: several per cent low.
        let (still, _) = read_with(0.0, r);
        eprintln!("  the motion left in: {:+.2} %", 100.0 * (still / l - 1.0));
        assert!(still / l - 1.0 < -0.02, "{periods}: {still} against {l}");
    }
}

/// A valve whose magnet is 29 % weaker than its file's, on a coil 24 % above its
/// resistance and a spring 29 % stiffer: near the open stop its coil's time constant is
/// about one period, and the bus sags behind the supply's resistance as the hold's large
/// current steps. The holds' probes read every hold within 2 % of the plant's inductance
/// (left in, the sag read the one near the open stop 4 % high).
#[test]
fn a_weak_magnet_on_a_resistive_coil_has_its_holds_read_within_two_percent() {
    let (_, a) = hil_sim::simulation::actuator::load("valve").unwrap();
    let draw = hil_sim::identification::commissioning::Specimen {
        factors: hil_sim::identification::commissioning::Factors {
            surfaces: 0.71,
            resistance: 1.24,
            spring: 1.29,
            mass: 0.79,
            friction: 1.2,
        },
        preload_share: 0.0,
        gain_error: 0.0,
        offset_share: 0.0,
        noise_seed: 144,
        current: hil_sim::simulation::hal::ChannelError::default(),
        vbus: hil_sim::simulation::hal::ChannelError::default(),
        growth_share: 0.0,
    };
    let report = hil_sim::identification::commissioning::run(&a, Some(&draw))
        .unwrap()
        .report
        .unwrap();
    let plant = hil_sim::identification::commissioning::true_plant(&a, Some(&draw)).unwrap();
    let m = hil_sim::identification::commissioning::mechanics(&a, &report, &plant, Some(&draw))
        .unwrap()
        .mechanics
        .unwrap();
    for (k, e) in m.inductance_errors(&plant).into_iter().enumerate() {
        eprintln!("hold {k}: {:+.2} %", 100.0 * e);
        assert!(e.abs() < 0.02, "hold {k}: {e}");
    }
}

/// Seed of a drawn product 21 % lighter than its file with 48 % less friction.
const LIGHT_SEED: u64 = 38;

/// A drawn product 21 % lighter than its file with 48 % less friction (damping ratio 0.42
/// against the file's 0.72): the actuator its commissioning writes carries the mass's
/// tolerances its measurement leaves
/// ([`hil_sim::identification::commissioning::fitted_tolerance`] plus the circuit's share
/// of the surface tolerance, the pull's uncertainty): the mass's narrower than the file's
/// 10 %, the friction's than half its 50 %, the surfaces' than a quarter of its 20 %, each
/// holding the true error; tuned for it, it meets every target on its true plant.
#[test]
fn a_light_lightly_damped_product_is_tuned_with_the_tolerances_its_measurement_leaves() {
    let (a, d, m) = drawn_product(LIGHT_SEED);
    let (measured, _) =
        hil_sim::identification::commissioning::measured(&a, &d.report, Some(&m)).unwrap();
    let t = measured.tolerance;
    let plant = &d.plant;
    eprintln!(
        "plant: mass {:.4} kg, friction {:.3} N s/m; measured tolerances: mass {}, friction {}",
        plant.mass_kg, plant.friction_n_s_per_m, t.mass, t.friction
    );
    assert!(plant.mass_kg < 0.8 * f64::from(a.mechanics.mass_kg));
    assert!(plant.friction_n_s_per_m < 0.55 * f64::from(a.mechanics.friction_n_s_per_m));
    let mass = f64::from(measured.mechanics.mass_kg) / plant.mass_kg - 1.0;
    let friction =
        f64::from(measured.mechanics.friction_n_s_per_m) / plant.friction_n_s_per_m - 1.0;
    let curve = hil_sim::identification::commissioning::curve_error(&measured, plant).unwrap();
    eprintln!(
        "errors: mass {:+.2} %, friction {:+.2} %, inductance over the stroke {:.2} %",
        100.0 * mass,
        100.0 * friction,
        100.0 * curve
    );
    assert!(
        mass.abs() <= f64::from(t.mass) && t.mass < a.tolerance.mass,
        "{t:?}"
    );
    // The mass's: the fit's own and the pull's share of the surface tolerance.
    let arm = m.armature.unwrap();
    let own = hil_sim::identification::commissioning::fitted_tolerance(
        arm.mass_kg,
        arm.mass_uncertainty_kg,
        arm.moves - 1,
    );
    let pull = f64::from(t.surface) - hil_sim::identification::commissioning::CONVERTER_SCALE;
    eprintln!("mass: the fit's own {own:.4}, the pull's {pull:.4}");
    assert!(
        (f64::from(t.mass) - (own + pull)).abs() < 1e-6,
        "{t:?} {own} {pull}"
    );
    // A mass read with two standard errors as large as itself: its 99 % interval reaches
    // zero, it has not been measured, and the file keeps its own mass and tolerance.
    let mut vague = m;
    if let Some(arm) = vague.armature.as_mut() {
        arm.mass_uncertainty_kg = arm.mass_kg;
    }
    let (kept, _) =
        hil_sim::identification::commissioning::measured(&a, &d.report, Some(&vague)).unwrap();
    assert_eq!(
        (kept.mechanics.mass_kg, kept.tolerance.mass),
        (a.mechanics.mass_kg, a.tolerance.mass)
    );
    assert_eq!(
        kept.mechanics.friction_n_s_per_m,
        measured.mechanics.friction_n_s_per_m
    );
    assert!(
        friction.abs() <= f64::from(t.friction) && t.friction < 0.5 * a.tolerance.friction,
        "{t:?}"
    );
    // The holds' probes read the circuit: a surface tolerance under a quarter of the
    // file's 20 %, holding the true curve. Had they read it 30 % below its form, the
    // tolerance would cover that.
    assert!(
        curve <= f64::from(t.surface) && t.surface < 0.25 * a.tolerance.surface,
        "{t:?}"
    );
    let deviation = m.form_deviation(&measured).unwrap();
    eprintln!(
        "the form within {:.2} % of the holds' probes",
        100.0 * deviation
    );
    assert!(deviation < 0.05, "{deviation}");
    let mut off = m;
    for p in off.inductances.iter_mut().flatten() {
        p.inductance_h *= 0.7;
    }
    let (wider, _) =
        hil_sim::identification::commissioning::measured(&a, &d.report, Some(&off)).unwrap();
    assert!(wider.tolerance.surface > 0.42, "{:?}", wider.tolerance);
    let c = hil_sim::identification::commissioning::closed_loop(
        &a,
        &d.report,
        Some(&m),
        plant,
        Some(&d.draw),
    )
    .unwrap();
    eprintln!("{c:?}");
    assert_eq!(c.misses(), Vec::<&str>::new(), "{c:?}");
}

/// Seed of a drawn product whose best point of a coarse grid misses a target with the
/// file's tolerances.
const BETWEEN_SEED: u64 = 46;

/// A drawn product (15 % heavier, spring 25 % stiffer, coil 24 % above its file)
/// commissioned, its surfaces' and spring's tolerances left at the file's (20 % and 10 %,
/// a datasheet's), the mass's 8 % and the friction's 5 % of the critical damping (what a
/// commissioning wrote for it when this was written): on a coarse grid (every other
/// `alpha` of `tune`'s) no point meets every target on every corner plant; the refinement
/// between the grid's points ([`hil_sim::analysis::tune::REFINE_SEEDS`]) finds gains that
/// meet every target on every corner, and they meet every target on the true plant.
#[test]
fn a_product_a_coarse_grid_misses_is_tuned_between_its_points() {
    let (a, d, m) = drawn_product(BETWEEN_SEED);
    let (mut measured, _) =
        hil_sim::identification::commissioning::measured(&a, &d.report, Some(&m)).unwrap();
    measured.tolerance.surface = a.tolerance.surface;
    measured.tolerance.spring = a.tolerance.spring;
    measured.tolerance.mass = 0.08;
    let mech = measured.mechanics;
    let critical = 2.0 * (mech.spring_n_per_m * mech.mass_kg).sqrt();
    measured.tolerance.friction = 0.05 * critical / mech.friction_n_s_per_m;
    let rate = f64::from(a.board.rate_hz);
    // A coarse grid: every other `alpha` of tune's own.
    let mut space = hil_sim::analysis::tune::Space::for_actuator(&measured, rate).unwrap();
    space.alpha = space.alpha.iter().copied().step_by(2).collect();
    let tuned = hil_sim::analysis::tune::tune(
        "between",
        &measured,
        &[rate],
        &space,
        1,
        hil_sim::identification::commissioning::CLOSED_LOOP_VALIDATION,
    )
    .unwrap();
    let chosen = tuned.chosen.as_ref().expect("tuned").candidate;
    eprintln!("chosen {chosen:?}; grid {space:?}");
    let on_grid = space.candidates(rate).contains(&chosen);
    assert!(!on_grid, "{chosen:?} is a grid point");
    let mut sc = hil_sim::simulation::actuator::scenario("between", &tuned.tuned.unwrap()).unwrap();
    sc.plant = hil_sim::simulation::scenario::TruePlant::Given(d.plant.clone());
    let run = hil_sim::simulation::sim::run(&sc).unwrap();
    let targets = hil_sim::simulation::targets::Targets::for_scenario(&sc);
    let worst = hil_sim::simulation::targets::Worst::of([&run.metrics], &targets);
    assert_eq!(worst.misses(&targets), Vec::<&str>::new(), "{worst:?}");
}

/// Family member `name`'s plant with each airgap's surface growing with the gap as a
/// square pole's fringing does, `(a + k g)^2` (the paper's rectangular-pole form with
/// `k` for its 1), the file's surface at mid-stroke, and the energy-consistent force
/// `-dL/dg` such a surface gives: the file, the plant and the growth `q` \[1/m\].
fn growing(
    name: &str,
    k: f64,
) -> (
    ema::control::actuator::Actuator,
    hil_sim::simulation::plant::Params,
    f64,
) {
    let (_, a) = hil_sim::simulation::actuator::load(name).unwrap();
    let mut plant = hil_sim::identification::commissioning::true_plant(&a, None).unwrap();
    let mid = plant.gap_m(0.5 * plant.stroke_m);
    let side = plant.gaps[0].area_m2(mid).sqrt() - k * mid;
    for g in &mut plant.gaps {
        *g = hil_sim::simulation::plant::Surface::Rectangular {
            a_m: side,
            b_m: side,
            spread: k,
        };
    }
    plant.force = hil_sim::simulation::plant::ForceModel::EnergyConsistent;
    (a, plant, k / side)
}

/// A product whose airgap surface grows with the gap (`k = 0.3`: 37 % more surface at
/// the open stop than at the closed one): the stops' two inductances alone model its
/// inductance more than 10 % off between them. The circuit fitted to them and to the
/// holds' probes ([`hil_sim::identification::commissioning::Circuit::fit`]) reads the
/// growth within 5 % and the curve within 0.5 % over the stroke; with its pull the spring
/// is read within 1 % and the mass within 2 %; the actuator written carries the growth
/// (`fringing_spread`), and, tuned, meets every target on the plant.
#[test]
fn a_surface_growing_with_the_gap_is_fitted_and_the_commissioned_loop_meets_its_targets() {
    use hil_sim::identification::commissioning as c;
    let (a, plant, growth) = growing("product", 0.3);
    let report = c::run_on(&a, &plant, None).unwrap().report.unwrap();
    let m = c::mechanics(&a, &report, &plant, None)
        .unwrap()
        .mechanics
        .unwrap();
    let (stops, _) = c::measured(&a, &report, None).unwrap();
    let (fitted, _) = c::measured(&a, &report, Some(&m)).unwrap();
    let (line, curve) = (
        c::curve_error(&stops, &plant).unwrap(),
        c::curve_error(&fitted, &plant).unwrap(),
    );
    let q = m.circuit.growth_per_m / growth - 1.0;
    let k = m.spring.n_per_m / plant.spring_n_per_m - 1.0;
    let mass = m.armature.unwrap().mass_kg / plant.mass_kg - 1.0;
    eprintln!(
        "growth {:.2} 1/m ({:+.2} %); curve: stops' line {:.2} %, fitted {:.3} %; spring {:+.2} %, mass {:+.2} %; {:?}",
        m.circuit.growth_per_m,
        100.0 * q,
        100.0 * line,
        100.0 * curve,
        100.0 * k,
        100.0 * mass,
        fitted.magnetics
    );
    assert!(line > 0.1, "{line}");
    assert!(q.abs() < 0.05, "{:?}", m.circuit);
    assert!(curve < 0.005, "{curve}");
    assert!(k.abs() < 0.01, "{:?}", m.spring);
    assert!(mass.abs() < 0.02, "{:?}", m.armature);
    let ema::control::actuator::Magnetics::Geometry {
        fringing_spread, ..
    } = fitted.magnetics
    else {
        panic!("{:?}", fitted.magnetics)
    };
    assert!(fringing_spread > 0.2, "{fringing_spread}");
    let closed = c::closed_loop(&a, &report, Some(&m), &plant, None).unwrap();
    eprintln!("{closed:?}");
    assert_eq!(closed.misses(), Vec::<&str>::new(), "{closed:?}");
}

/// A 12 V solenoid whose pole grows by a quarter of the gap, its file in the
/// two-inductance form, which carries no growth: the circuit fitted to the stops and the
/// holds reads the growth within 5 % and the spring within 2 %, but the file written
/// through the fitted circuit's stop values models the inductance about 7 % off between
/// them. It says so: its surface tolerance, the controller's uncertainty set, is that
/// deviation ([`hil_sim::identification::commissioning::Mechanics::form_deviation`]) and
/// the converters' scale, over the 5 % the routine is held to, and, tuned for it, the
/// loop meets every target on the plant. (A pole growing by 0.3 of the gap, about 9 %
/// off, is refused by `tune`: on the smallest surface of that set the moves need the
/// rated current and half a per cent more.)
#[test]
fn a_two_inductance_file_carries_a_growing_surface_as_its_uncertainty() {
    use hil_sim::identification::commissioning as c;
    let (a, plant, growth) = growing("solenoid-12v", 0.25);
    assert!(matches!(
        a.magnetics,
        ema::control::actuator::Magnetics::Inductance { .. }
    ));
    let report = c::run_on(&a, &plant, None).unwrap().report.unwrap();
    let m = c::mechanics(&a, &report, &plant, None)
        .unwrap()
        .mechanics
        .unwrap();
    let (fitted, _) = c::measured(&a, &report, Some(&m)).unwrap();
    let curve = c::curve_error(&fitted, &plant).unwrap();
    let q = m.circuit.growth_per_m / growth - 1.0;
    let k = m.spring.n_per_m / plant.spring_n_per_m - 1.0;
    let surface = f64::from(fitted.tolerance.surface);
    eprintln!(
        "growth {:+.2} %, spring {:+.2} %; curve of the file {:.2} % off, its surface tolerance {:.2} %",
        100.0 * q,
        100.0 * k,
        100.0 * curve,
        100.0 * surface
    );
    assert!(q.abs() < 0.05, "{:?}", m.circuit);
    assert!(k.abs() < 0.02, "{:?}", m.spring);
    assert!(curve > 0.05, "{curve}");
    assert!(surface > 0.9 * curve, "{surface} against {curve}");
    let closed = c::closed_loop(&a, &report, Some(&m), &plant, None).unwrap();
    eprintln!("{closed:?}");
    assert_eq!(closed.misses(), Vec::<&str>::new(), "{closed:?}");
}

/// Readings of a circuit whose surface is constant, each off by less than its own
/// standard deviation in a pattern a growing surface would explain better: the fit keeps
/// the surface constant ([`hil_sim::identification::commissioning::GROWTH_SIGNIFICANCE`])
/// and the line within 0.3 % of the true inductance over the stroke. The same fit reads a
/// growing surface's readings, as far off, within 5 % of its growth.
#[test]
fn the_circuit_fit_keeps_a_growth_only_where_the_readings_ask_for_it() {
    use hil_sim::identification::commissioning::{Circuit, CURVE_POSITIONS};
    for (k, grows) in [(0.0, false), (0.3, true)] {
        let (a, plant, growth) = growing("product", k);
        let at = |x: f64| plant.inductance_h(plant.gap_m(x));
        let stroke = plant.stroke_m;
        // Ends high, middle low: the shape a growth gives `1/L`; 2 standard errors 0.5 %.
        let off = [0.002, -0.002, -0.002, 0.002];
        let holds: Vec<Option<hil_sim::identification::commissioning::HoldInductance>> =
            hil_sim::simulation::actuator::SEQUENCE
                .iter()
                .zip(off)
                .map(|(f, e)| {
                    let l = at(f * stroke) * (1.0 + e);
                    Some(hil_sim::identification::commissioning::HoldInductance {
                        x_m: f * stroke,
                        inductance_h: l,
                        uncertainty_h: 0.005 * l,
                    })
                })
                .collect();
        let report = ema::device::commission::Report {
            inductance: ema::device::commission::Inductance {
                open_h: (at(0.0) * 1.002) as f32,
                closed_h: (at(stroke) * 1.002) as f32,
            },
            ..Default::default()
        };
        let fit = Circuit::fit(&report, &a, &holds);
        #[expect(clippy::cast_precision_loss)]
        let worst = (0..CURVE_POSITIONS)
            .map(|j| stroke * j as f64 / (CURVE_POSITIONS - 1) as f64)
            .map(|x| (fit.inductance_h(x) / at(x) - 1.0).abs())
            .fold(0.0, f64::max);
        eprintln!(
            "k {k}: growth {:.3} 1/m (plant {growth:.3}), curve within {:.3} %",
            fit.growth_per_m,
            100.0 * worst
        );
        if grows {
            assert!((fit.growth_per_m / growth - 1.0).abs() < 0.05, "{fit:?}");
        } else {
            assert_eq!(fit.growth_per_m, 0.0, "{fit:?}");
            assert!(worst < 0.003, "{worst}");
        }
    }
}

/// A loop that limit-cycles about its holds ends each window at another speed than it
/// started it: the window's mean pull is then the spring's plus the armature's mean
/// inertia and friction. Four holds of the product oscillating by 1 % of the stroke, 1.1
/// cycles per window, the pull exactly what the motion asks: with the mass and the
/// friction the moves read, [`hil_sim::identification::commissioning::fit_spring`] reads
/// the rate within 0.1 % and the preload within 0.1 % of `K x stroke`; without them, about
/// 2 % off.
#[test]
fn a_hold_that_limit_cycles_reads_the_spring_with_the_armature_s_inertia_taken_out() {
    use core::f64::consts::PI;
    use hil_sim::identification::commissioning::{fit_spring, Circuit};
    let (_, a) = hil_sim::simulation::actuator::load("product").unwrap();
    let plant = hil_sim::identification::commissioning::true_plant(&a, None).unwrap();
    let stroke = plant.stroke_m;
    let at = |x: f64| plant.inductance_h(plant.gap_m(x));
    let report = ema::device::commission::Report {
        inductance: ema::device::commission::Inductance {
            open_h: at(0.0) as f32,
            closed_h: at(stroke) as f32,
        },
        ends: ema::device::commission::Ends {
            open_m: 0.0,
            closed_m: stroke as f32,
            uncertainty_m: 0.0,
        },
        ..Default::default()
    };
    let circuit = Circuit::through_stops(&report, &a);
    let (m, c, k, f0) = (
        plant.mass_kg,
        plant.friction_n_s_per_m,
        plant.spring_n_per_m,
        plant.preload_n,
    );
    let (n, window_s) = (256_usize, 0.1);
    let dt = window_s / n as f64;
    let w = 2.0 * PI * 1.1 / window_s;
    let amplitude = 0.01 * stroke;
    let holds = core::array::from_fn(|h| {
        let centre = hil_sim::simulation::actuator::SEQUENCE[h] * stroke;
        let phase = 0.7 * h as f64;
        (0..n)
            .map(|j| {
                let t = (j as f64 + 0.5) * dt;
                let x = centre + amplitude * (w * t + phase).sin();
                let v = amplitude * w * (w * t + phase).cos();
                let acc = -amplitude * w * w * (w * t + phase).sin();
                let f = k * x + f0 + m * acc + c * v;
                (x, (2.0 * f / circuit.force_coefficient_h_per_m(x)).sqrt())
            })
            .collect::<Vec<_>>()
    });
    let with = fit_spring(&report, circuit, &holds, dt, Some((m, c)));
    let without = fit_spring(&report, circuit, &holds, dt, None);
    let rate = |s: &hil_sim::identification::commissioning::Spring| 100.0 * (s.n_per_m / k - 1.0);
    let preload = |s: &hil_sim::identification::commissioning::Spring| {
        100.0 * (s.preload_n - f0) / (k * stroke)
    };
    eprintln!(
        "rate error {:+.4} % (without the inertia {:+.2} %), preload {:+.4} % of K x stroke",
        rate(&with),
        rate(&without),
        preload(&with)
    );
    assert!(rate(&with).abs() < 0.1, "{with:?}");
    assert!(preload(&with).abs() < 0.1, "{with:?}");
    assert!(rate(&without).abs() > 1.0, "{without:?}");
}

/// Seed of a drawn 12 V solenoid 27 % lighter than its file, with 44 % less friction.
const LIGHT_SOLENOID_SEED: u64 = 18;

/// Seed of a drawn 50 kHz pilot 26 % lighter than its file, with 47 % more friction.
const LIGHT_PILOT_SEED: u64 = 82;

/// The holds on the file `name`'s plant drawn with `seed`, an armature lighter than its
/// file's: the first attempt ends by the monitor `first`, a slower one measures the
/// spring and the mass within the tolerances the file written with them carries, and the
/// actuator time counts every attempt.
fn a_slower_attempt_measures(name: &str, seed: u64, first: &str) {
    use hil_sim::identification::commissioning as c;
    use rand::SeedableRng;
    let (_, a) = hil_sim::simulation::actuator::load(name).unwrap();
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    eprintln!("{name}, seed {seed}");
    let d = holds_on_a_drawn_plant(&a, &mut rng);
    assert!(d.plant.mass_kg < 0.8 * f64::from(a.mechanics.mass_kg));
    let holding = c::mechanics(&a, &d.report, &d.plant, Some(&d.draw)).unwrap();
    eprintln!(
        "attempts ended by {:?}; {:.3} s",
        holding.faults, holding.took_s
    );
    assert_eq!(holding.faults.first(), Some(&first));
    let m = holding.mechanics.unwrap();
    let k = m.spring.n_per_m / d.plant.spring_n_per_m - 1.0;
    let arm = m.armature.unwrap();
    let mass = arm.mass_kg / d.plant.mass_kg - 1.0;
    eprintln!("K {:+.2} %, mass {:+.2} %", 100.0 * k, 100.0 * mass);
    let (file, _) = c::measured(&a, &d.report, Some(&m)).unwrap();
    let t = file.tolerance;
    assert!(k.abs() <= f64::from(t.spring), "{k}: {t:?}");
    assert!(mass.abs() <= f64::from(t.mass), "{mass}: {t:?}");
    // Every attempt's time: more than one whole attempt's holds.
    let (measured, _) = c::measured(&a, &d.report, None).unwrap();
    let one_s = hil_sim::simulation::actuator::scenario("holds", &measured)
        .unwrap()
        .duration_s;
    assert!(holding.took_s > one_s + 0.01, "{} s", holding.took_s);
}

/// A drawn solenoid 27 % lighter than its file: held with the default tuning, the
/// observer (with the file's mass) carries its velocity on after the light armature has
/// stopped, and the stuck-sensor monitor ends the holds. The holds run again with a slower
/// loop ([`hil_sim::identification::commissioning::hold_tuning`]) and measure the spring
/// and the mass.
#[test]
fn holds_a_monitor_ends_run_again_with_a_slower_loop_and_measure_the_armature() {
    a_slower_attempt_measures("solenoid-12v", LIGHT_SOLENOID_SEED, "position_stuck");
}

/// A drawn 50 kHz pilot 26 % lighter than its file: held with the default tuning, the
/// observer's disturbance runs away on the first move and the residual detector names
/// `current_stuck`; a slower loop measures the spring and the mass (gentler moves alone
/// did not: three attempts measured nothing).
#[test]
fn a_light_pilot_whose_observer_runs_away_is_measured_with_a_slower_loop() {
    a_slower_attempt_measures("pilot-50khz", LIGHT_PILOT_SEED, "current_stuck");
}

/// Seed of the drawn specimens whose surfaces' shapes are counted, and of the growing
/// product commissioned.
const GROWTH_SEED: u64 = 0x6a0f_0000_0000_0044;

/// The specimens `hil-sim commission` draws include airgap surfaces that grow with the
/// gap: of 200 draws (draw `k` from the seed plus `k`, as the command's), between 80 and
/// 120 give the product a true plant whose surface is larger at the open stop than at the
/// closed one, each within the file's 20 % surface tolerance of its own mid-stroke value
/// at both stops (the others a constant one); the largest growth the rule allows
/// ([`hil_sim::identification::commissioning::largest_spread`], `k` 0.36 on the
/// product's pole) reaches it at the open stop, far inside the largest the fit considers
/// ([`hil_sim::identification::commissioning::GROWTH_MAX`]). The first of them grown by
/// more than half of that is commissioned within its targets: the resistance within 2 %,
/// the stops' inductances within 5 % and their readings within 2 codes; its holds' fitted
/// circuit models the inductance within 1 % over the stroke where the stops' line alone
/// is more than 5 % off, the spring within its written tolerance; tuned, it meets every
/// target on its true plant.
#[test]
fn drawn_specimens_include_growing_surfaces_and_one_is_commissioned_within_its_targets() {
    use hil_sim::identification::commissioning as c;
    use rand::SeedableRng;
    let (_, a) = hil_sim::simulation::actuator::load("product").unwrap();
    let file = c::true_plant(&a, None).unwrap();
    let (g_closed, g_open) = file.gap_range_m();
    let mid = 0.5 * (g_closed + g_open);
    let largest = c::largest_spread(file.gaps[0], 0.2, (g_closed, g_open));
    let side = file.gaps[0].area_m2(mid).sqrt() - largest * mid;
    let q_open = largest / side * g_open;
    eprintln!("largest spread {largest:.3}, q g at the open stop {q_open:.3}");
    assert!((largest - 0.36).abs() < 0.005, "{largest}");
    assert!(q_open < c::GROWTH_MAX / 3.0, "{q_open}");
    let draws: Vec<(c::Specimen, hil_sim::simulation::plant::Params)> = (0..200)
        .map(|k| {
            let mut rng = rand_pcg::Pcg64::seed_from_u64(GROWTH_SEED + k);
            let draw = c::Specimen::new(&mut rng);
            let plant = c::true_plant(&a, Some(&draw)).unwrap();
            (draw, plant)
        })
        .collect();
    let mut growing = 0;
    for (draw, plant) in &draws {
        let s = |g: f64| plant.gaps[0].area_m2(g) / plant.gaps[0].area_m2(mid);
        let (open, closed) = (s(g_open), s(g_closed));
        if draw.growth_share > 0.0 {
            growing += 1;
            assert!(open > closed, "{draw:?}: {open} {closed}");
            assert!(
                open <= 1.2 + 1e-9 && closed >= 0.8 - 1e-9,
                "{draw:?}: {open} {closed}"
            );
            // The largest growth reaches the tolerance at the open stop.
            let full = open - 1.0 - 0.2 * draw.growth_share;
            assert!(full.abs() < 0.02, "{draw:?}: {open}");
        } else {
            assert_eq!(open, closed, "{draw:?}");
        }
    }
    eprintln!("{growing} of {} draws grow", draws.len());
    assert!((80..=120).contains(&growing), "{growing}");
    let (draw, plant) = draws
        .iter()
        .find(|(d, _)| d.growth_share > 0.5)
        .unwrap()
        .clone();
    let o = c::run(&a, Some(&draw)).unwrap();
    let e = o.errors().unwrap();
    let report = o.report.unwrap();
    let m = c::mechanics(&a, &report, &plant, Some(&draw))
        .unwrap()
        .mechanics
        .unwrap();
    let (fitted, _) = c::measured(&a, &report, Some(&m)).unwrap();
    let curve = c::curve_error(&fitted, &plant).unwrap();
    let spring = m.spring.n_per_m / plant.spring_n_per_m - 1.0;
    eprintln!(
        "{draw:?}\n{e:?}\nfitted curve {:.2} %, spring {:+.2} % (tolerance {:.2} %), growth {:?}",
        100.0 * curve,
        100.0 * spring,
        100.0 * fitted.tolerance.spring,
        m.circuit
    );
    assert!(e.resistance.abs() < 0.02, "{e:?}");
    assert!(
        e.inductance_open.abs() < 0.05 && e.inductance_closed.abs() < 0.05,
        "{e:?}"
    );
    assert!(e.open_codes < 2.0 && e.closed_codes < 2.0, "{e:?}");
    assert!(e.curve > 0.05, "{e:?}");
    assert!(curve < 0.01, "{curve}");
    assert!(m.circuit.growth_per_m > 0.0, "{:?}", m.circuit);
    assert!(
        spring.abs() < f64::from(fitted.tolerance.spring),
        "{spring}"
    );
    let closed = c::closed_loop(&a, &report, Some(&m), &plant, Some(&draw)).unwrap();
    eprintln!("{closed:?}");
    assert_eq!(closed.misses(), Vec::<&str>::new(), "{closed:?}");
}

/// Every actuator of the development seed's draw (`hil-sim actuators --draw 24 --seed
/// 101`: 2 g to 2 kg, coils of 0.05 to 100 ms) is commissioned on its file's plant: the
/// routine ends with a report whatever the coil's time constant against the armature's
/// period. A coil slower than its armature holds the armature at the closed stop until
/// its current has decayed, so the armature flies back inside the open stop's window,
/// which must be averaged again (the patience allows at least one restart).
#[test]
fn every_drawn_actuator_of_the_development_seed_is_commissioned_on_its_file_s_plant() {
    use rayon::prelude::*;
    let seed = hil_sim::analysis::seeds::DRAWN_DEVELOPMENT;
    let n = 24;
    println!("seed {seed}, {n} actuators");
    let outcomes: Vec<(String, Result<f64, String>)> = (0..n)
        .into_par_iter()
        .map(|k| {
            let d = hil_sim::analysis::drawn::draw_one(seed, k).unwrap();
            let o = hil_sim::identification::commissioning::run(&d.actuator, None).unwrap();
            let got = match o.report {
                Ok(_) => Ok(o.took_s),
                Err(abort) => Err(abort.name().to_owned()),
            };
            (d.name(), got)
        })
        .collect();
    let failed: Vec<_> = outcomes.iter().filter(|(_, o)| o.is_err()).collect();
    let longest = outcomes
        .iter()
        .filter_map(|(_, o)| o.as_ref().ok().copied())
        .fold(0.0, f64::max);
    println!("routine at most {longest:.2} s of actuator time");
    assert!(failed.is_empty(), "{failed:?}");
}

/// A commissioning whose measurements make an actuator no file can hold (here a spring
/// read pushing the wrong way) is counted as a refused file, named by the rule it breaks,
/// not an error that ends the batch it is in: `bench commission` refuses to write such a
/// file, and `hil-sim commission --tune` counts the draw as a miss and goes on.
#[test]
fn a_measured_actuator_that_breaks_a_rule_is_refused_by_name_in_closed_loop() {
    use hil_sim::identification::commissioning::{self, ClosedLoop};
    let (_, a) = hil_sim::simulation::actuator::load("product").unwrap();
    let o = commissioning::run(&a, None).unwrap();
    let report = o.report.unwrap();
    let plant = commissioning::true_plant(&a, None).unwrap();
    let mut m = commissioning::mechanics(&a, &report, &plant, None)
        .unwrap()
        .mechanics
        .unwrap();
    m.spring.n_per_m = -m.spring.n_per_m;
    let c = commissioning::closed_loop(&a, &report, Some(&m), &plant, None).unwrap();
    let ClosedLoop::Refused(why) = &c else {
        panic!("{c:?}")
    };
    assert!(why.contains("mechanics.spring_n_per_m"), "{why}");
    assert_eq!(c.misses(), ["refused"]);
}

/// Drawn actuator 233 of the development seed: a coil whose time constant at the open
/// stop is about half the period: its decay is over within the converter's delay and a
/// reading or two. The routine's readings there are as far off as
/// the converter's noise leaves them, and within the 99 % interval that noise gives
/// ([`hil_sim::identification::commissioning::stop_uncertainty`]); where that interval is
/// wider than the file's surface tolerance, the file written without the holds keeps the
/// file's open inductance, not the reading, and so does the circuit fitted without a
/// hold's probe.
#[test]
fn a_fast_coil_s_open_stop_is_read_within_what_its_noise_leaves() {
    use hil_sim::identification::commissioning::{
        measured, open_stop_interval, run, Circuit, Specimen,
    };
    use rand::SeedableRng;
    let a = hil_sim::analysis::drawn::draw_one(hil_sim::analysis::seeds::DRAWN_DEVELOPMENT, 233)
        .unwrap()
        .actuator;
    let t = a.time_scales().unwrap();
    let periods = t.coil_open_s * a.board.rate_hz;
    assert!(periods < 0.6, "open stop's time constant {periods} periods");
    let file_open_h = t.coil_open_s * a.coil.resistance_ohm;
    let seed = hil_sim::analysis::seeds::COMMISSION_DEVELOPMENT;
    eprintln!("specimens from seed {seed}");
    let (mut outside, mut kept, mut worst) = (0, 0, 0.0_f64);
    let n = 40;
    for k in 0..n {
        let draw = Specimen::new(&mut rand_pcg::Pcg64::seed_from_u64(seed + k));
        let o = run(&a, Some(&draw)).unwrap();
        let (Ok(r), Some(e)) = (o.report, o.errors()) else {
            continue;
        };
        let interval = open_stop_interval(&r, &a);
        worst = worst.max(e.inductance_open.abs());
        outside += usize::from(e.inductance_open.abs() > interval);
        let (written, _) = measured(&a, &r, None).unwrap();
        let ema::control::actuator::Magnetics::Inductance { open_h, .. } = written.magnetics else {
            panic!("{:?}", written.magnetics)
        };
        // The circuit fitted without a hold's probe: through the stops, the open one's
        // value as the file written carries it.
        let fitted = Circuit::fit(&r, &a, &[]).inductance_h(0.0);
        assert!(
            (fitted / f64::from(open_h) - 1.0).abs() < 1e-3,
            "{fitted} {open_h}"
        );
        if interval > f64::from(a.tolerance.surface) {
            kept += 1;
            assert!(
                (open_h / file_open_h - 1.0).abs() < 1e-6,
                "{open_h} {file_open_h}"
            );
        } else {
            assert!(
                (open_h / r.inductance.open_h - 1.0).abs() < 0.05,
                "{open_h}"
            );
        }
    }
    eprintln!(
        "worst open stop error {:.1} %; outside its 99 % interval: {outside} of {n}; the file's kept on {kept}",
        100.0 * worst
    );
    // The readings are far off (the noise, not the method) ...
    assert!(worst > 0.2, "{worst}");
    // ... and within what the noise leaves them, as a 99 % interval holds them.
    assert!(outside <= 1, "{outside} of {n} outside");
    assert!(kept > 0, "{kept}");
}

/// A drawn actuator whose file's poles grow with the gap (actuator 12 of the development
/// seed: two gaps, 605 g, 1.38 mm), its specimens drawn with the file's own shape: the
/// true plant pulls with `-dL/dg`, its growth included, as a real magnet does and as the
/// commissioning's fit reads it, and the holds read the mass within 3 % on each of six
/// draws. With the paper's frozen-surface force on such a plant (the pull without the
/// surface's growth), the same draws read the mass 19 % to 38 % light.
#[test]
fn a_file_s_own_growing_surface_pulls_with_its_growth_and_the_mass_is_read() {
    use hil_sim::identification::commissioning as c;
    use rand::SeedableRng;
    let d = hil_sim::analysis::drawn::draw_one(hil_sim::analysis::seeds::DRAWN_DEVELOPMENT, 12)
        .unwrap();
    let a = d.actuator;
    assert!(
        matches!(a.magnetics, ema::control::actuator::Magnetics::Geometry { fringing_spread, .. } if fringing_spread > 0.0),
        "{:?}",
        a.magnetics
    );
    let seed = hil_sim::analysis::seeds::COMMISSION_DEVELOPMENT;
    println!(
        "{}, specimens of seed {seed}, the file's shape kept",
        d.name()
    );
    for k in 0..6 {
        let mut draw = c::Specimen::new(&mut rand_pcg::Pcg64::seed_from_u64(seed + k));
        draw.growth_share = 0.0;
        let plant = c::true_plant(&a, Some(&draw)).unwrap();
        assert_eq!(
            plant.force,
            hil_sim::simulation::plant::ForceModel::EnergyConsistent
        );
        let report = c::run(&a, Some(&draw)).unwrap().report.unwrap();
        let m = c::mechanics(&a, &report, &plant, Some(&draw))
            .unwrap()
            .mechanics
            .unwrap();
        let mass = m.armature.unwrap().mass_kg / plant.mass_kg - 1.0;
        println!("draw {k}: mass {:+.2} %", 100.0 * mass);
        assert!(mass.abs() < 0.03, "draw {k}: {mass}");
    }
}
