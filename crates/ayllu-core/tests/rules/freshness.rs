//! Rule S4, freshness: every port records when it last accepted a value; a declared lifespan
//! makes it read as absent afterwards (`fresh` false, `get` None, `Ctx::int/float/bool/get`
//! None), which lets a behavior stop producing output when its input is stale.

use std::sync::{Arc, Mutex};

use ayllu_core::*;

fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}

/// `Src.Out` (int) -> `Dst.In` (int, lifespan 100 ms, Normal) and a suppressor `Sup.Out` that can
/// suppress `Dst.In`.
fn wired(kind: PortKind) -> NodeCore {
    let mut node = NodeCore::new(NodeId(1));
    let mut src = BehaviorClass::new("Src");
    src.port(PortSpec::new("Out", 0i64)).unwrap();
    let mut dst = BehaviorClass::new("Dst");
    dst.port(PortSpec::new("In", 0i64).kind(kind).lifespan(Duration::from_millis(100))).unwrap();
    node.define(src).unwrap();
    node.define(dst).unwrap();
    node.create("Src", "Src").unwrap();
    node.create("Src", "Sup").unwrap();
    node.create("Dst", "Dst").unwrap();
    let normal = ConnectionKind::Normal;
    node.connect(&Endpoint::local("Src", "Out"), &Endpoint::local("Dst", "In"), normal, ConnectOptions::default())
        .unwrap();
    node.connect(
        &Endpoint::local("Sup", "Out"),
        &Endpoint::local("Dst", "In"),
        ConnectionKind::Suppress(Duration::from_millis(1_000)),
        ConnectOptions::default(),
    )
    .unwrap();
    node
}

fn last_accepted(node: &NodeCore) -> Option<Instant> {
    node.why("Dst", "In").unwrap().last_accepted
}

#[test]
fn records_the_time_of_the_last_accepted_value() {
    // S4: the port records when it last *accepted* a value.
    let mut node = wired(PortKind::Normal);
    assert_eq!(last_accepted(&node), None);
    node.write_named(ms(10), "Src", "Out", 1i64).unwrap();
    assert_eq!(last_accepted(&node), Some(ms(10)));
    node.write_named(ms(30), "Dst", "In", 2i64).unwrap();
    assert_eq!(last_accepted(&node), Some(ms(30)));
}

#[test]
fn refused_or_absorbed_values_do_not_refresh() {
    // S4: a suppressed connection write (S6) or an absorbed Max write (S3) is not accepted, so
    // it does not make the port fresh again.
    let mut node = wired(PortKind::Normal);
    node.write_named(ms(0), "Src", "Out", 1i64).unwrap();
    node.write_named(ms(10), "Sup", "Out", 0i64).unwrap(); // suppress Dst.In until 1010
    node.write_named(ms(50), "Src", "Out", 2i64).unwrap();
    assert_eq!(last_accepted(&node), Some(ms(0)));
    node.poll(ms(100));
    assert!(!node.fresh(node.port("Dst", "In").unwrap()).unwrap());

    let mut node = wired(PortKind::Max);
    node.write_named(ms(0), "Src", "Out", 10i64).unwrap();
    node.write_named(ms(60), "Src", "Out", 5i64).unwrap(); // absorbed
    assert_eq!(last_accepted(&node), Some(ms(0)));
    node.poll(ms(100));
    let p = node.port("Dst", "In").unwrap();
    assert!(!node.fresh(p).unwrap());
    assert_eq!(node.get(p).unwrap(), None);
}

#[test]
fn lifespan_makes_the_port_absent() {
    // S4: after `lifespan` without an accepted value, fresh() is false and get() is None;
    // read() still returns the last value (freshness is advisory, not destructive).
    let mut node = wired(PortKind::Normal);
    let p = node.port("Dst", "In").unwrap();
    node.write_named(ms(200), "Src", "Out", 7i64).unwrap();
    node.poll(ms(299));
    assert!(node.fresh(p).unwrap());
    assert_eq!(node.get(p).unwrap(), Some(Value::Int(7)));
    node.poll(ms(300));
    assert!(!node.fresh(p).unwrap());
    assert_eq!(node.get(p).unwrap(), None);
    assert_eq!(node.read(p).unwrap(), Value::Int(7));
    assert!(!node.why("Dst", "In").unwrap().fresh);
    // A new value makes it fresh again for another lifespan.
    node.write_named(ms(350), "Src", "Out", 8i64).unwrap();
    assert_eq!(node.get(p).unwrap(), Some(Value::Int(8)));
    node.poll(ms(450));
    assert_eq!(node.get(p).unwrap(), None);
}

#[test]
fn without_lifespan_a_written_port_stays_fresh() {
    // S4: the lifespan is optional; without one a port stays fresh once written.
    let mut node = NodeCore::new(NodeId(1));
    let mut c = BehaviorClass::new("C");
    c.port(PortSpec::new("P", 0.0)).unwrap();
    node.define(c).unwrap();
    node.create("C", "C").unwrap();
    let p = node.port("C", "P").unwrap();
    node.write(ms(1), p, 1.0).unwrap();
    node.poll(Instant::from_secs(1_000_000));
    assert!(node.fresh(p).unwrap());
}

/// (now in ms, int, float, bool, fresh, read) as a process saw them.
type Seen = (u64, Option<i64>, Option<f64>, Option<bool>, bool, Value);

