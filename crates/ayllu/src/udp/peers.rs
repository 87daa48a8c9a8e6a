//! The peer table: who this node knows, at which address, for how long (N6), and how peers
//! prove their addresses. It promises that the table stays bounded (N4) and that a peer with
//! a proven address, one named by `peer=` or one in use keeps its place (D-N6.3-6.6), while an
//! unproven one is forgotten on a short clock of its own. HELLOs announce this node (to static
//! peers, group, broadcast and discovery addresses, and protected peers); peers silent too long
//! are reported lost.

use std::net::SocketAddr;

use ayllu_core::{Duration, Instant, NodeId};
use ayllu_wire::WireMessage;

use crate::datagram::DatagramSocket;
use crate::routability::Budget;
use crate::transport::{PeerInfo, TransportEvent};
use crate::udp_config::UdpConfig;

use super::UdpTransport;

/// Bounds that keep a flood from growing memory (N4).
pub(super) const MAX_PEERS: usize = 1024;
/// The longest HELLO period a peer may announce: it bounds how long a forged peer stays in the
/// table (three periods) and so how long it is greeted.
pub(super) const MAX_PEER_INTERVAL: Duration = Duration::from_secs(60);
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
/// How often an unproven peer, or a keyed sender not yet known fresh, is challenged again
/// while it is heard (the first CHALLENGE or ECHO may be lost).
pub(super) const RECHALLENGE: Duration = Duration::from_millis(250);

#[derive(Clone, Debug)]
pub(super) struct Peer {
    pub(super) addr: SocketAddr,
    pub(super) name: String,
    pub(super) groups: Vec<String>,
    pub(super) interval: Duration,
    pub(super) last_heard: Instant,
    /// When it was let in (or its address last changed): an unproven peer's clock starts here.
    pub(super) admitted: Instant,
    /// Its address is one the URL names (`peer=`): the operator vouched for it.
    pub(super) fixed: bool,
    /// When this node last sent it a message (a connection, a request, a group's unicast).
    pub(super) used: Option<Instant>,
    /// When it was last sent a CHALLENGE (at most one per [`RECHALLENGE`]).
    pub(super) challenged: Option<Instant>,
    /// What its address may still be sent before it proves it receives there; `proven` once
    /// it echoed a cookie, or authenticated as a sender known to be fresh.
    pub(super) budget: Budget,
}

impl Peer {
    /// A *protected* peer is never displaced by a newcomer and is greeted every period: its
    /// address is proven (ECHO, or a fresh authenticated datagram), named in the URL, or in use
    /// by this node. Anyone can send a second datagram or announce a group in an open team, so
    /// neither protects (docs/semantics.md N4).
    pub(super) fn protected(&self, now: Instant) -> bool {
        self.budget.proven || self.fixed || self.used.is_some_and(|u| now < u + IN_USE)
    }
}

/// When a peer is forgotten (N4, N6): three of its HELLO periods after it was last heard; and
/// an unproven one, not in use, `unproven` after it was let in at the latest. Hearing from a
/// peer, proving it or using it only ever moves this later, so a computed expiry is a lower
/// bound (`next_expiry`).
pub(super) fn expiry(p: &Peer, unproven: Duration) -> Instant {
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

/// Why discovery does not work here, and what to do instead.
pub(super) fn discovery_warning(config: &UdpConfig, error: &str) -> String {
    let at = config.discovery.map_or_else(String::new, |a| a.to_string());
    format!(
        "discovery by multicast at {at} is not available on this machine ({error}): nodes will not find each \
         other by themselves; list them with peer=ADDR:PORT in the udp:// URL (AYLLU_URL)"
    )
}

impl<S: DatagramSocket> UdpTransport<S> {
    pub(super) fn hello(&self) -> WireMessage {
        WireMessage::Hello {
            interval_ms: u32::try_from(self.config.hello_interval.as_nanos() / 1_000_000).unwrap_or(u32::MAX).max(1),
            name: self.config.name.as_str().into(),
            groups: self.joined.iter().map(|g| g.as_str().into()).collect(),
        }
    }

    pub(super) fn announce(&mut self) {
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

    /// Send `sender` at `from` a CHALLENGE now (pushed into the turn's datagram for `from`).
    pub(super) fn challenge(&mut self, sender: NodeId, from: SocketAddr) {
        let cookie = self.cookies.make(self.now, sender, from);
        self.push(from, &WireMessage::Challenge { cookie });
        self.count("challenges_sent");
    }

    /// `sender` proved it receives at `from`: it becomes that peer's address (a proven peer
    /// that moved), and other ids at the same address that proved nothing stronger leave the
    /// table. One socket is one node (lite/README.md), so an attacker that answers CHALLENGEs
    /// holds at most one proven place per address it really receives at, not one per id.
    pub(super) fn one_node_per_address(&mut self, sender: NodeId, from: SocketAddr) {
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

    /// How long an unproven peer is kept ([`UNPROVEN_PERIODS`] of our HELLO period, bounded).
    pub(super) fn unproven_lifetime(&self) -> Duration {
        (self.config.hello_interval * UNPROVEN_PERIODS).clamp(MIN_UNPROVEN_LIFETIME, MAX_UNPROVEN_LIFETIME)
    }

    /// Forget the peers whose time is up ([`expiry`]), each reported lost to the node, and
    /// find when the next one may be.
    pub(super) fn forget_expired_peers(&mut self, now: Instant) {
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
