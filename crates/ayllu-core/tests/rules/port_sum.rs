//! Rule S3, Sum ports: `c := c + m`. Aggregating (starts empty, first write sets, reset/window
//! empty it). Integers wrap, floats add, vectors add element-wise; a vector of another length is
//! refused as ShapeMismatch, NaN as NotANumber. Every accepted write propagates (S5).

use crate::fan_in;

use ayllu_core::*;
use fan_in::{ms, FanIn};

#[test]
fn starts_empty_and_the_first_write_sets() {
    // S3 Sum: empty reads the default and is not fresh; the first value *sets* (the default is
    // not added to it).
    let mut r = FanIn::new(PortSpec::new("In", 100i64).sum(), 1);
    assert!(r.report().empty);
    assert_eq!(r.read(), Value::Int(100));
    assert!(!r.node.fresh(r.agg).unwrap());
    r.send(0, ms(1), 5i64);
    assert_eq!(r.read(), Value::Int(5));
    assert!(r.node.fresh(r.agg).unwrap());
}

#[test]
fn integers_add_and_every_write_propagates() {
    // S3 Sum / S5: c := c + m; every write (even + 0, even a repeat) is accepted and propagates.
    let mut r = FanIn::new(PortSpec::new("In", 0i64).sum(), 3);
    r.send(0, ms(1), 1i64);
    r.send(1, ms(2), 2i64);
    r.send(2, ms(3), 0i64);
    r.send(0, ms(4), 1i64);
    r.own(ms(5), -10i64).unwrap();
    assert_eq!(r.read(), Value::Int(-6));
    assert_eq!(r.propagated(), 5);
    assert_eq!(r.tap(), Value::Int(-6));
    assert_eq!(r.dropped(DropCause::Absorbed), 0);
}

#[test]
fn integers_wrap_instead_of_overflowing() {
    // S3 Sum: integer sums wrap (no panic, no saturation).
    let mut r = FanIn::new(PortSpec::new("In", 0i64).sum(), 1);
    r.send(0, ms(1), i64::MAX);
    r.send(0, ms(2), 1i64);
    assert_eq!(r.read(), Value::Int(i64::MIN));
    r.send(0, ms(3), -1i64);
    assert_eq!(r.read(), Value::Int(i64::MAX));
}

#[test]
fn floats_add() {
    // S3 Sum: floats add.
    let mut r = FanIn::new(PortSpec::new("In", 0.0).sum(), 2);
    r.send(0, ms(1), 0.5);
    r.send(1, ms(2), 0.25);
    r.send(0, ms(3), -2.0);
    assert_eq!(r.read(), Value::Float(-1.25));
    assert_eq!(r.propagated(), 3);
}

#[test]
fn vectors_add_element_wise() {
    // S3 Sum: vectors add element-wise (e.g. summing velocity votes).
    let mut r = FanIn::new(PortSpec::new("In", Value::vector(&[0.0, 0.0])).sum(), 2);
    r.send(0, ms(1), vec![1.0, -1.0]);
    r.send(1, ms(2), vec![0.5, 2.0]);
    r.send(0, ms(3), vec![0.25, 0.0]);
    assert_eq!(r.read(), Value::vector(&[1.75, 1.0]));
    assert_eq!(r.tap(), Value::vector(&[1.75, 1.0]));
}

#[test]
fn vector_of_another_length_is_a_shape_mismatch() {
    // S3 Sum: a vector of another length is refused (ShapeMismatch), counted, not propagated.
    let mut r = FanIn::new(PortSpec::new("In", Value::vector(&[0.0, 0.0])).sum(), 1);
    r.send(0, ms(1), vec![1.0, 1.0]);
    r.send(0, ms(2), vec![1.0, 1.0, 1.0]);
    r.send(0, ms(3), vec![5.0]);
    assert_eq!(r.read(), Value::vector(&[1.0, 1.0]));
    assert_eq!(r.dropped(DropCause::ShapeMismatch), 2);
    assert_eq!(r.node.counters().get(DropCause::ShapeMismatch), 2);
    assert_eq!(r.propagated(), 1);
    // The behavior's own mis-shaped write is an error, and is not stored.
    assert!(r.own(ms(4), vec![1.0, 2.0, 3.0]).is_err());
    assert_eq!(r.read(), Value::vector(&[1.0, 1.0]));
    // D3.5: the shape is the declaration's (the default's length), not the first value's: an
    // empty port refuses another length too, so one mis-shaped sender cannot set the shape of
    // a window for everyone else.
    r.node.reset(r.agg).unwrap();
    r.send(0, ms(5), vec![1.0, 2.0, 3.0]);
    assert!(r.report().empty);
    assert_eq!(r.dropped(DropCause::ShapeMismatch), 4, "two sent, one own write, and this one");
    r.send(0, ms(6), vec![1.0, 2.0]);
    assert_eq!(r.read(), Value::vector(&[1.0, 2.0]));
}

