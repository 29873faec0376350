//! A table of strings: aligned text for a terminal or a README, CSV for a spreadsheet.

use std::path::Path;

use crate::analysis::report::sig;
use crate::simulation::metrics::Metrics;

/// A table: a header row and rows of cells, all strings (numbers formatted by the caller,
/// units in the header).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Table {
    /// Column names.
    pub header: Vec<String>,
    /// Rows; a row shorter than the header is padded with empty cells.
    pub rows: Vec<Vec<String>>,
}

impl Table {
    /// An empty table with these column names.
    #[must_use]
    pub fn new<S: Into<String>>(header: impl IntoIterator<Item = S>) -> Self {
        Self {
            header: header.into_iter().map(Into::into).collect(),
            rows: Vec::new(),
        }
    }

    /// Appends a row.
    pub fn push<S: Into<String>>(&mut self, row: impl IntoIterator<Item = S>) {
        self.rows.push(row.into_iter().map(Into::into).collect());
    }

    /// The cell in `row` under the column named `column`, if both exist.
    #[must_use]
    pub fn cell(&self, row: usize, column: &str) -> Option<&str> {
        let c = self.header.iter().position(|h| h == column)?;
        self.rows.get(row)?.get(c).map(String::as_str)
    }

    /// The row whose first cell is `key`.
    #[must_use]
    pub fn row(&self, key: &str) -> Option<&[String]> {
        self.rows
            .iter()
            .find(|r| r.first().is_some_and(|c| c == key))
            .map(Vec::as_slice)
    }

    /// The same table without the column named `column` (a quantity the source of its
    /// rows does not measure).
    #[must_use]
    pub fn without(mut self, column: &str) -> Self {
        if let Some(c) = self.header.iter().position(|h| h == column) {
            self.header.remove(c);
            for r in &mut self.rows {
                if c < r.len() {
                    r.remove(c);
                }
            }
        }
        self
    }

    /// The same table with rows and columns swapped: the header becomes the first column.
    /// Handy for printing a wide one-row-per-run table as one row per quantity.
    #[must_use]
    pub fn transposed(&self) -> Self {
        let n = self.rows.len();
        let mut out = Table::new(
            std::iter::once(self.header.first().cloned().unwrap_or_default()).chain(
                self.rows
                    .iter()
                    .map(|r| r.first().cloned().unwrap_or_default()),
            ),
        );
        for (c, name) in self.header.iter().enumerate().skip(1) {
            let mut row = Vec::with_capacity(n + 1);
            row.push(name.clone());
            row.extend(
                self.rows
                    .iter()
                    .map(|r| r.get(c).cloned().unwrap_or_default()),
            );
            out.rows.push(row);
        }
        out
    }

    /// The table as aligned Markdown: one line per row, `|`-separated, columns padded to
    /// their widest cell.
    #[must_use]
    pub fn to_text(&self) -> String {
        let cols = self
            .rows
            .iter()
            .map(Vec::len)
            .chain(std::iter::once(self.header.len()))
            .max()
            .unwrap_or(0);
        let cell = |row: &[String], c: usize| row.get(c).map_or("", |s| s.as_str()).to_owned();
        let mut width = vec![3; cols];
        for row in std::iter::once(&self.header).chain(&self.rows) {
            for (c, w) in width.iter_mut().enumerate() {
                *w = (*w).max(cell(row, c).chars().count());
            }
        }
        let line = |row: &[String]| {
            let mut s = String::from("|");
            for (c, w) in width.iter().enumerate() {
                let text = cell(row, c);
                let pad = w - text.chars().count();
                s.push(' ');
                s.push_str(&text);
                s.push_str(&" ".repeat(pad));
                s.push_str(" |");
            }
            s
        };
        let mut out = line(&self.header);
        out.push('\n');
        out.push('|');
        for w in &width {
            out.push_str(&"-".repeat(w + 2));
            out.push('|');
        }
        for row in &self.rows {
            out.push('\n');
            out.push_str(&line(row));
        }
        out.push('\n');
        out
    }

    /// Writes the table as CSV (header first).
    ///
    /// # Errors
    /// The file system's, with the file's name.
    pub fn write_csv(&self, path: &Path) -> anyhow::Result<()> {
        let fail = |e: csv::Error| anyhow::anyhow!("cannot write {}: {e}", path.display());
        let mut w = csv::WriterBuilder::new()
            .flexible(true)
            .from_path(path)
            .map_err(fail)?;
        w.write_record(&self.header).map_err(fail)?;
        for row in &self.rows {
            w.write_record(row).map_err(fail)?;
        }
        w.flush()
            .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))
    }
}

/// Column names of [`metrics_table`], units in brackets.
pub const METRICS_COLUMNS: [&str; 19] = [
    "case",
    "segment",
    "from [mm]",
    "to [mm]",
    "start [s]",
    "settling 2 % [s]",
    "overshoot [%]",
    "steady error [um]",
    "steady error [%]",
    "steady current [A]",
    "ripple p-p [A]",
    "ripple rms [A]",
    "peak current [A]",
    "peak |u| [V]",
    "rms u [V]",
    "peak |u command| [V]",
    "saturated samples",
    "faulted samples",
    "energy [J]",
];

/// The metrics of one or more runs, one row per reference segment: the case's name, the
/// segment number and every [`crate::simulation::metrics::Segment`] metric (definitions in
/// [`crate::simulation::metrics`]). A settling time that was not reached reads
/// `not settled`.
#[must_use]
pub fn metrics_table(cases: &[(&str, &Metrics)]) -> Table {
    let mut t = Table::new(METRICS_COLUMNS);
    for (name, m) in cases {
        for (k, s) in m.segments.iter().enumerate() {
            t.push([
                (*name).to_owned(),
                k.to_string(),
                sig(s.spec.from_m * 1e3, 4),
                sig(s.spec.to_m * 1e3, 4),
                sig(s.spec.start_s, 4),
                s.settling_time_s
                    .map_or_else(|| "not settled".into(), |v| sig(v, 4)),
                sig(s.overshoot_pct, 3),
                sig(s.steady_error_um, 4),
                sig(s.steady_error_pct, 3),
                sig(s.steady_current_a, 4),
                sig(s.ripple_pp_a, 3),
                sig(s.ripple_rms_a, 3),
                sig(s.i_peak_a, 4),
                sig(s.u_peak_v, 4),
                sig(s.u_rms_v, 4),
                sig(s.u_cmd_peak_v, 4),
                s.saturated_samples.to_string(),
                s.faulted_samples.to_string(),
                sig(s.energy_j, 4),
            ]);
        }
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn aligned_text_transpose_and_lookup() {
        let mut t = Table::new(["name", "value [A]"]);
        t.push(["peak", "22.4"]);
        t.push(["steady", "6.04"]);
        let text = t.to_text();
        assert_eq!(
            text,
            "| name   | value [A] |\n|--------|-----------|\n| peak   | 22.4      |\n| steady | 6.04      |\n"
        );
        assert_eq!(t.cell(1, "value [A]"), Some("6.04"));
        assert_eq!(t.row("peak").map(|r| r[1].as_str()), Some("22.4"));
        let tr = t.transposed();
        assert_eq!(tr.header, ["name", "peak", "steady"]);
        assert_eq!(tr.rows, [["value [A]", "22.4", "6.04"]]);
        let w = t.clone().without("value [A]");
        assert_eq!(w.header, ["name"]);
        assert_eq!(w.rows, [["peak"], ["steady"]]);
        assert_eq!(t.clone().without("energy [J]"), t);
    }
}
