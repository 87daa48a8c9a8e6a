//! Two nodes talking real UDP on this machine: a sonar on robot 1 drives the motor of robot 2
//! across the network, and a joystick on robot 2 overrides it while the operator holds it
//! (1 s to 2 s, plus the override's 0.5 s): the paper's subsumption, between robots. Prints
//! what reaches the motor, who supplied it, and finally `why`.
//!
//! Both nodes run in this one program, on the real clock, over loopback: node 1 binds a port
//! the system chooses, node 2 is told that address and greets it. On robots, each program
//! opens its node with `ayllu::default_url()` instead (the `AYLLU_URL` environment variable,
//! else discovery on the machine; docs/cli.md).
//!
//! Run: `cargo run --release --example two_nodes_udp`

use std::fmt::Write as _;

use ayllu::*;

/// A robot whose node knows three behavior classes: `Sonar` (a periodic process writes
/// `Range`), `Joystick` (an operator who holds the stick at 0 between 1 s and 2 s) and `Motor`
/// (`Speed`, stale 300 ms after its last command).
fn robot(id: u32, url: &str) -> Result<Node, Box<dyn std::error::Error>> {
    let mut node = Node::open(NodeId(id), url)?;
    let mut sonar = BehaviorClass::new("Sonar");
    let range = sonar.port(PortSpec::new("Range", 0.0))?;
    sonar.every_hz("Ping", 20.0, move |ctx| {
        let t = ctx.now().as_secs_f64();
        let _ = ctx.write(range, 1.0 + 0.5 * (t * 3.0).sin()); // metres
    })?;
    let mut joystick = BehaviorClass::new("Joystick");
    let stick = joystick.port(PortSpec::new("Speed", 0.0))?;
    joystick.every_hz("Read", 10.0, move |ctx| {
        if (1.0..2.0).contains(&ctx.now().as_secs_f64()) {
            let _ = ctx.write(stick, 0.0); // the operator stops the robot
        }
    })?;
    let mut motor = BehaviorClass::new("Motor");
    motor.port(PortSpec::new("Speed", 0.0).lifespan(Duration::from_millis(300)))?;
    node.define(sonar)?;
    node.define(joystick)?;
    node.define(motor)?;
    Ok(node)
}

pub fn run(seconds: f64) -> Result<String, Box<dyn std::error::Error>> {
    let mut out = String::new();
    // Robot 1 on a port the system chooses; robot 2 is told where robot 1 is.
    let mut r1 = robot(1, "udp://127.0.0.1:0")?;
    let r1_at = r1.address().ok_or("robot 1 has no address")?;
    let mut r2 = robot(2, &format!("udp://127.0.0.1:0?peer={r1_at}"))?;
    r1.create("Sonar", "SONAR")?;
    r2.create("Motor", "MOTOR")?;
    // Robot 1's sonar drives robot 2's motor across the network...
    r1.connect(
        &Endpoint::local("SONAR", "Range"),
        &Endpoint::node(NodeId(2), "MOTOR", "Speed"),
        ConnectionKind::Normal,
    )?;
    // ...until a joystick on robot 2 overrides it: for 0.5 s after each of its commands, only
    // the joystick may write the motor (Brooks' suppression is Ayllu's OverrideIn).
    r2.create("Joystick", "JOYSTICK")?;
    r2.connect(
        &Endpoint::local("JOYSTICK", "Speed"),
        &Endpoint::local("MOTOR", "Speed"),
        ConnectionKind::OverrideIn(Duration::from_millis(500)),
    )?;
    let start = std::time::Instant::now();
    let (mut last_print, mut suppliers) = (0.0, Vec::new());
    while start.elapsed().as_secs_f64() < seconds {
        r1.run_for(std::time::Duration::from_millis(5));
        r2.run_for(std::time::Duration::from_millis(5));
        let why = r2.why("MOTOR", "Speed")?;
        let by = why.supplier.map_or("nobody".to_owned(), |s| s.to_string());
        let t = start.elapsed().as_secs_f64();
        if t - last_print >= 0.5 {
            last_print = t;
            writeln!(out, "{t:4.1}s  MOTOR.Speed = {:.3} from {by}", why.value.as_float().unwrap_or(0.0))?;
        }
        if why.fresh && !suppliers.contains(&by) {
            suppliers.push(by);
        }
    }
    writeln!(out, "suppliers seen: {}", suppliers.join(", "))?;
    writeln!(out, "\n{}", r2.why("MOTOR", "Speed")?)?;
    Ok(out)
}

fn main() {
    match run(3.0) {
        Ok(text) => print!("{text}"),
        Err(e) => {
            eprintln!("two_nodes_udp: {e}");
            std::process::exit(1);
        }
    }
}
