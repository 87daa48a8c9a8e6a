//! Rule S11, Broadcast of Local Eligibility: every class has the implicit ports `Local`,
//! `Inhibit` and `Best`; `ble_join` wires `Local -> (group, behavior, Best)` (Normal) and
//! `Inhibit -> (group, behavior, output)` (WriteInhibit) and adds the `BLE_Select` process;
//! the behavior whose fresh `Local` beats `Best` (ties: lower node id) claims, which
//! write-inhibits the peers' output; claims are leases that lapse when the claimer dies; the
//! inhibit period is checked against the claim rate (the paper's Fig. 2 numbers are warned
//! about); `ble_status` shows who claims and who is inhibited by whom.
//!
//! Three `NodeCore`s run in lockstep on one virtual clock: each step polls every live node,
//! then the in-test shuttle (`tests/shuttle`) delivers every message.

use crate::shuttle;

use std::sync::{Arc, Mutex};

use ayllu_core::*;
use shuttle::Team;

fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}

type Eligibility = Arc<Mutex<Option<f64>>>;

struct Ble {
    team: Team,
    elig: Vec<Eligibility>,
    joined: Vec<BleGroup>,
    tick: u64,
}

/// Nodes 1..=k in group `Peers`. Each has behavior `OBS` (class `Observer`: output `Rotate`,
/// process `TurnToTarget` at `work_hz` writing `Local` := its eligibility — if it has one — and
/// `Rotate` := 1.0) wired locally to `Motor.Rotate`, and joined to BLE with `config`.
fn ble(eligibility: &[Option<f64>], work_hz: f64, config: &BleConfig) -> Ble {
    let ids: Vec<u32> = (1..=eligibility.len() as u32).collect();
    let mut team = Team::new(&ids);
    team.group("Peers", &ids);
    let mut elig = Vec::new();
    let mut joined = Vec::new();
    for (n, e) in team.nodes.iter_mut().zip(eligibility) {
        let cell: Eligibility = Arc::new(Mutex::new(*e));
        let mut obs = BehaviorClass::new("Observer");
        let rotate = obs.port(PortSpec::new("Rotate", 0.0)).unwrap();
        let mine = cell.clone();
        obs.every_hz("TurnToTarget", work_hz, move |ctx| {
            if let Some(e) = *mine.lock().unwrap() {
                ctx.write(Port::LOCAL, e).unwrap();
            }
            ctx.write(rotate, 1.0).unwrap();
        })
        .unwrap();
        let mut motor = BehaviorClass::new("Motor");
        motor.port(PortSpec::new("Rotate", 0.0)).unwrap();
        n.define(obs).unwrap();
        n.define(motor).unwrap();
        n.create("Observer", "OBS").unwrap();
        n.create("Motor", "Motor").unwrap();
        n.connect(
            &Endpoint::local("OBS", "Rotate"),
            &Endpoint::local("Motor", "Rotate"),
            ConnectionKind::Normal,
            ConnectOptions::default(),
        )
        .unwrap();
        joined.push(n.ble_join("OBS", config).unwrap());
        elig.push(cell);
    }
    Ble { team, elig, joined, tick: (1_000.0 / work_hz) as u64 }
}

impl Ble {
    /// Step every `tick` ms over `[from, to]`.
    fn run(&mut self, from: u64, to: u64) {
        let mut t = from;
        while t <= to {
            self.team.step(ms(t));
            t += self.tick;
        }
    }
    /// How many `Rotate` values reached node `n`'s motor (i.e. were not write-inhibited).
    fn motor(&self, n: u32) -> u64 {
        self.team.get(n).why("Motor", "Rotate").unwrap().accepted
    }
    fn motors(&self) -> Vec<u64> {
        (1..=self.elig.len() as u32).map(|n| self.motor(n)).collect()
    }
    fn status(&self, n: u32) -> BleStatus {
        self.team.get(n).ble_status("OBS").unwrap().unwrap()
    }
    fn set(&self, n: u32, e: Option<f64>) {
        *self.elig[n as usize - 1].lock().unwrap() = e;
    }
}

fn delta(before: &[u64], after: &[u64]) -> Vec<u64> {
    before.iter().zip(after).map(|(b, a)| a - b).collect()
}

fn ten_hz() -> BleConfig {
    // Claim period 100 ms; recommended inhibit period 2 x 100 + 50 + 25 = 275 ms.
    BleConfig::new("Peers", "Rotate", 10.0).unwrap()
}

