//! The "breaking point" charts of the `stress` suite, as SVG (plotters'
//! SVG backend, as the accuracy plots). A sweep's chart draws each
//! engine's metric against the swept value, passes as dots and failures as
//! crosses, the criterion's bound as a dashed line, and each engine's
//! breaking point in the legend. Log axes are drawn as linear axes over
//! log10 of the values, labelled at whole decades.

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::Point;
use crate::accuracy::plot::{tick_label, wrap};
use crate::accuracy::sim::Engine;

const SIZE: (u32, u32) = (1100, 600);
const LEGEND_W: u32 = 300;
const HEAD_H: u32 = 74;
const WRAP: usize = 150;

fn colour(e: Engine) -> RGBColor {
    match e {
        Engine::Ours => RGBColor(31, 119, 180),
        Engine::RapierF32 => RGBColor(230, 120, 10),
        Engine::RapierF64 => RGBColor(44, 160, 44),
    }
}

/// Everything one chart shows.
pub struct Chart<'a> {
    /// Heading: the sweep's name.
    pub name: &'a str,
    /// What is simulated.
    pub title: &'a str,
    /// The pass criterion.
    pub criterion: &'a str,
    /// x axis label.
    pub param: &'a str,
    /// y axis label.
    pub metric: &'a str,
    /// Whether x is logarithmic.
    pub log_x: bool,
    /// The criterion's bound on the metric (0: none drawn).
    pub limit: f64,
    /// Every trial.
    pub points: &'a [Point],
    /// The engines and their breaking-point lines, legend order.
    pub engines: &'a [(Engine, String)],
}

/// Where a metric is drawn on the log y axis: log10, zeros at `floor`,
/// NaN and infinity at `ceiling`.
pub fn y_of(metric: f64, floor: f64, ceiling: f64) -> f64 {
    if metric.is_nan() || metric.is_infinite() {
        ceiling.log10()
    } else {
        metric.clamp(floor, ceiling).log10()
    }
}

/// The y range: a decade below the smallest positive figure (or the
/// bound), a decade above the largest.
pub fn y_range(points: &[Point], limit: f64) -> (f64, f64) {
    let finite = points
        .iter()
        .map(|p| p.metric)
        .chain((limit > 0.0).then_some(limit))
        .filter(|m| m.is_finite() && *m > 0.0);
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for m in finite {
        lo = lo.min(m);
        hi = hi.max(m);
    }
    if !lo.is_finite() {
        return (0.1, 10.0);
    }
    (
        10f64.powf(lo.log10().floor() - 1.0),
        10f64.powf(hi.log10().ceil() + 1.0),
    )
}

fn decade_label(v: f64) -> String {
    if (v - v.round()).abs() < 1e-6 {
        tick_label(10f64.powf(v.round()))
    } else {
        String::new()
    }
}

/// The SVG text of one chart.
pub fn svg(chart: &Chart) -> Result<String, String> {
    let mut out = String::new();
    draw(&mut out, chart).map_err(|e| e.to_string())?;
    Ok(out)
}

type DrawResult = Result<(), Box<dyn std::error::Error>>;

