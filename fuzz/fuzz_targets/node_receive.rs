//! Fuzz target: arbitrary datagrams delivered into a running node.
//!
//! A node with the UDP transport on the in-memory datagram bus, with behaviors of every port
//! kind, a triggered process, connections of every kind and BLE, receives the input as
//! datagrams from a peer (split at 0xff 0xfe markers into up to 64 datagrams, so sequences of
//! messages across datagrams are explored; any other byte, 0xff included, stays in a
//! datagram), 3 ms of virtual time apart, then runs on for 100 ms. Promises checked: no panic;
//! the node never asks to be stepped again at the same instant without end (a busy loop); the
//! peer table stays bounded; the node keeps working afterwards (a well-formed write from a
//! real peer still lands).
//!
//! Speed: virtual time moves from one deadline the node reports ([`Node::step`]'s return) to
//! the next, as [`Node::run_for`] does in real time, instead of in fixed 1 ms ticks: a step
//! with nothing due and nothing received does nothing, so skipping it loses no behavior. The
//! behavior class, which no input can change, is built once and cloned.
#![no_main]

use std::net::SocketAddr;
use std::sync::OnceLock;

use ayllu::datagram::{DatagramBus, DatagramSocket};
use ayllu::{
    BehaviorClass, BleConfig, ConnectionKind, Duration, Endpoint, Instant, Lockstep, Node, NodeId, PortSpec, UdpConfig,
    UdpTransport, Value,
};
use libfuzzer_sys::fuzz_target;

fn addr(i: u32) -> SocketAddr {
    SocketAddr::from(([10, 0, 0, i as u8], 7400))
}

/// The most steps at one instant before the node counts as busy-looping: it reads at most 256
/// datagrams a turn and the input holds at most 64, so a handful is the most it needs.
const MAX_STEPS_AT_ONE_INSTANT: u32 = 1000;

/// Step the team's only node at every deadline it reports up to `until` (and at `until`), then
/// leave the clock at `until`.
fn run_until(team: &mut Lockstep, until: Instant) {
    let mut at_one_instant = 0;
    loop {
        let now = team.now();
        let next = team.node(0).step();
        match next {
            Some(t) if t <= now => {
                at_one_instant += 1;
                assert!(at_one_instant < MAX_STEPS_AT_ONE_INSTANT, "the node busy-loops at {now:?}");
            }
            Some(t) if t < until => {
                at_one_instant = 0;
                team.clock().set(t);
            }
            _ if now < until => {
                at_one_instant = 0;
                team.clock().set(until);
            }
            _ => return,
        }
    }
}

/// Every port kind and a process triggered by writes: made once, cloned for every input.
fn class() -> BehaviorClass {
    static CLASS: OnceLock<BehaviorClass> = OnceLock::new();
    CLASS
        .get_or_init(|| {
            let mut c = BehaviorClass::new("Every");
            for spec in [
                PortSpec::new("N", 0i64),
                PortSpec::new("Mx", 0.0).max().window(Duration::from_millis(50)),
                PortSpec::new("Mn", 0i64).min(),
                PortSpec::new("S", Value::vector(&[0.0, 0.0])).sum(),
                PortSpec::new("P", "").priority(),
                PortSpec::new("T", "").lifespan(Duration::from_millis(10)),
                PortSpec::new("B", false),
                PortSpec::new("Y", Value::bytes(&[])),
            ] {
                c.port(spec).unwrap();
            }
            let n = c.port_handle("N").unwrap();
            c.on_write("Echo", n, move |ctx| {
                let v = ctx.read(n);
                let _ = ctx.write(n, v);
            })
            .unwrap();
            c
        })
        .clone()
}

/// The input's datagrams: split at each 0xff 0xfe marker, at most 64.
fn datagrams(data: &[u8]) -> impl Iterator<Item = &[u8]> {
    let mut rest = Some(data);
    std::iter::from_fn(move || {
        let d = rest?;
        match d.windows(2).position(|w| w == [0xff, 0xfe]) {
            Some(i) => {
                rest = Some(&d[i + 2..]);
                Some(&d[..i])
            }
            None => {
                rest = None;
                Some(d)
            }
        }
    })
    .take(64)
}

fuzz_target!(|data: &[u8]| {
    let bus = DatagramBus::new();
    let mut team = Lockstep::new("fuzz");
    let mut config = UdpConfig::new(addr(1));
    config.team = u32::from_le_bytes([
        data.get(4).copied().unwrap_or(7),
        data.get(5).copied().unwrap_or(0),
        data.get(6).copied().unwrap_or(0),
        data.get(7).copied().unwrap_or(0),
    ]);
    let team_id = config.team;
    config.broadcast = Some(SocketAddr::from(([10, 0, 0, 255], 7400)));
    let t = UdpTransport::with_socket(NodeId(1), config, bus.bind(addr(1)).unwrap()).unwrap();
    let i = team.add_node(Node::new(team.clock().clone(), t));
    let node = team.node(i);
    node.define(class()).unwrap();
    node.create("Every", "E").unwrap();
    node.create("Every", "F").unwrap();
    for kind in [
        ConnectionKind::Normal,
        ConnectionKind::Suppress(Duration::from_millis(5)),
        ConnectionKind::OverrideOut(Duration::from_millis(5)),
        ConnectionKind::WriteInhibit(Duration::from_millis(5)),
    ] {
        node.connect(&Endpoint::local("E", "N"), &Endpoint::local("F", "N"), kind).unwrap();
    }
    node.connect(&Endpoint::local("F", "N"), &Endpoint::local("E", "N"), ConnectionKind::Normal).unwrap();
    let _ = node.ble_join("E", &BleConfig::new("Peers", "N", 10.0).unwrap());

    let mut evil = bus.bind(addr(66)).unwrap();
    for datagram in datagrams(data) {
        let _ = evil.send_to(datagram, addr(1));
        let until = team.now() + Duration::from_millis(3);
        run_until(&mut team, until);
    }
    let until = team.now() + Duration::from_millis(100);
    run_until(&mut team, until);
    assert!(team.nodes()[0].peers().len() <= 1024);

    // Still works. Anything the input could name may have been legitimately suppressed or
    // poisoned (a window of any period, a sequence number of u64::MAX), so the checks use what
    // the input could not reach: a behavior made afterwards, and the transport's own count of
    // well-formed datagrams from a real peer.
    let node = team.node(0);
    node.create("Every", "Fresh").unwrap();
    node.connect(&Endpoint::local("Fresh", "B"), &Endpoint::local("F", "Y"), ConnectionKind::Normal).ok();
    node.connect(&Endpoint::local("Fresh", "T"), &Endpoint::local("Fresh", "P"), ConnectionKind::Normal).unwrap();
    node.write("Fresh", "T", "still here").unwrap();
    assert_eq!(node.read("Fresh", "P").unwrap(), Value::text("still here"));
    let received = |n: &Node| n.transport_counters().iter().find(|(c, _)| c == "datagrams_received").map_or(0, |c| c.1);
    let before = received(&team.nodes()[0]);
    let hello = ayllu_wire::WireMessage::Hello { interval_ms: 1000, name: "friend".into(), groups: vec![] };
    let good = ayllu_wire::encode_datagram(team_id, NodeId(2), u64::MAX, None, &[hello]).unwrap();
    let mut friend = bus.bind(addr(2)).unwrap();
    friend.send_to(&good, addr(1)).unwrap();
    team.node(0).step();
    assert_eq!(received(&team.nodes()[0]), before + 1);
});
