//! Messages from other nodes (rules S8, S10; N1, N2, N4): port messages applied as new
//! waves, control requests answered, answers to this node's own requests taken in; and the
//! outbox, where everything this node sends waits for the runtime's transport.
//!
//! What it promises: nothing a peer sends can make the node panic or grow without bound.
//! A port message no newer than the newest already taken along its connection is dropped
//! (N1), and the table that remembers the newest is bounded; a control request is answered
//! once and the same answer resent when it is asked again (N2, idempotent), from a bounded
//! memory; requests over a sender's rate, or while too many answers wait to be sent, go
//! unanswered (the sender retries); and whatever cannot be applied is dropped and counted
//! by cause (N4). Access rules are checked before anything is applied.
//!
//! The receive path runs for every message of a simulated team, so it caches per
//! connection the port a message resolves to (`crate::sequence`), trusted only while no
//! behavior was removed and the message carries the very name strings it was resolved from.

use std::collections::VecDeque;
use std::sync::atomic::Ordering::Relaxed;
use std::sync::Arc;

use crate::address::{Endpoint, NodeId, Source};
use crate::connection::ConnectOptions;
use crate::counters::DropCause;
use crate::error::Error;
use crate::journal::Event;
use crate::message::{ControlBody, ControlMessage, Destination, Message, Outgoing, PortMessage, ReplyBody};
use crate::sequence::{incoming_key, Incoming, IncomingKey};
use crate::time::Instant;
use crate::value::Value;

use super::{NodeCore, PortState, RequestStatus, RATE_BUCKETS};

/// How many (sender, connection) sequence numbers a node remembers (N1). Bounded so a peer
/// inventing connection ids cannot grow memory; when full the table is cleared and counted.
const SEQ_TABLE_MAX: usize = 16_384;
/// How many answered control requests are remembered for idempotent replies (N2).
const ANSWERED_MAX: usize = 1_024;
/// And how many bytes they may take together (estimated, [`answer_bytes`]): a thousand LIST
/// answers of a large node held 262 MB for good; the oldest answers go first.
const ANSWERED_BYTES: usize = 2 << 20;
/// How many bytes of answers may wait in the outbox (estimated, [`answer_bytes`]) before
/// further control requests are dropped unanswered until it is sent (D9.3). A turn receives
/// everything waiting on its socket, and a flood of LIST requests from invented ids (each
/// its own sender, so under every per-sender rate) made one answer each: 3 000 of them, 70 KB
/// each, held 210 MB at once before the turn sent or dropped them.
const ANSWERS_WAITING_BYTES: usize = 2 << 20;

impl NodeCore {
    /// Apply a message from node `from`. Port messages are applied at once (a new wave);
    /// triggered processes run at the next `poll`. Never panics; what cannot be applied is
    /// counted.
    pub fn receive(&mut self, now: Instant, from: NodeId, message: Message) {
        self.advance(now);
        if self.journal.is_some() {
            let recorded = message.clone();
            self.journal(|| Event::Receive { from, message: Box::new(recorded) });
        }
        match message {
            Message::Port(m) => self.receive_port(from, &m),
            Message::Control(c) => self.receive_control(from, c),
        }
    }

    /// [`NodeCore::receive`] for a message shared by several receivers (a broadcast in a
    /// simulator): a port message is applied without being copied; a control message is.
    pub fn receive_shared(&mut self, now: Instant, from: NodeId, message: &Message) {
        self.advance(now);
        self.journal(|| Event::Receive { from, message: Box::new(message.clone()) });
        match message {
            Message::Port(m) => self.receive_port(from, m),
            Message::Control(c) => self.receive_control(from, c.clone()),
        }
    }

    /// [`NodeCore::receive_shared`] for each of `messages` in turn, in order: the same as one
    /// call a message (a simulator's radio handing a node its messages of a tick). Each port
    /// message's key is hashed once, for the hint that starts loading its sequence-table slot
    /// (given while the message before it is applied) and for its lookup, and the call's own
    /// work (saving registers, the clock) is done once for all of them. The messages come
    /// through a `dyn Iterator` so that this is compiled here, with this crate's inlining,
    /// rather than in the caller's crate, where the receive path's helpers are out of reach.
    pub fn receive_all_shared(&mut self, now: Instant, messages: &mut dyn Iterator<Item = (NodeId, &Message)>) {
        self.advance(now);
        let mut next = messages.next().map(|(from, message)| (from, message, self.hint_receive(from, message)));
        while let Some((from, message, hash)) = next {
            next = messages.next().map(|(from, message)| (from, message, self.hint_receive(from, message)));
            self.journal(|| Event::Receive { from, message: Box::new(message.clone()) });
            match message {
                Message::Port(m) => self.receive_port_hashed(from, m, hash),
                Message::Control(c) => self.receive_control(from, c.clone()),
            }
        }
    }

