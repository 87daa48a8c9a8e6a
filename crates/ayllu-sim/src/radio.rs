//! The radio medium between simulated robots: what the core's outgoing messages meet on their
//! way to other robots' nodes — loss, delay with jitter, a range limit and scheduled
//! partitions. Sans-IO and seeded: [`Radio::send`] and [`Radio::deliver`] take the time, and
//! the loss and jitter draws come from the radio's own stream, so the same seed loses the same
//! messages.
//!
//! A group message is one emission: it counts once in `sent` and reaches every other live
//! member of the group that the range, the partitions and an independent loss draw per
//! receiver allow (broadcast over a lossy channel loses per receiver).

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::sync::Arc;

use ayllu_core::{Destination, Duration, Instant, Message, NodeId, Outgoing};
use serde::{Deserialize, Serialize};

/// During `[start, end)` seconds, the robots in `island` (node ids) hear only each other, and
/// the rest hear only the rest.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Partition {
    pub start: f64,
    pub end: f64,
    pub island: Vec<u32>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RadioConfig {
    /// Probability that one receiver misses one message.
    pub loss: f64,
    /// Base latency and the width of a uniform jitter on top (s).
    pub delay: f64,
    pub jitter: f64,
    /// Messages reach only robots within this distance (m); `None`: everywhere.
    pub range: Option<f64>,
    pub partitions: Vec<Partition>,
}

impl Default for RadioConfig {
    /// A lab Wi-Fi: no loss, 2-5 ms, no range limit.
    fn default() -> Self {
        RadioConfig { loss: 0.0, delay: 0.002, jitter: 0.003, range: None, partitions: Vec::new() }
    }
}

/// What the radio needs to know about a robot when it routes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Station {
    pub node: NodeId,
    pub x: f64,
    pub y: f64,
    pub alive: bool,
}

/// A heap entry: small, so that sifting moves 24 bytes, not a whole message (the message
/// waits in `Radio::parked`).
struct InFlight {
    at: Instant,
    order: u64,
    slot: usize,
}

impl PartialEq for InFlight {
    fn eq(&self, other: &Self) -> bool {
        (self.at, self.order) == (other.at, other.order)
    }
}
impl Eq for InFlight {}
impl PartialOrd for InFlight {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for InFlight {
    // Ties in time keep send order, so delivery order is a function of the seed alone.
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        (self.at, self.order).cmp(&(other.at, other.order))
    }
}

pub struct Radio {
    config: RadioConfig,
    rng: fastrand::Rng,
    queue: BinaryHeap<Reverse<InFlight>>,
    order: u64,
    /// Messages in flight (receiver, sender, message), and the free entries.
    parked: Vec<Option<(usize, NodeId, Message)>>,
    free: Vec<usize>,
    /// Members of each group, by station index in increasing order.
    groups: Vec<(Arc<str>, Vec<usize>)>,
    /// Emissions per station, and deliveries lost (by loss draw) / cut (range, partition).
    pub sent: Vec<u64>,
    pub lost: u64,
    pub cut: u64,
    pub delivered: u64,
}

impl Radio {
    pub fn new(config: RadioConfig, stations: usize, seed: u64) -> Radio {
        Radio {
            config,
            rng: fastrand::Rng::with_seed(seed ^ 0x5EED_0004),
            queue: BinaryHeap::new(),
            order: 0,
            parked: Vec::new(),
            free: Vec::new(),
            groups: Vec::new(),
            sent: vec![0; stations],
            lost: 0,
            cut: 0,
            delivered: 0,
        }
    }

    pub fn config(&self) -> &RadioConfig {
        &self.config
    }

    /// Station `i` is a member of `groups` (its node's joined groups). Call in station order.
    pub fn set_groups(&mut self, i: usize, groups: &[Arc<str>]) {
        for g in groups {
            let gi = match self.groups.iter().position(|(name, _)| name == g) {
                Some(gi) => gi,
                None => {
                    self.groups.push((g.clone(), Vec::new()));
                    self.groups.len() - 1
                }
            };
            let members = &mut self.groups[gi].1;
            if !members.contains(&i) {
                members.push(i);
                members.sort_unstable();
            }
        }
    }

    fn connected(&self, now: f64, a: &Station, b: &Station) -> bool {
        if let Some(r) = self.config.range {
            if (a.x - b.x).hypot(a.y - b.y) > r {
                return false;
            }
        }
        self.config
            .partitions
            .iter()
            .all(|p| !(p.start <= now && now < p.end) || p.island.contains(&a.node.0) == p.island.contains(&b.node.0))
    }

    /// Station `from` emits `out` at `now`.
    pub fn send(&mut self, now: Instant, from: usize, out: Outgoing, stations: &[Station]) {
        self.sent[from] += 1;
        let src = stations[from];
        let t = now.as_secs_f64();
        match &out.to {
            Destination::Node(id) => {
                if let Some(to) = stations.iter().position(|s| s.node == *id) {
                    self.route(now, t, &src, to, &stations[to], out.message);
                }
            }
            Destination::Group(g) => {
                // Teams have a handful of groups: a scan beats hashing the name.
                let Some(gi) = self.groups.iter().position(|(name, _)| name == g) else { return };
                // Taken out for the loop so `route` can borrow the radio; put back after.
                let members = std::mem::take(&mut self.groups[gi].1);
                for &to in &members {
                    if to != from {
                        self.route(now, t, &src, to, &stations[to], out.message.clone());
                    }
                }
                self.groups[gi].1 = members;
            }
        }
    }

    fn route(&mut self, now: Instant, t: f64, src: &Station, to: usize, dst: &Station, message: Message) {
        if !dst.alive || !self.connected(t, src, dst) {
            self.cut += 1;
            return;
        }
        if self.config.loss > 0.0 && self.rng.f64() < self.config.loss {
            self.lost += 1;
            return;
        }
        let delay = self.config.delay + self.config.jitter * self.rng.f64();
        let at = now + Duration::from_nanos((delay * 1e9) as u64);
        self.order += 1;
        let entry = Some((to, src.node, message));
        let slot = match self.free.pop() {
            Some(slot) => {
                self.parked[slot] = entry;
                slot
            }
            None => {
                self.parked.push(entry);
                self.parked.len() - 1
            }
        };
        self.queue.push(Reverse(InFlight { at, order: self.order, slot }));
    }

    /// Hand every message due at or before `now` to `deliver(station, from, message)`.
    pub fn deliver(&mut self, now: Instant, mut deliver: impl FnMut(usize, NodeId, Message)) {
        while self.queue.peek().is_some_and(|Reverse(m)| m.at <= now) {
            let Reverse(m) = self.queue.pop().expect("peeked");
            let (to, from, message) = self.parked[m.slot].take().expect("parked while queued");
            self.free.push(m.slot);
            self.delivered += 1;
            deliver(to, from, message);
        }
    }

    pub fn in_flight(&self) -> usize {
        self.queue.len()
    }
}
