//! Team recordings: hearing a team's port messages from a node of our own, writing them as an
//! MCAP file in the team channel layout ([`crate::team_channels`]), and reading such a file
//! back for playback. `ayllu record` and `ayllu play` are thin loops around this module.
//!
//! What a listener hears (docs/cli.md, `ayllu record`): a unicast port message between two
//! other nodes never reaches a third, so a recorder hears (1) the messages of every broadcast
//! group it joins — it joins the groups the nodes announce in their HELLOs, and nodes then
//! deliver group messages to it as to any member (by the group's broadcast or multicast
//! address, or by unicast to every member that announced the group) — and (2) copies it asks
//! for: a Normal connection CONNECTed from a chosen port to the recorder, the same mechanism
//! `ayllu echo` uses. Everything else is unheard.
//!
//! Promises:
//! * [`Tap`] changes nothing about the transport it wraps: every message still reaches the
//!   core; port messages are copied, with the wall-clock time they arrived;
//! * a message is written on the channel of the port that *sent* it, found from the sender's
//!   connection table (LIST): [`Recorder`] holds messages whose connection it does not know yet
//!   and asks for the sender's table ([`Recorder::wanted_lists`]), for at most
//!   [`Recorder::HOLD`]; after that they are written on the fallback channel
//!   `/n{node}/_c{conn}/{behavior}.{port}` (the receiving port's name), counted as unresolved;
//! * the file is valid MCAP with a summary even when recording stops early, as long as
//!   [`TeamWriter::finish`] runs; [`read_recording`] reads every message of the layout back.

use std::collections::{BTreeSet, HashMap, VecDeque};
use std::io::{Seek, Write};
use std::sync::{Arc, Mutex};
use std::time::{Duration as StdDuration, SystemTime, UNIX_EPOCH};

use ayllu_core::{ConnectionKind, Endpoint, Message, NodeId, NodeReport, Outgoing, Value, ValueType};

use crate::mcap_records::{self, McapRecord};
use crate::team_channels::{self, PortChannel, Via};
use crate::transport::{SendTally, Transport, TransportWrapper};

/// One port message as a listener heard it.
#[derive(Clone, Debug, PartialEq)]
pub struct Heard {
    /// When it arrived: nanoseconds since the Unix epoch.
    pub unix_nanos: u64,
    /// The node that sent it.
    pub from: NodeId,
    /// The connection on the sender that carried it.
    pub conn: u64,
    /// Its sequence number on that connection.
    pub seq: u64,
    /// The receiving port it was addressed to.
    pub behavior: String,
    /// The receiving port.
    pub port: String,
    /// The connection's kind.
    pub kind: ConnectionKind,
    /// The connection's priority.
    pub priority: i32,
    /// The value.
    pub value: Value,
}

/// Nanoseconds since the Unix epoch now (0 before 1970, which no clock here is).
pub fn unix_nanos_now() -> u64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
}

/// The port messages a [`Tap`] copied and not yet taken. Shared between the tap (inside the
/// node) and the program that records.
#[derive(Clone, Default)]
pub struct HeardLog(Arc<Mutex<Vec<Heard>>>);

impl HeardLog {
    /// Everything heard since the last call, in arrival order.
    pub fn take(&self) -> Vec<Heard> {
        std::mem::take(&mut *self.0.lock().unwrap_or_else(|e| e.into_inner()))
    }

    fn push(&self, h: Heard) {
        self.0.lock().unwrap_or_else(|e| e.into_inner()).push(h);
    }
}

/// A transport that copies every port message it delivers into a [`HeardLog`].
pub struct Tap<T: Transport> {
    inner: T,
    log: HeardLog,
}

impl<T: Transport> Tap<T> {
    /// Wrap `inner`; the returned log sees every port message `inner` delivers from now on.
    pub fn new(inner: T) -> (Tap<T>, HeardLog) {
        let log = HeardLog::default();
        (Tap { inner, log: log.clone() }, log)
    }
}

/// Only what is received is seen; everything else reaches the wrapped transport unchanged.
impl<T: Transport> TransportWrapper for Tap<T> {
    type Inner = T;
    fn inner(&self) -> &T {
        &self.inner
    }
    fn inner_mut(&mut self) -> &mut T {
        &mut self.inner
    }
    fn recv(&mut self) -> Option<(NodeId, Message)> {
        let (from, message) = self.inner.recv()?;
        if let Message::Port(p) = &message {
            self.log.push(Heard {
                unix_nanos: unix_nanos_now(),
                from,
                conn: p.conn.0,
                seq: p.seq,
                behavior: p.behavior.to_string(),
                port: p.port.to_string(),
                kind: p.kind,
                priority: p.priority,
                value: p.value.clone(),
            });
        }
        Some((from, message))
    }
    // Sending and counting are unchanged: the wrapped transport's batch paths serve.
    fn send_all(&mut self, outbox: &mut VecDeque<Outgoing>, tally: &mut SendTally) {
        self.inner.send_all(outbox, tally)
    }
    fn counters_into(&self, out: &mut Vec<(String, u64)>) {
        self.inner.counters_into(out)
    }
}

