//! Connections (rules S6, S10) and this node's dealings with the team around it: connections
//! made and removed, nodes lost, who may reach in (access) and how much (limits), the groups
//! joined, and the control requests this node sends to other nodes (N2).
//!
//! What it promises: a connection is refused when it could never deliver (a zero period, a
//! source that is not a port here, a local destination of another type for the kinds that
//! write, a vector too long to send), so a mistake shows at wiring time rather than as
//! silent drops. Removing a
//! connection ends at once the windows it holds and the value it supplied to an aggregating
//! port (D3.7); a lost node's supplies and the connections it was leased (D9.1) go with it.
//! A request is resent until answered or given up, and the node keeps only a bounded number
//! of finished ones, so a tool that asks forever cannot grow it.

use std::sync::Arc;

use crate::access::{Access, Limits};
use crate::address::{ConnectionId, Endpoint, NodeId, Source};
use crate::connection::{ConnectOptions, ConnectionInfo, ConnectionKind};
use crate::error::Error;
use crate::journal::Event;
use crate::message::{ControlBody, ControlMessage, Destination, Message, Outgoing, ReplyBody};
use crate::time::{Duration, Instant};

use super::{current, Conn, Edge, NodeCore, RequestId, RequestStatus, Target};

/// Control requests are retried this often until answered...
const RETRY_INTERVAL: Duration = Duration::from_millis(200);
/// ...and given up after this many sends.
const RETRY_LIMIT: u32 = 25;
/// How many of this node's own finished requests (answered or failed) it keeps for
/// [`NodeCore::request_status`]. A tool that asks forever (a viewer polling LIST) would
/// otherwise grow without bound; the oldest finished ones are forgotten first, pending ones
/// never (they end by themselves after `RETRY_LIMIT` sends).
const FINISHED_REQUESTS_KEPT: usize = 1_024;

/// A control request this node sent, kept until forgotten (see `FINISHED_REQUESTS_KEPT`).
/// Its fields are the node's: answers are matched in `receive`, retries timed in `scheduler`.
#[derive(Clone)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub(super) struct Request {
    pub(super) id: u64,
    pub(super) to: NodeId,
    pub(super) body: ControlBody,
    pub(super) next_send: Instant,
    pub(super) sends: u32,
    pub(super) status: RequestStatus,
}

/// The CONNECT that asks `source`'s node for a connection to `destination` (a local
/// destination means `me`'s port), checked as [`NodeCore::request_connect`] documents: from
/// outside a process and from inside one alike.
pub(crate) fn connect_request(
    me: NodeId,
    source: &Endpoint,
    destination: &Endpoint,
    kind: ConnectionKind,
    options: ConnectOptions,
) -> Result<(NodeId, ControlBody), Error> {
    if kind.period().is_some_and(|p| p.is_zero()) {
        return Err(Error::ZeroPeriod { kind });
    }
    let Endpoint::Node { node, behavior, port } = source else {
        return Err(if matches!(source, Endpoint::Group { .. }) {
            Error::GroupSource
        } else {
            Error::NotLocal { what: "request_connect's source must be a (node, behavior, port)".into() }
        });
    };
    let destination = match destination {
        Endpoint::Local { behavior, port } => {
            Endpoint::Node { node: me, behavior: behavior.clone(), port: port.clone() }
        }
        other => other.clone(),
    };
    let body = ControlBody::Connect {
        source_behavior: behavior.clone(),
        source_port: port.clone(),
        destination,
        kind,
        priority: options.priority,
    };
    Ok((*node, body))
}

