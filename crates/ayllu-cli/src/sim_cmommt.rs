//! `ayllu sim cmommt`: the paper's multi-target observation study (section 4) in one command.
//!
//! It runs the plan of [`ayllu_sim::study`] (the paper's setting, the sweep, the robustness
//! scenario; every controller, seeds 1..=N) on worker threads, recording the runs the report
//! can replay (every controller and seed, up to [`REPLAY_SEEDS`], of the paper's setting and the
//! robustness scenario; seed 1 of each sweep cell), writes the report folder, then prints a
//! short summary: BLE against every other controller on A_w, whether the paper's claim held,
//! what a killed robot cost. The three tables go into the folder (`tables.txt`, the page) and
//! to stdout only with `--full`.
//!
//! Promises: stdout carries only results (the summary, the tables with `--full`, or one JSON
//! document with `--json`), the same for the same arguments whatever `--jobs` is, except for the
//! wall time line; progress goes to stderr (a bar on a terminal, a few plain lines otherwise,
//! so CI logs show it moving); exit 0 once the report is written — also when the reader of
//! stdout goes away early (`| head -1`): the rest of the output is dropped quietly — and 1 with
//! one message otherwise. Nothing written to stderr can panic.

use std::fmt;
use std::io::{self, IsTerminal, Write};
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use ayllu_sim::recording::CoverageSeries;
use ayllu_sim::report::{self, Replay, Report};
use ayllu_sim::scenario::Outcome;
use ayllu_sim::study::{self, Cell, Plan, StudyConfig, Table};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;

use crate::fail::Fail;

/// The seed of the run the page opens on (BLE, paper setting), of every controller's coverage on
/// that same world, and the only seed of the sweep's cells kept for a replay.
const REPLAY_SEED: u64 = 1;
/// Seeds kept for a replay in the paper's setting and the robustness scenario: 1..=this.
const REPLAY_SEEDS: u64 = 10;
/// Seconds between the poses a replay keeps (the simulator records a frame every 0.2 s). The
/// full study's page is then about 6 MB; the page says how it was thinned.
const REPLAY_STEP: f64 = 0.4;

