//! `udp://` — the network transport: Ayllu nodes on real IP networks (paper §3.1).
//!
//! What it does, by rule of `docs/semantics.md` and `spec/protocol.md`:
//! * N1: port messages are sent once, never retransmitted; the core drops stale sequence numbers.
//! * N3: messages for the same address leaving in one loop turn share datagrams up to the MTU;
//!   [`Transport::flush`] ends the turn, and sends a turn's datagrams for one address in one
//!   system call when they allow it (UDP GSO on Linux, D-N3.3).
//! * N4: every datagram that is malformed, oversized, of another version or team,
//!   unauthenticated, forged or replayed is dropped and counted by cause; memory for peers,
//!   replay windows and reply reassembly is bounded, so a flood cannot grow it.
//! * N5: with a team key, every datagram carries a MAC and is checked against a per-sender
//!   replay window; without one the team is open.
//! * N5, D-N5.4: a keyed sender this node has no memory of (no window, restored or made in this
//!   run, that it has answered a CHALLENGE in) has its port messages and requests dropped
//!   (`not_fresh`) until it sends an authenticated ECHO of our cookie; its window then restarts
//!   above that ECHO, so datagrams captured before a restart are refused without `state=`.
//! * N6: HELLO every `hello_ms` to static peers, group and broadcast addresses and protected
//!   peers; a peer silent for three of its periods is forgotten. A new peer is greeted at once,
//!   with a CHALLENGE: real nodes prove each other's address as they greet.
//! * D-N6.3-6.6: peers with a proven address, named by `peer=` or in use are never displaced by
//!   a newcomer; newcomers are let in at a rate per source address and block
//!   (`admission.rs`), and an unproven peer is forgotten on a short clock of its own.
//! * Return routability: answers to an address that has not proven it receives are bounded to
//!   three times what came from it; larger ones wait for a CHALLENGE/ECHO round trip
//!   ([`crate::routability`]). CHALLENGEs we receive are echoed at once.
//! * Operator key: with `operator=`, structure changes are applied only when signed, each
//!   once ([`crate::operator`]); with `operator_secret=`, the ones we request are signed.
//! * S10: `(node, ..)` goes to the peer's last known address; `(group, ..)` to the group's
//!   address, else the broadcast address, else by unicast to each peer that announced the group.
//!   A group's port messages name the group, and a node that has not joined it drops them
//!   (`not_member`, D-S10.6): those addresses reach non-members too.
//!
//! Where things are: this file holds the transport's state and its [`Transport`] methods, which
//! call into one file per concern: `peers.rs` (the peer table, HELLO, expiry, address proofs),
//! `admit.rs` (the checks a datagram passes before it is applied, replay windows), `receive.rs`
//! (reading and decoding datagrams, reply reassembly), `send.rs` (where a message goes, holding
//! it for a node not heard from yet), `batching.rs` (a turn's datagrams and trains),
//! `marks.rs` (replay marks saved across restarts) and `counters.rs` (the counts by cause).

use std::collections::{BTreeMap, VecDeque};
use std::net::{IpAddr, SocketAddr};

use ayllu_core::{Instant, Message, NodeId};
use ayllu_wire::{DatagramWriter, NameCache, PortTemplates, ReceiverConfig, ReplyAssembler, WireMessage};

use crate::admission::{Admission, Bucket};
use crate::datagram::{DatagramSocket, OsSocket};
use crate::error::Error;
use crate::operator::OperatorGate;
use crate::routability::Cookies;
use crate::transport::{PeerInfo, SendTally, Sent, Transport, TransportEvent};
use crate::udp_config::{UdpConfig, MAX_DATAGRAM};

mod admit;
mod batching;
mod counters;
mod inbox;
mod marks;
mod peers;
mod receive;
mod send;

use admit::{SenderWindow, REFUSED_CHALLENGES};
use batching::Train;
use counters::{Hot, Names, Tally};
use inbox::Inbox;
use marks::{load_marks, Marks};
use peers::{discovery_warning, Peer};
use send::Held;

