//! The `ayllu-zenoh` tool's commands that run nodes, over `zenoh://` (issue 12: every command
//! takes a `zenoh://` URL):
//! * two `ayllu-zenoh node` processes (the paper's cross-subsumption) in Zenoh peer mode on
//!   loopback greet each other, claim one target each, are seen by `list`, `why`, `echo`, `hz`
//!   and `record`, and the survivor takes over a killed node's target;
//! * `ayllu-zenoh sim serve` and two `ayllu-zenoh sim robot` processes, all Zenoh clients of a
//!   router in this process: every body hears its controller, the robots hear each other (BLE
//!   over the team's group key) and drive their bodies;
//! * the Zenoh socket's drops reach the node's transport counters (`zenoh_unattributed`).
//!
//! Ports: peer-mode nodes listen on loopback port 0 and say which port they got (the
//! `listening` line of `ayllu-zenoh node`, `Node::address` in this process); the router too
//! (its locators). Multicast scouting
//! is off, so nothing leaves the machine. Every wait is bounded and only ends early; timing
//! never decides a verdict.

mod common;

use std::process::Output;
use std::time::{Duration, Instant};

use ayllu::{Node, NodeId};
use common::{listening_line, strings, Proc};
use serde_json::Value as Json;
use zenoh::Wait;

const TEAM: u32 = 12;
const KEY: [u8; 32] = [0x5a; 32];
/// The longest any condition is waited for.
const PATIENCE: Duration = Duration::from_secs(60);

fn key_hex() -> String {
    common::key_hex(&KEY)
}

/// Run the tool to the end (killed after [`PATIENCE`]); its output, printed for --nocapture.
fn tool(args: &[&str], url: &str) -> Output {
    common::run_tool(args, url, PATIENCE, || std::thread::sleep(Duration::from_millis(20)))
}

fn claims(j: &Json) -> Vec<u64> {
    common::ints(j, "claims")
}

fn peers(j: &Json) -> Vec<u64> {
    common::ints(j, "peers")
}

#[test]
fn node_processes_over_zenoh_are_listed_explained_echoed_and_take_over() {
    let base = format!("zenoh://?scouting=0&team={TEAM}&key={}&hello_ms=200", key_hex());
    let node = |id: &str, url: String, sight: &str| {
        strings(&["node", "--id", id, "--udp", &url, "--sight", sight, "--status-ms", "300", "--for", "120"])
    };
    let n1 = Proc::start("n1", &node("1", format!("{base}&listen=tcp/127.0.0.1:0"), "1:0.9,2:0.5"));
    let first = n1.wait_line(PATIENCE, |j| j.get("listening").is_some()).unwrap_or_else(|| panic!("{}", n1.report()));
    assert_eq!(first["node"], 1);
    // Where n1 listens, as bound: `tcp/127.0.0.1:PORT`, the port the system chose.
    let at1 = listening_line(&first);
    let n2 = Proc::start("n2", &node("2", format!("{base}&listen=tcp/127.0.0.1:0&connect={at1}"), "1:0.6,2:0.8"));
    let second = n2.wait_line(PATIENCE, |j| j.get("listening").is_some()).unwrap_or_else(|| panic!("{}", n2.report()));
    let at2 = listening_line(&second);

    // HELLOs both ways, then one claimer per target: n1 sees target 1 best, n2 target 2.
    let give_up = Instant::now() + PATIENCE;
    let mut settled = false;
    while !settled && Instant::now() < give_up {
        std::thread::sleep(Duration::from_millis(100));
        if let (Some(a), Some(b)) = (n1.latest(), n2.latest()) {
            settled = peers(&a) == [2] && peers(&b) == [1] && claims(&a) == [1] && claims(&b) == [2];
        }
    }
    assert!(settled, "the two nodes never settled on one claimer per target\n{}\n{}", n1.report(), n2.report());

    let tool_url = format!("{base}&connect={at1}&connect={at2}");
    // `list`: both nodes heard, under the names the command gave them.
    let out = tool(&["list", "--json"], &tool_url);
    assert!(out.status.success(), "list failed");
    let heard: Json = serde_json::from_slice(&out.stdout).expect("list --json prints JSON");
    let names: Vec<(u64, String)> = heard
        .as_array()
        .expect("a list of nodes")
        .iter()
        .map(|n| (n["node"].as_u64().unwrap(), n["name"].as_str().unwrap_or("").to_owned()))
        .collect();
    assert!(names.contains(&(1, "node-1".to_owned())) && names.contains(&(2, "node-2".to_owned())), "{names:?}");

    // `list NODE`: the node's report, its observers there.
    let out = tool(&["list", "2"], &tool_url);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success() && text.contains("OBS1 (Observer)"), "list 2: {text}");

    // `why`: n1's claim on target 1 write-inhibits n2's OBS1.Rotate.
    let out = tool(&["why", "2", "OBS1.Rotate"], &tool_url);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success() && text.contains("n2:OBS1.Rotate"), "why: {text}");
    assert!(text.contains("write-inhibit held by n1"), "n1's claim shows on n2: {text}");

    // `echo`: a connection made on n1 by CONNECT over Zenoh, three values, then DISCONNECT.
    let out = tool(&["echo", "1", "BASE.Rotate", "--count", "3", "--json"], &tool_url);
    assert!(out.status.success(), "echo failed");
    let values: Vec<Json> =
        String::from_utf8_lossy(&out.stdout).lines().map(|l| serde_json::from_str(l).expect("a JSON line")).collect();
    assert_eq!(values.len(), 3);
    assert!(values.iter().all(|v| v["node"] == 1 && v["port"] == "BASE.Rotate"), "{values:?}");

    // `hz` and `record` put a tap around whatever transport the URL opens.
    let out = tool(&["hz", "1", "BASE.Rotate", "--count", "5", "--json"], &tool_url);
    assert!(out.status.success(), "hz failed");
    let rate: Json = serde_json::from_slice(&out.stdout).expect("hz --json prints JSON");
    assert!(rate["messages"].as_u64().unwrap_or(0) >= 5, "{rate}");
    let file = std::env::temp_dir().join(format!("ayllu-zenoh-record-{}.mcap", std::process::id()));
    let out =
        tool(&["record", "-o", file.to_str().unwrap(), "--for", "2", "--copy", "n1:BASE.Rotate", "--json"], &tool_url);
    let _ = std::fs::remove_file(&file);
    assert!(out.status.success(), "record failed");
    let summary: Json = serde_json::from_slice(&out.stdout).expect("record --json prints JSON");
    assert!(summary["channels"]["/n1/BASE/Rotate"].as_u64().unwrap_or(0) > 0, "{summary}");

    // Kill n1: n2 takes target 1 over once n1's lease lapses (the paper's cross-subsumption).
    drop(n1);
    let took_over =
        n2.wait_line(PATIENCE, |j| j.get("t").is_some() && claims(j).contains(&1) && !peers(j).contains(&1));
    assert!(took_over.is_some(), "n2 never took target 1 over\n{}", n2.report());
}

