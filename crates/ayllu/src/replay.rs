//! Deterministic replay: a flight recording ([`crate::recording`]) played back into a fresh
//! core, so that `why`, `list` and `echo` can be asked of any past instant
//! (spec/flight-recorder.md).
//!
//! How: the recording's inputs (definitions, structure changes, writes, messages received,
//! polls at their times) are fed to a new [`NodeCore`] in their order. The application's
//! processes are not needed: each class process is replaced by a *player* that, when the core
//! runs it, applies the effects the recorded activation had (its writes, slot changes,
//! triggers, resets, structure changes and requests, in order). Processes the core provides
//! itself (BLE's select) run as they are.
//!
//! What it promises:
//! * Checked, not assumed: every value a port accepts during the replay is compared, bit for
//!   bit and in order, with the one the recording says it accepted; and each player checks
//!   that the core runs the process the recording ran. The first difference stops the replay
//!   with a [`Divergence`] saying where (journal position, node time) and what.
//! * A replay stopped at `t` answers as the live node would have at `t`: every input up to
//!   `t` was applied, none after.
//! * A bad or cut file gives an error or a shorter recording ([`Ending`]), never a panic
//!   (the records are framed by `mcap_records`, not by the `mcap` crate's readers, which
//!   panic on some damaged files).
//! * A rolling recording (`--record-last`), whose beginning was deleted, replays the same way
//!   from the checkpoint that opens its oldest segment kept ([`Recording::checkpoint`]): the
//!   core is restored from it ([`NodeCore::restore`], with players for bodies) and the
//!   journal applied from there, checked as from a beginning.

use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, MutexGuard};

use ayllu_core::{
    BehaviorClass, ConnectOptions, Ctx, Entry, Event, Instant, Mono, NodeCore, NodeId, NodeReport, Outgoing, Port,
    PortReport, Slot, Snapshot, Value,
};

use crate::error::Error;
use crate::mcap_records::{self, McapRecord};
use crate::recording::{segment_numbers, segment_path};
use crate::recording_format::{decode, decode_checkpoint, same_bits, Topic, METADATA, VERSIONS_READ};

/// How a recording ends.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Ending {
    /// Its files were closed: everything journaled was written.
    Closed,
    /// The size cap was reached: the rest of the node's life was not written.
    Capped {
        /// Entries not written by the time the last segment was closed (the recorder's
        /// [`crate::RecordStats::dropped_cap`] counts them to the node's end).
        dropped: u64,
    },
    /// The files were not closed (the node was killed, or a file is cut short): the
    /// recording ends at the last complete chunk.
    Cut {
        /// What the reader found.
        reason: String,
    },
}

impl fmt::Display for Ending {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Ending::Closed => write!(f, "closed"),
            Ending::Capped { dropped } => write!(f, "size cap reached ({dropped} entries not written)"),
            Ending::Cut { reason } => write!(f, "cut short ({reason})"),
        }
    }
}

/// A flight recording read back: the node it is of and its journal, in order.
#[derive(Clone, Debug)]
pub struct Recording {
    /// The node recorded.
    pub node: NodeId,
    /// The segment files read, in order.
    pub segments: Vec<PathBuf>,
    /// The journal, in the order the core made it.
    pub entries: Vec<Entry>,
    /// How it ends.
    pub ending: Ending,
    /// Where the journal has a hole (entries dropped while recording, or a missing
    /// segment): a replay stops there. The journal position and node time.
    pub gap: Option<(u64, Instant)>,
    /// The checkpoint the journal starts from, in a rolling recording whose beginning was
    /// deleted: `entries[0]` is the node's journal entry number `checkpoint.seq`. `None`: the
    /// journal starts at the node's first definition.
    pub checkpoint: Option<Checkpoint>,
}

/// A checkpoint a recording starts from (see [`Recording::checkpoint`]).
#[derive(Clone)]
pub struct Checkpoint {
    /// The journal position it was taken before (entries from there on follow it).
    pub seq: u64,
    /// The node's time when it was taken.
    pub at: Instant,
    /// The node's state then.
    pub snapshot: Arc<Snapshot>,
}

