//! Values and reports as people and scripts read them: parsing a typed value from the command
//! line, values as plain JSON, reports as text and as JSON.
//!
//! JSON reports are `ayllu::report_json`'s, the shape C and Python use too.

use std::fmt::Write as _;

use ayllu::{
    Endpoint, Node, NodeId, NodeReport, PeerInfo, Trigger, Value, ValueType, BEST, BLE_SELECT, INHIBIT, LOCAL,
};
use serde_json::{json, Value as Json};

/// The first line a long-running command (`node`, `sim robot`) prints, as soon as its socket
/// is bound: `{"listening":"127.0.0.1:45125","node":1}`. A node started on port 0 tells here
/// which port it got, so scripts and tests never pick a port they do not hold.
pub fn listening_json(node: &Node) -> Json {
    json!({ "listening": node.address(), "node": node.id().0 })
}

/// Parse `text` as a value of type `ty`. The error says what was expected.
pub fn parse_value(ty: ValueType, text: &str) -> Result<Value, String> {
    let t = text.trim();
    match ty {
        ValueType::Bool => match t.to_ascii_lowercase().as_str() {
            "true" | "1" | "on" | "yes" => Ok(Value::Bool(true)),
            "false" | "0" | "off" | "no" => Ok(Value::Bool(false)),
            _ => Err("expected true or false".to_owned()),
        },
        ValueType::Int => t.parse::<i64>().map(Value::Int).map_err(|e| format!("expected an integer ({e})")),
        ValueType::Float => match t.parse::<f64>() {
            Ok(x) if x.is_finite() => Ok(Value::Float(x)),
            Ok(_) => Err("expected a finite number".to_owned()),
            Err(e) => Err(format!("expected a number ({e})")),
        },
        // Text is taken as typed, spaces and all.
        ValueType::Text => Ok(Value::text(text)),
        ValueType::Bytes => {
            let hex = t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")).unwrap_or(t);
            if !hex.len().is_multiple_of(2) || !hex.bytes().all(|b| b.is_ascii_hexdigit()) {
                return Err("expected bytes as an even number of hex digits (0a0b or 0x0a0b)".to_owned());
            }
            let bytes: Vec<u8> =
                (0..hex.len()).step_by(2).map(|i| u8::from_str_radix(&hex[i..i + 2], 16).unwrap_or(0)).collect();
            Ok(Value::bytes(&bytes))
        }
        ValueType::Vector => {
            let inner = t.strip_prefix('[').and_then(|s| s.strip_suffix(']')).unwrap_or(t).trim();
            if inner.is_empty() {
                return Ok(Value::vector(&[]));
            }
            let mut v = Vec::new();
            for item in inner.split(',') {
                match item.trim().parse::<f64>() {
                    Ok(x) if x.is_finite() => v.push(x),
                    _ => {
                        return Err(format!("expected a comma list of numbers (1,2.5,3); `{}` is not one", item.trim()))
                    }
                }
            }
            if v.len() > 255 {
                return Err("a vector holds at most 255 numbers".to_owned());
            }
            Ok(Value::vector(&v))
        }
    }
}

/// A value as JSON: the one form Ayllu writes everywhere (recordings, the Foxglove layout,
/// the tool's `--json`): numbers, booleans, strings, bytes as a hex string, vectors as arrays,
/// and a float that is not finite as `"NaN"`, `"inf"` or `"-inf"` (JSON has no such numbers;
/// `null` would lose which it was): `ayllu::team_channels::value_json`.
pub use ayllu::team_channels::value_json;

pub use ayllu::report_json::{counted, node_report_json, port_report_json};

/// A value for people: floats with at most 15 significant digits (so the sum 0.1 + 0.2 shows
/// as 0.3, not 0.30000000000000004), everything else as the value prints. JSON output keeps
/// every bit.
pub fn human(v: &Value) -> String {
    fn float(x: f64) -> String {
        if !x.is_finite() {
            return x.to_string();
        }
        let rounded: f64 = format!("{x:.14e}").parse().unwrap_or(x);
        rounded.to_string()
    }
    match v {
        Value::Float(x) => float(*x),
        Value::Vector(xs) => format!("[{}]", xs.iter().map(|x| float(*x)).collect::<Vec<_>>().join(", ")),
        other => other.to_string(),
    }
}

/// An AylluLite node's LIST (`{"node","lite":true,"behaviors":[{"name","ports"}]}`) as text;
/// any other unknown report as its JSON.
pub fn other_report_text(json_text: &str, peer: &PeerInfo) -> String {
    let Ok(j) = serde_json::from_str::<Json>(json_text) else { return json_text.to_owned() };
    if j["lite"] != json!(true) {
        return json_text.to_owned();
    }
    let name = if peer.name.is_empty() { "-" } else { &peer.name };
    let mut out =
        format!("{} ({name} at {}): an AylluLite node (it answers READ and LIST)\nbehaviors:\n", peer.node, peer.addr);
    for b in j["behaviors"].as_array().into_iter().flatten() {
        let ports: Vec<&str> = b["ports"].as_array().into_iter().flatten().filter_map(Json::as_str).collect();
        let _ = writeln!(out, "  {}: {}", b["name"].as_str().unwrap_or("?"), ports.join(", "));
    }
    out
}

