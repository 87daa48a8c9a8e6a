//! CMOMMT over ROS 2: the simulator served as a fleet of ROS 2 robots (`ayllu sim serve --ros2`)
//! and three BLE controllers with ROS 2 bodies (`ayllu sim robot --ros2
//! examples/ros2/sim-robot.toml`), each process in a network namespace of its own, all on one
//! bridge, as real robots on one Wi-Fi: DDS finds its peers by multicast across the bridge
//! (nothing tells a participant where another is), and the controllers' BLE claims go to the
//! subnet's broadcast. Every namespace's packet filter drops 10 % of the UDP it receives at
//! random (nftables `numgen random`: this kernel has no netem), so both the ROS 2 traffic (sensors,
//! `cmd_vel`, the simulator's word) and the Ayllu traffic (claims) cross a lossy network. One
//! scenario file, given to the server and to every robot, kills the most useful robot halfway.
//!
//! Checks, on the server's lines, the robots' status lines and the filters' counters:
//! * every body heard its controller before the world started (the server's `missing` is empty:
//!   DDS discovery crossed the bridge), and every controller heard the other two over Ayllu;
//! * the loss was applied to both kinds of traffic: in every namespace about 10 % of the DDS
//!   datagrams and of the Ayllu datagrams received were dropped;
//! * (a) A_w lies within the spread of in-process runs of the same scenario, with the network's
//!   loss as its radio model (wander seeds 1..=30, the world's seed fixed), widened by [`SLACK`];
//! * (b) the kill: the server announced it at the scenario's instant; the killed robot's process
//!   heard `/robotK/ayllu/alive` go 0 and stopped by itself (exit 0, `killed` in its last line)
//!   long before the run's end; the metrics judged a task lost with it (`recover_s`) and every
//!   such task re-covered by the survivors before the end (`unrecovered` 0); the highest-priority
//!   target the killed robot claimed is claimed by a survivor after the kill (the BLE handover,
//!   seen on the controllers' side);
//! * every surviving robot stops by itself once the server is gone.
//!
//! Needs root, `ip` and `nft` (scripts/install-test-tools installs nftables): without them it
//! fails, naming what is missing. Built only with `--features ros2` (`make test-ros2`). Bounded:
//! 100 s of world time on the real clock; the whole test takes about 105 s.

#![cfg(feature = "ros2")]

use crate::common;

use std::path::PathBuf;
use std::process::Command;
use std::time::{Duration, Instant};

use ayllu_sim::scenario::run;
use ayllu_sim::scenario_file;
use common::netns::Netns;
use common::{wait_for, Proc, BIN};
use serde_json::Value as Json;

const ROBOTS: usize = 3;
const TARGETS: usize = 4;
/// A world where the team's coverage is steady and a kill halfway is re-covered. Measured
/// in-process (BLE, 100 s, radio loss 0.1, the most useful robot killed at 50 s) over wander
/// seeds 1..=30: A_w 0.496-0.659 (mean 0.586), recover_s 4.4-27.2 s, no task left unrecovered;
/// Random (blind wandering) 0.020-0.187, Local 0.442-0.620.
const SEED: u64 = 6;
/// World seconds (paced on the real clock); the kill comes at half.
const DURATION: f64 = 100.0;
/// Percent of the UDP datagrams each namespace receives that its filter drops.
const LOSS_PERCENT: u32 = 10;
/// The ROS domain of the fleet (`sim serve --domain`, the robots' `ROS_DOMAIN_ID`). Its DDS
/// ports are `7400 + 250·d` to `+ 249` (RTPS's port mapping); the filter counts them apart.
const DOMAIN: u16 = 42;
/// The controllers' Ayllu port, outside the domain's DDS ports.
const AYLLU_PORT: u16 = 7300;
/// Wander seeds of the in-process reference runs.
const WANDER_SEEDS: u64 = 30;
/// How far outside the in-process range of A_w the run may fall. The distributed run is one
/// more draw of the same world, but not the simulator's lockstep: the world starts when the
/// three `cmd_vel` streams arrive, the controllers act on each sensing a few milliseconds later,
/// their sensor samples (best-effort DDS) are lost at 10 % too while in-process sensing is
/// lossless, and their wander draws follow the real clock. sim_distributed_scenario.rs allows
/// 0.12 on a 30 s run; this run is over three times longer, so its A_w averages more. Measured
/// here (2026-12-01, four runs on a 2-CPU machine shared with other builds): A_w 0.553, 0.604,
/// 0.616, 0.657, each inside the in-process range itself. It fails for a team that does not see
/// its targets or does not drive for a good part of the run: Random reaches at most 0.187 in
/// this world; runs whose survivors stopped early (a bug since fixed in `sim robot`: a scan or
/// two lost on the network was taken for the server gone) gave 0.301, rejected, and 0.408, just
/// accepted (the survivors' check fails such a run).
const SLACK: f64 = 0.10;
/// Status lines of the robots: twice a second, fine enough to see claims hand over.
const STATUS_MS: &str = "500";

