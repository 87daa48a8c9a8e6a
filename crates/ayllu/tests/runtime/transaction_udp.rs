//! Transactions over real loopback UDP with faults injected (crates/ayllu/src/faults.rs:
//! loss, duplication, reordering, delay with jitter) on every node's sends, the coordinator's
//! too, on one virtual clock (docs/semantics.md R8–R12). All switch within the measured skew
//! bound, or none does; a node killed between prepare and commit is named; a bad port name
//! aborts the whole plan.

use std::net::SocketAddr;

use ayllu::datagram::{DatagramSocket, OsSocket};
use ayllu::faults::{FaultConfig, FaultySocket};
use ayllu::transaction::{ApplyOptions, ApplyReport, Coordinator, Outcome, Part, Plan};
use ayllu::{
    BehaviorClass, Change, ConnectionKind, Duration, Endpoint, Instant, Lockstep, Node, NodeId, PortSpec,
    TransactionState, UdpConfig, UdpTransport,
};

const COORD: NodeId = NodeId(9);
const TICK: Duration = Duration::from_millis(1);

/// Nodes 1..=3 and the coordinator (index 3), each sending through `loss` and a delay of
/// 2 ms plus up to 6 ms of jitter.
fn team(loss: f64, seed: u64) -> Lockstep {
    let mut team = Lockstep::new("txn-udp");
    let mut sockets: Vec<OsSocket> = (0..4).map(|_| OsSocket::bind("127.0.0.1:0".parse().unwrap()).unwrap()).collect();
    let addrs: Vec<SocketAddr> = sockets.iter().map(|s| s.local_addr().unwrap()).collect();
    sockets.reverse();
    for id in [1u32, 2, 3, COORD.0] {
        let socket = sockets.pop().unwrap();
        let mut config = UdpConfig::new(socket.local_addr().unwrap());
        config.peers = addrs.clone();
        config.hello_interval = Duration::from_millis(200);
        let faults = FaultConfig {
            loss,
            duplicate: 0.05,
            reorder: 0.05,
            delay: Duration::from_millis(2),
            jitter: Duration::from_millis(6),
            ..FaultConfig::none(seed + u64::from(id))
        };
        let socket = FaultySocket::new(socket, team.clock().clone(), faults);
        let mut node = Node::new(team.clock().clone(), UdpTransport::with_socket(NodeId(id), config, socket).unwrap());
        if id != COORD.0 {
            let mut layer = BehaviorClass::new("Layer");
            layer.port(PortSpec::new("Out", 0i64)).unwrap();
            node.define(layer).unwrap();
            for b in ["Low", "High", "Motor"] {
                node.create("Layer", b).unwrap();
            }
            node.connect(&Endpoint::local("Low", "Out"), &Endpoint::local("Motor", "Out"), ConnectionKind::Normal)
                .unwrap();
        }
        team.add_node(node);
    }
    // Greetings first (a request to a node not heard from yet is held, D-S10.2).
    advance(&mut team, Duration::from_secs(1));
    team
}

fn advance(team: &mut Lockstep, d: Duration) {
    let end = team.now() + d;
    while team.now() < end {
        team.advance(TICK, TICK);
        // Real sockets: let the kernel deliver before the next step.
        std::thread::sleep(std::time::Duration::from_micros(100));
    }
}

fn swap() -> Vec<Change> {
    vec![
        Change::DisconnectBetween {
            source: Endpoint::local("Low", "Out"),
            destination: Endpoint::local("Motor", "Out"),
        },
        Change::Connect {
            source: Endpoint::local("High", "Out"),
            destination: Endpoint::local("Motor", "Out"),
            kind: ConnectionKind::Suppress(Duration::from_millis(300)),
            priority: 0,
        },
    ]
}

fn plan(parts: Vec<(u32, Vec<Change>)>) -> Plan {
    Plan {
        parts: parts.into_iter().map(|(n, changes)| Part { node: NodeId(n), changes }).collect(),
        options: ApplyOptions { hold: Duration::from_secs(3), ..ApplyOptions::default() },
    }
}

/// Run `plan` from the coordinator (node index 3); `kill` is called after every turn and may
/// kill a node.
fn run(team: &mut Lockstep, plan: &Plan, mut kill: impl FnMut(&mut Lockstep, &Coordinator)) -> ApplyReport {
    let mut c = Coordinator::new(5, plan, COORD).unwrap();
    for _ in 0..20_000 {
        advance(team, TICK);
        let now = team.now();
        let node = team.node_by_id(COORD).unwrap();
        let report = c.step(node.core_mut(), now);
        node.step();
        if let Some(r) = report {
            advance(team, Duration::from_millis(3500));
            return r;
        }
        kill(team, &c);
    }
    panic!("the transaction did not end");
}

