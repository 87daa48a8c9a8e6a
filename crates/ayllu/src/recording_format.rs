//! The JSON form of a flight recording's messages: one JSON object per journal entry
//! ([`ayllu_core::journal`]), on four MCAP channels with JSON Schemas, so Foxglove opens a
//! recording with no conversion (spec/flight-recorder.md).
//!
//! Promises:
//! * [`encode`] and [`decode`] are inverses on everything a replay needs: every value comes
//!   back bit for bit (floats are written in their shortest round-trip form and read back
//!   exactly; NaN and the infinities as `"NaN"`, `"inf"`, `"-inf"`), so replayed values can be
//!   compared with recorded ones exactly;
//! * every message carries `seq` (its place in the node's journal, from 0 in each recording)
//!   and `t_ns` (the node's time), so the messages of all channels can be put back in order;
//! * pure functions: no I/O, no clock. [`decode`] never panics on bad input: it says which
//!   field is wrong.

use std::sync::Arc;

use ayllu_core::{
    Access, Allow, BehaviorClass, BleConfig, Change, ConnectionId, ConnectionKind, ControlBody, ControlMessage,
    Duration, Endpoint, Entry, Event, Instant, Limits, Message, NodeId, PortKind, PortMessage, PortSpec, ReplyBody,
    Trigger, Value,
};
use serde::de::DeserializeOwned;
use serde_json::{json, Map, Value as Json};

/// The MCAP profile of a flight recording.
pub const PROFILE: &str = "ayllu-flight";
/// The name of the metadata record that opens every segment.
pub const METADATA: &str = "ayllu.flight_recording";
/// The JSON form's version, in the metadata; a reader refuses versions it does not know.
/// Written by earlier builds; this one writes [`VERSION`] and reads both.
pub const JSON_VERSION: &str = "1";
/// A rolling recording in the JSON form (`--record-last`): version 1 plus checkpoints
/// ([`Topic::Checkpoint`]), whose journal starts where its first checkpoint was taken.
pub const ROLLING_JSON_VERSION: &str = "2";
/// The version this build writes: the binary form ([`crate::recording_cdr`]), whole or rolling
/// (a rolling recording has the checkpoint channel and `keep_last_s` in its metadata).
pub const VERSION: &str = "3";
/// The versions this build reads.
pub const VERSIONS_READ: [&str; 3] = [JSON_VERSION, ROLLING_JSON_VERSION, VERSION];

/// The channels of a recording.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Topic {
    /// Structure changes and other calls that are not writes: define, create, connect, join,
    /// BLE join, access, limits, requests, warnings, lost peers, gaps.
    Structure,
    /// Writes from outside, triggers, resets, messages received and polls.
    Input,
    /// Process activations and their effects.
    Process,
    /// Values the ports accepted.
    Accepted,
    /// Checkpoints: the node's whole state ([`ayllu_core::Snapshot`]) where a segment of a
    /// rolling recording starts.
    Checkpoint,
}

impl Topic {
    /// Every topic, in channel-id order.
    pub const ALL: [Topic; 5] = [Topic::Structure, Topic::Input, Topic::Process, Topic::Accepted, Topic::Checkpoint];

