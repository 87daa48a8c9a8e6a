//! Introspection: answers to "why is this port blocked?", "who supplied this value?" and
//! "what is wired to what?" — the API the CLI and dashboards build on.
//!
//! Everything here is a snapshot (owned data) taken at the node's current time; nothing here
//! changes the node.

use core::fmt;

use crate::address::{NodeId, Source};
use crate::arbitration::{Origin, WindowKind};
use crate::behavior::Trigger;
use crate::connection::ConnectionInfo;
use crate::counters::{Counters, DropCause};
use crate::error::Error;
use crate::node::{current, NodeCore, ProcState, Target};
use crate::port::PortKind;
use crate::schedule::Periodic;
use crate::time::{Duration, Instant};
use crate::value::{Value, ValueType};

/// An open arbitration window on a port.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct WindowReport {
    /// What the window blocks (rule S6).
    pub kind: WindowKind,
    /// The connection that opened it (and holds the pass, for overrides).
    pub holder: Source,
    /// When it closes, on the node's clock (it is open while `now < ends`).
    pub ends: Instant,
    /// `ends - now`: how much longer it blocks, unless its holder refreshes it (D6.1).
    pub remaining: Duration,
}

/// Everything about one port: value, provenance, freshness, windows, counters, wiring.
///
/// The answer of [`NodeCore::why`]; its `Display` is what `ayllu why` prints. A bumper that
/// suppresses a motor's input for 2 s, asked about half a second later:
///
/// ```
/// use ayllu_core::*;
///
/// let mut node = NodeCore::new(NodeId(1));
/// for (class, port) in [("Planner", "Cmd"), ("Bumper", "Hit"), ("Motor", "Speed")] {
///     let mut c = BehaviorClass::new(class);
///     c.port(PortSpec::new(port, 0.0))?;
///     node.define(c)?;
///     node.create(class, class)?;
/// }
/// let (speed, opts) = (Endpoint::local("Motor", "Speed"), ConnectOptions::default());
/// node.connect(&Endpoint::local("Planner", "Cmd"), &speed, ConnectionKind::Normal, opts)?;
/// let stop = ConnectionKind::Suppress(Duration::from_secs(2));
/// node.connect(&Endpoint::local("Bumper", "Hit"), &speed, stop, opts)?;
/// let (hit, cmd) = (node.port("Bumper", "Hit")?, node.port("Planner", "Cmd")?);
/// node.write(Instant::ZERO, hit, 1.0)?;
/// node.write(Instant::from_millis(500), cmd, 0.4)?; // refused by the suppression
///
/// let report = node.why("Motor", "Speed")?;
/// assert_eq!(report.input_blocked, Some(DropCause::Suppressed));
/// assert_eq!(report.internal_output_blocked, None); // its own writes would still go out
/// assert_eq!(report.windows[0].kind, WindowKind::Suppress);
/// assert_eq!(report.windows[0].remaining, Duration::from_millis(1500));
/// assert_eq!(report.counters.get(DropCause::Suppressed), 1);
/// assert_eq!((report.fresh, report.supplier), (false, None)); // nothing ever got through
/// assert_eq!(report.incoming.len(), 2);
/// assert!(report.to_string().contains("input     BLOCKED (suppressed)"));
/// // Asked about a later instant, the window has closed (D8.2).
/// assert_eq!(node.why_at(Instant::from_secs(2), "Motor", "Speed")?.input_blocked, None);
/// # Ok::<(), Error>(())
/// ```
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct PortReport {
    /// The node that answered.
    pub node: NodeId,
    /// The instant the report describes (D8.2): windows and lifespans ended by then count as ended.
    pub now: Instant,
    /// The behavior instance.
    pub behavior: String,
    /// The port's name.
    pub port: String,
    /// How the port merges values (rule S3).
    pub kind: PortKind,
    /// The port's value type, fixed by its default (rule S1).
    pub ty: ValueType,
    /// The readable value (the default while an aggregating port is empty).
    pub value: Value,
    /// Whether `value` is fresh (rule S4); a never-written or empty port is not.
    pub fresh: bool,
    /// Aggregating ports only: no value in the current window.
    pub empty: bool,
    /// When the port last accepted a value; refused and absorbed values do not count.
    pub last_accepted: Option<Instant>,
    /// Who supplied the value it holds (D3.4); `None` while empty or never written.
    pub supplier: Option<Source>,
    /// A Priority port holding a value: the priority its supplier holds it at (D3.3): only a
    /// higher one replaces it. `None` otherwise.
    #[cfg_attr(feature = "serde", serde(default))]
    pub supplier_priority: Option<i32>,
    /// An aggregating port holding a value: how much longer it holds it unless it is renewed,
    /// i.e. until the end of its window (Max, Min, Sum: D3.2), its holder's lease (Priority:
    /// renewed by each accepted write, D3.7) or its lifespan, whichever comes first; then the
    /// port empties and the next value opens it. `None`: nothing ends it by time.
    #[cfg_attr(feature = "serde", serde(default))]
    pub released_in: Option<Duration>,
    /// Values the port has accepted since its behavior was created.
    pub accepted: u64,
    /// Every open window, soonest-ending first.
    pub windows: Vec<WindowReport>,
    /// Why a connection without a pass could not write the port now (`None`: it could).
    pub input_blocked: Option<DropCause>,
    /// Why the behavior's own writes would not propagate now (`None`: they would).
    pub internal_output_blocked: Option<DropCause>,
    /// Why a value arriving along a connection without a pass would not propagate now.
    pub connection_output_blocked: Option<DropCause>,
    /// This port's blocked and refused messages, by cause.
    pub counters: Counters,
    /// Local connections into this port.
    pub incoming: Vec<ConnectionInfo>,
    /// Connections out of this port (local, to nodes, to groups).
    pub outgoing: Vec<ConnectionInfo>,
    /// The processes this port triggers when it accepts a value, with their statistics (a
    /// process that triggers itself shows `retriggered`).
    #[cfg_attr(feature = "serde", serde(default))]
    pub triggers: Vec<ProcessReport>,
}

