//! Simulation speed against real time: how many simulated seconds one core runs per wall
//! second (and, for the largest team, every core: `Sim::set_threads`) for teams of 10, 100 and
//! 1000 robots on the CMOMMT task (5 targets, so five
//! observer layers per robot, 20 Hz ticks), with the BLE controller and, for comparison, the
//! Random one (wander only, no radio).
//!
//! Run with `make bench-sim` (i.e. `cargo bench -p ayllu-sim --bench speed`, about two minutes
//! once compiled). One `Sim` stepped in a loop, on one thread, then the 1000-robot team again
//! with its visits shared among as many threads as there are CPUs. Each size first runs a
//! short warm-up (BLE claims start, the radio queue fills), then a timed stretch of simulated
//! time chosen so the whole benchmark stays within a couple of minutes. Printed per size:
//! simulated and wall seconds, speed-up against real time, cost per robot per simulated second,
//! radio deliveries per robot per second, and cost per robot relative to the 10-robot run of
//! the same controller (1.0 = perfectly linear in team size). The rows run round by round
//! (every row once a round: nine rounds for BLE, three for Random), each run a child process
//! of its own (a fresh heap, as a simulation in its own program has); a row shows its median
//! run by wall time, and its cost vs 10 is the median of each round's ratio. Below the table,
//! each of the goals gets a verdict: MET or NOT met only when an interval holding the
//! median with about 95 % confidence lies on one side of the goal, otherwise "within noise"
//! (`spread`, shared with the network benchmark). Nothing here fails.
//!
//! `cargo bench -p ayllu-sim --bench speed -- 100 ble` runs one size and/or one controller.
//!
//! `speed callgrind [ROBOTS] [SECONDS]` (BLE, default 100 robots, 10 simulated seconds after a
//! 5 s warm-up) steps the timed stretch inside `callgrind_ticks`, for instruction counts (and,
//! with `--cache-sim=yes`, cache misses) that a loaded machine cannot move:
//! `valgrind --tool=callgrind --toggle-collect='*callgrind_ticks*' BINARY callgrind 100 10`.
//!
//! `speed hashes [THREADS]` prints the trace hash, radio totals and metrics of a fixed set of
//! runs (every controller with loss, jitter, range, a partition and a kill; BLE teams of 100
//! and 1000), each on up to THREADS threads (default 1): two builds, or two thread counts,
//! that print the same lines run the model bit for bit alike, which is what a change made for
//! speed must keep.

use std::time::Instant as WallClock;

use ayllu_sim::controller::Controller;
use ayllu_sim::radio::Partition;
use ayllu_sim::scenario::{run_on, Kill, Scenario, Sim};

const SEED: u64 = 1;
const TARGETS: usize = 5;

/// (robots, warm-up s, timed s): a few wall seconds each on the reference machine.
const SIZES: [(usize, f64, f64); 3] = [(10, 5.0, 6000.0), (100, 5.0, 1200.0), (1000, 2.0, 30.0)];
/// The BLE rows, which the goals are about, run this many rounds (the same seed: the same
/// work): enough for an interval that holds each figure's median with about 95 % confidence
/// (order statistics, `spread`), which is what decides a verdict on a noisy host.
const GOAL_ROUNDS: usize = 9;
/// The Random rows (for comparison, no goal) run this many rounds; the median counts.
const RUNS: usize = 3;
/// The goals: 100 robots on one core, 1000 robots, cost per robot at 1000 against 10.
const GOAL_100_SPEEDUP: f64 = 1000.0;
const GOAL_1000_SPEEDUP: f64 = 100.0;
const GOAL_COST_VS_10: f64 = 1.5;

// The runtime's benchmarks' machine line, shared rather than copied.
#[path = "../../ayllu/benches/machine/mod.rs"]
mod machine;
use machine::machine;
// The network benchmark's verdicts over runs, for the same reading of both.
#[path = "../../ayllu/benches/spread/mod.rs"]
mod spread;
use spread::spread;

struct Figures {
    robots: usize,
    sim_s: f64,
    wall_s: f64,
    deliveries_per_s: f64,
}

impl Figures {
    fn speedup(&self) -> f64 {
        self.sim_s / self.wall_s
    }