/// A connection as the recorder knows it: the port it starts from and where it goes.
#[derive(Clone, Debug, PartialEq)]
pub struct Route {
    /// The source behavior on the owning node.
    pub behavior: String,
    /// The source port.
    pub port: String,
    /// Where it goes, as `list NODE` writes it.
    pub to: String,
}

/// An MCAP file being written in the team channel layout.
pub struct TeamWriter<W: Write + Seek> {
    writer: mcap::Writer<W>,
    schemas: HashMap<ValueType, u16>,
    channels: HashMap<PortChannel, (u16, u32)>,
    messages: u64,
}

fn mcap_error(e: mcap::McapError) -> std::io::Error {
    std::io::Error::other(e)
}

impl<W: Write + Seek> TeamWriter<W> {
    /// Start a recording into `w` (MCAP header with profile `ayllu`, uncompressed chunks).
    pub fn new(w: W) -> std::io::Result<TeamWriter<W>> {
        let writer = mcap::WriteOptions::new()
            .compression(None)
            .profile(team_channels::PROFILE)
            .library(concat!("ayllu ", env!("CARGO_PKG_VERSION")))
            .create(w)
            .map_err(mcap_error)?;
        Ok(TeamWriter { writer, schemas: HashMap::new(), channels: HashMap::new(), messages: 0 })
    }

    /// Write one value on `channel` (added with its schema the first time), at `log_time`
    /// nanoseconds.
    pub fn write(
        &mut self,
        channel: &PortChannel,
        value: &Value,
        via: Option<&Via>,
        log_time: u64,
    ) -> std::io::Result<()> {
        let id = match self.channels.get_mut(channel) {
            Some((id, seq)) => {
                *seq += 1;
                (*id, *seq)
            }
            None => {
                let schema = match self.schemas.get(&channel.ty) {
                    Some(s) => *s,
                    None => {
                        let s = self
                            .writer
                            .add_schema(
                                &channel.schema_name(),
                                team_channels::SCHEMA_ENCODING,
                                channel.schema().as_bytes(),
                            )
                            .map_err(mcap_error)?;
                        self.schemas.insert(channel.ty, s);
                        s
                    }
                };
                let id = self
                    .writer
                    .add_channel(schema, &channel.topic(), team_channels::MESSAGE_ENCODING, &channel.metadata())
                    .map_err(mcap_error)?;
                self.channels.insert(channel.clone(), (id, 1));
                (id, 1)
            }
        };
        let header =
            mcap::records::MessageHeader { channel_id: id.0, sequence: id.1, log_time, publish_time: log_time };
        self.writer.write_to_known_channel(&header, &channel.message_bytes(value, via)).map_err(mcap_error)?;
        self.messages += 1;
        Ok(())
    }

    /// Messages written so far.
    pub fn messages(&self) -> u64 {
        self.messages
    }

    /// Channels written so far.
    pub fn channels(&self) -> usize {
        self.channels.len()
    }

    /// Write the summary and the footer: the file is complete.
    pub fn finish(&mut self) -> std::io::Result<()> {
        self.writer.finish().map(|_| ()).map_err(mcap_error)
    }
}

/// Turns what a [`Tap`] heard into messages on the right channels of a [`TeamWriter`].
pub struct Recorder<W: Write + Seek> {
    writer: TeamWriter<W>,
    routes: HashMap<(NodeId, u64), Route>,
    pending: VecDeque<Heard>,
    wanted: BTreeSet<NodeId>,
    listed: HashMap<NodeId, u64>,
    unresolved: u64,
    per_channel: HashMap<String, u64>,
}

impl<W: Write + Seek> Recorder<W> {
    /// How long a message whose connection is unknown waits for its sender's LIST before it is
    /// written on the fallback channel.
    pub const HOLD: StdDuration = StdDuration::from_secs(3);

    /// The shortest time between two LISTs of one node asked for by unknown connections (a
    /// connection made after the last LIST is learnt by the next).
    pub const RELIST: StdDuration = StdDuration::from_millis(500);

