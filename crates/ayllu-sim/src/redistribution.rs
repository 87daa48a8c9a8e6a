//! The paper's "redistribution of tasks across a group of robots" (§3), run: a team running
//! the paper's cross-subsumption (Fig. 2, the BLE controller) is switched while running to
//! another priority order of targets — observer layer `n` now watches target `order[n-1]` —
//! by one transaction (`ayllu::transaction`), so every robot changes at the same instant and
//! no two robots ever disagree on which target a layer (and its BLE claims) stands for.
//! Coverage is measured before, during and after the switch (`examples/reconfiguration`,
//! docs/cmommt.md "Redistribution").
//!
//! The coordinator is a base station on a link of its own to every robot (one tick each way,
//! loss `link_loss` per message), outside the robots' radio, as an operator's laptop would be.
//! Deterministic: same options, same report.

use std::fmt;

use ayllu::stdlib::VISION;
use ayllu::transaction::{ApplyOptions, ApplyReport, Coordinator, Part, Plan};
use ayllu_core::{
    Change, ConnectionKind, Destination, Duration, Endpoint, Error, Message, NodeCore, NodeId, TransactionState,
};

use crate::controller::Controller;
use crate::scenario::{node_id, Scenario, Sim, SimError};

/// The coordinator's node id (above any robot's).
pub const COORDINATOR: NodeId = NodeId(1000);

/// What to run.
#[derive(Clone, Debug, PartialEq)]
pub struct RedistributionOptions {
    /// The run: its controller must be the BLE one (the paper's cross-subsumption).
    pub scenario: Scenario,
    /// When the coordinator starts the transaction (s of virtual time).
    pub start: f64,
    /// The new order: layer n watches target `order[n-1]` (a permutation of 1..=m).
    pub order: Vec<u32>,
    /// Probability that a message between the coordinator and a robot is lost.
    pub link_loss: f64,
    /// How wide the "during" window is after the start (s).
    pub during: f64,
}

impl RedistributionOptions {
    /// The paper's setting (3 robots, 4 targets, BLE), `seconds` long, switched halfway to the
    /// reversed order (the least important target first).
    pub fn paper(seed: u64, seconds: f64) -> RedistributionOptions {
        RedistributionOptions {
            scenario: Scenario::paper(Controller::Ble, seed).duration(seconds),
            start: seconds / 2.0,
            order: vec![4, 3, 2, 1],
            link_loss: 0.0,
            during: 5.0,
        }
    }
}

/// Coverage over one window of the run.
#[derive(Clone, Debug, PartialEq)]
pub struct Window {
    /// Its name: before, during, after.
    pub name: &'static str,
    /// From (s).
    pub from: f64,
    /// To (s).
    pub to: f64,
    /// Mean number of targets observed (any robot within observe range and view).
    pub observed: f64,
    /// Fraction of the window each target (1..=m) was observed.
    pub per_target: Vec<f64>,
    /// Mean priority-weighted coverage under the *old* order (the paper's weights).
    pub weighted_old: f64,
    /// Mean priority-weighted coverage under the *new* order (weights moved with the order).
    pub weighted_new: f64,
}

/// What a redistribution run measured.
#[derive(Clone, Debug)]
pub struct RedistributionReport {
    /// The transaction's report.
    pub transaction: ApplyReport,
    /// When each robot switched (s, virtual time; `None`: it did not).
    pub switched: Vec<Option<f64>>,
    /// Before, during and after.
    pub windows: [Window; 3],
}

impl fmt::Display for RedistributionReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "{}", self.transaction)?;
        let at: Vec<String> = self
            .switched
            .iter()
            .enumerate()
            .map(|(i, t)| match t {
                Some(t) => format!("robot {}: {t:.2} s", i + 1),
                None => format!("robot {}: did not switch", i + 1),
            })
            .collect();
        writeln!(f, "switched at {}", at.join(", "))?;
        writeln!(f, "window          observed  weighted(old)  weighted(new)  observed share per target")?;
        for w in &self.windows {
            let shares: Vec<String> = w.per_target.iter().map(|s| format!("{s:.2}")).collect();
            writeln!(
                f,
                "{:<6} {:>5.1}-{:<5.1} {:>8.2}  {:>13.3}  {:>13.3}  [{}]",
                w.name,
                w.from,
                w.to,
                w.observed,
                w.weighted_old,
                w.weighted_new,
                shares.join(", ")
            )?;
        }
        Ok(())
    }
}

/// The plan that moves every robot of `robots` to `order`.
pub fn plan(robots: usize, order: &[u32], options: ApplyOptions) -> Plan {
    let mut parts = Vec::new();
    for i in 0..robots {
        let mut changes = Vec::new();
        for (k, &target) in order.iter().enumerate() {
            let layer = format!("OBS{}", k + 1);
            let old = k as u32 + 1;
            for (from, to) in [("Angle", "TargetX"), ("Bottom", "TargetY")] {
                changes.push(Change::DisconnectBetween {
                    source: Endpoint::local(VISION, &format!("Target{old}{from}")),
                    destination: Endpoint::local(&layer, to),
                });
                changes.push(Change::Connect {
                    source: Endpoint::local(VISION, &format!("Target{target}{from}")),
                    destination: Endpoint::local(&layer, to),
                    kind: ConnectionKind::Normal,
                    priority: 0,
                });
            }
        }
        parts.push(Part { node: node_id(i), changes });
    }
    Plan { parts, options }
}

