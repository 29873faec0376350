//! `hil-sim commission <name> [--n N --seed S --tune]`: the board's commissioning routine
//! on an actuator's file against N plants drawn wider than it (see
//! [`crate::identification::commissioning::Specimen`]), in parallel: the identification errors'
//! median, 99th percentile and maximum, the actuator time, the largest coil current, the
//! endings; then the spring, the mass and the friction measured from closed-loop holds
//! ([`crate::identification::commissioning::mechanics`]); with `--tune`, each commissioned
//! actuator tuned and run in closed loop on its true plant, through the drawn converter
//! with the position sensor's correction from the end stops applied: the steady error is
//! judged on the true position.

use std::collections::BTreeMap;
use std::io::Write;

use rand::SeedableRng;
use rayon::prelude::*;

use crate::analysis::report::{sig, Table};
use crate::identification::commissioning::{self, Specimen};
use crate::simulation::actuator;
use ema::control::actuator::Tolerances;

/// Arguments of `commission`.
#[derive(Clone, Debug, PartialEq, Eq, clap::Args)]
pub struct Args {
    /// A family member's name or an actuator file.
    pub actuator: String,
    /// Plants drawn.
    #[arg(long, default_value_t = 1000)]
    pub n: usize,
    /// Seed of the draws (draw k from seed + k); by default the one commissioning is
    /// judged on ([`crate::analysis::seeds::COMMISSION_JUDGE`]).
    #[arg(long, default_value_t = crate::analysis::seeds::COMMISSION_JUDGE)]
    pub seed: u64,
    /// Also tune each commissioned actuator and run it in closed loop on its true plant,
    /// its drawn converter and the correction from the end stops (see
    /// [`commissioning::closed_loop`]): the share that meets every target.
    #[arg(long)]
    pub tune: bool,
}

/// The quantities judged, with their targets (the inductance over the stroke is judged
/// apart: [`STOPS_LINE`]).
const QUANTITIES: [Quantity; 5] = [
    ("resistance error [%]", 2.0, |e| 100.0 * e.resistance),
    ("inductance error, open stop [%]", 5.0, |e| {
        100.0 * e.inductance_open
    }),
    ("inductance error, closed stop [%]", 5.0, |e| {
        100.0 * e.inductance_closed
    }),
    ("open stop reading error [codes]", 2.0, |e| e.open_codes),
    ("closed stop reading error [codes]", 2.0, |e| e.closed_codes),
];

/// The rows of the inductance's error over the stroke of the two-inductance form through
/// the stops' readings: judged on the specimens whose surface is constant, the only ones
/// that form models; on those whose surface grows with the gap it cannot (the holds'
/// fitted circuit models them, judged below), and the error is reported only.
const STOPS_LINE: [(&str, bool, Option<f64>); 2] = [
    (
        "inductance error over the stroke, stops' line, constant surfaces [%]",
        false,
        Some(5.0),
    ),
    ("same, surfaces growing with the gap [%]", true, None),
];