/// A process's schedule and statistics.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct ProcessReport {
    /// The process's name within its behavior.
    pub name: String,
    /// When it runs (rule S7).
    pub trigger: Trigger,
    /// Times it has run.
    pub runs: u64,
    /// Periodic activations skipped because the process was late.
    pub overruns: u64,
    /// Times a triggered process was triggered again in the poll in which it had already run
    /// (it triggers itself) and was held back by `RETRIGGER_INTERVAL` (D7.3).
    #[cfg_attr(feature = "serde", serde(default))]
    pub retriggered: u64,
    /// Periodic processes: the next activation on the node's clock; `None` for triggered ones.
    pub next_due: Option<Instant>,
}

/// A register as listed.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct RegisterReport {
    /// The port's name.
    pub name: String,
    /// How it merges values (rule S3).
    pub kind: PortKind,
    /// Its value type (rule S1).
    pub ty: ValueType,
    /// Its readable value (the default while an aggregating port is empty).
    pub value: Value,
    /// Whether that value is fresh (rule S4).
    pub fresh: bool,
}

/// One behavior as listed.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct BehaviorReport {
    /// The instance name (`OBS1`).
    pub name: String,
    /// The class it was created from.
    pub class: String,
    /// Its ports in handle order, the BLE ports first.
    pub ports: Vec<RegisterReport>,
    /// Its slots and their values.
    pub slots: Vec<(String, Value)>,
    /// Monostables and whether each is high now.
    pub monostables: Vec<(String, bool)>,
    /// Its processes, in declaration order (instance-specific ones, such as `BLE_Select`, last).
    pub processes: Vec<ProcessReport>,
}

/// The whole node.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct NodeReport {
    /// The node that answered.
    pub node: NodeId,
    /// The node's time when the report was taken.
    pub now: Instant,
    /// The broadcast groups it has joined.
    pub groups: Vec<String>,
    /// Every behavior, sorted by name.
    pub behaviors: Vec<BehaviorReport>,
    /// Every connection this node owns (those whose source is here).
    pub connections: Vec<ConnectionInfo>,
    /// Node-wide blocked and refused messages, by cause.
    pub counters: Counters,
    /// The transport's counters by cause (datagrams sent/received, drops before the core).
    pub transport: Vec<(String, u64)>,
    /// The body drivers' counters by cause (a ROS 2 body: samples taken and dropped, per
    /// topic); empty on a node without one. Absent from older nodes' reports.
    #[cfg_attr(feature = "serde", serde(default))]
    pub body: Vec<(String, u64)>,
    /// Warnings raised so far (see [`NodeCore::warnings`]).
    pub warnings: Vec<String>,
}

