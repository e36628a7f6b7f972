//! Pictures: heat maps with a colour bar or a categorical legend, and line and scatter
//! charts with named series, logarithmic axes, markers for special points and guide lines.
//! PNG or SVG, chosen by the file extension.
//!
//! Text is drawn with DejaVu Sans compiled into the binary (`assets/fonts/`, Bitstream Vera
//! licence) through plotters' `ab_glyph` feature, so pictures need no system font library
//! (fontconfig, freetype) and look the same on every machine.
//!
//! ```no_run
//! use longstep::plot::{AxisSpec, LineChart, MarkerSet, Series};
//! let mut chart = LineChart::new(
//!     "Energy error",
//!     AxisSpec::linear("outer step h (fs)"),
//!     AxisSpec::log("max |ΔE| / E0"),
//! );
//! chart.series.push(Series::line("impulse", vec![(1.0, 1e-4), (2.0, 4e-4)]));
//! chart.markers.push(MarkerSet::unstable(vec![(3.0, 1.0)]));
//! chart.save(std::path::Path::new("chart.png"))?;
//! # Ok::<(), longstep::Error>(())
//! ```

use std::f64::consts::PI;
use std::path::Path;
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint, Ranged, ValueFormatter};
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::error::{Error, Result};

mod labels;
use labels::{
    PointText, TextBox, group_guides, linear_ticks, log_axis_ticks, log_ticks, place_point_labels,
    stack_in_rows,
};

/// DejaVu Sans 2.37 (assets/fonts/README.md).
static FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// Register the font with plotters once; every drawing function calls this first.
fn register_font() -> Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font("sans-serif", FontStyle::Normal, FONT).is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err(Error::input(
            "the built-in font (DejaVu Sans) could not be loaded",
        ))
    }
}

/// Output format, from the file extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Png,
    Svg,
}

impl Format {
    /// The format by extension, checked before any work is done: a picture ends in .png or
    /// .svg and goes into a directory that exists.
    pub fn of(path: &Path) -> Result<Format> {
        let directory = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        if !directory.is_dir() {
            return Err(Error::input(format!(
                "cannot write the picture there: the directory {} does not exist",
                directory.display()
            ))
            .file(path)
            .expected("a path in a directory that exists"));
        }
        match path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .as_deref()
        {
            Some("png") => Ok(Format::Png),
            Some("svg") => Ok(Format::Svg),
            _ => Err(Error::input("a picture must end in .png or .svg")
                .file(path)
                .expected(".png or .svg")),
        }
    }
}

/// How an axis maps its values.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scale {
    Linear,
    /// Logarithmic (base 10); the values must be positive.
    Log,
    /// Linear, values in radians, ticks labelled in units of π.
    Pi,
}

/// An axis: label (with units), scale, an optional fixed range (else from the data) and
/// optional tick values (else round values inside the range, at least three).
#[derive(Clone, Debug, PartialEq)]
pub struct AxisSpec {
    pub label: String,
    pub scale: Scale,
    pub range: Option<(f64, f64)>,
    pub ticks: Option<Vec<f64>>,
}

impl AxisSpec {
    pub fn linear(label: &str) -> Self {
        AxisSpec {
            label: label.into(),
            scale: Scale::Linear,
            range: None,
            ticks: None,
        }
    }

    pub fn log(label: &str) -> Self {
        AxisSpec {
            label: label.into(),
            scale: Scale::Log,
            range: None,
            ticks: None,
        }
    }

    pub fn pi(label: &str) -> Self {
        AxisSpec {
            label: label.into(),
            scale: Scale::Pi,
            range: None,
            ticks: None,
        }
    }

    pub fn with_range(mut self, start: f64, end: f64) -> Self {
        self.range = Some((start, end));
        self
    }

    /// Ticks at these values only (those inside the range), e.g. whole thread counts.
    pub fn with_ticks(mut self, ticks: Vec<f64>) -> Self {
        self.ticks = Some(ticks);
        self
    }

    /// Plot coordinate of a value (radians become multiples of π).
    fn coordinate(&self, value: f64) -> f64 {
        match self.scale {
            Scale::Pi => value / PI,
            _ => value,
        }
    }
}

/// An RGB colour.
pub type Colour = RGBColor;