/// The scenario: BLE, the most useful robot killed halfway. `radio_loss`: the in-process
/// reference's radio model of the filters' loss (the distributed run has none of its own: the
/// network loses).
fn scenario_text(radio_loss: Option<f64>) -> String {
    let radio = radio_loss.map(|l| format!("[radio]\nloss = {l}\n")).unwrap_or_default();
    format!(
        "controller = \"BLE\"\nrobots = {ROBOTS}\ntargets = {TARGETS}\nseed = {SEED}\nduration = {DURATION}\n\
         {radio}[[kills]]\nat = {}\n",
        DURATION / 2.0
    )
}

/// The in-process figures of the same scenario, over wander seeds 1..=[`WANDER_SEEDS`].
struct Reference {
    lo: f64,
    hi: f64,
    mean: f64,
    recover: (f64, f64),
    unrecovered: u32,
    msgs: f64,
}

fn reference() -> Reference {
    let base = scenario_file::scenario(&scenario_text(Some(f64::from(LOSS_PERCENT) / 100.0)))
        .expect("the reference scenario reads");
    let mut r = Reference {
        lo: f64::INFINITY,
        hi: f64::NEG_INFINITY,
        mean: 0.0,
        recover: (f64::INFINITY, f64::NEG_INFINITY),
        unrecovered: 0,
        msgs: 0.0,
    };
    let n = WANDER_SEEDS as f64;
    for w in 1..=WANDER_SEEDS {
        let mut s = base.clone();
        s.controllers.wander_seed = w;
        let m = run(&s).expect("in-process run").metrics;
        r.lo = r.lo.min(m.a_w);
        r.hi = r.hi.max(m.a_w);
        r.mean += m.a_w / n;
        r.msgs += m.msgs_per_robot_s / n;
        if let Some(s) = m.recover_s {
            r.recover = (r.recover.0.min(s), r.recover.1.max(s));
        }
        r.unrecovered += m.unrecovered;
    }
    r
}

/// The DDS ports of [`DOMAIN`], as an nftables range.
fn dds_ports() -> String {
    let base = 7400 + 250 * u32::from(DOMAIN);
    format!("{base}-{}", base + 249)
}

/// Namespace `i`'s filter: count the Ayllu and the DDS datagrams received from the bridge, and
/// drop [`LOSS_PERCENT`] % of every UDP datagram received from it at random (a fresh draw per
/// datagram), counting the drops of each kind. Loopback inside a namespace is left alone.
fn lossy(net: &Netns, i: usize, dir: &std::path::Path) -> Result<(), String> {
    let (dds, ayllu) = (dds_ports(), AYLLU_PORT);
    let rules = format!(
        "table inet ayllu {{\n\
         counter ayllu_in {{}}\ncounter ayllu_lost {{}}\ncounter dds_in {{}}\ncounter dds_lost {{}}\n\
         chain input {{\n\
           type filter hook input priority 0;\n\
           iifname \"lo\" accept\n\
           udp dport {ayllu} counter name \"ayllu_in\"\n\
           udp dport {dds} counter name \"dds_in\"\n\
           meta l4proto udp numgen random mod 100 < {LOSS_PERCENT} jump lost\n\
         }}\n\
         chain lost {{\n\
           udp dport {ayllu} counter name \"ayllu_lost\" drop\n\
           udp dport {dds} counter name \"dds_lost\" drop\n\
           drop\n\
         }}\n\
         }}\n"
    );
    let file = dir.join("loss.nft");
    std::fs::write(&file, rules).map_err(|e| format!("writing {}: {e}", file.display()))?;
    net.exec(i, "nft", &["-f", file.to_str().expect("UTF-8 path")])
}

