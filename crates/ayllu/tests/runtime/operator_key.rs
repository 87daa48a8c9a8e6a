//! Operator key (docs/security.md, spec/protocol.md "Operator signature"): a node given an
//! operator public key applies CONNECT and DISCONNECT only when signed with the operator's
//! secret, each signed request once — across the retry horizon, the requester's peer expiry
//! and the node's own restart — while port writes and reads stay as they were.

use std::net::SocketAddr;

use ayllu::datagram::{BusSocket, DatagramBus, DatagramSocket};
use ayllu::{
    BehaviorClass, ConnectionKind, ControlBody, Duration, Endpoint, Lockstep, Node, NodeId, PortSpec, RequestStatus,
    UdpConfig, UdpTransport,
};
use ayllu_wire::{decode, encode_datagram, OperatorSecret, ReceiverConfig, ReplyPart, SignedRequest, WireMessage};

const TICK: Duration = Duration::from_millis(1);
const TEAM: u32 = 7;

fn addr(i: u32) -> SocketAddr {
    format!("10.0.0.{i}:7400").parse().unwrap()
}

fn operator() -> OperatorSecret {
    OperatorSecret::from_seed(&[42; 32])
}

/// Node `id` with behavior `R` (int ports In, Out), configured by `set`.
fn node(team: &mut Lockstep, bus: &DatagramBus, id: u32, set: impl FnOnce(&mut UdpConfig)) -> usize {
    let mut config = UdpConfig::new(addr(id));
    config.team = TEAM;
    config.peers = (1..=3).filter(|p| *p != id).map(addr).collect();
    config.hello_interval = Duration::from_millis(100);
    set(&mut config);
    let transport = UdpTransport::with_socket(NodeId(id), config, bus.bind(addr(id)).unwrap()).unwrap();
    let i = team.add_node(Node::new(team.clock().clone(), transport));
    let mut relay = BehaviorClass::new("Relay");
    relay.port(PortSpec::new("In", 0i64)).unwrap();
    relay.port(PortSpec::new("Out", 0i64)).unwrap();
    team.node(i).define(relay).unwrap();
    team.node(i).create("Relay", "R").unwrap();
    i
}

fn count(node: &Node, cause: &str) -> u64 {
    node.transport_counters().iter().find(|(c, _)| c == cause).map_or(0, |(_, n)| *n)
}

fn requested_connections(node: &Node) -> usize {
    node.core().report().connections.len()
}

/// Ask node 1 (from the node at `from`) to connect its R.Out to the asker's R.In; the outcome.
fn ask_connect(team: &mut Lockstep, from: usize) -> RequestStatus {
    let id = team
        .node(from)
        .core_mut()
        .request_connect(
            &Endpoint::node(NodeId(1), "R", "Out"),
            &Endpoint::local("R", "In"),
            ConnectionKind::Normal,
            Default::default(),
        )
        .unwrap();
    team.advance(Duration::from_millis(500), TICK);
    team.nodes()[from].core().request_status(id).unwrap()
}

#[test]
fn only_the_operator_may_rewire_a_node_that_holds_its_key() {
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("operator");
    let robot = node(&mut team, &bus, 1, |c| c.operator = Some(operator().public()));
    let tool = node(&mut team, &bus, 2, |c| c.operator_secret = Some(operator()));
    let intruder = node(&mut team, &bus, 3, |c| c.operator_secret = Some(OperatorSecret::from_seed(&[9; 32])));
    let stranger = team.add_node({
        let mut config = UdpConfig::new(addr(4));
        config.team = TEAM;
        config.peers = vec![addr(1)];
        Node::new(
            team.clock().clone(),
            UdpTransport::with_socket(NodeId(4), config, bus.bind(addr(4)).unwrap()).unwrap(),
        )
    });
    team.node(stranger).define(BehaviorClass::new("Empty")).unwrap();
    let mut empty = BehaviorClass::new("Relay");
    empty.port(PortSpec::new("In", 0i64)).unwrap();
    team.node(stranger).define(empty).unwrap();
    team.node(stranger).create("Relay", "R").unwrap();
    team.advance(Duration::from_millis(300), TICK);

    let refused = |s: RequestStatus| match s {
        RequestStatus::Failed(why) => why,
        other => panic!("expected a refusal, got {other:?}"),
    };
    let unsigned = refused(ask_connect(&mut team, stranger));
    assert!(unsigned.contains("operator key"), "{unsigned}");
    assert_eq!(count(&team.nodes()[robot], "unsigned"), 1);
    let forged = refused(ask_connect(&mut team, intruder));
    assert!(forged.contains("operator key") && forged.contains("bad_signature"), "{forged}");
    assert_eq!(count(&team.nodes()[robot], "bad_signature"), 1);
    assert_eq!(requested_connections(&team.nodes()[robot]), 0, "nothing was rewired");

    assert!(matches!(ask_connect(&mut team, tool), RequestStatus::Done(_)), "the operator's tool may");
    assert_eq!(requested_connections(&team.nodes()[robot]), 1);
    team.node(robot).write("R", "Out", 5i64).unwrap();
    team.advance(Duration::from_millis(20), TICK);
    assert_eq!(team.nodes()[tool].read("R", "In").unwrap(), 5i64.into(), "and the connection works");

    // Reads need no signature.
    let list = team.node(stranger).core_mut().request(NodeId(1), ControlBody::List).unwrap();
    team.advance(Duration::from_millis(600), TICK);
    assert!(matches!(team.nodes()[stranger].core().request_status(list), Some(RequestStatus::Done(_))));
}