fn switched(team: &mut Lockstep, id: u32) -> Option<Instant> {
    team.node_by_id(NodeId(id))?.core().transactions().iter().find_map(|t| match &t.state {
        TransactionState::Applied { at, .. } => Some(*at),
        _ => None,
    })
}

fn has_new_wiring(team: &mut Lockstep, id: u32) -> bool {
    let conns = team.node_by_id(NodeId(id)).unwrap().core().report().connections;
    conns.len() == 1 && conns[0].source.behavior() == "High"
}

#[test]
fn with_loss_all_switch_within_the_measured_bound() {
    for seed in [11, 12, 13] {
        let mut team = team(0.2, seed);
        let p = plan(vec![(1, swap()), (2, swap()), (3, swap())]);
        let report = run(&mut team, &p, |_, _| {});
        assert_eq!(report.outcome, Outcome::Switched, "seed {seed}: {report}");
        let at: Vec<Instant> = (1..=3).map(|i| switched(&mut team, i).expect("switched")).collect();
        let skew = *at.iter().max().unwrap() - *at.iter().min().unwrap();
        // The measured bound covers the actual skew (to a tick of polling), and it stays
        // within the slowest round trip plus the jitter of one copy's trip and the resends a
        // loss costs.
        let bound = report.skew_bound.unwrap();
        assert!(skew <= bound + TICK * 2, "seed {seed}: actual skew {skew} over the bound {bound}: {report}");
        for i in 1..=3 {
            assert!(has_new_wiring(&mut team, i), "seed {seed}: node {i}");
        }
        println!("seed {seed}: {report}\n  actual switches {at:?}, skew {skew}");
    }
}

#[test]
fn a_bad_port_name_aborts_the_plan_on_every_node() {
    let mut team = team(0.2, 21);
    let mut bad = swap();
    bad[1] = Change::Connect {
        source: Endpoint::local("High", "Out"),
        destination: Endpoint::local("Motor", "Inn"),
        kind: ConnectionKind::Normal,
        priority: 0,
    };
    let p = plan(vec![(1, swap()), (2, swap()), (3, bad)]);
    let report = run(&mut team, &p, |_, _| {});
    assert_eq!(report.outcome, Outcome::Aborted, "{report}");
    let refused = report.refused();
    assert_eq!(refused.iter().map(|r| r.0).collect::<Vec<_>>(), [NodeId(3)], "{report}");
    assert!(refused[0].1.contains("Inn"), "{report}");
    for i in 1..=3 {
        assert!(switched(&mut team, i).is_none(), "node {i}");
        assert!(!has_new_wiring(&mut team, i));
        assert!(team.node_by_id(NodeId(i)).unwrap().core().transaction_held().is_none(), "node {i} still holds");
    }
}

#[test]
fn a_node_killed_between_prepare_and_commit_is_named_and_the_others_switch_together() {
    let mut team = team(0.1, 31);
    let p = plan(vec![(1, swap()), (2, swap()), (3, swap())]);
    let mut done = false;
    let report = run(&mut team, &p, |team, c| {
        // Once node 2 has prepared (it holds the transaction), it dies before any COMMIT.
        if !done && team.node_by_id(NodeId(2)).is_some_and(|n| n.core().transaction_held().is_some()) {
            team.kill(NodeId(2));
            done = true;
        }
        let _ = c;
    });
    assert!(done);
    assert_ne!(report.outcome, Outcome::Switched, "{report}");
    if report.outcome == Outcome::Split {
        assert!(matches!(&report.nodes[1].commit, Some(Err(e)) if e.contains("no answer")), "{report}");
        let (a, b) = (switched(&mut team, 1).unwrap(), switched(&mut team, 3).unwrap());
        let skew = if a > b { a - b } else { b - a };
        assert!(skew <= report.max_rtt + Duration::from_millis(20), "{a:?} vs {b:?}: {report}");
    } else {
        // Killed before its PREPARE's answer got out: nobody switched.
        assert_eq!(report.outcome, Outcome::Aborted);
        assert!(switched(&mut team, 1).is_none() && switched(&mut team, 3).is_none());
    }
}
