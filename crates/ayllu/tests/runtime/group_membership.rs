//! S10 and D-S10.6: a message to `(group, behavior, port)` is applied by every node that joined
//! the group except the sender, and by no other node, even when the route reaches non-members
//! too (the team's `broadcast=` address, a group address, zenoh's team-wide key).
//!
//! On `udp://` a group's port messages name their group and a non-member drops them, counted
//! `not_member`: checked on the deterministic datagram bus with a shared broadcast address,
//! and over a real loopback socket (bound to port 0) with hand-made datagrams. `mem://`
//! delivers a group's messages to its members only, checked here with a non-member present.

use std::net::SocketAddr;
use std::time::Instant as WallClock;

use ayllu::datagram::DatagramBus;
use ayllu::{
    BehaviorClass, ConnectionId, ConnectionKind, Duration, Endpoint, Lockstep, MemNetwork, Node, NodeId, PortMessage,
    PortSpec, UdpConfig, UdpTransport, Value,
};
use ayllu_wire::{encode_datagram, WireMessage};

const TICK: Duration = Duration::from_millis(1);
const TEAM: u32 = 7;

fn addr(i: u32) -> SocketAddr {
    format!("10.0.0.{i}:7400").parse().unwrap()
}

/// Give a node the Relay behavior `R` (int ports In, Out).
fn relay(n: &mut Node) {
    let mut relay = BehaviorClass::new("Relay");
    relay.port(PortSpec::new("In", 0i64)).unwrap();
    relay.port(PortSpec::new("Out", 0i64)).unwrap();
    n.define(relay).unwrap();
    n.create("Relay", "R").unwrap();
}

fn count(node: &Node, cause: &str) -> u64 {
    node.transport_counters().iter().find(|(c, _)| c == cause).map_or(0, |(_, n)| *n)
}

fn input(node: &Node) -> Value {
    node.read("R", "In").unwrap()
}

/// Node `i` of `team` connects its `R.Out` to `R.In` of `group` and writes `v`.
fn write_to_group(team: &mut Lockstep, i: usize, group: &str, v: i64) {
    team.node(i)
        .connect(&Endpoint::local("R", "Out"), &Endpoint::group(group, "R", "In"), ConnectionKind::Normal)
        .unwrap();
    team.node(i).write("R", "Out", v).unwrap();
    team.advance(TICK * 3, TICK);
}

#[test]
fn udp_a_broadcast_group_message_is_applied_by_members_only() {
    // Three nodes share the broadcast address 10.0.0.255: every group message reaches all of
    // them. Nodes 1 and 2 joined `arm`, node 3 joined `legs`.
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("udp-group-membership");
    for (id, group) in [(1u32, "arm"), (2, "arm"), (3, "legs")] {
        let mut c = UdpConfig::new(addr(id));
        c.broadcast = Some("10.0.0.255:7400".parse().unwrap());
        c.team = TEAM;
        c.hello_interval = Duration::from_millis(100);
        let t = UdpTransport::with_socket(NodeId(id), c, bus.bind(addr(id)).unwrap()).unwrap();
        let i = team.add_node(Node::new(team.clock().clone(), t));
        relay(team.node(i));
        team.node(i).join(group);
    }
    team.advance(Duration::from_millis(300), TICK);

    write_to_group(&mut team, 0, "arm", 5);
    let nodes = team.nodes();
    assert_eq!(input(&nodes[1]), Value::Int(5), "member 2 applies it");
    assert_eq!(input(&nodes[2]), Value::Int(0), "node 3 did not join `arm`: its port is unchanged");
    assert_eq!(count(&nodes[2], "not_member"), 1, "node 3 received it (broadcast) and counted it");
    assert_eq!(input(&nodes[0]), Value::Int(0), "the sender does not apply its own group message");
    assert_eq!(count(&nodes[0], "not_member"), 0, "its echo is its own (`own`), not a non-member's");
    assert_eq!(count(&nodes[1], "not_member"), 0);

    // The other way round: to `legs`, node 3 applies and the members of `arm` count.
    write_to_group(&mut team, 1, "legs", 6);
    let nodes = team.nodes();
    assert_eq!(input(&nodes[2]), Value::Int(6), "member 3 applies it");
    assert_eq!(input(&nodes[0]), Value::Int(0), "node 1 is not in `legs`");
    assert_eq!(count(&nodes[0], "not_member"), 1);
    assert_eq!(input(&nodes[1]), Value::Int(5), "the sender keeps its value");

    // A node that leaves a group stops applying its messages.
    team.node(1).leave("arm");
    team.node(0).write("R", "Out", 7i64).unwrap();
    team.advance(TICK * 3, TICK);
    let nodes = team.nodes();
    assert_eq!(input(&nodes[1]), Value::Int(5), "node 2 left `arm`");
    assert_eq!(count(&nodes[1], "not_member"), 1);
    assert_eq!(count(&nodes[2], "not_member"), 2);

    // Node-addressed messages name no group and are applied as before.
    team.node(2)
        .connect(&Endpoint::local("R", "Out"), &Endpoint::node(NodeId(2), "R", "In"), ConnectionKind::Normal)
        .unwrap();
    team.node(2).write("R", "Out", 9i64).unwrap();
    team.advance(TICK * 3, TICK);
    assert_eq!(input(&team.nodes()[1]), Value::Int(9), "a message to node 2 is applied");
    assert_eq!(count(&team.nodes()[1], "not_member"), 1);
}

