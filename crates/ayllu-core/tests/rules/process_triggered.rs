//! Rule S7, triggered processes: an `OnWrite(port)` process runs after the propagation wave
//! (inside the next `poll`, never inside the write) whenever the port *accepted* a value —
//! from a connection or from the behavior itself — and not when the value was refused (a
//! suppressed connection write). An inhibited port still stores, so it still triggers.
//! Processes run one at a time, to completion; a process that re-triggers itself runs once per
//! poll and leaves `poll_at() == now`.

use std::sync::{Arc, Mutex};

use ayllu_core::*;

fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}

type Log = Arc<Mutex<Vec<String>>>;

/// `Src.Out` -Normal-> `Rx.In` -Normal-> `Tap.In`, plus `Sup.Out` -Suppress(1 s)-> `Rx.In` and
/// `Inh.Out` -Inhibit(1 s)-> `Rx.In`. `Rx` has `OnWrite(In)` process `Seen` logging the value it
/// reads.
fn rig() -> (NodeCore, Log) {
    let log: Log = Arc::default();
    let mut src = BehaviorClass::new("Src");
    src.port(PortSpec::new("Out", 0i64)).unwrap();
    let mut rx = BehaviorClass::new("Rx");
    let input = rx.port(PortSpec::new("In", 0i64)).unwrap();
    let l = log.clone();
    rx.on_write("Seen", input, move |ctx| {
        l.lock().unwrap().push(format!("seen {}", ctx.read(input)));
    })
    .unwrap();
    let mut tap = BehaviorClass::new("Tap");
    tap.port(PortSpec::new("In", 0i64)).unwrap();
    let mut n = NodeCore::new(NodeId(1));
    n.define(src).unwrap();
    n.define(rx).unwrap();
    n.define(tap).unwrap();
    for (class, name) in [("Src", "Src"), ("Src", "Sup"), ("Src", "Inh"), ("Rx", "Rx"), ("Tap", "Tap")] {
        n.create(class, name).unwrap();
    }
    let p = Duration::from_secs(1);
    for (from, to, kind) in [
        ("Src", "Rx", ConnectionKind::Normal),
        ("Rx", "Tap", ConnectionKind::Normal),
        ("Sup", "Rx", ConnectionKind::Suppress(p)),
        ("Inh", "Rx", ConnectionKind::Inhibit(p)),
    ] {
        let (fp, tp) = if from == "Rx" { ("In", "In") } else { ("Out", "In") };
        n.connect(&Endpoint::local(from, fp), &Endpoint::local(to, tp), kind, ConnectOptions::default()).unwrap();
    }
    (n, log)
}

fn runs(n: &NodeCore, behavior: &str, process: &str) -> u64 {
    let r = n.report();
    let b = r.behaviors.iter().find(|b| b.name == behavior).unwrap();
    b.processes.iter().find(|p| p.name == process).unwrap().runs
}

fn entries(log: &Log) -> Vec<String> {
    log.lock().unwrap().clone()
}

#[test]
fn runs_after_the_wave_on_a_connection_write() {
    // S7 OnWrite: the write propagates at once (S5) but the process waits for poll; poll_at
    // says it is due now.
    let (mut n, log) = rig();
    n.write_named(ms(5), "Src", "Out", 7i64).unwrap();
    assert_eq!(n.read(n.port("Tap", "In").unwrap()).unwrap(), Value::Int(7), "the wave is synchronous");
    assert!(entries(&log).is_empty(), "the process must not run inside the write");
    assert_eq!(n.poll_at(), Some(ms(5)));
    assert_eq!(n.poll(ms(5)), None);
    assert_eq!(entries(&log), vec!["seen 7"]);
    n.poll(ms(6));
    assert_eq!(runs(&n, "Rx", "Seen"), 1, "it runs once per accepted write, not per poll");
}

#[test]
fn runs_on_the_behaviors_own_write() {
    // S7 OnWrite: a value the behavior writes itself triggers too.
    let (mut n, log) = rig();
    n.write_named(ms(1), "Rx", "In", 3i64).unwrap();
    n.poll(ms(1));
    assert_eq!(entries(&log), vec!["seen 3"]);
}

#[test]
fn several_accepted_writes_before_a_poll_run_it_once_with_the_latest_value() {
    // S7: a pending process is queued once; it reads the port as it is when it runs.
    let (mut n, log) = rig();
    for v in [1i64, 2, 3] {
        n.write_named(ms(1), "Src", "Out", v).unwrap();
    }
    n.poll(ms(1));
    assert_eq!(entries(&log), vec!["seen 3"]);
}

