//! The report's four plots as SVG markup, drawn with `plotters`' SVG backend.
//!
//! Promises: every plot renders, also from an empty report (it then says what is missing rather
//! than failing); each controller has the same colour in every plot and in the page's replay
//! ([`controller_colour`]); the y axis of every A_w plot spans the whole 0..1 so plots compare
//! at a glance. Text is SVG `<text>` with a generic font family, so no font files are needed.

use std::collections::BTreeSet;
use std::error::Error;
use std::io;

use plotters::coord::Shift;
use plotters::prelude::*;

use super::Report;
use crate::study::Row;

/// One plot: its file name in the report folder, a caption for the page, and the markup.
pub(super) struct Plot {
    pub file: &'static str,
    pub caption: String,
    pub svg: String,
}

type Area<'a> = DrawingArea<SVGBackend<'a>, Shift>;
type Drawn = Result<(), Box<dyn Error>>;
/// Draws one plot onto its canvas.
type Painter<'a> = &'a dyn Fn(&Area) -> Drawn;

const FONT: &str = "sans-serif";
/// Height of the title and colour key above a plot's panels.
const HEADER: u32 = 58;
const AXIS_GREY: RGBColor = RGBColor(90, 90, 90);
const KILL_RED: RGBColor = RGBColor(200, 30, 30);

/// The controllers named in the paper and its baselines get fixed colours (BLE, the subject,
/// a strong blue; Random, the floor, grey); others take the next free colour of a palette.
pub(super) fn controller_colour(name: &str, index: usize) -> RGBColor {
    match name {
        "BLE" => RGBColor(31, 95, 191),
        "Centralized" => RGBColor(123, 63, 160),
        "Planner" => RGBColor(176, 48, 96),
        "ForceField" => RGBColor(46, 139, 87),
        "Local" => RGBColor(224, 123, 0),
        "Random" => RGBColor(128, 128, 128),
        _ => {
            const OTHERS: [RGBColor; 5] = [
                RGBColor(192, 57, 43),
                RGBColor(23, 162, 184),
                RGBColor(142, 108, 47),
                RGBColor(214, 51, 132),
                RGBColor(40, 40, 40),
            ];
            OTHERS[index % OTHERS.len()]
        }
    }
}

pub(super) fn hex(c: RGBColor) -> String {
    format!("#{:02x}{:02x}{:02x}", c.0, c.1, c.2)
}

/// Every controller in the report, in first-seen order (coverage, paper, robustness, sweep), with
/// its colour.
pub(super) fn controllers(report: &Report) -> Vec<(String, RGBColor)> {
    let mut names: Vec<String> = Vec::new();
    let all_rows = report.paper.iter().chain(&report.robustness).chain(&report.sweep);
    for name in report.coverage.iter().map(|(n, _)| n).chain(all_rows.map(|r| &r.controller)) {
        if !names.contains(name) {
            names.push(name.clone());
        }
    }
    names.into_iter().enumerate().map(|(i, n)| (n.clone(), controller_colour(&n, i))).collect()
}