    /// Record into `writer`.
    pub fn new(writer: TeamWriter<W>) -> Recorder<W> {
        Recorder {
            writer,
            routes: HashMap::new(),
            pending: VecDeque::new(),
            wanted: BTreeSet::new(),
            listed: HashMap::new(),
            unresolved: 0,
            per_channel: HashMap::new(),
        }
    }

    /// Learn a node's connections from its LIST report.
    pub fn learn(&mut self, report: &NodeReport) {
        for c in &report.connections {
            if let Endpoint::Local { behavior, port } | Endpoint::Node { behavior, port, .. } = &c.source {
                let route = Route {
                    behavior: behavior.to_string(),
                    port: port.to_string(),
                    to: team_channels::destination_text(report.node, &c.destination),
                };
                self.routes.insert((report.node, c.id.0), route);
            }
        }
        self.listed.insert(report.node, unix_nanos_now());
        self.wanted.remove(&report.node);
    }

    /// Learn one connection (one the recorder CONNECTed itself).
    pub fn learn_route(&mut self, node: NodeId, conn: u64, route: Route) {
        self.routes.insert((node, conn), route);
    }

    /// Nodes whose connection table the recorder needs (a message came along a connection it
    /// does not know). The caller LISTs them and calls [`Recorder::learn`], or
    /// [`Recorder::list_failed`].
    pub fn wanted_lists(&self) -> Vec<NodeId> {
        self.wanted.iter().copied().collect()
    }

    /// A LIST of `node` got no usable answer (an AylluLite node, gone): stop asking until new
    /// messages need it after [`Recorder::HOLD`].
    pub fn list_failed(&mut self, node: NodeId) {
        self.listed.insert(node, unix_nanos_now());
        self.wanted.remove(&node);
    }

    /// Record what was heard; messages on unknown connections wait (see the module docs).
    pub fn heard(&mut self, heard: Vec<Heard>) -> std::io::Result<()> {
        for h in heard {
            if self.pending.is_empty() && self.routes.contains_key(&(h.from, h.conn)) {
                self.write(&h, false)?;
            } else {
                if !self.routes.contains_key(&(h.from, h.conn)) {
                    let stale = self
                        .listed
                        .get(&h.from)
                        .is_none_or(|t| h.unix_nanos.saturating_sub(*t) > Self::RELIST.as_nanos() as u64);
                    if stale {
                        self.wanted.insert(h.from);
                    }
                }
                self.pending.push_back(h);
            }
        }
        self.drain(unix_nanos_now(), false)
    }

    /// Write the held messages that can be written now (in arrival order); with `all`, or once
    /// older than [`Recorder::HOLD`], unknown ones go to the fallback channel.
    fn drain(&mut self, now: u64, all: bool) -> std::io::Result<()> {
        while let Some(h) = self.pending.front() {
            let known = self.routes.contains_key(&(h.from, h.conn));
            let expired = now.saturating_sub(h.unix_nanos) > Self::HOLD.as_nanos() as u64;
            if !(known || expired || all) {
                break;
            }
            let h = self.pending.pop_front().expect("front exists");
            self.write(&h, !known)?;
        }
        Ok(())
    }

    fn write(&mut self, h: &Heard, fallback: bool) -> std::io::Result<()> {
        let (channel, to) = match self.routes.get(&(h.from, h.conn)) {
            Some(r) if !fallback => (PortChannel::new(h.from, &r.behavior, &r.port, h.value.ty()), Some(r.to.clone())),
            _ => {
                self.unresolved += 1;
                let port = format!("{}.{}", h.behavior, h.port);
                (PortChannel::new(h.from, &format!("_c{}", h.conn), &port, h.value.ty()), None)
            }
        };
        let via = Via { conn: h.conn, seq: h.seq, kind: h.kind, priority: h.priority, to };
        *self.per_channel.entry(channel.topic()).or_default() += 1;
        self.writer.write(&channel, &h.value, Some(&via), h.unix_nanos)
    }

    /// Messages written so far.
    pub fn messages(&self) -> u64 {
        self.writer.messages()
    }

    /// Messages written on fallback channels (their connection was never resolved).
    pub fn unresolved(&self) -> u64 {
        self.unresolved
    }

    /// Messages written per topic, sorted by topic.
    pub fn per_channel(&self) -> Vec<(String, u64)> {
        let mut v: Vec<(String, u64)> = self.per_channel.iter().map(|(t, n)| (t.clone(), *n)).collect();
        v.sort();
        v
    }

    /// Write everything still held and complete the file.
    pub fn finish(&mut self) -> std::io::Result<()> {
        self.drain(u64::MAX, true)?;
        self.writer.finish()
    }
}

