//! The team -> channels bridge: what a node's reports become on Foxglove channels. Both the
//! live server (`team_watch`) and the simulator's MCAP writer (`sim_mcap`) publish through it,
//! so a layout made on a recording works on the live team and back.
//!
//! Promises:
//! * port values follow the team channel layout (`ayllu::team_channels`, spec/recording.md
//!   "Team channels"): topic `/n{node}/{behavior}/{port}`, JSON messages with the layout's
//!   JSON Schema, so they are the channels `ayllu record` writes;
//! * windows and BLE claims, which the layout does not cover, get channels of their own
//!   (docs/cli.md, "ayllu foxglove"): `/n{node}/{behavior}/{port}/windows` (schema
//!   `ayllu.PortWindows`) and `/ble/{behavior}` (schema `ayllu.BleClaims`), JSON too, shaped
//!   so that the plot panel can plot them (`.open`, `.remaining.suppress`, `.claimer`);
//! * one channel per topic for the bridge's life: a channel is made the first time its topic
//!   is published and then reused (a port's type never changes, rule S1);
//! * nothing here does I/O itself: messages go to the sinks of the [`Context`] given (a
//!   WebSocket server, an MCAP file), stamped with the log time the caller passes.

use std::collections::{BTreeMap, HashMap};
use std::sync::Arc;

use ayllu::team_channels::{self, PortChannel};
use ayllu_core::{
    BehaviorReport, NodeId, NodeReport, PortReport, RegisterReport, Value, WindowKind, BEST, BLE_SELECT, INHIBIT, LOCAL,
};
use foxglove::{ChannelBuilder, Context, PartialMetadata, RawChannel, Schema};
use serde_json::{json, Value as Json};

/// The schema of the windows channels.
pub const WINDOWS_SCHEMA: &str = "ayllu.PortWindows";
/// The schema of the BLE claims channels.
pub const CLAIMS_SCHEMA: &str = "ayllu.BleClaims";

/// Every window kind, in the order messages list them.
const KINDS: [WindowKind; 5] = [
    WindowKind::Suppress,
    WindowKind::Inhibit,
    WindowKind::WriteInhibit,
    WindowKind::OverrideIn,
    WindowKind::OverrideOut,
];

/// The windows topic of `node`'s `behavior.port`: its value topic and `/windows`.
pub fn windows_topic(node: NodeId, behavior: &str, port: &str) -> String {
    // The value type plays no part in the topic; any will do.
    format!("{}/windows", PortChannel::new(node, behavior, port, ayllu_core::ValueType::Bool).topic())
}

/// The BLE claims topic of a layer (`/ble/OBS1`).
pub fn claims_topic(behavior: &str) -> String {
    format!("/ble/{}", behavior.replace('%', "%25").replace('/', "%2F"))
}

/// Who claims one BLE layer (a behavior name shared by the members of a group) at one time.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LayerClaims {
    /// The layer's behavior (`OBS1`).
    pub behavior: String,
    /// Its BLE group (`Peers`), when known.
    pub group: Option<String>,
    /// The nodes seen claiming it (normally one; two during a hand-over or a partition).
    pub claimers: Vec<NodeId>,
    /// The members whose standing is known (their claims were asked or simulated).
    pub members: Vec<NodeId>,
}

/// Publishes a team's reports on the channels of one [`Context`].
pub struct TeamBridge {
    ctx: Arc<Context>,
    channels: HashMap<String, Arc<RawChannel>>,
    published: u64,
}

impl TeamBridge {
    /// A bridge publishing on `ctx`'s sinks.
    pub fn new(ctx: &Arc<Context>) -> TeamBridge {
        TeamBridge { ctx: ctx.clone(), channels: HashMap::new(), published: 0 }
    }

    /// Topics made so far.
    pub fn topics(&self) -> usize {
        self.channels.len()
    }

    /// Messages published so far.
    pub fn published(&self) -> u64 {
        self.published
    }

    fn publish(
        &mut self,
        topic: String,
        schema: impl FnOnce() -> (String, String, BTreeMap<String, String>),
        message: &Json,
        log_time: u64,
    ) {
        let channel = match self.channels.get(&topic) {
            Some(c) => c.clone(),
            None => {
                let (name, text, metadata) = schema();
                let built = ChannelBuilder::new(topic.clone())
                    .context(&self.ctx)
                    .message_encoding(team_channels::MESSAGE_ENCODING)
                    .schema(Schema::new(name, team_channels::SCHEMA_ENCODING, text.into_bytes()))
                    .metadata(metadata)
                    .build_raw();
                // Refused only for a topic already taken with another schema on this context,
                // which the bridge never does; a dropped message is all that could follow.
                let Ok(c) = built else { return };
                self.channels.insert(topic, c.clone());
                c
            }
        };
        channel.log_with_meta(message.to_string().as_bytes(), PartialMetadata { log_time: Some(log_time) });
        self.published += 1;
    }

