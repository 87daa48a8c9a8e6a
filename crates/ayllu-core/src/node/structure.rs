//! Structure (rule S9): classes defined, behaviors created and removed, processes added, at
//! run time, and the handles ([`PortRef`], [`BehaviorRef`]) that name what was made.
//!
//! What it promises: removing a behavior removes every connection into or out of it first,
//! so nothing is left pointing at it; messages that later arrive for it are dropped and
//! counted (`unknown_behavior`), and handles to it go stale rather than reaching whatever
//! reuses its slot (behavior ids are never reused). A behavior removed while a process body
//! runs is parked until the body returns, since the body may be one of its own (see
//! `Running`). The schedule of periodic processes is kept in step with every change here.

use std::sync::Arc;

use crate::address::ConnectionId;
use crate::arbitration::Windows;
use crate::behavior::{validate_process, BehaviorClass, Mono, Port, ProcessSpec, Trigger};
use crate::counters::{Counters, DropCause};
use crate::error::Error;
use crate::journal::Event;
use crate::port::PortCell;
use crate::process::Ctx;
use crate::time::Instant;

use super::{Behavior, BehaviorRef, MonoState, NodeCore, PortRef, PortState, ProcState, Running, Target};

impl NodeCore {
    /// Make a behavior class available for [`NodeCore::create`]. A class is immutable once
    /// defined, so one `Arc<BehaviorClass>` may be defined on many nodes: a simulated team
    /// then keeps one copy of each process's closure and port specifications instead of one
    /// per node (its state is in the behaviors' ports and slots, never in the class).
    pub fn define(&mut self, class: impl Into<Arc<BehaviorClass>>) -> Result<(), Error> {
        let class: Arc<BehaviorClass> = class.into();
        if class.name.is_empty() {
            return Err(Error::EmptyName { what: "behavior class" });
        }
        if self.classes.contains_key(&class.name) {
            return Err(Error::DuplicateName { what: "behavior class", name: class.name.clone() });
        }
        self.classes.insert(class.name.clone(), class.clone());
        self.journal(|| Event::Define(class));
        Ok(())
    }

    /// Whether a class of this name has been defined here.
    pub fn has_class(&self, name: &str) -> bool {
        self.classes.contains_key(name)
    }

    /// Instantiate class `class` as behavior `name` (the paper's `ayInitBehavior`).
    pub fn create(&mut self, class: &str, name: &str) -> Result<BehaviorRef, Error> {
        if name.is_empty() {
            return Err(Error::EmptyName { what: "behavior" });
        }
        let class = self.classes.get(class).cloned().ok_or_else(|| Error::UnknownClass { class: class.to_owned() })?;
        if self.names.contains_key(name) {
            return Err(Error::DuplicateName { what: "behavior", name: name.to_owned() });
        }
        let now = self.now;
        let id = self.next_behavior_id;
        self.next_behavior_id += 1;
        let mut ports: Vec<PortState> = class
            .ports
            .iter()
            .map(|spec| PortState {
                plain: false,
                guarded: false,
                trigger_bits: 0,
                cell: PortCell::new(spec),
                windows: Windows::default(),
                out: Vec::new(),
                triggers: Vec::new(),
                visited: 0,
                counters: Counters::default(),
                accepted: 0,
                absorbed: 0,
            })
            .collect();
        let mut monos: Vec<MonoState> =
            class.monos.iter().map(|_| MonoState { end: Instant::ZERO, high: false, watchers: Vec::new() }).collect();
        let mut processes = Vec::with_capacity(class.processes.len());
        for (i, spec) in class.processes.iter().enumerate() {
            attach_trigger(&mut ports, &mut monos, spec.trigger, i as u16);
            processes.push(ProcState::new(spec.clone()));
        }
        ports.iter_mut().for_each(PortState::refresh_plain);
        let behavior = Behavior {
            id,
            name: Arc::from(name),
            slots: class.slots.iter().map(|s| s.default.clone()).collect(),
            class,
            ports,
            monos,
            processes,
            ble: None,
        };
        let b = match self.free_behaviors.pop() {
            Some(b) => {
                self.behaviors[b as usize] = Some(behavior);
                b
            }
            None => {
                self.behaviors.push(Some(behavior));
                (self.behaviors.len() - 1) as u32
            }
        };
        self.names.insert(name.into(), b);
        self.schedule.add_behavior(b, &self.behaviors[b as usize].as_ref().expect("just placed").processes, now);
        self.debug_check_schedule();
        let class = self.behaviors[b as usize].as_ref().map_or(String::new(), |beh| beh.class.name.clone());
        self.journal(|| Event::Create { class, name: name.to_owned() });
        Ok(BehaviorRef { b, id })
    }

