//! Checkpoints: a node's whole state as data ([`Snapshot`]), and a node made again from one.
//!
//! What it is for: a rolling flight recorder (`ayllu node --record-last`) keeps only the last
//! minutes of a node's life, so a replay of it cannot start from the node's first definition;
//! it starts from the checkpoint that opens the oldest segment kept (spec/flight-recorder.md,
//! "Checkpoints").
//!
//! What it promises:
//! * Everything the core keeps that decides what it does next is in a snapshot: classes and
//!   behaviors, each port's cell, windows and counters, slots, monostables, processes (their
//!   runs and unread change outcomes), BLE state, connections with their sequence counters,
//!   groups, access rules and limits, the schedule and the pending and deferred triggers, the
//!   newest sequence number per incoming connection (N1), the requests sent and the answers
//!   kept for retries, the request rate buckets, transactions, the outbox, counters, warnings
//!   and every id counter. A core restored from a snapshot and given the same inputs as the
//!   original accepts the same values, runs the same processes and sends the same messages
//!   (tests/rules/snapshot.rs checks it at random instants of random runs).
//! * Process bodies are code, not data: a snapshot names each process, and
//!   [`NodeCore::restore`] asks its caller for the bodies (a replay gives players). BLE's
//!   select, which the core provides itself, is put back by the core.
//! * Left out, because they change nothing the node does: the journal (a restored core
//!   journals nothing until started), and the sequence table's resolved-port caches (each
//!   entry comes back unresolved and is resolved again by its next message, as after N1's
//!   clear), with the name strings those caches kept alive.
//! * An error held in a change outcome comes back as [`crate::Error::Restored`], with its kind and
//!   words. Floats the core keeps outside values (BLE's eligibilities, rate buckets) keep
//!   their bits; values keep what their serde form keeps (in JSON, a NaN's payload is lost).
//! * [`NodeCore::restore`] checks every index a snapshot holds against what it describes: a
//!   damaged snapshot is refused with what is wrong, never a panic later.

use std::collections::VecDeque;
use std::sync::Arc;

use serde::{Deserialize, Serialize};

use super::connections::Request;
use super::tables::{Behavior, Conn, MonoState, PortState, ProcState, Target};
use super::NodeCore;
use crate::access::{Access, Limits};
use crate::address::{ConnectionId, NodeId, Source};
use crate::behavior::{BehaviorClass, Port, ProcessFn, ProcessSpec, SlotSpec, Trigger};
use crate::ble::{BleState, BLE_SELECT};
use crate::change::ChangeOutcome;
use crate::counters::Counters;
use crate::message::{Outgoing, ReplyBody};
use crate::port::PortSpec;
use crate::schedule::{Periodic, Schedule};
use crate::sequence::{incoming_key, SeqEntry};
use crate::time::{Duration, Instant};
use crate::transaction::Transactions;
use crate::value::Value;

/// The version of a snapshot's layout; [`NodeCore::restore`] refuses others.
pub const SNAPSHOT_VERSION: u32 = 1;

/// A node's state at an instant, as data (see the module docs). Serialize it with any serde
/// format; make a node of it with [`NodeCore::restore`].
#[derive(Clone, Serialize, Deserialize)]
pub struct Snapshot {
    version: u32,
    id: NodeId,
    now: Instant,
    wave: u64,
    removals: u16,
    outcomes_kept: bool,
    classes: Vec<ClassDecl>,
    behaviors: Vec<Option<BehaviorDecl>>,
    free_behaviors: Vec<u32>,
    next_behavior_id: u64,
    conns: Vec<Option<Conn>>,
    free_conns: Vec<u32>,
    next_conn_id: u64,
    groups: Vec<Arc<str>>,
    groups_generation: u64,
    /// (sender, connection, newest sequence number applied), sorted.
    newest_seq: Vec<(u32, u64, u64)>,
    seq_table_resets: u64,
    access: Access,
    limits: Limits,
    pending: VecDeque<(u32, u64, u16)>,
    poll_epoch: u64,
    deferred_due: Instant,
    deferred: Vec<(u32, u64, u16)>,
    schedule: ScheduleDecl,
    outbox: VecDeque<Outgoing>,
    requests: Vec<Request>,
    finished_requests: usize,
    next_request: u64,
    seq_base: u64,
    /// The answers kept for retries, in the order they are forgotten.
    answered: Vec<((NodeId, u64), Result<ReplyBody, String>)>,
    answered_bytes: usize,
    answers_waiting: usize,
    txns: Transactions,
    counters: Counters,
    warnings: Vec<String>,
    transport_counters: Vec<(String, u64)>,
    body_counters: Vec<(String, u64)>,
    /// Sender, tokens left (as bits), last refill; sorted by sender.
    request_buckets: Vec<(NodeId, u64, Instant)>,
}

