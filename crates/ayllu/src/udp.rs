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

use std::collections::{BTreeMap, VecDeque};
use std::net::{IpAddr, SocketAddr};
use std::sync::Arc;

use ayllu_core::{ControlBody, ControlMessage, Destination, Duration, Instant, Message, NodeId, PortMessage};
use ayllu_wire::{
    decode_into, DatagramWriter, EncodeError, Header, MessageSink, NameCache, ReceiverConfig, ReplayWindow,
    ReplyAssembler, SignedRequest, WireMessage,
};

use crate::admission::{Admission, Bucket, Rate};
use crate::datagram::{DatagramSocket, OsSocket};
use crate::error::Error;
use crate::operator::OperatorGate;
use crate::routability::{Budget, Cookies};
use crate::transport::{PeerInfo, SendTally, Sent, Transport, TransportEvent};
use crate::udp_config::{UdpConfig, MAX_DATAGRAM};

/// Bounds that keep a flood from growing memory (N4).
const MAX_PEERS: usize = 1024;
/// Senders whose replay windows are kept (N5), longer than their peer entries: a window
/// forgotten with its peer would let an old authenticated datagram be applied again.
const MAX_REPLAY_SENDERS: usize = 4096;
/// The longest HELLO period a peer may announce: it bounds how long a forged peer stays in the
/// table (three periods) and so how long it is greeted.
const MAX_PEER_INTERVAL: Duration = Duration::from_secs(60);
/// An unproven peer (one that has not echoed a cookie, authenticated, been named in the URL or
/// been sent to) is kept this many of *our* HELLO periods from when it was let in, whatever
/// period it announces and however often it is heard: a real node proves its address within
/// one round trip of its greeting, so only forgers run out this clock (N4, N6).
const UNPROVEN_PERIODS: u64 = 3;
/// Bounds on that lifetime, whatever `hello_ms` says.
const MIN_UNPROVEN_LIFETIME: Duration = Duration::from_secs(1);
const MAX_UNPROVEN_LIFETIME: Duration = Duration::from_secs(10);
/// A peer this node sent a message to (a connection's port messages, a request, a group's
/// messages sent to it by unicast) within this long is *in use* and keeps its place.
const IN_USE: Duration = MAX_PEER_INTERVAL;
/// CHALLENGEs sent to newcomers the admission rate refused (so that a real node can still join
/// during a flood by proving its address): at most this many, over all senders.
const REFUSED_CHALLENGES: Rate = Rate { burst: 64, every: Duration::from_millis(4) };
/// How often an unproven peer, or a keyed sender not yet known fresh, is challenged again
/// while it is heard (the first CHALLENGE or ECHO may be lost).
const RECHALLENGE: Duration = Duration::from_millis(250);
const MAX_ASSEMBLIES: usize = 64;
/// Report bytes held by all reply assemblies together: the oldest go first beyond it (one
/// honest report is at most 64 parts of 1.4 KB at the default MTU; forged parts could
/// otherwise hold 64 x 512 KiB).
const MAX_ASSEMBLY_BYTES: usize = 2 << 20;
/// Groups and group-name bytes kept per peer from its HELLO (a forged HELLO of 8 KB per id,
/// for 1024 ids, would otherwise hold 8 MB); the excess is counted `groups_truncated`.
const MAX_PEER_GROUPS: usize = 128;
const MAX_PEER_GROUP_BYTES: usize = 4096;
/// Sent datagrams' buffers kept for reuse (one per destination of a turn is plenty).
const SPARE_BUFFERS: usize = 8;
/// Datagrams read per `recv` refill, so one busy socket cannot starve the node's loop.
const RECV_BATCH: usize = 256;
/// Distinct addresses of nodes using our id that are reported (more are only counted).
const MAX_DUPLICATES: usize = 8;
/// Messages held for nodes not heard from yet, at most (the oldest goes first when full).
const MAX_HELD: usize = 256;
/// A message for a node not heard from yet waits this many of our HELLO periods for it to
/// greet (a peer greets as soon as it hears our HELLO, so one round trip is the usual wait).
const HOLD_PERIODS: u64 = 3;

/// Datagrams sent as one train at most (the kernel's limit on UDP GSO segments was 64 before
/// Linux 6.6), and bytes in one train at most (one IPv4 UDP payload, with room to spare).
const TRAIN_DATAGRAMS: usize = 64;
const TRAIN_BYTES: usize = 65_000;

/// A turn's finished datagrams for one address, back to back, that leave together at the end
/// of the turn ([`Transport::flush`]) in one system call (`DatagramSocket::send_segments`:
/// UDP GSO on Linux): each is `segment` bytes long but the last, which may be shorter, so the
/// kernel cuts the train into the very same datagrams. A datagram that does not fit this shape
/// sends the train before it at once and starts the next. The bytes on the wire are those of
/// separate sends; only the number of system calls changes (docs/performance.md).
struct Train {
    to: SocketAddr,
    bytes: Vec<u8>,
    segment: usize,
    count: usize,
    /// A shorter datagram ended it: nothing more may follow.
    closed: bool,
}

impl Train {
    /// Whether a datagram of `len` bytes may follow in this train.
    fn takes(&self, len: usize) -> bool {
        !self.closed && len <= self.segment && self.count < TRAIN_DATAGRAMS && self.bytes.len() + len <= TRAIN_BYTES
    }
}

/// A message waiting for its destination node to be heard from.
struct Held {
    to: NodeId,
    until: Instant,
    message: Message,
}

