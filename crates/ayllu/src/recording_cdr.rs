//! The binary form of a flight recording's messages (format version 3): every journal entry
//! is one ROS 2 message of type [`SCHEMA_NAME`] in CDR, on the same topics as the JSON form
//! ([`crate::recording_format`]), so Foxglove, `ros2 bag` and the Python `mcap` reader (with
//! `mcap-ros2-support`) decode it with no Ayllu code (spec/flight-recorder.md, "The file").
//!
//! Why CDR with a `ros2msg` schema: it is the encoding our users' robots already log (ROS 2),
//! its readers need no generated code (the schema is the message definition's text), and it is
//! simple enough to write by hand into a reused buffer, field by field, with no allocation per
//! entry: what lets the recorder's writer keep up with a busy node, where building a JSON tree
//! per entry did not (docs/performance.md).
//!
//! One flat message type for every event: the events every busy node makes (writes, accepted
//! values, process runs and their effects, polls) are in typed fields (`behavior`, `name`,
//! `index` and the value by its type); the rare ones (definitions, connections, messages
//! received, requests, checkpoints) carry their JSON form ([`crate::recording_format`]) whole in
//! `json`, so they need no second schema.
//!
//! What it promises:
//! * [`encode_into`] and [`decode`] are inverses on everything a replay needs, values bit for
//!   bit (NaN payloads included: floats are their IEEE bytes).
//! * [`decode`] never panics and never trusts a length: a bad message is an error naming the
//!   field.
//! * [`encode_into`] appends to the caller's buffer and allocates nothing for the hot events
//!   once the buffer has grown to the largest entry.

use std::borrow::Cow;
use std::sync::Arc;

use ayllu_core::{BehaviorClass, Duration, Entry, Event, Instant, JournalItem, Value};
use serde_json::Value as Json;

use crate::recording_format::{self, Topic};

/// The message type, as its schema record names it.
pub const SCHEMA_NAME: &str = "ayllu_msgs/msg/FlightEntry";

/// The message definition (`ros2msg` schema encoding).
pub const SCHEMA: &str = "\
# One journal entry of an Ayllu flight recording (spec/flight-recorder.md).
uint64 seq            # place in the node's journal
uint64 t_ns           # node time, ns
string event          # write, accepted, run, poll, set_slot, trigger, reset, ... (see json)
string behavior       # the behavior, for write, accepted, run
string name           # the port (write, accepted) or the process (run)
uint16 index          # the port, slot or monostable handle
uint8 type            # 0 none, 1 bool, 2 int, 3 float, 4 text, 5 bytes, 6 vector
bool bool_value
int64 int_value       # also a trigger's period in ns; run: 1 if native
float64 float_value
string text_value
uint8[] bytes_value
float64[] vector_value
string json           # the whole entry in its JSON form, for the other events
";

/// A CDR little-endian encapsulation header (XCDR1, as ROS 2 writes it).
const HEADER: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

/// Appends CDR fields to a buffer, aligned from the end of the encapsulation header.
struct Writer<'a> {
    out: &'a mut Vec<u8>,
    start: usize,
}

impl Writer<'_> {
    fn align(&mut self, n: usize) {
        while !(self.out.len() - self.start).is_multiple_of(n) {
            self.out.push(0);
        }
    }
    fn u8(&mut self, x: u8) {
        self.out.push(x);
    }
    fn u16(&mut self, x: u16) {
        self.align(2);
        self.out.extend_from_slice(&x.to_le_bytes());
    }
    fn u32(&mut self, x: u32) {
        self.align(4);
        self.out.extend_from_slice(&x.to_le_bytes());
    }
    fn u64(&mut self, x: u64) {
        self.align(8);
        self.out.extend_from_slice(&x.to_le_bytes());
    }
    fn string(&mut self, s: &str) {
        self.u32(s.len() as u32 + 1);
        self.out.extend_from_slice(s.as_bytes());
        self.out.push(0);
    }
    fn bytes(&mut self, b: &[u8]) {
        self.u32(b.len() as u32);
        self.out.extend_from_slice(b);
    }
    fn floats(&mut self, v: &[f64]) {
        self.u32(v.len() as u32);
        if !v.is_empty() {
            self.align(8);
        }
        for x in v {
            self.out.extend_from_slice(&x.to_le_bytes());
        }
    }
}

