//! The receive path: datagrams are read from the socket in bounded batches, decoded with
//! port messages going straight into the inbox in the datagram's order, checked (`admit.rs`),
//! and then every other message is applied: requests (through the operator key, if any),
//! CHALLENGE/ECHO, HELLO, reply parts reassembled within bounds (N4). A datagram that fails a
//! check leaves nothing behind in the inbox.

use std::net::SocketAddr;
use std::sync::Arc;

use ayllu_core::{ControlBody, ControlMessage, Destination, Duration, Message, NodeId, PortMessage};
use ayllu_wire::{decode_into, Header, MessageSink, ReplyAssembler, SignedRequest, WireMessage};

use crate::datagram::DatagramSocket;
use crate::udp_config::MAX_DATAGRAM;

use super::admit::Admitted;
use super::inbox::Inbox;
use super::peers::{expiry, MAX_PEER_INTERVAL, RECHALLENGE};
use super::UdpTransport;

/// Datagrams read per `recv` refill, so one busy socket cannot starve the node's loop.
const RECV_BATCH: usize = 256;
const MAX_ASSEMBLIES: usize = 64;
/// Report bytes held by all reply assemblies together: the oldest go first beyond it (one
/// honest report is at most 64 parts of 1.4 KB at the default MTU; forged parts could
/// otherwise hold 64 x 512 KiB).
const MAX_ASSEMBLY_BYTES: usize = 2 << 20;
/// Groups and group-name bytes kept per peer from its HELLO (a forged HELLO of 8 KB per id,
/// for 1024 ids, would otherwise hold 8 MB); the excess is counted `groups_truncated`.
const MAX_PEER_GROUPS: usize = 128;
const MAX_PEER_GROUP_BYTES: usize = 4096;

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
    inbox: &'a mut Inbox,
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
            self.inbox.push_back(self.sender, Message::Port(message));
        } else {
            self.not_member += 1;
        }
    }
    #[inline(always)]
    fn port_place(&mut self) -> Option<&mut PortMessage> {
        // After another message, everything waits in `rest`, in order.
        if !self.rest.is_empty() {
            return None;
        }
        self.inbox.port_place()
    }
    #[inline(always)]
    fn port_placed(&mut self, group: Option<Arc<str>>) {
        if group.is_none_or(|group| joined(self.joined, &group)) {
            self.inbox.commit(self.sender);
        } else {
            // Its place stays free.
            self.not_member += 1;
        }
    }
    fn other(&mut self, message: WireMessage) {
        self.rest.push(message);
    }
}

impl<S: DatagramSocket> UdpTransport<S> {
    /// Read datagrams (at most [`RECV_BATCH`]) until one puts a message into the inbox or the
    /// socket has nothing more. Inlined into its two callers: a call here is paid on every
    /// turn, and a loop that waits turns once per message.
    #[inline(always)]
    pub(super) fn refill(&mut self) {
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

    fn receive_datagram(&mut self, len: usize, from: SocketAddr) {
        // Port messages go into the inbox as they are decoded (the hot path); anything else,
        // and whatever follows it, waits in `rest` for the checks below, so the inbox keeps
        // the datagram's order. A refused datagram's messages are taken back out.
        let mark = self.inbox.end();
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
            let ports = self.inbox.end() - mark;
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
                WireMessage::Port(p) => self.inbox.push_back(sender, Message::Port(p)),
                WireMessage::GroupPort { group, message } => {
                    // Only a member applies a group's message (S10, D-S10.6).
                    if joined(&self.joined, &group) {
                        self.inbox.push_back(sender, Message::Port(message));
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
                        Ok(()) => self.inbox.push_back(sender, Message::Control(ControlMessage { id, body })),
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
                self.inbox.push_back(sender, Message::Control(ControlMessage { id, body }));
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
        let mut inbox = Inbox::default();
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
        let mut seqs = Vec::new();
        inbox.each_then_empty(|from, m| match m {
            Message::Port(p) if from == NodeId(9) => seqs.push(p.seq),
            other => panic!("{other:?}"),
        });
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
