//! What only the run's insides can show: the drive read from what a body saw is the drive read
//! from its ports, and loading ahead, threads and shared classes change nothing, bit for bit.

use super::visit::{LOOK_AHEAD_TEAM, ROBOTS_PER_THREAD};
use super::{Kill, Scenario, Sim};
use crate::controller::{chain_quiet, Brain, Controller};
use crate::radio::Partition;

/// `Sim::step` asks [`Brain::drive_seen`], which skips the layers whose target the body
/// has not written lately; it must give [`Brain::drive`]'s answer, every robot, every
/// tick, whatever the radio does to the BLE claims (loss, delay, range, partitions), after
/// kills, with the planner's override above the chain, and when the senses run every few
/// ticks.
#[test]
fn the_drive_from_what_the_body_saw_is_the_drive_from_the_ports() {
    let mut driven = 0u64;
    for (case, controller) in
        [Controller::Ble, Controller::Local, Controller::Planner, Controller::Ble].into_iter().enumerate()
    {
        for seed in [3, 11] {
            let mut s = Scenario::sized(controller, 12, 5, seed).loss(0.3).duration(40.0);
            s.radio.delay = 0.05;
            s.radio.jitter = 0.03;
            s.radio.range = Some(7.0);
            s.radio.partitions.push(Partition { start: 8.0, end: 18.0, island: vec![1, 2, 3, 4] });
            s.kills.push(Kill { at: 12.0, robot: None });
            s.kills.push(Kill { at: 25.0, robot: Some(5) });
            if case == 3 {
                s.sense_every = 3;
            }
            let mut sim = Sim::new(&s).expect("builds");
            while !sim.done() {
                sim.step().expect("steps");
                for (i, r) in sim.robots.iter().enumerate() {
                    if !sim.world.robots[i].alive {
                        continue;
                    }
                    let old = r.brain.drive(&r.core);
                    assert_eq!(r.brain.drive_seen(&r.core, r.body.seen()), old, "{controller:?} {seed} robot {i}");
                    if matches!(r.brain, Brain::Chain(_)) && chain_quiet(r.core.now(), r.body.latest_seen()) {
                        assert_eq!(old, 0, "{controller:?} {seed} robot {i}");
                    }
                    assert_eq!(sim.drives[i], old);
                    driven += u64::from(old != 0);
                }
            }
        }
    }
    // Not vacuous: observers drove often.
    assert!(driven > 10_000, "{driven}");
}

/// Loading messages ahead is a hint: a large team's run with it is the run without it,
/// bit for bit, with loss, a range limit, a partition and kills (dead robots' messages
/// are looked at but not delivered).
#[test]
fn loading_ahead_changes_nothing() {
    let mut s = Scenario::sized(Controller::Ble, LOOK_AHEAD_TEAM + 5, 5, 9).loss(0.2).duration(4.0);
    s.radio.range = Some(30.0);
    s.radio.partitions.push(Partition { start: 1.0, end: 2.0, island: (1..100).collect() });
    s.kills.push(Kill { at: 1.5, robot: None });
    s.kills.push(Kill { at: 2.5, robot: Some(7) });
    // Every node's report (each port's value, counts and drops) and the run's outcome.
    let outcome = |ahead: bool| {
        let mut sim = Sim::new(&s).expect("builds");
        assert!(sim.look_ahead, "the team is large enough");
        sim.look_ahead = ahead;
        while !sim.done() {
            sim.step().expect("steps");
        }
        let nodes: Vec<_> = sim.robots.iter().map(|r| r.core.report()).collect();
        (nodes, sim.finish())
    };
    let ((nodes_with, with), (nodes_without, without)) = (outcome(true), outcome(false));
    for (i, (a, b)) in nodes_with.iter().zip(&nodes_without).enumerate() {
        assert_eq!(a, b, "robot {i}");
    }
    assert_eq!(with.trace_hash, without.trace_hash);
    assert_eq!(with.radio, without.radio);
    assert_eq!(with.metrics, without.metrics);
    assert!(with.radio.delivered > 10_000, "messages flowed: {:?}", with.radio);
}

