//! `hil-sim` / `hil-sim paper`: the paper's example (section IV) run as the paper ran it,
//! near-continuous (1 MHz ISR, `scenarios/paper.toml`), and as firmware would run it
//! (20 kHz, `scenarios/paper-20khz.toml`); a table of the paper's claims beside the
//! measured values, CSV traces, and the paper's figures: x1 and x2, x3 and u against
//! time, and the z1-z2 plane for several initial positions.
//!
//! # When a claim holds
//!
//! | claim | holds when |
//! |---|---|
//! | settling about 0.2 s | 2 % settling time <= 0.25 s |
//! | no overshoot | overshoot <= 0.01 % of the step |
//! | error below 0.1 % | \|mean of x1 - y_r over the last 50 ms\| < 0.1 % of y_r |
//! | u within a 150 V supply | the law never asks for more than the bus voltage |
//! | current of a few amperes | peak <= 10 A; `partly` when only the steady current (mean plus half the ripple) is |
//! | no chattering on x1 and x2 | over the last 50 ms, peak-to-peak about the linear trend below 0.1 um (a tenth of a 12-bit position code) for x1 and below 1 % of the run's peak speed for x2 |
//! | chattering on the current | current ripple (peak to peak at the samples, last 50 ms) above 1 % of the steady current |

use std::io::Write;
use std::path::PathBuf;

use ema::control::law;

use crate::analysis::report::{
    self, decimated, figures, figures::Case, plot::Legend, sig, Figure, Panel, Series, Table,
};
use crate::simulation::catalog;
use crate::simulation::scenario::{Initial, Reference};
use crate::{Run, Sample, Scenario, Segment};

/// Arguments of `paper` (also what runs without a subcommand).
#[derive(Clone, Debug, PartialEq, Eq, clap::Args)]
pub struct Args {
    /// Output folder.
    #[command(flatten)]
    pub output: super::Output,
    /// Largest number of rows in each trace CSV: the trace keeps every n-th ISR sample,
    /// with the current and voltage extremes of the samples in between.
    #[arg(long, default_value_t = 20_000, value_name = "ROWS")]
    pub max_rows: usize,
}

impl Default for Args {
    fn default() -> Self {
        Self {
            output: super::Output::default(),
            max_rows: 20_000,
        }
    }
}

/// Initial positions of the z1-z2 figure \[m\]; each steps to 3 mm.
pub const Z_PLANE_STARTS_M: [f64; 4] = [0.5e-3, 1e-3, 2e-3, 3.5e-3];

/// Current trip of the z1-z2 runs \[A\]: the figure is about the law, and from 2 mm the law
/// asks for 33 A at once (`x3d^2 = 2 m alpha2 |z2| / mu_lo`), which the paper scenario's
/// 30 A trip would stop, dropping the armature on its stop.
pub const Z_PLANE_TRIP_A: f64 = 100.0;

/// What the claims are checked against, from one run.
#[derive(Clone, Debug, PartialEq)]
pub struct Measured {
    /// The scenario's name.
    pub name: String,
    /// Supply voltage \[V\].
    pub supply_v: f64,
    /// Metrics of the step.
    pub step: Segment,
    /// Largest `|x2|` over the run \[m/s\].
    pub v_peak_mps: f64,
    /// Peak-to-peak of `x1` about its linear trend over the steady window \[m\].
    pub x_chatter_m: f64,
    /// Peak-to-peak of `x2` about its linear trend over the steady window \[m/s\].
    pub v_chatter_mps: f64,
    /// Last sample at which the law asked for more than the bus voltage \[s\].
    pub last_over_bus_s: Option<f64>,
}

/// What `paper` measured and wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct Outcome {
    /// The claims table as printed.
    pub claims: Table,
    /// Metrics of both cases, one row per case.
    pub metrics: Table,
    /// The 1 MHz case.
    pub continuous: Measured,
    /// The 20 kHz case.
    pub discrete: Measured,
    /// Files written.
    pub files: Vec<PathBuf>,
}

/// Peak-to-peak of `f` about its least-squares line in time over `w` (0 for fewer than
/// two samples).
fn detrended_pp(w: &[Sample], f: impl Fn(&Sample) -> f64) -> f64 {
    if w.len() < 2 {
        return 0.0;
    }
    #[expect(clippy::cast_precision_loss)]
    let n = w.len() as f64;
    let mt = w.iter().map(|s| s.t_s).sum::<f64>() / n;
    let my = w.iter().map(&f).sum::<f64>() / n;
    let sxy: f64 = w.iter().map(|s| (s.t_s - mt) * (f(s) - my)).sum();
    let sxx: f64 = w.iter().map(|s| (s.t_s - mt).powi(2)).sum();
    let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    let (lo, hi) = w
        .iter()
        .map(|s| f(s) - my - slope * (s.t_s - mt))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), r| {
            (lo.min(r), hi.max(r))
        });
    hi - lo
}