/// The topic an entry goes on (as the JSON form's).
pub fn topic(event: &Event) -> Topic {
    match event {
        Event::Write { .. } | Event::Trigger { .. } | Event::Reset { .. } | Event::Receive { .. } | Event::Poll => {
            Topic::Input
        }
        Event::Run { .. }
        | Event::ProcessWrite { .. }
        | Event::ProcessSetSlot { .. }
        | Event::ProcessTrigger { .. }
        | Event::ProcessReset { .. }
        | Event::ProcessChange(_)
        | Event::ProcessRequest { .. } => Topic::Process,
        Event::Accepted { .. } => Topic::Accepted,
        _ => Topic::Structure,
    }
}

/// The typed fields of one message, borrowed from the entry.
#[derive(Default)]
struct Fields<'a> {
    event: &'a str,
    behavior: &'a str,
    name: &'a str,
    index: u16,
    value: Option<&'a Value>,
    int: i64,
}

/// Append journal entry number `seq` as one CDR message (header included) to `out`, and say
/// its topic.
pub fn encode_into(seq: u64, entry: &Entry, out: &mut Vec<u8>) -> Topic {
    let at = entry.at;
    let f = match &entry.event {
        Event::Write { behavior, class, port, value } => {
            let item =
                JournalItem::Value { at, write: true, behavior, class, port: *port, value: Cow::Borrowed(value) };
            return encode_item(seq, item, out);
        }
        Event::Accepted { behavior, class, port, value } => {
            let item =
                JournalItem::Value { at, write: false, behavior, class, port: *port, value: Cow::Borrowed(value) };
            return encode_item(seq, item, out);
        }
        Event::Run { behavior, process, native } => {
            Fields { event: "run", behavior, name: process, int: i64::from(*native), ..Fields::default() }
        }
        Event::ProcessWrite { port, value } => {
            Fields { event: "write", index: *port, value: Some(value), ..Fields::default() }
        }
        Event::ProcessSetSlot { slot, value } => {
            Fields { event: "set_slot", index: *slot, value: Some(value), ..Fields::default() }
        }
        Event::ProcessTrigger { mono, period } => Fields {
            event: "trigger",
            index: *mono,
            int: i64::try_from(period.as_nanos()).unwrap_or(i64::MAX),
            ..Fields::default()
        },
        Event::ProcessReset { port } => Fields { event: "reset", index: *port, ..Fields::default() },
        Event::Poll => Fields { event: "poll", ..Fields::default() },
        _ => return encode_json_into(seq, entry, out),
    };
    write(seq, entry.at, &f, "", out);
    topic(&entry.event)
}

/// [`encode_into`] for an entry of a [`JournalBatch`](ayllu_core::JournalBatch): a value
/// entry is encoded from what it borrows, with no `Entry` made.
pub fn encode_item(seq: u64, item: JournalItem<'_>, out: &mut Vec<u8>) -> Topic {
    match item {
        JournalItem::Value { at, write: is_write, behavior, class, port, value } => {
            let f = Fields {
                event: if is_write { "write" } else { "accepted" },
                behavior,
                name: port_name(class, port),
                index: port,
                value: Some(&value),
                int: 0,
            };
            write(seq, at, &f, "", out);
            if is_write {
                Topic::Input
            } else {
                Topic::Accepted
            }
        }
        JournalItem::Entry(e) => encode_into(seq, e, out),
    }
}

fn port_name(class: &BehaviorClass, port: u16) -> &str {
    class.ports().get(usize::from(port)).map_or("", |p| p.name.as_str())
}