/// A node's UDP transport. `S` is the socket: a real one, or a test bus / fault injector.
pub struct UdpTransport<S: DatagramSocket = OsSocket> {
    id: NodeId,
    config: UdpConfig,
    socket: S,
    receiver: ReceiverConfig,
    seq: u64,
    now: Instant,
    next_hello: Instant,
    /// No peer expires before this (a lower bound: hearing from a peer only delays its expiry).
    next_expiry: Instant,
    peers: BTreeMap<NodeId, Peer>,
    /// Peers lost, warnings and failed requests since the node last asked
    /// ([`Transport::take_events`]), in order.
    events: Vec<TransportEvent>,
    /// Replay windows by sender (outlive peer entries, N5), and their senders' freshness.
    replay: BTreeMap<NodeId, SenderWindow>,
    /// Newcomers' admission rates by source address and block (N4).
    admission: Admission,
    /// CHALLENGEs left for newcomers the admission rate refused ([`REFUSED_CHALLENGES`]).
    refused_challenges: Bucket,
    /// Replay windows changed since they were last saved to `config.state` (D-N5.3).
    replay_dirty: bool,
    /// When the windows may next be saved (at most once a second).
    next_save: Instant,
    /// Messages for nodes not heard from yet (never reported as sent, see [`Sent::Held`]).
    held: VecDeque<Held>,
    /// The first datagram sequence number this transport used: datagrams carrying our id and
    /// a number in `[seq_start, seq)` from our own address are our own, looped back.
    seq_start: u64,
    /// Addresses from which another node with our id was heard (reported once each).
    duplicates: Vec<SocketAddr>,
    /// Sending to the discovery address failed once (warned about once).
    discovery_failed: bool,
    /// Saving the replay marks failed once (warned about once).
    state_warned: bool,
    joined: Vec<String>,
    batches: Vec<(SocketAddr, DatagramWriter)>,
    /// This turn's finished datagrams, by address, waiting for the turn's end ([`Train`]).
    trains: Vec<Train>,
    inbox: Inbox,
    assemblies: VecDeque<((NodeId, u64), ReplyAssembler)>,
    /// New peers to greet at the end of the turn (HELLO, and a CHALLENGE unless proven).
    greet: Vec<(NodeId, SocketAddr)>,
    counters: Tally,
    /// The list [`Transport::counters_into`] last wrote whole: its address, and the names it
    /// holds (as counted by the tally).
    counters_written: std::cell::Cell<(usize, Names)>,
    generation: u64,
    buf: Vec<u8>,
    /// Messages handed over since the last flush, counted as `messages_sent` at the flush
    /// (one count per loop turn instead of one per message).
    unflushed: u64,
    /// Buffers of sent datagrams, for the next ones.
    spare: Vec<Vec<u8>>,
    /// What each connection's port messages share, encoded once (`ayllu_wire::PortTemplates`).
    templates: PortTemplates,
    /// Scratch list of a message's destination addresses.
    route_buf: Vec<SocketAddr>,
    /// Names received recently (decoding allocates nothing for a name seen before).
    names: NameCache,
    /// Makes and checks the cookies that prove a peer's address.
    cookies: Cookies,
    /// With `operator=`: the key structure changes must be signed with, and what it let through.
    operator: Option<OperatorGate>,
    /// The messages of the last datagram that waited for its checks (`receive::Inbound`'s `rest`),
    /// emptied: its allocation is reused.
    decoded: Vec<WireMessage>,
}

impl UdpTransport<OsSocket> {
    /// Bind a real UDP socket as `config` says.
    pub fn bind(id: NodeId, config: UdpConfig) -> Result<Self, Error> {
        let mut socket = OsSocket::bind(config.bind).map_err(|e| {
            let what = if e.kind() == std::io::ErrorKind::AddrInUse {
                // RTPS (DDS, so ROS 2) takes 7400 + 250 x domain and the ports just above it: a
                // fixed port there is the first thing a ROS 2 robot's node collides with.
                let dds = if config.bind.port() >= 7400 {
                    "; on a ROS 2 robot, DDS takes UDP 7400 and up (7400 + 250 x domain id), so pick a port \
                     below 7400"
                } else {
                    ""
                };
                format!(
                    "binding UDP socket {}: another process holds this address (an earlier node still \
                     running?); stop it, or bind port 0 to let the system choose a free one{dds}",
                    config.bind
                )
            } else {
                format!("binding UDP socket {}", config.bind)
            };
            Error::Io { what, error: e.to_string() }
        })?;
        // A socket bound to a unicast address does not hear broadcast or multicast datagrams:
        // listen on the team's broadcast and group addresses too.
        for addr in config.broadcast.iter().chain(config.groups.iter().map(|(_, a)| a)).chain(config.discovery.iter()) {
            socket.listen_also(*addr).map_err(|e| Error::Io {
                what: format!("binding UDP socket {addr} to receive group messages (or bind to 0.0.0.0)"),
                error: e.to_string(),
            })?;
        }
        UdpTransport::with_socket(id, config, socket)
    }
}

