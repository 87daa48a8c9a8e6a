//! The sequence table (rule N1): for each (sender, connection) a node has heard, the newest
//! sequence number it applied and the port that connection's messages resolved to.
//!
//! Open addressing with linear probing over entries of one cache line each, every entry
//! holding its own key: a lookup that finds its entry in its home slot reads one cache line.
//! A table with separate control bytes (hashbrown's, used before) reads two lines one after
//! the other, the control group and then the bucket, and those two dependent misses were the
//! hottest stall of a simulated team's deliveries (`docs/performance.md`).
//!
//! What it promises:
//! * At most three quarters full, so every probe ends at an empty slot.
//! * Entries are never removed one by one, only all together ([`SeqTable::clear`], N1's
//!   bound), so probing needs no tombstones.
//! * The hash is seeded per table (foldhash, from the process's random state), so a sender
//!   cannot choose connection ids that collide; a flood of new ids is bounded by N1's limit,
//!   which the node enforces by clearing the table.
//! * Lookups never allocate; an insert allocates only when the table doubles.

use std::hash::BuildHasher;
use std::sync::atomic::{AtomicPtr, AtomicU16, AtomicU32, AtomicU64, AtomicUsize, Ordering::Relaxed};

use crate::address::{ConnectionId, NodeId};
use crate::node::PortState;

/// What the node knows of one incoming connection (sender, connection id): the newest sequence
/// number applied (N1), and the port its last message was applied to, so that the next message
/// needs no name lookups. The names each message carries are still checked against that port,
/// since a sender may reuse a connection id.
///
/// 40 bytes, so that with its 16-byte key an entry of the table fits one cache line
/// ([`SeqEntry`]), where it took 80 bytes over two: the entry is the first cold load of every
/// message received.
#[derive(Copy, Clone)]
pub(crate) struct Incoming {
    pub(crate) newest: u64,
    /// The addresses of the name strings (`Arc<str>`) the message that resolved the port
    /// carried (0: no port resolved): a message carrying the same `Arc`s (the sender's
    /// connection shares them among its messages, e.g. in-process transports) names the same
    /// port, so it skips comparing strings. Those `Arc`s are held in `NodeCore::held_names` for
    /// as long as this entry may compare against them, so their addresses cannot be reused for
    /// other names meanwhile.
    pub(crate) behavior: usize,
    pub(crate) port: usize,
    /// The port: behavior slot and port index...
    pub(crate) b: u32,
    pub(crate) p: u16,
    /// ...valid while `NodeCore::removals` (as 16 bits) is this: no behavior was removed since,
    /// so slot `b` still holds the behavior it was resolved to (a slot is reused only after a
    /// removal). Names never change while a behavior lives.
    pub(crate) epoch: u16,
    /// The port itself (port `p` of slot `b`), so that a delivery reaches its line without
    /// reading the behavior's first (`NodeCore::deliver_to`); valid exactly when `b` and `p`
    /// are (null while unresolved).
    pub(crate) target: *mut PortState,
}

impl Incoming {
    /// A connection heard for the first time: its newest sequence number, no port resolved.
    pub(crate) fn unresolved(newest: u64) -> Incoming {
        Incoming { newest, behavior: 0, port: 0, b: 0, p: 0, epoch: 0, target: std::ptr::null_mut() }
    }
}

/// The sequence table's key for connection `conn` of node `from`.
pub(crate) fn incoming_key(from: NodeId, conn: ConnectionId) -> IncomingKey {
    IncomingKey { node: u64::from(from.0), conn: conn.0 }
}

