//! A mixed team: `udp://` nodes and `zenoh://` nodes joined by `ayllu_zenoh::Bridge` (docs/zenoh.md,
//! "A mixed team").
//! * In this process: UDP nodes 1 and 2 on loopback (each given the bridge as `peer=`), Zenoh
//!   nodes 3 and 4 in peer mode, the bridge stepped with them. Every node greets the three
//!   others; port messages, group messages, LIST/WHY/CONNECT cross both ways; a write-inhibit
//!   window opened across the bridge blocks the remote port's own writes; the team key's MACs
//!   verify end to end through the bridge, which does not hold the key; nothing loops.
//! * The same with no address given anywhere: a UDP node and the bridge on the default URL's
//!   discovery (multicast on this machine), a Zenoh node: HELLOs and group messages cross.
//! * A keyed bridge drops a forged datagram and another team's, and learns no route from them.
//! * As processes: `ayllu-zenoh bridge` joining an `ayllu-zenoh node` on `udp://` and one on
//!   `zenoh://` that run the paper's cross-subsumption: one claimer per target, `list` and
//!   `why` from the UDP side see the Zenoh node, and the survivor takes a killed node's target
//!   over.
//!
//! Ports: every socket binds port 0 and its owner says what it got: the UDP sockets (the
//! bridge's `udp`, `Node::address`) and the Zenoh listeners (`Bridge::zenoh_locators`, the
//! bridge command's `zenoh` field, `Node::address`). Every wait is bounded and only
//! ends early; timing never decides a verdict.

mod common;

use std::process::Command;
use std::time::{Duration, Instant};

use ayllu::{ConnectOptions, ConnectionKind, ControlBody, Endpoint, Node, NodeId, ReplyBody, Value, WindowKind};
use ayllu_zenoh::Bridge;
use common::{count, ints, listening, read, strings, Proc, BIN};

const TEAM: u32 = 12;
const KEY: [u8; 32] = [0x5a; 32];
const PATIENCE: Duration = Duration::from_secs(30);

fn key_hex() -> String {
    common::key_hex(&KEY)
}

fn relay_node(id: u32, url: &str) -> Node {
    common::relay_node(id, url, &["team"])
}

/// Nodes 1, 2 (udp://), 3, 4 (zenoh://) and the bridge between them.
fn mixed_team() -> (Vec<Node>, Bridge) {
    ayllu_zenoh::register();
    let bridge = Bridge::open(
        &format!("udp://127.0.0.1:0?team={TEAM}"),
        &format!("zenoh://?scouting=0&listen=tcp/127.0.0.1:0&team={TEAM}"),
    )
    .expect("open the bridge");
    let zenoh_at = bridge_locator(&bridge);
    let at = bridge.udp_address();
    let udp = |extra: &str| format!("udp://127.0.0.1:0?team={TEAM}&key={}&hello_ms=200&peer={at}{extra}", key_hex());
    let n1 = relay_node(1, &udp(""));
    let n1_at = n1.address().expect("node 1's address");
    let n2 = relay_node(2, &udp(&format!("&peer={n1_at}")));
    let zenoh = |extra: String| {
        format!("zenoh://?scouting=0&connect={zenoh_at}{extra}&team={TEAM}&key={}&hello_ms=200", key_hex())
    };
    let n3 = relay_node(3, &zenoh("&listen=tcp/127.0.0.1:0".into()));
    let n4 = relay_node(4, &zenoh(format!("&connect={}", listening(&n3))));
    (vec![n1, n2, n3, n4], bridge)
}

/// Where a bridge opened with `listen=tcp/127.0.0.1:0` listens on Zenoh, as bound.
fn bridge_locator(bridge: &Bridge) -> String {
    let at = bridge.zenoh_locators();
    assert!(at.len() == 1 && !at[0].ends_with(":0"), "the bridge's Zenoh locators: {at:?}");
    at[0].clone()
}

/// Step every node and the bridge until `done` holds or [`PATIENCE`] passes; whether it held.
fn run_until(nodes: &mut [Node], bridge: &mut Bridge, done: impl FnMut(&mut [Node]) -> bool) -> bool {
    common::run_until(nodes, PATIENCE, |n| step(n, bridge), done)
}

