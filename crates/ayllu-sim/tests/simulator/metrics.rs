//! The metrics that must not mislead (docs/cmommt.md): recovery across robots killed at the
//! same instant, and top-k against the robots still alive.

use ayllu_sim::metrics::Meter;
use ayllu_sim::world::{Pose, World, WorldConfig};

/// Three robots and one target at (4, 4): robots 1 and 2 look at it from 1 m, robot 3 looks
/// away, far off.
fn world() -> World {
    let mut w = World::new(WorldConfig::lab(&[1.0]), 3, 1);
    w.targets[0].x = 4.0;
    w.targets[0].y = 4.0;
    w.robots[0].pose = Pose { x: 3.0, y: 4.0, theta: 0.0 };
    w.robots[1].pose = Pose { x: 5.0, y: 4.0, theta: std::f64::consts::PI };
    w.robots[2].pose = Pose { x: 1.0, y: 1.0, theta: std::f64::consts::PI };
    w
}

#[test]
fn two_robots_killed_at_once_do_not_re_cover_each_others_target() {
    // Robots 1 and 2 both observe the target and die at t = 10: the task is lost until robot 3
    // turns to it at t = 15 (recovery 5 s). Judged one kill at a time with the other still
    // "alive", as before this rule, the first kill recorded a recovery of 0 s.
    let mut w = world();
    let mut meter = Meter::new(&[1.0], 3);
    meter.observe(10.0, 0.1, &w, &[1, 1, 0]);
    w.robots[0].alive = false;
    w.robots[1].alive = false;
    meter.killed_together(10.0, &w, &[0, 1]);
    meter.observe(12.0, 0.1, &w, &[0, 0, 0]);
    w.robots[2].pose = Pose { x: 3.0, y: 3.0, theta: std::f64::consts::FRAC_PI_4 };
    meter.observe(15.0, 0.1, &w, &[0, 0, 1]);
    let m = meter.finish(20.0, 3, 0, 0);
    assert_eq!(m.recover_s, Some(5.0), "one shared task, re-covered after 5 s: {m:?}");
    assert_eq!(m.unrecovered, 0);

    // The old way, for contrast: robot 1's kill judged while robot 2 still lives.
    let mut w = world();
    let mut old = Meter::new(&[1.0], 3);
    w.robots[0].alive = false;
    old.killed(10.0, &w, 0);
    assert_eq!(old.finish(20.0, 3, 0, 0).recover_s, Some(0.0), "what the simultaneous case used to report");
}

#[test]
fn top_k_alive_judges_a_shrunk_team_by_what_it_can_still_cover() {
    // Two targets, two robots; one robot dies and the other keeps the top target: top-k against
    // the starting team (k = 2) is 1/2, against the robots alive (k = 1) it is 1.
    let mut w = World::new(WorldConfig::lab(&[2.0, 1.0]), 2, 1);
    w.targets[0].x = 4.0;
    w.targets[0].y = 4.0;
    w.targets[1].x = 7.0;
    w.targets[1].y = 1.0;
    w.robots[0].pose = Pose { x: 3.0, y: 4.0, theta: 0.0 };
    w.robots[1].pose = Pose { x: 1.0, y: 7.0, theta: std::f64::consts::PI };
    w.robots[1].alive = false;
    let mut meter = Meter::new(&[2.0, 1.0], 2);
    meter.observe(1.0, 1.0, &w, &[1, 0]);
    let m = meter.finish(1.0, 2, 0, 0);
    assert_eq!((m.k, m.top_k, m.top_k_alive), (2, 0.5, 1.0), "{m:?}");
}
