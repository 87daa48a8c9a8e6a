//! Rule S2, monostables: `trigger(p)` makes one true until `max(old_end, now + p)` — a retrigger
//! extends, never shortens. An `OnMonostable` process (S7) runs on the rise (at the next poll)
//! and on the fall (at the first poll at or after the end, which `poll_at` announces).

use std::sync::{Arc, Mutex};

use ayllu_core::*;

fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}

type Log = Arc<Mutex<Vec<(u64, bool)>>>;

/// Behavior `B` with monostable `Busy`, a port `Ping` whose writes trigger `Busy` for 150 ms,
/// and (if `watch`) a process logging `(now_ms, is_high)` each time `Busy` rises or falls.
fn node(watch: bool) -> (NodeCore, Log) {
    let log: Log = Arc::default();
    let mut c = BehaviorClass::new("C");
    let busy = c.monostable("Busy").unwrap();
    let ping = c.port(PortSpec::new("Ping", 0i64)).unwrap();
    c.on_write("Retrigger", ping, move |ctx| ctx.trigger(busy, Duration::from_millis(150))).unwrap();
    if watch {
        let l = log.clone();
        c.on_monostable("Edge", busy, move |ctx| {
            l.lock().unwrap().push((ctx.now().as_nanos() / 1_000_000, ctx.is_high(busy)));
        })
        .unwrap();
    }
    let mut n = NodeCore::new(NodeId(1));
    n.define(c).unwrap();
    n.create("C", "B").unwrap();
    (n, log)
}

fn high(n: &NodeCore) -> bool {
    let r = n.report();
    let b = r.behaviors.iter().find(|b| b.name == "B").unwrap();
    b.monostables.iter().find(|(name, _)| name == "Busy").unwrap().1
}

fn at(n: &mut NodeCore, t: u64) -> bool {
    n.poll(ms(t));
    high(n)
}

#[test]
fn trigger_makes_it_true_for_the_period() {
    // S2: trigger(p) at t makes it true on [t, t + p).
    let (mut n, _) = node(false);
    assert!(!high(&n));
    n.trigger(ms(100), "B", "Busy", Duration::from_millis(500)).unwrap();
    assert!(high(&n));
    assert!(at(&mut n, 599));
    assert!(!at(&mut n, 600));
}

#[test]
fn a_retrigger_never_shortens() {
    // S2: end := max(old_end, now + p) — a shorter retrigger leaves the end alone.
    let (mut n, _) = node(false);
    n.trigger(ms(0), "B", "Busy", Duration::from_millis(1_000)).unwrap();
    n.trigger(ms(500), "B", "Busy", Duration::from_millis(100)).unwrap();
    assert!(at(&mut n, 700));
    assert!(at(&mut n, 999));
    assert!(!at(&mut n, 1_000));
}

#[test]
fn a_retrigger_extends() {
    // S2: a retrigger reaching further moves the end to now + p.
    let (mut n, _) = node(false);
    n.trigger(ms(0), "B", "Busy", Duration::from_millis(1_000)).unwrap();
    n.trigger(ms(800), "B", "Busy", Duration::from_millis(1_000)).unwrap();
    assert!(at(&mut n, 1_500));
    assert!(at(&mut n, 1_799));
    assert!(!at(&mut n, 1_800));
    // Once low, a trigger raises it again.
    n.trigger(ms(2_000), "B", "Busy", Duration::from_millis(10)).unwrap();
    assert!(high(&n));
}

#[test]
fn watcher_runs_on_rise_and_on_fall_and_poll_at_announces_the_fall() {
    // S2/S7: the OnMonostable process runs after the rise (at the next poll, which poll_at asks
    // for at once) and on the fall, at the first poll at or after the end; poll_at reports that
    // end time so a driver sleeps exactly until then.
    let (mut n, log) = node(true);
    assert_eq!(n.poll_at(), None);
    n.trigger(ms(100), "B", "Busy", Duration::from_millis(400)).unwrap();
    assert_eq!(n.poll_at(), Some(ms(100)), "the rise is due now");
    assert!(log.lock().unwrap().is_empty(), "processes run only inside poll");
    assert_eq!(n.poll(ms(100)), Some(ms(500)));
    assert_eq!(*log.lock().unwrap(), vec![(100, true)]);
    assert_eq!(n.poll(ms(499)), Some(ms(500)));
    assert_eq!(log.lock().unwrap().len(), 1);
    assert_eq!(n.poll(ms(500)), None);
    assert_eq!(*log.lock().unwrap(), vec![(100, true), (500, false)]);
    // A late poll still sees the fall, once.
    n.trigger(ms(1_000), "B", "Busy", Duration::from_millis(100)).unwrap();
    n.poll(ms(1_000));
    assert_eq!(n.poll_at(), Some(ms(1_100)));
    n.poll(ms(1_700));
    n.poll(ms(1_800));
    assert_eq!(*log.lock().unwrap(), vec![(100, true), (500, false), (1_000, true), (1_700, false)]);
}

#[test]
fn retriggering_while_high_is_not_a_new_rise() {
    // S2/S7: a monostable kept high by retriggers rises once and falls once, at the last
    // trigger's end; poll_at follows the extended end.
    let (mut n, log) = node(true);
    let ping = n.port("B", "Ping").unwrap();
    for t in [0u64, 100, 200] {
        n.write(ms(t), ping, t as i64).unwrap();
        n.poll(ms(t)); // Retrigger runs (OnWrite), then Edge on the first rise only
    }
    assert_eq!(n.poll_at(), Some(ms(350)));
    assert!(at(&mut n, 349));
    assert!(!at(&mut n, 350));
    assert_eq!(*log.lock().unwrap(), vec![(0, true), (350, false)]);
}

#[test]
fn unknown_monostable_is_an_error() {
    // S2: triggering a monostable that does not exist is reported, not ignored.
    let (mut n, _) = node(false);
    let e = n.trigger(ms(0), "B", "Nope", Duration::from_millis(1)).unwrap_err();
    assert!(matches!(e, Error::UnknownPort { .. }), "{e:?}");
    assert!(e.to_string().contains("Nope"));
    let e = n.trigger(ms(0), "Ghost", "Busy", Duration::from_millis(1)).unwrap_err();
    assert!(matches!(e, Error::UnknownBehavior { .. }), "{e:?}");
}
