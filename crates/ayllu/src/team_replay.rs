//! # Team replay: the flight recordings of several nodes as one system
//!
//! One node's flight recording replays that node alone ([`crate::replay`]). A team's
//! recordings together say more, because every port value one node received from another was
//! sent by that other, and the sender's replay makes that very message again: the same
//! connection, the same sequence number (the sequence base is recorded), the same value.
//! Matching what each node received with what the others' replays send gives, with no clock
//! synchronised while recording:
//!
//! * **The clocks, with a bound.** A message sent at `s` on A's clock and received at `r` on
//!   B's took no less than nothing, so B's clock minus A's is at most `r - s`; a message the
//!   other way bounds it from below. Every message gives one such difference constraint; the
//!   tightest bounds they imply (through every path of the team, by shortest paths) give each
//!   node's clock against the first recording's, as an interval. Its midpoint is the estimate
//!   and its half-width the bound printed: the true offset lies within it whatever the delays
//!   were.
//! * **Causality, checked.** Every remote value a node accepted was sent by its sender (a
//!   message of that connection and sequence number exists in the sender's replay), with the
//!   same value bit for bit, no later than it was accepted (the constraints have a solution:
//!   a message that arrived before it was sent makes them contradict each other), and was
//!   accepted once. A value never sent, one altered, one accepted twice, are *findings*, each
//!   naming the receiving node, its journal position and time, and the message.
//! * **Each node's replay**, checked as `ayllu replay FILE check` checks it: a divergence or a
//!   hole is a finding too.
//!
//! Values from nodes that were not recorded (a tool's `ayllu write`) are counted by sender,
//! not judged. Promises: the same files give the same answer; no recording makes it panic.

use std::collections::{BTreeMap, HashMap};
use std::fmt;

use ayllu_core::{ConnectionId, Destination, Event, Instant, Message, NodeId, PortMessage, Value};

use crate::recording_format::same_bits;
use crate::replay::{is_input, Divergence, Ending, Recording, Replay};

/// A port message's identity in a team: its sender, the sender's connection, its sequence
/// number on that connection (N1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct MessageId {
    /// The sending node.
    pub from: NodeId,
    /// The connection on the sender.
    pub conn: ConnectionId,
    /// Its sequence number on that connection.
    pub seq: u64,
}

impl fmt::Display for MessageId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{} #{}", self.from, self.conn, self.seq)
    }
}

/// A port message a node received, from its recording.
#[derive(Clone, Debug)]
pub struct Arrival {
    /// The receiving node.
    pub node: NodeId,
    /// Its position in the receiver's journal.
    pub entry: u64,
    /// When, on the receiver's clock.
    pub at: Instant,
    /// Which message.
    pub id: MessageId,
    /// The message as it arrived.
    pub message: PortMessage,
    /// Whether the destination port accepted it (rather than refusing it: a window, a stale
    /// sequence number, a type).
    pub accepted: bool,
}

/// A port message a node sent, from its replay.
#[derive(Clone, Debug)]
pub struct Sending {
    /// When, on the sender's clock (the input that made it; the live node sent it then or a
    /// moment after).
    pub at: Instant,
    /// To whom.
    pub to: Destination,
    /// The message.
    pub message: PortMessage,
}

/// One node's clock against the reference (the first recording's node): the interval that
/// holds `this clock - reference clock`, in seconds. A side is `None` when no chain of
/// messages bounds it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClockBound {
    /// The node.
    pub node: NodeId,
    /// The offset is at least this.
    pub low: Option<f64>,
    /// The offset is at most this.
    pub high: Option<f64>,
}

impl ClockBound {
    /// The estimate: the middle of the interval (`None` unless both sides are bounded).
    pub fn offset(&self) -> Option<f64> {
        Some((self.low? + self.high?) / 2.0)
    }
    /// How far the true offset may lie from [`ClockBound::offset`]: half the interval.
    pub fn bound(&self) -> Option<f64> {
        Some((self.high? - self.low?) / 2.0)
    }
}

/// Something the recordings contradict.
#[derive(Clone, Debug)]
pub enum Finding {
    /// A node's own replay did not reproduce its recording.
    Diverged {
        /// The node.
        node: NodeId,
        /// Where and what.
        divergence: Divergence,
    },
    /// A node's recording has a hole (entries dropped while recording, or removed since): its
    /// replay, and what the team replay knows of it, stop there.
    Hole {
        /// The node.
        node: NodeId,
        /// The journal position of the hole.
        entry: u64,
        /// Its node time.
        at: Instant,
    },
    /// Two recordings are of the same node id.
    SameNode {
        /// The node id.
        node: NodeId,
    },
    /// A node accepted a value its sender's replay never sent.
    NeverSent {
        /// What arrived.
        arrival: Arrival,
    },
    /// A node accepted a value other than the one its sender sent with that id.
    ValueDiffers {
        /// What arrived.
        arrival: Arrival,
        /// What the sender sent.
        sent: Value,
    },
    /// A node accepted the same message twice.
    AcceptedTwice {
        /// The first acceptance.
        first: Arrival,
        /// The second.
        again: Arrival,
    },
    /// Messages between two nodes that cannot all have been received after they were sent,
    /// whatever the offset between their clocks: one of them was received before it was sent.
    ReceivedBeforeSent {
        /// A message from the first node to the second, and the one the other way whose
        /// bounds contradict it.
        arrivals: Vec<Arrival>,
        /// By how much the bounds contradict each other (s).
        by: f64,
    },
}

