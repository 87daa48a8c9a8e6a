//! Propagating a scalar allocates nothing (design §6; lib docs "Fast"; issue: performance
//! evidence). A counting global allocator wraps the system one; each test counts only the
//! allocations made on its own thread while counting is switched on, so the test harness and
//! other tests running in parallel do not disturb it.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use ayllu::{
    BehaviorClass, ConnectOptions, ConnectionKind, Duration, Endpoint, Instant, NodeCore, NodeId, PortRef, PortSpec,
    Value,
};

struct Counting;

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    static COUNT: Cell<u64> = const { Cell::new(0) };
}

fn note() {
    if COUNTING.try_with(Cell::get).unwrap_or(false) {
        let _ = COUNT.try_with(|c| c.set(c.get() + 1));
    }
}

// SAFETY: every call is forwarded unchanged to `System`; we only count.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note();
        System.alloc(layout)
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        note();
        System.alloc_zeroed(layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        note();
        System.realloc(ptr, layout, new_size)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout)
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Allocations (alloc, alloc_zeroed, realloc) made by this thread while running `f`.
fn allocations(f: impl FnOnce()) -> u64 {
    COUNT.with(|c| c.set(0));
    COUNTING.with(|c| c.set(true));
    f();
    COUNTING.with(|c| c.set(false));
    COUNT.with(Cell::get)
}

#[test]
fn the_counter_sees_allocations() {
    // The instrument itself works: a Box and a format! are counted.
    let n = allocations(|| {
        std::hint::black_box(Box::new(7u64));
        std::hint::black_box(format!("{}", 42));
    });
    assert!(n >= 2, "counted {n}");
}

const PERIOD: Duration = Duration::from_millis(200);

fn connect(node: &mut NodeCore, from: (&str, &str), to: (&str, &str), kind: ConnectionKind) {
    node.connect(&Endpoint::local(from.0, from.1), &Endpoint::local(to.0, to.1), kind, ConnectOptions::default())
        .unwrap();
}

/// One node holding every hot path: for each of int, float, bool and text, a Normal hop
/// (`H_<t>.Out -> HD_<t>.In`) and a fan-out of 4 (`F_<t>.Out -> FD_<t>_{0..3}.In`); the
/// subsumption chain L1 -> ... -> L5 (OverrideOut, 200 ms) on int ports; and a port
/// `P.In` whose OnWrite process copies it to `P.Out`, which feeds `Q.In` (Normal), and
/// whose float and bool ports also trigger processes; and a wave that the plain path hands to
/// the general one midway (`M.Out -> MA.In`, a leaf, then `M.Out -> MB.In -> MC.In`).
struct Rig {
    node: NodeCore,
    hop: [PortRef; 4],
    mixed: PortRef,
    fan: [PortRef; 4],
    chain_top: PortRef,
    chain_bottom: PortRef,
    proc_in: PortRef,
    proc_float: PortRef,
    proc_bool: PortRef,
    q_in: PortRef,
    runs: Arc<AtomicU64>,
}

