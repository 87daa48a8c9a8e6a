//! `ayllu sim run SCENARIO.toml` and `ayllu sim sweep SWEEP.toml`: studies written as files
//! (`ayllu_sim::scenario_file`). This module reads the file, runs it with the library
//! (`ayllu_sim::sweep`, `ayllu_sim::trace`), and prints; `sweep` also writes the report folder
//! of `sim cmommt` (a table per cell, every run as `runs.csv` / `runs.jsonl`) into `--out`, and
//! both write per-tick traces on request.

use std::io::Write as _;
use std::path::{Path, PathBuf};

use ayllu_sim::report;
use ayllu_sim::scenario::{run_on, Outcome, Scenario};
use ayllu_sim::scenario_file;
use ayllu_sim::trace::{run_traced_on, TraceFormat};
use clap::Args;
use serde_json::json;

use crate::fail::Fail;

/// `ayllu sim run`.
#[derive(Args, Debug)]
pub struct RunArgs {
    /// The scenario file (TOML; docs/cmommt.md, "Studies as files").
    pub file: PathBuf,
    /// Print the metrics as JSON.
    #[arg(long)]
    pub json: bool,
    /// Also write the run to this new MCAP file: the 3-D scene, every robot's ports and the BLE
    /// claims, for Foxglove (docs/cli.md, "sim run --mcap").
    #[cfg(feature = "foxglove")]
    #[arg(long, value_name = "FILE")]
    pub mcap: Option<PathBuf>,
    /// Also write the run's per-tick trace to this file: CSV, or JSON lines if it ends in
    /// `.jsonl` (columns: docs/cmommt.md, "Per-tick traces").
    #[arg(long, value_name = "FILE")]
    pub trace: Option<PathBuf>,
    /// Threads that share each tick's robots [default: the number of CPUs]. The outcome is
    /// the same bit for bit; a thread takes at least 50 robots, so smaller teams use fewer.
    /// A run written to `--mcap` stays on one thread.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=256))]
    pub threads: Option<u32>,
}

impl RunArgs {
    /// `--threads`, or the number of CPUs.
    fn threads(&self) -> usize {
        self.threads.map_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()), |t| t as usize)
    }
}

/// `ayllu sim sweep`.
#[derive(Args, Debug)]
pub struct SweepArgs {
    /// The sweep file (TOML: a scenario plus `seeds`, `controllers` and a `[grid]`).
    pub file: PathBuf,
    /// The report folder (created if missing): `index.html` (a table per cell, replays of seed
    /// 1), `runs.csv`, `runs.jsonl`, `tables.txt`, `results.json`, the plots.
    #[arg(long, value_name = "DIR", default_value = "ayllu-sweep")]
    pub out: PathBuf,
    /// Also write every run's per-tick trace into this folder, as
    /// `cell{C}-{controller}-seed{S}.csv` (created if missing).
    #[arg(long, value_name = "DIR")]
    pub traces: Option<PathBuf>,
    /// Worker threads (default: the number of CPUs).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=256))]
    pub jobs: Option<u32>,
}

fn read(path: &PathBuf) -> Result<String, Fail> {
    std::fs::read_to_string(path).map_err(|e| Fail::error(format!("reading {}: {e}", path.display())))
}

/// `ayllu sim run FILE`: one run, its metrics.
pub fn run_file(args: &RunArgs) -> Result<(), Fail> {
    let scenario = scenario_file::scenario(&read(&args.file)?)
        .map_err(|e| Fail::error(format!("{}: {e}", args.file.display())))?;
    let outcome = match &args.trace {
        Some(path) => traced(args, &scenario, path)?,
        None => plain(args, &scenario)?,
    };
    print_run(args, &scenario, &outcome)
}