impl fmt::Display for Finding {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let at = |a: &Arrival| {
            format!(
                "{} entry {} (t={}): {} {}.{} = {}",
                a.node, a.entry, a.at, a.id, a.message.behavior, a.message.port, a.message.value
            )
        };
        match self {
            Finding::Diverged { node, divergence } => write!(f, "{node}'s own replay: {divergence}"),
            Finding::Hole { node, entry, at } => {
                write!(f, "{node}'s recording has a hole at entry {entry} (t={at}): it is known up to there")
            }
            Finding::SameNode { node } => write!(f, "two recordings are of {node}: give each node once"),
            Finding::NeverSent { arrival } => {
                write!(f, "never sent: {}; {} sent no such message", at(arrival), arrival.id.from)
            }
            Finding::ValueDiffers { arrival, sent } => {
                write!(f, "altered: {}; {} sent {sent}", at(arrival), arrival.id.from)
            }
            Finding::AcceptedTwice { first, again } => {
                write!(f, "accepted twice: {}; and again at entry {} (t={})", at(first), again.entry, again.at)
            }
            Finding::ReceivedBeforeSent { arrivals, by } => {
                let list: Vec<String> = arrivals.iter().map(at).collect();
                write!(f, "received before sent (by at least {}): {}", seconds(*by), list.join("; "))
            }
        }
    }
}

/// What a team replay found.
#[derive(Clone, Debug)]
pub struct TeamCheck {
    /// The nodes, in the order of the recordings given; the first one's clock is the reference.
    pub nodes: Vec<NodeId>,
    /// Each node's clock against the reference (the reference's own is 0).
    pub clocks: Vec<ClockBound>,
    /// How many port values each node's replay reproduced bit for bit.
    pub replayed: Vec<(NodeId, usize)>,
    /// Remote values accepted from recorded nodes.
    pub accepted_remote: usize,
    /// Of them, those matched with their sending: same value, once.
    pub explained: usize,
    /// Messages sent and received between recorded nodes, for each ordered pair (sender,
    /// receiver): what bounded the clocks.
    pub matched: BTreeMap<(NodeId, NodeId), usize>,
    /// Values accepted from nodes that were not recorded (tools), by sender: counted, not judged.
    pub from_unrecorded: BTreeMap<NodeId, usize>,
    /// Values accepted from a sender whose recording stops early (a hole, a divergence, a cut
    /// or capped file) and sent after that point, by sender: what the sender did then is not
    /// known, so they are counted, not judged.
    pub after_sender_stopped: BTreeMap<NodeId, usize>,
    /// Values accepted from a sender whose recording is rolling and starts later (its
    /// checkpoint), sent before that point, by sender: counted, not judged, for the same reason.
    pub before_sender_started: BTreeMap<NodeId, usize>,
    /// Recordings that end before their node stopped recording (cut short: the node was
    /// killed or the file cut; or capped), with how: not a contradiction (a killed robot's
    /// recording is cut), but what the team replay knows of that node ends there.
    pub endings: Vec<(NodeId, String)>,
    /// What the recordings contradict; empty when the team replay holds.
    pub findings: Vec<Finding>,
}

impl TeamCheck {
    /// Whether nothing was found.
    pub fn passed(&self) -> bool {
        self.findings.is_empty()
    }
    /// The same as one JSON object, for `ayllu replay ... check --json` and Python: `nodes`,
    /// `reference`, `clocks` (`node`, `low_s`, `high_s`, `offset_s`, `bound_s`; null where a
    /// side is unbounded), `replayed`, `matched`, `accepted_remote`, `explained`,
    /// `unexplained`, `from_unrecorded`, `after_sender_stopped`, `findings` (their lines) and
    /// `passed`.
    pub fn to_json(&self) -> serde_json::Value {
        use serde_json::json;
        let by_node = |m: &BTreeMap<NodeId, usize>| -> Vec<serde_json::Value> {
            m.iter().map(|(n, k)| json!({"node": n.0, "values": k})).collect()
        };
        let clocks: Vec<serde_json::Value> = self
            .clocks
            .iter()
            .map(|c| json!({"node": c.node.0, "low_s": c.low, "high_s": c.high, "offset_s": c.offset(), "bound_s": c.bound()}))
            .collect();
        json!({
            "nodes": self.nodes.iter().map(|n| n.0).collect::<Vec<_>>(),
            "reference": self.nodes.first().map(|n| n.0),
            "clocks": clocks,
            "replayed": self.replayed.iter().map(|(n, k)| json!({"node": n.0, "values": k})).collect::<Vec<_>>(),
            "matched": self.matched.iter().map(|((a, b), k)| json!({"from": a.0, "to": b.0, "messages": k})).collect::<Vec<_>>(),
            "accepted_remote": self.accepted_remote,
            "explained": self.explained,
            "unexplained": self.unexplained(),
            "from_unrecorded": by_node(&self.from_unrecorded),
            "after_sender_stopped": by_node(&self.after_sender_stopped),
            "before_sender_started": by_node(&self.before_sender_started),
            "endings": self.endings.iter().map(|(n, e)| json!({"node": n.0, "ending": e})).collect::<Vec<_>>(),
            "findings": self.findings.iter().map(|f| f.to_string()).collect::<Vec<_>>(),
            "passed": self.passed(),
        })
    }

