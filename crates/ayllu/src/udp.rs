//! `udp://` — the network transport: Ayllu nodes on real IP networks (paper §3.1).
//!
//! What it does, by rule of `../../docs/semantics.md` and `spec/protocol.md`:
//! * N1: port messages are sent once, never retransmitted; the core drops stale sequence numbers.
//! * N3: messages for the same address leaving in one loop turn share datagrams up to the MTU;
//!   [`Transport::flush`] ends the turn.
//! * N4: every datagram that is malformed, oversized, of another version or team,
//!   unauthenticated, forged or replayed is dropped and counted by cause; memory for peers,
//!   replay windows and reply reassembly is bounded, so a flood cannot grow it.
//! * N5: with a team key, every datagram carries a MAC and is checked against a per-sender
//!   replay window; without one the team is open.
//! * N6: HELLO every `hello_ms` to static peers, group and broadcast addresses and known peers;
//!   a peer silent for three of its periods is forgotten. A new peer is greeted at once.
//! * S10: `(node, ..)` goes to the peer's last known address; `(group, ..)` to the group's
//!   address, else the broadcast address, else by unicast to each peer that announced the group.

use std::collections::{BTreeMap, VecDeque};
use std::net::{IpAddr, SocketAddr};

use ayllu_core::{ControlBody, ControlMessage, Destination, Duration, Instant, Message, NodeId};
use ayllu_wire::{decode, DatagramWriter, EncodeError, ReceiverConfig, ReplayWindow, ReplyAssembler, WireMessage};

use crate::datagram::{DatagramSocket, OsSocket};
use crate::error::Error;
use crate::transport::{PeerInfo, Transport};
use crate::udp_config::{UdpConfig, MAX_DATAGRAM};

/// Bounds that keep a flood from growing memory (N4).
const MAX_PEERS: usize = 1024;
const MAX_ASSEMBLIES: usize = 64;
/// Datagrams read per `recv` refill, so one busy socket cannot starve the node's loop.
const RECV_BATCH: usize = 256;

#[derive(Clone, Debug)]
struct Peer {
    addr: SocketAddr,
    name: String,
    groups: Vec<String>,
    interval: Duration,
    last_heard: Instant,
    replay: ReplayWindow,
}

/// A node's UDP transport. `S` is the socket: a real one, or a test bus / fault injector.
pub struct UdpTransport<S: DatagramSocket = OsSocket> {
    id: NodeId,
    config: UdpConfig,
    socket: S,
    receiver: ReceiverConfig,
    seq: u64,
    now: Instant,
    next_hello: Instant,
    peers: BTreeMap<NodeId, Peer>,
    joined: Vec<String>,
    batches: Vec<(SocketAddr, DatagramWriter)>,
    inbox: VecDeque<(NodeId, Message)>,
    assemblies: VecDeque<((NodeId, u64), ReplyAssembler)>,
    greet: Vec<SocketAddr>,
    counters: BTreeMap<&'static str, u64>,
    generation: u64,
    buf: Vec<u8>,
}

impl UdpTransport<OsSocket> {
    /// Bind a real UDP socket as `config` says.
    pub fn bind(id: NodeId, config: UdpConfig) -> Result<Self, Error> {
        let socket = OsSocket::bind(config.bind)
            .map_err(|e| Error::Io { what: format!("binding UDP socket {}", config.bind), error: e.to_string() })?;
        UdpTransport::with_socket(id, config, socket)
    }
}

