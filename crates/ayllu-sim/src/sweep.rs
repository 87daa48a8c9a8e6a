//! A sweep read from a file ([`crate::scenario_file::Sweep`]), run: one row per run, a table
//! per cell, and the report page of `ayllu sim cmommt` built from them (`ayllu sim sweep`).
//!
//! What [`run`] promises: the runs are those of [`Sweep::runs`] (cells x controllers x seeds,
//! in that order), each deterministic, run on worker threads and stored by their place, so the
//! rows do not depend on the number of workers; seed 1 of every cell and controller is
//! recorded for the page's replay (recording changes no number); with a trace folder, every
//! run's per-tick trace is written there as `cell{C}-{controller}-seed{S}.csv`
//! ([`crate::trace`]), and tracing changes no number either.

use std::path::{Path, PathBuf};

use crate::recording::CoverageSeries;
use crate::report::{CellTable, Replay, Report};
use crate::scenario::{self, Outcome, Scenario};
use crate::scenario_file::Sweep;
use crate::study::{aggregate, run_each, Cell, Row, RunRow};
use crate::trace::{run_traced, TraceError, TraceFormat};

/// Seconds between the poses a replay keeps (as `ayllu sim cmommt`'s page).
const REPLAY_STEP: f64 = 0.4;

/// What a sweep produced.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepResults {
    /// Every run, in the sweep's order; `table` is `cell{C}` (1-based).
    pub runs: Vec<RunRow>,
    /// One table per cell: a row per controller, the means over the seeds.
    pub cells: Vec<CellTable>,
    /// The report page's content (tables per cell, replays of seed 1, coverage of the first
    /// cell's seed 1 per controller, every run).
    pub report: Report,
}

/// The title of cell `i` (0-based): its grid values.
pub fn cell_title(sweep: &Sweep, i: usize) -> String {
    let values: Vec<String> = sweep.cells[i]
        .values
        .iter()
        .map(|(k, v)| if k == crate::scenario_file::CASE { v.clone() } else { format!("{k} = {v}") })
        .collect();
    let what = if values.is_empty() { "the scenario as written".to_owned() } else { values.join(", ") };
    format!("cell{}: {what}", i + 1)
}

/// The path of run (cell `i`, 0-based; `controller`; `seed`)'s trace in `dir`.
pub fn trace_path(dir: &Path, i: usize, controller: &str, seed: u64) -> PathBuf {
    dir.join(format!("cell{}-{controller}-seed{seed}.csv", i + 1))
}

/// Why a sweep failed.
pub type SweepError = TraceError;

