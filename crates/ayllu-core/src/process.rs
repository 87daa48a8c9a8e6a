//! [`Ctx`]: what a running process can see and do (rule S7).
//!
//! A process reaches its own behavior's registers through the handles its class declared.
//! Writes to ports start a propagation wave at once (rule S5); processes triggered by them
//! run after the current process returns, never inside it.
//!
//! A process may also change its node's structure ([`Ctx::change`] and the calls named after
//! each change): the changes wait in the context and are applied, in order, when it returns,
//! before any other process runs (docs/semantics.md, R1–R6). Their outcomes are what the
//! process's next activation reads in [`Ctx::changes`]. Requests to other nodes
//! ([`Ctx::request_connect`]) leave at once, as the node's own would; their answers come back
//! in [`Ctx::request_status`]. Each change and request is a process effect in the journal,
//! so a replay repeats it.

use crate::address::{ConnectionId, Endpoint, NodeId, Source};
use crate::behavior::{Mono, Port, Slot};
use crate::ble::BleConfig;
use crate::change::{Change, ChangeOutcome};
use crate::connection::{ConnectOptions, ConnectionKind};
use crate::counters::DropCause;
use crate::error::Error;
use crate::journal::Event;
use crate::message::ControlBody;
use crate::node::{current, NodeCore, RequestId, RequestStatus};
use crate::time::{Duration, Instant};
use crate::value::Value;

/// The running process's view of its node and behavior.
pub struct Ctx<'a> {
    pub(crate) core: &'a mut NodeCore,
    pub(crate) b: u32,
    /// The running process's number in its behavior.
    pub(crate) pi: u16,
    /// Structure changes asked for, applied when the process returns (R1).
    pub(crate) changes: Vec<Change>,
}