impl<S: DatagramSocket> UdpTransport<S> {
    /// A transport over any datagram socket (tests use the in-memory bus and fault injector).
    pub fn with_socket(id: NodeId, config: UdpConfig, mut socket: S) -> Result<Self, Error> {
        for (_, addr) in &config.groups {
            if let IpAddr::V4(ip) = addr.ip() {
                if ip.is_multicast() {
                    socket.join_multicast(ip).map_err(|e| Error::Io {
                        what: format!("joining multicast group {ip}"),
                        error: e.to_string(),
                    })?;
                }
            }
        }
        // Start above any sequence number an earlier run of this node used (spec: boot
        // seconds in the high half), so restarts are not taken for replays.
        let boot = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_secs())
            .unwrap_or(0)
            .min(u64::from(u32::MAX));
        Ok(UdpTransport {
            id,
            receiver: ReceiverConfig { team: config.team, key: config.key },
            config,
            socket,
            seq: boot << 32,
            now: Instant::ZERO,
            next_hello: Instant::ZERO,
            peers: BTreeMap::new(),
            joined: Vec::new(),
            batches: Vec::new(),
            inbox: VecDeque::new(),
            assemblies: VecDeque::new(),
            greet: Vec::new(),
            counters: BTreeMap::new(),
            generation: 0,
            buf: vec![0u8; MAX_DATAGRAM + 1],
        })
    }

    pub fn local_addr(&self) -> Option<SocketAddr> {
        self.socket.local_addr().ok()
    }

    /// The socket, e.g. to read a fault injector's counts.
    pub fn socket(&self) -> &S {
        &self.socket
    }

    fn count(&mut self, cause: &'static str) {
        *self.counters.entry(cause).or_insert(0) += 1;
        self.generation += 1;
    }

    /// Where a destination's datagrams go now.
    fn route(&self, to: &Destination) -> Vec<SocketAddr> {
        match to {
            Destination::Node(n) => self.peers.get(n).map(|p| p.addr).into_iter().collect(),
            Destination::Group(g) => {
                if let Some((_, a)) = self.config.groups.iter().find(|(name, _)| **name == **g) {
                    vec![*a]
                } else if let Some(b) = self.config.broadcast {
                    vec![b]
                } else {
                    let mut v: Vec<SocketAddr> =
                        self.peers.values().filter(|p| p.groups.iter().any(|x| **x == **g)).map(|p| p.addr).collect();
                    v.dedup();
                    v
                }
            }
        }
    }

    fn writer(&mut self) -> DatagramWriter {
        let w = DatagramWriter::new(self.config.team, self.id, self.seq, self.config.key, self.config.mtu);
        self.seq += 1;
        w
    }

    /// Append a message to the open datagram for `addr`, sending the datagram when full.
    fn push(&mut self, addr: SocketAddr, message: &WireMessage) {
        let i = match self.batches.iter().position(|(a, _)| *a == addr) {
            Some(i) => i,
            None => {
                let w = self.writer();
                self.batches.push((addr, w));
                self.batches.len() - 1
            }
        };
        match self.batches[i].1.push(message) {
            Ok(()) => {}
            Err(EncodeError::DoesNotFit { .. }) => {
                let fresh = self.writer();
                let full = std::mem::replace(&mut self.batches[i].1, fresh);
                self.transmit(addr, full);
                if self.batches[i].1.push(message).is_err() {
                    self.count("too_large");
                }
            }
            Err(EncodeError::TooLarge { .. }) | Err(EncodeError::ReportTooLarge { .. }) => self.count("too_large"),
            Err(EncodeError::Invalid(_)) => self.count("unencodable"),
        }
    }

    fn transmit(&mut self, addr: SocketAddr, w: DatagramWriter) {
        if w.is_empty() {
            return;
        }
        let bytes = w.finish();
        match self.socket.send_to(&bytes, addr) {
            Ok(()) => self.count("datagrams_sent"),
            Err(_) => self.count("send_error"),
        }
    }

    fn hello(&self) -> WireMessage {
        WireMessage::Hello {
            interval_ms: u32::try_from(self.config.hello_interval.as_nanos() / 1_000_000).unwrap_or(u32::MAX).max(1),
            name: self.config.name.as_str().into(),
            groups: self.joined.iter().map(|g| g.as_str().into()).collect(),
        }
    }

    fn announce(&mut self) {
        let mut targets: Vec<SocketAddr> = self.config.peers.clone();
        targets.extend(self.config.groups.iter().map(|(_, a)| *a));
        targets.extend(self.config.broadcast);
        targets.extend(self.peers.values().map(|p| p.addr));
        targets.sort();
        targets.dedup();
        let hello = self.hello();
        for t in targets {
            self.push(t, &hello);
        }
    }

    fn receive_datagram(&mut self, len: usize, from: SocketAddr) {
        let datagram = match decode(&self.buf[..len], &self.receiver) {
            Ok(d) => d,
            Err(reason) => return self.count(reason.name()),
        };
        if datagram.sender == self.id {
            // Our own broadcast, looped back by the network.
            return self.count("own");
        }
        let now = self.now;
        let default_interval = self.config.hello_interval;
        if !self.peers.contains_key(&datagram.sender) && self.peers.len() >= MAX_PEERS {
            // Make room by forgetting the peer heard from longest ago.
            if let Some(oldest) = self.peers.iter().min_by_key(|(_, p)| p.last_heard).map(|(n, _)| *n) {
                self.peers.remove(&oldest);
                self.count("peer_evicted");
            }
        }
        let is_new = !self.peers.contains_key(&datagram.sender);
        let peer = self.peers.entry(datagram.sender).or_insert_with(|| Peer {
            addr: from,
            name: String::new(),
            groups: Vec::new(),
            interval: default_interval,
            last_heard: now,
            replay: ReplayWindow::new(),
        });
        if datagram.authenticated && !peer.replay.accept(datagram.seq) {
            if is_new {
                self.peers.remove(&datagram.sender);
            }
            return self.count("replayed");
        }
        peer.addr = from;
        peer.last_heard = now;
        self.count("datagrams_received");
        let sender = datagram.sender;
        for m in datagram.messages {
            match m {
                WireMessage::Port(p) => self.inbox.push_back((sender, Message::Port(p))),
                WireMessage::Request { id, body } => {
                    self.inbox.push_back((sender, Message::Control(ControlMessage { id, body })))
                }
                WireMessage::UnknownRequest { id, .. } => {
                    let reply = ControlBody::Reply { result: Err("unknown operation".into()) };
                    self.send_message(
                        &Destination::Node(sender),
                        &Message::Control(ControlMessage { id, body: reply }),
                    );
                }
                WireMessage::Reply { id, part, parts, payload } => self.reply_part(sender, id, part, parts, payload),
                WireMessage::Hello { interval_ms, name, groups } => {
                    if let Some(p) = self.peers.get_mut(&sender) {
                        p.interval = Duration::from_millis(u64::from(interval_ms.max(1)));
                        p.name = name.to_string();
                        p.groups = groups.iter().map(|g| g.to_string()).collect();
                    }
                    if is_new {
                        self.greet.push(from);
                    }
                    self.count("hellos_received");
                }
                WireMessage::Unknown { .. } => self.count("unknown_kind"),
            }
        }
    }

    fn reply_part(&mut self, sender: NodeId, id: u64, part: u16, parts: u16, payload: ayllu_wire::ReplyPart) {
        let key = (sender, id);
        let i = match self.assemblies.iter().position(|(k, _)| *k == key) {
            Some(i) => i,
            None => {
                if self.assemblies.len() >= MAX_ASSEMBLIES {
                    self.assemblies.pop_front();
                    self.count("reply_evicted");
                }
                self.assemblies.push_back((key, ReplyAssembler::new()));
                self.assemblies.len() - 1
            }
        };
        match self.assemblies[i].1.push(part, parts, payload) {
            Ok(Some(result)) => {
                self.assemblies.remove(i);
                let body = ControlBody::Reply { result };
                self.inbox.push_back((sender, Message::Control(ControlMessage { id, body })));
            }
            Ok(None) => {}
            Err(_) => {
                self.assemblies.remove(i);
                self.count("bad_reply");
            }
        }
    }

    fn send_message(&mut self, to: &Destination, message: &Message) {
        let addrs = self.route(to);
        if addrs.is_empty() {
            return self.count("no_route");
        }
        let parts = match WireMessage::from_core(message, self.config.mtu, self.config.key.is_some()) {
            Ok(p) => p,
            Err(_) => return self.count("unencodable"),
        };
        for addr in addrs {
            for m in &parts {
                self.push(addr, m);
            }
        }
        self.count("messages_sent");
    }

    /// The peers heard from recently.
    pub fn peer_list(&self) -> Vec<PeerInfo> {
        self.peers
            .iter()
            .map(|(n, p)| PeerInfo {
                node: *n,
                addr: p.addr.to_string(),
                name: p.name.clone(),
                groups: p.groups.clone(),
                last_heard: p.last_heard,
            })
            .collect()
    }
}

