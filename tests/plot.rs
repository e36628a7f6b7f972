//! The picture module: heat maps and charts in PNG and SVG, with the built-in font.

use std::path::PathBuf;

use longstep::plot::{
    AxisSpec, Category, Colouring, Corner, Guide, HeatMap, LineChart, MarkerSet, Series, viridis,
};
use plotters::style::RGBColor;

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("longstep-plot-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir.join(name)
}

fn chart(y: AxisSpec) -> LineChart {
    let steps: Vec<f64> = (1..=10).map(|k| k as f64 * 0.5).collect();
    LineChart {
        title: "Energy error against outer step".into(),
        x: AxisSpec::log("outer step h (fs)"),
        y,
        series: vec![
            Series::line(
                "impulse",
                steps.iter().map(|&h| (h, 1e-5 * h * h)).collect(),
            ),
            Series::scatter(
                "long-average",
                steps.iter().map(|&h| (h, 2e-6 * h * h)).collect(),
            ),
        ],
        markers: vec![MarkerSet::unstable(vec![(5.0, 3e-4)])],
        guides: vec![Guide {
            x: 4.4,
            label: "predicted resonance".into(),
        }],
        levels: Vec::new(),
        bands: Vec::new(),
        legend: Corner::UpperLeft,
    }
}

#[test]
fn line_chart_png_and_svg_with_log_axes() {
    let png = scratch("chart.png");
    let svg = scratch("chart.svg");
    let figure = chart(AxisSpec::log("max |ΔE| / E0"));
    figure.save(&png).expect("png");
    figure.save(&svg).expect("svg");
    let bytes = std::fs::read(&png).expect("png file");
    assert!(bytes.starts_with(b"\x89PNG\r\n\x1a\n"));
    let text = std::fs::read_to_string(&svg).expect("svg file");
    for expected in [
        "Energy error against outer step",
        "impulse",
        "long-average",
        "unstable",
        "predicted resonance",
        "outer step h (fs)",
    ] {
        assert!(text.contains(expected), "the SVG lacks \"{expected}\"");
    }
}

#[test]
fn bad_pictures_are_errors_not_panics() {
    let figure = chart(AxisSpec::linear("error"));
    let error = figure
        .save(&scratch("chart.jpg"))
        .expect_err("jpg is not supported");
    assert!(error.to_string().contains(".png or .svg"), "{error}");
    // A logarithmic axis with no positive data.
    let mut negative = chart(AxisSpec::log("error"));
    for series in &mut negative.series {
        for point in &mut series.points {
            point.1 = -point.1;
        }
    }
    negative.markers.clear();
    let error = negative
        .save(&scratch("negative.png"))
        .expect_err("no positive y");
    assert!(error.to_string().contains("no y values"), "{error}");
    // A heat map whose values do not fill its grid.
    let map = HeatMap {
        title: "t".into(),
        x: AxisSpec::linear("x"),
        y: AxisSpec::linear("y"),
        x_cells: (0.0, 1.0, 3),
        y_cells: (0.0, 1.0, 3),
        values: vec![0.0; 8],
        colouring: Colouring::Categorical(vec![]),
        size: (400, 300),
        note: String::new(),
    };
    assert!(map.save(&scratch("short.png")).is_err());
}

#[test]
fn heat_maps_continuous_and_categorical() {
    let n = 60;
    let values: Vec<f64> = (0..n * n)
        .map(|k| {
            let (i, j) = (k / n, k % n);
            if i + j > n {
                ((i * j) as f64).max(1.0) * 1e-6
            } else {
                0.0
            }
        })
        .collect();
    let continuous = HeatMap {
        title: "Continuous".into(),
        x: AxisSpec::pi("Γ1"),
        y: AxisSpec::pi("Γ2"),
        x_cells: (0.0, 2.0 * std::f64::consts::PI, n),
        y_cells: (0.0, 2.0 * std::f64::consts::PI, n),
        values: values.clone(),
        colouring: Colouring::Continuous {
            label: "ρ − 1".into(),
            min: 1e-6,
            max: 4e-3,
            log: true,
            below: Some(Category {
                value: 0.0,
                name: "stable".into(),
                colour: RGBColor(255, 255, 255),
            }),
        },
        size: (800, 600),
        note: String::new(),
    };
    let svg = scratch("heat.svg");
    continuous.save(&svg).expect("svg");
    continuous.save(&scratch("heat.png")).expect("png");
    let text = std::fs::read_to_string(&svg).expect("svg file");
    assert!(text.contains("Continuous") && text.contains("stable") && text.contains("π"));

    let mut categorical = continuous.clone();
    categorical.title = "Categorical".into();
    categorical.values = values
        .iter()
        .map(|&v| if v > 0.0 { 1.0 } else { 0.0 })
        .collect();
    categorical.values[0] = f64::NAN; // no data
    categorical.colouring = Colouring::Categorical(vec![
        Category {
            value: 0.0,
            name: "stable".into(),
            colour: RGBColor(255, 255, 255),
        },
        Category {
            value: 1.0,
            name: "type 1".into(),
            colour: RGBColor(214, 39, 40),
        },
    ]);
    let svg = scratch("categorical.svg");
    categorical.save(&svg).expect("svg");
    let text = std::fs::read_to_string(&svg).expect("svg file");
    assert!(text.contains("type 1") && text.contains("no data"));
}

#[test]
fn viridis_ends_and_clamps() {
    assert_eq!(viridis(0.0), RGBColor(68, 1, 84));
    assert_eq!(viridis(1.0), RGBColor(253, 231, 37));
    assert_eq!(viridis(-3.0), viridis(0.0));
    assert_eq!(viridis(f64::NAN), viridis(0.0));
    assert_eq!(viridis(7.0), viridis(1.0));
}
