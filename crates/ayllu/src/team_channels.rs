//! The team's channel layout: how a port's values are named and shaped when they leave the
//! team for a recording (`ayllu record`, the simulator's MCAP) or a live viewer (`ayllu
//! foxglove`). Every producer uses this module, so a Foxglove layout made on one file works
//! on another and on the live team. The layout is specified in `spec/recording.md`, "Team
//! channels".
//!
//! Promises:
//! * one channel per port that sends, named by the port's owner: topic `/n{node}/{behavior}/
//!   {port}` ([`PortChannel::topic`]), parsed back by [`PortChannel::parse_topic`];
//! * messages are JSON objects (`json` message encoding) described by a JSON Schema
//!   (`jsonschema` schema encoding) that depends only on the port's value type, so Foxglove's
//!   plot panel can plot `/n1/OBS1/Local.value` with no conversion;
//! * [`value_json`] and [`value_from_json`] are inverses for every value, NaN and the
//!   infinities included (written `"NaN"`, `"inf"`, `"-inf"`, as the core's serde form does);
//! * pure functions: no I/O, no clock.

use std::collections::BTreeMap;

use ayllu_core::{ConnectionKind, Endpoint, NodeId, Value, ValueType};
use serde_json::{json, Map, Value as Json};

/// The MCAP message encoding of every team channel.
pub const MESSAGE_ENCODING: &str = "json";
/// The MCAP schema encoding of every team channel's schema.
pub const SCHEMA_ENCODING: &str = "jsonschema";
/// The MCAP profile written in a recording's header (none of the registered profiles fits).
pub const PROFILE: &str = "ayllu";

/// One port of one node, as a channel: the sender's port, whatever connection carried it.
#[derive(Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct PortChannel {
    /// The node that owns the port.
    pub node: NodeId,
    /// The behavior instance (`OBS1`).
    pub behavior: String,
    /// The port (`Local`).
    pub port: String,
    /// The port's value type (rule S1: fixed for the port's life).
    pub ty: ValueType,
}

/// How a recorded value travelled: the connection that carried it from the channel's port.
/// Live viewers and simulators that read ports directly leave it out.
#[derive(Clone, Debug, PartialEq)]
pub struct Via {
    /// The connection's id on the sending node.
    pub conn: u64,
    /// Its sequence number (N1): gaps show lost messages.
    pub seq: u64,
    /// The connection's kind and period.
    pub kind: ConnectionKind,
    /// The connection's priority (D3.3).
    pub priority: i32,
    /// Where it goes, as `list NODE` writes it (`n2:OBS1.Best`, `*Peers:OBS1.Best`), when
    /// known.
    pub to: Option<String>,
}

/// Names in topics: `/` separates levels, so a name's own `/` (and the escape `%`) are
/// percent-encoded. Behavior and port names are identifiers in practice; this keeps any name
/// a single level.
fn escape(name: &str) -> String {
    name.replace('%', "%25").replace('/', "%2F")
}

fn unescape(level: &str) -> String {
    level.replace("%2F", "/").replace("%2f", "/").replace("%25", "%")
}

impl PortChannel {
    /// A channel for `node`'s `behavior.port` holding values of `ty`.
    pub fn new(node: NodeId, behavior: &str, port: &str, ty: ValueType) -> PortChannel {
        PortChannel { node, behavior: behavior.to_owned(), port: port.to_owned(), ty }
    }

    /// `/n{node}/{behavior}/{port}`, node in decimal: `/n1/OBS1/Local`.
    pub fn topic(&self) -> String {
        format!("/n{}/{}/{}", self.node.0, escape(&self.behavior), escape(&self.port))
    }

    /// The node, behavior and port a team topic names; `None` for topics outside the layout
    /// (other producers' topics, such as the simulator's `/sim/...`).
    pub fn parse_topic(topic: &str) -> Option<(NodeId, String, String)> {
        let mut levels = topic.strip_prefix("/n")?.split('/');
        let node = levels.next()?;
        if node.is_empty() || !node.bytes().all(|b| b.is_ascii_digit()) {
            return None;
        }
        let node = NodeId(node.parse().ok()?);
        let (behavior, port) = (levels.next()?, levels.next()?);
        if behavior.is_empty() || port.is_empty() || levels.next().is_some() {
            return None;
        }
        Some((node, unescape(behavior), unescape(port)))
    }

    /// The schema's name: `ayllu.PortValue.{type}` (`ayllu.PortValue.float`). Channels of one
    /// type share one schema.
    pub fn schema_name(&self) -> String {
        schema_name(self.ty)
    }

    /// The channel's JSON Schema, as text.
    pub fn schema(&self) -> String {
        schema(self.ty)
    }

    /// MCAP channel metadata: `node` (decimal), `behavior`, `port`, `type`.
    pub fn metadata(&self) -> BTreeMap<String, String> {
        BTreeMap::from([
            ("node".to_owned(), self.node.0.to_string()),
            ("behavior".to_owned(), self.behavior.clone()),
            ("port".to_owned(), self.port.clone()),
            ("type".to_owned(), self.ty.name().to_owned()),
        ])
    }

