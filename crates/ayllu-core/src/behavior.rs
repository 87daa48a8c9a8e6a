//! Behavior classes: the declared interface (ports, slots, monostables) and processes
//! (rules S2, S7).
//!
//! A [`BehaviorClass`] is a template, defined once per node and instantiated by name (`OBS1`,
//! `OBS2`, ...). Declaring returns typed handles ([`Port`], [`Slot`], [`Mono`]) that processes
//! use to reach their registers without string lookups. Every class implicitly has the BLE
//! ports `Local` (Normal float), `Inhibit` (Normal bool) and `Best` (Max float) — rule S11 —
//! at the fixed handles [`Port::LOCAL`], [`Port::INHIBIT`], [`Port::BEST`].

use std::fmt;
use std::sync::Arc;

use crate::error::Error;
use crate::port::{PortKind, PortSpec};
use crate::process::Ctx;
use crate::time::Duration;
use crate::value::Value;

/// A port of a behavior, as seen by its own processes.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Port(pub u16);
/// A slot: a register only the behavior's own processes see.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Slot(pub u16);
/// A monostable: true for a while after it is triggered.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Mono(pub u16);

impl Port {
    /// BLE: this behavior's local eligibility for its task (Normal float).
    pub const LOCAL: Port = Port(0);
    /// BLE: written when this behavior claims its task (Normal bool).
    pub const INHIBIT: Port = Port(1);
    /// BLE: the best eligibility heard from peers this cycle (Max float).
    pub const BEST: Port = Port(2);
}

/// The name of the implicit BLE port [`Port::LOCAL`] (rule S11). Reserved: declaring a
/// register of this name fails with [`Error::ReservedName`].
pub const LOCAL: &str = "Local";
/// The name of the implicit BLE port [`Port::INHIBIT`] (rule S11); reserved like [`LOCAL`].
pub const INHIBIT: &str = "Inhibit";
/// The name of the implicit BLE port [`Port::BEST`] (rule S11); reserved like [`LOCAL`].
pub const BEST: &str = "Best";

/// When a process runs.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Trigger {
    /// Every period, phase-locked to the behavior's creation; late activations are skipped
    /// and counted, never run in a burst.
    Periodic(Duration),
    /// Whenever this port of the behavior accepts a value (from a connection or a process).
    OnWrite(Port),
    /// Whenever this monostable rises or falls.
    OnMonostable(Mono),
    /// As `Periodic`, at the same due times, but only while this port of the behavior holds
    /// a fresh value (S4): a due time at which it does not is not an activation — the body
    /// is not run and nothing is counted (D7.5). For a body that does nothing without that
    /// port's value (the paper's observers: "no output when the target is not seen").
    PeriodicWhileFresh(Duration, Port),
}

impl Trigger {
    /// The period of a periodic trigger (`Periodic` or `PeriodicWhileFresh`).
    pub fn period(&self) -> Option<Duration> {
        match *self {
            Trigger::Periodic(p) | Trigger::PeriodicWhileFresh(p, _) => Some(p),
            Trigger::OnWrite(_) | Trigger::OnMonostable(_) => None,
        }
    }
}

/// A process body. It runs to completion; it must not block.
pub type ProcessFn = Arc<dyn Fn(&mut Ctx<'_>) + Send + Sync>;

/// A declared process.
#[derive(Clone)]
pub struct ProcessSpec {
    /// Unique within the behavior; reports and `why` name the process by it.
    pub name: String,
    /// When it runs (rule S7).
    pub trigger: Trigger,
    /// The code it runs, shared by every instance of the class.
    pub body: ProcessFn,
}

impl fmt::Debug for ProcessSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("ProcessSpec").field("name", &self.name).field("trigger", &self.trigger).finish()
    }
}

/// A slot declaration.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct SlotSpec {
    /// Unique among the behavior's registers (ports, slots, monostables).
    pub name: String,
    /// The initial value; its type is the slot's type for good (rule S1).
    pub default: Value,
}