/// A class as `define` declared it, its processes by name.
#[derive(Clone, Serialize, Deserialize)]
struct ClassDecl {
    name: String,
    ports: Vec<PortSpec>,
    slots: Vec<SlotSpec>,
    monos: Vec<String>,
    processes: Vec<(String, Trigger)>,
}

#[derive(Clone, Serialize, Deserialize)]
struct BehaviorDecl {
    id: u64,
    name: Arc<str>,
    class: String,
    ports: Vec<PortState>,
    processes: Vec<ProcessDecl>,
    slots: Vec<Value>,
    monos: Vec<MonoState>,
    ble: Option<BleState>,
}

#[derive(Clone, Serialize, Deserialize)]
struct ProcessDecl {
    name: String,
    trigger: Trigger,
    runs: u64,
    ran_in_poll: u64,
    pending: bool,
    overruns: u64,
    retriggers: u64,
    outcomes: Vec<ChangeOutcome>,
}

#[derive(Clone, Serialize, Deserialize)]
struct ScheduleDecl {
    /// (behavior slot, process, next due, period, runs), in the schedule's order.
    periodic: Vec<(u32, u16, Instant, Duration, u64)>,
    generation: u64,
    mono_edge: Instant,
}

impl Snapshot {
    /// The node the snapshot is of.
    pub fn node(&self) -> NodeId {
        self.id
    }

    /// The node's time when it was taken.
    pub fn at(&self) -> Instant {
        self.now
    }
}

impl NodeCore {
    /// The node's whole state now, as data (see the module docs). Taken between calls, as
    /// every `&self` method is; costs a copy of the state.
    pub fn snapshot(&self) -> Snapshot {
        let mut classes: Vec<ClassDecl> = self.classes.values().map(|c| class_decl(c)).collect();
        classes.sort_by(|a, b| a.name.cmp(&b.name));
        let behaviors = self
            .behaviors
            .iter()
            .map(|slot| {
                slot.as_ref().map(|b| BehaviorDecl {
                    id: b.id,
                    name: b.name.clone(),
                    class: b.class.name.clone(),
                    ports: b.ports.clone(),
                    processes: b
                        .processes
                        .iter()
                        .map(|p| ProcessDecl {
                            name: p.spec.name.clone(),
                            trigger: p.spec.trigger,
                            runs: p.runs,
                            ran_in_poll: p.ran_in_poll,
                            pending: p.pending,
                            overruns: p.overruns,
                            retriggers: p.retriggers,
                            outcomes: p.outcomes.clone(),
                        })
                        .collect(),
                    slots: b.slots.clone(),
                    monos: b.monos.clone(),
                    ble: b.ble.as_deref().cloned(),
                })
            })
            .collect();
        let mut request_buckets: Vec<(NodeId, u64, Instant)> =
            self.request_buckets.iter().map(|(n, (tokens, at))| (*n, tokens.to_bits(), *at)).collect();
        request_buckets.sort_unstable_by_key(|(n, ..)| *n);
        Snapshot {
            version: SNAPSHOT_VERSION,
            id: self.id,
            now: self.now,
            wave: self.wave,
            removals: self.removals,
            outcomes_kept: self.outcomes_kept,
            classes,
            behaviors,
            free_behaviors: self.free_behaviors.clone(),
            next_behavior_id: self.next_behavior_id,
            conns: self.conns.clone(),
            free_conns: self.free_conns.clone(),
            next_conn_id: self.next_conn_id,
            groups: self.groups.clone(),
            groups_generation: self.groups_generation,
            newest_seq: self.newest_seq.newest(),
            seq_table_resets: self.seq_table_resets,
            access: self.access.clone(),
            limits: self.limits.clone(),
            pending: self.pending.clone(),
            poll_epoch: self.poll_epoch,
            deferred_due: self.deferred_due,
            deferred: self.deferred.clone(),
            schedule: ScheduleDecl {
                periodic: self.schedule.periodic.iter().map(|e| (e.b, e.pi, e.next_due, e.period, e.runs)).collect(),
                generation: self.schedule.generation,
                mono_edge: self.schedule.mono_edge,
            },
            outbox: self.outbox.clone(),
            requests: self.requests.clone(),
            finished_requests: self.finished_requests,
            next_request: self.next_request,
            seq_base: self.seq_base,
            answered: self
                .answered_order
                .iter()
                .filter_map(|k| self.answered.get(k).map(|a| (*k, a.clone())))
                .collect(),
            answered_bytes: self.answered_bytes,
            answers_waiting: self.answers_waiting,
            txns: self.txns.clone(),
            counters: self.counters.clone(),
            warnings: self.warnings.clone(),
            transport_counters: self.transport_counters.clone(),
            body_counters: self.body_counters.clone(),
            request_buckets,
        }
    }