    /// Remote values accepted from recorded nodes, judged, and not matched with their sending.
    pub fn unexplained(&self) -> usize {
        self.accepted_remote
            - self.explained
            - self.after_sender_stopped.values().sum::<usize>()
            - self.before_sender_started.values().sum::<usize>()
    }
}

fn seconds(s: f64) -> String {
    if s.abs() < 1e-3 {
        format!("{:.1} us", s * 1e6)
    } else if s.abs() < 1.0 {
        format!("{:.3} ms", s * 1e3)
    } else {
        format!("{s:.6} s")
    }
}

impl fmt::Display for TeamCheck {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let names: Vec<String> = self.nodes.iter().map(|n| n.to_string()).collect();
        let reference = self.nodes.first().map_or("none".to_owned(), |n| n.to_string());
        writeln!(f, "team replay of {} recordings: {} (clocks against {reference}'s)", names.len(), names.join(", "))?;
        for c in self.clocks.iter().skip(1) {
            match (c.offset(), c.bound(), c.low, c.high) {
                (Some(o), Some(b), _, _) => {
                    let sign = if o < 0.0 { '-' } else { '+' };
                    writeln!(f, "  {} clock = {reference} {sign} {} ± {}", c.node, seconds(o.abs()), seconds(b))?
                }
                (_, _, Some(l), None) => {
                    writeln!(f, "  {} clock >= {reference} + {} (no message back)", c.node, seconds(l))?
                }
                (_, _, None, Some(h)) => {
                    writeln!(f, "  {} clock <= {reference} + {} (no message to it)", c.node, seconds(h))?
                }
                _ => writeln!(f, "  {} clock: no message joins it to {reference}'s", c.node)?,
            }
        }
        let pairs: Vec<String> = self.matched.iter().map(|((a, b), n)| format!("{a}->{b} {n}")).collect();
        writeln!(f, "messages matched: {}", if pairs.is_empty() { "none".into() } else { pairs.join(", ") })?;
        let own: Vec<String> = self.replayed.iter().map(|(n, k)| format!("{n} {k}")).collect();
        writeln!(f, "each node's replay: values reproduced bit for bit: {}", own.join(", "))?;
        writeln!(
            f,
            "remote values accepted: {}; sent by their sender with the same value, no later than accepted, once: {} \
             ({} unexplained)",
            self.accepted_remote,
            self.explained,
            self.unexplained()
        )?;
        if !self.after_sender_stopped.is_empty() {
            let from: Vec<String> = self.after_sender_stopped.iter().map(|(n, k)| format!("{n} ({k})")).collect();
            writeln!(f, "values sent after their sender's recording stops (not judged): {}", from.join(", "))?;
        }
        if !self.before_sender_started.is_empty() {
            let from: Vec<String> = self.before_sender_started.iter().map(|(n, k)| format!("{n} ({k})")).collect();
            writeln!(
                f,
                "values sent before their sender's rolling recording starts (not judged): {}",
                from.join(", ")
            )?;
        }
        if !self.from_unrecorded.is_empty() {
            let from: Vec<String> = self.from_unrecorded.iter().map(|(n, k)| format!("{n} ({k})")).collect();
            writeln!(f, "values from nodes not recorded (not judged): {}", from.join(", "))?;
        }
        for (node, ending) in &self.endings {
            writeln!(f, "NOTE {node}'s recording ends early: {ending}")?;
        }
        for finding in &self.findings {
            writeln!(f, "FOUND {finding}")?;
        }
        Ok(())
    }
}

/// The port messages `recording`'s node received, before its first hole, and whether each
/// was accepted: an `accepted` entry of the message's destination port among the consequences
/// of its `receive` (the entries up to the next input). A recorded `accepted` names its port by
/// handle; the name comes from the class the journal defined for that behavior.
pub fn arrivals(recording: &Recording) -> Vec<Arrival> {
    let end = recording.gap.map_or(recording.entries.len(), |(seq, _)| seq as usize);
    let entries = &recording.entries[..end.min(recording.entries.len())];
    let mut names = PortNames::default();
    let mut out = Vec::new();
    for (i, e) in entries.iter().enumerate() {
        names.see(&e.event);
        let Event::Receive { from, message } = &e.event else { continue };
        let Message::Port(m) = &**message else { continue };
        let consequences = entries[i + 1..].iter().take_while(|c| !is_input(&c.event));
        let accepted = consequences.into_iter().any(|c| match &c.event {
            Event::Accepted { behavior, port, .. } => {
                **behavior == *m.behavior && names.port(behavior, *port) == Some(&*m.port)
            }
            _ => false,
        });
        out.push(Arrival {
            node: recording.node,
            entry: i as u64,
            at: e.at,
            id: MessageId { from: *from, conn: m.conn, seq: m.seq },
            message: m.clone(),
            accepted,
        });
    }
    out
}