/// Measures one run of a step scenario.
///
/// # Errors
/// A run without a segment.
pub fn measure(sc: &Scenario, r: &Run) -> anyhow::Result<Measured> {
    let step = r
        .metrics
        .first()
        .cloned()
        .ok_or_else(|| anyhow::anyhow!("scenario `{}` has no reference segment", sc.name))?;
    let end = step.spec.end_s;
    let a = r
        .samples
        .partition_point(|s| s.t_s < end - sc.steady_window_s);
    let b = r.samples.partition_point(|s| s.t_s < end);
    let w = r.samples.get(a..b).unwrap_or_default();
    Ok(Measured {
        name: sc.name.clone(),
        supply_v: sc.supply.voltage_v,
        v_peak_mps: r.samples.iter().map(|s| s.v_mps.abs()).fold(0.0, f64::max),
        x_chatter_m: detrended_pp(w, |s| s.x_m),
        v_chatter_mps: detrended_pp(w, |s| s.v_mps),
        last_over_bus_s: r
            .samples
            .iter()
            .rev()
            .find(|s| s.u_cmd_v.abs() > s.vbus_v)
            .map(|s| s.t_s),
        step,
    })
}

fn yes(ok: bool) -> String {
    if ok { "yes" } else { "no" }.into()
}

/// `alpha1` of the law \[1/s\].
fn alpha1(sc: &Scenario) -> f64 {
    f64::from(match sc.controller.law {
        law::Settings::Paper(g) | law::Settings::BoundaryLayer(g) => g.alpha1,
        law::Settings::Practical(g) => g.alpha1,
    })
}

/// The table of the paper's claims (section IV) beside the measured values.
#[must_use]
pub fn claims(c: &Measured, d: &Measured, equilibrium_um: f64) -> Table {
    let mut t = Table::new([
        "claim (paper, section IV)",
        "paper",
        "1 MHz ISR (near-continuous)",
        "holds",
        "20 kHz ISR (firmware rate)",
        "holds",
        "note",
    ]);
    let settle = |m: &Measured| {
        m.step
            .settling_time_s
            .map_or_else(|| "not settled".into(), |s| format!("{} s", sig(s, 3)))
    };
    let settle_ok = |m: &Measured| yes(m.step.settling_time_s.is_some_and(|s| s <= 0.25));
    t.push([
        "settling time (2 % band)".into(),
        "about 0.2 s".into(),
        settle(c),
        settle_ok(c),
        settle(d),
        settle_ok(d),
        "continuous-time reproduction: 0.43 s".to_string(),
    ]);
    let over = |m: &Measured| format!("{} %", sig(m.step.overshoot_pct, 2));
    let over_ok = |m: &Measured| yes(m.step.overshoot_pct <= 0.01);
    t.push([
        "overshoot".into(),
        "none".into(),
        over(c),
        over_ok(c),
        over(d),
        over_ok(d),
        "the armature creeps up to the target from below".into(),
    ]);
    let err = |m: &Measured| {
        format!(
            "{} % ({} um)",
            sig(m.step.steady_error_pct, 2),
            sig(m.step.steady_error_um, 3)
        )
    };
    let err_ok = |m: &Measured| yes(m.step.steady_error_pct.abs() < 0.1);
    t.push([
        "error between x1 and y_r (last 50 ms)".into(),
        "below 0.1 %".into(),
        err(c),
        err_ok(c),
        err(d),
        err_ok(d),
        format!(
            "the law's own equilibrium: z1 = -(mu_lo/mu) K y_r / (m alpha1 alpha2) = {} um",
            sig(equilibrium_um, 3)
        ),
    ]);
    let volts = |m: &Measured| {
        format!(
            "law asks up to {} V; {} samples above the bus",
            sig(m.step.u_cmd_peak_v, 4),
            m.step.saturated_samples
        )
    };
    let volts_ok =
        |m: &Measured| yes(m.step.u_cmd_peak_v <= m.supply_v && m.step.saturated_samples == 0);
    t.push([
        format!("input u within a {} V supply", sig(c.supply_v, 3)),
        format!("within {} V", sig(c.supply_v, 3)),
        volts(c),
        volts_ok(c),
        volts(d),
        volts_ok(d),
        c.last_over_bus_s.map_or_else(
            || "the command never exceeds the bus at 1 MHz".into(),
            |t| format!("at 1 MHz only at start-up, until {} us", sig(t * 1e6, 3)),
        ),
    ]);
    let amps = |m: &Measured| {
        format!(
            "peak {} A, steady {} A",
            sig(m.step.i_peak_a, 3),
            sig(m.step.steady_current_a, 3)
        )
    };
    let amps_ok = |m: &Measured| {
        if m.step.i_peak_a <= 10.0 {
            "yes".to_string()
        } else if m.step.steady_current_a.abs() + 0.5 * m.step.ripple_pp_a <= 10.0 {
            "partly".into()
        } else {
            "no".into()
        }
    };
    t.push([
        "coil current x3".into(),
        "a few amperes".into(),
        amps(c),
        amps_ok(c),
        amps(d),
        amps_ok(d),
        "a few = 10 A or less; partly: only in steady state; 6.085 A holds 3 mm".into(),
    ]);
    let still = |m: &Measured| {
        format!(
            "x1 {} um, x2 {} mm/s p-p",
            sig(m.x_chatter_m * 1e6, 2),
            sig(m.v_chatter_mps * 1e3, 2)
        )
    };
    let still_ok =
        |m: &Measured| yes(m.x_chatter_m < 0.1e-6 && m.v_chatter_mps < 0.01 * m.v_peak_mps);
    t.push([
        "no chattering on position and speed".into(),
        "none".into(),
        still(c),
        still_ok(c),
        still(d),
        still_ok(d),
        "p-p about the linear trend, last 50 ms".into(),
    ]);
    let ripple = |m: &Measured| format!("{} A p-p", sig(m.step.ripple_pp_a, 3));
    let ripple_ok = |m: &Measured| yes(m.step.ripple_pp_a > 0.01 * m.step.steady_current_a.abs());
    t.push([
        "chattering on the current".into(),
        "present, harmless".into(),
        ripple(c),
        ripple_ok(c),
        ripple(d),
        ripple_ok(d),
        "at the samples, last 50 ms; at 20 kHz it is tens of amperes".into(),
    ]);
    t
}