    /// The MCAP topic.
    pub fn name(self) -> &'static str {
        match self {
            Topic::Structure => "/ayllu/structure",
            Topic::Input => "/ayllu/input",
            Topic::Process => "/ayllu/process",
            Topic::Accepted => "/ayllu/accepted",
            Topic::Checkpoint => "/ayllu/checkpoint",
        }
    }

    /// The schema's name.
    pub fn schema_name(self) -> &'static str {
        match self {
            Topic::Structure => "ayllu.Structure",
            Topic::Input => "ayllu.Input",
            Topic::Process => "ayllu.Process",
            Topic::Accepted => "ayllu.Accepted",
            Topic::Checkpoint => "ayllu.Checkpoint",
        }
    }

    /// The JSON Schema of the topic's messages (`jsonschema` schema encoding).
    pub fn schema(self) -> Json {
        let mut properties = json!({
            "seq": {"type": "integer", "description": "place in the node's journal"},
            "t_ns": {"type": "integer", "description": "node time, ns"},
            "t": {"type": "number", "description": "node time, s"},
            "event": {"type": "string"},
        });
        if self == Topic::Checkpoint {
            let extra = json!({
                "version": {"type": "integer", "description": "the snapshot's layout (ayllu_core::SNAPSHOT_VERSION)"},
                "snapshot": {"type": "object", "description": "the node's whole state; seq is the next entry's"},
            });
            if let (Some(p), Json::Object(e)) = (properties.as_object_mut(), extra) {
                p.extend(e);
            }
        }
        if self == Topic::Accepted {
            let extra = json!({
                "behavior": {"type": "string"},
                "port": {"type": "string"},
                "port_index": {"type": "integer"},
                "type": {"type": "string", "enum": ["bool", "int", "float", "text", "bytes", "vector"]},
                "value": {"description": "the value accepted (bytes as hex; NaN and infinities as strings)"},
            });
            if let (Some(p), Json::Object(e)) = (properties.as_object_mut(), extra) {
                p.extend(e);
            }
        }
        json!({
            "$schema": "https://json-schema.org/draft/2020-12/schema",
            "title": self.schema_name(),
            "type": "object",
            "properties": properties,
            "required": ["seq", "t_ns", "event"],
            "additionalProperties": true,
        })
    }

    /// The topic named `name`.
    pub fn from_name(name: &str) -> Option<Topic> {
        Topic::ALL.into_iter().find(|t| t.name() == name)
    }
}

/// Values use the team channels' JSON form (spec/recording.md): one encoder and decoder for
/// every recording Ayllu writes.
pub use crate::team_channels::value_json;
use crate::team_channels::{float_json, value_from_json, value_type};

fn float_from(j: &Json) -> Result<f64, String> {
    crate::team_channels::float_from_json(j).ok_or_else(|| format!("{j} is not a float"))
}

/// The value of type `ty` (as [`ayllu_core::ValueType::name`] writes it) that [`value_json`]
/// wrote as `j`.
pub fn value_from(ty: &str, j: &Json) -> Result<Value, String> {
    let t = value_type(ty).ok_or_else(|| format!("unknown value type `{ty}`"))?;
    value_from_json(t, j).ok_or_else(|| format!("{j} is not a {ty}"))
}

fn typed(v: &Value) -> (Json, Json) {
    (json!(v.ty().name()), value_json(v))
}

fn to_json<T: serde::Serialize>(x: &T) -> Json {
    serde_json::to_value(x).unwrap_or(Json::Null)
}

fn allow_json(a: &Allow) -> Json {
    match a {
        Allow::Everyone => json!("all"),
        Allow::Nobody => json!("none"),
        Allow::Only(ids) => Json::Array(ids.iter().map(|n| json!(n.0)).collect()),
    }
}

fn allow_from(j: &Json) -> Result<Allow, String> {
    match j {
        Json::String(s) if s == "all" => Ok(Allow::Everyone),
        Json::String(s) if s == "none" => Ok(Allow::Nobody),
        Json::Array(ids) => ids
            .iter()
            .map(|n| n.as_u64().and_then(|n| u32::try_from(n).ok()).map(NodeId).ok_or_else(|| format!("bad node {n}")))
            .collect::<Result<_, _>>()
            .map(Allow::Only),
        other => Err(format!("{other} is not an access rule")),
    }
}