    /// One message on this channel: `{"node":1,"behavior":"OBS1","port":"Local",
    /// "type":"float","value":0.6}`, plus `"via":{...}` when the value was heard on a
    /// connection.
    pub fn message(&self, value: &Value, via: Option<&Via>) -> Json {
        let mut m = Map::new();
        m.insert("node".into(), json!(self.node.0));
        m.insert("behavior".into(), json!(self.behavior));
        m.insert("port".into(), json!(self.port));
        m.insert("type".into(), json!(self.ty.name()));
        m.insert("value".into(), value_json(value));
        if let Some(via) = via {
            m.insert(
                "via".into(),
                json!({
                    "conn": via.conn,
                    "seq": via.seq,
                    "kind": via.kind.name(),
                    "period": via.kind.period().map(|p| p.as_secs_f64()),
                    "priority": via.priority,
                    "to": via.to,
                }),
            );
        }
        Json::Object(m)
    }

    /// [`PortChannel::message`] as the bytes an MCAP message or a WebSocket frame carries.
    pub fn message_bytes(&self, value: &Value, via: Option<&Via>) -> Vec<u8> {
        self.message(value, via).to_string().into_bytes()
    }
}

/// The channel a message of the layout belongs to and its value, from the message's JSON.
pub fn parse_message(bytes: &[u8]) -> Option<(PortChannel, Value)> {
    let j: Json = serde_json::from_slice(bytes).ok()?;
    let node = NodeId(u32::try_from(j.get("node")?.as_u64()?).ok()?);
    let ty = value_type(j.get("type")?.as_str()?)?;
    let channel = PortChannel::new(node, j.get("behavior")?.as_str()?, j.get("port")?.as_str()?, ty);
    let value = value_from_json(ty, j.get("value")?)?;
    Some((channel, value))
}

/// The value type named as [`ValueType::name`] writes it (`float`).
pub fn value_type(name: &str) -> Option<ValueType> {
    [ValueType::Bool, ValueType::Int, ValueType::Float, ValueType::Text, ValueType::Bytes, ValueType::Vector]
        .into_iter()
        .find(|t| t.name() == name)
}

/// A float as the layout writes it: a number, or `"NaN"`, `"inf"`, `"-inf"`.
pub(crate) fn float_json(x: f64) -> Json {
    if x.is_finite() {
        json!(x)
    } else if x.is_nan() {
        json!("NaN")
    } else if x > 0.0 {
        json!("inf")
    } else {
        json!("-inf")
    }
}

/// The float [`float_json`] wrote as `j`.
pub(crate) fn float_from_json(j: &Json) -> Option<f64> {
    match j {
        Json::Number(n) => n.as_f64(),
        Json::String(s) => match s.as_str() {
            "NaN" => Some(f64::NAN),
            "inf" => Some(f64::INFINITY),
            "-inf" => Some(f64::NEG_INFINITY),
            _ => None,
        },
        _ => None,
    }
}

/// A value as the layout writes it: bool, integer, number (`"NaN"`, `"inf"`, `"-inf"` when not
/// finite), string, bytes as lowercase hex, vector as an array of numbers.
pub fn value_json(v: &Value) -> Json {
    match v {
        Value::Bool(b) => json!(b),
        Value::Int(i) => json!(i),
        Value::Float(x) => float_json(*x),
        Value::Text(s) => json!(&**s),
        Value::Bytes(b) => json!(b.iter().map(|x| format!("{x:02x}")).collect::<String>()),
        Value::Vector(xs) => Json::Array(xs.iter().map(|x| float_json(*x)).collect()),
    }
}

/// The value of type `ty` that [`value_json`] wrote as `j`; `None` if `j` is not one.
pub fn value_from_json(ty: ValueType, j: &Json) -> Option<Value> {
    Some(match ty {
        ValueType::Bool => Value::Bool(j.as_bool()?),
        ValueType::Int => Value::Int(j.as_i64()?),
        ValueType::Float => Value::Float(float_from_json(j)?),
        ValueType::Text => Value::text(j.as_str()?),
        ValueType::Bytes => {
            let hex = j.as_str()?;
            if hex.len() % 2 != 0 || !hex.is_ascii() {
                return None;
            }
            let bytes: Option<Vec<u8>> =
                (0..hex.len()).step_by(2).map(|i| u8::from_str_radix(&hex[i..i + 2], 16).ok()).collect();
            Value::bytes(&bytes?)
        }
        ValueType::Vector => {
            let xs: Option<Vec<f64>> = j.as_array()?.iter().map(float_from_json).collect();
            Value::vector(&xs?)
        }
    })
}

/// `ayllu.PortValue.{type}`.
pub fn schema_name(ty: ValueType) -> String {
    format!("ayllu.PortValue.{}", ty.name())
}