/// A colour cycle for series (Tableau 10).
pub const PALETTE: [Colour; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// Viridis, sampled at nine stops (matplotlib's table, 0 → 1).
const VIRIDIS: [(u8, u8, u8); 9] = [
    (68, 1, 84),
    (71, 44, 122),
    (59, 81, 139),
    (44, 113, 142),
    (33, 144, 141),
    (39, 173, 129),
    (92, 200, 99),
    (170, 220, 50),
    (253, 231, 37),
];

/// The viridis colour at `t ∈ [0, 1]` (clamped), linearly interpolated between stops.
pub fn viridis(t: f64) -> Colour {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let position = t * (VIRIDIS.len() - 1) as f64;
    let i = (position.floor() as usize).min(VIRIDIS.len() - 2);
    let f = position - i as f64;
    let mix = |a: u8, b: u8| (a as f64 + f * (b as f64 - a as f64)).round() as u8;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// A named colour for a value of a categorical map, or for the values below a colour
/// bar's range.
#[derive(Clone, Debug, PartialEq)]
pub struct Category {
    pub value: f64,
    pub name: String,
    pub colour: Colour,
}

/// How a heat map colours its values. NaN is always "no data" (light grey).
#[derive(Clone, Debug, PartialEq)]
pub enum Colouring {
    /// Viridis over `[min, max]` with a colour bar labelled `label`; values at or below
    /// `below.value` get `below.colour` and a legend entry instead.
    Continuous {
        label: String,
        min: f64,
        max: f64,
        log: bool,
        below: Option<Category>,
    },
    /// Each listed value its colour, with a legend; other values are drawn as no data.
    Categorical(Vec<Category>),
}

const NO_DATA: RGBColor = RGBColor(220, 220, 220);

/// A heat map of `values` over a regular grid of cells, x slow: `values[i * ny + j]` is
/// at (x_i, y_j), as in a stability map's row order.
#[derive(Clone, Debug, PartialEq)]
pub struct HeatMap {
    pub title: String,
    pub x: AxisSpec,
    pub y: AxisSpec,
    /// First and last cell centres and the number of cells along x.
    pub x_cells: (f64, f64, usize),
    pub y_cells: (f64, f64, usize),
    pub values: Vec<f64>,
    pub colouring: Colouring,
    /// Picture size in pixels.
    pub size: (u32, u32),
    /// A line under the map saying what its symbols mean; empty for none.
    pub note: String,
}

impl HeatMap {
    pub fn save(&self, path: &Path) -> Result<()> {
        let (nx, ny) = (self.x_cells.2, self.y_cells.2);
        if nx == 0 || ny == 0 || self.values.len() != nx * ny {
            return Err(Error::input(format!(
                "heat map \"{}\": {} values for a {nx} × {ny} grid",
                self.title,
                self.values.len()
            )));
        }
        render(path, self.size, self)
    }

    fn colour_of(&self, value: f64) -> Option<Colour> {
        if value.is_nan() {
            return None;
        }
        match &self.colouring {
            Colouring::Continuous {
                min,
                max,
                log,
                below,
                ..
            } => {
                if let Some(below) = below
                    && value <= below.value
                {
                    return Some(below.colour);
                }
                let t = if *log {
                    (value.max(f64::MIN_POSITIVE).log10() - min.log10())
                        / (max.log10() - min.log10())
                } else {
                    (value - min) / (max - min)
                };
                Some(viridis(if t.is_finite() { t } else { 1.0 }))
            }
            Colouring::Categorical(categories) => categories
                .iter()
                .find(|c| c.value == value)
                .map(|c| c.colour),
        }
    }
}

impl Picture for HeatMap {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let (width, height) = root.dim_in_pixel();
        let root = if self.note.is_empty() {
            root.clone()
        } else {
            let (upper, note) = root.split_vertically(height.saturating_sub(26));
            note.draw(&Text::new(
                self.note.clone(),
                (12, 4),
                ("sans-serif", 13).into_font(),
            ))
            .map_err(|e| e.to_string())?;
            upper
        };
        let side = 150.min(width / 3);
        let (main, side_area) = root.split_horizontally(width - side);
        let (dx, dy) = self.cell_steps();
        let ((x0, x1), (y0, y1)) = self.plot_ranges(dx, dy);

        let mut chart = ChartBuilder::on(&main)
            .caption(&self.title, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(48)
            .y_label_area_size(64)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(self.cell_rectangles(dx, dy))
            .map_err(|e| e.to_string())?;
        configure_mesh(&mut chart, &self.x, &self.y, false)?;
        self.draw_side(&side_area)
    }
}

impl HeatMap {
    /// The spacing of the cell centres along x and y (1 for a single cell).
    fn cell_steps(&self) -> (f64, f64) {
        let step = |cells: (f64, f64, usize)| {
            if cells.2 > 1 {
                (cells.1 - cells.0) / (cells.2 - 1) as f64
            } else {
                1.0
            }
        };
        (step(self.x_cells), step(self.y_cells))
    }

    /// The plotted x and y ranges in axis coordinates: the axes' own, or the cells'
    /// centres widened by half a cell.
    fn plot_ranges(&self, dx: f64, dy: f64) -> ((f64, f64), (f64, f64)) {
        let x_range = self
            .x
            .range
            .unwrap_or((self.x_cells.0 - 0.5 * dx, self.x_cells.1 + 0.5 * dx));
        let y_range = self
            .y
            .range
            .unwrap_or((self.y_cells.0 - 0.5 * dy, self.y_cells.1 + 0.5 * dy));
        (
            (self.x.coordinate(x_range.0), self.x.coordinate(x_range.1)),
            (self.y.coordinate(y_range.0), self.y.coordinate(y_range.1)),
        )
    }

    /// The cells, with runs of equal colour along y merged into one rectangle (the stable
    /// region becomes a few rectangles, which keeps SVG files small).
    fn cell_rectangles(&self, dx: f64, dy: f64) -> Vec<Rectangle<(f64, f64)>> {
        let (nx, ny) = (self.x_cells.2, self.y_cells.2);
        let mut rectangles = Vec::new();
        for i in 0..nx {
            let xc = self.x_cells.0 + dx * i as f64;
            let (xa, xb) = (
                self.x.coordinate(xc - 0.5 * dx),
                self.x.coordinate(xc + 0.5 * dx),
            );
            let mut j = 0;
            while j < ny {
                let colour = self.colour_of(self.values[i * ny + j]).unwrap_or(NO_DATA);
                let mut k = j + 1;
                while k < ny && self.colour_of(self.values[i * ny + k]).unwrap_or(NO_DATA) == colour
                {
                    k += 1;
                }
                let ya = self.y.coordinate(self.y_cells.0 + dy * (j as f64 - 0.5));
                let yb = self.y.coordinate(self.y_cells.0 + dy * (k as f64 - 0.5));
                rectangles.push(Rectangle::new([(xa, ya), (xb, yb)], colour.filled()));
                j = k;
            }
        }
        rectangles
    }

    /// The side: a colour bar, a legend, or both.
    fn draw_side<DB: DrawingBackend>(
        &self,
        side_area: &DrawingArea<DB, Shift>,
    ) -> Result<(), String> {
        let mut entries: Vec<(String, Colour)> = Vec::new();
        match &self.colouring {
            Colouring::Continuous {
                label,
                min,
                max,
                log,
                below,
            } => {
                if let Some(below) = below {
                    entries.push((below.name.clone(), below.colour));
                }
                if self.values.iter().any(|v| v.is_nan()) {
                    entries.push(("no data".into(), NO_DATA));
                }
                let legend_height = 28 * entries.len() as u32 + 20;
                let (_, height) = side_area.dim_in_pixel();
                let (bar_area, legend_area) =
                    side_area.split_vertically(height.saturating_sub(legend_height));
                draw_colour_bar(&bar_area, label, *min, *max, *log)?;
                draw_legend(&legend_area, &entries)?;
            }
            Colouring::Categorical(categories) => {
                entries.extend(categories.iter().map(|c| (c.name.clone(), c.colour)));
                if self.values.iter().any(|v| v.is_nan()) {
                    entries.push(("no data".into(), NO_DATA));
                }
                draw_legend(&side_area.margin(60, 0, 0, 0), &entries)?;
            }
        }
        Ok(())
    }
}

fn draw_colour_bar<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    label: &str,
    min: f64,
    max: f64,
    log: bool,
) -> Result<(), String> {
    let steps = 128;
    let mut builder = ChartBuilder::on(area);
    builder
        .margin_top(48)
        .margin_bottom(12)
        .margin_right(8)
        .y_label_area_size(0)
        .right_y_label_area_size(62);
    // The bar in `steps` shades, evenly spaced in `lo..hi` and placed on the axis by
    // `to_axis`, then its labelled axis: one body for the log and the linear axis, whose
    // plotters coordinate types differ.
    macro_rules! shade_and_label {
        ($chart:expr, ($lo:expr, $hi:expr), $to_axis:expr) => {{
            let mut chart = $chart.map_err(|e| e.to_string())?;
            let (lo, hi): (f64, f64) = ($lo, $hi);
            let to_axis = $to_axis;
            chart
                .draw_series((0..steps).map(|k| {
                    let a = lo + (hi - lo) * k as f64 / steps as f64;
                    let b = lo + (hi - lo) * (k + 1) as f64 / steps as f64;
                    let t = (k as f64 + 0.5) / steps as f64;
                    Rectangle::new([(0.0, to_axis(a)), (1.0, to_axis(b))], viridis(t).filled())
                }))
                .map_err(|e| e.to_string())?;
            chart
                .configure_mesh()
                .disable_mesh()
                .disable_x_axis()
                .y_desc(label)
                .y_label_formatter(&|v| format_number(*v))
                .label_style(("sans-serif", 13))
                .draw()
                .map_err(|e| e.to_string())?;
        }};
    }
    if log {
        let axis = (min..max).log_scale().with_key_points(log_ticks(min, max));
        shade_and_label!(
            builder.build_cartesian_2d(0.0..1.0, axis),
            (min.log10(), max.log10()),
            |x: f64| 10f64.powf(x)
        );
    } else {
        shade_and_label!(
            builder.build_cartesian_2d(0.0..1.0, min..max),
            (min, max),
            |x: f64| x
        );
    }
    Ok(())
}

/// Guide lines closer than this (pixels) share one label.
const GUIDE_GROUP_GAP: i32 = 10;

/// The labels of guide lines, hung below the top of the plot beside their line (on the
/// side towards the middle, so they stay inside): lines too close to tell apart share one
/// label, and a label that would overlap another moves down a row. Each has a pale
/// backing so crosses and grid lines under it do not garble it.
fn draw_guide_labels<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    guides: &[(i32, String)],
    top: i32,
    x_middle: i32,
) -> Result<(), String> {
    if guides.is_empty() {
        return Ok(());
    }
    let grey = BLACK.mix(0.7);
    let style = TextStyle::from(("sans-serif", 12).into_font())
        .color(&grey)
        .pos(Pos::new(HPos::Left, VPos::Top));
    let groups = group_guides(guides, GUIDE_GROUP_GAP);
    let mut first_row = Vec::with_capacity(groups.len());
    for (x, text) in &groups {
        let (w, h) = root
            .estimate_text_size(text, &style)
            .map_err(|e| e.to_string())?;
        let (w, h) = (w as i32, h as i32);
        let left = if *x > x_middle { x - 4 - w } else { x + 4 };
        first_row.push(TextBox {
            left,
            top,
            width: w,
            height: h,
        });
    }
    for (place, (_, text)) in stack_in_rows(&first_row, 15, 2).iter().zip(&groups) {
        let corners = [
            (place.left - 1, place.top - 1),
            (place.left + place.width + 1, place.top + place.height + 1),
        ];
        root.draw(&Rectangle::new(corners, WHITE.mix(0.8).filled()))
            .map_err(|e| e.to_string())?;
        root.draw(&Text::new(
            text.clone(),
            (place.left, place.top),
            style.clone(),
        ))
        .map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// Labels beside points, in their series' colour, placed so no two overlap (a label
/// repeating the same text right beside it is left out), 8 px from the point: clear of a
/// cross's 6 px arms.
fn draw_point_labels<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    texts: &[((i32, i32), &str, Colour)],
    area: TextBox,
) -> Result<(), String> {
    let font = ("sans-serif", 11).into_font();
    let measure = TextStyle::from(font.clone());
    let mut labels = Vec::with_capacity(texts.len());
    for (at, text, _) in texts {
        let (w, h) = root
            .estimate_text_size(text, &measure)
            .map_err(|e| e.to_string())?;
        labels.push(PointText {
            at: *at,
            size: (w as i32, h as i32),
            text,
        });
    }
    for (place, (_, text, colour)) in place_point_labels(&labels, area, 8, 12).iter().zip(texts) {
        let Some(place) = place else { continue };
        let style = TextStyle::from(font.clone())
            .color(colour)
            .pos(Pos::new(HPos::Left, VPos::Top));
        root.draw(&Text::new(text.to_string(), (place.left, place.top), style))
            .map_err(|e| e.to_string())?;
    }
    Ok(())
}

fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[(String, Colour)],
) -> Result<(), String> {
    for (k, (name, colour)) in entries.iter().enumerate() {
        let y = 10 + 28 * k as i32;
        area.draw(&Rectangle::new([(8, y), (26, y + 18)], colour.filled()))
            .map_err(|e| e.to_string())?;
        area.draw(&Rectangle::new(
            [(8, y), (26, y + 18)],
            BLACK.stroke_width(1),
        ))
        .map_err(|e| e.to_string())?;
        area.draw(&Text::new(name.clone(), (32, y + 2), ("sans-serif", 14)))
            .map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// Short tick labels: `0.5`, `1e-6`, `120`.
fn format_number(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let magnitude = v.abs();
    if !(1e-3..1e5).contains(&magnitude) {
        // Three significant digits at most, so ticks 3e140 and 3.5e140 stay apart.
        let text = format!("{v:.2e}");
        let (mantissa, exponent) = text.split_once('e').unwrap_or((&text, "0"));
        let mantissa = mantissa.trim_end_matches('0').trim_end_matches('.');
        return match exponent {
            "0" => mantissa.to_string(),
            _ => format!("{mantissa}e{exponent}"),
        };
    }
    let text = format!("{v:.3}");
    text.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// A tick in units of π: `0`, `π/2`, `π`, `1.5π`.
fn format_pi(v: f64) -> String {
    let rounded = (v * 1000.0).round() / 1000.0;
    if rounded == 0.0 {
        "0".into()
    } else if rounded == 1.0 {
        "π".into()
    } else if rounded == -1.0 {
        "−π".into()
    } else if rounded == 0.5 {
        "π/2".into()
    } else {
        format!("{}π", format_number(rounded))
    }
}

fn configure_mesh<DB, X, Y>(
    chart: &mut ChartContext<'_, DB, Cartesian2d<X, Y>>,
    x: &AxisSpec,
    y: &AxisSpec,
    grid_lines: bool,
) -> Result<(), String>
where
    DB: DrawingBackend,
    X: Ranged<ValueType = f64> + ValueFormatter<f64>,
    Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
{
    let x_format = |v: &f64| match x.scale {
        Scale::Pi => format_pi(*v),
        _ => format_number(*v),
    };
    let y_format = |v: &f64| match y.scale {
        Scale::Pi => format_pi(*v),
        _ => format_number(*v),
    };
    let mut mesh = chart.configure_mesh();
    if !grid_lines {
        mesh.disable_mesh();
    }
    mesh.x_desc(x.label.as_str())
        .y_desc(y.label.as_str())
        .x_label_formatter(&x_format)
        .y_label_formatter(&y_format)
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 16))
        .draw()
        .map_err(|e| e.to_string())
}

/// How a series is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SeriesStyle {
    Line,
    Points,
    LineAndPoints,
    /// A vertical stick from the bottom of the plot to each point (a line spectrum).
    Sticks,
}