impl NodeCore {
    /// Connect `source` (a port on this node) to `destination` (a port on this node, another
    /// node, or every node of a group). Returns the new connection's id.
    ///
    /// Refused: a zero period ([`Error::ZeroPeriod`], D6.8); a source on another node
    /// ([`Error::NotLocal`]: use [`NodeCore::request_connect`]) or a group
    /// ([`Error::GroupSource`]); an unknown behavior or port, or a slot; for the kinds that
    /// write (Normal, OverrideIn, OverrideOut) a local destination of another type
    /// ([`Error::TypeMismatch`], D6.7). Remote destinations are checked by their node.
    pub fn connect(
        &mut self,
        source: &Endpoint,
        destination: &Endpoint,
        kind: ConnectionKind,
        options: ConnectOptions,
    ) -> Result<ConnectionId, Error> {
        if let Some(p) = kind.period() {
            if p.is_zero() {
                return Err(Error::ZeroPeriod { kind });
            }
        }
        let (sb, sp) = match source {
            Endpoint::Local { behavior, port } => self.local_port(behavior, port)?,
            Endpoint::Node { node, behavior, port } if *node == self.id => self.local_port(behavior, port)?,
            Endpoint::Node { .. } => {
                return Err(Error::NotLocal {
                    what: format!("the source {source} of connect (use request_connect for another node's port)"),
                })
            }
            Endpoint::Group { .. } => return Err(Error::GroupSource),
        };
        let src_ty = self.behavior(sb).expect("resolved").ports[usize::from(sp)].cell.ty();
        if !matches!(destination, Endpoint::Local { .. })
            && !matches!(destination, Endpoint::Node { node, .. } if *node == self.id)
        {
            // A value that can never be encoded would be dropped at every send (D-S10.7).
            let beh = self.behavior(sb).expect("resolved");
            let cell = &beh.ports[usize::from(sp)].cell;
            let len = current(cell, self.now).as_vector().map_or(0, <[f64]>::len);
            if len > crate::value::MAX_NETWORK_VECTOR {
                let name = beh.class.ports().get(usize::from(sp)).map_or("", |p| p.name.as_str());
                return Err(Error::TooLongForNetwork { port: format!("{}.{name}", beh.name), len });
            }
        }
        let dst = match destination {
            Endpoint::Local { behavior, port } => self.local_target(behavior, port, kind, src_ty)?,
            Endpoint::Node { node, behavior, port } if *node == self.id => {
                self.local_target(behavior, port, kind, src_ty)?
            }
            Endpoint::Node { node, behavior, port } => {
                check_name(behavior, port)?;
                Target::Remote { to: Destination::Node(*node), behavior: behavior.clone(), port: port.clone() }
            }
            Endpoint::Group { group, behavior, port } => {
                check_name(behavior, port)?;
                Target::Remote { to: Destination::Group(group.clone()), behavior: behavior.clone(), port: port.clone() }
            }
        };
        let id = self.next_conn_id;
        self.next_conn_id += 1;
        let source = match source {
            Endpoint::Node { behavior, port, .. } => Endpoint::Local { behavior: behavior.clone(), port: port.clone() },
            other => other.clone(),
        };
        let local = match dst {
            Target::Local { b, p } => Some((b, p)),
            Target::Remote { .. } => None,
        };
        let journaled_source = self.journal.is_some().then(|| source.clone());
        let conn = Conn {
            id,
            src: (sb, sp),
            dst,
            kind,
            priority: options.priority,
            seq: self.seq_base,
            seq_start: self.seq_base,
            requested_by: None,
            source,
            destination: destination.clone(),
        };
        let c = match self.free_conns.pop() {
            Some(c) => {
                self.conns[c as usize] = Some(conn);
                c
            }
            None => {
                self.conns.push(Some(conn));
                (self.conns.len() - 1) as u32
            }
        };
        self.conn_ids.insert(id, c);
        let edge = Edge { conn: c, id, local, kind, priority: options.priority };
        self.behavior_mut(sb).expect("resolved").ports[usize::from(sp)].out.push(edge);
        self.journal(|| Event::Connect {
            source: Box::new(journaled_source.unwrap_or_else(|| Endpoint::local("", ""))),
            destination: Box::new(destination.clone()),
            kind,
            priority: options.priority,
        });
        Ok(ConnectionId(id))
    }

