//! Where a node is reached (`Node::address`), over real loopback sockets: a node bound to port 0
//! reports the port the system gave it, and a node told only that address finds it (HELLO both
//! ways), which is how scripts and the process tests start teams without picking ports
//! (docs/testing.md). Transports without addresses report none.

use std::time::{Duration, Instant};

use ayllu::{Node, NodeId};

fn heard(node: &Node, id: u32) -> bool {
    node.peers().iter().any(|p| p.node == NodeId(id))
}

#[test]
fn a_node_bound_to_port_0_reports_its_port_and_is_reached_there() {
    let mut a = Node::open(NodeId(1), "udp://127.0.0.1:0?hello_ms=50").unwrap();
    let addr = a.address().expect("a udp:// node has an address");
    let port: u16 = addr.strip_prefix("127.0.0.1:").expect("the bound IP").parse().unwrap();
    assert_ne!(port, 0, "the port the system chose, not the 0 asked for");

    // b knows a's address; a learns b's from b's HELLO.
    let mut b = Node::open(NodeId(2), &format!("udp://127.0.0.1:0?hello_ms=50&peer={addr}")).unwrap();
    assert_ne!(b.address(), a.address());
    let limit = Instant::now() + Duration::from_secs(20);
    while !(heard(&a, 2) && heard(&b, 1)) {
        assert!(Instant::now() < limit, "a hears {:?}, b hears {:?}", a.peers(), b.peers());
        a.run_for(Duration::from_millis(5));
        b.run_for(Duration::from_millis(5));
    }
    let b_as_a_sees_it = a.peers().into_iter().find(|p| p.node == NodeId(2)).unwrap().addr;
    assert_eq!(Some(b_as_a_sees_it), b.address());
}

#[test]
fn an_in_process_node_has_no_address() {
    assert_eq!(Node::open(NodeId(1), "mem://address-test").unwrap().address(), None);
}

#[test]
fn binding_an_address_another_node_holds_fails_with_a_clear_error() {
    // A lingering node on an address must not silently share it with a new one (which would
    // take its unicast traffic): the second bind fails and says what to do.
    let first = Node::open(NodeId(21), "udp://127.0.0.1:0").unwrap();
    let addr = first.address().unwrap();
    let err = Node::open(NodeId(22), &format!("udp://{addr}")).err().expect("the address is taken");
    let text = err.to_string();
    assert!(text.contains(&addr) && text.contains("another process holds this address"), "{text}");
}
