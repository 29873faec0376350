//! PNG line plots: a [`Figure`] is a title over one or more stacked [`Panel`]s that share
//! the figure's width; each panel has its own axes (named, units in the label), series and
//! legend. Rendered by plotters' bitmap backend with the bundled DejaVu Sans, registered
//! once per process.

use std::path::Path;
use std::sync::OnceLock;

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::{register_font, FontStyle};

/// DejaVu Sans 2.37 (licence in `assets/LICENSE-DejaVu.txt`).
static FONT: &[u8] = include_bytes!("../../../assets/DejaVuSans.ttf");
/// The family name the bundled font is registered under.
const FAMILY: &str = "sans-serif";

/// Registers the bundled font with plotters, once.
fn font() -> anyhow::Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| register_font(FAMILY, FontStyle::Normal, FONT).is_ok());
    anyhow::ensure!(ok, "the bundled font could not be loaded");
    Ok(())
}

/// How a series is drawn.
#[derive(Clone, Debug, PartialEq)]
pub enum Kind {
    /// A solid line through the points.
    Line,
    /// A dashed line through the points (references, limits).
    Dashed,
    /// A filled band between a lower and an upper curve (the points are the upper
    /// curve); for the min/max envelope of a decimated signal.
    Band {
        /// Lower curve, same x as the points.
        lower: Vec<(f64, f64)>,
    },
}

/// One named series of `(x, y)` points.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    /// Legend entry.
    pub name: String,
    /// Points, in drawing order.
    pub points: Vec<(f64, f64)>,
    /// How it is drawn.
    pub kind: Kind,
    /// Palette index; `None` takes the series' position in its panel.
    pub color: Option<usize>,
}

impl Series {
    /// A solid line.
    #[must_use]
    pub fn line(name: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Self {
            name: name.into(),
            points,
            kind: Kind::Line,
            color: None,
        }
    }

    /// A dashed line.
    #[must_use]
    pub fn dashed(name: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Self {
            kind: Kind::Dashed,
            ..Self::line(name, points)
        }
    }

    /// A band between `lower` and `upper` (same x values).
    #[must_use]
    pub fn band(name: impl Into<String>, lower: Vec<(f64, f64)>, upper: Vec<(f64, f64)>) -> Self {
        Self {
            kind: Kind::Band { lower },
            ..Self::line(name, upper)
        }
    }

    /// Draws with palette colour `index` (0 blue, 1 red, 2 green, 3 orange, 4 purple,
    /// 5 brown, 6 grey, 7 black).
    #[must_use]
    pub fn color(mut self, index: usize) -> Self {
        self.color = Some(index);
        self
    }

    fn all_points(&self) -> impl Iterator<Item = &(f64, f64)> {
        let lower: &[(f64, f64)] = match &self.kind {
            Kind::Band { lower } => lower,
            _ => &[],
        };
        self.points.iter().chain(lower)
    }
}

/// Where a panel's legend goes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Legend {
    /// Upper right corner.
    #[default]
    UpperRight,
    /// Lower right corner.
    LowerRight,
    /// Upper left corner.
    UpperLeft,
    /// Lower left corner.
    LowerLeft,
    /// No legend.
    None,
}

/// One chart: axes, series, legend.
#[derive(Clone, Debug, PartialEq)]
pub struct Panel {
    /// Caption above the chart.
    pub caption: Option<String>,
    /// Horizontal axis label, units in brackets (`time [s]`).
    pub x_label: String,
    /// Vertical axis label, units in brackets (`x1 [mm]`).
    pub y_label: String,
    /// The series, drawn in order (bands first look best).
    pub series: Vec<Series>,
    /// Horizontal range; `None` fits the data.
    pub x_range: Option<(f64, f64)>,
    /// Vertical range; `None` fits the data with a 5 % margin.
    pub y_range: Option<(f64, f64)>,
    /// Legend position.
    pub legend: Legend,
}

impl Panel {
    /// An empty panel with these axis labels.
    #[must_use]
    pub fn new(x_label: impl Into<String>, y_label: impl Into<String>) -> Self {
        Self {
            caption: None,
            x_label: x_label.into(),
            y_label: y_label.into(),
            series: Vec::new(),
            x_range: None,
            y_range: None,
            legend: Legend::default(),
        }
    }

    /// Sets the caption.
    #[must_use]
    pub fn caption(mut self, caption: impl Into<String>) -> Self {
        self.caption = Some(caption.into());
        self
    }

    /// Adds a series.
    #[must_use]
    pub fn series(mut self, series: Series) -> Self {
        self.series.push(series);
        self
    }

    /// Fixes the horizontal range.
    #[must_use]
    pub fn x_range(mut self, lo: f64, hi: f64) -> Self {
        self.x_range = Some((lo, hi));
        self
    }

    /// Fixes the vertical range.
    #[must_use]
    pub fn y_range(mut self, lo: f64, hi: f64) -> Self {
        self.y_range = Some((lo, hi));
        self
    }

    /// Places the legend.
    #[must_use]
    pub fn legend(mut self, legend: Legend) -> Self {
        self.legend = legend;
        self
    }

