//! Rule S10 (with S6, S8, N1, N2) across nodes: every connection kind works over a node address
//! `(node, behavior, port)` and over a group address `(group, behavior, port)` — delivered to
//! every member but the sender — with the kind and period applied on the *receiver's* clock;
//! stale sequence numbers are dropped (`Stale`); a remote node can be asked to make (and
//! remove) a connection from its port (`request_connect`), reliably and idempotently.
//!
//! Three `NodeCore`s are joined by the in-test shuttle (`tests/shuttle`), which moves
//! `pop_outgoing()` messages into the destinations' `receive()`; group membership is decided
//! by the test.

use crate::shuttle;

use ayllu_core::*;
use shuttle::Team;

fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}

const P: Duration = Duration::from_millis(100);

#[derive(Copy, Clone, Debug)]
enum Addr {
    Node,
    Group,
}

/// Nodes 1, 2, 3 in group `team`. Each has `Tx.Out`, `Src.Out`, `Rx.In`, `Tap.In` (all int),
/// with `Src.Out -> Rx.In -> Tap.In` wired locally (Normal).
fn team() -> Team {
    let mut t = Team::new(&[1, 2, 3]);
    t.group("team", &[1, 2, 3]);
    for n in &mut t.nodes {
        for (class, port) in [("Tx", "Out"), ("Src", "Out"), ("Rx", "In"), ("Tap", "In")] {
            let mut c = BehaviorClass::new(class);
            c.port(PortSpec::new(port, 0i64)).unwrap();
            n.define(c).unwrap();
            n.create(class, class).unwrap();
        }
        n.join("team");
        let normal = ConnectionKind::Normal;
        n.connect(&Endpoint::local("Src", "Out"), &Endpoint::local("Rx", "In"), normal, ConnectOptions::default())
            .unwrap();
        n.connect(&Endpoint::local("Rx", "In"), &Endpoint::local("Tap", "In"), normal, ConnectOptions::default())
            .unwrap();
    }
    t
}

/// Connect node 1's `Tx.Out` to `Rx.In` on node 2 (Node) or on the group (Group).
fn wire(t: &mut Team, addr: Addr, kind: ConnectionKind) -> (ConnectionId, Vec<u32>, Vec<u32>) {
    let (dest, receivers, others) = match addr {
        Addr::Node => (Endpoint::node(NodeId(2), "Rx", "In"), vec![2], vec![1, 3]),
        Addr::Group => (Endpoint::group("team", "Rx", "In"), vec![2, 3], vec![1]),
    };
    let c = t.node(1).connect(&Endpoint::local("Tx", "Out"), &dest, kind, ConnectOptions::default()).unwrap();
    (c, receivers, others)
}

fn rx(t: &Team, n: u32) -> PortReport {
    t.get(n).why("Rx", "In").unwrap()
}
fn tap(t: &Team, n: u32) -> Value {
    let node = t.get(n);
    node.read(node.port("Tap", "In").unwrap()).unwrap()
}
fn src(t: &mut Team, n: u32, at: Instant, v: i64) {
    t.node(n).write_named(at, "Src", "Out", v).unwrap();
}
/// Node 1's `Tx` writes at `sent` (node 1's clock); the shuttle delivers at `arrives`
/// (receivers' clocks).
fn send(t: &mut Team, sent: Instant, arrives: Instant, v: i64) {
    t.node(1).write_named(sent, "Tx", "Out", v).unwrap();
    t.shuttle(arrives);
}

#[test]
fn normal_over_node_and_group() {
    // S10/S6 Normal: the value is written and propagates on every receiver, and only there —
    // a group message does not come back to its sender.
    for addr in [Addr::Node, Addr::Group] {
        let mut t = team();
        let (c, receivers, others) = wire(&mut t, addr, ConnectionKind::Normal);
        t.node(1).write_named(ms(0), "Tx", "Out", 7i64).unwrap();
        let out = t.drain();
        assert_eq!(out.len(), 1, "{addr:?}: one message, whatever the number of receivers");
        let expected_to = match addr {
            Addr::Node => Destination::Node(NodeId(2)),
            Addr::Group => Destination::Group("team".into()),
        };
        assert_eq!(out[0].1.to, expected_to);
        for (from, o) in out {
            t.deliver(ms(0), from, o);
        }
        for &n in &receivers {
            let r = rx(&t, n);
            assert_eq!(r.value, Value::Int(7), "{addr:?} node {n}");
            assert_eq!(r.supplier, Some(Source::connection(NodeId(1), c)));
            assert_eq!(tap(&t, n), Value::Int(7));
        }
        for &n in &others {
            assert!(!rx(&t, n).fresh, "{addr:?}: node {n} must not receive");
            assert_eq!(tap(&t, n), Value::Int(0));
        }
        assert_eq!(t.get(1).connection(c).unwrap().sent, 1);
    }
}

