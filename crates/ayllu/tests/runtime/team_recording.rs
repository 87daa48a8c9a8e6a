//! A recorder on the in-process `mem://` transport, deterministic on a manual clock: what a
//! listener hears (the groups it joins, not unicast between others), that tapping changes
//! nothing for the team, and that the file reads back on the sender's channels.

use ayllu::team_recording::{read_recording, Recorder, Tap, TeamWriter};
use ayllu::{
    BehaviorClass, ConnectionKind, Duration, Endpoint, ManualClock, MemNetwork, Node, NodeId, PortSpec, Value,
};

fn node(net: &MemNetwork, id: u32, clock: &ManualClock) -> Node {
    let mut n = Node::new(clock.clone(), net.attach(NodeId(id)).unwrap());
    let mut class = BehaviorClass::new("Relay");
    class.port(PortSpec::new("In", 0.0)).unwrap();
    class.port(PortSpec::new("Out", 0.0)).unwrap();
    n.define(class).unwrap();
    n.create("Relay", "R").unwrap();
    n.join("team");
    n
}

#[test]
fn a_recorder_hears_the_groups_it_joins_and_not_unicast_between_others() {
    let net = MemNetwork::named("team-recording-groups");
    let clock = ManualClock::new();
    let mut sender = node(&net, 1, &clock);
    let mut receiver = node(&net, 2, &clock);
    // Group traffic and unicast traffic from the same sender.
    sender.connect(&Endpoint::local("R", "Out"), &Endpoint::group("team", "R", "In"), ConnectionKind::Normal).unwrap();
    sender
        .connect(&Endpoint::local("R", "In"), &Endpoint::node(NodeId(2), "R", "Out"), ConnectionKind::Normal)
        .unwrap();

    let (tap, heard) = Tap::new(net.attach(NodeId(99)).unwrap());
    let mut listener = Node::new(clock.clone(), tap);
    listener.join("team");
    let mut buf = std::io::Cursor::new(Vec::new());
    {
        let mut recorder = Recorder::new(TeamWriter::new(&mut buf).unwrap());
        recorder.learn(&sender.core().report());
        for i in 1..=5 {
            sender.write("R", "Out", i as f64).unwrap();
            sender.write("R", "In", -(i as f64)).unwrap();
            for n in [&mut sender, &mut receiver, &mut listener] {
                n.step();
            }
            clock.advance(Duration::from_millis(10));
            for n in [&mut sender, &mut receiver, &mut listener] {
                n.step();
            }
            recorder.heard(heard.take()).unwrap();
        }
        assert!(recorder.wanted_lists().is_empty());
        recorder.finish().unwrap();
        assert_eq!(recorder.unresolved(), 0);
        assert_eq!(recorder.per_channel(), vec![("/n1/R/Out".to_owned(), 5)]);
    }
    // The tap took nothing from the team: the members still got the group's values and the
    // unicast ones.
    assert_eq!(receiver.read("R", "In").unwrap(), Value::Float(5.0));
    assert_eq!(receiver.read("R", "Out").unwrap(), Value::Float(-5.0));

    let back = read_recording(buf.get_ref()).unwrap();
    let values: Vec<Value> = back.iter().map(|r| r.value.clone()).collect();
    assert_eq!(values, (1..=5).map(|i| Value::Float(i as f64)).collect::<Vec<_>>());
    assert!(back.iter().all(|r| r.channel.topic() == "/n1/R/Out"));
    assert!(back.windows(2).all(|w| w[0].log_time <= w[1].log_time));
}

#[test]
fn a_file_that_is_not_mcap_is_an_error_not_a_panic() {
    assert!(read_recording(b"").is_err());
    assert!(read_recording(b"\x89MCAP0\r\n garbage").is_err());
}
