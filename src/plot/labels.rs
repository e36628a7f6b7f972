//! Where text goes on a picture: tick values for a logarithmic colour bar, and labels for
//! guide lines and points placed so that no two overlap. Pure geometry in pixels, so the
//! rules are tested without drawing.

/// A text box in backend pixels (y grows downwards).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TextBox {
    pub left: i32,
    pub top: i32,
    pub width: i32,
    pub height: i32,
}

impl TextBox {
    /// Whether the boxes overlap once each is grown by `pad` pixels on every side.
    pub fn overlaps(&self, other: &TextBox, pad: i32) -> bool {
        self.left - pad < other.left + other.width
            && other.left - pad < self.left + self.width
            && self.top - pad < other.top + other.height
            && other.top - pad < self.top + self.height
    }

    fn overlap_area(&self, other: &TextBox) -> i64 {
        let w = (self.left + self.width).min(other.left + other.width) - self.left.max(other.left);
        let h = (self.top + self.height).min(other.top + other.height) - self.top.max(other.top);
        i64::from(w.max(0)) * i64::from(h.max(0))
    }

    fn inside(&self, area: &TextBox) -> bool {
        self.left >= area.left
            && self.top >= area.top
            && self.left + self.width <= area.left + area.width
            && self.top + self.height <= area.top + area.height
    }
}

/// Tick values for a logarithmic bar over `[min, max]`: the decades if they give four
/// ticks, else 1-2-5 in each decade, else every 1–9 multiple — so a range of less than a
/// decade (ρ − 1 from 3e-4 to 3.5e-3) is labelled down to its bottom. Each value once.
pub fn log_ticks(min: f64, max: f64) -> Vec<f64> {
    if !(min > 0.0 && max > min && max.is_finite()) {
        return Vec::new();
    }
    let (low, high) = (min.log10().floor() as i32, max.log10().ceil() as i32);
    let within = |mantissas: &[f64]| -> Vec<f64> {
        (low..=high)
            .flat_map(|e| mantissas.iter().map(move |m| m * 10f64.powi(e)))
            // A tick at the very end of the range, up to round-off, still counts.
            .filter(|v| *v >= min * (1.0 - 1e-9) && *v <= max * (1.0 + 1e-9))
            .collect()
    };
    let ladders: [&[f64]; 3] = [
        &[1.0],
        &[1.0, 2.0, 5.0],
        &[1., 2., 3., 4., 5., 6., 7., 8., 9.],
    ];
    let mut ticks = Vec::new();
    for mantissas in ladders {
        ticks = within(mantissas);
        if ticks.len() >= 4 {
            break;
        }
    }
    ticks
}

/// Tick values for a linear axis over `[low, high]`: multiples of a round step (1, 2, 2.5
/// or 5 times a power of ten) chosen for about six ticks; never fewer than three, since the
/// step is at most 2.5 times a sixth of the span.
pub fn linear_ticks(low: f64, high: f64) -> Vec<f64> {
    if !(high > low && low.is_finite() && high.is_finite()) {
        return Vec::new();
    }
    let raw = (high - low) / 6.0;
    let magnitude = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 2.5, 5.0, 10.0]
        .iter()
        .map(|m| m * magnitude)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * magnitude);
    let (first, last) = ((low / step).ceil() as i64, (high / step).floor() as i64);
    (first..=last)
        .map(|k| k as f64 * step)
        .map(|v| if v.abs() < 1e-9 * step { 0.0 } else { v })
        .collect()
}

/// Tick values for a logarithmic chart axis over `[low, high]`: the decades (every k-th
/// when there are more than ten), else 1-2-5 in each decade, else 1–9 — the first that
/// gives at least three ticks; a range too narrow for that (200–340) gets round linear
/// ticks inside it, so the axis always carries numbers.
pub fn log_axis_ticks(low: f64, high: f64) -> Vec<f64> {
    if !(low > 0.0 && high > low && high.is_finite()) {
        return Vec::new();
    }
    let (first, last) = (low.log10().floor() as i32, high.log10().ceil() as i32);
    let within = |mantissas: &[f64]| -> Vec<f64> {
        (first..=last)
            .flat_map(|e| mantissas.iter().map(move |m| m * 10f64.powi(e)))
            .filter(|v| *v >= low * (1.0 - 1e-9) && *v <= high * (1.0 + 1e-9))
            .collect()
    };
    let decades = within(&[1.0]);
    if decades.len() > 10 {
        let every = decades.len().div_ceil(8) as i64;
        return decades
            .into_iter()
            .filter(|v| (v.log10().round() as i64).rem_euclid(every) == 0)
            .collect();
    }
    let ladders: [&[f64]; 2] = [&[1.0, 2.0, 5.0], &[1., 2., 3., 4., 5., 6., 7., 8., 9.]];
    if decades.len() >= 3 {
        return decades;
    }
    for mantissas in ladders {
        let ticks = within(mantissas);
        if ticks.len() >= 3 {
            return ticks;
        }
    }
    linear_ticks(low, high)
        .into_iter()
        .filter(|v| *v > 0.0)
        .collect()
}