impl fmt::Debug for Checkpoint {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Checkpoint").field("seq", &self.seq).field("at", &self.at).finish_non_exhaustive()
    }
}

/// What the segments of a recording hold, read in order.
struct Read {
    node: Option<NodeId>,
    entries: Vec<(u64, Entry)>,
    checkpoints: Vec<(u64, Snapshot)>,
}

fn bad(path: &Path, what: impl fmt::Display) -> Error {
    Error::Recording { what: format!("{}: {what}", path.display()) }
}

impl Recording {
    /// Read the recording whose first segment is `path`, with the segments that follow it
    /// (`run.1.mcap`, ...). Errors: a file that cannot be read, is not MCAP, is not an Ayllu
    /// flight recording, or holds a message that does not decode. A file cut short is not an
    /// error: the recording ends where the file does ([`Ending::Cut`]).
    ///
    /// A rolling recording's first segment may be gone: then the reading starts at the oldest
    /// segment kept (`run.N.mcap`), from its checkpoint ([`Recording::checkpoint`]).
    pub fn open(path: impl AsRef<Path>) -> Result<Recording, Error> {
        let first = path.as_ref();
        let mut read = Read { node: None, entries: Vec::new(), checkpoints: Vec::new() };
        let mut segments = Vec::new();
        let mut ending = Ending::Cut { reason: "no end record".into() };
        // The first segment's error, if there is no other segment, is the file's own.
        let mut n = segment_numbers(first).first().copied().filter(|_| !first.exists()).unwrap_or(0);
        loop {
            let p = segment_path(first, n);
            if !segments.is_empty() && !p.exists() {
                break;
            }
            let bytes = std::fs::read(&p).map_err(|e| bad(&p, e))?;
            let (seg_node, seg_ending) = read_segment(&p, &bytes, &mut read)?;
            if let Some(other) = read.node.filter(|&x| x != seg_node) {
                return Err(bad(&p, format!("a segment of node {seg_node}, after segments of node {other}")));
            }
            read.node = Some(seg_node);
            segments.push(p);
            ending = seg_ending;
            n += 1;
            if ending != Ending::Closed {
                break;
            }
        }
        Recording::assemble(read, segments, ending)
    }

    /// Read a one-segment recording held in memory: `bytes` as [`Recording::open`] reads a
    /// segment file, with the same errors and endings (errors name the file `<bytes>`). For
    /// a recording that came another way than as a file, and for fuzzing the reader.
    pub fn from_bytes(bytes: &[u8]) -> Result<Recording, Error> {
        let mut read = Read { node: None, entries: Vec::new(), checkpoints: Vec::new() };
        let (node, ending) = read_segment(Path::new("<bytes>"), bytes, &mut read)?;
        read.node = Some(node);
        Recording::assemble(read, Vec::new(), ending)
    }