/// Run `sweep` on up to `jobs` threads (`done` after each run), writing per-tick traces into
/// `traces` if given; `title` and `command` head the report.
pub fn run(
    sweep: &Sweep,
    jobs: usize,
    done: &(dyn Fn() + Sync),
    traces: Option<&Path>,
    title: &str,
    command: &str,
) -> Result<SweepResults, SweepError> {
    let runs = sweep.runs();
    let scenarios: Vec<Scenario> = runs
        .iter()
        .map(|(_, _, seed, s)| {
            let mut s = s.clone();
            // Seed 1 is recorded for the replay, if its recording fits in memory (crate::bounds).
            s.record = *seed == 1 && s.clone().recorded().validate().is_ok();
            s
        })
        .collect();
    let each = |k: usize, s: &Scenario| -> Result<(Outcome, Option<Replay>), SweepError> {
        let (cell, controller, seed, _) = &runs[k];
        let outcome = match traces {
            Some(dir) => {
                let path = trace_path(dir, *cell, controller.name(), *seed);
                let file = std::fs::File::create(&path)
                    .map_err(|e| std::io::Error::new(e.kind(), format!("{}: {e}", path.display())))?;
                let mut out = std::io::BufWriter::new(file);
                run_traced(s, TraceFormat::Csv, &mut out)?
            }
            None => scenario::run(s)?,
        };
        // The recording lives no longer than its run: a thinned replay is kept instead.
        let replay = outcome.recording.as_ref().map(|r| Replay::new(cell_title(sweep, *cell), r, REPLAY_STEP));
        Ok((Outcome { recording: None, ..outcome }, replay))
    };
    let outcomes = run_each(&scenarios, jobs, done, &each)?;

    let mut rows = Vec::with_capacity(runs.len());
    let mut replays = Vec::new();
    let mut coverage: Vec<(String, CoverageSeries)> = Vec::new();
    for ((cell, c, seed, s), (outcome, replay)) in runs.iter().zip(outcomes) {
        if *cell == 0 && *seed == 1 {
            coverage.push((c.name().to_owned(), outcome.coverage.clone()));
        }
        replays.extend(replay);
        rows.push(RunRow {
            table: format!("cell{}", cell + 1),
            controller: c.name().to_owned(),
            robots: s.robots as u32,
            targets: s.world.targets.len() as u32,
            loss: s.radio.loss,
            kill: !s.kills.is_empty(),
            seed: *seed,
            duration: s.duration,
            metrics: outcome.metrics,
        });
    }
    let mut cells = Vec::with_capacity(sweep.cells.len());
    for (i, cell) in sweep.cells.iter().enumerate() {
        let table = format!("cell{}", i + 1);
        let rows: Vec<Row> = sweep
            .controllers
            .iter()
            .map(|c| {
                let mine: Vec<_> = rows
                    .iter()
                    .filter(|r| r.table == table && r.controller == c.name())
                    .map(|r| r.metrics.clone())
                    .collect();
                let s = &cell.scenario;
                let place = Cell {
                    controller: *c,
                    robots: s.robots,
                    targets: s.world.targets.len(),
                    loss: s.radio.loss,
                    kill: !s.kills.is_empty(),
                    seeds: mine.len() as u32,
                    duration: s.duration,
                };
                aggregate(&place, &mine)
            })
            .collect();
        cells.push(CellTable { title: cell_title(sweep, i), rows });
    }
    let report = Report {
        title: title.to_owned(),
        command: command.to_owned(),
        duration: sweep.cells.first().map_or(0.0, |c| c.scenario.duration),
        replays,
        coverage,
        paper: Vec::new(),
        // Every cell's rows: the sweep plots (A_w against team size and loss) draw from them.
        sweep: cells.iter().flat_map(|c| c.rows.iter().cloned()).collect(),
        robustness: Vec::new(),
        runs: rows.clone(),
        cells: cells.clone(),
    };
    Ok(SweepResults { runs: rows, cells, report })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario_file;

    #[test]
    fn a_sweep_gives_a_row_per_run_a_table_per_cell_and_traces_on_request() {
        let sw = scenario_file::sweep(
            "seeds = 2\ncontrollers = [\"BLE\", \"Planner\"]\nduration = 6.0\n[grid]\n\"radio.loss\" = [0.0, 0.5]\n",
        )
        .unwrap();
        let dir = std::env::temp_dir().join(format!("ayllu-sweep-unit-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let traced = run(&sw, 2, &|| {}, Some(&dir), "t", "c").unwrap();
        let plain = run(&sw, 1, &|| {}, None, "t", "c").unwrap();
        assert_eq!(traced, plain, "tracing and the number of workers change nothing");
        assert_eq!(plain.runs.len(), 2 * 2 * 2);
        assert_eq!(plain.cells.len(), 2);
        assert_eq!(plain.cells[1].title, "cell2: radio.loss = 0.5");
        assert_eq!(plain.cells[1].rows.iter().map(|r| r.controller.as_str()).collect::<Vec<_>>(), ["BLE", "Planner"]);
        // Seed 1 of each cell and controller can be replayed.
        assert_eq!(plain.report.replays.len(), 4);
        let mean = (plain.runs[6].metrics.a_w + plain.runs[7].metrics.a_w) / 2.0;
        assert_eq!(plain.cells[1].rows[1].metrics.a_w, mean);
        let trace = std::fs::read_to_string(trace_path(&dir, 1, "Planner", 2)).unwrap();
        assert_eq!(trace.lines().count(), 1 + 120, "a header and 6 s of ticks");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
