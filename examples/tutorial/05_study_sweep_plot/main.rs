//! Tutorial 5, a study with a sweep and a plot (docs/tutorials/05-study-sweep-plot.md): weighted
//! coverage against radio loss for BLE and Random, three seeds per point, run on two threads
//! (`study::run_all` gives the outcomes of a serial run, in order), drawn as an SVG with
//! plotters.
//!
//! Run: `cargo run --release -p ayllu-sim --example tutorial_05_study_sweep_plot [-- PLOT.svg]`;
//! exits non-zero if what the tutorial says does not happen.

use std::fmt::Write as _;

use ayllu_sim::controller::Controller;
use ayllu_sim::scenario::Scenario;
use ayllu_sim::study::{mean_sd, run_all};
use plotters::prelude::*;

const LOSSES: [f64; 4] = [0.0, 0.3, 0.6, 0.9];
const SEEDS: [u64; 3] = [1, 2, 3];

/// The tutorial's program: writes the plot to `plot` and returns what it prints.
pub fn run_tutorial(plot: &std::path::Path) -> Result<String, Box<dyn std::error::Error>> {
    let mut out = String::new();
    let mut lines = Vec::new();
    for controller in [Controller::Ble, Controller::Random] {
        // The grid: every loss x every seed, 60 s each.
        let grid: Vec<Scenario> = LOSSES
            .iter()
            .flat_map(|&loss| SEEDS.map(|seed| Scenario::paper(controller, seed).duration(60.0).loss(loss)))
            .collect();
        let a_w = run_all(&grid, 2, &|| {}, &|outcome| outcome.metrics.a_w)?;
        let means: Vec<(f64, f64)> = LOSSES
            .iter()
            .zip(a_w.chunks(SEEDS.len()))
            .map(|(&loss, runs)| (loss, mean_sd(runs.iter().copied()).0))
            .collect();
        for (loss, m) in &means {
            writeln!(out, "{:<6} loss {:.1}: A_w {m:.3}", controller.name(), loss)?;
        }
        lines.push((controller.name(), means));
    }

    let root = SVGBackend::new(plot, (560, 360)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(-0.05..0.95, 0.0..1.0)?;
    chart.configure_mesh().x_desc("radio loss").y_desc("A_w (weighted coverage)").draw()?;
    for ((name, points), colour) in lines.iter().zip([BLUE, RED]) {
        chart
            .draw_series(LineSeries::new(points.clone(), colour.stroke_width(2)))?
            .label(*name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
        chart.draw_series(points.iter().map(|&p| Circle::new(p, 3, colour.filled())))?;
    }
    chart.configure_series_labels().background_style(WHITE).border_style(BLACK).draw()?;
    root.present()?;
    writeln!(out, "plot: {}", plot.display())?;

    let (ble, random) = (&lines[0].1, &lines[1].1);
    for i in 0..LOSSES.len() {
        assert!(ble[i].1 > random[i].1, "BLE beats wandering at every loss: {ble:?} {random:?}");
    }
    Ok(out)
}

#[allow(dead_code)] // the tests call `run_tutorial`
fn main() {
    let plot = std::env::args().nth(1).unwrap_or_else(|| "coverage_vs_loss.svg".into());
    match run_tutorial(std::path::Path::new(&plot)) {
        Ok(out) => print!("{out}"),
        Err(e) => {
            eprintln!("tutorial 5 failed: {e}");
            std::process::exit(1);
        }
    }
}