/// A node's turn: run it a millisecond, then let the bridge relay what it sent.
fn step(node: &mut Node, bridge: &mut Bridge) {
    node.run_for(Duration::from_millis(1));
    bridge.step(Duration::ZERO);
}

fn answer(nodes: &mut [Node], bridge: &mut Bridge, asker: usize, id: ayllu::RequestId) -> ReplyBody {
    common::answer(nodes, asker, id, PATIENCE, |n| step(n, bridge))
}

#[test]
fn udp_and_zenoh_nodes_are_one_team_through_the_bridge() {
    let (mut nodes, mut bridge) = mixed_team();
    let everyone = |nodes: &mut [Node]| {
        nodes.iter().all(|n| {
            let mut heard: Vec<u32> = n.peers().iter().map(|p| p.node.0).collect();
            heard.sort();
            heard == (1..=4).filter(|&k| k != n.id().0).collect::<Vec<_>>()
        })
    };
    assert!(run_until(&mut nodes, &mut bridge, everyone), "every node hears the three others (HELLO both ways)");
    assert_eq!(bridge.udp_nodes(), [NodeId(1), NodeId(2)]);
    assert_eq!(bridge.zenoh_nodes(), [NodeId(3), NodeId(4)]);
    // The UDP nodes reach a Zenoh node at its proxy, an ordinary UDP address.
    let proxy = bridge.proxy_address(NodeId(3)).expect("node 3's proxy").to_string();
    let seen = nodes[0].peers().into_iter().find(|p| p.node == NodeId(3)).expect("node 1 knows node 3").addr;
    assert_eq!(seen, proxy, "node 1 sends to node 3 through its proxy");
    for n in &nodes {
        assert!(n.peers().iter().all(|p| p.groups == ["team"]), "HELLOs carry the groups across");
    }

    // Port messages both ways: 1 (udp) -> 3 (zenoh), 4 (zenoh) -> 2 (udp).
    let normal = ConnectionKind::Normal;
    nodes[0].connect(&Endpoint::local("SRC", "Out"), &Endpoint::node(NodeId(3), "DST", "In"), normal).unwrap();
    nodes[0].write("SRC", "Out", 7i64).unwrap();
    nodes[3].connect(&Endpoint::local("SRC", "Out"), &Endpoint::node(NodeId(2), "DST", "In"), normal).unwrap();
    nodes[3].write("SRC", "Out", 9i64).unwrap();
    assert!(
        run_until(&mut nodes, &mut bridge, |n| read(&n[2], "DST", "In") == Value::Int(7)
            && read(&n[1], "DST", "In") == Value::Int(9)),
        "port messages cross the bridge both ways"
    );
    assert_eq!(read(&nodes[3], "DST", "In"), Value::Int(0), "node 4 was not addressed");
    assert_eq!(nodes[2].why("DST", "In").unwrap().supplier.map(|s| s.node), Some(NodeId(1)));

    // Group messages both ways reach every member but the sender.
    let group = |k: usize, nodes: &mut [Node], v: i64| {
        nodes[k].connect(&Endpoint::local("SRC", "In"), &Endpoint::group("team", "DST", "Out"), normal).unwrap();
        nodes[k].write("SRC", "In", v).unwrap();
    };
    group(0, &mut nodes, 5);
    assert!(
        run_until(&mut nodes, &mut bridge, |n| (1..4).all(|k| read(&n[k], "DST", "Out") == Value::Int(5))),
        "a UDP node's group message reaches the Zenoh members"
    );
    assert_eq!(read(&nodes[0], "DST", "Out"), Value::Int(0), "the sender is excluded");
    group(2, &mut nodes, 6);
    assert!(
        run_until(&mut nodes, &mut bridge, |n| [0, 1, 3].iter().all(|&k| read(&n[k], "DST", "Out") == Value::Int(6))),
        "a Zenoh node's group message reaches the UDP members"
    );

    // Control requests across: LIST and WHY from UDP node 2 to Zenoh node 4, CONNECT from
    // Zenoh node 4 on UDP node 1.
    let list = nodes[1].core_mut().request(NodeId(4), ControlBody::List).unwrap();
    match answer(&mut nodes, &mut bridge, 1, list) {
        ReplyBody::Node(report) => {
            assert_eq!(report.node, NodeId(4));
            assert!(report.behaviors.iter().any(|b| b.name == "SRC"), "LIST names node 4's behaviors");
        }
        other => panic!("LIST answered {other:?}"),
    }
    let why =
        nodes[1].core_mut().request(NodeId(3), ControlBody::Why { behavior: "DST".into(), port: "In".into() }).unwrap();
    match answer(&mut nodes, &mut bridge, 1, why) {
        ReplyBody::Port(report) => assert_eq!(report.value, Value::Int(7), "WHY reports node 3's value"),
        other => panic!("WHY answered {other:?}"),
    }
    let connect = nodes[3]
        .core_mut()
        .request_connect(
            &Endpoint::node(NodeId(1), "DST", "Out"),
            &Endpoint::local("DST", "In"),
            normal,
            ConnectOptions::default(),
        )
        .unwrap();
    assert!(matches!(answer(&mut nodes, &mut bridge, 3, connect), ReplyBody::Connection(_)));
    nodes[0].write("DST", "Out", 11i64).unwrap();
    assert!(
        run_until(&mut nodes, &mut bridge, |n| read(&n[3], "DST", "In") == Value::Int(11)),
        "the connection node 4 asked for carries node 1's writes to it"
    );

    // A cross-subsumption-style window across the bridge: UDP node 2 write-inhibits Zenoh
    // node 3's SRC.In (as a BLE claim does); node 3's own writes then stay in the port.
    let inhibit = ConnectionKind::WriteInhibit(ayllu::Duration::from_secs(30));
    nodes[1].connect(&Endpoint::local("SRC", "In"), &Endpoint::node(NodeId(3), "SRC", "In"), inhibit).unwrap();
    nodes[1].write("SRC", "In", 1i64).unwrap();
    let held = run_until(&mut nodes, &mut bridge, |n| {
        n[2].why("SRC", "In")
            .unwrap()
            .windows
            .iter()
            .any(|w| w.kind == WindowKind::WriteInhibit && w.holder.node == NodeId(2))
    });
    assert!(held, "node 2's write-inhibit window is open on node 3");

    for n in &nodes {
        assert_eq!(count(n, "bad_mac"), 0, "node {}: the team key verifies end to end", n.id());
        assert_eq!(count(n, "duplicate_id"), 0, "node {}: nothing looped back to its sender", n.id());
        assert_eq!(count(n, "own"), 0, "node {}: no own datagram heard back", n.id());
    }
    let counts = bridge.counts();
    let get = |c: &str| counts.iter().find(|(k, _)| k == c).map_or(0, |(_, n)| *n);
    assert!(get("to_zenoh") > 0 && get("to_udp") > 0, "{counts:?}");
    assert_eq!(get("malformed") + get("wrong_team") + get("no_route"), 0, "{counts:?}");
}