    /// A node in the state `snapshot` holds, its process bodies given by `body(owner,
    /// process)`: `owner` is the class for a class's processes, the behavior for one added
    /// with `add_process`. BLE's select gets the core's own body. Refused, with what is wrong:
    /// another version, or a snapshot whose parts do not fit together (a damaged file).
    pub fn restore(snapshot: Snapshot, mut body: impl FnMut(&str, &str) -> ProcessFn) -> Result<NodeCore, String> {
        let s = snapshot;
        if s.version != SNAPSHOT_VERSION {
            return Err(format!("snapshot version {}; this build reads {SNAPSHOT_VERSION}", s.version));
        }
        let mut core = NodeCore::new(s.id);
        for c in s.classes {
            if core.classes.contains_key(&c.name) {
                return Err(format!("class `{}` twice", c.name));
            }
            let processes = c
                .processes
                .iter()
                .map(|(name, trigger)| ProcessSpec { name: name.clone(), trigger: *trigger, body: body(&c.name, name) })
                .collect();
            let class = BehaviorClass { name: c.name, ports: c.ports, slots: c.slots, monos: c.monos, processes };
            core.classes.insert(class.name.clone(), Arc::new(class));
        }
        for (b, slot) in s.behaviors.into_iter().enumerate() {
            let Some(mut d) = slot else {
                core.behaviors.push(None);
                continue;
            };
            let class = core.classes.get(&d.class).cloned().ok_or_else(|| format!("no class `{}`", d.class))?;
            let shape = (d.ports.len(), d.slots.len(), d.monos.len());
            if shape != (class.ports.len(), class.slots.len(), class.monos.len())
                || d.processes.len() < class.processes.len()
            {
                return Err(format!("behavior `{}` does not have its class's registers", d.name));
            }
            // A guard port's flag first, since `set_triggers` works out `plain` from it (an
            // index out of range is refused by `check_indices` below).
            for p in &d.processes {
                if let Trigger::PeriodicWhileFresh(_, port) = p.trigger {
                    if let Some(port) = d.ports.get_mut(usize::from(port.0)) {
                        port.guarded = true;
                    }
                }
            }
            for port in &mut d.ports {
                port.set_triggers();
            }
            let processes = d
                .processes
                .into_iter()
                .enumerate()
                .map(|(pi, p)| {
                    let body = match class.processes.get(pi) {
                        Some(c) if c.name == p.name && c.trigger == p.trigger => c.body.clone(),
                        Some(_) => return Err(format!("`{}.{}` is not its class's process", d.name, p.name)),
                        None if d.ble.is_some() && p.name == BLE_SELECT => Arc::new(crate::ble::select) as ProcessFn,
                        None => body(&d.name, &p.name),
                    };
                    Ok(ProcState {
                        spec: ProcessSpec { name: p.name, trigger: p.trigger, body },
                        runs: p.runs,
                        ran_in_poll: p.ran_in_poll,
                        pending: p.pending,
                        overruns: p.overruns,
                        retriggers: p.retriggers,
                        outcomes: p.outcomes,
                    })
                })
                .collect::<Result<Vec<_>, String>>()?;
            if core.names.insert((&*d.name).into(), b as u32).is_some() {
                return Err(format!("behavior `{}` twice", d.name));
            }
            core.behaviors.push(Some(Behavior {
                id: d.id,
                ports: d.ports,
                processes,
                name: d.name,
                class,
                slots: d.slots,
                monos: d.monos,
                ble: d.ble.map(Box::new),
            }));
        }
        for (i, c) in s.conns.iter().enumerate() {
            if let Some(c) = c {
                if core.conn_ids.insert(c.id, i as u32).is_some() {
                    return Err(format!("connection {} twice", c.id));
                }
            }
        }
        core.conns = s.conns;
        check_indices(&core, &s.free_behaviors, &s.free_conns)?;
        let mut periodic = Vec::with_capacity(s.schedule.periodic.len());
        for (b, pi, next_due, period, runs) in s.schedule.periodic {
            let p = core.process_state(b, pi).ok_or_else(|| format!("a schedule entry for no process ({b}, {pi})"))?;
            // The entry's period is its process's (the trigger checked above): a damaged one,
            // zero above all, would make every poll divide by it. The guard is the process's
            // own: a snapshot does not repeat it.
            if p.spec.trigger.period() != Some(period) {
                return Err(format!("a schedule entry for ({b}, {pi}) with another period than its process's"));
            }
            // Nothing known of a guard: the first due time reads the port.
            let entry = Periodic::new(b, pi, p, next_due, runs);
            periodic.push(entry.ok_or_else(|| format!("a schedule entry for ({b}, {pi}), which is not periodic"))?);
        }
        if periodic.windows(2).any(|w| (w[0].b, w[0].pi) >= (w[1].b, w[1].pi)) {
            return Err("the schedule is not in process order".into());
        }
        core.schedule = Schedule { periodic, generation: s.schedule.generation, mono_edge: s.schedule.mono_edge };
        for &(b, _, pi) in s.pending.iter().chain(&s.deferred) {
            if core.process_state(b, pi).is_none() {
                return Err(format!("a trigger of no process ({b}, {pi})"));
            }
        }
        for (node, conn, newest) in s.newest_seq {
            let key = incoming_key(NodeId(node), ConnectionId(conn));
            if core.newest_seq.get(&key).is_some() {
                return Err(format!("sequence entry ({node}, {conn}) twice"));
            }
            core.newest_seq.insert(SeqEntry::new(key, newest));
        }
        core.now = s.now;
        core.wave = s.wave;
        core.removals = s.removals;
        core.outcomes_kept = s.outcomes_kept;
        core.free_behaviors = s.free_behaviors;
        core.next_behavior_id = s.next_behavior_id;
        core.free_conns = s.free_conns;
        core.next_conn_id = s.next_conn_id;
        core.groups = s.groups;
        core.groups_generation = s.groups_generation;
        core.seq_table_resets = s.seq_table_resets;
        core.access = s.access;
        core.limits = s.limits;
        core.pending = s.pending;
        core.poll_epoch = s.poll_epoch;
        core.deferred_due = s.deferred_due;
        core.deferred = s.deferred;
        core.outbox = s.outbox;
        core.requests = s.requests;
        core.finished_requests = s.finished_requests.min(core.requests.len());
        core.next_request = s.next_request;
        core.seq_base = s.seq_base;
        for (key, answer) in s.answered {
            if core.answered.insert(key, answer).is_none() {
                core.answered_order.push_back(key);
            }
        }
        core.answered_bytes = s.answered_bytes;
        core.answers_waiting = s.answers_waiting;
        core.txns = s.txns;
        core.counters = s.counters;
        core.warnings = s.warnings;
        core.transport_counters = s.transport_counters;
        core.body_counters = s.body_counters;
        core.request_buckets =
            s.request_buckets.into_iter().map(|(n, tokens, at)| (n, (f64::from_bits(tokens), at))).collect();
        Ok(core)
    }

