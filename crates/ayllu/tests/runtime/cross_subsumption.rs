//! The paper's cross-subsumption (§4.1, Fig. 1b/2): 3 nodes x 4 observer layers over WANDER,
//! each layer cross-inhibited with BLE over `mem://`, on virtual time (Lockstep).
//!
//! Checks (issue "port-arbitration core"):
//! * S11 + S6 OverrideOut: each node is driven by its highest-priority layer whose target it
//!   sees and that no other node claims (the greedy per-layer assignment computed here);
//! * S11: once settled, no layer is claimed by two nodes;
//! * S11 leases: stopping a claimer frees its task within the inhibition period plus one BLE
//!   cycle.

use std::net::SocketAddr;

use ayllu::datagram::{DatagramBus, DatagramSocket, OsSocket};
use ayllu::faults::{FaultConfig, FaultySocket};
use ayllu::stdlib::{cross_subsumption, BASE, VISION, WANDER_TURN};
use ayllu::{BleConfig, Duration, Instant, Lockstep, Node, NodeId, UdpConfig, UdpTransport};

const LAYERS: u32 = 4;
const CLAIM_HZ: f64 = 1.0;
const TICK: Duration = Duration::from_millis(10);

/// What node `i` sees: `sight[i][n-1] = Some(apparent height)` for target n.
type Sight = Vec<[Option<f64>; LAYERS as usize]>;

fn bearing(target: u32) -> f64 {
    0.1 * f64::from(target)
}

/// Which layer drives a node, from its base's Rotate (0 = WANDER).
fn driving_layer(rotate: f64) -> u32 {
    if rotate == WANDER_TURN {
        0
    } else {
        (-rotate / 0.1).round() as u32
    }
}

/// The network a team runs over.
#[derive(Clone)]
enum Net {
    /// In-process `mem://`.
    Mem,
    /// The UDP transport over the deterministic in-memory datagram bus, with subnet broadcast
    /// for the group (as on a robots' Wi-Fi), optionally through the fault injector.
    UdpBus(Option<FaultConfig>),
    /// The UDP transport over real loopback sockets; the group is delivered by unicast to the
    /// peers that announced it (loopback has no broadcast).
    UdpLoopback,
}

fn team(name: &str, nodes: u32) -> Lockstep {
    team_over(Net::Mem, name, nodes)
}

fn team_over(net: Net, name: &str, nodes: u32) -> Lockstep {
    let mut team = Lockstep::new(name);
    let bus = DatagramBus::new();
    // Loopback sockets are bound to port 0 first and kept: the nodes use the very sockets whose
    // ports the peers are told, so nothing else on the machine can take a port in between.
    let mut loopback: Vec<OsSocket> = match net {
        Net::UdpLoopback => (0..nodes).map(|_| OsSocket::bind("127.0.0.1:0".parse().unwrap()).unwrap()).collect(),
        _ => Vec::new(),
    };
    let loopback_addrs: Vec<SocketAddr> = loopback.iter().map(|s| s.local_addr().unwrap()).collect();
    loopback.reverse();
    for id in 1..=nodes {
        let i = match &net {
            Net::Mem => team.add(NodeId(id)).unwrap(),
            Net::UdpBus(faults) => {
                let addr: SocketAddr = format!("10.0.0.{id}:7400").parse().unwrap();
                let mut config = UdpConfig::new(addr);
                config.broadcast = Some("10.0.0.255:7400".parse().unwrap());
                config.hello_interval = Duration::from_millis(200);
                let socket = bus.bind(addr).unwrap();
                let node = match faults {
                    None => {
                        Node::new(team.clock().clone(), UdpTransport::with_socket(NodeId(id), config, socket).unwrap())
                    }
                    Some(f) => {
                        let f = FaultConfig { seed: f.seed + u64::from(id), ..f.clone() };
                        let socket = FaultySocket::new(socket, team.clock().clone(), f);
                        Node::new(team.clock().clone(), UdpTransport::with_socket(NodeId(id), config, socket).unwrap())
                    }
                };
                team.add_node(node)
            }
            Net::UdpLoopback => {
                let socket = loopback.pop().expect("one socket per node");
                let mut config = UdpConfig::new(socket.local_addr().unwrap());
                config.peers = loopback_addrs.clone();
                config.hello_interval = Duration::from_millis(200);
                team.add_node(Node::new(
                    team.clock().clone(),
                    UdpTransport::with_socket(NodeId(id), config, socket).unwrap(),
                ))
            }
        };
        let groups = cross_subsumption(team.node(i).core_mut(), LAYERS, "Peers", CLAIM_HZ).unwrap();
        assert_eq!(groups.len(), LAYERS as usize);
        assert!(groups.iter().all(|g| g.warnings.is_empty()), "recommended BLE config must not warn");
    }
    team
}

