//! SVG figures for the report (plotters): Pareto scatter plots and ULP histograms.

use plotters::prelude::*;

/// One point of a trade-off plot.
#[derive(Clone, Debug)]
pub struct Point {
    /// The point's label (method and precision).
    pub label: String,
    /// Horizontal position (cost).
    pub x: f64,
    /// Vertical position (error).
    pub y: f64,
    /// Drawn filled (robust methods) or hollow.
    pub robust: bool,
    /// Colour index (one per method) and marker: triangle for f64 (`square`), circle for f32.
    pub colour: usize,
    /// The `f64` marker (a triangle); `false`: the `f32` circle.
    pub square: bool,
}

/// Strong, distinguishable colours (Tableau 10).
const COLOURS: [RGBColor; 10] = [
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

/// The non-dominated points (no other point is at most as slow and at most as wrong, and better
/// in one), sorted by x: the curve a developer chooses on.
pub fn pareto_front(points: &[Point]) -> Vec<Point> {
    let mut front: Vec<Point> = points
        .iter()
        .filter(|p| {
            !points
                .iter()
                .any(|q| q.x <= p.x && q.y <= p.y && (q.x < p.x || q.y < p.y))
        })
        .cloned()
        .collect();
    front.sort_by(|a, b| a.x.total_cmp(&b.x));
    front
}

/// Renders a log–log scatter plot with the Pareto front. Values of y at or below `floor`
/// (exact zeros: no error measured) are drawn on the floor line, which is labelled.
pub fn pareto_svg(
    title: &str,
    x_label: &str,
    y_label: &str,
    points: &[Point],
    floor: f64,
) -> String {
    let mut svg = String::new();
    let clamp = |y: f64| y.max(floor);
    let pts: Vec<Point> = points
        .iter()
        .map(|p| Point {
            y: clamp(p.y),
            ..p.clone()
        })
        .collect();
    // Axis ranges, padded by a factor on the log scales
    let (xmin, xmax) = min_max(pts.iter().map(|p| p.x));
    let (_, ymax) = min_max(pts.iter().map(|p| p.y));
    let xr = (xmin / 1.6)..(xmax * 1.6);
    let yr = (floor / 3.0)..(ymax.max(floor * 10.0) * 6.0);
    {
        let root = SVGBackend::with_string(&mut svg, (760, 460)).into_drawing_area();
        let draw = || -> Result<(), Box<dyn std::error::Error + '_>> {
            root.fill(&WHITE)?;
            let mut chart = ChartBuilder::on(&root)
                .caption(title, ("sans-serif", 18))
                .margin(12)
                .x_label_area_size(42)
                .y_label_area_size(70)
                .build_cartesian_2d(xr.clone().log_scale(), yr.log_scale())?;
            chart
                .configure_mesh()
                .x_desc(x_label)
                .y_desc(y_label)
                .y_label_formatter(&|v| format!("{v:.0e}"))
                .draw()?;
            // Zero line
            chart.draw_series(LineSeries::new(
                [(xr.start, floor), (xr.end, floor)],
                ShapeStyle::from(&RGBColor(150, 150, 150)).stroke_width(1),
            ))?;
            chart.draw_series(std::iter::once(Text::new(
                "zero (none measured)",
                (xr.start * 1.05, floor * 0.62),
                ("sans-serif", 11)
                    .into_font()
                    .color(&RGBColor(110, 110, 110)),
            )))?;
            // The front
            let front = pareto_front(&pts);
            chart.draw_series(LineSeries::new(
                front.iter().map(|p| (p.x, p.y)),
                ShapeStyle::from(&RGBColor(200, 60, 40)).stroke_width(2),
            ))?;
            // The points, each labelled where no earlier label is (pixel boxes, tried in order:
            // right-above, right-below, then further away)
            let mut placed: Vec<(i32, i32, i32, i32)> = vec![];
            for p in &pts {
                let colour = COLOURS[p.colour % COLOURS.len()];
                let style = if p.robust {
                    ShapeStyle::from(colour).filled()
                } else {
                    ShapeStyle::from(colour).stroke_width(2)
                };
                if p.square {
                    chart.draw_series(std::iter::once(TriangleMarker::new(
                        (p.x, p.y),
                        6,
                        style,
                    )))?;
                } else {
                    chart.draw_series(std::iter::once(Circle::new((p.x, p.y), 5, style)))?;
                }
                let (px, py) = chart.backend_coord(&(p.x, p.y));
                let (w, h) = (6 * p.label.chars().count() as i32 + 2, 13);
                let free = |b: &(i32, i32, i32, i32)| {
                    placed
                        .iter()
                        .all(|o| b.2 <= o.0 || o.2 <= b.0 || b.3 <= o.1 || o.3 <= b.1)
                };
                let spot = [-16, 4, -30, 18, -44, 32, -58, 46]
                    .iter()
                    .map(|&dy| (px + 8, py + dy, px + 8 + w, py + dy + h))
                    .find(free)
                    .unwrap_or((px + 8, py - 16, px + 8 + w, py - 16 + h));
                placed.push(spot);
                root.draw(&Text::new(
                    p.label.clone(),
                    (spot.0, spot.1),
                    ("sans-serif", 11).into_font().color(&colour),
                ))?;
            }
            root.present()?;
            Ok(())
        };
        if let Err(e) = draw() {
            return format!("<!-- plot failed: {e} -->");
        }
    }
    svg
}