/// Replay `recording` whole, keeping the port messages it sends; a divergence or a hole is
/// returned beside what was sent up to it, with the number of values reproduced.
pub fn sendings(recording: &Recording) -> (HashMap<MessageId, Sending>, usize, Option<Divergence>) {
    let mut replay = Replay::new(recording);
    replay.keep_sent();
    let result = replay.run_to_end();
    let mut sent = HashMap::new();
    for (at, out) in replay.take_sent() {
        if let Message::Port(m) = out.message {
            let id = MessageId { from: recording.node, conn: m.conn, seq: m.seq };
            sent.insert(id, Sending { at, to: out.to, message: m });
        }
    }
    (sent, replay.checked(), result.err())
}

/// The tightest difference `receiver clock - sender clock` bounds from above, per ordered
/// pair: the least `r - s` over the messages between them, in nanoseconds, with that message.
type Tightest = HashMap<(usize, usize), (i128, Arrival)>;

/// Check a team's recordings as one system (see the module docs).
pub fn check(recordings: &[Recording]) -> TeamCheck {
    analyse(recordings).0
}

/// What the sender's replays sent, by message, and what each node received, by node.
type Matched = (HashMap<MessageId, Sending>, HashMap<NodeId, Vec<Arrival>>);

/// The check, with what it was made from: each recording is replayed and read once, for the
/// check and for the questions [`Team::why`] asks afterwards.
fn analyse(recordings: &[Recording]) -> (TeamCheck, Matched) {
    let nodes: Vec<NodeId> = recordings.iter().map(|r| r.node).collect();
    let index: HashMap<NodeId, usize> = nodes.iter().enumerate().map(|(i, n)| (*n, i)).rev().collect();
    let mut findings = Vec::new();
    let mut repeated = Vec::new();
    for (i, n) in nodes.iter().enumerate() {
        if nodes[..i].contains(n) && !repeated.contains(n) {
            repeated.push(*n);
            findings.push(Finding::SameNode { node: *n });
        }
    }

    let mut sent: HashMap<MessageId, Sending> = HashMap::new();
    let mut replayed = Vec::new();
    // For a sender whose replay stops early: the last sequence number it is known to have sent
    // on each connection (an arrival beyond it is not judged).
    let mut known_up_to: HashMap<NodeId, HashMap<ConnectionId, u64>> = HashMap::new();
    let mut endings = Vec::new();
    // For a sender whose rolling recording starts late: the first sequence number it is known to
    // have sent on each connection (an arrival before it is not judged).
    let mut known_from: HashMap<NodeId, HashMap<ConnectionId, u64>> = HashMap::new();
    for r in recordings {
        let (s, checked, divergence) = sendings(r);
        if r.checkpoint.is_some() {
            let first = known_from.entry(r.node).or_default();
            for id in s.keys() {
                let seq = first.entry(id.conn).or_insert(id.seq);
                *seq = (*seq).min(id.seq);
            }
        }
        if divergence.is_some() || r.gap.is_some() || r.ending != Ending::Closed {
            let last = known_up_to.entry(r.node).or_default();
            for id in s.keys() {
                let seq = last.entry(id.conn).or_default();
                *seq = (*seq).max(id.seq);
            }
        }
        sent.extend(s);
        replayed.push((r.node, checked));
        if r.ending != Ending::Closed {
            let known = r.last_known().map_or(String::new(), |t| format!("; known up to t={t}"));
            endings.push((r.node, format!("{}{known}", r.ending)));
        }
        if let Some(divergence) = divergence {
            findings.push(Finding::Diverged { node: r.node, divergence });
        }
        if let Some((entry, at)) = r.gap {
            findings.push(Finding::Hole { node: r.node, entry, at });
        }
    }

    let mut accepted_remote = 0;
    let mut explained = 0;
    let mut matched: BTreeMap<(NodeId, NodeId), usize> = BTreeMap::new();
    let mut from_unrecorded: BTreeMap<NodeId, usize> = BTreeMap::new();
    let mut after_sender_stopped: BTreeMap<NodeId, usize> = BTreeMap::new();
    let mut before_sender_started: BTreeMap<NodeId, usize> = BTreeMap::new();
    let mut tightest: Tightest = HashMap::new();
    let mut first_acceptance: HashMap<(NodeId, MessageId), Arrival> = HashMap::new();
    let mut received: HashMap<NodeId, Vec<Arrival>> = HashMap::new();
    for r in recordings {
        let all = arrivals(r);
        for a in all.iter().cloned() {
            let Some(&from) = index.get(&a.id.from) else {
                if a.accepted {
                    *from_unrecorded.entry(a.id.from).or_default() += 1;
                }
                continue;
            };
            // What arrived bounds the clocks whether or not it was accepted.
            let s = sent.get(&a.id);
            if let Some(s) = s {
                *matched.entry((a.id.from, a.node)).or_default() += 1;
                let diff = i128::from(a.at.as_nanos()) - i128::from(s.at.as_nanos());
                let to = index[&a.node];
                let slot = tightest.entry((from, to)).or_insert((diff, a.clone()));
                if diff < slot.0 {
                    *slot = (diff, a.clone());
                }
            }
            if !a.accepted {
                continue;
            }
            accepted_remote += 1;
            if let Some(first) = first_acceptance.get(&(a.node, a.id)) {
                findings.push(Finding::AcceptedTwice { first: first.clone(), again: a });
                continue;
            }
            first_acceptance.insert((a.node, a.id), a.clone());
            let beyond = known_up_to.get(&a.id.from).map(|last| last.get(&a.id.conn).is_none_or(|&q| a.id.seq > q));
            if s.is_none() && beyond == Some(true) {
                *after_sender_stopped.entry(a.id.from).or_default() += 1;
                continue;
            }
            let before = known_from.get(&a.id.from).map(|first| first.get(&a.id.conn).is_none_or(|&q| a.id.seq < q));
            if s.is_none() && before == Some(true) {
                *before_sender_started.entry(a.id.from).or_default() += 1;
                continue;
            }
            match s {
                None => findings.push(Finding::NeverSent { arrival: a }),
                Some(s) if !same_bits(&s.message.value, &a.message.value) => {
                    findings.push(Finding::ValueDiffers { sent: s.message.value.clone(), arrival: a })
                }
                Some(_) => explained += 1,
            }
        }
        received.insert(r.node, all);
    }

    let (clocks, contradictions) = clocks(&nodes, &tightest);
    findings.extend(contradictions);
    let check = TeamCheck {
        nodes,
        clocks,
        replayed,
        accepted_remote,
        explained,
        matched,
        from_unrecorded,
        after_sender_stopped,
        before_sender_started,
        endings,
        findings,
    };
    (check, (sent, received))
}