/// A named series of (x, y) points.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
    pub style: SeriesStyle,
    /// Default: the palette colour of the series' position.
    pub colour: Option<Colour>,
    /// Text beside each point, in the order of `points` (for example its step size);
    /// empty for none.
    pub point_labels: Vec<String>,
    /// Points drawn as open circles, in the order of `points` (for example a negative
    /// value drawn by its magnitude on a logarithmic axis); empty for none.
    pub hollow: Vec<bool>,
}

impl Series {
    fn with_style(name: &str, points: Vec<(f64, f64)>, style: SeriesStyle) -> Self {
        Series {
            name: name.into(),
            points,
            style,
            colour: None,
            point_labels: Vec::new(),
            hollow: Vec::new(),
        }
    }

    pub fn line(name: &str, points: Vec<(f64, f64)>) -> Self {
        Series::with_style(name, points, SeriesStyle::Line)
    }

    pub fn scatter(name: &str, points: Vec<(f64, f64)>) -> Self {
        Series::with_style(name, points, SeriesStyle::Points)
    }

    pub fn sticks(name: &str, points: Vec<(f64, f64)>) -> Self {
        Series::with_style(name, points, SeriesStyle::Sticks)
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MarkerShape {
    Cross,
    Triangle,
    /// An open circle.
    Circle,
}

/// Special points drawn on top of the series with their own legend entry (for example
/// the runs that went unstable). A set without points is a legend entry only (a key to
/// how points are drawn).
#[derive(Clone, Debug, PartialEq)]
pub struct MarkerSet {
    pub name: String,
    pub points: Vec<(f64, f64)>,
    pub shape: MarkerShape,
    pub colour: Colour,
    /// Drawn in a band along the top edge of the plot whatever their y (runs without a
    /// meaningful value), and left out of the y range.
    pub pin_top: bool,
    /// Text beside each marker, in the order of `points`; empty for none.
    pub labels: Vec<String>,
}

impl MarkerSet {
    pub fn new(name: &str, shape: MarkerShape, colour: Colour, points: Vec<(f64, f64)>) -> Self {
        MarkerSet {
            name: name.into(),
            points,
            shape,
            colour,
            pin_top: false,
            labels: Vec::new(),
        }
    }

    /// Crosses in a method's colour labelled "<method> unstable": unstable runs of several
    /// methods stay told apart.
    pub fn unstable_of(method: &str, colour: Colour, points: Vec<(f64, f64)>) -> Self {
        MarkerSet::new(
            &format!("{method} unstable"),
            MarkerShape::Cross,
            colour,
            points,
        )
    }

    /// Crosses in a method's colour on the top edge of the plot, labelled "<method>
    /// unstable (top edge)": runs without a meaningful value, kept out of the y range.
    pub fn unstable_on_top(method: &str, colour: Colour, points: Vec<(f64, f64)>) -> Self {
        let mut set = MarkerSet::unstable_of(method, colour, points);
        set.name = format!("{method} unstable (top edge)");
        set.pin_top = true;
        set
    }

    /// Red crosses labelled "unstable".
    pub fn unstable(points: Vec<(f64, f64)>) -> Self {
        MarkerSet::new("unstable", MarkerShape::Cross, RGBColor(200, 0, 0), points)
    }
}

/// A vertical guide line at `x` with a label (for example a predicted resonance).
#[derive(Clone, Debug, PartialEq)]
pub struct Guide {
    pub x: f64,
    pub label: String,
}

/// A horizontal dashed line at `y` across the plot, named in the legend (a bound).
#[derive(Clone, Debug, PartialEq)]
pub struct Level {
    pub y: f64,
    pub name: String,
    pub colour: Colour,
}

/// A shaded band between `low` and `high` along x (an error band), named in the legend.
#[derive(Clone, Debug, PartialEq)]
pub struct Band {
    pub name: String,
    /// (x, low, high), in order of x.
    pub points: Vec<(f64, f64, f64)>,
    pub colour: Colour,
}

/// Where the legend goes: right of the plot (the default: it hides no data), or inside
/// the plot in a corner.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Corner {
    #[default]
    Outside,
    UpperLeft,
    UpperRight,
    LowerLeft,
    LowerRight,
}

/// A line or scatter chart.
#[derive(Clone, Debug, PartialEq)]
pub struct LineChart {
    pub title: String,
    pub x: AxisSpec,
    pub y: AxisSpec,
    pub series: Vec<Series>,
    pub markers: Vec<MarkerSet>,
    pub guides: Vec<Guide>,
    pub levels: Vec<Level>,
    pub bands: Vec<Band>,
    pub legend: Corner,
}

impl LineChart {
    /// An empty chart; push series, markers and guides.
    pub fn new(title: &str, x: AxisSpec, y: AxisSpec) -> Self {
        LineChart {
            title: title.into(),
            x,
            y,
            series: Vec::new(),
            markers: Vec::new(),
            guides: Vec::new(),
            levels: Vec::new(),
            bands: Vec::new(),
            legend: Corner::default(),
        }
    }