/// A histogram of bits of error, one line per series (fraction of that series' cases per bit).
pub fn bits_histogram_svg(title: &str, series: &[(String, Vec<f64>)]) -> String {
    let max_bits = series
        .iter()
        .flat_map(|(_, v)| v.iter())
        .fold(0.0f64, |a, &b| a.max(b))
        .ceil()
        .max(1.0) as usize;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (760, 360)).into_drawing_area();
        let draw = || -> Result<(), Box<dyn std::error::Error + '_>> {
            root.fill(&WHITE)?;
            let mut chart = ChartBuilder::on(&root)
                .caption(title, ("sans-serif", 16))
                .margin(10)
                .x_label_area_size(36)
                .y_label_area_size(56)
                .build_cartesian_2d(0usize..max_bits + 1, (1e-5f64..1.5f64).log_scale())?;
            chart
                .configure_mesh()
                .x_desc("bits of error, ⌈log2(1 + ulps)⌉")
                .y_desc("fraction of hits")
                .y_label_formatter(&|v| format!("{v:.0e}"))
                .draw()?;
            for (i, (name, bits)) in series.iter().enumerate() {
                if bits.is_empty() {
                    continue;
                }
                let mut counts = vec![0usize; max_bits + 1];
                for b in bits {
                    counts[(b.ceil() as usize).min(max_bits)] += 1;
                }
                let n = bits.len() as f64;
                let colour = COLOURS[i % COLOURS.len()];
                chart
                    .draw_series(LineSeries::new(
                        counts
                            .iter()
                            .enumerate()
                            .filter(|(_, &c)| c > 0)
                            .map(|(k, &c)| (k, c as f64 / n)),
                        ShapeStyle::from(colour).stroke_width(2),
                    ))?
                    .label(name.clone())
                    .legend(move |(x, y)| {
                        PathElement::new([(x, y), (x + 16, y)], colour.stroke_width(2))
                    });
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .position(SeriesLabelPosition::UpperRight)
                .draw()?;
            root.present()?;
            Ok(())
        };
        if let Err(e) = draw() {
            return format!("<!-- plot failed: {e} -->");
        }
    }
    svg
}

