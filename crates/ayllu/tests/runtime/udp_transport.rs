//! The UDP transport's network rules (N1, N3–N6, S10) on the deterministic in-memory datagram
//! bus, with a hostile peer that crafts datagrams byte by byte with `ayllu-wire`.

use std::net::SocketAddr;

use ayllu::datagram::{BusSocket, DatagramBus, DatagramSocket};
use ayllu::{
    BehaviorClass, ConnectionId, ConnectionKind, DropCause, Duration, Endpoint, Lockstep, Node, NodeId, PortMessage,
    PortSpec, UdpConfig, UdpTransport, Value,
};
use ayllu_wire::{decode, encode_datagram, DatagramWriter, ReceiverConfig, ReplyPart, WireMessage};

const TICK: Duration = Duration::from_millis(1);
const KEY: [u8; 32] = [7; 32];
const TEAM: u32 = 7;

fn addr(i: u32) -> SocketAddr {
    format!("10.0.0.{i}:7400").parse().unwrap()
}

/// A node `id` at 10.0.0.id:7400 on `bus` with a Relay behavior `R` (int ports In, Out; text
/// port Txt) and the group `team` joined.
fn node(team: &mut Lockstep, bus: &DatagramBus, id: u32, key: Option<[u8; 32]>, team_id: u32) -> usize {
    let mut config = UdpConfig::new(addr(id));
    config.broadcast = Some("10.0.0.255:7400".parse().unwrap());
    config.team = team_id;
    config.key = key;
    config.hello_interval = Duration::from_millis(100);
    let transport = UdpTransport::with_socket(NodeId(id), config, bus.bind(addr(id)).unwrap()).unwrap();
    let i = team.add_node(Node::new(team.clock().clone(), transport));
    relay(team.node(i));
    team.node(i).join("team");
    i
}

/// Give a node the Relay behavior `R` (int ports In, Out; text port Txt).
fn relay(n: &mut Node) {
    let mut relay = BehaviorClass::new("Relay");
    relay.port(PortSpec::new("In", 0i64)).unwrap();
    relay.port(PortSpec::new("Out", 0i64)).unwrap();
    relay.port(PortSpec::new("Txt", "")).unwrap();
    n.define(relay).unwrap();
    n.create("Relay", "R").unwrap();
}

fn count(node: &Node, cause: &str) -> u64 {
    node.transport_counters().iter().find(|(c, _)| c == cause).map_or(0, |(_, n)| *n)
}

fn input(node: &Node) -> Value {
    node.read("R", "In").unwrap()
}

fn port_message(conn: u64, seq: u64, port: &str, value: Value) -> WireMessage {
    WireMessage::Port(PortMessage {
        conn: ConnectionId(conn),
        seq,
        behavior: "R".into(),
        port: port.into(),
        kind: ConnectionKind::Normal,
        priority: 0,
        value,
    })
}

/// Answer, as keyed node `id` at `socket`, the CHALLENGEs waiting there with an authenticated
/// ECHO numbered `seq`: a receiver with no memory of `id` applies its port messages and
/// requests only after that (D-N5.4). Returns how many CHALLENGEs were answered.
fn answer_challenges(team: &mut Lockstep, socket: &mut BusSocket, id: u32, to: u32, seq: u64) -> usize {
    let mut buf = [0u8; 9000];
    let mut answered = 0;
    while let Ok(Some((n, _))) = socket.recv_from(&mut buf) {
        let Ok(d) = decode(&buf[..n], &ReceiverConfig { team: TEAM, key: Some(KEY) }) else { continue };
        for m in d.messages {
            if let WireMessage::Challenge { cookie } = m {
                // Numbered apart: a greeting and a freshness CHALLENGE may both be waiting.
                let seq = seq + answered as u64 * 1000;
                let echo = encode_datagram(TEAM, NodeId(id), seq, Some(KEY), &[WireMessage::Echo { cookie }]).unwrap();
                socket.send_to(&echo, addr(to)).unwrap();
                answered += 1;
            }
        }
    }
    team.advance(TICK, TICK);
    answered
}

/// Send `bytes` from the attacker and let the team process them.
fn inject(team: &mut Lockstep, attacker: &mut BusSocket, to: u32, bytes: &[u8]) {
    attacker.send_to(bytes, addr(to)).unwrap();
    team.advance(TICK, TICK);
}

#[test]
fn n5_a_keyed_team_refuses_keyless_forged_and_replayed_datagrams() {
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("udp-auth");
    let a = node(&mut team, &bus, 1, Some(KEY), TEAM);
    let b = node(&mut team, &bus, 2, Some(KEY), TEAM);
    let stranger = node(&mut team, &bus, 3, None, TEAM);
    // A sniffer on the broadcast port records what the team says.
    let mut sniffer = bus.bind(addr(99)).unwrap();
    team.advance(Duration::from_millis(300), TICK);
    team.node(a)
        .connect(&Endpoint::local("R", "Out"), &Endpoint::group("team", "R", "In"), ConnectionKind::Normal)
        .unwrap();
    team.node(a).write("R", "Out", 1i64).unwrap();
    team.advance(TICK * 2, TICK);
    assert_eq!(input(&team.nodes()[b]), Value::Int(1), "keyed peers talk");
    assert_eq!(input(&team.nodes()[stranger]), Value::Int(0), "a keyless node cannot read the keyed team");
    assert!(count(&team.nodes()[stranger], "unexpected_auth") > 0);

    // Capture the datagram that carried the value 1, then move the port on to 2.
    let mut captured = Vec::new();
    let mut buf = [0u8; 9000];
    while let Some((n, from)) = sniffer.recv_from(&mut buf).unwrap() {
        if from == addr(1) {
            let d = decode(&buf[..n], &ReceiverConfig { team: TEAM, key: Some(KEY) }).unwrap();
            // A group's port message names its group (D-S10.6).
            let carries_1 =
                |m: &WireMessage| matches!(m, WireMessage::GroupPort { message: p, .. } if p.value == Value::Int(1));
            if d.messages.iter().any(carries_1) {
                captured = buf[..n].to_vec();
            }
        }
    }
    assert!(!captured.is_empty(), "sniffer saw the broadcast");
    team.node(a).write("R", "Out", 2i64).unwrap();
    team.advance(TICK * 2, TICK);
    assert_eq!(input(&team.nodes()[b]), Value::Int(2));
    inject(&mut team, &mut sniffer, 2, &captured);
    assert_eq!(input(&team.nodes()[b]), Value::Int(2), "N5: a replayed datagram is not applied");
    assert_eq!(count(&team.nodes()[b], "replayed"), 1);

    // Keyless traffic from the stranger, and a forgery with the wrong key.
    let keyless = encode_datagram(TEAM, NodeId(3), 1, None, &[port_message(1, 1, "In", Value::Int(66))]).unwrap();
    inject(&mut team, &mut sniffer, 2, &keyless);
    let forged =
        encode_datagram(TEAM, NodeId(1), u64::MAX / 2, Some([8; 32]), &[port_message(1, 99, "In", Value::Int(77))])
            .unwrap();
    inject(&mut team, &mut sniffer, 2, &forged);
    assert_eq!(input(&team.nodes()[b]), Value::Int(2));
    assert!(count(&team.nodes()[b], "unauthenticated") >= 1);
    assert_eq!(count(&team.nodes()[b], "bad_mac"), 1);
    // The forgery did not move node 1's replay window: node 1 still gets through.
    team.node(a).write("R", "Out", 3i64).unwrap();
    team.advance(TICK * 2, TICK);
    assert_eq!(input(&team.nodes()[b]), Value::Int(3));
}