    fn local_port(&self, behavior: &str, port: &str) -> Result<(u32, u16), Error> {
        let r = self.port(behavior, port)?;
        Ok((r.b, r.port.0))
    }

    fn local_target(
        &self,
        behavior: &str,
        port: &str,
        kind: ConnectionKind,
        src_ty: crate::value::ValueType,
    ) -> Result<Target, Error> {
        let (b, p) = self.local_port(behavior, port)?;
        let cell = &self.behavior(b).expect("resolved").ports[usize::from(p)].cell;
        if kind.writes() && cell.ty() != src_ty {
            return Err(Error::TypeMismatch {
                what: format!("port {behavior}.{port}"),
                expected: cell.ty(),
                found: src_ty,
            });
        }
        Ok(Target::Local { b, p })
    }

    /// Remove a connection this node owns. Windows it holds on local ports end at once.
    pub fn disconnect(&mut self, id: ConnectionId) -> Result<(), Error> {
        let c = self.conn_ids.remove(&id.0).ok_or(Error::UnknownConnection { id: id.0 })?;
        let conn = self.conns[c as usize].take().expect("indexed connection exists");
        self.free_conns.push(c);
        let me = self.id;
        if let Some(beh) = self.behavior_mut(conn.src.0) {
            beh.ports[usize::from(conn.src.1)].out.retain(|e| e.conn != c);
        }
        if let Target::Local { b, p } = conn.dst {
            if let Some(beh) = self.behavior_mut(b) {
                let port = &mut beh.ports[usize::from(p)];
                let gone = Source::connection(me, id);
                port.windows.forget_holder(gone);
                port.refresh_plain();
                // What the connection supplied to an aggregating port is no longer offered.
                port.cell.release_from(|s| s == gone);
            }
        }
        self.journal(|| Event::Disconnect { conn: id });
        Ok(())
    }

    /// Node `node` is gone (its transport has not heard from it for its liveness period, N6):
    /// every aggregating port it holds releases its value, so the next value is judged against
    /// what is still supplied, not against a dead robot's claim (D3.7). Its windows lapse by
    /// themselves at the end of their periods. Returns how many ports were released.
    pub fn node_lost(&mut self, now: Instant, node: NodeId) -> usize {
        self.advance(now);
        self.journal(|| Event::NodeLost { node });
        self.unjournaled(|core| core.release_node(node))
    }

    fn release_node(&mut self, node: NodeId) -> usize {
        if node == self.id {
            return 0;
        }
        let mut released = 0;
        for beh in self.behaviors.iter_mut().flatten() {
            for port in &mut beh.ports {
                if port.cell.release_from(|s| s.node == node) {
                    released += 1;
                }
            }
        }
        // Connections it asked for were leased to it (D9.1).
        let leased: Vec<u64> =
            self.conns.iter().flatten().filter(|c| c.requested_by == Some(node)).map(|c| c.id).collect();
        for id in leased {
            let _ = self.disconnect(ConnectionId(id));
        }
        released
    }

    /// Set who may write this node's ports and change its structure from the network.
    pub fn set_access(&mut self, access: Access) {
        self.journal(|| Event::SetAccess(access.clone()));
        self.access = access;
    }

    /// The access rules in force.
    pub fn access(&self) -> &Access {
        &self.access
    }

    /// Set the bounds on what the network can make this node hold.
    pub fn set_limits(&mut self, limits: Limits) {
        self.journal(|| Event::SetLimits(limits.clone()));
        self.limits = limits;
    }

    /// The limits in force.
    pub fn limits(&self) -> &Limits {
        &self.limits
    }

    /// Join a broadcast group: messages sent to `(group, behavior, port)` by others reach us.
    /// The transport decides delivery; the core only records membership for listing.
    pub fn join(&mut self, group: &str) {
        self.journal(|| Event::Join(group.to_owned()));
        if !self.groups.iter().any(|g| &**g == group) {
            self.groups.push(Arc::from(group));
            self.groups_generation += 1;
        }
    }

