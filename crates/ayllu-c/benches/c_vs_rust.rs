//! `make bench-c`: a port write and a process activation from C (benches/c/bench.c, built with
//! -O2 against the release libayllu and run as a child here) beside the same from Rust, in the
//! same run on the same machine, with the ratios. Not a test: it prints what it measured.
//!
//! The operations, each the best of 5 rounds:
//! * write through a port handle, crossing one Normal connection: C `ay_node_write_int_ref`,
//!   Rust `NodeCore::write` with a `PortRef`;
//! * write by names: C `ay_node_write_int`, Rust `Node::write`;
//! * activation: advance a manual clock 1 ms and step the node, whose 1 kHz process writes its
//!   own port (a C function through `ay_ctx_write_int`; a Rust closure through `Ctx::write`).

use std::process::Command;
use std::time::Instant as StdInstant;

use ayllu::{
    BehaviorClass, ConnectionKind, Duration, Endpoint, ManualClock, MemNetwork, Node, NodeId, PortSpec, Value,
};

const WRITES: u64 = 1_000_000;
const ACTIVATIONS: u64 = 200_000;

fn best(mut f: impl FnMut() -> f64) -> f64 {
    (0..5).map(|_| f()).fold(f64::INFINITY, f64::min)
}

fn rust() -> (f64, f64, f64) {
    let clock = ManualClock::new();
    let net = MemNetwork::new();
    let mut node = Node::new(clock.clone(), net.attach(NodeId(1)).expect("attach"));
    let mut relay = BehaviorClass::new("Relay");
    relay.port(PortSpec::new("V", 0i64)).expect("port");
    node.define(relay).expect("define");
    node.create("Relay", "A").expect("create");
    node.create("Relay", "B").expect("create");
    node.connect(&Endpoint::local("A", "V"), &Endpoint::local("B", "V"), ConnectionKind::Normal).expect("connect");
    let mut ticker = BehaviorClass::new("Ticker");
    let out = ticker.port(PortSpec::new("Out", 0i64)).expect("port");
    let n = std::sync::Arc::new(std::sync::atomic::AtomicI64::new(0));
    let count = n.clone();
    ticker
        .every_hz("Tick", 1000.0, move |ctx| {
            let k = count.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            ctx.write(out, k).expect("write");
        })
        .expect("process");
    node.define(ticker).expect("define");
    node.create("Ticker", "T").expect("create");
    let a = node.core().port("A", "V").expect("port");
    let by_ref = best(|| {
        let t = StdInstant::now();
        for i in 0..WRITES {
            let core = node.core_mut(); // told the present
            let now = core.now();
            core.write(now, a, Value::Int(i as i64)).expect("write");
        }
        t.elapsed().as_nanos() as f64 / WRITES as f64
    });
    let by_name = best(|| {
        let t = StdInstant::now();
        for i in 0..WRITES / 4 {
            node.write("A", "V", i as i64).expect("write");
        }
        t.elapsed().as_nanos() as f64 / (WRITES / 4) as f64
    });
    let activation = best(|| {
        let t = StdInstant::now();
        for _ in 0..ACTIVATIONS {
            clock.advance(Duration::from_millis(1));
            node.step();
        }
        t.elapsed().as_nanos() as f64 / ACTIVATIONS as f64
    });
    assert_eq!(node.read("B", "V").expect("read"), Value::Int(WRITES as i64 / 4 - 1), "the writes were done");
    assert!(n.load(std::sync::atomic::Ordering::Relaxed) >= ACTIVATIONS as i64, "the activations were done");
    (by_ref, by_name, activation)
}

fn main() {
    let Ok(c_bench) = std::env::var("AYLLU_C_BENCH") else {
        eprintln!("c_vs_rust: AYLLU_C_BENCH is not set (run `make bench-c`); nothing measured");
        return;
    };
    let out = Command::new(&c_bench)
        .args([WRITES.to_string(), ACTIVATIONS.to_string()])
        .output()
        .expect("running the C benchmark");
    assert!(out.status.success(), "the C benchmark failed: {}", String::from_utf8_lossy(&out.stderr));
    let c: serde_json::Value = serde_json::from_slice(&out.stdout).expect("the C benchmark's JSON line");
    let (r_ref, r_name, r_act) = rust();
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines().find(|l| l.starts_with("model name")).map(|l| l.split(':').nth(1).unwrap_or("").trim().to_owned())
        })
        .unwrap_or_else(|| "unknown CPU".to_owned());
    println!("libayllu: C beside Rust, same run ({cpu}; best of 5 rounds, ns per operation)");
    println!("{:<58} {:>9} {:>9} {:>8}", "operation", "C", "Rust", "C/Rust");
    for (name, key, rust) in [
        ("port write through a handle, across a Normal connection", "write_ref_ns", r_ref),
        ("port write by names, across a Normal connection", "write_named_ns", r_name),
        ("process activation (1 kHz process writing its port)", "activation_ns", r_act),
    ] {
        let c = c[key].as_f64().expect("a figure");
        println!("{name:<58} {c:>9.1} {rust:>9.1} {:>7.2}x", c / rust);
    }
}