fn rig() -> Rig {
    let mut node = NodeCore::new(NodeId(1));
    let types: [(&str, Value); 4] =
        [("int", Value::Int(0)), ("float", Value::Float(0.0)), ("bool", Value::Bool(false)), ("text", Value::text(""))];
    for (t, default) in &types {
        let mut src = BehaviorClass::new(&format!("Src_{t}"));
        src.port(PortSpec::new("Out", default.clone())).unwrap();
        node.define(src).unwrap();
        let mut dst = BehaviorClass::new(&format!("Dst_{t}"));
        dst.port(PortSpec::new("In", default.clone())).unwrap();
        node.define(dst).unwrap();
        node.create(&format!("Src_{t}"), &format!("H_{t}")).unwrap();
        node.create(&format!("Dst_{t}"), &format!("HD_{t}")).unwrap();
        connect(&mut node, (&format!("H_{t}"), "Out"), (&format!("HD_{t}"), "In"), ConnectionKind::Normal);
        node.create(&format!("Src_{t}"), &format!("F_{t}")).unwrap();
        for i in 0..4 {
            let d = format!("FD_{t}_{i}");
            node.create(&format!("Dst_{t}"), &d).unwrap();
            connect(&mut node, (&format!("F_{t}"), "Out"), (&d, "In"), ConnectionKind::Normal);
        }
    }
    node.create("Src_int", "M").unwrap();
    for d in ["MA", "MB", "MC"] {
        node.create("Dst_int", d).unwrap();
    }
    connect(&mut node, ("M", "Out"), ("MA", "In"), ConnectionKind::Normal);
    connect(&mut node, ("M", "Out"), ("MB", "In"), ConnectionKind::Normal);
    connect(&mut node, ("MB", "In"), ("MC", "In"), ConnectionKind::Normal);
    let mut layer = BehaviorClass::new("Layer");
    layer.port(PortSpec::new("Rotate", 0i64)).unwrap();
    node.define(layer).unwrap();
    for i in 1..=5 {
        node.create("Layer", &format!("L{i}")).unwrap();
    }
    for i in 1..5 {
        let (a, b) = (format!("L{i}"), format!("L{}", i + 1));
        connect(&mut node, (&a, "Rotate"), (&b, "Rotate"), ConnectionKind::OverrideOut(PERIOD));
    }

    let runs = Arc::new(AtomicU64::new(0));
    let mut p = BehaviorClass::new("Proc");
    let input = p.port(PortSpec::new("In", 0i64)).unwrap();
    let out = p.port(PortSpec::new("Out", 0i64)).unwrap();
    let fin = p.port(PortSpec::new("FIn", 0.0)).unwrap();
    let bin = p.port(PortSpec::new("BIn", false)).unwrap();
    let last_f = p.slot("LastF", 0.0).unwrap();
    let last_b = p.slot("LastB", false).unwrap();
    let r = runs.clone();
    p.on_write("Copy", input, move |ctx| {
        r.fetch_add(1, Ordering::Relaxed);
        let v = ctx.int(input).unwrap_or(0);
        ctx.write(out, v).unwrap();
    })
    .unwrap();
    let r = runs.clone();
    p.on_write("CopyF", fin, move |ctx| {
        r.fetch_add(1, Ordering::Relaxed);
        let v = ctx.float(fin).unwrap_or(0.0);
        ctx.set_slot(last_f, v).unwrap();
    })
    .unwrap();
    let r = runs.clone();
    p.on_write("CopyB", bin, move |ctx| {
        r.fetch_add(1, Ordering::Relaxed);
        let v = ctx.read(bin);
        ctx.set_slot(last_b, v).unwrap();
    })
    .unwrap();
    node.define(p).unwrap();
    let mut q = BehaviorClass::new("Q");
    q.port(PortSpec::new("In", 0i64)).unwrap();
    node.define(q).unwrap();
    node.create("Proc", "P").unwrap();
    node.create("Q", "Q").unwrap();
    connect(&mut node, ("P", "Out"), ("Q", "In"), ConnectionKind::Normal);

    let port = |n: &NodeCore, b: &str, p: &str| n.port(b, p).unwrap();
    Rig {
        hop: ["int", "float", "bool", "text"].map(|t| port(&node, &format!("H_{t}"), "Out")),
        mixed: port(&node, "M", "Out"),
        fan: ["int", "float", "bool", "text"].map(|t| port(&node, &format!("F_{t}"), "Out")),
        chain_top: port(&node, "L1", "Rotate"),
        chain_bottom: port(&node, "L5", "Rotate"),
        proc_in: port(&node, "P", "In"),
        proc_float: port(&node, "P", "FIn"),
        proc_bool: port(&node, "P", "BIn"),
        q_in: port(&node, "Q", "In"),
        node,
        runs,
    }
}

/// One round of scalar writes over every path, then the poll that runs the processes.
fn round(rig: &mut Rig, i: u64) {
    let now = Instant::from_nanos(i * 1_000);
    let node = &mut rig.node;
    let n = i as i64;
    let x = i as f64 * 0.5;
    let b = i & 1 == 0;
    node.write(now, rig.hop[0], n).unwrap();
    node.write(now, rig.hop[1], x).unwrap();
    node.write(now, rig.hop[2], b).unwrap();
    node.write(now, rig.fan[0], n).unwrap();
    node.write(now, rig.fan[1], x).unwrap();
    node.write(now, rig.fan[2], b).unwrap();
    node.write(now, rig.chain_top, n).unwrap();
    node.write(now, rig.mixed, n).unwrap();
    node.write(now, rig.proc_in, n).unwrap();
    node.write(now, rig.proc_float, x).unwrap();
    node.write(now, rig.proc_bool, b).unwrap();
    node.poll(now);
}