#[test]
fn suppress_over_node_and_group_uses_the_receivers_clock() {
    // S6 Suppress + S8: m is not written; connection writes into Rx.In are refused until
    // t + p, t being when the *receiver* applied the message (its clock: 500 ms, while the
    // sender's clock said 0).
    for addr in [Addr::Node, Addr::Group] {
        let mut t = team();
        let (_, receivers, others) = wire(&mut t, addr, ConnectionKind::Suppress(P));
        send(&mut t, ms(0), ms(500), 7);
        for &n in &receivers {
            assert!(!rx(&t, n).fresh, "{addr:?}: a Suppress message is not written");
            src(&mut t, n, ms(550), 1);
            assert_eq!(rx(&t, n).value, Value::Int(0), "{addr:?} node {n}: suppressed");
            assert_eq!(rx(&t, n).counters.get(DropCause::Suppressed), 1);
            src(&mut t, n, ms(600), 2);
            assert_eq!(rx(&t, n).value, Value::Int(2), "{addr:?} node {n}: window over at 600");
            assert_eq!(tap(&t, n), Value::Int(2));
        }
        for &n in &others {
            src(&mut t, n, ms(550), 1);
            assert_eq!(rx(&t, n).value, Value::Int(1), "{addr:?}: node {n} is not suppressed");
        }
    }
}

#[test]
fn inhibit_over_node_and_group() {
    // S6 Inhibit: m is not written; Rx.In still stores but nothing propagates until t + p.
    for addr in [Addr::Node, Addr::Group] {
        let mut t = team();
        let (_, receivers, others) = wire(&mut t, addr, ConnectionKind::Inhibit(P));
        send(&mut t, ms(0), ms(500), 7);
        for &n in &receivers {
            assert!(!rx(&t, n).fresh);
            src(&mut t, n, ms(550), 1);
            assert_eq!(rx(&t, n).value, Value::Int(1), "{addr:?}: stored");
            assert_eq!(tap(&t, n), Value::Int(0), "{addr:?} node {n}: not propagated");
            assert_eq!(rx(&t, n).counters.get(DropCause::Inhibited), 1);
            src(&mut t, n, ms(600), 2);
            assert_eq!(tap(&t, n), Value::Int(2));
        }
        for &n in &others {
            src(&mut t, n, ms(550), 1);
            assert_eq!(tap(&t, n), Value::Int(1));
        }
    }
}

#[test]
fn override_in_over_node_and_group() {
    // S6 OverrideIn: m is written and propagated; until t + p only this connection (the remote
    // sender's connection is the pass holder) may write Rx.In; a later message refreshes.
    for addr in [Addr::Node, Addr::Group] {
        let mut t = team();
        let (c, receivers, others) = wire(&mut t, addr, ConnectionKind::OverrideIn(P));
        send(&mut t, ms(0), ms(500), 7);
        for &n in &receivers {
            assert_eq!(rx(&t, n).value, Value::Int(7), "{addr:?}");
            assert_eq!(tap(&t, n), Value::Int(7));
            src(&mut t, n, ms(550), 1);
            assert_eq!(rx(&t, n).value, Value::Int(7), "{addr:?} node {n}: local input replaced");
            assert_eq!(rx(&t, n).counters.get(DropCause::OverriddenIn), 1);
            let w = &rx(&t, n).windows;
            assert_eq!(w.len(), 1);
            assert_eq!(
                (w[0].kind, w[0].holder, w[0].ends),
                (WindowKind::OverrideIn, Source::connection(NodeId(1), c), ms(600))
            );
        }
        send(&mut t, ms(10), ms(560), 8); // pass holder writes again: end := 660
        for &n in &receivers {
            assert_eq!(rx(&t, n).value, Value::Int(8));
            src(&mut t, n, ms(600), 2);
            assert_eq!(rx(&t, n).value, Value::Int(8), "{addr:?}: refreshed to 660");
            src(&mut t, n, ms(660), 3);
            assert_eq!(rx(&t, n).value, Value::Int(3));
        }
        for &n in &others {
            assert_eq!(rx(&t, n).value, Value::Int(0));
            assert!(rx(&t, n).windows.is_empty());
        }
    }
}

