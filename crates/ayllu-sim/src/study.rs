//! Many runs: the paper's setting over seeds, the sweep (robots x targets x loss) and the
//! robustness scenario (a robot killed halfway), each for BLE and every baseline.
//!
//! A [`Plan`] lists [`Cell`]s (a controller in one setting, run over seeds 1..=seeds); [`run_plan`]
//! runs every (cell, seed) on worker threads and [`aggregate`]s each cell into a [`Row`];
//! [`run_plan_recording`] does the same while recording the runs a caller picks, for replays.
//!
//! Promise: the rows are a pure function of the plan. Runs are independent and each is
//! deterministic (see [`crate::scenario`]); results are stored by their place in the plan, not
//! by when a worker finished, and averaged in seed order, so the number of workers and the
//! scheduling change nothing, down to the last bit.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;

use serde::{Deserialize, Serialize};

use crate::controller::Controller;
use crate::metrics::Metrics;
use crate::scenario::{self, Outcome, Scenario, SimError};

/// One cell of a table: a controller in one setting, metrics averaged over `seeds` runs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Row {
    /// The controller's name.
    pub controller: String,
    /// Robots at the start.
    pub robots: u32,
    /// Targets (priorities m, ..., 1).
    pub targets: u32,
    /// Radio loss probability per message and receiver.
    pub loss: f64,
    /// A robot is killed halfway through each run.
    pub kill: bool,
    /// Runs averaged (seeds 1..=seeds).
    pub seeds: u32,
    /// Means over the seeds (recover_s: over the runs that had something to re-cover).
    pub metrics: Metrics,
    /// Standard deviation of A_w over the seeds.
    pub a_w_sd: f64,
}

/// One run of a study: where it sits (table, cell, seed) and its metrics, for per-run exports
/// (`runs.csv`, `runs.jsonl`): every mean a table prints is recomputable from these rows.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunRow {
    /// `paper`, `sweep` or `robustness`.
    pub table: String,
    /// The controller's name, as in the tables.
    pub controller: String,
    /// Robots at the start.
    pub robots: u32,
    /// Targets (priorities m, ..., 1).
    pub targets: u32,
    /// Radio loss probability per message and receiver.
    pub loss: f64,
    /// Whether a robot was killed halfway.
    pub kill: bool,
    /// The run's seed.
    pub seed: u64,
    /// Seconds of virtual time.
    pub duration: f64,
    /// The run's metrics (docs/cmommt.md).
    pub metrics: Metrics,
}

impl Table {
    /// The table's name in exports.
    pub fn name(self) -> &'static str {
        match self {
            Table::Paper => "paper",
            Table::Sweep => "sweep",
            Table::Robustness => "robustness",
        }
    }
}

/// A controller in one setting, to be run with seeds 1..=`seeds`.
#[derive(Clone, Debug, PartialEq)]
pub struct Cell {
    /// The controller every robot runs.
    pub controller: Controller,
    /// Robots at the start.
    pub robots: usize,
    /// Targets (priorities m, ..., 1), in a room sized as by `Scenario::sized`.
    pub targets: usize,
    /// Radio loss probability per message and receiver.
    pub loss: f64,
    /// Kill the most useful robot halfway through.
    pub kill: bool,
    /// Runs (seeds 1..=seeds).
    pub seeds: u32,
    /// Seconds of virtual time per run.
    pub duration: f64,
}

impl Cell {
    /// The run of this cell with `seed`.
    pub fn scenario(&self, seed: u64) -> Scenario {
        let s =
            Scenario::sized(self.controller, self.robots, self.targets, seed).loss(self.loss).duration(self.duration);
        if self.kill {
            s.kill_halfway()
        } else {
            s
        }
    }

    /// Every run of the cell, seeds in order.
    pub fn scenarios(&self) -> impl Iterator<Item = Scenario> + '_ {
        (1..=u64::from(self.seeds)).map(|seed| self.scenario(seed))
    }
}