    /// One port's value on its team channel.
    pub fn port_value(&mut self, node: NodeId, behavior: &str, port: &str, value: &Value, log_time: u64) {
        let channel = PortChannel::new(node, behavior, port, value.ty());
        let message = channel.message(value, None);
        let topic = channel.topic();
        self.publish(topic, || (channel.schema_name(), channel.schema(), channel.metadata()), &message, log_time);
    }

    /// Every port of a node (its LIST answer): one message per port, except the implicit BLE
    /// ports of behaviors in no BLE group (see [`published_ports`]).
    pub fn node_report(&mut self, report: &NodeReport, log_time: u64) {
        for b in &report.behaviors {
            for p in published_ports(b) {
                self.port_value(report.node, &b.name, &p.name, &p.value, log_time);
            }
        }
    }

    /// One port's windows (its WHY answer).
    pub fn port_windows(&mut self, report: &PortReport, log_time: u64) {
        let message = windows_message(report);
        let topic = windows_topic(report.node, &report.behavior, &report.port);
        let metadata = BTreeMap::from([
            ("node".to_owned(), report.node.0.to_string()),
            ("behavior".to_owned(), report.behavior.clone()),
            ("port".to_owned(), report.port.clone()),
        ]);
        self.publish(topic, || (WINDOWS_SCHEMA.to_owned(), windows_schema(), metadata), &message, log_time);
    }

    /// Who claims one BLE layer.
    pub fn layer_claims(&mut self, claims: &LayerClaims, log_time: u64) {
        let message = claims_message(claims);
        let metadata = BTreeMap::from([("behavior".to_owned(), claims.behavior.clone())]);
        self.publish(
            claims_topic(&claims.behavior),
            || (CLAIMS_SCHEMA.to_owned(), claims_schema(), metadata),
            &message,
            log_time,
        );
    }
}

/// Whether a behavior is a BLE member: it runs the select process `ble_join` adds.
pub fn is_ble_member(b: &BehaviorReport) -> bool {
    b.processes.iter().any(|p| p.name == BLE_SELECT)
}

/// The ports of a behavior that get channels: all of them, except, in a behavior that joined
/// no BLE group, the implicit BLE ports (`Local`, `Inhibit`, `Best`, rule S11), which every
/// behavior has but only members use — they would triple the topics of a team for nothing.
pub fn published_ports(b: &BehaviorReport) -> impl Iterator<Item = &RegisterReport> {
    let member = is_ble_member(b);
    b.ports.iter().filter(move |p| member || ![LOCAL, INHIBIT, BEST].contains(&p.name.as_str()))
}

/// A port's windows as a message: every open window (kind, holder, seconds left), how many,
/// the seconds left of each kind (0 when none is open: plot-able), and what is blocked now.
pub fn windows_message(report: &PortReport) -> Json {
    let windows: Vec<Json> = report
        .windows
        .iter()
        .map(|w| {
            json!({
                "kind": w.kind.name(),
                "holder": w.holder.to_string(),
                "holder_node": w.holder.node.0,
                "holder_conn": w.holder.conn,
                "remaining": w.remaining.as_secs_f64(),
            })
        })
        .collect();
    let mut remaining = serde_json::Map::new();
    for kind in KINDS {
        let left =
            report.windows.iter().filter(|w| w.kind == kind).map(|w| w.remaining.as_secs_f64()).fold(0.0, f64::max);
        remaining.insert(kind.name().replace('-', "_"), json!(left));
    }
    json!({
        "node": report.node.0,
        "behavior": report.behavior,
        "port": report.port,
        "open": report.windows.len(),
        "windows": windows,
        "remaining": remaining,
        "input_blocked": report.input_blocked.map(|c| c.name()),
        "internal_output_blocked": report.internal_output_blocked.map(|c| c.name()),
        "connection_output_blocked": report.connection_output_blocked.map(|c| c.name()),
    })
}

/// A layer's claims as a message; `claimer` is the lowest claiming node id, 0 when nobody
/// claims (node ids plot as a step line).
pub fn claims_message(c: &LayerClaims) -> Json {
    json!({
        "behavior": c.behavior,
        "group": c.group,
        "claimer": c.claimers.iter().map(|n| n.0).min().unwrap_or(0),
        "claimers": c.claimers.iter().map(|n| n.0).collect::<Vec<_>>(),
        "members": c.members.iter().map(|n| n.0).collect::<Vec<_>>(),
    })
}