    /// Remove a behavior and every connection into or out of it (rule S9). Messages that
    /// later arrive for it are dropped and counted as `unknown_behavior`.
    pub fn remove(&mut self, name: &str) -> Result<(), Error> {
        self.journal(|| Event::Remove { name: name.to_owned() });
        self.unjournaled(|core| core.remove_behavior(name))
    }

    fn remove_behavior(&mut self, name: &str) -> Result<(), Error> {
        let b = *self.names.get(name).ok_or_else(|| Error::UnknownBehavior { behavior: name.to_owned() })?;
        let doomed: Vec<u64> = self
            .conns
            .iter()
            .flatten()
            .filter(|c| c.src.0 == b || matches!(c.dst, Target::Local { b: db, .. } if db == b))
            .map(|c| c.id)
            .collect();
        for id in doomed {
            self.disconnect(ConnectionId(id))?;
        }
        self.names.remove(name);
        let gone = self.behaviors[b as usize].take();
        if let Some(gone) = gone.as_ref() {
            // What its ports absorbed stays in the node-wide figure (see `counters`).
            let absorbed = gone.ports.iter().fold(0u64, |a, p| a.saturating_add(p.absorbed));
            self.counters.add_n(DropCause::Absorbed, absorbed);
        }
        if self.running != Running::Idle {
            // The running body may be among the removed behavior's (see `Running`).
            self.parked.extend(gone);
            self.running = Running::Parked;
        }
        self.behavior_removed();
        self.schedule.remove_behavior(b);
        self.debug_check_schedule();
        self.free_behaviors.push(b);
        Ok(())
    }