/// One entry of the sequence table: one whole cache line (the table is allocated at the
/// entry's alignment), the first cold load of every message received. The table hands out its
/// entries by shared reference, so the state ([`Incoming`]) is kept in atomics, read and
/// written `Relaxed` (plain loads and stores): it changes only under `&mut NodeCore`, and
/// atomics, unlike a `Cell`, leave the node `Sync`. The key of a filled slot never changes.
#[repr(C, align(64))]
pub(crate) struct SeqEntry {
    key: IncomingKey,
    pub(crate) newest: AtomicU64,
    behavior: AtomicUsize,
    port: AtomicUsize,
    b: AtomicU32,
    p: AtomicU16,
    pub(crate) epoch: AtomicU16,
    target: AtomicPtr<PortState>,
}

impl SeqEntry {
    pub(crate) fn new(key: IncomingKey, i: Incoming) -> SeqEntry {
        SeqEntry {
            key,
            newest: AtomicU64::new(i.newest),
            behavior: AtomicUsize::new(i.behavior),
            port: AtomicUsize::new(i.port),
            b: AtomicU32::new(i.b),
            p: AtomicU16::new(i.p),
            epoch: AtomicU16::new(i.epoch),
            target: AtomicPtr::new(i.target),
        }
    }

    /// A free slot.
    fn empty() -> SeqEntry {
        SeqEntry::new(IncomingKey { node: EMPTY, conn: 0 }, Incoming::unresolved(0))
    }

    pub(crate) fn get(&self) -> Incoming {
        Incoming {
            newest: self.newest.load(Relaxed),
            behavior: self.behavior.load(Relaxed),
            port: self.port.load(Relaxed),
            b: self.b.load(Relaxed),
            p: self.p.load(Relaxed),
            epoch: self.epoch.load(Relaxed),
            target: self.target.load(Relaxed),
        }
    }

    pub(crate) fn set(&self, i: Incoming) {
        self.newest.store(i.newest, Relaxed);
        self.behavior.store(i.behavior, Relaxed);
        self.port.store(i.port, Relaxed);
        self.b.store(i.b, Relaxed);
        self.p.store(i.p, Relaxed);
        self.epoch.store(i.epoch, Relaxed);
        self.target.store(i.target, Relaxed);
    }
}

/// A (sender, connection) pair, hashed in one piece as one 128-bit integer (a tuple is hashed
/// field by field, which costs more on every message received), but aligned to 8 bytes, not
/// 16: a `u128` key would pad every bucket of the table to a multiple of 16 bytes.
#[derive(Copy, Clone, PartialEq, Eq)]
pub(crate) struct IncomingKey {
    node: u64,
    conn: u64,
}

impl std::hash::Hash for IncomingKey {
    fn hash<H: std::hash::Hasher>(&self, state: &mut H) {
        state.write_u128((u128::from(self.node) << 64) | u128::from(self.conn));
    }
}

/// A slot's key while it holds no entry: node ids are 32-bit, so no key has this node.
const EMPTY: u64 = u64::MAX;
/// The fewest slots a table that holds anything has (1 KiB).
const MIN_SLOTS: usize = 16;

/// The table itself: see the module docs.
pub(crate) struct SeqTable {
    /// A power of two of them, or none before the first insert.
    slots: Vec<SeqEntry>,
    len: usize,
    hasher: foldhash::fast::RandomState,
}

impl SeqTable {
    pub(crate) fn new() -> SeqTable {
        SeqTable { slots: Vec::new(), len: 0, hasher: foldhash::fast::RandomState::default() }
    }

    pub(crate) fn len(&self) -> usize {
        self.len
    }

    /// The home slot of `key` in a table of `mask + 1` slots.
    #[inline(always)]
    fn home(&self, key: &IncomingKey, mask: usize) -> usize {
        self.hash(key) as usize & mask
    }

    /// What `key` hashes to in this table (its hasher is seeded once, when the table is made,
    /// and never changes, so a hash stays good through inserts, growth and clearing): for a
    /// caller that both hints a lookup ([`SeqTable::prefetch_hashed`]) and makes it
    /// ([`SeqTable::get_hashed`]), which then hashes once.
    #[inline(always)]
    pub(crate) fn hash(&self, key: &IncomingKey) -> u64 {
        self.hasher.hash_one(key)
    }

