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
use plotters::coord::ranged1d::{AsRangedCoord, Ranged, ValueFormatter};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::error::{Error, Result};

mod labels;
use labels::{PointText, TextBox, group_guides, log_ticks, place_point_labels, stack_in_rows};

/// DejaVu Sans 2.37 (assets/fonts/README.md).
static FONT: &[u8] = include_bytes!("../assets/fonts/DejaVuSans.ttf");

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
                "{}: cannot write the picture there: the directory {} does not exist",
                path.display(),
                directory.display()
            )));
        }
        match path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .as_deref()
        {
            Some("png") => Ok(Format::Png),
            Some("svg") => Ok(Format::Svg),
            _ => Err(Error::input(format!(
                "{}: a picture must end in .png or .svg",
                path.display()
            ))),
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

/// An axis: label (with units), scale, and an optional fixed range (else from the data).
#[derive(Clone, Debug, PartialEq)]
pub struct AxisSpec {
    pub label: String,
    pub scale: Scale,
    pub range: Option<(f64, f64)>,
}

impl AxisSpec {
    pub fn linear(label: &str) -> Self {
        AxisSpec {
            label: label.into(),
            scale: Scale::Linear,
            range: None,
        }
    }

    pub fn log(label: &str) -> Self {
        AxisSpec {
            label: label.into(),
            scale: Scale::Log,
            range: None,
        }
    }

    pub fn pi(label: &str) -> Self {
        AxisSpec {
            label: label.into(),
            scale: Scale::Pi,
            range: None,
        }
    }

    pub fn with_range(mut self, start: f64, end: f64) -> Self {
        self.range = Some((start, end));
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
        let (width, _) = root.dim_in_pixel();
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
    let shade = |t: f64| viridis(t).filled();
    if log {
        let mut chart = builder
            .build_cartesian_2d(
                0.0..1.0,
                (min..max).log_scale().with_key_points(log_ticks(min, max)),
            )
            .map_err(|e| e.to_string())?;
        let (lmin, lmax) = (min.log10(), max.log10());
        chart
            .draw_series((0..steps).map(|k| {
                let a = lmin + (lmax - lmin) * k as f64 / steps as f64;
                let b = lmin + (lmax - lmin) * (k + 1) as f64 / steps as f64;
                let t = (k as f64 + 0.5) / steps as f64;
                Rectangle::new([(0.0, 10f64.powf(a)), (1.0, 10f64.powf(b))], shade(t))
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
    } else {
        let mut chart = builder
            .build_cartesian_2d(0.0..1.0, min..max)
            .map_err(|e| e.to_string())?;
        chart
            .draw_series((0..steps).map(|k| {
                let a = min + (max - min) * k as f64 / steps as f64;
                let b = min + (max - min) * (k + 1) as f64 / steps as f64;
                let t = (k as f64 + 0.5) / steps as f64;
                Rectangle::new([(0.0, a), (1.0, b)], shade(t))
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
    guides: &[((i32, i32), String)],
    x_middle: i32,
) -> Result<(), String> {
    let Some(top) = guides.iter().map(|g| g.0.1).min() else {
        return Ok(());
    };
    let grey = BLACK.mix(0.7);
    let style = TextStyle::from(("sans-serif", 12).into_font())
        .color(&grey)
        .pos(Pos::new(HPos::Left, VPos::Top));
    let xs: Vec<(i32, String)> = guides.iter().map(|g| (g.0.0, g.1.clone())).collect();
    let groups = group_guides(&xs, GUIDE_GROUP_GAP);
    let mut first_row = Vec::with_capacity(groups.len());
    for (x, text) in &groups {
        let (w, h) = root
            .estimate_text_size(text, &style)
            .map_err(|e| e.to_string())?;
        let (w, h) = (w as i32, h as i32);
        let left = if *x > x_middle { x - 4 - w } else { x + 4 };
        first_row.push(TextBox {
            left,
            top: top + 4,
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
/// repeating the same text right beside it is left out).
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
    for (place, (_, text, colour)) in place_point_labels(&labels, area, 5, 12).iter().zip(texts) {
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
}

impl Series {
    pub fn line(name: &str, points: Vec<(f64, f64)>) -> Self {
        Series {
            name: name.into(),
            points,
            style: SeriesStyle::Line,
            colour: None,
            point_labels: Vec::new(),
        }
    }

    pub fn scatter(name: &str, points: Vec<(f64, f64)>) -> Self {
        Series {
            name: name.into(),
            points,
            style: SeriesStyle::Points,
            colour: None,
            point_labels: Vec::new(),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MarkerShape {
    Cross,
    Triangle,
    Circle,
}

/// Special points drawn on top of the series with their own legend entry (for example
/// the runs that went unstable).
#[derive(Clone, Debug, PartialEq)]
pub struct MarkerSet {
    pub name: String,
    pub points: Vec<(f64, f64)>,
    pub shape: MarkerShape,
    pub colour: Colour,
}

impl MarkerSet {
    /// Crosses in a method's colour labelled "<method> unstable": unstable runs of several
    /// methods stay told apart.
    pub fn unstable_of(method: &str, colour: Colour, points: Vec<(f64, f64)>) -> Self {
        MarkerSet {
            name: format!("{method} unstable"),
            points,
            shape: MarkerShape::Cross,
            colour,
        }
    }

    /// Red crosses labelled "unstable".
    pub fn unstable(points: Vec<(f64, f64)>) -> Self {
        MarkerSet {
            name: "unstable".into(),
            points,
            shape: MarkerShape::Cross,
            colour: RGBColor(200, 0, 0),
        }
    }
}

/// A vertical guide line at `x` with a label (for example a predicted resonance).
#[derive(Clone, Debug, PartialEq)]
pub struct Guide {
    pub x: f64,
    pub label: String,
}

/// Where the legend goes inside the plot.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Corner {
    #[default]
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
            legend: Corner::default(),
        }
    }

    pub fn save(&self, path: &Path) -> Result<()> {
        self.save_sized(path, (900, 600))
    }

    pub fn save_sized(&self, path: &Path, size: (u32, u32)) -> Result<()> {
        let points = || {
            self.series
                .iter()
                .flat_map(|s| s.points.iter())
                .chain(self.markers.iter().flat_map(|m| m.points.iter()))
        };
        let x_range = match self.x.range {
            Some(range) => range,
            None => data_range(points().map(|p| p.0), self.x.scale, "x", &self.title)?,
        };
        let y_range = match self.y.range {
            Some(range) => range,
            None => data_range(points().map(|p| p.1), self.y.scale, "y", &self.title)?,
        };
        for (range, axis, what) in [(x_range, &self.x, "x"), (y_range, &self.y, "y")] {
            if axis.scale == Scale::Log && !(range.0 > 0.0 && range.1 > range.0) {
                return Err(Error::input(format!(
                    "chart \"{}\": the logarithmic {what} axis needs a positive range, got {:?}",
                    self.title, range
                )));
            }
        }
        let prepared = PreparedChart {
            chart: self,
            x: (self.x.coordinate(x_range.0), self.x.coordinate(x_range.1)),
            y: (self.y.coordinate(y_range.0), self.y.coordinate(y_range.1)),
        };
        render(path, size, &prepared)
    }

    fn draw_in<DB, XS, YS>(
        &self,
        root: &DrawingArea<DB, Shift>,
        x_spec: XS,
        y_spec: YS,
    ) -> Result<(), String>
    where
        DB: DrawingBackend,
        XS: AsRangedCoord<Value = f64>,
        YS: AsRangedCoord<Value = f64>,
        XS::CoordDescType: Ranged<ValueType = f64> + ValueFormatter<f64>,
        YS::CoordDescType: Ranged<ValueType = f64> + ValueFormatter<f64>,
    {
        let mut chart = ChartBuilder::on(root)
            .caption(&self.title, ("sans-serif", 22))
            .margin(14)
            .x_label_area_size(48)
            .y_label_area_size(72)
            .build_cartesian_2d(x_spec, y_spec)
            .map_err(|e| e.to_string())?;
        configure_mesh(&mut chart, &self.x, &self.y, true)?;
        let (xc, yc) = (|v: f64| self.x.coordinate(v), |v: f64| self.y.coordinate(v));
        let (x_range, y_range) = (chart.x_range(), chart.y_range());
        let x_middle = chart.backend_coord(&(x_range.start, y_range.start)).0 / 2
            + chart.backend_coord(&(x_range.end, y_range.start)).0 / 2;
        let mut guide_pixels = Vec::with_capacity(self.guides.len());
        for guide in &self.guides {
            let x = xc(guide.x);
            chart
                .draw_series(LineSeries::new(
                    [(x, y_range.start), (x, y_range.end)],
                    BLACK.mix(0.4).stroke_width(1),
                ))
                .map_err(|e| e.to_string())?;
            guide_pixels.push((chart.backend_coord(&(x, y_range.end)), guide.label.clone()));
        }
        draw_guide_labels(root, &guide_pixels, x_middle)?;
        let mut point_texts: Vec<((i32, i32), &str, Colour)> = Vec::new();
        for (k, series) in self.series.iter().enumerate() {
            let colour = series.colour.unwrap_or(PALETTE[k % PALETTE.len()]);
            for (&(x, y), text) in series.points.iter().zip(&series.point_labels) {
                if x.is_finite() && y.is_finite() {
                    point_texts.push((chart.backend_coord(&(xc(x), yc(y))), text, colour));
                }
            }
            let points: Vec<(f64, f64)> = series
                .points
                .iter()
                .filter(|p| p.0.is_finite() && p.1.is_finite())
                .map(|&(x, y)| (xc(x), yc(y)))
                .collect();
            draw_series_in(&mut chart, series, colour, &points)?;
        }
        for set in &self.markers {
            let points: Vec<(f64, f64)> = set
                .points
                .iter()
                .filter(|p| p.0.is_finite() && p.1.is_finite())
                .map(|&(x, y)| (xc(x), yc(y)))
                .collect();
            draw_markers_in(&mut chart, set, &points)?;
        }
        let plot_area = {
            let (left, top) = chart.backend_coord(&(x_range.start, y_range.end));
            let (right, bottom) = chart.backend_coord(&(x_range.end, y_range.start));
            TextBox {
                left,
                top,
                width: right - left,
                height: bottom - top,
            }
        };
        draw_point_labels(root, &point_texts, plot_area)?;
        if !self.series.is_empty() || !self.markers.is_empty() {
            draw_series_legend(&mut chart, self.legend)?;
        }
        Ok(())
    }
}

type Cartesian<'a, DB, X, Y> = ChartContext<'a, DB, Cartesian2d<X, Y>>;

/// One series in backend-ready coordinates: a path per segment and/or dots, with its
/// legend entry.
fn draw_series_in<'a, DB, X, Y>(
    chart: &mut Cartesian<'a, DB, X, Y>,
    series: &Series,
    colour: Colour,
    points: &[(f64, f64)],
) -> Result<(), String>
where
    DB: DrawingBackend + 'a,
    X: Ranged<ValueType = f64>,
    Y: Ranged<ValueType = f64>,
{
    let line = matches!(series.style, SeriesStyle::Line | SeriesStyle::LineAndPoints);
    let dots = matches!(
        series.style,
        SeriesStyle::Points | SeriesStyle::LineAndPoints
    );
    if line {
        // One path per segment: a single wide polyline joins its segments with miters,
        // and where a dense series turns back sharply (an oscillating energy at 2000
        // rows) a miter shoots far past the plotting area.
        let style = colour.stroke_width(2);
        chart
            .draw_series(
                points
                    .windows(2)
                    .map(move |w| PathElement::new(vec![w[0], w[1]], style)),
            )
            .map_err(|e| e.to_string())?
            .label(series.name.clone())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
            });
    }
    if dots {
        let annotation = chart
            .draw_series(points.iter().map(|&p| Circle::new(p, 3, colour.filled())))
            .map_err(|e| e.to_string())?;
        if !line {
            annotation
                .label(series.name.clone())
                .legend(move |(x, y)| Circle::new((x + 10, y), 3, colour.filled()));
        }
    }
    Ok(())
}

/// A marker set in backend-ready coordinates; its legend entry shows its own shape.
fn draw_markers_in<'a, DB, X, Y>(
    chart: &mut Cartesian<'a, DB, X, Y>,
    set: &MarkerSet,
    points: &[(f64, f64)],
) -> Result<(), String>
where
    DB: DrawingBackend + 'a,
    X: Ranged<ValueType = f64>,
    Y: Ranged<ValueType = f64>,
{
    let (colour, shape) = (set.colour, set.shape);
    let style = colour.stroke_width(2);
    let annotation = match shape {
        MarkerShape::Cross => {
            chart.draw_series(points.iter().map(|&p| Cross::new(p, 6, style).into_dyn()))
        }
        MarkerShape::Triangle => chart.draw_series(
            points
                .iter()
                .map(|&p| TriangleMarker::new(p, 6, colour.filled()).into_dyn()),
        ),
        MarkerShape::Circle => {
            chart.draw_series(points.iter().map(|&p| Circle::new(p, 5, style).into_dyn()))
        }
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

/// The legend box in the chosen corner.
fn draw_series_legend<'a, DB, X, Y>(
    chart: &mut Cartesian<'a, DB, X, Y>,
    corner: Corner,
) -> Result<(), String>
where
    DB: DrawingBackend + 'a,
    X: Ranged<ValueType = f64>,
    Y: Ranged<ValueType = f64>,
{
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .position(match corner {
            Corner::UpperLeft => SeriesLabelPosition::UpperLeft,
            Corner::UpperRight => SeriesLabelPosition::UpperRight,
            Corner::LowerLeft => SeriesLabelPosition::LowerLeft,
            Corner::LowerRight => SeriesLabelPosition::LowerRight,
        })
        .draw()
        .map_err(|e| e.to_string())
}

/// A chart with its plot ranges decided.
struct PreparedChart<'a> {
    chart: &'a LineChart,
    x: (f64, f64),
    y: (f64, f64),
}

impl Picture for PreparedChart<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let chart = self.chart;
        let ((x0, x1), (y0, y1)) = (self.x, self.y);
        match (chart.x.scale == Scale::Log, chart.y.scale == Scale::Log) {
            (false, false) => chart.draw_in(root, x0..x1, y0..y1),
            (true, false) => chart.draw_in(root, (x0..x1).log_scale(), y0..y1),
            (false, true) => chart.draw_in(root, x0..x1, (y0..y1).log_scale()),
            (true, true) => chart.draw_in(root, (x0..x1).log_scale(), (y0..y1).log_scale()),
        }
    }
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
