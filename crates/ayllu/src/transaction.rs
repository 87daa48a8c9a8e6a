//! Transactional rewiring across nodes: a [`Plan`] of structure changes on several nodes,
//! applied by all of them at the same instant of their own clocks, or by none
//! (docs/semantics.md R8–R12; the participant's side is `ayllu_core::transaction`).
//!
//! The coordinator is a sans-IO state machine ([`Coordinator`]) driven with a [`NodeCore`]
//! and the time, so it runs the same on `mem://` with a [`crate::ManualClock`] as on UDP;
//! [`apply`] drives it with a [`Node`] in real time, as `ayllu apply` does.
//!
//! The protocol, from the coordinator's side:
//! 1. PREPARE every node its part (retried as any request, N2); the round trip of each is
//!    measured. A refusal, or no answer within [`ApplyOptions::prepare_timeout`], ends in 3.
//! 2. Aim the switch at `S = now + margin + max rtt` (coordinator clock) and send every node
//!    COMMIT copies every [`ApplyOptions::resend`], each with `delay = S − now − rtt/2`, until
//!    it answers or its hold may have ended. An answer says how long until (or since) its
//!    switch, which places the switch on the coordinator's clock within the copy's round trip.
//! 3. ABORT every node (also those that did not answer, so that a late PREPARE is refused).
//!
//! What it promises: the [`ApplyReport`] says what happened at each node (its round trip, who
//! refused and why, where its switch fell), the skew bound measured, and whether the team
//! switched, aborted, or — only if every COMMIT copy to a node was lost until the end of its
//! hold — is split, naming the nodes it cannot vouch for.

use std::fmt;

use ayllu_core::{
    Change, ControlBody, Duration, Endpoint, Instant, NodeCore, NodeId, ReplyBody, RequestId, RequestStatus, Value,
};

use crate::error::Error;
use crate::node::Node;

/// How a transaction is run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ApplyOptions {
    /// How long each node holds its part waiting for COMMIT or ABORT (from its receipt of
    /// PREPARE); then it aborts by itself (R11). Default 5 s.
    pub hold: Duration,
    /// Added to the slowest round trip to aim the switch (R10). Default 100 ms.
    pub margin: Duration,
    /// How long to wait for every PREPARE's answer before aborting (R12). Default 2 s.
    pub prepare_timeout: Duration,
    /// How often a COMMIT is sent again to a node that has not answered (R11). Default 20 ms.
    pub resend: Duration,
}

impl Default for ApplyOptions {
    fn default() -> Self {
        ApplyOptions {
            hold: ayllu_core::transaction::DEFAULT_HOLD,
            margin: Duration::from_millis(100),
            prepare_timeout: Duration::from_secs(2),
            resend: Duration::from_millis(20),
        }
    }
}

/// One node's part of a plan.
#[derive(Clone, Debug, PartialEq)]
pub struct Part {
    /// The node.
    pub node: NodeId,
    /// Its changes, in order. A `Local` endpoint means a port of this node.
    pub changes: Vec<Change>,
}

/// Structure changes on several nodes, to apply all at once or not at all.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Plan {
    /// One part per node (a node appears once).
    pub parts: Vec<Part>,
    /// How to run it.
    pub options: ApplyOptions,
}

/// How a transaction ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// Every node answered COMMIT: all switched, within the report's skew bound.
    Switched,
    /// No node switched: one refused or did not answer PREPARE (see the report's nodes).
    Aborted,
    /// Some nodes switched; the ones without a COMMIT answer either switched late or aborted
    /// by themselves at the end of their hold (R11). Re-apply, or inspect them.
    Split,
}

impl fmt::Display for Outcome {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Outcome::Switched => "switched",
            Outcome::Aborted => "aborted",
            Outcome::Split => "split",
        })
    }
}

/// Where a node's switch fell, on the coordinator's clock (R10).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SwitchWindow {
    /// Not before this.
    pub earliest: Instant,
    /// Not after this.
    pub latest: Instant,
}