/// The law's steady position error \[um\]: at equilibrium `x3 = x3d` gives
/// `mu x3^2 / 2 = K x1`, and `x3d^2 = -2 m alpha2 z2 / mu_lo` with `z2 = alpha1 z1`, so
/// `z1 = -(mu_lo / mu) K y_r / (m alpha1 alpha2)` (to first order in `z1`).
fn equilibrium_um(sc: &Scenario, r: &Run) -> f64 {
    let y = sc
        .reference
        .segments(sc.duration_s)
        .first()
        .map_or(0.0, |s| s.to_m);
    let p = &r.plant;
    let env = sc.controller.plant.envelope();
    #[expect(clippy::cast_possible_truncation)]
    let mu_lo = env.map_or(f64::NAN, |e| {
        f64::from(e.mu_lo(sc.controller.plant.gap_m(y as f32)))
    });
    let mu = p.mu_h_per_m(p.gap_m(y));
    let a2 = match sc.controller.law {
        law::Settings::Paper(g) | law::Settings::BoundaryLayer(g) => f64::from(g.alpha2),
        law::Settings::Practical(g) => f64::from(g.alpha2),
    };
    -(mu_lo / mu) * p.spring_n_per_m * y / (p.mass_kg * alpha1(sc) * a2) * 1e6
}

/// One z1-z2 trajectory, decimated: every 20 us for the first 20 ms, then every 0.5 ms.
fn z_plane(sc: &Scenario, trace: &[Sample]) -> Vec<(f64, f64, f64)> {
    let a1 = alpha1(sc);
    let mut next = 0.0;
    let mut out = Vec::new();
    for s in trace {
        if s.t_s + 1e-12 >= next {
            let z1 = s.x_m - s.r_m;
            out.push((s.t_s, z1, s.v_mps + a1 * z1));
            next = s.t_s + if s.t_s < 0.02 { 20e-6 } else { 0.5e-3 };
        }
    }
    out
}