/// A peer as `list` shows it in JSON.
pub fn peer_json(p: &PeerInfo, now: ayllu::Instant) -> Json {
    json!({
        "node": p.node.0,
        "name": p.name,
        "addr": p.addr,
        "groups": p.groups,
        "last_heard_secs_ago": now.saturating_since(p.last_heard).as_secs_f64(),
    })
}

/// The nodes heard, as a table.
pub fn peers_table(peers: &[PeerInfo]) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "{:<12} {:<16} {:<22} GROUPS", "NODE", "NAME", "ADDRESS");
    for p in peers {
        let groups = if p.groups.is_empty() { "-".to_owned() } else { p.groups.join(",") };
        let name = if p.name.is_empty() { "-" } else { &p.name };
        let _ = writeln!(out, "{:<12} {:<16} {:<22} {groups}", p.node.to_string(), name, p.addr);
    }
    out
}

/// A node report as text: one section each for behaviors, connections, counters.
pub fn node_report_text(r: &NodeReport, peer: Option<&PeerInfo>) -> String {
    let mut out = String::new();
    let at = peer.map(|p| format!(" ({} at {})", if p.name.is_empty() { "-" } else { &p.name }, p.addr));
    let _ = writeln!(out, "{}{} at {} on its clock", r.node, at.unwrap_or_default(), r.now);
    let groups = if r.groups.is_empty() { "none".to_owned() } else { r.groups.join(", ") };
    let _ = writeln!(out, "groups: {groups}");
    let _ = writeln!(out, "behaviors:");
    for b in &r.behaviors {
        let _ = writeln!(out, "  {} ({})", b.name, b.class);
        // Every behavior has the BLE ports; show them only where BLE runs (`--json` has all).
        let ble = b.processes.iter().any(|p| p.name == BLE_SELECT);
        for p in b.ports.iter().filter(|p| ble || ![LOCAL, INHIBIT, BEST].contains(&p.name.as_str())) {
            // An aggregating port that is not fresh holds nothing (never written, or its
            // window, lease or lifespan ended and released it): `why` says "empty", so does this.
            let state = match (p.fresh, p.kind.is_aggregating()) {
                (true, _) => "fresh",
                (false, true) => "empty",
                (false, false) => "stale",
            };
            let _ = writeln!(
                out,
                "    {:<14} {:<8} {:<6} {:<12} {state}",
                p.name,
                p.kind.name(),
                p.ty.name(),
                human(&p.value)
            );
        }
        for (name, v) in &b.slots {
            let _ = writeln!(out, "    {name:<14} slot     {:<6} {v}", v.ty().name());
        }
        for (name, high) in &b.monostables {
            let _ = writeln!(out, "    {name:<14} monostable {}", if *high { "high" } else { "low" });
        }
        for p in &b.processes {
            let port_name = |port: ayllu::Port| b.ports.get(usize::from(port.0)).map_or("?", |r| r.name.as_str());
            let trigger = match p.trigger {
                Trigger::Periodic(d) => format!("every {d}"),
                Trigger::PeriodicWhileFresh(d, port) => format!("every {d} while {} is fresh", port_name(port)),
                Trigger::OnWrite(port) => format!("on write of {}", port_name(port)),
                Trigger::OnMonostable(m) => {
                    format!("on {}", b.monostables.get(usize::from(m.0)).map_or("?", |(n, _)| n.as_str()))
                }
            };
            let _ = write!(out, "    process {} ({trigger}): {} runs, {} overruns", p.name, p.runs, p.overruns);
            if p.retriggered > 0 {
                let _ = write!(out, ", triggers itself (held back {} times)", p.retriggered);
            }
            let _ = writeln!(out);
        }
    }
    let _ = writeln!(out, "connections:");
    if r.connections.is_empty() {
        let _ = writeln!(out, "  none");
    }
    for c in &r.connections {
        let mut prio = if c.priority != 0 { format!(" priority {}", c.priority) } else { String::new() };
        if let Some(n) = c.requested_by {
            prio.push_str(&format!(" (requested by {n}: lasts while it lives)"));
        }
        // Only a connection to another node or a group sends messages; one inside the node
        // delivers in place, and its count would always read 0.
        let sent = if is_remote(&c.destination, r.node) { format!(" (sent {})", c.sent) } else { String::new() };
        let _ = writeln!(
            out,
            "  {:<5} {:<22} {} -> {}{prio}{sent}",
            c.id.to_string(),
            c.kind.to_string(),
            c.source,
            c.destination
        );
    }
    let core: Vec<String> = r.counters.nonzero().map(|(d, n)| format!("{d}: {n}")).collect();
    let transport: Vec<String> = r.transport.iter().map(|(k, v)| format!("{k}: {v}")).collect();
    let _ = writeln!(out, "counters:");
    let _ = writeln!(out, "  core       {}", if core.is_empty() { "none".to_owned() } else { core.join(", ") });
    let _ =
        writeln!(out, "  transport  {}", if transport.is_empty() { "none".to_owned() } else { transport.join(", ") });
    // A body's driver (the ROS 2 body): a line a topic, with what it counted (the matched
    // publishers or subscribers even at 0: "nobody publishes it" is the first thing to know).
    let mut topics: Vec<(&str, Vec<String>)> = Vec::new();
    for (key, n) in &r.body {
        let (topic, cause) = key.rsplit_once(' ').unwrap_or((key.as_str(), ""));
        let i = match topics.iter().position(|(t, _)| *t == topic) {
            Some(i) => i,
            None => {
                topics.push((topic, Vec::new()));
                topics.len() - 1
            }
        };
        if *n > 0 || cause == "publishers" || cause == "subscribers" {
            topics[i].1.push(format!("{cause} {n}"));
        }
    }
    for (topic, counts) in topics {
        let _ = writeln!(out, "  body       {topic}: {}", counts.join(", "));
    }
    for w in &r.warnings {
        let _ = writeln!(out, "warning: {w}");
    }
    out
}

