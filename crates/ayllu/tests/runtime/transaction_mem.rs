//! Transactions over `mem://` on virtual time (docs/semantics.md R8–R12): three nodes run the
//! paper's cross-subsumption-like wiring and a coordinator switches them to another priority
//! order at once. The coordinator's messages go through a link this test controls: each node
//! has its own one-way delays (asymmetric for one), and chosen messages are lost. Every test
//! checks the stated bound: no two nodes run different versions for longer than the skew
//! bound after the switch time (R10), or, when every COMMIT copy to a node is lost, than its
//! hold (R11); and all switch or none does.

use ayllu::transaction::{ApplyOptions, ApplyReport, Coordinator, Outcome, Part, Plan};
use ayllu::{
    BehaviorClass, Change, ConnectionKind, ControlBody, Duration, Endpoint, Instant, Lockstep, Message, NodeCore,
    NodeId, Outgoing, PortSpec, TransactionState, Transport,
};

const COORD: NodeId = NodeId(9);
const TICK: Duration = Duration::from_millis(1);

/// One-way delays from the coordinator to node i and back, in ms.
fn delays(node: NodeId) -> (u64, u64) {
    match node.0 {
        1 => (2, 2),
        2 => (10, 10),
        // Asymmetric: the bound must hold when the round trip is not split evenly.
        _ => (40, 5),
    }
}

/// Each node: two layers `Low` and `High` writing `Motor.In`; version 1 lets `High` suppress
/// `Low`; the plan swaps the order (version 2: `Low` suppresses `High`).
fn team() -> Lockstep {
    let mut team = Lockstep::new(&format!("txn-{}", std::process::id()));
    for id in 1..=3u32 {
        let i = team.add(NodeId(id)).unwrap();
        let node = team.node(i);
        let mut layer = BehaviorClass::new("Layer");
        layer.port(PortSpec::new("Out", 0i64)).unwrap();
        node.define(layer).unwrap();
        let mut motor = BehaviorClass::new("Motor");
        motor.port(PortSpec::new("In", 0i64)).unwrap();
        node.define(motor).unwrap();
        for b in ["Low", "High"] {
            node.create("Layer", b).unwrap();
        }
        node.create("Motor", "Motor").unwrap();
        node.connect(&Endpoint::local("Low", "Out"), &Endpoint::local("Motor", "In"), ConnectionKind::Normal).unwrap();
        node.connect(
            &Endpoint::local("High", "Out"),
            &Endpoint::local("Motor", "In"),
            ConnectionKind::Suppress(Duration::from_millis(500)),
        )
        .unwrap();
    }
    team
}

fn swap() -> Vec<Change> {
    let (low, high, motor) =
        (Endpoint::local("Low", "Out"), Endpoint::local("High", "Out"), Endpoint::local("Motor", "In"));
    vec![
        Change::DisconnectBetween { source: low.clone(), destination: motor.clone() },
        Change::DisconnectBetween { source: high.clone(), destination: motor.clone() },
        Change::Connect { source: high, destination: motor.clone(), kind: ConnectionKind::Normal, priority: 0 },
        Change::Connect {
            source: low,
            destination: motor,
            kind: ConnectionKind::Suppress(Duration::from_millis(500)),
            priority: 0,
        },
    ]
}

fn plan(parts: Vec<(u32, Vec<Change>)>) -> Plan {
    Plan {
        parts: parts.into_iter().map(|(n, changes)| Part { node: NodeId(n), changes }).collect(),
        options: ApplyOptions { hold: Duration::from_secs(3), ..ApplyOptions::default() },
    }
}

/// What the test lets through: `(now, message to node) -> deliver?`.
type Filter<'a> = &'a mut dyn FnMut(Instant, NodeId, &ControlBody) -> bool;

/// Kill node `.0` at the first message for it that `.1` matches.
type Kill<'a> = (NodeId, &'a dyn Fn(&ControlBody) -> bool);

struct Run {
    report: ApplyReport,
    team: Lockstep,
    /// Whether each node (1..=3) still ran at the end.
    alive: Vec<bool>,
}

