//! What a node's own views say about the team and its ports, with real node processes on
//! loopback (port 0):
//! * `ayllu node`'s status line lists the team members in `peers`, not the `ayllu` tool
//!   invocations that asked it something (each a peer of its own, ids from 0x7fff0000): those
//!   are only counted in `tools`, as `list` and `graph` leave them out (bugs/08 of probe 4);
//! * `ayllu list NODE` shows an aggregating port that holds nothing as `empty`, as `why`
//!   does, not as `stale` (bugs/06 of probe 4).

use crate::common;

use std::time::Duration;

use common::{ayllu, start_on_loopback, wait_for};

const LIMIT: Duration = Duration::from_secs(60);

#[test]
fn the_status_line_lists_the_team_not_the_tools_that_asked() {
    let (procs, addrs) = start_on_loopback(
        2,
        |k| format!("n{}", k + 1),
        |k, url| {
            let id = (k + 1).to_string();
            ["node", "--id", &id, "--controller", "relay", "--udp", url, "--status-ms", "200", "--for", "60"]
                .iter()
                .map(|s| s.to_string())
                .collect()
        },
    );
    let url = format!("udp://127.0.0.1:0?peer={}", addrs[0]);
    // Node 2 announced itself to node 1 on start; wait until node 1 has heard it.
    let heard_2 = wait_for(LIMIT, Duration::from_millis(50), || {
        procs[0].latest().filter(|(_, j)| j["peers"].as_array().is_some_and(|p| p.contains(&2.into())))
    });
    assert!(heard_2.is_some(), "node 1 never listed node 2: {}", procs[0].stderr());
    // Three tool invocations, three more ids node 1 hears from.
    for _ in 0..3 {
        ayllu(&["why", "1", "RELAY.In", "--udp", &url], LIMIT).ok();
    }
    let after = std::time::Instant::now();
    let line = wait_for(LIMIT, Duration::from_millis(50), || {
        procs[0].lines().into_iter().find(|(t, j)| *t > after && j["tools"].as_u64().is_some_and(|n| n >= 1))
    });
    let (_, j) = line.unwrap_or_else(|| panic!("no status line counts the tools: {:?}", procs[0].latest()));
    assert_eq!(j["peers"], serde_json::json!([2]), "only the team member, not the tools: {j}");
    assert!(j["tools"].as_u64().unwrap() <= 3, "{j}");
}

#[test]
fn list_shows_an_aggregating_port_that_holds_nothing_as_empty() {
    // A lone cross-subsumption node that sees nothing: no peer offers a target, so its
    // OBS1.Best (a Max port, BLE) holds nothing.
    let (_procs, addrs) = start_on_loopback(
        1,
        |_| "n1".to_owned(),
        |_, url| {
            ["node", "--id", "1", "--udp", url, "--layers", "1", "--for", "60"].iter().map(|s| s.to_string()).collect()
        },
    );
    let url = format!("udp://127.0.0.1:0?peer={}", addrs[0]);
    let why = ayllu(&["why", "1", "OBS1.Best", "--udp", &url], LIMIT).ok();
    assert!(why.stdout.contains("(empty"), "{why:?}");
    let list = ayllu(&["list", "1", "--udp", &url], LIMIT).ok();
    let best = list.stdout.lines().find(|l| l.trim_start().starts_with("Best ")).expect("OBS1.Best is listed");
    assert!(best.contains(" max ") && best.trim_end().ends_with("empty"), "{best:?} in {}", list.stdout);
    // Every aggregating port that is not fresh is empty; `stale` is for Normal ports.
    for l in list.stdout.lines().filter(|l| [" max ", " min ", " sum ", " priority "].iter().any(|k| l.contains(k))) {
        assert!(!l.trim_end().ends_with("stale"), "{l:?} in {}", list.stdout);
    }
}
