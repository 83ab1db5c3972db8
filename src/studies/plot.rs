//! Minimal SVG figures (convergence plots, load–displacement curves, sensitivity
//! comparisons) rendered with `plotters` and an embedded DejaVu Sans font, so no
//! system fontconfig is needed.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Once;

use plotters::coord::combinators::{LogCoord, WithKeyPoints};
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::coord::types::RangedCoordf64;
use plotters::element::DashedPathElement;
use plotters::prelude::*;

/// Figure size in pixels.
const SIZE: (u32, u32) = (800, 500);
/// Font family used for every text element (registered from `dejavu`).
const FONT: &str = "sans-serif";
/// Colour-blind-friendly palette (Okabe–Ito, yellow replaced by a dark olive).
const PALETTE: [RGBColor; 8] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
    RGBColor(0, 0, 0),
    RGBColor(140, 120, 20),
];
const GREY: RGBColor = RGBColor(150, 150, 150);

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Style {
    /// Solid line, broken across dropped (non-plottable) points.
    Line,
    /// Markers only.
    Points,
    /// Solid line with markers.
    LinePoints,
    /// Dashed line, broken across dropped points.
    Dashed,
}

/// One curve.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend label.
    pub label: String,
    /// Data points `(x, y)`; non-plottable points are dropped at render time.
    pub points: Vec<(f64, f64)>,
    /// Drawing style.
    pub style: Style,
}

/// A 2D figure.
#[derive(Debug, Clone)]
pub struct Figure {
    /// Title drawn above the plot.
    pub title: String,
    /// Label of the horizontal axis.
    pub x_label: String,
    /// Label of the vertical axis.
    pub y_label: String,
    /// Logarithmic horizontal axis.
    pub log_x: bool,
    /// Logarithmic vertical axis.
    pub log_y: bool,
    /// Curves, drawn in order.
    pub series: Vec<Series>,
    /// x positions to mark with thin vertical grey dashed lines (e.g. flagged non-differentiable increments)
    pub marks_x: Vec<f64>,
    /// optional horizontal reference line (value, label), e.g. a target ratio
    pub reference_y: Option<(f64, String)>,
}

impl Figure {
    /// Empty figure with linear axes.
    pub fn new(
        title: impl Into<String>,
        x_label: impl Into<String>,
        y_label: impl Into<String>,
    ) -> Self {
        Figure {
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            log_x: false,
            log_y: false,
            series: Vec::new(),
            marks_x: Vec::new(),
            reference_y: None,
        }
    }

    /// Use a logarithmic x axis.
    pub fn log_x(mut self) -> Self {
        self.log_x = true;
        self
    }

    /// Use a logarithmic y axis.
    pub fn log_y(mut self) -> Self {
        self.log_y = true;
        self
    }

    /// Append a series.
    pub fn series(
        mut self,
        label: impl Into<String>,
        points: Vec<(f64, f64)>,
        style: Style,
    ) -> Self {
        self.series.push(Series {
            label: label.into(),
            points,
            style,
        });
        self
    }

    /// Append x positions to mark with vertical dashed lines (drawn only inside the data's x range).
    pub fn marks(mut self, xs: impl IntoIterator<Item = f64>) -> Self {
        self.marks_x.extend(xs);
        self
    }

    /// Set the horizontal reference line `y = value`, shown in the legend as `label`.
    pub fn reference(mut self, value: f64, label: impl Into<String>) -> Self {
        self.reference_y = Some((value, label.into()));
        self
    }
}

/// Errors from [`write_svg`].
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// Writing the SVG file failed.
    #[error("cannot write plot {}: {source}", path.display())]
    Io {
        /// Target file.
        path: PathBuf,
        /// Underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// Rendering failed inside `plotters` (e.g. font unavailable).
    #[error("cannot draw plot {}: {message}", path.display())]
    Drawing {
        /// Target file.
        path: PathBuf,
        /// Error reported by the drawing backend.
        message: String,
    },
    /// No series has a single plottable point; carries the figure title.
    #[error("figure \"{0}\" has no plottable (finite, and positive on log axes) point")]
    NoData(String),
}

static FONT_INIT: Once = Once::new();
static FONT_OK: AtomicBool = AtomicBool::new(false);