pub(super) fn render_all(report: &Report) -> io::Result<Vec<Plot>> {
    let colours = controllers(report);
    let colour = |name: &str| colours.iter().find(|(n, _)| n == name).map_or(BLACK, |(_, c)| *c);
    let loss_robots = sweep_loss_robots(report);
    let plots: [(&'static str, String, (u32, u32), Painter); 4] = [
        (
            "coverage.svg",
            match smoothing_window(report) {
                Some(w) => format!(
                    "Priority-weighted coverage A_w(t) in the replayed world, one line per controller (same \
                     seed), as a centred moving average over {w:.1} s (the raw signal steps with every target \
                     gained or lost); red lines: robot killed."
                ),
                None => "Priority-weighted coverage A_w(t) in the replayed world, one line per controller \
                         (same seed); red lines: robot killed."
                    .to_string(),
            },
            (900, 400),
            &|a| coverage(a, report, &colour),
        ),
        (
            "sweep_robots.svg",
            "A_w against team size at 0 % loss, one panel per target count; bars: ± 1 sd over seeds.".to_string(),
            (panels_width(&target_counts(&report.sweep)), 360),
            &|a| sweep_robots(a, report, &colour),
        ),
        (
            "sweep_loss.svg",
            format!(
                "A_w against radio loss with {} robots, one panel per target count; bars: ± 1 sd over seeds.",
                loss_robots.map_or("?".to_string(), |r| r.to_string())
            ),
            (panels_width(&target_counts(&report.sweep)), 360),
            &|a| sweep_loss(a, report, loss_robots, &colour),
        ),
        (
            "robustness.svg",
            "A robot killed halfway: A_w and the mean time to re-cover the targets it observed, \
             against radio loss."
                .to_string(),
            (900, 360),
            &|a| robustness(a, report, &colour),
        ),
    ];
    let mut out = Vec::new();
    for (file, caption, size, draw) in plots {
        let mut svg = String::new();
        {
            let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
            root.fill(&WHITE).map_err(io::Error::other)?;
            draw(&root).map_err(|e| io::Error::other(format!("{file}: {e}")))?;
            root.present().map_err(io::Error::other)?;
        }
        out.push(Plot { file, caption, svg });
    }
    Ok(out)
}

fn target_counts(rows: &[Row]) -> Vec<u32> {
    rows.iter().map(|r| r.targets).collect::<BTreeSet<_>>().into_iter().collect()
}

fn panels_width(targets: &[u32]) -> u32 {
    (targets.len().max(1) as u32 * 420).clamp(600, 1320)
}

/// The team size of the loss sweep: the paper's setting when the sweep has it, so the plot
/// extends the paper's table; else the largest team swept.
fn sweep_loss_robots(report: &Report) -> Option<u32> {
    let swept: BTreeSet<u32> = report.sweep.iter().map(|r| r.robots).collect();
    report.paper.first().map(|r| r.robots).filter(|r| swept.contains(r)).or_else(|| swept.last().copied())
}

/// A strip across the top of a plot: a title, and under it the controllers' colour key. One
/// key per figure, because panels share their controllers.
fn header(area: &Area, title: &str, names: &[String], colour: &dyn Fn(&str) -> RGBColor) -> Drawn {
    area.draw(&Text::new(title.to_string(), (12, 8), (FONT, 17).into_font().style(FontStyle::Bold)))?;
    let mut x = 14;
    for name in names {
        let c = colour(name);
        area.draw(&PathElement::new(vec![(x, 42), (x + 22, 42)], c.stroke_width(3)))?;
        area.draw(&Circle::new((x + 11, 42), 3, c.filled()))?;
        area.draw(&Text::new(name.clone(), (x + 28, 35), (FONT, 14)))?;
        x += 44 + 7 * name.len() as i32;
    }
    Ok(())
}

fn note(area: &Area, text: &str) -> Drawn {
    let (w, h) = area.dim_in_pixel();
    area.draw(&Text::new(
        text.to_string(),
        (w as i32 / 2 - 4 * text.len() as i32, h as i32 / 2),
        (FONT, 15).into_font().color(&AXIS_GREY),
    ))?;
    Ok(())
}

fn coverage(root: &Area, report: &Report, colour: &dyn Fn(&str) -> RGBColor) -> Drawn {
    let names: Vec<String> = report.coverage.iter().map(|(n, _)| n.clone()).collect();
    let (top, body) = root.split_vertically(HEADER);
    header(&top, "Coverage over time", &names, colour)?;
    let series: Vec<_> = report.coverage.iter().filter(|(_, s)| !s.t.is_empty()).collect();
    if series.is_empty() {
        return note(&body, "no coverage series in this report");
    }
    let t_end = series.iter().filter_map(|(_, s)| s.t.last().copied()).fold(report.duration, f64::max).max(1e-9);
    let mut chart = ChartBuilder::on(&body)
        .margin_left(10)
        .margin_right(24)
        .margin_bottom(6)
        .x_label_area_size(40)
        .y_label_area_size(56)
        .build_cartesian_2d(0.0..t_end, 0.0..1.0)?;
    chart
        .configure_mesh()
        .x_desc("time (s)")
        .y_desc("A_w (weighted fraction observed)")
        .bold_line_style(BLACK.mix(0.12))
        .light_line_style(BLACK.mix(0.04))
        .axis_style(AXIS_GREY)
        .label_style((FONT, 13))
        .axis_desc_style((FONT, 14))
        .x_label_formatter(&|v| format!("{v:.0}"))
        .y_label_formatter(&|v| format!("{v:.1}"))
        .draw()?;
    // The coverage series come from the first replay's world; its events are theirs.
    for event in report.replays.first().map_or(&[][..], |r| &r.events[..]) {
        chart.draw_series(std::iter::once(PathElement::new(
            vec![(event.t, 0.0), (event.t, 1.0)],
            KILL_RED.mix(0.8).stroke_width(2),
        )))?;
        chart.draw_series(std::iter::once(Text::new(
            format!("R{} {}", event.robot, if event.kind == "kill" { "killed" } else { &event.kind }),
            (event.t, 0.99),
            (FONT, 13).into_font().color(&KILL_RED),
        )))?;
    }
    let window = smoothing_window(report);
    for (name, s) in &series {
        let c = colour(name);
        let points = match window {
            Some(w) => moving_average(&s.t, &s.weighted, w),
            None => s.t.iter().copied().zip(s.weighted.iter().copied()).collect(),
        };
        chart.draw_series(LineSeries::new(points, c.mix(0.9).stroke_width(2)))?;
    }
    Ok(())
}

/// The coverage plot's smoothing window (s), or None to plot the raw samples. Instantaneous A_w
/// jumps by a target's share at every gain or loss; over a long run five such lines overlap
/// into an unreadable band, so they are averaged over a fiftieth of the run. Short runs (a
/// window of at most 2 samples) are left raw.
fn smoothing_window(report: &Report) -> Option<f64> {
    let s = report.coverage.iter().map(|(_, s)| s).find(|s| s.t.len() >= 2)?;
    let dt = (s.t[s.t.len() - 1] - s.t[0]) / (s.t.len() - 1) as f64;
    let window = (s.t[s.t.len() - 1] - s.t[0]) / 50.0;
    (dt > 0.0 && window > 2.0 * dt).then_some(window)
}

/// Centred moving average over `window` seconds of samples at regular times `t`.
pub(super) fn moving_average(t: &[f64], y: &[f64], window: f64) -> Vec<(f64, f64)> {
    let n = t.len().min(y.len());
    if n < 2 {
        return t.iter().copied().zip(y.iter().copied()).collect();
    }
    let dt = (t[n - 1] - t[0]) / (n - 1) as f64;
    let half = ((window / dt / 2.0).round() as usize).max(1);
    let mut prefix = vec![0.0; n + 1];
    for i in 0..n {
        prefix[i + 1] = prefix[i] + y[i];
    }
    (0..n)
        .map(|i| {
            let (lo, hi) = (i.saturating_sub(half), (i + half + 1).min(n));
            (t[i], (prefix[hi] - prefix[lo]) / (hi - lo) as f64)
        })
        .collect()
}

/// A mean with its spread, drawn as a marker on a line and a vertical ± sd bar.
struct Point {
    x: f64,
    mean: f64,
    sd: f64,
}

/// Panels side by side, one per target count, each with one line per controller.
#[allow(clippy::too_many_arguments)]
fn panels(
    body: &Area,
    rows_of: &dyn Fn(u32, &str) -> Vec<Point>,
    targets: &[u32],
    names: &[String],
    x_range: (f64, f64),
    x_desc: &str,
    x_fmt: &dyn Fn(&f64) -> String,
    colour: &dyn Fn(&str) -> RGBColor,
) -> Drawn {
    let areas = body.split_evenly((1, targets.len()));
    let pad = ((x_range.1 - x_range.0) * 0.06).max(0.5);
    for (area, &m) in areas.iter().zip(targets) {
        let mut chart = ChartBuilder::on(area)
            .caption(format!("{m} targets"), (FONT, 15))
            .margin_left(6)
            .margin_right(16)
            .margin_bottom(6)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d((x_range.0 - pad)..(x_range.1 + pad), 0.0..1.0)?;
        chart
            .configure_mesh()
            .x_desc(x_desc)
            .y_desc("A_w")
            .bold_line_style(BLACK.mix(0.12))
            .light_line_style(TRANSPARENT)
            .axis_style(AXIS_GREY)
            .label_style((FONT, 13))
            .axis_desc_style((FONT, 14))
            .x_label_formatter(x_fmt)
            .y_label_formatter(&|v| format!("{v:.1}"))
            .draw()?;
        for name in names {
            let c = colour(name);
            let points = rows_of(m, name);
            if points.is_empty() {
                continue;
            }
            for p in &points {
                let lo = (p.mean - p.sd).max(0.0);
                let hi = (p.mean + p.sd).min(1.0);
                chart.draw_series(std::iter::once(PathElement::new(vec![(p.x, lo), (p.x, hi)], c.mix(0.5))))?;
            }
            let line: Vec<(f64, f64)> = points.iter().map(|p| (p.x, p.mean)).collect();
            chart.draw_series(LineSeries::new(line.clone(), c.stroke_width(2)))?;
            chart.draw_series(line.into_iter().map(|xy| Circle::new(xy, 3, c.filled())))?;
        }
    }
    Ok(())
}

fn names_of(rows: &[&Row]) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    for r in rows {
        if !names.contains(&r.controller) {
            names.push(r.controller.clone());
        }
    }
    names
}

