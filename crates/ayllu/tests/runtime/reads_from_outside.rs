//! The runtime's seams a user meets first (issue "aggregating ports ... and the seams"):
//! reads from outside answer at the clock's present (D8.2), monostables can be read from
//! outside a process, `Lockstep` kills by node id, and two teams of the same name in one
//! program never share a network.

use ayllu::{BehaviorClass, Clock, Duration, Lockstep, ManualClock, Node, NodeId, PortSpec, Value};

fn node_on(clock: &ManualClock) -> Node {
    let mut node = Node::new(clock.clone(), ayllu::MemNetwork::new().attach(NodeId(1)).unwrap());
    let mut c = BehaviorClass::new("C");
    c.port(PortSpec::new("Fresh", 0i64).lifespan(Duration::from_millis(100))).unwrap();
    c.port(PortSpec::new("Best2", 0i64).max().window(Duration::from_millis(100))).unwrap();
    c.monostable("Bumped").unwrap();
    node.define(c).unwrap();
    node.create("C", "B").unwrap();
    node
}

#[test]
fn reads_answer_at_the_clocks_present_not_at_the_last_step() {
    // D8.2: time passes on the clock without a step; a read must not answer as of the past.
    let clock = ManualClock::new();
    let mut node = node_on(&clock);
    node.write("B", "Fresh", 5i64).unwrap();
    node.write("B", "Best2", 9i64).unwrap();
    node.step();
    assert_eq!(node.get("B", "Fresh").unwrap(), Some(Value::Int(5)));
    assert!(node.fresh("B", "Best2").unwrap());
    clock.advance(Duration::from_millis(150));
    // No step since: the lifespan and the window have still ended.
    assert_eq!(node.get("B", "Fresh").unwrap(), None);
    assert!(!node.fresh("B", "Fresh").unwrap());
    assert_eq!(node.read("B", "Best2").unwrap(), Value::Int(0), "the window closed: default");
    let why = node.why("B", "Best2").unwrap();
    assert!(why.empty && why.now == clock.now(), "{why}");
}

#[test]
fn a_monostable_can_be_read_from_outside() {
    let clock = ManualClock::new();
    let mut node = node_on(&clock);
    assert!(!node.monostable("B", "Bumped").unwrap());
    let now = node.now();
    node.core_mut().trigger(now, "B", "Bumped", Duration::from_millis(50)).unwrap();
    assert!(node.monostable("B", "Bumped").unwrap());
    clock.advance(Duration::from_millis(50));
    assert!(!node.monostable("B", "Bumped").unwrap(), "high until its end, not until a poll sees the fall");
    assert!(node.monostable("B", "Nope").unwrap_err().to_string().contains("Nope"));
}

#[test]
fn lockstep_kills_by_node_id_and_teams_of_one_name_do_not_collide() {
    let mut a = Lockstep::new("same-name");
    let mut b = Lockstep::new("same-name");
    for id in 1..=3 {
        a.add(NodeId(id)).unwrap();
        b.add(NodeId(id)).expect("a second team of the same name has its own network");
    }
    assert!(a.kill(NodeId(2)).is_some());
    assert!(a.kill(NodeId(2)).is_none(), "already gone");
    // Indices shift, ids do not.
    assert_eq!(a.nodes().iter().map(|n| n.id().0).collect::<Vec<_>>(), [1, 3]);
    assert_eq!(a.node_by_id(NodeId(3)).unwrap().id(), NodeId(3));
    assert_eq!(b.nodes().len(), 3);
}