/// A row of [`QUANTITIES`]: its label, its target and its value in the label's unit.
type Quantity = (&'static str, f64, fn(&commissioning::Errors) -> f64);

/// What the holds read wrong, relative unless named otherwise (NaN: not read), and the
/// tolerances the file written with them carries ([`commissioning::measured`]).
#[derive(Clone, Copy, Debug, PartialEq)]
struct MechanicsErrors {
    /// The spring's rate.
    spring: f64,
    /// The preload, as a share of the spring's force over the stroke.
    preload: f64,
    /// The mass (NaN: no move fitted).
    mass: f64,
    /// The friction (NaN: no move fitted).
    friction: f64,
    /// The friction, as a share of the critical damping `2 sqrt(K m)`.
    friction_damping: f64,
    /// The largest inductance error over the holds' probes.
    held: f64,
    /// The largest over the holds' probes of the error, against the true inductance in
    /// the converters' units ([`Specimen::channel_factor`]), over its 99 % interval.
    held_over_interval: f64,
    /// The inductance curve's over the stroke, of the circuit fitted with the holds.
    fitted: f64,
    /// The tolerances the file written carries (NaN: no file written).
    tolerance: Tolerances,
    /// How far the true spring's rate, mass and friction lie from the value the file
    /// written carries, relative to it (the measured value where the measurement wrote
    /// it, the file's own where it did not: [`commissioning::measured`]), as a tolerance
    /// reads it: the plant is inside the file's set when this is within the tolerance;
    /// NaN: no file written.
    written: [f64; 3],
    /// Whether the file written carries the measured spring's rate, mass and friction
    /// (not its own: the measurement's 99 % interval did not reach zero).
    from_measurement: [bool; 3],
}

impl MechanicsErrors {
    /// [`MechanicsErrors::written`]'s `q`-th (spring, mass, friction) over the tolerance
    /// the file written carries for it \[-\]: above one, the true plant is outside.
    fn written_over_tolerance(&self, q: usize) -> f64 {
        let t = &self.tolerance;
        let tolerance = [t.spring, t.mass, t.friction][q];
        self.written[q] / f64::from(tolerance)
    }
}

/// A row of [`MECHANICS`]: its label, its target in the label's unit (none: reported
/// only) and its value in that unit.
type MechanicsRow = (&'static str, Option<f64>, fn(&MechanicsErrors) -> f64);

/// The holds' rows. The file's tolerances are judged against the true errors: an error
/// over its tolerance is a plant `tune` never validated on and the controller's robust
/// model does not cover.
const MECHANICS: [MechanicsRow; 15] = [
    ("spring rate error [%]", None, |e| 100.0 * e.spring),
    ("spring rate tolerance written [%]", None, |e| {
        100.0 * f64::from(e.tolerance.spring)
    }),
    (
        "spring rate written, error / its tolerance",
        Some(1.0),
        |e| e.written_over_tolerance(0),
    ),
    ("preload error [% of K x stroke]", None, |e| {
        100.0 * e.preload
    }),
    ("mass error [%]", None, |e| 100.0 * e.mass),
    ("mass tolerance written [%]", None, |e| {
        100.0 * f64::from(e.tolerance.mass)
    }),
    ("mass written, error / its tolerance", Some(1.0), |e| {
        e.written_over_tolerance(1)
    }),
    ("friction error [%]", None, |e| 100.0 * e.friction),
    ("friction error [% of the critical damping]", None, |e| {
        100.0 * e.friction_damping
    }),
    ("friction tolerance written [%]", None, |e| {
        100.0 * f64::from(e.tolerance.friction)
    }),
    ("friction written, error / its tolerance", Some(1.0), |e| {
        e.written_over_tolerance(2)
    }),
    ("inductance error at the holds [%]", Some(5.0), |e| {
        100.0 * e.held
    }),
    (
        "same, in the converters' units, over its 99 % interval",
        Some(1.0),
        |e| e.held_over_interval,
    ),
    (
        "inductance error over the stroke, fitted [%]",
        Some(5.0),
        |e| 100.0 * e.fitted,
    ),
    ("same, over the surface tolerance written", Some(1.0), |e| {
        e.fitted / f64::from(e.tolerance.surface)
    }),
];

/// Actuator time a commissioning may take, the board's routine and the holds \[s\].
pub const COMMISSIONING_S: f64 = 10.0;

/// What one specimen's commissioning gave: the board's routine, then (when it
/// commissioned) the holds' errors, the faults that ended an attempt at them and their
/// actuator time \[s\], and with `--tune` the tuned loop on the true plant.
type Commissioned = (
    commissioning::Outcome,
    Option<(Option<MechanicsErrors>, Vec<&'static str>, f64)>,
    Option<commissioning::ClosedLoop>,
);

/// Specimen `k` of `args`' seed commissioned off the file `a` ([`Commissioned`]).
fn commission(
    a: &ema::control::actuator::Actuator,
    args: &Args,
    k: usize,
) -> Result<Commissioned, crate::Error> {
    let draw = draw(args.seed, k);
    let o = commissioning::run(a, Some(&draw))?;
    let plant = commissioning::true_plant(a, Some(&draw))?;
    let Ok(r) = o.report else {
        return Ok((o, None, None));
    };
    let holding = commissioning::mechanics(a, &r, &plant, Some(&draw))?;
    let mechanics = holding.mechanics.as_ref();
    let errors = mechanics.map(|m| mechanics_errors(a, &r, m, &plant, &draw));
    let closed = if args.tune {
        Some(commissioning::closed_loop(
            a,
            &r,
            mechanics,
            &plant,
            Some(&draw),
        )?)
    } else {
        None
    };
    Ok((o, Some((errors, holding.faults, holding.took_s)), closed))
}

/// Specimen `k` of the draws from `seed`: draw `k` from `seed + k`.
fn draw(seed: u64, k: usize) -> Specimen {
    Specimen::new(&mut rand_pcg::Pcg64::seed_from_u64(
        seed.wrapping_add(k as u64),
    ))
}

/// What the holds `m` of a commissioning whose routine reported `r` read wrong on the
/// true `plant` with the converters of `draw`, and the tolerances the file written with
/// them carries.
fn mechanics_errors(
    a: &ema::control::actuator::Actuator,
    r: &ema::device::commission::Report,
    m: &commissioning::Mechanics,
    plant: &crate::simulation::plant::Params,
    draw: &Specimen,
) -> MechanicsErrors {
    // Relative mass and friction errors (NaN: no move fitted).
    let (mass, friction) = m.armature.map_or((f64::NAN, f64::NAN), |arm| {
        (
            arm.mass_kg / plant.mass_kg - 1.0,
            arm.friction_n_s_per_m / plant.friction_n_s_per_m - 1.0,
        )
    });
    let critical = 2.0 * (plant.spring_n_per_m * plant.mass_kg).sqrt();
    // The largest over the holds (NaN: a probe read nothing).
    let errors = m.inductance_errors(plant);
    let held = errors
        .iter()
        .fold(0.0, |w, e| crate::simulation::targets::worse(w, e.abs()));
    let held_over_interval = m.inductances.iter().zip(errors).fold(0.0, |w, (h, e)| {
        let over = h.map_or(f64::NAN, |h| {
            ((1.0 + e) / draw.channel_factor() - 1.0).abs() / (h.interval_h() / h.inductance_h)
        });
        crate::simulation::targets::worse(w, over)
    });
    // The circuit and the tolerances the file written with the holds carries.
    let file = commissioning::measured(a, r, Some(m)).map(|(f, _)| f);
    let fitted = file
        .as_ref()
        .ok()
        .and_then(|f| commissioning::curve_error(f, plant).ok())
        .unwrap_or(f64::NAN);
    let written = file.as_ref().map_or([f64::NAN; 3], |f| {
        [
            plant.spring_n_per_m / f64::from(f.mechanics.spring_n_per_m) - 1.0,
            plant.mass_kg / f64::from(f.mechanics.mass_kg) - 1.0,
            plant.friction_n_s_per_m / f64::from(f.mechanics.friction_n_s_per_m) - 1.0,
        ]
    });
    let from_measurement = file.as_ref().map_or([false; 3], |f| {
        [
            f.mechanics.spring_n_per_m != a.mechanics.spring_n_per_m,
            f.mechanics.mass_kg != a.mechanics.mass_kg,
            f.mechanics.friction_n_s_per_m != a.mechanics.friction_n_s_per_m,
        ]
    });
    let tolerance = file.map_or(
        Tolerances {
            surface: f32::NAN,
            mass: f32::NAN,
            spring: f32::NAN,
            friction: f32::NAN,
            resistance: f32::NAN,
        },
        |f| f.tolerance,
    );
    MechanicsErrors {
        spring: m.spring.n_per_m / plant.spring_n_per_m - 1.0,
        preload: (m.spring.preload_n - plant.preload_n) / (plant.spring_n_per_m * plant.stroke_m),
        mass,
        friction,
        friction_damping: friction * plant.friction_n_s_per_m / critical,
        held,
        held_over_interval,
        fitted,
        tolerance,
        written,
        from_measurement,
    }
}

/// Runs the draws and prints the table.
///
/// # Errors
/// An unknown actuator; a failed write.
pub fn run(args: &Args, out: &mut dyn Write) -> anyhow::Result<()> {
    let (name, a) = actuator::load(&args.actuator)?;
    let runs = (0..args.n)
        .into_par_iter()
        .map(|k| commission(&a, args, k))
        .collect::<Result<Vec<_>, crate::Error>>()?;
    let outcomes: Vec<_> = runs.iter().map(|(o, _, _)| *o).collect();
    let rated = f64::from(a.coil.rated_current_a);
    let mut endings: BTreeMap<&str, usize> = BTreeMap::new();
    // Each commissioned specimen's errors, whether its surface grows with the gap, and the
    // 99 % interval the converter's noise leaves the open stop's inductance, relative.
    let mut errors: Vec<(commissioning::Errors, bool, f64)> = Vec::new();
    for (k, o) in outcomes.iter().enumerate() {
        match (o.report, o.errors()) {
            (Ok(r), Some(e)) => errors.push((
                e,
                draw(args.seed, k).growth_share > 0.0,
                commissioning::open_stop_interval(&r, &a),
            )),
            (Err(abort), _) => *endings.entry(abort.name()).or_default() += 1,
            (Ok(_), None) => {}
        }
    }
    let growing = (0..args.n).filter(|&k| draw(args.seed, k).growth_share > 0.0);
    writeln!(
        out,
        "{name}: {} plants drawn wider than the file (seed {}): surfaces, R, K, m +-30 %, the file's preload +-30 % (or an unknown one), friction +-50 %, sensor offset and gain +-3 %, current and bus channels +-0.5 % and +-2 codes; surfaces growing with the gap within the file's surface tolerance over the stroke: {}",
        args.n,
        args.seed,
        growing.count()
    )?;
    let mut t = Table::new([
        "quantity",
        "median",
        "99th percentile",
        "max",
        "target",
        "over it",
    ]);
    let row = |t: &mut Table, what: &str, v: Vec<f64>, target: Option<f64>| {
        t.push(distribution_row(what, v, target));
    };
    for (what, target, value) in &QUANTITIES {
        let v = errors.iter().map(|(e, _, _)| value(e).abs()).collect();
        row(&mut t, what, v, Some(*target));
    }
    // The open stop of a coil whose time constant there is about the period is read from
    // few, small readings: what the noise leaves it, and the error against that where the
    // reading is written (within the file's surface tolerance; the file's value otherwise).
    let v = errors.iter().map(|(_, _, u)| 100.0 * u).collect();
    row(
        &mut t,
        "inductance uncertainty, open stop, 99 % [%]",
        v,
        None,
    );
    let surface = f64::from(a.tolerance.surface);
    let v = errors
        .iter()
        .filter(|(_, _, u)| *u <= surface)
        .map(|(e, _, u)| e.inductance_open.abs() / u)
        .collect();
    row(
        &mut t,
        "same, error over it where the reading is written",
        v,
        Some(1.0),
    );
    for (what, grows, target) in STOPS_LINE {
        let v = errors
            .iter()
            .filter(|(_, g, _)| *g == grows)
            .map(|(e, _, _)| 100.0 * e.curve)
            .collect();
        row(&mut t, what, v, target);
    }
    // The faults that ended an attempt at the holds, and those that ended the last.
    let mut attempts_faulted: BTreeMap<&str, usize> = BTreeMap::new();
    let mut holds_faulted: BTreeMap<&str, usize> = BTreeMap::new();
    let mut mechanics: Vec<MechanicsErrors> = Vec::new();
    // Holds measured on an attempt after the first.
    let mut retried = 0;
    for (s, faults, _) in runs.iter().filter_map(|(_, s, _)| s.as_ref()) {
        for f in faults {
            *attempts_faulted.entry(f).or_default() += 1;
        }
        match (s, faults.last()) {
            (Some(e), _) => {
                mechanics.push(*e);
                retried += usize::from(!faults.is_empty());
            }
            (None, last) => *holds_faulted.entry(last.unwrap_or(&"none")).or_default() += 1,
        }
    }
    for (what, target, value) in MECHANICS {
        let v = mechanics.iter().map(|e| value(e).abs()).collect();
        row(&mut t, what, v, target);
    }
    let unfitted = mechanics.iter().filter(|e| e.mass.is_nan()).count();
    let took = outcomes.iter().map(|o| o.took_s).collect();
    let with_holds = runs
        .iter()
        .map(|(o, s, _)| o.took_s + s.as_ref().map_or(0.0, |(_, _, held_s)| *held_s))
        .collect();
    let peak = outcomes.iter().map(|o| 100.0 * o.peak_a / rated).collect();
    row(&mut t, "actuator time, the board's routine [s]", took, None);
    row(
        &mut t,
        "actuator time, routine and holds [s]",
        with_holds,
        Some(COMMISSIONING_S),
    );
    row(
        &mut t,
        "largest coil current [% of the rating]",
        peak,
        Some(100.0),
    );
    write!(out, "{}", t.to_text())?;
    if args.tune {
        write_tuned(&runs, args.seed, out)?;
    }
    let endings: Vec<String> = endings.iter().map(|(k, v)| format!("{k} {v}")).collect();
    writeln!(
        out,
        "commissioned: {} of {} (the open stop's inductance from the file, the reading's 99 % interval wider than the surface tolerance: {}); stopped: {}",
        errors.len(),
        args.n,
        errors.iter().filter(|(_, _, u)| *u > surface).count(),
        if endings.is_empty() {
            "none".to_owned()
        } else {
            endings.join(", ")
        }
    )?;
    let named = |m: &BTreeMap<&str, usize>| {
        if m.is_empty() {
            "none".to_owned()
        } else {
            m.iter()
                .map(|(k, v)| format!("{k} {v}"))
                .collect::<Vec<_>>()
                .join(", ")
        }
    };
    writeln!(
        out,
        "spring measured on {} of the {} commissioned, the mass and the friction on {} (no move to fit: {unfitted}); attempts at the holds ended by a fault: {} (measured on a slower attempt: {retried}); holds that measured nothing: {}",
        mechanics.len(),
        errors.len(),
        mechanics.len() - unfitted,
        named(&attempts_faulted),
        named(&holds_faulted),
    )?;
    // Of the values the measurement wrote (`true`) or the file kept: how many, and how
    // many the true value lies outside the tolerance of.
    let count = |q: usize, wrote: bool| {
        let of: Vec<_> = mechanics
            .iter()
            .filter(|e| e.from_measurement[q] == wrote)
            .collect();
        let over = of
            .iter()
            .filter(|e| {
                let r = e.written_over_tolerance(q).abs();
                r > 1.0 || r.is_nan()
            })
            .count();
        format!("{} ({over} over)", of.len())
    };
    writeln!(
        out,
        "the file written carries the measured spring on {}, mass on {}, friction on {} of the {}; the file's own value and tolerance, where the measurement's 99 % interval reached zero, on {}, {}, {}",
        count(0, true),
        count(1, true),
        count(2, true),
        mechanics.len(),
        count(0, false),
        count(1, false),
        count(2, false),
    )?;
    Ok(())
}

/// The `--tune` lines: how many of the tuned `runs` (draw `k` from `seed + k`) meet every
/// target on their true plant, and which targets the others missed, with their seeds;
/// then, for each draw `tune` found no gains for, its diagnosis.
fn write_tuned(runs: &[Commissioned], seed: u64, out: &mut dyn Write) -> std::io::Result<()> {
    let mut misses: BTreeMap<&str, usize> = BTreeMap::new();
    let mut tuned = 0;
    let mut passed = 0;
    // Of them, those whose surface grows with the gap: tuned, passed.
    let mut growing = (0, 0);
    // The seed of each draw that missed: `--seed S --n 1` runs it again.
    let mut seeds = Vec::new();
    // `tune`'s diagnosis of each draw it found no gains for.
    let mut refusals = Vec::new();
    for (k, c) in runs
        .iter()
        .enumerate()
        .filter_map(|(k, (_, _, c))| Some((k, c.as_ref()?)))
    {
        tuned += 1;
        let grows = draw(seed, k).growth_share > 0.0;
        growing.0 += usize::from(grows);
        let m = c.misses();
        if m.is_empty() {
            passed += 1;
            growing.1 += usize::from(grows);
        } else {
            seeds.push(seed.wrapping_add(k as u64).to_string());
        }
        match c {
            commissioning::ClosedLoop::Untuned(why) => {
                refusals.push((seed.wrapping_add(k as u64), "not tuned", why));
            }
            commissioning::ClosedLoop::Refused(why) => {
                refusals.push((seed.wrapping_add(k as u64), "measured file refused", why));
            }
            commissioning::ClosedLoop::Ran { .. } => {}
        }
        for what in m {
            *misses.entry(what).or_default() += 1;
        }
    }
    let misses: Vec<String> = misses.iter().map(|(k, v)| format!("{k} {v}")).collect();
    writeln!(
        out,
        "tuned at the board's rate and run on the true plant: {passed} of {tuned} meet every target ({} of the {} whose surface grows with the gap); missed: {}",
        growing.1,
        growing.0,
        if misses.is_empty() {
            "none".to_owned()
        } else {
            format!("{} (seeds {})", misses.join(", "), seeds.join(", "))
        }
    )?;
    for (s, what, why) in refusals {
        writeln!(out, "{what}, seed {s}: {why}")?;
    }
    Ok(())
}

/// One row of the commission table: the median, the 99th percentile and the maximum of
/// the values of `v` that could be read, the target, and how many are over it (empty: a
/// quantity without one), where a NaN (a value that could not be read: a probe that read
/// nothing, a move not fitted) counts as over.
#[expect(
    clippy::cast_precision_loss,
    clippy::cast_possible_truncation,
    clippy::cast_sign_loss
)]
fn distribution_row(what: &str, v: Vec<f64>, target: Option<f64>) -> [String; 6] {
    let over = target.map_or(String::new(), |target| {
        v.iter()
            .filter(|x| x.is_nan() || **x > target)
            .count()
            .to_string()
    });
    let mut v: Vec<f64> = v.into_iter().filter(|x| !x.is_nan()).collect();
    v.sort_by(f64::total_cmp);
    let at = |q: f64| {
        v.get(((v.len() as f64 - 1.0) * q).round() as usize)
            .copied()
    };
    let [m, p, x] = [at(0.5), at(0.99), v.last().copied()].map(|x| x.unwrap_or(f64::NAN));
    [
        what.to_owned(),
        sig(m, 3),
        sig(p, 3),
        sig(x, 3),
        target.map_or(String::new(), |t| sig(t, 2)),
        over,
    ]
}

#[cfg(test)]
mod tests {
    use super::distribution_row;

    /// A value that could not be read counts as over its target, and stays out of the
    /// quantiles.
    #[test]
    fn a_value_not_read_counts_as_over_its_target() {
        let r = distribution_row("q", vec![1.0, f64::NAN, 3.0, 2.0], Some(2.5));
        assert_eq!(r[1], "2");
        assert_eq!(r[3], "3");
        assert_eq!(r[5], "2");
        let r = distribution_row("q", vec![1.0, f64::NAN], None);
        assert_eq!(r[5], "");
    }
}
