//! D7.3 in the runtime: a process that triggers itself does not spin a core under
//! `Node::run_for` on the real clock. The node sleeps until the process may run again
//! (`RETRIGGER_INTERVAL` later), so in 200 ms it steps at most about 200 times (it was 86,262
//! before this rule). A slower machine only steps less, so the verdict cannot fail by chance.

use ayllu::{BehaviorClass, Node, NodeId, PortSpec, RETRIGGER_INTERVAL};

#[test]
fn a_self_triggering_process_does_not_spin_the_node_loop() {
    let mut node = Node::open(NodeId(1), "mem://retrigger-spin").unwrap();
    let mut c = BehaviorClass::new("Loop");
    let count = c.port(PortSpec::new("Count", 0i64)).unwrap();
    c.on_write("Again", count, move |ctx| {
        let v = ctx.read(count).as_int().unwrap();
        ctx.write(count, v + 1).unwrap();
    })
    .unwrap();
    node.define(c).unwrap();
    node.create("Loop", "L").unwrap();
    node.write("L", "Count", 0i64).unwrap();
    let run = std::time::Duration::from_millis(200);
    node.run_for(run);
    let steps = node.stats().steps;
    let runs = node.core().report().behaviors[0].processes[0].runs;
    let per_interval = run.as_nanos() as u64 / RETRIGGER_INTERVAL.as_nanos();
    eprintln!("200 ms of run_for: {steps} steps, {runs} runs (at most about {per_interval} expected)");
    assert!(runs >= 2, "the process keeps running: {runs}");
    assert!(runs <= per_interval + 2, "runs at most once per interval: {runs}");
    assert!(steps <= 2 * per_interval + 10, "the loop sleeps between runs: {steps} steps");
    let why = node.why("L", "Count").unwrap();
    assert!(why.triggers[0].retriggered >= runs - 1, "{why}");
    assert!(node.core().warnings().iter().any(|w| w.contains("L.Again")), "{:?}", node.core().warnings());
}
