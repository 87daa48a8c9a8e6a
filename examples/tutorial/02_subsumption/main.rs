//! Tutorial 2, two behaviors in subsumption (docs/tutorials/02-subsumption.md): `Wander` keeps
//! the robot turning gently; `Avoid`, the higher layer, takes the motor over while an obstacle
//! is near, through an OverrideIn connection (Brooks's suppression: the input is replaced), and
//! gives it back half a second after its last command. Manual clock: the same output everywhere.
//!
//! Run: `cargo run -p ayllu --example tutorial_02_subsumption`; exits non-zero if what the
//! tutorial says does not happen.

use std::fmt::Write as _;

use ayllu::*;

fn classes() -> Result<[BehaviorClass; 3], Error> {
    let mut wander = BehaviorClass::new("Wander");
    let turn = wander.port(PortSpec::new("Turn", 0.0))?;
    wander.every_hz("Drift", 10.0, move |ctx| {
        let _ = ctx.write(turn, 0.2);
    })?;

    let mut avoid = BehaviorClass::new("Avoid");
    let range = avoid.port(PortSpec::new("Range", 10.0))?;
    let away = avoid.port(PortSpec::new("Turn", 0.0))?;
    avoid.on_write("React", range, move |ctx| {
        if ctx.float(range).is_some_and(|r| r < 0.5) {
            let _ = ctx.write(away, 1.0); // hard turn away from the obstacle
        }
    })?;

    let mut motor = BehaviorClass::new("Motor");
    motor.port(PortSpec::new("Turn", 0.0))?;
    Ok([wander, avoid, motor])
}

/// The tutorial's program: returns what it prints.
pub fn run() -> Result<String, Box<dyn std::error::Error>> {
    let mut out = String::new();
    let clock = ManualClock::new();
    let mut node = Node::open_with_clock(NodeId(1), "mem://tutorial-02", clock.clone())?;
    for class in classes()? {
        node.define(class)?;
    }
    node.create("Wander", "WANDER")?;
    node.create("Avoid", "AVOID")?;
    node.create("Motor", "MOTOR")?;
    // The lower layer drives the motor...
    node.connect(&Endpoint::local("WANDER", "Turn"), &Endpoint::local("MOTOR", "Turn"), ConnectionKind::Normal)?;
    // ...and the higher layer subsumes it: for 0.5 s after each of Avoid's values, only Avoid
    // may write MOTOR.Turn.
    node.connect(
        &Endpoint::local("AVOID", "Turn"),
        &Endpoint::local("MOTOR", "Turn"),
        ConnectionKind::OverrideIn(Duration::from_millis(500)),
    )?;

    let (mut seen, mut during) = (Vec::new(), String::new());
    for tenth in 0..=40u64 {
        let t = tenth as f64 / 10.0;
        if (10..20).contains(&tenth) {
            node.write("AVOID", "Range", 0.3)?; // an obstacle from 1 s to 2 s
        }
        node.step();
        let turn = node.read("MOTOR", "Turn")?.as_float().unwrap_or(f64::NAN);
        if tenth % 5 == 0 {
            writeln!(out, "{t:3.1} s  MOTOR.Turn = {turn}")?;
        }
        seen.push((t, turn));
        if tenth == 15 {
            during = node.why("MOTOR", "Turn")?.to_string(); // while Avoid holds the motor
        }
        clock.advance(Duration::from_millis(100));
    }
    let at = |t: f64| seen.iter().find(|(s, _)| (s - t).abs() < 1e-9).map(|p| p.1);
    assert_eq!(at(0.5), Some(0.2), "Wander drives the motor before the obstacle");
    assert_eq!(at(1.5), Some(1.0), "Avoid has taken the motor over");
    assert_eq!(at(2.2), Some(1.0), "Avoid's last command still holds: its window lasts 0.5 s");
    assert_eq!(at(3.0), Some(0.2), "Wander has the motor back");
    let why = node.why("MOTOR", "Turn")?;
    let refused = why.counters.get(DropCause::OverriddenIn);
    writeln!(out, "Wander's values refused while Avoid held the motor: {refused} (overridden_in)")?;
    write!(out, "why, at 1.5 s:\n{during}")?;
    assert!(refused >= 10, "Wander writes 10 times a second; about 14 were refused");
    Ok(out)
}

#[allow(dead_code)] // the tests call `run`
fn main() {
    match run() {
        Ok(out) => print!("{out}"),
        Err(e) => {
            eprintln!("tutorial 2 failed: {e}");
            std::process::exit(1);
        }
    }
}