fn class_json(c: &BehaviorClass) -> Json {
    let ports: Vec<Json> = c
        .ports()
        .iter()
        .map(|p| {
            let (ty, default) = typed(&p.default);
            json!({"name": p.name, "kind": to_json(&p.kind), "type": ty, "default": default,
                   "lifespan": to_json(&p.lifespan), "window": to_json(&p.window)})
        })
        .collect();
    let slots: Vec<Json> = c
        .slots()
        .iter()
        .map(|s| {
            let (ty, default) = typed(&s.default);
            json!({"name": s.name, "type": ty, "default": default})
        })
        .collect();
    let processes: Vec<Json> =
        c.processes().iter().map(|p| json!({"name": p.name, "trigger": to_json(&p.trigger)})).collect();
    json!({"name": c.name(), "ports": ports, "slots": slots, "monostables": c.monostables(), "processes": processes})
}

fn message_json(m: &Message) -> Json {
    match m {
        Message::Port(p) => {
            let (ty, value) = typed(&p.value);
            json!({"port_message": {"conn": p.conn.0, "seq": p.seq, "behavior": &*p.behavior, "port": &*p.port,
                   "kind": to_json(&p.kind), "priority": p.priority, "type": ty, "value": value}})
        }
        Message::Control(c) => json!({"control": {"id": c.id, "body": body_json(&c.body)}}),
    }
}

fn body_json(b: &ControlBody) -> Json {
    match b {
        ControlBody::Connect { source_behavior, source_port, destination, kind, priority } => json!({"connect": {
            "source_behavior": &**source_behavior, "source_port": &**source_port,
            "destination": to_json(destination), "kind": to_json(kind), "priority": priority}}),
        ControlBody::Disconnect { conn } => json!({"disconnect": conn.0}),
        ControlBody::List => json!("list"),
        ControlBody::Why { behavior, port } => json!({"why": {"behavior": &**behavior, "port": &**port}}),
        ControlBody::Read { behavior, port } => json!({"read": {"behavior": &**behavior, "port": &**port}}),
        ControlBody::Prepare { txn, changes, hold } => json!({"prepare": {"txn": txn,
            "changes": changes.iter().map(change_json).collect::<Vec<_>>(), "hold": to_json(hold)}}),
        ControlBody::Commit { txn, delay } => json!({"commit": {"txn": txn, "delay": to_json(delay)}}),
        ControlBody::Abort { txn } => json!({"abort": {"txn": txn}}),
        ControlBody::Reply { result } => json!({"reply": to_json(result)}),
    }
}

/// A structure change ([`Change`]) as a JSON object: `{"op": "connect", ...}`.
pub fn change_json(c: &Change) -> Json {
    match c {
        Change::Create { class, name } => json!({"op": "create", "class": class, "behavior": name}),
        Change::Remove { name } => json!({"op": "remove", "behavior": name}),
        Change::Connect { source, destination, kind, priority } => json!({"op": "connect",
            "source": to_json(source), "destination": to_json(destination), "kind": to_json(kind),
            "priority": priority}),
        Change::Disconnect { conn } => json!({"op": "disconnect", "conn": conn.0}),
        Change::DisconnectBetween { source, destination } => json!({"op": "disconnect_between",
            "source": to_json(source), "destination": to_json(destination)}),
        Change::Join { group } => json!({"op": "join", "group": group}),
        Change::Leave { group } => json!({"op": "leave", "group": group}),
        Change::BleJoin { behavior, config } => json!({"op": "ble_join", "behavior": behavior,
            "group": config.group, "output": config.output, "claim_rate_hz": float_json(config.claim_rate_hz),
            "inhibit_period": to_json(&config.inhibit_period), "network_delay": to_json(&config.network_delay)}),
    }
}

