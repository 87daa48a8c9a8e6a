//! Writes and propagation (rules S3–S6): a value written into a port, merged by the port's
//! kind, and carried on along its connections as one wave.
//!
//! What it promises: propagation is synchronous and depth-first inside the call that starts
//! it (a write, or a message received); every port is written at most once per wave (the
//! wave mark), so wiring cycles terminate; the value that travels is the port's value after
//! its merge. A behavior's own write is not stopped by suppression, only its propagation by
//! inhibition and write-inhibition (S6); a special connection's window takes effect when its
//! message arrives, whatever blocks are in force (D6.2). Remote destinations become numbered
//! port messages in the outbox. The explicit stack and the trigger queue are reused, so a
//! scalar propagates without allocating; the common local hop is taken without a stack
//! frame, and the unchecked fast path is `crate::plain`'s.

use crate::address::{ConnectionId, Source};
use crate::arbitration::{Origin, WindowKind};
use crate::connection::ConnectionKind;
use crate::counters::DropCause;
use crate::error::Error;
use crate::journal::{journal_value, JournalValue};
use crate::message::{Message, Outgoing, PortMessage};
use crate::time::Instant;
use crate::value::Value;

use super::{Edge, NodeCore, PortRef, PortState, Target};

/// Where a wave stands at one port: the next of its outgoing connections to take.
#[derive(Copy, Clone)]
pub(super) struct Frame {
    b: u32,
    p: u16,
    next: u32,
}

impl NodeCore {
    /// Write `value` into a port as its own behavior would (rule S6: suppression does not stop
    /// it; inhibition and write-inhibition stop its propagation). Triggered processes run at
    /// the next `poll`.
    #[inline]
    pub fn write(&mut self, now: Instant, port: PortRef, value: impl Into<Value>) -> Result<(), Error> {
        self.advance(now);
        let value = value.into();
        if self.write_plain(port, &value) {
            return Ok(());
        }
        self.resolve(port)?;
        if self.journal.is_some() {
            self.journal_write(port, &value);
        }
        self.write_internal(port.b, port.port.0, &value).map_err(|cause| self.drop_error(port, cause, &value))
    }

    /// Write by name; see [`NodeCore::write`].
    pub fn write_named(
        &mut self,
        now: Instant,
        behavior: &str,
        port: &str,
        value: impl Into<Value>,
    ) -> Result<(), Error> {
        let r = self.port(behavior, port)?;
        self.write(now, r, value)
    }

    fn drop_error(&self, port: PortRef, cause: DropCause, value: &Value) -> Error {
        let beh = self.behavior(port.b).expect("resolved");
        let spec = &beh.class.ports[usize::from(port.port.0)];
        let what = format!("port {}.{}", beh.name, spec.name);
        match cause {
            DropCause::TypeMismatch => Error::TypeMismatch { what, expected: spec.ty(), found: value.ty() },
            _ => Error::Refused { what, cause },
        }
    }

    /// A behavior's own write. `Ok` if the port stored the value (propagated or not);
    /// `Err(cause)` for a type mismatch or NaN (refused). `Absorbed` is reported as `Ok`.
    pub(crate) fn write_internal(&mut self, b: u32, p: u16, value: &Value) -> Result<(), DropCause> {
        self.wave += 1;
        let (now, wave, me) = (self.now, self.wave, self.id);
        let Some(beh) = self.behaviors.get_mut(b as usize).and_then(Option::as_mut) else {
            self.counters.add(DropCause::UnknownBehavior);
            return Err(DropCause::UnknownBehavior);
        };
        let id = beh.id;
        let Some(port) = beh.ports.get_mut(usize::from(p)) else {
            self.counters.add(DropCause::UnknownPort);
            return Err(DropCause::UnknownPort);
        };
        if let Err(cause) = port.cell.merge(now, value, Source::internal(me), 0) {
            port.count_both(&mut self.counters, cause);
            return if cause == DropCause::Absorbed { Ok(()) } else { Err(cause) };
        }
        port.visited = wave;
        port.accepted += 1;
        if let Some(j) = self.journal.as_deref_mut() {
            journal_value(j, now, JournalValue::Accepted, (b, id), (&beh.name, &beh.class), p, &port.cell.value);
        }
        port.queue_triggered(&mut self.pending, &mut beh.processes, b, id);
        if port.guarded {
            self.schedule.guard_accepted(b);
        }
        // A port with nowhere to send has nothing to block: only real blocks are counted.
        if port.out.is_empty() {
            return Ok(());
        }
        match port.windows.admit_propagation(now, Origin::Internal) {
            Ok(()) => self.propagate_from(b, p),
            Err(cause) => {
                port.count_both(&mut self.counters, cause);
            }
        }
        Ok(())
    }