fn register_font() -> bool {
    FONT_INIT.call_once(|| {
        let ok = plotters::style::register_font(FONT, FontStyle::Normal, dejavu::sans::regular())
            .is_ok();
        FONT_OK.store(ok, Ordering::SeqCst);
    });
    FONT_OK.load(Ordering::SeqCst)
}

fn usable(v: f64, log: bool) -> bool {
    v.is_finite() && (!log || v > 0.0)
}

/// Axis extent; for log axes `lo`/`hi` are the powers of ten bounding the data.
#[derive(Clone, Copy)]
struct Axis {
    lo: f64,
    hi: f64,
    log: bool,
}

impl Axis {
    /// Range of the given (already filtered) values; `None` if there are none.
    fn fit(values: impl Iterator<Item = f64>, log: bool) -> Option<Axis> {
        let (mut min, mut max) = (f64::INFINITY, f64::NEG_INFINITY);
        for v in values {
            min = min.min(v);
            max = max.max(v);
        }
        if min > max {
            return None;
        }
        if log {
            let lo = (min.log10() + 1e-9).floor();
            let hi = (max.log10() - 1e-9).ceil();
            let (lo, hi) = if hi <= lo {
                (lo - 1.0, lo + 1.0)
            } else {
                (lo, hi)
            };
            let lo = lo.clamp(-300.0, 299.0);
            let hi = hi.clamp(lo + 1.0, 300.0);
            return Some(Axis {
                lo: 10f64.powf(lo),
                hi: 10f64.powf(hi),
                log,
            });
        }
        // halves avoid overflow of max - min for huge magnitudes
        let mid = (0.5 * min + 0.5 * max).clamp(-1e300, 1e300);
        let mut half = 0.5 * max - 0.5 * min;
        if half <= 1e-6 * mid.abs() || half < 1e-300 {
            half = if mid.abs() > 1e-290 {
                0.1 * mid.abs()
            } else {
                1.0
            };
        }
        let half = (1.05 * half).min(1e300);
        Some(Axis {
            lo: mid - half,
            hi: mid + half,
            log,
        })
    }

    fn contains(&self, v: f64) -> bool {
        v >= self.lo && v <= self.hi
    }

    /// Fraction of the axis length at which `v` sits (for legend placement).
    fn frac(&self, v: f64) -> f64 {
        if self.log {
            (v.log10() - self.lo.log10()) / (self.hi.log10() - self.lo.log10())
        } else {
            (v - self.lo) / (self.hi - self.lo)
        }
    }

    /// Decade ticks (bold) and 2..9 sub-ticks (light) for a log axis. Plotters'
    /// own log key points silently skip values below ~2.2e-16, so they are given
    /// explicitly.
    fn decades(&self) -> (Vec<f64>, Vec<f64>) {
        let (a, b) = (
            self.lo.log10().round() as i32,
            self.hi.log10().round() as i32,
        );
        let step = ((b - a) as usize).div_ceil(10).max(1);
        let step = step as i32;
        let bold = (a..=b)
            .filter(|e| e.rem_euclid(step) == 0)
            .map(|e| 10f64.powi(e))
            .collect();
        let light = if b - a <= 8 {
            (a..b)
                .flat_map(|e| (2..10).map(move |m| f64::from(m) * 10f64.powi(e)))
                .collect()
        } else if b - a <= 60 {
            (a..=b).map(|e| 10f64.powi(e)).collect()
        } else {
            Vec::new()
        };
        (bold, light)
    }
}

/// Shortest scientific representation (up to 6 significant digits), e.g. `1e-6`, `2.5e3`.
fn fmt_sci(v: f64) -> String {
    (0..6)
        .map(|p| format!("{v:.p$e}"))
        .find(|s| {
            s.parse::<f64>()
                .is_ok_and(|r| (r - v).abs() <= 1e-9 * v.abs())
        })
        .unwrap_or_else(|| format!("{v:.5e}"))
}

/// Tick label for value `v` on axis `ax`: scientific on log axes and for very
/// large/small magnitudes, trimmed decimals otherwise.
fn fmt_tick(v: f64, ax: &Axis) -> String {
    let a = v.abs();
    if !ax.log && a <= 1e-9 * (ax.hi - ax.lo) {
        return "0".into(); // round-off residue of a zero tick
    }
    if ax.log || !(1e-3..1e5).contains(&a) {
        return fmt_sci(v);
    }
    let s = format!("{v:.6}");
    s.trim_end_matches('0').trim_end_matches('.').into()
}

