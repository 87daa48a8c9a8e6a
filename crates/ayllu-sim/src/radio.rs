//! The radio medium between simulated robots: what the core's outgoing messages meet on their
//! way to other robots' nodes — loss, delay with jitter, a range limit and scheduled
//! partitions. Sans-IO and seeded: [`Radio::send`] and [`Radio::deliver_shared`] take the time, and
//! the loss and jitter draws come from the radio's own stream, so the same seed loses the same
//! messages.
//!
//! A group message is one emission: it counts once in `sent` and reaches every other live
//! member of the group that the range, the partitions and an independent loss draw per
//! receiver allow (broadcast over a lossy channel loses per receiver). It is one frame on the
//! air: its delay (base + jitter) is drawn once, and every receiver hears it at that moment,
//! in station order. Jitter thus reorders emissions, not the receivers of one emission.

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::sync::Arc;

use ayllu_core::{Destination, Duration, Instant, Message, NodeId, Outgoing};
use serde::{Deserialize, Serialize};

/// During `[start, end)` seconds, the robots in `island` (node ids) hear only each other, and
/// the rest hear only the rest.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Partition {
    /// When the partition begins (s of virtual time).
    #[serde(deserialize_with = "crate::numbers::number_de")]
    pub start: f64,
    /// When it heals (s of virtual time; excluded).
    #[serde(deserialize_with = "crate::numbers::number_de")]
    pub end: f64,
    /// The node ids on one side; everyone else is on the other.
    pub island: Vec<u32>,
}

/// The radio medium: loss per receiver, delay and jitter, range and partitions.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RadioConfig {
    /// Probability that one receiver misses one message.
    #[serde(deserialize_with = "crate::numbers::number_de")]
    pub loss: f64,
    /// Base latency of every emission (s of virtual time).
    #[serde(deserialize_with = "crate::numbers::number_de")]
    pub delay: f64,
    /// Width of a uniform jitter added to `delay` (s), drawn once per emission.
    #[serde(deserialize_with = "crate::numbers::number_de")]
    pub jitter: f64,
    /// Messages reach only robots within this distance (m); `None`: everywhere.
    #[serde(default, deserialize_with = "crate::numbers::optional_number_de")]
    pub range: Option<f64>,
    /// Scheduled partitions (see [`Partition`]).
    pub partitions: Vec<Partition>,
}

impl RadioConfig {
    /// Whether stations `a` and `b` hear each other at `now` (s): within range and on the same
    /// side of every partition in force (aliveness and loss are not this function's).
    pub fn connects(&self, now: f64, a: &Station, b: &Station) -> bool {
        if let Some(r) = self.range {
            if (a.x - b.x).hypot(a.y - b.y) > r {
                return false;
            }
        }
        self.partitions
            .iter()
            .all(|p| !(p.start <= now && now < p.end) || p.island.contains(&a.node.0) == p.island.contains(&b.node.0))
    }
}

impl Default for RadioConfig {
    /// A lab Wi-Fi: no loss, 2-5 ms, no range limit.
    fn default() -> Self {
        RadioConfig { loss: 0.0, delay: 0.002, jitter: 0.003, range: None, partitions: Vec::new() }
    }
}

/// Bytes `message` takes on the wire: the udp:// transport's encoding (ayllu-wire), message
/// headers included, datagram headers, MACs and HELLOs not; 0 if it cannot be encoded (the
/// transport would drop it too). How `bytes_per_robot_s` counts, in-process and distributed.
pub fn wire_len(message: &Message) -> u64 {
    match message {
        // A PORT is one wire message whatever the MTU (`WireMessage::from_core`): measured
        // without building the list of parts.
        Message::Port(p) => ayllu_wire::encoded_len(&ayllu_wire::WireMessage::Port(p.clone())).map_or(0, |n| n as u64),
        _ => ayllu_wire::WireMessage::from_core(message, ayllu_wire::DEFAULT_MTU, false)
            .map(|parts| parts.iter().map(|p| ayllu_wire::encoded_len(p).unwrap_or(0) as u64).sum())
            .unwrap_or(0),
    }
}

/// What the radio needs to know about a robot when it routes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Station {
    /// The robot's node id.
    pub node: NodeId,
    /// Position (m, arena frame), for the range limit.
    pub x: f64,
    /// Position (m, arena frame), for the range limit.
    pub y: f64,
    /// A dead robot neither sends nor receives.
    pub alive: bool,
}