#[test]
fn does_not_run_when_the_write_is_refused() {
    // S7 + S6 Suppress: a suppressed connection write is refused (not stored), so no trigger;
    // the behavior's own write to the suppressed port is stored and does trigger.
    let (mut n, log) = rig();
    n.write_named(ms(0), "Sup", "Out", 0i64).unwrap(); // Rx.In suppressed until 1 s
    n.poll(ms(0));
    assert!(entries(&log).is_empty(), "the suppress message itself is not written");
    n.write_named(ms(10), "Src", "Out", 9i64).unwrap();
    assert_eq!(n.why("Rx", "In").unwrap().counters.get(DropCause::Suppressed), 1);
    assert_eq!(n.poll_at(), None);
    n.poll(ms(10));
    assert!(entries(&log).is_empty());
    n.write_named(ms(20), "Rx", "In", 4i64).unwrap();
    n.poll(ms(20));
    assert_eq!(entries(&log), vec!["seen 4"]);
}

#[test]
fn runs_even_when_the_port_is_inhibited() {
    // S7 + S6 Inhibit: an inhibited port stores what reaches it (and triggers), it only does
    // not propagate.
    let (mut n, log) = rig();
    n.write_named(ms(0), "Inh", "Out", 0i64).unwrap(); // Rx.In inhibited until 1 s
    n.write_named(ms(10), "Src", "Out", 5i64).unwrap();
    n.poll(ms(10));
    assert_eq!(entries(&log), vec!["seen 5"]);
    assert_eq!(n.read(n.port("Tap", "In").unwrap()).unwrap(), Value::Int(0), "nothing propagated");
    assert_eq!(n.why("Rx", "In").unwrap().counters.get(DropCause::Inhibited), 1);
}

#[test]
fn does_not_run_when_an_aggregating_port_absorbs() {
    // S7 + S3: an absorbed value was not accepted, so it triggers nothing.
    let log: Log = Arc::default();
    let mut c = BehaviorClass::new("C");
    let best = c.port(PortSpec::new("Top", 0i64).max()).unwrap();
    let l = log.clone();
    c.on_write("Seen", best, move |ctx| l.lock().unwrap().push(format!("seen {}", ctx.read(best)))).unwrap();
    let mut n = NodeCore::new(NodeId(1));
    n.define(c).unwrap();
    n.create("C", "B").unwrap();
    n.write_named(ms(0), "B", "Top", 10i64).unwrap();
    n.poll(ms(0));
    n.write_named(ms(1), "B", "Top", 3i64).unwrap();
    n.poll(ms(1));
    assert_eq!(entries(&log), vec!["seen 10"]);
}

#[test]
fn triggered_processes_run_to_completion_one_at_a_time() {
    // S7: a process that writes a port with an OnWrite process is not interrupted: the
    // triggered one starts only after the writer returned, and sees everything it wrote.
    let log: Log = Arc::default();
    let mut c = BehaviorClass::new("C");
    let go = c.port(PortSpec::new("Go", 0i64)).unwrap();
    let x = c.port(PortSpec::new("X", 0i64)).unwrap();
    let done = c.slot("WriterDone", false).unwrap();
    let (l1, l2) = (log.clone(), log.clone());
    c.on_write("Writer", go, move |ctx| {
        l1.lock().unwrap().push("writer start".into());
        ctx.set_slot(done, false).unwrap();
        ctx.write(x, 1i64).unwrap();
        ctx.write(x, 2i64).unwrap();
        l1.lock().unwrap().push("writer end".into());
        ctx.set_slot(done, true).unwrap();
    })
    .unwrap();
    c.on_write("Reader", x, move |ctx| {
        l2.lock().unwrap().push(format!("reader x={} writer_done={}", ctx.read(x), ctx.slot(done)));
    })
    .unwrap();
    let mut n = NodeCore::new(NodeId(1));
    n.define(c).unwrap();
    n.create("C", "B").unwrap();
    n.write_named(ms(0), "B", "Go", 1i64).unwrap();
    n.poll(ms(0));
    assert_eq!(entries(&log), vec!["writer start", "writer end", "reader x=2 writer_done=true"]);
}