#[test]
fn every_class_has_the_implicit_ble_ports() {
    // S11: Local (Normal float), Inhibit (Normal bool), Best (Max float) on every class, at
    // the fixed handles Port::LOCAL, Port::INHIBIT, Port::BEST.
    let class = BehaviorClass::new("Anything");
    let ports: Vec<(&str, PortKind, ValueType)> =
        class.ports().iter().map(|p| (p.name.as_str(), p.kind, p.ty())).collect();
    assert_eq!(
        ports,
        vec![
            (LOCAL, PortKind::Normal, ValueType::Float),
            (INHIBIT, PortKind::Normal, ValueType::Bool),
            (BEST, PortKind::Max, ValueType::Float),
        ]
    );
    assert_eq!(class.port_handle("Local"), Some(Port::LOCAL));
    assert_eq!(class.port_handle("Inhibit"), Some(Port::INHIBIT));
    assert_eq!(class.port_handle("Best"), Some(Port::BEST));
    let mut n = NodeCore::new(NodeId(1));
    n.define(class).unwrap();
    n.create("Anything", "A").unwrap();
    assert_eq!(n.why("A", "Best").unwrap().kind, PortKind::Max);
    assert!(n.why("A", "Best").unwrap().empty);
    assert_eq!(n.port("A", "Local").unwrap().port(), Port::LOCAL);
    // The names are reserved, and the error says so and why (S11), for every register kind.
    let mut c = BehaviorClass::new("C");
    for name in ["Local", "Inhibit", "Best"] {
        let err = c.port(PortSpec::new(name, 0.0)).unwrap_err();
        assert!(matches!(err, Error::ReservedName { .. }), "{err:?}");
        assert!(err.to_string().contains("BLE"), "{err}");
        assert!(matches!(c.slot(name, 0i64), Err(Error::ReservedName { .. })));
        assert!(matches!(c.monostable(name), Err(Error::ReservedName { .. })));
    }
}

#[test]
fn ble_join_wires_two_connections_and_the_select_process() {
    // S11: one call makes the eligibility broadcast, the inhibition broadcast and BLE_Select.
    let b = ble(&[Some(1.0), Some(2.0)], 10.0, &ten_hz());
    let n = b.team.get(1);
    let g = &b.joined[0];
    let elig = n.connection(g.eligibility).unwrap();
    assert_eq!(elig.source, Endpoint::local("OBS", "Local"));
    assert_eq!(elig.destination, Endpoint::group("Peers", "OBS", "Best"));
    assert_eq!(elig.kind, ConnectionKind::Normal);
    let inh = n.connection(g.inhibition).unwrap();
    assert_eq!(inh.source, Endpoint::local("OBS", "Inhibit"));
    assert_eq!(inh.destination, Endpoint::group("Peers", "OBS", "Rotate"));
    assert_eq!(inh.kind, ConnectionKind::WriteInhibit(Duration::from_millis(275)));
    let report = n.report();
    assert_eq!(report.connections.len(), 3, "the two BLE connections plus OBS.Rotate -> Motor");
    assert!(report.groups.contains(&"Peers".to_owned()));
    let obs = report.behaviors.iter().find(|b| b.name == "OBS").unwrap();
    let select = obs.processes.iter().find(|p| p.name == "BLE_Select").expect("BLE_Select added");
    assert_eq!(select.trigger, Trigger::Periodic(Duration::from_millis(100)));
    assert!(g.warnings.is_empty());
    let s = b.status(1);
    assert_eq!((s.behavior.as_str(), s.group.as_str(), s.claiming, s.claims), ("OBS", "Peers", false, 0));
    assert_eq!(n.ble_status("Motor").unwrap(), None);
}

#[test]
fn ble_join_misuse_is_reported() {
    // S11: an unknown output port, a second join, a zero inhibit period are errors.
    let mut b = ble(&[Some(1.0)], 10.0, &ten_hz());
    let n = b.team.node(1);
    let e = n.ble_join("OBS", &ten_hz()).unwrap_err();
    assert!(matches!(e, Error::Ble { .. }) && e.to_string().contains("OBS"), "{e}");
    let e = n.ble_join("Motor", &BleConfig::new("Peers", "Nope", 1.0).unwrap()).unwrap_err();
    assert!(matches!(e, Error::UnknownPort { .. }) && e.to_string().contains("Nope"), "{e}");
    let e = n.ble_join("Motor", &ten_hz().inhibit_period(Duration::ZERO)).unwrap_err();
    assert!(matches!(e, Error::ZeroPeriod { .. }), "{e}");
    let e = n.ble_join("Ghost", &ten_hz()).unwrap_err();
    assert!(matches!(e, Error::UnknownBehavior { .. }), "{e}");
    assert!(matches!(BleConfig::new("Peers", "Rotate", 0.0), Err(Error::InvalidRate { .. })));
}