#[test]
fn override_out_over_node_and_group() {
    // S6 OverrideOut: m is written and propagated; until t + p only values arriving along this
    // connection propagate out of Rx.In (others are stored, not passed on).
    for addr in [Addr::Node, Addr::Group] {
        let mut t = team();
        let (_, receivers, _) = wire(&mut t, addr, ConnectionKind::OverrideOut(P));
        send(&mut t, ms(0), ms(500), 7);
        for &n in &receivers {
            assert_eq!(tap(&t, n), Value::Int(7), "{addr:?}");
            src(&mut t, n, ms(550), 1);
            assert_eq!(rx(&t, n).value, Value::Int(1), "{addr:?}: stored");
            assert_eq!(tap(&t, n), Value::Int(7), "{addr:?} node {n}: not propagated");
            assert_eq!(rx(&t, n).counters.get(DropCause::OverriddenOut), 1);
        }
        send(&mut t, ms(20), ms(570), 9); // the pass holder's values keep flowing
        for &n in &receivers {
            assert_eq!(tap(&t, n), Value::Int(9));
            src(&mut t, n, ms(670), 2);
            assert_eq!(tap(&t, n), Value::Int(2), "{addr:?}: window over at 670");
        }
    }
}

#[test]
fn write_inhibit_over_node_and_group() {
    // S6 WriteInhibit: m is not written; until t + p the receiver's own writes into Rx.In are
    // stored but not propagated, while values arriving through connections still are.
    for addr in [Addr::Node, Addr::Group] {
        let mut t = team();
        let (_, receivers, others) = wire(&mut t, addr, ConnectionKind::WriteInhibit(P));
        send(&mut t, ms(0), ms(500), 7);
        for &n in &receivers {
            assert!(!rx(&t, n).fresh, "{addr:?}: a WriteInhibit message is not written");
            t.node(n).write_named(ms(550), "Rx", "In", 3i64).unwrap();
            assert_eq!(rx(&t, n).value, Value::Int(3));
            assert_eq!(tap(&t, n), Value::Int(0), "{addr:?} node {n}: own write held back");
            assert_eq!(rx(&t, n).counters.get(DropCause::WriteInhibited), 1);
            src(&mut t, n, ms(560), 4);
            assert_eq!(tap(&t, n), Value::Int(4), "{addr:?}: connection writes still pass");
            t.node(n).write_named(ms(600), "Rx", "In", 5i64).unwrap();
            assert_eq!(tap(&t, n), Value::Int(5));
        }
        for &n in &others {
            t.node(n).write_named(ms(550), "Rx", "In", 3i64).unwrap();
            assert_eq!(tap(&t, n), Value::Int(3));
        }
    }
}

#[test]
fn stale_sequence_numbers_are_dropped() {
    // N1/S10: each connection numbers its messages; a receiver ignores one not newer than the
    // newest it applied from that (node, connection) — reordered or duplicated.
    let mut t = team();
    wire(&mut t, Addr::Node, ConnectionKind::Normal);
    t.node(1).write_named(ms(0), "Tx", "Out", 1i64).unwrap();
    t.node(1).write_named(ms(1), "Tx", "Out", 2i64).unwrap();
    let out = t.drain();
    let seqs: Vec<u64> = out
        .iter()
        .map(|(_, o)| match &o.message {
            Message::Port(p) => p.seq,
            other => panic!("unexpected {other:?}"),
        })
        .collect();
    assert_eq!(seqs, vec![1, 2]);
    let (first, second) = (out[0].clone(), out[1].clone());
    t.deliver(ms(5), second.0, second.1.clone());
    t.deliver(ms(6), first.0, first.1); // overtaken: stale
    t.deliver(ms(7), second.0, second.1); // duplicate: stale
    assert_eq!(rx(&t, 2).value, Value::Int(2));
    assert_eq!(rx(&t, 2).accepted, 1);
    assert_eq!(t.get(2).counters().get(DropCause::Stale), 2);
}