#[test]
fn a_self_retriggering_process_runs_once_per_poll_and_at_most_once_per_interval() {
    // S7, D7.3: a process whose write re-triggers itself cannot spin: it runs once per poll;
    // then it is held back until RETRIGGER_INTERVAL later (poll_at says when), counted as
    // `retriggered` in the report and in `why` of its trigger port, and warned about once.
    let mut c = BehaviorClass::new("C");
    let count = c.port(PortSpec::new("Count", 0i64)).unwrap();
    c.on_write("Again", count, move |ctx| {
        let v = ctx.read(count).as_int().unwrap();
        ctx.write(count, v + 1).unwrap();
    })
    .unwrap();
    let mut n = NodeCore::new(NodeId(1));
    n.define(c).unwrap();
    n.create("C", "B").unwrap();
    n.write_named(ms(0), "B", "Count", 0i64).unwrap();
    let step = RETRIGGER_INTERVAL;
    let mut t = ms(0);
    for k in 1..=5u64 {
        let due = n.poll(t);
        assert_eq!(due, Some(t + step), "poll {k}: due again one interval later");
        assert_eq!(n.poll_at(), Some(t + step));
        assert_eq!(runs(&n, "B", "Again"), k);
        assert_eq!(n.read(n.port("B", "Count").unwrap()).unwrap(), Value::Int(k as i64));
        // Polling before the interval ends runs nothing.
        n.poll(t + Duration::from_nanos(step.as_nanos() / 2));
        assert_eq!(runs(&n, "B", "Again"), k, "held back until {:?}", t + step);
        t += step;
    }
    let p = n.report().behaviors[0].processes.iter().find(|p| p.name == "Again").unwrap().clone();
    assert_eq!(p.retriggered, 5);
    let why = n.why("B", "Count").unwrap();
    assert_eq!(why.triggers.len(), 1);
    assert_eq!((why.triggers[0].name.as_str(), why.triggers[0].retriggered), ("Again", 5));
    assert!(why.to_string().contains("TRIGGERS ITSELF"), "{why}");
    let warnings: Vec<&String> = n.warnings().iter().filter(|w| w.contains("B.Again")).collect();
    assert_eq!(warnings.len(), 1, "warned once: {:?}", n.warnings());
}

#[test]
fn a_process_triggered_once_per_poll_is_not_held_back() {
    // D7.3: a trigger from outside (a write between polls) runs at the next poll, however
    // often it comes; only a re-trigger within the poll in which the process ran is held back.
    let mut c = BehaviorClass::new("C");
    let input = c.port(PortSpec::new("In", 0i64)).unwrap();
    c.on_write("Count", input, |_| {}).unwrap();
    let mut n = NodeCore::new(NodeId(1));
    n.define(c).unwrap();
    n.create("C", "B").unwrap();
    for k in 1..=5u64 {
        let t = Instant::from_nanos(k * 1000);
        n.write_named(t, "B", "In", k as i64).unwrap();
        n.poll(t);
        assert_eq!(runs(&n, "B", "Count"), k);
    }
    assert_eq!(n.report().behaviors[0].processes[0].retriggered, 0);
    assert!(n.warnings().is_empty());
}

#[test]
fn triggered_process_of_a_removed_behavior_does_not_run() {
    // S7/S9: a pending trigger dies with its behavior; a re-created one under the same name
    // does not inherit it.
    let (mut n, log) = rig();
    n.write_named(ms(0), "Rx", "In", 1i64).unwrap();
    n.remove("Rx").unwrap();
    n.create("Rx", "Rx").unwrap();
    n.poll(ms(0));
    assert!(entries(&log).is_empty());
    assert_eq!(runs(&n, "Rx", "Seen"), 0);
}

#[test]
fn triggered_processes_run_in_declaration_order_however_many() {
    // A port's triggers are kept as bits while they are processes below 31 in ascending order
    // and as a list otherwise: both must queue them in declaration order, each once.
    let log: Log = Arc::default();
    let mut class = BehaviorClass::new("Many");
    let a = class.port(PortSpec::new("A", 0i64)).unwrap();
    let b = class.port(PortSpec::new("B", 0i64)).unwrap();
    let c = class.port(PortSpec::new("C", 0i64)).unwrap();
    // Process i: on A if i % 3 == 0 (up to 39: a list), on B if i % 3 == 1 below 31 (bits),
    // on C otherwise.
    let on = |i: usize| {
        if i.is_multiple_of(3) {
            a
        } else if i % 3 == 1 && i < 31 {
            b
        } else {
            c
        }
    };
    for i in 0..40 {
        let l = log.clone();
        class.on_write(&format!("P{i}"), on(i), move |_| l.lock().unwrap().push(format!("P{i}"))).unwrap();
    }
    let mut n = NodeCore::new(NodeId(1));
    n.define(class).unwrap();
    n.create("Many", "M").unwrap();
    let named = |pred: &dyn Fn(usize) -> bool| -> Vec<String> {
        (0..40).filter(|&i| pred(i)).map(|i| format!("P{i}")).collect()
    };
    let run = |n: &mut NodeCore, t: u64, port: &str| {
        log.lock().unwrap().clear();
        n.write_named(ms(t), "M", port, 1i64).unwrap();
        n.write_named(ms(t), "M", port, 2i64).unwrap(); // already pending: queued once
        n.poll(ms(t));
        entries(&log)
    };
    assert_eq!(run(&mut n, 1, "A"), named(&|i| on(i) == a));
    assert_eq!(run(&mut n, 2, "B"), named(&|i| on(i) == b));
    // Added after creation as process 40: B's triggers become a list.
    let l = log.clone();
    n.add_process("M", "Late", Trigger::OnWrite(b), move |_| l.lock().unwrap().push("Late".into())).unwrap();
    let mut expected = named(&|i| on(i) == b);
    expected.push("Late".into());
    assert_eq!(run(&mut n, 3, "B"), expected);
}