/// Run `plan` from a coordinator on the team's network, through the delays and `filter`,
/// killing node `kill.0` at the first message for it that `kill.1` matches.
fn run(mut team: Lockstep, plan: &Plan, filter: Filter<'_>, kill: Option<Kill<'_>>) -> Run {
    let mut core = NodeCore::new(COORD);
    let mut link = team.network().attach(COORD).unwrap();
    let mut c = Coordinator::new(77, plan, COORD).unwrap();
    let mut outgoing: Vec<(Instant, Outgoing)> = Vec::new();
    let mut incoming: Vec<(Instant, NodeId, Message)> = Vec::new();
    let mut killed = Vec::new();
    for _ in 0..20_000 {
        team.clock().advance(TICK);
        team.step();
        let now = team.now();
        while let Some((from, m)) = link.recv() {
            incoming.push((now + Duration::from_millis(delays(from).1), from, m));
        }
        incoming.sort_by_key(|(t, ..)| *t);
        while incoming.first().is_some_and(|(t, ..)| *t <= now) {
            let (_, from, m) = incoming.remove(0);
            core.receive(now, from, m);
        }
        core.poll(now);
        let report = c.step(&mut core, now);
        while let Some(out) = core.pop_outgoing() {
            let ayllu::Destination::Node(to) = out.to else { continue };
            if let Message::Control(cm) = &out.message {
                if let Some((victim, when)) = &kill {
                    if *victim == to && when(&cm.body) && !killed.contains(&to) {
                        team.kill(to);
                        killed.push(to);
                    }
                }
                if !filter(now, to, &cm.body) {
                    continue;
                }
            }
            outgoing.push((now + Duration::from_millis(delays(to).0), out));
        }
        outgoing.sort_by_key(|(t, _)| *t);
        while outgoing.first().is_some_and(|(t, _)| *t <= now) {
            let (_, out) = outgoing.remove(0);
            link.send(out);
        }
        link.flush();
        if let Some(report) = report {
            // Let the nodes reach their switch (or their hold's end) before looking.
            team.advance(Duration::from_secs(4), TICK);
            let alive = (1..=3).map(|i| !killed.contains(&NodeId(i))).collect();
            return Run { report, team, alive };
        }
    }
    panic!("the transaction did not end");
}

/// The instant node `id` switched, if it did.
fn switched(team: &mut Lockstep, id: u32) -> Option<Instant> {
    let node = team.node_by_id(NodeId(id))?;
    node.core().transactions().iter().find_map(|t| match &t.state {
        TransactionState::Applied { at, outcomes } => {
            assert!(outcomes.iter().all(|o| o.result.is_ok()), "{outcomes:?}");
            Some(*at)
        }
        _ => None,
    })
}

/// Version 2 is in: `Low` suppresses `High` at the motor.
fn runs_version_2(team: &mut Lockstep, id: u32) -> bool {
    let node = team.node_by_id(NodeId(id)).unwrap();
    let conns = node.core().report().connections;
    conns.iter().any(|c| {
        c.source.behavior() == "Low"
            && matches!(c.kind, ConnectionKind::Suppress(_))
            && c.destination.behavior() == "Motor"
    }) && conns.iter().any(|c| c.source.behavior() == "High" && c.kind == ConnectionKind::Normal)
}

fn runs_version_1(team: &mut Lockstep, id: u32) -> bool {
    let node = team.node_by_id(NodeId(id)).unwrap();
    let conns = node.core().report().connections;
    conns.len() == 2
        && conns.iter().any(|c| c.source.behavior() == "High" && matches!(c.kind, ConnectionKind::Suppress(_)))
}

/// The skew a transaction promises: half the sum of the two largest round trips (R10), plus
/// a tick of polling on each side.
fn stated_bound(r: &ApplyReport) -> Duration {
    let mut rtts: Vec<Duration> = r.nodes.iter().filter_map(|n| n.prepare.clone().ok()).collect();
    rtts.sort();
    rtts.reverse();
    let sum = rtts.iter().take(2).map(|d| d.as_nanos()).sum::<u64>();
    Duration::from_nanos(sum / 2) + TICK * 2
}