/// Each node's clock against the first's, from the tightest bounds per pair (difference
/// constraints `clock[to] - clock[from] <= r - s`, closed by Floyd-Warshall), and the pairs
/// whose messages contradict each other (a negative cycle: something arrived before it was sent).
fn clocks(nodes: &[NodeId], tightest: &Tightest) -> (Vec<ClockBound>, Vec<Finding>) {
    let n = nodes.len();
    let mut dist = vec![vec![None::<i128>; n]; n];
    for (i, row) in dist.iter_mut().enumerate() {
        row[i] = Some(0);
    }
    for (&(from, to), (d, _)) in tightest {
        let cell = &mut dist[from][to];
        *cell = Some(cell.map_or(*d, |c| c.min(*d)));
    }
    for k in 0..n {
        let through_k = dist[k].clone();
        for row in dist.iter_mut() {
            let Some(ik) = row[k] else { continue };
            for (cell, kj) in row.iter_mut().zip(&through_k) {
                if let Some(kj) = kj {
                    let through = ik + kj;
                    if cell.is_none_or(|d| through < d) {
                        *cell = Some(through);
                    }
                }
            }
        }
    }
    let mut findings = Vec::new();
    // A direct contradiction names its two messages; a longer cycle its nodes' messages.
    let mut named = false;
    for a in 0..n {
        for b in a + 1..n {
            if let (Some((ab, x)), Some((ba, y))) = (tightest.get(&(a, b)), tightest.get(&(b, a))) {
                if ab + ba < 0 {
                    named = true;
                    findings.push(Finding::ReceivedBeforeSent {
                        arrivals: vec![x.clone(), y.clone()],
                        by: -((ab + ba) as f64) / 1e9,
                    });
                }
            }
        }
    }
    if !named {
        if let Some(i) = (0..n).find(|&i| dist[i][i].is_some_and(|d| d < 0)) {
            let arrivals: Vec<Arrival> =
                tightest.iter().filter(|((f, t), _)| *f == i || *t == i).map(|(_, (_, a))| a.clone()).collect();
            findings.push(Finding::ReceivedBeforeSent { by: -(dist[i][i].unwrap_or(0) as f64) / 1e9, arrivals });
        }
    }
    let clocks = (0..n)
        .map(|k| ClockBound {
            node: nodes[k],
            // clock[k] - clock[0] <= dist[0][k]; clock[0] - clock[k] <= dist[k][0].
            high: dist[0][k].map(|d| d as f64 / 1e9),
            low: dist[k][0].map(|d| -(d as f64) / 1e9),
        })
        .collect();
    (clocks, findings)
}

/// A team's recordings, replayed as one system, ready to be asked [`Team::why`].
pub struct Team {
    recordings: Vec<Recording>,
    check: TeamCheck,
    sent: HashMap<MessageId, Sending>,
    arrivals: HashMap<NodeId, Vec<Arrival>>,
}

/// One line of a causal chain ([`Team::why`]): what was found at a node, at an instant of its
/// clock, `depth` hops of messages away from the port asked about.
#[derive(Clone, Debug, PartialEq)]
pub struct Link {
    /// Hops from the port asked about (0: on its node).
    pub depth: usize,
    /// Indentation: how many causes deep this line is.
    pub level: usize,
    /// The node it is about.
    pub node: NodeId,
    /// The instant, on that node's clock.
    pub at: Instant,
    /// What: `port` (a port's value and who supplied it), `window`, `message` (a message and its
    /// sending), `activation` (the process run that wrote a port), `input` (what that run could
    /// read), `outside` (written from outside the node), `end` (the chain stops here: why).
    pub kind: &'static str,
    /// The line, in words.
    pub text: String,
}

/// A causal chain: the port asked about, each window and supplier followed to the node that
/// holds or sent it, into that node's recording, as far as the depth asked.
#[derive(Clone, Debug, Default)]
pub struct Chain {
    /// The lines, in the order printed.
    pub links: Vec<Link>,
}

