//! Return routability (spec/protocol.md "CHALLENGE and ECHO"): a node's answers to an address
//! that has not proven it receives are at most three times what came from that address, so a
//! forger cannot turn a node's large LIST reports against a victim; a real requester still
//! gets every answer in full after one CHALLENGE/ECHO round trip.

use std::net::SocketAddr;

use ayllu::datagram::{BusSocket, DatagramBus, DatagramSocket};
use ayllu::routability::AMPLIFICATION_FACTOR;
use ayllu::{
    BehaviorClass, ControlBody, Duration, Lockstep, Node, NodeId, PortSpec, RequestStatus, UdpConfig, UdpTransport,
};
use ayllu_wire::{encode_datagram, WireMessage};

const TICK: Duration = Duration::from_millis(1);
const TEAM: u32 = 7;

fn addr(i: u32) -> SocketAddr {
    format!("10.0.0.{i}:7400").parse().unwrap()
}

fn count(node: &Node, cause: &str) -> u64 {
    node.transport_counters().iter().find(|(c, _)| c == cause).map_or(0, |(_, n)| *n)
}

/// Node 1, large enough that its LIST report spans several datagrams.
fn big_node(team: &mut Lockstep, bus: &DatagramBus) -> usize {
    let mut config = UdpConfig::new(addr(1));
    config.team = TEAM;
    let i = team.add_node(Node::new(
        team.clock().clone(),
        UdpTransport::with_socket(NodeId(1), config, bus.bind(addr(1)).unwrap()).unwrap(),
    ));
    let mut class = BehaviorClass::new("Wide");
    for p in 0..40 {
        class.port(PortSpec::new(&format!("Port{p:02}"), 0.0)).unwrap();
    }
    team.node(i).define(class).unwrap();
    for b in 0..8 {
        team.node(i).create("Wide", &format!("BEHAVIOR{b}")).unwrap();
    }
    i
}

/// Every byte waiting at `socket`, as (datagrams, bytes).
fn drain(socket: &mut BusSocket) -> (usize, usize) {
    let mut buf = [0u8; 9000];
    let (mut datagrams, mut bytes) = (0, 0);
    while let Ok(Some((n, _))) = socket.recv_from(&mut buf) {
        datagrams += 1;
        bytes += n;
    }
    (datagrams, bytes)
}

#[test]
fn forged_requests_make_a_node_send_a_victim_at_most_three_times_their_bytes() {
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("amplification");
    let node = big_node(&mut team, &bus);
    // The victim's address: the forger writes it as the source of its requests (on the bus,
    // by sending from a socket bound there), and we measure what reaches it.
    let mut victim = bus.bind(addr(66)).unwrap();
    let (mut sent, mut requests) = (0usize, 0usize);
    for round in 0..50u64 {
        // One forged id asking again and again, and a new forged id every round.
        for sender in [NodeId(500), NodeId(1000 + round as u32)] {
            let list = WireMessage::Request { id: round, body: ControlBody::List, signature: None };
            let bytes = encode_datagram(TEAM, sender, round, None, &[list]).unwrap();
            victim.send_to(&bytes, addr(1)).unwrap();
            sent += bytes.len();
            requests += 1;
        }
        team.advance(Duration::from_millis(20), TICK);
    }
    let (datagrams, received) = drain(&mut victim);
    let n = &team.nodes()[node];
    let full_report = n.core().report();
    let parts = ayllu_wire::reply_messages(0, &Ok(ayllu::ReplyBody::Node(Box::new(full_report))), 1472, false).unwrap();
    let report_bytes: usize = parts.iter().map(|m| ayllu_wire::encoded_len(m).unwrap()).sum();
    println!(
        "{requests} forged LIST requests, {sent} bytes; the victim got {datagrams} datagrams, {received} bytes \
         ({:.2}x); one LIST report is {report_bytes} bytes; amplification_limited {}, challenges_sent {}",
        received as f64 / sent as f64,
        count(n, "amplification_limited"),
        count(n, "challenges_sent"),
    );
    // The bound: 3x what was sent, plus one greeting (HELLO + CHALLENGE) per forged id.
    let greetings = 51 * (20 + 3 + 8 + 1 + 3 + 20 + 3 + 16);
    assert!(
        received as u64 <= AMPLIFICATION_FACTOR * sent as u64 + greetings as u64,
        "{received} bytes reached the victim for {sent} sent"
    );
    assert!(received < report_bytes * 2, "not even two whole reports got through");
    // The fresh forged ids from one address are mostly refused at admission now (N4); what
    // is let in is answered within the bound.
    assert!(
        count(n, "amplification_limited") + count(n, "admission_limited") >= 90,
        "large answers, or forged requesters, were refused and counted"
    );
}

#[test]
fn a_real_requester_gets_the_whole_report_after_one_round_trip() {
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("routability");
    let node = big_node(&mut team, &bus);
    // A tool that asks at once, before any HELLO has proven its address.
    let mut config = UdpConfig::new(addr(2));
    config.team = TEAM;
    config.peers = vec![addr(1)];
    let tool = team.add_node(Node::new(
        team.clock().clone(),
        UdpTransport::with_socket(NodeId(2), config, bus.bind(addr(2)).unwrap()).unwrap(),
    ));
    team.advance(TICK, TICK);
    let list = team.node(tool).core_mut().request(NodeId(1), ControlBody::List).unwrap();
    team.advance(Duration::from_secs(1), TICK);
    let Some(RequestStatus::Done(ayllu::ReplyBody::Node(report))) = team.nodes()[tool].core().request_status(list)
    else {
        panic!("no report: {:?}", team.nodes()[tool].core().request_status(list));
    };
    assert_eq!(report.behaviors.len(), 8, "the whole report arrived");
    let n = &team.nodes()[node];
    assert_eq!(count(n, "addresses_proven"), 1, "the tool echoed the cookie");
    assert!(count(&team.nodes()[tool], "challenges_received") >= 1);
    // Later answers go straight through.
    let again = team.node(tool).core_mut().request(NodeId(1), ControlBody::List).unwrap();
    let limited = count(&team.nodes()[node], "amplification_limited");
    team.advance(Duration::from_millis(50), TICK);
    assert!(matches!(team.nodes()[tool].core().request_status(again), Some(RequestStatus::Done(_))));
    assert_eq!(count(&team.nodes()[node], "amplification_limited"), limited);
}