impl<S: DatagramSocket> UdpTransport<S> {
    /// A transport over any datagram socket (tests use the in-memory bus and fault injector).
    pub fn with_socket(id: NodeId, config: UdpConfig, mut socket: S) -> Result<Self, Error> {
        socket.set_spin(config.spin);
        socket.set_multicast_ttl(config.ttl).map_err(|e| Error::Io {
            what: format!("setting the multicast TTL to {}", config.ttl),
            error: e.to_string(),
        })?;
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
        // Discovery is a convenience: a machine without multicast still runs the node, and
        // says why nobody is found.
        let mut warnings = Vec::new();
        let marks = match &config.state {
            Some(path) if config.key.is_some() || config.operator.is_some() => load_marks(path, &mut warnings),
            _ => Marks::default(),
        };
        // A sender whose mark was saved is one this node remembers: its numbers above the mark
        // are fresh (D-N5.3).
        let replay = match config.key {
            Some(_) => marks
                .datagrams
                .into_iter()
                .map(|(n, (window, used))| (n, SenderWindow { window, used, fresh: true, challenged: None }))
                .collect(),
            None => BTreeMap::new(),
        };
        let operator = config.operator.map(|key| OperatorGate::new(key, marks.requests));
        let cookies = Cookies::new().map_err(|e| Error::Io { what: "making the cookie secret".into(), error: e })?;
        if let Some(IpAddr::V4(ip)) = config.discovery.map(|a| a.ip()) {
            if let Err(e) = socket.join_multicast(ip) {
                warnings.push(discovery_warning(&config, &e.to_string()));
            }
        }
        // Start above any sequence number an earlier run of this node used, so restarts are
        // not taken for replays.
        let boot = crate::clock::boot_sequence_base();
        Ok(UdpTransport {
            id,
            receiver: ReceiverConfig { team: config.team, key: config.key },
            config,
            socket,
            seq: boot,
            now: Instant::ZERO,
            next_hello: Instant::ZERO,
            next_expiry: Instant::MAX,
            peers: BTreeMap::new(),
            events: warnings.into_iter().map(TransportEvent::Warning).collect(),
            replay,
            admission: Admission::default(),
            refused_challenges: REFUSED_CHALLENGES.full(Instant::ZERO),
            replay_dirty: false,
            next_save: Instant::ZERO,
            held: VecDeque::new(),
            seq_start: boot,
            duplicates: Vec::new(),
            discovery_failed: false,
            state_warned: false,
            joined: Vec::new(),
            batches: Vec::new(),
            trains: Vec::new(),
            inbox: Inbox::default(),
            assemblies: VecDeque::new(),
            greet: Vec::new(),
            counters: Tally::default(),
            counters_written: std::cell::Cell::new((0, 0)),
            generation: 0,
            buf: vec![0u8; MAX_DATAGRAM + 1],
            unflushed: 0,
            spare: Vec::new(),
            templates: PortTemplates::new(),
            route_buf: Vec::new(),
            names: NameCache::new(),
            decoded: Vec::new(),
            cookies,
            operator,
        })
    }

    /// The address the socket is bound to (the real port when the URL asked for port 0).
    pub fn local_addr(&self) -> Option<SocketAddr> {
        self.socket.local_addr().ok()
    }

    /// The socket, e.g. to read a fault injector's counts.
    pub fn socket(&self) -> &S {
        &self.socket
    }
}