fn draw(out: &mut String, c: &Chart) -> DrawResult {
    let root = SVGBackend::with_string(out, SIZE).into_drawing_area();
    root.fill(&WHITE)?;
    let (head, body) = root.split_vertically(HEAD_H);
    let (area, legend) = body.split_horizontally(SIZE.0 - LEGEND_W);
    let x_mid = SIZE.0 as i32 / 2;
    let centred = |size| {
        TextStyle::from(("sans-serif", size).into_font()).pos(Pos::new(HPos::Center, VPos::Top))
    };
    head.draw(&Text::new(
        format!("{}: where each engine breaks", c.name),
        (x_mid, 6),
        centred(19),
    ))?;
    let mut lines = wrap(c.title, WRAP);
    lines.extend(wrap(&format!("pass: {}", c.criterion), WRAP));
    for (i, line) in lines.iter().take(3).enumerate() {
        head.draw(&Text::new(
            line.clone(),
            (x_mid, 30 + 15 * i as i32),
            centred(13),
        ))?;
    }

    let xs: Vec<f64> = c
        .points
        .iter()
        .map(|p| if c.log_x { p.value.log10() } else { p.value })
        .collect();
    let (mut x0, mut x1) = xs
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    if !x0.is_finite() {
        (x0, x1) = (0.0, 1.0);
    }
    let pad = ((x1 - x0) * 0.05).max(0.5);
    let (x0, x1) = (x0 - pad, x1 + pad);
    let (floor, ceiling) = y_range(c.points, c.limit);
    let (y0, y1) = (floor.log10() - 0.2, ceiling.log10() + 0.2);
    let mut chart = ChartBuilder::on(&area)
        .margin(12)
        .x_label_area_size(50)
        .y_label_area_size(80)
        .build_cartesian_2d(x0..x1, y0..y1)?;
    let log_x = c.log_x;
    let x_fmt = move |v: &f64| {
        if log_x {
            decade_label(*v)
        } else if (v - v.round()).abs() < 1e-6 {
            format!("{}", v.round() as i64)
        } else {
            String::new()
        }
    };
    chart
        .configure_mesh()
        .x_desc(c.param)
        .y_desc(c.metric)
        .x_labels(14)
        .y_labels(((y1 - y0).ceil() as usize + 1).max(4))
        .x_label_formatter(&x_fmt)
        .y_label_formatter(&|v| decade_label(*v))
        .label_style(("sans-serif", 13))
        .axis_desc_style(("sans-serif", 14))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()?;
    if c.limit > 0.0 {
        let y = c.limit.log10();
        chart.draw_series(DashedLineSeries::new(
            vec![(x0, y), (x1, y)],
            6,
            4,
            RGBColor(200, 30, 30).stroke_width(1),
        ))?;
    }
    for (engine, _) in c.engines {
        let col = colour(*engine);
        let pts: Vec<(f64, f64, bool)> = c
            .points
            .iter()
            .filter(|p| p.engine == *engine)
            .map(|p| {
                let x = if log_x { p.value.log10() } else { p.value };
                (x, y_of(p.metric, floor, ceiling), p.passed)
            })
            .collect();
        chart.draw_series(LineSeries::new(
            pts.iter().map(|&(x, y, _)| (x, y)),
            col.stroke_width(2),
        ))?;
        chart.draw_series(
            pts.iter()
                .filter(|p| p.2)
                .map(|&(x, y, _)| Circle::new((x, y), 4, col.filled())),
        )?;
        chart.draw_series(
            pts.iter()
                .filter(|p| !p.2)
                .map(|&(x, y, _)| Cross::new((x, y), 7, col.stroke_width(2))),
        )?;
    }

    let style =
        TextStyle::from(("sans-serif", 13).into_font()).pos(Pos::new(HPos::Left, VPos::Center));
    let (x, mut y) = (10, 30);
    legend.draw(&Text::new(
        "breaking point (largest pass):".to_owned(),
        (x, y),
        style.clone(),
    ))?;
    y += 24;
    for (engine, line) in c.engines {
        let col = colour(*engine);
        legend.draw(&PathElement::new(
            vec![(x, y), (x + 28, y)],
            col.stroke_width(2),
        ))?;
        legend.draw(&Circle::new((x + 14, y), 4, col.filled()))?;
        legend.draw(&Text::new(
            engine.name().to_owned(),
            (x + 36, y),
            style.clone(),
        ))?;
        y += 18;
        for l in wrap(line, 38) {
            legend.draw(&Text::new(l, (x + 36, y), style.clone()))?;
            y += 16;
        }
        y += 8;
    }
    let grey = RGBColor(90, 90, 90);
    legend.draw(&Cross::new((x + 14, y), 7, grey.stroke_width(2)))?;
    legend.draw(&Text::new(
        "failed (CSV status)".to_owned(),
        (x + 36, y),
        style.clone(),
    ))?;
    y += 22;
    if c.limit > 0.0 {
        legend.draw(&PathElement::new(
            vec![(x, y), (x + 28, y)],
            RGBColor(200, 30, 30).stroke_width(1),
        ))?;
        legend.draw(&Text::new(
            format!("bound {}", tick_label(c.limit)),
            (x + 36, y),
            style.clone(),
        ))?;
        y += 22;
    }
    legend.draw(&Text::new(
        format!("0 drawn at {}", tick_label(floor)),
        (x, y),
        style.clone(),
    ))?;
    y += 18;
    legend.draw(&Text::new(
        format!("NaN drawn at {}", tick_label(ceiling)),
        (x, y),
        style,
    ))?;
    root.present()?;
    Ok(())
}

/// The soak's chart: the energy above the settled pile's, per chart bin,
/// against simulated time, one line per engine.
pub fn soak_svg(
    title: &str,
    series: &[(Engine, Vec<(f64, f64)>)],
    lines: &[(Engine, String)],
) -> Result<String, String> {
    let mut out = String::new();
    let points: Vec<Point> = series
        .iter()
        .flat_map(|(e, s)| {
            s.iter().map(|&(t, de)| Point {
                engine: *e,
                value: t,
                passed: true,
                metric: de.max(0.0),
                status: "ok",
                ms: 0.0,
                detail: String::new(),
            })
        })
        .collect();
    draw(
        &mut out,
        &Chart {
            name: "soak",
            title,
            criterion: "no fault or NaN; energy never more than 0.01 m × the pile's weight above its value right after the last kick; every body sleeps at some tick of the last quarter; no frozen pose gaining speed",
            param: "simulated time, s",
            metric: "energy above the value after the last kick (largest per bin), J",
            log_x: false,
            limit: 0.0,
            points: &points,
            engines: lines,
        },
    )
    .map_err(|e| e.to_string())?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(metric: f64) -> Point {
        Point {
            engine: Engine::Ours,
            value: 1.0,
            passed: true,
            metric,
            status: "ok",
            ms: 1.0,
            detail: String::new(),
        }
    }

    #[test]
    fn the_y_range_spans_the_data_and_the_bound_with_a_decade_each_side() {
        let (lo, hi) = y_range(&[p(0.0), p(3e-4), p(f64::NAN), p(0.2)], 0.02);
        assert!(
            (lo - 1e-5).abs() < 1e-12 && (hi - 10.0).abs() < 1e-9,
            "{lo} {hi}"
        );
        assert_eq!(y_of(0.0, lo, hi), lo.log10());
        assert_eq!(y_of(f64::NAN, lo, hi), hi.log10());
        assert_eq!(y_range(&[p(0.0)], 0.0), (0.1, 10.0));
    }

    #[test]
    fn log_axes_are_labelled_at_decades_only() {
        assert_eq!(decade_label(3.0), "1000");
        assert_eq!(decade_label(-2.0), "0.01");
        assert_eq!(decade_label(2.5), "");
    }
}
