//! The distributed mode means what the in-process simulator means: one scenario file, with
//! radio loss and a kill, run by `ayllu sim serve --scenario` and three `ayllu sim robot
//! --scenario` processes on loopback, for BLE, Local, ForceField and BLE-seek (three teams at
//! once to keep the test short, then BLE-seek's, whose robots are told their pose over the
//! body link and need the CPU on time: [`ROUNDS`]).
//!
//! Checks, for each controller, on the server's lines and the robots':
//! * the kill happened: the server announced it at the scenario's instant, robot 2's process
//!   reported itself killed and exited 0 well before the run's end, and the metrics judged it
//!   (a recovery time, or a task left unrecovered);
//! * the radio model was applied to the real traffic: the robots that talk (BLE, ForceField,
//!   BLE-seek)
//!   lost part of what their peers sent them, at about the scenario's rate;
//! * the metrics are the in-process ones: switches per minute above 0 (reported drives);
//!   messages and bytes per robot per second within a factor of two of in-process (0 for Local);
//! * A_w falls within the in-process spread for the same scenario (wander seeds 1..=8, the
//!   world's seed fixed), widened by [`SLACK`] for real processes on a real clock.
//!
//! Bounded: 30 s of world time on the real clock, three teams together and then BLE-seek's
//! (see [`ROUNDS`]); the whole test takes about 75 s.

use crate::common;

use std::path::PathBuf;
use std::process::Command;
use std::time::{Duration, Instant};

use ayllu_sim::controller::Controller;
use ayllu_sim::scenario::run;
use ayllu_sim::scenario_file;
use common::{start_on_loopback, wait_for, Proc, BIN};
use serde_json::Value as Json;

const ROBOTS: usize = 3;
/// World seconds (paced on the real clock).
const DURATION: f64 = 30.0;
const LOSS: f64 = 0.3;
/// How far outside the in-process range of A_w a distributed run may fall: the processes'
/// timing (startup, scheduling on a loaded machine) is not the simulator's lockstep.
const SLACK: f64 = 0.12;

fn scenario_text(controller: &str) -> String {
    format!(
        "controller = \"{controller}\"\nrobots = {ROBOTS}\ntargets = 4\nseed = 7\nduration = {DURATION}\n\
         [radio]\nloss = {LOSS}\n[[kills]]\nat = {}\nrobot = 2\n",
        DURATION / 2.0
    )
}

/// In-process for the same scenario over wander seeds 1..=8: (min A_w, max A_w, mean
/// msgs/robot/s, mean bytes/robot/s).
fn in_process(controller: &str) -> (f64, f64, f64, f64) {
    let base = scenario_file::scenario(&scenario_text(controller)).expect("the scenario reads");
    let (mut lo, mut hi, mut msgs, mut bytes) = (f64::INFINITY, f64::NEG_INFINITY, 0.0, 0.0);
    for w in 1..=8 {
        let mut s = base.clone();
        s.controllers.wander_seed = w;
        let m = run(&s).expect("in-process run").metrics;
        lo = lo.min(m.a_w);
        hi = hi.max(m.a_w);
        msgs += m.msgs_per_robot_s / 8.0;
        bytes += m.bytes_per_robot_s / 8.0;
    }
    (lo, hi, msgs, bytes)
}

struct Team {
    controller: &'static str,
    procs: Vec<Proc>,
}

fn start(controller: &'static str, dir: &std::path::Path) -> Team {
    let file: PathBuf = dir.join(format!("{controller}.toml"));
    std::fs::write(&file, scenario_text(controller)).expect("writing the scenario");
    let file = file.to_str().expect("UTF-8 path").to_owned();
    let (robots, addrs) = start_on_loopback(
        ROBOTS,
        |k| format!("{controller} robot{}", k + 1),
        |k, url| {
            [
                "sim",
                "robot",
                "--id",
                &(k + 1).to_string(),
                "--scenario",
                &file,
                "--udp",
                url,
                "--status-ms",
                "500",
                "--duration",
                &(DURATION + 60.0).to_string(),
            ]
            .iter()
            .map(|s| s.to_string())
            .collect()
        },
    );
    let mut cmd = Command::new(BIN);
    cmd.args(["sim", "serve", "--scenario", &file, "--wait", "20"]);
    for a in &addrs {
        cmd.args(["--udp", &format!("udp://127.0.0.1:0?peer={a}")]);
    }
    let mut procs = vec![Proc::spawn(&format!("{controller} server"), cmd)];
    procs.extend(robots);
    Team { controller, procs }
}

fn diagnostics(procs: &[Proc]) -> String {
    let mut s = String::new();
    for p in procs {
        let tail: Vec<String> = p.lines().iter().rev().take(3).map(|(_, j)| j.to_string()).collect();
        s.push_str(&format!("--- {}: last lines {tail:#?}\nstderr: {}\n", p.name, p.stderr()));
    }
    s
}

