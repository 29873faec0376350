//! `tune`: the practical law's gains for any actuator, searched on its own time scales,
//! checked against Theorem 1, chosen by the worst case over the uncertainty set at several
//! interrupt rates.
//!
//! 1. **The current loop is fixed by the bounds**: `reach` puts its pole at
//!    `1 - 0.7 L_lo / L`, never negative over the bounds; `integral` is fixed
//!    ([`ema::control::law::practical::REACH`],
//!    [`ema::control::law::practical::INTEGRAL`]).
//! 2. **The search space comes from the actuator** ([`Space::for_actuator`]): `alpha`
//!    (`alpha1 = alpha2`, error poles `-alpha +- j`) on a half-octave grid through the
//!    default gain, from a tenth to ten times its mechanical frequency
//!    ([`ema::control::actuator::TimeScales::mechanical_rad_s`]), below a tenth of the
//!    interrupt rate; the observer bandwidth as a multiple of `alpha`; the shaping margin.
//!    What the coil can follow is found by the simulation, not assumed. No bound is a
//!    number tuned on one actuator.
//! 3. **Theorem 1** as the practical law has it
//!    ([`crate::analysis::lyapunov::Problem::practical`]): the error system must be
//!    quadratically stable over every force gain the loop can meet; a candidate that fails
//!    it is not simulated.
//! 4. **Screening, then the worst case**: every candidate runs once on the nominal plant at
//!    the actuator's own rate; those within [`SCREEN`] of the targets are then run, best
//!    first, on the 49 corner plants of the uncertainty set ([`corners`]) at every rate, each judged by the actuator's targets
//!    ([`crate::simulation::targets::Targets::for_scenario`]). The score is the largest
//!    `worst / target` over the metrics, the plants and the rates (the ripple against
//!    [`RIPPLE_RESERVE`] of its target); a candidate stops at its first miss. A run in
//!    which a fault latches misses whatever follows, so it stops at the fault
//!    ([`crate::simulation::sim::Until::Fault`]); a screening run also stops at the
//!    first sample that makes a move miss its settling target
//!    ([`crate::simulation::sim::Until::Miss`]): it is not run on the corners whatever
//!    follows, so the same candidates go on, at a fraction of the screening's time.
//! 5. **Validation**: a candidate that meets every target on every corner then runs on a
//!    Monte Carlo sample of drawn plants at every rate (interior plants and other noise
//!    realisations find what the corners miss). The first candidate, in screening order,
//!    that passes both is chosen. The draws run a chunk at a time, and a candidate that
//!    misses stops after the chunk where it does
//!    ([`crate::analysis::montecarlo::montecarlo_until_miss`]): one that passes runs them
//!    all, so the choice is the same.
//! 6. **Refinement**: when no point of the grid passes, the [`REFINE_SEEDS`] best are
//!    refined: their neighbours half a grid step away (`alpha` and the observer a factor
//!    `2^(1/4)` either way, the margin halfway to the next) are screened, run on the
//!    corners and validated the same way. An actuator whose best grid point misses a
//!    target by a few per cent is often met between the points. When none passes, the
//!    best of all so far are refined again at half that step ([`REFINE_ROUNDS`]).
//!
//! When no candidate passes, [`Report::refusal`] names the target that stays out of
//! reach on the best candidate, at which rate, and by how much.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use ema::control::actuator::{Actuator, Tuning};
use ema::control::Settings;

use crate::analysis::lyapunov::{Bound, Problem};
use crate::analysis::montecarlo::montecarlo_until_miss;
use crate::simulation::plant::{ForceModel, Params, Surface};
use crate::simulation::scenario::{Scenario, TruePlant};
use crate::simulation::sim::{with_run_until, Until};
use crate::simulation::targets::{Targets, Worst};
use crate::simulation::Error;

/// Plants drawn to validate a candidate, per rate, unless told otherwise.
pub const DEFAULT_VALIDATE: usize = 100;

/// Control rates the board offers between 10 and 50 kHz (each divides TIM1's 84 MHz
/// half-clock, so a centre-aligned period is a whole number of counts) \[Hz\].
pub const BOARD_RATES_HZ: [f64; 5] = [10e3, 20e3, 25e3, 40e3, 50e3];

/// The default rates: the actuator's own, 20 kHz (the rate the product's Monte Carlo
/// and fault tables are run at), and the one of [`BOARD_RATES_HZ`] nearest to the
/// actuator's own by ratio (the lower first on a tie): three rates, so that the gains hold
/// when the rate moves to a neighbour.
#[must_use]
pub fn default_rates(own_hz: f64) -> Vec<f64> {
    let mut out = vec![own_hz];
    let reference = 20e3;
    if (reference - own_hz).abs() > 0.5 {
        out.push(reference);
    }
    let mut others: Vec<f64> = BOARD_RATES_HZ
        .into_iter()
        .filter(|r| out.iter().all(|o| (r - o).abs() > 0.5))
        .collect();
    others.sort_by(|a, b| (a / own_hz).ln().abs().total_cmp(&(b / own_hz).ln().abs()));
    out.extend(others.into_iter().take(3 - out.len()));
    out
}

/// One point of the search.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Candidate {
    /// `alpha1 = alpha2` \[1/s\].
    pub alpha: f64,
    /// Observer bandwidth at the actuator's own rate \[rad/s\].
    pub observer_rad_s: f64,
    /// Reference-shaping margin \[-\].
    pub margin: f64,
    /// The observer's disturbance follows the magnet's force.
    pub follows_force: bool,
}

impl Candidate {
    /// As the actuator file's tuning section.
    #[must_use]
    #[expect(clippy::cast_possible_truncation)]
    pub fn tuning(&self) -> Tuning {
        Tuning {
            alpha_per_s: self.alpha as f32,
            observer_rad_s: self.observer_rad_s as f32,
            margin: self.margin as f32,
            disturbance_follows_force: self.follows_force,
        }
    }

