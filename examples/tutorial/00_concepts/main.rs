//! The concepts page's code (docs/concepts.md), in Rust: each section between `--8<--` markers
//! is shown on that page beside the same in C and Python, and this program runs them all and
//! checks what the page says (it panics otherwise).
//!
//! Run: `cargo run -p ayllu --example concepts`.

use ayllu::*;

// --8<-- [start:behavior]
/// A behavior class: its registers (ports, slots, monostables) and its processes.
fn observer() -> Result<BehaviorClass, Error> {
    let mut obs = BehaviorClass::new("Observer");
    // Ports: connectable registers, typed by their default (a float here).
    let target = obs.port(PortSpec::new("TargetX", 0.0).lifespan(Duration::from_millis(250)))?;
    let rotate = obs.port(PortSpec::new("Rotate", 0.0))?;
    // A slot: internal state, never connectable.
    let seen = obs.slot("Seen", 0)?;
    // A monostable: true for a while after each trigger.
    let tracking = obs.monostable("Tracking")?;
    // A triggered process: runs whenever TargetX accepts a value.
    obs.on_write("Saw", target, move |ctx| {
        ctx.trigger(tracking, Duration::from_secs(1));
        let n = ctx.slot(seen).as_int().unwrap_or(0);
        let _ = ctx.set_slot(seen, n + 1);
    })?;
    // A periodic process: 20 times a second.
    obs.every_hz("Turn", 20.0, move |ctx| {
        let turn = match ctx.float(target) {
            Some(x) if ctx.is_high(tracking) => -0.5 * x, // None when stale: rule S4
            _ => 0.0,
        };
        let _ = ctx.write(rotate, turn);
    })?;
    Ok(obs)
}
// --8<-- [end:behavior]

fn behaviors_and_processes() -> Result<(), Box<dyn std::error::Error>> {
    let clock = ManualClock::new();
    let mut node = Node::open_with_clock(NodeId(1), "mem://concepts-1", clock.clone())?;
    // --8<-- [start:instance]
    node.define(observer()?)?;
    node.create("Observer", "OBS1")?; // a behavior: an instance of the class
    node.write("OBS1", "TargetX", 0.4)?; // as a camera would
    node.step(); // Saw runs, then Turn
    assert_eq!(node.read("OBS1", "Rotate")?.as_float(), Some(-0.2));
    assert!(node.monostable("OBS1", "Tracking")?);
    // --8<-- [end:instance]
    clock.advance(Duration::from_millis(300));
    node.step();
    assert_eq!(node.read("OBS1", "Rotate")?.as_float(), Some(0.0), "TargetX went stale after 250 ms");
    Ok(())
}

fn connections() -> Result<(), Box<dyn std::error::Error>> {
    let mut node = Node::open_with_clock(NodeId(1), "mem://concepts-2", ManualClock::new())?;
    let mut class = BehaviorClass::new("Cmd");
    class.port(PortSpec::new("Out", 0.0))?;
    node.define(class)?;
    for name in ["A", "B", "C", "D", "E", "F", "G"] {
        node.create("Cmd", name)?;
    }
    let to_g = Endpoint::local("G", "Out");
    // --8<-- [start:connections]
    let p = Duration::from_millis(500); // the window's period
    node.connect(&Endpoint::local("A", "Out"), &to_g, ConnectionKind::Normal)?;
    node.connect(&Endpoint::local("B", "Out"), &to_g, ConnectionKind::Suppress(p))?;
    node.connect(&Endpoint::local("C", "Out"), &to_g, ConnectionKind::Inhibit(p))?;
    node.connect(&Endpoint::local("D", "Out"), &to_g, ConnectionKind::OverrideIn(p))?;
    node.connect(&Endpoint::local("E", "Out"), &to_g, ConnectionKind::OverrideOut(p))?;
    node.connect(&Endpoint::local("F", "Out"), &to_g, ConnectionKind::WriteInhibit(p))?;
    // --8<-- [end:connections]
    node.write("B", "Out", 1.0)?; // opens a suppress window on G
    node.write("A", "Out", 2.0)?; // refused
    assert_eq!(node.why("G", "Out")?.counters.get(DropCause::Suppressed), 1);
    Ok(())
}

fn aggregating_ports() -> Result<(), Box<dyn std::error::Error>> {
    let mut node = Node::open_with_clock(NodeId(1), "mem://concepts-3", ManualClock::new())?;
    // --8<-- [start:aggregating]
    let mut task = BehaviorClass::new("Task");
    // The highest value offered within the last second wins; the port forgets it after that.
    task.port(PortSpec::new("Bid", 0.0).max().window(Duration::from_secs(1)))?;
    node.define(task)?;
    node.create("Task", "T")?;
    node.write("T", "Bid", 3.0)?;
    node.write("T", "Bid", 2.0)?; // absorbed: below the maximum
    assert_eq!(node.read("T", "Bid")?.as_float(), Some(3.0));
    // --8<-- [end:aggregating]
    Ok(())
}

fn ble() -> Result<(), Box<dyn std::error::Error>> {
    // --8<-- [start:ble]
    let mut team = Lockstep::new("concepts-ble"); // three nodes on one virtual clock
    for (id, eligibility) in [(1, 0.2), (2, 0.9), (3, 0.5)] {
        let i = team.add(NodeId(id))?;
        let node = team.node(i);
        let mut worker = BehaviorClass::new("Worker");
        let out = worker.port(PortSpec::new("Out", 0))?;
        worker.every_hz("Work", 10.0, move |ctx| {
            let _ = ctx.write(Port::LOCAL, eligibility); // how well suited this robot is
            let _ = ctx.write(out, i64::from(id));
        })?;
        node.define(worker)?;
        node.create("Worker", "W")?;
        // Join the group: the most eligible claims the task, write-inhibiting the others' Out.
        node.ble_join("W", &BleConfig::new("Peers", "Out", 2.0)?)?;
    }
    team.advance(Duration::from_secs(3), Duration::from_millis(10));
    let claiming: Vec<bool> =
        team.nodes().iter().map(|n| n.core().ble_status("W").ok().flatten().is_some_and(|s| s.claiming)).collect();
    assert_eq!(claiming, [false, true, false]); // robot 2 is the most eligible
                                                // --8<-- [end:ble]
    Ok(())
}

pub fn run() -> Result<String, Box<dyn std::error::Error>> {
    behaviors_and_processes()?;
    connections()?;
    aggregating_ports()?;
    ble()?;
    Ok("every concept ran as the page says\n".into())
}

#[allow(dead_code)] // the tests call `run`
fn main() {
    match run() {
        Ok(out) => print!("{out}"),
        Err(e) => {
            eprintln!("concepts failed: {e}");
            std::process::exit(1);
        }
    }
}