/// A heap entry: small, so that sifting moves 24 bytes, not a whole message (the emission
/// waits in `Radio::parked`).
struct InFlight {
    at: Instant,
    order: u64,
    slot: usize,
}

/// One emission in flight: who sent it, the message (shared by its receivers, never copied
/// in flight), and the stations it will reach. Slots are reused with their receiver lists, so
/// a run in steady state allocates nothing here.
struct Emission {
    from: NodeId,
    message: Option<Message>,
    /// The receivers, when listed (`everyone == 0`).
    to: Vec<usize>,
    /// Not 0: the receivers are every station below `everyone` but the sender, unlisted (a
    /// broadcast to a group of every station on an open, lossless radio with none dead, BLE's
    /// eligibility at every tick: writing and sorting a list of all the others per emission
    /// was most of the radio's work per delivery).
    everyone: usize,
    /// The sender's station, which an unlisted broadcast does not reach.
    from_station: usize,
}

/// An unlisted broadcast set aside by `Radio::take_due`: where it stands in delivery order
/// (its index in `Radio::due`), the slot of its emission, whom it reaches.
#[derive(Clone, Copy)]
struct Broadcast {
    at: u32,
    slot: u32,
    everyone: u32,
    from_station: u32,
}

impl Broadcast {
    #[inline]
    fn reaches(&self, station: usize) -> bool {
        station < self.everyone as usize && station != self.from_station as usize
    }
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

/// A station's due messages ([`Radio::due`]): the short way when only unlisted broadcasts
/// reach it, else merged with its listed ones.
enum Due<A, B> {
    Broadcasts(A),
    Merged(B),
}

impl<'a, A, B> Iterator for Due<A, B>
where
    A: Iterator<Item = (NodeId, &'a Message)>,
    B: Iterator<Item = (NodeId, &'a Message)>,
{
    type Item = (NodeId, &'a Message);

    #[inline]
    fn next(&mut self) -> Option<Self::Item> {
        match self {
            Due::Broadcasts(a) => a.next(),
            Due::Merged(b) => b.next(),
        }
    }
}

/// The simulated radio: routes the nodes' outgoing messages with loss, delay, jitter, range and
/// partitions, seeded, on virtual time.
pub struct Radio {
    config: RadioConfig,
    rng: fastrand::Rng,
    queue: BinaryHeap<Reverse<InFlight>>,
    order: u64,
    /// Emissions in flight, and the free entries.
    parked: Vec<Emission>,
    free: Vec<usize>,
    /// Emissions set aside by `take_due`, in delivery order.
    due: Vec<usize>,
    /// The same deliveries by receiver, for the emissions whose receivers are listed: station
    /// `s`'s are the emissions at `due[k]` for each `k` in `by_station[starts[s]..starts[s +
    /// 1]]`, in delivery order (a counting sort of the receiver lists, made once in
    /// `take_due`), so that handing one station its messages reads only its own.
    starts: Vec<u32>,
    by_station: Vec<u32>,
    /// The unlisted broadcasts among them, in delivery order: every station they reach
    /// walks this one short list, merged with its listed ones by position in `due`.
    broadcasts: Vec<Broadcast>,
    /// Members of each group, by station index in increasing order.
    groups: Vec<(Arc<str>, Vec<usize>)>,
    /// Emissions per station (a group message counts once).
    pub sent: Vec<u64>,
    /// Their encoded size per station, in bytes ([`wire_len`]).
    pub bytes: Vec<u64>,
    /// Deliveries (one per receiver) dropped by the loss draw.
    pub lost: u64,
    /// Deliveries (one per receiver) cut by the range limit or a partition.
    pub cut: u64,
    /// Deliveries (one per receiver) handed over.
    pub delivered: u64,
}

impl Radio {
    /// A radio for `stations` robots with `config`, its draws seeded by `seed`.
    pub fn new(config: RadioConfig, stations: usize, seed: u64) -> Radio {
        Radio {
            config,
            rng: fastrand::Rng::with_seed(seed ^ 0x5EED_0004),
            queue: BinaryHeap::new(),
            order: 0,
            parked: Vec::new(),
            free: Vec::new(),
            due: Vec::new(),
            starts: Vec::new(),
            by_station: Vec::new(),
            broadcasts: Vec::new(),
            groups: Vec::new(),
            sent: vec![0; stations],
            bytes: vec![0; stations],
            lost: 0,
            cut: 0,
            delivered: 0,
        }
    }

    /// The configuration it runs with.
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
        self.config.connects(now, a, b)
    }

    /// Station `from` emits `out` at `now`.
    pub fn send(&mut self, now: Instant, from: usize, out: Outgoing, stations: &[Station]) {
        self.emit(now, from, out, stations, false);
    }

    /// [`Radio::send`] by a caller that knows every station in `stations` is alive (the
    /// simulator's tick before any robot died): a broadcast on an open, lossless radio then
    /// lists its receivers (every member but the sender) without reading each station.
    pub fn send_all_alive(&mut self, now: Instant, from: usize, out: Outgoing, stations: &[Station]) {
        debug_assert!(stations.iter().all(|s| s.alive), "a station is dead");
        self.emit(now, from, out, stations, true);
    }

    fn emit(&mut self, now: Instant, from: usize, out: Outgoing, stations: &[Station], all_alive: bool) {
        self.sent[from] += 1;
        self.bytes[from] += wire_len(&out.message);
        let src = stations[from];
        let t = now.as_secs_f64();
        let slot = self.free.pop().unwrap_or_else(|| {
            self.parked.push(Emission { from: src.node, message: None, to: Vec::new(), everyone: 0, from_station: 0 });
            self.parked.len() - 1
        });
        // Taken out so that `reaches` can borrow the radio; put back below.
        let mut to = std::mem::take(&mut self.parked[slot].to);
        // Not 0: every station below it but the sender hears this, unlisted.
        let mut everyone = 0;
        match &out.to {
            Destination::Node(id) => {
                if let Some(i) = stations.iter().position(|s| s.node == *id) {
                    if self.reaches(t, &src, &stations[i]) {
                        to.push(i);
                    }
                }
            }
            Destination::Group(g) => {
                // Teams have a handful of groups: a scan beats hashing the name.
                if let Some(gi) = self.groups.iter().position(|(name, _)| name == g) {
                    let members = std::mem::take(&mut self.groups[gi].1);
                    let every_station = members.len() == stations.len()
                        && members.last().is_some_and(|&last| last + 1 == stations.len());
                    if self.config.loss == 0.0 && self.open() && all_alive && every_station {
                        // Nothing to draw, nothing to cut, and the group is every station
                        // (sorted and distinct, so 0..n): every other station, unlisted.
                        everyone = stations.len();
                    } else if self.config.loss == 0.0 && self.open() && all_alive {
                        // Nothing to draw, nothing to cut: the members (sorted) around the
                        // sender, as the pass below would keep them.
                        let k = members.partition_point(|&i| i < from);
                        to.extend_from_slice(&members[..k]);
                        let rest = if members.get(k) == Some(&from) { k + 1 } else { k };
                        to.extend_from_slice(&members[rest..]);
                    } else if self.config.loss == 0.0 && self.open() {
                        // Nothing to draw, nothing to cut but the dead: what `reaches` decides,
                        // in one pass without its checks per receiver.
                        to.reserve(members.len());
                        for &i in &members {
                            if i != from {
                                if stations[i].alive {
                                    to.push(i);
                                } else {
                                    self.cut += 1;
                                }
                            }
                        }
                    } else {
                        for &i in &members {
                            if i != from && self.reaches(t, &src, &stations[i]) {
                                to.push(i);
                            }
                        }
                    }
                    self.groups[gi].1 = members;
                }
            }
        }
        // An unlisted broadcast reaches `everyone - 1` stations.
        if to.is_empty() && everyone <= 1 {
            self.parked[slot].to = to;
            self.free.push(slot);
            return;
        }
        let delay = self.config.delay + self.config.jitter * self.rng.f64();
        let at = now + Duration::from_nanos((delay * 1e9) as u64);
        self.order += 1;
        self.parked[slot] = Emission { from: src.node, message: Some(out.message), to, everyone, from_station: from };
        self.queue.push(Reverse(InFlight { at, order: self.order, slot }));
    }

    /// No range limit and no partition: every live station hears every other.
    fn open(&self) -> bool {
        self.config.range.is_none() && self.config.partitions.is_empty()
    }

    /// Whether a message from `src` reaches `dst` (alive, connected, not lost), counting why not.
    #[inline]
    fn reaches(&mut self, t: f64, src: &Station, dst: &Station) -> bool {
        if !dst.alive || !(self.open() || self.connected(t, src, dst)) {
            self.cut += 1;
            return false;
        }
        if self.config.loss > 0.0 && self.rng.f64() < self.config.loss {
            self.lost += 1;
            return false;
        }
        true
    }

    /// Hand every message due at or before `now` to `deliver(station, from, message)`: station
    /// by station, and each station's messages by emission in (time, send) order. Receivers are
    /// independent nodes, so only the order at each receiver matters.
    pub fn deliver_shared(&mut self, now: Instant, mut deliver: impl FnMut(usize, NodeId, &Message)) {
        self.take_due(now);
        let unlisted = self.broadcasts.iter().map(|b| b.everyone as usize).max().unwrap_or(0);
        for station in 0..self.starts.len().saturating_sub(1).max(unlisted) {
            self.deliver_due(station, |from, message| deliver(station, from, message));
        }
        self.release_due();
    }

    /// Set aside the emissions due at or before `now`, for [`Radio::deliver_due`]. Emissions
    /// sent meanwhile wait for a later call, whatever their delay.
    pub fn take_due(&mut self, now: Instant) {
        self.release_due();
        while self.queue.peek().is_some_and(|Reverse(m)| m.at <= now) {
            let Reverse(m) = self.queue.pop().expect("peeked");
            let e = &self.parked[m.slot];
            if e.everyone > 0 {
                self.broadcasts.push(Broadcast {
                    at: self.due.len() as u32,
                    slot: m.slot as u32,
                    everyone: e.everyone as u32,
                    from_station: e.from_station as u32,
                });
            }
            self.due.push(m.slot);
        }
        // Counting sort of the listed receivers: count, prefix sums, then place (stable:
        // delivery order is kept within each station). Receivers are indices into the callers'
        // station lists: as many as the radio was made for, unless a caller passed a longer
        // list.
        let (due, parked) = (&self.due, &self.parked);
        let starts = &mut self.starts;
        starts.clear();
        starts.resize(self.sent.len() + 1, 0);
        for &e in due {
            for &s in &parked[e].to {
                if s + 1 >= starts.len() {
                    starts.resize(s + 2, 0);
                }
                starts[s + 1] += 1;
            }
        }
        let mut total = 0;
        for start in starts.iter_mut() {
            total += *start;
            *start = total;
        }
        self.by_station.clear();
        self.by_station.resize(total as usize, 0);
        // `starts[s]` serves as station s's next free place while placing: afterwards it is
        // station s + 1's start, so everything shifts back by one.
        for (k, &e) in due.iter().enumerate() {
            for &s in &parked[e].to {
                self.by_station[starts[s] as usize] = k as u32;
                starts[s] += 1;
            }
        }
        starts.rotate_right(1);
        starts[0] = 0;
    }

    /// Hand station `station` its messages among those set aside by [`Radio::take_due`], by
    /// emission in (time, send) order. Stations may be visited in any order, and again (a
    /// second call hands the same messages): a simulator can deliver to, sense and run each
    /// robot in one visit, its node staying in cache, and look at the next robot's messages
    /// beforehand to start loading what they will touch in its node — with a hundred nodes or
    /// more, most of a delivery's cost is fetching the receiving node from memory.
    pub fn deliver_due(&self, station: usize, mut deliver: impl FnMut(NodeId, &Message)) {
        if self.listed(station).is_empty() {
            // Unlisted broadcasts only (BLE's open radio): one short list, no merge.
            for b in self.broadcasts.iter().filter(|b| b.reaches(station)) {
                let (from, message) = self.emission(b.slot as usize);
                deliver(from, message);
            }
            return;
        }
        for (from, message) in self.due_to(station) {
            deliver(from, message);
        }
    }

    /// [`Radio::deliver_due`], each message handed over with the one that will follow it
    /// (same messages, same order): a receiver can start loading what the next message needs
    /// while it applies this one (`NodeCore::prefetch_receive`).
    pub fn deliver_due_ahead(
        &self,
        station: usize,
        mut deliver: impl FnMut((NodeId, &Message), Option<(NodeId, &Message)>),
    ) {
        if self.listed(station).is_empty() {
            // Unlisted broadcasts only: one pass, each message handed over once the one after
            // it is known.
            let mut held: Option<(NodeId, &Message)> = None;
            for b in &self.broadcasts {
                if b.reaches(station) {
                    let this = self.emission(b.slot as usize);
                    if let Some(before) = held {
                        deliver(before, Some(this));
                    }
                    held = Some(this);
                }
            }
            if let Some(last) = held {
                deliver(last, None);
            }
            return;
        }
        let mut list = self.due_to(station).peekable();
        while let Some(this) = list.next() {
            deliver(this, list.peek().copied());
        }
    }

    /// Station `station`'s messages among those set aside by [`Radio::take_due`], as
    /// [`Radio::deliver_due`] hands them over (the same messages in the same order), for a
    /// receiver that takes them all in one call (`NodeCore::receive_all_shared`).
    pub fn due(&self, station: usize) -> impl Iterator<Item = (NodeId, &Message)> + '_ {
        if self.listed(station).is_empty() {
            // Unlisted broadcasts only (BLE's open radio): no merge to make.
            let broadcasts = self.broadcasts.iter().filter(move |b| b.reaches(station));
            Due::Broadcasts(broadcasts.map(|b| self.emission(b.slot as usize)))
        } else {
            Due::Merged(self.due_to(station))
        }
    }

    /// The sender and message of the emission in `slot`, which is due.
    #[inline]
    fn emission(&self, slot: usize) -> (NodeId, &Message) {
        let e = &self.parked[slot];
        (e.from, e.message.as_ref().expect("parked while due"))
    }

    /// Station `station`'s listed messages: their places in `due`, in order.
    #[inline]
    fn listed(&self, station: usize) -> &[u32] {
        match (self.starts.get(station), self.starts.get(station + 1)) {
            (Some(&start), Some(&end)) => &self.by_station[start as usize..end as usize],
            _ => &[],
        }
    }

    /// Station `station`'s messages among those set aside, in delivery order: its listed ones
    /// merged with the unlisted broadcasts that reach it, by their place in `due`.
    #[inline]
    fn due_to(&self, station: usize) -> impl Iterator<Item = (NodeId, &Message)> + '_ {
        let mut listed = self.listed(station).iter().copied().peekable();
        let mut broadcasts = self.broadcasts.iter().filter(move |b| b.reaches(station)).peekable();
        std::iter::from_fn(move || {
            // An emission is listed or unlisted, never both: their places differ.
            let listed_first = match (listed.peek(), broadcasts.peek()) {
                (Some(&k), Some(b)) => k < b.at,
                (Some(_), None) => true,
                (None, Some(_)) => false,
                (None, None) => return None,
            };
            Some(if listed_first {
                self.emission(self.due[listed.next().expect("peeked") as usize])
            } else {
                self.emission(broadcasts.next().expect("peeked").slot as usize)
            })
        })
    }

    /// Free the emissions set aside by [`Radio::take_due`]: every receiver of theirs counts as
    /// delivered (a receiver that died meanwhile is the simulator's to skip).
    pub fn release_due(&mut self) {
        for &slot in &self.due {
            let e = &mut self.parked[slot];
            self.delivered += if e.everyone > 0 { e.everyone as u64 - 1 } else { e.to.len() as u64 };
            e.to.clear();
            e.everyone = 0;
            e.message = None;
            self.free.push(slot);
        }
        self.due.clear();
        self.starts.clear();
        self.by_station.clear();
        self.broadcasts.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ayllu_core::{ControlBody, ControlMessage};

    #[test]
    fn a_port_message_weighs_what_its_one_wire_part_weighs() {
        use ayllu_core::{ConnectionId, ConnectionKind, PortMessage, Value};
        let port = |behavior: &str, kind, value| {
            Message::Port(PortMessage {
                conn: ConnectionId(7),
                seq: 3,
                behavior: Arc::from(behavior),
                port: Arc::from("Eligibility"),
                kind,
                priority: 2,
                value,
            })
        };
        let by_parts = |m: &Message| {
            ayllu_wire::WireMessage::from_core(m, ayllu_wire::DEFAULT_MTU, false)
                .map(|parts| parts.iter().map(|p| ayllu_wire::encoded_len(p).unwrap_or(0) as u64).sum())
                .unwrap_or(0)
        };
        let window = ConnectionKind::Inhibit(Duration::from_millis(500));
        for m in [
            port("OBS1", ConnectionKind::Normal, Value::Float(0.25)),
            port("OBS2", window, Value::Int(-4)),
            port("OBS3", ConnectionKind::Normal, Value::vector(&[1.0, 2.0, 3.0])),
            port("", ConnectionKind::Normal, Value::Bool(true)),
            port(&"B".repeat(300), ConnectionKind::Normal, Value::Float(1.0)),
        ] {
            assert_eq!(wire_len(&m), by_parts(&m), "{m:?}");
        }
    }

    #[test]
    fn a_send_among_live_stations_reaches_whom_a_send_reaches() {
        let stations: Vec<Station> =
            (0..7).map(|i| Station { node: NodeId(i as u32 + 1), x: i as f64, y: 0.0, alive: true }).collect();
        let (peers, odd): (Arc<str>, Arc<str>) = (Arc::from("Peers"), Arc::from("Odd"));
        let build = || {
            let mut r = Radio::new(RadioConfig::default(), stations.len(), 4);
            // Station 3 is in no group; the odd stations are in a second one.
            for i in (0..stations.len()).filter(|&i| i != 3) {
                r.set_groups(i, std::slice::from_ref(&peers));
            }
            for i in (1..stations.len()).step_by(2) {
                r.set_groups(i, std::slice::from_ref(&odd));
            }
            r
        };
        let (mut a, mut b) = (build(), build());
        for (k, from) in [0, 3, 6, 1, 5, 2].into_iter().enumerate() {
            for g in [&peers, &odd] {
                let out = || Outgoing {
                    to: Destination::Group(g.clone()),
                    message: Message::Control(ControlMessage { id: k as u64, body: ControlBody::List }),
                };
                let now = Instant::from_nanos(k as u64 * 1_000_000);
                a.send(now, from, out(), &stations);
                b.send_all_alive(now, from, out(), &stations);
            }
        }
        let drain = |r: &mut Radio| {
            let mut got = Vec::new();
            r.deliver_shared(Instant::from_nanos(1_000_000_000), |to, from, _| got.push((to, from.0)));
            got
        };
        let (x, y) = (drain(&mut a), drain(&mut b));
        assert!(!x.is_empty());
        assert_eq!(x, y);
        assert_eq!((a.delivered, a.cut), (b.delivered, b.cut));
    }

    /// A broadcast to a group of every station, which the open lossless radio hands over
    /// without listing its receivers, reaches whom the listed route reaches, in the same
    /// order at every station, interleaved as before with messages whose receivers are listed
    /// (unicast ones here), whether handed over plainly or one ahead.
    #[test]
    fn an_unlisted_broadcast_reaches_whom_a_listed_one_reaches() {
        let stations: Vec<Station> =
            (0..6).map(|i| Station { node: NodeId(i as u32 + 1), x: i as f64, y: 0.0, alive: true }).collect();
        let peers: Arc<str> = Arc::from("Peers");
        let build = || {
            let mut r = Radio::new(RadioConfig::default(), stations.len(), 9);
            for i in 0..stations.len() {
                r.set_groups(i, std::slice::from_ref(&peers));
            }
            r
        };
        // `a` lists every receiver (`send` does not know that all are alive); `b` does not.
        let (mut a, mut b) = (build(), build());
        for (k, from) in [0, 3, 5, 1, 5, 2, 4, 0].into_iter().enumerate() {
            let now = Instant::from_nanos(k as u64 * 700_000);
            let control = |id: u64| Message::Control(ControlMessage { id, body: ControlBody::List });
            let group = || Outgoing { to: Destination::Group(peers.clone()), message: control(k as u64) };
            let unicast =
                || Outgoing { to: Destination::Node(NodeId((k % 6) as u32 + 1)), message: control(100 + k as u64) };
            a.send(now, from, group(), &stations);
            b.send_all_alive(now, from, group(), &stations);
            a.send(now, from, unicast(), &stations);
            b.send_all_alive(now, from, unicast(), &stations);
        }
        let id = |m: &Message| match m {
            Message::Control(c) => c.id,
            Message::Port(_) => unreachable!("only control messages sent"),
        };
        let heard = |r: &Radio, station: usize| {
            let mut got = Vec::new();
            r.deliver_due(station, |from, m| got.push((from.0, id(m))));
            let mut ahead = Vec::new();
            r.deliver_due_ahead(station, |(from, m), next| {
                ahead.push((from.0, id(m), next.map(|(f, n)| (f.0, id(n)))));
            });
            let plain: Vec<_> = ahead.iter().map(|&(f, m, _)| (f, m)).collect();
            assert_eq!(plain, got, "station {station}: one ahead hands over the same messages");
            let nexts: Vec<_> = ahead.iter().map(|&(.., n)| n).collect();
            let want: Vec<_> = got.iter().skip(1).map(|&x| Some(x)).chain([None]).take(got.len()).collect();
            assert_eq!(nexts, want, "station {station}: each with the one that follows");
            got
        };
        for t in [2_000_000, 4_000_000, 1_000_000_000] {
            a.take_due(Instant::from_nanos(t));
            b.take_due(Instant::from_nanos(t));
            for station in (0..stations.len()).rev() {
                let got = heard(&a, station);
                assert_eq!(heard(&b, station), got, "station {station} at {t} ns");
                let own = |&(from, m): &(u32, u64)| from == station as u32 + 1 && m < 100;
                assert!(!got.iter().any(own), "a sender does not hear its own broadcast");
            }
            a.release_due();
            b.release_due();
        }
        assert!(a.delivered > 0);
        assert_eq!((a.delivered, a.cut, a.lost), (b.delivered, b.cut, b.lost));
        assert_eq!(b.parked.iter().filter(|e| !e.to.is_empty()).count(), 0, "nothing stays listed");
    }

    /// Each station gets every other sender's messages in (time, send) order, whatever order
    /// the stations are visited in and however often.
    #[test]
    fn each_station_gets_its_messages_in_time_order_in_any_visiting_order() {
        let stations: Vec<Station> =
            (0..5).map(|i| Station { node: NodeId(i as u32 + 1), x: i as f64, y: 0.0, alive: true }).collect();
        let peers: Arc<str> = Arc::from("Peers");
        // No jitter: the order is the send time, then the send order.
        let config = RadioConfig { jitter: 0.0, ..RadioConfig::default() };
        let mut r = Radio::new(config, stations.len(), 4);
        for i in 0..stations.len() {
            r.set_groups(i, std::slice::from_ref(&peers));
        }
        // Sender `from` sends `from + 1` messages, message k at k ns: each time's messages
        // were sent in sender order.
        for from in 0..stations.len() {
            for k in 0..=from {
                let out = Outgoing {
                    to: Destination::Group(peers.clone()),
                    message: Message::Control(ControlMessage { id: (from * 10 + k) as u64, body: ControlBody::List }),
                };
                r.send(Instant::from_nanos(k as u64), from, out, &stations);
            }
        }
        r.take_due(Instant::from_nanos(1_000_000_000));
        let id = |m: &Message| match m {
            Message::Control(c) => c.id,
            Message::Port(_) => unreachable!("only control messages sent"),
        };
        let heard = |station: usize| {
            let mut got = Vec::new();
            r.deliver_due(station, |from, m| got.push((from.0, id(m))));
            got
        };
        let want = |station: usize| {
            let mut sent: Vec<(u64, usize)> = (0..stations.len())
                .filter(|&from| from != station)
                .flat_map(|from| (0..=from).map(move |k| (k as u64, from)))
                .collect();
            sent.sort_unstable();
            sent.into_iter().map(|(k, from)| (from as u32 + 1, from as u64 * 10 + k)).collect::<Vec<_>>()
        };
        let forward: Vec<_> = (0..stations.len()).map(heard).collect();
        for (station, got) in forward.iter().enumerate() {
            assert_eq!(got, &want(station), "station {station}");
        }
        for station in (0..stations.len()).rev() {
            assert_eq!(heard(station), forward[station], "station {station} visited again, backwards");
        }
        assert!(heard(stations.len()).is_empty(), "a station no message names gets none");
    }

    /// A caller whose station list is longer than the radio was made for (stations added
    /// later) still has its later stations' messages delivered.
    #[test]
    fn stations_beyond_the_radios_count_get_their_messages() {
        let stations: Vec<Station> =
            (0..4).map(|i| Station { node: NodeId(i as u32 + 1), x: 0.0, y: 0.0, alive: true }).collect();
        let mut r = Radio::new(RadioConfig::default(), 2, 4);
        let out = Outgoing {
            to: Destination::Node(NodeId(4)),
            message: Message::Control(ControlMessage { id: 9, body: ControlBody::List }),
        };
        r.send(Instant::ZERO, 0, out, &stations);
        r.take_due(Instant::from_nanos(1_000_000_000));
        let mut got = Vec::new();
        r.deliver_due(3, |from, _| got.push(from));
        assert_eq!(got, vec![NodeId(1)]);
    }
}
