//! Changes made to a node between its steps are dated at the clock's present, not at the
//! node's last step (`Node::core_mut`, `NodeCore::advance_to`): a node added to a running team,
//! or wired long after it was made and before it first steps, would otherwise date its
//! behaviors' creation and its BLE joins in the past. Then a periodic process was charged
//! overruns for the time before its behavior existed and ran off its creation's phase (D7.2),
//! and a new BLE member claimed at its first select, before it had heard a peer (D11.3). A
//! recording of such a node replays bit for bit (the replay is told each entry's time).

use std::sync::{Arc, Mutex};

use ayllu::replay::{Recording, Replay};
use ayllu::{BehaviorClass, BleConfig, Duration, Event, Instant, Lockstep, NodeId, PortSpec, RecordOptions, Value};

const TICK: Duration = Duration::from_millis(10);

/// Class `Per`: one port and a 10 Hz process that notes the time of each of its runs.
fn periodic_class(runs: &Arc<Mutex<Vec<Instant>>>) -> BehaviorClass {
    let mut class = BehaviorClass::new("Per");
    let out = class.port(PortSpec::new("O", 0i64)).unwrap();
    let runs = runs.clone();
    class
        .every_hz("Tick", 10.0, move |ctx| {
            runs.lock().unwrap().push(ctx.now());
            ctx.write(out, 1i64).unwrap();
        })
        .unwrap();
    class
}

fn overruns(team: &mut Lockstep, i: usize, behavior: &str) -> u64 {
    let report = team.node(i).core().report();
    let b = report.behaviors.iter().find(|b| b.name == behavior).expect("the behavior is reported");
    b.processes[0].overruns
}

/// D7.2: a behavior created on a node added to a team that has run for 3.03 s is phase-locked
/// to its creation (3.03 s), and no activation before it is counted as missed.
#[test]
fn a_process_on_a_node_added_to_a_running_team_keeps_its_creations_phase() {
    let mut team = Lockstep::new("late-node-phase");
    team.add(NodeId(1)).unwrap();
    team.advance(Duration::from_millis(3030), TICK);
    let late = team.add(NodeId(2)).unwrap();
    let runs = Arc::new(Mutex::new(Vec::new()));
    team.node(late).define(periodic_class(&runs)).unwrap();
    team.node(late).create("Per", "P").unwrap();
    team.advance(Duration::from_millis(300), TICK);
    let runs = runs.lock().unwrap().clone();
    // The first poll at or after the creation is the team's next step (3.04 s); then the grid.
    let expected: Vec<Instant> = [3040, 3130, 3230, 3330].into_iter().map(Instant::from_millis).collect();
    assert_eq!(runs, expected, "runs on the grid of the creation at 3.03 s");
    assert_eq!(overruns(&mut team, late, "P"), 0, "nothing was missed before the behavior existed");
}

/// The same on one node wired 2 s after it was made, before its first step: the creation is
/// dated when it was made, not at the node's time 0.
#[test]
fn a_process_created_before_a_nodes_first_step_is_dated_when_it_was_created() {
    let mut team = Lockstep::new("unstepped-node-phase");
    let i = team.add(NodeId(1)).unwrap();
    team.clock().set(Instant::from_millis(2000));
    let runs = Arc::new(Mutex::new(Vec::new()));
    team.node(i).define(periodic_class(&runs)).unwrap();
    team.node(i).create("Per", "P").unwrap();
    team.advance(Duration::from_millis(250), TICK);
    let runs = runs.lock().unwrap().clone();
    assert_eq!(runs.first().copied(), Some(Instant::from_millis(2010)), "first run at the first step");
    assert_eq!(runs.get(1).copied(), Some(Instant::from_millis(2100)), "then on the creation's grid");
    assert_eq!(overruns(&mut team, i, "P"), 0);
}

type Eligibility = f64;

/// Class `Obs` writing `Local` := `eligibility` and `Out` := its node id at 20 Hz.
fn observer(eligibility: Eligibility, id: i64) -> BehaviorClass {
    let mut class = BehaviorClass::new("Obs");
    let out = class.port(PortSpec::new("Out", 0i64)).unwrap();
    class
        .every_hz("Work", 20.0, move |ctx| {
            ctx.write(ayllu::Port::LOCAL, eligibility).unwrap();
            ctx.write(out, id).unwrap();
        })
        .unwrap();
    class
}

/// D11.3: a robot whose node joins a running team at 3 s listens for a whole claim cycle
/// before it may claim, so a poorly suited newcomer (0.1 against the incumbent's 0.9) never
/// write-inhibits the incumbent.
#[test]
fn a_ble_member_on_a_node_added_to_a_running_team_listens_before_it_claims() {
    let config = BleConfig::new("Peers", "Out", 1.0).unwrap();
    let mut team = Lockstep::new("late-ble-member");
    let a = team.add(NodeId(1)).unwrap();
    team.node(a).define(observer(0.9, 1)).unwrap();
    team.node(a).create("Obs", "W").unwrap();
    team.node(a).ble_join("W", &config).unwrap();
    team.advance(Duration::from_secs(3), TICK);
    assert!(team.node(a).core().ble_status("W").unwrap().unwrap().claiming, "the incumbent claims");

    let b = team.add(NodeId(2)).unwrap();
    team.node(b).define(observer(0.1, 2)).unwrap();
    team.node(b).create("Obs", "W").unwrap();
    team.node(b).ble_join("W", &config).unwrap();
    // Across the newcomer's first cycle and well beyond it.
    for _ in 0..300 {
        team.advance(TICK, TICK);
        let newcomer = team.node(b).core().ble_status("W").unwrap().unwrap();
        assert_eq!(newcomer.claims, 0, "at {:?} the newcomer claimed: {newcomer:?}", team.now());
        let incumbent = team.node(a).core().ble_status("W").unwrap().unwrap();
        assert!(incumbent.inhibited_by.is_empty(), "at {:?}: {incumbent:?}", team.now());
    }
}

/// A recording of a node whose behavior was created between steps, at a time its core had
/// not been told by a step, replays to its end with every accepted value equal.
#[test]
fn a_change_made_between_steps_replays_at_its_time() {
    let d = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("changes-between-steps-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    let path = d.join("late.mcap");
    let mut team = Lockstep::new("late-create-replay");
    let i = team.add(NodeId(1)).unwrap();
    team.node(i).record(&path, RecordOptions::default()).unwrap();
    let runs = Arc::new(Mutex::new(Vec::new()));
    team.node(i).define(periodic_class(&runs)).unwrap();
    team.advance(Duration::from_millis(100), TICK);
    team.clock().set(Instant::from_millis(1234));
    team.node(i).create("Per", "P").unwrap();
    team.advance(Duration::from_millis(500), TICK);
    team.node(i).stop_recording().unwrap();

    let rec = Recording::open(&path).unwrap();
    let created = rec.entries.iter().find(|e| matches!(e.event, Event::Create { .. })).expect("the create");
    assert_eq!(created.at, Instant::from_millis(1234), "journaled at the time it was made");
    let accepted = rec.entries.iter().filter(|e| matches!(e.event, Event::Accepted { .. })).count();
    assert!(accepted >= 5, "{accepted} values accepted");
    let mut replay = Replay::new(&rec);
    replay.run_to_end().unwrap_or_else(|d| panic!("{d}"));
    assert_eq!(replay.checked(), accepted);
    let port = replay.core().port("P", "O").unwrap();
    assert_eq!(replay.core().read(port).unwrap(), Value::Int(1));
}