#[test]
fn all_nodes_switch_at_one_instant_within_the_stated_bound() {
    let p = plan(vec![(1, swap()), (2, swap()), (3, swap())]);
    let Run { report, mut team, .. } = run(team(), &p, &mut |_, _, _| true, None);
    assert_eq!(report.outcome, Outcome::Switched, "{report}");
    let at: Vec<Instant> = (1..=3).map(|i| switched(&mut team, i).expect("switched")).collect();
    let skew = *at.iter().max().unwrap() - *at.iter().min().unwrap();
    let bound = stated_bound(&report);
    assert!(skew <= bound, "switches {at:?}: skew {skew} over the stated bound {bound}");
    // The coordinator's measured windows hold every actual switch, and its bound covers the skew.
    for (i, n) in report.nodes.iter().enumerate() {
        let w = n.commit.clone().unwrap().unwrap();
        assert!(w.earliest <= at[i] + TICK && at[i] <= w.latest + TICK, "node {}: {at:?} vs {w:?}", i + 1);
    }
    assert!(skew <= report.skew_bound.unwrap() + TICK, "{skew} vs {report}");
    let s = report.switch_at.unwrap();
    assert!(at.iter().all(|&t| t + bound >= s && t <= s + bound), "aimed at {s}, switched {at:?}");
    for i in 1..=3 {
        assert!(runs_version_2(&mut team, i), "node {i}");
    }
    // The report, as `ayllu apply` prints it.
    let text = report.to_string();
    assert!(text.starts_with("transaction 77: switched (skew at most"), "{text}");
    println!("{text}\nactual switches {at:?}, skew {skew}, stated bound {bound}");
}

#[test]
fn a_plan_refused_by_one_node_for_a_bad_port_name_changes_no_node() {
    let mut bad = swap();
    bad.push(Change::Connect {
        source: Endpoint::local("High", "Ouput"),
        destination: Endpoint::local("Motor", "In"),
        kind: ConnectionKind::Normal,
        priority: 0,
    });
    let p = plan(vec![(1, swap()), (2, bad), (3, swap())]);
    let Run { report, mut team, .. } = run(team(), &p, &mut |_, _, _| true, None);
    assert_eq!(report.outcome, Outcome::Aborted, "{report}");
    let refused = report.refused();
    assert_eq!(refused.len(), 1, "{refused:?}");
    assert_eq!(refused[0].0, NodeId(2));
    assert!(refused[0].1.contains("change 5") && refused[0].1.contains("Ouput"), "{}", refused[0].1);
    for i in 1..=3 {
        assert!(switched(&mut team, i).is_none(), "node {i} switched");
        assert!(runs_version_1(&mut team, i), "node {i}");
        assert!(team.node_by_id(NodeId(i)).unwrap().core().transaction_held().is_none());
    }
    assert!(report.nodes.iter().all(|n| n.abort == Some(Ok(()))), "{report}");
    assert!(report.to_string().contains("n2: refused: transaction refused: change 5"), "{report}");
}

#[test]
fn commits_lost_to_some_nodes_delay_only_them_within_the_stated_bound() {
    // The first 6 COMMIT copies to node 2 and the first 2 to node 3 are lost.
    let mut lost = [0u32; 4];
    let mut filter = |_: Instant, to: NodeId, body: &ControlBody| {
        if matches!(body, ControlBody::Commit { .. }) {
            let limit = [0, 0, 6, 2][to.0 as usize];
            if lost[to.0 as usize] < limit {
                lost[to.0 as usize] += 1;
                return false;
            }
        }
        true
    };
    let p = plan(vec![(1, swap()), (2, swap()), (3, swap())]);
    let Run { report, mut team, .. } = run(team(), &p, &mut filter, None);
    assert_eq!(report.outcome, Outcome::Switched, "{report}");
    let at: Vec<Instant> = (1..=3).map(|i| switched(&mut team, i).expect("switched")).collect();
    let s = report.switch_at.unwrap();
    // Node 2's first copy arrived 6 resends late: it switched late by at most that, never
    // beyond the hold (R11); the coordinator's windows still hold every switch.
    let resend = ApplyOptions::default().resend;
    let bound = stated_bound(&report) + resend * 6;
    let skew = *at.iter().max().unwrap() - *at.iter().min().unwrap();
    assert!(skew <= bound, "switches {at:?}, aimed at {s}: skew {skew} over {bound}");
    assert!(at[1] > s, "node 2 heard its first COMMIT after the switch time: {at:?} vs {s}");
    for (i, n) in report.nodes.iter().enumerate() {
        let w = n.commit.clone().unwrap().unwrap();
        assert!(w.earliest <= at[i] + TICK && at[i] <= w.latest + TICK, "node {}: {at:?} vs {w:?}", i + 1);
    }
    assert!(skew <= report.skew_bound.unwrap() + TICK);
}

