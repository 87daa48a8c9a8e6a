//! S10 over the in-process `mem://` transport: every connection kind across nodes, to a node
//! address and to a broadcast group, run deterministically with `Lockstep`; control requests
//! for a remote source; the transport URL errors.

use ayllu::{
    BehaviorClass, ConnectOptions, ConnectionKind, DropCause, Duration, Endpoint, Lockstep, NodeId, PortSpec,
    ReplyBody, RequestStatus, RuntimeError, Value,
};

const TICK: Duration = Duration::from_millis(1);

/// Three nodes joined to group `team`, each with Relay behaviors `SRC`, `DST`, `SINK` (int
/// ports In and Out) and a local Normal connection `DST.In -> SINK.In`, so that whether a value
/// written into `DST.In` propagated shows in `SINK.In`.
fn team(name: &str) -> Lockstep {
    let mut team = Lockstep::new(name);
    for id in 1..=3 {
        let i = team.add(NodeId(id)).unwrap();
        let node = team.node(i);
        let mut relay = BehaviorClass::new("Relay");
        relay.port(PortSpec::new("In", 0i64)).unwrap();
        relay.port(PortSpec::new("Out", 0i64)).unwrap();
        node.define(relay).unwrap();
        for b in ["SRC", "DST", "SINK"] {
            node.create("Relay", b).unwrap();
        }
        node.connect(&Endpoint::local("DST", "In"), &Endpoint::local("SINK", "In"), ConnectionKind::Normal).unwrap();
        node.join("team");
    }
    team
}

fn sink(team: &Lockstep, i: usize) -> Value {
    team.nodes()[i].read("SINK", "In").unwrap()
}
fn dst(team: &Lockstep, i: usize) -> Value {
    team.nodes()[i].read("DST", "In").unwrap()
}

fn write_and_deliver(team: &mut Lockstep, node: usize, behavior: &str, port: &str, v: i64) {
    team.node(node).write(behavior, port, v).unwrap();
    // Two steps: the sender sends, the receivers apply.
    team.advance(TICK * 2, TICK);
}

#[test]
fn s10_normal_to_a_node_address_reaches_only_that_node() {
    let mut team = team("mem-normal-node");
    team.node(0)
        .connect(&Endpoint::local("SRC", "Out"), &Endpoint::node(NodeId(2), "DST", "In"), ConnectionKind::Normal)
        .unwrap();
    write_and_deliver(&mut team, 0, "SRC", "Out", 7);
    assert_eq!(dst(&team, 1), Value::Int(7));
    assert_eq!(sink(&team, 1), Value::Int(7), "S5: the remote write propagates on the receiver");
    assert_eq!(dst(&team, 2), Value::Int(0));
    let why = team.nodes()[1].why("DST", "In").unwrap();
    assert_eq!(why.supplier.map(|s| s.node), Some(NodeId(1)), "supplier names the sending node");
}

#[test]
fn s10_group_address_reaches_every_member_but_the_sender() {
    let mut team = team("mem-group");
    team.node(0)
        .connect(&Endpoint::local("SRC", "Out"), &Endpoint::group("team", "DST", "In"), ConnectionKind::Normal)
        .unwrap();
    write_and_deliver(&mut team, 0, "SRC", "Out", 5);
    assert_eq!(dst(&team, 0), Value::Int(0), "the sender is excluded");
    assert_eq!(dst(&team, 1), Value::Int(5));
    assert_eq!(dst(&team, 2), Value::Int(5));
}

#[test]
fn s6_s10_suppress_and_override_in_across_nodes_on_the_receivers_clock() {
    let mut team = team("mem-suppress");
    let p = Duration::from_millis(100);
    // Gate does not exist on Relay: connecting it is a clear error (not a silent no-op).
    let err =
        team.node(0).connect(&Endpoint::local("SRC", "Gate"), &Endpoint::local("DST", "In"), ConnectionKind::Normal);
    assert!(matches!(err, Err(RuntimeError::Core(ayllu::Error::UnknownPort { .. }))), "{err:?}");
    team.node(0)
        .connect(&Endpoint::local("SRC", "Out"), &Endpoint::node(NodeId(2), "DST", "In"), ConnectionKind::Suppress(p))
        .unwrap();
    team.node(2)
        .connect(&Endpoint::local("SRC", "Out"), &Endpoint::node(NodeId(2), "DST", "In"), ConnectionKind::Normal)
        .unwrap();
    write_and_deliver(&mut team, 0, "SRC", "Out", 1); // suppresses n2:DST.In for 100 ms
    assert_eq!(dst(&team, 1), Value::Int(0), "S6 Suppress: m is not written");
    write_and_deliver(&mut team, 2, "SRC", "Out", 9);
    assert_eq!(dst(&team, 1), Value::Int(0), "S6 Suppress: no connection may write d");
    assert!(team.nodes()[1].core().counters().get(DropCause::Suppressed) >= 1);
    team.advance(p, TICK);
    write_and_deliver(&mut team, 2, "SRC", "Out", 9);
    assert_eq!(dst(&team, 1), Value::Int(9), "S6: the window lapsed on the receiver's clock");

    // OverrideIn from node 1: its values pass, node 3's are refused while the pass holds.
    team.node(0)
        .connect(&Endpoint::local("SRC", "In"), &Endpoint::node(NodeId(2), "DST", "In"), ConnectionKind::OverrideIn(p))
        .unwrap();
    write_and_deliver(&mut team, 0, "SRC", "In", 4);
    assert_eq!(dst(&team, 1), Value::Int(4), "S6 OverrideIn: m is written");
    write_and_deliver(&mut team, 2, "SRC", "Out", 3);
    assert_eq!(dst(&team, 1), Value::Int(4), "S6 OverrideIn: others blocked");
    assert!(team.nodes()[1].core().counters().get(DropCause::OverriddenIn) >= 1);
}

