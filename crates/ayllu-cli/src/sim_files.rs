//! `ayllu sim run SCENARIO.toml` and `ayllu sim sweep SWEEP.toml`: studies written as files
//! (`ayllu_sim::scenario_file`). This module reads the file, runs it with the library, and
//! prints; `sweep` also writes every run as `runs.csv` / `runs.jsonl` into `--out`.

use std::io::Write as _;
use std::path::PathBuf;

use ayllu_sim::report::runs_csv;
use ayllu_sim::scenario::run;
use ayllu_sim::scenario_file;
use ayllu_sim::study::{mean_sd, run_all, RunRow};
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
}

/// `ayllu sim sweep`.
#[derive(Args, Debug)]
pub struct SweepArgs {
    /// The sweep file (TOML: a scenario plus `seeds`, `controllers` and a `[grid]`).
    pub file: PathBuf,
    /// Where `runs.csv` and `runs.jsonl` go (created if missing).
    #[arg(long, value_name = "DIR", default_value = "ayllu-sweep")]
    pub out: PathBuf,
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
    #[cfg(feature = "foxglove")]
    let outcome = match &args.mcap {
        Some(path) => crate::foxglove::run_to_mcap(&scenario, path)?,
        None => run(&scenario).map_err(|e| Fail::error(format!("the run failed: {e}")))?,
    };
    #[cfg(not(feature = "foxglove"))]
    let outcome = run(&scenario).map_err(|e| Fail::error(format!("the run failed: {e}")))?;
    let m = &outcome.metrics;
    let mut out = std::io::stdout().lock();
    if args.json {
        writeln!(out, "{}", json!({ "controller": scenario.controller.name(), "seed": scenario.seed, "metrics": m }))?;
        return Ok(());
    }
    writeln!(
        out,
        "{}, {} robots, {} targets, seed {}, {} s: A_w {:.3}, A {:.2}, top-k {:.3} (alive {:.3}), switches/min {:.2}, \
         recover {}, msgs/robot/s {:.1}",
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
        m.msgs_per_robot_s
    )?;
    Ok(())
}

/// `ayllu sim sweep FILE`: every cell x controller x seed; a table of means on stdout, every
/// run in `--out`.
pub fn sweep_file(args: &SweepArgs) -> Result<(), Fail> {
    let sweep =
        scenario_file::sweep(&read(&args.file)?).map_err(|e| Fail::error(format!("{}: {e}", args.file.display())))?;
    let jobs = args.jobs.map_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()), |j| j as usize);
    let runs = sweep.runs();
    let scenarios: Vec<_> = runs.iter().map(|(_, _, _, s)| s.clone()).collect();
    let metrics =
        run_all(&scenarios, jobs, &|| {}, &|o| o.metrics).map_err(|e| Fail::error(format!("a run failed: {e}")))?;
    let rows: Vec<RunRow> = runs
        .iter()
        .zip(metrics)
        .map(|((cell, c, seed, s), m)| RunRow {
            table: format!("cell{}", cell + 1),
            controller: c.name().to_owned(),
            robots: s.robots as u32,
            targets: s.world.targets.len() as u32,
            loss: s.radio.loss,
            kill: !s.kills.is_empty(),
            seed: *seed,
            duration: s.duration,
            metrics: m,
        })
        .collect();
    std::fs::create_dir_all(&args.out).map_err(|e| Fail::error(format!("creating {}: {e}", args.out.display())))?;
    let write = |name: &str, text: &str| {
        std::fs::write(args.out.join(name), text)
            .map_err(|e| Fail::error(format!("writing {}: {e}", args.out.join(name).display())))
    };
    write("runs.csv", &runs_csv(&rows))?;
    let jsonl: String = rows.iter().map(|r| serde_json::to_string(r).unwrap_or_default() + "\n").collect();
    write("runs.jsonl", &jsonl)?;

    let mut out = std::io::stdout().lock();
    for (i, cell) in sweep.cells.iter().enumerate() {
        let values: Vec<String> = cell.values.iter().map(|(k, v)| format!("{k} = {v}")).collect();
        writeln!(
            out,
            "cell{}: {}",
            i + 1,
            if values.is_empty() { "(the scenario as written)".into() } else { values.join(", ") }
        )?;
        for c in &sweep.controllers {
            let mine: Vec<&RunRow> =
                rows.iter().filter(|r| r.table == format!("cell{}", i + 1) && r.controller == c.name()).collect();
            let (a_w, sd) = mean_sd(mine.iter().map(|r| r.metrics.a_w));
            let (msgs, _) = mean_sd(mine.iter().map(|r| r.metrics.msgs_per_robot_s));
            writeln!(out, "  {:<12} A_w {a_w:.3} ± {sd:.3}   msgs/robot/s {msgs:.1}", c.name())?;
        }
    }
    writeln!(out, "{} runs; every run in {}", rows.len(), args.out.join("runs.csv").display())?;
    Ok(())
}