    /// The refinement's points around this one, itself left out: `alpha` and the observer
    /// by `factor` either way, the margin halfway to its neighbours in `margins`
    /// (sorted), the disturbance model kept.
    fn neighbours(&self, margins: &[f64], factor: f64) -> Vec<Candidate> {
        let below = margins.iter().copied().rfind(|m| *m < self.margin);
        let above = margins.iter().copied().find(|m| *m > self.margin);
        let mut ms = vec![self.margin];
        ms.extend(below.map(|m| round3(0.5 * (m + self.margin))));
        ms.extend(above.map(|m| round3(0.5 * (m + self.margin))));
        let steps = [1.0 / factor, 1.0, factor];
        let mut out = Vec::new();
        for a in steps {
            for o in steps {
                for &margin in &ms {
                    let c = Candidate {
                        alpha: round3(self.alpha * a),
                        observer_rad_s: round3(self.observer_rad_s * o),
                        margin,
                        follows_force: self.follows_force,
                    };
                    if c != *self {
                        out.push(c);
                    }
                }
            }
        }
        out
    }
}

/// The search space.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Space {
    /// Values of `alpha` \[1/s\].
    pub alpha: Vec<f64>,
    /// Observer bandwidths per unit of `alpha` \[-\].
    pub observer_per_alpha: Vec<f64>,
    /// Shaping margins \[-\].
    pub margin: Vec<f64>,
}

/// Candidates whose score on the nominal plant is above this are not run on the corners:
/// the worst corner is never better than the nominal plant \[-\].
pub const SCREEN: f64 = 1.0;
// A screening run stops at a certain miss (`Until::Miss`), which only a screen of 1 allows.
const _: () = assert!(SCREEN <= 1.0);

/// Ratio of neighbouring points of the `alpha` grid: half an octave. The grid runs through
/// the default gain ([`ema::control::actuator::DEFAULT_ALPHA_PER_W`] times the mechanical
/// frequency) in these steps both ways until it covers [`ALPHA_LOW_PER_W`] to
/// [`ALPHA_HIGH_PER_W`], so an untuned file's own gain is always a candidate (15 points).
pub const ALPHA_STEP: f64 = std::f64::consts::SQRT_2;
/// The bottom of the `alpha` grid per unit of the mechanical frequency: a loop ten times
/// slower than the actuator's own dynamics leaves the disturbance estimate to do all the
/// work \[-\].
pub const ALPHA_LOW_PER_W: f64 = 0.1;
/// The top of the `alpha` grid per unit of the mechanical frequency, before the sampling
/// cap: a loop ten times faster than the actuator's dynamics only amplifies the sensors'
/// noise \[-\].
pub const ALPHA_HIGH_PER_W: f64 = 10.0;
/// Largest `alpha` per unit of the lowest interrupt rate in rad/s: the error poles
/// `-alpha +- j` of a loop sampled with one period of delay keep their damping only well
/// below the sampling rate, about a tenth of it \[-\].
pub const ALPHA_PER_RATE: f64 = 0.1;
/// Observer bandwidths, per unit of `alpha`.
pub const OBSERVER_PER_ALPHA: [f64; 6] = [0.7, 1.0, 1.5, 2.5, 4.0, 6.0];
/// Shaping margins.
pub const MARGINS: [f64; 9] = [0.01, 0.025, 0.05, 0.1, 0.2, 0.35, 0.5, 0.7, 0.85];

impl Space {
    /// The search space of an actuator (see the module documentation): `alpha` from
    /// [`ALPHA_LOW_PER_W`] to [`ALPHA_HIGH_PER_W`] times its mechanical frequency in
    /// [`ALPHA_STEP`]s through the default gain, those above [`ALPHA_PER_RATE`] of the lowest interrupt rate
    /// `rate_min_hz` in rad/s left out (the lowest point is kept); the observer at
    /// [`OBSERVER_PER_ALPHA`] times `alpha`, below a quarter of the Nyquist rate; the
    /// [`MARGINS`]. What the coil can follow is not assumed: a gain that asks for more
    /// current or voltage than it gives misses its targets in the simulation.
    ///
    /// # Errors
    /// An actuator whose settings do not derive, by name.
    pub fn for_actuator(act: &Actuator, rate_min_hz: f64) -> Result<Self, Error> {
        let ts = act.time_scales().map_err(Error::Actuator)?;
        let w = f64::from(ts.mechanical_rad_s());
        let cap = ALPHA_PER_RATE * 2.0 * std::f64::consts::PI * rate_min_hz;
        let default = f64::from(ema::control::actuator::DEFAULT_ALPHA_PER_W);
        let steps = |per_w: f64| (per_w / default).ln() / ALPHA_STEP.ln();
        #[expect(clippy::cast_possible_truncation)]
        let (low, high) = (
            steps(ALPHA_LOW_PER_W).floor() as i32,
            steps(ALPHA_HIGH_PER_W).ceil() as i32,
        );
        let alpha: Vec<f64> = (low..=high)
            .map(|k| round3(default * w * ALPHA_STEP.powi(k)))
            .enumerate()
            .filter(|&(k, a)| k == 0 || a <= cap)
            .map(|(_, a)| a)
            .collect();
        Ok(Self {
            alpha,
            observer_per_alpha: OBSERVER_PER_ALPHA.to_vec(),
            margin: MARGINS.to_vec(),
        })
    }

    /// Every candidate of the space at an actuator whose own rate is `rate_hz`, in the
    /// order `alpha`, observer, margin, disturbance model (observers at or above
    /// [`observer_limit_rad_s`] are left out).
    #[must_use]
    pub fn candidates(&self, rate_hz: f64) -> Vec<Candidate> {
        let nyquist_quarter = observer_limit_rad_s(rate_hz);
        let mut out = Vec::new();
        for &alpha in &self.alpha {
            for &k in &self.observer_per_alpha {
                let observer_rad_s = round3(k * alpha);
                if observer_rad_s >= nyquist_quarter {
                    continue;
                }
                for &margin in &self.margin {
                    for follows_force in [true, false] {
                        out.push(Candidate {
                            alpha,
                            observer_rad_s,
                            margin,
                            follows_force,
                        });
                    }
                }
            }
        }
        out
    }
}