/// The change [`change_json`] wrote as `f`.
fn change_from(f: &Fields<'_>) -> Result<Change, String> {
    Ok(match f.str("op")?.as_str() {
        "create" => Change::Create { class: f.str("class")?, name: f.str("behavior")? },
        "remove" => Change::Remove { name: f.str("behavior")? },
        "connect" => Change::Connect {
            source: f.serde("source")?,
            destination: f.serde("destination")?,
            kind: f.serde("kind")?,
            priority: f.i32("priority")?,
        },
        "disconnect" => Change::Disconnect { conn: ConnectionId(f.u64("conn")?) },
        "disconnect_between" => {
            Change::DisconnectBetween { source: f.serde("source")?, destination: f.serde("destination")? }
        }
        "join" => Change::Join { group: f.str("group")? },
        "leave" => Change::Leave { group: f.str("group")? },
        "ble_join" => Change::BleJoin {
            behavior: f.str("behavior")?,
            config: BleConfig {
                group: f.str("group")?,
                output: f.str("output")?,
                claim_rate_hz: float_from(f.get("claim_rate_hz")?)?,
                inhibit_period: f.serde("inhibit_period")?,
                network_delay: f.serde("network_delay")?,
            },
        },
        other => return Err(format!("unknown change `{other}`")),
    })
}

/// Whether a `request` entry is a process's effect (it says so: `"by": "process"`).
fn topic_is_process(f: &Fields<'_>) -> bool {
    f.0.get("by").and_then(Json::as_str) == Some("process")
}

/// The JSON object of a checkpoint taken before journal entry number `seq`.
pub fn encode_checkpoint(seq: u64, snapshot: &ayllu_core::Snapshot) -> Json {
    json!({
        "seq": seq,
        "t_ns": snapshot.at().as_nanos(),
        "t": snapshot.at().as_secs_f64(),
        "event": "checkpoint",
        "version": ayllu_core::SNAPSHOT_VERSION,
        "snapshot": serde_json::to_value(snapshot).unwrap_or(Json::Null),
    })
}

/// The checkpoint [`encode_checkpoint`] wrote as `j`: the journal position it was taken
/// before, and the snapshot. Errors name what is wrong.
pub fn decode_checkpoint(j: &Json) -> Result<(u64, ayllu_core::Snapshot), String> {
    let f = Fields(j.as_object().ok_or("a checkpoint is not a JSON object")?);
    let seq = f.u64("seq")?;
    let snapshot = f.serde::<ayllu_core::Snapshot>("snapshot")?;
    Ok((seq, snapshot))
}

