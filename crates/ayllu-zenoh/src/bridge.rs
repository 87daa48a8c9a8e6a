//! The mixed-team bridge: `udp://` nodes on one network and `zenoh://` nodes elsewhere made one
//! team (`ayllu-zenoh bridge --udp URL --zenoh URL`, docs/zenoh.md "A mixed team").
//!
//! Both transports carry the very same datagrams (spec/protocol.md), so the bridge relays
//! bytes, unchanged, keyed by the sender node id of each datagram's header. It is not a node:
//! it has no node id, holds no ports, and needs no team key (MACs travel intact, so the team
//! key works end to end through it). What it promises:
//! * **each side sees the other's nodes as its own kind**: a Zenoh-side node Z gets a *proxy*
//!   UDP socket of its own on the UDP side, and everything Z sends reaches the UDP nodes from
//!   that socket, so they learn Z at that address like any UDP peer; a UDP-side node U gets a
//!   Zenoh address of its own (`0.0.0.U:NONCE`, subscribed by the bridge, spec/zenoh.md), so the
//!   Zenoh nodes learn U there. Unicast needs no destination in the datagram: what arrives at
//!   Z's proxy socket goes to Z, what arrives on U's Zenoh key goes to U. Return routability
//!   holds as is: each node id keeps one address on the other side, and CHALLENGE/ECHO cross
//!   like any datagram;
//! * **broadcasts cross once**: what UDP nodes send to the bridge's own socket (HELLOs to it as
//!   a configured peer, HELLOs and group messages to the broadcast or discovery address) goes
//!   to the team's broadcast key; what Zenoh nodes publish there goes from the sender's proxy to
//!   the UDP URL's `peer=` addresses and its `broadcast=` and `discovery=` addresses, or, with
//!   neither, to every UDP node heard;
//! * **no loops**: a datagram from a node id known on the other side is never relayed back
//!   (counted `looped`); the bridge's own Zenoh publications never reach its subscribers;
//! * **bounded**: at most [`MAX_ROUTES`] node ids per side (then `table_full`), routes silent
//!   for [`ROUTE_TTL`] are forgotten (their proxies closed), at most [`QUEUE_LIMIT`] datagrams
//!   wait between two steps (then `overflowed`); nothing is dropped uncounted (N4);
//! * **optional filtering**: given the team key (`key=` in the UDP URL), the bridge relays only
//!   datagrams whose MAC verifies (others counted `unauthenticated` or `bad_mac`), so a forger
//!   can neither cross it nor move its routes; without it, it relays whatever has the team's
//!   header, and the nodes' own checks stay the guard.
//!
//! Threads: one receiving thread per UDP socket (the bridge's own and each proxy), and Zenoh's
//! own threads, all pushing into one bounded queue that [`Bridge::step`] drains; sends happen
//! in `step` only.

use std::collections::{BTreeMap, HashMap, VecDeque};
use std::net::{IpAddr, Ipv4Addr, SocketAddr, SocketAddrV4, UdpSocket};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use ayllu::datagram::{DatagramSocket, OsSocket};
use ayllu::{NodeId, RuntimeError, UdpConfig};
use ayllu_wire::{FLAG_AUTH, HEADER_LEN, MAC_LEN, MAGIC, MAX_DATAGRAM_LEN, VERSION};
use zenoh::pubsub::Subscriber;
use zenoh::sample::Locality;
use zenoh::{Session, Wait};

use crate::zenoh_socket::{key_for, locators_of, nonce_of, sender, zenoh_config, Publishers, BROADCAST};
use crate::zenoh_url::ZenohUrl;

/// Node ids kept per side; beyond it new ones are dropped and counted (`table_full`).
pub const MAX_ROUTES: usize = 256;
/// A route (and its proxy) not heard from for this long is forgotten: longer than any sane
/// liveness period (three HELLO periods), so only gone nodes are.
pub const ROUTE_TTL: Duration = Duration::from_secs(60);
/// Datagrams waiting between two steps; beyond it arrivals are dropped (`overflowed`).
pub const QUEUE_LIMIT: usize = 8192;
/// How often a receiving thread looks whether it should stop.
const RECV_POLL: Duration = Duration::from_millis(100);