/// The observer bandwidths `tune` tries stay below a quarter of the Nyquist rate of the
/// actuator's own rate `rate_hz`, `pi / (4 Ts)` \[rad/s\].
#[must_use]
pub fn observer_limit_rad_s(rate_hz: f64) -> f64 {
    0.25 * std::f64::consts::PI * rate_hz
}

/// Three significant digits: tuned files carry round numbers.
fn round3(v: f64) -> f64 {
    format!("{v:.2e}").parse().unwrap_or(v)
}

/// Theorem 1 for one candidate.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Theorem {
    /// Smallest force gain the loop meets \[-\].
    pub gamma_min: f64,
    /// Largest force gain \[-\].
    pub gamma_max: f64,
    /// Bound on the unmodelled acceleration before the disturbance estimate \[m/s^2\].
    pub delta_mps2: f64,
    /// Ball radius with `P = I` \[m\] (`None`: not quadratically stable with `P = I`).
    pub radius_identity_m: Option<f64>,
    /// Ball radius with the optimised `P` \[m\] (`None`: no Lyapunov matrix found).
    pub radius_optimised_m: Option<f64>,
}

impl Theorem {
    /// `true` when a common Lyapunov matrix exists over the force gains.
    #[must_use]
    pub fn holds(&self) -> bool {
        self.radius_optimised_m.is_some()
    }
}

/// Theorem 1 for the practical law with `alpha`, on the actuator of `settings`.
///
/// # Errors
/// Invalid plant parameters.
pub fn theorem(settings: &Settings, alpha: f64) -> Result<Theorem, Error> {
    let plant = &settings.plant;
    let env = plant.envelope()?;
    let robust = plant.robust_dynamics()?;
    let (g_lo, g_hi) = plant.convention.gap_range_m(plant.stroke_m);
    // theta = mu / mu_lo over the stroke, at most mu_hi / mu_lo.
    let theta_max = (0..=100)
        .map(|k| {
            let g = g_lo + (g_hi - g_lo) * k as f32 / 100.0;
            f64::from(env.mu_hi(g) / env.mu_lo(g))
        })
        .fold(1.0, f64::max);
    let t = &plant.tolerance;
    let m_d = f64::from(robust.mass_kg);
    let m = f64::from(plant.mass_kg);
    let (m_lo, m_hi) = (m * (1.0 - f64::from(t.mass)), m * (1.0 + f64::from(t.mass)));
    let gamma_min = m_d / m_hi;
    let gamma_max = theta_max * m_d / m_lo;
    // What the model leaves before the disturbance estimate: (gamma - 1) r'' plus the
    // spring (and preload) and friction mismatch at the end of the stroke and the fastest
    // move.
    let stroke = f64::from(plant.stroke_m);
    let k = f64::from(plant.spring_n_per_m);
    let f0 = f64::from(plant.preload_n);
    let lam = f64::from(plant.friction_n_s_per_m);
    let a_ref = settings
        .shaping
        .map_or(10.0, |s| f64::from(s.accel_max_mps2));
    let v_ref = 1.875 * (a_ref * stroke / 5.773_503).sqrt();
    let spring_lo = 1.0 - f64::from(t.spring);
    let k_err = theta_max * f64::from(robust.spring_n_per_m) - k * spring_lo;
    let f0_err = theta_max * f64::from(robust.preload_n) - f0 * spring_lo;
    let l_err =
        theta_max * f64::from(robust.friction_n_s_per_m) - lam * (1.0 - f64::from(t.friction));
    let delta = (gamma_max - 1.0).max(1.0 - gamma_min) * a_ref
        + (k_err.abs() * stroke + f0_err.abs() + l_err.abs() * v_ref) / m_lo;
    let problem = Problem::practical(alpha, alpha, gamma_min, gamma_max, delta);
    let radius = |b: Option<Bound>| b.map(|b| b.radius_per_m);
    Ok(Theorem {
        gamma_min,
        gamma_max,
        delta_mps2: delta,
        radius_identity_m: radius(problem.identity()),
        radius_optimised_m: radius(problem.optimise()),
    })
}

/// The corner plants: the nominal plant first, then every combination of mass, spring
/// (with its preload), friction and resistance at either end of their tolerance with each
/// of three airgaps: the surface constant at the physical lower bound, constant at the
/// upper bound (frozen force: the two ends of the paper's uncertainty), and growing across
/// the stroke from the lower bound to the upper one with the energy-consistent force (the
/// weakest pull the bounds allow at the open end, see `ema::control::actuator`). 49 plants.
#[must_use]
pub fn corners(plant: &ema::control::model::Plant) -> Vec<Params> {
    let nominal = Params::from_core(plant, ForceModel::Frozen);
    let t = &plant.tolerance;
    // Surfaces just inside the physical bounds (the draw margin of the Monte Carlo).
    let physical = plant.physical_bounds();
    let s_lo = f64::from(physical.s_lo_m2) * (1.0 + 1e-6);
    let s_hi = f64::from(physical.s_hi_m2) * (1.0 - 1e-6);
    let (g_lo, g_hi) = nominal.gap_range_m();
    let grown = {
        let (r1, r2) = (s_lo.sqrt(), s_hi.sqrt());
        let k = (r2 - r1) / (g_hi - g_lo).max(f64::MIN_POSITIVE);
        let a = r1 - k * g_lo;
        (a > 0.0).then_some(Surface::Rectangular {
            a_m: a,
            b_m: a,
            spread: k,
        })
    };
    let surfaces = [
        (Surface::Constant { s_m2: s_lo }, ForceModel::Frozen),
        (Surface::Constant { s_m2: s_hi }, ForceModel::Frozen),
        (
            grown.unwrap_or(Surface::Constant { s_m2: s_lo }),
            ForceModel::EnergyConsistent,
        ),
    ];
    let mut out = vec![nominal.clone()];
    for bits in 0..16_u32 {
        let pick = |bit: u32, rel: f32| {
            if bits & (1 << bit) == 0 {
                1.0 - f64::from(rel)
            } else {
                1.0 + f64::from(rel)
            }
        };
        for (surface, force) in surfaces {
            let mut p = nominal.clone();
            for gap in &mut p.gaps {
                *gap = surface;
            }
            p.force = force;
            p.mass_kg *= pick(0, t.mass);
            p.spring_n_per_m *= pick(1, t.spring);
            p.preload_n *= pick(1, t.spring);
            p.friction_n_s_per_m *= pick(2, t.friction);
            p.resistance_ohm *= pick(3, t.resistance);
            out.push(p);
        }
    }
    out
}

