//! The cost of BLE's eligibility broadcasts against coverage: the paper's setting (and a
//! larger team) run with the paper's policy (every 20 Hz activation) and with on-change
//! policies, 10 seeds x 300 s each, printing A_w ± sd and radio messages per robot per second.
//! The figures behind docs/cmommt.md, "A cheaper BLE".
//!
//! Run: `cargo run --release -p ayllu-sim --example eligibility [-- ROBOTS TARGETS LOSS]`

use ayllu::stdlib::Eligibility;
use ayllu::Duration;
use ayllu_sim::controller::Controller;
use ayllu_sim::scenario::Scenario;
use ayllu_sim::study::{mean_sd, run_all};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let robots: usize = args.first().and_then(|a| a.parse().ok()).unwrap_or(3);
    let targets: usize = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(4);
    let loss: f64 = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(0.0);
    let on_change = |threshold: f64, ms: u64| Eligibility::OnChange { threshold, refresh: Duration::from_millis(ms) };
    let policies = [
        ("every activation (paper)", Eligibility::EveryActivation),
        ("on 5 % change, 100 ms", on_change(0.05, 100)),
        ("on 10 % change, 300 ms", on_change(0.1, 300)),
        ("on 15 % change, 400 ms", on_change(0.15, 400)),
        ("on 10 % change, 500 ms", on_change(0.1, 500)),
        ("on 20 % change, 500 ms", on_change(0.2, 500)),
        ("on 20 % change, 1000 ms", on_change(0.2, 1000)),
    ];
    println!("BLE, {robots} robots, {targets} targets, {:.0} % loss, 10 seeds x 300 s", loss * 100.0);
    println!("{:<32} {:>14} {:>14} {:>10}", "eligibility", "A_w ± sd", "msgs/robot/s", "x fewer");
    let mut paper_msgs = None;
    for (name, policy) in policies {
        let scenarios: Vec<Scenario> = (1..=10)
            .map(|seed| {
                let mut s = Scenario::sized(Controller::Ble, robots, targets, seed).loss(loss);
                s.controllers.eligibility = policy;
                s
            })
            .collect();
        let metrics = run_all(&scenarios, 2, &|| {}, &|o| o.metrics).expect("runs");
        let (mean, sd) = mean_sd(metrics.iter().map(|m| m.a_w));
        let (msgs, _) = mean_sd(metrics.iter().map(|m| m.msgs_per_robot_s));
        let fewer = paper_msgs.map_or(1.0, |p: f64| p / msgs);
        paper_msgs.get_or_insert(msgs);
        println!("{name:<32} {mean:>7.3} ± {sd:.3} {msgs:>14.1} {fewer:>9.1}x");
    }
}
