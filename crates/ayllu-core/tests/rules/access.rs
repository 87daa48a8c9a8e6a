//! Open teams, bounded (docs/semantics.md D9.1-D9.3): access rules for port writes and for
//! structure changes by request, limits on connections made by request and on window periods
//! from the network, and connections leased to the node that asked for them.

use ayllu_core::*;

const ME: NodeId = NodeId(1);

fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}

/// Node 1 with `R` (int ports Out, In).
fn node() -> NodeCore {
    let mut n = NodeCore::new(ME);
    let mut c = BehaviorClass::new("Relay");
    c.port(PortSpec::new("Out", 0i64)).unwrap();
    c.port(PortSpec::new("In", 0i64)).unwrap();
    n.define(c).unwrap();
    n.create("Relay", "R").unwrap();
    n
}

/// Node `from` sends request `id` with `body`; returns node 1's answer.
fn ask(n: &mut NodeCore, t: Instant, from: u32, id: u64, body: ControlBody) -> Result<ReplyBody, String> {
    n.receive(t, NodeId(from), Message::Control(ControlMessage { id, body }));
    while let Some(out) = n.pop_outgoing() {
        if let (
            Destination::Node(to),
            Message::Control(ControlMessage { id: rid, body: ControlBody::Reply { result } }),
        ) = (out.to, out.message)
        {
            if to == NodeId(from) && rid == id {
                return result;
            }
        }
    }
    panic!("no answer to request {id}");
}

fn connect_to(from: u32, kind: ConnectionKind) -> ControlBody {
    ControlBody::Connect {
        source_behavior: "R".into(),
        source_port: "Out".into(),
        destination: Endpoint::node(NodeId(from), "Echo", "In"),
        kind,
        priority: 0,
    }
}

fn port_message(conn: u64, seq: u64, kind: ConnectionKind, v: i64) -> Message {
    Message::Port(PortMessage {
        conn: ConnectionId(conn),
        seq,
        behavior: "R".into(),
        port: "In".into(),
        kind,
        priority: 0,
        value: Value::Int(v),
    })
}

/// A connection made on the node itself, in code (never leased, never capped).
fn local_connection(n: &mut NodeCore) {
    n.connect(
        &Endpoint::local("R", "Out"),
        &Endpoint::local("R", "In"),
        ConnectionKind::Normal,
        ConnectOptions::default(),
    )
    .unwrap();
}

fn remote_connections(n: &NodeCore) -> Vec<(u64, Option<NodeId>)> {
    n.report().connections.iter().map(|c| (c.id.0, c.requested_by)).collect()
}

#[test]
fn structure_changes_by_request_follow_the_access_rule() {
    // D9.2: with `structure: Nobody` a CONNECT is refused with a reason and counted
    // not_allowed; reads stay open. With `Only`, listed nodes may, others may not.
    let mut n = node();
    n.set_access(Access { structure: Allow::Nobody, ..Access::default() });
    let refused = ask(&mut n, ms(0), 7, 1, connect_to(7, ConnectionKind::Normal)).unwrap_err();
    assert!(refused.contains("not allowed") && refused.contains("n7"), "{refused}");
    assert_eq!(n.counters().get(DropCause::NotAllowed), 1);
    assert!(remote_connections(&n).is_empty());
    assert!(matches!(ask(&mut n, ms(1), 7, 2, ControlBody::List), Ok(ReplyBody::Node(_))), "LIST stays open");

    n.set_access(Access { structure: Allow::Only(vec![NodeId(7)]), ..Access::default() });
    assert!(matches!(ask(&mut n, ms(2), 7, 3, connect_to(7, ConnectionKind::Normal)), Ok(ReplyBody::Connection(_))));
    assert!(ask(&mut n, ms(3), 8, 1, connect_to(8, ConnectionKind::Normal)).is_err());
    assert_eq!(remote_connections(&n).len(), 1);
    // DISCONNECT is a structure change too.
    let c = remote_connections(&n)[0].0;
    assert!(ask(&mut n, ms(4), 8, 2, ControlBody::Disconnect { conn: ConnectionId(c) }).is_err());
    assert!(ask(&mut n, ms(5), 7, 4, ControlBody::Disconnect { conn: ConnectionId(c) }).is_ok());
}