#[test]
fn n4_bad_input_is_dropped_and_counted_by_cause() {
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("udp-bad");
    let b = node(&mut team, &bus, 2, None, TEAM);
    let mut evil = bus.bind(addr(66)).unwrap();
    let good = |m: &[WireMessage]| encode_datagram(TEAM, NodeId(66), 1, None, m).unwrap();
    let valid = good(&[port_message(1, 1, "In", Value::Int(5))]);
    let cases: Vec<(&str, Vec<u8>)> = vec![
        ("truncated", valid[..10].to_vec()),
        ("bad_magic", [&[0x42u8, 0x59][..], &valid[2..]].concat()),
        ("bad_version", [&valid[..2], &[2u8][..], &valid[3..]].concat()),
        ("bad_flags", [&valid[..3], &[0x80u8][..], &valid[4..]].concat()),
        ("wrong_team", encode_datagram(8, NodeId(66), 1, None, &[port_message(1, 1, "In", Value::Int(5))]).unwrap()),
        ("oversized", vec![0u8; 8193]),
        (
            "unexpected_auth",
            encode_datagram(TEAM, NodeId(66), 1, Some(KEY), &[port_message(1, 1, "In", Value::Int(5))]).unwrap(),
        ),
        ("malformed", {
            let mut w = DatagramWriter::new(TEAM, NodeId(66), 1, None, 1472);
            w.push_raw(0x01, &[1, 2, 3]).unwrap();
            w.finish()
        }),
        ("truncated", [&valid[..], &[0x01u8, 0xff][..]].concat()),
    ];
    for (cause, bytes) in &cases {
        let before = count(&team.nodes()[b], cause);
        inject(&mut team, &mut evil, 2, bytes);
        assert_eq!(count(&team.nodes()[b], cause), before + 1, "cause {cause}");
    }
    assert_eq!(input(&team.nodes()[b]), Value::Int(0), "nothing from a dropped datagram was applied");

    // An unknown message kind is skipped; the known messages around it are applied.
    let mut w = DatagramWriter::new(TEAM, NodeId(66), 2, None, 1472);
    w.push(&port_message(1, 1, "In", Value::Int(5))).unwrap();
    w.push_raw(0x7e, b"from the future").unwrap();
    w.push(&port_message(2, 1, "Txt", Value::text("hi"))).unwrap();
    inject(&mut team, &mut evil, 2, &w.finish());
    assert_eq!(count(&team.nodes()[b], "unknown_kind"), 1);
    assert_eq!(input(&team.nodes()[b]), Value::Int(5));
    assert_eq!(team.nodes()[b].read("R", "Txt").unwrap(), Value::text("hi"));

    // Well-formed but not applicable: counted by the core.
    inject(&mut team, &mut evil, 2, &good(&[port_message(3, 1, "In", Value::text("five"))]));
    inject(
        &mut team,
        &mut evil,
        2,
        &good(&[WireMessage::Port(PortMessage {
            behavior: "GONE".into(),
            ..match port_message(4, 1, "In", Value::Int(1)) {
                WireMessage::Port(p) => p,
                _ => unreachable!(),
            }
        })]),
    );
    let core = team.nodes()[b].core().counters().clone();
    assert_eq!(core.get(DropCause::TypeMismatch), 1);
    assert_eq!(core.get(DropCause::UnknownBehavior), 1);
    // And the counters are in the node's report (what `ayllu list` shows remotely).
    let report = team.nodes()[b].core().report();
    assert!(report.transport.iter().any(|(c, n)| c == "bad_magic" && *n == 1), "{:?}", report.transport);
}

#[test]
fn n1_older_port_messages_from_a_connection_are_ignored() {
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("udp-stale");
    let b = node(&mut team, &bus, 2, None, TEAM);
    let mut peer = bus.bind(addr(5)).unwrap();
    let dg = |seq: u64, conn: u64, v: i64| {
        encode_datagram(TEAM, NodeId(5), seq, None, &[port_message(conn, seq, "In", Value::Int(v))]).unwrap()
    };
    inject(&mut team, &mut peer, 2, &dg(5, 1, 50));
    inject(&mut team, &mut peer, 2, &dg(4, 1, 40));
    inject(&mut team, &mut peer, 2, &dg(5, 1, 50));
    assert_eq!(input(&team.nodes()[b]), Value::Int(50), "the late, older message did not win");
    assert_eq!(team.nodes()[b].core().counters().get(DropCause::Stale), 2, "older and duplicate");
    inject(&mut team, &mut peer, 2, &dg(1, 2, 10));
    assert_eq!(input(&team.nodes()[b]), Value::Int(10), "sequence numbers are per connection");
}

