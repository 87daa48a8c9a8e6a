//! The `ayllu-zenoh` tool against a node of this process over `zenoh://` (Zenoh peer mode on
//! loopback port 0, the port the system chose read back from the node): `list NODE`, `write` then `why` answer as the `ayllu`
//! tool does over `udp://`. Every wait is bounded (the tool's own `--timeout`, and a deadline
//! here); timing never decides a verdict.

mod common;

use std::process::Output;
use std::time::Duration as StdDuration;

use ayllu::{BehaviorClass, Node, NodeId, PortSpec, Value};

const TEAM: u32 = 12;

/// Run the tool while stepping `node`, so it can answer; the tool's output.
fn tool(node: &mut Node, args: &[&str], url: &str) -> Output {
    common::run_tool(args, url, StdDuration::from_secs(30), || node.run_for(StdDuration::from_millis(5)))
}

#[test]
fn the_tool_lists_writes_and_explains_over_zenoh() {
    ayllu_zenoh::register();
    let key: String = "5a".repeat(32);
    let mut node = Node::open(
        NodeId(1),
        &format!("zenoh://?scouting=0&listen=tcp/127.0.0.1:0&team={TEAM}&key={key}&hello_ms=200&name=robot"),
    )
    .expect("open the node");
    let mut relay = BehaviorClass::new("Relay");
    relay.port(PortSpec::new("In", 0i64)).unwrap();
    node.define(relay).unwrap();
    node.create("Relay", "MOTOR").unwrap();
    let url = format!("zenoh://?scouting=0&connect={}&team={TEAM}&key={key}", common::listening(&node));

    let out = tool(&mut node, &["list", "1"], &url);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "list failed: {text}{}", String::from_utf8_lossy(&out.stderr));
    assert!(text.contains("MOTOR"), "list names the behavior: {text}");

    let out = tool(&mut node, &["write", "1", "MOTOR.In", "42"], &url);
    assert!(out.status.success(), "write failed: {}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(node.read("MOTOR", "In").unwrap(), Value::Int(42), "the write reached the node");

    let out = tool(&mut node, &["why", "1", "MOTOR.In"], &url);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "why failed: {}", String::from_utf8_lossy(&out.stderr));
    assert!(text.contains("42"), "why reports the value: {text}");
}