impl NodeCore {
    /// Why `behavior.port` holds what it holds and passes what it passes, as of
    /// [`NodeCore::now`] (see the example on [`PortReport`]). Errors: an unknown behavior or
    /// port, or a slot ([`Error::NotAPort`]).
    pub fn why(&self, behavior: &str, port: &str) -> Result<PortReport, Error> {
        self.why_at(self.now(), behavior, port)
    }

    /// [`NodeCore::why`] as of `now` (never before the node's own time): windows and
    /// lifespans that ended by `now` count as ended (D8.2).
    pub fn why_at(&self, now: Instant, behavior: &str, port: &str) -> Result<PortReport, Error> {
        let r = self.port(behavior, port)?;
        let now = now.max(self.now());
        let me = self.id();
        let beh = self.behavior(r.b).expect("resolved");
        let ps = &beh.ports[usize::from(r.port.0)];
        let spec = &beh.class.ports()[usize::from(r.port.0)];
        // A source that holds no pass: node and connection ids no real source uses.
        let nobody = Source { node: NodeId(u32::MAX), conn: u64::MAX };
        let windows = ps
            .windows
            .active(now)
            .into_iter()
            .map(|w| WindowReport { kind: w.kind, holder: w.holder, ends: w.end, remaining: w.end - now })
            .collect();
        let all = self.connection_infos();
        let incoming = self
            .conns
            .iter()
            .flatten()
            .filter(|c| matches!(c.dst, Target::Local { b, p } if b == r.b && p == r.port.0))
            .filter_map(|c| all.iter().find(|i| i.id.0 == c.id).cloned())
            .collect();
        let outgoing = ps
            .out
            .iter()
            .filter_map(|e| self.conns[e.conn as usize].as_ref())
            .filter_map(|c| all.iter().find(|i| i.id.0 == c.id).cloned())
            .collect();
        let empty = ps.cell.is_empty(now);
        let holds = spec.kind.is_aggregating() && !empty;
        let release = ps.cell.release_at();
        let triggers = ps
            .triggers
            .iter()
            .map(|&pi| process_report(&beh.processes[usize::from(pi)], self.periodic(r.b, pi)))
            .collect();
        Ok(PortReport {
            node: me,
            now,
            behavior: behavior.to_owned(),
            port: spec.name.clone(),
            kind: spec.kind,
            ty: spec.ty(),
            value: current(&ps.cell, now).clone(),
            fresh: ps.cell.fresh(now),
            empty,
            last_accepted: ps.cell.last_accepted(),
            supplier: if empty { None } else { ps.cell.supplier() },
            supplier_priority: (holds && spec.kind == PortKind::Priority).then_some(ps.cell.supplier_priority),
            released_in: (holds && release != Instant::MAX).then(|| release - now),
            accepted: ps.accepted,
            windows,
            input_blocked: ps.windows.admit_write(now, nobody).err(),
            internal_output_blocked: ps.windows.admit_propagation(now, Origin::Internal).err(),
            connection_output_blocked: ps.windows.admit_propagation(now, Origin::Connection(nobody)).err(),
            counters: ps.counters(),
            incoming,
            outgoing,
            triggers,
        })
    }

    /// Everything on this node: behaviors with registers and processes, connections, groups,
    /// counters and warnings.
    pub fn report(&self) -> NodeReport {
        self.report_at(self.now())
    }

    /// [`NodeCore::report`] as of `now` (never before the node's own time), as
    /// [`NodeCore::why_at`] is to `why`: values and monostables read as they do at `now`.
    pub fn report_at(&self, now: Instant) -> NodeReport {
        let now = now.max(self.now());
        let mut behaviors: Vec<BehaviorReport> = self
            .behaviors
            .iter()
            .enumerate()
            .filter_map(|(b, beh)| Some((b as u32, beh.as_ref()?)))
            .map(|(b, beh)| BehaviorReport {
                name: beh.name.to_string(),
                class: beh.class.name().to_owned(),
                ports: beh
                    .class
                    .ports()
                    .iter()
                    .zip(&beh.ports)
                    .map(|(spec, ps)| RegisterReport {
                        name: spec.name.clone(),
                        kind: spec.kind,
                        ty: spec.ty(),
                        value: current(&ps.cell, now).clone(),
                        fresh: ps.cell.fresh(now),
                    })
                    .collect(),
                slots: beh.class.slots().iter().zip(&beh.slots).map(|(s, v)| (s.name.clone(), v.clone())).collect(),
                monostables: beh
                    .class
                    .monostables()
                    .iter()
                    .zip(&beh.monos)
                    .map(|(n, m)| (n.clone(), now < m.end))
                    .collect(),
                processes: beh
                    .processes
                    .iter()
                    .enumerate()
                    .map(|(pi, p)| process_report(p, self.periodic(b, pi as u16)))
                    .collect(),
            })
            .collect();
        behaviors.sort_by(|a, b| a.name.cmp(&b.name));
        NodeReport {
            node: self.id(),
            now,
            groups: self.groups().iter().map(|g| g.to_string()).collect(),
            behaviors,
            connections: self.connection_infos(),
            counters: self.counters().clone(),
            transport: self.transport_counters.clone(),
            body: self.body_counters.clone(),
            warnings: self.warnings().to_vec(),
        }
    }