/// A candidate's results.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Evaluation {
    /// The candidate.
    pub candidate: Candidate,
    /// Theorem 1.
    pub theorem: Theorem,
    /// Largest `worst / target` on the nominal plant at the actuator's own rate.
    pub screen: f64,
    /// Worst metrics over the plants run, per rate (empty when it was not run on the
    /// corners).
    pub worst: Vec<Worst>,
    /// Largest `worst / target` over the metrics, plants and rates run (below 1: every
    /// target holds); infinite when a run faulted or Theorem 1 failed.
    pub score: f64,
    /// Every corner plant at every rate was run (the score is the candidate's own, not a
    /// lower bound at which it stopped).
    pub complete: bool,
    /// The metric furthest from its target, and the rate where (on the validation's drawn
    /// plants when [`Self::validated`] is `Some(false)`).
    pub limiting: Option<(String, f64)>,
    /// The corner plant of [`corners`] where the limiting metric is worst (0 is the
    /// nominal plant; `None`: not run on a plant).
    pub corner: Option<usize>,
    /// The detector that fired first there, when the limiting metric is a fault.
    pub detector: Option<String>,
    /// Whether it met every target on the validation draws (`None`: not validated).
    pub validated: Option<bool>,
}

/// The outcome of a tuning.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Report {
    /// The rates searched at \[Hz\].
    pub rates_hz: Vec<f64>,
    /// The search space.
    pub space: Space,
    /// Every candidate, in search order.
    pub evaluations: Vec<Evaluation>,
    /// The chosen candidate (the lowest complete score at or below 1), if any.
    pub chosen: Option<Evaluation>,
    /// The actuator with the chosen tuning.
    pub tuned: Option<Actuator>,
    /// Worst metrics of the validation Monte Carlo with the tuned actuator, per rate, with
    /// the targets they are judged by.
    pub validation: Vec<(Worst, Targets)>,
    /// Why nothing passed: the unreachable target, where and by how much (`None` when a
    /// candidate was chosen).
    pub refusal: Option<Refusal>,
}

/// The scenario of `act` with `c` at `rate_hz` and `substeps`, on `plant`.
///
/// # Errors
/// Settings that do not derive.
#[expect(clippy::cast_possible_truncation)]
pub fn condition(
    name: &str,
    act: &Actuator,
    c: &Candidate,
    rate_hz: f64,
    substeps: u32,
) -> Result<Scenario, Error> {
    let tuned = Actuator {
        tuning: Some(c.tuning()),
        ..*act
    }
    .with_rate_hz(rate_hz as f32);
    Ok(crate::simulation::actuator::scenario(name, &tuned)?.with_substeps(substeps))
}

/// Share of the ripple target a candidate may use on the corner plants: the ripple is the
/// peak to peak of converter noise through the loop, and another noise realisation moves
/// it by about a tenth (measured between the corners' and the Monte Carlo's seeds).
pub const RIPPLE_RESERVE: f64 = 0.9;

fn judge(w: &Worst, t: &Targets) -> (f64, &'static str) {
    if w.faulted_runs > 0 {
        return (f64::INFINITY, "fault");
    }
    w.ratios(t)
        .into_iter()
        .map(|(name, r)| {
            let r = if name == "ripple" {
                r / RIPPLE_RESERVE
            } else {
                r
            };
            (if r.is_nan() { f64::INFINITY } else { r }, name)
        })
        .fold((0.0, "none"), |a, b| if b.0 > a.0 { b } else { a })
}