fn check(team: &mut Team, started: Instant) {
    let name = team.controller;
    let limit = Duration::from_secs_f64(DURATION + 60.0).saturating_sub(started.elapsed());
    let procs = &mut team.procs;
    let done = wait_for(limit, Duration::from_millis(100), || {
        procs[0].lines().into_iter().map(|(_, j)| j).find(|j| j["done"] == true)
    });
    let done = done.unwrap_or_else(|| panic!("{name}: the server did not finish\n{}", diagnostics(procs)));
    let lines: Vec<Json> = procs[0].lines().into_iter().map(|(_, j)| j).collect();
    assert_eq!(lines[0]["missing"], serde_json::json!([]), "{name}: a body never heard its robot: {}", lines[0]);
    let m = &done["metrics"];
    let a_w = m["a_w"].as_f64().expect("a_w");
    let msgs = m["msgs_per_robot_s"].as_f64().expect("msgs");
    let switches = m["switches_per_min"].as_f64().expect("switches");
    let bytes = m["bytes_per_robot_s"].as_f64().expect("bytes");
    let (lo, hi, msgs_in, bytes_in) = in_process(name);

    // The kill: announced by the server at its instant, carried out by robot 2's process.
    let kill = lines.iter().find(|j| j.get("kill").is_some()).unwrap_or_else(|| panic!("{name}: no kill line"));
    assert_eq!(kill["kill"], 2, "{name}: {kill}");
    assert!((kill["t"].as_f64().unwrap() - DURATION / 2.0).abs() < 0.06, "{name}: {kill}");
    let robot2 = &mut procs[2];
    let status = robot2.exited().unwrap_or_else(|| panic!("{name}: robot 2 still runs after its kill"));
    assert!(status.success(), "{name}: robot 2 ended with {status}: {}", robot2.stderr());
    let last = robot2.latest().expect("robot 2's lines").1;
    assert_eq!(last["killed"], true, "{name}: {last}");
    // The metrics saw the kill: its re-cover judged, or (when robot 2 observed nothing that no
    // other robot also did at that instant, which the real clock's timing decides: nothing to
    // re-cover, `recover_s` null) the coverage of the robots left alive apart from the team's.
    let judged = m["recover_s"].is_number() || m["unrecovered"].as_u64() > Some(0);
    assert!(judged || m["top_k_alive"] != m["top_k"], "{name}: the metrics did not see the kill: {m}");

    // The radio model on the real traffic: what the others heard from their peers.
    let (mut lost, mut delivered) = (0, 0);
    for r in [&procs[1], &procs[3]] {
        let last = r.latest().expect("status lines").1;
        lost += last["radio"]["lost"].as_u64().unwrap_or(0);
        delivered += last["radio"]["delivered"].as_u64().unwrap_or(0);
    }
    let share = lost as f64 / (lost + delivered).max(1) as f64;
    eprintln!(
        "{name}: distributed A_w {a_w:.3} (in-process {lo:.3}..{hi:.3}), msgs/robot/s {msgs:.2} (in-process \
         {msgs_in:.2}), bytes/robot/s {bytes:.0} (in-process {bytes_in:.0}), switches/min {switches:.2}, lost \
         {lost} of {} ({:.0} %), recover {}, resyncs {}",
        lost + delivered,
        share * 100.0,
        m["recover_s"],
        done["resyncs"],
    );
    assert!(switches > 0.0, "{name}: no switch reported: {m}");
    if name == "Local" {
        assert_eq!(msgs, 0.0, "{name}: Local does not talk");
    } else {
        assert!(msgs > msgs_in / 2.0 && msgs < msgs_in * 2.0, "{name}: {msgs} msgs/robot/s vs {msgs_in} in-process");
        assert!(bytes > bytes_in / 2.0 && bytes < bytes_in * 2.0, "{name}: {bytes} bytes/robot/s vs {bytes_in}");
        assert!(lost + delivered > 100, "{name}: too little traffic to judge the loss");
        assert!((share - LOSS).abs() < 0.1, "{name}: {:.0} % lost, the scenario says {LOSS}", share * 100.0);
    }
    assert!(
        a_w >= lo - SLACK && a_w <= hi + SLACK,
        "{name}: distributed A_w {a_w:.3} outside the in-process spread {lo:.3}..{hi:.3} (± {SLACK})\n{}",
        diagnostics(procs)
    );
}

/// The teams run at once, in two rounds: BLE-seek's three robots run after the other nine. A
/// BLE-seek robot steers by the pose the server sends it each tick, so a robot process that
/// waits for the CPU steers by an old pose: beside two busy loops its team's A_w fell to 0.52
/// (0.74 alone; BLE, Local and ForceField unchanged), and beside the other teams and the rest
/// of `make test` it fell outside the slack in 2 of 3 full runs (docs/limits.md).
const ROUNDS: [&[&str]; 2] = [&["BLE", "Local", "ForceField"], &["BLE-seek"]];
const TEAMS: [&str; 4] = ["BLE", "Local", "ForceField", "BLE-seek"];

#[test]
fn ble_local_forcefield_and_ble_seek_with_loss_and_a_kill_match_in_process() {
    // The in-process references first, so they do not compete with the real-time processes.
    for c in TEAMS {
        assert!(Controller::parse(c).is_some());
        in_process(c);
    }
    let dir =
        PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("sim_distributed_scenario-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch folder");
    let mut teams: Vec<Team> = Vec::new();
    for round in ROUNDS {
        let started = Instant::now();
        let first = teams.len();
        teams.extend(round.iter().map(|&c| start(c, &dir)));
        for team in &mut teams[first..] {
            check(team, started);
        }
    }
    // Every surviving robot stops by itself once its server is gone.
    for team in &mut teams {
        for r in team.procs[1..].iter_mut() {
            let status = wait_for(Duration::from_secs(30), Duration::from_millis(100), || r.exited());
            assert!(
                status.is_some_and(|s| s.success()),
                "{}: {} outlived its server: {}",
                team.controller,
                r.name,
                r.stderr()
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