    /// For a port message: its key's hash in the sequence table, its slot's load started (a
    /// hint, as [`NodeCore::prefetch_receive`]); 0 for a control message, which has no key.
    #[inline(always)]
    fn hint_receive(&self, from: NodeId, message: &Message) -> u64 {
        let Message::Port(m) = message else { return 0 };
        let hash = self.newest_seq.hash(&incoming_key(from, m.conn));
        self.newest_seq.prefetch_hashed(hash);
        hash
    }

    /// A hint that `message` from `from` is about to be received: starts loading what its
    /// lookup reads first (the sequence table's slot), so that a caller holding several
    /// messages for this node (a simulator's radio) overlaps their loads. Changes nothing.
    #[inline]
    pub fn prefetch_receive(&self, from: NodeId, message: &Message) {
        if let Message::Port(m) = message {
            self.newest_seq.prefetch(&incoming_key(from, m.conn));
        }
    }

    /// The second hint, for a message whose [`NodeCore::prefetch_receive`] was given a while
    /// before: reads its sequence-table entry and starts loading the port the entry remembers,
    /// so that a caller holding several messages for this node has their ports' loads in flight
    /// together instead of one after the other. Changes nothing.
    #[inline]
    pub fn prefetch_target(&self, from: NodeId, message: &Message) {
        if let Message::Port(m) = message {
            self.newest_seq.prefetch_target(&incoming_key(from, m.conn));
        }
    }

    // Inlined into its callers (a plain `#[inline]` was not taken): a broadcast in a
    // simulator reaches each receiver through `receive_shared` or `receive_all_shared`, and one
    // call less per delivery is one register save and restore less (24 instructions).
    #[inline(always)]
    fn receive_port(&mut self, from: NodeId, m: &PortMessage) {
        self.receive_port_hashed(from, m, self.newest_seq.hash(&incoming_key(from, m.conn)));
    }

    /// [`NodeCore::receive_port`] with the sequence table's hash of the message's key made.
    #[inline(always)]
    fn receive_port_hashed(&mut self, from: NodeId, m: &PortMessage, hash: u64) {
        if !self.access.ports.admits(from) {
            self.counters.add(DropCause::NotAllowed);
            return;
        }
        if m.kind.period().is_some_and(|p| p > self.limits.max_remote_period) {
            self.counters.add(DropCause::TooLong);
            return;
        }
        let key = incoming_key(from, m.conn);
        // One hash lookup per message from a known connection: this runs for every message.
        let cached = match self.newest_seq.get_hashed(&key, hash) {
            Some(entry) => {
                let incoming = entry.get();
                if m.seq <= incoming.newest {
                    self.counters.add(DropCause::Stale);
                    return;
                }
                entry.newest.store(m.seq, Relaxed);
                // The port stands if no behavior was removed since it was resolved and the
                // message carries the very names it was resolved from.
                (incoming.epoch == self.removals && same_names(&incoming, m)).then_some((
                    incoming.b,
                    incoming.p,
                    incoming.target,
                ))
            }
            None => {
                if self.newest_seq.len() >= SEQ_TABLE_MAX {
                    self.forget_incoming();
                }
                self.newest_seq.enter(key, m.seq);
                None
            }
        };
        let (b, p, target) = match cached {
            Some(resolved) => resolved,
            None => match self.resolve_incoming(key, m) {
                Some(resolved) => resolved,
                None => return,
            },
        };
        self.wave += 1;
        let source = Source::connection(from, m.conn);
        // SAFETY: `target` is port `p` of the live behavior in slot `b`: either just resolved
        // (`resolve_incoming`), or remembered by the entry with the epoch checked above: no
        // behavior was removed since it was stored, so slot `b` holds the same behavior, whose
        // `ports` buffer has not moved (a behavior's ports are fixed at its creation). No
        // reference to the port is alive here.
        if unsafe { self.deliver_to(b, p, target, m.kind, source, m.priority, &m.value) } {
            self.propagate_from(b, p);
        }
    }

