//! Property tests for rule S3: the value *and* the supplier an aggregating port ends with are
//! independent of the order in which a multiset of writes arrives (Max, Min, Sum of ints,
//! Priority), and a declared window empties the port `window` after its first accepted write.
//!
//! Each property is checked twice: on a bare `PortCell` (the pure merge) and end to end through
//! `NodeCore::receive` (messages from arbitrary `(node, connection)` sources with arbitrary
//! priorities).

use std::collections::HashMap;

use ayllu_core::*;
use proptest::prelude::*;

const SELF: NodeId = NodeId(100);

fn source() -> impl Strategy<Value = Source> {
    // Few nodes and connections, so equal sources and ties are common.
    (0u32..4, 1u64..4).prop_map(|(n, c)| Source { node: NodeId(n), conn: c })
}

fn small_int() -> impl Strategy<Value = i64> {
    -4i64..4
}

/// Floats with ties, signed zeros, infinities and NaN (which must be refused in any order).
fn float() -> impl Strategy<Value = f64> {
    prop_oneof![
        4 => (-3i32..3).prop_map(f64::from),
        1 => Just(-0.0),
        1 => Just(0.0),
        1 => Just(f64::INFINITY),
        1 => Just(f64::NEG_INFINITY),
        1 => Just(f64::NAN),
        2 => any::<f64>(),
    ]
}

/// A multiset of writes and one permutation of it.
fn with_permutation<T: Clone + std::fmt::Debug>(
    items: impl Strategy<Value = Vec<T>>,
) -> impl Strategy<Value = (Vec<T>, Vec<T>)> {
    items.prop_flat_map(|v| (Just(v.clone()), Just(v).prop_shuffle()))
}

/// The final (value, supplier) of a fresh cell after merging `writes` in order.
fn cell_after(spec: &PortSpec, writes: &[(Value, Source, i32)]) -> (Value, Option<Source>, bool) {
    let mut cell = PortCell::new(spec);
    let now = Instant::from_millis(1);
    for (v, s, p) in writes {
        let _ = cell.merge(now, v, *s, *p);
    }
    (cell.value().clone(), cell.supplier(), cell.fresh(now))
}

/// The same through a node: each write is a port message from `(s.node, s.conn)` with priority
/// `p`; sequence numbers increase per (node, connection) in arrival order.
fn node_after(spec: &PortSpec, writes: &[(Value, Source, i32)]) -> (Value, Option<Source>, bool) {
    let mut n = NodeCore::new(SELF);
    let mut c = BehaviorClass::new("C");
    c.port(spec.clone()).unwrap();
    n.define(c).unwrap();
    n.create("C", "B").unwrap();
    let mut seq: HashMap<Source, u64> = HashMap::new();
    for (v, s, p) in writes {
        let k = seq.entry(*s).or_default();
        *k += 1;
        let m = PortMessage {
            conn: ConnectionId(s.conn),
            seq: *k,
            behavior: "B".into(),
            port: spec.name.as_str().into(),
            kind: ConnectionKind::Normal,
            priority: *p,
            value: v.clone(),
        };
        n.receive(Instant::from_millis(1), s.node, Message::Port(m));
    }
    assert_eq!(n.counters().get(DropCause::Stale), 0);
    let r = n.why("B", &spec.name).unwrap();
    (r.value, r.supplier, r.fresh)
}

/// Bitwise equality for values (so -0.0 and 0.0 differ).
fn same(a: &Value, b: &Value) -> bool {
    match (a, b) {
        (Value::Float(x), Value::Float(y)) => x.to_bits() == y.to_bits(),
        _ => a == b,
    }
}

