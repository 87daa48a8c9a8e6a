//! A served world on loopback (`ayllu_sim::served_world`): one robot's controller on a thread
//! of this process, on its own UDP node as `ayllu sim robot` would run it, against a
//! [`ServedWorld`] whose body greets it. Every socket binds port 0: the robot's address is
//! read back and named in the body's URL (`peer=`), the body's read back from the world.
//!
//! Checks: the body hears its controller before the start; the events come in order (start,
//! statuses every half second of world time, done) and serialize to `ayllu sim serve`'s lines;
//! the robot moves under its controller's commands; the metrics come back. A world without its
//! robot starts after its wait, reports it missing, and stops when asked from another thread.
//! URLs that do not fit the team are refused before anything is bound.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use ayllu::{Node, NodeId, Value};
use ayllu_sim::controller::{build, Controller, ControllerConfig, SEEK};
use ayllu_sim::scenario::{priorities, Scenario};
use ayllu_sim::served_robot::{self, LINK};
use ayllu_sim::served_world::{Event, ServeConfig, ServeError, ServedWorld};

const TARGETS: usize = 2;

/// Robot 1's controller (`controller`) on its own node, run on a thread until `stop`, reporting
/// its drive as `ayllu sim robot` does, its pose fed from the body link as `ayllu sim robot`
/// feeds it. Returns its address and the thread, which ends with the robot's last
/// `SEEK.Pose` (BLE-seek; empty for other controllers).
fn robot(controller: Controller, stop: Arc<AtomicBool>) -> (String, std::thread::JoinHandle<Vec<f64>>) {
    let mut node = Node::open(NodeId(1), "udp://127.0.0.1:0").expect("the robot's node binds");
    served_robot::install(node.core_mut(), TARGETS).expect("the served body");
    let brain =
        build(node.core_mut(), controller, &priorities(TARGETS), &ControllerConfig::default()).expect("the controller");
    served_robot::connect_pose(node.core_mut(), &brain).expect("the pose wired");
    let address = node.address().expect("a UDP node has an address");
    let thread = std::thread::spawn(move || {
        let end = Instant::now() + Duration::from_secs(60);
        while !stop.load(Ordering::Acquire) && Instant::now() < end {
            let drive = brain.drive(node.core());
            node.write(LINK, "Drive", i64::from(drive)).expect("LINK.Drive");
            node.run_for(Duration::from_millis(20));
        }
        match node.read(SEEK, "Pose") {
            Ok(Value::Vector(p)) => p.to_vec(),
            _ => Vec::new(),
        }
    });
    (address, thread)
}

#[test]
fn a_world_served_on_loopback_drives_an_in_process_robot_and_reports_its_metrics() {
    let stop = Arc::new(AtomicBool::new(false));
    let (address, thread) = robot(Controller::Ble, Arc::clone(&stop));
    let scenario = Scenario::sized(Controller::Random, 1, TARGETS, 7).duration(3.0);
    let mut config = ServeConfig::new(scenario, vec![format!("udp://127.0.0.1:0?peer={address}")]);
    config.status_every = Duration::from_millis(500);
    let mut world = ServedWorld::open(config).expect("the world opens");
    let body = world.body_addresses()[0].clone().expect("the body's address");
    assert!(!body.ends_with(":0"), "the body bound a port of its own: {body}");

    let started = Instant::now();
    let mut events = Vec::new();
    let done = world
        .run(|e| -> Result<(), ServeError> {
            events.push(e.clone());
            Ok(())
        })
        .expect("the run");
    stop.store(true, Ordering::Release);
    thread.join().expect("the robot's thread");
    // 3 s of world time on the real clock, after a wait of at most 10 s.
    assert!(started.elapsed() < Duration::from_secs(20), "took {:?}", started.elapsed());

    let Some(Event::Start(start)) = events.first() else { panic!("no start first: {events:?}") };
    assert!(start.missing.is_empty(), "the body never heard its controller: {start:?}");
    assert_eq!((start.robots, start.targets, start.seed, start.duration), (1, TARGETS, 7, 3.0));
    let statuses: Vec<_> = events
        .iter()
        .filter_map(|e| match e {
            Event::Status(s) => Some(s),
            _ => None,
        })
        .collect();
    assert_eq!(statuses.len(), 6, "a status every 0.5 s of 3 s: {statuses:?}");
    assert!(statuses.iter().all(|s| s.robots[0].linked && s.robots[0].alive));
    assert!(
        statuses.iter().any(|s| s.robots[0].translate != 0.0 || s.robots[0].rotate != 0.0),
        "the controller's commands drive the body: {statuses:?}"
    );
    assert!(matches!(events.last(), Some(Event::Done(d)) if *d == done));
    assert!(!done.stopped && (done.t - 3.0).abs() < 1e-9, "{done:?}");
    assert!((0.0..=1.0).contains(&done.metrics.a_w), "{:?}", done.metrics);

    // The serialized events are `ayllu sim serve`'s lines, keys in its order.
    let keys = |e: &Event| -> Vec<String> {
        serde_json::to_value(e).expect("JSON").as_object().expect("an object").keys().cloned().collect()
    };
    assert_eq!(
        keys(&events[0]),
        ["start", "waited", "missing", "arena", "robots", "targets", "seed", "duration", "kills", "loss"]
    );
    assert_eq!(keys(&Event::Status(statuses[0].clone())), ["t", "observed", "weighted", "a_w", "robots"]);
    assert_eq!(keys(events.last().unwrap()), ["done", "t", "stopped", "resyncs", "metrics", "radio"]);
    let robot = serde_json::to_value(&statuses[0].robots[0]).expect("JSON");
    let robot_keys: Vec<&String> = robot.as_object().expect("an object").keys().collect();
    assert_eq!(robot_keys, ["id", "x", "y", "theta", "translate", "rotate", "linked", "alive", "drive"]);
}