#[test]
fn n4_a_flood_of_invented_senders_cannot_grow_the_peer_table() {
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("udp-flood");
    let a = node(&mut team, &bus, 1, None, TEAM);
    let b = node(&mut team, &bus, 2, None, TEAM);
    let mut evil = bus.bind(addr(66)).unwrap();
    for sender in 1000..6000u32 {
        let hello = WireMessage::Hello { interval_ms: 60_000, name: "x".into(), groups: vec!["team".into()] };
        evil.send_to(&encode_datagram(TEAM, NodeId(sender), 1, None, &[hello]).unwrap(), addr(2)).unwrap();
        if sender % 500 == 0 {
            team.advance(TICK, TICK);
        }
    }
    team.advance(Duration::from_millis(250), TICK);
    let peers = team.nodes()[b].peers().len();
    assert!(peers <= 1024, "peer table grew to {peers}");
    // Forged newcomers from one address are mostly refused at admission (its rate, N4);
    // those let in make room only among the unprotected.
    let n = &team.nodes()[b];
    assert!(count(n, "admission_limited") + count(n, "peer_evicted") >= 3900, "{:?}", n.transport_counters());
    // The real peer still gets through.
    team.node(a)
        .connect(&Endpoint::local("R", "Out"), &Endpoint::node(NodeId(2), "R", "In"), ConnectionKind::Normal)
        .unwrap();
    team.node(a).write("R", "Out", 9i64).unwrap();
    team.advance(Duration::from_millis(250), TICK);
    assert_eq!(input(&team.nodes()[b]), Value::Int(9));
}

#[test]
fn n3_messages_for_one_destination_in_one_turn_share_datagrams() {
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("udp-batch");
    let a = node(&mut team, &bus, 1, None, TEAM);
    let b = node(&mut team, &bus, 2, None, TEAM);
    team.advance(Duration::from_millis(300), TICK);
    for _ in 0..60 {
        team.node(a)
            .connect(&Endpoint::local("R", "Out"), &Endpoint::node(NodeId(2), "R", "In"), ConnectionKind::Normal)
            .unwrap();
    }
    let before = count(&team.nodes()[a], "datagrams_sent");
    let received_before = team.nodes()[b].core().why("R", "In").unwrap().accepted;
    team.node(a).write("R", "Out", 4i64).unwrap();
    team.step();
    let datagrams = count(&team.nodes()[a], "datagrams_sent") - before;
    let accepted = team.nodes()[b].core().why("R", "In").unwrap().accepted - received_before;
    assert_eq!(accepted, 60, "every message applied");
    assert!(datagrams <= 3, "60 messages took {datagrams} datagrams");
}

#[test]
fn n6_silent_peers_are_forgotten_and_s10_groups_route_by_announcement() {
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("udp-liveness");
    // No broadcast address: group messages go by unicast to peers that announced the group.
    let config = |id: u32| {
        let mut c = UdpConfig::new(addr(id));
        c.peers = vec![addr(1), addr(2), addr(3)];
        c.hello_interval = Duration::from_millis(100);
        c
    };
    for id in 1..=3 {
        let t = UdpTransport::with_socket(NodeId(id), config(id), bus.bind(addr(id)).unwrap()).unwrap();
        let i = team.add_node(Node::new(team.clock().clone(), t));
        relay(team.node(i));
    }
    team.node(1).join("team"); // only node 2 is in the group
    team.advance(Duration::from_millis(300), TICK);
    team.node(0)
        .connect(&Endpoint::local("R", "Out"), &Endpoint::group("team", "R", "In"), ConnectionKind::Normal)
        .unwrap();
    team.node(0).write("R", "Out", 8i64).unwrap();
    team.advance(TICK * 2, TICK);
    assert_eq!(team.nodes()[1].read("R", "In").unwrap(), Value::Int(8));
    assert_eq!(team.nodes()[2].read("R", "In").unwrap(), Value::Int(0), "node 3 did not join the group");
    assert_eq!(team.nodes()[0].peers().len(), 2);
    drop(team.kill(NodeId(3)).expect("node 3 is in the team"));
    team.advance(Duration::from_millis(400), TICK);
    let peers: Vec<u32> = team.nodes()[0].peers().iter().map(|p| p.node.0).collect();
    assert_eq!(peers, vec![2], "N6: the silent node is forgotten after three hello periods");
    assert!(count(&team.nodes()[0], "peer_expired") >= 1);
}

#[test]
fn teams_sharing_a_subnet_ignore_each_other() {
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("udp-teams");
    let a = node(&mut team, &bus, 1, None, 7);
    let b = node(&mut team, &bus, 2, None, 8);
    team.advance(Duration::from_millis(300), TICK);
    team.node(a)
        .connect(&Endpoint::local("R", "Out"), &Endpoint::group("team", "R", "In"), ConnectionKind::Normal)
        .unwrap();
    team.node(a).write("R", "Out", 1i64).unwrap();
    team.advance(TICK * 2, TICK);
    assert_eq!(input(&team.nodes()[b]), Value::Int(0));
    assert!(count(&team.nodes()[b], "wrong_team") >= 1);
    assert!(team.nodes()[b].peers().is_empty());
}

#[test]
fn n2_an_unknown_request_operation_is_answered_with_an_error() {
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("udp-unknown-op");
    node(&mut team, &bus, 2, None, TEAM);
    let mut tool = bus.bind(addr(50)).unwrap();
    let mut w = DatagramWriter::new(TEAM, NodeId(50), 1, None, 1472);
    let mut body = 42u64.to_le_bytes().to_vec();
    body.push(99);
    w.push_raw(0x10, &body).unwrap();
    inject(&mut team, &mut tool, 2, &w.finish());
    team.advance(TICK, TICK);
    let mut buf = [0u8; 9000];
    let mut answered = false;
    while let Some((n, _)) = tool.recv_from(&mut buf).unwrap() {
        let d = decode(&buf[..n], &ReceiverConfig { team: TEAM, key: None }).unwrap();
        for m in d.messages {
            if let WireMessage::Reply { id: 42, payload: ReplyPart::Error(e), .. } = m {
                assert!(e.contains("unknown operation"), "{e}");
                answered = true;
            }
        }
    }
    assert!(answered, "no error reply to an unknown operation");
}