/// Whether a connection's destination is reached through the network (another node, a group)
/// rather than inside `node` (a local port, or a port named with `node`'s own id).
fn is_remote(destination: &Endpoint, node: NodeId) -> bool {
    match destination {
        Endpoint::Local { .. } => false,
        Endpoint::Node { node: to, .. } => *to != node,
        Endpoint::Group { .. } => true,
    }
}

/// Seconds rounded to the millisecond (positions to the millimetre), for people reading
/// status lines.
pub fn round3(x: f64) -> f64 {
    (x * 1000.0).round() / 1000.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_body_prints_a_line_a_topic_with_what_it_counted_and_its_matches() {
        let mut r = ayllu::NodeCore::new(ayllu::NodeId(1)).report();
        r.body = [
            ("/robot1/scan taken", 599),
            ("/robot1/scan truncated", 0),
            ("/robot1/scan nan", 2),
            ("/robot1/scan publishers", 1),
            ("/robot1/cmd_vel published", 0),
            ("/robot1/cmd_vel subscribers", 0),
        ]
        .into_iter()
        .map(|(k, n)| (k.to_owned(), n))
        .collect();
        let text = node_report_text(&r, None);
        assert!(text.contains("  body       /robot1/scan: taken 599, nan 2, publishers 1\n"), "{text}");
        assert!(text.contains("  body       /robot1/cmd_vel: subscribers 0\n"), "{text}");
    }

    #[test]
    fn values_parse_by_type() {
        assert_eq!(parse_value(ValueType::Bool, "true"), Ok(Value::Bool(true)));
        assert_eq!(parse_value(ValueType::Bool, "0"), Ok(Value::Bool(false)));
        assert_eq!(parse_value(ValueType::Int, "-42"), Ok(Value::Int(-42)));
        assert_eq!(parse_value(ValueType::Float, "0.25"), Ok(Value::Float(0.25)));
        assert_eq!(parse_value(ValueType::Text, "hi there"), Ok(Value::text("hi there")));
        assert_eq!(parse_value(ValueType::Bytes, "0x0aff"), Ok(Value::bytes(&[0x0a, 0xff])));
        assert_eq!(parse_value(ValueType::Bytes, "0aff"), Ok(Value::bytes(&[0x0a, 0xff])));
        assert_eq!(parse_value(ValueType::Vector, "1, 2.5,3"), Ok(Value::vector(&[1.0, 2.5, 3.0])));
        assert_eq!(parse_value(ValueType::Vector, "[1,2]"), Ok(Value::vector(&[1.0, 2.0])));
        assert_eq!(parse_value(ValueType::Vector, ""), Ok(Value::vector(&[])));
    }

    #[test]
    fn bad_values_say_what_was_expected() {
        for (ty, text, needle) in [
            (ValueType::Bool, "maybe", "true or false"),
            (ValueType::Int, "1.5", "integer"),
            (ValueType::Int, "abc", "integer"),
            (ValueType::Float, "abc", "number"),
            (ValueType::Float, "inf", "finite"),
            (ValueType::Bytes, "abc", "hex"),
            (ValueType::Bytes, "zz", "hex"),
            (ValueType::Vector, "1,x", "comma list"),
        ] {
            let e = parse_value(ty, text).unwrap_err();
            assert!(e.contains(needle), "{ty} `{text}`: {e}");
        }
    }

    #[test]
    fn values_become_plain_json() {
        assert_eq!(value_json(&Value::Int(3)), json!(3));
        assert_eq!(value_json(&Value::bytes(&[1, 255])), json!("01ff"));
        assert_eq!(value_json(&Value::vector(&[1.0, 2.0])), json!([1.0, 2.0]));
        assert_eq!(value_json(&Value::Float(f64::NAN)), json!("NaN"));
    }
}
