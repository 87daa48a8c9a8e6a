//! `mem://` — an in-process transport between nodes of one program.
//!
//! Delivery is immediate, lossless and in order, so tests and the deterministic examples
//! built on it are reproducible: a message sent during one node's step is received at the
//! receiver's next step. Groups deliver to members in node-id order, never to the sender.
//! A node whose transport is dropped is reported lost to the others at their next step
//! (the in-process counterpart of N6 liveness).
//! The network is shared behind a mutex, so nodes may also run on separate threads.
//!
//! Nodes attach to a [`MemNetwork`] made by hand or found by name (`mem://team` in every
//! node of the program reaches the same network, so two parts of one program that pick the
//! same name share it; a network made with [`MemNetwork::new`], as [`crate::Lockstep`] does,
//! is private to whoever holds it).

use std::collections::{BTreeMap, BTreeSet, HashMap, VecDeque};
use std::sync::{Arc, Condvar, Mutex, OnceLock};

use ayllu_core::{Destination, Message, NodeId, Outgoing};

use crate::error::Error;
use crate::transport::{Sent, Transport, TransportEvent};

type Inbox = Arc<(Mutex<VecDeque<(NodeId, Message)>>, Condvar)>;

#[derive(Default)]
struct Hub {
    inboxes: BTreeMap<NodeId, Inbox>,
    /// Per attached node, the nodes that detached since it last asked: in one program a
    /// detached node is gone for certain, so peers release what it held at once (D3.7).
    lost: BTreeMap<NodeId, Vec<NodeId>>,
    groups: BTreeMap<String, BTreeSet<NodeId>>,
    /// Messages addressed to a node that is not attached.
    undeliverable: u64,
    delivered: u64,
}

/// An in-process network. Cheap to clone; clones are the same network.
#[derive(Clone, Default)]
pub struct MemNetwork {
    hub: Arc<Mutex<Hub>>,
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    // A panic in another thread holding the lock leaves plain data behind; keep going.
    m.lock().unwrap_or_else(|e| e.into_inner())
}

impl MemNetwork {
    /// A private network: only transports attached to this value (or its clones) share it.
    pub fn new() -> MemNetwork {
        MemNetwork::default()
    }

    /// The network called `name` in this program, made on first use.
    pub fn named(name: &str) -> MemNetwork {
        static NETWORKS: OnceLock<Mutex<HashMap<String, MemNetwork>>> = OnceLock::new();
        let mut all = lock(NETWORKS.get_or_init(Default::default));
        all.entry(name.to_owned()).or_default().clone()
    }

    /// Attach node `id`; the returned transport detaches it when dropped.
    pub fn attach(&self, id: NodeId) -> Result<MemTransport, Error> {
        let mut hub = lock(&self.hub);
        if hub.inboxes.contains_key(&id) {
            return Err(Error::DuplicateNode { node: id });
        }
        let inbox: Inbox = Arc::default();
        hub.inboxes.insert(id, inbox.clone());
        hub.lost.insert(id, Vec::new());
        Ok(MemTransport { id, network: self.clone(), inbox })
    }

    /// (delivered, undeliverable) message counts.
    pub fn stats(&self) -> (u64, u64) {
        let hub = lock(&self.hub);
        (hub.delivered, hub.undeliverable)
    }

    /// Deliver at once; a message to a node that is not attached is dropped (in one program
    /// there is nobody to wait for: a node attaches before it can be written to).
    fn deliver(&self, from: NodeId, out: Outgoing) -> Sent {
        let mut hub = lock(&self.hub);
        match out.to {
            Destination::Node(to) => match hub.inboxes.get(&to).cloned() {
                Some(inbox) => {
                    push(&inbox, from, out.message);
                    hub.delivered += 1;
                    Sent::Now
                }
                None => {
                    hub.undeliverable += 1;
                    Sent::Dropped
                }
            },
            Destination::Group(group) => {
                let members: Vec<NodeId> =
                    hub.groups.get(&*group).map(|g| g.iter().copied().collect()).unwrap_or_default();
                for to in members.into_iter().filter(|&n| n != from) {
                    if let Some(inbox) = hub.inboxes.get(&to).cloned() {
                        push(&inbox, from, out.message.clone());
                        hub.delivered += 1;
                    }
                }
                // A group with no other member now is not an error: nobody is listening.
                Sent::Now
            }
        }
    }
}

fn push(inbox: &Inbox, from: NodeId, message: Message) {
    let (queue, ready) = &**inbox;
    lock(queue).push_back((from, message));
    ready.notify_all();
}

/// One node's attachment to a [`MemNetwork`].
pub struct MemTransport {
    id: NodeId,
    network: MemNetwork,
    inbox: Inbox,
}

impl Transport for MemTransport {
    fn local(&self) -> NodeId {
        self.id
    }
    fn send(&mut self, out: Outgoing) -> Sent {
        self.network.deliver(self.id, out)
    }
    fn recv(&mut self) -> Option<(NodeId, Message)> {
        lock(&self.inbox.0).pop_front()
    }
    fn wait(&mut self, timeout: std::time::Duration) {
        let (queue, ready) = &*self.inbox;
        let q = lock(queue);
        if q.is_empty() {
            let _ = ready.wait_timeout(q, timeout);
        }
    }
    fn join(&mut self, group: &str) {
        lock(&self.network.hub).groups.entry(group.to_owned()).or_default().insert(self.id);
    }
    fn leave(&mut self, group: &str) {
        if let Some(g) = lock(&self.network.hub).groups.get_mut(group) {
            g.remove(&self.id);
        }
    }
    fn take_events(&mut self, out: &mut Vec<TransportEvent>) {
        if let Some(lost) = lock(&self.network.hub).lost.get_mut(&self.id) {
            out.extend(lost.drain(..).map(TransportEvent::PeerLost));
        }
    }
}

/// How many departures a node that never steps may have waiting (older ones are dropped).
const LOST_MAX: usize = 1024;

impl Drop for MemTransport {
    fn drop(&mut self) {
        let mut hub = lock(&self.network.hub);
        hub.inboxes.remove(&self.id);
        hub.lost.remove(&self.id);
        for g in hub.groups.values_mut() {
            g.remove(&self.id);
        }
        for lost in hub.lost.values_mut() {
            if lost.len() < LOST_MAX {
                lost.push(self.id);
            }
        }
    }
}