/// A datagram waiting to be relayed.
enum Arrival {
    /// From the UDP side: on the bridge's own socket (`proxy: None`) or on Zenoh node
    /// `proxy`'s proxy socket.
    Udp { proxy: Option<NodeId>, bytes: Vec<u8>, from: SocketAddr },
    /// From the Zenoh side: on the team's broadcast key (`to: None`) or on UDP node `to`'s key.
    Zenoh { to: Option<NodeId>, bytes: Vec<u8>, from: SocketAddr },
}

/// The queue every receiving thread and Zenoh callback fills.
struct Queue {
    items: Mutex<VecDeque<Arrival>>,
    ready: Condvar,
    overflowed: AtomicU64,
    unattributed: AtomicU64,
}

impl Queue {
    fn push(&self, a: Arrival) {
        let mut items = self.items.lock().unwrap_or_else(|p| p.into_inner());
        if items.len() >= QUEUE_LIMIT {
            self.overflowed.fetch_add(1, Ordering::Relaxed);
            return;
        }
        items.push_back(a);
        self.ready.notify_one();
    }
}

/// A thread that receives on one of the bridge's sockets until told to stop; told and joined
/// when dropped (its socket's read timeout, [`RECV_POLL`], bounds how long that takes).
struct ReceivingThread {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl ReceivingThread {
    /// Run `receive` (given the stop flag to look at between reads) on a thread called `name`.
    fn spawn(name: &str, receive: impl FnOnce(&AtomicBool) + Send + 'static) -> std::io::Result<ReceivingThread> {
        let stop = Arc::new(AtomicBool::new(false));
        let halt = stop.clone();
        let thread = std::thread::Builder::new().name(name.into()).spawn(move || receive(&halt))?;
        Ok(ReceivingThread { stop, thread: Some(thread) })
    }
}

impl Drop for ReceivingThread {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// A UDP socket and the thread that receives on it, stopped and joined when dropped.
struct Receiver {
    socket: Arc<UdpSocket>,
    _thread: ReceivingThread,
}

impl Receiver {
    fn start(socket: UdpSocket, proxy: NodeId, ttl: u32, queue: Arc<Queue>) -> std::io::Result<Receiver> {
        socket.set_read_timeout(Some(RECV_POLL))?;
        socket.set_broadcast(true)?;
        // Relayed HELLOs and group messages may go to the discovery (multicast) address.
        socket.set_multicast_ttl_v4(ttl)?;
        let proxy = Some(proxy);
        let socket = Arc::new(socket);
        let s = socket.clone();
        let thread = ReceivingThread::spawn("ayllu-bridge-udp", move |halt| {
            let mut buf = vec![0u8; MAX_DATAGRAM_LEN + 1];
            while !halt.load(Ordering::Relaxed) {
                match s.recv_from(&mut buf) {
                    Ok((n, from)) => queue.push(Arrival::Udp { proxy, bytes: buf[..n].to_vec(), from }),
                    // Timeouts (to look at `halt`), and ICMP errors from earlier sends.
                    Err(_) => continue,
                }
            }
        })?;
        Ok(Receiver { socket, _thread: thread })
    }
}

/// The bridge's own UDP socket ([`OsSocket`], as a node's: it also hears the team's broadcast
/// and discovery addresses) and the thread that receives on it; stopped and joined when dropped.
struct Listener {
    addr: SocketAddr,
    _thread: ReceivingThread,
}

impl Listener {
    fn start(mut socket: OsSocket, queue: Arc<Queue>) -> std::io::Result<Listener> {
        let addr = socket.local_addr()?;
        let thread = ReceivingThread::spawn("ayllu-bridge-main", move |halt| {
            let mut buf = vec![0u8; MAX_DATAGRAM_LEN + 1];
            while !halt.load(Ordering::Relaxed) {
                socket.wait(RECV_POLL);
                while let Ok(Some((n, from))) = socket.recv_from(&mut buf) {
                    queue.push(Arrival::Udp { proxy: None, bytes: buf[..n].to_vec(), from });
                }
            }
        })?;
        Ok(Listener { addr, _thread: thread })
    }
}

/// A node heard on the Zenoh side, as the UDP side sees it.
struct ZenohNode {
    /// Where it is on Zenoh (`0.0.0.Z:NONCE`).
    addr: SocketAddr,
    /// Its proxy on the UDP side.
    proxy: Receiver,
    last_heard: Instant,
}

/// A node heard on the UDP side, as the Zenoh side sees it.
struct UdpNode {
    /// Where it is on the UDP network.
    addr: SocketAddr,
    /// Its address on Zenoh, as an attachment (spec/zenoh.md).
    attachment: [u8; 6],
    /// Kept alive: dropping it undeclares U's Zenoh key.
    _subscriber: Subscriber<()>,
    last_heard: Instant,
}

/// What a datagram's header says, once it is the team's.
struct Header {
    sender: NodeId,
}

/// The bridge (module docs).
pub struct Bridge {
    team: u32,
    key: Option<[u8; 32]>,
    session: Session,
    nonce: u16,
    main: Listener,
    bind_ip: IpAddr,
    ttl: u32,
    /// The UDP side's broadcast and discovery addresses: where Zenoh nodes' broadcasts go.
    broadcast: Vec<SocketAddr>,
    peers: Vec<SocketAddr>,
    zenoh_nodes: HashMap<NodeId, ZenohNode>,
    udp_nodes: HashMap<NodeId, UdpNode>,
    publishers: Publishers,
    /// Kept alive: the team's broadcast key.
    _broadcast: Subscriber<()>,
    queue: Arc<Queue>,
    counts: BTreeMap<&'static str, u64>,
    next_expiry: Instant,
    scratch: Vec<SocketAddr>,
}

fn fail(what: &str, e: impl std::fmt::Display) -> RuntimeError {
    RuntimeError::Io { what: what.to_owned(), error: e.to_string() }
}

impl Bridge {
    /// Bind the UDP side as `udp_url` says (its address, `team=`, `peer=`, `broadcast=`, and
    /// optionally `key=`) and join Zenoh as `zenoh_url` says (`mode`, `connect`, `listen`,
    /// `scouting`, `config`; its `team=` must be the UDP URL's, when both give one).
    /// `discovery=` (a multicast address, as in the default URL) is heard and relayed to like
    /// `broadcast=`; `group=` (a group's own multicast address) is refused (docs/zenoh.md).
    pub fn open(udp_url: &str, zenoh_url: &str) -> Result<Bridge, RuntimeError> {
        let udp = UdpConfig::parse(udp_url)?;
        let zenoh = ZenohUrl::parse(zenoh_url)?;
        let bad = |reason: String| RuntimeError::BadUrl { url: udp_url.to_owned(), reason };
        if !udp.groups.is_empty() {
            return Err(bad("the bridge takes peer=, broadcast= and discovery= on its UDP side, not group= \
                            (a group's own multicast address): let the UDP nodes send groups to their \
                            broadcast or to each member"
                .into()));
        }
        let has_team = |url: &str| ayllu::transport::url_setting(url, "team").is_some();
        let team = match (has_team(udp_url), has_team(zenoh_url)) {
            (true, true) if udp.team != zenoh.config.team => {
                return Err(bad(format!(
                    "the UDP side's team={} is not the Zenoh side's team={}: a bridge joins one team",
                    udp.team, zenoh.config.team
                )))
            }
            (false, true) => zenoh.config.team,
            _ => udp.team,
        };
        let queue = Arc::new(Queue {
            items: Mutex::new(VecDeque::new()),
            ready: Condvar::new(),
            overflowed: AtomicU64::new(0),
            unattributed: AtomicU64::new(0),
        });
        // The bridge's own socket, set up as a node's (the udp:// transport's rules): it also
        // hears the broadcast and discovery addresses, joining the discovery group.
        let mut socket = OsSocket::bind(udp.bind).map_err(|e| fail(&format!("binding {}", udp.bind), e))?;
        let heard: Vec<SocketAddr> = udp.broadcast.iter().chain(udp.discovery.iter()).copied().collect();
        for addr in &heard {
            socket.listen_also(*addr).map_err(|e| fail(&format!("listening on {addr}"), e))?;
        }
        if let Some(SocketAddr::V4(d)) = udp.discovery {
            socket.join_multicast(*d.ip()).map_err(|e| fail(&format!("joining {d}"), e))?;
        }
        let main = Listener::start(socket, queue.clone()).map_err(|e| fail("the bridge's UDP socket", e))?;
        let config = zenoh_config(&zenoh).map_err(|e| fail("configuring Zenoh", e))?;
        let session = zenoh::open(config).wait().map_err(|e| fail("opening the Zenoh session", e))?;
        let nonce = nonce_of(&session);
        let q = queue.clone();
        let broadcast_key = key_for(team, BROADCAST);
        let subscriber = session
            .declare_subscriber(broadcast_key.clone())
            .allowed_origin(Locality::Remote)
            .callback(move |sample| match sample.attachment().and_then(|a| sender(&a.to_bytes())) {
                Some(from) => {
                    q.push(Arrival::Zenoh { to: None, bytes: sample.payload().to_bytes().into_owned(), from })
                }
                None => {
                    q.unattributed.fetch_add(1, Ordering::Relaxed);
                }
            })
            .wait()
            .map_err(|e| fail(&format!("subscribing to {broadcast_key}"), e))?;
        Ok(Bridge {
            team,
            key: udp.key,
            session,
            nonce,
            main,
            bind_ip: udp.bind.ip(),
            ttl: udp.ttl,
            broadcast: heard,
            peers: udp.peers,
            zenoh_nodes: HashMap::new(),
            udp_nodes: HashMap::new(),
            publishers: Publishers::new(2 * MAX_ROUTES),
            _broadcast: subscriber,
            queue,
            counts: BTreeMap::new(),
            next_expiry: Instant::now() + ROUTE_TTL,
            scratch: Vec::new(),
        })
    }

