//! The paper's cross-subsumption with every robot a real OS process on real sockets: three
//! `ayllu node` processes (the stdlib controller, 4 layers, BLE at 1 Hz, the paper's sight
//! table), watched through their JSON status lines.
//!
//! Checks, on loopback (group delivered by unicast to the peers that announced it in HELLO)
//! and in network namespaces joined by a bridge (group delivered by real subnet broadcast):
//! * settled, each node is driven by its highest unclaimed layer (n1: 1, n2: 2, n3: 3) and
//!   every target has exactly one claimer (T1 n1, T2 n2, T3 n3, T4 n3), steadily;
//! * after n1's process is SIGKILLed, n2 is driven by layer 1 within the inhibit period plus
//!   one BLE cycle, and not before n1's last lease ran out (inhibit period less the cycles
//!   since its last renewal).
//!   Process scheduling adds delay the in-process test does not have, so every limit is
//!   derived from the configured periods with room for a busy machine (see [`Bounds`]), never
//!   from how fast this machine was; the measured times are printed.
//!
//! The namespace variants need root and `ip` (and nftables, /dev/net/tun); without them they
//! fail, naming what is missing, unless `AYLLU_SKIP` asks to skip it ([`common::unavailable`]).

use crate::common;

use std::time::{Duration, Instant};

use ayllu::BleConfig;
use common::netns::Netns;
use common::{ayllu, start_on_loopback, unavailable, wait_for, Proc, BIN};
use serde_json::Value as Json;

const SIGHT: [&str; 3] = ["1:0.9,2:0.5", "1:0.6,2:0.8,3:0.4", "3:0.7,4:0.5"];
const CLAIM_HZ: f64 = 1.0;
/// Each node's status period (`--status-ms`).
const STATUS: Duration = Duration::from_millis(100);

/// The limits of the checks, all derived from the claim rate and the inhibit period BLE
/// derives from it (1 Hz: cycle 1 s, inhibit 2.25 s).
struct Bounds {
    /// One BLE cycle.
    cycle: Duration,
    /// The protocol's take-over bound: the dead node's last lease (`inhibit`) plus the cycle in
    /// which the next claimer claims.
    takeover: Duration,
    /// The take-over may not come before this: the dead node renewed its lease at most one
    /// cycle before it died (two, if a busy machine made it miss one renewal), and the lease
    /// lasts `inhibit`.
    lease_floor: Duration,
    /// Room on top of the take-over bound for scheduling and for reading status lines: one
    /// whole bound more (a node would have to be starved of the CPU for a whole lease to miss
    /// it, which a busy 2-core machine does not do) plus one status period.
    margin: Duration,
    /// Starting from nothing, the team agrees within this: HELLOs both ways, then each layer
    /// claimed in turn; 20 cycles (measured: 1-2 s).
    settle: Duration,
}

impl Bounds {
    fn new() -> Bounds {
        let inhibit = BleConfig::new("Peers", "Rotate", CLAIM_HZ).unwrap().inhibit_period;
        let cycle = Duration::from_nanos(ayllu::Duration::try_from_hz(CLAIM_HZ).unwrap().as_nanos());
        let inhibit = Duration::from_nanos(inhibit.as_nanos());
        let takeover = inhibit + cycle;
        Bounds { cycle, takeover, lease_floor: inhibit - cycle * 2, margin: takeover + STATUS, settle: cycle * 20 }
    }
}

/// `ayllu node` arguments for node `id` (1-based) of the paper's team, running 40 s.
fn node_args(id: u32, url: &str) -> Vec<String> {
    node_args_for(id, url, 40)
}

/// As [`node_args`], running `secs` seconds.
fn node_args_for(id: u32, url: &str, secs: u32) -> Vec<String> {
    let secs = secs.to_string();
    [
        "node",
        "--id",
        &id.to_string(),
        "--udp",
        url,
        "--controller",
        "cross-subsumption",
        "--layers",
        "4",
        "--claim-hz",
        &CLAIM_HZ.to_string(),
        "--sight",
        SIGHT[id as usize - 1],
        "--status-ms",
        &STATUS.as_millis().to_string(),
        "--for",
        &secs,
    ]
    .iter()
    .map(|s| s.to_string())
    .collect()
}

fn drive(j: &Json) -> u64 {
    j["drive"].as_u64().unwrap_or(u64::MAX)
}

fn claims(j: &Json) -> Vec<u64> {
    j["claims"].as_array().map(|a| a.iter().filter_map(Json::as_u64).collect()).unwrap_or_default()
}

/// Whether the latest status of the live nodes shows `drives` (node id, layer) and exactly the
/// claimers `claimers[target-1]`. `Err` says what differs.
fn state_is(nodes: &[&Proc], drives: &[(u64, u64)], claimers: &[u64; 4]) -> Result<(), String> {
    let latest: Vec<Json> = nodes
        .iter()
        .map(|p| p.latest().map(|(_, j)| j).ok_or_else(|| format!("{} printed nothing yet", p.name)))
        .collect::<Result<_, _>>()?;
    for &(id, layer) in drives {
        let j = latest.iter().find(|j| j["node"].as_u64() == Some(id)).ok_or(format!("no status from n{id}"))?;
        if drive(j) != layer {
            return Err(format!("n{id} driven by layer {}, expected {layer}", drive(j)));
        }
    }
    for (t, &want) in claimers.iter().enumerate() {
        let target = t as u64 + 1;
        let by: Vec<u64> =
            latest.iter().filter(|j| claims(j).contains(&target)).filter_map(|j| j["node"].as_u64()).collect();
        if by != [want] {
            return Err(format!("T{target} claimed by {by:?}, expected [{want}]"));
        }
    }
    Ok(())
}

