//! `ayllu sim cmommt`: the paper's multi-target observation study (section 4) in one command.
//!
//! It runs the plan of [`ayllu_sim::study`] (the paper's setting, the sweep, the robustness
//! scenario; every controller, seeds 1..=N) on worker threads, prints the three tables and how
//! each controller's A_w compares with BLE's, then records BLE's run in the paper's setting
//! (seed 1) with every controller's coverage on that same world, and writes the report folder.
//!
//! Promises: stdout carries only results (tables and comparisons, or one JSON document with
//! `--json`), the same for the same arguments whatever `--jobs` is, except for the wall time
//! line; progress goes to stderr (a bar on a terminal, a few plain lines otherwise, so CI logs
//! show it moving); exit 0 once the report is written, 1 with one message otherwise.

use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use ayllu_sim::controller::Controller;
use ayllu_sim::recording::CoverageSeries;
use ayllu_sim::report::{self, Report};
use ayllu_sim::scenario::{Outcome, Scenario};
use ayllu_sim::study::{self, Plan, Results, Row, StudyConfig, PAPER_ROBOTS, PAPER_TARGETS};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;

use crate::fail::Fail;

/// Seed of the replayed run (and of the coverage comparison on the same world).
const REPLAY_SEED: u64 = 1;

#[derive(Args, Debug)]
#[command(after_help = "\
The full study is 1400 runs (paper 5 cells, sweep 120, robustness 15; x 10 seeds of 300 s),
plus 5 for the replay: about 30 CPU-seconds in a release build, so 15-35 s on 2 cores
depending on what else runs; --quick (125 runs) takes under a second.
The columns are defined in docs/cmommt.md; the command in docs/cli.md.")]
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
    /// Print the rows as one JSON document instead of tables.
    #[arg(long)]
    pub json: bool,
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
    let jobs = args.jobs.map_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()), |j| j as usize);
    let plan = Plan::new(&config);
    let replays = replay_scenarios(&config);
    let total = plan.runs() + replays.len();

    eprintln!(
        "sim cmommt: {total} runs of {} s (paper {} cells, sweep {}, robustness {}; {} seeds; {} replayed) on {}",
        config.duration,
        plan.paper.len(),
        plan.sweep.len(),
        plan.robustness.len(),
        config.seeds,
        replays.len(),
        threads(jobs),
    );
    let progress = Progress::new(total as u64, started);
    let results =
        study::run_plan(&plan, jobs, &|| progress.tick()).map_err(|e| Fail::error(format!("a run failed: {e}")))?;
    let outcomes = study::run_all(&replays, jobs, &|| progress.tick(), &|o: Outcome| o)
        .map_err(|e| Fail::error(format!("the replay run failed: {e}")))?;
    progress.finish();

    let mut recording = None;
    let mut coverage: Vec<(String, CoverageSeries)> = Vec::new();
    for (scenario, outcome) in replays.iter().zip(outcomes) {
        coverage.push((scenario.controller.name().to_owned(), outcome.coverage));
        recording = recording.or(outcome.recording);
    }
    let recording = recording.ok_or_else(|| Fail::error("the replay run kept no recording"))?;
    let report = Report {
        title: "W-CMOMMT: Broadcast of Local Eligibility against the baselines".to_owned(),
        command: command_line(),
        recording,
        coverage,
        paper: results.paper.clone(),
        sweep: results.sweep.clone(),
        robustness: results.robustness.clone(),
    };
    let index = args.out.join("index.html");
    report::write(&args.out, &report)
        .map_err(|e| Fail::error(format!("writing the report into {}: {e}", args.out.display())))?;
    let wall = started.elapsed().as_secs_f64();

    let mut out = std::io::stdout().lock();
    if args.json {
        let doc = json!({
            "paper": results.paper,
            "robustness": results.robustness,
            "sweep": results.sweep,
            "report": index.display().to_string(),
        });
        let text = serde_json::to_string_pretty(&doc).map_err(|e| Fail::error(e.to_string()))?;
        writeln!(out, "{text}")?;
        // Kept off stdout so the document is the same for the same arguments.
        eprintln!("sim cmommt: wall time {wall:.1} s ({total} runs on {})", threads(jobs));
    } else {
        write_tables(&mut out, &config, &results)?;
        writeln!(out, "Report: {}", index.display())?;
        writeln!(out, "Wall time: {wall:.1} s ({total} runs on {})", threads(jobs))?;
    }
    out.flush()?;
    Ok(())
}