impl fmt::Display for Chain {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for l in &self.links {
            writeln!(f, "{}{}", "  ".repeat(l.level), l.text)?;
        }
        Ok(())
    }
}

impl Chain {
    /// The chain as JSON: an array of links (`depth`, `level`, `node`, `t` on that node's
    /// clock, `kind`, `text`).
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::Value::Array(
            self.links
                .iter()
                .map(|l| {
                    serde_json::json!({"depth": l.depth, "level": l.level, "node": l.node.0, "t": l.at.as_secs_f64(),
                                       "kind": l.kind, "text": l.text})
                })
                .collect(),
        )
    }
}

/// Port names by behavior, from the classes a journal defined and the behaviors it created,
/// as the journal is read in order (a recorded `accepted` or process write names its port by
/// handle, and the class of the entry is a stand-in).
#[derive(Default)]
struct PortNames {
    classes: HashMap<String, Vec<String>>,
    behaviors: HashMap<String, Vec<String>>,
}

impl PortNames {
    /// Learn from one journal entry.
    fn see(&mut self, e: &Event) {
        match e {
            Event::Define(class) => {
                self.classes.insert(class.name().to_owned(), class.ports().iter().map(|p| p.name.clone()).collect());
            }
            Event::Create { class, name } => {
                if let Some(ports) = self.classes.get(class) {
                    self.behaviors.insert(name.clone(), ports.clone());
                }
            }
            _ => {}
        }
    }

    /// The name of `behavior`'s port with handle `handle`.
    fn port(&self, behavior: &str, handle: u16) -> Option<&str> {
        self.behaviors.get(behavior)?.get(usize::from(handle)).map(String::as_str)
    }

    /// The names of `behavior`'s ports, in handle order.
    fn ports(&self, behavior: &str) -> &[String] {
        self.behaviors.get(behavior).map_or(&[], Vec::as_slice)
    }

    /// What `recording` defined up to `until`.
    fn until(recording: &Recording, until: Instant) -> PortNames {
        let mut names = PortNames::default();
        recording.entries.iter().take_while(|e| e.at <= until).for_each(|e| names.see(&e.event));
        names
    }
}

/// How a port got its value last, at or before `t`: the process run that wrote it (its index
/// in the journal, its behavior and process, whether the core provides it) or a write from
/// outside the node.
enum Writer {
    /// `input`: the journal position of the input (a poll) in which the process ran.
    Activation {
        at: Instant,
        process: String,
        native: bool,
        input: usize,
        value: Value,
    },
    Outside {
        at: Instant,
    },
}

fn last_writer(recording: &Recording, t: Instant, behavior: &str, port: &str) -> Option<Writer> {
    let names = PortNames::until(recording, t);
    let handle = names.ports(behavior).iter().position(|p| p == port)? as u16;
    let mut run: Option<(&str, &str, bool)> = None;
    let mut input = 0;
    let mut found = None;
    for (i, e) in recording.entries.iter().enumerate().take_while(|(_, e)| e.at <= t) {
        match &e.event {
            Event::Run { behavior, process, native } => run = Some((behavior, process, *native)),
            Event::ProcessWrite { port, value } if *port == handle => {
                if let Some((_, p, native)) = run.filter(|(b, _, _)| *b == behavior) {
                    let value = value.clone();
                    found = Some(Writer::Activation { at: e.at, process: p.to_owned(), native, input, value });
                }
            }
            Event::Write { behavior: b, port: p, .. } if &**b == behavior && *p == handle => {
                found = Some(Writer::Outside { at: e.at });
            }
            ev if is_input(ev) => {
                run = None;
                input = i;
            }
            _ => {}
        }
    }
    found
}

impl Team {
    /// Replay `recordings` as one system (the check of [`check`] is made once, here).
    pub fn open(recordings: Vec<Recording>) -> Team {
        let (check, (sent, arrivals)) = analyse(&recordings);
        Team { recordings, check, sent, arrivals }
    }

    /// What the recordings say of the team as one system.
    pub fn check(&self) -> &TeamCheck {
        &self.check
    }

    fn recording(&self, node: NodeId) -> Option<&Recording> {
        self.recordings.iter().find(|r| r.node == node)
    }

    /// `node`'s clock minus `other`'s, estimated, and its bound (s), from [`TeamCheck::clocks`].
    fn offset(&self, node: NodeId, other: NodeId) -> Option<(f64, f64)> {
        let c = |n: NodeId| self.check.clocks.iter().find(|c| c.node == n);
        let (a, b) = (c(node)?, c(other)?);
        Some((a.offset()? - b.offset()?, a.bound()? + b.bound()?))
    }