/// Run it (see the module docs). Errors: a scenario out of bounds or that cannot be built, an
/// order that is not a permutation of the targets.
pub fn run(o: &RedistributionOptions) -> Result<RedistributionReport, SimError> {
    let m = o.scenario.world.targets.len();
    let mut sorted = o.order.clone();
    sorted.sort_unstable();
    if sorted != (1..=m as u32).collect::<Vec<_>>() {
        return Err(Error::NotLocal { what: format!("the order {:?} as a permutation of 1..={m}", o.order) }.into());
    }
    let mut sim = Sim::new(&o.scenario)?;
    let robots = o.scenario.robots;
    let options = ApplyOptions { hold: Duration::from_secs(5), ..ApplyOptions::default() };
    let plan = plan(robots, &o.order, options);
    let mut coordinator =
        Coordinator::new(1, &plan, COORDINATOR).map_err(|e| Error::NotLocal { what: e.to_string() })?;
    let mut core = NodeCore::new(COORDINATOR);
    let mut rng = fastrand::Rng::with_seed(o.scenario.seed ^ 0x7e57);
    // Messages on the link, delivered at the next tick.
    let mut to_robots: Vec<(usize, Message)> = Vec::new();
    let mut to_coordinator: Vec<(NodeId, Message)> = Vec::new();
    let mut report = None;
    let priorities: Vec<f64> = sim.scenario().world.targets.iter().map(|t| t.priority).collect();
    let mut new_priorities = vec![0.0; m];
    for (k, &t) in o.order.iter().enumerate() {
        new_priorities[t as usize - 1] = priorities[k];
    }
    let bounds = [0.0, o.start, o.start + o.during, o.scenario.duration];
    let mut sums = [[0.0f64; 3]; 3];
    let mut seen = vec![vec![0.0f64; m]; 3];
    let mut ticks = [0u64; 3];
    let range = sim.scenario().world.observe_range;
    while !sim.done() {
        sim.step()?;
        let now = sim.now();
        let t = now.as_secs_f64();
        // The link: what was sent last tick arrives now (or is lost).
        for (i, m) in std::mem::take(&mut to_robots) {
            let robot = sim.core_mut(i);
            robot.receive(now, COORDINATOR, m);
            // The only thing a control request makes a robot send is its reply.
            while let Some(out) = robot.pop_outgoing() {
                if out.to == Destination::Node(COORDINATOR) && !rng.f64().lt(&o.link_loss) {
                    to_coordinator.push((node_id(i), out.message));
                }
            }
        }
        for (from, m) in std::mem::take(&mut to_coordinator) {
            core.receive(now, from, m);
        }
        core.poll(now);
        if t >= o.start && report.is_none() {
            report = coordinator.step(&mut core, now);
        }
        while let Some(out) = core.pop_outgoing() {
            let Destination::Node(n) = out.to else { continue };
            if (1..=robots as u32).contains(&n.0) && !rng.f64().lt(&o.link_loss) {
                to_robots.push((n.0 as usize - 1, out.message));
            }
        }
        // Coverage, from the ground truth.
        let w = bounds.windows(2).position(|b| t > b[0] && t <= b[1] + 1e-9).unwrap_or(2);
        let world = sim.world();
        let mut observed = vec![false; m];
        for i in 0..world.robots.len() {
            if world.robots[i].alive {
                world.in_view(i, range, |j, _, _| observed[j] = true);
            }
        }
        let count = observed.iter().filter(|&&x| x).count() as f64;
        let weigh = |p: &[f64]| {
            observed.iter().zip(p).filter(|(o, _)| **o).map(|(_, p)| p).sum::<f64>() / p.iter().sum::<f64>()
        };
        sums[w][0] += count;
        sums[w][1] += weigh(&priorities);
        sums[w][2] += weigh(&new_priorities);
        for (j, &o) in observed.iter().enumerate() {
            if o {
                seen[w][j] += 1.0;
            }
        }
        ticks[w] += 1;
    }
    let transaction = report.ok_or_else(|| Error::NotLocal { what: "the transaction ended before the run".into() })?;
    let switched = (0..robots)
        .map(|i| {
            sim.core(i).transactions().iter().find_map(|t| match &t.state {
                TransactionState::Applied { at, .. } => Some(at.as_secs_f64()),
                _ => None,
            })
        })
        .collect();
    let names = ["before", "during", "after"];
    let windows = std::array::from_fn(|w| {
        let n = ticks[w].max(1) as f64;
        Window {
            name: names[w],
            from: bounds[w],
            to: bounds[w + 1],
            observed: sums[w][0] / n,
            per_target: seen[w].iter().map(|s| s / n).collect(),
            weighted_old: sums[w][1] / n,
            weighted_new: sums[w][2] / n,
        }
    });
    Ok(RedistributionReport { transaction, switched, windows })
}
