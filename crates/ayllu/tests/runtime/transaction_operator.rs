//! Transactions obey the operator key (docs/security.md D9.4; docs/semantics.md R8): a node
//! given the operator's public key takes a plan's PREPARE, COMMIT and ABORT only when signed
//! with the operator's secret, as it takes CONNECT. A coordinator without the secret is refused
//! (`unsigned`) and no node switches; the operator's tool switches them. UDP on an in-process
//! datagram bus, virtual time.

use std::net::SocketAddr;

use ayllu::datagram::DatagramBus;
use ayllu::transaction::{ApplyOptions, ApplyReport, Coordinator, Outcome, Part, Plan};
use ayllu::{
    BehaviorClass, Change, ConnectionKind, Duration, Endpoint, Lockstep, Node, NodeId, PortSpec, UdpConfig,
    UdpTransport,
};
use ayllu_wire::OperatorSecret;

const TICK: Duration = Duration::from_millis(1);

fn addr(i: u32) -> SocketAddr {
    format!("10.0.1.{i}:7400").parse().unwrap()
}

fn operator() -> OperatorSecret {
    OperatorSecret::from_seed(&[42; 32])
}

fn node(team: &mut Lockstep, bus: &DatagramBus, id: u32, set: impl FnOnce(&mut UdpConfig)) {
    let mut config = UdpConfig::new(addr(id));
    config.team = 7;
    config.peers = [1, 2, 8, 9].into_iter().filter(|p| *p != id).map(addr).collect();
    config.hello_interval = Duration::from_millis(100);
    set(&mut config);
    let transport = UdpTransport::with_socket(NodeId(id), config, bus.bind(addr(id)).unwrap()).unwrap();
    let i = team.add_node(Node::new(team.clock().clone(), transport));
    let mut relay = BehaviorClass::new("Relay");
    relay.port(PortSpec::new("In", 0i64)).unwrap();
    relay.port(PortSpec::new("Out", 0i64)).unwrap();
    team.node(i).define(relay).unwrap();
    team.node(i).create("Relay", "R").unwrap();
}

fn run(team: &mut Lockstep, from: u32, txn: u64) -> ApplyReport {
    let change = Change::Connect {
        source: Endpoint::local("R", "Out"),
        destination: Endpoint::local("R", "In"),
        kind: ConnectionKind::Suppress(Duration::from_millis(200)),
        priority: 0,
    };
    let plan = Plan {
        parts: (1..=2).map(|n| Part { node: NodeId(n), changes: vec![change.clone()] }).collect(),
        options: ApplyOptions { hold: Duration::from_secs(3), ..ApplyOptions::default() },
    };
    let mut c = Coordinator::new(txn, &plan, NodeId(from)).unwrap();
    for _ in 0..10_000 {
        team.advance(TICK, TICK);
        let now = team.now();
        let node = team.node_by_id(NodeId(from)).unwrap();
        let r = c.step(node.core_mut(), now);
        node.step();
        if let Some(r) = r {
            team.advance(Duration::from_millis(500), TICK);
            return r;
        }
    }
    panic!("the transaction did not end");
}

fn connections(team: &mut Lockstep, id: u32) -> usize {
    team.node_by_id(NodeId(id)).unwrap().core().report().connections.len()
}

#[test]
fn only_the_operator_may_apply_a_plan_to_nodes_that_hold_its_key() {
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("txn-operator");
    for id in [1, 2] {
        node(&mut team, &bus, id, |c| c.operator = Some(operator().public()));
    }
    node(&mut team, &bus, 8, |_| {});
    node(&mut team, &bus, 9, |c| c.operator_secret = Some(operator()));
    team.advance(Duration::from_millis(500), TICK);

    let refused = run(&mut team, 8, 1);
    assert_eq!(refused.outcome, Outcome::Aborted, "{refused}");
    assert!(refused.refused().iter().all(|(_, e)| e.contains("operator")), "{refused}");
    assert_eq!((connections(&mut team, 1), connections(&mut team, 2)), (0, 0));
    let unsigned: u64 = [1, 2]
        .iter()
        .map(|&id| {
            let n = team.node_by_id(NodeId(id)).unwrap();
            n.transport_counters().iter().find(|(c, _)| c == "unsigned").map_or(0, |(_, v)| *v)
        })
        .sum();
    assert!(unsigned >= 2, "the refusals are counted as unsigned: {unsigned}");

    let done = run(&mut team, 9, 2);
    assert_eq!(done.outcome, Outcome::Switched, "{done}");
    assert_eq!((connections(&mut team, 1), connections(&mut team, 2)), (1, 1));
}