/// Start, settle, check, kill n1, check the take-over. `nodes` are n1, n2, n3 in order;
/// `why_n2` asks the CLI to explain n2's OBS1.Rotate (held off by n1's claim).
fn settle_and_kill(label: &str, mut nodes: Vec<Proc>, why_n2: impl Fn() -> common::Run) {
    let bounds = Bounds::new();
    let started = Instant::now();
    for n in &mut nodes {
        n.wait_ready();
    }
    let settled_drives = [(1, 1), (2, 2), (3, 3)];
    let settled_claims = [1, 2, 3, 3];
    // Settled: the whole expected state at once.
    let mut last = String::new();
    let ok = wait_for(bounds.settle, Duration::from_millis(50), || {
        let refs: Vec<&Proc> = nodes.iter().collect();
        match state_is(&refs, &settled_drives, &settled_claims) {
            Ok(()) => Some(()),
            Err(e) => {
                last = e;
                None
            }
        }
    });
    assert!(ok.is_some(), "{label}: never settled within {:?}: {last}\n{}", bounds.settle, diagnostics(&nodes));
    let settle_time = started.elapsed();
    // ... and stays so for a cycle and a half (claims are leases renewed every cycle; nothing
    // may flap).
    let hold_until = Instant::now() + bounds.cycle * 3 / 2;
    while Instant::now() < hold_until {
        std::thread::sleep(STATUS);
        let refs: Vec<&Proc> = nodes.iter().collect();
        if let Err(e) = state_is(&refs, &settled_drives, &settled_claims) {
            panic!("{label}: settled state did not hold: {e}\n{}", diagnostics(&nodes));
        }
    }

    // The CLI sees why n2's OBS1 is quiet: n1's claim write-inhibits it.
    let why = why_n2().ok().json();
    assert_eq!(why["internal_output_blocked"], "WriteInhibited", "{why}");
    let windows = why["windows"].as_array().cloned().unwrap_or_default();
    assert!(
        windows.iter().any(|w| w["kind"] == "WriteInhibit" && w["holder"]["node"] == 1),
        "n2's OBS1.Rotate should be write-inhibited by n1: {why}"
    );

    // Kill n1: its claims are leases and lapse; n2 sees target 1 and takes over.
    let killed_at = Instant::now();
    nodes[0].kill();
    let took = wait_for(bounds.takeover + bounds.margin * 2, Duration::from_millis(20), || {
        nodes[1].lines().into_iter().find(|(t, j)| *t > killed_at && drive(j) == 1).map(|(t, _)| t - killed_at)
    });
    let took = took.unwrap_or_else(|| panic!("{label}: n2 never took over target 1\n{}", diagnostics(&nodes)));
    eprintln!(
        "{label}: settled {:.2}s after start; n2 driven by layer 1 {:.3}s after n1 was killed \
         (protocol bound {:?}, lease floor {:?}, asserted with {:?} margin)",
        settle_time.as_secs_f64(),
        took.as_secs_f64(),
        bounds.takeover,
        bounds.lease_floor,
        bounds.margin,
    );
    assert!(
        took <= bounds.takeover + bounds.margin,
        "{label}: took {took:?}, bound {:?} + margin {:?}",
        bounds.takeover,
        bounds.margin
    );
    // The lease held while it was valid. Delays only make `took` longer, so this floor needs
    // no margin.
    assert!(took >= bounds.lease_floor, "{label}: took over after only {took:?}: the lease did not hold");

    // Settled again without n1: n2 claims T1 and T2 and is driven by layer 1, n3 unchanged.
    let mut last = String::new();
    let ok = wait_for(bounds.takeover + bounds.margin, Duration::from_millis(50), || {
        match state_is(&[&nodes[1], &nodes[2]], &[(2, 1), (3, 3)], &[2, 2, 3, 3]) {
            Ok(()) => Some(()),
            Err(e) => {
                last = e;
                None
            }
        }
    });
    assert!(ok.is_some(), "{label}: did not settle without n1: {last}\n{}", diagnostics(&nodes));
}

fn diagnostics(nodes: &[Proc]) -> String {
    let mut s = String::new();
    for n in nodes {
        let tail: Vec<String> = n.lines().iter().rev().take(3).map(|(_, j)| j.to_string()).collect();
        s.push_str(&format!("--- {}: last lines {tail:#?}\nstderr: {}\n", n.name, n.stderr()));
    }
    s
}

#[test]
fn three_processes_on_loopback_settle_and_survive_a_kill() {
    let (nodes, addrs) = start_on_loopback(3, |k| format!("n{}", k + 1), |k, url| node_args(k as u32 + 1, url));
    let cli_url = format!("udp://127.0.0.1:0?peer={}", addrs[1]);
    settle_and_kill("loopback", nodes, || {
        ayllu(&["why", "2", "OBS1.Rotate", "--json", "--udp", &cli_url], Duration::from_secs(10))
    });
}

