//! Output for people and for other tools: tables (aligned text and CSV), decimated sample
//! CSV files, and PNG line plots, shared by every subcommand of the command line.
//!
//! * [`Table`]: a header and rows of strings; [`Table::to_text`] aligns it as a
//!   Markdown table (readable in a terminal, pasteable into a README),
//!   [`Table::write_csv`] writes it for a spreadsheet. [`metrics_table`] is the metrics
//!   of one or more runs, one row per reference segment.
//! * [`decimated`]: the simulation's samples decimated to every `n`-th ISR sample, with the minimum and maximum
//!   of the current and voltage over each bucket of `n` samples so that chatter stays
//!   visible ([`decimated::decimate`], [`decimated::write_csv`]).
//! * [`plot`]: [`Figure`]s of stacked [`Panel`]s, each with named axes (units in the
//!   label), several [`Series`] (lines, dashed lines, min/max bands) and a legend, written
//!   as PNG through plotters' bitmap backend. Text is rendered with the bundled DejaVu Sans
//!   (`assets/`), so no system font library is needed.
//!
//! ```no_run
//! use hil_sim::analysis::report::{self, Figure, Panel, Series};
//! use hil_sim::{run, Scenario};
//!
//! let r = run(&Scenario::paper(20_000.0).with_current_trip_a(100.0))?;
//! report::metrics_table(&[("paper 20 kHz", &r.metrics)]).write_csv("metrics.csv".as_ref())?;
//! report::decimated::write_csv("trace.csv".as_ref(), &r.samples, 10)?;
//! let x: Vec<(f64, f64)> = r.samples.iter().map(|s| (s.t_s, s.x_m * 1e3)).collect();
//! Figure::new("Position")
//!     .panel(Panel::new("time [s]", "x1 [mm]").series(Series::line("x1", x)))
//!     .write_png("x1.png".as_ref())?;
//! # Ok::<(), anyhow::Error>(())
//! ```

pub mod decimated;
pub mod figures;
pub mod plot;
mod table;

pub use plot::{Figure, Panel, Series};
pub use table::{metrics_table, Table, METRICS_COLUMNS};

use std::path::Path;

/// Creates `dir` and its parents if needed.
///
/// # Errors
/// The file system's, with the folder's name.
pub fn create_dir(dir: &Path) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir)
        .map_err(|e| anyhow::anyhow!("cannot create the folder {}: {e}", dir.display()))
}

/// `v` rounded to `digits` significant digits, trailing zeros dropped, without an
/// exponent for ordinary magnitudes (`0.4347`, `22.42`, `-14.78`, `150`, `1.2e-6`); `-` for
/// NaN.
#[must_use]
pub fn sig(v: f64, digits: usize) -> String {
    if v.is_nan() {
        return "-".into();
    }
    if v == 0.0 {
        return "0".into();
    }
    if !v.is_finite() {
        return if v > 0.0 { "inf".into() } else { "-inf".into() };
    }
    let mag = v.abs().log10().floor();
    if !(-3.0..6.0).contains(&mag) {
        return format!("{:.*e}", digits.saturating_sub(1), v);
    }
    // Decimals so that `digits` significant digits show; at least 0.
    #[expect(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    let decimals = (digits as f64 - 1.0 - mag).max(0.0) as usize;
    let s = format!("{v:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_owned()
    } else {
        s
    }
}

/// Counts one more `key` in `counts`: its entry's count up by one, or a new entry with
/// one at the end (the order of first appearance).
pub fn tally<K: PartialEq>(counts: &mut Vec<(K, usize)>, key: K) {
    match counts.iter_mut().find(|(k, _)| *k == key) {
        Some((_, n)) => *n += 1,
        None => counts.push((key, 1)),
    }
}

#[cfg(test)]
mod tests {
    use super::{sig, tally};

    #[test]
    fn a_tally_counts_each_key_in_the_order_it_first_came() {
        let mut counts = Vec::new();
        for k in ["b", "a", "b", "c", "b"] {
            tally(&mut counts, k);
        }
        assert_eq!(counts, vec![("b", 3), ("a", 1), ("c", 1)]);
    }

    #[test]
    fn significant_digits() {
        assert_eq!(sig(0.434_719, 3), "0.435");
        assert_eq!(sig(22.417_58, 3), "22.4");
        assert_eq!(sig(-14.775_8, 3), "-14.8");
        assert_eq!(sig(259.58, 4), "259.6");
        assert_eq!(sig(1.2e-6, 2), "1.2e-6");
        assert_eq!(sig(0.0, 3), "0");
        assert_eq!(sig(f64::NAN, 3), "-");
        assert_eq!(sig(37.658, 3), "37.7");
        assert_eq!(sig(150.0, 4), "150");
        assert_eq!(sig(0.650_43, 3), "0.65");
    }
}