/// Tunes the practical law for `act` (named `name`) at `rates_hz` (the first one is the
/// actuator's own rate, where candidates are screened) with `substeps` RK4 substeps per
/// period; validates the choice on `validation_draws` drawn plants per rate.
///
/// # Errors
/// No rate; an actuator whose settings do not derive or that breaks a physical rule
/// ([`Actuator::check_consistency`]); a scenario that does not validate.
pub fn tune(
    name: &str,
    act: &Actuator,
    rates_hz: &[f64],
    space: &Space,
    substeps: u32,
    validation_draws: usize,
) -> Result<Report, Error> {
    let &own_rate = rates_hz
        .first()
        .ok_or_else(|| Error::param("rates_hz", 0.0, "tune needs at least one rate"))?;
    let base = act.settings().map_err(Error::Actuator)?;
    act.check_consistency().map_err(Error::Actuator)?;
    let plants = corners(&base.plant);
    let candidates = space.candidates(f64::from(act.board.rate_hz));
    if candidates.is_empty() {
        return Err(Error::param(
            "space",
            0.0,
            "the search space holds no candidate",
        ));
    }

    // Theorem 1 and the screening run, in parallel over the candidates. A screening run
    // stops at the first certain miss ([`Until::Miss`]): only a candidate that meets every
    // target goes on, so a miss's size matters only to a refusal at this stage, which
    // screens again to the end (below).
    let screen = |cs: &[Candidate], until: Until| -> Result<Vec<Evaluation>, Error> {
        cs.par_iter()
            .map(|c| -> Result<Evaluation, Error> {
                let theorem = theorem(&base, c.alpha)?;
                let mut e = Evaluation {
                    candidate: *c,
                    theorem,
                    screen: f64::INFINITY,
                    worst: Vec::new(),
                    score: f64::INFINITY,
                    complete: false,
                    limiting: None,
                    corner: None,
                    detector: None,
                    validated: None,
                };
                if !theorem.holds() {
                    e.limiting = Some(("Theorem 1".into(), own_rate));
                    return Ok(e);
                }
                let sc = condition(name, act, c, own_rate, substeps)?;
                let t = Targets::for_scenario(&sc);
                let m = with_run_until(&sc, until, |r| r.metrics.clone())?;
                let (score, what) = judge(&Worst::of([&m], &t), &t);
                e.screen = score;
                e.limiting = Some((what.into(), own_rate));
                e.corner = Some(0);
                e.detector = first_detector(&m);
                Ok(e)
            })
            .collect()
    };
    let search = Search {
        name,
        act,
        rates_hz,
        substeps,
        plants: &plants,
        validation_draws,
    };
    let mut evaluations = screen(&candidates, Until::Miss)?;
    let mut found = search.worst_case(&mut evaluations)?;
    // The best so far, refined: the neighbours of the best few between their points, each
    // round at half the last round's step.
    let nyquist_quarter = observer_limit_rad_s(f64::from(act.board.rate_hz));
    let mut margins = space.margin.clone();
    let mut factor = REFINE_FACTOR;
    for _ in 0..REFINE_ROUNDS {
        if found.is_some() {
            break;
        }
        let mut best: Vec<&Evaluation> =
            evaluations.iter().filter(|e| e.score.is_finite()).collect();
        best.sort_by(|a, b| a.score.total_cmp(&b.score));
        let mut refined: Vec<Candidate> = Vec::new();
        for e in best.iter().take(REFINE_SEEDS) {
            for c in e.candidate.neighbours(&margins, factor) {
                let known = evaluations.iter().any(|e| e.candidate == c) || refined.contains(&c);
                if !known && c.observer_rad_s < nyquist_quarter {
                    refined.push(c);
                }
            }
        }
        margins.extend(refined.iter().map(|c| c.margin));
        margins.sort_by(f64::total_cmp);
        margins.dedup();
        let mut more = screen(&refined, Until::Miss)?;
        found = search.worst_case(&mut more)?;
        evaluations.extend(more);
        factor = factor.sqrt();
    }
    let (chosen, validation) = match found {
        Some((chosen, validation)) => (Some(chosen), validation),
        None => (None, Vec::new()),
    };
    let tuned = chosen.as_ref().map(|c| Actuator {
        tuning: Some(c.candidate.tuning()),
        ..*act
    });
    let refusal = if chosen.is_some() {
        None
    } else {
        if evaluations.iter().all(|e| e.worst.is_empty()) {
            // None screened in, so none was refined: the refusal names the best screening,
            // which takes every miss's full size.
            evaluations = screen(&candidates, Until::Fault)?;
        }
        // Every candidate was at least screened, so there is a best.
        refusal(&evaluations)
    };
    evaluations.sort_by(|a, b| {
        (a.score, a.screen)
            .partial_cmp(&(b.score, b.screen))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    Ok(Report {
        rates_hz: rates_hz.to_vec(),
        space: space.clone(),
        evaluations,
        chosen,
        tuned,
        validation,
        refusal,
    })
}

/// Corner plants a candidate runs first, those where earlier candidates missed: only when
/// it meets every target on them does it run the others. A candidate that misses is
/// usually stopped by these, at a fraction of the runs; one that passes runs every plant,
/// so the choice is the same as with every plant at once (the score of one that misses is
/// then the worst over the plants it ran).
pub const PROBE_PLANTS: usize = 8;

/// The grid's best candidates [`tune`] refines when none of the grid passes.
pub const REFINE_SEEDS: usize = 3;

/// The steps of the refinement's first round around a grid point: `alpha` and the
/// observer a factor `2^(1/4)` either way (half the grid's step), the margin halfway to
/// its neighbours.
const REFINE_FACTOR: f64 = 1.189_207_115_002_721;

/// Rounds of refinement, each at half the step of the one before (`2^(1/4)`, then
/// `2^(1/8)`): a target missed by a per cent or two on the best point sits closer to it
/// than half a grid step.
pub const REFINE_ROUNDS: usize = 2;

/// A candidate chosen, with its validation at every rate.
type Chosen = (Evaluation, Vec<(Worst, Targets)>);

/// What [`tune`] runs each candidate on.
struct Search<'a> {
    name: &'a str,
    act: &'a Actuator,
    rates_hz: &'a [f64],
    substeps: u32,
    plants: &'a [Params],
    validation_draws: usize,
}

impl Search<'_> {
    /// The worst case, best screened first: every corner plant at every rate, stopping at
    /// the first miss; a candidate that passes is validated on drawn plants, and the first
    /// that passes both is returned with its validation.
    fn worst_case(&self, evaluations: &mut [Evaluation]) -> Result<Option<Chosen>, Error> {
        let mut order: Vec<usize> = (0..evaluations.len())
            .filter(|&k| evaluations.get(k).is_some_and(|e| e.screen <= SCREEN))
            .collect();
        order.sort_by(|&a, &b| evaluations[a].screen.total_cmp(&evaluations[b].screen));
        // The corner plants, those where earlier candidates missed first: a candidate that
        // misses is usually stopped by the first few (see [`PROBE_PLANTS`]).
        let mut priority: Vec<usize> = (0..self.plants.len()).collect();
        let mut missed_at = vec![0_usize; self.plants.len()];
        for k in order {
            let Some(e) = evaluations.get_mut(k) else {
                continue;
            };
            let mut score = 0.0_f64;
            let mut worst = Vec::new();
            let mut limiting = None;
            let mut complete = true;
            for &rate in self.rates_hz {
                let sc = condition(self.name, self.act, &e.candidate, rate, self.substeps)?;
                let t = Targets::for_scenario(&sc);
                let run_on = |plants: &[usize]| {
                    plants
                        .par_iter()
                        .filter_map(|&k| self.plants.get(k).map(|p| (k, p)))
                        .map(|(k, p)| {
                            with_run_until(
                                &sc.clone().with_plant(TruePlant::Given(p.clone())),
                                Until::Fault,
                                |r| (k, r.metrics.clone()),
                            )
                        })
                        .collect::<Result<Vec<_>, _>>()
                };
                let (first, rest) = priority.split_at(PROBE_PLANTS.min(priority.len()));
                let mut runs = run_on(first)?;
                if judge(&Worst::of(runs.iter().map(|r| &r.1), &t), &t).0 <= 1.0 {
                    runs.extend(run_on(rest)?);
                }
                let w = Worst::of(runs.iter().map(|r| &r.1), &t);
                let (s, what) = judge(&w, &t);
                if s > score {
                    score = s;
                    limiting = Some((what.to_owned(), rate));
                    // The plant where it is worst, and what fired there.
                    let (at, metrics) = runs
                        .iter()
                        .map(|(k, m)| (k, m, judge(&Worst::of([m], &t), &t).0))
                        .fold((0, None), |a, b| {
                            if a.1.is_none_or(|(_, s)| b.2 > s) {
                                (*b.0, Some((b.1, b.2)))
                            } else {
                                a
                            }
                        });
                    e.corner = Some(at);
                    e.detector = metrics.and_then(|(m, _)| first_detector(m));
                    if s > 1.0 {
                        if let Some(n) = missed_at.get_mut(at) {
                            *n += 1;
                        }
                        priority.sort_by_key(|&k| std::cmp::Reverse(missed_at.get(k).copied()));
                    }
                }
                worst.push(w);
                if score > 1.0 {
                    complete = false;
                    break;
                }
            }
            e.score = score;
            e.worst = worst;
            e.limiting = limiting;
            e.complete = complete;
            if !complete {
                continue;
            }
            let mut checked = Vec::new();
            for &rate in self.rates_hz {
                let sc = condition(self.name, self.act, &e.candidate, rate, self.substeps)?;
                let t = Targets::for_scenario(&sc);
                // A candidate that passes runs every draw; one that misses stops with the
                // chunk of draws where it does, and the target it names is the first
                // missed there.
                let draws = montecarlo_until_miss(
                    &sc,
                    self.validation_draws,
                    crate::analysis::seeds::TUNE_VALIDATION,
                    &t,
                )?;
                let w = Worst::of_draws(&draws, &t);
                let misses = w.misses(&t);
                checked.push((w, t));
                if let Some(what) = misses.first() {
                    e.validated = Some(false);
                    e.limiting = Some(((*what).to_owned(), rate));
                    break;
                }
            }
            if e.validated.is_none() {
                e.validated = Some(true);
                return Ok(Some((e.clone(), checked)));
            }
        }
        Ok(None)
    }
}

