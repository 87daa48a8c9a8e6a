//! The TOML form of a transaction's [`Plan`] (`ayllu apply PLAN.toml`; docs/cli.md "ayllu
//! apply"). Parsing lives here, not in the tool, so that Rust, C and Python programs read the
//! same files the same way.
//!
//! ```toml
//! hold = 5.0              # seconds each node holds its part (optional)
//! margin = 0.1            # added to the slowest round trip to aim the switch (optional)
//!
//! [[node]]
//! id = 2                  # or "n2", "0x2"
//! changes = [
//!   { op = "disconnect", from = "Low.Out", to = "Motor.In" },
//!   { op = "connect", from = "High.Out", to = "Motor.In", kind = "suppress", period = 0.5 },
//!   { op = "create", class = "Avoid", behavior = "Avoid2" },
//! ]
//! ```
//!
//! Endpoints: `BEHAVIOR.PORT` is a port of the node whose part it is; `n3:BEHAVIOR.PORT` a
//! port of node 3; `@GROUP:BEHAVIOR.PORT` every node of a group. What promises: every error
//! names the node and change at fault (`node 2, change 3: ...`), and unknown fields are
//! refused rather than ignored.

use serde::Deserialize;

use ayllu_core::{BleConfig, Change, ConnectionId, ConnectionKind, Duration, Endpoint, NodeId};

use crate::error::Error;
use crate::transaction::{ApplyOptions, Part, Plan};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PlanFile {
    hold: Option<f64>,
    margin: Option<f64>,
    prepare_timeout: Option<f64>,
    resend: Option<f64>,
    #[serde(default)]
    node: Vec<NodeFile>,
}