    /// Where the bridge listens on the UDP side (give it to the UDP nodes as `peer=`).
    pub fn udp_address(&self) -> SocketAddr {
        self.main.addr
    }

    /// Where the bridge listens on the Zenoh side, as bound (give them to the Zenoh nodes as
    /// `connect=`): its session's locators, `listen=tcp/127.0.0.1:0` resolved to the port the
    /// system chose ([`crate::zenoh_socket::locators_of`]); empty without `listen=`.
    pub fn zenoh_locators(&self) -> Vec<String> {
        locators_of(&self.session)
    }

    /// The Zenoh session (its id, for diagnostics).
    pub fn session(&self) -> &Session {
        &self.session
    }

    /// The node ids heard on the UDP side, in order.
    pub fn udp_nodes(&self) -> Vec<NodeId> {
        let mut v: Vec<NodeId> = self.udp_nodes.keys().copied().collect();
        v.sort();
        v
    }

    /// The node ids heard on the Zenoh side, in order.
    pub fn zenoh_nodes(&self) -> Vec<NodeId> {
        let mut v: Vec<NodeId> = self.zenoh_nodes.keys().copied().collect();
        v.sort();
        v
    }

    /// The address a Zenoh-side node has on the UDP side (its proxy), if it was heard.
    pub fn proxy_address(&self, node: NodeId) -> Option<SocketAddr> {
        self.zenoh_nodes.get(&node).and_then(|z| z.proxy.socket.local_addr().ok())
    }

