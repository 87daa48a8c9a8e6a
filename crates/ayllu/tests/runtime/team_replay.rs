//! Team replay (docs/tools.md, spec/flight-recorder.md "A team's recordings"): three nodes'
//! flight recordings checked as one system. Every remote value a node accepted is matched with
//! the message its sender's replay sends (same connection and sequence number, same value,
//! once), the clocks are recovered from the messages alone within the bound printed, and a
//! recording altered or with a message removed is caught and named.
//!
//! The nodes talk over real loopback UDP through the fault injector (loss, duplication,
//! reordering, delay); their clocks are the team's virtual clock shifted by a different offset
//! each, as three robots' clocks started at different moments are.

use std::path::PathBuf;

use ayllu::replay::Recording;
use ayllu::team_replay::{self, Finding};
use ayllu::{Event, Instant, Message, NodeId, Value};

use crate::replay::recorded_udp_team;

/// The offset of each node's clock from the team's (node 1's is the reference): robots started
/// at different moments.
const SHIFT_MS: [u64; 3] = [0, 1_500, 250];

/// Three recorded nodes for 4 s ([`recorded_udp_team`]: BLE cross-subsumption and a relay ring
/// over loopback UDP with faults); their recordings.
fn recorded_team(name: &str) -> Vec<Recording> {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("team-replay-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    let mut team = recorded_udp_team(&d, &format!("team-replay-{name}"), 11, SHIFT_MS, 4);
    for i in 0..3 {
        team.node(i).stop_recording().unwrap();
    }
    (1..=3).map(|id| Recording::open(d.join(format!("n{id}.mcap"))).unwrap()).collect()
}

#[test]
fn a_teams_recordings_hold_together_and_give_the_clocks_within_their_bound() {
    let recs = recorded_team("whole");
    let team = team_replay::check(&recs);
    println!("{team}");
    assert!(team.passed(), "{team}");
    assert_eq!(team.nodes, [NodeId(1), NodeId(2), NodeId(3)]);
    assert!(team.accepted_remote > 200 && team.unexplained() == 0, "{team}");
    // Every ordered pair exchanged messages, so every clock is bounded on both sides, and the
    // true offset (the shift) lies within the interval printed.
    assert_eq!(team.matched.len(), 6, "{team}");
    for (c, shift) in team.clocks.iter().zip(SHIFT_MS) {
        let truth = shift as f64 / 1e3;
        let (low, high) = (c.low.unwrap(), c.high.unwrap());
        assert!(low <= truth + 1e-9 && truth <= high + 1e-9, "{}: {truth} s outside [{low}, {high}]", c.node);
        // The messages were stepped every 10 ms: the bound is that, not seconds.
        assert!(c.bound().unwrap() < 0.02, "{}: bound {:?}", c.node, c.bound());
    }

    // The merged timeline: every value each replay reproduced, on the reference clock, in
    // time order, readable by an MCAP reader, a channel per node's port.
    let path = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("timeline-{}.mcap", std::process::id()));
    let written = team_replay::Team::open(recs).write_timeline(&path).unwrap();
    let reproduced: usize = team.replayed.iter().map(|(_, k)| k).sum();
    assert_eq!(written, reproduced as u64);
    let bytes = std::fs::read(&path).unwrap();
    let times: Vec<u64> = mcap::MessageStream::new(&bytes).unwrap().map(|m| m.unwrap().log_time).collect();
    assert_eq!(times.len(), reproduced);
    assert!(times.windows(2).all(|w| w[0] <= w[1]), "in time order");
    let summary = mcap::read::Summary::read(&bytes).unwrap().expect("a summary");
    for n in 1..=3 {
        assert!(summary.channels.values().any(|c| c.topic.starts_with(&format!("/n{n}/"))), "node {n}'s channels");
    }
}

#[test]
fn an_altered_value_and_a_removed_message_are_caught_and_named() {
    let mut recs = recorded_team("tampered");
    // In n2's recording: one remote value accepted, altered as it arrived (and as its port
    // accepted it, so that n2's own replay holds: only the team can tell); and in n3's, one
    // received message taken out, with everything it caused.
    let rec = &mut recs[1];
    let i = rec
        .entries
        .iter()
        .position(|e| matches!(&e.event, Event::Receive { message, .. } if matches!(&**message, Message::Port(m) if &*m.behavior == "R")))
        .unwrap();
    let altered_at = rec.entries[i].at;
    let (conn, seq, original) = {
        let Event::Receive { message, .. } = &mut rec.entries[i].event else { unreachable!() };
        let Message::Port(m) = &mut **message else { unreachable!() };
        let original = std::mem::replace(&mut m.value, Value::Float(4242.0));
        (m.conn, m.seq, original)
    };
    for e in rec.entries[i + 1..].iter_mut().take_while(|e| !matches!(e.event, Event::Poll | Event::Receive { .. })) {
        if let Event::Accepted { behavior, value, .. } = &mut e.event {
            if &**behavior == "R" && *value == original {
                *value = Value::Float(4242.0);
            }
        }
    }
    let rec3 = &mut recs[2];
    let j = rec3.entries.iter().position(|e| matches!(e.event, Event::Receive { .. })).unwrap();
    rec3.entries.remove(j);
    rec3.gap = Some((j as u64, rec3.entries[j].at));

    let team = team_replay::check(&recs);
    println!("{team}");
    assert!(!team.passed());
    let altered = team.findings.iter().find_map(|f| match f {
        Finding::ValueDiffers { arrival, sent } => Some((arrival, sent)),
        _ => None,
    });
    let (arrival, sent) = altered.unwrap_or_else(|| panic!("the altered value is named: {team}"));
    assert_eq!((arrival.node, arrival.entry, arrival.at), (NodeId(2), i as u64, altered_at));
    assert_eq!((arrival.id.from, arrival.id.conn, arrival.id.seq), (NodeId(1), conn, seq));
    assert_ne!(*sent, Value::Float(4242.0));
    assert!(
        team.findings
            .iter()
            .any(|f| matches!(f, Finding::Hole { node, entry, .. } if *node == NodeId(3) && *entry == j as u64)),
        "the removed message is named as n3's hole: {team}"
    );
    assert!(team.to_string().contains("altered: n2 entry"), "{team}");
}

#[test]
fn a_value_received_before_it_was_sent_contradicts_the_clocks() {
    let mut recs = recorded_team("causality");
    // Move one of n2's arrivals from n1 two seconds earlier than anything n1 could have sent it
    // at, given the messages the other way: no offset explains both.
    let rec = &mut recs[1];
    let i = rec
        .entries
        .iter()
        .rposition(|e| matches!(&e.event, Event::Receive { from, message } if *from == NodeId(1) && matches!(&**message, Message::Port(_))))
        .unwrap();
    let Event::Receive { message, .. } = rec.entries[i].event.clone() else { unreachable!() };
    let Message::Port(m) = *message else { unreachable!() };
    let early = Instant::from_nanos(rec.entries[i].at.as_nanos().saturating_sub(3_000_000_000));
    rec.entries[i].at = early;
    let team = team_replay::check(&recs);
    assert!(
        team.findings.iter().any(|f| matches!(f, Finding::ReceivedBeforeSent { arrivals, .. }
            if arrivals.iter().any(|a| a.node == NodeId(2) && a.id.seq == m.seq && a.id.conn == m.conn))),
        "{team}"
    );
}