/// What happened at one node.
#[derive(Clone, Debug, PartialEq)]
pub struct NodeOutcome {
    /// The node.
    pub node: NodeId,
    /// Its PREPARE's round trip, or why there is none (its refusal, or no answer).
    pub prepare: Result<Duration, String>,
    /// Whether it refused its part (then `prepare` holds its reason).
    pub refused: bool,
    /// Its switch (COMMIT answered), or why there is none; `None` if no COMMIT was sent.
    pub commit: Option<Result<SwitchWindow, String>>,
    /// Its ABORT's answer, if the transaction aborted.
    pub abort: Option<Result<(), String>>,
}

/// What a transaction did (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct ApplyReport {
    /// The transaction's number.
    pub txn: u64,
    /// How it ended.
    pub outcome: Outcome,
    /// Each node, in the plan's order.
    pub nodes: Vec<NodeOutcome>,
    /// The instant aimed at, on the coordinator's clock (if COMMIT was sent).
    pub switch_at: Option<Instant>,
    /// The measured bound on how far apart two nodes switched (if all answered COMMIT):
    /// the latest `latest` minus the earliest `earliest`.
    pub skew_bound: Option<Duration>,
    /// The slowest PREPARE round trip.
    pub max_rtt: Duration,
}

impl ApplyReport {
    /// The nodes that refused their part, with their reasons.
    pub fn refused(&self) -> Vec<(NodeId, String)> {
        self.nodes
            .iter()
            .filter(|n| n.refused)
            .filter_map(|n| n.prepare.as_ref().err().map(|e| (n.node, e.clone())))
            .collect()
    }
}

impl ApplyReport {
    /// The report as JSON (times in seconds on the coordinator's clock, as `ayllu apply
    /// --json` prints it).
    pub fn to_json(&self) -> serde_json::Value {
        let secs = |d: Duration| d.as_secs_f64();
        let nodes: Vec<serde_json::Value> = self
            .nodes
            .iter()
            .map(|n| {
                let mut o = serde_json::json!({"node": n.node.0, "refused": n.refused});
                match &n.prepare {
                    Ok(rtt) => o["round_trip"] = secs(*rtt).into(),
                    Err(e) => o["prepare_error"] = e.clone().into(),
                }
                match &n.commit {
                    Some(Ok(w)) => {
                        o["switch_earliest"] = w.earliest.as_secs_f64().into();
                        o["switch_latest"] = w.latest.as_secs_f64().into();
                    }
                    Some(Err(e)) => o["commit_error"] = e.clone().into(),
                    None => {}
                }
                match &n.abort {
                    Some(Ok(())) => o["aborted"] = true.into(),
                    Some(Err(e)) => o["abort_error"] = e.clone().into(),
                    None => {}
                }
                o
            })
            .collect();
        serde_json::json!({
            "txn": self.txn,
            "outcome": self.outcome.to_string(),
            "switch_at": self.switch_at.map(Instant::as_secs_f64),
            "skew_bound": self.skew_bound.map(secs),
            "max_round_trip": secs(self.max_rtt),
            "nodes": nodes,
        })
    }
}

impl fmt::Display for ApplyReport {
    /// One line for the transaction, one per node.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "transaction {}: {}", self.txn, self.outcome)?;
        if let Some(s) = self.skew_bound {
            write!(f, " (skew at most {s}, slowest round trip {})", self.max_rtt)?;
        }
        for n in &self.nodes {
            write!(f, "\n  {}: ", n.node)?;
            match (&n.prepare, &n.commit, &n.abort) {
                (Err(e), _, _) if n.refused => write!(f, "refused: {e}")?,
                (Err(e), _, _) => write!(f, "{e}")?,
                (Ok(rtt), Some(Ok(w)), _) => {
                    write!(f, "switched (round trip {rtt}, within {})", w.latest - w.earliest)?
                }
                (Ok(_), Some(Err(e)), _) => write!(f, "{e}")?,
                (Ok(_), None, Some(Ok(()))) => write!(f, "prepared, aborted")?,
                (Ok(_), None, Some(Err(e))) => write!(f, "prepared; abort: {e}")?,
                (Ok(rtt), None, None) => write!(f, "prepared (round trip {rtt})")?,
            }
        }
        Ok(())
    }
}

