//! Quick timing of one run per team size (the real benchmark is benches/speed.rs).
use ayllu_sim::controller::Controller;
use ayllu_sim::scenario::{run, Scenario};
fn main() {
    let only: Option<usize> = std::env::args().nth(1).and_then(|s| s.parse().ok());
    let ctl = std::env::args().nth(2).and_then(|s| Controller::parse(&s));
    for robots in [3usize, 10, 100] {
        if only.is_some_and(|o| o != robots) { continue; }
        for c in [Controller::Ble, Controller::Random] {
            if ctl.is_some_and(|x| x != c) { continue; }
            let s = Scenario::sized(c, robots, 5, 1).duration(if robots >= 100 { 20.0 } else { 100.0 });
            let t0 = std::time::Instant::now();
            let o = run(&s).unwrap();
            let el = t0.elapsed().as_secs_f64();
            println!("{robots:4} {:8} {:.1}x real time  msgs/robot/s {:.1} delivered {}", c.name(), s.duration / el, o.metrics.msgs_per_robot_s, o.radio.delivered);
        }
    }
}