/// One message of a recording, read back.
#[derive(Clone, Debug, PartialEq)]
pub struct Recorded {
    /// Its channel.
    pub channel: PortChannel,
    /// Its value.
    pub value: Value,
    /// When it was heard (MCAP `log_time`), nanoseconds.
    pub log_time: u64,
}

/// Every message of the team channel layout in an MCAP file, ordered by `log_time` (stable).
/// Channels outside the layout are skipped. Errors: not MCAP, a file cut short or damaged,
/// or a message that is not the layout's JSON on a layout topic. Never a panic, whatever the
/// bytes: the records are framed by `mcap_records`, not by the `mcap` crate's readers.
pub fn read_recording(bytes: &[u8]) -> std::io::Result<Vec<Recorded>> {
    let invalid = |what: String| std::io::Error::new(std::io::ErrorKind::InvalidData, what);
    let mut topics: HashMap<u16, &str> = HashMap::new();
    let mut out = Vec::new();
    for record in mcap_records::records(bytes).map_err(|e| invalid(e.to_string()))? {
        match record.map_err(|e| invalid(e.to_string()))? {
            McapRecord::Channel { id, topic } => {
                topics.insert(id, topic);
            }
            McapRecord::Message { channel, log_time, data, .. } => {
                let Some(topic) = topics.get(&channel) else {
                    return Err(invalid(format!("a message on channel {channel}, which the file does not declare")));
                };
                if PortChannel::parse_topic(topic).is_none() {
                    continue;
                }
                let (channel, value) = team_channels::parse_message(data)
                    .ok_or_else(|| invalid(format!("a message on {topic} is not a team channel message")))?;
                out.push(Recorded { channel, value, log_time });
            }
            McapRecord::Metadata { .. } | McapRecord::DataEnd | McapRecord::Footer => {}
        }
    }
    out.sort_by_key(|r| r.log_time);
    Ok(out)
}

/// Whether `bytes` start as a team recording (`ayllu record`, [`TeamWriter`]) does: an MCAP
/// header with the team channel layout's profile. For the reader of the other kind, the flight
/// recordings of `ayllu replay`, to say which tool reads the file instead.
pub fn is_team_recording(bytes: &[u8]) -> bool {
    crate::replay::mcap_profile(bytes) == Some(team_channels::PROFILE)
}

/// When each message of a playback is due, from the start of the playback: the recording's
/// own gaps divided by `speed` (2.0 = twice as fast).
pub fn playback_offsets(recorded: &[Recorded], speed: f64) -> Vec<StdDuration> {
    let Some(first) = recorded.first().map(|r| r.log_time) else { return Vec::new() };
    recorded
        .iter()
        .map(|r| {
            let secs = (r.log_time.saturating_sub(first)) as f64 / 1e9 / speed;
            StdDuration::try_from_secs_f64(secs).unwrap_or(StdDuration::MAX)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn heard(from: u32, conn: u64, seq: u64, value: f64, t: u64) -> Heard {
        Heard {
            unix_nanos: t,
            from: NodeId(from),
            conn,
            seq,
            behavior: "OBS1".into(),
            port: "Best".into(),
            kind: ConnectionKind::Normal,
            priority: 0,
            value: Value::Float(value),
        }
    }

    #[test]
    fn messages_land_on_their_senders_channel_and_read_back() {
        let mut buf = std::io::Cursor::new(Vec::new());
        {
            let mut rec = Recorder::new(TeamWriter::new(&mut buf).unwrap());
            let now = unix_nanos_now();
            rec.learn_route(NodeId(1), 20, Route { behavior: "OBS1".into(), port: "Local".into(), to: "x".into() });
            rec.heard(vec![heard(1, 20, 1, 0.5, now), heard(1, 20, 2, 0.6, now + 1)]).unwrap();
            // Unknown connection: held, and its sender's table is wanted.
            rec.heard(vec![heard(2, 7, 1, 0.9, now + 2)]).unwrap();
            assert_eq!(rec.wanted_lists(), vec![NodeId(2)]);
            assert_eq!(rec.messages(), 2);
            rec.finish().unwrap();
            assert_eq!(rec.unresolved(), 1);
        }
        let back = read_recording(buf.get_ref()).unwrap();
        let topics: Vec<String> = back.iter().map(|r| r.channel.topic()).collect();
        assert_eq!(topics, ["/n1/OBS1/Local", "/n1/OBS1/Local", "/n2/_c7/OBS1.Best"]);
        assert_eq!(back[1].value, Value::Float(0.6));
        let offsets = playback_offsets(&back, 2.0);
        assert_eq!(offsets[0], StdDuration::ZERO);
        assert_eq!(offsets[2], StdDuration::from_nanos(1));
    }
}