/// Every controller in the paper's setting on the replay seed: the same world for all (where
/// robots and targets start, and how targets move, depend on the seed only, not on what the
/// robots do). The first controller's run (BLE) is recorded.
fn replay_scenarios(config: &StudyConfig) -> Vec<Scenario> {
    config
        .controllers
        .iter()
        .enumerate()
        .map(|(i, &c)| {
            let s = Scenario::sized(c, PAPER_ROBOTS, PAPER_TARGETS, REPLAY_SEED).duration(config.duration);
            if i == 0 {
                s.recorded()
            } else {
                s
            }
        })
        .collect()
}

fn write_tables(out: &mut impl Write, config: &StudyConfig, results: &Results) -> std::io::Result<()> {
    let runs = format!("{} seeds x {} s", config.seeds, config.duration);
    writeln!(
        out,
        "Paper setting: {PAPER_ROBOTS} robots, {PAPER_TARGETS} targets (priorities 4,3,2,1), no loss; {runs}"
    )?;
    writeln!(out, "{}", report::text_table(&results.paper))?;
    writeln!(out, "Robustness: paper setting, the most useful robot killed at {} s; {runs}", config.duration / 2.0)?;
    writeln!(out, "{}", report::text_table(&results.robustness))?;
    if results.sweep.is_empty() {
        writeln!(out, "Sweep: skipped (--no-sweep)\n")?;
    } else {
        writeln!(out, "Sweep: robots x targets x radio loss; {runs}")?;
        writeln!(out, "{}", report::text_table(&results.sweep))?;
    }
    write_comparison(out, &results.paper)
}

/// One line per controller: its A_w in the paper's setting against BLE's, with the standard
/// error of the difference so that a gap can be told from seed-to-seed noise.
fn write_comparison(out: &mut impl Write, paper: &[Row]) -> std::io::Result<()> {
    let Some(ble) = paper.iter().find(|r| r.controller == Controller::Ble.name()) else { return Ok(()) };
    let width = paper.iter().map(|r| r.controller.len()).max().unwrap_or(0);
    writeln!(out, "A_w against BLE (paper setting; ± is one standard error of the difference):")?;
    for row in paper {
        let (a, b) = (&row.metrics, &ble.metrics);
        let name = &row.controller;
        if row.controller == ble.controller {
            writeln!(out, "  {name:<width$}  A_w {:.3} ± {:.3} sd", a.a_w, row.a_w_sd)?;
            continue;
        }
        let diff = b.a_w - a.a_w;
        let se = (ble.a_w_sd.powi(2) / f64::from(ble.seeds.max(1)) + row.a_w_sd.powi(2) / f64::from(row.seeds.max(1)))
            .sqrt();
        let ratio = if a.a_w > 0.0 { format!("x{:.2}", b.a_w / a.a_w) } else { "-".to_owned() };
        let verdict = if diff.abs() <= 2.0 * se {
            "within noise"
        } else if diff > 0.0 {
            "BLE better"
        } else {
            "BLE worse"
        };
        writeln!(
            out,
            "  {name:<width$}  A_w {:.3} ± {:.3} sd   BLE − {name} = {diff:+.3} ± {se:.3} ({ratio}): {verdict}",
            a.a_w, row.a_w_sd
        )?;
    }
    writeln!(out)
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
            eprintln!(
                "sim cmommt: {done}/{total} runs ({}%), {:.1} s",
                done * 100 / total,
                self.started.elapsed().as_secs_f64()
            );
        }
    }

    fn finish(&self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
    }
}
