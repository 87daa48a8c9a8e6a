//! The paper's cross-subsumption (Werger §4.1, Fig. 2) with three robots and four targets,
//! on virtual time over the in-process `mem://` transport. Prints, once a second, which
//! layer drives each robot and which robot claims each target, and a line whenever a claim
//! changes hands. Robot 1 dies halfway; watch its target get taken over.
//!
//! Run: `cargo run --release --example cross_subsumption [-- SECONDS]`

use std::fmt::Write as _;

use ayllu::stdlib::{cross_subsumption, BASE, VISION, WANDER_TURN};
use ayllu::{Duration, Lockstep, NodeId};

const ROBOTS: u32 = 3;
const TARGETS: u32 = 4;

/// Apparent height of target n (1-based) seen by robot r (1-based) at second `t`; `None` if
/// out of view. Targets drift: target 2 leaves robot 2's view for a while.
fn sight(robot: u32, target: u32, t: f64) -> Option<f64> {
    match (robot, target) {
        (1, 1) => Some(0.9),
        (1, 2) => Some(0.5),
        (2, 1) => Some(0.6),
        (2, 2) if !(6.0..10.0).contains(&t) => Some(0.8),
        (2, 3) => Some(0.4),
        (3, 3) => Some(0.7),
        (3, 4) => Some(0.5),
        _ => None,
    }
}

fn layer_of(rotate: f64) -> String {
    if rotate == WANDER_TURN {
        "WANDER".into()
    } else {
        format!("OBS{}", (-rotate / 0.1).round() as u32)
    }
}

/// Run the demo for `seconds` of virtual time, killing robot 1 at half time; returns the
/// printed report.
pub fn run(seconds: u64) -> String {
    let mut out = String::new();
    let mut team = Lockstep::new("cross-subsumption-demo");
    for id in 1..=ROBOTS {
        let i = team.add(NodeId(id)).expect("fresh network");
        let groups = cross_subsumption(team.node(i).core_mut(), TARGETS, "Peers", 1.0).expect("valid controller");
        for w in groups.iter().flat_map(|g| &g.warnings) {
            let _ = writeln!(out, "warning: {w}");
        }
    }
    let tick = Duration::from_millis(10);
    let kill_at = seconds * 1000 / 2;
    let mut claims: Vec<Option<u32>> = vec![None; TARGETS as usize];
    let _ = writeln!(out, "time   | robot1  robot2  robot3 | claims: T1 T2 T3 T4");
    for ms in (0..seconds * 1000).step_by(10) {
        let t = ms as f64 / 1000.0;
        if ms == kill_at {
            drop(team.kill(NodeId(1)));
            let _ = writeln!(out, "{t:6.2} | robot 1 stops (its claims are leases: they lapse)");
        }
        if ms.is_multiple_of(100) {
            for i in 0..team.nodes().len() {
                let robot = team.nodes()[i].id().0;
                for n in 1..=TARGETS {
                    if let Some(h) = sight(robot, n, t) {
                        let node = team.node(i);
                        node.write(VISION, &format!("Target{n}Angle"), 0.1 * f64::from(n)).expect("vision port");
                        node.write(VISION, &format!("Target{n}Bottom"), h).expect("vision port");
                    }
                }
            }
        }
        team.advance(tick, tick);
        // Who claims each target now: the robot whose claim is still in force, if any.
        for n in 1..=TARGETS {
            let holder = team
                .nodes()
                .iter()
                .filter(|node| {
                    node.core()
                        .ble_status(&format!("OBS{n}"))
                        .ok()
                        .flatten()
                        .is_some_and(|s| s.last_claim.is_some_and(|c| team.now() < c + Duration::from_millis(1010)))
                })
                .map(|node| node.id().0)
                .min();
            if holder != claims[n as usize - 1] {
                let who = holder.map_or("nobody".to_owned(), |r| format!("robot {r}"));
                let _ = writeln!(out, "{:6.2} | T{n} now claimed by {who}", team.now().as_secs_f64());
                claims[n as usize - 1] = holder;
            }
        }
        if (ms + 10).is_multiple_of(1000) {
            let mut line = format!("{:6.2} |", team.now().as_secs_f64());
            for r in 1..=ROBOTS {
                match team.nodes().iter().find(|n| n.id().0 == r) {
                    Some(node) => {
                        let rotate = node.read(BASE, "Rotate").expect("base").as_float().unwrap_or(0.0);
                        let _ = write!(line, " {:7}", layer_of(rotate));
                    }
                    None => line.push_str(" (dead) "),
                }
            }
            line.push_str(" |        ");
            for c in &claims {
                let _ = write!(line, " {:2}", c.map_or("-".to_owned(), |r| format!("r{r}")));
            }
            let _ = writeln!(out, "{line}");
        }
    }
    out
}

#[allow(dead_code)]
fn main() {
    let seconds = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(20);
    print!("{}", run(seconds));
}