#[derive(Debug)]
struct NodeState {
    node: NodeId,
    changes: Vec<Change>,
    prepare: Option<RequestId>,
    /// When the PREPARE was last sent (the core resends it until answered, N2).
    prepare_sent: (u32, Instant),
    rtt: Option<Duration>,
    /// Why there is no round trip: a refusal (`true`) or no answer (`false`).
    refused: Option<(bool, String)>,
    /// The COMMIT copies in flight and when each was sent.
    copies: Vec<(RequestId, Instant)>,
    next_copy: Instant,
    commit: Option<Result<SwitchWindow, String>>,
    abort: Option<RequestId>,
    abort_result: Option<Result<(), String>>,
}

#[derive(Copy, Clone, Debug, PartialEq, Eq)]
enum Phase {
    Start,
    Preparing,
    Committing,
    Aborting,
}

/// A transaction in progress, coordinated from one node (see the module docs).
#[derive(Debug)]
pub struct Coordinator {
    txn: u64,
    options: ApplyOptions,
    nodes: Vec<NodeState>,
    phase: Phase,
    started: Instant,
    switch_at: Option<Instant>,
    max_rtt: Duration,
}

/// A local endpoint of `node`'s part, named with its node (local endpoints are never sent).
fn on_node(node: NodeId, e: &Endpoint) -> Endpoint {
    match e {
        Endpoint::Local { behavior, port } => Endpoint::Node { node, behavior: behavior.clone(), port: port.clone() },
        other => other.clone(),
    }
}

fn sent_form(node: NodeId, c: &Change) -> Change {
    match c {
        Change::Connect { source, destination, kind, priority } => Change::Connect {
            source: on_node(node, source),
            destination: on_node(node, destination),
            kind: *kind,
            priority: *priority,
        },
        Change::DisconnectBetween { source, destination } => {
            Change::DisconnectBetween { source: on_node(node, source), destination: on_node(node, destination) }
        }
        other => other.clone(),
    }
}

/// How long a COMMIT copy waits for its answer: less than the core's 200 ms resend interval
/// (N2), so the core never sends a copy again with a delay gone stale. A node whose round
/// trip is longer answers no copy (R11).
const COPY_LIFETIME: Duration = Duration::from_millis(180);

fn invalid(what: String) -> Error {
    Error::Plan { what }
}

impl Coordinator {
    /// A transaction numbered `txn` (unique among this coordinator's) of `plan`, coordinated
    /// by node `me`. Refused: an empty plan, a node twice, the coordinator in its own plan, a
    /// change wrong whatever the node holds ([`Change::check`]), more than 255 changes for a
    /// node, or options that leave no time to commit within the hold.
    pub fn new(txn: u64, plan: &Plan, me: NodeId) -> Result<Coordinator, Error> {
        let o = plan.options;
        if plan.parts.is_empty() {
            return Err(invalid("the plan changes no node".into()));
        }
        if o.resend.is_zero() || o.prepare_timeout.is_zero() {
            return Err(invalid("resend and prepare_timeout must be above zero".into()));
        }
        if o.hold < o.prepare_timeout + o.margin + o.resend * 4 {
            return Err(invalid(format!(
                "a hold of {} leaves no time to commit: it must be at least prepare_timeout + margin + 4 resends ({})",
                o.hold,
                o.prepare_timeout + o.margin + o.resend * 4
            )));
        }
        let mut nodes: Vec<NodeState> = Vec::new();
        for part in &plan.parts {
            if part.node == me {
                return Err(invalid(format!(
                    "{me} coordinates this plan and cannot be part of it (send it from another node, e.g. the ayllu tool)"
                )));
            }
            if nodes.iter().any(|n| n.node == part.node) {
                return Err(invalid(format!("{} appears twice in the plan", part.node)));
            }
            if part.changes.len() > 255 {
                return Err(invalid(format!("{} changes for {}; at most 255", part.changes.len(), part.node)));
            }
            let changes: Vec<Change> = part.changes.iter().map(|c| sent_form(part.node, c)).collect();
            for (i, c) in changes.iter().enumerate() {
                c.check().map_err(|e| invalid(format!("{}, change {} ({}): {e}", part.node, i + 1, c.describe())))?;
            }
            nodes.push(NodeState {
                node: part.node,
                changes,
                prepare: None,
                prepare_sent: (0, Instant::ZERO),
                rtt: None,
                refused: None,
                copies: Vec::new(),
                next_copy: Instant::ZERO,
                commit: None,
                abort: None,
                abort_result: None,
            });
        }
        Ok(Coordinator {
            txn,
            options: o,
            nodes,
            phase: Phase::Start,
            started: Instant::ZERO,
            switch_at: None,
            max_rtt: Duration::ZERO,
        })
    }

