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

struct InFlight {
    at: Instant,
    order: u64,
    to: usize,
    from: NodeId,
    message: Message,
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
    /// Group memberships, by station index.
    groups: Vec<Vec<Arc<str>>>,
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
            groups: vec![Vec::new(); stations],
            sent: vec![0; stations],
            lost: 0,
            cut: 0,
            delivered: 0,
        }
    }

    pub fn config(&self) -> &RadioConfig {
        &self.config
    }

    /// Station `i` is a member of `groups` (its node's joined groups).
    pub fn set_groups(&mut self, i: usize, groups: &[Arc<str>]) {
        self.groups[i] = groups.to_vec();
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
                for (to, st) in stations.iter().enumerate() {
                    if to != from && self.groups[to].iter().any(|m| m == g) {
                        self.route(now, t, &src, to, st, out.message.clone());
                    }
                }
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
        self.queue.push(Reverse(InFlight { at, order: self.order, to, from: src.node, message }));
    }

    /// Hand every message due at or before `now` to `deliver(station, from, message)`.
    pub fn deliver(&mut self, now: Instant, mut deliver: impl FnMut(usize, NodeId, Message)) {
        while self.queue.peek().is_some_and(|Reverse(m)| m.at <= now) {
            let Reverse(m) = self.queue.pop().expect("peeked");
            self.delivered += 1;
            deliver(m.to, m.from, m.message);
        }
    }

    pub fn in_flight(&self) -> usize {
        self.queue.len()
    }
}