    pub fn save(&self, path: &Path) -> Result<()> {
        self.save_sized(path, (900, 600))
    }

    pub fn save_sized(&self, path: &Path, size: (u32, u32)) -> Result<()> {
        render(path, size, &self.prepare()?)
    }

    /// The x and y values that decide the plotted ranges (pinned markers only x).
    fn range_values(&self) -> (Vec<f64>, Vec<f64>) {
        let mut xs = Vec::new();
        let mut ys = Vec::new();
        for p in self.series.iter().flat_map(|s| s.points.iter()) {
            xs.push(p.0);
            ys.push(p.1);
        }
        for set in &self.markers {
            xs.extend(set.points.iter().map(|p| p.0));
            if !set.pin_top {
                ys.extend(set.points.iter().map(|p| p.1));
            }
        }
        for band in &self.bands {
            xs.extend(band.points.iter().map(|p| p.0));
            ys.extend(band.points.iter().flat_map(|p| [p.1, p.2]));
        }
        ys.extend(self.levels.iter().map(|l| l.y));
        (xs, ys)
    }

    /// The chart with its axes' ranges and ticks decided.
    fn prepare(&self) -> Result<PreparedChart<'_>> {
        let (xs, ys) = self.range_values();
        let pinned = self
            .markers
            .iter()
            .any(|m| m.pin_top && !m.points.is_empty());
        let x_range = match self.x.range {
            Some(range) => range,
            None => data_range(xs.into_iter(), self.x.scale, "x", &self.title)?,
        };
        let y_range = match self.y.range {
            Some(range) => range,
            None if pinned && ys.iter().all(|y| !y.is_finite()) => match self.y.scale {
                Scale::Log => (1e-3, 1.0),
                _ => (0.0, 1.0),
            },
            None => {
                let range = data_range(ys.into_iter(), self.y.scale, "y", &self.title)?;
                if pinned {
                    room_on_top(range, self.y.scale)
                } else {
                    range
                }
            }
        };
        for (range, axis, what) in [(x_range, &self.x, "x"), (y_range, &self.y, "y")] {
            if axis.scale == Scale::Log && !(range.0 > 0.0 && range.1 > range.0) {
                return Err(Error::input(format!(
                    "chart \"{}\": the logarithmic {what} axis needs a positive range, got {:?}",
                    self.title, range
                )));
            }
        }
        Ok(PreparedChart {
            chart: self,
            x: TickedAxis::new(&self.x, x_range),
            y: TickedAxis::new(&self.y, y_range),
        })
    }
}