    /// Add a process to one behavior instance (used by the BLE helper; also for users who
    /// want an instance-specific process).
    pub fn add_process(
        &mut self,
        behavior: &str,
        name: &str,
        trigger: Trigger,
        body: impl Fn(&mut Ctx<'_>) + Send + Sync + 'static,
    ) -> Result<(), Error> {
        let now = self.now;
        let b = self.behavior_index(behavior)?;
        let beh = self.behaviors[b as usize].as_mut().expect("indexed behavior exists");
        let spec = ProcessSpec { name: name.to_owned(), trigger, body: Arc::new(body) };
        let existing: Vec<ProcessSpec> = beh.processes.iter().map(|p| p.spec.clone()).collect();
        validate_process(&beh.name, &spec, beh.ports.len(), beh.monos.len(), &existing)?;
        let ix = u16::try_from(beh.processes.len())
            .map_err(|_| Error::TooManyRegisters { behavior: behavior.to_owned() })?;
        attach_trigger(&mut beh.ports, &mut beh.monos, spec.trigger, ix);
        let trigger = spec.trigger;
        beh.processes.push(ProcState::new(spec));
        if trigger.period().is_some() {
            self.schedule.add_process(b, ix, beh.processes.last().expect("just pushed"), now);
            self.debug_check_schedule();
        }
        self.journal(|| Event::AddProcess { behavior: behavior.to_owned(), name: name.to_owned(), trigger });
        Ok(())
    }

    /// Whether class `class` has a port named `port`; `None` if no such class is defined.
    pub(crate) fn class_port(&self, class: &str, port: &str) -> Option<bool> {
        self.classes.get(class).map(|c| c.port_handle(port).is_some())
    }

    /// The value type of port `port` of class `class`, if both exist.
    pub(crate) fn class_port_type(&self, class: &str, port: &str) -> Option<crate::value::ValueType> {
        let c = self.classes.get(class)?;
        c.port_handle(port).map(|h| c.ports[usize::from(h.0)].ty())
    }

    /// The id the next connection made on this node will get (ids are never reused).
    pub(crate) fn next_connection_id(&self) -> u64 {
        self.next_conn_id
    }

    /// Whether the existing behavior `name` is in a BLE group.
    pub(crate) fn in_ble_group(&self, name: &str) -> bool {
        self.behavior_index(name).ok().and_then(|b| self.behavior(b)).is_some_and(|b| b.ble.is_some())
    }

    /// The class of behavior `name`, if it exists.
    pub(crate) fn class_name_of(&self, name: &str) -> Option<String> {
        let b = self.behavior_index(name).ok()?;
        self.behavior(b).map(|beh| beh.class.name.clone())
    }

    pub(crate) fn behavior_index(&self, name: &str) -> Result<u32, Error> {
        self.names.get(name).copied().ok_or_else(|| Error::UnknownBehavior { behavior: name.to_owned() })
    }

    pub(crate) fn behavior(&self, b: u32) -> Option<&Behavior> {
        self.behaviors.get(b as usize).and_then(Option::as_ref)
    }

    pub(crate) fn behavior_mut(&mut self, b: u32) -> Option<&mut Behavior> {
        self.behaviors.get_mut(b as usize).and_then(Option::as_mut)
    }

    /// A handle to `behavior.port` for fast repeated writes and reads.
    pub fn port(&self, behavior: &str, port: &str) -> Result<PortRef, Error> {
        let b = self.behavior_index(behavior)?;
        let beh = self.behavior(b).expect("indexed behavior exists");
        match beh.class.port_handle(port) {
            Some(p) => Ok(PortRef { b, id: beh.id, port: p }),
            None if beh.class.slot_handle(port).is_some() => {
                Err(Error::NotAPort { behavior: behavior.to_owned(), name: port.to_owned() })
            }
            None => Err(Error::UnknownPort { behavior: behavior.to_owned(), port: port.to_owned() }),
        }
    }

    /// A handle to the port whose handle within its class is `port` (as the class's
    /// processes know it), of behavior `behavior`; [`NodeCore::port`] finds it by name.
    pub fn port_by_handle(&self, behavior: &str, port: Port) -> Result<PortRef, Error> {
        let b = self.behavior_index(behavior)?;
        let beh = self.behavior(b).expect("indexed behavior exists");
        if usize::from(port.0) >= beh.ports.len() {
            return Err(Error::UnknownPort { behavior: behavior.to_owned(), port: format!("#{}", port.0) });
        }
        Ok(PortRef { b, id: beh.id, port })
    }

    /// The behavior handle for `name`.
    pub fn behavior_ref(&self, name: &str) -> Result<BehaviorRef, Error> {
        let b = self.behavior_index(name)?;
        Ok(BehaviorRef { b, id: self.behavior(b).expect("indexed behavior exists").id })
    }

    /// The port a handle names, if its behavior still lives. Inlined into the readers below
    /// (which a body calls for every robot each tick), its error built out of line.
    #[inline]
    pub(crate) fn resolve(&self, r: PortRef) -> Result<&PortState, Error> {
        match self.behavior(r.b).filter(|beh| beh.id == r.id).and_then(|beh| beh.ports.get(usize::from(r.port.0))) {
            Some(ps) => Ok(ps),
            None => Err(stale_handle(r)),
        }
    }
}

/// The error for a handle whose behavior was removed (or whose slot was reused).
#[cold]
#[inline(never)]
fn stale_handle(r: PortRef) -> Error {
    Error::UnknownBehavior { behavior: format!("(removed behavior #{})", r.id) }
}

fn attach_trigger(ports: &mut [PortState], monos: &mut [MonoState], trigger: Trigger, ix: u16) {
    match trigger {
        Trigger::OnWrite(Port(p)) => {
            let port = &mut ports[usize::from(p)];
            port.add_trigger(ix);
            port.refresh_plain();
        }
        Trigger::OnMonostable(Mono(m)) => monos[usize::from(m)].watchers.push(ix),
        // The schedule checks the guard port at each due time, unless it knows the port has
        // been stale since an earlier one: the port tells it when it accepts.
        Trigger::PeriodicWhileFresh(_, Port(p)) => {
            let port = &mut ports[usize::from(p)];
            port.guarded = true;
            port.refresh_plain();
        }
        Trigger::Periodic(_) => {}
    }
}