/// Runs the paper's example and writes the tables, traces and figures.
///
/// # Errors
/// An embedded scenario that no longer loads, a failed write.
pub fn run(args: &Args, out: &mut dyn Write) -> anyhow::Result<Outcome> {
    let continuous = catalog::load("paper")?;
    let discrete = catalog::load("paper-20khz")?;
    let planes: Vec<Scenario> = Z_PLANE_STARTS_M
        .iter()
        .map(|&x0| {
            let mut sc = continuous
                .clone()
                .with_reference(Reference::Step {
                    from_m: x0,
                    to_m: 3e-3,
                    at_s: 0.0,
                })
                .with_initial(Initial {
                    x_m: x0,
                    v_mps: 0.0,
                    i_a: 0.0,
                })
                .with_probes_s(Vec::new())
                .with_current_trip_a(Z_PLANE_TRIP_A);
            sc.name = format!("paper from {} mm", sig(x0 * 1e3, 2));
            sc
        })
        .collect();
    for sc in &planes {
        catalog::preflight(sc)?;
    }
    let dir = args.output.dir("paper");
    writeln!(
        out,
        "The paper's example (Deschaux, Gouaisbaut, Ariba, CDC 2018, section IV): step from 1 mm to 3 mm."
    )?;
    writeln!(out, "  1 MHz:  {}", super::run::describe(&continuous))?;
    writeln!(
        out,
        "  20 kHz: {} (current trip raised to 100 A)",
        super::run::describe(&discrete)
    )?;

    let mut files = Vec::new();
    let mut cases = Vec::new();
    let mut plane_traces = Vec::new();
    let mut equilibrium = f64::NAN;
    let mut startup = Vec::new();
    for sc in [&continuous, &discrete] {
        let r = crate::run(sc)?;
        let m = measure(sc, &r)?;
        if std::ptr::eq(sc, &continuous) {
            equilibrium = equilibrium_um(sc, &r);
            // Its 30 A trip never acts (peak 22.4 A), so it is also the 1 mm trajectory.
            plane_traces.push((1e-3, z_plane(sc, &r.samples)));
            let n = r.samples.partition_point(|s| s.t_s < STARTUP_S);
            startup = decimated::decimate(r.samples.get(..n).unwrap_or_default(), 1);
        }
        let csv_rows = decimated::decimate(
            &r.samples,
            decimated::every_for(r.samples.len(), args.max_rows),
        );
        let plot_rows =
            decimated::decimate(&r.samples, decimated::every_for(r.samples.len(), 4000));
        cases.push((sc.clone(), r.metrics, m, csv_rows, plot_rows));
    }
    for (sc, x0) in planes.iter().zip(Z_PLANE_STARTS_M) {
        if (x0 - 1e-3).abs() < 1e-12 {
            continue;
        }
        let r = crate::run(sc)?;
        if let Some(f) = r.metrics.first_fault {
            writeln!(
                out,
                "note: the z1-z2 run from {} mm faulted ({}) at {} s",
                sig(x0 * 1e3, 2),
                f.fault.map_or("?", ema::control::supervisor::Fault::name),
                sig(f.t_s, 3)
            )?;
        }
        plane_traces.push((x0, z_plane(sc, &r.samples)));
    }
    plane_traces.sort_by(|a, b| a.0.total_cmp(&b.0));

    let (c, d) = match cases.as_slice() {
        [c, d] => (c, d),
        _ => anyhow::bail!("two cases expected"),
    };
    let claims = claims(&c.2, &d.2, equilibrium);
    write!(out, "\n{}", claims.to_text())?;
    let metrics = report::metrics_table(&[("paper, 1 MHz", &c.1), ("paper, 20 kHz", &d.1)]);
    for (sc, m, ..) in [c, d] {
        writeln!(out, "\n{}:", sc.name)?;
        super::run::write_notes(out, m)?;
    }

    report::create_dir(&dir)?;
    let path = dir.join("claims.csv");
    claims.write_csv(&path)?;
    files.push(path);
    let path = dir.join("metrics.csv");
    metrics.write_csv(&path)?;
    files.push(path);
    for (sc, _, _, rows, _) in [c, d] {
        let path = dir.join(format!("trace-{}.csv", sc.name));
        decimated::write_rows(&path, rows)?;
        files.push(path);
    }
    let path = dir.join("z1-z2.csv");
    write_z_plane(&path, &plane_traces)?;
    files.push(path);

    let both = [
        Case {
            label: "1 MHz ISR",
            rows: &c.4,
        },
        Case {
            label: "20 kHz ISR",
            rows: &d.4,
        },
    ];
    let figs = [
        (
            "x1-x2.png",
            figures::position_velocity(
                "Paper's law: position x1 and velocity x2 (paper Fig. 4)",
                &both,
            ),
        ),
        (
            "x3.png",
            figures::current("Paper's law: coil current x3 (paper Fig. 5)", &both),
        ),
        (
            "u.png",
            figures::voltage(
                "Paper's law: coil voltage u (paper Fig. 6)",
                &both,
                c.0.supply.voltage_v,
            )
            .panel(startup_panel(&startup, c.0.supply.voltage_v)),
        ),
        ("z1-z2.png", z_figure(&plane_traces, equilibrium)),
    ];
    for (file, fig) in figs {
        let path = dir.join(file);
        fig.write_png(&path)?;
        files.push(path);
    }
    super::list_files(out, &files)?;
    Ok(Outcome {
        claims,
        metrics,
        continuous: c.2.clone(),
        discrete: d.2.clone(),
        files,
    })
}