/// Run `total` of virtual time, feeding every live node's VISION at 10 Hz from `sight`
/// (indexed by node id - 1).
fn run(team: &mut Lockstep, sight: &Sight, total: Duration, mut each_tick: impl FnMut(&Lockstep)) {
    let end = team.now() + total;
    while team.now() < end {
        if team.now().as_nanos().is_multiple_of(100_000_000) {
            for i in 0..team.nodes().len() {
                let id = team.nodes()[i].id().0 as usize;
                for n in 1..=LAYERS {
                    if let Some(h) = sight[id - 1][n as usize - 1] {
                        let node = team.node(i);
                        node.write(VISION, &format!("Target{n}Angle"), bearing(n)).unwrap();
                        node.write(VISION, &format!("Target{n}Bottom"), h).unwrap();
                    }
                }
            }
        }
        team.advance(TICK, TICK);
        each_tick(team);
    }
}

/// The expected claimer of each layer among `alive` node ids: highest height, ties to the
/// lower id; and the expected driving layer of each node.
fn expected(sight: &Sight, alive: &[u32]) -> (Vec<Option<u32>>, Vec<(u32, u32)>) {
    let claimers: Vec<Option<u32>> = (0..LAYERS as usize)
        .map(|l| {
            let mut best: Option<(f64, u32)> = None;
            for &id in alive {
                if let Some(h) = sight[id as usize - 1][l] {
                    if best.is_none_or(|(bh, bid)| h > bh || (h == bh && id < bid)) {
                        best = Some((h, id));
                    }
                }
            }
            best.map(|(_, id)| id)
        })
        .collect();
    let drive = alive
        .iter()
        .map(|&id| {
            let layer = (1..=LAYERS).find(|&n| claimers[n as usize - 1] == Some(id)).unwrap_or(0);
            (id, layer)
        })
        .collect();
    (claimers, drive)
}

fn check_settled(team: &Lockstep, sight: &Sight, alive: &[u32]) {
    let (claimers, drive) = expected(sight, alive);
    for (id, layer) in drive {
        let node = team.nodes().iter().find(|n| n.id().0 == id).unwrap();
        let rotate = node.read(BASE, "Rotate").unwrap().as_float().unwrap();
        assert_eq!(driving_layer(rotate), layer, "node {id} at {}: expected to be driven by layer {layer}", team.now());
    }
    let now = team.now();
    let period = Duration::try_from_hz(CLAIM_HZ).unwrap();
    for n in 1..=LAYERS {
        // Nodes that renewed a claim on layer n during the last claim period.
        let recent: Vec<u32> = team
            .nodes()
            .iter()
            .filter(|node| {
                let s = node.core().ble_status(&format!("OBS{n}")).unwrap().unwrap();
                s.last_claim.is_some_and(|t| now < t + period + TICK)
            })
            .map(|node| node.id().0)
            .collect();
        assert!(recent.len() <= 1, "layer {n} claimed by {recent:?} at {now}");
        assert_eq!(recent.first().copied(), claimers[n as usize - 1], "claimer of layer {n} at {now}");
    }
}