#[test]
fn sequence_numbers_are_per_sender_and_connection() {
    // N1: the same connection id and seq from another node is a different stream.
    let mut t = team();
    let msg = |v: i64| {
        Message::Port(PortMessage {
            conn: ConnectionId(5),
            seq: 1,
            behavior: "Rx".into(),
            port: "In".into(),
            kind: ConnectionKind::Normal,
            priority: 0,
            value: Value::Int(v),
        })
    };
    t.node(2).receive(ms(1), NodeId(1), msg(10));
    t.node(2).receive(ms(2), NodeId(3), msg(30));
    assert_eq!(rx(&t, 2).value, Value::Int(30));
    assert_eq!(rx(&t, 2).supplier, Some(Source { node: NodeId(3), conn: 5 }));
    assert_eq!(t.get(2).counters().get(DropCause::Stale), 0);
}

#[test]
fn a_stale_special_message_does_not_refresh_its_window() {
    // N1 + S6: a stale Suppress is dropped before it takes effect.
    let mut t = team();
    wire(&mut t, Addr::Node, ConnectionKind::Suppress(P));
    t.node(1).write_named(ms(0), "Tx", "Out", 1i64).unwrap();
    t.node(1).write_named(ms(0), "Tx", "Out", 2i64).unwrap();
    let out = t.drain();
    t.deliver(ms(0), out[1].0, out[1].1.clone()); // suppressed until 100
    t.deliver(ms(90), out[0].0, out[0].1.clone()); // stale: must not extend to 190
    src(&mut t, 2, ms(100), 4);
    assert_eq!(rx(&t, 2).value, Value::Int(4));
}

#[test]
fn group_delivery_follows_membership() {
    // S10: who is in the group is the transport's business; the core sends one group message
    // and each member applies it on its own.
    let mut t = team();
    t.groups.clear();
    t.group("team", &[1, 3]);
    let (_, _, _) = wire(&mut t, Addr::Group, ConnectionKind::Normal);
    send(&mut t, ms(0), ms(0), 6);
    assert_eq!(rx(&t, 3).value, Value::Int(6));
    assert!(!rx(&t, 2).fresh);
}

fn control_to(out: &Outgoing) -> (NodeId, u64) {
    match (&out.to, &out.message) {
        (Destination::Node(n), Message::Control(c)) => (*n, c.id),
        other => panic!("expected a control message to a node, got {other:?}"),
    }
}

#[test]
fn request_connect_from_a_remote_source_is_idempotent() {
    // S9/S10 + N2: node 1 asks node 2 to connect node 2's Tx.Out to node 1's Rx.In; a
    // duplicated request makes one connection and gets the same answer twice; the requester
    // ends Done with the connection id, and values flow.
    let mut t = team();
    let src_ep = Endpoint::node(NodeId(2), "Tx", "Out");
    let rid = t
        .node(1)
        .request_connect(&src_ep, &Endpoint::local("Rx", "In"), ConnectionKind::Normal, ConnectOptions::default())
        .unwrap();
    assert_eq!(t.get(1).request_status(rid), Some(RequestStatus::Pending { sends: 1 }));
    let before = t.get(2).report().connections.len();
    let req = t.node(1).pop_outgoing().unwrap();
    assert_eq!(control_to(&req).0, NodeId(2));
    t.node(2).receive(ms(1), NodeId(1), req.message.clone());
    t.node(2).receive(ms(2), NodeId(1), req.message.clone());
    let conns = t.get(2).report().connections;
    assert_eq!(conns.len(), before + 1, "a duplicated request must not connect twice");
    let made = conns.last().unwrap().clone();
    assert_eq!(made.source, Endpoint::local("Tx", "Out"));
    assert_eq!(made.destination, Endpoint::node(NodeId(1), "Rx", "In"));
    let mut replies = Vec::new();
    while let Some(o) = t.node(2).pop_outgoing() {
        replies.push(o);
    }
    assert_eq!(replies.len(), 2);
    for r in &replies {
        match &r.message {
            Message::Control(ControlMessage { id, body: ControlBody::Reply { result } }) => {
                assert_eq!(*id, control_to(&req).1);
                assert_eq!(result, &Ok(ReplyBody::Connection(made.id)));
            }
            other => panic!("expected a reply, got {other:?}"),
        }
    }
    for r in replies {
        t.node(1).receive(ms(3), NodeId(2), r.message);
    }
    assert_eq!(t.get(1).request_status(rid), Some(RequestStatus::Done(ReplyBody::Connection(made.id))));
    // The connection works.
    t.node(2).write_named(ms(4), "Tx", "Out", 12i64).unwrap();
    t.shuttle(ms(4));
    assert_eq!(rx(&t, 1).value, Value::Int(12));
    assert_eq!(rx(&t, 1).supplier, Some(Source::connection(NodeId(2), made.id)));
    // Done requests are not re-sent.
    t.node(1).poll(ms(10_000));
    assert_eq!(t.get(1).outgoing_len(), 0);
}