#[derive(Args, Debug)]
#[command(after_help = "\
The full study is 1680 runs (paper 6 cells, sweep 144, robustness 18; x 10 seeds of 300 s):
about 30 CPU-seconds in a release build, so 15-40 s on 2 cores depending on what else runs;
--quick (144 runs) takes about a second. Stdout gets a short summary (BLE against each baseline,
whether the paper's claim held); the tables are in DIR/tables.txt and DIR/index.html, which
also replays any run. The columns are defined in docs/cmommt.md; the command in docs/cli.md.")]
pub struct CmommtArgs {
    /// Runs per setting, seeds 1..=N [default: 10; 3 with --quick].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=10_000))]
    pub seeds: Option<u32>,
    /// Virtual seconds per run [default: 300; 120 with --quick]. A robustness run kills its
    /// robot at half of it.
    #[arg(long, value_name = "SECS", allow_negative_numbers = true, value_parser = crate::positive_secs)]
    pub duration: Option<f64>,
    /// A small study for a first look or a smoke test: 3 seeds of 120 s, sweep 2 and 5 robots x
    /// 4 targets x 0 and 30 % loss (--seeds and --duration still apply).
    #[arg(long)]
    pub quick: bool,
    /// The report folder (created if missing; its files are overwritten).
    #[arg(long, value_name = "DIR", default_value = "ayllu-report")]
    pub out: PathBuf,
    /// Worker threads [default: the number of CPUs]. The results do not depend on it.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..=1024))]
    pub jobs: Option<u64>,
    /// Skip the sweep (paper setting and robustness only).
    #[arg(long)]
    pub no_sweep: bool,
    /// Print the rows as one JSON document instead of the summary.
    #[arg(long, conflicts_with = "full")]
    pub json: bool,
    /// Also print the three tables after the summary (they are always in DIR/tables.txt).
    #[arg(long)]
    pub full: bool,
    /// `lean` adds a BLE-lean row after BLE in every table: BLE offering its eligibility on a
    /// 10 % change or every 500 ms instead of at every activation, so that the two policies'
    /// coverage and messages are side by side. `paper` (the default): the study as it was.
    #[arg(long, value_name = "POLICY", default_value = "paper", value_parser = ["paper", "lean"])]
    pub eligibility: String,
}

pub fn run(args: &CmommtArgs) -> Result<(), Fail> {
    let started = Instant::now();
    let mut config = if args.quick { StudyConfig::quick() } else { StudyConfig::default() };
    if let Some(seeds) = args.seeds {
        config.seeds = seeds;
    }
    if let Some(duration) = args.duration {
        config.duration = duration;
    }
    if args.no_sweep {
        config.sweep_robots.clear();
    }
    if args.eligibility == "lean" {
        config = config.with_lean_row();
    }
    let jobs = args.jobs.map_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()), |j| j as usize);
    let plan = Plan::new(&config);
    let total = plan.runs();
    let recorded = plan
        .cells_by_table()
        .flat_map(|(t, c)| (1..=u64::from(c.seeds)).map(move |seed| (t, seed)))
        .filter(|&(t, seed)| record(t, seed))
        .count();

    note(format_args!(
        "sim cmommt: {total} runs of {} s (paper {} cells, sweep {}, robustness {}; {} seeds; {recorded} recorded for \
         the report's replay) on {}",
        config.duration,
        plan.paper.len(),
        plan.sweep.len(),
        plan.robustness.len(),
        config.seeds,
        threads(jobs),
    ));
    let progress = Progress::new(total as u64, started);
    let (results, kept) =
        study::run_plan_recording(&plan, jobs, &|| progress.tick(), &|t, _, seed| record(t, seed), &keep)
            .map_err(|e| Fail::error(format!("a run failed: {e}")))?;
    progress.finish();

    let mut coverage: Vec<(String, CoverageSeries)> = Vec::new();
    let mut replays: [Vec<Replay>; 3] = Default::default();
    for (table, cell, seed, kept) in kept {
        // Recorded runs always have a recording; a run without one simply has no replay.
        let Some((replay, series)) = kept else { continue };
        if table == Table::Paper && seed == REPLAY_SEED {
            coverage.push((cell.controller.name().to_owned(), series));
        }
        // The menus list the paper's setting, then the robustness scenario, then the sweep.
        let at = match table {
            Table::Paper => 0,
            Table::Robustness => 1,
            Table::Sweep => 2,
        };
        replays[at].push(replay);
    }
    // Opening on BLE in the paper's setting, seed 1: the plan lists BLE first, seeds in order.
    let replays: Vec<Replay> = replays.into_iter().flatten().collect();
    if replays.is_empty() {
        return Err(Fail::error("no run was recorded for the report's replay"));
    }
    let report = Report {
        title: "W-CMOMMT: Broadcast of Local Eligibility against the baselines".to_owned(),
        command: command_line(),
        duration: config.duration,
        replays,
        coverage,
        paper: results.paper.clone(),
        sweep: results.sweep.clone(),
        robustness: results.robustness.clone(),
        runs: results.runs.clone(),
        cells: Vec::new(),
    };
    let index = args.out.join("index.html");
    report::write(&args.out, &report)
        .map_err(|e| Fail::error(format!("writing the report into {}: {e}", args.out.display())))?;
    let wall = started.elapsed().as_secs_f64();
    let timing = format!("{wall:.1} s ({total} runs on {})", threads(jobs));

    let printed = if args.json {
        let doc = json!({
            "paper": results.paper,
            "robustness": results.robustness,
            "sweep": results.sweep,
            "report": index.display().to_string(),
        });
        let text = serde_json::to_string_pretty(&doc).map_err(|e| Fail::error(e.to_string()))?;
        print_json(&text).inspect(|()| {
            // Kept off stdout so the document is the same for the same arguments.
            note(format_args!("sim cmommt: wall time {timing}"));
        })
    } else {
        print_summary(&report, &args.out, args.full, &timing)
    };
    match printed {
        // The reader went away (`ayllu sim cmommt | head -1`): it has read what it wanted, and
        // the report is written. A normal end, not an error.
        Err(e) if e.kind() == io::ErrorKind::BrokenPipe => Ok(()),
        Err(e) => Err(Fail::error(format!("writing output: {e}"))),
        Ok(()) => Ok(()),
    }
}