    /// Counts by cause: `to_zenoh`, `to_udp` (datagrams relayed), and every drop (`looped`,
    /// `wrong_team`, `malformed`, `unauthenticated`, `bad_mac`, `no_route`, `table_full`,
    /// `send_failed`, `overflowed`, `unattributed`), each once not zero.
    pub fn counts(&self) -> Vec<(String, u64)> {
        let mut all: BTreeMap<&str, u64> = self.counts.clone();
        for (name, n) in [
            ("overflowed", self.queue.overflowed.load(Ordering::Relaxed)),
            ("unattributed", self.queue.unattributed.load(Ordering::Relaxed)),
        ] {
            if n > 0 {
                all.insert(name, n);
            }
        }
        all.into_iter().map(|(k, v)| (k.to_owned(), v)).collect()
    }

    fn count(&mut self, cause: &'static str) {
        *self.counts.entry(cause).or_insert(0) += 1;
    }

    /// Relay what has arrived, waiting at most `timeout` for something to arrive first.
    /// Returns how many datagrams were handled (relayed or dropped).
    pub fn step(&mut self, timeout: Duration) -> usize {
        let batch: Vec<Arrival> = {
            let mut items = self.queue.items.lock().unwrap_or_else(|p| p.into_inner());
            if items.is_empty() {
                items = self.queue.ready.wait_timeout(items, timeout).unwrap_or_else(|p| p.into_inner()).0;
            }
            items.drain(..).collect()
        };
        let handled = batch.len();
        for a in batch {
            match a {
                Arrival::Udp { proxy, bytes, from } => self.relay_udp(proxy, &bytes, from),
                Arrival::Zenoh { to, bytes, from } => self.relay_zenoh(to, &bytes, from),
            }
        }
        let now = Instant::now();
        if now >= self.next_expiry {
            self.next_expiry = now + ROUTE_TTL / 4;
            self.zenoh_nodes.retain(|_, z| now.duration_since(z.last_heard) < ROUTE_TTL);
            self.udp_nodes.retain(|_, u| now.duration_since(u.last_heard) < ROUTE_TTL);
        }
        handled
    }