#[derive(Deserialize)]
#[serde(untagged)]
enum Id {
    Number(u32),
    Text(String),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct NodeFile {
    id: Id,
    #[serde(default)]
    changes: Vec<ChangeFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ChangeFile {
    op: String,
    class: Option<String>,
    behavior: Option<String>,
    from: Option<String>,
    to: Option<String>,
    kind: Option<String>,
    period: Option<f64>,
    priority: Option<i32>,
    conn: Option<u64>,
    group: Option<String>,
    output: Option<String>,
    rate_hz: Option<f64>,
    inhibit: Option<f64>,
    delay: Option<f64>,
}

fn seconds(x: f64, what: &str) -> Result<Duration, String> {
    if !(x.is_finite() && x > 0.0 && x < 1e9) {
        return Err(format!(
            "{what} = {}: must be a number of seconds above zero and under 1e9",
            ayllu_core::Compact(x)
        ));
    }
    Ok(Duration::from_nanos((x * 1e9).round() as u64))
}

/// A node id as the tools write it: `3`, `n3` or `0x3`.
pub fn parse_node_id(s: &str) -> Result<NodeId, String> {
    let digits = s.strip_prefix('n').unwrap_or(s);
    let parsed = match digits.strip_prefix("0x").or_else(|| digits.strip_prefix("0X")) {
        Some(hex) => u32::from_str_radix(hex, 16),
        None => digits.parse::<u32>(),
    };
    parsed.map(NodeId).map_err(|_| format!("`{s}` is not a node id (3, n3 or 0x3)"))
}

/// `BEHAVIOR.PORT`, `nN:BEHAVIOR.PORT` or `@GROUP:BEHAVIOR.PORT`.
pub fn parse_endpoint(s: &str) -> Result<Endpoint, String> {
    let (place, path) = match s.split_once(':') {
        Some((place, path)) => (Some(place), path),
        None => (None, s),
    };
    let (behavior, port) = path
        .split_once('.')
        .filter(|(b, p)| !b.is_empty() && !p.is_empty())
        .ok_or_else(|| format!("`{s}` is not BEHAVIOR.PORT (optionally nN: or @GROUP: before it)"))?;
    Ok(match place {
        None => Endpoint::local(behavior, port),
        Some(g) if g.starts_with('@') && g.len() > 1 => Endpoint::group(&g[1..], behavior, port),
        Some(n) => Endpoint::node(parse_node_id(n)?, behavior, port),
    })
}

fn change(c: &ChangeFile) -> Result<Change, String> {
    let need = |v: &Option<String>, field: &str| v.clone().ok_or_else(|| format!("`{}` needs `{field}`", c.op));
    let endpoint = |v: &Option<String>, field: &str| need(v, field).and_then(|s| parse_endpoint(&s));
    Ok(match c.op.as_str() {
        "create" => Change::Create { class: need(&c.class, "class")?, name: need(&c.behavior, "behavior")? },
        "remove" => Change::Remove { name: need(&c.behavior, "behavior")? },
        "connect" => {
            let name = c.kind.clone().unwrap_or_else(|| "normal".into());
            let period = match (name.as_str(), c.period) {
                ("normal", None) => Duration::ZERO,
                ("normal", Some(_)) => return Err("a normal connection has no `period`".into()),
                (_, Some(p)) => seconds(p, "period")?,
                (_, None) => return Err(format!("a {name} connection needs `period` (seconds)")),
            };
            let kind = ConnectionKind::from_name(&name, period).ok_or_else(|| {
                format!("unknown kind `{name}` (normal, suppress, inhibit, override-in, override-out, write-inhibit)")
            })?;
            Change::Connect {
                source: endpoint(&c.from, "from")?,
                destination: endpoint(&c.to, "to")?,
                kind,
                priority: c.priority.unwrap_or(0),
            }
        }
        "disconnect" => match c.conn {
            Some(id) => Change::Disconnect { conn: ConnectionId(id) },
            None => {
                Change::DisconnectBetween { source: endpoint(&c.from, "from")?, destination: endpoint(&c.to, "to")? }
            }
        },
        "join" => Change::Join { group: need(&c.group, "group")? },
        "leave" => Change::Leave { group: need(&c.group, "group")? },
        "ble_join" => {
            let mut config =
                BleConfig::new(&need(&c.group, "group")?, &need(&c.output, "output")?, c.rate_hz.unwrap_or(1.0))
                    .map_err(|e| e.to_string())?;
            if let Some(d) = c.delay {
                config = config.network_delay(seconds(d, "delay")?);
            }
            if let Some(i) = c.inhibit {
                config = config.inhibit_period(seconds(i, "inhibit")?);
            }
            Change::BleJoin { behavior: need(&c.behavior, "behavior")?, config }
        }
        other => {
            return Err(format!("unknown op `{other}` (create, remove, connect, disconnect, join, leave, ble_join)"))
        }
    })
}

impl Plan {
    /// The plan a TOML text describes (see the module docs).
    pub fn from_toml(text: &str) -> Result<Plan, Error> {
        let bad = |what: String| Error::Plan { what };
        let file: PlanFile = toml::from_str(text).map_err(|e| bad(e.to_string()))?;
        let mut options = ApplyOptions::default();
        for (value, slot, name) in [
            (file.hold, &mut options.hold, "hold"),
            (file.margin, &mut options.margin, "margin"),
            (file.prepare_timeout, &mut options.prepare_timeout, "prepare_timeout"),
            (file.resend, &mut options.resend, "resend"),
        ] {
            if let Some(x) = value {
                *slot = seconds(x, name).map_err(bad)?;
            }
        }
        let mut parts = Vec::new();
        for n in &file.node {
            let node = match &n.id {
                Id::Number(x) => NodeId(*x),
                Id::Text(t) => parse_node_id(t).map_err(bad)?,
            };
            let changes = n
                .changes
                .iter()
                .enumerate()
                .map(|(i, c)| change(c).map_err(|e| bad(format!("node {node}, change {}: {e}", i + 1))))
                .collect::<Result<Vec<_>, _>>()?;
            parts.push(Part { node, changes });
        }
        if parts.is_empty() {
            return Err(bad("no [[node]] in the plan".into()));
        }
        Ok(Plan { parts, options })
    }

    /// [`Plan::from_toml`] of a file.
    pub fn read(path: impl AsRef<std::path::Path>) -> Result<Plan, Error> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path)
            .map_err(|e| Error::Io { what: format!("reading the plan {}", path.display()), error: e.to_string() })?;
        Plan::from_toml(&text).map_err(|e| match e {
            Error::Plan { what } => Error::Plan { what: format!("{}: {what}", path.display()) },
            other => other,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_plan_with_every_op() {
        let plan = Plan::from_toml(
            r#"
            hold = 4.0
            [[node]]
            id = "n2"
            changes = [
              { op = "disconnect", from = "Low.Out", to = "Motor.In" },
              { op = "connect", from = "High.Out", to = "Motor.In", kind = "suppress", period = 0.5, priority = 2 },
              { op = "connect", from = "OBS.Local", to = "@Peers:OBS.Best" },
              { op = "create", class = "Avoid", behavior = "A2" },
              { op = "remove", behavior = "A1" },
              { op = "disconnect", conn = 4 },
              { op = "join", group = "G" },
              { op = "leave", group = "H" },
              { op = "ble_join", behavior = "OBS", group = "Peers", output = "Rotate", rate_hz = 2.0 },
            ]
            [[node]]
            id = 3
            changes = [{ op = "connect", from = "A.Out", to = "n2:B.In" }]
            "#,
        )
        .unwrap();
        assert_eq!(plan.options.hold, Duration::from_secs(4));
        assert_eq!(plan.parts.len(), 2);
        assert_eq!(plan.parts[0].node, NodeId(2));
        assert_eq!(plan.parts[0].changes.len(), 9);
        assert_eq!(
            plan.parts[0].changes[1],
            Change::Connect {
                source: Endpoint::local("High", "Out"),
                destination: Endpoint::local("Motor", "In"),
                kind: ConnectionKind::Suppress(Duration::from_millis(500)),
                priority: 2
            }
        );
        assert_eq!(
            plan.parts[1].changes[0],
            Change::Connect {
                source: Endpoint::local("A", "Out"),
                destination: Endpoint::node(NodeId(2), "B", "In"),
                kind: ConnectionKind::Normal,
                priority: 0
            }
        );
    }

    #[test]
    fn errors_name_the_node_and_change() {
        let e = Plan::from_toml("[[node]]\nid = 2\nchanges = [{ op = \"create\", class = \"A\" }, { op = \"x\" }]")
            .unwrap_err()
            .to_string();
        assert!(e.contains("node n2, change 1") && e.contains("`behavior`"), "{e}");
        let e = Plan::from_toml("[[node]]\nid = 2\nchanges = [{ op = \"connect\", from = \"A\", to = \"B.In\" }]")
            .unwrap_err()
            .to_string();
        assert!(e.contains("BEHAVIOR.PORT"), "{e}");
        let e = Plan::from_toml(
            "[[node]]\nid = 2\nchanges = [{ op = \"connect\", from = \"A.O\", to = \"B.In\", kind = \"suppress\" }]",
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("needs `period`"), "{e}");
        assert!(Plan::from_toml("hold = 1\nfoo = 2").is_err(), "unknown fields are refused");
        assert!(Plan::from_toml("").unwrap_err().to_string().contains("no [[node]]"));
    }
}