#[test]
fn s6_s10_inhibit_override_out_and_write_inhibit_across_a_group() {
    let mut team = team("mem-inhibit");
    let p = Duration::from_millis(100);
    team.node(0)
        .connect(&Endpoint::local("SRC", "Out"), &Endpoint::group("team", "DST", "In"), ConnectionKind::Inhibit(p))
        .unwrap();
    write_and_deliver(&mut team, 0, "SRC", "Out", 1);
    // Own writes on the receivers are stored but do not reach SINK.
    for i in [1, 2] {
        team.node(i).write("DST", "In", 8i64).unwrap();
        assert_eq!(dst(&team, i), Value::Int(8), "S6 Inhibit: still stored");
        assert_eq!(sink(&team, i), Value::Int(0), "S6 Inhibit: nothing propagates");
    }
    team.advance(p, TICK);
    team.node(1).write("DST", "In", 6i64).unwrap();
    assert_eq!(sink(&team, 1), Value::Int(6), "lapsed");

    // WriteInhibit: node 2's own writes stop at DST; values along connections still pass.
    team.node(0)
        .connect(
            &Endpoint::local("SRC", "In"),
            &Endpoint::node(NodeId(2), "DST", "In"),
            ConnectionKind::WriteInhibit(p),
        )
        .unwrap();
    team.node(2)
        .connect(&Endpoint::local("SRC", "Out"), &Endpoint::node(NodeId(2), "DST", "In"), ConnectionKind::Normal)
        .unwrap();
    write_and_deliver(&mut team, 0, "SRC", "In", 1);
    team.node(1).write("DST", "In", 11i64).unwrap();
    assert_eq!(sink(&team, 1), Value::Int(6), "S6 WriteInhibit: own write not propagated");
    write_and_deliver(&mut team, 2, "SRC", "Out", 12);
    assert_eq!(sink(&team, 1), Value::Int(12), "S6 WriteInhibit: connection writes propagate");

    // OverrideOut from node 1 to node 3: only values along it propagate.
    team.node(0)
        .connect(
            &Endpoint::local("SINK", "Out"),
            &Endpoint::node(NodeId(3), "DST", "In"),
            ConnectionKind::OverrideOut(p),
        )
        .unwrap();
    write_and_deliver(&mut team, 0, "SINK", "Out", 21);
    assert_eq!(sink(&team, 2), Value::Int(21), "S6 OverrideOut: m written and propagated");
    team.node(2).write("DST", "In", 30i64).unwrap();
    assert_eq!(dst(&team, 2), Value::Int(30));
    assert_eq!(sink(&team, 2), Value::Int(21), "S6 OverrideOut: others stored, not propagated");
}

#[test]
fn s10_request_connect_makes_a_connection_from_another_nodes_port() {
    let mut team = team("mem-request");
    let req = team
        .node(0)
        .core_mut()
        .request_connect(
            &Endpoint::node(NodeId(3), "SRC", "Out"),
            &Endpoint::local("DST", "In"),
            ConnectionKind::Normal,
            ConnectOptions::default(),
        )
        .unwrap();
    team.advance(TICK * 3, TICK);
    let status = team.nodes()[0].core().request_status(req).unwrap();
    let RequestStatus::Done(ReplyBody::Connection(id)) = status else { panic!("request not answered: {status:?}") };
    assert!(team.nodes()[2].core().connection(id).is_some(), "the connection lives on the source's node");
    write_and_deliver(&mut team, 2, "SRC", "Out", 42);
    assert_eq!(dst(&team, 0), Value::Int(42));
    // A request for a port that does not exist fails with a reason, not silently.
    let bad = team
        .node(0)
        .core_mut()
        .request_connect(
            &Endpoint::node(NodeId(3), "SRC", "Nope"),
            &Endpoint::local("DST", "In"),
            ConnectionKind::Normal,
            ConnectOptions::default(),
        )
        .unwrap();
    team.advance(TICK * 3, TICK);
    match team.nodes()[0].core().request_status(bad).unwrap() {
        RequestStatus::Failed(why) => assert!(why.contains("Nope"), "{why}"),
        other => panic!("expected failure, got {other:?}"),
    }
}