#[test]
fn port_writes_follow_the_access_rule() {
    // D9.2: port messages from a node without the right are dropped (not_allowed) before
    // anything else, windows included; the right is separate from the structure right.
    let mut n = node();
    n.set_access(Access { ports: Allow::Only(vec![NodeId(7)]), structure: Allow::Everyone });
    n.receive(ms(0), NodeId(8), port_message(1, 1, ConnectionKind::OverrideIn(Duration::from_secs(5)), 8));
    assert_eq!(n.counters().get(DropCause::NotAllowed), 1);
    assert!(n.why("R", "In").unwrap().windows.is_empty(), "no window from a refused message");
    n.receive(ms(1), NodeId(7), port_message(1, 1, ConnectionKind::Normal, 7));
    assert_eq!(n.read(n.port("R", "In").unwrap()).unwrap(), Value::Int(7));
    // And the own code is never restricted.
    n.set_access(Access { ports: Allow::Nobody, structure: Allow::Nobody });
    n.write_named(ms(2), "R", "In", 3i64).unwrap();
    assert_eq!(n.read(n.port("R", "In").unwrap()).unwrap(), Value::Int(3));
}

#[test]
fn windows_longer_than_the_limit_are_refused_not_clamped() {
    // D9.3: an override-out of 164 years from the network is dropped and counted too_long; a
    // CONNECT asking for one is refused with the limit in its reason.
    let mut n = node();
    let years = Duration::from_secs(164 * 365 * 24 * 3600);
    n.receive(ms(0), NodeId(7), port_message(1, 1, ConnectionKind::OverrideOut(years), 1));
    assert_eq!(n.counters().get(DropCause::TooLong), 1);
    assert!(n.why("R", "In").unwrap().windows.is_empty());
    let limit = n.limits().max_remote_period;
    n.receive(ms(1), NodeId(7), port_message(1, 2, ConnectionKind::Inhibit(limit), 1));
    assert_eq!(n.why("R", "In").unwrap().windows.len(), 1, "up to the limit is fine");
    let refused = ask(&mut n, ms(2), 7, 1, connect_to(7, ConnectionKind::Suppress(years))).unwrap_err();
    assert!(refused.contains("limit"), "{refused}");
}

#[test]
fn connections_made_by_request_are_capped_per_node_and_in_all() {
    let mut n = node();
    n.set_limits(Limits { remote_connections: 5, remote_connections_per_node: 3, ..Limits::default() });
    for id in 1..=3 {
        assert!(ask(&mut n, ms(id), 7, id, connect_to(7, ConnectionKind::Normal)).is_ok());
    }
    let refused = ask(&mut n, ms(4), 7, 4, connect_to(7, ConnectionKind::Normal)).unwrap_err();
    assert!(refused.contains("3 per node"), "{refused}");
    assert!(ask(&mut n, ms(5), 8, 1, connect_to(8, ConnectionKind::Normal)).is_ok());
    assert!(ask(&mut n, ms(6), 8, 2, connect_to(8, ConnectionKind::Normal)).is_ok());
    let refused = ask(&mut n, ms(7), 9, 1, connect_to(9, ConnectionKind::Normal)).unwrap_err();
    assert!(refused.contains("5 in all"), "{refused}");
    assert_eq!(n.counters().get(DropCause::NotAllowed), 2);
    // Connections made in code do not count and are not capped.
    for _ in 0..10 {
        local_connection(&mut n);
    }
}

#[test]
fn a_lost_requester_takes_its_connections_with_it() {
    // D9.1: a connection made by request is leased to its requester: when the runtime says
    // that node is gone, the connection goes; connections made here stay.
    let mut n = node();
    assert!(ask(&mut n, ms(0), 7, 1, connect_to(7, ConnectionKind::Normal)).is_ok());
    assert!(ask(&mut n, ms(1), 8, 1, connect_to(8, ConnectionKind::Normal)).is_ok());
    local_connection(&mut n);
    let before = remote_connections(&n);
    assert_eq!(before.iter().filter(|(_, by)| by.is_some()).count(), 2);
    n.node_lost(ms(2), NodeId(7));
    let after = remote_connections(&n);
    assert_eq!(after.len(), 2, "{after:?}");
    assert!(after.iter().all(|(_, by)| *by != Some(NodeId(7))));
    assert!(after.iter().any(|(_, by)| by.is_none()), "made here: stays");
}