// Design §6 / lib docs: "propagating a scalar allocates nothing" — over a Normal hop, a
// fan-out of 4, a 5-layer OverrideOut chain (S6 override windows refreshed every write), a wave
// the plain path hands to the general one midway, and an OnWrite-triggered process (S7) whose
// own write propagates, for i64, f64 and bool values.
#[test]
fn scalar_propagation_does_not_allocate() {
    let mut rig = rig();
    // Warm up: the wave stack, trigger queue and window lists reach their working size.
    for i in 0..16 {
        round(&mut rig, i);
    }
    let runs_before = rig.runs.load(Ordering::Relaxed);
    const ROUNDS: u64 = 10_000;
    let n = allocations(|| {
        for i in 16..16 + ROUNDS {
            round(&mut rig, i);
        }
    });
    assert_eq!(n, 0, "{n} allocations over {ROUNDS} rounds of scalar writes + polls");

    // The writes really went through (so zero is not vacuous).
    let last = 16 + ROUNDS - 1;
    let node = &rig.node;
    assert_eq!(node.read(node.port("HD_int", "In").unwrap()).unwrap(), Value::Int(last as i64));
    assert_eq!(node.read(node.port("HD_float", "In").unwrap()).unwrap(), Value::Float(last as f64 * 0.5));
    assert_eq!(node.read(node.port("FD_float_3", "In").unwrap()).unwrap(), Value::Float(last as f64 * 0.5));
    assert_eq!(node.read(node.port("FD_bool_3", "In").unwrap()).unwrap(), Value::Bool(last & 1 == 0));
    for i in 0..4 {
        let d = node.port(&format!("FD_int_{i}"), "In").unwrap();
        assert_eq!(node.read(d).unwrap(), Value::Int(last as i64));
    }
    assert_eq!(node.read(rig.chain_bottom).unwrap(), Value::Int(last as i64));
    for d in ["MA", "MB", "MC"] {
        assert_eq!(node.read(node.port(d, "In").unwrap()).unwrap(), Value::Int(last as i64));
    }
    assert_eq!(node.read(rig.q_in).unwrap(), Value::Int(last as i64));
    assert_eq!(rig.runs.load(Ordering::Relaxed) - runs_before, 3 * ROUNDS);
    assert_eq!(node.counters().total(), 0, "nothing was dropped: {:?}", node.counters());
}

// S1 / design §6: text is reference-counted, so a text value propagating (Normal hop, fan-out
// of 4) bumps a count but never allocates: the Arc is made once, re-written many times.
#[test]
fn text_propagation_does_not_allocate() {
    let mut rig = rig();
    let text: Arc<str> = Arc::from("approach target 1");
    for i in 0..16 {
        let now = Instant::from_nanos(i * 1_000);
        rig.node.write(now, rig.hop[3], Value::Text(text.clone())).unwrap();
        rig.node.write(now, rig.fan[3], Value::Text(text.clone())).unwrap();
        rig.node.poll(now);
    }
    const ROUNDS: u64 = 10_000;
    let n = allocations(|| {
        for i in 16..16 + ROUNDS {
            let now = Instant::from_nanos(i * 1_000);
            rig.node.write(now, rig.hop[3], Value::Text(text.clone())).unwrap();
            rig.node.write(now, rig.fan[3], Value::Text(text.clone())).unwrap();
            rig.node.poll(now);
        }
    });
    assert_eq!(n, 0, "{n} allocations over {ROUNDS} text writes");
    let node = &rig.node;
    let got = node.read(node.port("FD_text_2", "In").unwrap()).unwrap();
    match got {
        // The very same allocation arrived, not a copy.
        Value::Text(s) => assert!(Arc::ptr_eq(&s, &text)),
        other => panic!("expected text, got {other:?}"),
    }
    // Source, hop destination and 4 fan-out destinations (+ the two source ports) hold it.
    assert_eq!(Arc::strong_count(&text), 1 + 2 + 1 + 4);
}