#[test]
fn request_connect_is_retried_until_answered() {
    // N2: an unanswered request is sent again (same id) at the retry interval.
    let mut t = team();
    let rid = t
        .node(1)
        .request_connect(
            &Endpoint::node(NodeId(2), "Tx", "Out"),
            &Endpoint::node(NodeId(1), "Rx", "In"),
            ConnectionKind::Normal,
            ConnectOptions::default(),
        )
        .unwrap();
    let lost = t.node(1).pop_outgoing().unwrap(); // lost in the network
    assert!(t.node(1).poll_at().is_some(), "a pending request keeps the node's schedule");
    t.node(1).poll(ms(100));
    assert_eq!(t.get(1).outgoing_len(), 0, "not yet");
    let at = t.get(1).poll_at().unwrap();
    t.node(1).poll(at);
    let again = t.node(1).pop_outgoing().expect("retried");
    assert_eq!(control_to(&again), control_to(&lost));
    assert_eq!(t.get(1).request_status(rid), Some(RequestStatus::Pending { sends: 2 }));
    t.deliver(at, NodeId(1), again);
    t.shuttle(at);
    assert!(matches!(t.get(1).request_status(rid), Some(RequestStatus::Done(_))));
    // The late original arriving now changes nothing (idempotent).
    let n_conns = t.get(2).report().connections.len();
    t.deliver(at, NodeId(1), lost);
    t.shuttle(at);
    assert_eq!(t.get(2).report().connections.len(), n_conns);
}

#[test]
fn a_special_connection_to_a_group_by_request() {
    // S10: special kinds work over every address, including one made by request: node 1 has
    // node 2 override-in Rx.In on the rest of the group.
    let mut t = team();
    let rid = t
        .node(1)
        .request_connect(
            &Endpoint::node(NodeId(2), "Tx", "Out"),
            &Endpoint::group("team", "Rx", "In"),
            ConnectionKind::OverrideIn(P),
            ConnectOptions::default(),
        )
        .unwrap();
    t.shuttle(ms(0));
    let Some(RequestStatus::Done(ReplyBody::Connection(c))) = t.get(1).request_status(rid) else { panic!("not done") };
    t.node(2).write_named(ms(0), "Tx", "Out", 5i64).unwrap();
    t.shuttle(ms(0));
    for n in [1, 3] {
        assert_eq!(rx(&t, n).value, Value::Int(5));
        assert_eq!(rx(&t, n).windows[0].holder, Source::connection(NodeId(2), c));
        src(&mut t, n, ms(50), 1);
        assert_eq!(rx(&t, n).value, Value::Int(5), "node {n}: overridden");
    }
    assert!(!rx(&t, 2).fresh, "the sender is not in its own broadcast");
}

#[test]
fn a_failing_request_reports_why() {
    // N2: a request the remote node cannot honour ends Failed with its reason; the remote
    // counts a bad request.
    let mut t = team();
    let rid = t
        .node(1)
        .request_connect(
            &Endpoint::node(NodeId(2), "Tx", "Nope"),
            &Endpoint::local("Rx", "In"),
            ConnectionKind::Normal,
            ConnectOptions::default(),
        )
        .unwrap();
    t.shuttle(ms(0));
    match t.get(1).request_status(rid) {
        Some(RequestStatus::Failed(why)) => assert!(why.contains("Nope") && why.contains("Tx"), "{why}"),
        other => panic!("expected Failed, got {other:?}"),
    }
    assert_eq!(t.get(2).counters().get(DropCause::BadRequest), 1);
}