    /// The transaction's number.
    pub fn txn(&self) -> u64 {
        self.txn
    }

    /// When [`Coordinator::step`] next has something to do at the latest (it may be called
    /// more often; answers are looked at whenever it is).
    pub fn next_due(&self, now: Instant) -> Instant {
        now + self.options.resend.min(Duration::from_millis(5))
    }

    /// Advance the transaction at `now` (the coordinator node's time), sending through
    /// `core`; the report once it has ended. Call it after every step of the node.
    pub fn step(&mut self, core: &mut NodeCore, now: Instant) -> Option<ApplyReport> {
        match self.phase {
            Phase::Start => {
                self.started = now;
                for n in &mut self.nodes {
                    let body =
                        ControlBody::Prepare { txn: self.txn, changes: n.changes.clone(), hold: self.options.hold };
                    n.prepare = core.request(n.node, body).ok();
                    n.prepare_sent = (1, now);
                }
                self.phase = Phase::Preparing;
                None
            }
            Phase::Preparing => {
                self.collect_prepares(core, now);
                if self.nodes.iter().any(|n| n.refused.is_some()) {
                    self.start_abort(core);
                    return None;
                }
                if self.nodes.iter().all(|n| n.rtt.is_some()) {
                    self.max_rtt = self.nodes.iter().filter_map(|n| n.rtt).max().unwrap_or(Duration::ZERO);
                    let s = now + self.options.margin + self.max_rtt;
                    if s + self.options.resend * 4 > self.started + self.options.hold {
                        for n in &mut self.nodes {
                            n.refused = Some((false, "the team answered too slowly to commit within the hold".into()));
                        }
                        self.start_abort(core);
                        return None;
                    }
                    self.switch_at = Some(s);
                    self.phase = Phase::Committing;
                    return self.commit_round(core, now);
                }
                if now >= self.started + self.options.prepare_timeout {
                    let t = self.options.prepare_timeout;
                    for n in self.nodes.iter_mut().filter(|n| n.rtt.is_none() && n.refused.is_none()) {
                        n.refused = Some((false, format!("no answer to PREPARE within {t}")));
                    }
                    self.start_abort(core);
                }
                None
            }
            Phase::Committing => self.commit_round(core, now),
            Phase::Aborting => {
                for n in &mut self.nodes {
                    if n.abort_result.is_some() {
                        continue;
                    }
                    let Some(id) = n.abort else { continue };
                    match core.take_answer(id) {
                        Some(Ok(_)) => n.abort_result = Some(Ok(())),
                        Some(Err(e)) => n.abort_result = Some(Err(e)),
                        None => {}
                    }
                }
                let end = self.started + self.options.hold;
                if now >= end {
                    for n in self.nodes.iter_mut().filter(|n| n.abort_result.is_none()) {
                        n.abort_result = Some(Err(
                            "no answer to ABORT (a node that prepared aborts by itself at the end of its hold)".into(),
                        ));
                    }
                }
                if self.nodes.iter().all(|n| n.abort_result.is_some()) {
                    for n in &self.nodes {
                        if let Some(id) = n.abort {
                            core.forget_request(id);
                        }
                    }
                    return Some(self.report(Outcome::Aborted));
                }
                None
            }
        }
    }

