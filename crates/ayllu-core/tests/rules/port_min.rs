//! Rule S3, Min ports: `c := min(c, m)`, aggregating, remembers the supplier of the minimum,
//! ties to the smaller `Source`, equal values accepted (S5), larger ones absorbed, NaN refused.

use crate::fan_in;

use ayllu_core::*;
use fan_in::{ms, FanIn, N};

fn min_int(k: usize) -> FanIn {
    FanIn::new(PortSpec::new("In", 0i64).min(), k)
}

#[test]
fn starts_empty_reads_default_and_is_not_fresh() {
    // S3 Min: aggregating ports start empty (read = default, fresh = false).
    let r = FanIn::new(PortSpec::new("In", -3i64).min(), 1);
    assert_eq!(r.read(), Value::Int(-3));
    assert!(!r.node.fresh(r.agg).unwrap());
    assert_eq!(r.node.get(r.agg).unwrap(), None);
    assert!(r.report().empty);
    assert_eq!(r.supplier(), None);
}

#[test]
fn first_write_sets_even_above_the_default() {
    // S3 Min: the first write sets the port; the default (0) takes no part in the minimum.
    let mut r = min_int(1);
    r.send(0, ms(1), 25i64);
    assert_eq!(r.read(), Value::Int(25));
    assert!(r.node.fresh(r.agg).unwrap());
    assert_eq!(r.supplier(), Some(r.source(0)));
}

#[test]
fn keeps_the_minimum_and_remembers_its_supplier() {
    // S3 Min: c := min(c, m); the port remembers who supplied the minimum.
    let mut r = min_int(3);
    r.send(0, ms(1), 30i64);
    r.send(1, ms(2), 10i64);
    r.send(2, ms(3), 20i64);
    assert_eq!(r.read(), Value::Int(10));
    assert_eq!(r.supplier(), Some(r.source(1)));
    assert_eq!(r.dropped(DropCause::Absorbed), 1);
    assert_eq!(r.propagated(), 2);
    assert_eq!(r.tap(), Value::Int(10));
}

#[test]
fn larger_value_is_absorbed_and_not_propagated() {
    // S3 Min + S5: a value above the minimum is absorbed and counted; nothing propagates.
    let mut r = min_int(2);
    r.send(0, ms(1), 1i64);
    r.send(1, ms(2), 2i64);
    r.send(1, ms(3), i64::MAX);
    assert_eq!(r.read(), Value::Int(1));
    assert_eq!(r.dropped(DropCause::Absorbed), 2);
    assert_eq!(r.node.counters().get(DropCause::Absorbed), 2);
    assert_eq!(r.propagated(), 1);
}

#[test]
fn equal_value_is_accepted_and_propagates() {
    // S3 Min / S5: an equal value is accepted and propagates.
    let mut r = min_int(2);
    r.send(1, ms(1), -2i64);
    r.send(0, ms(2), -2i64);
    r.send(1, ms(3), -2i64);
    assert_eq!(r.propagated(), 3);
    assert_eq!(r.dropped(DropCause::Absorbed), 0);
    assert_eq!(r.supplier(), Some(r.source(0)));
}

#[test]
fn ties_go_to_the_smaller_source_whatever_the_arrival_order() {
    // S3 Min: ties keep the smaller source (node, then connection), in every arrival order.
    for order in [[0usize, 1, 2], [2, 1, 0], [1, 0, 2], [2, 0, 1]] {
        let mut r = FanIn::new(PortSpec::new("In", 0.0).min(), 3);
        for (t, &i) in order.iter().enumerate() {
            r.send(i, ms(t as u64 + 1), -1.25);
        }
        assert_eq!(r.read(), Value::Float(-1.25));
        assert_eq!(r.supplier(), Some(r.source(0)), "order {order:?}");
    }
    // The behavior's own process (conn 0) is the smallest source on its node.
    let mut r = min_int(1);
    r.send(0, ms(1), 5i64);
    r.own(ms(2), 5i64).unwrap();
    assert_eq!(r.supplier(), Some(Source::internal(N)));
}

#[test]
fn nan_is_refused_and_counted() {
    // S3 Min: NaN is refused (NotANumber), the port keeps its state.
    let mut r = FanIn::new(PortSpec::new("In", 0.0).min(), 1);
    r.send(0, ms(1), f64::NAN);
    assert!(r.report().empty);
    r.send(0, ms(2), 3.0);
    r.send(0, ms(3), f64::NAN);
    assert_eq!(r.read(), Value::Float(3.0));
    assert_eq!(r.dropped(DropCause::NotANumber), 2);
    assert!(r.own(ms(4), f64::NAN).is_err());
    assert_eq!(r.read(), Value::Float(3.0));
    assert_eq!(r.propagated(), 1);
}

#[test]
fn reset_empties_the_port() {
    // S3 Min: reset() empties; the next write sets, however large.
    let mut r = min_int(1);
    r.send(0, ms(1), -50i64);
    r.node.reset(r.agg).unwrap();
    assert!(r.report().empty);
    assert!(!r.node.fresh(r.agg).unwrap());
    assert_eq!(r.read(), Value::Int(0));
    r.send(0, ms(2), 50i64);
    assert_eq!(r.read(), Value::Int(50));
}

#[test]
fn declared_window_opens_at_first_accepted_write_and_empties() {
    // S3 Min: window opens at the first accepted write, empties the port `window` later.
    let mut r = FanIn::new(PortSpec::new("In", 0i64).min().window(Duration::from_millis(40)), 2);
    r.send(0, ms(10), 8i64); // window [10, 50)
    r.send(1, ms(45), 3i64);
    r.at(ms(49));
    assert_eq!(r.read(), Value::Int(3));
    assert_eq!(r.supplier(), Some(r.source(1)));
    r.at(ms(50));
    assert!(r.report().empty);
    assert_eq!(r.read(), Value::Int(0));
    assert!(!r.node.fresh(r.agg).unwrap());
    // After the window the larger value is accepted as the first of a new window.
    r.send(0, ms(60), 8i64);
    assert_eq!(r.read(), Value::Int(8));
    assert_eq!(r.supplier(), Some(r.source(0)));
}