/// A log–log line plot, one line (with markers) per series of `(x, y)` points (points with a
/// y at or below 0 are left out: a log scale cannot show them).
pub fn lines_svg(
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[(String, Vec<(f64, f64)>)],
) -> String {
    let mut svg = String::new();
    let pts = || {
        series
            .iter()
            .flat_map(|(_, v)| v.iter())
            .filter(|p| p.1 > 0.0)
    };
    let (xmin, xmax) = min_max(pts().map(|p| p.0));
    let (ymin, ymax) = min_max(pts().map(|p| p.1));
    if !(xmin.is_finite() && ymin.is_finite()) {
        return "<!-- nothing to plot -->".into();
    }
    let xr = (xmin / 2.0)..(xmax * 2.0);
    let yr = (ymin / 3.0)..(ymax * 3.0);
    {
        let root = SVGBackend::with_string(&mut svg, (760, 460)).into_drawing_area();
        let draw = || -> Result<(), Box<dyn std::error::Error + '_>> {
            root.fill(&WHITE)?;
            let mut chart = ChartBuilder::on(&root)
                .caption(title, ("sans-serif", 18))
                .margin(12)
                .x_label_area_size(42)
                .y_label_area_size(70)
                .build_cartesian_2d(xr.log_scale(), yr.log_scale())?;
            chart
                .configure_mesh()
                .x_desc(x_label)
                .y_desc(y_label)
                .x_label_formatter(&|v| format!("{v:.0e}"))
                .y_label_formatter(&|v| format!("{v:.0e}"))
                .draw()?;
            for (i, (name, v)) in series.iter().enumerate() {
                let colour = COLOURS[i % COLOURS.len()];
                let v: Vec<(f64, f64)> = v.iter().copied().filter(|p| p.1 > 0.0).collect();
                chart
                    .draw_series(LineSeries::new(
                        v.iter().copied(),
                        ShapeStyle::from(colour).stroke_width(2),
                    ))?
                    .label(name.clone())
                    .legend(move |(x, y)| {
                        PathElement::new(
                            [(x, y), (x + 16, y)],
                            ShapeStyle::from(colour).stroke_width(2),
                        )
                    });
                chart.draw_series(
                    v.iter()
                        .map(|&p| Circle::new(p, 3, ShapeStyle::from(colour).filled())),
                )?;
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .position(SeriesLabelPosition::UpperLeft)
                .draw()?;
            root.present()?;
            Ok(())
        };
        if let Err(e) = draw() {
            return format!("<!-- plot failed: {e} -->");
        }
    }
    svg
}

fn min_max(v: impl Iterator<Item = f64>) -> (f64, f64) {
    v.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
        (a.min(x), b.max(x))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(label: &str, x: f64, y: f64) -> Point {
        Point {
            label: label.into(),
            x,
            y,
            robust: false,
            colour: 0,
            square: false,
        }
    }

    #[test]
    fn front_keeps_only_undominated_points() {
        let pts = [
            p("a", 1.0, 10.0),
            p("b", 2.0, 1.0),
            p("c", 3.0, 5.0),
            p("d", 4.0, 0.0),
        ];
        let names: Vec<String> = pareto_front(&pts).into_iter().map(|p| p.label).collect();
        assert_eq!(names, ["a", "b", "d"]);
    }

    #[test]
    fn plots_are_svg_with_every_label() {
        let s = pareto_svg(
            "t",
            "x",
            "y",
            &[p("geometric/f32", 3.0, 1e-3), p("rtg7/f64", 9.0, 0.0)],
            1e-7,
        );
        assert!(s.starts_with("<svg") && s.contains("geometric/f32") && s.contains("rtg7/f64"));
        let h = bits_histogram_svg("h", &[("inside".into(), vec![0.0, 1.0, 1.0, 3.5])]);
        assert!(h.starts_with("<svg") && h.contains("inside"));
    }

    /// Points at nearly the same place get labels on different lines (the report's
    /// `algebraic/f32` once sat on `press/f32`).
    #[test]
    fn labels_of_coinciding_points_do_not_overlap() {
        let names = ["algebraic/f32", "press/f32", "geometric/f32"];
        let pts: Vec<Point> = names.iter().map(|n| p(n, 3.0, 1e-3)).collect();
        let s = pareto_svg("t", "x", "y", &pts, 1e-7);
        // The y of each label's <text> element
        let ys: Vec<String> = names
            .iter()
            .map(|n| {
                let at = s.find(n).expect("label drawn");
                let open = s[..at].rfind("<text").unwrap();
                let tag = &s[open..at];
                let y = tag.find(" y=\"").unwrap() + 4;
                tag[y..y + tag[y..].find('"').unwrap()].to_string()
            })
            .collect();
        assert!(ys[0] != ys[1] && ys[1] != ys[2] && ys[0] != ys[2], "{ys:?}");
    }
}