/// Node 1 with `R` and 100 behaviors of 40 ports each: a large LIST answer.
fn large_node() -> NodeCore {
    let mut n = node();
    let mut big = BehaviorClass::new("Big");
    for p in 0..40 {
        big.port(PortSpec::new(&format!("P{p}"), 0i64)).unwrap();
    }
    n.define(big).unwrap();
    for b in 0..100 {
        n.create("Big", &format!("B{b}")).unwrap();
    }
    n
}

#[test]
fn remembered_answers_are_bounded_in_bytes_not_only_in_count() {
    // N2 answers repeats from memory; a thousand LIST answers of a large node held 262 MB. The
    // memory is bounded in bytes (2 MiB): with big reports, old answers are forgotten long
    // before the count bound, and a repeat is answered afresh.
    let mut n = large_node();
    let behaviors = |r: Result<ReplyBody, String>| match r {
        Ok(ReplyBody::Node(report)) => report.behaviors.len(),
        other => panic!("{other:?}"),
    };
    assert_eq!(behaviors(ask(&mut n, ms(0), 7, 1, ControlBody::List)), 101);
    n.create("Relay", "NEW").unwrap();
    // A repeat while remembered: the same answer as before (idempotent).
    assert_eq!(behaviors(ask(&mut n, ms(1), 7, 1, ControlBody::List)), 101);
    // Twenty more large answers push it out of the byte budget (the count bound is 1024).
    for id in 2..22 {
        ask(&mut n, ms(id), 7, id, ControlBody::List).unwrap();
    }
    assert_eq!(behaviors(ask(&mut n, ms(30), 7, 1, ControlBody::List)), 102, "answered afresh");
}

#[test]
fn answers_waiting_to_be_sent_are_bounded_in_bytes() {
    // A turn receives everything waiting on its socket: a flood of LIST requests, each from an
    // invented id (so under every per-sender rate), made a large answer each, all waiting in
    // the outbox at once. Beyond 2 MiB of answers waiting (estimated), requests are dropped
    // unanswered (`rate_limited`) until the outbox has been sent; requesters retry (N2).
    let mut n = large_node();
    let list = || Message::Control(ControlMessage { id: 1, body: ControlBody::List });
    for from in 100..300 {
        n.receive(ms(1), NodeId(from), list());
    }
    let mut answered = 0;
    while n.pop_outgoing().is_some() {
        answered += 1;
    }
    assert!((2..200).contains(&answered), "{answered} answers waited together");
    assert_eq!(n.counters().get(DropCause::RateLimited), 200 - answered);
    // Once sent, the next requests are answered again, a repeat from memory included.
    n.receive(ms(2), NodeId(100), list());
    n.receive(ms(2), NodeId(299), list());
    assert_eq!(std::iter::from_fn(|| n.pop_outgoing()).count(), 2);
}

#[test]
fn requests_over_a_senders_rate_are_dropped_unanswered() {
    // D9.3: a burst of 100 requests, then 50 a second, per sender; beyond that no answer (an
    // answer is the traffic the limit bounds) and a count. Other senders are not affected.
    let mut n = node();
    let read = || ControlBody::Read { behavior: "R".into(), port: "In".into() };
    let answered = |n: &mut NodeCore, t: Instant, from: u32, ids: std::ops::Range<u64>| {
        let mut got = 0;
        for id in ids {
            n.receive(t, NodeId(from), Message::Control(ControlMessage { id, body: read() }));
            while let Some(out) = n.pop_outgoing() {
                got += usize::from(matches!(out.message, Message::Control(_)));
            }
        }
        got
    };
    assert_eq!(answered(&mut n, ms(0), 7, 0..150), 100);
    assert_eq!(n.counters().get(DropCause::RateLimited), 50);
    assert_eq!(answered(&mut n, ms(0), 8, 0..10), 10, "another sender has its own rate");
    assert_eq!(answered(&mut n, ms(1000), 7, 150..200), 50, "50 more after one second");
    assert_eq!(answered(&mut n, ms(1000), 7, 200..201), 0);
}