    /// The journal put back in order from its beginning, or from its first checkpoint when
    /// the beginning is gone, and its first hole found. A checkpoint that does not restore
    /// (damaged) is an error, found here rather than when replayed.
    fn assemble(read: Read, segments: Vec<PathBuf>, ending: Ending) -> Result<Recording, Error> {
        let Read { node, mut entries, checkpoints } = read;
        let node = node.unwrap_or(NodeId(0));
        entries.sort_by_key(|(seq, _)| *seq);
        let from_start = entries.first().is_none_or(|(seq, _)| *seq == 0) || checkpoints.is_empty();
        let checkpoint = if from_start {
            None
        } else {
            let (seq, snapshot) = checkpoints.into_iter().min_by_key(|(seq, _)| *seq).expect("not empty");
            let at = snapshot.at();
            let name = segments.first().map_or_else(|| PathBuf::from("<bytes>"), PathBuf::clone);
            if snapshot.node() != node {
                return Err(bad(&name, format!("a checkpoint of node {}, in a recording of {node}", snapshot.node())));
            }
            let trial = NodeCore::restore(snapshot.clone(), |_, _| Arc::new(|_: &mut Ctx<'_>| {}));
            trial.map_err(|e| bad(&name, format!("its checkpoint at entry {seq} does not restore: {e}")))?;
            entries.retain(|(s, _)| *s >= seq);
            Some(Checkpoint { seq, at, snapshot: Arc::new(snapshot) })
        };
        let base = checkpoint.as_ref().map_or(0, |c| c.seq);
        let mut gap = None;
        for (i, (seq, e)) in entries.iter().enumerate() {
            if *seq != base + i as u64 || matches!(e.event, Event::Gap { .. }) {
                gap = Some((i as u64, e.at));
                break;
            }
        }
        let entries = entries.into_iter().map(|(_, e)| e).collect();
        Ok(Recording { node, segments, entries, ending, gap, checkpoint })
    }

    /// The first instant the recording tells about: its checkpoint's, for a rolling
    /// recording whose beginning was deleted; zero otherwise. Before it, a replay knows nothing.
    pub fn start(&self) -> Instant {
        self.checkpoint.as_ref().map_or(Instant::ZERO, |c| c.at)
    }

    /// The node time of the last entry (zero for an empty recording).
    pub fn end(&self) -> Instant {
        self.entries.last().map_or(Instant::ZERO, |e| e.at)
    }

    /// The journal position a replay stops at: the whole journal of a closed recording
    /// without a hole; else the last input before the hole or the end, whose consequences may
    /// be missing (the replay ends before that input).
    fn stop(&self) -> usize {
        let stop = self.gap.map_or(self.entries.len(), |(seq, _)| seq as usize);
        if stop < self.entries.len() || self.ending != Ending::Closed {
            self.entries[..stop].iter().rposition(|e| is_input(&e.event)).unwrap_or(0)
        } else {
            stop
        }
    }

    /// The last instant the recording tells about, when it does not run to the node's own end:
    /// the node time of the last entry a replay applies, for a recording with a hole or one
    /// that was capped or cut (spec/flight-recorder.md, "Replay"). After it the node lived on
    /// (or died) unrecorded, so an answer about a later instant would be made up: a replay
    /// does not give one. `None` for a closed recording without a hole (it ends where the node
    /// stopped recording; [`Recording::end`]).
    pub fn last_known(&self) -> Option<Instant> {
        if self.gap.is_none() && self.ending == Ending::Closed {
            return None;
        }
        Some(self.entries[..self.stop()].last().map_or(Instant::ZERO, |e| e.at))
    }
}

/// The profile an MCAP file's header names (`ayllu-flight` for a flight recording, `ayllu`
/// for a team recording), read from the first bytes without trusting any length beyond them.
pub(crate) fn mcap_profile(bytes: &[u8]) -> Option<&str> {
    // Magic (8 bytes), then the header record: opcode 0x01, its length (u64), its profile (a
    // string: u32 length, then the bytes).
    let rest = bytes.strip_prefix(b"\x89MCAP0\r\n")?;
    let (&op, rest) = rest.split_first()?;
    if op != 0x01 {
        return None;
    }
    let (record_len, rest) = rest.split_at_checked(8)?;
    let record_len = u64::from_le_bytes(record_len.try_into().ok()?);
    let (len, rest) = rest.split_at_checked(4)?;
    let len = u32::from_le_bytes(len.try_into().ok()?) as usize;
    if len as u64 + 4 > record_len {
        return None;
    }
    std::str::from_utf8(rest.get(..len)?).ok()
}

/// Whether `bytes` start as a flight recording (`ayllu node --record`, [`crate::Node::record`])
/// does: an MCAP header with the flight recorder's profile. For the reader of the other kind,
/// the team recordings of `ayllu record`, to say which tool reads the file instead.
pub fn is_flight_recording(bytes: &[u8]) -> bool {
    mcap_profile(bytes) == Some(crate::recording_format::PROFILE)
}

/// The refusal of a file that is not a flight recording, `why` it is not. A team recording
/// (`ayllu record`, profile `ayllu`) is named as such, with the tools that read it: the two
/// kinds are both `.mcap` files, and replaying the wrong one is an easy mistake.
fn not_flight(path: &Path, bytes: &[u8], why: String) -> Error {
    if crate::team_recording::is_team_recording(bytes) {
        return bad(
            path,
            "a team recording (made by `ayllu record`), not a flight recording: play it with `ayllu play`, or open it \
             in Foxglove; `ayllu replay` reads the flight recording of one node (`ayllu node --record`)",
        );
    }
    bad(path, format!("not an Ayllu flight recording ({why})"))
}

/// Read one segment's messages into `out`; its node and how it ends.
fn read_segment(path: &Path, bytes: &[u8], out: &mut Read) -> Result<(NodeId, Ending), Error> {
    let mut topics: Vec<(u16, Topic)> = Vec::new();
    // The binary form (version 3) or the JSON one (1 and 2), from the metadata.
    let mut binary = false;
    let mut node = None;
    let mut ending = Ending::Cut { reason: "the file has no end record (was the node killed?)".into() };
    let reader = mcap_records::records(bytes).map_err(|e| bad(path, e.what))?;
    for record in reader {
        let record = match record {
            Ok(r) => r,
            Err(e) => {
                ending = Ending::Cut { reason: format!("unreadable {e}") };
                // Before its metadata, a file that cannot be read is not a recording at all:
                // the reason it cannot be read is the useful part of the error.
                if node.is_none() {
                    return Err(not_flight(path, bytes, format!("unreadable {e}")));
                }
                break;
            }
        };
        match &record {
            McapRecord::Channel { id, topic } => {
                if let Some(t) = Topic::from_name(topic) {
                    topics.push((*id, t));
                }
            }
            McapRecord::Metadata { name, .. } if *name == METADATA => {
                let version = record.get("version").unwrap_or("");
                binary = version == crate::recording_format::VERSION;
                if !VERSIONS_READ.contains(&version) {
                    let known = VERSIONS_READ.join(" and ");
                    return Err(bad(path, format!("flight recording version `{version}`; this build reads {known}")));
                }
                let id = record.get("node").and_then(|n| n.parse::<u32>().ok());
                node = Some(NodeId(id.ok_or_else(|| bad(path, "no node id in its metadata"))?));
            }
            McapRecord::Metadata { name, .. } if name.strip_prefix(METADATA) == Some(".end") => {
                let capped = record.get("capped") == Some("true");
                let dropped = record.get("dropped_cap").and_then(|d| d.parse().ok()).unwrap_or(0);
                ending = if capped { Ending::Capped { dropped } } else { Ending::Closed };
            }
            McapRecord::Message { channel, sequence, data, .. } => {
                let Some(topic) = topics.iter().find(|(id, _)| id == channel).map(|(_, t)| *t) else { continue };
                if binary {
                    match crate::recording_cdr::decode(data)
                        .map_err(|e| bad(path, format!("message {sequence}: {e}")))?
                    {
                        crate::recording_cdr::Decoded::Entry(d) => out.entries.push((d.seq, d.entry)),
                        crate::recording_cdr::Decoded::Checkpoint(j) => {
                            let c =
                                decode_checkpoint(&j).map_err(|e| bad(path, format!("checkpoint {sequence}: {e}")))?;
                            out.checkpoints.push(c);
                        }
                    }
                    continue;
                }
                let json: serde_json::Value = serde_json::from_slice(data)
                    .map_err(|e| bad(path, format!("message {sequence} is not JSON: {e}")))?;
                if topic == Topic::Checkpoint {
                    let c = decode_checkpoint(&json).map_err(|e| bad(path, format!("checkpoint {sequence}: {e}")))?;
                    out.checkpoints.push(c);
                    continue;
                }
                let d = decode(&json).map_err(|e| bad(path, format!("message {sequence}: {e}")))?;
                out.entries.push((d.seq, d.entry));
            }
            McapRecord::Metadata { .. } | McapRecord::DataEnd | McapRecord::Footer => {}
        }
    }
    let node = node.ok_or_else(|| not_flight(path, bytes, "no ayllu.flight_recording metadata".into()))?;
    Ok((node, ending))
}

/// Where a replay departed from its recording.
#[derive(Clone, Debug, PartialEq)]
pub struct Divergence {
    /// The journal position (entry number) where it showed.
    pub seq: u64,
    /// The node time there.
    pub at: Instant,
    /// What differed.
    pub what: String,
}

impl fmt::Display for Divergence {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "replay diverged at entry {} (t={}): {}", self.seq, self.at, self.what)
    }
}