/// Namespace `i`'s counters: (Ayllu received, Ayllu dropped, DDS received, DDS dropped).
fn counters(net: &Netns, i: usize) -> (u64, u64, u64, u64) {
    let out = net.command(i, "nft").args(["-j", "list", "counters", "table", "inet", "ayllu"]).output();
    let out = out.unwrap_or_else(|e| panic!("running nft: {e}"));
    assert!(out.status.success(), "nft list counters: {}", String::from_utf8_lossy(&out.stderr));
    let j: Json = serde_json::from_slice(&out.stdout).expect("nft -j prints JSON");
    let packets = |name: &str| {
        j["nftables"]
            .as_array()
            .into_iter()
            .flatten()
            .find(|e| e["counter"]["name"] == name)
            .and_then(|e| e["counter"]["packets"].as_u64())
            .unwrap_or_else(|| panic!("no counter {name} in {j}"))
    };
    (packets("ayllu_in"), packets("ayllu_lost"), packets("dds_in"), packets("dds_lost"))
}

fn example(name: &str) -> String {
    format!("{}/../../examples/ros2/{name}", env!("CARGO_MANIFEST_DIR"))
}

fn claims(j: &Json) -> Vec<u64> {
    j["claims"].as_array().map(|a| a.iter().filter_map(Json::as_u64).collect()).unwrap_or_default()
}

/// Every line of every process, as read (seconds since `since`, then the line), into
/// `dir/NAME.jsonl`: what a failure is diagnosed from (the folder is removed on success).
fn keep_lines(procs: &[Proc], since: Instant, dir: &std::path::Path) {
    for p in procs {
        let text: String = p
            .lines()
            .iter()
            .map(|(t, j)| format!("{:.3} {j}\n", t.saturating_duration_since(since).as_secs_f64()))
            .collect();
        let _ = std::fs::write(dir.join(format!("{}.jsonl", p.name)), text);
        let _ = std::fs::write(dir.join(format!("{}.stderr", p.name)), p.stderr());
    }
}

fn diagnostics(procs: &[Proc]) -> String {
    let mut s = String::new();
    for p in procs {
        let tail: Vec<String> = p.lines().iter().rev().take(3).map(|(_, j)| j.to_string()).collect();
        s.push_str(&format!("--- {}: last lines {tail:#?}\nstderr: {}\n", p.name, p.stderr()));
    }
    s
}

