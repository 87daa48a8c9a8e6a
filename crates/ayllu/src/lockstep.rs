//! [`Lockstep`]: several nodes on one manual clock, stepped in a fixed order.
//!
//! This is how tests, examples and the simulator run a team deterministically: time moves
//! only by [`Lockstep::advance`], and every node steps once per tick in the order the nodes
//! were added. A message sent in one tick is received in the next step of its receiver.

use ayllu_core::{Duration, Instant, NodeId};

use crate::clock::ManualClock;
use crate::error::Error;
use crate::node::Node;

/// A deterministic team on virtual time.
pub struct Lockstep {
    clock: ManualClock,
    nodes: Vec<Node>,
    url: String,
}

impl Lockstep {
    /// A team whose nodes will share the in-process network `mem://name`.
    pub fn new(name: &str) -> Lockstep {
        Lockstep { clock: ManualClock::new(), nodes: Vec::new(), url: format!("mem://{name}") }
    }

    /// Add a node with id `id`; returns its index.
    pub fn add(&mut self, id: NodeId) -> Result<usize, Error> {
        let node = Node::open_with_clock(id, &self.url, self.clock.clone())?;
        self.nodes.push(node);
        Ok(self.nodes.len() - 1)
    }

    /// Add a node built elsewhere (any transport); it must use [`Lockstep::clock`] for the
    /// team to stay in step. Returns its index.
    pub fn add_node(&mut self, node: Node) -> usize {
        self.nodes.push(node);
        self.nodes.len() - 1
    }

    pub fn now(&self) -> Instant {
        use crate::clock::Clock;
        self.clock.now()
    }
    pub fn clock(&self) -> &ManualClock {
        &self.clock
    }
    pub fn nodes(&self) -> &[Node] {
        &self.nodes
    }
    pub fn node(&mut self, i: usize) -> &mut Node {
        &mut self.nodes[i]
    }
    /// Remove a node (as if its robot died); its transport detaches.
    pub fn kill(&mut self, i: usize) -> Node {
        self.nodes.remove(i)
    }

    /// Step every node once at the current time.
    pub fn step(&mut self) {
        for n in &mut self.nodes {
            n.step();
        }
    }

    /// Move time forward by `total` in ticks of `tick`, stepping every node each tick.
    pub fn advance(&mut self, total: Duration, tick: Duration) {
        let end = self.now() + total;
        while self.now() < end {
            let step = tick.min(end - self.now());
            self.clock.advance(step);
            self.step();
        }
    }
}