/// The label of each group of guide lines drawn closer than `min_gap` pixels apart (their
/// labels would print over each other): one label naming the distinct texts and, for
/// more than one line, how many lines. Input: pixel x and text of each guide, any order.
/// Output: (pixel x of the group's first line, label), left to right.
pub fn group_guides(guides: &[(i32, String)], min_gap: i32) -> Vec<(i32, String)> {
    let mut sorted: Vec<&(i32, String)> = guides.iter().collect();
    sorted.sort_by_key(|g| g.0);
    let mut groups: Vec<(i32, i32, Vec<&str>, usize)> = Vec::new();
    for (x, text) in sorted {
        match groups.last_mut() {
            Some(group) if x - group.1 < min_gap => {
                group.1 = *x;
                group.3 += 1;
                if !group.2.contains(&text.as_str()) {
                    group.2.push(text);
                }
            }
            _ => groups.push((*x, *x, vec![text], 1)),
        }
    }
    groups
        .into_iter()
        .map(|(x, _, texts, count)| {
            let label = texts.join(" / ");
            if count > 1 {
                (x, format!("{label} ({count} lines)"))
            } else {
                (x, label)
            }
        })
        .collect()
}

/// Rows for labels hung from the top of the plot, each given as its box in the first row:
/// a label goes down one row of `row_height` until it overlaps none placed before it.
/// Returns each label's box where it goes.
pub fn stack_in_rows(first_row: &[TextBox], row_height: i32, pad: i32) -> Vec<TextBox> {
    let mut placed: Vec<TextBox> = Vec::with_capacity(first_row.len());
    for label in first_row {
        let mut candidate = *label;
        while placed.iter().any(|p| p.overlaps(&candidate, pad)) {
            candidate.top += row_height;
        }
        placed.push(candidate);
    }
    placed
}

/// A label to put beside a point: the point in pixels, the label's size, its text.
pub struct PointText<'a> {
    pub at: (i32, i32),
    pub size: (i32, i32),
    pub text: &'a str,
}