    /// The entry of `key`, if there is one: this runs for every message received.
    #[inline(always)]
    pub(crate) fn get(&self, key: &IncomingKey) -> Option<&SeqEntry> {
        self.get_hashed(key, self.hash(key))
    }

    /// [`SeqTable::get`] with the key's [`SeqTable::hash`] already made.
    #[inline(always)]
    pub(crate) fn get_hashed(&self, key: &IncomingKey, hash: u64) -> Option<&SeqEntry> {
        if self.slots.is_empty() {
            return None;
        }
        let mask = self.slots.len() - 1;
        let mut i = hash as usize & mask;
        loop {
            let entry = &self.slots[i];
            if entry.key == *key {
                return Some(entry);
            }
            if entry.key.node == EMPTY {
                return None;
            }
            i = (i + 1) & mask;
        }
    }

    /// Ask the processor to start loading the port `key`'s entry remembers (its first three
    /// lines: what a delivery reads and writes), reading the entry itself: call once its slot
    /// has had time to arrive ([`SeqTable::prefetch`] a while before). A hint: nothing changes,
    /// and a stale or null address only wastes the hint.
    #[inline(always)]
    pub(crate) fn prefetch_target(&self, key: &IncomingKey) {
        let Some(entry) = self.get(key) else { return };
        let target = entry.target.load(Relaxed);
        if !target.is_null() {
            crate::prefetch::lines(target, 3);
        }
    }

    /// Ask the processor to start loading `key`'s home slot (a hint: nothing else changes), so
    /// that a lookup a little later finds the line on its way.
    #[inline(always)]
    pub(crate) fn prefetch(&self, key: &IncomingKey) {
        self.prefetch_hashed(self.hash(key));
    }

    /// [`SeqTable::prefetch`] of the key whose [`SeqTable::hash`] is `hash`.
    #[inline(always)]
    pub(crate) fn prefetch_hashed(&self, hash: u64) {
        if self.slots.is_empty() {
            return;
        }
        // In bounds: masked by the length, a power of two.
        crate::prefetch::line(&self.slots[hash as usize & (self.slots.len() - 1)]);
    }

    /// Add `entry`, whose key the table does not hold (the caller looked it up first).
    pub(crate) fn insert(&mut self, entry: SeqEntry) {
        debug_assert!(self.get(&entry.key).is_none(), "a key is inserted once");
        if (self.len + 1) * 4 > self.slots.len() * 3 {
            self.grow();
        }
        self.place(entry);
        self.len += 1;
    }

    /// Put `entry` in the first empty slot from its home (there is one: at most 3/4 full).
    fn place(&mut self, entry: SeqEntry) {
        let mask = self.slots.len() - 1;
        let mut i = self.home(&entry.key, mask);
        while self.slots[i].key.node != EMPTY {
            i = (i + 1) & mask;
        }
        self.slots[i] = entry;
    }

    /// Twice the slots (at least [`MIN_SLOTS`]), every entry placed again.
    #[cold]
    fn grow(&mut self) {
        let slots = (self.slots.len() * 2).max(MIN_SLOTS);
        let old = std::mem::replace(&mut self.slots, (0..slots).map(|_| SeqEntry::empty()).collect());
        for entry in old {
            if entry.key.node != EMPTY {
                self.place(entry);
            }
        }
    }

    /// Forget every entry (N1's bound); the slots are kept for what comes next.
    pub(crate) fn clear(&mut self) {
        for entry in &mut self.slots {
            entry.key.node = EMPTY;
        }
        self.len = 0;
    }

    /// Every entry, in no particular order.
    pub(crate) fn iter(&self) -> impl Iterator<Item = &SeqEntry> {
        self.slots.iter().filter(|e| e.key.node != EMPTY)
    }