#[test]
fn s10_a_group_with_a_multicast_address_is_delivered_by_multicast() {
    // `group=NAME@239.x.y.z:PORT`: members join the multicast group; non-members on the same
    // port do not hear it, and nothing goes to the broadcast address.
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("udp-multicast");
    let group: SocketAddr = "239.7.7.7:7400".parse().unwrap();
    let mut sniffer = bus.bind("10.0.0.255:7400".parse().unwrap()).ok();
    for id in 1..=3u32 {
        let mut c = UdpConfig::new(addr(id));
        c.peers = vec![addr(1), addr(2), addr(3)];
        if id != 3 {
            c.groups = vec![("team".to_owned(), group)];
        }
        let t = UdpTransport::with_socket(NodeId(id), c, bus.bind(addr(id)).unwrap()).unwrap();
        let i = team.add_node(Node::new(team.clock().clone(), t));
        relay(team.node(i));
        if id != 3 {
            // The URL gives the group's address; membership is the program's join (D-S10.6).
            team.node(i).join("team");
        }
    }
    team.advance(Duration::from_millis(300), TICK);
    team.node(0)
        .connect(&Endpoint::local("R", "Out"), &Endpoint::group("team", "R", "In"), ConnectionKind::Normal)
        .unwrap();
    team.node(0).write("R", "Out", 3i64).unwrap();
    team.advance(TICK * 2, TICK);
    assert_eq!(input(&team.nodes()[1]), Value::Int(3), "member 2 joined 239.7.7.7");
    assert_eq!(input(&team.nodes()[2]), Value::Int(0), "node 3 did not join the multicast group");
    let mut buf = [0u8; 9000];
    assert!(sniffer.as_mut().unwrap().recv_from(&mut buf).unwrap().is_none(), "nothing was broadcast");
}

#[test]
fn a_write_before_the_greeting_is_held_until_the_peer_greets_never_reported_sent() {
    // N6 + issue "first hour": node 1 writes node 2's port before either has heard the other.
    // The message is held (counted `held`, `NodeStats::held`, not `sent`), and leaves as soon as
    // node 2 greets (`held_sent`). Only the newest value of a connection is kept (N1).
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("udp-held");
    let a = node(&mut team, &bus, 1, None, TEAM);
    team.node(a)
        .connect(&Endpoint::local("R", "Out"), &Endpoint::node(NodeId(2), "R", "In"), ConnectionKind::Normal)
        .unwrap();
    team.node(a).write("R", "Out", 1i64).unwrap();
    team.node(a).write("R", "Out", 2i64).unwrap();
    team.step();
    let stats = team.nodes()[a].stats();
    assert_eq!((stats.sent, stats.held), (0, 2), "nothing can have left: node 2 does not exist yet");
    assert_eq!(count(&team.nodes()[a], "held"), 1);
    assert_eq!(count(&team.nodes()[a], "held_superseded"), 1);
    assert_eq!(count(&team.nodes()[a], "no_route"), 0);
    // Node 2 comes up; the nodes greet (broadcast HELLO) and the held value arrives.
    let b = node(&mut team, &bus, 2, None, TEAM);
    team.advance(Duration::from_millis(250), TICK);
    assert_eq!(input(&team.nodes()[b]), Value::Int(2), "the newest held value was delivered");
    assert_eq!(count(&team.nodes()[a], "held_sent"), 1);
    assert_eq!(team.nodes()[a].stats().sent, 0, "held messages are counted by the transport, not as sent now");
}

#[test]
fn a_reply_to_a_node_no_longer_known_is_dropped_not_held() {
    // D-S10.2: what is held waits for a node *not heard from yet*. A reply goes to a node heard
    // a moment ago; if the peer table has lost it since (a flood of invented ids evicted it),
    // holding the reply kept a whole LIST report per forged requester. It is dropped
    // (`no_route`); the requester retries (N2). A request to an unknown node is still held.
    use ayllu::{ControlBody, ControlMessage, Destination, Message, Outgoing, ReplyBody, Sent, Transport};
    let bus = DatagramBus::new();
    let mut t = UdpTransport::with_socket(NodeId(1), UdpConfig::new(addr(1)), bus.bind(addr(1)).unwrap()).unwrap();
    let to = |id: u64, body: ControlBody| Outgoing {
        to: Destination::Node(NodeId(9)),
        message: Message::Control(ControlMessage { id, body }),
    };
    let reply = ControlBody::Reply { result: Ok(ReplyBody::Value(Value::Int(1))) };
    assert_eq!(t.send(to(1, reply)), Sent::Dropped);
    assert_eq!(t.send(to(2, ControlBody::List)), Sent::Held);
    let counters = t.counters();
    let count = |name: &str| counters.iter().find(|(c, _)| c == name).map_or(0, |(_, n)| *n);
    assert_eq!((count("no_route"), count("held")), (1, 1), "{counters:?}");
}

#[test]
fn a_held_write_to_a_node_that_never_greets_expires_and_is_counted() {
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("udp-held-expiry");
    let a = node(&mut team, &bus, 1, None, TEAM);
    team.node(a)
        .connect(&Endpoint::local("R", "Out"), &Endpoint::node(NodeId(9), "R", "In"), ConnectionKind::Normal)
        .unwrap();
    team.node(a).write("R", "Out", 1i64).unwrap();
    // Three HELLO periods of 100 ms.
    team.advance(Duration::from_millis(290), TICK);
    assert_eq!(count(&team.nodes()[a], "held_expired"), 0);
    team.advance(Duration::from_millis(20), TICK);
    assert_eq!(count(&team.nodes()[a], "held_expired"), 1);
    let stats = team.nodes()[a].stats();
    assert_eq!((stats.sent, stats.held), (0, 1));
}

#[test]
fn a_second_node_with_the_same_id_is_reported_by_both() {
    // Node ids are unique in a team: two nodes with id 4 at different addresses each count the
    // other's datagrams as duplicate_id (dropped) and warn once, naming the other's address.
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("udp-duplicate-id");
    for i in [4u32, 5] {
        let mut config = UdpConfig::new(addr(i));
        config.broadcast = Some("10.0.0.255:7400".parse().unwrap());
        config.hello_interval = Duration::from_millis(100);
        let transport = UdpTransport::with_socket(NodeId(4), config, bus.bind(addr(i)).unwrap()).unwrap();
        team.add_node(Node::new(team.clock().clone(), transport));
    }
    team.advance(Duration::from_millis(350), TICK);
    for (i, other) in [(0, addr(5)), (1, addr(4))] {
        let n = &team.nodes()[i];
        assert!(count(n, "duplicate_id") >= 3, "{:?}", n.transport_counters());
        let warnings: Vec<&String> = n.core().warnings().iter().filter(|w| w.contains("id 4")).collect();
        assert_eq!(warnings.len(), 1, "{:?}", n.core().warnings());
        assert!(warnings[0].contains(&other.to_string()), "{}", warnings[0]);
        assert!(n.peers().is_empty(), "a node using our id is not a peer");
    }
}