impl<S: DatagramSocket> Transport for UdpTransport<S> {
    fn local(&self) -> NodeId {
        self.id
    }
    fn send(&mut self, out: ayllu_core::Outgoing) {
        self.send_message(&out.to, &out.message);
    }
    fn flush(&mut self) {
        let greet = std::mem::take(&mut self.greet);
        if !greet.is_empty() {
            let hello = self.hello();
            for addr in greet {
                self.push(addr, &hello);
            }
        }
        for (addr, w) in std::mem::take(&mut self.batches) {
            self.transmit(addr, w);
        }
    }
    fn recv(&mut self) -> Option<(NodeId, Message)> {
        if self.inbox.is_empty() {
            for _ in 0..RECV_BATCH {
                let mut buf = std::mem::take(&mut self.buf);
                let got = self.socket.recv_from(&mut buf);
                self.buf = buf;
                match got {
                    Ok(Some((len, from))) if len > MAX_DATAGRAM => {
                        let _ = (len, from);
                        self.count("oversized");
                    }
                    Ok(Some((len, from))) => self.receive_datagram(len, from),
                    Ok(None) => break,
                    Err(_) => {
                        self.count("recv_error");
                        break;
                    }
                }
                if !self.inbox.is_empty() {
                    break;
                }
            }
        }
        self.inbox.pop_front()
    }
    fn wait(&mut self, timeout: std::time::Duration) {
        if self.inbox.is_empty() {
            self.socket.wait(timeout);
        }
    }
    fn join(&mut self, group: &str) {
        if !self.joined.iter().any(|g| g == group) {
            self.joined.push(group.to_owned());
            // Tell the team at once rather than at the next HELLO.
            self.next_hello = self.now;
        }
    }
    fn leave(&mut self, group: &str) {
        self.joined.retain(|g| g != group);
    }
    fn tick(&mut self, now: Instant) -> Option<Instant> {
        self.now = self.now.max(now);
        let before = self.peers.len();
        self.peers.retain(|_, p| now < p.last_heard + p.interval * 3);
        for _ in self.peers.len()..before {
            self.count("peer_expired");
        }
        if now >= self.next_hello {
            self.announce();
            self.next_hello = now + self.config.hello_interval;
        }
        let expiry = self.peers.values().map(|p| p.last_heard + p.interval * 3).min();
        Some(expiry.map_or(self.next_hello, |e| e.min(self.next_hello)))
    }
    fn counters(&self) -> Vec<(String, u64)> {
        self.counters.iter().map(|(k, v)| ((*k).to_owned(), *v)).collect()
    }
    fn counters_generation(&self) -> u64 {
        self.generation
    }
    fn peers(&self) -> Vec<PeerInfo> {
        self.peer_list()
    }
}