    /// The ranges drawn: the fixed ones, else the data's (y with a 5 % margin).
    #[must_use]
    pub fn ranges(&self) -> ((f64, f64), (f64, f64)) {
        let pts = || self.series.iter().flat_map(Series::all_points);
        let fit = |vals: &mut dyn Iterator<Item = f64>, margin: f64| {
            let (lo, hi) = vals
                .filter(|v| v.is_finite())
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                    (lo.min(v), hi.max(v))
                });
            if lo > hi {
                return (0.0, 1.0);
            }
            let span = hi - lo;
            if span <= f64::EPSILON * lo.abs().max(hi.abs()).max(1e-300) {
                let pad = if lo == 0.0 { 1.0 } else { 0.1 * lo.abs() };
                return (lo - pad, hi + pad);
            }
            (lo - margin * span, hi + margin * span)
        };
        let x = self
            .x_range
            .unwrap_or_else(|| fit(&mut pts().map(|p| p.0), 0.0));
        let y = self
            .y_range
            .unwrap_or_else(|| fit(&mut pts().map(|p| p.1), 0.05));
        (x, y)
    }
}

/// A titled stack of panels.
#[derive(Clone, Debug, PartialEq)]
pub struct Figure {
    /// Title over the figure.
    pub title: String,
    /// Panels, top to bottom.
    pub panels: Vec<Panel>,
    /// Width \[px\].
    pub width_px: u32,
    /// Height of one panel \[px\].
    pub panel_height_px: u32,
}

/// Colour-blind-friendly palette (Okabe-Ito, plus grey and black).
const PALETTE: [RGBColor; 8] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(230, 159, 0),
    RGBColor(204, 121, 167),
    RGBColor(140, 86, 75),
    RGBColor(128, 128, 128),
    RGBColor(0, 0, 0),
];

impl Figure {
    /// An empty figure, 1200 px wide, 450 px per panel.
    #[must_use]
    pub fn new(title: impl Into<String>) -> Self {
        Self {
            title: title.into(),
            panels: Vec::new(),
            width_px: 1200,
            panel_height_px: 450,
        }
    }

    /// Adds a panel below the others.
    #[must_use]
    pub fn panel(mut self, panel: Panel) -> Self {
        self.panels.push(panel);
        self
    }

    /// Sets the size: width and height of one panel \[px\].
    #[must_use]
    pub fn size(mut self, width_px: u32, panel_height_px: u32) -> Self {
        self.width_px = width_px;
        self.panel_height_px = panel_height_px;
        self
    }

    /// Renders the figure to a PNG file.
    ///
    /// # Errors
    /// No panel, the font, or the file system, with the file's name.
    pub fn write_png(&self, path: &Path) -> anyhow::Result<()> {
        anyhow::ensure!(
            !self.panels.is_empty(),
            "figure `{}` has no panel",
            self.title
        );
        font()?;
        let fail = |e: String| anyhow::anyhow!("cannot draw {}: {e}", path.display());
        let n = u32::try_from(self.panels.len()).unwrap_or(u32::MAX);
        let title_px = 50;
        let height = title_px + self.panel_height_px.saturating_mul(n);
        let root = BitMapBackend::new(path, (self.width_px, height)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| fail(e.to_string()))?;
        // The title is drawn by hand, centred in its strip: plotters' `titled` places
        // ab_glyph text too high and clips its top.
        let (head, body) = root.split_vertically(title_px);
        let style = TextStyle::from((FAMILY, 28).into_font())
            .color(&BLACK)
            .pos(Pos::new(HPos::Center, VPos::Center));
        let centre = (
            i32::try_from(self.width_px / 2).unwrap_or(0),
            i32::try_from(title_px / 2).unwrap_or(0) + 4,
        );
        head.draw_text(&self.title, &style, centre)
            .map_err(|e| fail(e.to_string()))?;
        for (area, panel) in body
            .split_evenly((self.panels.len(), 1))
            .iter()
            .zip(&self.panels)
        {
            draw_panel(area, panel).map_err(fail)?;
        }
        root.present().map_err(|e| fail(e.to_string()))
    }
}

fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    panel: &Panel,
) -> Result<(), String> {
    let ((x0, x1), (y0, y1)) = panel.ranges();
    let mut builder = ChartBuilder::on(area);
    builder
        .margin_left(12)
        .margin_right(28)
        .margin_top(8)
        .margin_bottom(8)
        .x_label_area_size(52)
        .y_label_area_size(86);
    if let Some(c) = &panel.caption {
        builder.caption(c, (FAMILY, 21));
    }
    let mut chart = builder
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc(&panel.x_label)
        .y_desc(&panel.y_label)
        .label_style((FAMILY, 16))
        .axis_desc_style((FAMILY, 18))
        .x_label_formatter(&|v| tick(*v))
        .y_label_formatter(&|v| tick(*v))
        .x_max_light_lines(1)
        .y_max_light_lines(1)
        .light_line_style(RGBColor(240, 240, 240))
        .bold_line_style(RGBColor(215, 215, 215))
        .draw()
        .map_err(|e| e.to_string())?;
    let (xr, yr) = (x0.min(x1)..=x0.max(x1), y0.min(y1)..=y0.max(y1));
    let inside = |p: &(f64, f64)| xr.contains(&p.0) && yr.contains(&p.1);
    for (k, s) in panel.series.iter().enumerate() {
        let color = PALETTE[s.color.unwrap_or(k) % PALETTE.len()];
        // plotters does not clip to the plotting area: lines keep only their runs of
        // points inside it, bands are clamped to it. Dense lines are drawn 1 px wide: the
        // miter joins of a thick zigzag spike far out of the chart.
        let width = if s.points.len() > DENSE_POINTS { 1 } else { 2 };
        let runs = runs(&s.points, &inside);
        let anno = match &s.kind {
            Kind::Line => chart.draw_series(
                runs.into_iter()
                    .map(|r| PathElement::new(r, color.stroke_width(width))),
            ),
            Kind::Dashed => chart.draw_series(
                runs.into_iter()
                    .flat_map(|r| DashedLineSeries::new(r, 8, 6, color.stroke_width(2))),
            ),
            Kind::Band { lower } => {
                let outline: Vec<(f64, f64)> = s
                    .points
                    .iter()
                    .copied()
                    .chain(lower.iter().rev().copied())
                    .filter(|p| p.0.is_finite() && p.1.is_finite())
                    .map(|(x, y)| {
                        (
                            x.clamp(*xr.start(), *xr.end()),
                            y.clamp(*yr.start(), *yr.end()),
                        )
                    })
                    .collect();
                chart.draw_series(std::iter::once(Polygon::new(
                    outline,
                    color.mix(0.35).filled(),
                )))
            }
        }
        .map_err(|e| e.to_string())?;
        if s.name.is_empty() {
            continue;
        }
        match s.kind {
            Kind::Band { .. } => anno.label(&s.name).legend(move |(x, y)| {
                Rectangle::new([(x, y - 6), (x + 24, y + 6)], color.mix(0.35).filled())
            }),
            _ => anno.label(&s.name).legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 24, y)], color.stroke_width(2))
            }),
        };
    }
    let position = match panel.legend {
        Legend::None => return Ok(()),
        Legend::UpperRight => SeriesLabelPosition::UpperRight,
        Legend::LowerRight => SeriesLabelPosition::LowerRight,
        Legend::UpperLeft => SeriesLabelPosition::UpperLeft,
        Legend::LowerLeft => SeriesLabelPosition::LowerLeft,
    };
    if panel.series.iter().any(|s| !s.name.is_empty()) {
        chart
            .configure_series_labels()
            .position(position)
            .label_font((FAMILY, 16))
            .background_style(WHITE.mix(0.9))
            .border_style(RGBColor(160, 160, 160))
            .draw()
            .map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// Above this many points a line is drawn 1 px wide.
const DENSE_POINTS: usize = 500;

/// The maximal runs of consecutive points that satisfy `keep`.
fn runs(points: &[(f64, f64)], keep: &dyn Fn(&(f64, f64)) -> bool) -> Vec<Vec<(f64, f64)>> {
    let mut out: Vec<Vec<(f64, f64)>> = Vec::new();
    let mut current = Vec::new();
    for p in points {
        if keep(p) {
            current.push(*p);
        } else if !current.is_empty() {
            out.push(std::mem::take(&mut current));
        }
    }
    if !current.is_empty() {
        out.push(current);
    }
    out
}

/// A tick label: short, without float noise (`0.25`, `-14`, `1e-6`).
fn tick(v: f64) -> String {
    // Range arithmetic leaves float noise where a tick should read 0.
    if v.abs() < 1e-12 {
        return "0".into();
    }
    let a = v.abs();
    if !(1e-3..1e5).contains(&a) {
        let s = format!("{v:.1e}");
        return s.replace(".0e", "e");
    }
    let s = format!("{v:.4}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".into()
    } else {
        s.into()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_labels_are_short() {
        assert_eq!(tick(0.25), "0.25");
        assert_eq!(tick(-14.0), "-14");
        assert_eq!(tick(0.30000000000000004), "0.3");
        assert_eq!(tick(1e-6), "1e-6");
        assert_eq!(tick(0.0), "0");
        assert_eq!(tick(-2.2e-16), "0");
    }

    #[test]
    fn ranges_fit_the_data_with_a_margin() {
        let p = Panel::new("t [s]", "i [A]")
            .series(Series::line("a", vec![(0.0, 1.0), (1.0, 3.0)]))
            .series(Series::band(
                "b",
                vec![(0.0, -1.0), (1.0, -1.0)],
                vec![(0.0, 2.0), (1.0, 2.0)],
            ));
        let ((x0, x1), (y0, y1)) = p.ranges();
        assert_eq!((x0, x1), (0.0, 1.0));
        assert!((y0 + 1.2).abs() < 1e-12 && (y1 - 3.2).abs() < 1e-12);
        let flat = Panel::new("t", "y").series(Series::line("c", vec![(0.0, 5.0), (1.0, 5.0)]));
        assert_eq!(flat.ranges().1, (4.5, 5.5));
    }
}
