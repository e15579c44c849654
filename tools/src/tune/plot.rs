//! The scene's work-precision plot, as SVG: x = CPU ms per simulated second,
//! y = trajectory error against the reference, both log scales; one point
//! per combination tried, the bound dashed, the choice and the scene's own
//! settings ringed. plotters' SVG backend only: labels are SVG `<text>`, so
//! no font files or system libraries are needed.

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::report::fmt_len;
use super::{Trial, TuneReport};

/// The plot size, px.
const SIZE: (u32, u32) = (1100, 640);
/// The legend panel's width at the right, px.
const LEGEND_W: u32 = 230;
/// The heading's height, px.
const HEAD_H: u32 = 62;

/// One colour per substep count, in ascending order of the counts.
const COLOURS: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(230, 120, 10),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(23, 190, 207),
];

type DrawResult = Result<(), Box<dyn std::error::Error>>;

/// The SVG text of a report's plot.
///
/// # Errors
/// plotters' drawing error, as text.
pub fn svg(r: &TuneReport) -> Result<String, String> {
    let mut out = String::new();
    draw(&mut out, r).map_err(|e| e.to_string())?;
    Ok(out)
}

/// A tick label for a log axis: plain decimals in a readable range,
/// scientific outside it.
fn tick_label(v: f64) -> String {
    let a = v.abs();
    if (1e-3..1e4).contains(&a) {
        let s = format!("{v:.3}");
        s.trim_end_matches('0').trim_end_matches('.').to_owned()
    } else {
        format!("{v:.0e}")
    }
}

/// The (floor, ceiling) of the error axis, m: zeros are drawn at the floor,
/// faulted runs at the ceiling.
fn error_range(r: &TuneReport) -> (f64, f64) {
    let errors = r
        .trials
        .iter()
        .filter_map(|t| t.deviation.map(|d| d.error))
        .filter(|&e| e > 0.0);
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for e in errors {
        lo = lo.min(e);
        hi = hi.max(e);
    }
    let bound = if r.max_error > 0.0 { r.max_error } else { 1e-6 };
    lo = lo.min(bound);
    hi = hi.max(bound);
    (
        10f64.powf((lo / 10.0).log10().floor()),
        10f64.powf((hi * 10.0).log10().ceil()),
    )
}

fn draw(out: &mut String, r: &TuneReport) -> DrawResult {
    let root = SVGBackend::with_string(out, SIZE).into_drawing_area();
    root.fill(&WHITE)?;
    let (head, body) = root.split_vertically(HEAD_H);
    let (plot_area, legend) = body.split_horizontally(SIZE.0 - LEGEND_W);
    heading(&head, r)?;

    let (floor, ceiling) = error_range(r);
    let at = |t: &Trial| {
        let y = match t.deviation {
            Some(d) => d.error.clamp(floor, ceiling),
            None => ceiling,
        };
        (t.cpu_ms_per_s.max(1e-6), y)
    };
    let (mut x0, mut x1) = (f64::INFINITY, 0.0f64);
    for t in &r.trials {
        let x = at(t).0;
        x0 = x0.min(x);
        x1 = x1.max(x);
    }
    if !x0.is_finite() {
        (x0, x1) = (0.1, 1.0);
    }
    let (x0, x1) = (
        10f64.powf((x0 / 1.2).log10().floor()) * 0.999,
        10f64.powf((x1 * 1.2).log10().ceil()) * 1.001,
    );
    let mut chart = ChartBuilder::on(&plot_area)
        .margin(12)
        .x_label_area_size(50)
        .y_label_area_size(80)
        .build_cartesian_2d((x0..x1).log_scale(), (floor..ceiling).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("CPU ms per simulated second (log)")
        .y_desc("trajectory error against the reference, m (log)")
        .x_labels(12)
        .y_labels(12)
        .x_label_formatter(&|v| tick_label(*v))
        .y_label_formatter(&|v| tick_label(*v))
        .label_style(("sans-serif", 13))
        .axis_desc_style(("sans-serif", 14))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()?;

    // The bound.
    if r.max_error > 0.0 {
        chart.draw_series(DashedLineSeries::new(
            [(x0, r.max_error), (x1, r.max_error)],
            8,
            5,
            BLACK.stroke_width(1),
        ))?;
    }

    let mut substeps: Vec<u32> = r.trials.iter().map(|t| t.settings.substeps).collect();
    substeps.sort_unstable();
    substeps.dedup();
    let colour = |n: u32| {
        let i = substeps.iter().position(|&s| s == n).unwrap_or(0);
        COLOURS[i % COLOURS.len()]
    };
    let mut solves: Vec<u32> = r
        .trials
        .iter()
        .map(|t| t.settings.solver_iterations)
        .collect();
    solves.sort_unstable();
    solves.dedup();
    let min_relax = r
        .trials
        .iter()
        .map(|t| t.settings.relax_iterations)
        .min()
        .unwrap_or(1);

    // A thin line through each family (same substeps and iterations) in
    // tick-rate order.
    let mut families: Vec<(u32, u32, u32)> = r
        .trials
        .iter()
        .map(|t| {
            let s = t.settings;
            (s.substeps, s.solver_iterations, s.relax_iterations)
        })
        .collect();
    families.sort_unstable();
    families.dedup();
    for &(sub, solve, relax) in &families {
        let mut pts: Vec<&Trial> = r
            .trials
            .iter()
            .filter(|t| {
                let s = t.settings;
                (s.substeps, s.solver_iterations, s.relax_iterations) == (sub, solve, relax)
                    && t.deviation.is_some()
            })
            .collect();
        pts.sort_by_key(|t| t.settings.tick_rate);
        chart.draw_series(LineSeries::new(
            pts.iter().map(|t| at(t)),
            colour(sub).mix(0.35).stroke_width(1),
        ))?;
    }

    for t in &r.trials {
        let s = t.settings;
        let c = colour(s.substeps);
        let p = at(t);
        if t.deviation.is_none() {
            chart.draw_series([Cross::new(p, 6, RED.stroke_width(2))])?;
            continue;
        }
        let shape = solves
            .iter()
            .position(|&n| n == s.solver_iterations)
            .unwrap_or(0);
        let style = if s.relax_iterations == min_relax {
            c.filled()
        } else {
            c.stroke_width(1)
        };
        match shape % 3 {
            0 => chart.draw_series([Circle::new(p, 4, style)])?,
            1 => chart.draw_series([TriangleMarker::new(p, 5, style)])?,
            _ => chart
                .draw_series([EmptyElement::at(p) + Rectangle::new([(-4, -4), (4, 4)], style)])?,
        };
    }

    let own = r.own_trial();
    let grey = RGBColor(90, 90, 90);
    chart.draw_series([EmptyElement::at(at(own))
        + Circle::new((0, 0), 11, grey.stroke_width(2))
        + Text::new(
            "scene's own".to_owned(),
            (14, 8),
            TextStyle::from(("sans-serif", 13).into_font()).color(&grey),
        )])?;
    if let Some(t) = r.chosen() {
        let s = t.settings;
        let label = format!(
            "chosen: {} Hz × {}, {}+{}",
            s.tick_rate, s.substeps, s.solver_iterations, s.relax_iterations
        );
        chart.draw_series([EmptyElement::at(at(t))
            + Circle::new((0, 0), 11, BLACK.stroke_width(2))
            + Text::new(
                label,
                (14, -16),
                TextStyle::from(("sans-serif", 13).into_font()).color(&BLACK),
            )])?;
    }

    legend_panel(&legend, r, &substeps, &solves, min_relax, floor, ceiling)?;
    root.present()?;
    Ok(())
}

/// The scene, the reference, the metric and the bound, centred.
fn heading<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    r: &TuneReport,
) -> DrawResult
where
    DB::ErrorType: 'static,
{
    let x_mid = SIZE.0 as i32 / 2;
    let centred = |size| {
        TextStyle::from(("sans-serif", size).into_font()).pos(Pos::new(HPos::Center, VPos::Top))
    };
    area.draw(&Text::new(
        format!("lockstep tune: {} (work-precision)", r.scene),
        (x_mid, 6),
        centred(18),
    ))?;
    area.draw(&Text::new(
        format!(
            "reference {}; {} s, compared every 1/{} s; {} dynamic bod{}",
            r.reference,
            r.plan.seconds(),
            r.plan.sample_hz,
            r.dynamic_bodies,
            if r.dynamic_bodies == 1 { "y" } else { "ies" }
        ),
        (x_mid, 30),
        centred(13),
    ))?;
    area.draw(&Text::new(
        format!(
            "error: largest distance of a body point from its reference position; dashed: the \
             bound, {}",
            fmt_len(r.max_error)
        ),
        (x_mid, 45),
        centred(13),
    ))?;
    Ok(())
}