    /// Why `behavior.port` on `node` held what it held at `at` (on `node`'s clock), followed
    /// across the team: each window and the supplier to the connection that holds or sent it;
    /// a remote one to the message that carried it and the sender's replay, which says what
    /// wrote the source port (a process run, and what that run could read: for BLE's select,
    /// the eligibilities it compared and where each came from), and on, as far as `depth`
    /// messages away.
    pub fn why(
        &self,
        node: NodeId,
        at: Instant,
        behavior: &str,
        port: &str,
        depth: usize,
    ) -> Result<Chain, crate::RuntimeError> {
        let rec = self.recording(node).ok_or_else(|| crate::RuntimeError::Recording {
            what: format!("no recording of {node} among the team's ({})", self.names()),
        })?;
        let mut replay = Replay::new(rec);
        let report = replay.why_at(at, behavior, port)?;
        let mut chain = Chain::default();
        chain.links.push(Link {
            depth: 0,
            level: 0,
            node,
            at,
            kind: "port",
            text: format!("{report}").trim_end().replace('\n', "\n  "),
        });
        for w in &report.windows {
            let text =
                format!("{:?} window held by {}/c{}, {} more:", w.kind, w.holder.node, w.holder.conn, w.remaining);
            chain.links.push(Link { depth: 0, level: 1, node, at, kind: "window", text });
            self.follow(&mut chain, node, at, w.holder.node, w.holder.conn, 2, 0, depth);
        }
        if let Some(s) = report.supplier {
            self.supplier(&mut chain, node, at, behavior, port, s.node, s.conn, 1, 0, depth);
        }
        Ok(chain)
    }

    fn names(&self) -> String {
        self.recordings.iter().map(|r| r.node.to_string()).collect::<Vec<_>>().join(", ")
    }

    /// Who supplied `behavior.port` on `node` at `at`: its own behavior (the process run that
    /// wrote it), or a connection (followed).
    #[allow(clippy::too_many_arguments)]
    fn supplier(
        &self,
        chain: &mut Chain,
        node: NodeId,
        at: Instant,
        behavior: &str,
        port: &str,
        from: NodeId,
        conn: u64,
        level: usize,
        hops: usize,
        depth: usize,
    ) {
        if conn != 0 {
            let text = format!("{node}:{behavior}.{port} supplied by {from}/c{conn}:");
            chain.links.push(Link { depth: hops, level, node, at, kind: "port", text });
            self.follow(chain, node, at, from, conn, level + 1, hops, depth);
            return;
        }
        let Some(rec) = self.recording(node) else { return };
        match last_writer(rec, at, behavior, port) {
            Some(Writer::Outside { at: w }) => chain.links.push(Link {
                depth: hops,
                level,
                node,
                at: w,
                kind: "outside",
                text: format!("{node}:{behavior}.{port} written from outside the node (the application) at {w}"),
            }),
            Some(Writer::Activation { at: w, process, native, input, value }) => {
                let who = if native { " (the core's own process)" } else { "" };
                let claim = match (process == ayllu_core::BLE_SELECT, &value) {
                    (true, Value::Bool(true)) => ": a claim",
                    _ => "",
                };
                chain.links.push(Link {
                    depth: hops,
                    level,
                    node,
                    at: w,
                    kind: "activation",
                    text: format!(
                        "{node}:{behavior}.{port} = {value}, written at {w} by {behavior}'s process {process}{who}{claim}"
                    ),
                });
                self.inputs(chain, node, w, input, behavior, port, &process, level + 1, hops, depth);
            }
            None => chain.links.push(Link {
                depth: hops,
                level,
                node,
                at,
                kind: "end",
                text: format!("{node}:{behavior}.{port}: no write to it is recorded up to {at}"),
            }),
        }
    }

    /// What the process run at `at` (in the poll at journal position `input`) could read: the
    /// other ports of its behavior, with their values and suppliers just before that poll (for
    /// BLE's select, the two eligibilities it compares); each remote supplier followed.
    #[allow(clippy::too_many_arguments)]
    fn inputs(
        &self,
        chain: &mut Chain,
        node: NodeId,
        at: Instant,
        input: usize,
        behavior: &str,
        written: &str,
        process: &str,
        level: usize,
        hops: usize,
        depth: usize,
    ) {
        let Some(rec) = self.recording(node) else { return };
        let names = PortNames::until(rec, at);
        let ble = process == ayllu_core::BLE_SELECT;
        let ports: Vec<String> = if ble {
            vec![ayllu_core::LOCAL.to_owned(), ayllu_core::BEST.to_owned()]
        } else {
            names.ports(behavior).iter().filter(|p| *p != written).cloned().collect()
        };
        let mut replay = Replay::new(rec);
        if replay.run_before(input).is_err() {
            return;
        }
        let mut follow = Vec::new();
        let mut read = Vec::new();
        for p in &ports {
            let Ok(r) = replay.core().why_at(at, behavior, p) else { continue };
            if !r.fresh && !ble {
                continue;
            }
            let by = r.supplier.map_or("nobody".to_owned(), |s| {
                if s.conn == 0 {
                    format!("{}'s own", s.node)
                } else {
                    format!("{}/c{}", s.node, s.conn)
                }
            });
            let fresh = if r.fresh { "" } else { ", stale" };
            read.push(format!("{p} = {} ({by}{fresh})", r.value));
            if let Some(s) = r.supplier.filter(|s| s.node != node && s.conn != 0) {
                follow.push((p.clone(), s));
            }
        }
        let what = if ble {
            format!("BLE select compared its own eligibility (Local) with the best heard (Best): {}", read.join(", "))
        } else {
            format!("that run could read: {}", if read.is_empty() { "no fresh port".into() } else { read.join(", ") })
        };
        chain.links.push(Link { depth: hops, level, node, at, kind: "input", text: what });
        for (p, s) in follow {
            let text = format!("{node}:{behavior}.{p} from {}/c{}:", s.node, s.conn);
            chain.links.push(Link { depth: hops, level, node, at, kind: "port", text });
            self.follow(chain, node, at, s.node, s.conn, level + 1, hops, depth);
        }
    }