impl<S: DatagramSocket> Transport for UdpTransport<S> {
    fn local(&self) -> NodeId {
        self.id
    }
    fn send(&mut self, out: ayllu_core::Outgoing) -> Sent {
        self.send_message(&out.to, &out.message)
    }
    fn send_all(&mut self, outbox: &mut VecDeque<ayllu_core::Outgoing>, tally: &mut SendTally) {
        // The messages are sent where they lie (each a `memcpy` of 136 bytes to move out). One
        // alone (a loop's usual turn) is popped at once and a batch dropped by one loop over the
        // queue, each shape the cheaper one by callgrind (the other way round cost 87
        // instructions more for one message alone, 47 more a message of a batch of 64). Written
        // out rather than through a closure called from both shapes, which was not inlined.
        if outbox.len() == 1 {
            if let Some(out) = outbox.front() {
                tally.add(self.send_message(&out.to, &out.message));
            }
            outbox.pop_front();
            return;
        }
        let mut last = None;
        for out in outbox.iter() {
            tally.add(self.send_message_after(&out.to, &out.message, &mut last));
        }
        outbox.clear();
    }
    fn flush(&mut self) {
        // Most calls (a node flushes twice a turn) have nothing to send.
        if self.unflushed == 0 && self.greet.is_empty() && self.batches.is_empty() && self.trains.is_empty() {
            return;
        }
        if self.unflushed > 0 {
            self.counters.add_hot(Hot::MessagesSent, std::mem::take(&mut self.unflushed));
            self.generation += 1;
        }
        let greet = std::mem::take(&mut self.greet);
        if !greet.is_empty() {
            let hello = self.hello();
            for (node, addr) in greet {
                self.push(addr, &hello);
                let now = self.now;
                if let Some(p) = self.peers.get_mut(&node).filter(|p| !p.budget.proven && p.addr == addr) {
                    // Proves the peer's address as part of the greeting: a proven peer keeps its
                    // place in the table (N4) and may ask for anything large.
                    p.challenged = Some(now);
                    self.challenge(node, addr);
                }
            }
        }
        // Drained and put back, so the lists keep their allocations from turn to turn.
        let mut batches = std::mem::take(&mut self.batches);
        for (addr, w) in batches.drain(..) {
            self.transmit(addr, w);
        }
        self.batches = batches;
        let mut trains = std::mem::take(&mut self.trains);
        for train in trains.drain(..) {
            self.send_train(train);
        }
        self.trains = trains;
    }
    fn recv(&mut self) -> Option<(NodeId, Message)> {
        if self.inbox.is_empty() {
            self.refill();
        }
        self.inbox.pop_front()
    }
    fn recv_all(&mut self, deliver: &mut dyn FnMut(NodeId, &Message)) {
        loop {
            if self.inbox.is_empty() {
                self.refill();
                if self.inbox.is_empty() {
                    return;
                }
            }
            self.inbox.each_then_empty(|from, message| deliver(from, message));
        }
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
        self.socket.set_turn_time(self.now);
        // The peer table is walked only when a peer may have expired, not every loop turn.
        if now >= self.next_expiry {
            self.forget_expired_peers(now);
        }
        if now >= self.next_hello {
            self.announce();
            self.next_hello = now + self.config.hello_interval;
        }
        self.save_marks(now);
        let mut next = self.next_expiry.min(self.next_hello);
        if (self.replay_dirty || self.operator.as_ref().is_some_and(|g| g.dirty)) && self.config.state.is_some() {
            next = next.min(self.next_save);
        }
        if !self.held.is_empty() {
            next = self.expire_held(now, next);
        }
        Some(next)
    }
    fn set_real_time(&mut self, real_time: bool) {
        let recheck = if real_time { crate::datagram::RECHECK } else { std::time::Duration::ZERO };
        self.socket.set_recheck(recheck);
    }
    fn counters(&self) -> Vec<(String, u64)> {
        self.counters.0.iter().map(|(k, v)| ((*k).to_owned(), *v)).collect()
    }
    fn counters_into(&self, out: &mut Vec<(String, u64)>) {
        // The node calls this every turn with traffic, always with the same list: when that list
        // (by address) was last written here and no cause was added since, the names are known
        // to match and only the numbers are copied, without a dozen string comparisons a turn.
        let written = (out.as_ptr() as usize, self.counters.1);
        let same_names = out.len() == self.counters.0.len()
            && (self.counters_written.get() == written
                || out.iter().zip(&self.counters.0).all(|((have, _), (name, _))| have == name));
        if same_names {
            for ((_, have), (_, n)) in out.iter_mut().zip(&self.counters.0) {
                *have = *n;
            }
        } else {
            *out = self.counters();
        }
        self.counters_written.set((out.as_ptr() as usize, self.counters.1));
    }
    fn counters_generation(&self) -> u64 {
        self.generation
    }
    fn peers(&self) -> Vec<PeerInfo> {
        self.peer_list()
    }
    fn address(&self) -> Option<String> {
        self.local_addr().map(|a| a.to_string())
    }
    fn take_events(&mut self, out: &mut Vec<TransportEvent>) {
        out.append(&mut self.events);
    }
}