    /// Run until `until` (or for ever), relaying.
    pub fn run_until(&mut self, until: Option<Instant>, mut keep_going: impl FnMut(&Bridge) -> bool) {
        while until.is_none_or(|u| Instant::now() < u) && keep_going(self) {
            let slice = until.map_or(RECV_POLL, |u| RECV_POLL.min(u.saturating_duration_since(Instant::now())));
            self.step(slice);
        }
    }

    /// The team's header, checked as far as the bridge needs (and the MAC, with the key).
    fn check(&mut self, bytes: &[u8]) -> Option<Header> {
        if bytes.len() < HEADER_LEN || bytes[..2] != MAGIC || bytes[2] != VERSION {
            self.count("malformed");
            return None;
        }
        let word = |at: usize| u32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]]);
        if word(4) != self.team {
            self.count("wrong_team");
            return None;
        }
        if let Some(key) = &self.key {
            if bytes[3] & FLAG_AUTH == 0 || bytes.len() < HEADER_LEN + MAC_LEN {
                self.count("unauthenticated");
                return None;
            }
            let (data, tag) = bytes.split_at(bytes.len() - MAC_LEN);
            if !ayllu_wire::verify_mac(key, data, tag) {
                self.count("bad_mac");
                return None;
            }
        }
        Some(Header { sender: NodeId(word(8)) })
    }

    fn relay_udp(&mut self, proxy: Option<NodeId>, bytes: &[u8], from: SocketAddr) {
        let Some(header) = self.check(bytes) else { return };
        let u = header.sender;
        if self.zenoh_nodes.contains_key(&u) {
            // Our own relay of a Zenoh node (a broadcast heard back), or a node id used on both
            // sides: never sent back where it came from.
            return self.count("looped");
        }
        let now = Instant::now();
        if !self.udp_nodes.contains_key(&u) {
            if self.udp_nodes.len() >= MAX_ROUTES {
                return self.count("table_full");
            }
            match self.zenoh_identity(u) {
                Ok(node) => {
                    self.udp_nodes.insert(u, node);
                }
                Err(_) => return self.count("send_failed"),
            }
        }
        let node = self.udp_nodes.get_mut(&u).expect("inserted above");
        node.addr = from;
        node.last_heard = now;
        let attachment = node.attachment;
        let to = match proxy {
            None => BROADCAST,
            Some(z) => match self.zenoh_nodes.get(&z) {
                Some(z) => z.addr,
                None => return self.count("no_route"),
            },
        };
        match self.publishers.put(&self.session, self.team, to, bytes, &attachment) {
            Ok(()) => self.count("to_zenoh"),
            Err(_) => self.count("send_failed"),
        }
    }

    /// UDP node `u`'s Zenoh address: its key subscribed before anything of it is relayed, so
    /// that answers to its first datagram find it.
    fn zenoh_identity(&self, u: NodeId) -> Result<UdpNode, RuntimeError> {
        let addr = SocketAddr::V4(SocketAddrV4::new(Ipv4Addr::from(u.0), self.nonce));
        let mut attachment = [0u8; 6];
        attachment[..4].copy_from_slice(&u.0.to_be_bytes());
        attachment[4..].copy_from_slice(&self.nonce.to_be_bytes());
        let key = key_for(self.team, addr);
        let q = self.queue.clone();
        let subscriber = self
            .session
            .declare_subscriber(key.clone())
            .allowed_origin(Locality::Remote)
            .callback(move |sample| match sample.attachment().and_then(|a| sender(&a.to_bytes())) {
                Some(from) => {
                    q.push(Arrival::Zenoh { to: Some(u), bytes: sample.payload().to_bytes().into_owned(), from })
                }
                None => {
                    q.unattributed.fetch_add(1, Ordering::Relaxed);
                }
            })
            .wait()
            .map_err(|e| fail(&format!("subscribing to {key}"), e))?;
        Ok(UdpNode { addr, attachment, _subscriber: subscriber, last_heard: Instant::now() })
    }

    fn relay_zenoh(&mut self, to: Option<NodeId>, bytes: &[u8], from: SocketAddr) {
        let Some(header) = self.check(bytes) else { return };
        let z = header.sender;
        if from.ip() != IpAddr::V4(Ipv4Addr::from(z.0)) {
            // The attachment names another node than the header: not a node's own datagram.
            return self.count("malformed");
        }
        if self.udp_nodes.contains_key(&z) {
            return self.count("looped");
        }
        let now = Instant::now();
        if !self.zenoh_nodes.contains_key(&z) {
            if self.zenoh_nodes.len() >= MAX_ROUTES {
                return self.count("table_full");
            }
            let proxy = UdpSocket::bind(SocketAddr::new(self.bind_ip, 0))
                .and_then(|s| Receiver::start(s, z, self.ttl, self.queue.clone()));
            match proxy {
                Ok(proxy) => {
                    self.zenoh_nodes.insert(z, ZenohNode { addr: from, proxy, last_heard: now });
                }
                Err(_) => return self.count("send_failed"),
            }
        }
        let node = self.zenoh_nodes.get_mut(&z).expect("inserted above");
        node.addr = from;
        node.last_heard = now;
        let mut targets = std::mem::take(&mut self.scratch);
        targets.clear();
        match to {
            Some(u) => match self.udp_nodes.get(&u) {
                Some(u) => targets.push(u.addr),
                None => {
                    self.scratch = targets;
                    return self.count("no_route");
                }
            },
            None => {
                targets.extend(self.peers.iter().copied());
                if self.broadcast.is_empty() {
                    targets.extend(self.udp_nodes.values().map(|u| u.addr));
                } else {
                    targets.extend(self.broadcast.iter().copied());
                }
                targets.sort();
                targets.dedup();
            }
        }
        let socket = self.zenoh_nodes[&z].proxy.socket.clone();
        for t in &targets {
            match socket.send_to(bytes, t) {
                Ok(_) => self.count("to_udp"),
                Err(_) => self.count("send_failed"),
            }
        }
        self.scratch = targets;
    }
}

