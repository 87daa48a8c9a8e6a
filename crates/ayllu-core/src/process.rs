//! [`Ctx`]: what a running process can see and do (rule S7).
//!
//! A process reaches its own behavior's registers through the handles its class declared.
//! Writes to ports start a propagation wave at once (rule S5); processes triggered by them
//! run after the current process returns, never inside it.

use crate::address::{NodeId, Source};
use crate::behavior::{Mono, Port, Slot};
use crate::counters::DropCause;
use crate::error::Error;
use crate::journal::Event;
use crate::node::{current, NodeCore};
use crate::time::{Duration, Instant};
use crate::value::Value;

/// The running process's view of its node and behavior.
pub struct Ctx<'a> {
    pub(crate) core: &'a mut NodeCore,
    pub(crate) b: u32,
}

impl Ctx<'_> {
    /// The node's time: the `now` of the poll running this process (node clock, ns).
    pub fn now(&self) -> Instant {
        self.core.now()
    }
    /// This node's id, e.g. to break ties the way BLE does (lower wins).
    pub fn node(&self) -> NodeId {
        self.core.id()
    }
    /// The instance name of the running behavior (`OBS1`).
    pub fn behavior(&self) -> &str {
        self.core.behavior(self.b).map_or("", |beh| &beh.name)
    }

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
    /// The port's integer value if fresh and an int.
    pub fn int(&self, p: Port) -> Option<i64> {
        let now = self.now();
        self.cell(p).and_then(|c| c.get(now)).and_then(Value::as_int)
    }
    /// The port's float value if fresh and a float.
    pub fn float(&self, p: Port) -> Option<f64> {
        let now = self.now();
        self.cell(p).and_then(|c| c.get(now)).and_then(Value::as_float)
    }
    /// The port's bool value if fresh and a bool.
    pub fn bool(&self, p: Port) -> Option<bool> {
        let now = self.now();
        self.cell(p).and_then(|c| c.get(now)).and_then(Value::as_bool)
    }
    /// Whether the port holds a fresh value (rule S4); false for an empty aggregating port.
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
        self.cell(p).and_then(|c| c.last_accepted)
    }

    /// Write the behavior's own port. Never blocked by suppression; its propagation can be
    /// stopped by inhibition, another's OverrideOut, or WriteInhibit (rule S6). `Err` says why
    /// the port refused the value (type mismatch, NaN into an ordered port).
    pub fn write(&mut self, p: Port, value: impl Into<Value>) -> Result<(), DropCause> {
        let value = value.into();
        if self.core.journal.is_some() {
            let recorded = value.clone();
            self.core.journal(|| Event::ProcessWrite { port: p.0, value: recorded });
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
}
