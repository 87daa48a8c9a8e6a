//! Tutorial 6, recording a team and asking `why` in the past
//! (docs/tutorials/06-recording-why-in-the-past.md): two robots share a task by BLE, each
//! node a flight recorder; robot 1 (the more eligible) dies at 3 s and robot 2 takes over.
//! Afterwards, from robot 2's recording alone, the program asks why its output was blocked at
//! 2 s (robot 1's claim write-inhibited it) and that it was not at 7 s: time travel, without
//! the robots' code.
//!
//! Run: `cargo run -p ayllu --example tutorial_06_recording_why_in_the_past [-- DIR]`; exits
//! non-zero if what the tutorial says does not happen.

use std::fmt::Write as _;
use std::path::Path;

use ayllu::*;

/// A worker that wants the task as much as `eligibility` says.
fn worker(eligibility: f64) -> Result<BehaviorClass, Error> {
    let mut worker = BehaviorClass::new("Worker");
    let out = worker.port(PortSpec::new("Out", 0.0))?;
    worker.every_hz("Work", 10.0, move |ctx| {
        let _ = ctx.write(Port::LOCAL, eligibility); // how well suited this robot is
        let _ = ctx.write(out, 1.0); // doing the task
    })?;
    Ok(worker)
}

/// The tutorial's program: records into `dir`, then replays; returns what it prints.
pub fn run(dir: &Path) -> Result<String, Box<dyn std::error::Error>> {
    let mut out = String::new();
    let mut team = Lockstep::new("tutorial-06");
    for (id, eligibility) in [(1, 0.9), (2, 0.5)] {
        let i = team.add(NodeId(id))?;
        let node = team.node(i);
        // Record first: a replay rebuilds the node from its first definition.
        node.record(dir.join(format!("n{id}.mcap")), RecordOptions::default())?;
        node.define(worker(eligibility)?)?;
        node.create("Worker", "W")?;
        node.ble_join("W", &BleConfig::new("Peers", "Out", 1.0)?)?;
    }
    let tick = Duration::from_millis(10);
    team.advance(Duration::from_secs(3), tick);
    drop(team.kill(NodeId(1))); // robot 1 dies; dropping a node closes its recording
    team.advance(Duration::from_secs(5), tick);
    drop(team); // robot 2's recording is closed too

    // Later, anywhere: robot 2's recording, played back into a fresh core.
    let recording = Recording::open(dir.join("n2.mcap"))?;
    let mut replay = Replay::new(&recording);
    let at_2s = replay.why_at(Instant::from_secs(2), "W", "Out")?;
    writeln!(out, "robot 2 at 2 s:\n{at_2s}")?;
    assert_eq!(at_2s.internal_output_blocked, Some(DropCause::WriteInhibited), "robot 1's claim held it");
    let at_7s = replay.why_at(Instant::from_secs(7), "W", "Out")?;
    writeln!(out, "robot 2 at 7 s:\n{at_7s}")?;
    assert_eq!(at_7s.internal_output_blocked, None, "robot 1's claims lapsed: robot 2 does the task");
    replay.run_to_end()?; // every accepted value reproduced bit for bit, or an error saying where
    writeln!(out, "replayed {} accepted values of robot 2 bit for bit", replay.checked())?;
    Ok(out)
}

#[allow(dead_code)] // the tests call `run`
fn main() {
    let dir = std::env::args().nth(1).unwrap_or_else(|| ".".into());
    match run(Path::new(&dir)) {
        Ok(out) => print!("{out}"),
        Err(e) => {
            eprintln!("tutorial 6 failed: {e}");
            std::process::exit(1);
        }
    }
}