    /// Leave a broadcast group (nothing if not a member). Connections *to* the group stay:
    /// remove them with [`NodeCore::disconnect`].
    pub fn leave(&mut self, group: &str) {
        self.journal(|| Event::Leave(group.to_owned()));
        let before = self.groups.len();
        self.groups.retain(|g| &**g != group);
        if self.groups.len() != before {
            self.groups_generation += 1;
        }
    }

    /// Changes whenever the set of joined groups changes, so a runtime can keep its
    /// transport's memberships in step with the core's without comparing lists every turn.
    pub fn groups_generation(&self) -> u64 {
        self.groups_generation
    }

    /// The groups joined, in join order.
    pub fn groups(&self) -> &[Arc<str>] {
        &self.groups
    }

    /// Ask `source`'s node to make a connection from its port to `destination` (N2: retried
    /// until answered, idempotent). `destination` must name a node or group, since "local"
    /// would be ambiguous on the other side.
    pub fn request_connect(
        &mut self,
        source: &Endpoint,
        destination: &Endpoint,
        kind: ConnectionKind,
        options: ConnectOptions,
    ) -> Result<RequestId, Error> {
        let (node, body) = connect_request(self.id, source, destination, kind, options)?;
        Ok(self.send_request(node, body))
    }

    /// Ask `node` to remove its connection `conn`.
    pub fn request_disconnect(&mut self, node: NodeId, conn: ConnectionId) -> RequestId {
        self.send_request(node, ControlBody::Disconnect { conn })
    }

    /// Ask `node` to describe itself (LIST), explain a port (WHY) or read one (READ); the
    /// answer arrives in [`NodeCore::request_status`].
    pub fn request(&mut self, node: NodeId, body: ControlBody) -> Result<RequestId, Error> {
        match body {
            ControlBody::Reply { .. } => Err(Error::NotLocal { what: "a reply is not a request".into() }),
            body => Ok(self.send_request(node, body)),
        }
    }

    fn send_request(&mut self, to: NodeId, body: ControlBody) -> RequestId {
        if self.journal.is_some() {
            let recorded = body.clone();
            self.journal(|| Event::Request { to, body: Box::new(recorded) });
        }
        let id = self.next_request;
        self.next_request += 1;
        self.requests.push(Request {
            id,
            to,
            body,
            next_send: self.now,
            sends: 0,
            status: RequestStatus::Pending { sends: 0 },
        });
        self.flush_requests();
        RequestId(id)
    }

    /// Where request `id` stands; `None` if this node never sent it or has forgotten it. The
    /// runtime's [`NodeCore::poll`] drives the retries. A finished request (answered or
    /// failed) is kept until [`NodeCore::forget_request`] or until 1,024 newer ones have
    /// finished, whichever comes first, so a program that never forgets stays bounded.
    pub fn request_status(&self, id: RequestId) -> Option<RequestStatus> {
        self.requests.iter().rev().find(|r| r.id == id.0).map(|r| r.status.clone())
    }

    /// Forget request `id` and return where it stood: a pending request is no longer retried
    /// and its answer, if one comes, is ignored. `None` if this node never sent it or has
    /// already forgotten it.
    pub fn forget_request(&mut self, id: RequestId) -> Option<RequestStatus> {
        let i = self.requests.iter().rposition(|r| r.id == id.0)?;
        let r = self.requests.remove(i);
        if !matches!(r.status, RequestStatus::Pending { .. }) {
            self.finished_requests -= 1;
        }
        Some(r.status)
    }