    /// Resolve the port message `m` names, for the sequence table's entry `key` (which exists)
    /// whose remembered port does not stand as it is (a behavior was removed since, or the
    /// message carries other name strings). If the behavior now in the remembered slot has the
    /// names the message carries, that is the port the names resolve to (names are unique on
    /// a node), and the entry keeps it and the strings it holds. Otherwise the names are looked
    /// up and the port and the message's name strings remembered. `None`, counted, if there is
    /// no such port.
    #[cold]
    #[inline(never)]
    fn resolve_incoming(&mut self, key: IncomingKey, m: &PortMessage) -> Option<(u32, u16, *mut PortState)> {
        let incoming = self.newest_seq.get(&key).expect("entered by the caller").get();
        if incoming.behavior != 0 {
            let named = self.behavior(incoming.b).is_some_and(|beh| {
                *beh.name == *m.behavior
                    && beh.class.ports.get(usize::from(incoming.p)).is_some_and(|p| p.name == *m.port)
            });
            if named {
                // The slot may hold a behavior re-created since: its ports are new.
                let target = self.port_address(incoming.b, incoming.p);
                if let Some(entry) = self.newest_seq.get(&key) {
                    entry.set_port(incoming.b, incoming.p, self.removals, target);
                }
                return Some((incoming.b, incoming.p, target));
            }
        }
        let Some(&b) = self.names.get(&*m.behavior) else {
            self.counters.add(DropCause::UnknownBehavior);
            return None;
        };
        let Some(beh) = self.behavior(b) else {
            self.counters.add(DropCause::UnknownBehavior);
            return None;
        };
        let Some(port) = beh.class.port_handle(&m.port) else {
            self.counters.add(DropCause::UnknownPort);
            return None;
        };
        let p = port.0;
        // The names held are bounded like the entries (N1): a sender that keeps re-pointing
        // a connection id clears the table as one that invents connection ids does.
        if self.newest_seq.held() >= SEQ_TABLE_MAX {
            self.forget_incoming();
            self.newest_seq.enter(key, incoming.newest);
        }
        let target = self.port_address(b, p);
        let Some(entry) = self.newest_seq.get(&key) else { return Some((b, p, target)) };
        entry.set_port(b, p, self.removals, target);
        self.newest_seq.hold(&key, &m.behavior, &m.port);
        Some((b, p, target))
    }

    /// Where port `p` of the live behavior in slot `b` is, for [`NodeCore::deliver_to`]: taken
    /// with `as_mut_ptr`, which makes no reference to the buffer, so the pointer stays usable
    /// beside the references later code makes to it (and to the other ports) in turn.
    fn port_address(&mut self, b: u32, p: u16) -> *mut PortState {
        let beh = self.behaviors[b as usize].as_mut().expect("a resolved port's behavior lives");
        assert!(usize::from(p) < beh.ports.len(), "a resolved port exists");
        // SAFETY: in bounds (asserted), inside the buffer's one allocation.
        unsafe { beh.ports.as_mut_ptr().add(usize::from(p)) }
    }

    /// Clear the sequence table (N1) and the names its entries held; counted.
    fn forget_incoming(&mut self) {
        self.newest_seq.clear();
        self.seq_table_resets += 1;
    }

    /// A behavior was removed: the sequence table's resolved ports are no longer trusted as
    /// they are ([`Incoming::epoch`]). When the 16-bit epoch wraps, an entry resolved 65 536
    /// removals ago would look current: every entry forgets its port instead (and with it
    /// the names it held).
    pub(super) fn behavior_removed(&mut self) {
        self.removals = self.removals.wrapping_add(1);
        if self.removals == 0 {
            self.newest_seq.forget_names();
        }
    }