fn paper_sight() -> Sight {
    vec![
        [Some(0.9), Some(0.5), None, None],
        [Some(0.6), Some(0.8), Some(0.4), None],
        [None, None, Some(0.7), Some(0.5)],
    ]
}

#[test]
fn each_node_is_driven_by_its_highest_unclaimed_layer() {
    settles(Net::Mem, "xsub-settle");
}

#[test]
fn n3_s10_over_udp_with_subnet_broadcast_each_node_is_driven_by_its_highest_unclaimed_layer() {
    settles(Net::UdpBus(None), "xsub-udp-bus");
}

#[test]
fn n3_s10_over_real_loopback_udp_each_node_is_driven_by_its_highest_unclaimed_layer() {
    settles(Net::UdpLoopback, "xsub-udp-loopback");
}

fn settles(net: Net, name: &str) {
    let sight = paper_sight();
    let mut team = team_over(net, name, 3);
    run(&mut team, &sight, Duration::from_secs(5), |_| {});
    // Settled: check every 100 ms for 5 s.
    let mut checks = 0;
    run(&mut team, &sight, Duration::from_secs(5), |t| {
        if t.now().as_nanos().is_multiple_of(100_000_000) {
            check_settled(t, &sight, &[1, 2, 3]);
            checks += 1;
        }
    });
    assert!(checks >= 40);
    // Node 2 sees target 1 but node 1 claims it: node 2's OBS1 output is write-inhibited.
    let why = team.nodes()[1].why("OBS1", "Rotate").unwrap();
    assert_eq!(why.internal_output_blocked, Some(ayllu::DropCause::WriteInhibited), "{why}");
    assert!(why.windows.iter().any(|w| w.holder.node == NodeId(1)), "{why}");
}

#[test]
fn pseudo_random_scenes_settle_to_the_greedy_assignment() {
    // A fixed set of scenes from a small LCG: deterministic, varied.
    let mut state: u64 = 0x5eed;
    let mut next = move || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (state >> 33) as u32
    };
    for scene in 0..6 {
        let sight: Sight = (0..3)
            .map(|_| {
                let mut row = [None; LAYERS as usize];
                for cell in &mut row {
                    if next() % 3 != 0 {
                        *cell = Some(f64::from(next() % 90 + 10) / 100.0);
                    }
                }
                row
            })
            .collect();
        let mut team = team(&format!("xsub-random-{scene}"), 3);
        run(&mut team, &sight, Duration::from_secs(6), |_| {});
        check_settled(&team, &sight, &[1, 2, 3]);
    }
}

#[test]
fn stopping_a_claimer_frees_its_task_within_inhibit_period_plus_one_cycle() {
    frees_on_kill(Net::Mem, "xsub-kill");
}

#[test]
fn over_udp_stopping_a_claimer_frees_its_task_within_inhibit_period_plus_one_cycle() {
    frees_on_kill(Net::UdpBus(None), "xsub-udp-kill");
}

fn frees_on_kill(net: Net, name: &str) {
    let sight = paper_sight();
    let mut team = team_over(net, name, 3);
    run(&mut team, &sight, Duration::from_secs(6), |_| {});
    check_settled(&team, &sight, &[1, 2, 3]);
    // Node 1 claims target 1; node 2 sees it too but is held off.
    let inhibit = BleConfig::new("Peers", "Rotate", CLAIM_HZ).unwrap().inhibit_period;
    let cycle = Duration::try_from_hz(CLAIM_HZ).unwrap();
    let killed_at: Instant = team.now();
    drop(team.kill(NodeId(1)).expect("node 1 is in the team"));
    let mut freed_at: Option<Instant> = None;
    run(&mut team, &sight, inhibit + cycle + Duration::from_secs(2), |t| {
        let rotate = t.nodes()[0].read(BASE, "Rotate").unwrap().as_float().unwrap();
        if freed_at.is_none() && driving_layer(rotate) == 1 {
            freed_at = Some(t.now());
        }
    });
    let freed_at = freed_at.expect("node 2 never took over target 1");
    let took = freed_at - killed_at;
    assert!(took <= inhibit + cycle, "took {took}, limit {}", inhibit + cycle);
    // And it did not happen before the dead claim lapsed: the lease held while it was valid.
    assert!(took > Duration::from_millis(200), "took over after only {took}");
    // Settled again without node 1.
    run(&mut team, &sight, Duration::from_secs(3), |_| {});
    check_settled(&team, &sight, &[2, 3]);
}

