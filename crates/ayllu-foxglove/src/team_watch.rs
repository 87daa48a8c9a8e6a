//! Watching a live team from the outside: a small node of its own on the team's network asks
//! every node it hears what its ports hold (LIST) and what windows are open on them (WHY),
//! and hands the answers to a [`TeamBridge`].
//!
//! The strategy, and what it misses (docs/cli.md, "ayllu foxglove"):
//! * every `1 / list_hz` seconds (default 5 Hz) each node heard is sent one LIST, unless its
//!   previous one is unanswered: one answer carries every port's value, so port topics are
//!   samples at that rate — a value that lives shorter than a period may never be seen (an
//!   `ayllu record` of the network sees every message a connection sends instead);
//! * WHY, one request per port, is spent within a budget of `why_hz` requests per node per
//!   second (default 20), first where windows are: ports that are the destination of a
//!   windowed connection any LIST shows (suppress, inhibit, override, write-inhibit, which
//!   includes every BLE claim's target), ports a WHY found a window on, and every BLE member's
//!   `Inhibit` port (its last write is the member's last claim); these are asked every period
//!   while they fit in three quarters of the budget, else in turn. The rest of the budget
//!   (at least one request a period) sweeps all the other ports round-robin, so a window
//!   opened by a node the watcher cannot LIST (a tool that has exited, an AylluLite node) is
//!   found within one sweep (ports / (a quarter of `why_hz`) seconds at worst);
//! * a node answers at most 50 requests a second from one sender (its `Limits`, burst 100):
//!   `list_hz + why_hz` must stay below that, which [`WatchConfig::check`] enforces;
//! * the watcher forgets each request once its answer is read (`NodeCore::take_answer`, how
//!   every asker collects) or it is given up (`NodeCore::forget_request`), so its node holds only the requests in flight; the core
//!   would also forget the oldest finished ones by itself past 1,024. Replacing the watcher's
//!   node every `renew_after` requests is kept as an option (off by default) for a test that a
//!   watch survives losing its node's state.

use std::collections::{BTreeMap, BTreeSet};
use std::time::{Duration as StdDuration, Instant as StdInstant, SystemTime, UNIX_EPOCH};

use ayllu::{MonotonicClock, Node, Transport, UdpConfig, UdpTransport};
use ayllu_core::{ConnectionKind, ControlBody, Endpoint, NodeId, NodeReport, ReplyBody, RequestId};

use crate::team_bridge::{is_ble_member, published_ports, LayerClaims, TeamBridge};

/// Requests sent by one watcher node before it is replaced, by default: 0, never (see the
/// module docs; requests are forgotten as they are read, so nothing grows).
pub const RENEW_AFTER: u64 = 0;
/// A request unanswered this long is forgotten (the node gives up after 25 sends, 5 s).
const GIVE_UP: StdDuration = StdDuration::from_secs(6);
/// The most requests a second a node answers from one sender by default (`Limits`).
pub const NODE_REQUEST_LIMIT: f64 = 50.0;

/// How a [`TeamWatch`] asks.
#[derive(Clone, Debug)]
pub struct WatchConfig {
    /// The watcher's udp:// URL (bind address, team, key, discovery=, peer=, ...), or a URL of
    /// another scheme `ayllu::transport::open` knows (`zenoh://` once registered).
    pub url: String,
    /// The watcher's node id.
    pub id: NodeId,
    /// LIST rate per node (Hz).
    pub list_hz: f64,
    /// WHY budget per node per second.
    pub why_hz: f64,
    /// Requests sent by one watcher node before it is replaced; 0 never ([`RENEW_AFTER`]).
    pub renew_after: u64,
}

impl WatchConfig {
    /// Refuses rates that are not positive and finite, and rates a node would throttle.
    pub fn check(&self) -> Result<(), String> {
        for (name, x) in [("list rate", self.list_hz), ("WHY rate", self.why_hz)] {
            if !x.is_finite() || x <= 0.0 {
                return Err(format!("the {name} must be a positive number of hertz (got {x})"));
            }
        }
        if self.list_hz > 20.0 {
            return Err(format!("--hz {} is above 20: one LIST answer is a whole node", self.list_hz));
        }
        if self.list_hz + self.why_hz >= NODE_REQUEST_LIMIT {
            return Err(format!(
                "--hz {} plus --why-hz {} reach the {NODE_REQUEST_LIMIT} requests a second a node answers one sender",
                self.list_hz, self.why_hz
            ));
        }
        Ok(())
    }
}

/// What a request asked.
#[derive(Clone, Debug, PartialEq, Eq)]
enum Asked {
    List(NodeId),
    Why(NodeId, String, String),
}