    /// Take one token from `from`'s request bucket (`Limits::requests_per_second`, burst
    /// `requests_burst`); `false` when it is empty. At most [`RATE_BUCKETS`] senders are
    /// tracked; the one idle longest is forgotten first (a forgotten sender starts full).
    fn admit_request(&mut self, from: NodeId) -> bool {
        let rate = f64::from(self.limits.requests_per_second);
        let burst = f64::from(self.limits.requests_burst.max(1));
        let now = self.now;
        if !self.request_buckets.contains_key(&from) && self.request_buckets.len() >= RATE_BUCKETS {
            if let Some(idle) = self.request_buckets.iter().min_by_key(|(_, (_, t))| *t).map(|(n, _)| *n) {
                self.request_buckets.remove(&idle);
            }
        }
        let (tokens, last) = self.request_buckets.entry(from).or_insert((burst, now));
        let refill = (now - *last).as_secs_f64() * rate;
        *tokens = (*tokens + refill).min(burst);
        *last = now;
        if *tokens < 1.0 {
            return false;
        }
        *tokens -= 1.0;
        true
    }

    fn receive_control(&mut self, from: NodeId, c: ControlMessage) {
        let result = match c.body {
            ControlBody::Reply { result } => {
                if let Some(r) = self.requests.iter_mut().rev().find(|r| r.id == c.id && r.to == from) {
                    if matches!(r.status, RequestStatus::Pending { .. }) {
                        r.status = match result {
                            Ok(body) => RequestStatus::Done(body),
                            Err(e) => RequestStatus::Failed(e),
                        };
                        self.request_finished();
                    }
                }
                return;
            }
            body => {
                if !self.admit_request(from) {
                    // Unanswered: an answer would be the very traffic the limit is for.
                    self.counters.add(DropCause::RateLimited);
                    return;
                }
                // The outbox is emptied by whoever sends it (the transport takes it all): an
                // empty one holds no answers.
                if self.outbox.is_empty() {
                    self.answers_waiting = 0;
                }
                if self.answers_waiting >= ANSWERS_WAITING_BYTES {
                    // As over the rate: the requester retries (N2) once this turn's answers
                    // have gone.
                    self.counters.add(DropCause::RateLimited);
                    return;
                }
                if let Some(result) = self.answered.get(&(from, c.id)) {
                    self.answers_waiting += answer_bytes(result);
                    result.clone()
                } else {
                    let result = self.unjournaled(|core| core.apply_control(from, body));
                    if let Err(e) = &result {
                        let refused = matches!(e, Error::NotAllowed { .. });
                        self.counters.add(if refused { DropCause::NotAllowed } else { DropCause::BadRequest });
                    }
                    let result = result.map_err(|e| e.to_string());
                    let bytes = answer_bytes(&result);
                    while self.answered_order.len() >= ANSWERED_MAX
                        || (self.answered_bytes + bytes > ANSWERED_BYTES && !self.answered_order.is_empty())
                    {
                        if let Some(old) = self.answered_order.pop_front() {
                            if let Some(gone) = self.answered.remove(&old) {
                                self.answered_bytes -= answer_bytes(&gone);
                            }
                        }
                    }
                    self.answered.insert((from, c.id), result.clone());
                    self.answered_order.push_back((from, c.id));
                    self.answered_bytes += bytes;
                    self.answers_waiting += bytes;
                    result
                }
            }
        };
        self.outbox.push_back(Outgoing {
            to: Destination::Node(from),
            message: Message::Control(ControlMessage { id: c.id, body: ControlBody::Reply { result } }),
        });
    }