    /// Request `id`'s outcome once it has one, forgetting the request as it is handed over:
    /// `Some(Ok(answer))`, `Some(Err(why))` (refused, unanswered after every resend, or not
    /// sendable), or `None` while it is pending (or was never sent, or already taken). How every
    /// asker collects an answer (the runtime's `Node::ask`, transactions, the Foxglove
    /// watcher), so that none keeps finished requests or reads them differently.
    pub fn take_answer(&mut self, id: RequestId) -> Option<Result<ReplyBody, String>> {
        let r = self.requests.iter().rev().find(|r| r.id == id.0)?;
        if matches!(r.status, RequestStatus::Pending { .. }) {
            return None;
        }
        match self.forget_request(id)? {
            RequestStatus::Done(body) => Some(Ok(body)),
            RequestStatus::Failed(why) => Some(Err(why)),
            RequestStatus::Pending { .. } => None,
        }
    }

    /// Request `id` to `to` cannot be sent at all (the transport says why: larger than a
    /// datagram, ...): it fails now with `reason` instead of being retried until it gives up.
    /// Nothing happens if it is not pending.
    pub fn fail_request(&mut self, to: NodeId, id: u64, reason: String) {
        let Some(r) = self.requests.iter_mut().rev().find(|r| r.id == id && r.to == to) else { return };
        if matches!(r.status, RequestStatus::Pending { .. }) {
            r.status = RequestStatus::Failed(reason);
            self.request_finished();
        }
    }

    /// How many requests this node holds (pending and finished): bounded, see
    /// [`NodeCore::request_status`].
    pub fn requests_held(&self) -> usize {
        self.requests.len()
    }

    /// Count one more finished request and, past the bound, forget the oldest finished ones
    /// (in batches, so the cost per request stays constant).
    pub(super) fn request_finished(&mut self) {
        self.finished_requests += 1;
        if self.finished_requests > FINISHED_REQUESTS_KEPT + FINISHED_REQUESTS_KEPT / 4 {
            let mut excess = self.finished_requests - FINISHED_REQUESTS_KEPT;
            self.requests.retain(|r| {
                if excess > 0 && !matches!(r.status, RequestStatus::Pending { .. }) {
                    excess -= 1;
                    false
                } else {
                    true
                }
            });
            self.finished_requests = FINISHED_REQUESTS_KEPT;
        }
    }

    pub(super) fn flush_requests(&mut self) {
        let now = self.now;
        let mut failed = 0;
        for r in &mut self.requests {
            if !matches!(r.status, RequestStatus::Pending { .. }) || r.next_send > now {
                continue;
            }
            if r.sends >= RETRY_LIMIT {
                r.status = RequestStatus::Failed(format!("no answer from {} after {} tries", r.to, r.sends));
                failed += 1;
                continue;
            }
            r.sends += 1;
            r.status = RequestStatus::Pending { sends: r.sends };
            r.next_send = now + RETRY_INTERVAL;
            self.outbox.push_back(Outgoing {
                to: Destination::Node(r.to),
                message: Message::Control(ControlMessage { id: r.id, body: r.body.clone() }),
            });
        }
        for _ in 0..failed {
            self.request_finished();
        }
    }

    pub(crate) fn connection_infos(&self) -> Vec<ConnectionInfo> {
        let mut v: Vec<ConnectionInfo> = self
            .conns
            .iter()
            .flatten()
            .map(|c| ConnectionInfo {
                id: ConnectionId(c.id),
                source: c.source.clone(),
                destination: c.destination.clone(),
                kind: c.kind,
                priority: c.priority,
                sent: c.seq - c.seq_start,
                requested_by: c.requested_by,
            })
            .collect();
        v.sort_by_key(|c| c.id);
        v
    }

    pub(crate) fn conn_index(&self, id: ConnectionId) -> Option<&Conn> {
        self.conn_ids.get(&id.0).and_then(|&c| self.conns[c as usize].as_ref())
    }
}

fn check_name(behavior: &str, port: &str) -> Result<(), Error> {
    if behavior.is_empty() {
        return Err(Error::EmptyName { what: "behavior" });
    }
    if port.is_empty() {
        return Err(Error::EmptyName { what: "port" });
    }
    Ok(())
}