struct Pending {
    id: RequestId,
    asked: Asked,
    sent: StdInstant,
}

/// A BLE member as a LIST shows it.
#[derive(Clone, Debug)]
struct Member {
    group: Option<String>,
    /// Its claims' write-inhibition period: a claim holds this long after `Inhibit` is written.
    inhibit_period: Option<ayllu_core::Duration>,
    claiming: Option<bool>,
}

#[derive(Default)]
struct Watched {
    report: Option<NodeReport>,
    /// Every port, for the sweep.
    ports: Vec<(String, String)>,
    sweep: usize,
    /// Where the watched ports' turn starts, when they are more than the budget.
    turn: usize,
    /// Ports a WHY found windows on.
    windowed: BTreeSet<(String, String)>,
    members: BTreeMap<String, Member>,
    /// WHY not yet spent this period (fractions carry over).
    credit: f64,
}

/// Counts for status lines.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct WatchCounts {
    /// Requests sent.
    pub requests: u64,
    /// Answers received.
    pub answers: u64,
    /// Requests refused or never answered.
    pub failed: u64,
    /// Times the watcher's node was replaced.
    pub renewals: u64,
}

/// A watcher of a live team.
pub struct TeamWatch {
    config: WatchConfig,
    /// The parsed URL when it is `udp://` (the only scheme whose peers have addresses to greet).
    udp: Option<UdpConfig>,
    node: Node,
    nodes: BTreeMap<NodeId, Watched>,
    pending: Vec<Pending>,
    since_renewal: u64,
    next_cycle: StdInstant,
    counts: WatchCounts,
}

/// The watcher's node name unless its URL names it.
const WATCHER_NAME: &str = "ayllu-foxglove";

/// The watcher's transport: `udp` (parsed from the URL, perhaps with peers added) when the
/// scheme is `udp://`, else whatever `ayllu::transport::open` makes of the URL.
fn open_transport(config: &WatchConfig, udp: Option<&UdpConfig>) -> Result<Box<dyn Transport>, ayllu::RuntimeError> {
    match udp {
        Some(udp) => Ok(Box::new(UdpTransport::bind(config.id, udp.clone())?)),
        None => ayllu::transport::open_named(&config.url, config.id, WATCHER_NAME),
    }
}

fn unix_nanos() -> u64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| d.as_nanos() as u64)
}

impl TeamWatch {
    /// Join the team's network as `config.url` says.
    pub fn open(config: WatchConfig) -> Result<TeamWatch, ayllu::RuntimeError> {
        // udp:// is parsed here, for the renewal's greeting of known addresses; any other
        // scheme ayllu::transport::open knows (zenoh:// once registered) is reopened from its
        // URL, its own discovery finding the team again.
        let udp = if config.url.starts_with("udp://") {
            let mut udp = UdpConfig::parse(&config.url)?;
            if udp.name.is_empty() {
                udp.name = WATCHER_NAME.to_owned();
            }
            Some(udp)
        } else {
            None
        };
        let node = Node::new(MonotonicClock::new(), open_transport(&config, udp.as_ref())?);
        Ok(TeamWatch {
            config,
            udp,
            node,
            nodes: BTreeMap::new(),
            pending: Vec::new(),
            since_renewal: 0,
            next_cycle: StdInstant::now(),
            counts: WatchCounts::default(),
        })
    }

    /// The watcher's own udp address.
    pub fn address(&self) -> Option<String> {
        self.node.address()
    }

    /// The nodes heard so far.
    pub fn nodes(&self) -> Vec<NodeId> {
        self.nodes.keys().copied().collect()
    }

    /// Counts so far.
    pub fn counts(&self) -> WatchCounts {
        self.counts.clone()
    }

    /// Run for `slice`: send what is due, publish what has been answered.
    pub fn run_for(&mut self, bridge: &mut TeamBridge, slice: StdDuration) {
        let end = StdInstant::now() + slice;
        loop {
            let now = StdInstant::now();
            if now >= self.next_cycle {
                self.cycle(bridge);
                let period = StdDuration::from_secs_f64(1.0 / self.config.list_hz);
                self.next_cycle = (self.next_cycle + period).max(now);
            }
            let wake = self.next_cycle.min(end);
            self.node.run_for(wake.saturating_duration_since(StdInstant::now()).min(StdDuration::from_millis(10)));
            self.collect(bridge);
            if StdInstant::now() >= end {
                return;
            }
        }
    }

