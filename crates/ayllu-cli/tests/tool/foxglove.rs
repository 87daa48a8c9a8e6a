//! Foxglove, live and recorded, with clients that are not ours: a Python WebSocket client
//! written from the `foxglove.websocket.v1` protocol (crates/ayllu-foxglove/tests/
//! foxglove_ws_client.py, on the `websockets` package) subscribes to `ayllu foxglove`'s topics
//! and receives the values a live team of `ayllu node` processes holds; the `mcap` package
//! (the reference Python reader) reads back what `sim run --mcap` wrote.
//!
//! The Python packages come from scripts/install-test-tools (`make test` runs it first).
//! Without them the tests fail and say so; `AYLLU_SKIP_PYTHON_CLIENTS=1` turns that into a
//! loud skip. Every wait is bounded; timing decides nothing (a value is waited for, then
//! checked).

#![cfg(feature = "foxglove")]

use crate::common;

use std::path::PathBuf;
use std::process::Command;
use std::time::Duration;

use common::{ayllu, start_on_loopback, wait_for, Proc, BIN};
use serde_json::{json, Value as Json};

/// How long a value may take to reach the client (polling at 5 Hz; a loaded machine).
const ARRIVAL: Duration = Duration::from_secs(30);
const LIMIT: Duration = Duration::from_secs(120);

fn python() -> String {
    std::env::var("PYTHON").unwrap_or_else(|_| "python3".to_owned())
}

fn script(name: &str) -> String {
    format!("{}/../ayllu-foxglove/tests/{name}", env!("CARGO_MANIFEST_DIR"))
}

/// Whether the Python packages are there; panics (or skips, see the module docs) if not.
fn python_ready(modules: &str) -> bool {
    let ok =
        Command::new(python()).args(["-c", &format!("import {modules}")]).output().is_ok_and(|o| o.status.success());
    if ok {
        return true;
    }
    if std::env::var_os("AYLLU_SKIP_PYTHON_CLIENTS").is_some() {
        eprintln!("SKIPPED: {} cannot import {modules} (AYLLU_SKIP_PYTHON_CLIENTS is set)", python());
        return false;
    }
    panic!("{} cannot import {modules}: run scripts/install-test-tools (or set AYLLU_SKIP_PYTHON_CLIENTS=1)", python());
}

/// The messages the client printed for `topic`.
fn received(client: &Proc, topic: &str) -> Vec<Json> {
    client.lines().into_iter().filter(|(_, j)| j["topic"] == topic).map(|(_, j)| j).collect()
}

fn wait_message(client: &Proc, fox: &Proc, topic: &str, what: &str, check: impl Fn(&Json) -> bool) -> Json {
    wait_for(ARRIVAL, Duration::from_millis(50), || received(client, topic).into_iter().find(|m| check(&m["message"])))
        .unwrap_or_else(|| {
            panic!(
                "no message on {topic} with {what} within {ARRIVAL:?}; got {:?}\nclient stderr: {}\nfoxglove: {:?}\n{}",
                received(client, topic),
                client.stderr(),
                fox.latest(),
                fox.stderr()
            )
        })
}

