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
//! * Each entry holds the name strings it compares addresses against ([`Incoming::behavior`])
//!   itself, in the line's last 8 bytes ([`SeqTable::hold`]), and lets go of them when it
//!   takes others or is cleared. (A list of every pair ever held, kept beside the table, was
//!   one more cold line for every port resolved, and grew, copied, on every node of a team at
//!   once.) How many pairs were held since the table was last cleared is counted all the same
//!   ([`SeqTable::held`]): it is N1's bound on re-pointing (docs/semantics.md, D10.2).

use std::hash::BuildHasher;
use std::sync::atomic::{AtomicPtr, AtomicU16, AtomicU32, AtomicU64, AtomicUsize, Ordering::Relaxed};
use std::sync::Arc;

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
    /// port, so it skips comparing strings. The entry holds those `Arc`s itself for as long as
    /// it compares against them ([`SeqTable::hold`]), so their addresses cannot be reused for
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

/// The sequence table's key for connection `conn` of node `from`.
pub(crate) fn incoming_key(from: NodeId, conn: ConnectionId) -> IncomingKey {
    IncomingKey { node: u64::from(from.0), conn: conn.0 }
}

/// One entry of the sequence table: one whole cache line (the table is allocated at the
/// entry's alignment), the first cold load of every message received. The table hands out its
/// entries by shared reference, so the state ([`Incoming`]) is kept in atomics, read and
/// written `Relaxed` (plain loads and stores): it changes only under `&mut NodeCore`, and
/// atomics, unlike a `Cell`, leave the node `Sync`. The key of a filled slot never changes.
///
/// The name strings (`behavior`, `port`: their addresses, 0 for none) are the entry's own
/// strong references, taken by [`SeqTable::hold`] with `Arc::into_raw` and given back by
/// [`SeqEntry::let_go`] (on a new pair, on clearing, on drop), which only `&mut` reaches; with
/// their lengths in the line's last 8 bytes, holding them costs no line beyond the entry.
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
    /// The lengths of the strings `behavior` and `port` hold (meaningless while they are 0).
    behavior_len: u32,
    port_len: u32,
}

// The names' lengths fill the line the entry took already: holding the names costs no line.
const _: () = assert!(std::mem::size_of::<SeqEntry>() == 64);

impl SeqEntry {
    /// A connection heard for the first time: its newest sequence number, no port resolved and
    /// no names held.
    pub(crate) fn new(key: IncomingKey, newest: u64) -> SeqEntry {
        SeqEntry {
            key,
            newest: AtomicU64::new(newest),
            behavior: AtomicUsize::new(0),
            port: AtomicUsize::new(0),
            b: AtomicU32::new(0),
            p: AtomicU16::new(0),
            epoch: AtomicU16::new(0),
            target: AtomicPtr::new(std::ptr::null_mut()),
            behavior_len: 0,
            port_len: 0,
        }
    }

    /// A free slot.
    fn empty() -> SeqEntry {
        SeqEntry::new(IncomingKey { node: EMPTY, conn: 0 }, 0)
    }

    /// Give back the name strings this entry holds, if any: its addresses become 0 (no port
    /// resolved by address).
    #[inline]
    fn let_go(&mut self) {
        if *self.behavior.get_mut() != 0 {
            self.give_back();
        }
    }

