//! Zero configuration: nodes and the `ayllu` tool started with no `--udp` and no `AYLLU_URL`
//! find each other on one machine (multicast discovery with TTL 0, the default URL); with
//! `AYLLU_URL` set to the subnet form (TTL 1) they find each other across machines; and a
//! node of another team is named as such in the tool's error, not taken for silence.
//!
//! Each "machine" is a network namespace on a bridge that the test creates, so the multicast
//! never touches the host's own network. Without root or `ip` the tests fail, naming what is
//! missing, unless `AYLLU_SKIP=netns` asks to skip them.

use crate::common;

use std::process::Command;
use std::time::Duration;

use common::netns::Netns;
use common::{Proc, BIN};

const LIMIT: Duration = Duration::from_secs(20);
const SUBNET_URL: &str = "udp://0.0.0.0:0?discovery=239.255.65.89:7390&ttl=1";

fn namespaces(tag: &str, subnet: u8, n: usize) -> Option<Netns> {
    match Netns::create(tag, subnet, n) {
        Ok(net) => Some(net),
        Err(reason) => {
            common::unavailable("netns", &reason);
            None
        }
    }
}

/// `ayllu ARGS` in namespace `i` with `AYLLU_URL` as given (`None`: unset, the defaults).
fn command(net: &Netns, i: usize, url: Option<&str>, args: &[&str]) -> Command {
    let mut cmd = net.command(i, BIN);
    cmd.args(args);
    match url {
        Some(u) => cmd.env("AYLLU_URL", u),
        None => cmd.env_remove("AYLLU_URL"),
    };
    cmd
}

fn relay(net: &Netns, i: usize, id: u32, url: Option<&str>) -> Proc {
    let id = id.to_string();
    let args = ["node", "--id", &id, "--controller", "relay", "--status-ms", "100", "--for", "60"];
    let mut p = Proc::spawn(&format!("n{id}"), command(net, i, url, &args));
    p.wait_ready();
    p
}

fn heard(run: &common::Run) -> Vec<u64> {
    let list = run.json();
    let mut ids: Vec<u64> = list.as_array().unwrap().iter().filter_map(|p| p["node"].as_u64()).collect();
    ids.sort();
    ids
}

#[test]
fn with_no_configuration_the_tool_finds_the_nodes_of_this_machine() {
    let Some(net) = namespaces("zc", 79, 1) else { return };
    let _n1 = relay(&net, 0, 1, None);
    let _n2 = relay(&net, 0, 2, None);
    let run = common::run(command(&net, 0, None, &["list", "--json"]), LIMIT).ok();
    assert_eq!(heard(&run), [1, 2], "{run:?}");
    // The nodes found each other too, and the tool reaches a port with no address given.
    let why = common::run(command(&net, 0, None, &["why", "2", "RELAY.In", "--json"]), LIMIT).ok().json();
    assert_eq!(why["node"], 2, "{why}");
    let report = common::run(command(&net, 0, None, &["list", "1", "--json"]), LIMIT).ok().json();
    assert!(report["transport_counted"]["hellos_received"].as_u64().unwrap_or(0) > 0, "{report}");
}

#[test]
fn with_the_subnet_url_nodes_on_other_machines_are_found() {
    let Some(net) = namespaces("zs", 80, 2) else { return };
    // TTL 0 (the default) stays on its machine: a tool on the other machine hears nothing.
    let n2 = relay(&net, 0, 2, None);
    let run = common::run(command(&net, 1, None, &["list", "--timeout", "1"]), LIMIT);
    assert_eq!(run.code, Some(1), "{run:?}");
    drop(n2);
    // With the subnet URL (TTL 1) on both machines, the other machine's node is found.
    let _n1 = relay(&net, 0, 1, Some(SUBNET_URL));
    let run = common::run(command(&net, 1, Some(SUBNET_URL), &["list", "--json"]), LIMIT).ok();
    assert_eq!(heard(&run), [1], "{run:?}");
}

#[test]
fn a_node_of_another_team_is_named_as_such() {
    let Some(net) = namespaces("zt", 81, 1) else { return };
    let team5 = "udp://0.0.0.0:0?discovery=239.255.65.89:7390&ttl=0&team=5";
    let _n3 = relay(&net, 0, 3, Some(team5));
    let run = common::run(command(&net, 0, None, &["why", "3", "RELAY.In", "--timeout", "1.5"]), LIMIT)
        .fails(1, "unknown node n3");
    assert!(run.stderr.contains("another team") && run.stderr.contains("team="), "{run:?}");
    // With the team's id the same command works.
    let same = "udp://0.0.0.0:0?discovery=239.255.65.89:7390&ttl=0&team=5";
    common::run(command(&net, 0, Some(same), &["why", "3", "RELAY.In"]), LIMIT).ok();
}

/// A socket bound to a loopback address gets no multicast: a tool on `udp://127.0.0.1:0` with
/// `discovery=` never hears the HELLOs of a node that is on loopback too. Hearing nothing, it
/// says so (bind 0.0.0.0 or use peer=); bound to 0.0.0.0 the same tool finds the node.
#[test]
fn discovery_on_a_loopback_bind_is_named_when_nothing_is_heard() {
    let Some(net) = namespaces("lb", 82, 1) else { return };
    let on_loopback = "udp://127.0.0.1:0?discovery=239.255.65.89:7390&ttl=0";
    let _n4 = relay(&net, 0, 4, Some(on_loopback));
    let run =
        common::run(command(&net, 0, Some(on_loopback), &["list", "--timeout", "1"]), LIMIT).fails(1, "no node heard");
    assert!(run.stderr.contains("binds a loopback address") && run.stderr.contains("bind 0.0.0.0"), "{run:?}");
    let run = common::run(command(&net, 0, Some(on_loopback), &["why", "4", "RELAY.In", "--timeout", "1"]), LIMIT)
        .fails(1, "unknown node n4");
    assert!(run.stderr.contains("binds a loopback address"), "{run:?}");
    // The advice works: bound to any address, the tool hears the node's HELLOs.
    let any = "udp://0.0.0.0:0?discovery=239.255.65.89:7390&ttl=0";
    let run = common::run(command(&net, 0, Some(any), &["list", "--json"]), LIMIT).ok();
    assert_eq!(heard(&run), [4], "{run:?}");
}
