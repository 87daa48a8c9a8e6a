//! BLE-seek (docs/cmommt.md, "BLE-seek") against the paper's BLE, BLE-lean, the Planner and the
//! force field, in `examples/sim/ble_seek.toml`'s setting (issue 37: 12 x 8 m, 6 robots, 9
//! targets): the orderings of the comparison table on a few seeds, and the base station's
//! failure as a scenario event.
//!
//! * With the base station working: Planner > BLE-seek > BLE > ForceField on mean A_w, BLE-seek
//!   within 8 % of the Planner, and messages per robot per second BLE > BLE-lean > BLE-seek.
//!   Measured (seeds 1..=4 of 200 s): Planner 0.774, BLE-seek 0.725 (93.7 %; the BLE-seek of
//!   before the hold bonus fell to 1.1 had 0.696, 89.9 %, and fails the check), BLE 0.648,
//!   ForceField 0.469; messages 35.2, 6.1, 3.7 (and ForceField 2.9: BLE-seek costs more than the
//!   force field, less than 1.5 times as much).
//! * The base station killed early (at 20 s): BLE-seek > Planner (0.455), whose robots fall
//!   back to their observer chains; cut off by the radio instead, the Planner loses as much
//!   (0.455).
//! * A controller without a base station runs through the event unchanged, bit for bit, so one
//!   sweep compares the Planner losing its base station with teams that have none.
//!
//! The runs are deterministic, so the verdicts are too; the 20-seed figures of the table are
//! `sim sweep examples/sim/ble_seek.toml`'s (and `the_issue_37_table_holds_on_20_seeds`, ignored:
//! `cargo test --release -p ayllu-sim --test simulator ble_seek:: -- --ignored`).

use ayllu_sim::controller::Controller;
use ayllu_sim::scenario::{run, BaseStationFailure, BaseStationLoss, Scenario};
use ayllu_sim::scenario_file;
use ayllu_sim::study::mean_sd;

const SEEDS: u64 = 4;
const DURATION: f64 = 200.0;