    fn apply_control(&mut self, from: NodeId, body: ControlBody) -> Result<ReplyBody, Error> {
        if body.changes_structure() && !self.access.structure.admits(from) {
            return Err(Error::NotAllowed {
                what: format!("{from} may not change this node's structure (its access rules)"),
            });
        }
        if matches!(body, ControlBody::Connect { .. } | ControlBody::Disconnect { .. }) {
            if let Some((coordinator, txn)) = self.transaction_held() {
                // The reservation a PREPARE holds (R9).
                return Err(Error::Transaction {
                    what: format!("busy: transaction {txn} of {coordinator} is held here"),
                });
            }
        }
        match body {
            body @ (ControlBody::Prepare { .. } | ControlBody::Commit { .. } | ControlBody::Abort { .. }) => {
                self.apply_transaction(from, body)
            }
            ControlBody::Connect { source_behavior, source_port, destination, kind, priority } => {
                if matches!(destination, Endpoint::Local { .. }) {
                    return Err(Error::NotLocal {
                        what: "a requested connection's destination must name its node".into(),
                    });
                }
                if kind.period().is_some_and(|p| p > self.limits.max_remote_period) {
                    return Err(Error::NotAllowed {
                        what: format!(
                            "a {} period over this node's limit of {} for requests",
                            kind.name(),
                            self.limits.max_remote_period
                        ),
                    });
                }
                let mine = self.conns.iter().flatten().filter(|c| c.requested_by == Some(from)).count();
                let all = self.conns.iter().flatten().filter(|c| c.requested_by.is_some()).count();
                if mine >= self.limits.remote_connections_per_node || all >= self.limits.remote_connections {
                    return Err(Error::NotAllowed {
                        what: format!(
                            "a new connection: this node holds {all} made by request ({mine} by {from}); its limits \
                             are {} in all and {} per node",
                            self.limits.remote_connections, self.limits.remote_connections_per_node
                        ),
                    });
                }
                let source = Endpoint::Local { behavior: source_behavior, port: source_port };
                let id = self.connect(&source, &destination, kind, ConnectOptions { priority })?;
                if let Some(c) = self.conn_ids.get(&id.0).and_then(|&c| self.conns[c as usize].as_mut()) {
                    c.requested_by = Some(from);
                }
                Ok(ReplyBody::Connection(id))
            }
            ControlBody::Disconnect { conn } => self.disconnect(conn).map(|()| ReplyBody::Connection(conn)),
            ControlBody::List => Ok(ReplyBody::Node(Box::new(self.report()))),
            ControlBody::Why { behavior, port } => self.why(&behavior, &port).map(|r| ReplyBody::Port(Box::new(r))),
            ControlBody::Read { behavior, port } => {
                let r = self.port(&behavior, &port)?;
                self.read(r).map(ReplyBody::Value)
            }
            ControlBody::Reply { .. } => unreachable!("replies are handled before apply_control"),
        }
    }

    /// The next message to send, oldest first.
    pub fn pop_outgoing(&mut self) -> Option<Outgoing> {
        self.outbox.pop_front()
    }

    /// The messages waiting to be sent, oldest first, for a runtime that sends them where
    /// they lie and then empties the queue, rather than taking them out one by one with
    /// [`NodeCore::pop_outgoing`] (each a move of the whole message). Sending them in this
    /// order, each once, is the caller's part.
    pub fn outgoing_mut(&mut self) -> &mut VecDeque<Outgoing> {
        &mut self.outbox
    }

    /// How many messages wait to be sent.
    pub fn outgoing_len(&self) -> usize {
        self.outbox.len()
    }
}

/// A cheap upper estimate of what a remembered answer holds in memory, for the byte bound of
/// the answer memory (it need not be exact, only grow with the answer).
fn answer_bytes(result: &Result<ReplyBody, String>) -> usize {
    const BASE: usize = 64;
    let value = |v: &Value| match v {
        Value::Text(t) => t.len(),
        Value::Bytes(b) => b.len(),
        Value::Vector(x) => x.len() * 8,
        _ => 8,
    };
    BASE + match result {
        Err(e) => e.len(),
        Ok(ReplyBody::Connection(_)) => 8,
        Ok(ReplyBody::Value(v)) => value(v),
        Ok(ReplyBody::OtherReport(text)) => text.len(),
        Ok(ReplyBody::Port(r)) => {
            512 + r.windows.len() * 64 + (r.incoming.len() + r.outgoing.len()) * 256 + r.triggers.len() * 128
        }
        Ok(ReplyBody::Node(r)) => {
            let behaviors: usize = r
                .behaviors
                .iter()
                .map(|b| {
                    256 + b.ports.iter().map(|p| 96 + p.name.len() + value(&p.value)).sum::<usize>()
                        + b.slots.iter().map(|(n, v)| 64 + n.len() + value(v)).sum::<usize>()
                        + b.monostables.len() * 64
                        + b.processes.len() * 128
                })
                .sum();
            512 + behaviors
                + r.connections.len() * 256
                + r.transport.len() * 64
                + r.warnings.iter().map(|w| 32 + w.len()).sum::<usize>()
        }
    }
}

/// Whether `m` carries the very name strings `incoming`'s port was resolved from (address
/// comparison; the entry itself holds those strings, `SeqTable::hold`).
fn same_names(incoming: &Incoming, m: &PortMessage) -> bool {
    incoming.behavior == name_address(&m.behavior) && incoming.port == name_address(&m.port)
}

/// The address of a name string, which identifies it while it lives (never 0).
fn name_address(name: &Arc<str>) -> usize {
    Arc::as_ptr(name).cast::<u8>() as usize
}
