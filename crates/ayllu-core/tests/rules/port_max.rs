//! Rule S3, Max ports: `c := max(c, m)`, aggregating (starts empty, first write sets, `reset()`
//! and the declared window empty it), remembers who supplied the maximum, ties go to the smaller
//! `Source` whatever the arrival order, equal values are accepted (and so propagate, S5),
//! smaller ones are absorbed and counted, NaN is refused.

use crate::fan_in;

use ayllu_core::*;
use fan_in::{ms, FanIn, N};

fn max_int(k: usize) -> FanIn {
    FanIn::new(PortSpec::new("In", 0i64).max(), k)
}

#[test]
fn starts_empty_reads_default_and_is_not_fresh() {
    // S3 Max: aggregating ports start empty (read = default, fresh = false).
    let r = FanIn::new(PortSpec::new("In", 42i64).max(), 1);
    assert_eq!(r.read(), Value::Int(42));
    assert!(!r.node.fresh(r.agg).unwrap());
    assert_eq!(r.node.get(r.agg).unwrap(), None);
    let rep = r.report();
    assert!(rep.empty);
    assert_eq!(rep.supplier, None);
    assert_eq!(rep.last_accepted, None);
}

#[test]
fn first_write_sets_even_below_the_default() {
    // S3 Max: the first write into an empty port sets it; the default takes no part in the max.
    let mut r = max_int(1);
    r.send(0, ms(1), -5i64);
    assert_eq!(r.read(), Value::Int(-5));
    assert!(r.node.fresh(r.agg).unwrap());
    assert!(!r.report().empty);
    assert_eq!(r.supplier(), Some(r.source(0)));
    assert_eq!(r.propagated(), 1);
}

#[test]
fn keeps_the_maximum_and_remembers_its_supplier() {
    // S3 Max: c := max(c, m); the port remembers which connection supplied the maximum.
    let mut r = max_int(3);
    r.send(0, ms(1), 3i64);
    r.send(1, ms(2), 7i64);
    r.send(2, ms(3), 5i64);
    assert_eq!(r.read(), Value::Int(7));
    assert_eq!(r.supplier(), Some(r.source(1)));
    assert_eq!(r.supplier(), Some(Source { node: N, conn: r.conns[1].0 }));
    // 3 and 7 were accepted and propagated; 5 was absorbed.
    assert_eq!(r.propagated(), 2);
    assert_eq!(r.tap(), Value::Int(7));
    assert_eq!(r.dropped(DropCause::Absorbed), 1);
    assert_eq!(r.node.counters().get(DropCause::Absorbed), 1);
}

#[test]
fn absorbed_values_stay_counted_on_the_node_when_the_port_goes() {
    // The node's Absorbed figure is its ports' counts summed (they are kept on the ports
    // only): what a removed behavior's ports absorbed stays in it, and other causes are
    // counted on the node as before.
    let mut r = max_int(2);
    r.send(0, ms(1), 9i64);
    r.send(1, ms(2), 4i64);
    r.send(1, ms(3), 5i64);
    r.own(ms(4), 1i64).unwrap(); // a behavior's own write is absorbed too
    assert_eq!(r.dropped(DropCause::Absorbed), 3);
    assert_eq!(r.node.counters().get(DropCause::Absorbed), 3);
    assert_eq!(r.node.counters().total(), 3);
    r.node.remove("Agg").unwrap();
    assert_eq!(r.node.counters().get(DropCause::Absorbed), 3, "kept after the port is gone");
    r.node.create("Agg", "Agg").unwrap();
    let agg = r.node.port("Agg", "In").unwrap();
    r.node.write(ms(5), agg, 8i64).unwrap();
    r.node.write(ms(6), agg, 2i64).unwrap();
    assert_eq!(r.node.counters().get(DropCause::Absorbed), 4, "the new port's count adds up");
    assert_eq!(r.node.counters().total(), 4);
}