    /// Wall microseconds per robot per simulated second.
    fn cost(&self) -> f64 {
        self.wall_s * 1e6 / self.robots as f64 / self.sim_s
    }
}

/// Warm up, then time `timed` simulated seconds. Radio deliveries are the whole run's
/// (warm-up included) per simulated second.
fn measure(controller: Controller, robots: usize, warmup: f64, timed: f64, threads: usize) -> Figures {
    let scenario = Scenario::sized(controller, robots, TARGETS, SEED).duration(warmup + timed);
    let mut sim = Sim::new(&scenario).expect("the scenario builds");
    sim.set_threads(threads).expect("the threads start");
    while sim.now().as_secs_f64() < warmup - 1e-9 {
        sim.step().expect("a tick runs");
    }
    let start_sim = sim.now().as_secs_f64();
    let start = WallClock::now();
    while !sim.done() {
        sim.step().expect("a tick runs");
    }
    let wall_s = start.elapsed().as_secs_f64();
    let sim_s = sim.now().as_secs_f64() - start_sim;
    let total_s = sim.now().as_secs_f64();
    let delivered = sim.finish().radio.delivered;
    Figures { robots, sim_s, wall_s, deliveries_per_s: delivered as f64 / total_s }
}

/// [`measure`] in a child process of its own (this binary, `row CONTROLLER ROBOTS WARMUP
/// TIMED THREADS`), so that a figure does not depend on the runs before it: a team built on a heap
/// that earlier, smaller teams left fragmented is spread over more pages (about 52x against
/// 70x alone for 1000 robots on the reference machine: the TLB), which is the benchmark's
/// doing, not the simulator's. A simulation in a program of its own starts from a fresh heap.
fn measure_alone(controller: Controller, robots: usize, warmup: f64, timed: f64, threads: usize) -> Figures {
    let exe = std::env::current_exe().expect("the benchmark knows its own path");
    let (robots_s, warmup_s, timed_s, threads_s) =
        (robots.to_string(), warmup.to_string(), timed.to_string(), threads.to_string());
    let out = std::process::Command::new(exe)
        .args(["row", controller.name(), &robots_s, &warmup_s, &timed_s, &threads_s])
        .output()
        .expect("the benchmark runs a row in a child process");
    let text = String::from_utf8_lossy(&out.stdout);
    let line = text.lines().find_map(|l| l.strip_prefix("row ")).unwrap_or_else(|| {
        panic!("the child printed no row (status {}): {}", out.status, String::from_utf8_lossy(&out.stderr))
    });
    let v: Vec<f64> = line.split_whitespace().map(|x| x.parse().expect("a number")).collect();
    Figures { robots, sim_s: v[0], wall_s: v[1], deliveries_per_s: v[2] }
}

/// Nanoseconds one dependent load takes when each lands on a random cache line of `bytes` of
/// memory (a pointer chase round one random cycle, Sattolo's shuffle): about what a robot's
/// visit pays for each line of its node that is no longer in the cache. Printed beside the
/// figures because the simulator is memory-bound at 1000 robots (about 60 MB of nodes), so a
/// host whose memory is slower runs it slower with the same instructions; comparing this line
/// tells a slow host from a slow simulator.
fn dependent_load_ns(bytes: usize, loads: usize) -> f64 {
    const STRIDE: usize = 8; // usizes a cache line holds
    let lines = bytes / 64;
    let mut order: Vec<usize> = (0..lines).collect();
    let mut rng = fastrand::Rng::with_seed(7);
    for i in (1..lines).rev() {
        order.swap(i, rng.usize(0..i));
    }
    let mut next = vec![0usize; lines * STRIDE];
    for (i, &j) in order.iter().enumerate() {
        next[i * STRIDE] = j * STRIDE;
    }
    let mut at = 0;
    let start = WallClock::now();
    for _ in 0..loads {
        at = next[at];
    }
    let ns = start.elapsed().as_nanos() as f64 / loads as f64;
    std::hint::black_box(at);
    ns
}

/// Step `sim` until it is done, alone in a function so that callgrind can collect just this.
#[inline(never)]
fn callgrind_ticks(sim: &mut Sim) {
    while !sim.done() {
        sim.step().expect("a tick runs");
    }
}