fn windows_schema() -> String {
    let kinds: serde_json::Map<String, Json> =
        KINDS.iter().map(|k| (k.name().replace('-', "_"), json!({"type": "number", "minimum": 0}))).collect();
    json!({
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": WINDOWS_SCHEMA,
        "description": "The arbitration windows open on one Ayllu port (docs/cli.md, ayllu foxglove)",
        "type": "object",
        "properties": {
            "node": {"type": "integer"},
            "behavior": {"type": "string"},
            "port": {"type": "string"},
            "open": {"type": "integer", "description": "how many windows are open"},
            "windows": {"type": "array", "items": {"type": "object", "properties": {
                "kind": {"type": "string"},
                "holder": {"type": "string", "description": "the connection holding it, n{node}/c{conn}"},
                "holder_node": {"type": "integer"},
                "holder_conn": {"type": "integer"},
                "remaining": {"type": "number", "description": "seconds until it closes unless refreshed"}
            }}},
            "remaining": {"type": "object", "properties": kinds,
                "description": "seconds left of the longest open window of each kind, 0 if none"},
            "input_blocked": {"type": ["string", "null"]},
            "internal_output_blocked": {"type": ["string", "null"]},
            "connection_output_blocked": {"type": ["string", "null"]}
        },
        "required": ["node", "behavior", "port", "open", "windows", "remaining"]
    })
    .to_string()
}

fn claims_schema() -> String {
    json!({
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": CLAIMS_SCHEMA,
        "description": "Who claims one BLE layer (docs/cli.md, ayllu foxglove)",
        "type": "object",
        "properties": {
            "behavior": {"type": "string"},
            "group": {"type": ["string", "null"]},
            "claimer": {"type": "integer", "description": "the lowest claiming node id, 0 if nobody claims"},
            "claimers": {"type": "array", "items": {"type": "integer"}},
            "members": {"type": "array", "items": {"type": "integer"}}
        },
        "required": ["behavior", "claimer", "claimers", "members"]
    })
    .to_string()
}

#[cfg(test)]
mod tests {
    use super::*;
    use ayllu_core::{Duration, Instant, Source, ValueType, WindowReport};

    #[test]
    fn windows_topics_hang_under_the_port_topic() {
        assert_eq!(windows_topic(NodeId(3), "RELAY", "Aux"), "/n3/RELAY/Aux/windows");
        assert_eq!(claims_topic("OBS1"), "/ble/OBS1");
        assert_eq!(PortChannel::new(NodeId(3), "RELAY", "Aux", ValueType::Int).topic(), "/n3/RELAY/Aux");
    }

    #[test]
    fn window_messages_say_what_is_open_and_for_how_long() {
        let mut node = ayllu_core::NodeCore::new(NodeId(1));
        let mut c = ayllu_core::BehaviorClass::new("R");
        c.port(ayllu_core::PortSpec::new("P", 0.0)).unwrap();
        node.define(c).unwrap();
        node.create("R", "R").unwrap();
        let mut report = node.why("R", "P").unwrap();
        report.windows = vec![WindowReport {
            kind: WindowKind::Suppress,
            holder: Source { node: NodeId(7), conn: 3 },
            ends: Instant::from_secs(5),
            remaining: Duration::from_millis(4500),
        }];
        let m = windows_message(&report);
        assert_eq!(m["open"], json!(1));
        assert_eq!(m["windows"][0]["kind"], json!("suppress"));
        assert_eq!(m["windows"][0]["holder"], json!("n7/c3"));
        assert_eq!(m["remaining"]["suppress"], json!(4.5));
        assert_eq!(m["remaining"]["write_inhibit"], json!(0.0));
        let schema: Json = serde_json::from_str(&windows_schema()).unwrap();
        assert_eq!(schema["title"], json!(WINDOWS_SCHEMA));
    }

    #[test]
    fn implicit_ble_ports_are_published_for_ble_members_only() {
        let mut node = ayllu_core::NodeCore::new(NodeId(1));
        for name in ["Plain", "Member"] {
            let mut c = ayllu_core::BehaviorClass::new(name);
            c.port(ayllu_core::PortSpec::new("Rotate", 0.0)).unwrap();
            node.define(c).unwrap();
            node.create(name, name).unwrap();
        }
        node.ble_join("Member", &ayllu_core::BleConfig::new("Peers", "Rotate", 1.0).unwrap()).unwrap();
        let report = node.report();
        let names = |b: &str| -> Vec<String> {
            let b = report.behaviors.iter().find(|x| x.name == b).unwrap();
            published_ports(b).map(|p| p.name.clone()).collect()
        };
        assert_eq!(names("Plain"), ["Rotate"]);
        assert_eq!(names("Member"), ["Local", "Inhibit", "Best", "Rotate"]);
    }

    #[test]
    fn claims_name_the_lowest_claimer_or_nobody() {
        let mut c = LayerClaims { behavior: "OBS1".into(), group: Some("Peers".into()), ..LayerClaims::default() };
        assert_eq!(claims_message(&c)["claimer"], json!(0));
        c.claimers = vec![NodeId(3), NodeId(2)];
        assert_eq!(claims_message(&c)["claimer"], json!(2));
        assert_eq!(claims_message(&c)["claimers"], json!([3, 2]));
    }
}