#[test]
fn smaller_value_is_absorbed_counted_and_not_propagated() {
    // S3 Max + S5: a value below the maximum is absorbed (counted), nothing propagates.
    let mut r = max_int(2);
    r.send(0, ms(1), 10i64);
    r.send(1, ms(2), 9i64);
    r.send(1, ms(3), -100i64);
    assert_eq!(r.read(), Value::Int(10));
    assert_eq!(r.supplier(), Some(r.source(0)));
    assert_eq!(r.dropped(DropCause::Absorbed), 2);
    assert_eq!(r.propagated(), 1);
    // An absorbed value is not an accepted one: last_accepted stays at the first write (S4).
    assert_eq!(r.report().last_accepted, Some(ms(1)));
}

#[test]
fn equal_value_is_accepted_and_propagates() {
    // S3 Max / S5: a value equal to the maximum is accepted, so it propagates again.
    let mut r = max_int(2);
    r.send(0, ms(1), 4i64);
    assert_eq!(r.propagated(), 1);
    r.send(1, ms(2), 4i64);
    assert_eq!(r.propagated(), 2);
    r.send(0, ms(3), 4i64);
    assert_eq!(r.propagated(), 3);
    assert_eq!(r.dropped(DropCause::Absorbed), 0);
    assert_eq!(r.report().last_accepted, Some(ms(3)));
    // The smaller source keeps the tie.
    assert_eq!(r.supplier(), Some(r.source(0)));
}

#[test]
fn ties_go_to_the_smaller_source_whatever_the_arrival_order() {
    // S3 Max: ties break deterministically on the source (node, then connection); smaller wins.
    for order in [[0usize, 1, 2], [2, 1, 0], [1, 2, 0], [2, 0, 1]] {
        let mut r = max_int(3);
        for (t, &i) in order.iter().enumerate() {
            r.send(i, ms(t as u64 + 1), 8i64);
        }
        assert_eq!(r.read(), Value::Int(8), "order {order:?}");
        assert_eq!(r.supplier(), Some(r.source(0)), "order {order:?}");
        assert!(r.source(0) < r.source(1) && r.source(1) < r.source(2));
    }
}

#[test]
fn own_write_is_the_smallest_source_on_its_node() {
    // S3 Max: a process of the port's own behavior is Source { node, conn: 0 }, which is smaller
    // than every connection of the same node, so it keeps a tie in either order.
    for own_first in [true, false] {
        let mut r = max_int(1);
        if own_first {
            r.own(ms(1), 6i64).unwrap();
            r.send(0, ms(2), 6i64);
        } else {
            r.send(0, ms(1), 6i64);
            r.own(ms(2), 6i64).unwrap();
        }
        assert_eq!(r.supplier(), Some(Source::internal(N)), "own_first={own_first}");
    }
}

#[test]
fn larger_value_replaces_the_supplier() {
    // S3 Max: a new maximum takes over the supplier, even from a smaller source.
    let mut r = max_int(2);
    r.send(0, ms(1), 1i64);
    r.send(1, ms(2), 2i64);
    assert_eq!(r.supplier(), Some(r.source(1)));
    r.send(0, ms(3), 3i64);
    assert_eq!(r.supplier(), Some(r.source(0)));
    assert_eq!(r.read(), Value::Int(3));
}

#[test]
fn float_and_bool_maxima() {
    // S3 Max: ordered types are bool, int and float.
    let mut r = FanIn::new(PortSpec::new("In", 0.0).max(), 2);
    r.send(0, ms(1), -0.5);
    r.send(1, ms(2), 0.25);
    r.send(0, ms(3), 0.125);
    assert_eq!(r.read(), Value::Float(0.25));
    assert_eq!(r.supplier(), Some(r.source(1)));

    let mut r = FanIn::new(PortSpec::new("In", false).max(), 2);
    r.send(0, ms(1), false);
    assert_eq!(r.read(), Value::Bool(false));
    assert!(r.node.fresh(r.agg).unwrap());
    r.send(1, ms(2), true);
    r.send(0, ms(3), false);
    assert_eq!(r.read(), Value::Bool(true));
    assert_eq!(r.supplier(), Some(r.source(1)));
}