/// The topic and JSON object of journal entry number `seq`.
pub fn encode(seq: u64, entry: &Entry) -> (Topic, Json) {
    let mut m = Map::new();
    m.insert("seq".into(), json!(seq));
    m.insert("t_ns".into(), json!(entry.at.as_nanos()));
    m.insert("t".into(), json!(entry.at.as_secs_f64()));
    let mut put = |k: &str, v: Json| {
        m.insert(k.to_owned(), v);
    };
    let (topic, event) = match &entry.event {
        Event::Define(c) => {
            put("class", class_json(c));
            (Topic::Structure, "define")
        }
        Event::Create { class, name } => {
            put("class", json!(class));
            put("behavior", json!(name));
            (Topic::Structure, "create")
        }
        Event::Remove { name } => {
            put("behavior", json!(name));
            (Topic::Structure, "remove")
        }
        Event::AddProcess { behavior, name, trigger } => {
            put("behavior", json!(behavior));
            put("process", json!(name));
            put("trigger", to_json(trigger));
            (Topic::Structure, "add_process")
        }
        Event::Connect { source, destination, kind, priority } => {
            put("source", to_json(source));
            put("destination", to_json(destination));
            put("kind", to_json(kind));
            put("priority", json!(priority));
            (Topic::Structure, "connect")
        }
        Event::Disconnect { conn } => {
            put("conn", json!(conn.0));
            (Topic::Structure, "disconnect")
        }
        Event::NodeLost { node } => {
            put("node", json!(node.0));
            (Topic::Structure, "node_lost")
        }
        Event::SetAccess(a) => {
            put("ports", allow_json(&a.ports));
            put("structure", allow_json(&a.structure));
            (Topic::Structure, "set_access")
        }
        Event::SetLimits(l) => {
            put("remote_connections", json!(l.remote_connections));
            put("remote_connections_per_node", json!(l.remote_connections_per_node));
            put("max_remote_period", to_json(&l.max_remote_period));
            put("requests_per_second", json!(l.requests_per_second));
            put("requests_burst", json!(l.requests_burst));
            (Topic::Structure, "set_limits")
        }
        Event::Join(g) => {
            put("group", json!(g));
            (Topic::Structure, "join")
        }
        Event::Leave(g) => {
            put("group", json!(g));
            (Topic::Structure, "leave")
        }
        Event::BleJoin { behavior, config } => {
            put("behavior", json!(behavior));
            put("group", json!(config.group));
            put("output", json!(config.output));
            put("claim_rate_hz", float_json(config.claim_rate_hz));
            put("inhibit_period", to_json(&config.inhibit_period));
            put("network_delay", to_json(&config.network_delay));
            (Topic::Structure, "ble_join")
        }
        Event::SequenceBase(b) => {
            put("base", json!(b));
            (Topic::Structure, "sequence_base")
        }
        Event::Warn(w) => {
            put("warning", json!(w));
            (Topic::Structure, "warn")
        }
        Event::Request { to, body } => {
            put("to", json!(to.0));
            put("body", body_json(body));
            (Topic::Structure, "request")
        }
        Event::Gap { lost } => {
            put("lost", json!(lost));
            (Topic::Structure, "gap")
        }
        Event::Write { behavior, class, port, value } => {
            put("behavior", json!(&**behavior));
            put("port", json!(class.ports().get(usize::from(*port)).map_or("", |p| p.name.as_str())));
            put("port_index", json!(port));
            let (ty, v) = typed(value);
            put("type", ty);
            put("value", v);
            (Topic::Input, "write")
        }
        Event::Trigger { behavior, mono, period } => {
            put("behavior", json!(behavior));
            put("mono", json!(mono));
            put("period", to_json(period));
            (Topic::Input, "trigger")
        }
        Event::Reset { behavior, port } => {
            put("behavior", json!(&**behavior));
            put("port", json!(port));
            (Topic::Input, "reset")
        }
        Event::Receive { from, message } => {
            put("from", json!(from.0));
            put("message", message_json(message));
            (Topic::Input, "receive")
        }
        Event::Poll => (Topic::Input, "poll"),
        Event::Run { behavior, process, native } => {
            put("behavior", json!(&**behavior));
            put("process", json!(process));
            put("native", json!(native));
            (Topic::Process, "run")
        }
        Event::ProcessWrite { port, value } => {
            put("port_index", json!(port));
            let (ty, v) = typed(value);
            put("type", ty);
            put("value", v);
            (Topic::Process, "write")
        }
        Event::ProcessSetSlot { slot, value } => {
            put("slot_index", json!(slot));
            let (ty, v) = typed(value);
            put("type", ty);
            put("value", v);
            (Topic::Process, "set_slot")
        }
        Event::ProcessTrigger { mono, period } => {
            put("mono_index", json!(mono));
            put("period", to_json(period));
            (Topic::Process, "trigger")
        }
        Event::ProcessReset { port } => {
            put("port_index", json!(port));
            (Topic::Process, "reset")
        }
        Event::ProcessChange(change) => {
            put("change", change_json(change));
            (Topic::Process, "change")
        }
        Event::ProcessRequest { to, body } => {
            put("to", json!(to.0));
            put("body", body_json(body));
            put("by", json!("process"));
            (Topic::Process, "request")
        }
        Event::Accepted { behavior, class, port, value } => {
            put("behavior", json!(&**behavior));
            put("port", json!(class.ports().get(usize::from(*port)).map_or("", |p| p.name.as_str())));
            put("port_index", json!(port));
            let (ty, v) = typed(value);
            put("type", ty);
            put("value", v);
            (Topic::Accepted, "accepted")
        }
    };
    m.insert("event".into(), json!(event));
    (topic, Json::Object(m))
}