#[test]
fn three_processes_in_network_namespaces_use_real_subnet_broadcast() {
    let net = match Netns::create("ay", 77, 3) {
        Ok(net) => net,
        Err(reason) => return unavailable("netns", &reason),
    };
    // Declared after `net`, so the processes die before their namespaces go.
    let nodes: Vec<Proc> = (1..=3)
        .map(|i| {
            let url = format!("udp://10.77.0.{i}:7400?broadcast=10.77.0.255:7400");
            let mut cmd = net.command(i - 1, BIN);
            cmd.args(node_args(i as u32, &url));
            Proc::spawn(&format!("n{i}"), cmd)
        })
        .collect();
    // The CLI finds the team by broadcast too: from n2's namespace, no peer given.
    let in_ns2 = |args: &[&str]| {
        let mut cmd = net.command(1, BIN);
        cmd.args(args);
        common::run(cmd, Duration::from_secs(10))
    };
    let broadcast_url = "udp://0.0.0.0:0?broadcast=10.77.0.255:7400";
    settle_and_kill("netns broadcast", nodes, || {
        let heard = in_ns2(&["list", "--json", "--udp", broadcast_url]).ok().json();
        let ids: Vec<u64> = heard.as_array().unwrap().iter().filter_map(|p| p["node"].as_u64()).collect();
        assert_eq!(ids, [1, 2, 3], "list by broadcast should hear every node: {heard}");
        let groups = &heard[0]["groups"];
        assert_eq!(groups, &serde_json::json!(["Peers"]), "{heard}");
        in_ns2(&["why", "2", "OBS1.Rotate", "--json", "--udp", broadcast_url])
    });
}

/// The packet filter of namespace `i`: a table with an input and an output chain, the input
/// dropping `loss` % of UDP at random (`numgen random`).
fn filter(net: &Netns, i: usize, loss: u32) -> Result<(), String> {
    let nft = |args: &[&str]| net.exec(i, "nft", args);
    nft(&["add", "table", "inet", "ayllu"])?;
    nft(&["add", "chain", "inet", "ayllu", "input", "{ type filter hook input priority 0; }"])?;
    nft(&["add", "chain", "inet", "ayllu", "output", "{ type filter hook output priority 0; }"])?;
    random_loss(net, i, loss)
}

/// The rule dropping `loss` % of namespace `i`'s incoming UDP.
fn random_loss(net: &Netns, i: usize, loss: u32) -> Result<(), String> {
    let loss = loss.to_string();
    let rule =
        ["add", "rule", "inet", "ayllu", "input", "meta", "l4proto", "udp", "numgen", "random", "mod", "100", "<"];
    net.exec(i, "nft", &[&rule[..], &[&loss, "drop"]].concat())
}

/// Cut namespace `i` off (every UDP datagram in and out dropped), or heal it (back to `loss`).
fn partition(net: &Netns, i: usize, cut: bool, loss: u32) -> Result<(), String> {
    let nft = |args: &[&str]| net.exec(i, "nft", args);
    nft(&["flush", "chain", "inet", "ayllu", "input"])?;
    nft(&["flush", "chain", "inet", "ayllu", "output"])?;
    if cut {
        nft(&["add", "rule", "inet", "ayllu", "input", "meta", "l4proto", "udp", "drop"])?;
        nft(&["add", "rule", "inet", "ayllu", "output", "meta", "l4proto", "udp", "drop"])
    } else {
        random_loss(net, i, loss)
    }
}

/// A node that printed no status line for this long (on its own clock, or as the test read
/// them) was starved of the CPU: its BLE select ran late too.
const STALL: Duration = Duration::from_millis(300);

/// Whether `node` ran on time through the `lease` before `at`: its status lines (every
/// [`STATUS`]) came with no gap over [`STALL`], on its clock and as read. A claim is a lease:
/// a node starved for longer than it (a loaded machine, the test's own reader behind) stops
/// renewing, and its peers rightly claim its target. Those instants say nothing about the
/// protocol, only about the machine, so the double-claim share leaves them out.
fn on_time(lines: &[(Instant, Json)], at: Instant, lease: Duration) -> bool {
    let first = lines.iter().rposition(|(t, _)| *t + lease <= at).unwrap_or(0);
    let last = match lines.iter().rposition(|(t, _)| *t <= at) {
        Some(last) if at.duration_since(lines[last].0) <= STALL => last,
        _ => return false,
    };
    let node_t = |j: &Json| j["t"].as_f64().unwrap_or(f64::NAN);
    lines[first..=last]
        .windows(2)
        .all(|w| w[1].0.duration_since(w[0].0) <= STALL && node_t(&w[1].1) - node_t(&w[0].1) <= STALL.as_secs_f64())
}

/// Double claims among status lines: of the instants (status lines of the live nodes, from
/// `from` on) at which every node ran on time through the last `lease` ([`on_time`]), the
/// fraction at which some target is claimed by two nodes, taking each node's latest line at that
/// instant; and how many instants were on time, and how many not.
fn double_claims(nodes: &[&Proc], from: Instant, lease: Duration) -> (f64, usize, usize) {
    let lines: Vec<Vec<(Instant, Json)>> = nodes.iter().map(|p| p.lines()).collect();
    let all: Vec<Instant> = lines.iter().flatten().map(|(t, _)| *t).filter(|t| *t >= from).collect();
    let instants: Vec<Instant> =
        all.iter().copied().filter(|&at| lines.iter().all(|l| on_time(l, at, lease))).collect();
    let mut doubled = 0;
    for &at in &instants {
        let mut count = [0u32; 5];
        for node in &lines {
            if let Some((_, j)) = node.iter().rev().find(|(t, _)| *t <= at) {
                for c in claims(j) {
                    if let Some(n) = count.get_mut(c as usize) {
                        *n += 1;
                    }
                }
            }
        }
        if count.iter().any(|&n| n > 1) {
            doubled += 1;
        }
    }
    (doubled as f64 / instants.len().max(1) as f64, instants.len(), all.len() - instants.len())
}