#[test]
fn a_vector_sum_must_declare_its_shape() {
    // D3.5: a vector Sum's shape comes from its default, so an empty default is refused.
    let mut c = BehaviorClass::new("C");
    let err = c.port(PortSpec::new("V", Value::vector(&[])).sum()).unwrap_err();
    assert!(err.to_string().contains("shape"), "{err}");
    assert!(c.port(PortSpec::new("V", Value::vector(&[0.0; 3])).sum()).is_ok());
}

#[test]
fn infinities_of_opposite_sign_cannot_poison_the_sum() {
    // D3.6: +inf then -inf would make NaN: the second is refused (NotANumber), counted, and the
    // sum keeps +inf; for vectors too, element by element.
    let mut r = FanIn::new(PortSpec::new("In", 0.0).sum(), 2);
    r.send(0, ms(1), f64::INFINITY);
    r.send(1, ms(2), f64::NEG_INFINITY);
    assert_eq!(r.read(), Value::Float(f64::INFINITY));
    assert_eq!(r.dropped(DropCause::NotANumber), 1);
    assert!(r.own(ms(3), f64::NEG_INFINITY).is_err(), "the behavior's own write is refused too");
    r.send(1, ms(4), 1.0);
    assert_eq!(r.read(), Value::Float(f64::INFINITY), "finite values still add");

    let mut r = FanIn::new(PortSpec::new("In", Value::vector(&[0.0, 0.0])).sum(), 2);
    r.send(0, ms(1), vec![1.0, f64::INFINITY]);
    r.send(1, ms(2), vec![1.0, f64::NEG_INFINITY]);
    assert_eq!(r.read(), Value::vector(&[1.0, f64::INFINITY]));
    assert_eq!(r.dropped(DropCause::NotANumber), 1);
}

#[test]
fn nan_is_refused_for_floats_and_vectors() {
    // S3 Sum: NaN is refused (NotANumber) — one NaN would poison the sum for the whole window.
    let mut r = FanIn::new(PortSpec::new("In", 0.0).sum(), 1);
    r.send(0, ms(1), f64::NAN);
    assert!(r.report().empty);
    r.send(0, ms(2), 1.0);
    r.send(0, ms(3), f64::NAN);
    assert_eq!(r.read(), Value::Float(1.0));
    assert_eq!(r.dropped(DropCause::NotANumber), 2);
    assert!(r.own(ms(4), f64::NAN).is_err());

    let mut r = FanIn::new(PortSpec::new("In", Value::vector(&[0.0, 0.0])).sum(), 1);
    // Also as the first value of an empty port.
    r.send(0, ms(1), vec![f64::NAN, 1.0]);
    assert!(r.report().empty, "a vector holding NaN must not open the sum");
    r.send(0, ms(2), vec![1.0, 1.0]);
    r.send(0, ms(3), vec![1.0, f64::NAN]);
    assert_eq!(r.read(), Value::vector(&[1.0, 1.0]));
    assert_eq!(r.dropped(DropCause::NotANumber), 2);
    assert_eq!(r.propagated(), 1);
}

#[test]
fn reset_empties_the_sum() {
    // S3 Sum: reset() empties; the next write starts a new sum.
    let mut r = FanIn::new(PortSpec::new("In", 0i64).sum(), 1);
    r.send(0, ms(1), 40i64);
    r.send(0, ms(2), 2i64);
    r.node.reset(r.agg).unwrap();
    assert!(r.report().empty);
    assert_eq!(r.read(), Value::Int(0));
    assert!(!r.node.fresh(r.agg).unwrap());
    r.send(0, ms(3), 7i64);
    assert_eq!(r.read(), Value::Int(7));
}

#[test]
fn declared_window_sums_one_cycle() {
    // S3 Sum: the window (the paper's "current cycle") opens at the first accepted write and
    // empties the port `window` later; the next write starts a fresh sum.
    let mut r = FanIn::new(PortSpec::new("In", 0i64).sum().window(Duration::from_millis(100)), 2);
    r.at(ms(1_000));
    r.send(0, ms(1_010), 1i64); // window [1010, 1110)
    r.send(1, ms(1_050), 1i64);
    r.send(0, ms(1_109), 1i64);
    assert_eq!(r.read(), Value::Int(3));
    r.at(ms(1_110));
    assert!(r.report().empty);
    assert_eq!(r.read(), Value::Int(0));
    r.send(1, ms(1_120), 5i64); // window [1120, 1220)
    assert_eq!(r.read(), Value::Int(5));
    r.send(0, ms(1_219), 5i64);
    assert_eq!(r.read(), Value::Int(10));
    // A write arriving after the window ended starts a new sum rather than adding to the old.
    r.send(0, ms(1_220), 1i64);
    assert_eq!(r.read(), Value::Int(1));
}
