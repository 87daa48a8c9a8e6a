//! Prints each controller's metrics in the paper's setting over seeds: how the test
//! thresholds in tests/simulator/cmommt.rs were chosen. `cargo run --release -p ayllu-sim --example calibrate [SEEDS]`
use ayllu_sim::controller::Controller;
use ayllu_sim::scenario::{run, Scenario};

fn main() {
    let seeds: u64 = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(10);
    let kill = std::env::args().any(|a| a == "--kill");
    for c in Controller::ALL {
        let mut aws = Vec::new();
        for seed in 1..=seeds {
            let mut s = Scenario::paper(c, seed);
            if kill {
                s = s.kill_halfway();
            }
            let o = run(&s).expect("runs");
            let m = &o.metrics;
            aws.push(m.a_w);
            println!(
                "{:12} seed {seed:2} A {:.2} A_w {:.3} topk {:.3} red {:.2} sw/min {:.2} rec {:?} msg {:.1}",
                c.name(),
                m.a,
                m.a_w,
                m.top_k,
                m.redundant,
                m.switches_per_min,
                m.recover_s.map(|r| (r * 10.0).round() / 10.0),
                m.msgs_per_robot_s
            );
        }
        aws.sort_by(f64::total_cmp);
        let mean = aws.iter().sum::<f64>() / aws.len() as f64;
        println!("{:12} A_w mean {mean:.3} min {:.3} max {:.3}", c.name(), aws[0], aws[aws.len() - 1]);
    }
}