#[test]
fn a_websocket_client_receives_the_live_teams_values_windows_and_claims() {
    if !python_ready("websockets") {
        return;
    }
    // Node 1 relays (every connection kind by hand); nodes 2 and 3 run the paper's
    // cross-subsumption and both see target 1, so one of them claims OBS1 through BLE.
    let (_nodes, addrs) = start_on_loopback(
        3,
        |k| format!("node{}", k + 1),
        |k, url| {
            let id = (k + 1).to_string();
            let mut a: Vec<String> =
                ["node", "--id", &id, "--status-ms", "500", "--for", "150", "--udp", url].map(str::to_owned).to_vec();
            if k == 0 {
                a.extend(["--controller", "relay"].map(str::to_owned));
            } else {
                a.extend(["--layers", "2", "--sight", if k == 1 { "1:0.9" } else { "1:0.5" }].map(str::to_owned));
            }
            a
        },
    );
    let peers: Vec<String> = addrs.iter().map(|a| format!("peer={a}")).collect();
    let url = format!("udp://127.0.0.1:0?{}", peers.join("&"));
    let mut cmd = Command::new(BIN);
    // The tool's own node is replaced every 300 requests here (2000 by default), so that the
    // values written below also have to arrive through a renewed node.
    cmd.args(["foxglove", "--udp", &url, "--port", "0", "--for", "150", "--status-ms", "500", "--renew-after", "300"]);
    let mut fox = Proc::spawn("ayllu foxglove", cmd);
    let ws = fox.wait_ready();
    assert!(ws.starts_with("ws://127.0.0.1:") && !ws.ends_with(":0"), "{ws}");

    let mut cmd = Command::new(python());
    cmd.args([&script("foxglove_ws_client.py"), &ws, "--seconds", "140"]);
    for topic in ["/n1/RELAY/Aux", "/n1/FRELAY/Aux", "/n1/RELAY/Aux/windows", "/ble/OBS1", "/n2/OBS1/Local"] {
        cmd.args(["--topic", topic]);
    }
    let client = Proc::spawn("python client", cmd);

    // The SDK negotiates the v1 protocol under its current name (`foxglove.websocket.v1` was
    // its old one; the client offers both).
    let hello = wait_for(ARRIVAL, Duration::from_millis(50), || {
        client.lines().into_iter().map(|(_, j)| j).find(|j| j["subprotocol"].is_string())
    })
    .unwrap_or_else(|| panic!("no serverInfo: {}", client.stderr()));
    assert_eq!(hello, json!({"server": "ayllu", "subprotocol": "foxglove.sdk.v1"}));

    // Values written into node 1 arrive on its port topics, in the layout's shape.
    let node1 = format!("udp://127.0.0.1:0?peer={}", addrs[0]);
    for v in ["41", "42"] {
        ayllu(&["write", "1", "RELAY.In", v, "--udp", &node1], LIMIT).ok();
        let m = wait_message(&client, &fox, "/n1/RELAY/Aux", &format!("value {v}"), |m| {
            m["value"] == json!(v.parse::<i64>().unwrap())
        });
        assert_eq!(
            m["message"],
            json!({"node": 1, "behavior": "RELAY", "port": "Aux", "type": "int", "value": v.parse::<i64>().unwrap()})
        );
    }
    ayllu(&["write", "1", "FRELAY.In", "-2.5", "--udp", &node1], LIMIT).ok();
    wait_message(&client, &fox, "/n1/FRELAY/Aux", "value -2.5", |m| m["value"] == json!(-2.5));
    // Only values that were written ever arrived, in the order written, with rising log times.
    let values: Vec<i64> =
        received(&client, "/n1/RELAY/Aux").iter().map(|m| m["message"]["value"].as_i64().unwrap()).collect();
    assert!(values.windows(2).all(|w| w[0] <= w[1]), "{values:?}");
    assert!(values.iter().all(|v| [0, 41, 42].contains(v)), "{values:?}");
    let times: Vec<u64> = received(&client, "/n1/RELAY/Aux").iter().map(|m| m["log_time"].as_u64().unwrap()).collect();
    assert!(times.windows(2).all(|w| w[0] < w[1]), "{times:?}");

    // A suppression written by a tool that then exits is found by the WHY sweep.
    ayllu(&["write", "1", "RELAY.Aux", "7", "--kind", "suppress", "--period", "60", "--udp", &node1], LIMIT).ok();
    let w = wait_message(&client, &fox, "/n1/RELAY/Aux/windows", "a suppress window", |m| m["open"] == json!(1));
    assert_eq!(w["message"]["windows"][0]["kind"], "suppress");
    assert_eq!(w["message"]["input_blocked"], "suppressed");
    let left = w["message"]["remaining"]["suppress"].as_f64().unwrap();
    assert!(left > 0.0 && left <= 60.0, "{w}");

    // BLE: node 2 or node 3 claims OBS1 (both see target 1), and the claim is published.
    let c = wait_message(&client, &fox, "/ble/OBS1", "a claimer", |m| m["claimer"].as_u64().is_some_and(|n| n > 0));
    let claimer = c["message"]["claimer"].as_u64().unwrap();
    assert!([2, 3].contains(&claimer), "{c}");
    assert_eq!(c["message"]["group"], "Peers");
    assert_eq!(c["message"]["members"], json!([2, 3]));
    wait_message(&client, &fox, "/n2/OBS1/Local", "an eligibility", |m| m["type"] == "float");

    let status = fox.latest().expect("status lines").1;
    assert_eq!(status["nodes"], json!([1, 2, 3]), "{status}");
    assert_eq!(status["clients"], json!(1), "{status}");

    // After a renewal of the tool's node, values still arrive (the nodes are greeted again).
    wait_for(ARRIVAL, Duration::from_millis(100), || fox.latest().filter(|(_, s)| s["renewals"].as_u64() >= Some(1)))
        .unwrap_or_else(|| panic!("no renewal after 300 requests: {:?}", fox.latest()));
    ayllu(&["write", "1", "FRELAY.In", "4.25", "--udp", &node1], LIMIT).ok();
    wait_message(&client, &fox, "/n1/FRELAY/Aux", "value 4.25 after a renewal", |m| m["value"] == json!(4.25));
}