/// Reads the fields of one message, naming the field at fault.
struct Fields<'a>(&'a Map<String, Json>);

impl Fields<'_> {
    fn get(&self, k: &str) -> Result<&Json, String> {
        self.0.get(k).ok_or_else(|| format!("no field `{k}`"))
    }
    fn str(&self, k: &str) -> Result<String, String> {
        self.get(k)?.as_str().map(str::to_owned).ok_or_else(|| format!("`{k}` is not text"))
    }
    fn u64(&self, k: &str) -> Result<u64, String> {
        self.get(k)?.as_u64().ok_or_else(|| format!("`{k}` is not a count"))
    }
    fn u16(&self, k: &str) -> Result<u16, String> {
        u16::try_from(self.u64(k)?).map_err(|_| format!("`{k}` is out of range"))
    }
    fn u32(&self, k: &str) -> Result<u32, String> {
        u32::try_from(self.u64(k)?).map_err(|_| format!("`{k}` is out of range"))
    }
    fn i32(&self, k: &str) -> Result<i32, String> {
        self.get(k)?.as_i64().and_then(|x| i32::try_from(x).ok()).ok_or_else(|| format!("`{k}` is not an i32"))
    }
    fn serde<T: DeserializeOwned>(&self, k: &str) -> Result<T, String> {
        serde_json::from_value(self.get(k)?.clone()).map_err(|e| format!("`{k}`: {e}"))
    }
    fn value(&self) -> Result<Value, String> {
        value_from(&self.str("type")?, self.get("value")?)
    }
    fn object(&self, k: &str) -> Result<Fields<'_>, String> {
        self.get(k)?.as_object().map(Fields).ok_or_else(|| format!("`{k}` is not an object"))
    }
}

fn class_from(f: &Fields<'_>) -> Result<BehaviorClass, String> {
    let mut c = BehaviorClass::new(&f.str("name")?);
    let implicit = c.ports().len();
    let list = |k: &str| f.get(k)?.as_array().ok_or_else(|| format!("`{k}` is not a list"));
    for (i, p) in list("ports")?.iter().enumerate() {
        let p = Fields(p.as_object().ok_or("a port is not an object")?);
        let default = value_from(&p.str("type")?, p.get("default")?)?;
        let spec = PortSpec {
            name: p.str("name")?,
            kind: p.serde::<PortKind>("kind")?,
            default,
            lifespan: p.serde::<Option<Duration>>("lifespan")?,
            window: p.serde::<Option<Duration>>("window")?,
        };
        // The implicit BLE ports come with every class (rule S11).
        if i >= implicit {
            c.port(spec).map_err(|e| e.to_string())?;
        }
    }
    for s in list("slots")? {
        let s = Fields(s.as_object().ok_or("a slot is not an object")?);
        c.slot(&s.str("name")?, value_from(&s.str("type")?, s.get("default")?)?).map_err(|e| e.to_string())?;
    }
    for m in list("monostables")? {
        c.monostable(m.as_str().ok_or("a monostable is not a name")?).map_err(|e| e.to_string())?;
    }
    for p in list("processes")? {
        let p = Fields(p.as_object().ok_or("a process is not an object")?);
        // The body is the application's code: a replay puts a player in its place.
        c.process(&p.str("name")?, p.serde::<Trigger>("trigger")?, |_| {}).map_err(|e| e.to_string())?;
    }
    Ok(c)
}