    fn collect_prepares(&mut self, core: &mut NodeCore, now: Instant) {
        for n in &mut self.nodes {
            if n.rtt.is_some() || n.refused.is_some() {
                continue;
            }
            let Some(id) = n.prepare else {
                n.refused = Some((false, "the request could not be sent".into()));
                continue;
            };
            if let Some(RequestStatus::Pending { sends }) = core.request_status(id) {
                if sends > n.prepare_sent.0 {
                    n.prepare_sent = (sends, now);
                }
                continue;
            }
            match core.take_answer(id) {
                Some(Ok(ReplyBody::Value(Value::Text(t)))) if &*t == "prepared" => {
                    // From the last send: a resent PREPARE's answer says nothing of the first.
                    n.rtt = Some(now - n.prepare_sent.1);
                }
                Some(Ok(other)) => n.refused = Some((true, format!("an unexpected answer to PREPARE: {other:?}"))),
                Some(Err(e)) => n.refused = Some((true, e)),
                None => {}
            }
        }
    }

    fn start_abort(&mut self, core: &mut NodeCore) {
        self.phase = Phase::Aborting;
        for n in &mut self.nodes {
            if let Some(id) = n.prepare.take() {
                core.forget_request(id);
            }
            if n.rtt.is_none() {
                n.refused.get_or_insert_with(|| (false, "no answer to PREPARE before the abort".into()));
            }
            n.abort = core.request(n.node, ControlBody::Abort { txn: self.txn }).ok();
        }
    }

    fn commit_round(&mut self, core: &mut NodeCore, now: Instant) -> Option<ApplyReport> {
        let s = self.switch_at.expect("committing has a switch time");
        let end = self.started + self.options.hold;
        for n in &mut self.nodes {
            if n.commit.is_some() {
                continue;
            }
            // Any copy's answer will do: each places the switch within its own round trip.
            let mut answer = None;
            for &(id, sent) in &n.copies {
                match core.take_answer(id) {
                    Some(Ok(ReplyBody::Value(Value::Int(x)))) => {
                        let shift = |t: Instant| {
                            if x >= 0 {
                                t + Duration::from_nanos(x.unsigned_abs())
                            } else {
                                Instant::from_nanos(t.as_nanos().saturating_sub(x.unsigned_abs()))
                            }
                        };
                        answer = Some(Ok(SwitchWindow { earliest: shift(sent), latest: shift(now) }));
                        break;
                    }
                    Some(Ok(other)) => {
                        answer = Some(Err(format!("an unexpected answer to COMMIT: {other:?}")));
                        break;
                    }
                    // The node refused: it aborted by itself (its hold ended) or never prepared.
                    Some(Err(e)) => {
                        answer = Some(Err(e));
                        break;
                    }
                    None => {}
                }
            }
            if answer.is_none() && now >= end {
                answer = Some(Err(
                    "no answer to COMMIT: it switched late, or aborted by itself at the end of its hold".into(),
                ));
            }
            if let Some(a) = answer {
                for (id, _) in n.copies.drain(..) {
                    core.forget_request(id);
                }
                n.commit = Some(a);
                continue;
            }
            // A copy is forgotten before the core would send it again with its stale delay
            // (R11); a newer copy carries a fresh one.
            n.copies.retain(|&(id, sent)| {
                let keep = now - sent < COPY_LIFETIME;
                if !keep {
                    core.forget_request(id);
                }
                keep
            });
            if n.copies.is_empty() || now >= n.next_copy {
                let half = Duration::from_nanos(n.rtt.unwrap_or(Duration::ZERO).as_nanos() / 2);
                let delay = if s > now + half { s - now - half } else { Duration::ZERO };
                if let Ok(id) = core.request(n.node, ControlBody::Commit { txn: self.txn, delay }) {
                    n.copies.push((id, now));
                }
                n.next_copy = now + self.options.resend;
            }
        }
        if self.nodes.iter().all(|n| n.commit.is_some()) {
            let all = self.nodes.iter().all(|n| matches!(n.commit, Some(Ok(_))));
            return Some(self.report(if all { Outcome::Switched } else { Outcome::Split }));
        }
        None
    }