#[test]
fn nan_is_refused_and_counted() {
    // S3 Max: NaN has no place in an order; it is refused (NotANumber) and leaves the port as
    // it was — empty stays empty, a held value is kept, nothing propagates.
    let mut r = FanIn::new(PortSpec::new("In", 0.0).max(), 1);
    r.send(0, ms(1), f64::NAN);
    assert!(r.report().empty);
    assert!(!r.node.fresh(r.agg).unwrap());
    assert_eq!(r.dropped(DropCause::NotANumber), 1);
    r.send(0, ms(2), 1.5);
    r.send(0, ms(3), f64::NAN);
    assert_eq!(r.read(), Value::Float(1.5));
    assert_eq!(r.dropped(DropCause::NotANumber), 2);
    assert_eq!(r.node.counters().get(DropCause::NotANumber), 2);
    assert_eq!(r.propagated(), 1);
    // The behavior's own NaN write is refused with an error, not stored.
    assert!(r.own(ms(4), f64::NAN).is_err());
    assert_eq!(r.read(), Value::Float(1.5));
}

#[test]
fn reset_empties_the_port() {
    // S3 Max: reset() empties at once; the next write sets, however small.
    let mut r = max_int(2);
    r.send(0, ms(1), 100i64);
    r.node.reset(r.agg).unwrap();
    assert!(r.report().empty);
    assert_eq!(r.read(), Value::Int(0));
    assert!(!r.node.fresh(r.agg).unwrap());
    assert_eq!(r.supplier(), None);
    r.send(1, ms(2), -7i64);
    assert_eq!(r.read(), Value::Int(-7));
    assert_eq!(r.supplier(), Some(r.source(1)));
}

#[test]
fn declared_window_opens_at_first_accepted_write_and_empties() {
    // S3 Max: the window opens at the first accepted write into an empty port (not at creation,
    // not extended by later writes) and empties the port `window` later.
    let mut r = FanIn::new(PortSpec::new("In", 0i64).max().window(Duration::from_millis(100)), 2);
    r.at(ms(500));
    assert!(r.report().empty);
    r.send(0, ms(500), 5i64); // window [500, 600)
    r.send(1, ms(590), 9i64); // accepted, but the window is not extended
    r.at(ms(599));
    assert_eq!(r.read(), Value::Int(9));
    assert!(r.node.fresh(r.agg).unwrap());
    r.at(ms(600));
    assert_eq!(r.read(), Value::Int(0));
    assert!(!r.node.fresh(r.agg).unwrap());
    assert!(r.report().empty);
    assert_eq!(r.supplier(), None);
    // A new window opens with the next accepted write; a smaller value now sets the port.
    r.send(0, ms(650), 1i64); // window [650, 750)
    assert_eq!(r.read(), Value::Int(1));
    assert_eq!(r.supplier(), Some(r.source(0)));
    r.at(ms(749));
    assert_eq!(r.read(), Value::Int(1));
    r.at(ms(750));
    assert!(r.report().empty);
}

#[test]
fn a_refused_first_write_does_not_open_the_window() {
    // S3 Max: only an *accepted* write opens the window.
    let mut r = FanIn::new(PortSpec::new("In", 0.0).max().window(Duration::from_millis(100)), 1);
    r.send(0, ms(0), f64::NAN); // refused: no window
    r.send(0, ms(50), 2.0); // window [50, 150)
    r.at(ms(120));
    assert_eq!(r.read(), Value::Float(2.0));
    r.at(ms(150));
    assert_eq!(r.read(), Value::Float(0.0));
}