/// Split a series into runs of consecutive plottable points (clamped to the axes).
fn runs(points: &[(f64, f64)], x: &Axis, y: &Axis) -> Vec<Vec<(f64, f64)>> {
    let mut out: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
    for &(px, py) in points {
        if usable(px, x.log) && usable(py, y.log) {
            out.last_mut()
                .unwrap()
                .push((px.clamp(x.lo, x.hi), py.clamp(y.lo, y.hi)));
        } else if !out.last().unwrap().is_empty() {
            out.push(Vec::new());
        }
    }
    out.retain(|r| !r.is_empty());
    out
}

/// Legend corner with the fewest data points nearby.
fn legend_position(data: &[Vec<Vec<(f64, f64)>>], x: &Axis, y: &Axis) -> SeriesLabelPosition {
    use SeriesLabelPosition::*;
    // corners as (right?, upper?), in order of preference
    let corners = [(true, true), (false, true), (true, false), (false, false)];
    let mut count = [0usize; 4];
    for &(px, py) in data.iter().flatten().flatten() {
        let (fx, fy) = (x.frac(px), y.frac(py));
        for (n, &(right, upper)) in count.iter_mut().zip(&corners) {
            let inx = if right { fx > 0.6 } else { fx < 0.4 };
            let iny = if upper { fy > 0.6 } else { fy < 0.4 };
            *n += usize::from(inx && iny);
        }
    }
    match (0..4).min_by_key(|&c| count[c]) {
        Some(1) => UpperLeft,
        Some(2) => LowerRight,
        Some(3) => LowerLeft,
        _ => UpperRight,
    }
}

type Area<'a> = DrawingArea<SVGBackend<'a>, plotters::coord::Shift>;

/// Render a 2D figure to an 800x500 SVG file at `path` (the parent directory must exist).
///
/// Points that cannot be shown (non-finite, or non-positive on a log axis) are
/// dropped; lines are broken across them. The axes span the plottable data (and
/// the reference line); marks outside the x range are not drawn. Returns
/// [`PlotError::NoData`] when no series has a plottable point.
pub fn write_svg(fig: &Figure, path: &Path) -> Result<(), PlotError> {
    write_svg_stack(std::slice::from_ref(fig), path)
}

