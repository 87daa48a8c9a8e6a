//! Reports as JSON: the one shape `ayllu why --json` and `ayllu list --json` print, C's
//! `ay_node_why_json` / `ay_node_report_json` return and Python's reports are built from.
//!
//! Promises: the serde form of [`PortReport`] / [`NodeReport`] (the JSON a REPLY carries,
//! spec/protocol.md) with every time (`Instant`, `Duration`: `{"nanos": N}` in serde) as
//! seconds, a number people and scripts read directly, and for scripts a `counted` object
//! `{cause: count}` beside each positional `counters` array (a node report also has
//! `transport_counted` and `body_counted`). The wire keeps nanoseconds: exact integers.

use ayllu_core::{Counters, NodeReport, PortReport};
use serde_json::{json, Map, Value as Json};

/// `{cause: count}` for the non-zero counters.
pub fn counted(counters: &Counters) -> Json {
    Json::Object(counters.nonzero().map(|(d, n)| (d.name().to_owned(), json!(n))).collect())
}

/// A port report (`why`) as JSON (module docs).
pub fn port_report_json(r: &PortReport) -> Json {
    let mut j = serde_json::to_value(r).unwrap_or(Json::Null);
    if let Json::Object(m) = &mut j {
        m.insert("counted".to_owned(), counted(&r.counters));
    }
    seconds(&mut j);
    j
}

/// A node report (`list`) as JSON (module docs).
pub fn node_report_json(r: &NodeReport) -> Json {
    let mut j = serde_json::to_value(r).unwrap_or(Json::Null);
    if let Json::Object(m) = &mut j {
        m.insert("counted".to_owned(), counted(&r.counters));
        let transport: Map<String, Json> = r.transport.iter().map(|(k, v)| (k.clone(), json!(v))).collect();
        m.insert("transport_counted".to_owned(), Json::Object(transport));
        let body: Map<String, Json> = r.body.iter().map(|(k, v)| (k.clone(), json!(v))).collect();
        m.insert("body_counted".to_owned(), Json::Object(body));
    }
    seconds(&mut j);
    j
}

/// Any serde value (a BLE status, a transaction report) with its times as seconds.
pub fn with_seconds<T: serde::Serialize>(value: &T) -> Json {
    let mut j = serde_json::to_value(value).unwrap_or(Json::Null);
    seconds(&mut j);
    j
}

/// Replace every time (`Instant` and `Duration` serialize as `{"nanos": N}`) by seconds.
fn seconds(j: &mut Json) {
    match j {
        Json::Object(m) => {
            if m.len() == 1 {
                if let Some(n) = m.get("nanos").and_then(Json::as_u64) {
                    *j = json!(n as f64 / 1e9);
                    return;
                }
            }
            m.values_mut().for_each(seconds);
        }
        Json::Array(a) => a.iter_mut().for_each(seconds),
        _ => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ayllu_core::{Duration, Instant};

    #[test]
    fn times_are_seconds_at_any_depth() {
        let j = with_seconds(&(Instant::ZERO + Duration::from_millis(1500), vec![Duration::from_micros(250)]));
        assert_eq!(j, json!([1.5, [0.00025]]));
    }
}