/// [`double_claims`] from now on, over at least 5 cycles and until 30 instants were on time
/// (at most a minute: a machine that starves the nodes that long fails the test, saying so).
fn sample_double_claims(nodes: &[Proc], bounds: &Bounds) -> (f64, usize, usize) {
    let from = Instant::now();
    std::thread::sleep(bounds.cycle * 5);
    let live: Vec<&Proc> = nodes.iter().collect();
    loop {
        let sample = double_claims(&live, from, bounds.takeover);
        if sample.1 >= 30 || from.elapsed() > Duration::from_secs(60) {
            return sample;
        }
        std::thread::sleep(bounds.cycle);
    }
}

#[test]
fn three_processes_with_loss_a_partition_and_a_kill_keep_the_arbitration_properties() {
    // Issue "open teams": the paper's team in namespaces with 30 % of every node's incoming UDP
    // dropped by the kernel's packet filter, then node 1 cut off, then healed and node 3
    // killed. Checked from the recorded claims, with limits from the BLE periods (Bounds):
    // * settled despite the loss, and double claims rare (a claim lost twice in a row lets a
    //   peer claim for a moment: at most a fifth of the instants);
    // * a node that cannot hear its peers loses its hold on them within its lease: n2 takes
    //   target 1 within the take-over bound after n1 is cut off;
    // * a killed claimer's task is re-claimed within the bound: n2 claims target 3 after n3 dies.
    const LOSS: u32 = 30;
    let net = match Netns::create("ft", 83, 3) {
        Ok(net) => net,
        Err(reason) => return unavailable("netns", &reason),
    };
    if let Err(reason) = (0..3).try_for_each(|i| filter(&net, i, LOSS)) {
        return unavailable("nft", &reason);
    }
    let bounds = Bounds::new();
    let mut nodes: Vec<Proc> = (1..=3)
        .map(|i| {
            let url = format!("udp://10.83.0.{i}:7400?broadcast=10.83.0.255:7400");
            let mut cmd = net.command(i - 1, BIN);
            cmd.args(node_args_for(i as u32, &url, 90));
            Proc::spawn(&format!("n{i}"), cmd)
        })
        .collect();
    for n in &mut nodes {
        n.wait_ready();
    }
    // Settled despite the loss.
    let settled = wait_for(bounds.settle, Duration::from_millis(50), || {
        let live: Vec<&Proc> = nodes.iter().collect();
        state_is(&live, &[(1, 1), (2, 2), (3, 3)], &[1, 2, 3, 3]).ok()
    });
    assert!(settled.is_some(), "never settled with {LOSS} % loss\n{}", diagnostics(&nodes));
    let (doubled, samples, stalled) = sample_double_claims(&nodes, &bounds);
    eprintln!(
        "{LOSS} % loss: a target claimed twice at {:.1} % of {samples} instants (and {stalled} left out: a node \
         starved of the CPU)",
        doubled * 100.0
    );
    assert!(
        samples >= 10 && doubled <= 0.2,
        "double claims at {:.0} % of {samples} instants at which every node ran on time ({stalled} were not)\n{}",
        doubled * 100.0,
        diagnostics(&nodes)
    );

    // Node 1 cut off: its claims stop reaching n2, whose inhibition lapses within the lease.
    partition(&net, 0, true, LOSS).unwrap();
    let cut_at = Instant::now();
    let took = wait_for(bounds.takeover + bounds.margin * 2, Duration::from_millis(20), || {
        nodes[1].lines().into_iter().find(|(t, j)| *t > cut_at && drive(j) == 1).map(|(t, _)| t - cut_at)
    });
    let took = took.unwrap_or_else(|| panic!("n2 never took target 1 from the cut-off n1\n{}", diagnostics(&nodes)));
    eprintln!(
        "partition: n2 driven by layer 1 {:.3}s after n1 was cut off (bound {:?})",
        took.as_secs_f64(),
        bounds.takeover
    );
    assert!(took <= bounds.takeover + bounds.margin, "took {took:?}");

    // Healed, then node 3 killed: its targets are re-claimed (n2 sees target 3).
    partition(&net, 0, false, LOSS).unwrap();
    std::thread::sleep(bounds.takeover);
    let killed_at = Instant::now();
    nodes[2].kill();
    let took = wait_for(bounds.takeover + bounds.margin * 2, Duration::from_millis(20), || {
        nodes[1].lines().into_iter().find(|(t, j)| *t > killed_at && claims(j).contains(&3)).map(|(t, _)| t - killed_at)
    });
    let took = took.unwrap_or_else(|| panic!("target 3 never re-claimed after n3 died\n{}", diagnostics(&nodes)));
    eprintln!("kill: n2 claims target 3 {:.3}s after n3 was killed (bound {:?})", took.as_secs_f64(), bounds.takeover);
    assert!(took <= bounds.takeover + bounds.margin, "took {took:?}");
}

/// The shaper's arguments for the shaped-team test: 20-50 ms of delay (jitter reorders frames
/// closer than 30 ms), 5 % of frames held back behind the next, 5 % delivered twice; no loss
/// (the packet-filter test above covers loss), so the settled team must never show a target
/// claimed twice.
const SHAPE: [&str; 10] =
    ["--delay-ms", "20", "--jitter-ms", "30", "--reorder", "0.05", "--duplicate", "0.05", "--seed", "18"];
/// How much later than sent a frame may arrive through the shaper with [`SHAPE`]: 20 ms + up
/// to 30 ms, and 50 ms for a frame held back for reordering, which waits for the next frame to
/// the same namespace (the three nodes send about 65 frames a second between them: measured
/// 730 in an 11 s run). Only ever added to a bound that already has a margin of a whole
/// take-over bound.
const SHAPE_WAIT: Duration = Duration::from_millis(20 + 30 + 50);