/// An entry whose typed fields are not enough: its JSON form in `json`.
fn encode_json_into(seq: u64, entry: &Entry, out: &mut Vec<u8>) -> Topic {
    let (topic, json) = recording_format::encode(seq, entry);
    let event = json.get("event").and_then(Json::as_str).unwrap_or("").to_owned();
    let text = json.to_string();
    write(seq, entry.at, &Fields { event: &event, ..Fields::default() }, &text, out);
    topic
}

/// A checkpoint taken before journal entry `seq`, as one message (its JSON form in `json`).
pub fn encode_checkpoint_into(seq: u64, snapshot: &ayllu_core::Snapshot, out: &mut Vec<u8>) {
    let text = recording_format::encode_checkpoint(seq, snapshot).to_string();
    write(seq, snapshot.at(), &Fields { event: "checkpoint", ..Fields::default() }, &text, out);
}

fn write(seq: u64, at: Instant, f: &Fields<'_>, json: &str, out: &mut Vec<u8>) {
    out.extend_from_slice(&HEADER);
    let start = out.len();
    let mut w = Writer { out, start };
    w.u64(seq);
    w.u64(at.as_nanos());
    w.string(f.event);
    w.string(f.behavior);
    w.string(f.name);
    w.u16(f.index);
    let (ty, b, i, x, text, bytes, vector): (u8, bool, i64, f64, &str, &[u8], &[f64]) = match f.value {
        None => (0, false, f.int, 0.0, "", &[], &[]),
        Some(Value::Bool(v)) => (1, *v, 0, 0.0, "", &[], &[]),
        Some(Value::Int(v)) => (2, false, *v, 0.0, "", &[], &[]),
        Some(Value::Float(v)) => (3, false, 0, *v, "", &[], &[]),
        Some(Value::Text(v)) => (4, false, 0, 0.0, v, &[], &[]),
        Some(Value::Bytes(v)) => (5, false, 0, 0.0, "", v, &[]),
        Some(Value::Vector(v)) => (6, false, 0, 0.0, "", &[], v),
    };
    w.u8(ty);
    w.u8(u8::from(b));
    w.u64(i as u64);
    w.u64(x.to_bits());
    w.string(text);
    w.bytes(bytes);
    w.floats(vector);
    w.string(json);
}

/// Reads CDR fields, never past the end.
struct Reader<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn align(&mut self, n: usize) {
        self.pos = self.pos.next_multiple_of(n);
    }
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], String> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.data.len());
        let end = end.ok_or_else(|| format!("`{what}` runs past the end of the message"))?;
        let s = &self.data[self.pos..end];
        self.pos = end;
        Ok(s)
    }
    fn u8(&mut self, what: &str) -> Result<u8, String> {
        Ok(self.take(1, what)?[0])
    }
    fn u16(&mut self, what: &str) -> Result<u16, String> {
        self.align(2);
        Ok(u16::from_le_bytes(self.take(2, what)?.try_into().map_err(|_| what.to_owned())?))
    }
    fn u32(&mut self, what: &str) -> Result<u32, String> {
        self.align(4);
        Ok(u32::from_le_bytes(self.take(4, what)?.try_into().map_err(|_| what.to_owned())?))
    }
    fn u64(&mut self, what: &str) -> Result<u64, String> {
        self.align(8);
        Ok(u64::from_le_bytes(self.take(8, what)?.try_into().map_err(|_| what.to_owned())?))
    }
    fn string(&mut self, what: &str) -> Result<&'a str, String> {
        let n = self.u32(what)? as usize;
        let raw = self.take(n, what)?;
        let text = raw.strip_suffix(&[0]).ok_or_else(|| format!("`{what}` is not NUL-terminated"))?;
        std::str::from_utf8(text).map_err(|_| format!("`{what}` is not UTF-8"))
    }
    fn bytes(&mut self, what: &str) -> Result<&'a [u8], String> {
        let n = self.u32(what)? as usize;
        self.take(n, what)
    }
    fn floats(&mut self, what: &str) -> Result<Vec<f64>, String> {
        let n = self.u32(what)? as usize;
        if n > 0 {
            self.align(8);
        }
        let raw = self.take(n.checked_mul(8).ok_or_else(|| format!("`{what}` is too long"))?, what)?;
        Ok(raw.chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().unwrap_or([0; 8]))).collect())
    }
}

