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
use crate::time::{Duration, Instant};
use crate::value::{Value, ValueType};

/// An open arbitration window on a port.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct WindowReport {
    pub kind: WindowKind,
    /// The connection that opened it (and holds the pass, for overrides).
    pub holder: Source,
    pub ends: Instant,
    pub remaining: Duration,
}

/// Everything about one port: value, provenance, freshness, windows, counters, wiring.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct PortReport {
    pub node: NodeId,
    pub now: Instant,
    pub behavior: String,
    pub port: String,
    pub kind: PortKind,
    pub ty: ValueType,
    /// The readable value (the default while an aggregating port is empty).
    pub value: Value,
    pub fresh: bool,
    /// Aggregating ports only: no value in the current window.
    pub empty: bool,
    pub last_accepted: Option<Instant>,
    pub supplier: Option<Source>,
    pub accepted: u64,
    pub windows: Vec<WindowReport>,
    /// Why a connection without a pass could not write the port now (`None`: it could).
    pub input_blocked: Option<DropCause>,
    /// Why the behavior's own writes would not propagate now (`None`: they would).
    pub internal_output_blocked: Option<DropCause>,
    /// Why a value arriving along a connection without a pass would not propagate now.
    pub connection_output_blocked: Option<DropCause>,
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
    pub name: String,
    pub trigger: Trigger,
    pub runs: u64,
    /// Periodic activations skipped because the process was late.
    pub overruns: u64,
    /// Times a triggered process was triggered again in the poll in which it had already run
    /// (it triggers itself) and was held back by `RETRIGGER_INTERVAL` (D7.3).
    #[cfg_attr(feature = "serde", serde(default))]
    pub retriggered: u64,
    pub next_due: Option<Instant>,
}

/// A register as listed.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct RegisterReport {
    pub name: String,
    pub kind: PortKind,
    pub ty: ValueType,
    pub value: Value,
    pub fresh: bool,
}

/// One behavior as listed.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct BehaviorReport {
    pub name: String,
    pub class: String,
    pub ports: Vec<RegisterReport>,
    pub slots: Vec<(String, Value)>,
    /// Monostables and whether each is high now.
    pub monostables: Vec<(String, bool)>,
    pub processes: Vec<ProcessReport>,
}

/// The whole node.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct NodeReport {
    pub node: NodeId,
    pub now: Instant,
    pub groups: Vec<String>,
    pub behaviors: Vec<BehaviorReport>,
    pub connections: Vec<ConnectionInfo>,
    pub counters: Counters,
    /// The transport's counters by cause (datagrams sent/received, drops before the core).
    pub transport: Vec<(String, u64)>,
    pub warnings: Vec<String>,
}

impl NodeCore {
    /// Why `behavior.port` holds what it holds and passes what it passes.
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
        let triggers = ps.triggers.iter().map(|&pi| process_report(&beh.processes[usize::from(pi)])).collect();
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
            last_accepted: ps.cell.last_accepted,
            supplier: if empty { None } else { ps.cell.supplier() },
            accepted: ps.accepted,
            windows,
            input_blocked: ps.windows.admit_write(now, nobody).err(),
            internal_output_blocked: ps.windows.admit_propagation(now, Origin::Internal).err(),
            connection_output_blocked: ps.windows.admit_propagation(now, Origin::Connection(nobody)).err(),
            counters: ps.counters.clone(),
            incoming,
            outgoing,
            triggers,
        })
    }

    /// Everything on this node: behaviors with registers and processes, connections, groups,
    /// counters and warnings.
    pub fn report(&self) -> NodeReport {
        let now = self.now();
        let mut behaviors: Vec<BehaviorReport> = self
            .behaviors
            .iter()
            .flatten()
            .map(|beh| BehaviorReport {
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
                processes: beh.processes.iter().map(process_report).collect(),
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
            warnings: self.warnings().to_vec(),
        }
    }

    /// The connection with this id, if this node owns it.
    pub fn connection(&self, id: crate::address::ConnectionId) -> Option<ConnectionInfo> {
        self.conn_index(id)?;
        self.connection_infos().into_iter().find(|c| c.id == id)
    }
}

fn process_report(p: &ProcState) -> ProcessReport {
    ProcessReport {
        name: p.spec.name.clone(),
        trigger: p.spec.trigger,
        runs: p.runs,
        overruns: p.overruns,
        retriggered: p.retriggers,
        next_due: matches!(p.spec.trigger, Trigger::Periodic(_)).then_some(p.next_due),
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
            Some(s) => writeln!(f, "  supplier  {s}")?,
            None => writeln!(f, "  supplier  none")?,
        }
        let blocked = |d: Option<DropCause>| d.map_or("open".to_owned(), |d| format!("BLOCKED ({d})"));
        writeln!(f, "  input     {}", blocked(self.input_blocked))?;
        writeln!(
            f,
            "  output    own writes {}, connection writes {}",
            blocked(self.internal_output_blocked),
            blocked(self.connection_output_blocked)
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