/// A behavior class: interface plus processes.
///
/// Build it once, [`NodeCore::define`](crate::NodeCore::define) it on a node, then
/// [`NodeCore::create`](crate::NodeCore::create) as many instances as needed. Declaring a
/// register returns the handle its processes use; processes run only inside
/// [`NodeCore::poll`](crate::NodeCore::poll) (rule S7).
///
/// ```
/// use ayllu_core::*;
///
/// let mut c = BehaviorClass::new("Avoid");
/// let range = c.port(PortSpec::new("Range", 10.0))?; // metres, written by a sonar
/// let turn = c.port(PortSpec::new("Turn", 0.0))?; // rad/s, to the motors
/// let seen = c.slot("Seen", 0i64)?; // internal count, not connectable
/// let backing = c.monostable("Backing")?; // true for a while after a trigger (S2)
/// // Triggered: runs when Range accepts a value; an obstacle closer than 0.5 m starts a
/// // 2 s turn (a second trigger while high only extends it).
/// c.on_write("React", range, move |ctx| {
///     if ctx.float(range).is_some_and(|r| r < 0.5) {
///         ctx.trigger(backing, Duration::from_secs(2));
///         let n = ctx.slot(seen).as_int().unwrap_or(0);
///         ctx.set_slot(seen, n + 1).unwrap();
///     }
/// })?;
/// // Periodic: 10 Hz, phase-locked to the behavior's creation.
/// c.every_hz("Steer", 10.0, move |ctx| {
///     let w = if ctx.is_high(backing) { 1.0 } else { 0.0 };
///     ctx.write(turn, w).unwrap();
/// })?;
/// assert_eq!(c.port_handle("Turn"), Some(turn));
/// assert_eq!(c.ports()[0].name, LOCAL); // the BLE ports come first
/// assert!(matches!(c.slot("Best", 0.0), Err(Error::ReservedName { .. })));
///
/// let mut node = NodeCore::new(NodeId(1));
/// node.define(c)?;
/// node.create("Avoid", "A")?;
/// let (r, t) = (node.port("A", "Range")?, node.port("A", "Turn")?);
/// node.write(Instant::from_millis(50), r, 0.3)?;
/// node.poll(Instant::from_millis(50)); // React, then Steer's first activation
/// assert_eq!(node.read(t)?, Value::Float(1.0));
/// assert!(node.monostable_at(Instant::from_millis(2049), "A", "Backing")?);
/// assert!(!node.monostable_at(Instant::from_millis(2050), "A", "Backing")?);
/// # Ok::<(), Error>(())
/// ```
#[derive(Clone, Debug)]
pub struct BehaviorClass {
    pub(crate) name: String,
    pub(crate) ports: Vec<PortSpec>,
    pub(crate) slots: Vec<SlotSpec>,
    pub(crate) monos: Vec<String>,
    pub(crate) processes: Vec<ProcessSpec>,
}

impl BehaviorClass {
    /// A new class with only the implicit BLE ports.
    pub fn new(name: &str) -> BehaviorClass {
        BehaviorClass {
            name: name.to_owned(),
            ports: vec![
                PortSpec::new(LOCAL, 0.0),
                PortSpec::new(INHIBIT, false),
                PortSpec::new(BEST, 0.0).kind(PortKind::Max),
            ],
            slots: Vec::new(),
            monos: Vec::new(),
            processes: Vec::new(),
        }
    }

    /// The class name, as [`NodeCore::create`](crate::NodeCore::create) takes it.
    pub fn name(&self) -> &str {
        &self.name
    }

    fn check_new_name(&self, what: &'static str, name: &str) -> Result<(), Error> {
        if name.is_empty() {
            return Err(Error::EmptyName { what });
        }
        if [LOCAL, INHIBIT, BEST].contains(&name) {
            return Err(Error::ReservedName {
                name: format!("{}.{name}", self.name),
                reason:
                    "every behavior already has the BLE ports Local, Inhibit and Best (rule S11); choose another name",
            });
        }
        let taken = self.ports.iter().any(|p| p.name == name)
            || self.slots.iter().any(|s| s.name == name)
            || self.monos.iter().any(|m| m == name);
        if taken {
            return Err(Error::DuplicateName { what: "register", name: format!("{}.{}", self.name, name) });
        }
        Ok(())
    }

    fn next_index(&self, len: usize) -> Result<u16, Error> {
        u16::try_from(len).map_err(|_| Error::TooManyRegisters { behavior: self.name.clone() })
    }

    /// Declare a port. Refused: an empty, reserved ([`Error::ReservedName`]) or taken name
    /// ([`Error::DuplicateName`]), and a spec its kind cannot honour
    /// ([`Error::KindNotSupported`], [`Error::ZeroWindow`], [`Error::WindowOnNormalPort`],
    /// [`Error::VectorShape`]).
    pub fn port(&mut self, spec: PortSpec) -> Result<Port, Error> {
        self.check_new_name("port", &spec.name)?;
        spec.validate()?;
        let ix = self.next_index(self.ports.len())?;
        self.ports.push(spec);
        Ok(Port(ix))
    }

    /// Declare a slot (internal register, Normal merge, not connectable).
    pub fn slot(&mut self, name: &str, default: impl Into<Value>) -> Result<Slot, Error> {
        self.check_new_name("slot", name)?;
        let ix = self.next_index(self.slots.len())?;
        self.slots.push(SlotSpec { name: name.to_owned(), default: default.into() });
        Ok(Slot(ix))
    }

    /// Declare a monostable.
    pub fn monostable(&mut self, name: &str) -> Result<Mono, Error> {
        self.check_new_name("monostable", name)?;
        let ix = self.next_index(self.monos.len())?;
        self.monos.push(name.to_owned());
        Ok(Mono(ix))
    }