    fn process_state(&self, b: u32, pi: u16) -> Option<&ProcState> {
        self.behaviors.get(b as usize)?.as_ref()?.processes.get(usize::from(pi))
    }
}

fn class_decl(c: &BehaviorClass) -> ClassDecl {
    ClassDecl {
        name: c.name.clone(),
        ports: c.ports.clone(),
        slots: c.slots.clone(),
        monos: c.monos.clone(),
        processes: c.processes.iter().map(|p| (p.name.clone(), p.trigger)).collect(),
    }
}

/// Refuse a restored core whose tables point where nothing is: every index the propagation,
/// the scheduler and the receive path follow without checking.
fn check_indices(core: &NodeCore, free_behaviors: &[u32], free_conns: &[u32]) -> Result<(), String> {
    let port = |b: u32, p: u16| {
        core.behaviors.get(b as usize).and_then(|x| x.as_ref()).is_some_and(|x| usize::from(p) < x.ports.len())
    };
    for (b, beh) in core.behaviors.iter().enumerate() {
        let Some(beh) = beh else { continue };
        let n_ports = beh.ports.len();
        for (p, st) in beh.ports.iter().enumerate() {
            if st.triggers.iter().any(|&pi| usize::from(pi) >= beh.processes.len()) {
                return Err(format!("port {b}.{p} triggers no process"));
            }
            for e in &st.out {
                let live = core.conns.get(e.conn as usize).and_then(|c| c.as_ref()).is_some_and(|c| c.id == e.id);
                if !live || e.local.is_some_and(|(tb, tp)| !port(tb, tp)) {
                    return Err(format!("port {b}.{p} leads to no connection or port"));
                }
            }
        }
        for m in &beh.monos {
            if m.watchers.iter().any(|&pi| usize::from(pi) >= beh.processes.len()) {
                return Err(format!("a monostable of {b} wakes no process"));
            }
        }
        for p in &beh.processes {
            let fits = match p.spec.trigger {
                Trigger::OnWrite(port) => usize::from(port.0) < n_ports,
                Trigger::OnMonostable(m) => usize::from(m.0) < beh.monos.len(),
                Trigger::Periodic(period) => !period.is_zero(),
                Trigger::PeriodicWhileFresh(period, port) => !period.is_zero() && usize::from(port.0) < n_ports,
            };
            if !fits {
                return Err(format!("process `{}.{}` has a trigger its behavior lacks", beh.name, p.spec.name));
            }
        }
        if beh.ble.as_ref().is_some_and(|ble| usize::from(ble.output.0) >= n_ports) {
            return Err(format!("the BLE output of `{}` is no port", beh.name));
        }
    }
    for c in core.conns.iter().flatten() {
        if !port(c.src.0, c.src.1) || matches!(c.dst, Target::Local { b, p } if !port(b, p)) {
            return Err(format!("connection {} joins no port", c.id));
        }
        if c.seq < c.seq_start {
            return Err(format!("connection {} numbered below its start", c.id));
        }
    }
    let free_b = free_behaviors.iter().all(|&b| matches!(core.behaviors.get(b as usize), Some(None)));
    let free_c = free_conns.iter().all(|&c| matches!(core.conns.get(c as usize), Some(None)));
    if !free_b || !free_c {
        return Err("a free slot that is not free".into());
    }
    Ok(())
}