#[test]
fn n2_requests_to_a_dead_node_are_retried_then_fail() {
    let mut team = team("mem-dead");
    let req = team
        .node(0)
        .core_mut()
        .request_connect(
            &Endpoint::node(NodeId(9), "SRC", "Out"),
            &Endpoint::local("DST", "In"),
            ConnectionKind::Normal,
            ConnectOptions::default(),
        )
        .unwrap();
    team.advance(Duration::from_secs(2), Duration::from_millis(10));
    assert!(matches!(team.nodes()[0].core().request_status(req), Some(RequestStatus::Pending { sends }) if sends > 5));
    team.advance(Duration::from_secs(10), Duration::from_millis(10));
    assert!(matches!(team.nodes()[0].core().request_status(req), Some(RequestStatus::Failed(_))));
}

#[test]
fn transport_urls_are_checked() {
    assert!(matches!(ayllu::Node::open(NodeId(1), "team"), Err(RuntimeError::BadUrl { .. })));
    assert!(matches!(ayllu::Node::open(NodeId(1), "carrier-pigeon://x"), Err(RuntimeError::BadUrl { .. })));
    let err = ayllu::Node::open(NodeId(1), "sim://arena").err().unwrap();
    assert!(err.to_string().contains("not yet supported"), "{err}");
    let _a = ayllu::Node::open(NodeId(1), "mem://dup").unwrap();
    assert!(matches!(ayllu::Node::open(NodeId(1), "mem://dup"), Err(RuntimeError::DuplicateNode { .. })));
}

#[test]
fn s8_real_time_nodes_on_threads_exchange_messages() {
    // Two nodes on the monotonic clock, each on its own thread, over mem://. The verdict is
    // whether the value arrived, never how fast.
    let mut a = ayllu::Node::open(NodeId(1), "mem://realtime").unwrap();
    let mut b = ayllu::Node::open(NodeId(2), "mem://realtime").unwrap();
    for n in [&mut a, &mut b] {
        let mut c = BehaviorClass::new("Counter");
        let out = c.port(PortSpec::new("Out", 0i64)).unwrap();
        c.port(PortSpec::new("In", 0i64)).unwrap();
        c.every_hz("Tick", 100.0, move |ctx| {
            let next = ctx.read(out).as_int().unwrap_or(0) + 1;
            let _ = ctx.write(out, next);
        })
        .unwrap();
        n.define(c).unwrap();
        n.create("Counter", "C").unwrap();
    }
    a.connect(&Endpoint::local("C", "Out"), &Endpoint::node(NodeId(2), "C", "In"), ConnectionKind::Normal).unwrap();
    let handle = std::thread::spawn(move || {
        a.run_for(std::time::Duration::from_millis(300));
        a
    });
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
    while b.read("C", "In").unwrap() == Value::Int(0) && std::time::Instant::now() < deadline {
        b.run_for(std::time::Duration::from_millis(20));
    }
    let a = handle.join().unwrap();
    let got = b.read("C", "In").unwrap().as_int().unwrap();
    assert!(got >= 1, "node 2 never heard node 1");
    assert!(a.stats().sent >= 1 && b.stats().received >= 1);
}

#[test]
fn s10_list_why_and_read_requests_answer_with_reports() {
    use ayllu::ControlBody;
    let mut team = team("mem-list");
    team.node(1).write("DST", "In", 17i64).unwrap();
    let core = team.node(0).core_mut();
    let list = core.request(NodeId(2), ControlBody::List).unwrap();
    let why = core.request(NodeId(2), ControlBody::Why { behavior: "DST".into(), port: "In".into() }).unwrap();
    let read = core.request(NodeId(2), ControlBody::Read { behavior: "DST".into(), port: "In".into() }).unwrap();
    let bad = core.request(NodeId(2), ControlBody::Read { behavior: "NOPE".into(), port: "In".into() }).unwrap();
    team.advance(TICK * 3, TICK);
    let core = team.nodes()[0].core();
    match core.request_status(list) {
        Some(RequestStatus::Done(ReplyBody::Node(report))) => {
            assert_eq!(report.node, NodeId(2));
            assert_eq!(report.behaviors.iter().map(|b| b.name.as_str()).collect::<Vec<_>>(), ["DST", "SINK", "SRC"]);
        }
        other => panic!("{other:?}"),
    }
    match core.request_status(why) {
        Some(RequestStatus::Done(ReplyBody::Port(report))) => {
            assert_eq!(report.value, Value::Int(17));
            assert_eq!(report.outgoing.len(), 1);
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(core.request_status(read), Some(RequestStatus::Done(ReplyBody::Value(Value::Int(17)))));
    assert!(matches!(core.request_status(bad), Some(RequestStatus::Failed(why)) if why.contains("NOPE")));
}
