//! Tutorial 4, a BLE group of three robots in the simulator
//! (docs/tutorials/04-ble-in-the-simulator.md): the paper's setting (3 robots, 4 moving targets
//! with priorities 4, 3, 2, 1), every robot running Fig. 2's cross-subsumption, one robot
//! killed at 30 s. Every 10 s it prints which robot claims which target (each layer `OBSn` is
//! one BLE group), then the run's weighted coverage beside Random's in the same world.
//!
//! Run: `cargo run -p ayllu-sim --example tutorial_04_ble_in_the_simulator`; exits non-zero if
//! what the tutorial says does not happen.

use std::fmt::Write as _;

use ayllu_sim::controller::Controller;
use ayllu_sim::scenario::{run, Kill, Scenario, Sim};

/// The tutorial's program: returns what it prints.
pub fn run_tutorial() -> Result<String, Box<dyn std::error::Error>> {
    let mut out = String::new();
    let mut scenario = Scenario::paper(Controller::Ble, 1).duration(60.0);
    scenario.kills.push(Kill { at: 30.0, robot: Some(1) }); // robot 1 fails at 30 s

    let mut sim = Sim::new(&scenario)?;
    let mut next_print = 10.0;
    let mut claimed_after_kill = Vec::new();
    writeln!(out, "time | who claims T1 T2 T3 T4 (robot, or -)")?;
    while !sim.done() {
        sim.step()?;
        let t = sim.now().as_secs_f64();
        if t + 1e-9 < next_print {
            continue;
        }
        next_print += 10.0;
        let mut line = format!("{t:4.0} |           ");
        for target in 1..=4 {
            // A robot claims target n while its layer OBSn holds the BLE claim (rule S11).
            let who: Vec<usize> = (0..scenario.robots)
                .filter(|&i| sim.world().robots[i].alive)
                .filter(|&i| sim.core(i).ble_status(&format!("OBS{target}")).ok().flatten().is_some_and(|s| s.claiming))
                .map(|i| i + 1)
                .collect();
            assert!(who.len() <= 1, "one claim per target at {t} s: {who:?}"); // cross-inhibition
            let cell = if who.is_empty() { "-".to_owned() } else { who.iter().map(|r| format!("r{r}")).collect() };
            write!(line, " {cell:>2}")?;
            if t > 30.0 {
                claimed_after_kill.extend(who);
            }
        }
        writeln!(out, "{line}")?;
    }
    let ble = sim.finish();
    let random = run(&Scenario { controller: Controller::Random, ..scenario.clone() })?;
    writeln!(
        out,
        "A_w with BLE {:.3}, with Random {:.3} (same world, same kill)",
        ble.metrics.a_w, random.metrics.a_w
    )?;
    assert!(!claimed_after_kill.contains(&1), "a dead robot claims nothing: its claims were leases");
    assert!(!claimed_after_kill.is_empty(), "the live robots claim targets after the kill");
    assert!(ble.metrics.a_w > random.metrics.a_w + 0.2, "BLE observes far more than wandering");
    Ok(out)
}

#[allow(dead_code)] // the tests call `run_tutorial`
fn main() {
    match run_tutorial() {
        Ok(out) => print!("{out}"),
        Err(e) => {
            eprintln!("tutorial 4 failed: {e}");
            std::process::exit(1);
        }
    }
}
