//! The paper's claim, tested: in its setting (3 robots, 4 targets with priorities 4, 3, 2, 1),
//! BLE cross-subsumption covers the priority-weighted targets better than wandering (Random)
//! and than each robot greedily following what it sees (Local), and a killed robot's task is
//! picked up by the others.
//!
//! Thresholds come from measured distributions (`cargo run --release -p ayllu-sim --example
//! calibrate 20 [--kill]`, seeds 1-20, 300 s; figures in docs/cmommt.md):
//! A_w — BLE mean 0.760 (min 0.680, max 0.855), Local 0.493 (0.415-0.620), Random 0.092
//! (0.056-0.142), ForceField 0.519 (0.371-0.696), Centralized 0.834 (0.677-0.908).
//! With a kill halfway, BLE re-covered every lost task, in 1-71 s (mean ~24 s).
//! Runs are deterministic, so these tests cannot flake; the margins guard against regressions
//! and against changes of the model that would make the claim false.

use ayllu_sim::controller::Controller;
use ayllu_sim::metrics::Metrics;
use ayllu_sim::scenario::{run, Scenario};

const SEEDS: std::ops::RangeInclusive<u64> = 1..=10;

fn metrics(c: Controller, kill: bool) -> Vec<Metrics> {
    SEEDS
        .map(|seed| {
            let s = Scenario::paper(c, seed);
            let s = if kill { s.kill_halfway() } else { s };
            run(&s).expect("runs").metrics
        })
        .collect()
}

fn mean(xs: impl Iterator<Item = f64>) -> f64 {
    let v: Vec<f64> = xs.collect();
    v.iter().sum::<f64>() / v.len() as f64
}

#[test]
fn ble_beats_random_and_local_on_weighted_coverage() {
    let ble = metrics(Controller::Ble, false);
    let local = metrics(Controller::Local, false);
    let random = metrics(Controller::Random, false);
    for (i, ((b, l), r)) in ble.iter().zip(&local).zip(&random).enumerate() {
        println!("seed {:2}: A_w BLE {:.3} Local {:.3} Random {:.3}", i + 1, b.a_w, l.a_w, r.a_w);
    }
    let (b, l, r) =
        (mean(ble.iter().map(|m| m.a_w)), mean(local.iter().map(|m| m.a_w)), mean(random.iter().map(|m| m.a_w)));
    println!("mean A_w: BLE {b:.3} Local {l:.3} Random {r:.3}");
    // Random is far below on every seed (measured max 0.142 vs BLE min 0.680).
    assert!(ble.iter().zip(&random).all(|(b, r)| b.a_w > 2.0 * r.a_w));
    // Local: measured mean gap 0.27; require at least half of it on the mean, and BLE ahead on
    // at least 8 of 10 seeds (measured: ahead on every seed of 1-20).
    assert!(b - l >= 0.12, "BLE {b:.3} vs Local {l:.3}");
    let ahead = ble.iter().zip(&local).filter(|(b, l)| b.a_w > l.a_w).count();
    assert!(ahead >= 8, "BLE ahead of Local on {ahead}/10 seeds");
}

#[test]
fn ble_spreads_robots_over_targets() {
    // The mechanism behind the coverage: cross-inhibition stops robots from observing the
    // same target. Measured mean redundant observations: BLE ~0.2, Local ~1.1.
    let ble = mean(metrics(Controller::Ble, false).iter().map(|m| m.redundant));
    let local = mean(metrics(Controller::Local, false).iter().map(|m| m.redundant));
    println!("redundant: BLE {ble:.2} Local {local:.2}");
    assert!(ble * 2.0 < local, "BLE {ble:.2} vs Local {local:.2}");
}

#[test]
fn a_killed_robots_task_is_re_covered() {
    for (i, m) in metrics(Controller::Ble, true).iter().enumerate() {
        println!("seed {:2}: recover {:?} unrecovered {}", i + 1, m.recover_s, m.unrecovered);
        // A task was lost (the kill takes the robot observing the top target) ...
        let recover = m.recover_s.expect("the killed robot observed a target");
        // ... and every one was re-covered before the end: measured 1-71 s; the run has 150 s
        // left, so "re-covered" is the verdict and the bound is only a sanity check.
        assert_eq!(m.unrecovered, 0, "seed {}", i + 1);
        assert!(recover < 120.0, "seed {}: {recover:.1} s", i + 1);
    }
}

#[test]
fn the_omniscient_planner_bounds_ble_from_above() {
    // The upper bound is an upper bound (measured: Centralized 0.834 vs BLE 0.760), and BLE
    // is the closest decentralized controller to it.
    let ble = mean(metrics(Controller::Ble, false).iter().map(|m| m.a_w));
    let central = mean(metrics(Controller::Centralized, false).iter().map(|m| m.a_w));
    let field = mean(metrics(Controller::ForceField, false).iter().map(|m| m.a_w));
    println!("A_w: Centralized {central:.3} BLE {ble:.3} ForceField {field:.3}");
    assert!(central > ble);
    assert!(ble > field);
}

/// A_w mean and sample sd, and mean messages per robot per second, of BLE with `policy` over
/// seeds 1..=`seeds` (300 s each).
fn ble_with(policy: ayllu::stdlib::Eligibility, robots: usize, targets: usize, seeds: u64) -> (f64, f64, f64) {
    let scenarios: Vec<Scenario> = (1..=seeds)
        .map(|seed| {
            let mut s = Scenario::sized(Controller::Ble, robots, targets, seed);
            s.controllers.eligibility = policy;
            s
        })
        .collect();
    let runs = ayllu_sim::study::run_all(&scenarios, 2, &|| {}, &|o| o.metrics).unwrap();
    let (mean, sd) = ayllu_sim::study::mean_sd(runs.iter().map(|m| m.a_w));
    (mean, sd, ayllu_sim::study::mean_sd(runs.iter().map(|m| m.msgs_per_robot_s)).0)
}

#[test]
fn the_lean_eligibility_keeps_coverage_with_five_times_fewer_messages() {
    // docs/cmommt.md, "A cheaper BLE": offering eligibility on a 10 % change or every 500 ms
    // instead of at every 20 Hz activation sends at least 5x fewer messages, and keeps A_w
    // within the paper policy's seed-to-seed spread (mean - one sd), in the paper's setting and
    // in a team twice as large. Deterministic: the same seeds give the same figures.
    use ayllu::stdlib::Eligibility;
    for (robots, targets) in [(3, 4), (6, 8)] {
        let (paper, sd, paper_msgs) = ble_with(Eligibility::EveryActivation, robots, targets, 10);
        let (lean, _, lean_msgs) = ble_with(Eligibility::LEAN, robots, targets, 10);
        eprintln!(
            "{robots} robots, {targets} targets: A_w {paper:.3} ± {sd:.3} -> {lean:.3}; messages/robot/s \
             {paper_msgs:.1} -> {lean_msgs:.1} ({:.1}x fewer)",
            paper_msgs / lean_msgs
        );
        assert!(paper_msgs >= 5.0 * lean_msgs, "only {:.1}x fewer messages", paper_msgs / lean_msgs);
        assert!(lean >= paper - sd, "A_w {lean:.3} below the paper's spread {paper:.3} ± {sd:.3}");
    }
}