#[test]
fn the_same_run_twice_is_identical() {
    let sight = paper_sight();
    let trace = |name: &str| {
        let mut team = team(name, 3);
        let mut trace = Vec::new();
        run(&mut team, &sight, Duration::from_secs(4), |t| {
            for n in t.nodes() {
                trace.push(n.read(BASE, "Rotate").unwrap().as_float().unwrap().to_bits());
            }
        });
        trace
    };
    assert_eq!(trace("xsub-det-a"), trace("xsub-det-b"));
}

/// Arbitration under a bad network: 10 % loss, duplication, reordering, corruption, delay and
/// jitter on every robot's sends. BLE claims are leases renewed every second and eligibility
/// is broadcast at 20 Hz, so an occasional lost claim must not change who drives. The verdict
/// is a fraction of samples (a lost claim *can* let a window lapse for a moment): over 8 s of
/// settled time at least 90 % of samples must show exactly the fault-free assignment. Measured:
/// 100 % with these seeds.
#[test]
fn arbitration_stays_correct_under_loss_duplication_reordering_and_corruption() {
    let faults = FaultConfig {
        seed: 42,
        loss: 0.10,
        duplicate: 0.05,
        reorder: 0.05,
        corrupt: 0.02,
        delay: Duration::from_millis(5),
        jitter: Duration::from_millis(10),
    };
    let sight = paper_sight();
    let mut team = team_over(Net::UdpBus(Some(faults)), "xsub-faults", 3);
    run(&mut team, &sight, Duration::from_secs(6), |_| {});
    let (claimers, drive) = expected(&sight, &[1, 2, 3]);
    let (mut good, mut total) = (0u32, 0u32);
    run(&mut team, &sight, Duration::from_secs(8), |t| {
        if !t.now().as_nanos().is_multiple_of(100_000_000) {
            return;
        }
        total += 1;
        let drives_ok = drive.iter().all(|&(id, layer)| {
            let node = t.nodes().iter().find(|n| n.id().0 == id).unwrap();
            driving_layer(node.read(BASE, "Rotate").unwrap().as_float().unwrap()) == layer
        });
        let claims_ok = (1..=LAYERS).all(|n| {
            let holders: Vec<u32> = t
                .nodes()
                .iter()
                .filter(|node| node.core().ble_status(&format!("OBS{n}")).unwrap().unwrap().claiming)
                .map(|node| node.id().0)
                .collect();
            holders.len() <= 1 && holders.first().copied() == claimers[n as usize - 1]
        });
        good += u32::from(drives_ok && claims_ok);
    });
    // The faults really happened, and the decoder caught the corrupted datagrams.
    let corrupted: u64 = team
        .nodes()
        .iter()
        .map(|n| {
            transport_count(n, "bad_magic")
                + transport_count(n, "malformed")
                + transport_count(n, "truncated")
                + transport_count(n, "bad_version")
                + transport_count(n, "wrong_team")
                + transport_count(n, "bad_flags")
                + transport_count(n, "unknown_kind")
                + transport_count(n, "own")
        })
        .sum();
    let received: u64 = team.nodes().iter().map(|n| transport_count(n, "datagrams_received")).sum();
    assert!(corrupted > 0, "the fault injector corrupted nothing the decoder noticed");
    assert!(received > 1000, "received {received}");
    assert!(good * 10 >= total * 9, "{good} of {total} samples correct (corrupted seen: {corrupted})");
}

fn transport_count(node: &Node, cause: &str) -> u64 {
    node.transport_counters().iter().find(|(c, _)| c == cause).map_or(0, |(_, n)| *n)
}