fn port(seq: u64, v: i64) -> PortMessage {
    PortMessage {
        conn: ConnectionId(1),
        seq,
        behavior: "R".into(),
        port: "In".into(),
        kind: ConnectionKind::Normal,
        priority: 0,
        value: Value::Int(v),
    }
}

#[test]
fn udp_over_loopback_a_port_message_naming_another_group_is_not_applied() {
    // A real socket bound to port 0; a raw socket plays a team mate whose group messages reach
    // this node (as a shared broadcast address would deliver them).
    let mut node = Node::open(NodeId(1), "udp://127.0.0.1:0?team=7&hello_ms=50").unwrap();
    relay(&mut node);
    node.join("legs");
    let to: SocketAddr = node.address().unwrap().parse().unwrap();
    let raw = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let send = |seq: u64, m: WireMessage| {
        let bytes = encode_datagram(TEAM, NodeId(9), seq, None, &[m]).unwrap();
        raw.send_to(&bytes, to).unwrap();
    };
    // Each datagram is sent, then the node runs until it has counted it (bounded in time).
    let run_until = |node: &mut Node, done: &dyn Fn(&Node) -> bool| {
        let limit = WallClock::now() + std::time::Duration::from_secs(20);
        while !done(node) {
            assert!(WallClock::now() < limit, "counters {:?}", node.transport_counters());
            node.run_for(std::time::Duration::from_millis(5));
        }
    };
    send(1, WireMessage::GroupPort { group: "arm".into(), message: port(1, 5) });
    run_until(&mut node, &|n| count(n, "not_member") == 1);
    assert_eq!(input(&node), Value::Int(0), "not a member of `arm`: nothing applied");

    send(2, WireMessage::GroupPort { group: "legs".into(), message: port(2, 6) });
    run_until(&mut node, &|n| input(n) == Value::Int(6));
    send(3, WireMessage::Port(port(3, 7)));
    run_until(&mut node, &|n| input(n) == Value::Int(7));
    assert_eq!(count(&node, "not_member"), 1, "member and node-addressed messages are applied");
}

#[test]
fn mem_group_messages_reach_members_only() {
    // mem:// keeps the group table itself and delivers to members: no message reaches a
    // non-member, so nothing is counted.
    let net = MemNetwork::new();
    let mut team = Lockstep::new("mem-group-membership");
    for (id, group) in [(1u32, "arm"), (2, "arm"), (3, "legs")] {
        let t = net.attach(NodeId(id)).unwrap();
        let i = team.add_node(Node::new(team.clock().clone(), t));
        relay(team.node(i));
        team.node(i).join(group);
    }
    write_to_group(&mut team, 0, "arm", 5);
    let nodes = team.nodes();
    assert_eq!(input(&nodes[1]), Value::Int(5), "member 2 applies it");
    assert_eq!(input(&nodes[2]), Value::Int(0), "node 3 did not join `arm`");
    assert_eq!(input(&nodes[0]), Value::Int(0), "not the sender");
    let (delivered, _) = net.stats();
    assert_eq!(delivered, 1, "one delivery: to the one other member");
}
