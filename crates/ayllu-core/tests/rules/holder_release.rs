//! Rule D3.7, aggregating ports follow their holder: the value that holds a Max, Min, Sum or
//! Priority port is released when it goes stale (its lifespan ends), when the local connection
//! that supplied it is removed, or when the node that supplied it is gone (`node_lost`); the
//! next value is judged against what is still supplied. A Priority port's window is its
//! holder's lease, renewed by each of its writes, so a holder that keeps renewing is never
//! displaced by a lower priority at a window boundary.

use crate::fan_in;

use ayllu_core::*;
use fan_in::{ms, FanIn, N};
use proptest::prelude::*;

#[test]
fn a_stale_priority_holder_releases_the_port() {
    // D3.7: priority 9 written at 0 with a 100 ms lifespan; afterwards priority 3 takes the port
    // (before this rule it read absent yet refused priority 3 for good).
    let mut r =
        FanIn::with_priorities(PortSpec::new("In", 0i64).priority().lifespan(Duration::from_millis(100)), &[9, 3]);
    r.send(0, ms(0), 90i64);
    r.send(1, ms(50), 30i64);
    assert_eq!(r.read(), Value::Int(90), "still fresh: the higher priority holds");
    assert_eq!(r.dropped(DropCause::Absorbed), 1);
    r.at(ms(100));
    assert!(r.report().empty, "released at last write + lifespan");
    assert_eq!(r.read(), Value::Int(0));
    assert_eq!(r.node.get(r.agg).unwrap(), None);
    r.send(1, ms(500), 31i64);
    assert_eq!(r.read(), Value::Int(31));
    assert_eq!(r.supplier(), Some(r.source(1)));
    r.send(1, ms(5000), 32i64);
    assert_eq!(r.read(), Value::Int(32), "the new holder renews");
    // The old holder comes back: it outranks the current one again.
    r.send(0, ms(5001), 91i64);
    assert_eq!((r.read(), r.supplier()), (Value::Int(91), Some(r.source(0))));
}

#[test]
fn a_stale_max_or_min_holder_releases_the_port() {
    // D3.7 for Max and Min without a window: the extreme is held only while it is fresh.
    for (spec, high, low, expect) in
        [(PortSpec::new("In", 0.0).max(), 9.0, 3.0, 3.0), (PortSpec::new("In", 0.0).min(), 3.0, 9.0, 9.0)]
    {
        let mut r = FanIn::new(spec.lifespan(Duration::from_millis(100)), 2);
        r.send(0, ms(0), high);
        r.send(1, ms(99), low);
        assert_eq!(r.read(), Value::Float(high), "the holder's value is still fresh at 99 ms");
        r.send(1, ms(100), low);
        assert_eq!(r.read(), Value::Float(expect), "at 100 ms the stale extreme no longer counts");
        assert_eq!(r.supplier(), Some(r.source(1)));
        assert_eq!(r.propagated(), 2);
    }
}

#[test]
fn a_stale_sum_starts_again() {
    // D3.7 for Sum: a sum whose last contribution went stale is released; the next value
    // starts a new sum instead of adding to a dead one.
    let mut r = FanIn::new(PortSpec::new("In", 0i64).sum().lifespan(Duration::from_millis(100)), 2);
    r.send(0, ms(0), 5i64);
    r.send(1, ms(60), 5i64);
    r.send(0, ms(150), 1i64);
    assert_eq!(r.read(), Value::Int(11), "60 ms + 100 ms lifespan: still fresh at 150");
    r.send(1, ms(300), 2i64);
    assert_eq!(r.read(), Value::Int(2));
}

#[test]
fn a_renewing_priority_holder_keeps_the_port_across_window_boundaries() {
    // D3.7: Priority window of 100 ms; priority 9 writes every 10 ms, priority 3 every 10 ms in
    // between. The low value must never be accepted (before: it got in at 100, 200, 300 ms).
    let mut r =
        FanIn::with_priorities(PortSpec::new("In", 0i64).priority().window(Duration::from_millis(100)), &[9, 3]);
    for k in 0..100u64 {
        r.send(0, ms(10 * k), 900 + k as i64);
        r.send(1, ms(10 * k + 5), 300 + k as i64);
        assert_eq!(r.supplier(), Some(r.source(0)), "at {} ms", 10 * k + 5);
        assert_eq!(r.tap(), Value::Int(900 + k as i64));
    }
    assert_eq!(r.propagated(), 100, "only the holder's values reached the tap");
    // The holder stops after 990 ms: its lease ends 100 ms later, and the next low write wins.
    r.send(1, ms(1085), 1i64);
    assert_eq!(r.supplier(), Some(r.source(0)), "lease still running at 1085 ms");
    r.send(1, ms(1090), 2i64);
    assert_eq!((r.read(), r.supplier()), (Value::Int(2), Some(r.source(1))));
}

#[test]
fn removing_the_supplying_connection_releases_the_port() {
    // D3.7: what a removed connection supplied is no longer offered.
    let mut r = FanIn::with_priorities(PortSpec::new("In", 0i64).priority(), &[9, 3]);
    r.send(0, ms(0), 90i64);
    r.send(1, ms(1), 30i64);
    assert_eq!(r.read(), Value::Int(90));
    r.node.disconnect(r.conns[0]).unwrap();
    assert!(r.report().empty);
    r.send(1, ms(2), 31i64);
    assert_eq!((r.read(), r.supplier()), (Value::Int(31), Some(r.source(1))));
    // Removing a connection that does not hold the port changes nothing.
    let mut r = FanIn::new(PortSpec::new("In", 0i64).max(), 2);
    r.send(0, ms(0), 9i64);
    r.send(1, ms(1), 3i64);
    r.node.disconnect(r.conns[1]).unwrap();
    assert_eq!(r.read(), Value::Int(9));
}

