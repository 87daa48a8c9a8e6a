//! Where a message goes and whether it may go now: the address of a node or a group (S10),
//! a message held for a node not heard from yet until it greets, answers bounded by what an
//! unproven address sent (return routability), requests that cannot fit one datagram refused
//! with a reason, and structure changes signed with the operator secret. Sending itself is
//! `batching.rs`'s.

use std::collections::VecDeque;
use std::net::SocketAddr;

use ayllu_core::{ControlBody, ControlMessage, Destination, Instant, Message, NodeId};
use ayllu_wire::{EncodeError, SignedRequest, WireMessage};

use crate::datagram::DatagramSocket;
use crate::transport::{Sent, TransportEvent};

use super::UdpTransport;

/// Messages held for nodes not heard from yet, at most (the oldest goes first when full).
const MAX_HELD: usize = 256;
/// A message for a node not heard from yet waits this many of our HELLO periods for it to
/// greet (a peer greets as soon as it hears our HELLO, so one round trip is the usual wait).
const HOLD_PERIODS: u64 = 3;

/// A message waiting for its destination node to be heard from.
pub(super) struct Held {
    to: NodeId,
    until: Instant,
    message: Message,
}

impl<S: DatagramSocket> UdpTransport<S> {
    /// Send `message` to `to`, from a borrowed message: only a message held for a node not
    /// heard from yet is copied (the rare case).
    pub(super) fn send_message(&mut self, to: &Destination, message: &Message) -> Sent {
        self.send_message_after(to, message, &mut None)
    }

    /// [`UdpTransport::send_message`] for one of a run of messages (a turn's outbox): `last`
    /// is the node the run's previous port message went to and its address, if it had one,
    /// and the peer table has not changed since (nothing in a run changes it). A run of
    /// messages to one node then looks its peer up once.
    #[inline(always)]
    pub(super) fn send_message_after(
        &mut self,
        to: &Destination,
        message: &Message,
        last: &mut Option<(NodeId, SocketAddr)>,
    ) -> Sent {
        // The hot path, a port message to one node: one lookup, no list of addresses.
        if let (Destination::Node(n), Message::Port(p)) = (to, message) {
            let addr = match *last {
                Some((node, addr)) if node == *n => addr,
                _ => {
                    let now = self.now;
                    let Some(addr) = self.peers.get_mut(n).map(|peer| {
                        peer.used = Some(now);
                        peer.addr
                    }) else {
                        return self.hold(*n, message.clone());
                    };
                    *last = Some((*n, addr));
                    addr
                }
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
    pub(super) fn release_held(&mut self, node: NodeId) {
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

    /// Drop the held messages whose wait is over ([`HOLD_PERIODS`]); the next time one is, or
    /// `next` if that is sooner.
    pub(super) fn expire_held(&mut self, now: Instant, next: Instant) -> Instant {
        let before = self.held.len();
        self.held.retain(|h| now < h.until);
        for _ in self.held.len()..before {
            self.count("held_expired");
        }
        self.held.iter().map(|h| h.until).fold(next, Instant::min)
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
}