/// BLE-seek's robots localize (docs/cmommt.md, "BLE-seek"): served, the pose comes over the
/// body link (`LINK.Pose`, every sensing tick) to `SEEK.Pose`, as the in-process simulator
/// writes it. The robot's last pose is the world's, within what the robot moves between a
/// status and the end of its thread.
#[test]
fn a_served_ble_seek_robot_is_told_its_pose_over_the_body_link() {
    let stop = Arc::new(AtomicBool::new(false));
    let (address, thread) = robot(Controller::BleSeek, Arc::clone(&stop));
    let scenario = Scenario::sized(Controller::BleSeek, 1, TARGETS, 7).duration(3.0);
    let mut config = ServeConfig::new(scenario, vec![format!("udp://127.0.0.1:0?peer={address}")]);
    config.status_every = Duration::from_millis(500);
    let mut world = ServedWorld::open(config).expect("the world opens");
    let mut last = None;
    let done = world
        .run(|e| -> Result<(), ServeError> {
            if let Event::Status(s) = e {
                last = Some(s.robots[0].clone());
            }
            Ok(())
        })
        .expect("the run");
    stop.store(true, Ordering::Release);
    let pose = thread.join().expect("the robot's thread");
    assert!(!done.stopped, "{done:?}");
    let last = last.expect("statuses");
    assert!(last.linked && last.alive, "{last:?}");
    assert_eq!(pose.len(), 3, "SEEK.Pose never written: {pose:?}");
    // At most 0.4 m/s for the world's last tick and the link's delay: well under 0.5 m.
    let off = (pose[0] - last.x).hypot(pose[1] - last.y);
    assert!(off < 0.5, "the robot's pose {pose:?} vs the world's ({}, {}): {off:.2} m", last.x, last.y);
}

#[test]
fn a_world_without_its_robot_starts_after_its_wait_and_stops_when_asked() {
    let scenario = Scenario::sized(Controller::Random, 1, TARGETS, 1).duration(60.0);
    // Nobody listens at the peer: the body greets into the void.
    let mut config = ServeConfig::new(scenario, vec!["udp://127.0.0.1:0".to_owned()]);
    config.wait = Duration::from_millis(300);
    let mut world = ServedWorld::open(config).expect("the world opens");
    let start = world.start();
    assert_eq!(start.missing, [1]);
    assert!(start.waited >= 0.3 && start.waited < 5.0, "{start:?}");
    let stopper = world.stopper();
    let stopping = std::thread::spawn(move || {
        std::thread::sleep(Duration::from_millis(400));
        stopper.stop();
    });
    let done = world.run(|_| -> Result<(), ServeError> { Ok(()) }).expect("the run");
    stopping.join().expect("the stopping thread");
    assert!(done.stopped && done.t < 30.0, "{done:?}");
    assert!(world.done() && world.step().expect("a step once done").is_empty());
}

#[test]
fn urls_that_do_not_fit_the_team_are_refused_before_anything_is_bound() {
    let two = Scenario::sized(Controller::Random, 2, TARGETS, 1).duration(5.0);
    let open =
        |urls: &[&str]| ServedWorld::open(ServeConfig::new(two.clone(), urls.iter().map(|u| u.to_string()).collect()));
    assert!(matches!(
        open(&["udp://127.0.0.1:0", "udp://127.0.0.1:0", "udp://127.0.0.1:0"]),
        Err(ServeError::UrlCount { urls: 3, robots: 2 })
    ));
    assert!(matches!(open(&["udp://127.0.0.1:7400"]), Err(ServeError::SharedFixedPort { .. })));
    let bad = open(&["nope"]).err().expect("a URL without a scheme is refused");
    assert!(matches!(bad, ServeError::Runtime(_)) && bad.to_string().contains("nope"), "{bad}");
    let many = Scenario::sized(Controller::Random, 1000, TARGETS, 1).duration(5.0);
    let refused = ServedWorld::open(ServeConfig::new(many, vec!["udp://127.0.0.1:0".into()]));
    assert!(matches!(refused, Err(ServeError::TooManyRobots { robots: 1000 })));
    let mut zero =
        ServeConfig::new(Scenario::sized(Controller::Random, 1, TARGETS, 1), vec!["udp://127.0.0.1:0".into()]);
    zero.scenario.duration = 0.0;
    assert!(matches!(ServedWorld::open(zero), Err(ServeError::Duration(_))));
}