/// The runs `speed hashes [THREADS]` prints (see the module docs), each run on up to
/// `threads` threads (the same lines for any number).
fn hashes(threads: usize) {
    let mut runs = Vec::new();
    for c in Controller::ALL {
        for seed in [1, 7] {
            let mut s = Scenario::sized(c, 5, 4, seed).loss(0.2).duration(60.0);
            s.radio.range = Some(9.0);
            s.radio.partitions.push(Partition { start: 10.0, end: 20.0, island: vec![1, 2] });
            s.kills.push(Kill { at: 30.0, robot: None });
            runs.push((format!("{} busy seed {seed}", c.name()), s));
        }
        runs.push((format!("{} 30 robots", c.name()), Scenario::sized(c, 30, 5, 3).duration(60.0)));
    }
    runs.push(("BLE 100 robots".to_owned(), Scenario::sized(Controller::Ble, 100, TARGETS, SEED).duration(120.0)));
    runs.push(("BLE 1000 robots".to_owned(), Scenario::sized(Controller::Ble, 1000, TARGETS, SEED).duration(10.0)));
    for (name, s) in runs {
        let out = run_on(&s, threads).expect("the scenario runs");
        println!("{name}: {} {:?} {:?}", out.trace_hash, out.radio, out.metrics);
    }
}