/// What a study covers. The defaults are the study the README describes.
#[derive(Clone, Debug, PartialEq)]
pub struct StudyConfig {
    /// Runs per cell (seeds 1..=seeds).
    pub seeds: u32,
    /// Seconds of virtual time per run.
    pub duration: f64,
    /// The controllers compared, in every table, in this order.
    pub controllers: Vec<Controller>,
    /// Team sizes of the sweep.
    pub sweep_robots: Vec<usize>,
    /// Target counts of the sweep.
    pub sweep_targets: Vec<usize>,
    /// Radio loss probabilities of the sweep.
    pub sweep_loss: Vec<f64>,
    /// Loss levels of the robustness scenario (the paper's setting, a robot killed halfway).
    pub robustness_loss: Vec<f64>,
}

impl Default for StudyConfig {
    fn default() -> Self {
        StudyConfig {
            seeds: 10,
            duration: 300.0,
            controllers: Controller::ALL.to_vec(),
            sweep_robots: vec![2, 3, 5, 8],
            sweep_targets: vec![4, 8],
            sweep_loss: vec![0.0, 0.1, 0.3],
            robustness_loss: vec![0.0, 0.1, 0.3],
        }
    }
}

impl StudyConfig {
    /// The same study with a `BLE-lean` row after `BLE` in every table (BLE offering its
    /// eligibility by [`ayllu::stdlib::Eligibility::LEAN`]), so that the paper's policy and
    /// the lean one are side by side, coverage and messages (`ayllu sim cmommt --eligibility
    /// lean`). Without BLE in the list the row goes first; already there, nothing changes.
    pub fn with_lean_row(mut self) -> StudyConfig {
        if !self.controllers.contains(&Controller::BleLean) {
            let at = self.controllers.iter().position(|&c| c == Controller::Ble).map_or(0, |i| i + 1);
            self.controllers.insert(at, Controller::BleLean);
        }
        self
    }

    /// A study small enough for a smoke run: 3 seeds of 120 s, sweep 2 and 5 robots x 4
    /// targets x 0 and 30 % loss.
    pub fn quick() -> StudyConfig {
        StudyConfig {
            seeds: 3,
            duration: 120.0,
            sweep_robots: vec![2, 5],
            sweep_targets: vec![4],
            sweep_loss: vec![0.0, 0.3],
            ..StudyConfig::default()
        }
    }
}

/// The three tables of a plan.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Table {
    /// The paper's setting: 3 robots, 4 targets, no loss.
    Paper,
    /// robots x targets x loss, every controller.
    Sweep,
    /// The paper's setting with the most useful robot killed halfway, at several loss levels.
    Robustness,
}

/// The three tables' cells, each table in the order its rows print.
#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    /// The paper's setting (3 robots, 4 targets, no loss): one cell per controller.
    pub paper: Vec<Cell>,
    /// robots x targets x loss x controller, in that nesting order.
    pub sweep: Vec<Cell>,
    /// The paper's setting with a robot killed halfway: loss x controller.
    pub robustness: Vec<Cell>,
}

/// Robots in the paper's setting (section 4.3).
pub const PAPER_ROBOTS: usize = 3;
/// Targets in the paper's setting (section 4.3), priorities 4, 3, 2, 1.
pub const PAPER_TARGETS: usize = 4;

impl Plan {
    /// The cells of `config`'s three tables.
    pub fn new(config: &StudyConfig) -> Plan {
        let cell = |controller, robots, targets, loss, kill| Cell {
            controller,
            robots,
            targets,
            loss,
            kill,
            seeds: config.seeds,
            duration: config.duration,
        };
        let cs = &config.controllers;
        let paper = cs.iter().map(|&c| cell(c, PAPER_ROBOTS, PAPER_TARGETS, 0.0, false)).collect();
        let mut sweep = Vec::new();
        for &robots in &config.sweep_robots {
            for &targets in &config.sweep_targets {
                for &loss in &config.sweep_loss {
                    sweep.extend(cs.iter().map(|&c| cell(c, robots, targets, loss, false)));
                }
            }
        }
        let robustness = config
            .robustness_loss
            .iter()
            .flat_map(|&loss| cs.iter().map(move |&c| (c, loss)))
            .map(|(c, loss)| cell(c, PAPER_ROBOTS, PAPER_TARGETS, loss, true))
            .collect();
        Plan { paper, sweep, robustness }
    }