impl Ctx<'_> {
    /// The node's time: the `now` of the poll running this process (node clock, ns).
    #[inline]
    pub fn now(&self) -> Instant {
        self.core.now()
    }
    /// This node's id, e.g. to break ties the way BLE does (lower wins).
    #[inline]
    pub fn node(&self) -> NodeId {
        self.core.id()
    }
    /// The instance name of the running behavior (`OBS1`).
    pub fn behavior(&self) -> &str {
        self.core.behavior(self.b).map_or("", |beh| &beh.name)
    }
    /// The class of the running behavior (`Observer`).
    pub fn class_name(&self) -> &str {
        self.core.behavior(self.b).map_or("", |beh| beh.class.name())
    }

    #[inline]
    fn cell(&self, p: Port) -> Option<&crate::port::PortCell> {
        self.core.behavior(self.b).and_then(|beh| beh.ports.get(usize::from(p.0))).map(|ps| &ps.cell)
    }

    /// The port's value; its default while empty. Use [`Ctx::get`] to respect freshness.
    pub fn read(&self, p: Port) -> Value {
        let now = self.now();
        self.cell(p).map(|c| current(c, now).clone()).unwrap_or(Value::Bool(false))
    }

    /// The port's value if fresh (rule S4), else `None` ("absent").
    pub fn get(&self, p: Port) -> Option<Value> {
        let now = self.now();
        self.cell(p).and_then(|c| c.get(now).cloned())
    }
    /// [`Ctx::get`] without copying the value out (a vector's or text's `Arc` is not
    /// cloned): borrowed from the node, so it ends before the process's next write.
    #[inline]
    pub fn get_ref(&self, p: Port) -> Option<&Value> {
        let now = self.now();
        self.cell(p).and_then(|c| c.get(now))
    }
    /// The port's integer value if fresh and an int.
    #[inline]
    pub fn int(&self, p: Port) -> Option<i64> {
        let now = self.now();
        self.cell(p).and_then(|c| c.get(now)).and_then(Value::as_int)
    }
    /// The port's float value if fresh and a float.
    #[inline]
    pub fn float(&self, p: Port) -> Option<f64> {
        let now = self.now();
        self.cell(p).and_then(|c| c.get(now)).and_then(Value::as_float)
    }
    /// The port's bool value if fresh and a bool.
    #[inline]
    pub fn bool(&self, p: Port) -> Option<bool> {
        let now = self.now();
        self.cell(p).and_then(|c| c.get(now)).and_then(Value::as_bool)
    }
    /// Whether the port holds a fresh value (rule S4); false for an empty aggregating port.
    #[inline]
    pub fn fresh(&self, p: Port) -> bool {
        let now = self.now();
        self.cell(p).is_some_and(|c| c.fresh(now))
    }
    /// Who supplied the port's current value (for Max/Min: the extreme's supplier).
    pub fn supplier(&self, p: Port) -> Option<Source> {
        let now = self.now();
        self.cell(p).filter(|c| c.fresh(now) || !c.kind().is_aggregating()).and_then(|c| c.supplier())
    }
    /// When the port last accepted a value.
    pub fn last_accepted(&self, p: Port) -> Option<Instant> {
        self.cell(p).and_then(|c| c.last_accepted())
    }

    /// Write the behavior's own port. Never blocked by suppression; its propagation can be
    /// stopped by inhibition, another's OverrideOut, or WriteInhibit (rule S6). `Err` says why
    /// the port refused the value (type mismatch, NaN into an ordered port).
    pub fn write(&mut self, p: Port, value: impl Into<Value>) -> Result<(), DropCause> {
        let value = value.into();
        let plain = if self.core.journal.is_some() {
            let recorded = value.clone();
            self.core.journal(|| Event::ProcessWrite { port: p.0, value: recorded });
            self.core.write_plain_at::<true>(self.b, p.0, None, &value)
        } else {
            self.core.write_plain_at::<false>(self.b, p.0, None, &value)
        };
        if plain {
            return Ok(());
        }
        self.core.write_internal(self.b, p.0, &value)
    }

    /// Empty an aggregating port now (the paper's end of "the current cycle").
    pub fn reset(&mut self, p: Port) {
        self.core.journal(|| Event::ProcessReset { port: p.0 });
        if let Some(ps) = self.core.behavior_mut(self.b).and_then(|beh| beh.ports.get_mut(usize::from(p.0))) {
            ps.cell.reset();
        }
    }

    /// The slot's value. Slots have no freshness; a handle from another class reads as `false`.
    #[inline]
    pub fn slot(&self, s: Slot) -> Value {
        self.core
            .behavior(self.b)
            .and_then(|beh| beh.slots.get(usize::from(s.0)))
            .cloned()
            .unwrap_or(Value::Bool(false))
    }
    /// Set a slot (Normal merge, never propagated: slots are not connectable, D2.1). Refused:
    /// a value of another type ([`Error::TypeMismatch`], rule S1), or a handle from another
    /// class ([`Error::UnknownPort`]).
    pub fn set_slot(&mut self, s: Slot, value: impl Into<Value>) -> Result<(), Error> {
        let value = value.into();
        if self.core.journal.is_some() {
            let recorded = value.clone();
            self.core.journal(|| Event::ProcessSetSlot { slot: s.0, value: recorded });
        }
        self.core.set_slot(self.b, s, value)
    }

    /// Make `m` true until at least `now + period` (rule S2: `end := max(end, now + p)`).
    pub fn trigger(&mut self, m: Mono, period: Duration) {
        self.core.journal(|| Event::ProcessTrigger { mono: m.0, period });
        self.core.trigger_mono(self.b, m, period);
    }
    /// Whether monostable `m` is true now.
    pub fn is_high(&self, m: Mono) -> bool {
        let now = self.now();
        self.core.behavior(self.b).and_then(|beh| beh.monos.get(usize::from(m.0))).is_some_and(|mono| now < mono.end)
    }

    // ----- structure (docs/semantics.md, "Reconfiguration") ---------------------------------

    /// Ask for a structure change of this node, applied when the process returns (R1). Returns
    /// its position in this activation's list: the next activation finds its outcome at that
    /// position in [`Ctx::changes`]. Refused at once, and not queued: what is wrong whatever
    /// the node holds ([`Change::check`]); everything else is found when it is applied (R2).
    pub fn change(&mut self, change: Change) -> Result<usize, Error> {
        change.check()?;
        if self.core.journal.is_some() {
            let recorded = change.clone();
            self.core.journal(|| Event::ProcessChange(Box::new(recorded)));
        }
        self.changes.push(change);
        Ok(self.changes.len() - 1)
    }

    /// Ask to create behavior `name` of class `class` (see [`Ctx::change`]).
    pub fn create(&mut self, class: &str, name: &str) -> Result<usize, Error> {
        self.change(Change::Create { class: class.to_owned(), name: name.to_owned() })
    }

    /// Ask to remove behavior `name` (possibly this very one: R3).
    pub fn remove(&mut self, name: &str) -> Result<usize, Error> {
        self.change(Change::Remove { name: name.to_owned() })
    }

    /// Ask to connect `source` (a port of this node) to `destination`.
    pub fn connect(
        &mut self,
        source: &Endpoint,
        destination: &Endpoint,
        kind: ConnectionKind,
        options: ConnectOptions,
    ) -> Result<usize, Error> {
        self.change(Change::Connect {
            source: source.clone(),
            destination: destination.clone(),
            kind,
            priority: options.priority,
        })
    }

    /// Ask to remove connection `conn` of this node.
    pub fn disconnect(&mut self, conn: ConnectionId) -> Result<usize, Error> {
        self.change(Change::Disconnect { conn })
    }

    /// Ask to remove every connection of this node from `source` to `destination`.
    pub fn disconnect_between(&mut self, source: &Endpoint, destination: &Endpoint) -> Result<usize, Error> {
        self.change(Change::DisconnectBetween { source: source.clone(), destination: destination.clone() })
    }

    /// Ask to join broadcast group `group`.
    pub fn join(&mut self, group: &str) -> Result<usize, Error> {
        self.change(Change::Join { group: group.to_owned() })
    }

    /// Ask to leave broadcast group `group`.
    pub fn leave(&mut self, group: &str) -> Result<usize, Error> {
        self.change(Change::Leave { group: group.to_owned() })
    }

    /// Ask to make `behavior` a member of a BLE peer group.
    pub fn ble_join(&mut self, behavior: &str, config: &BleConfig) -> Result<usize, Error> {
        self.change(Change::BleJoin { behavior: behavior.to_owned(), config: config.clone() })
    }

    /// The changes this activation has asked for so far (applied when it returns).
    pub fn pending_changes(&self) -> &[Change] {
        &self.changes
    }

    /// What became of the changes this process's previous activation asked for, in the order
    /// asked (R2). Empty if it asked for none.
    pub fn changes(&self) -> &[ChangeOutcome] {
        self.core
            .behavior(self.b)
            .and_then(|beh| beh.processes.get(usize::from(self.pi)))
            .map_or(&[], |p| p.outcomes.as_slice())
    }

    /// Ask `source`'s node (another node) to connect its port to `destination`, as
    /// [`NodeCore::request_connect`] does; sent at once, answered in [`Ctx::request_status`]
    /// (R6). A `Local` destination means a port of this node.
    pub fn request_connect(
        &mut self,
        source: &Endpoint,
        destination: &Endpoint,
        kind: ConnectionKind,
        options: ConnectOptions,
    ) -> Result<RequestId, Error> {
        let (node, body) = crate::node::connect_request(self.core.id(), source, destination, kind, options)?;
        self.request(node, body)
    }

    /// Ask `node` to remove its connection `conn` (R6).
    pub fn request_disconnect(&mut self, node: NodeId, conn: ConnectionId) -> RequestId {
        self.request(node, ControlBody::Disconnect { conn }).expect("a disconnect is a request")
    }

    /// Send control request `body` to `node` at once, as [`NodeCore::request`] does (R6);
    /// journaled as this process's effect. A reply is not a request.
    pub fn request(&mut self, node: NodeId, body: ControlBody) -> Result<RequestId, Error> {
        if matches!(body, ControlBody::Reply { .. }) {
            return Err(Error::NotLocal { what: "a reply is not a request".into() });
        }
        if self.core.journal.is_some() {
            let recorded = body.clone();
            self.core.journal(|| Event::ProcessRequest { to: node, body: Box::new(recorded) });
        }
        self.core.unjournaled(|core| core.request(node, body))
    }

    /// Where a request this node sent stands (see [`NodeCore::request_status`]).
    pub fn request_status(&self, id: RequestId) -> Option<RequestStatus> {
        self.core.request_status(id)
    }
}