    /// Every (sender, connection, newest sequence number), sorted: what a checkpoint keeps of
    /// the table (the resolved ports are caches, found again by the next message).
    #[cfg(feature = "serde")]
    pub(crate) fn newest(&self) -> Vec<(u32, u64, u64)> {
        let mut all: Vec<(u32, u64, u64)> = self
            .iter()
            .map(|e| (u32::try_from(e.key.node).unwrap_or(u32::MAX), e.key.conn, e.newest.load(Relaxed)))
            .collect();
        all.sort_unstable();
        all
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::collections::HashMap;

    fn entry(node: u64, conn: u64, newest: u64) -> SeqEntry {
        SeqEntry::new(IncomingKey { node, conn }, Incoming::unresolved(newest))
    }

    /// Keys that share a home slot (the table's own hash, one of them chosen, the rest found
    /// by search) are all found, wherever probing put them, through growth and after clear.
    #[test]
    fn colliding_keys_are_found_through_growth_and_clear() {
        let mut t = SeqTable::new();
        assert!(t.get(&IncomingKey { node: 1, conn: 1 }).is_none(), "an empty table finds nothing");
        t.insert(entry(1, 1, 10));
        let mask = t.slots.len() - 1;
        let home = t.home(&IncomingKey { node: 1, conn: 1 }, mask);
        let same: Vec<u64> =
            (2..).filter(|&c| t.home(&IncomingKey { node: 1, conn: c }, mask) == home).take(8).collect();
        for (n, &c) in same.iter().enumerate() {
            t.insert(entry(1, c, 100 + n as u64));
        }
        for (n, &c) in same.iter().enumerate() {
            let e = t.get(&IncomingKey { node: 1, conn: c }).expect("a colliding key is found");
            assert_eq!(e.get().newest, 100 + n as u64);
        }
        // Grow past several doublings; every key stays found.
        for c in 1000..1500 {
            t.insert(entry(2, c, c));
        }
        assert_eq!(t.len(), 509);
        assert!(t.len() * 4 <= t.slots.len() * 3, "at most three quarters full");
        assert_eq!(t.iter().count(), 509);
        assert!((1000..1500).all(|c| t.get(&IncomingKey { node: 2, conn: c }).is_some_and(|e| e.get().newest == c)));
        assert_eq!(t.get(&IncomingKey { node: 1, conn: 1 }).map(|e| e.get().newest), Some(10));
        let slots = t.slots.len();
        t.clear();
        assert_eq!((t.len(), t.iter().count(), t.slots.len()), (0, 0, slots), "cleared, slots kept");
        assert!(t.get(&IncomingKey { node: 2, conn: 1200 }).is_none());
        t.insert(entry(2, 1200, 7));
        assert_eq!(t.get(&IncomingKey { node: 2, conn: 1200 }).map(|e| e.get().newest), Some(7));
    }

    proptest! {
        /// The table answers as a map would, over any mix of inserts of new keys, lookups,
        /// updates through the entry and clears.
        #[test]
        fn the_table_answers_as_a_map(ops in proptest::collection::vec((0u8..10, 0u64..40, 0u64..40, any::<u64>()), 0..400)) {
            let mut t = SeqTable::new();
            let mut model: HashMap<(u64, u64), u64> = HashMap::new();
            for (op, node, conn, v) in ops {
                let key = IncomingKey { node, conn };
                match op {
                    0 => { t.clear(); model.clear(); }
                    1..=5 => {
                        if let Some(e) = t.get(&key) {
                            e.newest.store(v, Relaxed);
                            *model.get_mut(&(node, conn)).expect("the model has it too") = v;
                        } else {
                            prop_assert!(!model.contains_key(&(node, conn)));
                            t.insert(entry(node, conn, v));
                            model.insert((node, conn), v);
                        }
                    }
                    _ => prop_assert_eq!(t.get(&key).map(|e| e.get().newest), model.get(&(node, conn)).copied()),
                }
                prop_assert_eq!(t.len(), model.len());
            }
            prop_assert_eq!(t.iter().count(), model.len());
        }
    }
}
