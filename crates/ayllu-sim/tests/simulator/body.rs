//! The body as behaviors with ports: the interface a controller sees is the stdlib's, the
//! simulator writes only what the camera sees, and the standard behaviors (SafeVelocity,
//! the observer) close the loop through it.

use ayllu::stdlib::{base_class, sonar_class, vision_class, BASE, SONAR, VEL, VISION};
use ayllu_core::{Duration, Instant, NodeCore, NodeId};
use ayllu_sim::body::Body;
use ayllu_sim::controller::{build, Controller, ControllerConfig};
use ayllu_sim::world::{Pose, WorldConfig};

use crate::common;
use common::quiet;

#[test]
fn a_robot_driver_built_from_the_stdlib_classes_is_a_body() {
    // What a real robot's driver would create (the paper's ayInitPioControl), by hand:
    let mut robot = NodeCore::new(NodeId(1));
    robot.define(vision_class(3).unwrap()).unwrap();
    robot.define(sonar_class(8, 3.0).unwrap()).unwrap();
    robot.define(base_class().unwrap()).unwrap();
    robot.create("Vision", VISION).unwrap();
    robot.create("Sonar", SONAR).unwrap();
    robot.create("Base", BASE).unwrap();
    // The simulator's body attaches to it unchanged: same behaviors, same ports.
    assert!(Body::attach(&robot, 3, 8).is_ok());
    // And the simulator's own install gives a node with the same interface.
    let mut sim = NodeCore::new(NodeId(2));
    Body::install(&mut sim, 3, &WorldConfig::lab(&[3.0, 2.0, 1.0])).unwrap();
    for (b, p) in [(VISION, "Target3Bottom"), (SONAR, "Ranges"), (BASE, "Rotate"), (BASE, "Translate")] {
        assert_eq!(robot.why(b, p).unwrap().kind, sim.why(b, p).unwrap().kind, "{b}.{p}");
    }
}

#[test]
fn only_seen_targets_are_written_and_unseen_ones_go_stale() {
    let mut w = quiet(Pose { x: 2.0, y: 2.0, theta: 0.0 }, (4.0, 2.0));
    let mut core = NodeCore::new(NodeId(1));
    let mut body = Body::install(&mut core, 1, &w.config).unwrap();
    let angle = core.port(VISION, "Target1Angle").unwrap();
    let t0 = Instant::ZERO + Duration::from_millis(100);
    w.index();
    body.sense(&mut core, t0, &mut w, 0).unwrap();
    core.poll(t0);
    assert!(core.fresh(angle).unwrap());
    // Turn away: the next frames do not see it; after the lifespan the port is stale.
    w.robots[0].pose.theta = std::f64::consts::PI;
    let mut t = t0;
    for _ in 0..4 {
        t += Duration::from_millis(100);
        body.sense(&mut core, t, &mut w, 0).unwrap();
        core.poll(t);
    }
    assert!(!core.fresh(angle).unwrap());
}

#[test]
fn the_observer_and_safe_velocity_bring_the_robot_to_its_target() {
    // Target off to the left; BLE controller alone (no peers: it claims after one cycle).
    let mut w = quiet(Pose { x: 1.5, y: 2.0, theta: 0.0 }, (5.0, 3.5));
    let mut core = NodeCore::new(NodeId(1));
    let mut body = Body::install(&mut core, 1, &w.config).unwrap();
    let brain = build(&mut core, Controller::Ble, &[1.0], &ControllerConfig::default()).unwrap();
    let dt = Duration::from_millis(50);
    let mut now = Instant::ZERO;
    for tick in 1..=600u32 {
        now += dt;
        if tick % 2 == 0 {
            w.index();
            body.sense(&mut core, now, &mut w, 0).unwrap();
        }
        core.poll(now);
        let cmd = body.command(&core);
        w.step(0.05, &[cmd]);
    }
    let p = w.robots[0].pose;
    let (dx, dy) = (5.0 - p.x, 3.5 - p.y);
    let gap = dx.hypot(dy) - w.config.robot_radius - w.config.target_radius;
    let bearing = ayllu_sim::world::wrap(dy.atan2(dx) - p.theta);
    assert_eq!(brain.drive(&core), 1, "OBS1 drives");
    // SafeVelocity stops 0.3 m from what is ahead (sonar noise: a few cm).
    assert!((0.2..0.45).contains(&gap), "gap {gap:.3}");
    assert!(bearing.abs() < 0.2, "faces the target: {bearing:.3}");
    let translate = core.read(core.port(VEL, "Translate").unwrap()).unwrap().as_float().unwrap();
    assert!(translate < 0.05, "stopped: {translate}");
}