/// Which runs are recorded for the page: every seed (up to [`REPLAY_SEEDS`]) of the paper's
/// setting and of the robustness scenario, seed [`REPLAY_SEED`] of the sweep (120 cells of bigger
/// teams: all their seeds would multiply the page by ten).
fn record(table: Table, seed: u64) -> bool {
    match table {
        Table::Paper | Table::Robustness => seed <= REPLAY_SEEDS,
        Table::Sweep => seed == REPLAY_SEED,
    }
}

/// What a recorded run leaves for the report, taken on the worker that ran it (so its
/// frame-by-frame recording is dropped there): its replay and its coverage series.
fn keep(table: Table, cell: &Cell, _seed: u64, outcome: Outcome) -> Option<(Replay, CoverageSeries)> {
    let setting = match table {
        Table::Paper => "Paper setting".to_owned(),
        Table::Robustness => format!("Robustness: {} % loss", percent(cell.loss)),
        Table::Sweep => {
            format!("Sweep: {} robots, {} targets, {} % loss", cell.robots, cell.targets, percent(cell.loss))
        }
    };
    let replay = Replay::new(setting, outcome.recording.as_ref()?, REPLAY_STEP);
    Some((replay, outcome.coverage))
}

/// A loss probability as the tables write it: "10", "2.5".
fn percent(loss: f64) -> String {
    let p = loss * 100.0;
    if (p - p.round()).abs() < 1e-9 {
        format!("{p:.0}")
    } else {
        format!("{p:.1}")
    }
}

fn print_json(text: &str) -> io::Result<()> {
    let mut out = io::stdout().lock();
    writeln!(out, "{text}")?;
    out.flush()
}

/// The summary first (the point), then with `full` the tables, then where the rest is.
fn print_summary(report: &Report, dir: &std::path::Path, full: bool, timing: &str) -> io::Result<()> {
    let mut out = io::stdout().lock();
    write!(out, "{}", report::summary_text(report))?;
    if full {
        write!(out, "\n{}", report::tables_text(report))?;
    } else {
        writeln!(out)?;
    }
    writeln!(out, "Report: {} (replays any run; tables, plots)", dir.join("index.html").display())?;
    if !full {
        writeln!(out, "Tables: {} (or run with --full)", dir.join("tables.txt").display())?;
    }
    writeln!(out, "Wall time: {timing}")?;
    out.flush()
}

/// A line on stderr. Progress and notes must never end the command: if stderr is closed (the
/// command piped with `2>&1 | head -1`), the line is dropped rather than panicking as
/// `eprintln!` would.
fn note(line: fmt::Arguments) {
    let _ = writeln!(io::stderr().lock(), "{line}");
}

fn threads(jobs: usize) -> String {
    if jobs == 1 {
        "1 thread".to_owned()
    } else {
        format!("{jobs} threads")
    }
}

/// The command as typed, for the report (arguments with spaces or shell characters quoted).
fn command_line() -> String {
    std::env::args()
        .map(|a| {
            let plain = !a.is_empty() && a.chars().all(|c| c.is_ascii_alphanumeric() || "-_./=:,+@%".contains(c));
            if plain {
                a
            } else {
                format!("'{}'", a.replace('\'', r"'\''"))
            }
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// Progress on stderr: a bar on a terminal; otherwise one plain line per tenth of the runs.
struct Progress {
    bar: Option<ProgressBar>,
    total: u64,
    done: AtomicUsize,
    started: Instant,
}

impl Progress {
    fn new(total: u64, started: Instant) -> Progress {
        let bar = std::io::stderr().is_terminal().then(|| {
            let bar = ProgressBar::new(total);
            let style = ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {pos}/{len} runs, {eta} left")
                .unwrap_or_else(|_| ProgressStyle::default_bar())
                .progress_chars("=> ");
            bar.set_style(style);
            bar
        });
        Progress { bar, total, done: AtomicUsize::new(0), started }
    }

    /// One run finished (called from the workers).
    fn tick(&self) {
        if let Some(bar) = &self.bar {
            bar.inc(1);
            return;
        }
        // Each count is seen by exactly one worker, so each tenth prints once.
        let done = self.done.fetch_add(1, Ordering::Relaxed) as u64 + 1;
        let total = self.total.max(1);
        if done * 10 / total > (done - 1) * 10 / total {
            note(format_args!(
                "sim cmommt: {done}/{total} runs ({}%), {:.1} s",
                done * 100 / total,
                self.started.elapsed().as_secs_f64()
            ));
        }
    }

    fn finish(&self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
    }
}
