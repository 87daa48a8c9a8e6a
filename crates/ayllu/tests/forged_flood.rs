//! A flood of forged requests at a live node over real UDP keeps its memory bounded
//! (docs/security.md "Memory, bounded in bytes"; D9.3, D-S10.2). One test in this file: it
//! reads the whole process's live heap through a counting global allocator, so nothing else
//! may run beside it.
//!
//! The case an outside test found: a node with 90 behaviors, 3 000 LIST requests of 25 bytes,
//! each from an invented node id, all waiting on the socket when the node's turn starts. The
//! turn answered every one (each id is under its own rate), 70 KB a report, so 210 MB of answers
//! waited for the send at the turn's end; the replies to ids the flood had pushed out of the
//! peer table were then held, 256 reports at a time. The process kept 262 MB.

use std::alloc::{GlobalAlloc, Layout, System};
use std::net::UdpSocket;
use std::sync::atomic::{AtomicIsize, Ordering::Relaxed};

use ayllu::{BehaviorClass, MonotonicClock, Node, NodeId, PortSpec, UdpConfig, UdpTransport};

struct Counting;

static LIVE: AtomicIsize = AtomicIsize::new(0);
static PEAK: AtomicIsize = AtomicIsize::new(0);

fn grew(by: usize) {
    let now = LIVE.fetch_add(by as isize, Relaxed) + by as isize;
    PEAK.fetch_max(now, Relaxed);
}

// SAFETY: every call is forwarded unchanged to `System`; we only add up sizes.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        grew(layout.size());
        System.alloc(layout)
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        grew(layout.size());
        System.alloc_zeroed(layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        LIVE.fetch_sub(layout.size() as isize, Relaxed);
        grew(new_size);
        System.realloc(ptr, layout, new_size)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        LIVE.fetch_sub(layout.size() as isize, Relaxed);
        System.dealloc(ptr, layout)
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// A LIST request (spec/protocol.md: header, then one REQUEST message) from node `sender`.
fn forged_list(sender: u32, datagram: u64) -> Vec<u8> {
    let mut d = b"AY\x01\x00".to_vec(); // magic, version 1, no flags
    d.extend_from_slice(&0u32.to_le_bytes()); // open team
    d.extend_from_slice(&sender.to_le_bytes());
    d.extend_from_slice(&datagram.to_le_bytes());
    let mut body = 5u64.to_le_bytes().to_vec(); // request id
    body.push(3); // LIST
    d.push(0x10); // REQUEST
    d.extend_from_slice(&(body.len() as u16).to_le_bytes());
    d.extend_from_slice(&body);
    d
}

#[test]
fn a_flood_of_forged_list_requests_in_one_turn_keeps_the_heap_bounded() {
    let transport = UdpTransport::bind(NodeId(2), UdpConfig::new("127.0.0.1:0".parse().unwrap())).unwrap();
    let addr = transport.local_addr().unwrap();
    let mut node = Node::new(MonotonicClock::new(), transport);
    let mut relay = BehaviorClass::new("Relay");
    for port in ["In", "Out", "Aux"] {
        relay.port(PortSpec::new(port, 0i64)).unwrap();
    }
    node.define(relay).unwrap();
    for b in 0..90 {
        node.create("Relay", &format!("C90_{b:03}")).unwrap();
    }
    node.step();
    let flood = UdpSocket::bind("127.0.0.1:0").unwrap();
    let base = LIVE.load(Relaxed);
    PEAK.store(base, Relaxed);
    // Sent in bursts the socket buffer holds, each received by one turn.
    const SENDERS: u32 = 3_000;
    for k in 0..SENDERS {
        flood.send_to(&forged_list(300_000 + k, (1 << 40) + u64::from(k)), addr).unwrap();
        if k % 1_500 == 1_499 {
            node.step();
        }
    }
    for _ in 0..5 {
        node.step();
    }
    let peak = (PEAK.load(Relaxed) - base) as f64 / (1 << 20) as f64;
    let counters = node.transport_counters();
    let count = |name: &str| counters.iter().find(|(c, _)| c == name).map_or(0, |(_, n)| *n);
    let report = node.core().report_at(node.now());
    let rate_limited = report.counters.get(ayllu::DropCause::RateLimited);
    println!("peak {peak:.1} MiB above the start; transport {counters:?}; rate_limited {rate_limited}");
    assert!(
        count("datagrams_received") + count("admission_limited") >= 1_000,
        "the flood reached the node: {counters:?}"
    );
    // Most forged ids are now refused at admission (one source address: its newcomer rate,
    // docs/semantics.md N4); those let in are answered within what may wait for the send.
    assert!(
        rate_limited + count("admission_limited") > 0,
        "forged requesters beyond the admission rate, or answers beyond what may wait, are dropped unanswered"
    );
    assert_eq!(count("held"), 0, "no reply is held for a requester the table has lost");
    // Answers remembered (2 MiB), answers waiting (2 MiB), each estimated, the peer table and
    // the socket's read-ahead: a few MiB. Before: about 200 MiB.
    assert!(peak < 16.0, "the heap grew by {peak:.1} MiB under the flood");
}
