//! Tutorial 1, a first behavior (docs/tutorials/01-first-behavior.md): a class with ports, a
//! slot, a monostable and two processes, made on a node that runs on a manual clock, so the
//! program decides when time passes and every line it prints is the same on every machine.
//!
//! Run: `cargo run -p ayllu --example tutorial_01_first_behavior`. It checks what the tutorial
//! says happens and exits non-zero (a panic) if anything differs.

use std::fmt::Write as _;

use ayllu::*;

/// `Avoid`: when the sonar's `Range` falls under half a metre, back off (`Backing` stays high
/// for 2 s) and turn; a 10 Hz process writes the turn to `Turn`.
fn avoid() -> Result<BehaviorClass, Error> {
    let mut avoid = BehaviorClass::new("Avoid");
    let range = avoid.port(PortSpec::new("Range", 10.0))?; // metres, written by a sonar
    let turn = avoid.port(PortSpec::new("Turn", 0.0))?; // rad/s, to the motors
    let seen = avoid.slot("Seen", 0)?; // internal: not connectable
    let backing = avoid.monostable("Backing")?; // high for a while after a trigger
    avoid.on_write("React", range, move |ctx| {
        // Runs whenever Range accepts a value; `float` is None when the value is stale (S4).
        if ctx.float(range).is_some_and(|r| r < 0.5) {
            ctx.trigger(backing, Duration::from_secs(2));
            let n = ctx.slot(seen).as_int().unwrap_or(0);
            let _ = ctx.set_slot(seen, n + 1);
        }
    })?;
    avoid.every_hz("Steer", 10.0, move |ctx| {
        let _ = ctx.write(turn, if ctx.is_high(backing) { 1.0 } else { 0.0 });
    })?;
    Ok(avoid)
}

/// The tutorial's program: returns what it prints.
pub fn run() -> Result<String, Box<dyn std::error::Error>> {
    let mut out = String::new();
    let clock = ManualClock::new(); // time moves only when we say
    let mut node = Node::open_with_clock(NodeId(1), "mem://tutorial-01", clock.clone())?;
    node.define(avoid()?)?;
    node.create("Avoid", "A")?;

    node.write("A", "Range", 0.3)?; // at 0 s, as a sonar would
    node.step(); // React, then Steer's first activation
    let turn = node.read("A", "Turn")?.as_float();
    writeln!(out, "0.0 s: Range 0.3 m -> Turn {turn:?}, Backing {}", node.monostable("A", "Backing")?)?;
    assert_eq!(turn, Some(1.0));
    assert!(node.monostable("A", "Backing")?);

    for _ in 0..20 {
        clock.advance(Duration::from_millis(100)); // 2 s in ten steps a second
        node.step();
    }
    let turn = node.read("A", "Turn")?.as_float();
    writeln!(out, "2.0 s: Turn {turn:?}, Backing {}", node.monostable("A", "Backing")?)?;
    assert_eq!(turn, Some(0.0), "the monostable fell after 2 s, so Steer writes 0");
    assert!(!node.monostable("A", "Backing")?);
    write!(out, "{}", node.why("A", "Turn")?)?;
    Ok(out)
}

#[allow(dead_code)] // the tests call `run`
fn main() {
    match run() {
        Ok(out) => print!("{out}"),
        Err(e) => {
            eprintln!("tutorial 1 failed: {e}");
            std::process::exit(1);
        }
    }
}
