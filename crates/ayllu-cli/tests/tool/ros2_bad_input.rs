//! Bad input at a live ROS 2 body: misbehaving publishers on the independent stack (Cyclone DDS
//! from Python: `peer.py bad`) and mistyped mapping files. A sample that cannot be used is
//! dropped and counted by topic and cause, the counts are in `ayllu list`, the node keeps
//! running and keeps taking good samples; a publisher DDS will never match (another type) is
//! counted and named in a warning; a mapping file's mistake is refused naming the field and the
//! fix.
//!
//! Built only with `--features ros2` (`make test-ros2`); each test in a network namespace of
//! its own.

#![cfg(feature = "ros2")]

use crate::common;

use std::time::Duration;

use common::ros2::{own_network, peer, temp_file};
use common::{ayllu, wait_for, Proc, BIN};
use serde_json::Value as Json;

const MAPPING: &str = r#"
[ros2]
node = "bad_input"

[[topic]]
name = "/bad/float"
type = "std_msgs/msg/Float64"
direction = "in"
qos = "default"
fields = { data = "R.F" }

[[topic]]
name = "/bad/scan"
type = "sensor_msgs/msg/LaserScan"
direction = "in"
fields = { ranges = "S.Ranges" }

[[topic]]
name = "/bad/twist"
type = "geometry_msgs/msg/Twist"
direction = "in"
qos = "default"
fields = { "linear.x" = "T.X", "angular.z" = "T.Z" }
"#;

fn list(url: &str) -> Json {
    ayllu(&["list", "1", "--json", "--udp", url], Duration::from_secs(10)).ok().json()
}

fn counted(j: &Json, key: &str) -> u64 {
    j["body_counted"][key].as_u64().unwrap_or(0)
}

/// The value `behavior.port` holds in a `list --json` report.
fn port_value(j: &Json, behavior: &str, port: &str) -> Json {
    let b =
        j["behaviors"].as_array().into_iter().flatten().find(|b| b["name"] == behavior).cloned().unwrap_or_default();
    b["ports"]
        .as_array()
        .into_iter()
        .flatten()
        .find(|p| p["name"] == port)
        .map(|p| p["value"].clone())
        .unwrap_or_default()
}