/// Sharing a tick's visits among threads (`Sim::set_threads`) must give the run of one
/// thread bit for bit: every controller (the Centralized oracle's words and the Planner's
/// base station included), with loss, jitter, a range limit, a partition and kills, split
/// in two and in three unequal shares, and a team large enough to load its messages
/// ahead of the visits.
#[test]
fn threads_change_nothing() {
    let mut cases: Vec<(Scenario, usize)> = Controller::ALL
        .iter()
        .map(|&c| {
            let mut s = Scenario::sized(c, 3 * ROBOTS_PER_THREAD + 7, 5, 4).loss(0.15).duration(5.0);
            s.radio.jitter = 0.03;
            s.radio.range = Some(25.0);
            s.radio.partitions.push(Partition { start: 1.0, end: 2.0, island: (1..40).collect() });
            s.kills.push(Kill { at: 1.5, robot: None });
            s.kills.push(Kill { at: 2.5, robot: Some(ROBOTS_PER_THREAD as u32 + 1) });
            (s, 3)
        })
        .collect();
    cases.push((Scenario::sized(Controller::Ble, LOOK_AHEAD_TEAM + 5, 5, 9).loss(0.1).duration(3.0), 2));
    for (s, threads) in cases {
        let outcome = |threads: usize| {
            let mut sim = Sim::new(&s).expect("builds");
            sim.set_threads(threads).expect("the threads start");
            assert_eq!(sim.threads(), threads);
            while !sim.done() {
                sim.step().expect("steps");
            }
            let nodes: Vec<_> = sim.robots.iter().map(|r| r.core.report()).collect();
            (nodes, sim.finish())
        };
        let ((nodes_one, one), (nodes_more, more)) = (outcome(1), outcome(threads));
        let name = s.controller.name();
        for (i, (a, b)) in nodes_one.iter().zip(&nodes_more).enumerate() {
            assert_eq!(a, b, "{name}: robot {i}");
        }
        assert_eq!(one.trace_hash, more.trace_hash, "{name}");
        assert_eq!(one.radio, more.radio, "{name}");
        assert_eq!(one.metrics, more.metrics, "{name}");
        assert_eq!(one.coverage, more.coverage, "{name}");
        if matches!(s.controller, Controller::Ble | Controller::Planner) {
            assert!(one.radio.delivered > 1000, "{name}: messages flowed: {:?}", one.radio);
        }
    }
}

/// A team too small for two shares of [`ROBOTS_PER_THREAD`] runs on one thread whatever is
/// allowed, and 0 counts as 1.
#[test]
fn small_teams_stay_on_one_thread() {
    let mut sim = Sim::new(&Scenario::sized(Controller::Ble, 2 * ROBOTS_PER_THREAD - 1, 4, 1)).unwrap();
    sim.set_threads(8).unwrap();
    assert_eq!(sim.threads(), 1);
    sim.set_threads(0).unwrap();
    assert_eq!(sim.threads(), 1);
    let mut sim = Sim::new(&Scenario::sized(Controller::Ble, 2 * ROBOTS_PER_THREAD, 4, 1)).unwrap();
    sim.set_threads(8).unwrap();
    assert_eq!(sim.threads(), 2);
}

/// `Sim::new` defines one copy of each class on every robot (crate::classes); each robot
/// building its own classes (`controller::build`, as `with_controller` callers do) must
/// give the same run bit for bit, for every controller: no class keeps per-robot state.
#[test]
fn sharing_classes_changes_nothing() {
    for controller in Controller::ALL {
        let mut s = Scenario::sized(controller, 12, 4, 5).loss(0.1).duration(6.0);
        s.kills.push(Kill { at: 3.0, robot: Some(2) });
        let run_with = |sim: Sim| {
            let mut sim = sim;
            while !sim.done() {
                sim.step().expect("steps");
            }
            let nodes: Vec<_> = sim.robots.iter().map(|r| r.core.report()).collect();
            (nodes, sim.finish())
        };
        let (nodes_shared, shared) = run_with(Sim::new(&s).expect("builds"));
        let own =
            Sim::with_controller(&s, &mut |core, prios, cfg| crate::controller::build(core, controller, prios, cfg));
        let (nodes_own, own) = run_with(own.expect("builds"));
        for (i, (a, b)) in nodes_shared.iter().zip(&nodes_own).enumerate() {
            assert_eq!(a, b, "{} robot {i}", controller.name());
        }
        assert_eq!(shared.trace_hash, own.trace_hash, "{}", controller.name());
        assert_eq!(shared.metrics, own.metrics, "{}", controller.name());
    }
}