fn body_from(j: &Json) -> Result<ControlBody, String> {
    if j.as_str() == Some("list") {
        return Ok(ControlBody::List);
    }
    let o = Fields(j.as_object().ok_or("a control body is not an object")?);
    let names = |k: &str| -> Result<(Arc<str>, Arc<str>), String> {
        let x = o.object(k)?;
        Ok((Arc::from(x.str("behavior")?), Arc::from(x.str("port")?)))
    };
    if let Ok(c) = o.object("connect") {
        return Ok(ControlBody::Connect {
            source_behavior: Arc::from(c.str("source_behavior")?),
            source_port: Arc::from(c.str("source_port")?),
            destination: c.serde::<Endpoint>("destination")?,
            kind: c.serde::<ConnectionKind>("kind")?,
            priority: c.i32("priority")?,
        });
    }
    if o.0.contains_key("disconnect") {
        return Ok(ControlBody::Disconnect { conn: ConnectionId(o.u64("disconnect")?) });
    }
    if o.0.contains_key("why") {
        let (behavior, port) = names("why")?;
        return Ok(ControlBody::Why { behavior, port });
    }
    if o.0.contains_key("read") {
        let (behavior, port) = names("read")?;
        return Ok(ControlBody::Read { behavior, port });
    }
    if let Ok(p) = o.object("prepare") {
        let list = p.get("changes")?.as_array().ok_or("`changes` is not a list")?;
        let changes: Result<Vec<Change>, String> =
            list.iter().map(|c| change_from(&Fields(c.as_object().ok_or("a change is not an object")?))).collect();
        return Ok(ControlBody::Prepare { txn: p.u64("txn")?, changes: changes?, hold: p.serde("hold")? });
    }
    if let Ok(c) = o.object("commit") {
        return Ok(ControlBody::Commit { txn: c.u64("txn")?, delay: c.serde("delay")? });
    }
    if let Ok(a) = o.object("abort") {
        return Ok(ControlBody::Abort { txn: a.u64("txn")? });
    }
    if o.0.contains_key("reply") {
        return Ok(ControlBody::Reply { result: o.serde::<Result<ReplyBody, String>>("reply")? });
    }
    Err("unknown control body".into())
}

fn message_from(j: &Json) -> Result<Message, String> {
    let o = Fields(j.as_object().ok_or("a message is not an object")?);
    if let Ok(p) = o.object("port_message") {
        return Ok(Message::Port(PortMessage {
            conn: ConnectionId(p.u64("conn")?),
            seq: p.u64("seq")?,
            behavior: Arc::from(p.str("behavior")?),
            port: Arc::from(p.str("port")?),
            kind: p.serde::<ConnectionKind>("kind")?,
            priority: p.i32("priority")?,
            value: p.value()?,
        }));
    }
    let c = o.object("control")?;
    Ok(Message::Control(ControlMessage { id: c.u64("id")?, body: body_from(c.get("body")?)? }))
}

/// One decoded message: its place in the journal, and the entry.
#[derive(Clone, Debug)]
pub struct Decoded {
    /// The `seq` it was written with.
    pub seq: u64,
    /// The entry. An `Accepted` entry's class is a stand-in that names no ports: the port is
    /// known by its handle (the replayed node knows its name).
    pub entry: Entry,
}