fn main() {
    // `cargo bench` passes `--bench`; the filters are the other arguments.
    let args: Vec<String> = std::env::args().skip(1).filter(|a| !a.starts_with("--")).collect();
    if args.first().map(String::as_str) == Some("hashes") {
        hashes(args.get(1).and_then(|a| a.parse().ok()).unwrap_or(1));
        return;
    }
    if args.first().map(String::as_str) == Some("row") {
        // One measurement for `measure_alone`, in this fresh process.
        let controller = args.get(1).and_then(|a| Controller::parse(a)).expect("row: a controller");
        let num = |i: usize| args.get(i).and_then(|a| a.parse::<f64>().ok()).expect("row: a number");
        let threads = args.get(5).map_or(1.0, |_| num(5)) as usize;
        let f = measure(controller, num(2) as usize, num(3), num(4), threads);
        println!("row {} {} {}", f.sim_s, f.wall_s, f.deliveries_per_s);
        return;
    }
    if args.first().map(String::as_str) == Some("callgrind") {
        let robots = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(100);
        let timed: f64 = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(10.0);
        let scenario = Scenario::sized(Controller::Ble, robots, TARGETS, SEED).duration(5.0 + timed);
        let mut sim = Sim::new(&scenario).expect("the scenario builds");
        while sim.now().as_secs_f64() < 5.0 - 1e-9 {
            sim.step().expect("a tick runs");
        }
        callgrind_ticks(&mut sim);
        let ticks = (timed * 20.0).round();
        println!("BLE, {robots} robots: {timed} simulated s ({ticks} ticks) after a 5 s warm-up");
        return;
    }
    let only_size: Option<usize> = args.iter().find_map(|a| a.parse().ok());
    let only_ctl: Option<Controller> = args.iter().find_map(|a| Controller::parse(a));
    println!("Simulation speed: CMOMMT, {TARGETS} targets (5 observer layers), 20 Hz ticks, seed {SEED}");
    println!("machine: {}", machine());
    println!(
        "memory: a dependent load at random takes {:.1} ns over 64 MB (a 1000-robot team), {:.1} ns over 4 MB, {:.1} ns over 256 KB",
        dependent_load_ns(64 << 20, 2_000_000),
        dependent_load_ns(4 << 20, 2_000_000),
        dependent_load_ns(256 << 10, 2_000_000),
    );
    println!();
    // Every size on one thread, then the largest on every CPU (`Sim::set_threads`: the same
    // run, its robots' visits shared out).
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mut rows: Vec<(usize, f64, f64, usize)> = SIZES.iter().map(|&(r, w, t)| (r, w, t, 1)).collect();
    if cpus > 1 {
        let (r, w, t) = SIZES[SIZES.len() - 1];
        rows.push((r, w, t, cpus));
    }
    println!(
        "{:<7} {:>6} {:>7} {:>9} {:>8} {:>11} {:>17} {:>16} {:>12}",
        "ctl", "robots", "threads", "sim s", "wall s", "x real", "µs/robot/sim s", "deliv/robot/s", "cost vs 10"
    );
    let mut goal_lines = Vec::new();
    for controller in [Controller::Ble, Controller::Random] {
        if only_ctl.is_some_and(|c| c != controller) {
            continue;
        }
        let chosen: Vec<_> =
            rows.iter().copied().filter(|&(robots, ..)| only_size.is_none_or(|s| s == robots)).collect();
        // Round by round, every row once in each: a burst of load from elsewhere then
        // falls on every row of its round alike, and each round's cost against its own
        // 10-robot run is a ratio of neighbours in time.
        let rounds = if controller == Controller::Ble { GOAL_ROUNDS } else { RUNS };
        let mut runs: Vec<Vec<Figures>> = chosen.iter().map(|_| Vec::new()).collect();
        for _ in 0..rounds {
            for (row, &(robots, warmup, timed, threads)) in chosen.iter().enumerate() {
                runs[row].push(measure_alone(controller, robots, warmup, timed, threads));
            }
        }
        let base_row = chosen.iter().position(|&(robots, _, _, threads)| robots == 10 && threads == 1);
        for (row, &(robots, _, _, threads)) in chosen.iter().enumerate() {
            let per_round = &runs[row];
            let vs_10: Option<Vec<f64>> =
                base_row.map(|b| per_round.iter().zip(&runs[b]).map(|(f, base)| f.cost() / base.cost()).collect());
            let speedups = spread(per_round.iter().map(Figures::speedup).collect());
            // The row shown is its median run by wall time, as the figures beside it say.
            let mut by_wall: Vec<&Figures> = per_round.iter().collect();
            by_wall.sort_by(|a, b| a.wall_s.total_cmp(&b.wall_s));
            let f = by_wall[by_wall.len() / 2];
            let ratio = vs_10.clone().map_or_else(|| "-".to_owned(), |v| format!("{:.2}", spread(v).median));
            println!(
                "{:<7} {:>6} {:>7} {:>9.1} {:>8.2} {:>10.0}x {:>17.2} {:>16.1} {:>12}",
                controller.name(),
                robots,
                threads,
                f.sim_s,
                f.wall_s,
                f.speedup(),
                f.cost(),
                f.deliveries_per_s / robots as f64,
                ratio,
            );
            if controller != Controller::Ble {
                continue;
            }
            let at = if threads == 1 { "one core".to_owned() } else { format!("{threads} threads") };
            if robots == 100 && threads == 1 {
                goal_lines.push(format!(
                    "100 robots on one core, x real time >= {GOAL_100_SPEEDUP}: {}",
                    speedups.verdict(GOAL_100_SPEEDUP, false)
                ));
                goal_lines.push(speedups.describe_in("x", 0));
            }
            if robots == 1000 {
                goal_lines.push(format!(
                    "1000 robots on {at}, x real time >= {GOAL_1000_SPEEDUP}: {}",
                    speedups.verdict(GOAL_1000_SPEEDUP, false)
                ));
                goal_lines.push(speedups.describe_in("x", 0));
                if let Some(v) = vs_10 {
                    let r = spread(v);
                    goal_lines.push(format!(
                        "1000 robots on {at}, cost per robot vs 10 (each round's own) <= {GOAL_COST_VS_10}: {}",
                        r.verdict(GOAL_COST_VS_10, true)
                    ));
                    goal_lines.push(r.describe());
                }
            }
        }
    }
    println!();
    if !goal_lines.is_empty() {
        println!(
            "Goals (BLE rows, {GOAL_ROUNDS} rounds; MET or NOT met only when the median's 95 % interval lies on one side):"
        );
        for l in goal_lines {
            println!("  {l}");
        }
        println!();
    }
    println!("goal: 100 robots x 5 observer layers (BLE) at 20 Hz >= 1000x real time on one core;");
    println!("      1000 robots >= 100x, cost per robot <= 1.5x that at 10 (cost vs 10: wall time");
    println!("      per robot, so a row on several threads counts the time it took, not the CPU time;");
    println!("      the median over rounds of each round's ratio to its own 10-robot run).");
    println!("reference (not measured here): a popular Python 2-D robot simulator runs about 8x real");
    println!("      time at 100 robots.");
}