#[test]
fn bad_samples_are_dropped_and_counted_by_cause_and_the_node_runs_on() {
    own_network();
    let domain = 0;
    let mapping = temp_file("bad.toml", MAPPING);
    let mut cmd = std::process::Command::new(BIN);
    cmd.args(["node", "--id", "1", "--controller", "relay", "--ros2"])
        .arg(&mapping)
        .args(["--for", "120", "--status-ms", "500"])
        .env("ROS_DOMAIN_ID", domain.to_string());
    let mut node = Proc::spawn("ayllu node", cmd);
    let address = node.wait_ready();
    let url = format!("udp://127.0.0.1:0?peer={address}");

    let bad = |topic: &str, kind: &str, ty: &str, count: &str| {
        let out = peer(
            "peer.py",
            domain,
            &[
                "bad",
                "--topic",
                topic,
                "--kind",
                kind,
                "--type",
                ty,
                "--count",
                count,
                "--rate",
                "20",
                "--wait-match",
                "10",
                "--linger",
                "1",
            ],
        )
        .output()
        .expect("peer.py bad");
        assert!(
            out.status.success() || kind == "wrong_type",
            "peer.py bad {kind} on {topic}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    bad("/bad/float", "truncated", "Float64", "10");
    bad("/bad/scan", "truncated", "LaserScan", "10");
    bad("/bad/scan", "huge", "LaserScan", "2");
    bad("/bad/twist", "nan", "Twist", "10");
    bad("/bad/float", "nan", "Float64", "10");

    let j = wait_for(Duration::from_secs(15), Duration::from_millis(500), || {
        let j = list(&url);
        (counted(&j, "/bad/float truncated") > 0
            && counted(&j, "/bad/scan truncated") > 0
            && counted(&j, "/bad/scan too_long") > 0
            && counted(&j, "/bad/twist nan") > 0
            && counted(&j, "/bad/float nan") > 0)
            .then_some(j)
    })
    .unwrap_or_else(|| panic!("not every bad sample was counted: {}", list(&url)["body_counted"]));
    eprintln!("body counters after the bad publishers: {}", j["body_counted"]);
    // Nothing bad was written: the ports hold their defaults.
    assert_eq!(port_value(&j, "R", "F"), serde_json::json!({"Float": 0.0}), "{j}");
    assert_eq!(port_value(&j, "T", "X"), serde_json::json!({"Float": 0.0}), "{j}");
    for key in ["/bad/float taken", "/bad/twist taken"] {
        assert_eq!(counted(&j, key), 0, "{key}: {}", j["body_counted"]);
    }

    // A publisher of another type on the same topic: DDS never matches it, so no sample can
    // arrive; it is counted as a publisher of the wrong type and named in a warning.
    let mut wrong = Proc::spawn(
        "wrong type",
        peer(
            "peer.py",
            domain,
            &["bad", "--topic", "/bad/float", "--kind", "wrong_type", "--count", "100", "--rate", "10"],
        ),
    );
    let j = wait_for(Duration::from_secs(15), Duration::from_millis(500), || {
        let j = list(&url);
        (counted(&j, "/bad/float wrong_type_publishers") > 0).then_some(j)
    })
    .unwrap_or_else(|| panic!("the wrong-type publisher was never counted: {}", list(&url)));
    let warnings = j["warnings"].to_string();
    assert!(warnings.contains("/bad/float") && warnings.contains("std_msgs/msg/String"), "{warnings}");
    wrong.kill();

    // The node runs on and takes a good sample.
    let out = peer(
        "peer.py",
        domain,
        &[
            "publish",
            "--topic",
            "/bad/float",
            "--type",
            "Float64",
            "--values",
            r#"{"data": 3.5}"#,
            "--rate",
            "10",
            "--count",
            "5",
            "--wait-match",
            "10",
        ],
    )
    .output()
    .expect("peer.py publish");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let j = wait_for(Duration::from_secs(10), Duration::from_millis(300), || {
        let j = list(&url);
        (port_value(&j, "R", "F") == serde_json::json!({"Float": 3.5})).then_some(j)
    })
    .unwrap_or_else(|| panic!("the good sample never arrived: {}", list(&url)));
    assert!(counted(&j, "/bad/float taken") >= 1);
    assert!(node.exited().is_none(), "the node stopped: {}", node.stderr());
    assert!(!node.stderr().contains("panicked"), "{}", node.stderr());
}

/// A mapping file with a mistake is refused before anything starts, with the file, the place
/// and the fix in the message.
#[test]
fn a_mistyped_mapping_file_is_refused_naming_the_field_and_the_fix() {
    own_network();
    let base = r#"[ros2]
node = "typo"

[[topic]]
name = "cmd_vel"
type = "geometry_msgs/msg/Twist"
direction = "out"
fields = { "linear.x" = "BASE.Translate" }
"#;
    for (wrong, right, needle) in [
        ("direction = \"out\"", "directon = \"out\"", "did you mean `direction`?"),
        ("geometry_msgs/msg/Twist", "geometry_msgs/Twist", "did you mean \"geometry_msgs/msg/Twist\"?"),
        ("\"linear.x\"", "\"linear.xx\"", "did you mean `linear.x`?"),
        ("\"BASE.Translate\"", "\"BASE\"", "write \"BEHAVIOR.Port\""),
        ("fields =", "qos = \"sensor\"\nfields =", "did you mean \"sensor_data\"?"),
        ("[ros2]", "[ros2]\ndomain = 300", "from 0 to 232"),
    ] {
        let text = base.replace(wrong, right);
        assert_ne!(text, base, "{wrong}");
        let path = temp_file("typo.toml", &text);
        let run = ayllu(
            &["node", "--id", "1", "--controller", "wander", "--ros2", path.to_str().unwrap(), "--for", "5"],
            Duration::from_secs(20),
        );
        let run = run.fails(1, needle);
        assert!(run.stderr.contains("typo.toml"), "the message names the file: {}", run.stderr);
        eprintln!("{}", run.stderr.trim());
    }
}