impl std::error::Error for Divergence {}

/// A value a port accepted during the replay.
#[derive(Clone, Debug, PartialEq)]
pub struct Accepted {
    /// When (node time).
    pub at: Instant,
    /// The behavior.
    pub behavior: Arc<str>,
    /// The port's name.
    pub port: String,
    /// The value, as the merge stored it.
    pub value: Value,
}

/// The recording as the core and its players share it.
struct Tape {
    entries: Arc<[Entry]>,
    next: usize,
    /// Inside the effects of a native activation (they are the core's to reproduce).
    in_native: bool,
    divergence: Option<Divergence>,
}

fn is_effect(e: &Event) -> bool {
    matches!(
        e,
        Event::ProcessWrite { .. }
            | Event::ProcessSetSlot { .. }
            | Event::ProcessTrigger { .. }
            | Event::ProcessReset { .. }
            | Event::ProcessChange(_)
            | Event::ProcessRequest { .. }
    )
}

/// Whether the replay loop applies `e` itself (what is not a consequence of another entry).
pub(crate) fn is_input(e: &Event) -> bool {
    !matches!(e, Event::Accepted { .. } | Event::Run { .. } | Event::Gap { .. }) && !is_effect(e)
}

impl Tape {
    /// Move past what neither the replay loop nor a player consumes: accepted values (checked
    /// separately) and native activations with their effects.
    fn skip(&mut self) {
        while let Some(e) = self.entries.get(self.next) {
            match &e.event {
                Event::Accepted { .. } => {}
                Event::Run { native: true, .. } => self.in_native = true,
                ev if self.in_native && is_effect(ev) => {}
                _ => {
                    self.in_native = false;
                    return;
                }
            }
            self.next += 1;
        }
    }