    /// Every cell: paper, then sweep, then robustness.
    pub fn cells(&self) -> impl Iterator<Item = &Cell> {
        self.paper.iter().chain(&self.sweep).chain(&self.robustness)
    }

    /// Every cell with its table, in the order of [`Plan::cells`].
    pub fn cells_by_table(&self) -> impl Iterator<Item = (Table, &Cell)> {
        let tag = |table: Table| move |c| (table, c);
        self.paper
            .iter()
            .map(tag(Table::Paper))
            .chain(self.sweep.iter().map(tag(Table::Sweep)))
            .chain(self.robustness.iter().map(tag(Table::Robustness)))
    }

    /// How many runs the plan makes.
    pub fn runs(&self) -> usize {
        self.cells().map(|c| c.seeds as usize).sum()
    }
}

/// The plan's rows, table by table, in the plan's order.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Results {
    /// The paper's setting: one row per controller.
    pub paper: Vec<Row>,
    /// The sweep: one row per cell and controller, in the plan's order.
    pub sweep: Vec<Row>,
    /// The robustness scenario: one row per loss level and controller.
    pub robustness: Vec<Row>,
    /// Every run, in the plan's order (table, cell, seed).
    #[serde(default)]
    pub runs: Vec<RunRow>,
}

/// The mean and the sample standard deviation of `xs` (sd 0 for fewer than two values; both
/// 0 for none): how every A_w ± sd of the tables, sweeps and examples is computed.
pub fn mean_sd(xs: impl IntoIterator<Item = f64>) -> (f64, f64) {
    let xs: Vec<f64> = xs.into_iter().collect();
    if xs.is_empty() {
        return (0.0, 0.0);
    }
    let n = xs.len() as f64;
    let mean = xs.iter().sum::<f64>() / n;
    let sd = if xs.len() > 1 { (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt() } else { 0.0 };
    (mean, sd)
}

/// One cell's row from its runs' metrics (in seed order): means of every metric; `recover_s`
/// the mean over the runs that have one (`None` if none has); `unrecovered` the total over the
/// runs (a count of failures to report, not a rate); `a_w_sd` the sample standard deviation of
/// A_w (0 for fewer than two runs).
pub fn aggregate(cell: &Cell, runs: &[Metrics]) -> Row {
    let n = runs.len().max(1) as f64;
    let mean = |f: fn(&Metrics) -> f64| runs.iter().map(f).sum::<f64>() / n;
    let recovers: Vec<f64> = runs.iter().filter_map(|m| m.recover_s).collect();
    let (a_w, a_w_sd) = mean_sd(runs.iter().map(|m| m.a_w));
    Row {
        controller: cell.controller.name().to_owned(),
        robots: cell.robots as u32,
        targets: cell.targets as u32,
        loss: cell.loss,
        kill: cell.kill,
        seeds: runs.len() as u32,
        metrics: Metrics {
            a: mean(|m| m.a),
            a_per_m: mean(|m| m.a_per_m),
            a_w,
            top_k: mean(|m| m.top_k),
            // The same in every run of a cell: min(robots, targets).
            k: runs.first().map_or(cell.robots.min(cell.targets) as u32, |m| m.k),
            top_k_alive: mean(|m| m.top_k_alive),
            redundant: mean(|m| m.redundant),
            switches_per_min: mean(|m| m.switches_per_min),
            recover_s: (!recovers.is_empty()).then(|| recovers.iter().sum::<f64>() / recovers.len() as f64),
            unrecovered: runs.iter().map(|m| m.unrecovered).sum(),
            msgs_per_robot_s: mean(|m| m.msgs_per_robot_s),
            bytes_per_robot_s: mean(|m| m.bytes_per_robot_s),
        },
        a_w_sd,
    }
}

/// Run every scenario on up to `jobs` worker threads, keeping what `keep` takes of each
/// outcome; results in the order of `scenarios`. `done` is called (from a worker) after each
/// run. On an error the workers stop taking runs and the error of the first failed scenario
/// (in the order of `scenarios`, among those that ran) is returned.
pub fn run_all<R: Send>(
    scenarios: &[Scenario],
    jobs: usize,
    done: &(dyn Fn() + Sync),
    keep: &(dyn Fn(Outcome) -> R + Sync),
) -> Result<Vec<R>, SimError> {
    run_indexed(scenarios, jobs, done, &|_, outcome| keep(outcome))
}

/// [`run_all`], with `keep` also told the scenario's index.
fn run_indexed<R: Send>(
    scenarios: &[Scenario],
    jobs: usize,
    done: &(dyn Fn() + Sync),
    keep: &(dyn Fn(usize, Outcome) -> R + Sync),
) -> Result<Vec<R>, SimError> {
    run_each(scenarios, jobs, done, &|i, s| scenario::run(s).map(|outcome| keep(i, outcome)))
}

/// Call `each(index, scenario)` for every scenario on up to `jobs` worker threads (each a run
/// of the caller's making: traced, recorded, ...); results in the order of `scenarios`, with
/// [`run_all`]'s scheduling and error rules.
pub fn run_each<R: Send, E: Send>(
    scenarios: &[Scenario],
    jobs: usize,
    done: &(dyn Fn() + Sync),
    each: &(dyn Fn(usize, &Scenario) -> Result<R, E> + Sync),
) -> Result<Vec<R>, E> {
    // Bigger teams in bigger rooms take longer: start them first so that no long run is left
    // alone at the end while the other workers idle. Only the order of work changes.
    let mut order: Vec<usize> = (0..scenarios.len()).collect();
    order.sort_by(|&a, &b| cost(&scenarios[b]).total_cmp(&cost(&scenarios[a])));
    let next = AtomicUsize::new(0);
    let failed = AtomicBool::new(false);
    let slots: Vec<Mutex<Option<Result<R, E>>>> = scenarios.iter().map(|_| Mutex::new(None)).collect();
    let workers = jobs.clamp(1, scenarios.len().max(1));
    std::thread::scope(|scope| {
        for _ in 0..workers {
            scope.spawn(|| loop {
                if failed.load(Ordering::Relaxed) {
                    break;
                }
                let Some(&i) = order.get(next.fetch_add(1, Ordering::Relaxed)) else { break };
                let result = each(i, &scenarios[i]);
                if result.is_err() {
                    failed.store(true, Ordering::Relaxed);
                }
                *slots[i].lock().unwrap_or_else(|e| e.into_inner()) = Some(result);
                done();
            });
        }
    });
    let mut out = Vec::with_capacity(scenarios.len());
    for slot in slots {
        match slot.into_inner().unwrap_or_else(|e| e.into_inner()) {
            Some(Ok(r)) => out.push(r),
            Some(Err(e)) => return Err(e),
            // Skipped because a run failed: its error is in a slot further on (a worker sets
            // `failed` only after a run fails and writes the error before the scope ends).
            None => {}
        }
    }
    Ok(out)
}

/// Relative cost of a run, for scheduling only: robots x (robots + targets) interactions per
/// tick, times the ticks.
fn cost(s: &Scenario) -> f64 {
    let robots = s.robots as f64;
    robots * (robots + s.world.targets.len() as f64) * s.duration
}

/// Run the whole plan on up to `jobs` threads; `done` is called after each run.
pub fn run_plan(plan: &Plan, jobs: usize, done: &(dyn Fn() + Sync)) -> Result<Results, SimError> {
    let (results, _) = run_plan_recording::<()>(plan, jobs, done, &|_, _, _| false, &|_, _, _, _| ())?;
    Ok(results)
}

/// [`run_plan`], recording the runs `record` picks (by table, cell and seed) and handing each
/// one's outcome to `keep` on the worker that ran it, so that a frame-by-frame recording lives
/// no longer than its run. Recording changes nothing in a run (the rows are those of
/// [`run_plan`], bit for bit); what `keep` returned comes back in the plan's order, each with
/// its table, cell and seed.
#[allow(clippy::type_complexity)]
pub fn run_plan_recording<R: Send>(
    plan: &Plan,
    jobs: usize,
    done: &(dyn Fn() + Sync),
    record: &(dyn Fn(Table, &Cell, u64) -> bool + Sync),
    keep: &(dyn Fn(Table, &Cell, u64, Outcome) -> R + Sync),
) -> Result<(Results, Vec<(Table, Cell, u64, R)>), SimError> {
    let cells: Vec<&Cell> = plan.cells().collect();
    let runs: Vec<(Table, &Cell, u64)> =
        plan.cells_by_table().flat_map(|(t, c)| (1..=u64::from(c.seeds)).map(move |seed| (t, c, seed))).collect();
    let scenarios: Vec<Scenario> = runs
        .iter()
        .map(|&(t, c, seed)| {
            let s = c.scenario(seed);
            // A recording too large for memory (crate::bounds) is not made: the run still is.
            if record(t, c, seed) && s.clone().recorded().validate().is_ok() {
                s.recorded()
            } else {
                s
            }
        })
        .collect();
    let outcomes = run_indexed(&scenarios, jobs, done, &|i, o: Outcome| {
        let metrics = o.metrics.clone();
        let kept = scenarios[i].record.then(|| {
            let (t, c, seed) = runs[i];
            keep(t, c, seed, o)
        });
        (metrics, kept)
    })?;
    let mut kept = Vec::new();
    let mut metrics = Vec::with_capacity(outcomes.len());
    for (i, (m, k)) in outcomes.into_iter().enumerate() {
        metrics.push(m);
        if let Some(k) = k {
            let (t, c, seed) = runs[i];
            kept.push((t, c.clone(), seed, k));
        }
    }
    let run_rows: Vec<RunRow> = runs
        .iter()
        .zip(&metrics)
        .map(|(&(t, c, seed), m)| RunRow {
            table: t.name().to_owned(),
            controller: c.controller.name().to_owned(),
            robots: c.robots as u32,
            targets: c.targets as u32,
            loss: c.loss,
            kill: c.kill,
            seed,
            duration: c.duration,
            metrics: m.clone(),
        })
        .collect();
    let mut rest = metrics.as_slice();
    let mut rows = cells.iter().map(|cell| {
        let (runs, tail) = rest.split_at(cell.seeds as usize);
        rest = tail;
        aggregate(cell, runs)
    });
    let mut take = |n: usize| rows.by_ref().take(n).collect::<Vec<Row>>();
    let paper = take(plan.paper.len());
    let sweep = take(plan.sweep.len());
    let robustness = take(plan.robustness.len());
    Ok((Results { paper, sweep, robustness, runs: run_rows }, kept))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn metrics(a_w: f64, recover_s: Option<f64>) -> Metrics {
        Metrics {
            a: 4.0 * a_w,
            a_per_m: a_w,
            a_w,
            top_k: a_w / 2.0,
            k: 3,
            top_k_alive: a_w / 2.0,
            redundant: 0.5,
            switches_per_min: 2.0 * a_w,
            recover_s,
            unrecovered: u32::from(recover_s.is_some()),
            msgs_per_robot_s: 10.0,
            bytes_per_robot_s: 400.0,
        }
    }

    fn cell(kill: bool) -> Cell {
        Cell { controller: Controller::Ble, robots: 3, targets: 4, loss: 0.1, kill, seeds: 3, duration: 10.0 }
    }

    #[test]
    fn a_row_is_the_mean_and_sample_sd_of_its_runs() {
        let runs = [metrics(0.2, Some(3.0)), metrics(0.4, None), metrics(0.6, Some(5.0))];
        let row = aggregate(&cell(true), &runs);
        let close = |a: f64, b: f64| (a - b).abs() < 1e-12;
        assert_eq!((row.controller.as_str(), row.robots, row.targets, row.seeds), ("BLE", 3, 4, 3));
        assert!(row.kill && close(row.loss, 0.1));
        assert!(close(row.metrics.a_w, 0.4));
        assert!(close(row.metrics.a, 1.6));
        assert!(close(row.metrics.top_k, 0.2));
        assert!(close(row.metrics.switches_per_min, 0.8));
        assert!(close(row.metrics.redundant, 0.5) && close(row.metrics.msgs_per_robot_s, 10.0));
        assert_eq!(row.metrics.k, 3);
        // Over the two runs that had something to re-cover, not three.
        assert!(close(row.metrics.recover_s.unwrap(), 4.0));
        assert_eq!(row.metrics.unrecovered, 2);
        // Sample sd (n - 1): deviations ±0.2 and 0 -> sqrt(0.08 / 2) = 0.2.
        assert!(close(row.a_w_sd, 0.2), "{}", row.a_w_sd);
    }

    #[test]
    fn edge_cases_of_aggregation() {
        let one = aggregate(&cell(false), &[metrics(0.3, None)]);
        assert_eq!(one.a_w_sd, 0.0);
        assert_eq!(one.metrics.recover_s, None);
        assert_eq!(one.seeds, 1);
        let none = aggregate(&cell(false), &[]);
        assert_eq!((none.seeds, none.metrics.a_w, none.metrics.k), (0, 0.0, 3));
    }

    #[test]
    fn the_lean_row_follows_ble_and_leaves_the_other_cells_as_they_were() {
        let plain = Plan::new(&StudyConfig::quick());
        let lean = Plan::new(&StudyConfig::quick().with_lean_row());
        assert_eq!(lean.paper.len(), plain.paper.len() + 1);
        assert_eq!(lean.paper[1].controller, Controller::BleLean);
        let others: Vec<&Cell> = lean.cells().filter(|c| c.controller != Controller::BleLean).collect();
        assert_eq!(others, plain.cells().collect::<Vec<_>>());
        // Asked twice, one row; without BLE in the list, first.
        assert_eq!(StudyConfig::quick().with_lean_row().with_lean_row().controllers.len(), 7);
        let no_ble = StudyConfig { controllers: vec![Controller::Random], ..StudyConfig::quick() };
        assert_eq!(no_ble.with_lean_row().controllers, [Controller::BleLean, Controller::Random]);
    }

    #[test]
    fn the_default_plan_has_the_documented_sizes() {
        let plan = Plan::new(&StudyConfig::default());
        let n = Controller::ALL.len();
        assert_eq!(plan.paper.len(), n);
        assert_eq!(plan.sweep.len(), 4 * 2 * 3 * n);
        assert_eq!(plan.robustness.len(), 3 * n);
        assert!(plan.paper.iter().all(|c| (c.robots, c.targets, c.loss, c.kill) == (3, 4, 0.0, false)));
        assert!(plan.robustness.iter().all(|c| (c.robots, c.targets, c.kill) == (3, 4, true)));
        assert!(plan.sweep.iter().all(|c| !c.kill));
        assert!(plan.cells().all(|c| c.seeds == 10 && c.duration == 300.0));
        assert_eq!(plan.runs(), (n + 24 * n + 3 * n) * 10);
        // Every controller in every setting, BLE first.
        assert_eq!(plan.paper.iter().map(|c| c.controller).collect::<Vec<_>>(), Controller::ALL);

        let quick = Plan::new(&StudyConfig::quick());
        assert_eq!(quick.sweep.len(), 2 * 2 * n);
        assert!(quick.cells().all(|c| c.seeds == 3 && c.duration == 120.0));
    }

    #[test]
    fn a_cell_scenario_carries_its_setting() {
        let s = cell(true).scenario(7);
        assert_eq!((s.robots, s.world.targets.len(), s.seed, s.duration), (3, 4, 7, 10.0));
        assert_eq!(s.radio.loss, 0.1);
        assert_eq!(s.kills.len(), 1);
        assert_eq!(s.kills[0].at, 5.0);
        assert!(cell(false).scenario(7).kills.is_empty());
    }

    #[test]
    fn the_same_plan_gives_the_same_rows_whatever_the_threads() {
        let config = StudyConfig {
            seeds: 2,
            duration: 8.0,
            controllers: vec![Controller::Ble, Controller::Random],
            sweep_robots: vec![2, 4],
            sweep_targets: vec![3],
            sweep_loss: vec![0.0, 0.3],
            robustness_loss: vec![0.2],
        };
        let plan = Plan::new(&config);
        let count = AtomicUsize::new(0);
        let tick = || {
            count.fetch_add(1, Ordering::Relaxed);
        };
        let one = run_plan(&plan, 1, &tick).unwrap();
        let four = run_plan(&plan, 4, &tick).unwrap();
        let again = run_plan(&plan, 3, &tick).unwrap();
        assert_eq!(count.load(Ordering::Relaxed), 3 * plan.runs());
        // Bit for bit: PartialEq on f64 fields.
        assert_eq!(one, four);
        assert_eq!(one, again);
        assert_eq!((one.paper.len(), one.sweep.len(), one.robustness.len()), (2, 8, 2));
        let names: Vec<&str> = one.sweep.iter().map(|r| r.controller.as_str()).collect();
        assert_eq!(&names[..4], ["BLE", "Random", "BLE", "Random"]);
        assert_eq!((one.sweep[2].robots, one.sweep[2].loss), (2, 0.3));
        assert!(one.robustness.iter().all(|r| r.kill && r.seeds == 2));
    }

    #[test]
    fn recording_picks_runs_and_changes_no_row() {
        let config = StudyConfig {
            seeds: 2,
            duration: 6.0,
            controllers: vec![Controller::Ble, Controller::Local],
            sweep_robots: vec![2],
            sweep_targets: vec![3],
            sweep_loss: vec![0.0],
            robustness_loss: vec![0.1],
        };
        let plan = Plan::new(&config);
        let plain = run_plan(&plan, 2, &|| {}).unwrap();
        // Everything but the sweep's second seed, as `ayllu sim cmommt` keeps seed 1 of the sweep.
        let record = |t: Table, _: &Cell, seed: u64| t != Table::Sweep || seed == 1;
        let keep = |_: Table, _: &Cell, _: u64, o: Outcome| o.recording.map(|r| (r.meta.controller, r.frames.len()));
        let (rows, kept) = run_plan_recording(&plan, 2, &|| {}, &record, &keep).unwrap();
        assert_eq!(rows, plain, "recording changes no number");
        let seen: Vec<(Table, &str, u64)> =
            kept.iter().map(|(t, c, seed, _)| (*t, c.controller.name(), *seed)).collect();
        use Table::*;
        assert_eq!(
            seen,
            [
                (Paper, "BLE", 1),
                (Paper, "BLE", 2),
                (Paper, "Local", 1),
                (Paper, "Local", 2),
                (Sweep, "BLE", 1),
                (Sweep, "Local", 1),
                (Robustness, "BLE", 1),
                (Robustness, "BLE", 2),
                (Robustness, "Local", 1),
                (Robustness, "Local", 2),
            ]
        );
        // Each kept value came from its own run: a recording of its controller, every frame.
        for (_, cell, _, recording) in &kept {
            let (controller, frames) = recording.as_ref().expect("a recorded run has a recording");
            assert_eq!(controller, cell.controller.name());
            assert_eq!(*frames, 31, "6 s at a frame every 0.2 s, both ends");
        }
    }
}