#[test]
fn a_bridge_on_the_discovery_address_joins_zero_configuration_nodes() {
    // The default URL's discovery (multicast on this machine, TTL 0): neither side is told the
    // other's address. A team of this test's own, so that other tests' discovery traffic on
    // the shared multicast address is another team's.
    ayllu_zenoh::register();
    let team = 40_000 + std::process::id() % 20_000;
    let discovery = "discovery=239.255.65.89:7390&ttl=0";
    let mut bridge = Bridge::open(
        &format!("udp://0.0.0.0:0?{discovery}&team={team}"),
        &format!("zenoh://?scouting=0&listen=tcp/127.0.0.1:0&team={team}"),
    )
    .expect("open the bridge");
    let zenoh_at = bridge_locator(&bridge);
    let key = key_hex();
    let n1 = relay_node(1, &format!("udp://0.0.0.0:0?{discovery}&team={team}&key={key}&hello_ms=200"));
    let n2 = relay_node(2, &format!("zenoh://?scouting=0&connect={zenoh_at}&team={team}&key={key}&hello_ms=200"));
    let mut nodes = vec![n1, n2];
    // Heard, and (the team is keyed) proven fresh: until a keyed round trip a sender's port
    // messages are dropped as `not_fresh` (D-N5.4), so the single write below could be lost.
    let greeted = |n: &mut [Node]| {
        n[0].peers().iter().any(|p| p.node == NodeId(2))
            && n[1].peers().iter().any(|p| p.node == NodeId(1))
            && n.iter().all(|node| count(node, "senders_fresh") >= 1)
    };
    assert!(run_until(&mut nodes, &mut bridge, greeted), "HELLOs cross between discovery and Zenoh");
    for (from, v) in [(0usize, 21i64), (1, 22)] {
        nodes[from]
            .connect(&Endpoint::local("SRC", "Out"), &Endpoint::group("team", "DST", "In"), ConnectionKind::Normal)
            .unwrap();
        nodes[from].write("SRC", "Out", v).unwrap();
        let to = 1 - from;
        assert!(
            run_until(&mut nodes, &mut bridge, |n| read(&n[to], "DST", "In") == Value::Int(v)),
            "a group message from node {} crosses the bridge",
            from + 1
        );
    }
    for n in &nodes {
        assert_eq!(count(n, "bad_mac") + count(n, "duplicate_id"), 0, "node {}", n.id());
    }
}