/// `ayllu shape` joining namespaces 0..n of `net` (interface `ayllu0` in each, addressed once
/// it exists), with `shape` as its fault arguments; `Err` if it could not start.
fn start_shaper(net: &Netns, n: usize, shape: &[&str], secs: u32) -> Result<Proc, String> {
    let mut cmd = std::process::Command::new(BIN);
    cmd.args(["shape", "--status-ms", "200", "--for", &secs.to_string()]);
    for i in 0..n {
        cmd.args(["--netns", net.ns(i)]);
    }
    cmd.args(shape);
    let mut shaper = Proc::spawn("shaper", cmd);
    // Its first line says the TAP interfaces exist.
    let ready = wait_for(common::START_LIMIT, Duration::from_millis(20), || {
        if shaper.latest().is_some() {
            return Some(Ok(()));
        }
        shaper.exited().map(|status| Err(format!("ayllu shape exited ({status}): {}", shaper.stderr())))
    });
    ready.unwrap_or_else(|| Err(format!("ayllu shape did not start: {}", shaper.stderr())))?;
    (0..n).try_for_each(|i| net.configure(i, "ayllu0"))?;
    Ok(shaper)
}

/// The shaper's latest counters.
fn shaper_counts(shaper: &Proc) -> Json {
    shaper.latest().map(|(_, j)| j).filter(|j| j.get("written").is_some()).unwrap_or(Json::Null)
}

#[test]
fn three_processes_through_the_userspace_shaper_keep_the_arbitration_properties() {
    // Issue 18: the paper's team as three `ayllu node` processes in network namespaces joined
    // only by the userspace shaper (`ayllu shape`: a TAP interface per namespace, a hub
    // between them that delays, jitters, reorders and duplicates every frame, ARP and subnet
    // broadcast included). Checked from the recorded claims, with limits from the BLE periods
    // (Bounds) plus the shaper's longest wait:
    // * settled, no target is ever claimed by two nodes over five cycles; unicast (a CLI's
    //   LIST) gets through as well as broadcast;
    // * n1 SIGKILLed: n2 takes target 1 within inhibit + cycle (+ margin), not before n1's
    //   lease ran out; n1 restarted: the team returns to the first assignment;
    // * the shaper's own counters show every fault happened.
    if !std::path::Path::new("/dev/net/tun").exists() {
        return unavailable("tun", "no /dev/net/tun, the shaper cannot make TAP interfaces");
    }
    let net = match Netns::bare("sh", 85, 3) {
        Ok(net) => net,
        Err(reason) => return unavailable("netns", &reason),
    };
    // Declared after `net` and before the nodes: dropped (killed) after them, before the
    // namespaces go.
    // Any failure of the shaper fails the test: its own errors name /dev/net/tun and
    // TUNSETIFF too, so telling the environment from a broken `ayllu shape` by the message
    // would let the latter pass as skipped. AYLLU_SKIP=tun is the way to skip it.
    let shaper = match start_shaper(&net, 3, &SHAPE, 120) {
        Ok(shaper) => shaper,
        Err(reason) => panic!("the shaper (`ayllu shape`): {reason}"),
    };
    let bounds = Bounds::new();
    let start_node = |i: usize| {
        let url = format!("udp://10.85.0.{}:7400?broadcast=10.85.0.255:7400", i + 1);
        let mut cmd = net.command(i, BIN);
        cmd.args(node_args_for(i as u32 + 1, &url, 90));
        let mut p = Proc::spawn(&format!("n{}", i + 1), cmd);
        p.wait_ready();
        p
    };
    let mut nodes: Vec<Proc> = (0..3).map(start_node).collect();
    let started = Instant::now();
    let first = ([(1, 1), (2, 2), (3, 3)], [1, 2, 3, 3]);
    let settled = wait_for(bounds.settle, Duration::from_millis(50), || {
        state_is(&nodes.iter().collect::<Vec<_>>(), &first.0, &first.1).ok()
    });
    assert!(
        settled.is_some(),
        "never settled through the shaper\n{}\nshaper: {}",
        diagnostics(&nodes),
        shaper_counts(&shaper)
    );
    let settle_time = started.elapsed();
    let (doubled, samples, stalled) = sample_double_claims(&nodes, &bounds);
    assert!(
        samples >= 10 && doubled == 0.0,
        "a target claimed twice at {:.1} % of {samples} instants at which every node ran on time ({stalled} were \
         not)\n{}",
        doubled * 100.0,
        diagnostics(&nodes)
    );
    // Unicast crosses the shaper too (ARP, then request and reply): the CLI in n3's namespace
    // finds n1 by its broadcast HELLO and reads its behaviors.
    let mut cli = net.command(2, BIN);
    cli.args(["list", "1", "--json", "--udp", "udp://0.0.0.0:0?broadcast=10.85.0.255:7400"]);
    let report = common::run(cli, Duration::from_secs(10)).ok().json();
    let behaviors: Vec<&str> =
        report["behaviors"].as_array().into_iter().flatten().filter_map(|b| b["name"].as_str()).collect();
    assert!(behaviors.contains(&"OBS1"), "n1's LIST through the shaper: {report}");

    // n1 killed: its lease lapses at n2, which takes target 1.
    let killed_at = Instant::now();
    nodes[0].kill();
    let took = wait_for(bounds.takeover + bounds.margin * 2, Duration::from_millis(20), || {
        nodes[1].lines().into_iter().find(|(t, j)| *t > killed_at && drive(j) == 1).map(|(t, _)| t - killed_at)
    });
    let took = took.unwrap_or_else(|| panic!("n2 never took target 1 through the shaper\n{}", diagnostics(&nodes)));
    // n1's last claim may reach n2 up to the shaper's longest wait late.
    let bound = bounds.takeover + SHAPE_WAIT;
    assert!(took <= bound + bounds.margin, "took {took:?}, bound {bound:?} + margin {:?}", bounds.margin);
    assert!(took >= bounds.lease_floor, "took over after only {took:?}: the lease did not hold");

    // n1 restarted: the first assignment again (n1 sees target 1 best).
    nodes[0] = start_node(0);
    let restarted_at = Instant::now();
    let back = wait_for(bounds.settle, Duration::from_millis(50), || {
        state_is(&nodes.iter().collect::<Vec<_>>(), &first.0, &first.1).ok().map(|()| restarted_at.elapsed())
    });
    let back = back.unwrap_or_else(|| panic!("the team did not settle after n1 restarted\n{}", diagnostics(&nodes)));

    // The faults happened: the shaper's own counters.
    std::thread::sleep(Duration::from_millis(300));
    let c = shaper_counts(&shaper);
    let count = |k: &str| c[k].as_u64().unwrap_or(0);
    eprintln!(
        "shaper ({}): settled {:.2}s after start, no double claim in {samples} instants; n2 took target 1 \
         {:.3}s after n1 was killed (protocol bound {:?} + shaper wait {:?} = {:?}, lease floor {:?}, asserted \
         with {:?} margin); n1 restarted, team back {:.2}s later. Shaper: {} frames read, {} copies to \
         deliver, {} written, {} delayed, {} duplicated, {} held back, {} out of order, {} lost",
        SHAPE.join(" "),
        settle_time.as_secs_f64(),
        took.as_secs_f64(),
        bounds.takeover,
        SHAPE_WAIT,
        bound,
        bounds.lease_floor,
        bounds.margin,
        back.as_secs_f64(),
        count("received"),
        count("sent"),
        count("written"),
        count("delayed"),
        count("duplicated"),
        count("reordered"),
        count("out_of_order"),
        count("lost"),
    );
    for k in ["written", "delayed", "duplicated", "reordered", "out_of_order"] {
        assert!(count(k) > 0, "the shaper's `{k}` is 0: {c}");
    }
    // Every copy was delayed (no loss configured), and the nodes' traffic went through it.
    assert_eq!(count("lost"), 0, "{c}");
    assert!(count("written") >= 100 && count("delayed") + 1 >= count("written"), "{c}");
}