/// Datagrams waiting at `socket`, drained.
fn drain(socket: &mut BusSocket) -> usize {
    let mut buf = [0u8; 9000];
    let mut n = 0;
    while let Ok(Some(_)) = socket.recv_from(&mut buf) {
        n += 1;
    }
    n
}

#[test]
fn n6_a_forged_hello_is_greeted_once_and_forgotten_on_the_unproven_clock() {
    // Issue "open teams": one forged HELLO announcing a period of 0xFFFFFFFF ms used to keep its
    // peer for 149 days and be greeted every second (646 datagrams per datagram). Issue 33: the
    // period clamped to 60 s still kept it 3 minutes. Now: one greeting (HELLO + CHALLENGE in
    // one datagram), and an unproven peer is forgotten on its own short clock (3 of our
    // periods, at least 1 s), whatever period it announced.
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("udp-forged-hello");
    let b = node(&mut team, &bus, 2, None, TEAM);
    // On another port than the team's, so the node's own broadcasts do not reach it.
    let mut victim = bus.bind("10.0.0.77:9999".parse().unwrap()).unwrap();
    let hello = WireMessage::Hello { interval_ms: u32::MAX, name: "forged".into(), groups: vec![] };
    victim.send_to(&encode_datagram(TEAM, NodeId(500), 1, None, &[hello]).unwrap(), addr(2)).unwrap();
    team.advance(Duration::from_millis(500), Duration::from_millis(10));
    assert!(team.nodes()[b].peers().iter().any(|p| p.node == NodeId(500)));
    team.advance(Duration::from_millis(600), Duration::from_millis(10));
    assert_eq!(drain(&mut victim), 1, "one greeting, no periodic HELLOs to an unproven peer");
    assert!(team.nodes()[b].peers().iter().all(|p| p.node != NodeId(500)), "forgotten after 1 s");
    assert_eq!(count(&team.nodes()[b], "peer_expired"), 1);
}

#[test]
fn n4_forged_newcomers_never_evict_proven_peers() {
    // A burst of 3000 invented senders between two HELLOs of the real peer used to evict it
    // (it had become the peer heard longest ago). Proven peers are never evicted for a
    // newcomer: only unproven ones make room (or the newcomer is refused: peer_table_full).
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("udp-flood-proven");
    let a = node(&mut team, &bus, 1, None, TEAM);
    let b = node(&mut team, &bus, 2, None, TEAM);
    team.advance(Duration::from_millis(300), TICK); // node 1 is proven at node 2
    let mut evil = bus.bind(addr(66)).unwrap();
    for sender in 1000..4000u32 {
        let hello = WireMessage::Hello { interval_ms: 60_000, name: "x".into(), groups: vec![] };
        evil.send_to(&encode_datagram(TEAM, NodeId(sender), 1, None, &[hello]).unwrap(), addr(2)).unwrap();
    }
    // All of it at one instant (a node reads at most 256 datagrams a step).
    for _ in 0..16 {
        team.step();
    }
    let node2 = &team.nodes()[b];
    assert!(node2.peers().len() <= 1024);
    assert!(node2.peers().iter().any(|p| p.node == NodeId(1)), "the real peer stayed");
    assert!(
        count(node2, "admission_limited") + count(node2, "peer_evicted") >= 1900,
        "{:?}",
        node2.transport_counters()
    );
    team.node(a)
        .connect(&Endpoint::local("R", "Out"), &Endpoint::node(NodeId(2), "R", "In"), ConnectionKind::Normal)
        .unwrap();
    team.node(a).write("R", "Out", 9i64).unwrap();
    team.advance(TICK * 2, TICK);
    assert_eq!(input(&team.nodes()[b]), Value::Int(9));
}

#[test]
fn n5_a_replay_after_the_senders_peer_entry_expired_is_still_refused() {
    // N5: the replay window outlives the peer entry; an authenticated datagram captured and
    // sent again after its sender was forgotten is dropped as replayed, not re-applied.
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("udp-replay-after-expiry");
    let b = node(&mut team, &bus, 2, Some(KEY), TEAM);
    let mut sender = bus.bind(addr(5)).unwrap();
    let hello = WireMessage::Hello { interval_ms: 100, name: "five".into(), groups: vec![] };
    inject(&mut team, &mut sender, 2, &encode_datagram(TEAM, NodeId(5), 1, Some(KEY), &[hello]).unwrap());
    assert!(answer_challenges(&mut team, &mut sender, 5, 2, 2) >= 1, "node 5 is challenged for freshness");
    let captured =
        encode_datagram(TEAM, NodeId(5), 5000, Some(KEY), &[port_message(1, 1, "In", Value::Int(42))]).unwrap();
    inject(&mut team, &mut sender, 2, &captured);
    assert_eq!(input(&team.nodes()[b]), Value::Int(42));
    team.node(b).write("R", "In", 0i64).unwrap();
    // Node 5 falls silent and is forgotten (3 x 100 ms, its default period here is ours).
    team.advance(Duration::from_secs(5), Duration::from_millis(10));
    assert!(team.nodes()[b].peers().iter().all(|p| p.node != NodeId(5)));
    inject(&mut team, &mut sender, 2, &captured);
    assert_eq!(count(&team.nodes()[b], "replayed"), 1);
    assert_eq!(input(&team.nodes()[b]), Value::Int(0), "the old value was not applied again");
}