/// A node with `Agg.P` of `spec`, receiving from other nodes over connection 1.
fn remote_rig(spec: PortSpec) -> (NodeCore, PortRef) {
    let mut n = NodeCore::new(N);
    let mut c = BehaviorClass::new("Agg");
    c.port(spec).unwrap();
    n.define(c).unwrap();
    n.create("Agg", "Agg").unwrap();
    let p = n.port("Agg", "P").unwrap();
    (n, p)
}

fn from_node(n: &mut NodeCore, t: Instant, node: u32, seq: u64, priority: i32, v: i64) {
    let m = PortMessage {
        conn: ConnectionId(1),
        seq,
        behavior: "Agg".into(),
        port: "P".into(),
        kind: ConnectionKind::Normal,
        priority,
        value: Value::Int(v),
    };
    n.receive(t, NodeId(node), Message::Port(m));
}

#[test]
fn a_lost_node_releases_what_it_holds_and_nothing_else() {
    // D3.7: the runtime calls node_lost when a peer falls silent (N6); ports held by that node
    // release, ports held by others do not.
    let (mut n, p) = remote_rig(PortSpec::new("P", 0i64).priority());
    from_node(&mut n, ms(0), 7, 1, 9, 90);
    from_node(&mut n, ms(1), 8, 1, 3, 30);
    assert_eq!(n.read(p).unwrap(), Value::Int(90));
    assert_eq!(n.node_lost(ms(2), NodeId(8)), 0, "node 8 holds nothing");
    assert_eq!(n.node_lost(ms(3), NodeId(7)), 1);
    assert!(n.why("Agg", "P").unwrap().empty);
    from_node(&mut n, ms(4), 8, 2, 3, 31);
    assert_eq!(n.read(p).unwrap(), Value::Int(31));
    assert_eq!(n.node_lost(ms(5), N), 0, "a node never loses itself");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn a_renewing_holder_is_never_displaced_by_a_lower_priority(
        lease_ms in 5u64..200,
        by_window in any::<bool>(),
        gaps in prop::collection::vec(1u64..1000, 1..40),
        others in prop::collection::vec((0u64..1000, -5i32..9, -100i64..100), 0..60),
    ) {
        // D3.7: holder at priority 9 renewing at gaps within its lease (lifespan or window); any
        // lower-priority writes at any times. After the holder's first write, the port always
        // holds the holder's latest value.
        let lease = Duration::from_millis(lease_ms);
        let spec = PortSpec::new("In", 0i64).priority();
        let spec = if by_window { spec.window(lease) } else { spec.lifespan(lease) };
        let mut prios = vec![9];
        prios.extend(others.iter().map(|o| o.1));
        let mut r = FanIn::with_priorities(spec, &prios);
        // The holder's schedule (gaps scaled to stay strictly within the lease).
        let mut t = 0u64;
        let mut events: Vec<(u64, usize, i64)> = vec![(0, 0, 0)];
        for (k, g) in gaps.iter().enumerate() {
            t += 1 + g % (lease_ms - 1).max(1);
            events.push((t, 0, k as i64 + 1));
        }
        let end = t;
        for (i, (at, _, v)) in others.iter().enumerate() {
            events.push((at % (end + 1), i + 1, *v));
        }
        events.sort_by_key(|e| (e.0, e.1 != 0));
        let mut last = None;
        for (at, who, v) in events {
            r.send(who, Instant::from_millis(at), v);
            if who == 0 {
                last = Some(v);
            }
            prop_assert_eq!(r.supplier(), Some(r.source(0)), "at {} ms", at);
            prop_assert_eq!(r.read(), Value::Int(last.unwrap()));
        }
    }

    #[test]
    fn a_silent_holder_is_released_exactly_when_its_lease_ends(
        lease_ms in 2u64..500,
        kind in prop::sample::select(vec![PortKind::Max, PortKind::Min, PortKind::Priority]),
        by_window in any::<bool>(),
        probe in 0u64..1000,
    ) {
        // D3.7: after the holder's last write at 0, a worse value from another source is absorbed
        // before `lease` and accepted from `lease` on. (A window is a lease only for Priority;
        // for Max and Min a window ends at the same instant here, since there is one write.)
        let lease = Duration::from_millis(lease_ms);
        let spec = PortSpec::new("In", 0i64).kind(kind);
        let spec = if by_window { spec.window(lease) } else { spec.lifespan(lease) };
        let mut r = FanIn::with_priorities(spec, &[9, 3]);
        let (best, worse) = if kind == PortKind::Min { (-50i64, 50i64) } else { (50, -50) };
        r.send(0, ms(0), best);
        r.send(1, ms(probe), worse);
        if probe < lease_ms {
            prop_assert_eq!((r.read(), r.supplier()), (Value::Int(best), Some(r.source(0))));
        } else {
            prop_assert_eq!((r.read(), r.supplier()), (Value::Int(worse), Some(r.source(1))));
        }
    }
}