#[test]
fn every_commit_lost_to_one_node_is_a_split_bounded_by_its_hold_and_reported() {
    let mut filter =
        |_: Instant, to: NodeId, body: &ControlBody| !(to == NodeId(3) && matches!(body, ControlBody::Commit { .. }));
    let p = plan(vec![(1, swap()), (2, swap()), (3, swap())]);
    let Run { report, mut team, .. } = run(team(), &p, &mut filter, None);
    assert_eq!(report.outcome, Outcome::Split, "{report}");
    let n3 = &report.nodes[2];
    assert!(matches!(&n3.commit, Some(Err(e)) if e.contains("no answer to COMMIT")), "{report}");
    assert!(switched(&mut team, 1).is_some() && switched(&mut team, 2).is_some());
    // Node 3 did not switch; it aborted by itself at the end of its hold, so the split lasted
    // at most from the switch time to that end: the bound R11 states.
    let node = team.node_by_id(NodeId(3)).unwrap();
    let aborted_at = node
        .core()
        .transactions()
        .iter()
        .find_map(|t| match &t.state {
            TransactionState::Aborted { at, why } => Some((*at, why.clone())),
            _ => None,
        })
        .expect("node 3 aborted by itself");
    assert!(aborted_at.1.contains("no COMMIT or ABORT"), "{aborted_at:?}");
    let s = report.switch_at.unwrap();
    let hold = p.options.hold;
    assert!(aborted_at.0 <= s + hold, "the split ended by the end of node 3's hold: {aborted_at:?}");
    assert!(runs_version_1(&mut team, 3));
    assert!(report.to_string().contains("n3: no answer to COMMIT"), "{report}");
}

#[test]
fn a_node_killed_between_prepare_and_commit() {
    let p = plan(vec![(1, swap()), (2, swap()), (3, swap())]);
    let Run { report, mut team, alive } =
        run(team(), &p, &mut |_, _, _| true, Some((NodeId(2), &|b| matches!(b, ControlBody::Commit { .. }))));
    assert!(!alive[1]);
    // The others switched together; the dead node is named, never silently counted.
    assert_eq!(report.outcome, Outcome::Split, "{report}");
    assert!(matches!(&report.nodes[1].commit, Some(Err(e)) if e.contains("no answer to COMMIT")), "{report}");
    let (a, b) = (switched(&mut team, 1).unwrap(), switched(&mut team, 3).unwrap());
    let skew = if a > b { a - b } else { b - a };
    assert!(skew <= stated_bound(&report), "{a} vs {b}");
}

#[test]
fn a_node_killed_before_it_answers_prepare_aborts_everyone() {
    let p = plan(vec![(1, swap()), (2, swap()), (3, swap())]);
    let Run { report, mut team, alive } =
        run(team(), &p, &mut |_, _, _| true, Some((NodeId(3), &|b| matches!(b, ControlBody::Prepare { .. }))));
    assert!(!alive[2]);
    assert_eq!(report.outcome, Outcome::Aborted, "{report}");
    assert!(matches!(&report.nodes[2].prepare, Err(e) if e.contains("no answer to PREPARE")), "{report}");
    for i in 1..=2 {
        assert!(switched(&mut team, i).is_none());
        assert!(runs_version_1(&mut team, i));
    }
}

#[test]
fn the_coordinator_cannot_be_in_its_own_plan_and_bad_plans_are_refused_before_sending() {
    let p = plan(vec![(9, swap())]);
    assert!(Coordinator::new(1, &p, COORD).is_err());
    let p = plan(vec![(1, swap()), (1, swap())]);
    assert!(Coordinator::new(1, &p, COORD).unwrap_err().to_string().contains("twice"));
    let p = plan(vec![(1, vec![Change::Create { class: "Layer".into(), name: String::new() }])]);
    assert!(Coordinator::new(1, &p, COORD).is_err());
    let mut p = plan(vec![(1, swap())]);
    p.options.hold = Duration::from_millis(500);
    assert!(Coordinator::new(1, &p, COORD).unwrap_err().to_string().contains("no time to commit"));
}

/// `apply` needs a node on the real clock: on a manual one it fails after its bound instead of
/// waiting for ever.
#[test]
fn apply_on_a_manual_clock_fails_instead_of_hanging() {
    let mut team = Lockstep::new(&format!("txn-manual-{}", std::process::id()));
    let i = team.add(COORD).unwrap();
    let mut p = plan(vec![(1, swap())]);
    p.options = ApplyOptions {
        hold: Duration::from_millis(400),
        prepare_timeout: Duration::from_millis(100),
        margin: Duration::from_millis(20),
        resend: Duration::from_millis(20),
    };
    let e = ayllu::transaction::apply(team.node(i), &p).unwrap_err();
    assert!(e.to_string().contains("does not advance"), "{e}");
}