fn check_both(
    spec: &PortSpec,
    a: &[(Value, Source, i32)],
    b: &[(Value, Source, i32)],
) -> Result<(Value, Option<Source>), TestCaseError> {
    let ca = cell_after(spec, a);
    let cb = cell_after(spec, b);
    prop_assert!(same(&ca.0, &cb.0), "cell values differ: {:?} vs {:?}", ca.0, cb.0);
    prop_assert_eq!(ca.1, cb.1, "cell suppliers differ");
    prop_assert_eq!(ca.2, cb.2);
    let na = node_after(spec, a);
    let nb = node_after(spec, b);
    prop_assert!(same(&na.0, &nb.0), "node values differ: {:?} vs {:?}", na.0, nb.0);
    prop_assert_eq!(na.1, nb.1, "node suppliers differ");
    prop_assert!(same(&ca.0, &na.0) && ca.1 == na.1, "cell and node disagree");
    Ok((ca.0, ca.1))
}

fn tagged<T: Into<Value> + Clone>(w: &[(T, Source)]) -> Vec<(Value, Source, i32)> {
    w.iter().map(|(v, s)| (v.clone().into(), *s, 0)).collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn max_int_is_order_independent((a, b) in with_permutation(prop::collection::vec((small_int(), source()), 1..24))) {
        // S3 Max: value = the maximum; supplier = the smallest source that offered it.
        let spec = PortSpec::new("P", 0i64).max();
        let (v, s) = check_both(&spec, &tagged(&a), &tagged(&b))?;
        let top = a.iter().map(|(x, _)| *x).max().unwrap();
        prop_assert_eq!(v, Value::Int(top));
        prop_assert_eq!(s, a.iter().filter(|(x, _)| *x == top).map(|(_, s)| *s).min());
    }

    #[test]
    fn min_int_is_order_independent((a, b) in with_permutation(prop::collection::vec((small_int(), source()), 1..24))) {
        // S3 Min: value = the minimum; supplier = the smallest source that offered it.
        let spec = PortSpec::new("P", 0i64).min();
        let (v, s) = check_both(&spec, &tagged(&a), &tagged(&b))?;
        let low = a.iter().map(|(x, _)| *x).min().unwrap();
        prop_assert_eq!(v, Value::Int(low));
        prop_assert_eq!(s, a.iter().filter(|(x, _)| *x == low).map(|(_, s)| *s).min());
    }

    #[test]
    fn max_and_min_float_are_order_independent_and_refuse_nan(
        (a, b) in with_permutation(prop::collection::vec((float(), source()), 1..24)),
        max in any::<bool>(),
    ) {
        // S3 Max/Min on floats: NaN is refused in any position; signed zeros, infinities and
        // ties still give one answer, bit for bit, whatever the order.
        let spec = if max { PortSpec::new("P", 0.0).max() } else { PortSpec::new("P", 0.0).min() };
        let (v, s) = check_both(&spec, &tagged(&a), &tagged(&b))?;
        let offered: Vec<(f64, Source)> = a.iter().copied().filter(|(x, _)| !x.is_nan()).collect();
        if offered.is_empty() {
            prop_assert_eq!(s, None);
            prop_assert!(same(&v, &Value::Float(0.0)));
        } else {
            let pick = |x: f64, y: f64| if max { if x.total_cmp(&y).is_ge() { x } else { y } } else if x.total_cmp(&y).is_le() { x } else { y };
            let best = offered.iter().map(|(x, _)| *x).reduce(pick).unwrap();
            prop_assert!(!v.is_nan());
            prop_assert_eq!(v.as_float().unwrap(), best);
            let who = offered.iter().filter(|(x, _)| x.to_bits() == best.to_bits()).map(|(_, s)| *s).min();
            prop_assert_eq!(s, who);
        }
    }

    #[test]
    fn sum_int_is_order_independent((a, b) in with_permutation(prop::collection::vec((any::<i64>(), source()), 1..24))) {
        // S3 Sum: the (wrapping) sum does not depend on the order. (A Sum port's supplier is
        // its latest contributor, which by nature does depend on it.)
        let spec = PortSpec::new("P", 0i64).sum();
        let (v, _) = check_both_value(&spec, &tagged(&a), &tagged(&b))?;
        let total = a.iter().fold(0i64, |acc, (x, _)| acc.wrapping_add(*x));
        prop_assert_eq!(v, Value::Int(total));
    }

    #[test]
    fn priority_with_a_unique_top_is_order_independent(
        (a, b) in with_permutation(
            (prop::collection::vec((small_int(), -3i32..3), 1..12), any::<prop::sample::Index>()).prop_map(|(writes, top)| {
                // One write per source (a connection has one priority), one strict top priority.
                let t = top.index(writes.len());
                let highest = writes.iter().map(|(_, p)| *p).max().unwrap() + 1;
                writes
                    .into_iter()
                    .enumerate()
                    .map(|(i, (v, p))| (v, Source { node: NodeId(i as u32 % 3), conn: i as u64 + 1 }, if i == t { highest } else { p }))
                    .collect::<Vec<_>>()
            })
        )
    ) {
        // S3 Priority: the highest priority wins, whatever arrives when.
        let conv = |w: &[(i64, Source, i32)]| w.iter().map(|(v, s, p)| (Value::Int(*v), *s, *p)).collect::<Vec<_>>();
        let (v, s) = check_both(&PortSpec::new("P", 0i64).priority(), &conv(&a), &conv(&b))?;
        let top = a.iter().max_by_key(|(_, _, p)| *p).unwrap();
        prop_assert_eq!(v, Value::Int(top.0));
        prop_assert_eq!(s, Some(top.1));
    }

    #[test]
    fn priority_follows_its_rule_for_any_arrival_order(
        writes in prop::collection::vec((small_int(), 0usize..5), 1..24),
        prios in prop::collection::vec(-2i32..3, 5),
    ) {
        // S3 Priority, closed form: the port ends held by the *first* source to arrive with the
        // top priority (a different source at equal priority is absorbed), holding that
        // source's *latest* value (the holder may update at equal priority).
        let sources: Vec<Source> = (0..5u64).map(|i| Source { node: NodeId(1), conn: i + 1 }).collect();
        let w: Vec<(Value, Source, i32)> = writes.iter().map(|(v, i)| (Value::Int(*v), sources[*i], prios[*i])).collect();
        let top = w.iter().map(|(_, _, p)| *p).max().unwrap();
        let holder = w.iter().find(|(_, _, p)| *p == top).unwrap().1;
        let latest = w.iter().rev().find(|(_, s, _)| *s == holder).unwrap().0.clone();
        let spec = PortSpec::new("P", 0i64).priority();
        let (v, s, _) = cell_after(&spec, &w);
        prop_assert_eq!(&v, &latest);
        prop_assert_eq!(s, Some(holder));
        let (nv, ns, _) = node_after(&spec, &w);
        prop_assert_eq!(nv, latest);
        prop_assert_eq!(ns, Some(holder));
    }

    #[test]
    fn window_expiry_empties(
        steps in prop::collection::vec((0u64..80, small_int(), source()), 1..16),
        wait in 0u64..250,
        kind in prop::sample::select(vec![PortKind::Max, PortKind::Min, PortKind::Sum, PortKind::Priority]),
    ) {
        // S3: a window opens at the first accepted write into an empty port and empties the port
        // `window` later — later writes inside it do not extend it; a write after it opens a new
        // one. D3.7: a Priority port's window is its holder's lease instead, renewed by each of
        // the holder's writes. Model: track the open window, its end and its holder.
        const W: u64 = 100;
        let mut n = NodeCore::new(SELF);
        let mut c = BehaviorClass::new("C");
        c.port(PortSpec::new("P", 7i64).kind(kind).window(Duration::from_millis(W))).unwrap();
        n.define(c).unwrap();
        n.create("C", "B").unwrap();
        let p = n.port("B", "P").unwrap();
        let mut t = 0u64;
        let mut open: Option<u64> = None;
        let mut end = 0u64;
        let mut holder: Option<Source> = None;
        let mut seq: HashMap<Source, u64> = HashMap::new();
        for (dt, v, s) in &steps {
            t += dt;
            if open.is_some() && t >= end {
                open = None;
            }
            if open.is_none() {
                open = Some(t);
                end = t + W;
                holder = Some(*s);
            } else if kind == PortKind::Priority && holder == Some(*s) {
                end = t + W;
            }
            let k = seq.entry(*s).or_default();
            *k += 1;
            n.receive(Instant::from_millis(t), s.node, Message::Port(PortMessage {
                conn: ConnectionId(s.conn), seq: *k, behavior: "B".into(), port: "P".into(),
                kind: ConnectionKind::Normal, priority: 0, value: Value::Int(*v),
            }));
            prop_assert!(n.fresh(p).unwrap(), "a write always leaves the port holding a value");
        }
        let check = t + wait;
        n.poll(Instant::from_millis(check));
        let r = n.why("B", "P").unwrap();
        if check >= end {
            prop_assert!(r.empty, "window [{}, {}) must have closed by {}", open.unwrap(), end, check);
            prop_assert!(!r.fresh);
            prop_assert_eq!(r.value, Value::Int(7));
            prop_assert_eq!(r.supplier, None);
            prop_assert_eq!(n.get(p).unwrap(), None);
        } else {
            prop_assert!(!r.empty, "window [{}, {}) still open at {}", open.unwrap(), end, check);
            prop_assert!(r.fresh);
            // The port holds only what arrived inside the current window.
            let mut inside: Vec<(i64, Source)> = Vec::new();
            let mut t = 0u64;
            for (dt, v, s) in &steps {
                t += dt;
                if t >= open.unwrap() {
                    inside.push((*v, *s));
                }
            }
            let expect = match kind {
                PortKind::Max => inside.iter().map(|(v, _)| *v).max().unwrap(),
                PortKind::Min => inside.iter().map(|(v, _)| *v).min().unwrap(),
                PortKind::Sum => inside.iter().map(|(v, _)| *v).sum(),
                // Priority, all at priority 0: the window's first source holds it and may update.
                _ => {
                    let holder = inside[0].1;
                    prop_assert_eq!(r.supplier, Some(holder));
                    inside.iter().rev().find(|(_, s)| *s == holder).unwrap().0
                }
            };
            prop_assert_eq!(r.value, Value::Int(expect));
        }
    }
}

