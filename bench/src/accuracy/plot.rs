//! One work-precision plot per case, as SVG (plotters' SVG backend only:
//! labels are SVG `<text>` drawn by the viewer, so no font files or system
//! libraries are needed to make them).

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::Measurement;
use super::frontier::{self, Point};
use super::sim::Engine;

/// The plot size, px.
const SIZE: (u32, u32) = (1100, 640);
/// The legend panel's width at the right, px.
const LEGEND_W: u32 = 250;
/// The heading's height (three lines), px.
const HEAD_H: u32 = 74;
/// Heading lines longer than this many characters are wrapped.
const WRAP: usize = 150;

fn colour(e: Engine) -> RGBColor {
    match e {
        Engine::Ours => RGBColor(31, 119, 180),
        Engine::RapierF32 => RGBColor(230, 120, 10),
        Engine::RapierF64 => RGBColor(44, 160, 44),
    }
}

/// A tick label for a log axis: plain decimals in a readable range,
/// scientific outside it.
pub fn tick_label(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if (1e-3..1e4).contains(&a) {
        let s = format!("{v:.3}");
        s.trim_end_matches('0').trim_end_matches('.').to_owned()
    } else {
        let s = format!("{v:.0e}");
        s.replace("e-0", "e-").replace("e0", "e")
    }
}

/// Where a measurement is drawn: its time and its error clamped into
/// `[floor, ceiling]` (NaN at the ceiling).
pub fn drawn(m: &Measurement, floor: f64, ceiling: f64) -> (f64, f64) {
    let e = if m.error.is_nan() {
        ceiling
    } else {
        m.error.clamp(floor, ceiling)
    };
    (m.ms, e)
}

/// Splits `text` at spaces into lines of at most `width` characters (a
/// longer word gets a line of its own).
pub fn wrap(text: &str, width: usize) -> Vec<String> {
    let mut lines: Vec<String> = Vec::new();
    let mut line = String::new();
    for word in text.split(' ') {
        if !line.is_empty() && line.chars().count() + 1 + word.chars().count() > width {
            lines.push(std::mem::take(&mut line));
        }
        if !line.is_empty() {
            line.push(' ');
        }
        line.push_str(word);
    }
    if !line.is_empty() || lines.is_empty() {
        lines.push(line);
    }
    lines
}

/// Everything one plot shows.
pub struct Plot<'a> {
    /// The case's name (first heading line).
    pub name: &'a str,
    /// What is simulated.
    pub title: &'a str,
    /// The reference.
    pub reference: &'a str,
    /// The y axis: the error and its unit.
    pub metric: &'a str,
    /// How the times were taken (the x axis).
    pub runs_note: &'a str,
    /// The points, every engine and setting.
    pub measurements: &'a [Measurement],
    /// The engines, in legend order.
    pub engines: &'a [Engine],
    /// The swept solver iteration counts: one family, and line, per engine
    /// and count (the first solid with filled dots, the others dashed with
    /// hollow ones).
    pub iterations: &'a [u32],
    /// Errors below this (zeros) are drawn here.
    pub floor: f64,
    /// NaN and errors above this are drawn here.
    pub ceiling: f64,
}

/// The SVG text of one case's plot.
pub fn svg(plot: &Plot) -> Result<String, String> {
    let mut out = String::new();
    draw(&mut out, plot).map_err(|e| e.to_string())?;
    Ok(out)
}

type DrawResult = Result<(), Box<dyn std::error::Error>>;

fn draw(out: &mut String, plot: &Plot) -> DrawResult {
    let Plot {
        measurements,
        engines,
        iterations,
        floor,
        ceiling,
        ..
    } = *plot;
    let text = plot;
    let root = SVGBackend::with_string(out, SIZE).into_drawing_area();
    root.fill(&WHITE)?;
    let (head, body) = root.split_vertically(HEAD_H);
    let (plot_area, legend) = body.split_horizontally(SIZE.0 - LEGEND_W);
    heading(&head, text)?;

    let (mut x0, mut x1) = (f64::INFINITY, 0.0f64);
    for m in measurements
        .iter()
        .filter(|m| m.ms.is_finite() && m.ms > 0.0)
    {
        x0 = x0.min(m.ms);
        x1 = x1.max(m.ms);
    }
    if !x0.is_finite() || x1 <= 0.0 {
        (x0, x1) = (0.1, 1.0);
    }
    // Whole decades (a hair wider, against rounding), so every axis has
    // labelled powers of ten: plotters labels a log axis from its first
    // power of ten on.
    let (x0, x1) = (
        10f64.powf((x0 / 1.2).log10().floor()) * 0.999,
        10f64.powf((x1 * 1.2).log10().ceil()) * 1.001,
    );
    let (y0, y1) = (floor / 1.5, ceiling * 1.5);
    let mut chart = ChartBuilder::on(&plot_area)
        .margin(12)
        .x_label_area_size(50)
        .y_label_area_size(80)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())?;
    chart
        .configure_mesh()
        .x_desc(format!("CPU ms per simulated second ({})", text.runs_note))
        .y_desc(text.metric)
        .x_labels(12)
        .y_labels(12)
        .x_label_formatter(&|v| tick_label(*v))
        .y_label_formatter(&|v| tick_label(*v))
        .label_style(("sans-serif", 13))
        .axis_desc_style(("sans-serif", 14))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()?;

    let mut entries: Vec<(Engine, usize, u32)> = Vec::new();
    for &engine in engines {
        let c = colour(engine);
        for (family, &iters) in iterations.iter().enumerate() {
            let ms: Vec<&Measurement> = measurements
                .iter()
                .filter(|m| m.engine == engine && m.settings.iterations == iters)
                .collect();
            if ms.is_empty() {
                continue;
            }
            entries.push((engine, family, iters));
            let pts: Vec<Point> = ms
                .iter()
                .filter(|m| m.on_frontier())
                .map(|m| {
                    let (time, error) = drawn(m, floor, ceiling);
                    Point { time, error }
                })
                .collect();
            let line: Vec<(f64, f64)> = frontier::frontier(&pts)
                .iter()
                .map(|p| (p.time, p.error))
                .collect();
            let style = c.stroke_width(2);
            if family == 0 {
                chart.draw_series(LineSeries::new(line, style))?;
            } else {
                chart.draw_series(DashedLineSeries::new(line, 8, 5, style))?;
            }
            let marks = ms.iter().filter(|m| m.failure.is_none()).map(|m| {
                let at = drawn(m, floor, ceiling);
                if family == 0 {
                    Circle::new(at, 3, c.filled())
                } else {
                    Circle::new(at, 4, c.stroke_width(1))
                }
            });
            chart.draw_series(marks)?;
            let failed = ms
                .iter()
                .filter(|m| m.failure.is_some())
                .map(|m| Cross::new(drawn(m, floor, ceiling), 6, c.stroke_width(2)));
            chart.draw_series(failed)?;
        }
    }
    legend_panel(&legend, &entries, floor, ceiling)?;
    root.present()?;
    Ok(())
}