/// Charts stacked top to bottom in one picture, each with its own axes and legend (for
/// quantities whose scales differ).
pub fn save_panels(charts: &[LineChart], path: &Path, size: (u32, u32)) -> Result<()> {
    let prepared = charts
        .iter()
        .map(LineChart::prepare)
        .collect::<Result<Vec<_>>>()?;
    render(path, size, &Panels(prepared))
}

struct Panels<'a>(Vec<PreparedChart<'a>>);

impl Picture for Panels<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let areas = root.split_evenly((self.0.len().max(1), 1));
        let mut side = 0;
        for (panel, area) in self.0.iter().zip(&areas) {
            side = side.max(panel.legend_width(area)?);
        }
        for (panel, area) in self.0.iter().zip(&areas) {
            panel.draw_body_beside(area, side)?;
        }
        Ok(())
    }
}

/// 8 % more room above the data, for the band of pinned markers.
fn room_on_top(range: (f64, f64), scale: Scale) -> (f64, f64) {
    match scale {
        Scale::Log => (range.0, range.1 * (range.1 / range.0).powf(0.08)),
        _ => (range.0, range.1 + 0.08 * (range.1 - range.0)),
    }
}

/// A chart axis in plot coordinates (radians as multiples of π), linear or logarithmic,
/// with the values its ticks and grid lines are drawn at.
#[derive(Clone, Debug)]
struct TickedAxis {
    low: f64,
    high: f64,
    log: bool,
    ticks: Vec<f64>,
}

impl TickedAxis {
    fn new(spec: &AxisSpec, range: (f64, f64)) -> Self {
        let (low, high) = (spec.coordinate(range.0), spec.coordinate(range.1));
        let log = spec.scale == Scale::Log;
        let ticks = match &spec.ticks {
            Some(ticks) => ticks
                .iter()
                .map(|&t| spec.coordinate(t))
                .filter(|t| *t >= low.min(high) && *t <= low.max(high))
                .collect(),
            None if log => log_axis_ticks(low, high),
            None => linear_ticks(low.min(high), low.max(high)),
        };
        TickedAxis {
            low,
            high,
            log,
            ticks,
        }
    }