    /// The message from `from`'s connection `conn` that `node` received last at or before `at`:
    /// its sending in `from`'s replay, the port it came from, and who wrote that port.
    #[allow(clippy::too_many_arguments)]
    fn follow(
        &self,
        chain: &mut Chain,
        node: NodeId,
        at: Instant,
        from: NodeId,
        conn: u64,
        level: usize,
        hops: usize,
        depth: usize,
    ) {
        let end = |chain: &mut Chain, text: String| {
            chain.links.push(Link { depth: hops + 1, level, node: from, at, kind: "end", text });
        };
        if from == node {
            // A local connection: its source port on this node, at the same instant.
            let Some(rec) = self.recording(node) else { return };
            let mut replay = Replay::new(rec);
            let Ok(report) = replay.list_at(at) else { return };
            let Some(c) = report.connections.iter().find(|c| c.id.0 == conn) else { return };
            if let ayllu_core::Endpoint::Local { behavior, port } = &c.source {
                let Ok(r) = replay.core().why_at(at, behavior, port) else { return };
                if let Some(s) = r.supplier {
                    self.supplier(chain, node, at, behavior, port, s.node, s.conn, level, hops, depth);
                }
            }
            return;
        }
        if self.recording(from).is_none() {
            return end(chain, format!("{from} was not recorded: its side is not known"));
        }
        let arrival = self.arrivals.get(&node).and_then(|all| {
            all.iter()
                .filter(|a| a.id.from == from && a.id.conn.0 == conn && a.at <= at)
                .max_by_key(|a| (a.accepted, a.at))
        });
        let Some(a) = arrival else {
            return end(chain, format!("no message from {from}/c{conn} reached {node} by {at}"));
        };
        let Some(s) = self.sent.get(&a.id) else {
            return end(chain, format!("{} at {}: its sender's replay never sent it", a.id, a.at));
        };
        let clocks = match self.offset(from, node) {
            Some((o, b)) => format!(
                "; {from}'s clock = {node}'s {} {} ± {}",
                if o < 0.0 { '-' } else { '+' },
                seconds(o.abs()),
                seconds(b)
            ),
            None => String::new(),
        };
        chain.links.push(Link {
            depth: hops + 1,
            level,
            node: from,
            at: s.at,
            kind: "message",
            text: format!(
                "{} -> {node}:{}.{} ({}) = {}: sent by {from} at {} on its clock, received by {node} at {} on its \
                 clock{clocks}",
                a.id, s.message.behavior, s.message.port, s.message.kind, s.message.value, s.at, a.at
            ),
        });
        if hops + 1 > depth {
            return end(chain, format!("(--depth {depth} reached)"));
        }
        // The port it came from, on the sender, then, and who wrote it.
        let Some(rec) = self.recording(from) else { return };
        let mut replay = Replay::new(rec);
        let Ok(report) = replay.list_at(s.at) else {
            return end(chain, format!("{from}'s replay did not reach {}", s.at));
        };
        let Some(c) = report.connections.iter().find(|c| c.id.0 == conn) else { return };
        let ayllu_core::Endpoint::Local { behavior, port } = &c.source else { return };
        let Ok(r) = replay.core().why_at(s.at, behavior, port) else { return };
        match r.supplier {
            Some(sup) => self.supplier(chain, from, s.at, behavior, port, sup.node, sup.conn, level, hops + 1, depth),
            None => end(chain, format!("{from}:{behavior}.{port} had no supplier at {}", s.at)),
        }
    }
}

impl Team {
    /// Every value each node's ports accepted, replayed, on one timeline: the reference node's
    /// clock (each node's own time minus its estimated offset, [`TeamCheck::clocks`]), in
    /// nanoseconds from that node's start. Written to `path` as an MCAP file in the team
    /// layout `ayllu record` writes (a channel `/nK/BEHAVIOR/PORT` per port; Foxglove and the
    /// `mcap` readers open it), in time order. Returns how many values. A node whose clock no
    /// message joins to the reference is placed on its own clock.
    pub fn write_timeline(&self, path: &std::path::Path) -> std::io::Result<u64> {
        let mut values: Vec<(i128, NodeId, crate::replay::Accepted)> = Vec::new();
        for r in &self.recordings {
            let offset = self.offset(r.node, self.check.nodes[0]).map_or(0.0, |(o, _)| o);
            let mut replay = Replay::new(r);
            // A divergence is a finding of the check; the timeline keeps what was reproduced.
            let _ = replay.run_to_end();
            for a in replay.accepted() {
                let t = i128::from(a.at.as_nanos()) - (offset * 1e9).round() as i128;
                values.push((t, r.node, a.clone()));
            }
        }
        values.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.cmp(&b.1)));
        let file = std::io::BufWriter::new(std::fs::File::create(path)?);
        let mut w = crate::team_recording::TeamWriter::new(file)?;
        for (t, node, a) in &values {
            let channel = crate::team_channels::PortChannel::new(*node, &a.behavior, &a.port, a.value.ty());
            w.write(&channel, &a.value, None, u64::try_from(*t).unwrap_or(0))?;
        }
        w.finish()?;
        Ok(values.len() as u64)
    }
}
