//! Registers (rule S2) from outside the processes: ports read (as of the node's time or a
//! later instant) and reset, monostables triggered and read; and the slot and monostable
//! writes a process's `Ctx` makes, which go through the same code so both get the same checks.
//!
//! What it promises: a read answers at the latest time the node was told, or at a later
//! instant asked for (D8.2), never an earlier one (time does not go backwards); a port's
//! freshness is its lifespan's (S4); an empty aggregating port reads as its default. A
//! handle to a removed behavior is an error, never another behavior's port. Values are
//! never coerced (S1): a slot refuses a value of another type.

use crate::behavior::{Mono, Slot};
use crate::error::Error;
use crate::journal::Event;
use crate::port::PortCell;
use crate::time::{Duration, Instant};
use crate::value::Value;

use super::scheduler::queue;
use super::{NodeCore, PortRef};

impl NodeCore {
    /// The port's value, or its default while empty (aggregating ports) — see `get` for
    /// freshness. Answers at the latest time the node was told ([`NodeCore::now`]); use
    /// [`NodeCore::read_at`] to ask about a later instant without polling (D8.2).
    #[inline]
    pub fn read(&self, port: PortRef) -> Result<Value, Error> {
        self.read_at(self.now, port)
    }

    /// [`NodeCore::read`] as of `now` (never before the node's own time: time does not go
    /// backwards). Windows and lifespans that ended by `now` count as ended.
    #[inline]
    pub fn read_at(&self, now: Instant, port: PortRef) -> Result<Value, Error> {
        let now = now.max(self.now);
        self.resolve(port).map(|ps| current(&ps.cell, now).clone())
    }

    /// What `f` makes of the value [`NodeCore::read`] would return, without copying it out:
    /// e.g. `read_with(p, Value::as_float)` for a body's motor command each tick.
    #[inline]
    pub fn read_with<R>(&self, port: PortRef, f: impl FnOnce(&Value) -> R) -> Result<R, Error> {
        self.resolve(port).map(|ps| f(current(&ps.cell, self.now)))
    }

    /// The port's value if fresh (rule S4), else `None`.
    #[inline]
    pub fn get(&self, port: PortRef) -> Result<Option<Value>, Error> {
        self.get_at(self.now, port)
    }

    /// [`NodeCore::get`] as of `now` (see [`NodeCore::read_at`]).
    #[inline]
    pub fn get_at(&self, now: Instant, port: PortRef) -> Result<Option<Value>, Error> {
        let now = now.max(self.now);
        self.resolve(port).map(|ps| ps.cell.get(now).cloned())
    }

    /// Whether the port holds a fresh value (rule S4) at [`NodeCore::now`]; errors for a handle
    /// to a removed behavior.
    #[inline]
    pub fn fresh(&self, port: PortRef) -> Result<bool, Error> {
        self.fresh_at(self.now, port)
    }

    /// [`NodeCore::fresh`] as of `now` (see [`NodeCore::read_at`]).
    #[inline]
    pub fn fresh_at(&self, now: Instant, port: PortRef) -> Result<bool, Error> {
        let now = now.max(self.now);
        self.resolve(port).map(|ps| ps.cell.fresh(now))
    }

    /// When the port last accepted a value (refused writes do not count), if ever — e.g. to
    /// tell which subsumption layer is driving without allocating a report.
    #[inline]
    pub fn last_accepted(&self, port: PortRef) -> Result<Option<Instant>, Error> {
        self.resolve(port).map(|ps| ps.cell.last_accepted())
    }

    /// Whether monostable `mono` of `behavior` is high (rule S2), as of `now` (see
    /// [`NodeCore::read_at`]): true until the end its triggers set, whether or not a poll has
    /// seen the fall yet.
    pub fn monostable_at(&self, now: Instant, behavior: &str, mono: &str) -> Result<bool, Error> {
        let now = now.max(self.now);
        let b = self.behavior_index(behavior)?;
        let beh = self.behavior(b).expect("indexed behavior exists");
        let m = beh
            .class
            .mono_handle(mono)
            .ok_or_else(|| Error::UnknownPort { behavior: behavior.to_owned(), port: mono.to_owned() })?;
        Ok(now < beh.monos[usize::from(m.0)].end)
    }

    /// Empty an aggregating port (a Normal port returns to its default).
    pub fn reset(&mut self, port: PortRef) -> Result<(), Error> {
        self.resolve(port)?;
        if self.journal.is_some() {
            let beh = self.behavior(port.b).expect("resolved");
            let (behavior, name) = (beh.name.clone(), beh.class.ports[usize::from(port.port.0)].name.clone());
            self.journal(|| Event::Reset { behavior, port: name });
        }
        self.behavior_mut(port.b).expect("resolved").ports[usize::from(port.port.0)].cell.reset();
        Ok(())
    }

    /// Trigger monostable `mono` of `behavior` for `period` (rule S2).
    pub fn trigger(&mut self, now: Instant, behavior: &str, mono: &str, period: Duration) -> Result<(), Error> {
        self.advance(now);
        self.journal(|| Event::Trigger { behavior: behavior.to_owned(), mono: mono.to_owned(), period });
        let b = self.behavior_index(behavior)?;
        let m = self
            .behavior(b)
            .and_then(|beh| beh.class.mono_handle(mono))
            .ok_or_else(|| Error::UnknownPort { behavior: behavior.to_owned(), port: mono.to_owned() })?;
        self.trigger_mono(b, m, period);
        Ok(())
    }

    pub(crate) fn trigger_mono(&mut self, b: u32, m: Mono, period: Duration) {
        let now = self.now;
        let Some(beh) = self.behaviors.get_mut(b as usize).and_then(Option::as_mut) else { return };
        let id = beh.id;
        let Some(mono) = beh.monos.get_mut(usize::from(m.0)) else { return };
        let rising = now >= mono.end;
        mono.end = mono.end.max(now + period);
        if rising && mono.end > now {
            mono.high = true;
            for &pi in &mono.watchers {
                queue(&mut self.pending, &mut beh.processes[usize::from(pi)], b, id, pi);
            }
        }
        if mono.high {
            self.schedule.mono_high_until(mono.end);
        }
    }

    pub(crate) fn set_slot(&mut self, b: u32, s: Slot, value: Value) -> Result<(), Error> {
        let Some(beh) = self.behavior_mut(b) else {
            return Err(Error::UnknownBehavior { behavior: format!("#{b}") });
        };
        let Some(slot) = beh.slots.get_mut(usize::from(s.0)) else {
            return Err(Error::UnknownPort { behavior: beh.name.to_string(), port: format!("slot #{}", s.0) });
        };
        if slot.ty() != value.ty() {
            return Err(Error::TypeMismatch {
                what: format!("slot {}.{}", beh.name, beh.class.slots[usize::from(s.0)].name),
                expected: slot.ty(),
                found: value.ty(),
            });
        }
        // Scalars are stored field by field: moving the whole enum in costs a store-forwarding
        // stall (see `port::assign`).
        match (slot, value) {
            (Value::Int(d), Value::Int(x)) => *d = x,
            (Value::Float(d), Value::Float(x)) => *d = x,
            (Value::Bool(d), Value::Bool(x)) => *d = x,
            (slot, value) => *slot = value,
        }
        Ok(())
    }
}

/// The readable value of a cell at `now`: its value, or its default once it released it.
/// Inlined with the readers; a Normal port (never empty) is answered without a call.
#[inline]
pub(crate) fn current(cell: &PortCell, now: Instant) -> &Value {
    if cell.kind.is_aggregating() && cell.is_empty(now) {
        &cell.default
    } else {
        &cell.value
    }
}