/// The legend, beside the plot so it never hides a point.
fn legend_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    r: &TuneReport,
    substeps: &[u32],
    solves: &[u32],
    min_relax: u32,
    floor: f64,
    ceiling: f64,
) -> DrawResult
where
    DB::ErrorType: 'static,
{
    let style =
        TextStyle::from(("sans-serif", 13).into_font()).pos(Pos::new(HPos::Left, VPos::Center));
    let (x, mut y) = (10, 30);
    let grey = RGBColor(90, 90, 90);
    area.draw(&Text::new(
        "colour: substeps".to_owned(),
        (x, y),
        style.clone(),
    ))?;
    y += 20;
    for (i, &n) in substeps.iter().enumerate() {
        let c = COLOURS[i % COLOURS.len()];
        area.draw(&Circle::new((x + 14, y), 4, c.filled()))?;
        area.draw(&Text::new(
            format!("{n} substeps"),
            (x + 30, y),
            style.clone(),
        ))?;
        y += 18;
    }
    y += 12;
    area.draw(&Text::new(
        "shape: solve iterations".to_owned(),
        (x, y),
        style.clone(),
    ))?;
    y += 20;
    for (i, &n) in solves.iter().enumerate() {
        let p = (x + 14, y);
        match i % 3 {
            0 => area.draw(&Circle::new(p, 4, grey.filled()))?,
            1 => area.draw(&TriangleMarker::new(p, 5, grey.filled()))?,
            _ => area.draw(&Rectangle::new(
                [(p.0 - 4, p.1 - 4), (p.0 + 4, p.1 + 4)],
                grey.filled(),
            ))?,
        }
        area.draw(&Text::new(format!("{n} solve"), (x + 30, y), style.clone()))?;
        y += 18;
    }
    y += 12;
    area.draw(&Text::new(
        format!("filled: {min_relax} relax; hollow: more"),
        (x, y),
        style.clone(),
    ))?;
    y += 22;
    area.draw(&Cross::new((x + 14, y), 6, RED.stroke_width(2)))?;
    area.draw(&Text::new(
        "arithmetic fault (fails)".to_owned(),
        (x + 30, y),
        style.clone(),
    ))?;
    y += 26;
    let notes = [
        "lines: one family (substeps and".to_owned(),
        "  iterations) over tick rates".to_owned(),
        format!("error 0 drawn at {}", tick_label(floor)),
        format!("faults drawn at {}", tick_label(ceiling)),
        "x: minimum of the timed runs".to_owned(),
        format!("cost basis: {:?}", r.cost),
    ];
    for note in notes {
        area.draw(&Text::new(note, (x, y), style.clone()))?;
        y += 18;
    }
    Ok(())
}