#[test]
fn n5_a_replay_after_the_receivers_restart_is_refused_with_a_state_file() {
    // D-N5.3: with `state=PATH`, a keyed node keeps the newest number it accepted from each
    // sender across a restart; a datagram captured before the restart is refused after it.
    let path = std::env::temp_dir().join(format!(
        "ayllu-replay-marks-{}-{:?}",
        std::process::id(),
        std::thread::current().id()
    ));
    let _ = std::fs::remove_file(&path);
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("udp-replay-after-restart");
    let keyed_node = |team: &mut Lockstep| {
        let mut config = UdpConfig::new(addr(2));
        config.key = Some(KEY);
        config.team = TEAM;
        config.state = Some(path.clone());
        let transport = UdpTransport::with_socket(NodeId(2), config, bus.bind(addr(2)).unwrap()).unwrap();
        let i = team.add_node(Node::new(team.clock().clone(), transport));
        relay(team.node(i));
        i
    };
    let b = keyed_node(&mut team);
    let mut sender = bus.bind(addr(5)).unwrap();
    let hello = WireMessage::Hello { interval_ms: 100, name: "five".into(), groups: vec![] };
    inject(&mut team, &mut sender, 2, &encode_datagram(TEAM, NodeId(5), 8, Some(KEY), &[hello]).unwrap());
    answer_challenges(&mut team, &mut sender, 5, 2, 9);
    let captured =
        encode_datagram(TEAM, NodeId(5), 5000, Some(KEY), &[port_message(1, 1, "In", Value::Int(42))]).unwrap();
    inject(&mut team, &mut sender, 2, &captured);
    assert_eq!(input(&team.nodes()[b]), Value::Int(42));
    team.advance(Duration::from_millis(1500), TICK); // saved within a second
    assert!(count(&team.nodes()[b], "state_saved") >= 1);
    drop(team.kill(NodeId(2)));
    // The node restarts on the same address with the same state file.
    let b = keyed_node(&mut team);
    inject(&mut team, &mut sender, 2, &captured);
    assert_eq!(count(&team.nodes()[b], "replayed"), 1);
    assert_eq!(input(&team.nodes()[b]), Value::Int(0), "the captured value was not applied again");
    let newer = encode_datagram(TEAM, NodeId(5), 5001, Some(KEY), &[port_message(1, 2, "In", Value::Int(7))]).unwrap();
    inject(&mut team, &mut sender, 2, &newer);
    assert_eq!(input(&team.nodes()[b]), Value::Int(7), "newer datagrams are accepted");
    // The node saves its state once more when dropped: drop it before removing the file.
    drop(team);
    let _ = std::fs::remove_file(&path);
}

#[test]
fn a_request_retried_before_the_greeting_is_held_once() {
    // N2 retries a request every 200 ms; while its node has not greeted, each retry replaces
    // the held copy instead of queueing again, so the node gets one copy when it greets.
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("udp-held-request");
    let a = node(&mut team, &bus, 1, None, TEAM);
    let id = team.node(a).core_mut().request(NodeId(2), ayllu::ControlBody::List).unwrap();
    team.advance(Duration::from_millis(250), TICK);
    let n = &team.nodes()[a];
    assert_eq!(count(n, "held"), 1, "{:?}", n.transport_counters());
    assert!(count(n, "held_superseded") >= 1, "the retry replaced the held copy");
    let b = node(&mut team, &bus, 2, None, TEAM);
    team.advance(Duration::from_millis(300), TICK);
    assert!(matches!(team.nodes()[a].core().request_status(id), Some(ayllu::RequestStatus::Done(_))));
    let _ = b;
}

#[test]
fn a_report_too_large_for_a_reply_is_answered_with_an_error_that_says_so() {
    // A LIST of a node whose report needs more than 64 datagrams was not answered at all (the
    // requester waited 5 s and called the node silent). It is answered with an error naming
    // the size and what to do.
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("udp-report-too-large");
    let a = node(&mut team, &bus, 1, None, TEAM);
    let b = node(&mut team, &bus, 2, None, TEAM);
    for i in 0..400 {
        team.node(b).create("Relay", &format!("R{i:03}")).unwrap();
    }
    team.advance(Duration::from_millis(250), TICK);
    let id = team.node(a).core_mut().request(NodeId(2), ayllu::ControlBody::List).unwrap();
    team.advance(Duration::from_millis(100), TICK);
    match team.nodes()[a].core().request_status(id) {
        Some(ayllu::RequestStatus::Failed(e)) => {
            assert!(e.contains("more than 64 datagrams") && e.contains("mtu"), "{e}");
        }
        other => panic!("{other:?}; {:?}", team.nodes()[b].transport_counters()),
    }
    assert_eq!(count(&team.nodes()[b], "report_too_large"), 1);
    assert_eq!(count(&team.nodes()[b], "unencodable"), 0);
}

#[test]
fn a_value_too_large_for_a_reply_is_answered_with_an_error_that_says_so() {
    // A READ of a text port holding more than a datagram's worth was never answered (counted
    // `too_large` at each retry); `ayllu echo` and `write` read first and reported the node as
    // silent. It is answered with an error naming the size and the remedy.
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("udp-value-too-large");
    let a = node(&mut team, &bus, 1, None, TEAM);
    let b = node(&mut team, &bus, 2, None, TEAM);
    team.node(b).write("R", "Txt", "x".repeat(2_000).as_str()).unwrap();
    team.advance(Duration::from_millis(250), TICK);
    let read = ayllu::ControlBody::Read { behavior: "R".into(), port: "Txt".into() };
    let id = team.node(a).core_mut().request(NodeId(2), read).unwrap();
    team.advance(Duration::from_millis(100), TICK);
    match team.nodes()[a].core().request_status(id) {
        Some(ayllu::RequestStatus::Failed(e)) => {
            assert!(e.contains("more than one datagram") && e.contains("mtu"), "{e}")
        }
        other => panic!("{other:?}; {:?}", team.nodes()[b].transport_counters()),
    }
    assert_eq!(count(&team.nodes()[b], "too_large"), 1, "counted once: the retry is answered from memory");
}