    fn report(&self, outcome: Outcome) -> ApplyReport {
        let nodes: Vec<NodeOutcome> = self
            .nodes
            .iter()
            .map(|n| NodeOutcome {
                node: n.node,
                prepare: match (&n.refused, n.rtt) {
                    (Some((_, e)), _) => Err(e.clone()),
                    (None, Some(rtt)) => Ok(rtt),
                    (None, None) => Err("no answer to PREPARE".into()),
                },
                refused: n.refused.as_ref().is_some_and(|(r, _)| *r),
                commit: n.commit.clone(),
                abort: n.abort_result.clone(),
            })
            .collect();
        let windows: Vec<SwitchWindow> =
            nodes.iter().filter_map(|n| n.commit.as_ref().and_then(|c| c.as_ref().ok()).copied()).collect();
        let skew_bound = (outcome == Outcome::Switched && !windows.is_empty()).then(|| {
            let latest = windows.iter().map(|w| w.latest).max().expect("not empty");
            let earliest = windows.iter().map(|w| w.earliest).min().expect("not empty");
            latest - earliest
        });
        ApplyReport { txn: self.txn, outcome, nodes, switch_at: self.switch_at, skew_bound, max_rtt: self.max_rtt }
    }
}

/// A transaction number unlikely to repeat: the node's clock and the system time mixed, so
/// that a restarted tool does not reuse one a node still remembers.
pub fn fresh_txn(node: &Node) -> u64 {
    let wall = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_nanos() as u64);
    wall ^ node.now().as_nanos().rotate_left(32) ^ u64::from(node.id().0)
}

/// Apply `plan` from `node` (which must not be part of it) in real time: the blocking form of
/// [`Coordinator`], as `ayllu apply` uses it. Returns when the transaction has ended and, if
/// the team switched, once every node's switch is past (at most the plan's hold after it
/// started).
pub fn apply(node: &mut Node, plan: &Plan) -> Result<ApplyReport, Error> {
    let mut c = Coordinator::new(fresh_txn(node), plan, node.id())?;
    // On a manual clock nothing would ever time out: bounded by the wall clock as well.
    let wall_end = std::time::Instant::now()
        + std::time::Duration::from_nanos(plan.options.hold.as_nanos())
        + std::time::Duration::from_secs(2);
    let stuck = || Error::Plan {
        what: "the node's clock does not advance (a manual clock?): apply needs a node on the real clock; \
               drive a Coordinator with your own clock instead"
            .into(),
    };
    loop {
        if std::time::Instant::now() > wall_end {
            return Err(stuck());
        }
        node.step();
        let now = node.now();
        let report = c.step(node.core_mut(), now);
        // Send what the step asked at once: a COMMIT copy's delay counts from now.
        node.step();
        if let Some(r) = report {
            // Return once every node has switched (the latest end of their windows), so that
            // what the caller asks next sees the new structure.
            let latest = r.nodes.iter().filter_map(|n| n.commit.as_ref()?.as_ref().ok().map(|w| w.latest)).max();
            while let Some(t) = latest.filter(|&t| node.now() < t) {
                if std::time::Instant::now() > wall_end {
                    return Err(stuck());
                }
                node.wait(std::time::Duration::from_nanos((t - node.now()).as_nanos().min(1_000_000)));
                node.step();
            }
            return Ok(r);
        }
        let wait = c.next_due(now) - now;
        node.wait(std::time::Duration::from_nanos(wait.as_nanos()));
    }
}
