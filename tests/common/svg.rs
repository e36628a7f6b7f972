//! Reading pictures back from the SVG files plotters writes: its `<text>`, `<line>`,
//! `<polyline>` and `<circle>` elements carry positions, sizes, colours and content.

/// One `<text>` element of an SVG written by plotters.
#[derive(Debug)]
pub struct SvgText {
    pub x: f64,
    pub y: f64,
    pub size: f64,
    pub anchor: String,
    pub fill: String,
    pub content: String,
}

pub fn attribute(tag: &str, name: &str) -> Option<String> {
    let start = tag.find(&format!(" {name}=\""))? + name.len() + 3;
    let end = start + tag[start..].find('"')?;
    Some(tag[start..end].to_string())
}

pub fn svg_texts(svg: &str) -> Vec<SvgText> {
    let mut texts = Vec::new();
    for piece in svg.split("<text").skip(1) {
        let Some((tag, rest)) = piece.split_once('>') else {
            continue;
        };
        let content = rest
            .split("</text>")
            .next()
            .unwrap_or("")
            .trim()
            .replace("&lt;", "<")
            .replace("&gt;", ">")
            .replace("&quot;", "\"")
            .replace("&apos;", "'")
            .replace("&amp;", "&");
        let number = |name: &str| attribute(tag, name).and_then(|v| v.parse::<f64>().ok());
        texts.push(SvgText {
            x: number("x").unwrap_or(0.0),
            y: number("y").unwrap_or(0.0),
            size: number("font-size").unwrap_or(0.0),
            anchor: attribute(tag, "text-anchor").unwrap_or_else(|| "start".into()),
            fill: attribute(tag, "fill").unwrap_or_default(),
            content,
        });
    }
    texts
}

/// The opening tags of every `<name …>` element, as text.
pub fn svg_tags<'a>(svg: &'a str, name: &str) -> Vec<&'a str> {
    svg.split(&format!("<{name} "))
        .skip(1)
        .filter_map(|piece| piece.split_once('>').map(|(tag, _)| tag))
        .collect()
}

/// A numeric attribute of a tag (NaN when absent).
pub fn number(tag: &str, name: &str) -> f64 {
    attribute(tag, name)
        .and_then(|v| v.parse().ok())
        .unwrap_or(f64::NAN)
}

/// The points of a `<polyline>` tag.
pub fn polyline_points(tag: &str) -> Vec<(f64, f64)> {
    attribute(tag, "points")
        .unwrap_or_default()
        .split_whitespace()
        .filter_map(|p| {
            let (x, y) = p.split_once(',')?;
            Some((x.parse().ok()?, y.parse().ok()?))
        })
        .collect()
}

/// The plotting area of a single chart, (left, top, right, bottom) in pixels: the box of
/// its black axis lines — the longest vertical and horizontal polylines drawn in black.
pub fn plot_frame(svg: &str) -> (f64, f64, f64, f64) {
    let (mut vertical, mut horizontal) = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0));
    for tag in svg_tags(svg, "polyline") {
        if attribute(tag, "stroke").as_deref() != Some("#000000") {
            continue;
        }
        let points = polyline_points(tag);
        if points.len() != 2 {
            continue;
        }
        let ((x0, y0), (x1, y1)) = (points[0], points[1]);
        if x0 == x1 && (y1 - y0).abs() > vertical.2 - vertical.1 {
            vertical = (x0, y0.min(y1), y0.max(y1));
        }
        if y0 == y1 && (x1 - x0).abs() > horizontal.2 - horizontal.1 {
            horizontal = (y0, x0.min(x1), x0.max(x1));
        }
    }
    (vertical.0, vertical.1, horizontal.2, vertical.2)
}

/// The box a label covers, with a generous width: DejaVu Sans averages about 0.55 em per
/// character on this text, 0.62 em bounds it (digits and capitals are the widest).
pub fn text_box(t: &SvgText) -> (f64, f64, f64, f64) {
    let width = 0.62 * t.size * t.content.chars().count() as f64;
    let left = match t.anchor.as_str() {
        "end" => t.x - width,
        "middle" => t.x - width / 2.0,
        _ => t.x,
    };
    (left, t.y, left + width, t.y + t.size)
}

pub fn overlap(a: (f64, f64, f64, f64), b: (f64, f64, f64, f64)) -> bool {
    a.0 < b.2 && b.0 < a.2 && a.1 < b.3 && b.1 < a.3
}

/// The numbers written as tick labels left of the plot (the y axis: right-aligned texts
/// ending left of `left`) and below it (the x axis: centred texts below `bottom`, above
/// the axis title).
pub fn tick_labels(svg: &str) -> (Vec<String>, Vec<String>) {
    let (left, _, _, bottom) = plot_frame(svg);
    let texts = svg_texts(svg);
    let is_number = |t: &&SvgText| t.content.parse::<f64>().is_ok();
    let y = texts
        .iter()
        .filter(|t| t.anchor == "end" && t.x < left)
        .filter(is_number)
        .map(|t| t.content.clone())
        .collect();
    let x = texts
        .iter()
        .filter(|t| t.anchor == "middle" && t.y > bottom && t.y < bottom + 30.0)
        .filter(is_number)
        .map(|t| t.content.clone())
        .collect();
    (x, y)
}