fn scratch(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("foxglove-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn a_simulator_run_written_to_mcap_reads_back_with_the_reference_reader() {
    if !python_ready("mcap") {
        return;
    }
    let dir = scratch("sim");
    let scenario = dir.join("short.toml");
    std::fs::write(&scenario, "controller = \"BLE\"\nrobots = 3\ntargets = 4\nseed = 2\nduration = 10.0\n").unwrap();
    let file = dir.join("run.mcap");
    let run =
        ayllu(&["sim", "run", scenario.to_str().unwrap(), "--json", "--mcap", file.to_str().unwrap()], LIMIT).ok();
    assert!(run.stderr.contains("51 frames"), "{run:?}");
    assert_eq!(run.json()["controller"], "BLE");

    let out = Command::new(python()).args([&script("mcap_summary.py"), file.to_str().unwrap()]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let summary: Json = serde_json::from_slice(&out.stdout).unwrap();
    let topics = &summary["topics"];
    // 10 s at one frame every 0.2 s, frame 0 included.
    let frames = 51;
    assert_eq!(topics["/sim/scene"]["schema"], "foxglove.SceneUpdate");
    assert_eq!(topics["/sim/scene"]["schema_encoding"], "protobuf");
    assert_eq!(topics["/sim/scene"]["count"], frames);
    assert_eq!(topics["/sim/tf"]["schema"], "foxglove.FrameTransforms");
    assert_eq!(topics["/sim/tf"]["count"], frames);
    for n in 1..=4 {
        let ble = &topics[format!("/ble/OBS{n}")];
        assert_eq!(ble["schema"], "ayllu.BleClaims");
        assert_eq!(ble["count"], frames);
    }
    // Every robot's ports, on the team channels (the layout of `ayllu record`).
    for node in 1..=3 {
        let local = &topics[format!("/n{node}/OBS1/Local")];
        assert_eq!(local["schema"], "ayllu.PortValue.float", "{local}");
        assert_eq!(local["schema_encoding"], "jsonschema");
        assert_eq!(local["message_encoding"], "json");
        assert_eq!(local["count"], frames);
        assert_eq!(local["first"]["node"], node);
        assert_eq!(local["first"]["port"], "Local");
    }
    assert_eq!(summary["in_order"], true, "messages are written in log-time order");
    // The same run again is refused rather than overwritten; into another file it is the same
    // bytes (log times are virtual time, the simulator is deterministic).
    ayllu(&["sim", "run", scenario.to_str().unwrap(), "--mcap", file.to_str().unwrap()], LIMIT).fails(1, "run.mcap");
    let again = dir.join("again.mcap");
    ayllu(&["sim", "run", scenario.to_str().unwrap(), "--mcap", again.to_str().unwrap()], LIMIT).ok();
    assert!(std::fs::read(&file).unwrap() == std::fs::read(&again).unwrap(), "two runs of one seed differ");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `foxglove --mcap FILE` names FILE when it cannot write it: a file that exists (never
/// replaced, left as it was) or one it cannot create. Checked before the server starts.
#[test]
fn foxglove_names_the_mcap_file_it_cannot_create() {
    let dir = scratch("live-mcap");
    let existing = dir.join("earlier.mcap");
    std::fs::write(&existing, b"an earlier session").unwrap();
    let foxglove = |file: &std::path::Path| {
        let file = file.display().to_string();
        ayllu(&["foxglove", "--port", "0", "--for", "1", "--udp", "udp://127.0.0.1:0", "--mcap", &file], LIMIT)
    };
    let run = foxglove(&existing).fails(1, &format!("{} exists (an MCAP file is never replaced)", existing.display()));
    assert!(run.stdout.is_empty(), "refused before the server started: {run:?}");
    assert_eq!(std::fs::read(&existing).unwrap(), b"an earlier session");
    let unreachable = dir.join("no-such-dir").join("live.mcap");
    foxglove(&unreachable).fails(1, &format!("cannot create {}", unreachable.display()));
    let fresh = dir.join("fresh.mcap");
    foxglove(&fresh).ok();
    assert!(fresh.exists(), "the server wrote the file the check removed");
}