    /// The wave from port (b, p), which has just accepted and may propagate (rule S5): the
    /// common cases — local edges into ports that do not pass the value on, and remote
    /// destinations, where the wave ends in a message — are taken here without a stack frame.
    /// The first edge that needs more (a destination that propagates further) hands the rest
    /// of the wave to [`NodeCore::run_wave`] at exactly that point, so the depth-first order,
    /// and every check `deliver` makes, are those of the general path.
    #[inline]
    pub(crate) fn propagate_from(&mut self, b: u32, p: u16) {
        self.propagate_from_edge(b, p, 0);
    }

    /// [`NodeCore::propagate_from`] from the port's edge `next` on (the ones before it taken).
    pub(crate) fn propagate_from_edge(&mut self, b: u32, p: u16, mut next: u32) {
        let me = self.id;
        loop {
            let Some(beh) = self.behaviors.get(b as usize).and_then(Option::as_ref) else { return };
            let port = &beh.ports[usize::from(p)];
            let Some(&edge) = port.out.get(next as usize) else { return };
            let last = next as usize + 1 == port.out.len();
            let value = port.cell.value.clone();
            next += 1;
            let Some((db, dp)) = edge.local else {
                // A remote edge ends there: taken here, not by the general loop's frame.
                self.send_along(edge, value);
                if last {
                    return;
                }
                continue;
            };
            let from = Source::connection(me, ConnectionId(edge.id));
            if edge.kind == ConnectionKind::Normal && self.hop_plain_checked(db, dp, from, &value) {
                if last {
                    return;
                }
                continue;
            }
            if self.deliver(db, dp, edge.kind, from, edge.priority, &value) {
                if !last {
                    self.stack.push(Frame { b, p, next });
                }
                self.stack.push(Frame { b: db, p: dp, next: 0 });
                self.run_wave();
                return;
            }
            if last {
                return;
            }
        }
    }

    /// Depth-first propagation from the frames on the stack (rule S5).
    fn run_wave(&mut self) {
        let me = self.id;
        while let Some(top) = self.stack.last_mut() {
            let Frame { b, p, next } = *top;
            let Some(beh) = self.behaviors.get(b as usize).and_then(Option::as_ref) else {
                self.stack.pop();
                continue;
            };
            let port = &beh.ports[usize::from(p)];
            let Some(&edge) = port.out.get(next as usize) else {
                self.stack.pop();
                continue;
            };
            // Taking the port's last connection finishes its frame: pop it now rather than
            // revisit it (same depth-first order; `out` cannot change during a wave).
            if next as usize + 1 == port.out.len() {
                self.stack.pop();
            } else {
                top.next += 1;
            }
            let value = port.cell.value.clone();
            if let Some((db, dp)) = edge.local {
                let from = Source::connection(me, ConnectionId(edge.id));
                if self.deliver(db, dp, edge.kind, from, edge.priority, &value) {
                    self.stack.push(Frame { b: db, p: dp, next: 0 });
                }
                continue;
            }
            self.send_along(edge, value);
        }
    }

    /// The remote end of a wave: a numbered port message along `edge` (a connection to
    /// another node) into the outbox. Nothing follows from it on this node, so the wave goes
    /// on with the next edge, whichever loop took this one.
    #[inline(always)]
    pub(crate) fn send_along(&mut self, edge: Edge, value: Value) {
        let Some(conn) = self.conns.get_mut(edge.conn as usize).and_then(Option::as_mut) else { return };
        if let Target::Remote { to, behavior, port } = &conn.dst {
            conn.seq += 1;
            let message = Message::Port(PortMessage {
                conn: ConnectionId(conn.id),
                seq: conn.seq,
                behavior: behavior.clone(),
                port: port.clone(),
                kind: edge.kind,
                priority: edge.priority,
                value,
            });
            self.outbox.push_back(Outgoing { to: to.clone(), message });
        }
    }

    /// Apply one message arriving along a connection at local port (b, p). Returns whether the
    /// value was stored *and* may propagate.
    #[inline]
    fn deliver(&mut self, b: u32, p: u16, kind: ConnectionKind, from: Source, priority: i32, value: &Value) -> bool {
        let Some(beh) = self.behaviors.get_mut(b as usize).and_then(Option::as_mut) else {
            self.counters.add(DropCause::UnknownBehavior);
            return false;
        };
        let Some(port) = beh.ports.get_mut(usize::from(p)) else {
            self.counters.add(DropCause::UnknownPort);
            return false;
        };
        let port: *mut PortState = port;
        // SAFETY: `port` is port `p` of the live behavior in slot `b`, borrowed just above and
        // released; nothing else refers to it during the call.
        unsafe { self.deliver_to(b, p, port, kind, from, priority, value) }
    }