fn sweep_robots(root: &Area, report: &Report, colour: &dyn Fn(&str) -> RGBColor) -> Drawn {
    let rows: Vec<&Row> = report.sweep.iter().filter(|r| r.loss == 0.0 && !r.kill).collect();
    let names = names_of(&rows);
    let (top, body) = root.split_vertically(HEADER);
    header(&top, "Sweep: A_w against team size (0 % loss)", &names, colour)?;
    if rows.is_empty() {
        return note(&body, "no sweep runs at 0 % loss");
    }
    let targets = target_counts(&report.sweep);
    let lo = rows.iter().map(|r| r.robots).min().unwrap_or(1) as f64;
    let hi = rows.iter().map(|r| r.robots).max().unwrap_or(1) as f64;
    let points = |m: u32, name: &str| {
        let mut p: Vec<Point> = rows
            .iter()
            .filter(|r| r.targets == m && r.controller == name)
            .map(|r| Point { x: r.robots as f64, mean: r.metrics.a_w, sd: r.a_w_sd })
            .collect();
        p.sort_by(|a, b| a.x.total_cmp(&b.x));
        p
    };
    // Team sizes are whole: only label whole numbers.
    let fmt = |v: &f64| if (v - v.round()).abs() < 1e-6 { format!("{v:.0}") } else { String::new() };
    panels(&body, &points, &targets, &names, (lo, hi), "robots", &fmt, colour)
}