/// The run with its per-tick trace written to `path`.
fn traced(args: &RunArgs, scenario: &Scenario, path: &Path) -> Result<Outcome, Fail> {
    #[cfg(feature = "foxglove")]
    if args.mcap.is_some() {
        return Err(Fail::usage("--trace and --mcap: give one of them"));
    }
    #[cfg(not(feature = "foxglove"))]
    let _ = args;
    let file = std::fs::File::create(path).map_err(|e| Fail::error(format!("creating {}: {e}", path.display())))?;
    let mut out = std::io::BufWriter::new(file);
    run_traced_on(scenario, args.threads(), TraceFormat::for_path(path), &mut out)
        .map_err(|e| Fail::error(e.to_string()))
}

/// The run, as an MCAP file if asked.
fn plain(args: &RunArgs, scenario: &Scenario) -> Result<Outcome, Fail> {
    #[cfg(feature = "foxglove")]
    let outcome = match &args.mcap {
        Some(path) => crate::foxglove::run_to_mcap(scenario, path)?,
        None => run_on(scenario, args.threads()).map_err(|e| Fail::error(format!("the run failed: {e}")))?,
    };
    #[cfg(not(feature = "foxglove"))]
    let outcome = run_on(scenario, args.threads()).map_err(|e| Fail::error(format!("the run failed: {e}")))?;
    Ok(outcome)
}

fn print_run(args: &RunArgs, scenario: &Scenario, outcome: &Outcome) -> Result<(), Fail> {
    let m = &outcome.metrics;
    let mut out = std::io::stdout().lock();
    if args.json {
        writeln!(out, "{}", json!({ "controller": scenario.controller.name(), "seed": scenario.seed, "metrics": m }))?;
        return Ok(());
    }
    writeln!(
        out,
        "{}, {} robots, {} targets, seed {}, {} s: A_w {:.3}, A {:.2}, top-k {:.3} (alive {:.3}), switches/min {:.2}, \
         recover {}, msgs/robot/s {:.1} ({:.0} bytes)",
        scenario.controller.name(),
        scenario.robots,
        scenario.world.targets.len(),
        scenario.seed,
        scenario.duration,
        m.a_w,
        m.a,
        m.top_k,
        m.top_k_alive,
        m.switches_per_min,
        m.recover_s.map_or("-".to_owned(), |r| format!("{r:.1} s")),
        m.msgs_per_robot_s,
        m.bytes_per_robot_s
    )?;
    Ok(())
}

/// `ayllu sim sweep FILE`: every cell x controller x seed; a table of means per cell on stdout,
/// the report folder in `--out`, traces in `--traces` if asked.
pub fn sweep_file(args: &SweepArgs) -> Result<(), Fail> {
    let sweep =
        scenario_file::sweep(&read(&args.file)?).map_err(|e| Fail::error(format!("{}: {e}", args.file.display())))?;
    let jobs = args.jobs.map_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()), |j| j as usize);
    if let Some(dir) = &args.traces {
        std::fs::create_dir_all(dir).map_err(|e| Fail::error(format!("creating {}: {e}", dir.display())))?;
    }
    let title = format!("Sweep: {}", args.file.display());
    let command: Vec<String> = std::env::args().collect();
    let results = ayllu_sim::sweep::run(&sweep, jobs, &|| {}, args.traces.as_deref(), &title, &command.join(" "))
        .map_err(|e| Fail::error(e.to_string()))?;
    report::write(&args.out, &results.report)
        .map_err(|e| Fail::error(format!("writing the report into {}: {e}", args.out.display())))?;

    let mut out = std::io::stdout().lock();
    for cell in &results.cells {
        writeln!(out, "{}", cell.title)?;
        for r in &cell.rows {
            writeln!(
                out,
                "  {:<12} A_w {:.3} ± {:.3}   msgs/robot/s {:.1} ({:.0} bytes)",
                r.controller, r.metrics.a_w, r.a_w_sd, r.metrics.msgs_per_robot_s, r.metrics.bytes_per_robot_s
            )?;
        }
    }
    writeln!(out, "{} runs; every run in {}", results.runs.len(), args.out.join("runs.csv").display())?;
    writeln!(out, "Report: {}", args.out.join("index.html").display())?;
    if let Some(dir) = &args.traces {
        writeln!(out, "Traces: {}", dir.display())?;
    }
    Ok(())
}