/// The fault that latched first in a run, by name.
fn first_detector(m: &crate::simulation::metrics::Metrics) -> Option<String> {
    m.first_fault
        .as_ref()
        .and_then(|f| f.fault)
        .map(|f| f.name().to_owned())
}

/// Corner plant `k` of [`corners`] in words: `the nominal plant`, or which end of each
/// tolerance and which airgap.
#[must_use]
pub fn corner_name(k: usize) -> String {
    let Some(j) = k.checked_sub(1) else {
        return "the nominal plant".into();
    };
    let bits = j / 3;
    let end = |bit: usize| {
        if bits & (1 << bit) == 0 {
            "low"
        } else {
            "high"
        }
    };
    let surface = match j % 3 {
        0 => "the smallest constant surface",
        1 => "the largest constant surface",
        _ => "a surface growing across the bounds",
    };
    format!(
        "corner plant {k} (mass {}, spring {}, friction {}, resistance {}, {surface})",
        end(0),
        end(1),
        end(2),
        end(3)
    )
}

/// Where the best candidate stopped when nothing passed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Stage {
    /// Theorem 1 fails for every candidate.
    Theorem,
    /// No candidate passed the nominal plant (none ran on the corners).
    Nominal,
    /// The best missed a target on a corner plant.
    Corners,
    /// The best met every corner plant but missed on the validation draws.
    Validation,
}

/// Why [`tune`] chose nothing: the best candidate, the target it misses, where and by how
/// much.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Refusal {
    /// Where the best stopped.
    pub stage: Stage,
    /// The best candidate.
    pub candidate: Candidate,
    /// The target it misses (`settling`, `overshoot`, `steady error`, `ripple`, `current`,
    /// `voltage`, `fault`).
    pub what: String,
    /// The rate where \[Hz\].
    pub rate_hz: f64,
    /// Its `worst / target` there (infinite for a fault).
    pub by: f64,
    /// The corner plant of [`corners`] where it is worst.
    pub corner: Option<usize>,
    /// The detector that fired, for a fault.
    pub detector: Option<String>,
}

impl Refusal {
    /// The refusal in a few words, for a table: what, by how much, where.
    #[must_use]
    pub fn short(&self) -> String {
        let at = format!(
            "{} kHz",
            crate::analysis::report::sig(self.rate_hz / 1e3, 3)
        );
        let corner = self
            .corner
            .map_or_else(String::new, |k| format!(", corner {k}"));
        match (self.stage, &self.detector) {
            (Stage::Theorem, _) => "Theorem 1 fails".into(),
            (Stage::Validation, _) => format!("{} on drawn plants at {at}", self.what),
            (_, Some(d)) if self.what == "fault" => format!("`{d}` fires at {at}{corner}"),
            _ => format!("{} x{} at {at}{corner}", self.what, over_one(self.by, 3)),
        }
    }
}