#[test]
fn the_highest_local_claims_and_write_inhibits_its_peers() {
    // S11: a new member listens for one cycle (nobody claims at 0 ms, when Best has heard no
    // peer yet); from then on only node 2 (eligibility 0.9) claims; nodes 1 and 3 have their
    // Rotate write-inhibited, so only node 2's motor moves.
    let mut b = ble(&[Some(0.2), Some(0.9), Some(0.5)], 10.0, &ten_hz());
    b.run(0, 0);
    assert_eq!((1..=3).map(|n| b.status(n).claims).collect::<Vec<_>>(), vec![0, 0, 0]);
    b.run(100, 300);
    let before = b.motors();
    let claims_before: Vec<u64> = (1..=3).map(|n| b.status(n).claims).collect();
    b.run(400, 1_500);
    assert_eq!(delta(&before, &b.motors()), vec![0, 12, 0]);
    let claims_after: Vec<u64> = (1..=3).map(|n| b.status(n).claims).collect();
    assert_eq!(delta(&claims_before, &claims_after), vec![0, 12, 0]);
    // ble_status: who claims, who is inhibited by whom.
    let winner = b.status(2);
    assert!(winner.claiming);
    assert_eq!(winner.last_claim, Some(ms(1_500)));
    assert_eq!(winner.local, Some(0.9));
    assert!(winner.inhibited_by.is_empty());
    let holder = Source::connection(NodeId(2), b.joined[1].inhibition);
    for n in [1, 3] {
        let s = b.status(n);
        assert!(!s.claiming, "node {n}");
        assert_eq!(s.best.map(|(v, who)| (v, who.node)), Some((0.9, NodeId(2))), "node {n}");
        assert_eq!(s.inhibited_by.len(), 1, "node {n}");
        let (who, left) = s.inhibited_by[0];
        assert_eq!(who, holder);
        assert_eq!(left, Duration::from_millis(275), "refreshed at this very step");
        assert_eq!(
            b.team.get(n).why("OBS", "Rotate").unwrap().internal_output_blocked,
            Some(DropCause::WriteInhibited)
        );
    }
}

#[test]
fn ties_go_to_the_lower_node_id() {
    // S11: equal eligibilities — node 2 (lower id) claims, node 3 yields.
    let mut b = ble(&[Some(0.1), Some(0.7), Some(0.7)], 10.0, &ten_hz());
    b.run(0, 300);
    let before = b.motors();
    b.run(400, 1_000);
    assert_eq!(delta(&before, &b.motors()), vec![0, 7, 0]);
    assert!(b.status(2).claiming);
    assert!(!b.status(3).claiming);
    assert_eq!(b.status(3).inhibited_by[0].0.node, NodeId(2));
}

#[test]
fn no_claim_without_a_fresh_local() {
    // S11: eligibility counts only if Local was written during the last claim period: a
    // behavior with no output has no claim, so nobody is inhibited.
    let mut b = ble(&[None, None, None], 10.0, &ten_hz());
    b.run(0, 1_000);
    for n in 1..=3 {
        assert_eq!(b.status(n).claims, 0);
        assert_eq!(b.status(n).local, None);
        assert!(b.status(n).inhibited_by.is_empty());
    }
    assert_eq!(b.motors(), vec![11, 11, 11]);
    // Node 1 starts producing eligibility: it claims (the only candidate) and the others yield.
    b.set(1, Some(0.3));
    b.run(1_100, 1_500);
    assert!(b.status(1).claiming);
    let before = b.motors();
    b.run(1_600, 2_000);
    assert_eq!(delta(&before, &b.motors()), vec![5, 0, 0]);
    // Node 1 stops: its Local goes stale, its claims stop, the others get the task back once
    // the lease has run out (275 ms).
    b.set(1, None);
    let claims = b.status(1).claims;
    b.run(2_100, 2_300);
    assert_eq!(b.status(1).claims, claims, "a stale Local must not claim");
    let before = b.motors();
    b.run(2_400, 2_800);
    assert_eq!(delta(&before, &b.motors()), vec![5, 5, 5]);
}