#[test]
fn a_request_larger_than_a_datagram_fails_at_once_with_the_reason() {
    // A PREPARE of 130 changes at the default MTU was never sent (counted `too_large`) and
    // retried for 5 s: the coordinator reported "no answer to PREPARE", as if the node were
    // dead. The request now fails at its first send, saying why and what to do.
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("udp-request-too-large");
    let a = node(&mut team, &bus, 1, None, TEAM);
    node(&mut team, &bus, 2, None, TEAM);
    team.advance(Duration::from_millis(250), TICK);
    let changes: Vec<ayllu::Change> =
        (0..130).map(|i| ayllu::Change::Create { class: "Relay".into(), name: format!("C{i:03}") }).collect();
    let hold = Duration::from_secs(5);
    let id = team.node(a).core_mut().request(NodeId(2), ayllu::ControlBody::Prepare { txn: 1, changes, hold }).unwrap();
    team.step();
    match team.nodes()[a].core().request_status(id) {
        Some(ayllu::RequestStatus::Failed(e)) => {
            assert!(e.contains("more than one datagram") && e.contains("130 changes"), "{e}");
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(count(&team.nodes()[a], "too_large"), 1);
    // A small request to the same node still goes.
    let id = team.node(a).core_mut().request(NodeId(2), ayllu::ControlBody::List).unwrap();
    team.advance(Duration::from_millis(50), TICK);
    assert!(matches!(team.nodes()[a].core().request_status(id), Some(ayllu::RequestStatus::Done(_))));
}

#[test]
fn n4_forged_hellos_and_reply_parts_are_bounded_in_bytes_not_only_in_entries() {
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("udp-bytes");
    let b = node(&mut team, &bus, 2, None, TEAM);
    let mut evil = bus.bind(addr(66)).unwrap();
    // A HELLO of 180 groups of 40 bytes keeps at most 4 KiB of group names for its sender.
    let groups: Vec<std::sync::Arc<str>> = (0..180).map(|g| format!("{g:040}").into()).collect();
    let hello = WireMessage::Hello { interval_ms: 1000, name: "x".into(), groups };
    evil.send_to(&encode_datagram(TEAM, NodeId(500), 1, None, &[hello]).unwrap(), addr(2)).unwrap();
    team.advance(TICK, TICK);
    assert_eq!(count(&team.nodes()[b], "groups_truncated"), 1);
    // Report parts for answers nobody asked: 6 replies of 63 parts of 7 KB each (2.6 MB).
    // Fewer than the 64 assemblies allowed, but more than their 2 MiB of bytes.
    let slice = "r".repeat(7000);
    for id in 0..6u64 {
        for part in 0..63u16 {
            let reply = WireMessage::Reply { id, part, parts: 64, payload: ReplyPart::Report(slice.clone()) };
            let bytes = encode_datagram(TEAM, NodeId(500), 2 + id * 64 + u64::from(part), None, &[reply]).unwrap();
            evil.send_to(&bytes, addr(2)).unwrap();
        }
        team.advance(TICK, TICK);
    }
    assert!(count(&team.nodes()[b], "reply_evicted") >= 1, "held more than 2 MiB of report parts");
}

#[test]
fn every_message_of_a_turn_is_sent_once_and_counted_by_its_fate() {
    // A turn's messages leave from the node's queue where they lie (`Transport::send_all`):
    // one message alone, and several of different fates together, each counted once.
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("udp-send-all");
    let a = node(&mut team, &bus, 1, None, TEAM);
    let b = node(&mut team, &bus, 2, None, TEAM);
    team.advance(Duration::from_millis(250), TICK);
    let to_b = |port: &str| Endpoint::node(NodeId(2), "R", port);
    team.node(a).connect(&Endpoint::local("R", "Txt"), &to_b("Txt"), ConnectionKind::Normal).unwrap();
    team.node(a).connect(&Endpoint::local("R", "Out"), &to_b("In"), ConnectionKind::Normal).unwrap();
    team.node(a)
        .connect(&Endpoint::local("R", "Out"), &Endpoint::node(NodeId(9), "R", "In"), ConnectionKind::Normal)
        .unwrap();
    let before = team.nodes()[a].stats();

    // One message in the turn.
    team.node(a).write("R", "Txt", Value::text("one")).unwrap();
    team.advance(TICK * 2, TICK);
    let stats = team.nodes()[a].stats();
    assert_eq!((stats.sent - before.sent, stats.held - before.held), (1, 0));
    assert_eq!(team.nodes()[b].read("R", "Txt").unwrap(), Value::text("one"));

    // Three in one turn: two to node 2 (sent, one datagram), one to node 9, never heard (held).
    team.node(a).write("R", "Txt", Value::text("two")).unwrap();
    team.node(a).write("R", "Out", 5i64).unwrap();
    team.advance(TICK * 2, TICK);
    let stats = team.nodes()[a].stats();
    assert_eq!((stats.sent - before.sent, stats.held - before.held, stats.dropped - before.dropped), (3, 1, 0));
    assert_eq!(team.nodes()[b].read("R", "Txt").unwrap(), Value::text("two"));
    assert_eq!(input(&team.nodes()[b]), Value::Int(5));
    assert_eq!(count(&team.nodes()[a], "held"), 1);
    assert_eq!(team.nodes()[b].stats().received, 3, "each message arrived once");
}

#[test]
fn recv_all_hands_over_what_recv_would_in_the_same_order() {
    // Two receivers with the same configuration get the same datagrams: one is read with
    // `recv` until it returns nothing, the other with `recv_all` (what a node uses). Datagrams
    // of one and of many port messages, a group message for a non-member, a port message after
    // a CHALLENGE (which waits for the checks with everything after it), a malformed one and
    // one from another team; many datagrams, so the inbox is refilled again and again.
    use ayllu::Transport;
    let (bus_a, bus_b) = (DatagramBus::new(), DatagramBus::new());
    let receiver = |bus: &DatagramBus| {
        let mut config = UdpConfig::new(addr(2));
        config.team = TEAM;
        let mut t = UdpTransport::with_socket(NodeId(2), config, bus.bind(addr(2)).unwrap()).unwrap();
        t.join("team");
        t
    };
    let (mut by_recv, mut by_recv_all) = (receiver(&bus_a), receiver(&bus_b));
    let (mut from_a, mut from_b) = (bus_a.bind(addr(5)).unwrap(), bus_b.bind(addr(5)).unwrap());
    let mut datagrams = Vec::new();
    let mut seq = 0;
    let mut next = || {
        seq += 1;
        seq
    };
    for round in 0..300u64 {
        let mut w = DatagramWriter::new(TEAM, NodeId(5), next(), None, 1472);
        let n = if round % 7 == 0 { 9 } else { 1 };
        for k in 0..n {
            w.push(&port_message(k, round + 1, "In", Value::Int((round * 10 + k) as i64))).unwrap();
        }
        match round % 11 {
            3 => {
                let WireMessage::Port(p) = port_message(50, round + 1, "In", Value::Int(-1)) else { unreachable!() };
                w.push(&WireMessage::GroupPort { group: "legs".into(), message: p }).unwrap();
            }
            5 => {
                w.push(&WireMessage::Challenge { cookie: [round as u8; 16] }).unwrap();
                w.push(&port_message(60, round + 1, "In", Value::Int(-2))).unwrap();
            }
            7 => w.push_raw(0x01, &[1, 2, 3]).unwrap(),
            _ => {}
        }
        datagrams.push(w.finish());
        if round % 13 == 0 {
            datagrams.push(
                encode_datagram(TEAM + 1, NodeId(5), next(), None, &[port_message(1, 1, "In", Value::Int(9))]).unwrap(),
            );
        }
    }
    for d in &datagrams {
        from_a.send_to(d, addr(2)).unwrap();
        from_b.send_to(d, addr(2)).unwrap();
    }
    let mut got_recv = Vec::new();
    while let Some(m) = by_recv.recv() {
        got_recv.push(m);
    }
    let mut got_recv_all = Vec::new();
    by_recv_all.recv_all(&mut |from, m| got_recv_all.push((from, m.clone())));
    assert!(got_recv.len() > 600, "{}", got_recv.len());
    assert_eq!(got_recv_all, got_recv);
    assert_eq!(by_recv_all.counters(), by_recv.counters());
    assert!(by_recv.counters().iter().any(|(c, n)| c == "not_member" && *n > 0));
    assert!(by_recv.counters().iter().any(|(c, n)| c == "malformed" && *n > 0));
}

#[test]
fn n5_a_keyed_node_restarted_with_default_options_refuses_a_replayed_port_and_connect() {
    // Issue 33 (D-N5.4): a keyed node restarted without `state=` used to apply a PORT and a
    // CONNECT captured before the restart. Now a node with no memory of a keyed sender applies
    // its port messages and requests only once the sender answered a CHALLENGE of this run with
    // an authenticated ECHO, and then only numbers above that ECHO's: every captured datagram
    // is older. Refused ones are counted `not_fresh`.
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("udp-replay-after-plain-restart");
    let b = node(&mut team, &bus, 2, Some(KEY), TEAM);
    let mut five = bus.bind(addr(5)).unwrap();
    let hello = WireMessage::Hello { interval_ms: 100, name: "five".into(), groups: vec![] };
    inject(
        &mut team,
        &mut five,
        2,
        &encode_datagram(TEAM, NodeId(5), 1, Some(KEY), std::slice::from_ref(&hello)).unwrap(),
    );
    answer_challenges(&mut team, &mut five, 5, 2, 2);
    // What an attacker captures on the wire, and node 2 applies the first time.
    let port = encode_datagram(TEAM, NodeId(5), 3000, Some(KEY), &[port_message(1, 1, "In", Value::Int(42))]).unwrap();
    let connect = WireMessage::Request {
        id: 77,
        body: ayllu::ControlBody::Connect {
            source_behavior: "R".into(),
            source_port: "Out".into(),
            destination: Endpoint::node(NodeId(5), "R", "In"),
            kind: ConnectionKind::Normal,
            priority: 0,
        },
        signature: None,
    };
    let connect = encode_datagram(TEAM, NodeId(5), 3001, Some(KEY), &[connect]).unwrap();
    inject(&mut team, &mut five, 2, &port);
    inject(&mut team, &mut five, 2, &connect);
    let to_five = || (Endpoint::local("R", "Out"), Endpoint::node(NodeId(5), "R", "In"));
    let connections = |team: &Lockstep, i: usize| {
        let (from, to) = to_five();
        team.nodes()[i].core().connections_between(&from, &to).len()
    };
    assert_eq!(input(&team.nodes()[b]), Value::Int(42), "applied before the restart");
    assert_eq!(connections(&team, b), 1, "the CONNECT was applied before the restart");

    // Node 2 restarts with its default options: same id, key and address, no state file.
    drop(team.kill(NodeId(2)));
    let b = node(&mut team, &bus, 2, Some(KEY), TEAM);
    drain(&mut five);
    let mut attacker = bus.bind(addr(66)).unwrap();
    inject(&mut team, &mut attacker, 2, &port);
    inject(&mut team, &mut attacker, 2, &connect);
    team.advance(Duration::from_millis(50), TICK);
    let n = &team.nodes()[b];
    assert_eq!(input(n), Value::Int(0), "the replayed PORT was not applied");
    assert_eq!(connections(&team, b), 0, "the replayed CONNECT was not applied");
    assert_eq!(count(n, "not_fresh"), 2, "both refused and counted: {:?}", n.transport_counters());
    assert!(count(n, "challenges_sent") >= 1, "the replayer was challenged (and cannot answer)");
    // Sent again later (the window now knows them), they are refused as replays.
    inject(&mut team, &mut attacker, 2, &port);
    assert_eq!(count(&team.nodes()[b], "replayed"), 1);

    // The real node 5, sending on, answers the CHALLENGE and is heard again one round trip later.
    inject(&mut team, &mut five, 2, &encode_datagram(TEAM, NodeId(5), 4000, Some(KEY), &[hello]).unwrap());
    assert!(answer_challenges(&mut team, &mut five, 5, 2, 4001) >= 1);
    let newer = encode_datagram(TEAM, NodeId(5), 5001, Some(KEY), &[port_message(1, 2, "In", Value::Int(7))]).unwrap();
    inject(&mut team, &mut five, 2, &newer);
    let n = &team.nodes()[b];
    assert_eq!(input(n), Value::Int(7), "a fresh sender's values are applied");
    assert_eq!(count(n, "senders_fresh"), 1);
    // A captured datagram numbered between the two lives of the window is still refused.
    inject(&mut team, &mut attacker, 2, &connect);
    assert_eq!(connections(&team, b), 0);
}