/// Write several figures into one SVG file, stacked top to bottom (one panel of the
/// usual size each), with the rules of [`write_svg`] applied to every panel. Returns
/// [`PlotError::NoData`] for the first panel without a plottable point.
pub(crate) fn write_svg_stack(figs: &[Figure], path: &Path) -> Result<(), PlotError> {
    let draw_err = |message: String| PlotError::Drawing {
        path: path.to_path_buf(),
        message,
    };
    let mut axes = Vec::with_capacity(figs.len());
    for fig in figs {
        axes.push(fit_axes(fig)?);
    }
    if figs.is_empty() {
        return Err(PlotError::NoData(String::new()));
    }
    if !register_font() {
        return Err(draw_err(
            "embedded DejaVu Sans font could not be registered".into(),
        ));
    }
    let mut svg = String::new();
    {
        let size = (SIZE.0, SIZE.1 * figs.len() as u32);
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        let panels = root.split_evenly((figs.len(), 1));
        for ((fig, (x, y)), area) in figs.iter().zip(&axes).zip(&panels) {
            let r = match (x.log, y.log) {
                (false, false) => render(area, fig, x, y, lin(x), lin(y)),
                (true, false) => render(area, fig, x, y, logr(x), lin(y)),
                (false, true) => render(area, fig, x, y, lin(x), logr(y)),
                (true, true) => render(area, fig, x, y, logr(x), logr(y)),
            };
            r.map_err(draw_err)?;
        }
        root.present().map_err(|e| draw_err(e.to_string()))?;
    }
    std::fs::write(path, svg).map_err(|source| PlotError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// The axes of a figure's plottable data (and reference line).
fn fit_axes(fig: &Figure) -> Result<(Axis, Axis), PlotError> {
    let all = fig.series.iter().flat_map(|s| s.points.iter());
    let good: Vec<(f64, f64)> = all
        .copied()
        .filter(|&(x, y)| usable(x, fig.log_x) && usable(y, fig.log_y))
        .collect();
    let (Some(x), Some(y)) = (
        Axis::fit(good.iter().map(|p| p.0), fig.log_x),
        Axis::fit(
            good.iter().map(|p| p.1).chain(
                fig.reference_y
                    .iter()
                    .map(|r| r.0)
                    .filter(|&v| usable(v, fig.log_y)),
            ),
            fig.log_y,
        ),
    ) else {
        return Err(PlotError::NoData(fig.title.clone()));
    };
    Ok((x, y))
}

fn lin(a: &Axis) -> RangedCoordf64 {
    (a.lo..a.hi).into()
}

fn logr(a: &Axis) -> WithKeyPoints<LogCoord<f64>> {
    let (bold, light) = a.decades();
    (a.lo..a.hi)
        .log_scale()
        .with_key_points(bold)
        .with_light_points(light)
}

fn render<X, Y>(root: &Area, fig: &Figure, x: &Axis, y: &Axis, xr: X, yr: Y) -> Result<(), String>
where
    X: AsRangedCoord<Value = f64>,
    Y: AsRangedCoord<Value = f64>,
    X::CoordDescType: ValueFormatter<f64>,
    Y::CoordDescType: ValueFormatter<f64>,
{
    let e = |e: DrawingAreaErrorKind<std::io::Error>| e.to_string();
    root.fill(&WHITE).map_err(e)?;
    let mut chart = ChartBuilder::on(root)
        .caption(&fig.title, (FONT, 22))
        .margin(15)
        .x_label_area_size(50)
        .y_label_area_size(75)
        .build_cartesian_2d(xr, yr)
        .map_err(e)?;
    let (fx, fy) = (|v: &f64| fmt_tick(*v, x), |v: &f64| fmt_tick(*v, y));
    chart
        .configure_mesh()
        .x_desc(fig.x_label.as_str())
        .y_desc(fig.y_label.as_str())
        .x_label_formatter(&fx)
        .y_label_formatter(&fy)
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 16))
        .bold_line_style(RGBColor(215, 215, 215))
        .light_line_style(RGBColor(240, 240, 240))
        .max_light_lines(4)
        .draw()
        .map_err(e)?;

    for &m in fig
        .marks_x
        .iter()
        .filter(|&&m| usable(m, x.log) && x.contains(m))
    {
        chart
            .draw_series(DashedLineSeries::new(
                [(m, y.lo), (m, y.hi)],
                4,
                4,
                GREY.stroke_width(1),
            ))
            .map_err(e)?;
    }
    if let Some((v, label)) = fig.reference_y.as_ref().filter(|r| usable(r.0, y.log)) {
        let st = RGBColor(90, 90, 90).stroke_width(1);
        chart
            .draw_series(DashedLineSeries::new([(x.lo, *v), (x.hi, *v)], 10, 4, st))
            .map_err(e)?
            .label(label.as_str())
            .legend(move |(px, py)| DashedPathElement::new([(px, py), (px + 20, py)], 6, 3, st));
    }

    let data: Vec<_> = fig.series.iter().map(|s| runs(&s.points, x, y)).collect();
    for (i, (s, rs)) in fig.series.iter().zip(&data).enumerate() {
        let c = PALETTE[i % PALETTE.len()];
        let line = c.stroke_width(2);
        let shape = (i % PALETTE.len() + i / PALETTE.len()) % 3;
        match s.style {
            Style::Line | Style::LinePoints => {
                for r in rs {
                    chart
                        .draw_series(LineSeries::new(r.iter().copied(), line))
                        .map_err(e)?;
                }
            }
            Style::Dashed => {
                for r in rs {
                    chart
                        .draw_series(DashedLineSeries::new(r.iter().copied(), 8, 5, line))
                        .map_err(e)?;
                }
            }
            Style::Points => {}
        }
        if s.style != Style::Points {
            // isolated points between gaps would otherwise be invisible
            let lone = rs
                .iter()
                .filter(|r| r.iter().all(|p| *p == r[0]))
                .map(|r| Circle::new(r[0], 2, c.filled()));
            chart.draw_series(lone).map_err(e)?;
        }
        let has_marker = matches!(s.style, Style::Points | Style::LinePoints);
        let pts = rs.iter().flatten().copied().filter(|_| has_marker);
        // markers are drawn with concrete types: a `DynElement` inside `draw_series`
        // would need a `'static` backend
        let anno = match shape {
            0 => chart.draw_series(pts.map(|p| Circle::new(p, 4, c.filled()))),
            1 => chart.draw_series(pts.map(|p| TriangleMarker::new(p, 5, c.filled()))),
            _ => chart.draw_series(pts.map(|p| Cross::new(p, 4, line))),
        };
        let anno = anno.map_err(e)?.label(s.label.as_str());
        // Legend glyphs must be concrete element types: a `DynElement` nested in a
        // composition needs a `'static` backend, and `DrawingErrorKind` is not
        // re-exported, so no custom `Drawable` can be written either.
        let seg = if s.style == Style::Points {
            vec![(10, 0)]
        } else {
            vec![(0, 0), (20, 0)]
        };
        match (s.style, shape) {
            (Style::Dashed, _) => anno.legend(move |(px, py)| {
                DashedPathElement::new([(px, py), (px + 20, py)], 6, 3, line)
            }),
            (Style::Line, _) => {
                anno.legend(move |(px, py)| PathElement::new([(px, py), (px + 20, py)], line))
            }
            (_, 0) => anno.legend(move |p| {
                EmptyElement::at(p)
                    + PathElement::new(seg.clone(), line)
                    + Circle::new((10, 0), 4, c.filled())
            }),
            (_, 1) => anno.legend(move |p| {
                EmptyElement::at(p)
                    + PathElement::new(seg.clone(), line)
                    + TriangleMarker::new((10, 0), 5, c.filled())
            }),
            _ => anno.legend(move |p| {
                EmptyElement::at(p)
                    + PathElement::new(seg.clone(), line)
                    + Cross::new((10, 0), 4, line)
            }),
        };
    }
    chart
        .configure_series_labels()
        .position(legend_position(&data, x, y))
        .background_style(WHITE.mix(0.85))
        .border_style(RGBColor(160, 160, 160))
        .label_font((FONT, 14))
        .draw()
        .map_err(e)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(fig: &Figure, name: &str) -> String {
        let path =
            std::env::temp_dir().join(format!("fricsens_plot_{}_{name}.svg", std::process::id()));
        write_svg(fig, &path).unwrap_or_else(|e| panic!("{name}: {e}"));
        let s = std::fs::read_to_string(&path).unwrap();
        assert!(s.starts_with("<svg"), "{name}");
        assert!(s.contains(&fig.title), "{name}: title missing");
        s
    }

    #[test]
    fn linear() {
        let pts: Vec<_> = (0..50)
            .map(|i| (f64::from(i) * 0.1, (f64::from(i) * 0.1).sin()))
            .collect();
        let f = Figure::new("Linear sine", "u [mm]", "F [N]").series("sin", pts, Style::Line);
        check(&f, "linear");
    }

    #[test]
    fn log_log_with_bad_values() {
        let mut e: Vec<_> = (0..20)
            .map(|i| (10f64.powi(-i), 10f64.powi(-2 * i) + 1e-30))
            .collect();
        e[3].1 = 0.0;
        e[5].1 = f64::NAN;
        e[7].0 = f64::INFINITY;
        e[9].1 = -1.0;
        e.push((f64::NEG_INFINITY, f64::NAN));
        let f = Figure::new("FD convergence", "h", "rel. error")
            .log_x()
            .log_y();
        let f = f
            .series("FDM", e.clone(), Style::LinePoints)
            .series("DDM", e, Style::Dashed);
        let s = check(&f, "loglog");
        assert!(
            s.contains(">\n1e-18\n<"),
            "decade tick labels below 1e-16 expected"
        );
    }

    #[test]
    fn single_point_and_constant() {
        check(
            &Figure::new("Single", "x", "y").series("p", vec![(1.0, 2.0)], Style::Points),
            "single",
        );
        check(
            &Figure::new("Zero", "x", "y").series("p", vec![(0.0, 0.0), (0.0, 0.0)], Style::Line),
            "zero",
        );
        let f = Figure::new("SingleLog", "x", "y").log_x().log_y().series(
            "p",
            vec![(1e-6, 1e-6)],
            Style::LinePoints,
        );
        check(&f, "single_log");
        let huge = vec![
            (-f64::MAX, f64::MIN_POSITIVE),
            (f64::MAX, 5e-324),
            (0.0, f64::MAX),
        ];
        check(
            &Figure::new("Huge", "x", "y").series("h", huge.clone(), Style::Dashed),
            "huge",
        );
        check(
            &Figure::new("HugeLog", "x", "y")
                .log_y()
                .series("h", huge, Style::LinePoints),
            "huge_log",
        );
    }

    #[test]
    fn no_data() {
        let f = Figure::new("Nothing", "x", "y").series(
            "nan",
            vec![(f64::NAN, 1.0), (1.0, f64::INFINITY)],
            Style::Line,
        );
        assert!(
            matches!(write_svg(&f, &std::env::temp_dir().join("never.svg")), Err(PlotError::NoData(t)) if t == "Nothing")
        );
        let f = Figure::new("Zeros", "x", "y").log_y().series(
            "z",
            vec![(1.0, 0.0), (2.0, -1.0)],
            Style::Points,
        );
        assert!(matches!(
            write_svg(&f, &std::env::temp_dir().join("never.svg")),
            Err(PlotError::NoData(_))
        ));
        assert!(matches!(
            write_svg(&Figure::new("Empty", "x", "y"), Path::new("never.svg")),
            Err(PlotError::NoData(_))
        ));
    }

    #[test]
    fn many_series_marks_reference() {
        let mut f =
            Figure::new("Many series", "increment", "ratio").marks([3.0, 7.5, f64::NAN, 100.0]);
        f = f.reference(1.0, "target");
        for k in 0..11 {
            let pts = (0..12)
                .map(|i| (f64::from(i), 1.0 + f64::from(k * i) * 0.01))
                .collect();
            let style =
                [Style::Line, Style::Points, Style::LinePoints, Style::Dashed][k as usize % 4];
            f = f.series(format!("s{k}"), pts, style);
        }
        f = f.series("empty", vec![], Style::Line);
        let s = check(&f, "many");
        assert!(s.contains("target") && s.contains("s10"));
    }

    #[test]
    fn special_value_sweep_never_panics() {
        let v = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            5e-324,
            1e-300,
            f64::MAX,
            f64::NAN,
            f64::INFINITY,
            1e10,
        ];
        let path =
            std::env::temp_dir().join(format!("fricsens_plot_{}_sweep.svg", std::process::id()));
        for (k, &a) in v.iter().enumerate() {
            for &b in &v {
                let style = [Style::Line, Style::Points, Style::LinePoints, Style::Dashed][k % 4];
                let mut f =
                    Figure::new("Sweep", "x", "y").series("s", vec![(a, b), (b, a), (a, a)], style);
                f = f.marks([a, b]).reference(b, "ref");
                for (lx, ly) in [(false, false), (true, false), (false, true), (true, true)] {
                    (f.log_x, f.log_y) = (lx, ly);
                    match write_svg(&f, &path) {
                        Ok(()) | Err(PlotError::NoData(_)) => {}
                        Err(e) => panic!("({a}, {b}) log {lx}/{ly}: {e}"),
                    }
                }
            }
        }
    }

    #[test]
    fn io_error_has_path() {
        let f = Figure::new("T", "x", "y").series("a", vec![(0.0, 1.0)], Style::Line);
        let err = write_svg(&f, Path::new("/nonexistent_dir_fricsens/x.svg")).unwrap_err();
        assert!(
            matches!(err, PlotError::Io { .. })
                && err.to_string().contains("nonexistent_dir_fricsens")
        );
    }

    #[test]
    fn tick_format() {
        let log = Axis::fit([1e-20, 1e6].into_iter(), true).unwrap();
        let lin = Axis::fit([-1.0, 1.0].into_iter(), false).unwrap();
        assert_eq!(fmt_tick(1e-6, &log), "1e-6");
        assert_eq!(fmt_tick(10f64.powi(-17), &log), "1e-17");
        assert_eq!(fmt_tick(3e5, &log), "3e5");
        assert_eq!(fmt_tick(0.30000000000000004, &lin), "0.3");
        assert_eq!(fmt_tick(-2.220446049250313e-16, &lin), "0");
        assert_eq!(fmt_tick(-0.5, &lin), "-0.5");
        let tiny = Axis::fit([0.0, 1e-6].into_iter(), false).unwrap();
        assert_eq!(fmt_tick(2.5e-7, &tiny), "2.5e-7");
    }
}
