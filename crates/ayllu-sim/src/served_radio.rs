//! The scenario's radio model applied to a served robot's real traffic: in the distributed
//! mode (`ayllu sim serve` + `ayllu sim robot`) the controllers talk real UDP, which on
//! loopback loses nothing and delays nothing, so each robot's transport is wrapped in a
//! [`RadioLink`] that does to the messages from its peers what the in-process [`crate::radio`]
//! does (docs/cmommt.md, "The distributed mode").
//!
//! What a link does to a message from another robot (node ids below
//! [`crate::served_robot::BODY_BASE`]), at the receiver:
//! * cut when the server says the sender is out of reach: dead, out of range or across a
//!   partition. The server knows the world's true positions and time, so it computes every
//!   robot's row of reachability each sensing tick and sends it over the body link
//!   ([`crate::served_robot`]'s `LINK.Reach`); the robot's [`crate::served_robot::LinkDriver`]
//!   hands it to [`LinkHandle::set_reach`] each turn;
//! * lost with the scenario's probability, drawn per receiver from a stream seeded by the
//!   scenario's seed and the robot's id (as a broadcast over a lossy channel loses per receiver);
//! * held for `delay + jitter·U(0,1)` on the node's clock, drawn per received message (in-process
//!   it is drawn once per emission, so there every receiver of a broadcast hears it at once).
//!
//! Messages from the robot's body (its sensors, the server's word) pass untouched: that link is
//! the robot's own wiring, not the radio. Outgoing messages pass untouched too, but those to
//! anyone but the body are counted as radio emissions (a group message once) with their encoded
//! size, the figures of `msgs_per_robot_s` and bytes per robot per second.
//!
//! Promise: the link never blocks and keeps the [`Transport`] contract; nothing is held longer
//! than `delay + jitter` after the node's clock passes it.

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::sync::{Arc, Mutex, MutexGuard};

use ayllu::transport::TransportWrapper;
use ayllu::{Sent, Transport};
use ayllu_core::{Destination, Duration, Instant, Message, NodeId, Outgoing};

use crate::radio::{wire_len, RadioConfig, Station};
use crate::served_robot::BODY_BASE;

/// Robot `i`'s row of reachability at `t` (s), as the server sends it (`LINK.Reach`): entry j
/// is 1.0 when robot j + 1's messages reach robot i + 1 — both alive, and `radio` connects
/// them ([`RadioConfig::connects`]: range, partitions) — else 0.0 (itself: 0.0).
pub fn reach_row(radio: &RadioConfig, t: f64, stations: &[Station], i: usize, row: &mut [f64]) {
    let me = &stations[i];
    for (j, (r, s)) in row.iter_mut().zip(stations).enumerate() {
        let heard = j != i && me.alive && s.alive && radio.connects(t, s, me);
        *r = f64::from(u8::from(heard));
    }
}

/// What a link has done so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkCounts {
    /// Radio emissions (messages to anyone but the body; a group message counts once).
    pub sent: u64,
    /// Their encoded size in bytes (wire format, message headers included, datagram headers not).
    pub bytes: u64,
    /// Peers' messages handed to the node.
    pub delivered: u64,
    /// Peers' messages dropped by the loss draw.
    pub lost: u64,
    /// Peers' messages cut because the sender was out of reach.
    pub cut: u64,
}

struct Held {
    at: Instant,
    order: u64,
    from: NodeId,
    message: Message,
}

impl PartialEq for Held {
    fn eq(&self, other: &Self) -> bool {
        (self.at, self.order) == (other.at, other.order)
    }
}
impl Eq for Held {}
impl PartialOrd for Held {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Held {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        (self.at, self.order).cmp(&(other.at, other.order))
    }
}

struct LinkState {
    robot: NodeId,
    body: NodeId,
    loss: f64,
    delay: f64,
    jitter: f64,
    rng: fastrand::Rng,
    /// Whether robot k (index k - 1) is in reach; robots beyond the list are.
    reach: Vec<bool>,
    held: BinaryHeap<Reverse<Held>>,
    order: u64,
    now: Instant,
    counts: LinkCounts,
}

/// A transport with the scenario's radio applied to what the robot hears from its peers (see
/// the module docs).
pub struct RadioLink<T> {
    inner: T,
    state: Arc<Mutex<LinkState>>,
}

/// The robot loop's side of a [`RadioLink`]: sets the reachability the server sends, reads the
/// counts.
#[derive(Clone)]
pub struct LinkHandle(Arc<Mutex<LinkState>>);

fn lock(state: &Mutex<LinkState>) -> MutexGuard<'_, LinkState> {
    // A panic elsewhere cannot leave the state half-updated in a way that matters here.
    state.lock().unwrap_or_else(|e| e.into_inner())
}

impl LinkHandle {
    /// Reachability from the server: `reach[k - 1]` says whether robot k's messages reach this
    /// robot now (values above 0.5 are yes).
    pub fn set_reach(&self, reach: &[f64]) {
        let mut s = lock(&self.0);
        s.reach.clear();
        s.reach.extend(reach.iter().map(|&r| r > 0.5));
    }