    fn ask(&mut self, asked: Asked) {
        let (to, body) = match &asked {
            Asked::List(n) => (*n, ControlBody::List),
            Asked::Why(n, b, p) => (*n, ControlBody::Why { behavior: b.as_str().into(), port: p.as_str().into() }),
        };
        if self.pending.iter().any(|p| p.asked == asked) {
            return;
        }
        if let Ok(id) = self.node.core_mut().request(to, body) {
            self.pending.push(Pending { id, asked, sent: StdInstant::now() });
            self.counts.requests += 1;
            self.since_renewal += 1;
        }
    }

    /// One period: LIST every node heard, WHY the watched ports and the sweep's next ones.
    fn cycle(&mut self, bridge: &mut TeamBridge) {
        if self.config.renew_after > 0 && self.since_renewal >= self.config.renew_after {
            self.renew();
        }
        for peer in self.node.peers() {
            self.nodes.entry(peer.node).or_default();
        }
        let targets = self.window_targets();
        let per_cycle = self.config.why_hz / self.config.list_hz;
        let ids: Vec<NodeId> = self.nodes.keys().copied().collect();
        for n in ids {
            self.ask(Asked::List(n));
            let w = self.nodes.get_mut(&n).expect("listed");
            w.credit = (w.credit + per_cycle).min(per_cycle * 2.0);
            let add = |b: &str, p: &str, list: &mut Vec<(String, String)>| {
                if !list.iter().any(|(x, y)| x == b && y == p) {
                    list.push((b.to_owned(), p.to_owned()));
                }
            };
            let mut watched: Vec<(String, String)> = Vec::new();
            for (b, p) in targets.get(&n).into_iter().flatten() {
                add(b, p, &mut watched);
            }
            for (b, p) in &w.windowed {
                add(b, p, &mut watched);
            }
            for b in w.members.keys() {
                add(b, ayllu_core::INHIBIT, &mut watched);
            }
            // The budget is whole requests; watched ports first (in turn when they are more
            // than the budget), but a quarter (at least one) is kept for the sweep, so that a
            // window no LIST explains is still found; the sweep also gets what they leave.
            let budget = w.credit.floor().max(0.0) as usize;
            let for_watched = if w.ports.is_empty() { budget } else { budget - (budget / 4).max(1).min(budget) };
            let mut asks: Vec<(String, String)> = Vec::new();
            let watched_len = watched.len();
            let taken = watched_len.min(for_watched);
            for k in 0..taken {
                let (b, p) = &watched[(w.turn + k) % watched_len];
                add(b, p, &mut asks);
            }
            if watched_len > 0 {
                w.turn = (w.turn + taken) % watched_len;
            }
            let spare = budget.saturating_sub(asks.len()).min(w.ports.len());
            for _ in 0..spare {
                let (b, p) = w.ports[w.sweep % w.ports.len()].clone();
                w.sweep = (w.sweep + 1) % w.ports.len();
                add(&b, &p, &mut asks);
            }
            w.credit = (w.credit - asks.len() as f64).max(0.0);
            for (b, p) in asks {
                self.ask(Asked::Why(n, b, p));
            }
        }
        self.publish_claims(bridge);
    }

    /// The ports of each node that a windowed connection (any LIST shows) points at.
    fn window_targets(&self) -> BTreeMap<NodeId, Vec<(String, String)>> {
        let mut out: BTreeMap<NodeId, Vec<(String, String)>> = BTreeMap::new();
        for (owner, w) in &self.nodes {
            let Some(report) = &w.report else { continue };
            for c in &report.connections {
                if c.kind == ConnectionKind::Normal {
                    continue;
                }
                match &c.destination {
                    Endpoint::Local { behavior, port } => {
                        out.entry(*owner).or_default().push((behavior.to_string(), port.to_string()))
                    }
                    Endpoint::Node { node, behavior, port } => {
                        out.entry(*node).or_default().push((behavior.to_string(), port.to_string()))
                    }
                    Endpoint::Group { group, behavior, port } => {
                        // Every node that joined the group (its own LIST says so), the sender
                        // excepted: a group broadcast does not come back to it.
                        for (member, mw) in &self.nodes {
                            let joined = mw.report.as_ref().is_some_and(|r| r.groups.iter().any(|g| g == &**group));
                            if joined && member != owner {
                                out.entry(*member).or_default().push((behavior.to_string(), port.to_string()));
                            }
                        }
                    }
                }
            }
        }
        out
    }