#[test]
fn cmommt_over_ros2_in_namespaces_with_loss_and_a_kill_matches_in_process() {
    let started = Instant::now();
    // What the test needs, or a failure that names it (it never passes by skipping).
    let nft = Command::new("nft").arg("--version").output();
    assert!(
        nft.is_ok_and(|o| o.status.success()),
        "`nft` (nftables) is missing: the loss is applied by its packet filter; scripts/install-test-tools installs it"
    );
    // Namespace 0 hosts the server, k the controller of robot k.
    let net = Netns::create("rc", 86, ROBOTS + 1).unwrap_or_else(|reason| {
        panic!("this test needs network namespaces on a bridge (root and `ip` from iproute2): {reason}")
    });
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("ros2_cmommt-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch folder");
    for i in 0..=ROBOTS {
        lossy(&net, i, &dir).unwrap_or_else(|e| panic!("nftables in namespace {}: {e}", net.ns(i)));
    }
    // The in-process reference first, so it does not compete with the real-time processes.
    let reference = reference();
    let file = dir.join("scenario.toml");
    std::fs::write(&file, scenario_text(None)).expect("writing the scenario");
    let file = file.to_str().expect("UTF-8 path").to_owned();

    // Declared after `net`, so the processes die before their namespaces go.
    let mut procs = Vec::new();
    let mut cmd = net.command(0, BIN);
    cmd.args(["sim", "serve", "--ros2", "--domain", &DOMAIN.to_string(), "--scenario", &file, "--wait", "20"]);
    procs.push(Proc::spawn("server", cmd));
    let broadcast = format!("{}:{AYLLU_PORT}", net.broadcast());
    for k in 1..=ROBOTS {
        let url = format!("udp://{}:{AYLLU_PORT}?broadcast={broadcast}", net.addr(k));
        let mut cmd = net.command(k, BIN);
        cmd.args(["sim", "robot", "--id", &k.to_string(), "--ros2", &example("sim-robot.toml")])
            .args(["--scenario", &file, "--udp", &url, "--status-ms", STATUS_MS])
            .args(["--duration", &(DURATION + 60.0).to_string()])
            .env("ROS_DOMAIN_ID", DOMAIN.to_string());
        procs.push(Proc::spawn(&format!("robot{k}"), cmd));
    }

    // The run: startup, the server's wait for its controllers, the world on the real clock.
    let limit = Duration::from_secs_f64(DURATION + 60.0);
    let done =
        wait_for(limit, Duration::from_millis(100), || procs[0].lines().into_iter().find(|(_, j)| j["done"] == true));
    let Some((done_at, done)) = done else {
        keep_lines(&procs, started, &dir);
        panic!("the server did not finish within {limit:?} (lines in {})\n{}", dir.display(), diagnostics(&procs));
    };
    keep_lines(&procs, started, &dir);
    let lines = procs[0].lines();
    let start = lines.first().expect("a start line precedes done").1.clone();
    let m = &done["metrics"];
    let a_w = m["a_w"].as_f64().expect("metrics.a_w");
    let recover = m["recover_s"].as_f64();
    let unrecovered = m["unrecovered"].as_u64();
    let kill = lines.iter().find(|(_, j)| j.get("kill").is_some()).cloned();
    let (kill_at, kill) = kill.unwrap_or_else(|| panic!("no kill line\n{}", diagnostics(&procs)));
    let killed = kill["kill"].as_u64().expect("the kill names its robot") as usize;
    assert!((1..=ROBOTS).contains(&killed), "{kill}");
    // The killed robot has had the second half of the run to stop; the survivors stop once the
    // server is gone (their sonar stays stale).
    let mut exits = Vec::new();
    for r in procs.iter_mut().skip(1) {
        exits.push(wait_for(Duration::from_secs(30), Duration::from_millis(100), || r.exited()));
    }
    keep_lines(&procs, started, &dir);
    let victim = &procs[killed];
    let (last_at, last) = victim.latest().expect("the killed robot's lines");
    // When its last line was read, after (or, by the readers' scheduling, just before) the
    // server's kill line.
    let stopped_after = match last_at.checked_duration_since(kill_at) {
        Some(d) => d.as_secs_f64(),
        None => -kill_at.duration_since(last_at).as_secs_f64(),
    };
    // The BLE handover on the controllers' side: the highest-priority target the killed robot
    // claimed when it died, claimed by a survivor afterwards (seconds after the kill).
    let lost_claim = claims(&last).into_iter().min();
    let survivors: Vec<&Proc> = (1..=ROBOTS).filter(|&k| k != killed).map(|k| &procs[k]).collect();
    let taken_over = lost_claim.and_then(|target| {
        survivors
            .iter()
            .flat_map(|r| r.lines())
            .filter(|(t, j)| *t > kill_at && claims(j).contains(&target))
            .map(|(t, _)| t.saturating_duration_since(kill_at).as_secs_f64())
            .reduce(f64::min)
    });
    // The filters' counters, per namespace: (Ayllu received, dropped, DDS received, dropped).
    let filters: Vec<(u64, u64, u64, u64)> = (0..=ROBOTS).map(|i| counters(&net, i)).collect();
    let bodies: Vec<String> = procs[1..]
        .iter()
        .enumerate()
        .filter_map(|(i, r)| {
            let b = r.latest()?.1["body_counters"].clone();
            let n = |what: &str| b[format!("/robot{}/{what}", i + 1)].as_u64().unwrap_or(0);
            Some(format!(
                "{}: scans taken {}, cmd_vel published {}, alive taken {}",
                r.name,
                n("scan taken"),
                n("cmd_vel published"),
                n("ayllu/alive taken")
            ))
        })
        .collect();
    let percent = |lost: u64, seen: u64| 100.0 * lost as f64 / seen.max(1) as f64;
    eprintln!(
        "CMOMMT over ROS 2: {ROBOTS} robots in namespaces on a bridge, {LOSS_PERCENT} % of received UDP dropped by \
         nftables, the most useful robot killed at {}s\n  A_w {a_w:.3}; in-process (radio loss {}, wander seeds \
         1..={WANDER_SEEDS}) {:.3}..{:.3} (mean {:.3}); accepted {:.3}..{:.3}\n  kill: robot {killed}, its process \
         stopped by itself {stopped_after:+.3}s from the server's kill line; recover_s {} (in-process {:.1}..{:.1}), \
         unrecovered {} (in-process {} over {WANDER_SEEDS} runs); its top claim {lost_claim:?} claimed by a survivor \
         {} s after the kill\n  msgs/robot/s {} (in-process mean {:.2}), switches/min {}, resyncs {}, the server \
         waited {}s for its controllers\n  dropped by the filters (Ayllu, DDS): {}\n  {}\n  took {:.1}s",
        DURATION / 2.0,
        f64::from(LOSS_PERCENT) / 100.0,
        reference.lo,
        reference.hi,
        reference.mean,
        reference.lo - SLACK,
        reference.hi + SLACK,
        m["recover_s"],
        reference.recover.0,
        reference.recover.1,
        m["unrecovered"],
        reference.unrecovered,
        taken_over.map_or("-".to_owned(), |s| format!("{s:.1}")),
        m["msgs_per_robot_s"],
        reference.msgs,
        m["switches_per_min"],
        done["resyncs"],
        start["waited"],
        filters
            .iter()
            .enumerate()
            .map(|(i, (a, al, d, dl))| format!(
                "{}: {al}/{a} ({:.1} %), {dl}/{d} ({:.1} %)",
                if i == 0 { "server".to_owned() } else { format!("robot{i}") },
                percent(*al, *a),
                percent(*dl, *d)
            ))
            .collect::<Vec<_>>()
            .join("; "),
        bodies.join("; "),
        started.elapsed().as_secs_f64(),
    );
    eprintln!("every process's lines: {}", dir.display());

    // The verdicts. DDS found every controller across the bridge (by multicast: nothing else
    // tells a participant where the others are), and the controllers each other.
    assert_eq!(
        start["missing"],
        serde_json::json!([]),
        "a body never heard its controller's cmd_vel (DDS discovery across the bridge?): {start}\n{}",
        diagnostics(&procs)
    );
    for r in &procs[1..] {
        let heard = r.lines().iter().any(|(_, j)| j["peers"].as_array().is_some_and(|p| p.len() == ROBOTS - 1));
        assert!(heard, "{} never heard both other controllers\n{}", r.name, diagnostics(&procs));
    }
    // The loss hit both kinds of traffic in every namespace: at 10 % of thousands of datagrams
    // per kind and namespace, the share dropped lies within 10 ± 1 % but for a fluke of many
    // standard deviations; 5-15 % says the filter was applied to that traffic at the rate written.
    for (i, &(a_in, a_lost, d_in, d_lost)) in filters.iter().enumerate() {
        for (kind, seen, lost) in [("Ayllu", a_in, a_lost), ("DDS", d_in, d_lost)] {
            assert!(seen >= 500, "namespace {i}: only {seen} {kind} datagrams received: too few to judge");
            let share = lost as f64 / seen as f64;
            assert!(
                (0.05..=0.15).contains(&share),
                "namespace {i}: {:.1} % of the {kind} datagrams dropped, the filter says {LOSS_PERCENT} %",
                share * 100.0
            );
        }
    }
    // Every process stopped by itself, cleanly; the survivors only once the run was over (a scan
    // or two lost is no server gone).
    for (k, exit) in (1..=ROBOTS).zip(&exits) {
        let r = &procs[k];
        let status = exit.unwrap_or_else(|| panic!("{} outlived its server: {}", r.name, r.stderr()));
        assert!(status.success(), "{} ended with {status}: {}", r.name, r.stderr());
        if k != killed {
            let lived = r.lines().iter().any(|(t, _)| *t >= done_at);
            assert!(lived, "{} stopped before the run's end: {}", r.name, r.stderr());
        }
    }
    // (a) Coverage as in-process.
    assert!(
        a_w >= reference.lo - SLACK && a_w <= reference.hi + SLACK,
        "A_w {a_w:.3} outside the in-process spread {:.3}..{:.3} (± {SLACK})\n{}",
        reference.lo,
        reference.hi,
        diagnostics(&procs)
    );
    // (b) The kill: at the scenario's instant; the robot heard `/robotK/ayllu/alive` go 0 and
    // stopped at once (its last line says so, and it had taken the topic)...
    assert!((kill["t"].as_f64().unwrap_or(-1.0) - DURATION / 2.0).abs() < 0.06, "{kill}");
    assert_eq!(last["killed"], true, "robot {killed} did not stop for its kill: {last}\n{}", victim.stderr());
    let alive_taken = last["body_counters"][format!("/robot{killed}/ayllu/alive taken")].as_u64().unwrap_or(0);
    assert!(alive_taken > 0, "robot {killed} never took /robot{killed}/ayllu/alive: {last}");
    // ... the kill lost a task, and every task lost with the robot was re-covered before the end
    // (in-process: in every one of the 30 runs, within 27.2 s of the 50 s left) ...
    assert!(recover.is_some(), "the kill lost no task to re-cover (the most useful robot saw nothing?): {m}");
    assert_eq!(unrecovered, Some(0), "a task lost with robot {killed} was never re-covered: {m}");
    // ... and a survivor took over the killed robot's best claim.
    if let Some(target) = lost_claim {
        assert!(
            taken_over.is_some(),
            "robot {killed} claimed target {target} when it died, and no survivor claimed it afterwards\n{}",
            diagnostics(&procs)
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
