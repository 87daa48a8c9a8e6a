//! An Ayllu controller drives a ROS 2 robot through the ROS 2 body, against an independent
//! ROS 2 stack: a kinematic robot written in Python on Cyclone DDS (the DDS under
//! `rmw_cyclonedds_cpp`), publishing `/robot1/scan` and `/robot1/odom` and obeying
//! `/robot1/cmd_vel` with ROS 2's names, types and QoS, as a ROS 2 driver does. The controller is
//! `ayllu node --controller wander --ros2 examples/ros2/turtlebot.toml` (safe velocity + wander +
//! avoid), unchanged from any other body.
//!
//! Built only with `--features ros2` (`make test-ros2`); each test in a network namespace of
//! its own.

#![cfg(feature = "ros2")]

use crate::common;

use std::time::Duration;

use common::ros2::{own_network, peer};
use common::{ayllu, wait_for, Proc, BIN};
use serde_json::Value as Json;

fn example(name: &str) -> String {
    format!("{}/../../examples/ros2/{name}", env!("CARGO_MANIFEST_DIR"))
}

/// The robot's last line of a kind (`done`, `ready`, or the status lines).
fn last_with(p: &Proc, key: &str) -> Option<Json> {
    p.lines().into_iter().rev().map(|(_, j)| j).find(|j| !j[key].is_null())
}

#[test]
fn a_wander_controller_drives_a_cyclone_robot_for_a_minute_without_collision() {
    own_network();
    let domain = 0;
    let seconds = 60.0;
    let mut robot = Proc::spawn(
        "robot",
        peer("robot.py", domain, &["--namespace", "robot1", "--duration", &format!("{seconds}"), "--seed", "7"]),
    );
    wait_for(Duration::from_secs(20), Duration::from_millis(50), || last_with(&robot, "ready"))
        .unwrap_or_else(|| panic!("the robot did not start: {}", robot.stderr()));

    let mut cmd = std::process::Command::new(BIN);
    cmd.args(["node", "--id", "1", "--controller", "wander", "--ros2", &example("turtlebot.toml")])
        .args(["--for", &format!("{}", seconds + 10.0), "--status-ms", "1000"])
        .env("ROS_DOMAIN_ID", domain.to_string());
    let mut node = Proc::spawn("ayllu node", cmd);
    let address = node.wait_ready();

    // What `ros2 topic list -t` would print, read from the independent stack's discovery data
    // (its built-in publication and subscription topics), once Ayllu's body is up.
    let listed = wait_for(Duration::from_secs(20), Duration::from_millis(500), || {
        let out = peer("topics.py", domain, &["--seconds", "2", "--json"]).output().ok()?;
        let j: Json = serde_json::from_slice(&out.stdout).ok()?;
        let cmd_vel = &j["/robot1/cmd_vel"];
        (cmd_vel["publishers"].as_u64()? >= 1 && j["/robot1/scan"]["subscribers"].as_u64()? >= 1).then_some(j)
    })
    .unwrap_or_else(|| panic!("Cyclone DDS never saw Ayllu's endpoints; node stderr: {}", node.stderr()));
    for (topic, ty) in [
        ("/robot1/cmd_vel", "geometry_msgs/msg/Twist"),
        ("/robot1/scan", "sensor_msgs/msg/LaserScan"),
        ("/robot1/odom", "nav_msgs/msg/Odometry"),
    ] {
        let types: Vec<&str> =
            listed[topic]["types"].as_array().map_or(vec![], |a| a.iter().filter_map(Json::as_str).collect());
        assert_eq!(types, [ty], "{topic}: {listed}");
    }
    let plain = peer("topics.py", domain, &["--seconds", "2"]).output().expect("topics.py");
    let plain = String::from_utf8_lossy(&plain.stdout);
    assert!(plain.lines().any(|l| l == "/robot1/cmd_vel [geometry_msgs/msg/Twist]"), "{plain}");

    // While it runs: `ayllu list` shows the body's samples by topic.
    let list_url = format!("udp://127.0.0.1:0?peer={address}");
    let list = wait_for(Duration::from_secs(10), Duration::from_millis(500), || {
        let run = ayllu(&["list", "1", "--json", "--udp", &list_url], Duration::from_secs(10));
        let j = run.json();
        (j["body_counted"]["/robot1/scan taken"].as_u64()? > 0).then_some(j)
    })
    .expect("ayllu list never showed scans taken");
    assert!(list["body_counted"]["/robot1/cmd_vel published"].as_u64().unwrap_or(0) > 0, "{list}");

    let done =
        wait_for(Duration::from_secs_f64(seconds + 30.0), Duration::from_millis(200), || last_with(&robot, "done"))
            .unwrap_or_else(|| panic!("the robot never finished: {}", robot.stderr()));
    let status = node.latest().map(|(_, j)| j).unwrap_or_default();
    eprintln!("robot: {done}\nnode: {status}");
    node.kill();
    let _ = robot.exited();

    // The robot moved for the minute, driven by what it received, and never hit anything.
    let received = done["cmd_received"].as_u64().unwrap_or(0);
    let nonzero = done["cmd_nonzero"].as_u64().unwrap_or(0);
    let distance = done["distance"].as_f64().unwrap_or(0.0);
    assert_eq!(done["collisions"].as_u64(), Some(0), "the robot collided: {done}\nnode: {status}");
    assert!(received >= 300, "only {received} cmd_vel samples in {seconds} s at 10 Hz: {done}");
    assert!(nonzero * 2 >= received, "mostly zero commands: {done}");
    assert!(distance >= 3.0, "the robot moved only {distance} m in a minute: {done}");
    // The body took the robot's scans and published its commands, and dropped nothing.
    let body = &status["counters"]["body"];
    assert!(body["/robot1/scan taken"].as_u64().unwrap_or(0) >= 300, "{status}");
    for cause in ["truncated", "too_long", "malformed", "bad_text", "nan", "refused"] {
        assert_eq!(body[format!("/robot1/scan {cause}")].as_u64(), Some(0), "{cause}: {status}");
    }
}