    /// [`SeqEntry::let_go`] of an entry that holds names. Out of line: inlined, the drop glue
    /// of the slot an insert overwrites made the receive path, into which the insert is
    /// inlined, about 10 instructions a message dearer (`speed callgrind 100 10`).
    #[cold]
    #[inline(never)]
    fn give_back(&mut self) {
        let (behavior, port) = (std::mem::take(self.behavior.get_mut()), std::mem::take(self.port.get_mut()));
        for (address, len) in [(behavior, self.behavior_len), (port, self.port_len)] {
            let raw = std::ptr::slice_from_raw_parts(address as *const u8, len as usize) as *const str;
            // SAFETY: a non-zero `behavior` (and with it `port`) is only ever stored by
            // `SeqTable::hold`, as `Arc::into_raw` of a clone of an `Arc<str>` of exactly `len`
            // bytes, a strong reference the entry owns; only this function, which zeroes both
            // before returning and is reached through `&mut self` only, gives it back. So each
            // reference is taken back exactly once, with the pointer and length it was made
            // from.
            drop(unsafe { Arc::from_raw(raw) });
        }
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

    /// Remember the port (slot `b`, port `p`, at address `target`) the connection's messages
    /// resolve to, valid while the node's removal count is `epoch`. The names it compares
    /// against are [`SeqTable::hold`]'s to change.
    pub(crate) fn set_port(&self, b: u32, p: u16, epoch: u16, target: *mut PortState) {
        self.b.store(b, Relaxed);
        self.p.store(p, Relaxed);
        self.epoch.store(epoch, Relaxed);
        self.target.store(target, Relaxed);
    }
}

impl Drop for SeqEntry {
    fn drop(&mut self) {
        self.let_go();
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
    /// Entries, and name pairs held since the table was last cleared ([`SeqTable::held`]), in
    /// 32 bits each (the node bounds both far below, N1), so that the count takes no room in
    /// the node's hot lines beyond the word `len` had.
    len: u32,
    held: u32,
    hasher: foldhash::fast::RandomState,
}

impl SeqTable {
    pub(crate) fn new() -> SeqTable {
        SeqTable { slots: Vec::new(), len: 0, held: 0, hasher: foldhash::fast::RandomState::default() }
    }

    pub(crate) fn len(&self) -> usize {
        self.len as usize
    }

    /// How many name pairs [`SeqTable::hold`] took since the table was last cleared (or its
    /// names forgotten), those let go of since included: the node bounds it as it bounds the
    /// entries, so that a sender re-pointing one connection id without end clears the table as
    /// one inventing ids does (docs/semantics.md, D10.2).
    pub(crate) fn held(&self) -> usize {
        self.held as usize
    }

    /// Make `key`'s entry (if there is one) hold `behavior` and `port` and compare against
    /// their addresses ([`Incoming::behavior`]), letting go of the pair it held before; counted
    /// in [`SeqTable::held`]. Strings whose length does not fit 32 bits are not held: the entry
    /// then compares against none, and its next message resolves its port by name again.
    pub(crate) fn hold(&mut self, key: &IncomingKey, behavior: &Arc<str>, port: &Arc<str>) {
        let Some(i) = self.index(key, self.hash(key)) else { return };
        let entry = &mut self.slots[i];
        entry.let_go();
        let (Ok(behavior_len), Ok(port_len)) = (u32::try_from(behavior.len()), u32::try_from(port.len())) else {
            return;
        };
        entry.behavior_len = behavior_len;
        entry.port_len = port_len;
        // The addresses `into_raw` gives are the strings' own (`Arc::as_ptr`), the ones
        // messages are compared by; `let_go` takes the references back.
        *entry.behavior.get_mut() = Arc::into_raw(behavior.clone()).cast::<u8>() as usize;
        *entry.port.get_mut() = Arc::into_raw(port.clone()).cast::<u8>() as usize;
        self.held += 1;
    }

    /// Every entry forgets the names its port was resolved from and lets go of them (its next
    /// message resolves its port by name); [`SeqTable::held`] starts again from 0.
    pub(crate) fn forget_names(&mut self) {
        for entry in &mut self.slots {
            entry.let_go();
        }
        self.held = 0;
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
        self.probe(key, hash).map(|(_, entry)| entry)
    }

    /// The slot of `key`, whose [`SeqTable::hash`] is `hash`, if the table holds it.
    fn index(&self, key: &IncomingKey, hash: u64) -> Option<usize> {
        self.probe(key, hash).map(|(i, _)| i)
    }