/// Length of the start-up close-up of the coil voltage \[s\].
const STARTUP_S: f64 = 200e-6;

/// The first [`STARTUP_S`] at 1 MHz, every sample: what the law asks for against what the
/// supply gives.
fn startup_panel(rows: &[decimated::Row], supply_v: f64) -> Panel {
    let us = |f: fn(&decimated::Row) -> f64| rows.iter().map(|r| (r.t_s * 1e6, f(r))).collect();
    let t1 = STARTUP_S * 1e6;
    Panel::new("time [us]", "coil voltage u [V]")
        .caption("1 MHz ISR, first 200 us: the law's command against the supply")
        .series(Series::line("law's command u", us(|r| r.u_cmd_v)).color(1))
        .series(Series::line("applied u (period mean)", us(|r| r.u_mean_v)).color(0))
        .series(
            Series::dashed(
                format!("+-{} V supply", sig(supply_v, 4)),
                vec![(0.0, supply_v), (t1, supply_v)],
            )
            .color(7),
        )
        .series(Series::dashed("", vec![(0.0, -supply_v), (t1, -supply_v)]).color(7))
        .x_range(0.0, t1)
}

type Plane = (f64, Vec<(f64, f64, f64)>);

fn write_z_plane(path: &std::path::Path, planes: &[Plane]) -> anyhow::Result<()> {
    let mut t = Table::new(["x0_m", "t_s", "z1_m", "z2_mps"]);
    for (x0, pts) in planes {
        for (time, z1, z2) in pts {
            t.push([
                x0.to_string(),
                time.to_string(),
                z1.to_string(),
                z2.to_string(),
            ]);
        }
    }
    t.write_csv(path)
}

/// The z1-z2 plane: whole trajectories, and a zoom on where they end.
fn z_figure(planes: &[Plane], equilibrium_um: f64) -> Figure {
    let mut whole = Panel::new("z1 = x1 - y_r [mm]", "z2 = x2 + alpha1 z1 [mm/s]")
        .caption("whole trajectories, step to 3 mm (current trip 100 A)")
        .legend(Legend::LowerRight);
    let mut zoom = Panel::new("z1 = x1 - y_r [um]", "z2 = x2 + alpha1 z1 [mm/s]")
        .caption("zoom on the tracking error (paper Fig. 7): from 0.5 s on")
        .legend(Legend::UpperLeft);
    for (k, (x0, pts)) in planes.iter().enumerate() {
        let label = format!("x0 = {} mm", sig(x0 * 1e3, 2));
        whole = whole.series(
            Series::line(
                label.clone(),
                pts.iter().map(|p| (p.1 * 1e3, p.2 * 1e3)).collect(),
            )
            .color(k),
        );
        zoom = zoom.series(
            Series::line(
                label,
                pts.iter()
                    .filter(|p| p.0 >= 0.5)
                    .map(|p| (p.1 * 1e6, p.2 * 1e3))
                    .collect(),
            )
            .color(k),
        );
    }
    let (_, (y0, y1)) = zoom.ranges();
    if equilibrium_um.is_finite() {
        let e = equilibrium_um;
        zoom = zoom.series(
            Series::dashed(
                format!("z1 = {} um (the law's equilibrium)", sig(e, 3)),
                vec![(e, y0), (e, y1)],
            )
            .color(7),
        );
    }
    zoom = zoom.y_range(y0, y1);
    Figure::new("Paper's law, 1 MHz ISR: the z1-z2 plane for several initial positions")
        .panel(whole)
        .panel(zoom)
}