fn sweep_loss(root: &Area, report: &Report, robots: Option<u32>, colour: &dyn Fn(&str) -> RGBColor) -> Drawn {
    let rows: Vec<&Row> = report.sweep.iter().filter(|r| Some(r.robots) == robots && !r.kill).collect();
    let names = names_of(&rows);
    let (top, body) = root.split_vertically(HEADER);
    let title = match robots {
        Some(n) => format!("Sweep: A_w against radio loss ({n} robots)"),
        None => "Sweep: A_w against radio loss".to_string(),
    };
    header(&top, &title, &names, colour)?;
    if rows.is_empty() {
        return note(&body, "no sweep runs");
    }
    let targets = target_counts(&report.sweep);
    let hi = rows.iter().map(|r| r.loss * 100.0).fold(0.0, f64::max).max(1.0);
    let points = |m: u32, name: &str| {
        let mut p: Vec<Point> = rows
            .iter()
            .filter(|r| r.targets == m && r.controller == name)
            .map(|r| Point { x: r.loss * 100.0, mean: r.metrics.a_w, sd: r.a_w_sd })
            .collect();
        p.sort_by(|a, b| a.x.total_cmp(&b.x));
        p
    };
    let fmt = |v: &f64| if *v < -1e-9 { String::new() } else { format!("{v:.0}%") };
    panels(&body, &points, &targets, &names, (0.0, hi), "radio loss", &fmt, colour)
}

fn robustness(root: &Area, report: &Report, colour: &dyn Fn(&str) -> RGBColor) -> Drawn {
    let rows: Vec<&Row> = report.robustness.iter().collect();
    let names = names_of(&rows);
    let (top, body) = root.split_vertically(HEADER);
    header(&top, "Robustness: one robot killed halfway", &names, colour)?;
    if rows.is_empty() {
        return note(&body, "no robustness runs");
    }
    let areas = body.split_evenly((1, 2));
    let hi_loss = rows.iter().map(|r| r.loss * 100.0).fold(0.0, f64::max).max(1.0);
    let pad = hi_loss * 0.06;
    let max_recover = rows.iter().filter_map(|r| r.metrics.recover_s).fold(0.0, f64::max);
    let recover_top = if max_recover > 0.0 { max_recover * 1.15 } else { 1.0 };
    type Pick = fn(&Row) -> Option<f64>;
    let panels: [(&str, &str, f64, Pick); 2] = [
        ("coverage", "A_w", 1.0, |r| Some(r.metrics.a_w)),
        ("re-cover time", "recover (s)", recover_top, |r| r.metrics.recover_s),
    ];
    for (area, (caption, y_desc, y_top, pick)) in areas.iter().zip(panels) {
        let mut chart = ChartBuilder::on(area)
            .caption(caption, (FONT, 15))
            .margin_left(6)
            .margin_right(16)
            .margin_bottom(6)
            .x_label_area_size(40)
            .y_label_area_size(54)
            .build_cartesian_2d(-pad..(hi_loss + pad), 0.0..y_top)?;
        chart
            .configure_mesh()
            .x_desc("radio loss")
            .y_desc(y_desc)
            .bold_line_style(BLACK.mix(0.12))
            .light_line_style(TRANSPARENT)
            .axis_style(AXIS_GREY)
            .label_style((FONT, 13))
            .axis_desc_style((FONT, 14))
            .x_label_formatter(&|v| if *v < -1e-9 { String::new() } else { format!("{v:.0}%") })
            .draw()?;
        for name in &names {
            let c = colour(name);
            let mut line: Vec<(f64, f64)> = rows
                .iter()
                .filter(|r| &r.controller == name)
                .filter_map(|r| pick(r).map(|y| (r.loss * 100.0, y)))
                .collect();
            line.sort_by(|a, b| a.0.total_cmp(&b.0));
            chart.draw_series(LineSeries::new(line.clone(), c.stroke_width(2)))?;
            chart.draw_series(line.into_iter().map(|xy| Circle::new(xy, 3, c.filled())))?;
        }
    }
    Ok(())
}