impl core::fmt::Display for Refusal {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let c = &self.candidate;
        let (what, rate, score) = (&self.what, self.rate_hz, self.by);
        match self.stage {
            Stage::Theorem => {
                return write!(
                    f,
                    "Theorem 1 fails for every candidate (best: alpha {} 1/s): the force gains \
                     the uncertainty allows are too far apart for a common Lyapunov matrix",
                    c.alpha
                )
            }
            Stage::Validation => {
                return write!(
                    f,
                    "no candidate meets every target on the drawn plants; the best (alpha {} \
                     1/s, observer {} rad/s, margin {}) meets every target on every corner \
                     plant (worst at {score:.3} of its target) but misses `{what}` at {} kHz",
                    c.alpha,
                    c.observer_rad_s,
                    c.margin,
                    rate / 1e3,
                )
            }
            Stage::Nominal | Stage::Corners => {}
        }
        let why = match what.as_str() {
            "settling" => {
                "the moves the current limit allows on the weakest plant take longer than \
                 the target, or the loop is too slow to finish them"
            }
            "overshoot" => {
                "the disturbance estimate lags the model error of the corner plants at the \
                 end of a move"
            }
            "steady error" => "the loop does not remove the model error within the steady window",
            "ripple" => {
                "converter noise through the observer and the gains moves the current more \
                 than 2 % of the rating"
            }
            "current" => "the moves need more than the rated current on some corner plant",
            "voltage" => "the coil sees more than the supply and the freewheeling diodes' drop",
            "fault" => "a fault detector fires",
            _ => "",
        };
        let plant = self
            .corner
            .map_or_else(String::new, |k| format!(" on {}", corner_name(k)));
        let why = match &self.detector {
            Some(d) if what == "fault" => format!("the `{d}` detector fires{plant}"),
            _ if why.is_empty() => plant.trim_start().to_owned(),
            _ => format!("{why} ({})", plant.trim_start()),
        };
        write!(
            f,
            "no candidate meets every target {}; the best (alpha {} 1/s, observer {} rad/s, \
             margin {}) misses `{what}` at {} kHz by a factor {}: {why}",
            if self.stage == Stage::Corners {
                "on every corner plant at every rate"
            } else {
                "even on the nominal plant"
            },
            c.alpha,
            c.observer_rad_s,
            c.margin,
            rate / 1e3,
            over_one(score, 4)
        )
    }
}

/// A factor by which a target is missed (above 1), to `digits` significant digits, or as
/// many more as it takes not to read `1`: a miss by 0.04 % is still a miss.
fn over_one(by: f64, digits: usize) -> String {
    let sig = crate::analysis::report::sig;
    (digits..digits + 4)
        .map(|d| sig(by, d))
        .find(|s| s != "1")
        .unwrap_or_else(|| sig(by, digits + 4))
}