/// What one message holds: a journal entry, or a checkpoint (its JSON form).
pub enum Decoded {
    /// A journal entry and its place in the journal.
    Entry(recording_format::Decoded),
    /// A checkpoint's JSON form ([`recording_format::decode_checkpoint`] reads it).
    Checkpoint(Json),
}

/// The entry or checkpoint [`encode_into`] wrote as `data`; errors name what is wrong.
pub fn decode(data: &[u8]) -> Result<Decoded, String> {
    let body = data.strip_prefix(&HEADER).ok_or("not a little-endian CDR message (its header)")?;
    let mut r = Reader { data: body, pos: 0 };
    let seq = r.u64("seq")?;
    let at = Instant::from_nanos(r.u64("t_ns")?);
    let event = r.string("event")?;
    let behavior = r.string("behavior")?;
    let name = r.string("name")?;
    let index = r.u16("index")?;
    let ty = r.u8("type")?;
    let b = r.u8("bool_value")?;
    let int = r.u64("int_value")? as i64;
    let x = f64::from_bits(r.u64("float_value")?);
    let text = r.string("text_value")?;
    let bytes = r.bytes("bytes_value")?;
    let vector = r.floats("vector_value")?;
    let json = r.string("json")?;
    let value = || -> Result<Value, String> {
        Ok(match ty {
            1 => Value::Bool(b != 0),
            2 => Value::Int(int),
            3 => Value::Float(x),
            4 => Value::Text(Arc::from(text)),
            5 => Value::Bytes(Arc::from(bytes)),
            6 => Value::Vector(Arc::from(vector.as_slice())),
            other => return Err(format!("`type` {other} is no value's type")),
        })
    };
    if !json.is_empty() {
        let j: Json = serde_json::from_str(json).map_err(|e| format!("`json` is not JSON: {e}"))?;
        if event == "checkpoint" {
            return Ok(Decoded::Checkpoint(j));
        }
        return recording_format::decode(&j).map(Decoded::Entry);
    }
    let stand_in = || Arc::new(BehaviorClass::new(""));
    let event = match event {
        "write" if !behavior.is_empty() => {
            Event::Write { behavior: Arc::from(behavior), class: stand_in(), port: index, value: value()? }
        }
        "write" => Event::ProcessWrite { port: index, value: value()? },
        "accepted" => {
            Event::Accepted { behavior: Arc::from(behavior), class: stand_in(), port: index, value: value()? }
        }
        "run" => Event::Run { behavior: Arc::from(behavior), process: name.to_owned(), native: int != 0 },
        "set_slot" => Event::ProcessSetSlot { slot: index, value: value()? },
        "trigger" => Event::ProcessTrigger {
            mono: index,
            period: Duration::from_nanos(u64::try_from(int).map_err(|_| "a negative trigger period")?),
        },
        "reset" => Event::ProcessReset { port: index },
        "poll" => Event::Poll,
        other => return Err(format!("unknown event `{other}` without its JSON form")),
    };
    Ok(Decoded::Entry(recording_format::Decoded { seq, entry: Entry { at, event } }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use ayllu_core::PortSpec;

    fn round_trip(entry: Entry) {
        let mut buf = Vec::new();
        encode_into(7, &entry, &mut buf);
        let Ok(Decoded::Entry(d)) = decode(&buf) else { panic!("{entry:?} does not decode") };
        assert_eq!(d.seq, 7);
        assert_eq!(d.entry.at, entry.at);
        // The class is a stand-in on decoding (the replayed node knows the port's name).
        assert_eq!(format!("{:?}", strip(&d.entry.event)), format!("{:?}", strip(&entry.event)));
        for cut in 0..buf.len() {
            assert!(decode(&buf[..cut]).is_err(), "a message cut at {cut} of {} decodes", buf.len());
        }
    }

    fn strip(e: &Event) -> Event {
        match e.clone() {
            Event::Write { behavior, port, value, .. } => {
                Event::Write { behavior, class: Arc::new(BehaviorClass::new("")), port, value }
            }
            Event::Accepted { behavior, port, value, .. } => {
                Event::Accepted { behavior, class: Arc::new(BehaviorClass::new("")), port, value }
            }
            other => other,
        }
    }

    #[test]
    fn every_hot_event_and_value_type_comes_back_bit_for_bit() {
        let mut class = BehaviorClass::new("C");
        class.port(PortSpec::new("Out", 0.0)).unwrap();
        let class = Arc::new(class);
        let values = [
            Value::Bool(true),
            Value::Int(-42),
            Value::Float(f64::from_bits(0x7ff8_0000_0000_0abc)),
            Value::text("ñ"),
            Value::Bytes(Arc::from(&[0u8, 255, 7][..])),
            Value::Vector(Arc::from(&[1.5, -0.0, f64::INFINITY][..])),
        ];
        let at = Instant::from_nanos(123_456_789);
        for v in values {
            let b: Arc<str> = Arc::from("B");
            round_trip(Entry {
                at,
                event: Event::Write { behavior: b.clone(), class: class.clone(), port: 3, value: v.clone() },
            });
            round_trip(Entry {
                at,
                event: Event::Accepted { behavior: b, class: class.clone(), port: 3, value: v.clone() },
            });
            round_trip(Entry { at, event: Event::ProcessWrite { port: 4, value: v.clone() } });
            round_trip(Entry { at, event: Event::ProcessSetSlot { slot: 1, value: v } });
        }
        round_trip(Entry { at, event: Event::Run { behavior: Arc::from("B"), process: "P".into(), native: true } });
        round_trip(Entry { at, event: Event::ProcessTrigger { mono: 2, period: Duration::from_millis(90) } });
        round_trip(Entry { at, event: Event::ProcessReset { port: 5 } });
        round_trip(Entry { at, event: Event::Poll });
        round_trip(Entry { at, event: Event::Join("G".into()) });
        round_trip(Entry { at, event: Event::Gap { lost: 3 } });
    }

    /// Golden bytes: a poll at 1 ns, entry 2 (spec/flight-recorder.md shows this layout).
    #[test]
    fn a_poll_is_these_bytes() {
        let mut buf = Vec::new();
        encode_into(2, &Entry { at: Instant::from_nanos(1), event: Event::Poll }, &mut buf);
        let mut want = vec![0, 1, 0, 0];
        want.extend(2u64.to_le_bytes()); // seq
        want.extend(1u64.to_le_bytes()); // t_ns
        want.extend(5u32.to_le_bytes()); // event: "poll\0"
        want.extend(b"poll\0");
        want.extend([0, 0, 0]); // to 4
        want.extend(1u32.to_le_bytes()); // behavior: ""
        want.push(0);
        want.extend([0, 0, 0]);
        want.extend(1u32.to_le_bytes()); // name: ""
        want.push(0);
        want.push(0); // to 2
        want.extend(0u16.to_le_bytes()); // index
        want.push(0); // type
        want.push(0); // bool_value
        want.extend([0, 0]); // to 8
        want.extend(0u64.to_le_bytes()); // int_value
        want.extend(0u64.to_le_bytes()); // float_value
        want.extend(1u32.to_le_bytes()); // text_value: ""
        want.push(0);
        want.extend([0, 0, 0]);
        want.extend(0u32.to_le_bytes()); // bytes_value: []
        want.extend(0u32.to_le_bytes()); // vector_value: []
        want.extend(1u32.to_le_bytes()); // json: ""
        want.push(0);
        assert_eq!(buf, want);
    }
}
