//! A wrapped transport tells the node everything its inner transport does: lost peers,
//! warnings and failed requests reach the node through every wrapper ([`TransportWrapper`]),
//! the recording tap included, and through a box. Before the wrappers delegated by default, the tap
//! forwarded lost peers and warnings by hand but not failed requests, so a request too large
//! for a datagram was retried for 5 s through it instead of failing at once.

use std::collections::VecDeque;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};

use ayllu::datagram::DatagramBus;
use ayllu::team_recording::Tap;
use ayllu::transport::TransportWrapper;
use ayllu::{
    BehaviorClass, ConnectionKind, ControlBody, ControlMessage, Duration, Endpoint, Lockstep, ManualClock, Message,
    Node, NodeId, Outgoing, PortSpec, RequestStatus, Sent, Transport, TransportEvent, UdpConfig, UdpTransport,
};

const TICK: Duration = Duration::from_millis(1);

/// What the scripted transport is told to deliver and report.
#[derive(Default)]
struct Script {
    incoming: VecDeque<(NodeId, Message)>,
    events: Vec<TransportEvent>,
}

/// An inner transport whose arrivals and events a test decides. It cannot send a LIST (it
/// reports the request failed, as the UDP transport does for one larger than a datagram);
/// everything else it sends goes nowhere.
struct Scripted {
    script: Arc<Mutex<Script>>,
}

impl Transport for Scripted {
    fn local(&self) -> NodeId {
        NodeId(1)
    }
    fn send(&mut self, out: Outgoing) -> Sent {
        match (&out.to, &out.message) {
            (ayllu::Destination::Node(to), Message::Control(ControlMessage { id, body: ControlBody::List })) => {
                let why = "scripted: this transport cannot carry a LIST".to_owned();
                self.script.lock().unwrap().events.push(TransportEvent::RequestFailed { to: *to, id: *id, why });
                Sent::Dropped
            }
            _ => Sent::Now,
        }
    }
    fn recv(&mut self) -> Option<(NodeId, Message)> {
        self.script.lock().unwrap().incoming.pop_front()
    }
    fn wait(&mut self, _timeout: std::time::Duration) {}
    fn join(&mut self, _group: &str) {}
    fn leave(&mut self, _group: &str) {}
    fn take_events(&mut self, out: &mut Vec<TransportEvent>) {
        out.append(&mut self.script.lock().unwrap().events);
    }
}

/// A wrapper that overrides nothing: what every wrapper gets by default.
struct Bare<T: Transport>(T);

impl<T: Transport> TransportWrapper for Bare<T> {
    type Inner = T;
    fn inner(&self) -> &T {
        &self.0
    }
    fn inner_mut(&mut self) -> &mut T {
        &mut self.0
    }
}

/// Give a node the Relay behavior `R` (int ports In, Out).
fn relay(n: &mut Node) {
    let mut relay = BehaviorClass::new("Relay");
    relay.port(PortSpec::new("In", 0i64)).unwrap();
    relay.port(PortSpec::new("Out", 0i64)).unwrap();
    n.define(relay).unwrap();
    n.create("Relay", "R").unwrap();
}

/// Every kind of event the scripted transport raises reaches the node built on `wrap(it)`.
fn events_reach_the_node(wrap: impl FnOnce(Scripted) -> Box<dyn Transport>) {
    let script = Arc::new(Mutex::new(Script::default()));
    let clock = ManualClock::new();
    let mut node = Node::new(clock.clone(), wrap(Scripted { script: script.clone() }));
    relay(&mut node);
    // Node 9 asks for a connection: leased to it (D9.1), so released when it is lost.
    let connect = ControlBody::Connect {
        source_behavior: "R".into(),
        source_port: "Out".into(),
        destination: Endpoint::Node { node: NodeId(9), behavior: "S".into(), port: "In".into() },
        kind: ConnectionKind::Normal,
        priority: 0,
    };
    script.lock().unwrap().incoming.push_back((NodeId(9), Message::Control(ControlMessage { id: 77, body: connect })));
    node.step();
    assert_eq!(node.core().report().connections.len(), 1, "node 9's CONNECT was applied");

    script.lock().unwrap().events.push(TransportEvent::Warning("scripted warning".into()));
    script.lock().unwrap().events.push(TransportEvent::PeerLost(NodeId(9)));
    clock.advance(TICK);
    node.step();
    assert!(node.core().warnings().iter().any(|w| w == "scripted warning"), "{:?}", node.core().warnings());
    assert!(node.core().report().connections.is_empty(), "the lost peer's connection was released");

    let id = node.core_mut().request(NodeId(2), ControlBody::List).unwrap();
    clock.advance(TICK);
    node.step();
    match node.core().request_status(id) {
        Some(RequestStatus::Failed(e)) => assert!(e.contains("cannot carry a LIST"), "{e}"),
        other => panic!("the request did not fail at its first send: {other:?}"),
    }
}

#[test]
fn every_event_reaches_the_node_through_a_wrapper_that_overrides_nothing() {
    events_reach_the_node(|t| Box::new(Bare(t)));
}

#[test]
fn every_event_reaches_the_node_through_the_recording_tap() {
    events_reach_the_node(|t| Box::new(Tap::new(t).0));
}

#[test]
fn every_event_reaches_the_node_through_a_box_and_wrappers_of_wrappers() {
    events_reach_the_node(|t| Box::new(Box::new(Bare(Tap::new(t).0)) as Box<dyn Transport>));
}

fn addr(i: u32) -> SocketAddr {
    format!("10.0.0.{i}:7400").parse().unwrap()
}

#[test]
fn a_request_larger_than_a_datagram_fails_at_once_through_the_recording_tap() {
    // The UDP transport's own rule (udp_transport.rs), with `ayllu record`'s tap around it.
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("tap-request-too-large");
    let mut nodes = Vec::new();
    for id in 1..=2 {
        let mut config = UdpConfig::new(addr(id));
        config.broadcast = Some("10.0.0.255:7400".parse().unwrap());
        config.hello_interval = Duration::from_millis(100);
        let udp = UdpTransport::with_socket(NodeId(id), config, bus.bind(addr(id)).unwrap()).unwrap();
        let (tap, _log) = Tap::new(udp);
        let i = team.add_node(Node::new(team.clock().clone(), tap));
        relay(team.node(i));
        nodes.push(i);
    }
    team.advance(Duration::from_millis(250), TICK);
    let changes: Vec<ayllu::Change> =
        (0..130).map(|i| ayllu::Change::Create { class: "Relay".into(), name: format!("C{i:03}") }).collect();
    let prepare = ControlBody::Prepare { txn: 1, changes, hold: Duration::from_secs(5) };
    let id = team.node(nodes[0]).core_mut().request(NodeId(2), prepare).unwrap();
    team.step();
    match team.nodes()[nodes[0]].core().request_status(id) {
        Some(RequestStatus::Failed(e)) => assert!(e.contains("more than one datagram"), "{e}"),
        other => panic!("retried instead of failing at once: {other:?}"),
    }
}