/// Counters by cause, in name order. There are a dozen causes, and the traffic ones are
/// counted for every datagram and message: a short vector searched by pointer first (callers
/// pass the same `&'static str`) is cheaper than a map keyed by string comparison, and the
/// three counted on every turn with traffic ([`Hot`]) are found by an index kept up to date.
struct Tally(Vec<(&'static str, u64)>, Names, [usize; HOT_NAMES.len()]);

/// How many times a cause was added to a [`Tally`]: its list of names changes only then.
type Names = u64;

/// The causes counted for every datagram or turn of traffic.
#[derive(Clone, Copy)]
enum Hot {
    DatagramsSent,
    DatagramsReceived,
    MessagesSent,
}

/// The names of [`Hot`]'s causes, in its order.
const HOT_NAMES: [&str; 3] = ["datagrams_sent", "datagrams_received", "messages_sent"];

impl Default for Tally {
    fn default() -> Tally {
        Tally(Vec::new(), 0, [usize::MAX; HOT_NAMES.len()])
    }
}

impl Tally {
    fn add(&mut self, cause: &'static str) {
        self.add_n(cause, 1);
    }
    /// Count a hot cause: an index, not a search (its position once it is in the list).
    fn add_hot(&mut self, cause: Hot, n: u64) {
        match self.0.get_mut(self.2[cause as usize]) {
            Some(entry) => entry.1 += n,
            None => self.add_n(HOT_NAMES[cause as usize], n),
        }
    }
    fn add_n(&mut self, cause: &'static str, n: u64) {
        if let Some(entry) = self.0.iter_mut().find(|(name, _)| std::ptr::eq(*name, cause)) {
            entry.1 += n;
            return;
        }
        match self.0.binary_search_by(|(name, _)| (*name).cmp(cause)) {
            Ok(i) => self.0[i].1 += n,
            Err(i) => {
                self.0.insert(i, (cause, n));
                self.1 += 1;
                // The insertion moved the names after it: find the hot ones again (rare: once
                // per cause over the transport's life).
                for (slot, name) in self.2.iter_mut().zip(HOT_NAMES) {
                    *slot = self.0.binary_search_by(|(have, _)| (*have).cmp(name)).unwrap_or(usize::MAX);
                }
            }
        }
    }
}

impl<S: DatagramSocket> Drop for UdpTransport<S> {
    /// A node that stops cleanly saves its replay marks now (a crash loses at most the last
    /// second's: D-N5.3).
    fn drop(&mut self) {
        self.next_save = Instant::ZERO;
        let now = self.now;
        self.save_marks(now);
    }
}

/// Replay high-water marks as saved in a state file: datagram numbers by sender (`NODE SEQ`
/// lines) and signed request ids by requester (`op NODE ID` lines), each restored as a window
/// that accepts only newer numbers.
#[derive(Default)]
struct Marks {
    datagrams: BTreeMap<NodeId, (ReplayWindow, Instant)>,
    requests: BTreeMap<NodeId, ReplayWindow>,
}

/// The marks saved in `path`. A missing file is a first start; unreadable lines are skipped
/// with a warning.
fn load_marks(path: &std::path::Path, warnings: &mut Vec<String>) -> Marks {
    let mut marks = Marks::default();
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return marks,
        Err(e) => {
            warnings.push(format!("cannot read replay marks from {}: {e}", path.display()));
            return marks;
        }
    };
    let mut bad = 0;
    for line in text.lines().take(MAX_REPLAY_SENDERS + crate::operator::MAX_REQUESTERS) {
        let (signed, line) = match line.strip_prefix("op ") {
            Some(rest) => (true, rest),
            None => (false, line),
        };
        let mut parts = line.split_whitespace();
        match (parts.next().and_then(|n| n.parse().ok()), parts.next().and_then(|q| q.parse().ok())) {
            (Some(n), Some(seq)) if signed => {
                marks.requests.insert(NodeId(n), ReplayWindow::after(seq));
            }
            (Some(n), Some(seq)) => {
                marks.datagrams.insert(NodeId(n), (ReplayWindow::after(seq), Instant::ZERO));
            }
            _ => bad += 1,
        }
    }
    if bad > 0 {
        warnings.push(format!("{bad} unreadable lines in replay marks {} were skipped", path.display()));
    }
    marks
}

/// Why discovery does not work here, and what to do instead.
fn discovery_warning(config: &UdpConfig, error: &str) -> String {
    let at = config.discovery.map_or_else(String::new, |a| a.to_string());
    format!(
        "discovery by multicast at {at} is not available on this machine ({error}): nodes will not find each \
         other by themselves; list them with peer=ADDR:PORT in the udp:// URL (AYLLU_URL)"
    )
}

/// When a peer is forgotten (N4, N6): three of its HELLO periods after it was last heard; and
/// an unproven one, not in use, `unproven` after it was let in at the latest. Hearing from a
/// peer, proving it or using it only ever moves this later, so a computed expiry is a lower
/// bound (`next_expiry`).
fn expiry(p: &Peer, unproven: Duration) -> Instant {
    let normal = p.last_heard + p.interval * 3;
    if p.budget.proven || p.fixed {
        return normal;
    }
    let mut short = p.admitted + unproven;
    if let Some(used) = p.used {
        short = short.max(used + IN_USE);
    }
    normal.min(short)
}

#[derive(Clone, Debug)]
struct Peer {
    addr: SocketAddr,
    name: String,
    groups: Vec<String>,
    interval: Duration,
    last_heard: Instant,
    /// When it was let in (or its address last changed): an unproven peer's clock starts here.
    admitted: Instant,
    /// Its address is one the URL names (`peer=`): the operator vouched for it.
    fixed: bool,
    /// When this node last sent it a message (a connection, a request, a group's unicast).
    used: Option<Instant>,
    /// When it was last sent a CHALLENGE (at most one per [`RECHALLENGE`]).
    challenged: Option<Instant>,
    /// What its address may still be sent before it proves it receives there; `proven` once
    /// it echoed a cookie, or authenticated as a sender known to be fresh.
    budget: Budget,
}

impl Peer {
    /// A *protected* peer is never displaced by a newcomer and is greeted every period: its
    /// address is proven (ECHO, or a fresh authenticated datagram), named in the URL, or in use
    /// by this node. Anyone can send a second datagram or announce a group in an open team, so
    /// neither protects (docs/semantics.md N4).
    fn protected(&self, now: Instant) -> bool {
        self.budget.proven || self.fixed || self.used.is_some_and(|u| now < u + IN_USE)
    }
}

/// What [`UdpTransport::admit`] let through: the sender, whether it is new to the peer table,
/// and whether its datagram may be applied whole (`fresh`: not a keyed sender this node has no
/// memory of and that has not yet answered a CHALLENGE, D-N5.4).
struct Admitted {
    sender: NodeId,
    is_new: bool,
    fresh: bool,
}

/// A keyed sender's replay window (N5), with when it was last used, and what is known of its
/// freshness: a window made here for a sender this node has no memory of accepts numbers, but
/// the datagrams are applied only once the sender answered a CHALLENGE with an authenticated
/// ECHO (D-N5.4).
struct SenderWindow {
    window: ReplayWindow,
    used: Instant,
    fresh: bool,
    /// When it was last challenged for freshness.
    challenged: Option<Instant>,
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
    inbox: VecDeque<(NodeId, Message)>,
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
    /// Scratch list of a message's destination addresses.
    route_buf: Vec<SocketAddr>,
    /// Names received recently (decoding allocates nothing for a name seen before).
    names: NameCache,
    /// Makes and checks the cookies that prove a peer's address.
    cookies: Cookies,
    /// With `operator=`: the key structure changes must be signed with, and what it let through.
    operator: Option<OperatorGate>,
    /// The messages of the last datagram that waited for its checks ([`Inbound`]'s `rest`),
    /// emptied: its allocation is reused.
    decoded: Vec<WireMessage>,
}

impl UdpTransport<OsSocket> {
    /// Bind a real UDP socket as `config` says.
    pub fn bind(id: NodeId, config: UdpConfig) -> Result<Self, Error> {
        let mut socket = OsSocket::bind(config.bind).map_err(|e| {
            let what = if e.kind() == std::io::ErrorKind::AddrInUse {
                format!(
                    "binding UDP socket {}: another process holds this address (an earlier node still \
                     running?); stop it, or bind port 0 to let the system choose a free one",
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

/// Hand `f` each element of `queue` where it lies, oldest first, then empty the queue: the
/// node's outgoing messages and the transport's inbox, whose elements (128-136 bytes) each cost
/// a `memcpy` to move out. One element (a loop's usual turn) is popped at once and several (a
/// batch) dropped by one loop over the queue, each shape the cheaper one by callgrind (the other
/// way round cost 87 instructions more for one message alone, 47 more a message in a batch of 64).
#[inline(always)]
fn each_then_empty<T>(queue: &mut VecDeque<T>, mut f: impl FnMut(&T)) {
    if queue.len() == 1 {
        if let Some(x) = queue.front() {
            f(x);
        }
        queue.pop_front();
        return;
    }
    for x in queue.iter() {
        f(x);
    }
    queue.clear();
}

/// Whether this node joined `group`, for a group's port message (S10, D-S10.6): a handful of
/// names compared as bytes, nothing allocated. One rule for both ways a message reaches the
/// inbox ([`Inbound::port`], and the messages that waited for the checks).
fn joined(joined: &[String], group: &str) -> bool {
    joined.iter().any(|g| g == group)
}

/// The receiving end of [`decode_into`] for one datagram: its port messages go straight into
/// the inbox, a group's only if this node joined the group (S10, D-S10.6; the others are
/// counted as `not_member` once the datagram is admitted). Any other message goes to `rest`,
/// and so does every message after it, so that the inbox keeps the datagram's order.
struct Inbound<'a> {
    inbox: &'a mut VecDeque<(NodeId, Message)>,
    joined: &'a [String],
    rest: &'a mut Vec<WireMessage>,
    sender: NodeId,
    not_member: u64,
}

impl MessageSink for Inbound<'_> {
    fn header(&mut self, header: &Header) {
        self.sender = header.sender;
    }
    #[inline(always)]
    fn port(&mut self, message: PortMessage, group: Option<Arc<str>>) {
        if !self.rest.is_empty() {
            return self.rest.port(message, group);
        }
        if group.is_none_or(|group| joined(self.joined, &group)) {
            self.inbox.push_back((self.sender, Message::Port(message)));
        } else {
            self.not_member += 1;
        }
    }
    fn other(&mut self, message: WireMessage) {
        self.rest.push(message);
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
            inbox: VecDeque::new(),
            assemblies: VecDeque::new(),
            greet: Vec::new(),
            counters: Tally::default(),
            counters_written: std::cell::Cell::new((0, 0)),
            generation: 0,
            buf: vec![0u8; MAX_DATAGRAM + 1],
            unflushed: 0,
            spare: Vec::new(),
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

    fn count(&mut self, cause: &'static str) {
        self.counters.add(cause);
        self.generation += 1;
    }

    fn count_hot(&mut self, cause: Hot, n: u64) {
        self.counters.add_hot(cause, n);
        self.generation += 1;
    }

    /// Where a destination's datagrams go now, into `out` (emptied first; a buffer kept
    /// between messages, since this runs for every message sent).
    /// The peers it names are marked in use (N4).
    fn route(&mut self, to: &Destination, out: &mut Vec<SocketAddr>) {
        out.clear();
        let now = self.now;
        match to {
            Destination::Node(n) => out.extend(self.peers.get_mut(n).map(|p| {
                p.used = Some(now);
                p.addr
            })),
            Destination::Group(g) => {
                if let Some((_, a)) = self.config.groups.iter().find(|(name, _)| **name == **g) {
                    out.push(*a);
                } else if let Some(b) = self.config.broadcast {
                    out.push(b);
                } else {
                    // A group membership in use keeps a member's place through its proof, not
                    // through the announcement: anyone can announce a group, and a real member
                    // proves its address at its greeting (N4). So it is not marked in use here.
                    out.extend(self.peers.values().filter(|p| p.groups.iter().any(|x| **x == **g)).map(|p| p.addr));
                    out.dedup();
                }
            }
        }
    }

    /// Check an authenticated datagram's number against its sender's replay window (N5), kept
    /// apart from the peer table so that it outlives the peer entry; at most
    /// [`MAX_REPLAY_SENDERS`] windows, the least recently used forgotten first (counted).
    /// `None` for a number seen before, else whether the sender is known to be fresh. A
    /// window made here, for a sender this node has no memory of (a first contact, a restart
    /// without `state=`, a window evicted), starts not fresh (D-N5.4).
    fn accept_sequence(&mut self, sender: NodeId, seq: u64) -> Option<bool> {
        if !self.replay.contains_key(&sender) && self.replay.len() >= MAX_REPLAY_SENDERS {
            if let Some(oldest) = self.replay.iter().min_by_key(|(_, w)| w.used).map(|(n, _)| *n) {
                self.replay.remove(&oldest);
                self.count("replay_window_evicted");
            }
        }
        let now = self.now;
        let w = self.replay.entry(sender).or_insert_with(|| SenderWindow {
            window: ReplayWindow::new(),
            used: now,
            fresh: false,
            challenged: None,
        });
        if !w.window.accept(seq) {
            return None;
        }
        w.used = now;
        self.replay_dirty = true;
        Some(w.fresh)
    }

    /// Whether `rest` holds an ECHO of a cookie this node made for `sender` at `from`.
    fn echoes_cookie(&self, sender: NodeId, from: SocketAddr, rest: &[WireMessage]) -> bool {
        rest.iter()
            .any(|m| matches!(m, WireMessage::Echo { cookie } if self.cookies.check(self.now, sender, from, cookie)))
    }

    /// Send `sender` at `from` a CHALLENGE now (pushed into the turn's datagram for `from`).
    fn challenge(&mut self, sender: NodeId, from: SocketAddr) {
        let cookie = self.cookies.make(self.now, sender, from);
        self.push(from, &WireMessage::Challenge { cookie });
        self.count("challenges_sent");
    }

    /// Write the newest accepted number of every sender to `config.state`, atomically (a
    /// temporary file renamed over the old one), if they changed and a second has passed.
    fn save_marks(&mut self, now: Instant) {
        // Checked before the path is copied: this runs every turn.
        let signed_dirty = self.operator.as_ref().is_some_and(|g| g.dirty);
        if !(self.replay_dirty || signed_dirty) || now < self.next_save {
            return;
        }
        let Some(path) = self.config.state.clone() else { return };
        self.replay_dirty = false;
        self.next_save = now + Duration::from_secs(1);
        let mut text: String =
            self.replay.iter().filter_map(|(n, w)| w.window.newest().map(|seq| format!("{} {seq}\n", n.0))).collect();
        if let Some(gate) = &mut self.operator {
            gate.dirty = false;
            text.extend(gate.marks().map(|(n, id)| format!("op {} {id}\n", n.0)));
        }
        let tmp = path.with_extension("tmp");
        let saved = std::fs::write(&tmp, text).and_then(|()| std::fs::rename(&tmp, &path));
        match saved {
            Ok(()) => self.count("state_saved"),
            Err(e) => {
                self.count("state_error");
                if !self.state_warned {
                    self.state_warned = true;
                    self.events.push(TransportEvent::Warning(format!(
                        "cannot save replay marks to {}: {e}; a restart may accept replayed datagrams",
                        path.display()
                    )));
                }
            }
        }
    }

    /// Whether a datagram carrying our id came from us: from our own address (or our port on
    /// a local address, when bound to the unspecified address) and numbered as ours.
    fn is_own(&self, from: SocketAddr, seq: u64) -> bool {
        let ours = (self.seq_start..self.seq).contains(&seq);
        let here = self.socket.local_addr().is_ok_and(|l| {
            l.port() == from.port() && (l.ip() == from.ip() || l.ip().is_unspecified() || from.ip().is_loopback())
        });
        ours && here
    }

    fn writer(&mut self) -> DatagramWriter {
        let buf = self.spare.pop().unwrap_or_default();
        let w = DatagramWriter::with_buffer(buf, self.config.team, self.id, self.seq, self.config.key, self.config.mtu);
        self.seq += 1;
        w
    }

    /// Append a message to the open datagram for `addr`; a full datagram is finished and queued
    /// for the end of the turn.
    fn push(&mut self, addr: SocketAddr, message: &WireMessage) {
        self.push_with(addr, |w| w.push(message));
    }

    /// [`UdpTransport::push`] for a port message, encoded from the core's own message.
    fn push_port(&mut self, addr: SocketAddr, message: &PortMessage, group: Option<&str>) {
        self.push_with(addr, |w| w.push_port(message, group));
    }

    /// Add one message, written by `encode`, to the turn's datagram for `addr`; a full datagram
    /// leaves and the message starts the next.
    #[inline(always)]
    fn push_with(&mut self, addr: SocketAddr, encode: impl Fn(&mut DatagramWriter) -> Result<(), EncodeError>) {
        let i = match self.batches.iter().position(|(a, _)| *a == addr) {
            Some(i) => i,
            None => {
                let w = self.writer();
                self.batches.push((addr, w));
                self.batches.len() - 1
            }
        };
        match encode(&mut self.batches[i].1) {
            Ok(()) => {}
            Err(EncodeError::DoesNotFit { .. }) => {
                let fresh = self.writer();
                let full = std::mem::replace(&mut self.batches[i].1, fresh);
                self.transmit(addr, full);
                if encode(&mut self.batches[i].1).is_err() {
                    self.count("too_large");
                }
            }
            Err(EncodeError::TooLarge { .. }) | Err(EncodeError::ReportTooLarge { .. }) => self.count("too_large"),
            Err(EncodeError::Invalid(_)) => self.count("unencodable"),
        }
    }

    /// Finish `w` and queue it to leave at the end of the turn with the turn's other datagrams
    /// for `addr`, in one system call when their sizes allow (see [`Train`]).
    fn transmit(&mut self, addr: SocketAddr, w: DatagramWriter) {
        if w.is_empty() {
            return;
        }
        let bytes = w.finish();
        let len = bytes.len();
        if let Some(i) = self.trains.iter().position(|t| t.to == addr) {
            if self.trains[i].takes(len) {
                let train = &mut self.trains[i];
                train.bytes.extend_from_slice(&bytes);
                train.count += 1;
                train.closed = len < train.segment;
                self.keep_buffer(bytes);
                return;
            }
            // Sizes or room do not allow: what is queued leaves now, in order, and a new train
            // starts with this datagram.
            let full = self.trains.swap_remove(i);
            self.send_train(full);
        }
        self.trains.push(Train { to: addr, bytes, segment: len, count: 1, closed: false });
    }

    /// Send a train's datagrams: one `send_to`, or one `send_segments` for several.
    fn send_train(&mut self, train: Train) {
        let Train { to, bytes, segment, count, .. } = train;
        let sent =
            if count == 1 { self.socket.send_to(&bytes, to) } else { self.socket.send_segments(&bytes, segment, to) };
        match sent {
            Ok(()) => self.count_hot(Hot::DatagramsSent, count as u64),
            Err(e) => {
                self.count("send_error");
                if Some(to) == self.config.discovery && !self.discovery_failed {
                    self.discovery_failed = true;
                    self.events.push(TransportEvent::Warning(discovery_warning(&self.config, &e.to_string())));
                }
            }
        }
        self.keep_buffer(bytes);
    }

    /// Keep a sent datagram's buffer for the next ones: a loop turn then allocates nothing to
    /// send.
    fn keep_buffer(&mut self, bytes: Vec<u8>) {
        if self.spare.len() < SPARE_BUFFERS {
            self.spare.push(bytes);
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
        targets.extend(self.config.discovery);
        // Unproven peers were greeted once when first heard; greeting them every period would
        // reflect traffic at whatever address a forger wrote.
        let now = self.now;
        targets.extend(self.peers.values().filter(|p| p.protected(now)).map(|p| p.addr));
        targets.sort();
        targets.dedup();
        let hello = self.hello();
        for t in targets {
            self.push(t, &hello);
        }
    }

    fn receive_datagram(&mut self, len: usize, from: SocketAddr) {
        // Port messages go into the inbox as they are decoded (the hot path); anything else,
        // and whatever follows it, waits in `rest` for the checks below, so the inbox keeps
        // the datagram's order. A refused datagram's messages are taken back out.
        let mark = self.inbox.len();
        let mut rest = std::mem::take(&mut self.decoded);
        rest.clear();
        let mut sink =
            Inbound { inbox: &mut self.inbox, joined: &self.joined, rest: &mut rest, sender: NodeId(0), not_member: 0 };
        let decoded = decode_into(&self.buf[..len], &self.receiver, &mut self.names, &mut sink);
        let not_member = sink.not_member;
        let admitted = match decoded {
            Ok(header) => self.admit(header, from, len, &rest),
            Err(reason) => {
                self.count(reason.name());
                None
            }
        };
        let Some(Admitted { sender, is_new, fresh }) = admitted else {
            self.inbox.truncate(mark);
            self.decoded = rest;
            return;
        };
        if !fresh {
            // A keyed sender not yet known fresh (D-N5.4): its port messages and requests may
            // be replays captured before this node started; they wait for its ECHO (values are
            // best effort, N1; requests are retried, N2). Replies go through: they match only
            // our own pending requests, whose ids start at this run's boot time.
            let ports = self.inbox.len() - mark;
            self.inbox.truncate(mark);
            let mut refused = ports as u64;
            rest.retain(|m| {
                let applies =
                    matches!(m, WireMessage::Port(_) | WireMessage::GroupPort { .. } | WireMessage::Request { .. })
                        || matches!(m, WireMessage::UnknownRequest { .. });
                refused += u64::from(applies);
                !applies
            });
            if refused > 0 {
                self.counters.add_n("not_fresh", refused);
                self.generation += 1;
            }
        }
        if not_member > 0 {
            self.counters.add_n("not_member", not_member);
            self.generation += 1;
        }
        let now = self.now;
        let mut hello = false;
        for m in rest.drain(..) {
            match m {
                WireMessage::Port(p) => self.inbox.push_back((sender, Message::Port(p))),
                WireMessage::GroupPort { group, message } => {
                    // Only a member applies a group's message (S10, D-S10.6).
                    if joined(&self.joined, &group) {
                        self.inbox.push_back((sender, Message::Port(message)));
                    } else {
                        self.count("not_member");
                    }
                }
                WireMessage::Request { id, body, signature } => {
                    let team = self.config.team;
                    let verdict = match &mut self.operator {
                        Some(gate) => {
                            let request = SignedRequest { team, requester: sender, receiver: self.id, id, body: &body };
                            gate.admit(now, &request, signature.as_ref())
                        }
                        None => Ok(()),
                    };
                    match verdict {
                        Ok(()) => self.inbox.push_back((sender, Message::Control(ControlMessage { id, body }))),
                        Err(refusal) => {
                            self.count(refusal.cause());
                            // A replay or a request over the rate is not answered: the answer
                            // would be the very traffic the limit is for.
                            use crate::operator::Refusal;
                            if !matches!(refusal, Refusal::Replayed | Refusal::RateLimited) {
                                // Answered, so the requester learns why rather than retrying.
                                let what =
                                    if matches!(body, ControlBody::Connect { .. }) { "CONNECT" } else { "DISCONNECT" };
                                let why = format!(
                                    "not allowed: this node applies {what} only when signed with its operator key ({})",
                                    refusal.cause()
                                );
                                let reply = ControlBody::Reply { result: Err(why) };
                                let _ = self.send_message(
                                    &Destination::Node(sender),
                                    &Message::Control(ControlMessage { id, body: reply }),
                                );
                            }
                        }
                    }
                }
                WireMessage::Challenge { cookie } => {
                    // Echoed at once, to where it came from: the same size, so no amplification.
                    self.push(from, &WireMessage::Echo { cookie });
                    self.count("challenges_received");
                }
                WireMessage::Echo { cookie } => {
                    if self.cookies.check(now, sender, from, &cookie) {
                        if let Some(p) = self.peers.get_mut(&sender) {
                            if p.addr == from && !p.budget.proven {
                                p.budget.proven = true;
                                self.count("addresses_proven");
                            }
                        }
                        self.one_node_per_address(sender, from);
                    } else {
                        self.count("bad_cookie");
                    }
                }
                WireMessage::UnknownRequest { id, .. } => {
                    let reply = ControlBody::Reply { result: Err("unknown operation".into()) };
                    let _ = self.send_message(
                        &Destination::Node(sender),
                        &Message::Control(ControlMessage { id, body: reply }),
                    );
                }
                WireMessage::Reply { id, part, parts, payload } => self.reply_part(sender, id, part, parts, payload),
                WireMessage::Hello { interval_ms, name, groups } => {
                    if let Some(p) = self.peers.get_mut(&sender) {
                        // Clamped: a forged peer announcing 0xFFFFFFFF ms would stay 149 days.
                        p.interval = Duration::from_millis(u64::from(interval_ms.max(1))).min(MAX_PEER_INTERVAL);
                        p.name = name.to_string();
                        p.groups.clear();
                        let mut bytes = 0;
                        for g in groups.iter().take(MAX_PEER_GROUPS) {
                            bytes += g.len();
                            if bytes > MAX_PEER_GROUP_BYTES {
                                break;
                            }
                            p.groups.push(g.to_string());
                        }
                        if p.groups.len() < groups.len() {
                            self.counters.add("groups_truncated");
                        }
                    }
                    if is_new {
                        self.greet.push((sender, from));
                    } else if let Some(p) = self.peers.get_mut(&sender) {
                        // Proving each other is part of greeting (N6): a peer still unproven
                        // is challenged again at its HELLOs, within its 3x budget, until it
                        // echoes or its short clock runs out.
                        let due = p.challenged.is_none_or(|t| now >= t + RECHALLENGE);
                        if p.addr == from && !p.budget.proven && due {
                            p.challenged = Some(now);
                            let challenge = (ayllu_wire::HEADER_LEN
                                + ayllu_wire::MESSAGE_HEADER_LEN
                                + ayllu_wire::COOKIE_LEN) as u64;
                            if p.budget.spend(challenge) {
                                self.challenge(sender, from);
                            }
                        }
                    }
                    self.count("hellos_received");
                    hello = true;
                }
                WireMessage::Unknown { .. } => self.count("unknown_kind"),
            }
        }
        self.decoded = rest;
        if is_new {
            self.release_held(sender);
        }
        if is_new || hello {
            // A new peer, or a new HELLO period, may expire before every other peer.
            let unproven = self.unproven_lifetime();
            if let Some(p) = self.peers.get(&sender) {
                self.next_expiry = self.next_expiry.min(expiry(p, unproven));
            }
        }
    }

    /// How long an unproven peer is kept ([`UNPROVEN_PERIODS`] of our HELLO period, bounded).
    fn unproven_lifetime(&self) -> Duration {
        (self.config.hello_interval * UNPROVEN_PERIODS).clamp(MIN_UNPROVEN_LIFETIME, MAX_UNPROVEN_LIFETIME)
    }

    /// `sender` proved it receives at `from`: it becomes that peer's address (a proven peer
    /// that moved), and other ids at the same address that proved nothing stronger leave the
    /// table. One socket is one node (lite/README.md), so an attacker that answers CHALLENGEs
    /// holds at most one proven place per address it really receives at, not one per id.
    fn one_node_per_address(&mut self, sender: NodeId, from: SocketAddr) {
        let now = self.now;
        if let Some(p) = self.peers.get_mut(&sender) {
            if p.addr != from {
                p.addr = from;
                p.budget = Budget { proven: true, ..Budget::default() };
                p.admitted = now;
                p.fixed = self.config.peers.contains(&from);
                self.count("addresses_proven");
            }
        }
        let before = self.peers.len();
        self.peers.retain(|n, p| *n == sender || p.addr != from || p.fixed);
        for _ in self.peers.len()..before {
            self.count("peer_replaced");
        }
    }

    /// The checks a decoded datagram passes before anything in it is applied (our own
    /// looped-back broadcast, another node with our id, a replayed number, the admission of a
    /// newcomer, a full peer table), and the peer table's update for its sender; `None`,
    /// counted, for a datagram to drop. `rest` is the datagram's messages other than its
    /// leading port messages (an ECHO among them proves the sender's address at once).
    fn admit(&mut self, header: Header, from: SocketAddr, len: usize, rest: &[WireMessage]) -> Option<Admitted> {
        if header.sender == self.id {
            if self.is_own(from, header.seq) {
                // Our own broadcast, looped back by the network.
                self.count("own");
                return None;
            }
            // Another node uses our id: both of us hear the other, so both report it.
            self.count("duplicate_id");
            if !self.duplicates.contains(&from) && self.duplicates.len() < MAX_DUPLICATES {
                self.duplicates.push(from);
                self.events.push(TransportEvent::Warning(format!(
                    "another node with this node's id {} is sending from {from}: node ids must be unique in a team \
                     (its messages are dropped and counted as duplicate_id)",
                    self.id.0
                )));
            }
            return None;
        }
        let now = self.now;
        let sender = header.sender;
        // Checked only for a datagram that carries an ECHO (rare): one MAC each.
        let has_echo = rest.iter().any(|m| matches!(m, WireMessage::Echo { .. }));
        let echoed = has_echo && self.echoes_cookie(sender, from, rest);
        // A keyed sender is *fresh* once this node remembers it (a window of this run or the
        // state file) and it answered a CHALLENGE of this run with an authenticated ECHO: a
        // captured datagram is older than that ECHO, and the window restarts above it (D-N5.4).
        let mut fresh = true;
        if header.authenticated {
            match self.accept_sequence(sender, header.seq) {
                None => {
                    self.count("replayed");
                    return None;
                }
                Some(true) => {}
                Some(false) if echoed => {
                    if let Some(w) = self.replay.get_mut(&sender) {
                        w.window = ReplayWindow::after(header.seq);
                        w.fresh = true;
                    }
                    self.count("senders_fresh");
                }
                Some(false) => fresh = false,
            }
        }
        // What an authenticated datagram proves (the sender holds the key and receives at its
        // address) holds only for a fresh one: a replay comes from wherever the attacker is.
        let trusted = header.authenticated && fresh;
        let is_new = !self.peers.contains_key(&sender);
        if is_new {
            // The operator vouched for an address named in the URL, for one id at a time.
            let fixed = self.config.peers.contains(&from) && !self.peers.values().any(|p| p.fixed && p.addr == from);
            // Only a newcomer that proves nothing spends an admission token.
            let vouched = trusted || fixed || echoed;
            if !(vouched || self.admission.admit(now, from.ip())) {
                self.count("admission_limited");
                // A real newcomer greets: challenge it (within a global rate, and within 3x
                // of this datagram: a CHALLENGE is 39 bytes, a HELLO datagram at least 30), so
                // that its ECHO lets it in past the rate.
                let greets = rest.iter().any(|m| matches!(m, WireMessage::Hello { .. }));
                if greets && REFUSED_CHALLENGES.take(&mut self.refused_challenges, now) {
                    self.challenge(sender, from);
                }
                return None;
            }
            if self.peers.len() >= MAX_PEERS {
                // Make room by forgetting the unprotected peer let in longest ago (the nearest
                // to its own expiry); protected peers are never displaced by a newcomer.
                let oldest = self.peers.iter().filter(|(_, p)| !p.protected(now)).min_by_key(|(_, p)| p.admitted);
                match oldest.map(|(n, _)| *n) {
                    Some(n) => {
                        self.peers.remove(&n);
                        self.count("peer_evicted");
                    }
                    None => {
                        self.count("peer_table_full");
                        return None;
                    }
                }
            }
            self.peers.insert(
                sender,
                Peer {
                    addr: from,
                    name: String::new(),
                    groups: Vec::new(),
                    interval: self.config.hello_interval,
                    last_heard: now,
                    admitted: now,
                    fixed,
                    used: None,
                    challenged: None,
                    budget: Budget::default(),
                },
            );
        }
        let peer = self.peers.get_mut(&sender).expect("inserted above");
        let (mut challenge_at, mut unconfirmed) = (None, false);
        if peer.addr != from {
            if trusted || echoed || !(peer.budget.proven || peer.fixed) {
                // A fresh authenticated datagram, a proof, or a peer that had nothing to lose:
                // the peer moved. The proof was for the old address; the new one starts over.
                peer.budget.reset();
                peer.addr = from;
                peer.admitted = now;
                peer.fixed = self.config.peers.contains(&from);
                peer.challenged = None;
            } else {
                // Anyone can write a proven peer's id: its messages are applied (an open team
                // authenticates nothing), but its traffic keeps going to the proven address
                // until the new one proves itself (QUIC's path validation, RFC 9000 8.2).
                unconfirmed = true;
                if peer.challenged.is_none_or(|t| now >= t + RECHALLENGE) {
                    peer.challenged = Some(now);
                    challenge_at = Some(from);
                }
            }
        }
        if peer.addr == from {
            peer.last_heard = now;
            peer.budget.received = peer.budget.received.saturating_add(len as u64);
            // Forging a fresh authenticated datagram needs the team key.
            peer.budget.proven |= trusted;
        }
        if !fresh {
            // Challenged for freshness, from wherever it came (a replay's address is the
            // attacker's: the CHALLENGE is no larger than the datagram, so no amplification).
            if let Some(w) = self.replay.get_mut(&sender) {
                if w.challenged.is_none_or(|t| now >= t + RECHALLENGE) {
                    w.challenged = Some(now);
                    challenge_at = Some(from);
                }
            }
        }
        if unconfirmed {
            self.count("address_unconfirmed");
        }
        if let Some(to) = challenge_at {
            self.challenge(sender, to);
        }
        self.count_hot(Hot::DatagramsReceived, 1);
        Some(Admitted { sender, is_new, fresh })
    }

    /// Read datagrams (at most [`RECV_BATCH`]) until one puts a message into the inbox or the
    /// socket has nothing more. Inlined into its two callers: a call here is paid on every
    /// turn, and a loop that waits turns once per message.
    #[inline(always)]
    fn refill(&mut self) {
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
            Ok(None) => {
                // Bounded in bytes as well as in count: the oldest other assemblies go first.
                let mut total: usize = self.assemblies.iter().map(|(_, a)| a.bytes()).sum();
                while total > MAX_ASSEMBLY_BYTES && self.assemblies.len() > 1 {
                    let oldest = usize::from(self.assemblies.front().is_some_and(|(k, _)| *k == key));
                    if let Some((_, gone)) = self.assemblies.remove(oldest) {
                        total -= gone.bytes();
                        self.count("reply_evicted");
                    }
                }
            }
            Err(_) => {
                self.assemblies.remove(i);
                self.count("bad_reply");
            }
        }
    }

    /// Keep `message` for node `to` until it greets, or drop it after [`HOLD_PERIODS`]. Of
    /// the port messages of one connection only the newest is kept: stale values are
    /// worthless (N1).
    fn hold(&mut self, to: NodeId, message: Message) -> Sent {
        let until = self.now + self.config.hello_interval * HOLD_PERIODS;
        // The newest of one connection's port messages replaces the older (N1); a retried
        // request (same id, N2) replaces its earlier copy instead of queueing again.
        let same = |h: &Held| {
            h.to == to
                && match (&h.message, &message) {
                    (Message::Port(a), Message::Port(b)) => a.conn == b.conn,
                    (Message::Control(a), Message::Control(b)) => a.id == b.id,
                    _ => false,
                }
        };
        if let Some(i) = self.held.iter().position(same) {
            self.held[i] = Held { to, until, message };
            self.count("held_superseded");
            return Sent::Held;
        }
        if self.held.len() >= MAX_HELD {
            self.held.pop_front();
            self.count("held_dropped");
        }
        self.held.push_back(Held { to, until, message });
        self.count("held");
        Sent::Held
    }

    /// `node` was just heard from: send what was held for it.
    fn release_held(&mut self, node: NodeId) {
        if !self.held.iter().any(|h| h.to == node) {
            return;
        }
        let (mine, rest): (VecDeque<Held>, VecDeque<Held>) =
            std::mem::take(&mut self.held).into_iter().partition(|h| h.to == node);
        self.held = rest;
        for h in mine {
            if self.send_message(&Destination::Node(node), &h.message) == Sent::Now {
                self.count("held_sent");
            }
        }
    }

    /// Send `message` to `to`, from a borrowed message: only a message held for a node not
    /// heard from yet is copied (the rare case).
    fn send_message(&mut self, to: &Destination, message: &Message) -> Sent {
        // The hot path, a port message to one node: one lookup, no list of addresses.
        if let (Destination::Node(n), Message::Port(p)) = (to, message) {
            let now = self.now;
            let Some(addr) = self.peers.get_mut(n).map(|peer| {
                peer.used = Some(now);
                peer.addr
            }) else {
                return self.hold(*n, message.clone());
            };
            self.push_port(addr, p, None);
            self.unflushed += 1;
            return Sent::Now;
        }
        let mut addrs = std::mem::take(&mut self.route_buf);
        self.route(to, &mut addrs);
        let mut sent = Sent::Now;
        if addrs.is_empty() {
            self.route_buf = addrs;
            return match to {
                // A reply is never held: its requester was heard a moment ago and has gone from
                // the peer table since (evicted by a flood of invented ids, or refused by a
                // full table). Holding it kept a whole LIST report per forged requester (256
                // of 150 KB each); the requester retries (N2), and a retry it sends once it is
                // a peer again is answered from the core's memory (D-S10.2).
                Destination::Node(_)
                    if matches!(message, Message::Control(ControlMessage { body: ControlBody::Reply { .. }, .. })) =>
                {
                    self.count("no_route");
                    Sent::Dropped
                }
                Destination::Node(n) => self.hold(*n, message.clone()),
                Destination::Group(_) => {
                    self.count("no_route");
                    Sent::Dropped
                }
            };
        } else if let Message::Port(p) = message {
            // A port message is one wire message, encoded from the core's message (the hot
            // path). To a group it names the group: its address or the team's broadcast
            // reaches non-members too, and they drop it (D-S10.6).
            let group = match to {
                Destination::Group(group) => Some(&**group),
                Destination::Node(_) => None,
            };
            for &addr in &addrs {
                self.push_port(addr, p, group);
            }
            self.unflushed += 1;
        } else {
            let (mtu, keyed) = (self.config.mtu, self.config.key.is_some());
            // An answer larger than a reply may carry (a report over 64 parts, a value over one
            // datagram) is answered with an error that says so, rather than silently not at
            // all (the requester waited for 5 s, then reported the node as not answering).
            let error_reply = |why: String| {
                let Message::Control(c) = message else { unreachable!("only replies carry answers") };
                ayllu_wire::reply::reply_messages(c.id, &Err(why), mtu, keyed)
            };
            let parts = match WireMessage::from_core(message, mtu, keyed) {
                Err(EncodeError::ReportTooLarge { bytes, max_parts }) => {
                    self.count("report_too_large");
                    error_reply(format!(
                        "the answer is a report of {bytes} bytes, more than {max_parts} datagrams carry at this \
                         node's mtu of {mtu} bytes: ask for less (one port: `why`), or give this node a larger \
                         mtu= in its URL (at most 8192)"
                    ))
                }
                Ok(parts) if matches!(parts.as_slice(), [WireMessage::Reply { .. }]) => {
                    match self.datagram_bytes(&parts[0]) {
                        Some(bytes) if bytes > mtu => {
                            self.count("too_large");
                            error_reply(format!(
                                "the answer takes {bytes} bytes, more than one datagram carries at this node's \
                                 mtu of {mtu} bytes: give both nodes a larger mtu= in their URLs (at most 8192)"
                            ))
                        }
                        _ => Ok(parts),
                    }
                }
                other => other,
            };
            match parts {
                Ok(mut parts) => {
                    if let (Destination::Node(n), Some(too_big)) = (to, self.oversized_request(&parts)) {
                        let Message::Control(c) = message else { unreachable!("requests are control messages") };
                        self.count("too_large");
                        self.events.push(TransportEvent::RequestFailed { to: *n, id: c.id, why: too_big });
                        self.route_buf = addrs;
                        return Sent::Dropped;
                    }
                    if let Destination::Node(n) = to {
                        if !self.may_answer(*n, &parts) {
                            self.route_buf = addrs;
                            return Sent::Dropped;
                        }
                        self.sign(*n, &mut parts);
                    }
                    for &addr in &addrs {
                        for m in &parts {
                            self.push(addr, m);
                        }
                    }
                    self.unflushed += 1;
                }
                Err(_) => {
                    self.count("unencodable");
                    sent = Sent::Dropped;
                }
            }
        }
        self.route_buf = addrs;
        sent
    }

    /// The bytes of a datagram holding `m` alone (header and MAC included); `None` if it
    /// cannot be encoded at all (counted `unencodable` when pushed).
    fn datagram_bytes(&self, m: &WireMessage) -> Option<usize> {
        let auth = if self.config.key.is_some() { ayllu_wire::MAC_LEN } else { 0 };
        Some(ayllu_wire::HEADER_LEN + auth + ayllu_wire::encoded_len(m).ok()?)
    }

    /// Why the request among `parts` cannot leave, if it is larger than one datagram at this
    /// node's MTU (the wire has no fragments for requests: a PREPARE of many changes must fit).
    fn oversized_request(&self, parts: &[WireMessage]) -> Option<String> {
        parts.iter().find_map(|m| {
            let WireMessage::Request { body, .. } = m else { return None };
            // A signature may be added after this check: count its room.
            let signature =
                if self.config.operator_secret.is_some() { 1 + ayllu_wire::operator::SIGNATURE_LEN } else { 0 };
            let bytes = self.datagram_bytes(m)? + signature;
            (bytes > self.config.mtu).then(|| {
                let hint = match body {
                    ControlBody::Prepare { changes, .. } => format!(
                        " ({} changes): split the plan into smaller transactions, or give the nodes a larger mtu= in \
                         their URLs (at most 8192)",
                        changes.len()
                    ),
                    _ => ": give both nodes a larger mtu= in their URLs (at most 8192)".to_owned(),
                };
                format!(
                    "the request takes {bytes} bytes, more than one datagram carries at mtu {}{hint}",
                    self.config.mtu
                )
            })
        })
    }

    /// Whether an answer made of `parts` may go to node `n` now (spec "Return routability"):
    /// always to a proven address; to an unproven one only within its budget, charged. When it
    /// may not, a CHALLENGE goes instead (if the budget allows even that) and the requester's
    /// retry, after its ECHO, is answered from the core's memory.
    fn may_answer(&mut self, n: NodeId, parts: &[WireMessage]) -> bool {
        if !parts.iter().any(|m| matches!(m, WireMessage::Reply { .. })) {
            return true;
        }
        let Some(addr) = self.peers.get(&n).map(|p| p.addr) else { return true };
        let auth = if self.config.key.is_some() { ayllu_wire::MAC_LEN } else { 0 };
        // An upper bound: each part in a datagram of its own.
        let per_datagram = (ayllu_wire::HEADER_LEN + auth) as u64;
        let bytes: u64 = parts.iter().map(|m| per_datagram + ayllu_wire::encoded_len(m).unwrap_or(0) as u64).sum();
        let Some(peer) = self.peers.get_mut(&n) else { return true };
        if peer.budget.spend(bytes) {
            return true;
        }
        let challenge = per_datagram + (ayllu_wire::MESSAGE_HEADER_LEN + ayllu_wire::COOKIE_LEN) as u64;
        let may_challenge = peer.budget.spend(challenge);
        self.count("amplification_limited");
        if may_challenge {
            let cookie = self.cookies.make(self.now, n, addr);
            self.push(addr, &WireMessage::Challenge { cookie });
            self.count("challenges_sent");
        }
        false
    }

    /// Sign the structure changes among `parts`, requests to node `to`, with the operator
    /// secret (`operator_secret=`), if this node holds one.
    fn sign(&mut self, to: NodeId, parts: &mut [WireMessage]) {
        let Some(secret) = &self.config.operator_secret else { return };
        for m in parts {
            if let WireMessage::Request { id, body, signature } = m {
                if ayllu_wire::operator::changes_structure(body) {
                    let request =
                        SignedRequest { team: self.config.team, requester: self.id, receiver: to, id: *id, body };
                    *signature = secret.sign(&request).ok();
                }
            }
        }
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
    fn send(&mut self, out: ayllu_core::Outgoing) -> Sent {
        self.send_message(&out.to, &out.message)
    }
    fn send_all(&mut self, outbox: &mut VecDeque<ayllu_core::Outgoing>, tally: &mut SendTally) {
        each_then_empty(outbox, |out| tally.add(self.send_message(&out.to, &out.message)));
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
            each_then_empty(&mut self.inbox, |(from, message)| deliver(*from, message));
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
            let before = self.peers.len();
            let unproven = self.unproven_lifetime();
            // Kept until the node takes them (bounded, in case nobody does).
            let events = &mut self.events;
            self.peers.retain(|id, p| {
                let alive = now < expiry(p, unproven);
                if !alive && events.len() < MAX_PEERS {
                    events.push(TransportEvent::PeerLost(*id));
                }
                alive
            });
            for _ in self.peers.len()..before {
                self.count("peer_expired");
            }
            self.next_expiry = self.peers.values().map(|p| expiry(p, unproven)).min().unwrap_or(Instant::MAX);
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
            let before = self.held.len();
            self.held.retain(|h| now < h.until);
            for _ in self.held.len()..before {
                self.count("held_expired");
            }
            next = self.held.iter().map(|h| h.until).fold(next, Instant::min);
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

#[cfg(test)]
mod tests {
    use super::*;
    use ayllu_core::{ConnectionId, ConnectionKind, Value};

    fn port(seq: u64) -> PortMessage {
        PortMessage {
            conn: ConnectionId(1),
            seq,
            behavior: "R".into(),
            port: "In".into(),
            kind: ConnectionKind::Normal,
            priority: 0,
            value: Value::Int(seq as i64),
        }
    }

    /// Port messages before any other message go straight to the inbox (a group's only to a
    /// member); from the first other message on, everything waits in `rest`, in order, so the
    /// inbox gets a datagram's messages in the order they were sent.
    #[test]
    fn inbound_keeps_the_datagrams_order() {
        let mut inbox = VecDeque::new();
        let mut rest = Vec::new();
        let joined = ["arm".to_string()];
        let mut sink =
            Inbound { inbox: &mut inbox, joined: &joined, rest: &mut rest, sender: NodeId(0), not_member: 0 };
        sink.header(&Header { sender: NodeId(9), seq: 1, authenticated: false });
        sink.port(port(1), None);
        sink.port(port(2), Some("arm".into()));
        sink.port(port(3), Some("legs".into()));
        sink.other(WireMessage::Challenge { cookie: [0; 16] });
        sink.port(port(4), None);
        sink.port(port(5), Some("legs".into()));
        assert_eq!(sink.not_member, 1, "counted once the datagram is admitted");
        let seqs: Vec<u64> = inbox
            .iter()
            .map(|(from, m)| match m {
                Message::Port(p) if *from == NodeId(9) => p.seq,
                other => panic!("{other:?}"),
            })
            .collect();
        assert_eq!(seqs, [1, 2]);
        assert_eq!(
            rest,
            [
                WireMessage::Challenge { cookie: [0; 16] },
                WireMessage::Port(port(4)),
                WireMessage::GroupPort { group: "legs".into(), message: port(5) },
            ]
        );
    }
}