/// `make soak MINUTES=N`: the faulted team for N minutes (default 60), in rounds: the
/// namespaces joined by the userspace shaper ([`SHAPE`]: delay, jitter, reordering,
/// duplication) with 30 % loss made by the packet filter throughout, node 1 cut off and healed,
/// node 3 killed and restarted. Every round checks the
/// take-overs against the bounds; at the end node 2 (never restarted) and the shaper must have
/// kept their memory and descriptors bounded (within 2x their settled figures + 8 MB), and
/// double claims must stay rare. Prints the figures. Not in the test command (it is long): `--ignored`.
#[test]
#[ignore]
fn soak() {
    const LOSS: u32 = 30;
    let minutes: f64 = std::env::var("SOAK_MINUTES").ok().and_then(|m| m.parse().ok()).unwrap_or(60.0);
    let net = match Netns::bare("sk", 84, 3) {
        Ok(net) => net,
        Err(reason) => panic!("the soak needs network namespaces (root and ip): {reason}"),
    };
    let run_secs = (minutes * 60.0) as u32 + 120;
    // Declared after `net`, before the nodes: killed after them, before the namespaces go.
    let shaper = start_shaper(&net, 3, &SHAPE, run_secs + 60).unwrap_or_else(|e| panic!("the soak's shaper: {e}"));
    (0..3).try_for_each(|i| filter(&net, i, LOSS)).expect("nftables in the namespaces");
    let bounds = Bounds::new();
    let start_node = |i: usize| {
        let url = format!("udp://10.84.0.{}:7400?broadcast=10.84.0.255:7400", i + 1);
        let mut cmd = net.command(i, BIN);
        cmd.args(node_args_for(i as u32 + 1, &url, run_secs));
        let mut p = Proc::spawn(&format!("n{}", i + 1), cmd);
        p.wait_ready();
        p
    };
    let mut nodes: Vec<Proc> = (0..3).map(start_node).collect();
    let settled = wait_for(bounds.settle, Duration::from_millis(50), || {
        state_is(&nodes.iter().collect::<Vec<_>>(), &[(1, 1), (2, 2), (3, 3)], &[1, 2, 3, 3]).ok()
    });
    assert!(settled.is_some(), "never settled\n{}", diagnostics(&nodes));
    let (rss0, fds0) = nodes[1].resources().expect("/proc");
    let (shaper_rss0, shaper_fds0) = shaper.resources().expect("/proc");
    let began = Instant::now();
    let end = began + Duration::from_secs_f64(minutes * 60.0);
    let (mut rounds, mut worst_cut, mut worst_kill) = (0u32, Duration::ZERO, Duration::ZERO);
    while Instant::now() < end {
        rounds += 1;
        partition(&net, 0, true, LOSS).unwrap();
        let cut_at = Instant::now();
        let took = wait_for(bounds.takeover + bounds.margin * 2, Duration::from_millis(20), || {
            nodes[1].lines().into_iter().find(|(t, j)| *t > cut_at && drive(j) == 1).map(|(t, _)| t - cut_at)
        })
        .unwrap_or_else(|| panic!("round {rounds}: n2 never took target 1\n{}", diagnostics(&nodes)));
        worst_cut = worst_cut.max(took);
        partition(&net, 0, false, LOSS).unwrap();
        std::thread::sleep(bounds.takeover);
        let killed_at = Instant::now();
        nodes[2].kill();
        let took = wait_for(bounds.takeover + bounds.margin * 2, Duration::from_millis(20), || {
            nodes[1]
                .lines()
                .into_iter()
                .find(|(t, j)| *t > killed_at && claims(j).contains(&3))
                .map(|(t, _)| t - killed_at)
        })
        .unwrap_or_else(|| panic!("round {rounds}: target 3 never re-claimed\n{}", diagnostics(&nodes)));
        worst_kill = worst_kill.max(took);
        nodes[2] = start_node(2);
        std::thread::sleep(bounds.settle.min(Duration::from_secs(10)));
        eprintln!(
            "soak round {rounds}: cut-off take-over {:.2}s, kill re-claim {:.2}s",
            worst_cut.as_secs_f64(),
            worst_kill.as_secs_f64()
        );
    }
    let (rss1, fds1) = nodes[1].resources().expect("/proc");
    let (doubled, samples, _) = double_claims(&nodes.iter().collect::<Vec<_>>(), began, bounds.takeover);
    eprintln!(
        "soak: {minutes} min, {rounds} rounds; n2 RSS {rss0} -> {rss1} KiB, descriptors {fds0} -> {fds1}; worst take-over \
         after a cut-off {:.2}s, after a kill {:.2}s (bound {:?} + margin {:?}); double claims at {:.1} % of {samples} instants",
        worst_cut.as_secs_f64(),
        worst_kill.as_secs_f64(),
        bounds.takeover + SHAPE_WAIT,
        bounds.margin,
        doubled * 100.0
    );
    let (shaper_rss1, shaper_fds1) = shaper.resources().expect("/proc");
    eprintln!(
        "soak: shaper ({}): RSS {shaper_rss0} -> {shaper_rss1} KiB, descriptors {shaper_fds0} -> {shaper_fds1}; {}",
        SHAPE.join(" "),
        shaper_counts(&shaper)
    );
    assert!(shaper_rss1 <= 2 * shaper_rss0 + 8 * 1024, "the shaper's memory grew {shaper_rss0} -> {shaper_rss1} KiB");
    assert!(shaper_fds1 <= shaper_fds0, "the shaper's descriptors grew {shaper_fds0} -> {shaper_fds1}");
    let bound = bounds.takeover + SHAPE_WAIT;
    assert!(worst_cut <= bound + bounds.margin && worst_kill <= bound + bounds.margin);
    assert!(rss1 <= 2 * rss0 + 8 * 1024, "n2's memory grew {rss0} -> {rss1} KiB");
    assert!(fds1 <= fds0 + 2, "n2's descriptors grew {fds0} -> {fds1}");
    assert!(doubled <= 0.2, "double claims at {:.0} % of instants", doubled * 100.0);
}

