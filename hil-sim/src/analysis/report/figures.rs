//! The standard figures of a run, like the paper's: position and velocity, coil current,
//! coil voltage (all against time), from decimated traces ([`super::decimated::Row`]). Several
//! cases share the position/velocity axes; current and voltage get one panel per case,
//! since a chattering case would hide a quiet one.

use super::decimated::Row;
use super::plot::{Figure, Legend, Panel, Series};

/// One labelled, decimated trace.
#[derive(Clone, Copy, Debug)]
pub struct Case<'a> {
    /// Legend entry or panel caption (`paper, 1 MHz ISR`).
    pub label: &'a str,
    /// The decimated trace.
    pub rows: &'a [Row],
}

fn points(rows: &[Row], f: impl Fn(&Row) -> f64) -> Vec<(f64, f64)> {
    rows.iter().map(|r| (r.t_s, f(r))).collect()
}

/// `x1` and the reference `y_r` \[mm\] (top), `x2` \[mm/s\] (bottom) against time.
#[must_use]
pub fn position_velocity(title: &str, cases: &[Case<'_>]) -> Figure {
    let mut x = Panel::new("time [s]", "position x1 [mm]")
        .caption("position x1 and reference y_r")
        .legend(Legend::LowerRight);
    let mut v = Panel::new("time [s]", "velocity x2 [mm/s]")
        .caption("velocity x2")
        .legend(Legend::UpperRight);
    for (k, c) in cases.iter().enumerate() {
        x = x.series(
            Series::line(format!("x1, {}", c.label), points(c.rows, |r| r.x_m * 1e3)).color(k),
        );
        v = v.series(
            Series::line(
                format!("x2, {}", c.label),
                points(c.rows, |r| r.v_mps * 1e3),
            )
            .color(k),
        );
    }
    if let Some(c) = cases.first() {
        x = x.series(Series::dashed("y_r", points(c.rows, |r| r.r_m * 1e3)).color(7));
    }
    Figure::new(title).panel(x).panel(v)
}

/// Coil current `x3` \[A\]: per case, the band between the smallest and largest sampled
/// current of each bucket, and the bucket's mean.
#[must_use]
pub fn current(title: &str, cases: &[Case<'_>]) -> Figure {
    let mut fig = Figure::new(title);
    for (k, c) in cases.iter().enumerate() {
        let every = bucket_label(c.rows);
        fig = fig.panel(
            Panel::new("time [s]", "coil current x3 [A]")
                .caption(c.label)
                .series(
                    Series::band(
                        format!("x3, min to max over {every}"),
                        points(c.rows, |r| r.i_min_a),
                        points(c.rows, |r| r.i_max_a),
                    )
                    .color(k),
                )
                .series(
                    Series::line(
                        format!("x3, mean over {every}"),
                        points(c.rows, |r| r.i_avg_a),
                    )
                    .color(k),
                ),
        );
    }
    fig
}

/// Coil voltage `u` \[V\]: per case, the band of the period-mean coil voltage over each
/// bucket, the bucket's mean, and the supply's limits `+-supply_v` dashed.
#[must_use]
pub fn voltage(title: &str, cases: &[Case<'_>], supply_v: f64) -> Figure {
    let mut fig = Figure::new(title);
    for (k, c) in cases.iter().enumerate() {
        let every = bucket_label(c.rows);
        let (t0, t1) = (
            c.rows.first().map_or(0.0, |r| r.t_s),
            c.rows.last().map_or(1.0, |r| r.t_s),
        );
        fig = fig.panel(
            Panel::new("time [s]", "coil voltage u [V]")
                .caption(c.label)
                .series(
                    Series::band(
                        format!("u, min to max over {every}"),
                        points(c.rows, |r| r.u_min_v),
                        points(c.rows, |r| r.u_max_v),
                    )
                    .color(k),
                )
                .series(
                    Series::line(
                        format!("u, mean over {every}"),
                        points(c.rows, |r| r.u_avg_v),
                    )
                    .color(k),
                )
                .series(
                    Series::dashed(
                        format!("+-{supply_v} V supply"),
                        vec![(t0, supply_v), (t1, supply_v)],
                    )
                    .color(7),
                )
                .series(Series::dashed("", vec![(t0, -supply_v), (t1, -supply_v)]).color(7))
                .y_range(-1.15 * supply_v, 1.15 * supply_v),
        );
    }
    fig
}

/// The bucket length of a decimated trace, in words (`0.5 ms`).
fn bucket_label(rows: &[Row]) -> String {
    match rows {
        [a, b, ..] => {
            let dt = b.t_s - a.t_s;
            if dt >= 1e-3 {
                format!("{} ms", super::sig(dt * 1e3, 3))
            } else {
                format!("{} us", super::sig(dt * 1e6, 3))
            }
        }
        _ => "each sample".into(),
    }
}
