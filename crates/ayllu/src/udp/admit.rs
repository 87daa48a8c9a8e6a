//! The checks a decoded datagram passes before anything in it is applied: not our own datagram
//! looped back, not another node using our id, not a replayed number (N5, against the sender's
//! replay window, kept here), and for a sender new to the peer table, admission at a bounded
//! rate per source (D-N6.3-6.5) into a table of bounded size (N4). A datagram that fails is
//! dropped and counted by cause; one that passes updates its sender's peer entry and says
//! whether the sender is known fresh (D-N5.4: until it is, its port messages and requests wait).

use std::net::SocketAddr;

use ayllu_core::{Duration, Instant, NodeId};
use ayllu_wire::{Header, ReplayWindow, WireMessage};

use crate::admission::Rate;
use crate::datagram::DatagramSocket;
use crate::routability::Budget;
use crate::transport::TransportEvent;

use super::counters::Hot;
use super::peers::{Peer, MAX_PEERS, RECHALLENGE};
use super::UdpTransport;

/// Senders whose replay windows are kept (N5), longer than their peer entries: a window
/// forgotten with its peer would let an old authenticated datagram be applied again.
pub(super) const MAX_REPLAY_SENDERS: usize = 4096;
/// CHALLENGEs sent to newcomers the admission rate refused (so that a real node can still join
/// during a flood by proving its address): at most this many, over all senders.
pub(super) const REFUSED_CHALLENGES: Rate = Rate { burst: 64, every: Duration::from_millis(4) };
/// Distinct addresses of nodes using our id that are reported (more are only counted).
const MAX_DUPLICATES: usize = 8;

/// What [`UdpTransport::admit`] let through: the sender, whether it is new to the peer table,
/// and whether its datagram may be applied whole (`fresh`: not a keyed sender this node has no
/// memory of and that has not yet answered a CHALLENGE, D-N5.4).
pub(super) struct Admitted {
    pub(super) sender: NodeId,
    pub(super) is_new: bool,
    pub(super) fresh: bool,
}

/// A keyed sender's replay window (N5), with when it was last used, and what is known of its
/// freshness: a window made here for a sender this node has no memory of accepts numbers, but
/// the datagrams are applied only once the sender answered a CHALLENGE with an authenticated
/// ECHO (D-N5.4).
pub(super) struct SenderWindow {
    pub(super) window: ReplayWindow,
    pub(super) used: Instant,
    pub(super) fresh: bool,
    /// When it was last challenged for freshness.
    pub(super) challenged: Option<Instant>,
}

impl<S: DatagramSocket> UdpTransport<S> {
    /// The checks a decoded datagram passes before anything in it is applied (our own
    /// looped-back broadcast, another node with our id, a replayed number, the admission of a
    /// newcomer, a full peer table), and the peer table's update for its sender; `None`,
    /// counted, for a datagram to drop. `rest` is the datagram's messages other than its
    /// leading port messages (an ECHO among them proves the sender's address at once).
    pub(super) fn admit(
        &mut self,
        header: Header,
        from: SocketAddr,
        len: usize,
        rest: &[WireMessage],
    ) -> Option<Admitted> {
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

    /// Whether a datagram carrying our id came from us: from our own address (or our port on
    /// a local address, when bound to the unspecified address) and numbered as ours.
    fn is_own(&self, from: SocketAddr, seq: u64) -> bool {
        let ours = (self.seq_start..self.seq).contains(&seq);
        let here = self.socket.local_addr().is_ok_and(|l| {
            l.port() == from.port() && (l.ip() == from.ip() || l.ip().is_unspecified() || from.ip().is_loopback())
        });
        ours && here
    }
}
