//! Rule S3, Priority ports: `c := m` iff `prio(m) > prio(c)`. The priority is the connection's
//! (`ConnectOptions::priority`; a behavior's own writes have priority 0). Higher wins; the
//! current supplier may update at equal priority; a different source at equal priority is
//! absorbed. Aggregating: starts empty, the first write sets whatever its priority, reset and
//! window empty it.

use crate::fan_in;

use ayllu_core::*;
use fan_in::{ms, FanIn, N};

#[test]
fn starts_empty_and_the_first_write_sets_whatever_its_priority() {
    // S3 Priority: empty until the first write, which sets even at a negative priority.
    let mut r = FanIn::with_priorities(PortSpec::new("In", 0i64).priority(), &[-5]);
    assert!(r.report().empty);
    assert!(!r.node.fresh(r.agg).unwrap());
    assert_eq!(r.read(), Value::Int(0));
    r.send(0, ms(1), 11i64);
    assert_eq!(r.read(), Value::Int(11));
    assert_eq!(r.supplier(), Some(r.source(0)));
    assert!(r.node.fresh(r.agg).unwrap());
}

#[test]
fn higher_priority_wins_lower_is_absorbed() {
    // S3 Priority: a higher priority takes the port; a lower one is absorbed (counted, not
    // propagated) whatever its value.
    let mut r = FanIn::with_priorities(PortSpec::new("In", 0i64).priority(), &[1, 5]);
    r.send(0, ms(1), 100i64);
    r.send(1, ms(2), 2i64);
    assert_eq!(r.read(), Value::Int(2));
    assert_eq!(r.supplier(), Some(r.source(1)));
    r.send(0, ms(3), 1_000i64);
    assert_eq!(r.read(), Value::Int(2));
    assert_eq!(r.dropped(DropCause::Absorbed), 1);
    assert_eq!(r.propagated(), 2);
    assert_eq!(r.tap(), Value::Int(2));
}

#[test]
fn the_current_supplier_may_update_at_equal_priority() {
    // S3 Priority: the holder keeps writing (c := m), each update propagates.
    let mut r = FanIn::with_priorities(PortSpec::new("In", 0i64).priority(), &[1, 5]);
    r.send(1, ms(1), 1i64);
    r.send(1, ms(2), 2i64);
    r.send(1, ms(3), -3i64);
    assert_eq!(r.read(), Value::Int(-3));
    assert_eq!(r.propagated(), 3);
    assert_eq!(r.dropped(DropCause::Absorbed), 0);
}

#[test]
fn a_different_source_at_equal_priority_is_absorbed() {
    // S3 Priority: equal priority from another source does not take the port, whatever the
    // source ids (the incumbent keeps it).
    for (first, second) in [(0usize, 1usize), (1, 0)] {
        let mut r = FanIn::with_priorities(PortSpec::new("In", 0i64).priority(), &[3, 3]);
        r.send(first, ms(1), 10i64);
        r.send(second, ms(2), 20i64);
        assert_eq!(r.read(), Value::Int(10));
        assert_eq!(r.supplier(), Some(r.source(first)));
        assert_eq!(r.dropped(DropCause::Absorbed), 1);
        assert_eq!(r.propagated(), 1);
    }
}

#[test]
fn own_writes_have_priority_zero() {
    // S3 Priority: a behavior's own write counts as priority 0.
    let mut r = FanIn::with_priorities(PortSpec::new("In", 0i64).priority(), &[-1, 1]);
    r.send(0, ms(1), 1i64); // priority -1
    r.own(ms(2), 2i64).unwrap(); // priority 0 > -1: wins
    assert_eq!(r.read(), Value::Int(2));
    assert_eq!(r.supplier(), Some(Source::internal(N)));
    r.send(0, ms(3), 3i64); // -1 < 0: absorbed
    assert_eq!(r.read(), Value::Int(2));
    r.send(1, ms(4), 4i64); // 1 > 0: wins
    assert_eq!(r.read(), Value::Int(4));
    // An own write below the holder's priority is absorbed: stored nowhere, but not an error.
    r.own(ms(5), 5i64).unwrap();
    assert_eq!(r.read(), Value::Int(4));
    assert_eq!(r.supplier(), Some(r.source(1)));
    assert_eq!(r.dropped(DropCause::Absorbed), 2);
}

#[test]
fn priority_ports_hold_any_type() {
    // S3 Priority: the merge needs no order on values, so text works too.
    let mut r = FanIn::with_priorities(PortSpec::new("In", Value::text("idle")).priority(), &[0, 9]);
    r.send(0, ms(1), "wander");
    r.send(1, ms(2), "avoid");
    r.send(0, ms(3), "wander");
    assert_eq!(r.read(), Value::text("avoid"));
}

#[test]
fn reset_empties_and_lets_a_lower_priority_in() {
    // S3 Priority: after reset() the port is empty again and any priority may set it.
    let mut r = FanIn::with_priorities(PortSpec::new("In", 0i64).priority(), &[1, 9]);
    r.send(1, ms(1), 9i64);
    r.send(0, ms(2), 1i64);
    assert_eq!(r.read(), Value::Int(9));
    r.node.reset(r.agg).unwrap();
    assert!(r.report().empty);
    assert_eq!(r.supplier(), None);
    r.send(0, ms(3), 1i64);
    assert_eq!(r.read(), Value::Int(1));
    assert_eq!(r.supplier(), Some(r.source(0)));
}

#[test]
fn window_end_releases_the_port() {
    // S3 Priority: when the window ends the high-priority holder loses the port.
    let mut r =
        FanIn::with_priorities(PortSpec::new("In", 0i64).priority().window(Duration::from_millis(200)), &[1, 9]);
    r.send(1, ms(0), 9i64); // window [0, 200)
    r.send(0, ms(199), 1i64);
    assert_eq!(r.read(), Value::Int(9));
    r.at(ms(200));
    assert!(r.report().empty);
    assert_eq!(r.read(), Value::Int(0));
    r.send(0, ms(200), 1i64);
    assert_eq!(r.read(), Value::Int(1));
    assert_eq!(r.supplier(), Some(r.source(0)));
}
