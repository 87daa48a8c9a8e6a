//! Tutorial 3, two nodes over UDP (docs/tutorials/03-two-nodes-udp.md): robot 1's sonar writes
//! robot 2's motor across real sockets on loopback. Each node binds port 0 (the system picks a
//! free one) and robot 2 is told where robot 1 is; both run on the real clock in one program.
//!
//! Run: `cargo run -p ayllu --example tutorial_03_two_nodes_udp`; exits non-zero if no value
//! crosses the network within 10 s.

use std::fmt::Write as _;

use ayllu::*;

/// Robot 1: a sonar whose 20 Hz process writes `Range`.
fn sonar_robot() -> Result<Node, Box<dyn std::error::Error>> {
    let mut node = Node::open(NodeId(1), "udp://127.0.0.1:0")?;
    let mut sonar = BehaviorClass::new("Sonar");
    let range = sonar.port(PortSpec::new("Range", 0.0))?;
    sonar.every_hz("Ping", 20.0, move |ctx| {
        let _ = ctx.write(range, 0.75); // metres
    })?;
    node.define(sonar)?;
    node.create("Sonar", "SONAR")?;
    Ok(node)
}

/// Robot 2: a motor whose `Speed` goes stale 300 ms after its last command (rule S4).
fn motor_robot(peer: &str) -> Result<Node, Box<dyn std::error::Error>> {
    let mut node = Node::open(NodeId(2), &format!("udp://127.0.0.1:0?peer={peer}"))?;
    let mut motor = BehaviorClass::new("Motor");
    motor.port(PortSpec::new("Speed", 0.0).lifespan(Duration::from_millis(300)))?;
    node.define(motor)?;
    node.create("Motor", "MOTOR")?;
    Ok(node)
}

/// The tutorial's program: returns what it prints.
pub fn run() -> Result<String, Box<dyn std::error::Error>> {
    let mut out = String::new();
    let mut r1 = sonar_robot()?;
    let r1_at = r1.address().ok_or("robot 1 has no address")?;
    let mut r2 = motor_robot(&r1_at)?;
    writeln!(out, "robot 1 at {r1_at}, robot 2 at {}", r2.address().unwrap_or_default())?;
    // A connection whose destination is a port on another node: robot 1 sends each value
    // of SONAR.Range to robot 2, which applies it (and the kind) on its own clock.
    r1.connect(
        &Endpoint::local("SONAR", "Range"),
        &Endpoint::node(NodeId(2), "MOTOR", "Speed"),
        ConnectionKind::Normal,
    )?;

    let start = std::time::Instant::now();
    let mut arrived = false;
    // Bounded: at most 10 s, in 5 ms turns of each node.
    while !arrived && start.elapsed() < std::time::Duration::from_secs(10) {
        r1.run_for(std::time::Duration::from_millis(5));
        r2.run_for(std::time::Duration::from_millis(5));
        arrived = r2.fresh("MOTOR", "Speed")?;
    }
    assert!(arrived, "no value crossed the network in 10 s");
    let why = r2.why("MOTOR", "Speed")?;
    let from = why.supplier.map(|s| s.to_string()).unwrap_or_default();
    writeln!(out, "MOTOR.Speed on robot 2 came from {from}: {}", why.value)?;
    assert!(from.starts_with("n1"), "the supplier is robot 1's connection: {from}");
    assert_eq!(why.value.as_float(), Some(0.75));
    write!(out, "{why}")?;
    Ok(out)
}

#[allow(dead_code)] // the tests call `run`
fn main() {
    match run() {
        Ok(out) => print!("{out}"),
        Err(e) => {
            eprintln!("tutorial 3 failed: {e}");
            std::process::exit(1);
        }
    }
}
