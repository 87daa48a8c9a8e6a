//! D-S10.7: a vector longer than a message carries ([`MAX_NETWORK_VECTOR`], one byte counts it on
//! the wire) can never reach another node, so a connection to another node or a group from a
//! port that holds one is refused up front, naming the port and what to do; locally a vector has
//! any length, and a port that holds a short one now may still connect (a longer value later is
//! dropped at sending and counted, as any value the wire cannot carry).

use ayllu_core::*;

fn node_with(len: usize) -> NodeCore {
    let mut n = NodeCore::new(NodeId(1));
    let mut c = BehaviorClass::new("Scan");
    c.port(PortSpec::new("Ranges", Vec::<f64>::new())).unwrap();
    c.port(PortSpec::new("Copy", Vec::<f64>::new())).unwrap();
    n.define(c).unwrap();
    n.create("Scan", "S").unwrap();
    n.write_named(Instant::from_millis(1), "S", "Ranges", vec![1.0; len]).unwrap();
    n
}

#[test]
fn a_vector_longer_than_a_message_carries_is_refused_to_other_nodes() {
    let src = Endpoint::local("S", "Ranges");
    for dst in [Endpoint::node(NodeId(2), "S", "Ranges"), Endpoint::group("team", "S", "Ranges")] {
        let mut n = node_with(1080);
        let e = n.connect(&src, &dst, ConnectionKind::Normal, ConnectOptions::default()).unwrap_err();
        assert_eq!(e, Error::TooLongForNetwork { port: "S.Ranges".into(), len: 1080 });
        let text = e.to_string();
        assert!(text.contains("1080") && text.contains("at most 255") && text.contains("beams"), "{text}");
        assert_eq!(n.report().connections.len(), 0, "nothing was made");
    }
}

#[test]
fn the_longest_vector_a_message_carries_connects() {
    let mut n = node_with(MAX_NETWORK_VECTOR);
    let dst = Endpoint::node(NodeId(2), "S", "Ranges");
    n.connect(&Endpoint::local("S", "Ranges"), &dst, ConnectionKind::Normal, ConnectOptions::default()).unwrap();
    let mut n = node_with(MAX_NETWORK_VECTOR + 1);
    assert!(n
        .connect(&Endpoint::local("S", "Ranges"), &dst, ConnectionKind::Normal, ConnectOptions::default())
        .is_err());
}

#[test]
fn locally_and_to_this_node_by_its_id_a_vector_has_any_length() {
    for dst in [Endpoint::local("S", "Copy"), Endpoint::node(NodeId(1), "S", "Copy")] {
        let mut n = node_with(100_000);
        n.connect(&Endpoint::local("S", "Ranges"), &dst, ConnectionKind::Normal, ConnectOptions::default()).unwrap();
        n.write_named(Instant::from_millis(2), "S", "Ranges", vec![2.0; 100_000]).unwrap();
        assert_eq!(n.read(n.port("S", "Copy").unwrap()).unwrap().as_vector().map(<[f64]>::len), Some(100_000));
    }
}