#[test]
fn a_keyed_bridge_relays_only_the_teams_datagrams() {
    let key = key_hex();
    let mut bridge = Bridge::open(
        &format!("udp://127.0.0.1:0?team={TEAM}&key={key}"),
        &format!("zenoh://?scouting=0&listen=tcp/127.0.0.1:0&team={TEAM}"),
    )
    .expect("open the bridge");
    let socket = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let hello = ayllu_wire::WireMessage::Hello { interval_ms: 200, name: "x".into(), groups: vec![] };
    let forged =
        ayllu_wire::encode_datagram(TEAM, NodeId(9), 1, Some([0x11; 32]), std::slice::from_ref(&hello)).unwrap();
    let good = ayllu_wire::encode_datagram(TEAM, NodeId(8), 1, Some([0x5a; 32]), std::slice::from_ref(&hello)).unwrap();
    let other_team = ayllu_wire::encode_datagram(TEAM + 1, NodeId(7), 1, Some([0x5a; 32]), &[hello]).unwrap();
    for d in [&forged, &good, &other_team] {
        socket.send_to(d, bridge.udp_address()).unwrap();
    }
    let give_up = Instant::now() + PATIENCE;
    let mut handled = 0;
    while handled < 3 && Instant::now() < give_up {
        handled += bridge.step(Duration::from_millis(100));
    }
    let counts = bridge.counts();
    let get = |c: &str| counts.iter().find(|(k, _)| k == c).map_or(0, |(_, n)| *n);
    assert_eq!((get("bad_mac"), get("wrong_team"), get("to_zenoh")), (1, 1, 1), "{counts:?}");
    assert_eq!(bridge.udp_nodes(), [NodeId(8)], "only the authenticated sender became a route");
}