/// The best of the evaluations when none passed, and what it missed (`None`: no
/// evaluation, which [`tune`] refuses before it searches).
fn refusal(evaluations: &[Evaluation]) -> Option<Refusal> {
    // Those run on the corners (their score is where they stopped, at their first miss),
    // else the screening.
    let on_corners = evaluations
        .iter()
        .filter(|e| !e.worst.is_empty())
        .min_by(|a, b| a.score.total_cmp(&b.score));
    let (best, by, stage) = on_corners
        .map(|e| (e, e.score, Stage::Corners))
        .or_else(|| {
            evaluations
                .iter()
                .min_by(|a, b| a.screen.total_cmp(&b.screen))
                .map(|e| (e, e.screen, Stage::Nominal))
        })?;
    let stage = if !best.theorem.holds() {
        Stage::Theorem
    } else if best.validated == Some(false) {
        Stage::Validation
    } else {
        stage
    };
    let (what, rate_hz) = best
        .limiting
        .clone()
        .unwrap_or_else(|| ("none".into(), f64::NAN));
    Some(Refusal {
        stage,
        candidate: best.candidate,
        what,
        rate_hz,
        by,
        corner: best.corner,
        detector: best.detector.clone(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn theorem_one_holds_for_the_product_gains_and_bounds_the_ball() {
        let s = Settings::practical(20e3, 24.0).unwrap();
        let alpha = match s.law {
            ema::control::law::Settings::Practical(g) => f64::from(g.alpha1),
            _ => unreachable!(),
        };
        assert_eq!(
            alpha,
            f64::from(Actuator::PRODUCT.tuning.unwrap().alpha_per_s)
        );
        let t = theorem(&s, alpha).unwrap();
        // m_design/m in [1, 1.1/0.9]; mu_hi/mu_lo is S_hi/S_lo of the controller's bounds
        // at the largest gaps (the iron path matters little there).
        let b = s.plant.bounds;
        let theta = f64::from(b.s_hi_m2 / b.s_lo_m2);
        assert!((t.gamma_min - 1.0).abs() < 1e-6, "{}", t.gamma_min);
        let expect = theta * 1.1 / 0.9;
        assert!(
            (t.gamma_max - expect).abs() < 0.01 * expect,
            "{} {expect}",
            t.gamma_max
        );
        // V = |z|^2 / 2 (the paper's choice) cannot prove it over the whole gain range: at
        // the largest gain the cross term of A' + A is too large. The optimised P does.
        assert_eq!(t.radius_identity_m, None);
        assert!(t.holds());
        assert!(t.radius_optimised_m.unwrap() > 0.0);
        // At a single gain of 1, P = I works and gives delta / alpha.
        let p = Problem::practical(alpha, alpha, 1.0, 1.0, t.delta_mps2);
        let r = p.identity().unwrap().radius_per_m;
        assert!((r - t.delta_mps2 / alpha).abs() < 1e-9);
    }

    #[test]
    fn corners_span_the_tolerances() {
        let p = ema::control::model::Plant::paper();
        let c = corners(&p);
        assert_eq!(c.len(), 49);
        let masses: Vec<f64> = c.iter().map(|p| p.mass_kg).collect();
        let (lo, hi) = masses
            .iter()
            .fold((f64::INFINITY, 0.0_f64), |(a, b), &m| (a.min(m), b.max(m)));
        assert!(
            (lo - 0.09).abs() < 1e-6 && (hi - 0.11).abs() < 1e-6,
            "{lo} {hi}"
        );
    }

    #[test]
    fn corner_names_say_which_end_of_each_tolerance() {
        let c = corners(&ema::control::model::Plant::paper());
        let nominal = &c[0];
        assert_eq!(corner_name(0), "the nominal plant");
        for (k, q) in c.iter().enumerate().skip(1) {
            let name = corner_name(k);
            for (word, high) in [
                ("mass high", q.mass_kg > nominal.mass_kg),
                ("spring high", q.spring_n_per_m > nominal.spring_n_per_m),
                (
                    "friction high",
                    q.friction_n_s_per_m > nominal.friction_n_s_per_m,
                ),
                ("resistance high", q.resistance_ohm > nominal.resistance_ohm),
            ] {
                assert_eq!(name.contains(word), high, "{name}: {word}");
            }
            assert_eq!(
                name.contains("growing"),
                q.force == ForceModel::EnergyConsistent,
                "{name}"
            );
        }
    }

    #[test]
    fn the_space_follows_the_actuator() {
        let product = Space::for_actuator(&Actuator::PRODUCT, 10e3).unwrap();
        let valve = crate::simulation::actuator::load("valve").unwrap().1;
        let valve = Space::for_actuator(&valve, 10e3).unwrap();
        // The valve's spring and magnet are faster: its grid sits higher.
        assert!(
            valve.alpha[0] > 1.5 * product.alpha[0],
            "{valve:?} {product:?}"
        );
        // The product's tuned alpha lies inside its own grid, which spans a tenth to ten
        // times the mechanical frequency in half-octave steps through the default gain.
        let tuned = f64::from(Actuator::PRODUCT.tuning.unwrap().alpha_per_s);
        let (lo, hi) = (product.alpha[0], *product.alpha.last().unwrap());
        assert!(lo < tuned && tuned < hi, "{product:?}");
        let w = f64::from(Actuator::PRODUCT.time_scales().unwrap().mechanical_rad_s());
        assert!(lo <= 0.1 * w && hi >= 10.0 * w, "{product:?}");
        assert_eq!(product.alpha.len(), 15, "{product:?}");
        assert!(product.alpha.contains(&round3(2.0 * w)), "{product:?}");
        for pair in product.alpha.windows(2) {
            assert!((pair[1] / pair[0] - ALPHA_STEP).abs() < 0.01, "{pair:?}");
        }
    }

    /// A miss that rounds to 1 at the table's precision still reads as a miss.
    #[test]
    fn a_miss_factor_never_reads_one() {
        assert_eq!(over_one(1.0174, 3), "1.02");
        assert_eq!(over_one(1.0004, 3), "1.0004");
        assert_eq!(over_one(1.3271, 4), "1.327");
        assert_eq!(over_one(1.000_04, 4), "1.00004");
    }

    #[test]
    fn the_refinement_looks_half_a_grid_step_around_a_point() {
        let c = Candidate {
            alpha: 139.0,
            observer_rad_s: 208.0,
            margin: 0.35,
            follows_force: true,
        };
        let n = c.neighbours(&MARGINS, REFINE_FACTOR);
        // Three alphas, three observers, three margins, the point itself left out.
        assert_eq!(n.len(), 26, "{n:?}");
        assert!(!n.contains(&c));
        let alphas: Vec<f64> = n.iter().map(|c| c.alpha).collect();
        assert!(
            alphas.contains(&117.0) && alphas.contains(&165.0),
            "{alphas:?}"
        );
        let observers: Vec<f64> = n.iter().map(|c| c.observer_rad_s).collect();
        assert!(
            observers.contains(&175.0) && observers.contains(&247.0),
            "{observers:?}"
        );
        let margins: Vec<f64> = n.iter().map(|c| c.margin).collect();
        assert!(
            margins.contains(&0.275) && margins.contains(&0.425),
            "{margins:?}"
        );
        assert!(n.iter().all(|c| c.follows_force));
        // At the end of the margins, no step beyond them.
        let top = Candidate { margin: 0.85, ..c };
        let n = top.neighbours(&MARGINS, REFINE_FACTOR);
        assert_eq!(n.len(), 17, "{n:?}");
        assert!(n.iter().all(|c| c.margin <= 0.85));
    }

    /// When no candidate screens in, the refusal gives the best screening's full miss,
    /// not the stopped run's: moves shaped half as gently as the product's miss their
    /// settling on the nominal plant (the screening run stops there), and the refusal
    /// names what the full run misses most, by its factor.
    #[test]
    fn a_refusal_on_the_nominal_plant_gives_the_miss_s_full_size() {
        use crate::simulation::sim::{run, with_run_until};
        let act = Actuator::PRODUCT;
        let t = act.tuning.unwrap();
        let space = Space {
            alpha: vec![f64::from(t.alpha_per_s)],
            observer_per_alpha: vec![f64::from(t.observer_rad_s / t.alpha_per_s)],
            margin: vec![f64::from(t.margin) / 2.0],
        };
        let rate = f64::from(act.board.rate_hz);
        let report = tune("product", &act, &[rate], &space, 1, 4).unwrap();
        assert_eq!(report.evaluations.len(), 2);
        let r = report.refusal.unwrap();
        let sc = condition("product", &act, &r.candidate, rate, 1).unwrap();
        let full = run(&sc).unwrap();
        let stopped = with_run_until(&sc, Until::Miss, |r| r.samples.len()).unwrap();
        assert!(stopped < full.samples.len(), "{stopped}");
        let targets = Targets::for_scenario(&sc);
        let (by, what) = judge(&Worst::of([&full.metrics], &targets), &targets);
        assert!(by.is_finite() && by > 1.0, "{by} {what}");
        assert_eq!((r.stage, r.what.as_str(), r.by), (Stage::Nominal, what, by));
    }
}