/// Boxes for point labels: each tries right, left, above and below its point (a gap of
/// `gap` pixels) and takes the first position inside `area` that overlaps no label placed
/// before it, else the position of least overlap. A label whose text is already placed
/// within `same_within` pixels of its point is left out (`None`): it would repeat what
/// is written beside it (the same h at the same cost on an error-against-cost chart).
pub fn place_point_labels(
    labels: &[PointText],
    area: TextBox,
    gap: i32,
    same_within: i32,
) -> Vec<Option<TextBox>> {
    let mut placed: Vec<(TextBox, &str)> = Vec::new();
    let mut result = Vec::with_capacity(labels.len());
    for label in labels {
        let (x, y) = label.at;
        let (w, h) = label.size;
        let near = |b: &TextBox| {
            let (cx, cy) = (b.left + b.width / 2, b.top + b.height / 2);
            (cx - x).abs() <= same_within + w && (cy - y).abs() <= same_within
        };
        if placed.iter().any(|(b, t)| *t == label.text && near(b)) {
            result.push(None);
            continue;
        }
        let candidates = [
            TextBox {
                left: x + gap,
                top: y - h / 2,
                width: w,
                height: h,
            },
            TextBox {
                left: x - gap - w,
                top: y - h / 2,
                width: w,
                height: h,
            },
            TextBox {
                left: x - w / 2,
                top: y - gap - h,
                width: w,
                height: h,
            },
            TextBox {
                left: x - w / 2,
                top: y + gap,
                width: w,
                height: h,
            },
        ];
        let overlap = |c: &TextBox| -> i64 { placed.iter().map(|(b, _)| c.overlap_area(b)).sum() };
        let chosen = candidates
            .iter()
            .find(|c| c.inside(&area) && overlap(c) == 0)
            .or_else(|| {
                candidates
                    .iter()
                    .filter(|c| c.inside(&area))
                    .min_by_key(|c| overlap(c))
            })
            .copied()
            .unwrap_or(candidates[0]);
        placed.push((chosen, label.text));
        result.push(Some(chosen));
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    fn text_box(left: i32, top: i32, width: i32) -> TextBox {
        TextBox {
            left,
            top,
            width,
            height: 14,
        }
    }

    #[test]
    fn a_range_under_a_decade_is_ticked_down_to_its_bottom() {
        // The long-average radius map: ρ − 1 from 3e-4 to 3.5e-3.
        let ticks = log_ticks(3e-4, 3.5e-3);
        assert!(ticks[0] < 1e-3 && ticks[0] >= 3e-4, "{ticks:?}");
        assert!(ticks.len() >= 4);
        // Two decades and more: 1-2-5 or decades, never two equal values.
        let wide = log_ticks(8e-4, 4.5e-2);
        assert_eq!(wide, vec![1e-3, 2e-3, 5e-3, 1e-2, 2e-2]);
        assert_eq!(log_ticks(1e-12, 1.0).len(), 13);
        assert!(log_ticks(0.0, 1.0).is_empty());
    }

    #[test]
    fn chart_axes_always_carry_at_least_three_round_ticks() {
        // ns/day between 200 and 340 on a log axis: no decade, no 1-2-5 value but 200.
        let ticks = log_axis_ticks(200.0, 340.0);
        assert!(ticks.len() >= 3, "{ticks:?}");
        assert!(ticks.iter().all(|t| (200.0..=340.0).contains(t)));
        // Drifts from 1e-16 to 1e7: at most ten decades, each once.
        let wide = log_axis_ticks(1e-16, 1e7);
        assert!((3..=10).contains(&wide.len()), "{wide:?}");
        // A work-precision cost axis of one decade: 1-2-5, not a lone tick.
        assert_eq!(log_axis_ticks(30.0, 300.0), vec![50.0, 100.0, 200.0]);
        let linear = linear_ticks(-2100.0, 550.0);
        assert!(linear.len() >= 3 && linear.contains(&0.0), "{linear:?}");
        assert_eq!(linear_ticks(0.5, 2.5), vec![0.5, 1.0, 1.5, 2.0, 2.5]);
    }

    #[test]
    fn lines_closer_than_the_gap_share_one_label() {
        let guides: Vec<(i32, String)> =
            [(500, "type2 k=1"), (504, "type1 k=1"), (509, "type2 k=1")]
                .into_iter()
                .chain([(700, "type1 k=2")])
                .map(|(x, t)| (x, t.to_string()))
                .collect();
        let groups = group_guides(&guides, 8);
        assert_eq!(
            groups,
            vec![
                (500, "type2 k=1 / type1 k=1 (3 lines)".to_string()),
                (700, "type1 k=2".to_string())
            ]
        );
    }

    #[test]
    fn stacked_labels_never_overlap() {
        let first: Vec<TextBox> = (0..12).map(|k| text_box(100 + 9 * k, 40, 70)).collect();
        let placed = stack_in_rows(&first, 15, 2);
        for (i, a) in placed.iter().enumerate() {
            for b in &placed[i + 1..] {
                assert!(!a.overlaps(b, 0), "{a:?} overlaps {b:?}");
            }
        }
        // A label alone keeps the first row.
        assert_eq!(stack_in_rows(&first[..1], 15, 2)[0], first[0]);
    }

    #[test]
    fn point_labels_avoid_each_other_and_repeat_nothing() {
        let area = text_box(0, 0, 400);
        let area = TextBox {
            height: 300,
            ..area
        };
        // Four methods at the same cost (same x) with errors close together, the same four
        // step sizes each.
        let mut labels = Vec::new();
        let texts = ["h = 0.4", "h = 0.2", "h = 0.1"];
        for method in 0..4 {
            for (k, text) in texts.iter().enumerate() {
                labels.push(PointText {
                    at: (100 + 100 * k as i32, 100 + 12 * method),
                    size: (48, 14),
                    text,
                });
            }
        }
        let placed = place_point_labels(&labels, area, 6, 30);
        let drawn: Vec<&TextBox> = placed.iter().flatten().collect();
        for (i, a) in drawn.iter().enumerate() {
            for b in &drawn[i + 1..] {
                assert!(!a.overlaps(b, 0), "{a:?} overlaps {b:?}");
            }
        }
        // Each step size is written at least once.
        for text in texts {
            assert!(
                labels
                    .iter()
                    .zip(&placed)
                    .any(|(l, p)| l.text == text && p.is_some())
            );
        }
    }
}