    /// The position of a value along the axis, 0 at `low` and 1 at `high`.
    fn fraction(&self, value: f64) -> f64 {
        if self.log {
            (value.max(f64::MIN_POSITIVE).log10() - self.low.log10())
                / (self.high.log10() - self.low.log10())
        } else {
            (value - self.low) / (self.high - self.low)
        }
    }

    /// The value at a position along the axis.
    fn at_fraction(&self, f: f64) -> f64 {
        if self.log {
            10f64.powf(self.low.log10() + f * (self.high.log10() - self.low.log10()))
        } else {
            self.low + f * (self.high - self.low)
        }
    }
}

impl Ranged for TickedAxis {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        let f = self.fraction(*value);
        // Far outside the plot is far enough: no overflow of the pixel type.
        let f = if f.is_finite() {
            f.clamp(-10.0, 10.0)
        } else {
            0.0
        };
        limit.0 + ((limit.1 - limit.0) as f64 * f).round() as i32
    }

    fn key_points<Hint: KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        if hint.weight().allow_light_points() {
            Vec::new()
        } else {
            self.ticks.clone()
        }
    }

    fn range(&self) -> std::ops::Range<f64> {
        self.low..self.high
    }
}

type Cartesian<'a, DB> = ChartContext<'a, DB, Cartesian2d<TickedAxis, TickedAxis>>;

/// A chart with its plot ranges decided.
struct PreparedChart<'a> {
    chart: &'a LineChart,
    x: TickedAxis,
    y: TickedAxis,
}

impl Picture for PreparedChart<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        self.draw_body(root)
    }
}

/// How a legend entry's key is drawn.
#[derive(Clone, Copy)]
enum LegendKey {
    Line(Colour),
    Dot(Colour),
    Marker(MarkerShape, Colour),
    Band(Colour),
    Dashed(Colour),
}

impl PreparedChart<'_> {
    /// The chart in `root`: with the legend outside, the plot on the left and the legend
    /// in a column on the right as wide as its longest entry.
    fn draw_body<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
        let side = self.legend_width(root)?;
        self.draw_body_beside(root, side)
    }

    /// The width of the legend column: its longest entry and the key, at most half the
    /// area; 0 with the legend inside the plot or nothing to name.
    fn legend_width<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
    ) -> Result<u32, String> {
        if self.chart.legend != Corner::Outside {
            return Ok(0);
        }
        let font = TextStyle::from(("sans-serif", 14).into_font());
        let mut widest = None;
        for (name, _) in &self.legend_entries() {
            let width = root
                .estimate_text_size(name, &font)
                .map_err(|e| e.to_string())?
                .0;
            widest = Some(widest.unwrap_or(0).max(width));
        }
        Ok(widest.map_or(0, |w| (w + 52).min(root.dim_in_pixel().0 / 2)))
    }

    /// The plot with a legend column `side` pixels wide on its right (none for 0), so that
    /// stacked panels given the same width line their time axes up.
    fn draw_body_beside<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        side: u32,
    ) -> Result<(), String> {
        if side == 0 {
            return self.draw_plot(root);
        }
        let (width, _) = root.dim_in_pixel();
        let (plot, legend) = root.split_horizontally(width.saturating_sub(side));
        self.draw_plot(&plot)?;
        draw_side_legend(&legend, &self.legend_entries())
    }

    fn legend_entries(&self) -> Vec<(String, LegendKey)> {
        let chart = self.chart;
        let mut entries = Vec::new();
        for (k, series) in chart.series.iter().enumerate() {
            let colour = series.colour.unwrap_or(PALETTE[k % PALETTE.len()]);
            let key = match series.style {
                SeriesStyle::Points => LegendKey::Dot(colour),
                _ => LegendKey::Line(colour),
            };
            entries.push((series.name.clone(), key));
        }
        for band in &chart.bands {
            entries.push((band.name.clone(), LegendKey::Band(band.colour)));
        }
        for level in &chart.levels {
            entries.push((level.name.clone(), LegendKey::Dashed(level.colour)));
        }
        for set in &chart.markers {
            entries.push((set.name.clone(), LegendKey::Marker(set.shape, set.colour)));
        }
        entries
    }

    fn draw_plot<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
        let chart = self.chart;
        let mut context = ChartBuilder::on(root)
            .caption(&chart.title, ("sans-serif", 22))
            .margin(14)
            .x_label_area_size(48)
            .y_label_area_size(72)
            .build_cartesian_2d(self.x.clone(), self.y.clone())
            .map_err(|e| e.to_string())?;
        configure_mesh(&mut context, &chart.x, &chart.y, true)?;
        let base = root.get_base_pixel();
        let pixel = |context: &Cartesian<'_, DB>, p: (f64, f64)| {
            let (x, y) = context.backend_coord(&p);
            (x - base.0, y - base.1)
        };
        let (left, top) = pixel(&context, (self.x.low, self.y.high));
        let (right, bottom) = pixel(&context, (self.x.high, self.y.low));
        let plot_area = TextBox {
            left,
            top,
            width: right - left,
            height: bottom - top,
        };
        let guide_pixels = self.draw_backdrop(&mut context, base)?;
        let pinned = chart
            .markers
            .iter()
            .any(|m| m.pin_top && !m.points.is_empty());
        // Pinned markers sit 8 px below the top edge; guide labels hang below them.
        let pin_y = self
            .y
            .at_fraction(1.0 - 8.0 / f64::from(plot_area.height.max(16)));
        let label_top = top + if pinned { 18 } else { 4 };
        draw_guide_labels(root, &guide_pixels, label_top, left + plot_area.width / 2)?;
        let mut point_texts: Vec<((i32, i32), &str, Colour)> = Vec::new();
        for (k, series) in chart.series.iter().enumerate() {
            let colour = series.colour.unwrap_or(PALETTE[k % PALETTE.len()]);
            let points = self.plotted(&series.points, |i| {
                series.hollow.get(i).copied().unwrap_or(false)
            });
            for (&(x, y), text) in series.points.iter().zip(&series.point_labels) {
                if x.is_finite() && y.is_finite() {
                    let at = (chart.x.coordinate(x), chart.y.coordinate(y));
                    point_texts.push((pixel(&context, at), text, colour));
                }
            }
            draw_series_in(&mut context, series, colour, &points, self.y.low)?;
        }
        for set in &chart.markers {
            let points = self.marker_points(set, pin_y);
            for (p, text) in points.iter().zip(&set.labels) {
                point_texts.push((pixel(&context, (p.0, p.1)), text, set.colour));
            }
            draw_markers_in(&mut context, set, &points)?;
        }
        draw_point_labels(root, &point_texts, plot_area)?;
        if chart.legend != Corner::Outside
            && (!chart.series.is_empty() || !chart.markers.is_empty())
        {
            draw_series_legend(&mut context, chart.legend)?;
        }
        Ok(())
    }

    /// A marker set's finite points in plot coordinates; pinned ones at `pin_y`.
    fn marker_points(&self, set: &MarkerSet, pin_y: f64) -> Vec<Plotted> {
        if !set.pin_top {
            return self.plotted(&set.points, |_| false);
        }
        // Any finite y will do: it is replaced by the band's.
        let on_top: Vec<(f64, f64)> = set.points.iter().map(|p| (p.0, 1.0)).collect();
        let mut points = self.plotted(&on_top, |_| false);
        points.iter_mut().for_each(|p| p.1 = pin_y);
        points
    }

    /// Finite points in plot coordinates, each with its `hollow` flag.
    fn plotted(&self, points: &[(f64, f64)], hollow: impl Fn(usize) -> bool) -> Vec<Plotted> {
        let (x, y) = (&self.chart.x, &self.chart.y);
        points
            .iter()
            .enumerate()
            .filter(|(_, p)| p.0.is_finite() && p.1.is_finite())
            .map(|(i, &(px, py))| (x.coordinate(px), y.coordinate(py), hollow(i)))
            .collect()
    }

    /// Bands, levels and guide lines, under the data. Returns each guide's pixel x in the
    /// drawing area whose top-left backend pixel is `base`, with its label.
    fn draw_backdrop<'a, DB: DrawingBackend + 'a>(
        &self,
        context: &mut Cartesian<'a, DB>,
        base: (i32, i32),
    ) -> Result<Vec<(i32, String)>, String> {
        let (x, y) = (&self.chart.x, &self.chart.y);
        for band in &self.chart.bands {
            let upper = band.points.iter().map(|p| (p.0, p.2));
            let lower = band.points.iter().rev().map(|p| (p.0, p.1));
            let outline: Vec<(f64, f64)> = upper
                .chain(lower)
                .filter(|p| p.0.is_finite() && p.1.is_finite())
                .map(|p| (x.coordinate(p.0), y.coordinate(p.1)))
                .collect();
            context
                .draw_series(std::iter::once(Polygon::new(
                    outline,
                    band.colour.mix(0.3).filled(),
                )))
                .map_err(|e| e.to_string())?;
        }
        for level in &self.chart.levels {
            let at = y.coordinate(level.y);
            context
                .draw_series(std::iter::once(DashedPathElement::new(
                    vec![(self.x.low, at), (self.x.high, at)],
                    8,
                    5,
                    level.colour.stroke_width(2),
                )))
                .map_err(|e| e.to_string())?;
        }
        let mut guides = Vec::with_capacity(self.chart.guides.len());
        for guide in &self.chart.guides {
            let at = x.coordinate(guide.x);
            context
                .draw_series(LineSeries::new(
                    [(at, self.y.low), (at, self.y.high)],
                    BLACK.mix(0.4).stroke_width(1),
                ))
                .map_err(|e| e.to_string())?;
            let pixel = context.backend_coord(&(at, self.y.high)).0 - base.0;
            guides.push((pixel, guide.label.clone()));
        }
        Ok(guides)
    }
}

