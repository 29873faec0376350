//! The simulation's samples ([`crate::simulation::sim::Run::samples`]) decimated for a CSV
//! file or a plot (the `trace*.csv` files). At a 1 MHz ISR one second is a million 144-byte
//! samples; a CSV or a plot keeps every `n`-th sample and, so that a current chattering
//! from one sample to the next stays visible, the minimum and maximum of the current and of
//! the coil voltage over each bucket of `n` samples.

use std::path::Path;

use serde::Serialize;

use crate::simulation::sim::Sample;

/// One row of a decimated trace: the first sample of a bucket of `n` ISR samples, and the
/// extremes over the bucket. SI units, as in [`Sample`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Row {
    /// Sample instant \[s\].
    pub t_s: f64,
    /// Reference \[m\].
    pub r_m: f64,
    /// True position \[m\].
    pub x_m: f64,
    /// True velocity \[m/s\].
    pub v_mps: f64,
    /// True coil current at the sample \[A\].
    pub i_a: f64,
    /// Smallest current at the samples of the bucket \[A\].
    pub i_min_a: f64,
    /// Largest current at the samples of the bucket \[A\].
    pub i_max_a: f64,
    /// Mean current at the samples of the bucket \[A\].
    pub i_avg_a: f64,
    /// Largest `|i|` over the bucket, between samples too \[A\].
    pub i_abs_peak_a: f64,
    /// Law's voltage command before saturation \[V\].
    pub u_cmd_v: f64,
    /// Mean coil voltage over the sample's period \[V\].
    pub u_mean_v: f64,
    /// Smallest period-mean coil voltage over the bucket \[V\].
    pub u_min_v: f64,
    /// Largest period-mean coil voltage over the bucket \[V\].
    pub u_max_v: f64,
    /// Mean coil voltage over the bucket \[V\].
    pub u_avg_v: f64,
    /// Law's desired current \[A\].
    pub i_d_a: f64,
    /// Observer's position estimate \[m\].
    pub x_est_m: f64,
    /// Observer's velocity estimate \[m/s\].
    pub v_est_mps: f64,
    /// Observer's disturbance estimate \[m/s^2\].
    pub d_est_mps2: f64,
    /// Shaped reference \[m\].
    pub r_shaped_m: f64,
    /// Bus voltage at the sample \[V\].
    pub vbus_v: f64,
    /// PWM compare value.
    pub duty: u16,
    /// Bridge mode (`coast`, `forward`, `reverse`).
    pub mode: &'static str,
    /// Latched fault, by name; empty without one.
    pub fault: &'static str,
}

/// The CSV header of a decimated trace, in column order.
pub const COLUMNS: [&str; 23] = [
    "t_s",
    "r_m",
    "x_m",
    "v_mps",
    "i_a",
    "i_min_a",
    "i_max_a",
    "i_avg_a",
    "i_abs_peak_a",
    "u_cmd_v",
    "u_mean_v",
    "u_min_v",
    "u_max_v",
    "u_avg_v",
    "i_d_a",
    "x_est_m",
    "v_est_mps",
    "d_est_mps2",
    "r_shaped_m",
    "vbus_v",
    "duty",
    "mode",
    "fault",
];

/// The bucket size that brings `len` samples down to at most `max_rows` rows (at least 1).
#[must_use]
pub fn every_for(len: usize, max_rows: usize) -> usize {
    len.div_ceil(max_rows.max(1)).max(1)
}

/// One row per bucket of `every` samples (the last bucket may be shorter).
#[must_use]
pub fn decimate(trace: &[Sample], every: usize) -> Vec<Row> {
    trace
        .chunks(every.max(1))
        .filter_map(|bucket| {
            let s = bucket.first()?;
            let (mut i_min, mut i_max, mut i_peak) = (s.i_a, s.i_a, 0.0_f64);
            let (mut u_min, mut u_max) = (s.u_mean_v, s.u_mean_v);
            let (mut i_sum, mut u_sum) = (0.0, 0.0);
            for b in bucket {
                i_sum += b.i_a;
                u_sum += b.u_mean_v;
                i_min = i_min.min(b.i_a);
                i_max = i_max.max(b.i_a);
                i_peak = i_peak.max(b.i_abs_max_a);
                u_min = u_min.min(b.u_mean_v);
                u_max = u_max.max(b.u_mean_v);
            }
            #[expect(clippy::cast_precision_loss)]
            let n = bucket.len() as f64;
            Some(Row {
                t_s: s.t_s,
                r_m: s.r_m,
                x_m: s.x_m,
                v_mps: s.v_mps,
                i_a: s.i_a,
                i_min_a: i_min,
                i_max_a: i_max,
                i_avg_a: i_sum / n,
                i_abs_peak_a: i_peak,
                u_cmd_v: s.u_cmd_v,
                u_mean_v: s.u_mean_v,
                u_min_v: u_min,
                u_max_v: u_max,
                u_avg_v: u_sum / n,
                i_d_a: s.i_d_a,
                x_est_m: s.x_est_m,
                v_est_mps: s.v_est_mps,
                d_est_mps2: s.d_est_mps2,
                r_shaped_m: s.r_shaped_m,
                vbus_v: s.vbus_v,
                duty: s.duty,
                mode: s.mode.name(),
                fault: s.fault.map_or("", ema::control::supervisor::Fault::name),
            })
        })
        .collect()
}

/// Writes decimated rows as CSV with the header [`COLUMNS`].
///
/// # Errors
/// The file system's, with the file's name.
pub fn write_rows(path: &Path, rows: &[Row]) -> anyhow::Result<()> {
    let fail = |e: csv::Error| anyhow::anyhow!("cannot write {}: {e}", path.display());
    let mut w = csv::Writer::from_path(path).map_err(fail)?;
    if rows.is_empty() {
        w.write_record(COLUMNS).map_err(fail)?;
    }
    for r in rows {
        w.serialize(r).map_err(fail)?;
    }
    w.flush()
        .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))
}

/// Decimates `trace` to every `every`-th sample and writes it as CSV.
///
/// # Errors
/// The file system's, with the file's name.
pub fn write_csv(path: &Path, trace: &[Sample], every: usize) -> anyhow::Result<()> {
    write_rows(path, &decimate(trace, every))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buckets_keep_the_extremes() {
        let trace: Vec<Sample> = (0..10)
            .map(|k| Sample {
                t_s: f64::from(k) * 1e-3,
                i_a: if k % 2 == 0 { 5.0 } else { -3.0 },
                i_abs_max_a: if k == 7 { 9.0 } else { 5.0 },
                u_mean_v: f64::from(k),
                ..Sample::default()
            })
            .collect();
        let rows = decimate(&trace, 4);
        assert_eq!(rows.len(), 3);
        assert_eq!(rows[1].t_s, 4e-3);
        assert_eq!((rows[1].i_min_a, rows[1].i_max_a), (-3.0, 5.0));
        assert_eq!(rows[1].i_abs_peak_a, 9.0);
        assert_eq!((rows[1].u_min_v, rows[1].u_max_v), (4.0, 7.0));
        assert_eq!((rows[1].i_avg_a, rows[1].u_avg_v), (1.0, 5.5));
        assert_eq!((rows[2].u_min_v, rows[2].u_max_v), (8.0, 9.0));
        assert_eq!(rows[0].mode, "coast");
        assert_eq!(every_for(1_000_000, 20_000), 50);
        assert_eq!(every_for(10_000, 20_000), 1);
        assert_eq!(every_for(0, 0), 1);
    }
}
