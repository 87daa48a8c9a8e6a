//! Rule S3, Normal ports: `c := m` — every value is accepted (larger, smaller, equal) and
//! propagates (S5). A Normal port is not aggregating: it is never "empty", but it is not
//! fresh before its first accepted value (S4).

use crate::fan_in;

use ayllu_core::*;
use fan_in::{ms, FanIn, N};

#[test]
fn every_write_replaces_the_value_and_propagates() {
    // S3 Normal: c := m, whatever m is relative to c; each accepted value propagates (S5).
    let mut r = FanIn::new(PortSpec::new("In", 0i64), 2);
    for (i, (src, v)) in [(0usize, 5i64), (1, 2), (0, 2), (1, 9), (0, -1)].into_iter().enumerate() {
        r.send(src, ms(i as u64 + 1), v);
        assert_eq!(r.read(), Value::Int(v));
        assert_eq!(r.tap(), Value::Int(v));
        assert_eq!(r.supplier(), Some(r.source(src)));
    }
    assert_eq!(r.propagated(), 5);
    assert_eq!(r.report().accepted, 5);
    assert_eq!(r.dropped(DropCause::Absorbed), 0);
}

#[test]
fn not_empty_but_not_fresh_before_the_first_value() {
    // S3 Normal is not aggregating; S4 freshness still needs a first accepted value.
    let mut r = FanIn::new(PortSpec::new("In", 7i64), 1);
    let rep = r.report();
    assert!(!rep.empty);
    assert!(!rep.fresh);
    assert_eq!(r.read(), Value::Int(7));
    assert_eq!(r.node.get(r.agg).unwrap(), None);
    r.send(0, ms(3), 1i64);
    assert_eq!(r.node.get(r.agg).unwrap(), Some(Value::Int(1)));
    assert_eq!(r.report().last_accepted, Some(ms(3)));
}

#[test]
fn own_writes_and_connection_writes_both_replace() {
    // S3 Normal: the behavior's own write is just another m; the supplier says who wrote last.
    let mut r = FanIn::new(PortSpec::new("In", Value::text("")), 1);
    r.send(0, ms(1), "from a connection");
    r.own(ms(2), "from my process").unwrap();
    assert_eq!(r.read(), Value::text("from my process"));
    assert_eq!(r.supplier(), Some(Source::internal(N)));
    assert_eq!(r.tap(), Value::text("from my process"));
}

#[test]
fn normal_ports_hold_every_type_including_nan() {
    // S1/S3 Normal: any type; a float NaN is a value like any other for a Normal port.
    let mut r = FanIn::new(PortSpec::new("In", 0.0), 1);
    r.send(0, ms(1), f64::NAN);
    assert!(r.read().is_nan());
    assert_eq!(r.propagated(), 1);
    let mut r = FanIn::new(PortSpec::new("In", Value::vector(&[0.0, 0.0])), 1);
    r.send(0, ms(1), vec![1.0, 2.0, 3.0]);
    assert_eq!(r.read(), Value::vector(&[1.0, 2.0, 3.0]));
    let mut r = FanIn::new(PortSpec::new("In", Value::bytes(b"")), 1);
    r.send(0, ms(1), Value::bytes(b"\x01\x02"));
    assert_eq!(r.tap(), Value::bytes(b"\x01\x02"));
}

#[test]
fn a_wrong_typed_own_write_is_an_error_and_changes_nothing() {
    // S1: never coerced — an Int is not a Float.
    let mut r = FanIn::new(PortSpec::new("In", 0.0), 1);
    let e = r.own(ms(1), 1i64).unwrap_err();
    assert!(matches!(e, Error::TypeMismatch { expected: ValueType::Float, found: ValueType::Int, .. }), "{e:?}");
    assert_eq!(r.read(), Value::Float(0.0));
    assert!(!r.node.fresh(r.agg).unwrap());
    assert_eq!(r.propagated(), 0);
}