    /// The counts so far.
    pub fn counts(&self) -> LinkCounts {
        lock(&self.0).counts
    }
}

impl<T: Transport> RadioLink<T> {
    /// Wrap `inner`, the transport of robot `robot`'s controller node, with `radio`'s loss,
    /// delay and jitter (range and partitions come from the server through
    /// [`LinkHandle::set_reach`]); `seed` is the scenario's.
    pub fn new(inner: T, radio: &RadioConfig, seed: u64) -> (RadioLink<T>, LinkHandle) {
        let robot = inner.local();
        let state = LinkState {
            robot,
            body: crate::served_robot::body_node(robot.0),
            loss: radio.loss,
            delay: radio.delay,
            jitter: radio.jitter,
            rng: fastrand::Rng::with_seed(seed ^ 0x5EED_0005 ^ (u64::from(robot.0) << 32)),
            reach: Vec::new(),
            held: BinaryHeap::new(),
            order: 0,
            now: Instant::ZERO,
            counts: LinkCounts::default(),
        };
        let state = Arc::new(Mutex::new(state));
        (RadioLink { inner, state: state.clone() }, LinkHandle(state))
    }
}

/// Sending, receiving, timing and counting go through the radio; everything else reaches the
/// wrapped transport unchanged.
impl<T: Transport> TransportWrapper for RadioLink<T> {
    type Inner = T;

    fn inner(&self) -> &T {
        &self.inner
    }

    fn inner_mut(&mut self) -> &mut T {
        &mut self.inner
    }

    fn send(&mut self, out: Outgoing) -> Sent {
        {
            let mut s = lock(&self.state);
            let to_body = matches!(out.to, Destination::Node(id) if id == s.body);
            if !to_body {
                s.counts.sent += 1;
                s.counts.bytes += wire_len(&out.message);
            }
        }
        self.inner.send(out)
    }

    fn recv(&mut self) -> Option<(NodeId, Message)> {
        let mut s = lock(&self.state);
        let now = s.now;
        if s.held.peek().is_some_and(|Reverse(h)| h.at <= now) {
            let Reverse(h) = s.held.pop().expect("peeked");
            s.counts.delivered += 1;
            return Some((h.from, h.message));
        }
        while let Some((from, message)) = self.inner.recv() {
            let peer = from.0 != 0 && from.0 < BODY_BASE && from != s.robot;
            if !peer {
                return Some((from, message));
            }
            let reach = s.reach.get(from.0 as usize - 1).copied().unwrap_or(true);
            if !reach {
                s.counts.cut += 1;
                continue;
            }
            if s.loss > 0.0 && s.rng.f64() < s.loss {
                s.counts.lost += 1;
                continue;
            }
            let delay = s.delay + s.jitter * s.rng.f64();
            let at = now + Duration::from_nanos((delay.max(0.0) * 1e9) as u64);
            if at <= now {
                s.counts.delivered += 1;
                return Some((from, message));
            }
            s.order += 1;
            let order = s.order;
            s.held.push(Reverse(Held { at, order, from, message }));
        }
        None
    }