/// The JSON Schema of a port value message of type `ty`, as text.
pub fn schema(ty: ValueType) -> String {
    let not_finite = json!({"type": "string", "enum": ["NaN", "inf", "-inf"]});
    let value = match ty {
        ValueType::Bool => json!({"type": "boolean"}),
        ValueType::Int => json!({"type": "integer"}),
        ValueType::Float => json!({"anyOf": [{"type": "number"}, not_finite]}),
        ValueType::Text => json!({"type": "string"}),
        ValueType::Bytes => json!({"type": "string", "pattern": "^([0-9a-f]{2})*$", "description": "hex"}),
        ValueType::Vector => json!({"type": "array", "items": {"anyOf": [{"type": "number"}, not_finite]}}),
    };
    json!({
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": schema_name(ty),
        "description": "One value sent by an Ayllu port (spec/recording.md, Team channels)",
        "type": "object",
        "properties": {
            "node": {"type": "integer", "minimum": 0, "description": "the node that owns the port"},
            "behavior": {"type": "string"},
            "port": {"type": "string"},
            "type": {"const": ty.name()},
            "value": value,
            "via": {
                "type": "object",
                "description": "the connection that carried the value, when recorded from the network",
                "properties": {
                    "conn": {"type": "integer"},
                    "seq": {"type": "integer"},
                    "kind": {"type": "string"},
                    "period": {"type": ["number", "null"], "description": "seconds"},
                    "priority": {"type": "integer"},
                    "to": {"type": ["string", "null"]}
                }
            }
        },
        "required": ["node", "behavior", "port", "type", "value"]
    })
    .to_string()
}

/// Where a connection goes, as the `to` of [`Via`]: `n2:OBS1.Best`, `*Peers:OBS1.Best`, or
/// `n{owner}:B.P` for a local destination.
pub fn destination_text(owner: NodeId, destination: &Endpoint) -> String {
    match destination {
        Endpoint::Local { behavior, port } => format!("{owner}:{behavior}.{port}"),
        other => other.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn topics_name_the_owner_and_parse_back() {
        let c = PortChannel::new(NodeId(1), "OBS1", "Local", ValueType::Float);
        assert_eq!(c.topic(), "/n1/OBS1/Local");
        assert_eq!(PortChannel::parse_topic("/n1/OBS1/Local"), Some((NodeId(1), "OBS1".into(), "Local".into())));
        let odd = PortChannel::new(NodeId(7), "a/b%", "p", ValueType::Int);
        assert_eq!(odd.topic(), "/n7/a%2Fb%25/p");
        assert_eq!(PortChannel::parse_topic(&odd.topic()), Some((NodeId(7), "a/b%".into(), "p".into())));
        for other in ["/sim/robots", "/n/OBS1/Local", "/nx/A/B", "/n1/A", "/n1/A/B/C", "n1/A/B", "/n1//B"] {
            assert_eq!(PortChannel::parse_topic(other), None, "{other}");
        }
    }

    #[test]
    fn values_round_trip_through_json() {
        let values = [
            Value::Bool(true),
            Value::Int(-3),
            Value::Float(0.1),
            Value::Float(f64::NAN),
            Value::Float(f64::NEG_INFINITY),
            Value::text("hi"),
            Value::bytes(&[0, 0xab, 0xff]),
            Value::vector(&[1.0, f64::INFINITY, -2.5]),
        ];
        for v in values {
            let back = value_from_json(v.ty(), &value_json(&v)).unwrap();
            assert!(back == v || (v.is_nan() && back.is_nan()), "{v:?} -> {back:?}");
        }
        assert_eq!(value_json(&Value::Float(f64::NAN)), json!("NaN"));
        assert_eq!(value_from_json(ValueType::Bytes, &json!("abc")), None);
        assert_eq!(value_from_json(ValueType::Int, &json!(0.5)), None);
    }

    #[test]
    fn messages_carry_the_channel_and_parse_back() {
        let c = PortChannel::new(NodeId(2), "OBS1", "Local", ValueType::Float);
        let via = Via {
            conn: 20,
            seq: 5,
            kind: ConnectionKind::Normal,
            priority: 0,
            to: Some(destination_text(NodeId(2), &Endpoint::group("Peers", "OBS1", "Best"))),
        };
        let j = c.message(&Value::Float(0.6), Some(&via));
        assert_eq!(j["value"], json!(0.6));
        assert_eq!(j["via"]["to"], json!("*Peers:OBS1.Best"));
        assert_eq!(j["via"]["period"], Json::Null);
        let (back, v) = parse_message(&c.message_bytes(&Value::Float(0.6), None)).unwrap();
        assert_eq!((back, v), (c, Value::Float(0.6)));
    }

    #[test]
    fn schemas_are_json_and_name_their_type() {
        for ty in
            [ValueType::Bool, ValueType::Int, ValueType::Float, ValueType::Text, ValueType::Bytes, ValueType::Vector]
        {
            let s: Json = serde_json::from_str(&schema(ty)).unwrap();
            assert_eq!(s["title"], json!(schema_name(ty)));
            assert_eq!(s["properties"]["type"]["const"], json!(ty.name()));
            assert_eq!(value_type(ty.name()), Some(ty));
        }
    }
}