    /// The linear probe for `key` from its home slot: the slot and the entry, so that a caller
    /// wanting the entry does not index the slots again (a second bounds check and about 10
    /// instructions on every message received).
    #[inline(always)]
    fn probe(&self, key: &IncomingKey, hash: u64) -> Option<(usize, &SeqEntry)> {
        if self.slots.is_empty() {
            return None;
        }
        let mask = self.slots.len() - 1;
        let mut i = hash as usize & mask;
        loop {
            let entry = &self.slots[i];
            if entry.key == *key {
                return Some((i, entry));
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

    /// Add a new entry for `key` (which the table does not hold) with no port resolved:
    /// [`SeqTable::insert`] kept out of the receive path, into which it was inlined, entry,
    /// drop glue and all, at about 8 instructions a message (`speed callgrind 100 10`).
    #[inline(never)]
    pub(crate) fn enter(&mut self, key: IncomingKey, newest: u64) {
        self.insert(SeqEntry::new(key, newest));
    }

    /// Add `entry`, whose key the table does not hold (the caller looked it up first).
    pub(crate) fn insert(&mut self, entry: SeqEntry) {
        debug_assert!(self.get(&entry.key).is_none(), "a key is inserted once");
        if (self.len() + 1) * 4 > self.slots.len() * 3 {
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

    /// Forget every entry and let go of the names they held (N1's bound); the slots are kept
    /// for what comes next.
    pub(crate) fn clear(&mut self) {
        for entry in &mut self.slots {
            entry.let_go();
            entry.key.node = EMPTY;
        }
        self.len = 0;
        self.held = 0;
    }

    /// Every entry, in no particular order.
    #[cfg(any(test, feature = "serde"))]
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
        SeqEntry::new(IncomingKey { node, conn }, newest)
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

    /// An entry holds one reference to each name string it compares against, and gives it
    /// back when it takes other names, when its names are forgotten, when the table is cleared
    /// and when the table is dropped; every pair taken is counted until the table is cleared.
    #[test]
    fn held_names_are_given_back_once() {
        let names = |b: &str, p: &str| (Arc::<str>::from(b), Arc::<str>::from(p));
        let counts = |n: &(Arc<str>, Arc<str>)| (Arc::strong_count(&n.0), Arc::strong_count(&n.1));
        let (a, b) = (names("A", "In"), names("B", "Out"));
        let (k1, k2) = (IncomingKey { node: 1, conn: 1 }, IncomingKey { node: 2, conn: 1 });
        let mut t = SeqTable::new();
        t.hold(&k1, &a.0, &a.1);
        assert_eq!((counts(&a), t.held()), ((1, 1), 0), "no entry, nothing held");
        t.insert(entry(1, 1, 1));
        t.insert(entry(2, 1, 1));
        t.hold(&k1, &a.0, &a.1);
        t.hold(&k2, &a.0, &a.1);
        assert_eq!((counts(&a), t.held()), ((3, 3), 2));
        let address = |t: &SeqTable, k: &IncomingKey| t.get(k).map(|e| (e.get().behavior, e.get().port));
        let of = |n: &(Arc<str>, Arc<str>)| {
            (Arc::as_ptr(&n.0).cast::<u8>() as usize, Arc::as_ptr(&n.1).cast::<u8>() as usize)
        };
        assert_eq!(address(&t, &k1), Some(of(&a)), "compared by the strings' own addresses");
        t.hold(&k1, &b.0, &b.1);
        assert_eq!((counts(&a), counts(&b), t.held()), ((2, 2), (2, 2), 3), "re-pointed: the old pair let go");
        assert_eq!(address(&t, &k1), Some(of(&b)));
        // Growing moves the entries with what they hold.
        for c in 10..100 {
            t.insert(entry(3, c, 1));
        }
        assert_eq!((counts(&a), counts(&b), address(&t, &k2)), ((2, 2), (2, 2), Some(of(&a))));
        t.forget_names();
        assert_eq!((counts(&a), counts(&b), t.held(), address(&t, &k1)), ((1, 1), (1, 1), 0, Some((0, 0))));
        t.hold(&k1, &a.0, &a.1);
        t.hold(&k2, &b.0, &b.1);
        t.clear();
        assert_eq!((counts(&a), counts(&b), t.held(), t.len()), ((1, 1), (1, 1), 0, 0));
        t.insert(entry(1, 1, 1));
        t.hold(&k1, &a.0, &a.1);
        assert_eq!(counts(&a), (2, 2));
        drop(t);
        assert_eq!(counts(&a), (1, 1), "dropped with the table");
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