#[test]
fn three_recorded_processes_through_the_shaper_replay_as_one_team() {
    // Issue 35: three `ayllu node --record` processes, the paper's team, through the userspace
    // shaper with loss on top of its delay, jitter, reordering and duplication. Their three
    // flight recordings, replayed as one system (`ayllu replay n1 n2 n3 check`, and the folder
    // form), explain every remote value accepted (0 unexplained), bound every clock from both
    // sides, and say by how much.
    let net = match Netns::bare("tr", 89, 3) {
        Ok(net) => net,
        Err(reason) => return unavailable("netns", &reason),
    };
    let lossy: Vec<&str> = SHAPE.iter().copied().chain(["--loss", "0.1"]).collect();
    let shaper = match start_shaper(&net, 3, &lossy, 60) {
        Ok(shaper) => shaper,
        Err(reason) => panic!("the shaper (`ayllu shape`): {reason}"),
    };
    let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("team-replay-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let files: Vec<String> = (1..=3).map(|i| dir.join(format!("n{i}.mcap")).to_string_lossy().into_owned()).collect();
    // When each node was started, on this test's clock: its own clock starts after that.
    let epoch = Instant::now();
    let mut spawned = Vec::new();
    let mut nodes: Vec<Proc> = (0..3)
        .map(|i| {
            let url = format!("udp://10.89.0.{}:7400?broadcast=10.89.0.255:7400", i + 1);
            let mut cmd = net.command(i, BIN);
            cmd.args(node_args_for(i as u32 + 1, &url, 8)).args(["--record", &files[i]]);
            spawned.push(epoch.elapsed().as_secs_f64());
            let mut p = Proc::spawn(&format!("n{}", i + 1), cmd);
            p.wait_ready();
            p
        })
        .collect();
    // Each ends by itself after 8 s, closing its recording.
    for n in &mut nodes {
        let status = wait_for(Duration::from_secs(30), Duration::from_millis(100), || n.exited());
        let status = status.unwrap_or_else(|| panic!("{} did not end\n{}", n.name, n.stderr()));
        assert!(status.success(), "{} ended with {status}: {}", n.name, n.stderr());
    }
    let shaped = shaper_counts(&shaper);
    let mut args = vec!["replay"];
    args.extend(files.iter().map(String::as_str));
    args.extend(["check", "--json"]);
    let run = ayllu(&args, Duration::from_secs(60));
    let team = run.json();
    eprintln!("team replay: {team}\nshaper: {shaped}");
    assert_eq!(run.code, Some(0), "{run:?}");
    assert_eq!(team["passed"], true, "{team}");
    assert_eq!(team["unexplained"], 0, "{team}");
    assert!(team["accepted_remote"].as_u64() > Some(100), "{team}");
    assert_eq!(team["matched"].as_array().map(Vec::len), Some(6), "every pair exchanged values: {team}");
    // Each node's clock against this test's, known from outside the recordings: it started
    // after the node was spawned, so (node clock - test clock) <= -spawned; and each status
    // line `t` was printed before the test read it at `r`, so it is >= t - r.
    let outside: Vec<(f64, f64)> = nodes
        .iter()
        .zip(&spawned)
        .map(|(n, &spawn)| {
            let low = n
                .lines()
                .into_iter()
                .filter_map(|(r, j)| Some(j["t"].as_f64()? - r.duration_since(epoch).as_secs_f64()));
            (low.fold(f64::NEG_INFINITY, f64::max), -spawn)
        })
        .collect();
    for (k, c) in team["clocks"].as_array().unwrap().iter().enumerate() {
        // Bounded on both sides; by the shaper's delays, well under a second.
        let bound = c["bound_s"].as_f64().unwrap_or_else(|| panic!("a clock bounded on both sides: {c}"));
        assert!(bound < 0.5, "{c}");
        // And the team replay's interval for node k's clock minus node 1's meets the one known
        // from outside: the estimate is within what the processes' own timing allows.
        let (low, high) = (c["low_s"].as_f64().unwrap(), c["high_s"].as_f64().unwrap());
        let (out_low, out_high) = (outside[k].0 - outside[0].1, outside[k].1 - outside[0].0);
        eprintln!("n{}: team replay [{low:.4}, {high:.4}] s, from outside [{out_low:.4}, {out_high:.4}] s", k + 1);
        assert!(low <= out_high + 1e-6 && out_low <= high + 1e-6, "n{}: {c} against [{out_low}, {out_high}]", k + 1);
    }
    // The faults were real.
    for counter in ["lost", "duplicated", "reordered", "delayed"] {
        assert!(shaped[counter].as_u64() > Some(0), "the shaper {counter} frames: {shaped}");
    }
    // Why, across robots: robot 1 sees no target 3, and its layer 3 is write-inhibited by
    // robot 3's claim. The chain reaches robot 3's BLE select and the eligibility it heard
    // from robot 2 (a third robot), with the message that carried each.
    // An instant at which the claim holds robot 1: a claim is renewed every second and lasts
    // 2.3 s, so with 10 % loss it is held nearly always; the first of a few instants that
    // shows it (the recordings decide, not the clock).
    let why_at = |at: &str| {
        let mut why_args = vec!["replay"];
        why_args.extend(files.iter().map(String::as_str));
        why_args.extend(["--at", at, "why", "--node", "1", "OBS3.Rotate", "--depth", "2", "--json"]);
        ayllu(&why_args, Duration::from_secs(60)).ok().json()
    };
    let held = |chain: &Json| {
        chain.as_array().is_some_and(|links| {
            links
                .iter()
                .any(|l| l["kind"] == "window" && l["text"].as_str().is_some_and(|t| t.contains("held by n3/c")))
        })
    };
    let chain = ["6", "5.5", "6.5", "5", "7", "4.5", "7.5"]
        .iter()
        .map(|at| why_at(at))
        .find(held)
        .unwrap_or_else(|| panic!("robot 3's claim never held robot 1's layer 3: {}", why_at("6")));
    let links = chain.as_array().expect("a chain of links");
    let has = |node: u64, kind: &str, text: &str| {
        links
            .iter()
            .any(|l| l["node"] == node && l["kind"] == kind && l["text"].as_str().is_some_and(|t| t.contains(text)))
    };
    assert!(has(1, "window", "WriteInhibit window held by n3/c"), "robot 1's window from robot 3: {chain:#}");
    assert!(has(3, "message", "write-inhibit"), "the claim's message from robot 3: {chain:#}");
    assert!(has(3, "activation", "BLE_Select"), "robot 3's BLE select wrote the claim: {chain:#}");
    assert!(has(3, "input", "Best = 0.4 (n2/c"), "the eligibility robot 3 heard from robot 2: {chain:#}");
    assert!(has(2, "message", "-> n3:OBS3.Best"), "and its message from robot 2: {chain:#}");

    // A recording edited by hand, from outside (a fixture rewrites the MCAP file with the
    // `mcap` package): one received value altered, one received message removed. The team
    // replay fails and names both: the value with its sender's, the removal as a hole.
    let tampered = dir.join("tampered");
    std::fs::create_dir_all(&tampered).unwrap();
    let n2x = tampered.join("n2.mcap").to_string_lossy().into_owned();
    let fixture = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/tool/fixtures/tamper_recording.py");
    let mut python = std::process::Command::new("python3");
    python.args([fixture, &files[1], &n2x]);
    let edit = common::run(python, Duration::from_secs(60)).ok().json();
    let (altered, removed) = (edit["altered"].as_u64().expect("a value altered"), edit["removed"].as_u64().unwrap());
    let run = ayllu(&["replay", &files[0], &n2x, &files[2], "check", "--json"], Duration::from_secs(60));
    assert_eq!(run.code, Some(1), "a tampered team fails: {run:?}");
    let found = run.json()["findings"].clone();
    let named = |text: &str| found.as_array().unwrap().iter().any(|f| f.as_str().is_some_and(|f| f.contains(text)));
    assert!(named(&format!("altered: n2 entry {altered} ")), "the altered value is named: {found:#}");
    assert!(
        named(&format!("n2's recording has a hole at entry {removed} ")),
        "the removed message is named: {found:#}"
    );

    // A folder stands for its recordings.
    let folder = ayllu(&["replay", dir.to_str().unwrap(), "check", "--json"], Duration::from_secs(60)).ok().json();
    assert_eq!(folder["nodes"], team["nodes"], "{folder}");
    assert_eq!(folder["explained"], team["explained"], "{folder}");
}
