//! [`Lockstep`]: several nodes on one manual clock, stepped in a fixed order.
//!
//! This is how tests, examples and the simulator run a team deterministically: time moves
//! only by [`Lockstep::advance`], and every node steps once per tick in the order the nodes
//! were added. A message sent in one tick is received in the next step of its receiver.
//! Each team has an in-process network of its own ([`Lockstep::network`]): two teams never
//! share one, whatever their names, so tests running in parallel in one process cannot collide.

use ayllu_core::{Duration, Instant, NodeId};

use crate::clock::ManualClock;
use crate::error::Error;
use crate::mem::MemNetwork;
use crate::node::Node;

/// A deterministic team on virtual time.
///
/// ```
/// use ayllu::*;
/// let mut team = Lockstep::new("demo");
/// for id in 1..=3 {
///     let i = team.add(NodeId(id))?;
///     team.node(i).join("Peers");
/// }
/// team.advance(Duration::from_millis(100), Duration::from_millis(10));
/// assert_eq!(team.now(), Instant::from_millis(100));
/// drop(team.kill(NodeId(2))); // robot 2 dies; the others go on
/// assert_eq!(team.nodes().len(), 2);
/// # Ok::<(), RuntimeError>(())
/// ```
pub struct Lockstep {
    name: String,
    clock: ManualClock,
    nodes: Vec<Node>,
    network: MemNetwork,
}

impl Lockstep {
    /// A team with an in-process network of its own; `name` is for messages only.
    pub fn new(name: &str) -> Lockstep {
        Lockstep { name: name.to_owned(), clock: ManualClock::new(), nodes: Vec::new(), network: MemNetwork::new() }
    }

    /// The name given at creation (for messages).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The team's in-process network, to attach nodes built elsewhere
    /// (`Node::new(team.clock().clone(), team.network().attach(id)?)`).
    pub fn network(&self) -> &MemNetwork {
        &self.network
    }

    /// Add a node with id `id` on the team's network; returns its index.
    pub fn add(&mut self, id: NodeId) -> Result<usize, Error> {
        let node = Node::new(self.clock.clone(), self.network.attach(id)?);
        self.nodes.push(node);
        Ok(self.nodes.len() - 1)
    }

    /// Add a node built elsewhere (any transport); it must use [`Lockstep::clock`] for the
    /// team to stay in step. Returns its index.
    pub fn add_node(&mut self, node: Node) -> usize {
        self.nodes.push(node);
        self.nodes.len() - 1
    }

    /// The team's virtual time.
    pub fn now(&self) -> Instant {
        use crate::clock::Clock;
        self.clock.now()
    }
    /// The team's clock: nodes added with [`Lockstep::add_node`] must use a clone of it.
    pub fn clock(&self) -> &ManualClock {
        &self.clock
    }
    /// The live nodes, in the order they were added.
    pub fn nodes(&self) -> &[Node] {
        &self.nodes
    }
    /// The node at index `i` (the order they were added; indices shift when a node is
    /// killed, so prefer [`Lockstep::node_by_id`] after a kill).
    pub fn node(&mut self, i: usize) -> &mut Node {
        &mut self.nodes[i]
    }
    /// The node with id `id`, if it is in the team.
    pub fn node_by_id(&mut self, id: NodeId) -> Option<&mut Node> {
        self.nodes.iter_mut().find(|n| n.id() == id)
    }
    /// Remove node `id` (as if its robot died): it steps no more and its transport detaches
    /// when the returned node is dropped. `None` if no such node is in the team.
    pub fn kill(&mut self, id: NodeId) -> Option<Node> {
        let i = self.nodes.iter().position(|n| n.id() == id)?;
        Some(self.nodes.remove(i))
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