#[test]
fn ctx_accessors_return_none_when_stale() {
    // S4: inside a process, int/float/bool/get/fresh report absence once the lifespan ran out;
    // read() still gives the stored value.
    let seen: Arc<Mutex<Vec<Seen>>> = Arc::default();
    let mut node = NodeCore::new(NodeId(1));
    let mut c = BehaviorClass::new("C");
    let life = Duration::from_millis(150);
    let i = c.port(PortSpec::new("I", 0i64).lifespan(life)).unwrap();
    let f = c.port(PortSpec::new("F", 0.0).lifespan(life)).unwrap();
    let b = c.port(PortSpec::new("B", false).lifespan(life)).unwrap();
    let log = seen.clone();
    c.every_hz("Look", 10.0, move |ctx| {
        let row = (ctx.now().as_nanos() / 1_000_000, ctx.int(i), ctx.float(f), ctx.bool(b), ctx.fresh(i), ctx.read(i));
        assert_eq!(ctx.get(i), row.1.map(Value::Int));
        assert_eq!(ctx.get_ref(i), ctx.get(i).as_ref());
        assert_eq!(ctx.get_ref(f).and_then(Value::as_float), ctx.float(f));
        log.lock().unwrap().push(row);
    })
    .unwrap();
    node.define(c).unwrap();
    node.create("C", "C").unwrap();
    node.poll(ms(0)); // nothing written yet: absent
    node.write_named(ms(50), "C", "I", 3i64).unwrap();
    node.write_named(ms(50), "C", "F", 0.5).unwrap();
    node.write_named(ms(50), "C", "B", true).unwrap();
    for t in [100, 199, 200, 300] {
        node.poll(ms(t));
    }
    let seen = seen.lock().unwrap().clone();
    assert_eq!(
        seen,
        vec![
            (0, None, None, None, false, Value::Int(0)),
            (100, Some(3), Some(0.5), Some(true), true, Value::Int(3)),
            (200, None, None, None, false, Value::Int(3)),
            (300, None, None, None, false, Value::Int(3)),
        ]
    );
}

#[test]
fn a_behavior_stops_its_output_when_its_input_is_stale() {
    // S4 (the manual's "data availability"): a controller that only writes `Out` while `In` is
    // fresh goes quiet once its sensor stops, instead of repeating a stale command as Fig. 2
    // would.
    let mut node = NodeCore::new(NodeId(1));
    let mut ctl = BehaviorClass::new("Ctl");
    let input = ctl.port(PortSpec::new("In", 0.0).lifespan(Duration::from_millis(250))).unwrap();
    let out = ctl.port(PortSpec::new("Out", 0.0)).unwrap();
    ctl.every_hz("Steer", 10.0, move |ctx| {
        if let Some(x) = ctx.float(input) {
            ctx.write(out, 2.0 * x).unwrap();
        }
    })
    .unwrap();
    let mut motor = BehaviorClass::new("Motor");
    motor.port(PortSpec::new("Cmd", 0.0)).unwrap();
    node.define(ctl).unwrap();
    node.define(motor).unwrap();
    node.create("Ctl", "Ctl").unwrap();
    node.create("Motor", "Motor").unwrap();
    node.connect(
        &Endpoint::local("Ctl", "Out"),
        &Endpoint::local("Motor", "Cmd"),
        ConnectionKind::Normal,
        ConnectOptions::default(),
    )
    .unwrap();
    let commands = |node: &NodeCore| node.why("Motor", "Cmd").unwrap().accepted;

    node.poll(ms(0)); // no input yet: no command
    assert_eq!(commands(&node), 0);
    node.write_named(ms(10), "Ctl", "In", 1.5).unwrap(); // fresh until 260
    for t in [100, 200] {
        node.poll(ms(t));
    }
    assert_eq!(commands(&node), 2);
    assert_eq!(node.read(node.port("Motor", "Cmd").unwrap()).unwrap(), Value::Float(3.0));
    for t in [300, 400, 500] {
        node.poll(ms(t));
    }
    assert_eq!(commands(&node), 2, "stale input must stop the output");
    node.write_named(ms(550), "Ctl", "In", -1.0).unwrap();
    node.poll(ms(600));
    assert_eq!(commands(&node), 3);
    assert_eq!(node.read(node.port("Motor", "Cmd").unwrap()).unwrap(), Value::Float(-2.0));
}

#[test]
fn read_with_sees_what_read_returns() {
    // Normal (never empty) and Max (released to its default when stale), before a write,
    // while fresh and after the lifespan; then a handle to a removed behavior.
    for kind in [PortKind::Normal, PortKind::Max] {
        let mut node = wired(kind);
        let src = node.port("Src", "Out").unwrap();
        let dst = node.port("Dst", "In").unwrap();
        let check = |node: &NodeCore| {
            assert_eq!(node.read_with(dst, Value::clone).unwrap(), node.read(dst).unwrap());
            assert_eq!(node.read_with(dst, Value::as_int).unwrap(), node.read(dst).unwrap().as_int());
        };
        check(&node);
        node.write(ms(10), src, 7i64).unwrap();
        check(&node);
        assert_eq!(node.read_with(dst, Value::as_int).unwrap(), Some(7));
        node.poll(ms(200));
        check(&node);
        node.remove("Dst").unwrap();
        assert!(node.read_with(dst, Value::clone).is_err() && node.read(dst).is_err());
    }
}