#[test]
fn the_papers_team_runs_across_the_bridge_command() {
    let key = key_hex();
    let bridge = Proc::start(
        "bridge",
        &strings(&[
            "bridge",
            "--udp",
            &format!("udp://127.0.0.1:0?team={TEAM}"),
            "--zenoh",
            &format!("zenoh://?scouting=0&listen=tcp/127.0.0.1:0&team={TEAM}"),
            "--status-ms",
            "500",
            "--for",
            "120",
        ]),
    );
    let first = bridge.wait_line(PATIENCE, |j| j.get("udp").is_some()).expect("the bridge's first line");
    let at = first["udp"].as_str().unwrap().to_owned();
    // The Zenoh side's listener, as bound (port 0 resolved).
    let zenoh_at: Vec<&str> = first["zenoh"].as_array().into_iter().flatten().filter_map(|l| l.as_str()).collect();
    assert!(zenoh_at.len() == 1 && !zenoh_at[0].ends_with(":0"), "the bridge's Zenoh locators: {first}");
    let zenoh_at = zenoh_at[0].to_owned();
    let udp_url = format!("udp://127.0.0.1:0?team={TEAM}&key={key}&hello_ms=200&peer={at}");
    let zenoh_url = format!("zenoh://?scouting=0&connect={zenoh_at}&team={TEAM}&key={key}&hello_ms=200");
    let node = |id: &str, url: &str, sight: &str| {
        Proc::start(
            &format!("n{id}"),
            &strings(&["node", "--id", id, "--udp", url, "--sight", sight, "--status-ms", "300", "--for", "120"]),
        )
    };
    let n1 = node("1", &udp_url, "1:0.9,2:0.5");
    let n2 = node("2", &zenoh_url, "1:0.6,2:0.8");

    let give_up = Instant::now() + Duration::from_secs(60);
    let mut settled = false;
    while !settled && Instant::now() < give_up {
        std::thread::sleep(Duration::from_millis(100));
        if let (Some(a), Some(b)) = (n1.latest(), n2.latest()) {
            settled = ints(&a, "peers") == [2]
                && ints(&b, "peers") == [1]
                && ints(&a, "claims") == [1]
                && ints(&b, "claims") == [2];
        }
    }
    assert!(settled, "one claimer per target across the bridge: n1 {:?}, n2 {:?}", n1.latest(), n2.latest());
    let status = bridge.latest().expect("a status line");
    assert_eq!((ints(&status, "udp_nodes"), ints(&status, "zenoh_nodes")), (vec![1], vec![2]), "{status}");

    // The UDP side's tool sees the Zenoh node and asks it why (through the bridge, on udp://).
    let tool = Command::new(BIN)
        .args(["why", "2", "OBS1.Rotate", "--udp", &udp_url, "--timeout", "15"])
        .output()
        .expect("run the tool");
    let text = String::from_utf8_lossy(&tool.stdout);
    assert!(tool.status.success(), "why across the bridge: {text}{}", String::from_utf8_lossy(&tool.stderr));
    assert!(text.contains("write-inhibit held by n1"), "n1's claim (udp://) holds n2's port (zenoh://): {text}");

    // Kill the UDP node: the Zenoh node takes target 1 over.
    drop(n1);
    let took_over = n2.wait_line(Duration::from_secs(60), |j| {
        j.get("t").is_some() && ints(j, "claims").contains(&1) && !ints(j, "peers").contains(&1)
    });
    assert!(took_over.is_some(), "n2 took target 1 over: {:?}", n2.latest());
}

/// Round trip of a port write across the bridge (UDP node 1 writes Zenoh node 3's port, node 3
/// forwards it back), the nodes and the bridge in this process stepped in turn on one thread
/// (the bridge's receiving threads and Zenoh's run beside it). A figure, not a verdict:
/// `make test-zenoh` skips it; run it with
/// `cargo test --release --test zenoh_bridge -- --ignored --nocapture`.
#[test]
#[ignore]
fn round_trip_across_the_bridge() {
    let (nodes, mut bridge) = mixed_team();
    let mut nodes: Vec<Node> = nodes.into_iter().filter(|n| n.id() == NodeId(1) || n.id() == NodeId(3)).collect();
    let greeted = |n: &mut [Node]| {
        n[0].peers().iter().any(|p| p.node == NodeId(3)) && n[1].peers().iter().any(|p| p.node == NodeId(1))
    };
    assert!(run_until(&mut nodes, &mut bridge, greeted), "the pair greets across the bridge");
    let normal = ConnectionKind::Normal;
    nodes[0].connect(&Endpoint::local("SRC", "Out"), &Endpoint::node(NodeId(3), "DST", "In"), normal).unwrap();
    nodes[1].connect(&Endpoint::local("DST", "In"), &Endpoint::node(NodeId(1), "DST", "In"), normal).unwrap();
    let mut rtts = Vec::new();
    for k in 1..=500i64 {
        let t0 = Instant::now();
        nodes[0].write("SRC", "Out", k).unwrap();
        while read(&nodes[0], "DST", "In") != Value::Int(k) && t0.elapsed() < Duration::from_secs(2) {
            nodes[0].step();
            bridge.step(Duration::ZERO);
            nodes[1].step();
            bridge.step(Duration::ZERO);
        }
        if read(&nodes[0], "DST", "In") == Value::Int(k) {
            rtts.push(t0.elapsed().as_secs_f64() * 1e6);
        }
    }
    rtts.sort_by(f64::total_cmp);
    let q = |f: f64| rtts.get(((rtts.len() as f64 - 1.0) * f) as usize).copied().unwrap_or(f64::NAN);
    println!(
        "udp:// -> bridge -> zenoh:// and back: {} of 500 round trips, median {:.0} us, p90 {:.0} us, p99 {:.0} us",
        rtts.len(),
        q(0.5),
        q(0.9),
        q(0.99)
    );
}