#[test]
fn the_distributed_simulator_runs_over_a_zenoh_router() {
    let router = ayllu_zenoh::Router::open(&ayllu_zenoh::RouterOptions {
        listen: vec!["tcp/127.0.0.1:0".into()],
        scouting: Some(false),
        ..Default::default()
    })
    .expect("start a router");
    let locators = router.locators().expect("the router's locators");
    let at = locators.iter().find(|l| l.starts_with("tcp/127.0.0.1:")).expect("a loopback locator").clone();
    let url = format!("zenoh://?mode=client&scouting=0&connect={at}&team={TEAM}&key={}&hello_ms=200", key_hex());

    let serve = Proc::start(
        "serve",
        &strings(&[
            "sim",
            "serve",
            "--robots",
            "2",
            "--targets",
            "2",
            "--seed",
            "7",
            "--duration",
            "10",
            "--wait",
            "30",
            "--status-ms",
            "1000",
            "--udp",
            &url,
        ]),
    );
    let robots: Vec<Proc> = (1..=2)
        .map(|k| {
            Proc::start(
                &format!("robot-{k}"),
                &strings(&[
                    "sim",
                    "robot",
                    "--id",
                    &k.to_string(),
                    "--controller",
                    "ble",
                    "--targets",
                    "2",
                    "--seed",
                    "7",
                    "--udp",
                    &url,
                    "--status-ms",
                    "500",
                    "--duration",
                    "90",
                ]),
            )
        })
        .collect();
    let report = || format!("{}\n{}\n{}", serve.report(), robots[0].report(), robots[1].report());

    let start =
        serve.wait_line(PATIENCE, |j| j["start"] == true).unwrap_or_else(|| panic!("no start line\n{}", report()));
    assert_eq!(start["missing"], serde_json::json!([]), "every body heard its controller over Zenoh\n{}", report());
    let done =
        serve.wait_line(PATIENCE, |j| j["done"] == true).unwrap_or_else(|| panic!("the run did not end\n{}", report()));
    assert_eq!(done["stopped"], false, "{done}");
    assert!(done["radio"]["sent"].as_u64().unwrap_or(0) > 0, "the robots reported their traffic: {done}");
    let linked = serve
        .lines()
        .iter()
        .any(|j| j["robots"].as_array().is_some_and(|r| r.len() == 2 && r.iter().all(|r| r["linked"] == true)));
    assert!(linked, "a status line with both bodies linked\n{}", report());
    for (k, robot) in robots.iter().enumerate() {
        let other = 2 - k as u64;
        let line = robot.lines().into_iter().find(|j| j["body"] == true && peers(j).contains(&other));
        assert!(line.is_some(), "robot {} heard its body and robot {other}\n{}", k + 1, report());
    }
    let claimed = robots.iter().flat_map(Proc::lines).any(|j| !claims(&j).is_empty());
    assert!(claimed, "BLE claims crossed Zenoh\n{}", report());
    drop(robots);
    router.close().expect("close the router");
}

#[test]
fn the_sockets_drops_are_in_the_transport_counters() {
    ayllu_zenoh::register();
    let mut node = Node::open(
        NodeId(1),
        &format!("zenoh://?scouting=0&listen=tcp/127.0.0.1:0&team={TEAM}&key={}&hello_ms=200", key_hex()),
    )
    .expect("open the node");
    let mut config = zenoh::Config::default();
    config.insert_json5("scouting/multicast/enabled", "false").unwrap();
    config.insert_json5("listen/endpoints", "[]").unwrap();
    config.insert_json5("connect/endpoints", &format!("[\"{}\"]", common::listening(&node))).unwrap();
    let intruder = zenoh::open(config).wait().expect("a session that is not an Ayllu node");
    let count =
        |node: &Node| node.transport_counters().iter().find(|(c, _)| c == "zenoh_unattributed").map_or(0, |(_, n)| *n);
    let give_up = Instant::now() + PATIENCE;
    while count(&node) == 0 && Instant::now() < give_up {
        // Without the sender attachment every Ayllu node puts on its samples.
        intruder.put(format!("ayllu/{TEAM}/b"), vec![0u8; 16]).wait().expect("publish");
        node.run_for(Duration::from_millis(50));
    }
    assert!(count(&node) > 0, "counted: {:?}", node.transport_counters());
    intruder.close().wait().unwrap();
}