    /// The connection with this id, if this node owns it.
    pub fn connection(&self, id: crate::address::ConnectionId) -> Option<ConnectionInfo> {
        self.conn_index(id)?;
        self.connection_infos().into_iter().find(|c| c.id == id)
    }
}

/// A process's report; a periodic one's due time and run count are in the node's schedule.
fn process_report(p: &ProcState, periodic: Option<&Periodic>) -> ProcessReport {
    ProcessReport {
        name: p.spec.name.clone(),
        trigger: p.spec.trigger,
        runs: periodic.map_or(p.runs, |e| e.runs),
        overruns: p.overruns,
        retriggered: p.retriggers,
        next_due: periodic.map(|e| e.next_due),
    }
}

impl fmt::Display for PortReport {
    /// A human answer to "why": one fact a line, blocking causes first.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{}:{}.{} ({} {}) at {}",
            self.node,
            self.behavior,
            self.port,
            self.kind.name(),
            self.ty,
            self.now
        )?;
        let state = if self.empty {
            "empty".to_owned()
        } else if self.fresh {
            "fresh".to_owned()
        } else {
            "stale".to_owned()
        };
        write!(f, "  value     {} ({state}", self.value)?;
        if let Some(t) = self.last_accepted {
            write!(f, ", last accepted {} ago", self.now - t)?;
        }
        writeln!(f, ")")?;
        match self.supplier {
            Some(s) => write!(f, "  supplier  {s}")?,
            None => write!(f, "  supplier  none")?,
        }
        if let Some(p) = self.supplier_priority {
            write!(f, " at priority {p} (only a higher one replaces it)")?;
        }
        if let Some(d) = self.released_in {
            let by = if self.kind == PortKind::Priority { "its lease ends" } else { "its window or lifespan ends" };
            write!(f, "; released in {d} unless renewed ({by})")?;
        }
        writeln!(f)?;
        let blocked = |d: Option<DropCause>| d.map_or("open".to_owned(), |d| format!("BLOCKED ({d})"));
        // An override's holder has a pass (S6): its values still get through the window it
        // opened, unless something without passes blocks them too (then that is the cause).
        let passes = |cause: Option<DropCause>, overriding: DropCause, kind: WindowKind| {
            let holders: Vec<String> =
                self.windows.iter().filter(|w| w.kind == kind).map(|w| w.holder.to_string()).collect();
            if cause != Some(overriding) || holders.is_empty() {
                return String::new();
            }
            format!(" except along {} (the override's pass)", holders.join(", "))
        };
        writeln!(
            f,
            "  input     {}{}",
            blocked(self.input_blocked),
            passes(self.input_blocked, DropCause::OverriddenIn, WindowKind::OverrideIn)
        )?;
        writeln!(
            f,
            "  output    own writes {}, connection writes {}{}",
            blocked(self.internal_output_blocked),
            blocked(self.connection_output_blocked),
            passes(self.connection_output_blocked, DropCause::OverriddenOut, WindowKind::OverrideOut)
        )?;
        for w in &self.windows {
            writeln!(f, "  window    {} held by {} for {} more", w.kind.name(), w.holder, w.remaining)?;
        }
        for c in &self.incoming {
            writeln!(f, "  in        {} {} <- {}", c.id, c.kind, c.source)?;
        }
        for c in &self.outgoing {
            writeln!(f, "  out       {} {} -> {}", c.id, c.kind, c.destination)?;
        }
        for p in &self.triggers {
            write!(f, "  triggers  process {}: {} runs", p.name, p.runs)?;
            if p.retriggered > 0 {
                write!(f, ", TRIGGERS ITSELF: held back {} times (runs at most once per ms)", p.retriggered)?;
            }
            writeln!(f)?;
        }
        for (d, n) in self.counters.nonzero() {
            writeln!(f, "  counted   {d}: {n}")?;
        }
        Ok(())
    }
}