/// A point in plot coordinates and whether it is drawn open.
type Plotted = (f64, f64, bool);

/// The legend in its own column: a key and the name of each entry, top to bottom.
fn draw_side_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[(String, LegendKey)],
) -> Result<(), String> {
    let style =
        TextStyle::from(("sans-serif", 14).into_font()).pos(Pos::new(HPos::Left, VPos::Center));
    for (k, (name, key)) in entries.iter().enumerate() {
        let y = 64 + 24 * k as i32;
        match *key {
            LegendKey::Line(c) => {
                area.draw(&PathElement::new(vec![(4, y), (28, y)], c.stroke_width(2)))
            }
            LegendKey::Dot(c) => area.draw(&Circle::new((16, y), 3, c.filled())),
            LegendKey::Marker(MarkerShape::Cross, c) => {
                area.draw(&Cross::new((16, y), 5, c.stroke_width(2)))
            }
            LegendKey::Marker(MarkerShape::Triangle, c) => {
                area.draw(&TriangleMarker::new((16, y), 5, c.filled()))
            }
            LegendKey::Marker(MarkerShape::Circle, c) => {
                area.draw(&Circle::new((16, y), 4, c.stroke_width(2)))
            }
            LegendKey::Band(c) => area.draw(&Rectangle::new(
                [(4, y - 6), (28, y + 6)],
                c.mix(0.3).filled(),
            )),
            LegendKey::Dashed(c) => area.draw(&DashedPathElement::new(
                vec![(4, y), (28, y)],
                6,
                3,
                c.stroke_width(2),
            )),
        }
        .map_err(|e| e.to_string())?;
        area.draw(&Text::new(name.clone(), (36, y), style.clone()))
            .map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// One series in plot coordinates: a path per segment, dots (open where flagged) or
/// sticks up from `bottom`.
fn draw_series_in<'a, DB: DrawingBackend + 'a>(
    chart: &mut Cartesian<'a, DB>,
    series: &Series,
    colour: Colour,
    points: &[Plotted],
    bottom: f64,
) -> Result<(), String> {
    let line = matches!(series.style, SeriesStyle::Line | SeriesStyle::LineAndPoints);
    let dots = matches!(
        series.style,
        SeriesStyle::Points | SeriesStyle::LineAndPoints
    );
    let at = |p: &Plotted| (p.0, p.1);
    let annotation = if line {
        // One path per segment: a single wide polyline joins its segments with miters,
        // and where a dense series turns back sharply (an oscillating energy at 2000
        // rows) a miter shoots far past the plotting area.
        let style = colour.stroke_width(2);
        Some(
            chart
                .draw_series(
                    points
                        .windows(2)
                        .map(move |w| PathElement::new(vec![at(&w[0]), at(&w[1])], style)),
                )
                .map_err(|e| e.to_string())?,
        )
    } else if series.style == SeriesStyle::Sticks {
        let style = colour.stroke_width(2);
        Some(
            chart
                .draw_series(
                    points
                        .iter()
                        .map(move |p| PathElement::new(vec![(p.0, bottom), at(p)], style)),
                )
                .map_err(|e| e.to_string())?,
        )
    } else {
        None
    };
    if let Some(annotation) = annotation {
        annotation.label(series.name.clone()).legend(move |(x, y)| {
            PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
        });
    }
    if dots {
        let annotation = chart
            .draw_series(points.iter().flat_map(|p| {
                if p.2 {
                    vec![
                        Circle::new(at(p), 4, WHITE.filled()),
                        Circle::new(at(p), 4, colour.stroke_width(2)),
                    ]
                } else {
                    vec![Circle::new(at(p), 3, colour.filled())]
                }
            }))
            .map_err(|e| e.to_string())?;
        if !line {
            annotation
                .label(series.name.clone())
                .legend(move |(x, y)| Circle::new((x + 10, y), 3, colour.filled()));
        }
    }
    Ok(())
}

/// A marker set in plot coordinates; its legend entry shows its own shape.
fn draw_markers_in<'a, DB: DrawingBackend + 'a>(
    chart: &mut Cartesian<'a, DB>,
    set: &MarkerSet,
    points: &[Plotted],
) -> Result<(), String> {
    let (colour, shape) = (set.colour, set.shape);
    let style = colour.stroke_width(2);
    let at = |p: &Plotted| (p.0, p.1);
    let annotation = match shape {
        MarkerShape::Cross => chart.draw_series(
            points
                .iter()
                .map(|p| Cross::new(at(p), 6, style).into_dyn()),
        ),
        MarkerShape::Triangle => chart.draw_series(
            points
                .iter()
                .map(|p| TriangleMarker::new(at(p), 6, colour.filled()).into_dyn()),
        ),
        MarkerShape::Circle => chart.draw_series(
            points
                .iter()
                .map(|p| Circle::new(at(p), 5, style).into_dyn()),
        ),
    }
    .map_err(|e| e.to_string())?;
    annotation
        .label(set.name.clone())
        .legend(move |(x, y)| match shape {
            MarkerShape::Cross => Cross::new((x + 10, y), 5, colour.stroke_width(2)).into_dyn(),
            MarkerShape::Triangle => {
                TriangleMarker::new((x + 10, y), 5, colour.filled()).into_dyn()
            }
            MarkerShape::Circle => Circle::new((x + 10, y), 4, colour.stroke_width(2)).into_dyn(),
        });
    Ok(())
}

/// The legend box in the chosen corner inside the plot.
fn draw_series_legend<'a, DB: DrawingBackend + 'a>(
    chart: &mut Cartesian<'a, DB>,
    corner: Corner,
) -> Result<(), String> {
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .position(match corner {
            Corner::UpperLeft | Corner::Outside => SeriesLabelPosition::UpperLeft,
            Corner::UpperRight => SeriesLabelPosition::UpperRight,
            Corner::LowerLeft => SeriesLabelPosition::LowerLeft,
            Corner::LowerRight => SeriesLabelPosition::LowerRight,
        })
        .draw()
        .map_err(|e| e.to_string())
}

/// The range of the finite (and for a log axis, positive) values, padded by 5 %.
fn data_range(
    values: impl Iterator<Item = f64>,
    scale: Scale,
    what: &str,
    title: &str,
) -> Result<(f64, f64)> {
    let (mut low, mut high) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite() && (scale != Scale::Log || *v > 0.0)) {
        low = low.min(v);
        high = high.max(v);
    }
    if !low.is_finite() {
        return Err(Error::input(format!(
            "chart \"{title}\": no {what} values to draw"
        )));
    }
    Ok(match scale {
        Scale::Log => {
            let (a, b) = if high > low {
                (low, high)
            } else {
                (low / 10.0, high * 10.0)
            };
            let pad = (b / a).powf(0.05);
            (a / pad, b * pad)
        }
        _ => {
            let span = if high > low {
                high - low
            } else {
                low.abs().max(1.0)
            };
            (low - 0.05 * span, high + 0.05 * span)
        }
    })
}

/// Something drawn on any backend.
trait Picture {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String>;
}

/// Draw into a PNG or SVG file chosen by the extension.
fn render<P: Picture>(path: &Path, size: (u32, u32), picture: &P) -> Result<()> {
    register_font()?;
    // Open the file first, so a path that cannot be written reads as the system's reason
    // rather than the plotting library's backend dump.
    std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
    let failed = |message: String| Error::io(path, std::io::Error::other(message));
    match Format::of(path)? {
        Format::Png => {
            let root = BitMapBackend::new(path, size).into_drawing_area();
            picture.draw(&root).map_err(failed)?;
            root.present().map_err(|e| failed(e.to_string()))
        }
        Format::Svg => {
            let root = SVGBackend::new(path, size).into_drawing_area();
            picture.draw(&root).map_err(failed)?;
            root.present().map_err(|e| failed(e.to_string()))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::format_number;

    #[test]
    fn tick_labels_keep_neighbouring_ticks_apart() {
        assert_eq!(format_number(1e-6), "1e-6");
        assert_eq!(format_number(3e-4), "3e-4");
        assert_eq!(format_number(3.5e140), "3.5e140");
        assert_ne!(format_number(3e140), format_number(3.5e140));
        assert_eq!(format_number(-2.25e7), "-2.25e7");
        assert_eq!(format_number(0.5), "0.5");
        assert_eq!(format_number(120.0), "120");
    }
}