    fn diverge(&mut self, what: String) {
        if self.divergence.is_none() {
            let at = self.entries.get(self.next).or(self.entries.last()).map_or(Instant::ZERO, |e| e.at);
            self.divergence = Some(Divergence { seq: self.next as u64, at, what });
        }
    }
}

fn lock(tape: &Mutex<Tape>) -> MutexGuard<'_, Tape> {
    // A player that panicked cannot leave the tape half-moved in a way that matters here.
    tape.lock().unwrap_or_else(|p| p.into_inner())
}

/// The stand-in for process `name`: it applies what the recorded activation did.
fn player(tape: Arc<Mutex<Tape>>, name: String) -> impl Fn(&mut Ctx<'_>) + Send + Sync + 'static {
    move |ctx| {
        let effects = {
            let mut t = lock(&tape);
            if t.divergence.is_some() {
                return;
            }
            t.skip();
            let ok = matches!(t.entries.get(t.next).map(|e| &e.event),
                Some(Event::Run { behavior, process, native: false }) if **behavior == *ctx.behavior() && *process == name);
            if !ok {
                let found = t.entries.get(t.next).map_or("the end of the recording".to_owned(), |e| describe(&e.event));
                t.diverge(format!("the core ran {}.{name} where the recording has {found}", ctx.behavior()));
                return;
            }
            t.next += 1;
            let mut effects = Vec::new();
            while let Some(e) = t.entries.get(t.next) {
                if is_effect(&e.event) {
                    effects.push(e.event.clone());
                } else if !matches!(e.event, Event::Accepted { .. }) {
                    break;
                }
                t.next += 1;
            }
            effects
        };
        for e in effects {
            match e {
                Event::ProcessWrite { port, value } => {
                    let _ = ctx.write(Port(port), value);
                }
                Event::ProcessSetSlot { slot, value } => {
                    let _ = ctx.set_slot(Slot(slot), value);
                }
                Event::ProcessTrigger { mono, period } => ctx.trigger(Mono(mono), period),
                Event::ProcessReset { port } => ctx.reset(Port(port)),
                // Asked for again, so the core applies them when the player returns, as it
                // did live when the process returned.
                Event::ProcessChange(change) => {
                    let _ = ctx.change(*change);
                }
                Event::ProcessRequest { to, body } => {
                    let _ = ctx.request(to, *body);
                }
                _ => {}
            }
        }
    }
}

/// A short description of an entry, for divergence reports.
fn describe(e: &Event) -> String {
    match e {
        Event::Run { behavior, process, .. } => format!("an activation of {behavior}.{process}"),
        Event::Accepted { behavior, port, .. } => format!("a value accepted by {behavior} port #{port}"),
        Event::Poll => "a poll".into(),
        other => {
            let text = format!("{other:?}");
            text.chars().take(80).collect()
        }
    }
}

/// A recording being replayed into a fresh core. See the module docs.
pub struct Replay {
    core: NodeCore,
    tape: Arc<Mutex<Tape>>,
    /// The first instant the recording tells about ([`Recording::start`]).
    start: Instant,
    /// Positions of the recorded accepted values, in order, and the next to compare.
    recorded_accepted: Vec<usize>,
    next_accepted: usize,
    accepted: Vec<Accepted>,
    scratch: Vec<Entry>,
    /// Where the recording has a hole: the replay does not go past it.
    stop: usize,
    /// The node time up to which inputs were applied.
    reached: Instant,
    /// The messages the replayed core sent, with the node time of the input that made them,
    /// when asked for ([`Replay::keep_sent`]; a team replay matches them with what the other
    /// nodes received); else they are dropped as made.
    sent: Option<Vec<(Instant, Outgoing)>>,
}

impl Replay {
    /// A replay of `recording`, at its beginning.
    pub fn new(recording: &Recording) -> Replay {
        let entries: Arc<[Entry]> = recording.entries.clone().into();
        // The consequences of the last input before a hole or the end of a recording that was
        // not closed may be missing: the replay ends before that input.
        let stop = recording.stop();
        let recorded_accepted = entries
            .iter()
            .enumerate()
            .filter(|(_, e)| matches!(e.event, Event::Accepted { .. }))
            .map(|(i, _)| i)
            .collect();
        let tape = Arc::new(Mutex::new(Tape { entries, next: 0, in_native: false, divergence: None }));
        let mut core = match &recording.checkpoint {
            // Checked when the recording was read (`Recording::assemble`).
            Some(c) => {
                NodeCore::restore((*c.snapshot).clone(), |_, process| Arc::new(player(tape.clone(), process.into())))
                    .unwrap_or_else(|_| NodeCore::new(recording.node))
            }
            None => NodeCore::new(recording.node),
        };
        let reached = recording.checkpoint.as_ref().map_or(Instant::ZERO, |c| c.at);
        core.start_journal(usize::MAX);
        Replay {
            core,
            start: recording.start(),
            tape,
            recorded_accepted,
            next_accepted: 0,
            accepted: Vec::new(),
            scratch: Vec::new(),
            stop,
            reached,
            sent: None,
        }
    }

    /// Keep the messages the replayed core sends from now on (each with the node time of the
    /// input that made it: the live node sent it then or a moment later), for
    /// [`Replay::take_sent`]. A replay reproduces them as the live node made them, sequence
    /// numbers included, since the sequence base is recorded.
    pub fn keep_sent(&mut self) {
        self.sent.get_or_insert_with(Vec::new);
    }

    /// The messages kept since [`Replay::keep_sent`] (or the last call), oldest first.
    pub fn take_sent(&mut self) -> Vec<(Instant, Outgoing)> {
        self.sent.as_mut().map(std::mem::take).unwrap_or_default()
    }

    /// The replayed core, as it stands (ask it `why_at`, `report_at`, `read_at`).
    pub fn core(&self) -> &NodeCore {
        &self.core
    }

    /// Every value a port accepted so far in the replay, in order.
    pub fn accepted(&self) -> &[Accepted] {
        &self.accepted
    }

    /// How many accepted values were compared with the recording and found equal.
    pub fn checked(&self) -> usize {
        self.next_accepted
    }

    /// The node time up to which inputs have been applied.
    pub fn reached(&self) -> Instant {
        self.reached
    }

    /// Apply every input recorded at or before `t`. Stops at the first divergence.
    pub fn run_until(&mut self, t: Instant) -> Result<(), Divergence> {
        loop {
            let entry = {
                let mut tape = lock(&self.tape);
                tape.skip();
                if tape.next >= self.stop {
                    break;
                }
                match tape.entries.get(tape.next).filter(|e| e.at <= t).cloned() {
                    Some(e) => {
                        tape.next += 1;
                        e
                    }
                    None => break,
                }
            };
            self.reached = self.reached.max(entry.at);
            self.apply(entry)?;
        }
        self.reached = self.reached.max(t);
        Ok(())
    }

    /// Apply every input recorded before journal position `entry` (and none from it on): the
    /// node as it stood just before that input, e.g. before the poll in which a process ran,
    /// to see what the process read. Stops at the first divergence.
    pub fn run_before(&mut self, entry: usize) -> Result<(), Divergence> {
        loop {
            let next = {
                let mut tape = lock(&self.tape);
                tape.skip();
                if tape.next >= self.stop.min(entry) {
                    break;
                }
                let e = tape.entries[tape.next].clone();
                tape.next += 1;
                e
            };
            self.reached = self.reached.max(next.at);
            self.apply(next)?;
        }
        Ok(())
    }

    /// Apply the whole recording (up to its end or its first hole).
    pub fn run_to_end(&mut self) -> Result<(), Divergence> {
        self.run_until(Instant::MAX)?;
        let tape = lock(&self.tape);
        let end = self.recorded_accepted.partition_point(|&i| i < tape.next.min(self.stop));
        if self.next_accepted < end {
            let i = self.recorded_accepted[self.next_accepted];
            let e = &tape.entries[i];
            return Err(Divergence {
                seq: i as u64,
                at: e.at,
                what: format!("the recording has {} that the replay never accepted", describe(&e.event)),
            });
        }
        Ok(())
    }

    /// Why `behavior.port` held what it held at `t`: the replay runs up to `t` and asks the
    /// core as the live node would have been asked then.
    pub fn why_at(&mut self, t: Instant, behavior: &str, port: &str) -> Result<PortReport, Error> {
        self.known_at(t)?;
        self.run_until(t).map_err(|d| Error::Recording { what: d.to_string() })?;
        Ok(self.core.why_at(t, behavior, port)?)
    }

    /// The whole node as it stood at `t` (see [`Replay::why_at`]).
    pub fn list_at(&mut self, t: Instant) -> Result<NodeReport, Error> {
        self.known_at(t)?;
        self.run_until(t).map_err(|d| Error::Recording { what: d.to_string() })?;
        Ok(self.core.report_at(t))
    }

    /// Refuse an instant before the recording's first (a rolling recording's beginning is
    /// gone: the node then is not known).
    fn known_at(&self, t: Instant) -> Result<(), Error> {
        if t < self.start {
            return Err(Error::Recording {
                what: format!(
                    "t={:.3}s is before {:.3}s, where this rolling recording starts (its checkpoint): what came \
                     before was not kept; ask at or after it",
                    t.as_secs_f64(),
                    self.start.as_secs_f64()
                ),
            });
        }
        Ok(())
    }

    fn fail(&self, what: String) -> Divergence {
        let tape = lock(&self.tape);
        let at = tape.entries.get(tape.next.saturating_sub(1)).map_or(Instant::ZERO, |e| e.at);
        Divergence { seq: tape.next.saturating_sub(1) as u64, at, what }
    }

    fn apply(&mut self, entry: Entry) -> Result<(), Divergence> {
        let at = entry.at;
        // Each entry carries the node's time once its call had moved it, and a live node is
        // told the present before a change made between polls (`Node::core_mut`): a change is
        // dated as it was live only if the replay is at that time too. For a call that moves
        // the time itself (a write, a message, a poll) this changes nothing.
        self.core.advance_to(at);
        let core = &mut self.core;
        // Inputs are applied whatever they returned live: a refused call is refused again, and
        // what it changed (counters) is what the comparison of accepted values checks.
        match entry.event {
            Event::Define(class) => {
                let rebuilt = self.with_players(&class);
                let _ = self.core.define(rebuilt);
            }
            Event::Create { class, name } => drop(core.create(&class, &name)),
            Event::Remove { name } => drop(core.remove(&name)),
            Event::AddProcess { behavior, name, trigger } => {
                let body = player(self.tape.clone(), name.clone());
                let _ = core.add_process(&behavior, &name, trigger, body);
            }
            Event::Connect { source, destination, kind, priority } => {
                let _ = core.connect(&source, &destination, kind, ConnectOptions { priority });
            }
            Event::Disconnect { conn } => drop(core.disconnect(conn)),
            Event::NodeLost { node } => drop(core.node_lost(at, node)),
            Event::SetAccess(a) => core.set_access(a),
            Event::SetLimits(l) => core.set_limits(l),
            Event::Join(g) => core.join(&g),
            Event::Leave(g) => core.leave(&g),
            Event::BleJoin { behavior, config } => drop(core.ble_join(&behavior, &config)),
            Event::SequenceBase(b) => core.set_sequence_base(b),
            Event::Warn(w) => core.warn(w),
            Event::Request { to, body } => drop(core.request(to, *body)),
            Event::Write { behavior, port, value, .. } => {
                if let Ok(r) = core.port_by_handle(&behavior, Port(port)) {
                    let _ = core.write(at, r, value);
                }
            }
            Event::Trigger { behavior, mono, period } => drop(core.trigger(at, &behavior, &mono, period)),
            Event::Reset { behavior, port } => {
                if let Ok(r) = core.port(&behavior, &port) {
                    let _ = core.reset(r);
                }
            }
            Event::Receive { from, message } => core.receive(at, from, *message),
            Event::Poll => drop(core.poll(at)),
            Event::Run { behavior, process, .. } => {
                return Err(
                    self.fail(format!("the recording ran {behavior}.{process} here; the replayed core did not"))
                );
            }
            e if is_effect(&e) => {
                return Err(self.fail(format!("a process effect outside any activation ({})", describe(&e))));
            }
            _ => {}
        }
        while let Some(out) = self.core.pop_outgoing() {
            if let Some(sent) = &mut self.sent {
                sent.push((at, out));
            }
        }
        if let Some(d) = lock(&self.tape).divergence.clone() {
            return Err(d);
        }
        self.compare()
    }

    /// Compare what the replayed ports accepted with what the recording says they accepted.
    fn compare(&mut self) -> Result<(), Divergence> {
        self.scratch.clear();
        self.core.take_journal(&mut self.scratch);
        let tape = lock(&self.tape);
        for e in self.scratch.drain(..) {
            let Event::Accepted { behavior, class, port, value } = e.event else { continue };
            let name = class.ports().get(usize::from(port)).map_or(String::new(), |p| p.name.clone());
            let Some(&i) = self.recorded_accepted.get(self.next_accepted) else {
                return Err(Divergence {
                    seq: tape.next as u64,
                    at: e.at,
                    what: format!("{behavior}.{name} accepted {value:?}, beyond what the recording holds"),
                });
            };
            let rec = &tape.entries[i];
            let same = match &rec.event {
                Event::Accepted { behavior: rb, port: rp, value: rv, .. } => {
                    *rb == behavior && *rp == port && same_bits(rv, &value) && rec.at == e.at
                }
                _ => false,
            };
            if !same {
                let recorded = match &rec.event {
                    Event::Accepted { behavior, port, value, .. } => {
                        format!("{behavior} port #{port} accepting {value:?}")
                    }
                    other => describe(other),
                };
                return Err(Divergence {
                    seq: i as u64,
                    at: rec.at,
                    what: format!(
                        "{behavior}.{name} accepted {value:?} at {}; the recording has {recorded} at {}",
                        e.at, rec.at
                    ),
                });
            }
            self.next_accepted += 1;
            self.accepted.push(Accepted { at: e.at, behavior, port: name, value });
        }
        Ok(())
    }

    /// `class` with a player in place of each process body.
    fn with_players(&self, class: &BehaviorClass) -> BehaviorClass {
        let mut c = BehaviorClass::new(class.name());
        let implicit = c.ports().len();
        for spec in class.ports().iter().skip(implicit) {
            let _ = c.port(spec.clone());
        }
        for s in class.slots() {
            let _ = c.slot(&s.name, s.default.clone());
        }
        for m in class.monostables() {
            let _ = c.monostable(m);
        }
        for p in class.processes() {
            let _ = c.process(&p.name, p.trigger, player(self.tape.clone(), p.name.clone()));
        }
        c
    }
}
