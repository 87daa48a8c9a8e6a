//! The transport's counts by cause (`datagrams_sent`, `replayed`, `admission_limited`, ...),
//! as [`Transport::counters`](crate::Transport::counters) reports them. A tally is updated for
//! every datagram and message, so it is built to be cheap on that path; every count also moves
//! the transport's generation, which tells the node the counts changed.

use crate::datagram::DatagramSocket;

use super::UdpTransport;

/// Counters by cause, in name order. There are a dozen causes, and the traffic ones are
/// counted for every datagram and message: a short vector searched by pointer first (callers
/// pass the same `&'static str`) is cheaper than a map keyed by string comparison, and the
/// three counted on every turn with traffic ([`Hot`]) are found by an index kept up to date.
pub(super) struct Tally(pub(super) Vec<(&'static str, u64)>, pub(super) Names, [usize; HOT_NAMES.len()]);

/// How many times a cause was added to a [`Tally`]: its list of names changes only then.
pub(super) type Names = u64;

/// The causes counted for every datagram or turn of traffic.
#[derive(Clone, Copy)]
pub(super) enum Hot {
    DatagramsSent,
    DatagramsReceived,
    MessagesSent,
}

/// The names of [`Hot`]'s causes, in its order.
const HOT_NAMES: [&str; 3] = ["datagrams_sent", "datagrams_received", "messages_sent"];

impl Default for Tally {
    fn default() -> Tally {
        Tally(Vec::new(), 0, [usize::MAX; HOT_NAMES.len()])
    }
}

impl Tally {
    pub(super) fn add(&mut self, cause: &'static str) {
        self.add_n(cause, 1);
    }
    /// Count a hot cause: an index, not a search (its position once it is in the list).
    pub(super) fn add_hot(&mut self, cause: Hot, n: u64) {
        match self.0.get_mut(self.2[cause as usize]) {
            Some(entry) => entry.1 += n,
            None => self.add_n(HOT_NAMES[cause as usize], n),
        }
    }
    pub(super) fn add_n(&mut self, cause: &'static str, n: u64) {
        if let Some(entry) = self.0.iter_mut().find(|(name, _)| std::ptr::eq(*name, cause)) {
            entry.1 += n;
            return;
        }
        match self.0.binary_search_by(|(name, _)| (*name).cmp(cause)) {
            Ok(i) => self.0[i].1 += n,
            Err(i) => {
                self.0.insert(i, (cause, n));
                self.1 += 1;
                // The insertion moved the names after it: find the hot ones again (rare: once
                // per cause over the transport's life).
                for (slot, name) in self.2.iter_mut().zip(HOT_NAMES) {
                    *slot = self.0.binary_search_by(|(have, _)| (*have).cmp(name)).unwrap_or(usize::MAX);
                }
            }
        }
    }
}

impl<S: DatagramSocket> UdpTransport<S> {
    pub(super) fn count(&mut self, cause: &'static str) {
        self.counters.add(cause);
        self.generation += 1;
    }

    pub(super) fn count_hot(&mut self, cause: Hot, n: u64) {
        self.counters.add_hot(cause, n);
        self.generation += 1;
    }
}