fn check_both_value(
    spec: &PortSpec,
    a: &[(Value, Source, i32)],
    b: &[(Value, Source, i32)],
) -> Result<(Value, Option<Source>), TestCaseError> {
    let ca = cell_after(spec, a);
    let cb = cell_after(spec, b);
    prop_assert!(same(&ca.0, &cb.0), "cell values differ: {:?} vs {:?}", ca.0, cb.0);
    let na = node_after(spec, a);
    let nb = node_after(spec, b);
    prop_assert!(same(&na.0, &nb.0), "node values differ: {:?} vs {:?}", na.0, nb.0);
    prop_assert!(same(&ca.0, &na.0));
    Ok((ca.0, ca.1))
}

#[test]
fn max_float_keeps_signed_zero_deterministic() {
    // S3 Max: a fixed example of the float property — -0.0 from the smaller source and 0.0
    // from a larger one must end the same, bit for bit, in both orders.
    let spec = PortSpec::new("P", 1.0).max();
    let lo = Source { node: NodeId(1), conn: 1 };
    let hi = Source { node: NodeId(2), conn: 1 };
    let a = vec![(Value::Float(-0.0), lo, 0), (Value::Float(0.0), hi, 0)];
    let b = vec![(Value::Float(0.0), hi, 0), (Value::Float(-0.0), lo, 0)];
    let (va, sa, _) = cell_after(&spec, &a);
    let (vb, sb, _) = cell_after(&spec, &b);
    assert!(same(&va, &vb), "{va:?} vs {vb:?}");
    assert_eq!(sa, sb);
}
