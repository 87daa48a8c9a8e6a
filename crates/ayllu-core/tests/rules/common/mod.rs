//! Shared fixtures for the rule tests: a node with "Relay" behaviors (one int port `V`,
//! Normal) wired by name, and millisecond time.
//!
//! Each test binary uses a different subset of these, hence `allow(dead_code)`.
#![allow(dead_code)]

use ayllu_core::*;

/// The node every fixture runs on.
pub const NODE: NodeId = NodeId(1);
/// The one port of a Relay.
pub const V: &str = "V";

/// A node with class "Relay" (port `V`: Normal int, default 0) and one Relay per name.
pub fn wiring(names: &[&str]) -> NodeCore {
    let mut node = NodeCore::new(NODE);
    let mut relay = BehaviorClass::new("Relay");
    relay.port(PortSpec::new(V, 0i64)).unwrap();
    node.define(relay).unwrap();
    for name in names {
        node.create("Relay", name).unwrap();
    }
    node
}

/// Connect `from.V` to `to.V` with `kind`.
pub fn link(node: &mut NodeCore, from: &str, to: &str, kind: ConnectionKind) -> ConnectionId {
    node.connect(&Endpoint::local(from, V), &Endpoint::local(to, V), kind, ConnectOptions::default()).unwrap()
}

/// `name.V := v` as `name`'s own behavior would write it, at `t`.
pub fn put(node: &mut NodeCore, t: Instant, name: &str, v: i64) {
    node.write_named(t, name, V, v).unwrap();
}

/// The value of `name.V`.
pub fn value(node: &NodeCore, name: &str) -> i64 {
    node.read(node.port(name, V).unwrap()).unwrap().as_int().unwrap()
}

/// How many values `name.V` has accepted so far.
pub fn accepted(node: &NodeCore, name: &str) -> u64 {
    node.why(name, V).unwrap().accepted
}

/// How often `name.V` counted `cause`.
pub fn dropped(node: &NodeCore, name: &str, cause: DropCause) -> u64 {
    node.why(name, V).unwrap().counters.get(cause)
}

/// The pass holder / supplier name of a local connection.
pub fn held_by(conn: ConnectionId) -> Source {
    Source::connection(NODE, conn)
}

/// `n` milliseconds after the clock's origin.
pub fn at(n: u64) -> Instant {
    Instant::from_millis(n)
}

/// `n` milliseconds.
pub fn ms(n: u64) -> Duration {
    Duration::from_millis(n)
}

/// D6.7, for either override kind: a remote override message whose value the port cannot
/// take (wrong type) is refused whole: counted as type_mismatch, nothing written, and no
/// window, so the local writer `A -> D -> E` is not blocked by a message never applied.
pub fn refused_override_opens_no_window(kind: ConnectionKind) {
    let mut node = wiring(&["A", "D", "E"]);
    link(&mut node, "A", "D", ConnectionKind::Normal);
    link(&mut node, "D", "E", ConnectionKind::Normal);
    let bad = PortMessage {
        conn: ConnectionId(9),
        seq: 1,
        behavior: "D".into(),
        port: V.into(),
        kind,
        priority: 0,
        value: Value::text("not an int"),
    };
    node.receive(at(0), NodeId(2), Message::Port(bad));
    let why = node.why("D", V).unwrap();
    assert!(why.windows.is_empty(), "{why}");
    assert_eq!(dropped(&node, "D", DropCause::TypeMismatch), 1);
    put(&mut node, at(1), "A", 5);
    assert_eq!((value(&node, "D"), value(&node, "E")), (5, 5), "the local writer is not blocked");
}