/// The example sweep file, read as `ayllu sim sweep` reads it.
fn sweep() -> scenario_file::Sweep {
    let path = format!("{}/../../examples/sim/ble_seek.toml", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    scenario_file::sweep(&text).expect("the example sweep file reads")
}

/// The first case of the file ("as is") for `controller` and `seed`, `duration` long.
fn as_is(controller: Controller, seed: u64, duration: f64) -> Scenario {
    let sw = sweep();
    assert_eq!(sw.cells[0].values[0].1, "as is", "the file's first case is the setting as is");
    let mut s = sw.cells[0].scenario.clone();
    s.controller = controller;
    s.seed = seed;
    s.controllers.wander_seed = seed;
    s.duration = duration;
    s
}

/// Mean A_w and mean messages per robot per second over seeds 1..=SEEDS.
fn mean(controller: Controller, tweak: impl Fn(&mut Scenario)) -> (f64, f64) {
    let (mut a_w, mut msgs) = (Vec::new(), Vec::new());
    for seed in 1..=SEEDS {
        let mut s = as_is(controller, seed, DURATION);
        tweak(&mut s);
        let m = run(&s).expect("runs").metrics;
        a_w.push(m.a_w);
        msgs.push(m.msgs_per_robot_s);
    }
    (mean_sd(a_w).0, mean_sd(msgs).0)
}

fn killed_at(at: f64) -> impl Fn(&mut Scenario) {
    move |s| s.base_station_failure = Some(BaseStationFailure { at, how: BaseStationLoss::Killed, until: None })
}

#[test]
fn the_comparison_tables_orderings_hold_on_a_few_seeds() {
    let (planner, planner_msgs) = mean(Controller::Planner, |_| {});
    let (seek, seek_msgs) = mean(Controller::BleSeek, |_| {});
    let (ble, ble_msgs) = mean(Controller::Ble, |_| {});
    let (_, lean_msgs) = mean(Controller::BleLean, |_| {});
    let (field, field_msgs) = mean(Controller::ForceField, |_| {});
    let (orphaned, _) = mean(Controller::Planner, killed_at(20.0));
    let (cut_off, _) = mean(Controller::Planner, |s| {
        s.base_station_failure = Some(BaseStationFailure { at: 20.0, how: BaseStationLoss::Partitioned, until: None })
    });
    eprintln!(
        "A_w over seeds 1..={SEEDS}, {DURATION} s: Planner {planner:.3} ({planner_msgs:.1} msgs/robot/s), BLE-seek \
         {seek:.3} ({seek_msgs:.1}), BLE {ble:.3} ({ble_msgs:.1}; BLE-lean {lean_msgs:.1}), ForceField {field:.3} \
         ({field_msgs:.1}); base station killed at 20 s: Planner {orphaned:.3}, cut off: {cut_off:.3}"
    );
    assert!(planner > seek, "the Planner with its base station leads: {planner:.3} vs BLE-seek {seek:.3}");
    // Over 20 seeds of 600 s the gap is under 5 %; four short runs are noisier, hence 8 %.
    assert!(seek >= 0.92 * planner, "BLE-seek within 8 % of the Planner: {seek:.3} vs {planner:.3}");
    assert!(seek > ble, "BLE-seek beats the paper's BLE: {seek:.3} vs {ble:.3}");
    assert!(ble > field, "BLE beats the force field: {ble:.3} vs {field:.3}");
    assert!(ble_msgs > lean_msgs && lean_msgs > seek_msgs, "messages: {ble_msgs:.1} > {lean_msgs:.1} > {seek_msgs:.1}");
    assert!(
        seek_msgs < 1.5 * field_msgs,
        "BLE-seek's messages {seek_msgs:.1} under 1.5 times ForceField's {field_msgs:.1}"
    );
    assert!(orphaned < seek, "without its base station the Planner falls below BLE-seek: {orphaned:.3} vs {seek:.3}");
    assert!(cut_off < seek, "cut off, as killed: {cut_off:.3} vs {seek:.3}");
}

#[test]
fn a_team_without_a_base_station_runs_through_its_failure_unchanged() {
    for controller in [Controller::Ble, Controller::BleSeek, Controller::ForceField] {
        let plain = run(&as_is(controller, 3, 40.0)).expect("runs");
        for how in [BaseStationLoss::Killed, BaseStationLoss::Partitioned] {
            let mut s = as_is(controller, 3, 40.0);
            s.base_station_failure = Some(BaseStationFailure { at: 10.0, how, until: None });
            let failed = run(&s).expect("runs");
            assert_eq!(failed.trace_hash, plain.trace_hash, "{controller:?}, {how:?}");
            assert_eq!(failed.metrics, plain.metrics, "{controller:?}, {how:?}");
        }
    }
}

#[test]
fn the_planner_loses_its_base_station_at_the_instant_and_a_partition_can_heal() {
    let plain = run(&as_is(Controller::Planner, 2, 60.0)).expect("runs");
    let mut killed = as_is(Controller::Planner, 2, 60.0);
    killed.base_station_failure = Some(BaseStationFailure { at: 30.0, how: BaseStationLoss::Killed, until: None });
    let killed = run(&killed).expect("runs");
    // Fewer messages: the base station's assignments stop (the robots still report, unheard).
    assert!(killed.metrics.msgs_per_robot_s < plain.metrics.msgs_per_robot_s);
    let mut healed = as_is(Controller::Planner, 2, 60.0);
    healed.base_station_failure =
        Some(BaseStationFailure { at: 30.0, how: BaseStationLoss::Partitioned, until: Some(35.0) });
    let healed = run(&healed).expect("runs");
    assert_ne!(healed.trace_hash, plain.trace_hash, "a 5 s partition changes the run");
    // Before the instant the runs are the same: a 20 s run with the failure at 30 s is the plain one.
    let mut before = as_is(Controller::Planner, 2, 20.0);
    before.base_station_failure = Some(BaseStationFailure { at: 30.0, how: BaseStationLoss::Killed, until: None });
    assert_eq!(
        run(&before).expect("runs").trace_hash,
        run(&as_is(Controller::Planner, 2, 20.0)).expect("runs").trace_hash
    );
    // A killed base station does not come back.
    let mut back = as_is(Controller::Planner, 2, 20.0);
    back.base_station_failure = Some(BaseStationFailure { at: 5.0, how: BaseStationLoss::Killed, until: Some(9.0) });
    let e = back.validate().unwrap_err().to_string();
    assert!(e.contains("base_station_failure.until"), "{e}");
}

/// The issue's criteria on `examples/sim/ble_seek.toml` as written (20 seeds x 600 s, every
/// case): about 2 minutes in release. Prints the table; checks what the docs claim of it.
#[test]
#[ignore = "the full 20-seed study: cargo test --release -p ayllu-sim --test simulator ble_seek:: -- --ignored"]
fn the_issue_37_table_holds_on_20_seeds() {
    let sw = sweep();
    let out = ayllu_sim::sweep::run(&sw, 2, &|| {}, None, "ble-seek", "test").expect("the sweep runs");
    let a_w = |cell: usize, c: &str| {
        let row = out.cells[cell].rows.iter().find(|r| r.controller == c).expect("a row");
        (row.metrics.a_w, row.metrics.msgs_per_robot_s)
    };
    for (i, cell) in out.cells.iter().enumerate() {
        let rows: Vec<String> = cell
            .rows
            .iter()
            .map(|r| format!("{} {:.3} ({:.1})", r.controller, r.metrics.a_w, r.metrics.msgs_per_robot_s))
            .collect();
        eprintln!("{}: {}", cell.title, rows.join(", "));
        let (seek, seek_msgs) = a_w(i, "BLE-seek");
        let (ble, ble_msgs) = a_w(i, "BLE");
        let (_, lean_msgs) = a_w(i, "BLE-lean");
        let (_, field_msgs) = a_w(i, "ForceField");
        assert!(seek > ble, "{}: BLE-seek {seek:.3}, BLE {ble:.3}", cell.title);
        assert!(seek_msgs < lean_msgs && lean_msgs < ble_msgs, "{}: messages", cell.title);
        // Not at most ForceField's (docs/cmommt.md: missed by 0.6-1.0 a robot a second), but
        // under 1.5 times as many.
        assert!(seek_msgs < 1.5 * field_msgs, "{}: messages {seek_msgs:.1} vs {field_msgs:.1}", cell.title);
    }
    // Where the radio reaches everyone (as is, two robots killed, 20 % loss, the paper's
    // setting): within 5 % of the Planner.
    for cell in [0, 1, 2, 6] {
        let (seek, _) = a_w(cell, "BLE-seek");
        let (planner, _) = a_w(cell, "Planner");
        assert!(seek >= 0.95 * planner, "{}: BLE-seek {seek:.3}, Planner {planner:.3}", out.cells[cell].title);
    }
    // Where the base station fails or the range is short (4 m; the large room's 5 m): above it.
    for cell in [3, 4, 5, 7] {
        let (seek, _) = a_w(cell, "BLE-seek");
        let (planner, _) = a_w(cell, "Planner");
        assert!(seek > planner, "{}: BLE-seek {seek:.3}, Planner {planner:.3}", out.cells[cell].title);
    }
}