/// A signed CONNECT from node 5 (its R.Out to node 5's R.In), as an operator tool would send.
fn signed_connect(id: u64, seq: u64) -> Vec<u8> {
    let body = ControlBody::Connect {
        source_behavior: "R".into(),
        source_port: "Out".into(),
        destination: Endpoint::node(NodeId(5), "R", "In"),
        kind: ConnectionKind::Normal,
        priority: 0,
    };
    let request = SignedRequest { team: TEAM, requester: NodeId(5), receiver: NodeId(1), id, body: &body };
    let signature = Some(operator().sign(&request).unwrap());
    encode_datagram(TEAM, NodeId(5), seq, None, &[WireMessage::Request { id, body, signature }]).unwrap()
}

fn replies(socket: &mut BusSocket) -> Vec<ReplyPart> {
    let mut buf = [0u8; 9000];
    let mut out = Vec::new();
    while let Ok(Some((n, _))) = socket.recv_from(&mut buf) {
        if let Ok(d) = decode(&buf[..n], &ReceiverConfig::open(TEAM)) {
            out.extend(d.messages.into_iter().filter_map(|m| match m {
                WireMessage::Reply { payload, .. } => Some(payload),
                _ => None,
            }));
        }
    }
    out
}

#[test]
fn a_captured_signed_request_is_applied_once_even_after_expiry_and_restart() {
    let dir = std::env::temp_dir().join(format!("ayllu-operator-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let state = dir.join("robot.state");
    let _ = std::fs::remove_file(&state);
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("operator-replay");
    let set = |c: &mut UdpConfig| {
        c.operator = Some(operator().public());
        c.state = Some(state.clone());
        c.peers.clear();
    };
    let robot = node(&mut team, &bus, 1, set);
    let mut tool = bus.bind(addr(5)).unwrap();
    let captured = signed_connect(1 << 40, 1);

    tool.send_to(&captured, addr(1)).unwrap();
    team.advance(Duration::from_millis(10), TICK);
    assert_eq!(requested_connections(&team.nodes()[robot]), 1);
    assert!(matches!(replies(&mut tool)[..], [ReplyPart::Connection(_)]));
    // A retry within the horizon is answered from memory, not applied twice.
    tool.send_to(&signed_connect(1 << 40, 2), addr(1)).unwrap();
    team.advance(Duration::from_millis(10), TICK);
    assert_eq!(requested_connections(&team.nodes()[robot]), 1);
    assert!(matches!(replies(&mut tool)[..], [ReplyPart::Connection(_)]));

    // The requester falls silent: its peer entry expires and its leased connection goes (D9.1).
    team.advance(Duration::from_secs(12), Duration::from_millis(10));
    assert_eq!(requested_connections(&team.nodes()[robot]), 0, "the lease ended");
    tool.send_to(&signed_connect(1 << 40, 3), addr(1)).unwrap();
    team.advance(Duration::from_millis(10), TICK);
    assert_eq!(requested_connections(&team.nodes()[robot]), 0, "replayed after expiry: refused");
    assert_eq!(count(&team.nodes()[robot], "replayed"), 1);

    // The robot restarts with its state file: the replay is still refused, a newer request is not.
    team.advance(Duration::from_secs(2), Duration::from_millis(10));
    team.kill(NodeId(1));
    let bus2 = DatagramBus::new();
    let mut team2 = Lockstep::new("operator-restart");
    let robot2 = node(&mut team2, &bus2, 1, set);
    let mut tool2 = bus2.bind(addr(5)).unwrap();
    tool2.send_to(&captured, addr(1)).unwrap();
    team2.advance(Duration::from_millis(10), TICK);
    assert_eq!(requested_connections(&team2.nodes()[robot2]), 0, "replayed after the restart: refused");
    assert_eq!(count(&team2.nodes()[robot2], "replayed"), 1);
    tool2.send_to(&signed_connect((1 << 40) + 1, 4), addr(1)).unwrap();
    team2.advance(Duration::from_millis(10), TICK);
    assert_eq!(requested_connections(&team2.nodes()[robot2]), 1, "a newer signed request is applied");
    let _ = std::fs::remove_dir_all(&dir);
}