/// The case name, what is simulated and the reference, centred and
/// wrapped.
fn heading<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    text: &Plot,
) -> DrawResult
where
    DB::ErrorType: 'static,
{
    let x_mid = SIZE.0 as i32 / 2;
    let centred = |size| {
        TextStyle::from(("sans-serif", size).into_font()).pos(Pos::new(HPos::Center, VPos::Top))
    };
    area.draw(&Text::new(text.name.to_owned(), (x_mid, 6), centred(19)))?;
    let mut lines = wrap(text.title, WRAP);
    lines.extend(wrap(&format!("reference: {}", text.reference), WRAP));
    // Three lines fit under the name; more are shrunk to fit.
    let size = if lines.len() <= 3 { 13 } else { 11 };
    let step = if lines.len() <= 3 { 15 } else { 12 };
    for (i, line) in lines.iter().enumerate() {
        area.draw(&Text::new(
            line.clone(),
            (x_mid, 30 + step * i as i32),
            centred(size),
        ))?;
    }
    Ok(())
}

/// The legend, beside the plot so it never hides a point.
fn legend_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    entries: &[(Engine, usize, u32)],
    floor: f64,
    ceiling: f64,
) -> DrawResult
where
    DB::ErrorType: 'static,
{
    let style =
        TextStyle::from(("sans-serif", 13).into_font()).pos(Pos::new(HPos::Left, VPos::Center));
    let (x, mut y) = (10, 30);
    for &(engine, family, iters) in entries {
        let c = colour(engine);
        if family == 0 {
            area.draw(&PathElement::new(
                vec![(x, y), (x + 28, y)],
                c.stroke_width(2),
            ))?;
            area.draw(&Circle::new((x + 14, y), 3, c.filled()))?;
        } else {
            area.draw(&PathElement::new(
                vec![(x, y), (x + 9, y)],
                c.stroke_width(2),
            ))?;
            area.draw(&PathElement::new(
                vec![(x + 19, y), (x + 28, y)],
                c.stroke_width(2),
            ))?;
            area.draw(&Circle::new((x + 14, y), 4, c.stroke_width(1)))?;
        }
        let label = format!(
            "{}, {} iteration{}",
            engine.name(),
            iters,
            if iters == 1 { "" } else { "s" }
        );
        area.draw(&Text::new(label, (x + 36, y), style.clone()))?;
        y += 22;
    }
    y += 8;
    let grey = RGBColor(90, 90, 90);
    area.draw(&Cross::new((x + 14, y), 6, grey.stroke_width(2)))?;
    area.draw(&Text::new(
        "unstable or wrong".to_owned(),
        (x + 36, y),
        style.clone(),
    ))?;
    y += 16;
    area.draw(&Text::new(
        "(CSV status column)".to_owned(),
        (x + 36, y),
        style.clone(),
    ))?;
    y += 30;
    let notes = [
        "lines: each family's frontier".to_owned(),
        format!("error 0 drawn at {}", tick_label(floor)),
        format!("NaN/∞ drawn at {}", tick_label(ceiling)),
    ];
    for note in notes {
        area.draw(&Text::new(note, (x, y), style.clone()))?;
        y += 18;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_labels_are_short() {
        assert_eq!(tick_label(1.0), "1");
        assert_eq!(tick_label(0.25), "0.25");
        assert_eq!(tick_label(200.0), "200");
        assert_eq!(tick_label(1e-5), "1e-5");
        assert_eq!(tick_label(3e6), "3e6");
    }

    #[test]
    fn headings_wrap_at_spaces() {
        assert_eq!(wrap("a bb ccc", 4), vec!["a bb", "ccc"]);
        assert_eq!(wrap("abcdef g", 3), vec!["abcdef", "g"]);
        assert_eq!(wrap("", 10), vec![""]);
    }
}