/// `Option<f64>` by its bits, so that a NaN or an infinity survives any serde format.
pub(crate) mod float_bits {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub fn serialize<S: Serializer>(x: &Option<f64>, s: S) -> Result<S::Ok, S::Error> {
        x.map(f64::to_bits).serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
        Ok(Option::<u64>::deserialize(d)?.map(f64::from_bits))
    }
}

/// A BLE member's bookkeeping as a checkpoint holds it: `BleState`'s fields in their order of
/// before `BleState` was laid out for `select` (a checkpoint's form does not follow the
/// layout), under the same name.
#[derive(Serialize, Deserialize)]
#[serde(rename = "BleState")]
pub(crate) struct BleStateForm {
    group: Arc<str>,
    output: Port,
    claim_period: Duration,
    inhibit_period: Duration,
    joined_at: Instant,
    claims: u64,
    last_claim: Option<Instant>,
    #[serde(with = "best_bits")]
    last_best: Option<(f64, Source)>,
    #[serde(with = "float_bits")]
    last_local: Option<f64>,
}

impl From<BleState> for BleStateForm {
    fn from(s: BleState) -> BleStateForm {
        BleStateForm {
            group: s.group,
            output: s.output,
            claim_period: s.claim_period,
            inhibit_period: s.inhibit_period,
            joined_at: s.joined_at,
            claims: s.claims,
            last_claim: s.last_claim,
            last_best: s.last_best,
            last_local: s.last_local,
        }
    }
}

impl From<BleStateForm> for BleState {
    fn from(s: BleStateForm) -> BleState {
        BleState {
            claim_period: s.claim_period,
            joined_at: s.joined_at,
            last_local: s.last_local,
            last_best: s.last_best,
            claims: s.claims,
            last_claim: s.last_claim,
            group: s.group,
            inhibit_period: s.inhibit_period,
            output: s.output,
        }
    }
}

/// BLE's best heard eligibility and its supplier, the eligibility by its bits.
pub(crate) mod best_bits {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    use crate::address::Source;

    pub fn serialize<S: Serializer>(x: &Option<(f64, Source)>, s: S) -> Result<S::Ok, S::Error> {
        x.map(|(e, src)| (e.to_bits(), src)).serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<(f64, Source)>, D::Error> {
        Ok(Option::<(u64, Source)>::deserialize(d)?.map(|(e, src)| (f64::from_bits(e), src)))
    }
}

/// A change outcome's result, its error by kind and words ([`Error::Restored`]).
pub(crate) mod outcome {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    use crate::change::Applied;
    use crate::error::{Error, ErrorKind};

    pub fn serialize<S: Serializer>(r: &Result<Applied, Error>, s: S) -> Result<S::Ok, S::Error> {
        r.as_ref().map_err(|e| (e.kind(), e.to_string())).serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Result<Applied, Error>, D::Error> {
        let r = Result::<Applied, (ErrorKind, String)>::deserialize(d)?;
        Ok(r.map_err(|(kind, what)| Error::Restored { kind, what }))
    }
}