#[test]
fn request_disconnect_removes_the_remote_connection() {
    // S9 by request: the remote connection goes away, values stop.
    let mut t = team();
    let rid = t
        .node(1)
        .request_connect(
            &Endpoint::node(NodeId(2), "Tx", "Out"),
            &Endpoint::local("Rx", "In"),
            ConnectionKind::Normal,
            ConnectOptions::default(),
        )
        .unwrap();
    t.shuttle(ms(0));
    let Some(RequestStatus::Done(ReplyBody::Connection(c))) = t.get(1).request_status(rid) else { panic!("not done") };
    let d = t.node(1).request_disconnect(NodeId(2), c);
    t.shuttle(ms(1));
    assert_eq!(t.get(1).request_status(d), Some(RequestStatus::Done(ReplyBody::Connection(c))));
    assert!(t.get(2).connection(c).is_none());
    t.node(2).write_named(ms(2), "Tx", "Out", 1i64).unwrap();
    assert_eq!(t.shuttle(ms(2)), 0);
    assert!(!rx(&t, 1).fresh);
}

#[test]
fn request_connect_rejects_bad_sources_locally() {
    // S10: a group is never a source; a period must be above zero.
    let mut t = team();
    let n = t.node(1);
    let dst = Endpoint::local("Rx", "In");
    let e = n.request_connect(
        &Endpoint::group("team", "Tx", "Out"),
        &dst,
        ConnectionKind::Normal,
        ConnectOptions::default(),
    );
    assert_eq!(e, Err(Error::GroupSource));
    let e = n.request_connect(
        &Endpoint::node(NodeId(2), "Tx", "Out"),
        &dst,
        ConnectionKind::Inhibit(Duration::ZERO),
        ConnectOptions::default(),
    );
    assert!(matches!(e, Err(Error::ZeroPeriod { .. })));
    assert_eq!(n.outgoing_len(), 0);
}

/// N1/N2 across a restart: a node that comes back under the same id numbers its messages and
/// requests from a higher base (`set_sequence_base`, the runtime passes its boot time), so the
/// peer neither drops its new values as stale nor answers its new requests from memory.
#[test]
fn n1_n2_a_node_restarted_under_the_same_id_is_not_taken_for_its_old_self() {
    fn sender(base: u64) -> NodeCore {
        let mut a = NodeCore::new(NodeId(1));
        a.set_sequence_base(base);
        let mut c = BehaviorClass::new("Tx");
        c.port(PortSpec::new("Out", 0i64)).unwrap();
        a.define(c).unwrap();
        a.create("Tx", "Tx").unwrap();
        a.connect(
            &Endpoint::local("Tx", "Out"),
            &Endpoint::node(NodeId(2), "Rx", "In"),
            ConnectionKind::Normal,
            ConnectOptions::default(),
        )
        .unwrap();
        a
    }
    let mut b = NodeCore::new(NodeId(2));
    let mut c = BehaviorClass::new("Rx");
    c.port(PortSpec::new("In", 0i64)).unwrap();
    b.define(c).unwrap();
    b.create("Rx", "Rx").unwrap();
    let deliver = |a: &mut NodeCore, b: &mut NodeCore, now: Instant| {
        while let Some(out) = a.pop_outgoing() {
            b.receive(now, NodeId(1), out.message);
        }
        while let Some(out) = b.pop_outgoing() {
            a.receive(now, NodeId(2), out.message);
        }
    };
    // The first life writes five values and reads once.
    let mut a = sender(1 << 32);
    for v in 1..=5u64 {
        a.write_named(ms(v), "Tx", "Out", v as i64).unwrap();
        deliver(&mut a, &mut b, ms(v));
    }
    let first = a.request(NodeId(2), ControlBody::Read { behavior: "Rx".into(), port: "In".into() }).unwrap();
    deliver(&mut a, &mut b, ms(6));
    assert_eq!(a.request_status(first), Some(RequestStatus::Done(ReplyBody::Value(Value::Int(5)))));
    // The second life, started later: its first value is applied, not dropped as stale.
    let mut a = sender(2 << 32);
    a.write_named(ms(10), "Tx", "Out", 42i64).unwrap();
    deliver(&mut a, &mut b, ms(10));
    assert_eq!(b.read(b.port("Rx", "In").unwrap()).unwrap(), Value::Int(42));
    assert_eq!(b.counters().get(DropCause::Stale), 0);
    // Its first request is a new request, answered afresh.
    let second = a.request(NodeId(2), ControlBody::Read { behavior: "Rx".into(), port: "In".into() }).unwrap();
    assert_ne!(second, first);
    deliver(&mut a, &mut b, ms(11));
    assert_eq!(a.request_status(second), Some(RequestStatus::Done(ReplyBody::Value(Value::Int(42)))));
    // `sent` still counts messages, not the base.
    assert_eq!(a.report().connections[0].sent, 1);
}