    /// [`NodeCore::deliver`] at a port already found: `port` is port `p` of behavior slot `b`.
    /// The behavior itself is read only when it must be (the port triggers processes, or the
    /// journal records the value), so a message whose port the sequence table remembers
    /// ([`crate::sequence::SeqEntry`]) loads the port's line and the behavior's side by side
    /// instead of the behavior's first and the port's after it (its address is in the
    /// behavior): one cold load less on the chain of every remote message.
    ///
    /// # Safety
    /// `port` points to port `p` of the live behavior in slot `b`, inside that behavior's
    /// `ports` buffer (which neither moves nor changes length while the behavior lives), and
    /// no reference to that port is alive during the call.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(super) unsafe fn deliver_to(
        &mut self,
        b: u32,
        p: u16,
        port: *mut PortState,
        kind: ConnectionKind,
        from: Source,
        priority: i32,
        value: &Value,
    ) -> bool {
        let (now, wave) = (self.now, self.wave);
        // SAFETY: the caller's promise; `self.behaviors` below is read for other fields of
        // the behavior (its id, processes, name), never for its ports.
        let port = unsafe { &mut *port };
        // An override's value must be one the port could take (type, NaN, shape): a message
        // refused as invalid opens no window (D6.7). The blocking kinds carry no value to check.
        if matches!(kind, ConnectionKind::OverrideIn(_) | ConnectionKind::OverrideOut(_)) {
            if let Err(cause) = port.cell.check(value) {
                port.count_both(&mut self.counters, cause);
                return false;
            }
        }
        // A special connection's window always takes effect when its message arrives; only
        // the write of `m` itself is subject to the blocks in force (docs/semantics.md, D6.2).
        if kind != ConnectionKind::Normal {
            port.plain = false; // a window opens below
        }
        match kind {
            ConnectionKind::Normal => {}
            ConnectionKind::Suppress(d) => {
                port.windows.refresh(now, WindowKind::Suppress, from, now + d);
                return false;
            }
            ConnectionKind::Inhibit(d) => {
                port.windows.refresh(now, WindowKind::Inhibit, from, now + d);
                return false;
            }
            ConnectionKind::WriteInhibit(d) => {
                port.windows.refresh(now, WindowKind::WriteInhibit, from, now + d);
                return false;
            }
            ConnectionKind::OverrideIn(d) => port.windows.refresh(now, WindowKind::OverrideIn, from, now + d),
            ConnectionKind::OverrideOut(d) => port.windows.refresh(now, WindowKind::OverrideOut, from, now + d),
        }
        let outcome = if port.visited == wave {
            Err(DropCause::WaveRevisit)
        } else {
            port.windows.admit_write(now, from).and_then(|()| port.cell.merge(now, value, from, priority))
        };
        if let Err(cause) = outcome {
            port.count_both(&mut self.counters, cause);
            return false;
        }
        port.visited = wave;
        port.accepted += 1;
        if let Some(j) = self.journal.as_deref_mut() {
            let beh = self.behaviors[b as usize].as_ref().expect("the caller's live behavior");
            journal_value(j, now, JournalValue::Accepted, (b, beh.id), (&beh.name, &beh.class), p, &port.cell.value);
        }
        if port.trigger_bits != 0 {
            let beh = self.behaviors[b as usize].as_mut().expect("the caller's live behavior");
            let id = beh.id;
            port.queue_triggered(&mut self.pending, &mut beh.processes, b, id);
        }
        if port.guarded {
            self.schedule.guard_accepted(b);
        }
        if port.out.is_empty() {
            return false;
        }
        match port.windows.admit_propagation(now, Origin::Connection(from)) {
            Ok(()) => true,
            Err(cause) => {
                port.count_both(&mut self.counters, cause);
                false
            }
        }
    }

    /// Journal a write from outside (kept out of line: `write` is the hot path).
    #[cold]
    #[inline(never)]
    fn journal_write(&mut self, port: PortRef, value: &Value) {
        let now = self.now;
        let Some(beh) = self.behaviors.get(port.b as usize).and_then(Option::as_ref) else { return };
        if let Some(j) = self.journal.as_deref_mut() {
            j.push_value(now, JournalValue::Write, (port.b, beh.id), (&beh.name, &beh.class), port.port.0, value);
        }
    }
}
