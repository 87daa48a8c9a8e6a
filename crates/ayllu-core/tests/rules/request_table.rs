//! Rule N2 from the requester's side: a node's own control requests are retried until
//! answered, and what it keeps of them is bounded. A finished request (answered or failed)
//! stays readable with `request_status` until the program forgets it (`forget_request`) or
//! until 1,024 newer ones have finished; pending requests are never forgotten by the bound.
//! A viewer that asks LIST forever (ayllu foxglove, ayllu record) therefore stays bounded.

use ayllu_core::*;

fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}

/// Node 2 answers whatever node 1 asked; returns how many replies were delivered.
fn answer_all(asker: &mut NodeCore, answerer: &mut NodeCore, now: Instant) -> usize {
    let mut n = 0;
    while let Some(out) = asker.pop_outgoing() {
        answerer.receive(now, NodeId(1), out.message);
    }
    while let Some(out) = answerer.pop_outgoing() {
        if let Message::Control(ControlMessage { body: ControlBody::Reply { .. }, .. }) = out.message {
            asker.receive(now, NodeId(2), out.message);
            n += 1;
        }
    }
    n
}

fn pair() -> (NodeCore, NodeCore) {
    let a = NodeCore::new(NodeId(1));
    let mut b = NodeCore::new(NodeId(2));
    // The answerer's request rate limit would refuse a burst of thousands from one sender.
    b.set_limits(Limits { requests_per_second: 1_000_000, requests_burst: 1_000_000, ..Limits::default() });
    (a, b)
}

#[test]
fn finished_requests_are_kept_up_to_the_bound_and_the_oldest_go_first() {
    let (mut a, mut b) = pair();
    let mut ids = Vec::new();
    for i in 0..3_000u64 {
        ids.push(a.request(NodeId(2), ControlBody::List).unwrap());
        assert_eq!(answer_all(&mut a, &mut b, ms(i)), 1);
        assert!(a.requests_held() <= 1_024 + 256, "held {} after {} requests", a.requests_held(), i + 1);
    }
    assert!(matches!(a.request_status(*ids.last().unwrap()), Some(RequestStatus::Done(ReplyBody::Node(_)))));
    assert_eq!(a.request_status(ids[0]), None, "the oldest finished request was forgotten");
    let kept = ids.iter().filter(|id| a.request_status(**id).is_some()).count();
    assert!((1_024..=1_280).contains(&kept), "kept {kept}");
}

#[test]
fn pending_requests_survive_the_bound() {
    let (mut a, mut b) = pair();
    // One request to a node that never answers, then many answered ones.
    let silent = a.request(NodeId(9), ControlBody::List).unwrap();
    while a.pop_outgoing().is_some() {}
    for i in 0..2_000u64 {
        a.request(NodeId(2), ControlBody::List).unwrap();
        answer_all(&mut a, &mut b, ms(i / 100));
    }
    assert!(matches!(a.request_status(silent), Some(RequestStatus::Pending { .. })));
}

#[test]
fn forget_request_returns_the_status_once() {
    let (mut a, mut b) = pair();
    let id = a.request(NodeId(2), ControlBody::List).unwrap();
    answer_all(&mut a, &mut b, ms(1));
    assert!(matches!(a.forget_request(id), Some(RequestStatus::Done(_))));
    assert_eq!(a.forget_request(id), None);
    assert_eq!(a.request_status(id), None);
    assert_eq!(a.requests_held(), 0);
    // A forgotten pending request is no longer retried, and a late answer is ignored.
    let id = a.request(NodeId(2), ControlBody::List).unwrap();
    let sent = a.pop_outgoing().unwrap();
    assert!(matches!(a.forget_request(id), Some(RequestStatus::Pending { .. })));
    assert_eq!(a.poll(ms(10_000)), None, "nothing left to retry");
    assert!(a.pop_outgoing().is_none());
    b.receive(ms(10_001), NodeId(1), sent.message);
    let reply = b.pop_outgoing().unwrap();
    a.receive(ms(10_002), NodeId(2), reply.message);
    assert_eq!(a.request_status(id), None);
}
