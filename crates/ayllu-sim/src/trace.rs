//! Per-tick traces of a run, for analysis elsewhere (`ayllu sim run --trace FILE`, `ayllu sim
//! sweep --traces DIR`): the world and the team at every tick, as CSV or JSON lines.
//!
//! One record per tick (every `dt`, 50 ms by default), after the world has moved and the
//! metrics have counted the tick. Columns (docs/cmommt.md, "Per-tick traces"):
//! * `t` — virtual seconds since the start;
//! * `observed` — targets observed by at least one live robot; `weighted` — the
//!   priority-weighted fraction observed (0..1; its time average is A_w);
//! * `messages` — radio emissions so far, all robots together (as `msgs_per_robot_s` counts);
//! * per robot k (1..=N): `rK_x`, `rK_y` (m), `rK_theta` (rad, counter-clockwise from +x),
//!   `rK_alive` (1/0), `rK_drive` (the target driving it, 0 none);
//! * per target n (1..=M, decreasing priority): `tN_x`, `tN_y` (m), `tN_observers` (live robots
//!   observing it).
//!
//! JSON lines carry the same as `{"t", "observed", "weighted", "messages", "robots": [{"x", "y",
//! "theta", "alive", "drive"}], "targets": [{"x", "y", "observers"}]}`. Numbers are written in
//! full (shortest round trip), so a trace recomputes the run's A_w exactly up to summation order.
//!
//! Promise: tracing reads the run and changes nothing in it (the same outcome, trace hash
//! included, as [`crate::scenario::run`]).

use std::io::{self, Write};

use ayllu_core::Error;
use serde::Serialize;

use crate::scenario::{Outcome, Scenario, Sim, SimError};

/// How a trace is written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TraceFormat {
    /// A header line, then one comma-separated line per tick.
    Csv,
    /// One JSON object per line and tick.
    JsonLines,
}

impl TraceFormat {
    /// The format a file name asks for: `.jsonl` / `.json` / `.ndjson` JSON lines, else CSV.
    pub fn for_path(path: &std::path::Path) -> TraceFormat {
        match path.extension().and_then(|e| e.to_str()) {
            Some("jsonl" | "json" | "ndjson") => TraceFormat::JsonLines,
            _ => TraceFormat::Csv,
        }
    }
}

/// A robot at one tick.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RobotTick {
    /// Position (m).
    pub x: f64,
    /// Position (m).
    pub y: f64,
    /// Heading (rad, counter-clockwise from +x).
    pub theta: f64,
    /// 1 while alive, 0 once killed.
    pub alive: u8,
    /// The target driving it (0: none).
    pub drive: u32,
}

/// A target at one tick.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TargetTick {
    /// Position (m).
    pub x: f64,
    /// Position (m).
    pub y: f64,
    /// Live robots observing it (in view, within the observe range).
    pub observers: u32,
}

/// One tick of a trace (module docs).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Tick {
    /// Virtual seconds since the start.
    pub t: f64,
    /// Targets observed by at least one live robot.
    pub observed: u32,
    /// Priority-weighted fraction observed (0..1).
    pub weighted: f64,
    /// Radio emissions so far, all robots together.
    pub messages: u64,
    /// Robots by node id - 1.
    pub robots: Vec<RobotTick>,
    /// Targets by id - 1 (decreasing priority).
    pub targets: Vec<TargetTick>,
}

impl Tick {
    /// The state of `sim` after its last step.
    pub fn of(sim: &Sim) -> Tick {
        let world = sim.world();
        let (observed, weighted) = sim.coverage_now();
        let mut observers = vec![0u32; world.targets.len()];
        for (i, r) in world.robots.iter().enumerate() {
            if r.alive {
                world.in_view(i, world.config.observe_range, |j, _, _| observers[j] += 1);
            }
        }
        Tick {
            t: sim.now().as_secs_f64(),
            observed,
            weighted,
            messages: sim.messages_sent(),
            robots: world
                .robots
                .iter()
                .enumerate()
                .map(|(i, r)| RobotTick {
                    x: r.pose.x,
                    y: r.pose.y,
                    theta: r.pose.theta,
                    alive: u8::from(r.alive),
                    drive: if r.alive { sim.drive(i) } else { 0 },
                })
                .collect(),
            targets: world
                .targets
                .iter()
                .zip(observers)
                .map(|(t, observers)| TargetTick { x: t.x, y: t.y, observers })
                .collect(),
        }
    }
}

/// The CSV header for `robots` robots and `targets` targets (module docs).
pub fn csv_header(robots: usize, targets: usize) -> String {
    let mut h = String::from("t,observed,weighted,messages");
    for k in 1..=robots {
        for c in ["x", "y", "theta", "alive", "drive"] {
            h.push_str(&format!(",r{k}_{c}"));
        }
    }
    for n in 1..=targets {
        for c in ["x", "y", "observers"] {
            h.push_str(&format!(",t{n}_{c}"));
        }
    }
    h
}