    /// Declare a process with any trigger. Refused: an empty or taken process name, a zero
    /// period ([`Error::ZeroProcessPeriod`]), a port or monostable handle this class did not
    /// declare ([`Error::UnknownPort`]).
    pub fn process(
        &mut self,
        name: &str,
        trigger: Trigger,
        body: impl Fn(&mut Ctx<'_>) + Send + Sync + 'static,
    ) -> Result<(), Error> {
        let spec = ProcessSpec { name: name.to_owned(), trigger, body: Arc::new(body) };
        validate_process(&self.name, &spec, self.ports.len(), self.monos.len(), &self.processes)?;
        self.processes.push(spec);
        Ok(())
    }

    /// Declare a periodic process at `hz` activations per second (the paper's
    /// `ratepersecond`). A rate that is not finite and above zero is refused with
    /// [`Error::InvalidRate`] (D7.4).
    pub fn every_hz(
        &mut self,
        name: &str,
        hz: f64,
        body: impl Fn(&mut Ctx<'_>) + Send + Sync + 'static,
    ) -> Result<(), Error> {
        let period = Duration::try_from_hz(hz)?;
        self.process(name, Trigger::Periodic(period), body)
    }

    /// Declare a periodic process at `hz` activations per second that is activated only while
    /// `port` holds a fresh value ([`Trigger::PeriodicWhileFresh`], D7.5): the same due times
    /// as [`BehaviorClass::every_hz`], without the runs that would find the port stale. A rate
    /// that is not finite and above zero is refused with [`Error::InvalidRate`], a port this
    /// class did not declare with [`Error::UnknownPort`].
    pub fn every_hz_while_fresh(
        &mut self,
        name: &str,
        hz: f64,
        port: Port,
        body: impl Fn(&mut Ctx<'_>) + Send + Sync + 'static,
    ) -> Result<(), Error> {
        let period = Duration::try_from_hz(hz)?;
        self.process(name, Trigger::PeriodicWhileFresh(period, port), body)
    }

    /// Declare a process that runs when `port` accepts a value.
    pub fn on_write(
        &mut self,
        name: &str,
        port: Port,
        body: impl Fn(&mut Ctx<'_>) + Send + Sync + 'static,
    ) -> Result<(), Error> {
        self.process(name, Trigger::OnWrite(port), body)
    }

    /// Declare a process that runs when `mono` rises or falls.
    pub fn on_monostable(
        &mut self,
        name: &str,
        mono: Mono,
        body: impl Fn(&mut Ctx<'_>) + Send + Sync + 'static,
    ) -> Result<(), Error> {
        self.process(name, Trigger::OnMonostable(mono), body)
    }

    /// The handle of a declared port, by name.
    pub fn port_handle(&self, name: &str) -> Option<Port> {
        self.ports.iter().position(|p| p.name == name).map(|i| Port(i as u16))
    }
    /// The handle of a declared slot, by name.
    pub fn slot_handle(&self, name: &str) -> Option<Slot> {
        self.slots.iter().position(|p| p.name == name).map(|i| Slot(i as u16))
    }
    /// The handle of a declared monostable, by name.
    pub fn mono_handle(&self, name: &str) -> Option<Mono> {
        self.monos.iter().position(|p| p == name).map(|i| Mono(i as u16))
    }
    /// Every port in handle order: the BLE ports `Local`, `Inhibit`, `Best` (handles 0–2), then
    /// the declared ones.
    pub fn ports(&self) -> &[PortSpec] {
        &self.ports
    }
    /// Every slot in handle order.
    pub fn slots(&self) -> &[SlotSpec] {
        &self.slots
    }
    /// The monostables' names in handle order.
    pub fn monostables(&self) -> &[String] {
        &self.monos
    }
    /// The processes in declaration order, which is their order within a poll (D7.1).
    pub fn processes(&self) -> &[ProcessSpec] {
        &self.processes
    }
}

pub(crate) fn validate_process(
    behavior: &str,
    spec: &ProcessSpec,
    n_ports: usize,
    n_monos: usize,
    existing: &[ProcessSpec],
) -> Result<(), Error> {
    if spec.name.is_empty() {
        return Err(Error::EmptyName { what: "process" });
    }
    if existing.iter().any(|p| p.name == spec.name) {
        return Err(Error::DuplicateName { what: "process", name: format!("{behavior}.{}", spec.name) });
    }
    match spec.trigger {
        Trigger::Periodic(p) | Trigger::PeriodicWhileFresh(p, _) if p.is_zero() => {
            Err(Error::ZeroProcessPeriod { process: format!("{behavior}.{}", spec.name) })
        }
        Trigger::OnWrite(Port(i)) | Trigger::PeriodicWhileFresh(_, Port(i)) if usize::from(i) >= n_ports => {
            Err(Error::UnknownPort { behavior: behavior.to_owned(), port: format!("#{i}") })
        }
        Trigger::OnMonostable(Mono(i)) if usize::from(i) >= n_monos => {
            Err(Error::UnknownPort { behavior: behavior.to_owned(), port: format!("monostable #{i}") })
        }
        _ => Ok(()),
    }
}