    /// Publish what has been answered; forget what will not be.
    fn collect(&mut self, bridge: &mut TeamBridge) {
        let now = StdInstant::now();
        let mut keep = Vec::with_capacity(self.pending.len());
        for p in std::mem::take(&mut self.pending) {
            match self.node.core_mut().take_answer(p.id) {
                Some(Ok(body)) => {
                    self.counts.answers += 1;
                    self.answered(bridge, &p.asked, body);
                }
                Some(Err(_)) => self.counts.failed += 1,
                None if self.node.core().request_status(p.id).is_some() && now.duration_since(p.sent) <= GIVE_UP => {
                    keep.push(p)
                }
                // Unanswered past the give-up, or forgotten: not retried any more.
                None => {
                    self.node.core_mut().forget_request(p.id);
                    self.counts.failed += 1;
                }
            }
        }
        self.pending = keep;
    }

    fn answered(&mut self, bridge: &mut TeamBridge, asked: &Asked, body: ReplyBody) {
        let t = unix_nanos();
        match (asked, body) {
            (Asked::List(n), ReplyBody::Node(report)) => {
                bridge.node_report(&report, t);
                let w = self.nodes.entry(*n).or_default();
                w.ports = report
                    .behaviors
                    .iter()
                    .flat_map(|b| published_ports(b).map(|p| (b.name.clone(), p.name.clone())))
                    .collect();
                let mut members = BTreeMap::new();
                for b in report.behaviors.iter().filter(|b| is_ble_member(b)) {
                    // The member's claim connection: its Inhibit port, write-inhibiting the group.
                    let claim = report.connections.iter().find(|c| {
                        matches!(&c.source, Endpoint::Local { behavior, port } if **behavior == *b.name && &**port == ayllu_core::INHIBIT)
                            && matches!(c.kind, ConnectionKind::WriteInhibit(_))
                    });
                    let group = claim.and_then(|c| match &c.destination {
                        Endpoint::Group { group, .. } => Some(group.to_string()),
                        _ => None,
                    });
                    let claiming = w.members.get(&b.name).and_then(|m| m.claiming);
                    members.insert(
                        b.name.clone(),
                        Member { group, inhibit_period: claim.and_then(|c| c.kind.period()), claiming },
                    );
                }
                w.members = members;
                w.report = Some(*report);
            }
            (Asked::Why(n, b, p), ReplyBody::Port(report)) => {
                bridge.port_windows(&report, t);
                let w = self.nodes.entry(*n).or_default();
                let key = (b.clone(), p.clone());
                if report.windows.is_empty() {
                    w.windowed.remove(&key);
                } else {
                    w.windowed.insert(key);
                }
                if p == ayllu_core::INHIBIT {
                    if let Some(m) = w.members.get_mut(b) {
                        // A claim holds for the inhibit period after it was written (S11).
                        m.claiming = Some(match (report.last_accepted, m.inhibit_period) {
                            (Some(at), Some(period)) => report.now < at + period,
                            _ => false,
                        });
                    }
                }
            }
            // An AylluLite node answers LIST with a report of its own shape, and refuses WHY:
            // nothing to publish.
            _ => {}
        }
    }

    fn publish_claims(&mut self, bridge: &mut TeamBridge) {
        let mut layers: BTreeMap<&str, LayerClaims> = BTreeMap::new();
        for (n, w) in &self.nodes {
            for (b, m) in &w.members {
                let Some(claiming) = m.claiming else { continue };
                let l =
                    layers.entry(b).or_insert_with(|| LayerClaims { behavior: b.clone(), ..LayerClaims::default() });
                if l.group.is_none() {
                    l.group = m.group.clone();
                }
                l.members.push(*n);
                if claiming {
                    l.claimers.push(*n);
                }
            }
        }
        let t = unix_nanos();
        for l in layers.values() {
            bridge.layer_claims(l, t);
        }
    }

    /// Replace the watcher's node by a fresh one that greets the known nodes by address.
    fn renew(&mut self) {
        let mut udp = self.udp.clone();
        if let Some(udp) = &mut udp {
            for p in self.node.peers() {
                if let Ok(addr) = p.addr.parse() {
                    if !udp.peers.contains(&addr) {
                        udp.peers.push(addr);
                    }
                }
            }
        }
        // The old socket goes first: a fixed bind address must be free for the new one.
        if let Ok(placeholder) = ayllu::MemNetwork::new().attach(self.config.id) {
            drop(std::mem::replace(&mut self.node, Node::new(MonotonicClock::new(), placeholder)));
        }
        match open_transport(&self.config, udp.as_ref()) {
            Ok(t) => self.node = Node::new(MonotonicClock::new(), t),
            Err(_) => {
                // Try again with the configured URL alone next period.
                if let Ok(t) = open_transport(&self.config, self.udp.as_ref()) {
                    self.node = Node::new(MonotonicClock::new(), t);
                }
            }
        }
        self.counts.failed += self.pending.len() as u64;
        self.pending.clear();
        self.since_renewal = 0;
        self.counts.renewals += 1;
    }
}