/// `ayllu-zenoh bridge`'s usage.
pub const USAGE: &str = "usage: ayllu-zenoh bridge --udp URL --zenoh URL [--for SECONDS] [--status-ms MS]\n  e.g. \
                         ayllu-zenoh bridge --udp 'udp://0.0.0.0:7400?team=7&broadcast=10.0.0.255:7400' \\\n         \
                         --zenoh 'zenoh://?mode=client&connect=tcp/203.0.113.5:7447&team=7'";

/// `ayllu-zenoh bridge ARGS`: start a bridge, print one JSON line
/// `{"bridge":ZID,"udp":"ADDR:PORT","zenoh":[LOCATOR,..],"team":N}` (the UDP address and the
/// Zenoh side's listening locators as bound: port 0 resolved),
/// then a status line every `--status-ms` (`{"t":..,"udp_nodes":[..],"zenoh_nodes":[..],
/// "counts":{..}}`), until killed or `--for` seconds have passed. Returns the exit status (2:
/// usage, 1: the bridge failed).
pub fn bridge_main(args: &[String]) -> std::process::ExitCode {
    let usage = |why: &str| {
        eprintln!("ayllu-zenoh bridge: {why}\n{USAGE}");
        std::process::ExitCode::from(2)
    };
    let (mut udp, mut zenoh, mut run_for, mut status_ms) = (None, None, None, 1000u64);
    let mut it = args.iter();
    while let Some(flag) = it.next() {
        if flag == "-h" || flag == "--help" {
            println!("{USAGE}");
            return std::process::ExitCode::SUCCESS;
        }
        let Some(value) = it.next() else { return usage(&format!("{flag} needs a value")) };
        match flag.as_str() {
            "--udp" => udp = Some(value.clone()),
            "--zenoh" => zenoh = Some(value.clone()),
            "--for" => match crate::router::seconds(value) {
                Some(d) => run_for = Some(d),
                None => return usage(&format!("--for takes seconds, got `{value}`")),
            },
            "--status-ms" => match value.parse::<u64>() {
                Ok(ms) if ms > 0 => status_ms = ms,
                _ => return usage(&format!("--status-ms takes a positive number, got `{value}`")),
            },
            _ => return usage(&format!("unknown argument `{flag}`")),
        }
    }
    let (Some(udp), Some(zenoh)) = (udp, zenoh) else { return usage("--udp and --zenoh are both needed") };
    let mut bridge = match Bridge::open(&udp, &zenoh) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("ayllu-zenoh bridge: {e}");
            return std::process::ExitCode::from(1);
        }
    };
    let started = Instant::now();
    println!(
        "{}",
        serde_json::json!({"bridge": bridge.session().zid().to_string(), "udp": bridge.udp_address().to_string(),
                           "zenoh": bridge.zenoh_locators(), "team": bridge.team})
    );
    let end = run_for.map(|d| started + d);
    let period = Duration::from_millis(status_ms);
    let mut next_status = started + period;
    while end.is_none_or(|e| Instant::now() < e) {
        let until = end.map_or(next_status, |e| e.min(next_status));
        bridge.run_until(Some(until), |_| true);
        if Instant::now() >= next_status {
            next_status += period;
            let counts: serde_json::Map<String, serde_json::Value> =
                bridge.counts().into_iter().map(|(k, v)| (k, v.into())).collect();
            let line = serde_json::json!({
                "t": (started.elapsed().as_secs_f64() * 1000.0).round() / 1000.0,
                "udp_nodes": bridge.udp_nodes().iter().map(|n| n.0).collect::<Vec<_>>(),
                "zenoh_nodes": bridge.zenoh_nodes().iter().map(|n| n.0).collect::<Vec<_>>(),
                "counts": counts,
            });
            use std::io::Write as _;
            let mut out = std::io::stdout().lock();
            if writeln!(out, "{line}").and_then(|_| out.flush()).is_err() {
                break;
            }
        }
    }
    std::process::ExitCode::SUCCESS
}