    fn tick(&mut self, now: Instant) -> Option<Instant> {
        let next = {
            let mut s = lock(&self.state);
            s.now = now;
            s.held.peek().map(|Reverse(h)| h.at)
        };
        match (self.inner.tick(now), next) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    fn counters(&self) -> Vec<(String, u64)> {
        let c = lock(&self.state).counts;
        let mut out = self.inner.counters();
        out.extend([
            ("radio_sent".to_owned(), c.sent),
            ("radio_bytes".to_owned(), c.bytes),
            ("radio_lost".to_owned(), c.lost),
            ("radio_cut".to_owned(), c.cut),
        ]);
        out
    }

    fn counters_generation(&self) -> u64 {
        let c = lock(&self.state).counts;
        self.inner.counters_generation().wrapping_add(c.sent + c.lost + c.cut)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ayllu::MemNetwork;
    use ayllu_core::{ConnectionId, ConnectionKind, PortMessage, Value};

    fn message(v: f64) -> Message {
        Message::Port(PortMessage {
            conn: ConnectionId(1),
            seq: v as u64,
            behavior: "B".into(),
            port: "P".into(),
            kind: ConnectionKind::Normal,
            priority: 0,
            value: Value::Float(v),
        })
    }

    #[test]
    fn peers_are_lost_cut_and_delayed_the_body_passes() {
        let net = MemNetwork::named("served-radio-unit");
        let mut peer = net.attach(NodeId(2)).unwrap();
        let mut body = net.attach(crate::served_robot::body_node(1)).unwrap();
        let radio = RadioConfig { loss: 0.0, delay: 0.1, jitter: 0.0, range: None, partitions: Vec::new() };
        let (mut link, handle) = RadioLink::new(net.attach(NodeId(1)).unwrap(), &radio, 7);
        let t0 = Instant::ZERO + Duration::from_secs(1);
        Transport::tick(&mut link, t0);
        peer.send(Outgoing { to: Destination::Node(NodeId(1)), message: message(1.0) });
        body.send(Outgoing { to: Destination::Node(NodeId(1)), message: message(2.0) });
        // The body's message comes at once; the peer's is held for the delay.
        let (from, _) = Transport::recv(&mut link).expect("the body's message");
        assert_eq!(from, crate::served_robot::body_node(1));
        assert!(Transport::recv(&mut link).is_none(), "the peer's message waits 100 ms");
        assert_eq!(Transport::tick(&mut link, t0), Some(t0 + Duration::from_millis(100)));
        Transport::tick(&mut link, t0 + Duration::from_millis(100));
        assert_eq!(Transport::recv(&mut link).map(|(f, _)| f), Some(NodeId(2)));
        // Out of reach: cut.
        handle.set_reach(&[1.0, 0.0]);
        peer.send(Outgoing { to: Destination::Node(NodeId(1)), message: message(3.0) });
        Transport::tick(&mut link, t0 + Duration::from_secs(1));
        assert!(Transport::recv(&mut link).is_none());
        assert_eq!(handle.counts().cut, 1);
        // Sending: to the body is wiring, to a peer is radio.
        Transport::send(
            &mut link,
            Outgoing { to: Destination::Node(crate::served_robot::body_node(1)), message: message(4.0) },
        );
        Transport::send(&mut link, Outgoing { to: Destination::Node(NodeId(2)), message: message(5.0) });
        let c = handle.counts();
        assert_eq!((c.sent, c.delivered), (1, 1));
        assert!(c.bytes > 0);
    }

    #[test]
    fn a_request_larger_than_a_datagram_fails_at_once_through_the_radio() {
        // Through the radio the UDP transport's failed requests once went unheard (the link
        // forwarded lost peers and warnings by hand, not them): a PREPARE too large for a
        // datagram was retried for 5 s. As a TransportWrapper the link passes every event on.
        use ayllu::datagram::DatagramBus;
        use ayllu::{BehaviorClass, ControlBody, Lockstep, Node, PortSpec, RequestStatus, UdpConfig, UdpTransport};
        let bus = DatagramBus::new();
        let mut team = Lockstep::new("radio-request-too-large");
        let mut nodes = Vec::new();
        for id in 1..=2u32 {
            let at: std::net::SocketAddr = format!("10.0.0.{id}:7400").parse().unwrap();
            let mut config = UdpConfig::new(at);
            config.broadcast = Some("10.0.0.255:7400".parse().unwrap());
            config.hello_interval = Duration::from_millis(100);
            let udp = UdpTransport::with_socket(NodeId(id), config, bus.bind(at).unwrap()).unwrap();
            let (link, _handle) = RadioLink::new(udp, &RadioConfig::default(), 7);
            let i = team.add_node(Node::new(team.clock().clone(), link));
            let mut relay = BehaviorClass::new("Relay");
            relay.port(PortSpec::new("In", 0i64)).unwrap();
            team.node(i).define(relay).unwrap();
            nodes.push(i);
        }
        team.advance(Duration::from_millis(250), Duration::from_millis(1));
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

    #[test]
    fn the_reach_row_follows_life_range_and_partitions() {
        use crate::radio::Partition;
        let at = |node: u32, x: f64, alive: bool| Station { node: NodeId(node), x, y: 0.0, alive };
        let stations = [at(1, 0.0, true), at(2, 3.0, true), at(3, 9.0, true), at(4, 1.0, false)];
        let radio = RadioConfig {
            range: Some(5.0),
            partitions: vec![Partition { start: 10.0, end: 20.0, island: vec![1] }],
            ..RadioConfig::default()
        };
        let mut row = [9.0; 4];
        reach_row(&radio, 0.0, &stations, 0, &mut row);
        assert_eq!(row, [0.0, 1.0, 0.0, 0.0], "itself no, 3 m yes, 9 m out of range, dead no");
        reach_row(&radio, 15.0, &stations, 0, &mut row);
        assert_eq!(row, [0.0; 4], "robot 1 alone on its island");
        reach_row(&radio, 15.0, &stations, 1, &mut row);
        assert_eq!(row, [0.0, 0.0, 0.0, 0.0], "robot 2: 1 across the partition, 3 out of range");
        reach_row(&radio, 0.0, &stations, 3, &mut row);
        assert_eq!(row, [0.0; 4], "a dead robot hears nobody");
    }

    #[test]
    fn loss_drops_about_its_share() {
        let net = MemNetwork::named("served-radio-loss");
        let mut peer = net.attach(NodeId(2)).unwrap();
        let radio = RadioConfig { loss: 0.3, delay: 0.0, jitter: 0.0, range: None, partitions: Vec::new() };
        let (mut link, handle) = RadioLink::new(net.attach(NodeId(1)).unwrap(), &radio, 1);
        let mut got = 0;
        for i in 0..1000 {
            peer.send(Outgoing { to: Destination::Node(NodeId(1)), message: message(f64::from(i)) });
            while Transport::recv(&mut link).is_some() {
                got += 1;
            }
        }
        let c = handle.counts();
        assert_eq!(got + c.lost, 1000);
        assert!((230..=370).contains(&c.lost), "lost {} of 1000 at p = 0.3", c.lost);
    }
}