#[test]
fn a_dead_claimer_frees_the_task_within_inhibit_period_plus_one_claim_period() {
    // S11: claims are leases. Node 2 claims, then dies (no longer stepped or forwarded) after
    // the 1000 ms step. Node 3 (next best) must get its output through by 1000 + 275 + 100 ms,
    // and not before node 2's last lease (1000 + 275) ran out; node 1 stays inhibited.
    let mut b = ble(&[Some(0.2), Some(0.9), Some(0.5)], 10.0, &ten_hz());
    b.run(0, 1_000);
    assert!(b.status(2).claiming);
    b.team.kill(2);
    let mut freed_at = None;
    let mut t = 1_100;
    let node1_before = b.motor(1);
    while t <= 2_000 {
        let before = b.motor(3);
        b.team.step(ms(t));
        if freed_at.is_none() && b.motor(3) > before {
            freed_at = Some(t);
        }
        t += 100;
    }
    let freed_at = freed_at.expect("the task was never freed");
    assert!((1_275..=1_375).contains(&freed_at), "freed at {freed_at} ms");
    assert!(b.status(3).claiming);
    assert_eq!(b.status(1).inhibited_by[0].0.node, NodeId(3), "node 1 now yields to node 3");
    assert_eq!(b.motor(1), node1_before, "node 1 never got through");
}

#[test]
fn the_period_check_warns_for_the_papers_fig_2_numbers() {
    // S11: claims at 1 Hz with a 0.5 s inhibition lapse between renewals — warned about, in
    // the join result and in NodeCore::warnings; the recommended config is not.
    let fig2 = BleConfig::new("Peers", "Rotate", 1.0).unwrap().inhibit_period(Duration::from_millis(500));
    let b = ble(&[Some(1.0), Some(2.0)], 20.0, &fig2);
    let w = &b.joined[0].warnings;
    assert_eq!(w.len(), 1);
    assert!(w[0].contains("500ms") && w[0].contains("OBS"), "{}", w[0]);
    assert_eq!(b.team.get(1).warnings(), &w[..]);
    assert_eq!(b.team.get(1).report().warnings, *w);

    let good = BleConfig::new("Peers", "Rotate", 1.0).unwrap();
    assert!(good.inhibit_period >= minimum_inhibit_period(1.0, good.network_delay).unwrap());
    let b = ble(&[Some(1.0), Some(2.0)], 20.0, &good);
    assert!(b.joined[0].warnings.is_empty());
    assert!(b.team.get(1).warnings().is_empty());

    assert!(check_inhibit_period(1.0, Duration::from_millis(500), Duration::ZERO).unwrap().is_some());
    assert_eq!(check_inhibit_period(1.0, Duration::from_millis(2_000), Duration::ZERO).unwrap(), None);
    assert!(check_inhibit_period(1.0, Duration::from_millis(2_000), Duration::from_millis(1)).unwrap().is_some());
    assert_eq!(minimum_inhibit_period(1.0, Duration::from_millis(50)).unwrap(), Duration::from_millis(2_050));
    assert!(matches!(
        check_inhibit_period(f64::NAN, Duration::from_secs(1), Duration::ZERO),
        Err(Error::InvalidRate { .. })
    ));
}

#[test]
fn with_the_fig_2_numbers_the_losers_output_leaks_between_claims() {
    // S11: why the warning matters. TurnToTarget at 20 Hz, claims at 1 Hz, inhibition 0.5 s:
    // the losing peer is inhibited for only half of every second and drives its motor the
    // other half. With the recommended period it never does.
    let fig2 = BleConfig::new("Peers", "Rotate", 1.0).unwrap().inhibit_period(Duration::from_millis(500));
    let mut b = ble(&[Some(0.1), Some(0.9)], 20.0, &fig2);
    b.run(0, 950);
    let before = b.motors();
    b.run(1_000, 2_950);
    let leaked = delta(&before, &b.motors());
    assert_eq!(leaked[1], 40, "the claimer drives every tick");
    // Inhibited on [claim, claim + 0.5 s) only: the loser gets through at 1500..1950 ms and
    // also at 1000 and 2000 ms, where its write runs before the renewed claim has arrived.
    assert_eq!(leaked[0], 22, "the loser leaks 11 of the 20 ticks of each second");

    let good = BleConfig::new("Peers", "Rotate", 1.0).unwrap();
    let mut b = ble(&[Some(0.1), Some(0.9)], 20.0, &good);
    b.run(0, 2_950);
    let before = b.motors();
    b.run(3_000, 4_950);
    assert_eq!(delta(&before, &b.motors()), vec![0, 40]);
}