/// One tick as a CSV line (no newline), in [`csv_header`]'s order.
pub fn csv_line(tick: &Tick) -> String {
    let mut l = format!("{},{},{},{}", tick.t, tick.observed, tick.weighted, tick.messages);
    for r in &tick.robots {
        l.push_str(&format!(",{},{},{},{},{}", r.x, r.y, r.theta, r.alive, r.drive));
    }
    for t in &tick.targets {
        l.push_str(&format!(",{},{},{}", t.x, t.y, t.observers));
    }
    l
}

/// Run `scenario` to its end, writing its trace to `out` in `format` (module docs).
pub fn run_traced(scenario: &Scenario, format: TraceFormat, out: &mut dyn Write) -> Result<Outcome, TraceError> {
    run_traced_on(scenario, 1, format, out)
}

/// [`run_traced`] with up to `threads` threads visiting the robots
/// ([`crate::scenario::Sim::set_threads`]): the same outcome and trace, sooner for a large team.
pub fn run_traced_on(
    scenario: &Scenario,
    threads: usize,
    format: TraceFormat,
    out: &mut dyn Write,
) -> Result<Outcome, TraceError> {
    let mut sim = Sim::new(scenario)?;
    // The outcome does not depend on the threads: a refused one only costs time.
    let _ = sim.set_threads(threads);
    if format == TraceFormat::Csv {
        writeln!(out, "{}", csv_header(scenario.robots, scenario.world.targets.len()))?;
    }
    while !sim.done() {
        sim.step()?;
        let tick = Tick::of(&sim);
        match format {
            TraceFormat::Csv => writeln!(out, "{}", csv_line(&tick))?,
            TraceFormat::JsonLines => {
                serde_json::to_writer(&mut *out, &tick).map_err(io::Error::other)?;
                out.write_all(b"\n")?;
            }
        }
    }
    out.flush()?;
    Ok(sim.finish())
}

/// Why a traced run failed: the run itself, or writing its trace.
#[derive(Debug)]
pub enum TraceError {
    /// The simulation failed (a scenario out of bounds, a controller that could not be
    /// built, ...).
    Run(SimError),
    /// The trace could not be written.
    Io(io::Error),
}

impl From<Error> for TraceError {
    fn from(e: Error) -> Self {
        TraceError::Run(SimError::Node(e))
    }
}

impl From<SimError> for TraceError {
    fn from(e: SimError) -> Self {
        TraceError::Run(e)
    }
}

impl From<io::Error> for TraceError {
    fn from(e: io::Error) -> Self {
        TraceError::Io(e)
    }
}

impl std::fmt::Display for TraceError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            TraceError::Run(e) => write!(f, "the run failed: {e}"),
            TraceError::Io(e) => write!(f, "writing the trace: {e}"),
        }
    }
}

impl std::error::Error for TraceError {}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::controller::Controller;
    use crate::scenario::{run, Kill};

    #[test]
    fn a_trace_changes_nothing_and_recomputes_a_w() {
        let mut s = Scenario::paper(Controller::Ble, 2).duration(12.0);
        s.kills.push(Kill { at: 6.0, robot: Some(1) });
        let plain = run(&s).unwrap();
        let mut csv = Vec::new();
        let traced = run_traced(&s, TraceFormat::Csv, &mut csv).unwrap();
        assert_eq!(traced.trace_hash, plain.trace_hash);
        assert_eq!(traced.metrics, plain.metrics);
        let text = String::from_utf8(csv).unwrap();
        let mut lines = text.lines();
        let header: Vec<&str> = lines.next().unwrap().split(',').collect();
        assert_eq!(header.len(), 4 + 3 * 5 + 4 * 3);
        let rows: Vec<Vec<f64>> = lines.map(|l| l.split(',').map(|c| c.parse().unwrap()).collect()).collect();
        assert_eq!(rows.len(), 240, "12 s of 50 ms ticks");
        let a_w = rows.iter().map(|r| r[2] * s.dt).sum::<f64>() / 12.0;
        assert!((a_w - plain.metrics.a_w).abs() < 1e-9, "{a_w} vs {}", plain.metrics.a_w);
        // Robot 1 dies at 6 s: alive column 0 from then on.
        let alive = header.iter().position(|h| *h == "r1_alive").unwrap();
        assert_eq!(rows[100][alive], 1.0);
        assert_eq!(rows[200][alive], 0.0);
        let mut jsonl = Vec::new();
        run_traced(&s, TraceFormat::JsonLines, &mut jsonl).unwrap();
        let first: serde_json::Value = serde_json::from_slice(jsonl.split(|b| *b == b'\n').next().unwrap()).unwrap();
        assert_eq!(first["robots"].as_array().unwrap().len(), 3);
        assert_eq!(first["t"], rows[0][0]);
    }
}