/// The entry [`encode`] wrote as `j`; errors name what is wrong.
pub fn decode(j: &Json) -> Result<Decoded, String> {
    let f = Fields(j.as_object().ok_or("a message is not a JSON object")?);
    let seq = f.u64("seq")?;
    let at = Instant::from_nanos(f.u64("t_ns")?);
    let event = match f.str("event")?.as_str() {
        "define" => Event::Define(Arc::new(class_from(&f.object("class")?)?)),
        "create" => Event::Create { class: f.str("class")?, name: f.str("behavior")? },
        "remove" => Event::Remove { name: f.str("behavior")? },
        "add_process" => {
            Event::AddProcess { behavior: f.str("behavior")?, name: f.str("process")?, trigger: f.serde("trigger")? }
        }
        "connect" => Event::Connect {
            source: f.serde("source")?,
            destination: f.serde("destination")?,
            kind: f.serde("kind")?,
            priority: f.i32("priority")?,
        },
        "disconnect" => Event::Disconnect { conn: ConnectionId(f.u64("conn")?) },
        "node_lost" => Event::NodeLost { node: NodeId(f.u32("node")?) },
        "set_access" => Event::SetAccess(Access {
            ports: allow_from(f.get("ports")?)?,
            structure: allow_from(f.get("structure")?)?,
        }),
        "set_limits" => Event::SetLimits(Limits {
            remote_connections: f.u64("remote_connections")? as usize,
            remote_connections_per_node: f.u64("remote_connections_per_node")? as usize,
            max_remote_period: f.serde("max_remote_period")?,
            requests_per_second: f.u32("requests_per_second")?,
            requests_burst: f.u32("requests_burst")?,
        }),
        "join" => Event::Join(f.str("group")?),
        "leave" => Event::Leave(f.str("group")?),
        "ble_join" => Event::BleJoin {
            behavior: f.str("behavior")?,
            config: Box::new(BleConfig {
                group: f.str("group")?,
                output: f.str("output")?,
                claim_rate_hz: float_from(f.get("claim_rate_hz")?)?,
                inhibit_period: f.serde("inhibit_period")?,
                network_delay: f.serde("network_delay")?,
            }),
        },
        "sequence_base" => Event::SequenceBase(f.u64("base")?),
        "warn" => Event::Warn(f.str("warning")?),
        "change" => Event::ProcessChange(Box::new(change_from(&f.object("change")?)?)),
        "request" if topic_is_process(&f) => {
            Event::ProcessRequest { to: NodeId(f.u32("to")?), body: Box::new(body_from(f.get("body")?)?) }
        }
        "request" => Event::Request { to: NodeId(f.u32("to")?), body: Box::new(body_from(f.get("body")?)?) },
        "gap" => Event::Gap { lost: f.u64("lost")? },
        // A process's write names no behavior (it is the running one's).
        "write" if !f.0.contains_key("behavior") => {
            Event::ProcessWrite { port: f.u16("port_index")?, value: f.value()? }
        }
        "write" => Event::Write {
            behavior: Arc::from(f.str("behavior")?),
            class: Arc::new(BehaviorClass::new("")),
            port: f.u16("port_index")?,
            value: f.value()?,
        },
        "trigger" if f.0.contains_key("mono_index") => {
            Event::ProcessTrigger { mono: f.u16("mono_index")?, period: f.serde("period")? }
        }
        "trigger" => Event::Trigger { behavior: f.str("behavior")?, mono: f.str("mono")?, period: f.serde("period")? },
        "reset" if f.0.contains_key("port_index") => Event::ProcessReset { port: f.u16("port_index")? },
        "reset" => Event::Reset { behavior: Arc::from(f.str("behavior")?), port: f.str("port")? },
        "receive" => {
            Event::Receive { from: NodeId(f.u32("from")?), message: Box::new(message_from(f.get("message")?)?) }
        }
        "poll" => Event::Poll,
        "run" => Event::Run {
            behavior: Arc::from(f.str("behavior")?),
            process: f.str("process")?,
            native: f.get("native")?.as_bool().ok_or("`native` is not a bool")?,
        },
        "set_slot" => Event::ProcessSetSlot { slot: f.u16("slot_index")?, value: f.value()? },
        "accepted" => Event::Accepted {
            behavior: Arc::from(f.str("behavior")?),
            class: Arc::new(BehaviorClass::new("")),
            port: f.u16("port_index")?,
            value: f.value()?,
        },
        other => return Err(format!("unknown event `{other}`")),
    };
    Ok(Decoded { seq, entry: Entry { at, event } })
}

/// Whether two values are the same bit for bit (floats by their bits: `-0.0` is not `0.0`,
/// and a NaN is itself).
pub fn same_bits(a: &Value, b: &Value) -> bool {
    match (a, b) {
        (Value::Float(x), Value::Float(y)) => x.to_bits() == y.to_bits(),
        (Value::Vector(x), Value::Vector(y)) => {
            x.len() == y.len() && x.iter().zip(y.iter()).all(|(x, y)| x.to_bits() == y.to_bits())
        }
        _ => a == b,
    }
}
