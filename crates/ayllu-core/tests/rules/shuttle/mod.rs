//! A tiny in-test transport: moves what each `NodeCore` puts in its outbox to the `receive()` of
//! its destination(s). Group membership is decided here, by the test, exactly as a real
//! transport would decide it (every member except the sender). Nodes marked `down` neither
//! send nor receive, which is how the tests "kill" a node.
#![allow(dead_code)]

use ayllu_core::{Destination, Instant, Message, NodeCore, NodeId, Outgoing};

/// Several nodes, their broadcast groups, and which of them are dead.
pub struct Team {
    pub nodes: Vec<NodeCore>,
    pub groups: Vec<(String, Vec<NodeId>)>,
    pub down: Vec<NodeId>,
    /// Every message delivered so far: (from, to, message).
    pub delivered: Vec<(NodeId, NodeId, Message)>,
}

impl Team {
    /// Nodes with the given ids, no groups.
    pub fn new(ids: &[u32]) -> Team {
        Team {
            nodes: ids.iter().map(|&i| NodeCore::new(NodeId(i))).collect(),
            groups: Vec::new(),
            down: Vec::new(),
            delivered: Vec::new(),
        }
    }

    /// Declare `group` to consist of `members` (the test decides membership).
    pub fn group(&mut self, group: &str, members: &[u32]) {
        self.groups.push((group.to_owned(), members.iter().map(|&i| NodeId(i)).collect()));
    }

    pub fn node(&mut self, id: u32) -> &mut NodeCore {
        self.nodes.iter_mut().find(|n| n.id() == NodeId(id)).expect("node in team")
    }

    pub fn get(&self, id: u32) -> &NodeCore {
        self.nodes.iter().find(|n| n.id() == NodeId(id)).expect("node in team")
    }

    pub fn kill(&mut self, id: u32) {
        self.down.push(NodeId(id));
    }

    fn alive(&self, id: NodeId) -> bool {
        !self.down.contains(&id)
    }

    /// The nodes an outgoing message from `from` reaches.
    pub fn recipients(&self, from: NodeId, to: &Destination) -> Vec<NodeId> {
        match to {
            Destination::Node(n) => vec![*n],
            Destination::Group(g) => self
                .groups
                .iter()
                .filter(|(name, _)| **name == **g)
                .flat_map(|(_, members)| members.iter().copied())
                .filter(|&m| m != from)
                .collect(),
        }
    }

    /// Take every waiting message out of every outbox (dead nodes' outboxes are emptied and
    /// lost).
    pub fn drain(&mut self) -> Vec<(NodeId, Outgoing)> {
        let mut out = Vec::new();
        for n in &mut self.nodes {
            while let Some(m) = n.pop_outgoing() {
                out.push((n.id(), m));
            }
        }
        out.retain(|(from, _)| !self.down.contains(from));
        out
    }

    /// Deliver one outgoing message from `from` at `now` on the receivers' clocks.
    pub fn deliver(&mut self, now: Instant, from: NodeId, out: Outgoing) {
        for to in self.recipients(from, &out.to) {
            if !self.alive(to) {
                continue;
            }
            if let Some(n) = self.nodes.iter_mut().find(|n| n.id() == to) {
                n.receive(now, from, out.message.clone());
                self.delivered.push((from, to, out.message.clone()));
            }
        }
    }

    /// Move messages until every outbox is empty; returns how many were moved.
    pub fn shuttle(&mut self, now: Instant) -> usize {
        let mut moved = 0;
        for _ in 0..1_000 {
            let batch = self.drain();
            if batch.is_empty() {
                return moved;
            }
            moved += batch.len();
            for (from, out) in batch {
                self.deliver(now, from, out);
            }
        }
        panic!("messages kept flowing for 1000 rounds");
    }

    /// Lockstep: poll every live node at `now`, then shuttle at `now`.
    pub fn step(&mut self, now: Instant) {
        let down = self.down.clone();
        for n in &mut self.nodes {
            if !down.contains(&n.id()) {
                n.poll(now);
            }
        }
        self.shuttle(now);
    }
}
