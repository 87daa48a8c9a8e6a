//! Asking another node a question and waiting for the answer: [`Node::ask`] and
//! [`Node::await_answer`], the request client of every tool (the CLI's `ayllu why`, `read`,
//! `list`, `connect`...) and of programs that want the same.
//!
//! What it promises:
//! * The wait runs the node as usual (it receives, sends, runs its processes and resends the
//!   request every 200 ms, N2), so a node that asks keeps behaving while it waits.
//! * It ends, always: when the answer comes, when the request fails (the receiver refused it,
//!   or 25 sends went unanswered, or the transport could not send it at all), when the
//!   deadline passes, or when the caller's `stop` says so (Ctrl-C in a tool).
//! * A finished request is forgotten by the core as it is returned (`take_answer`), so a
//!   program that asks forever holds nothing for the requests it has had answered.
//! * It waits on the node's own clock in real time; a node on virtual time (a
//!   [`ManualClock`](crate::ManualClock), [`Lockstep`](crate::Lockstep)) is stepped by its owner,
//!   who follows [`NodeCore::request_status`](ayllu_core::NodeCore::request_status) instead, and
//!   is refused here rather than left waiting for a time that never comes.
//!
//! Programs that keep several requests in flight at once (transactions, the Foxglove watcher)
//! drive their own loop and collect with `NodeCore::take_answer`, the same rule one call down.

use std::fmt;
use std::time::{Duration as StdDuration, Instant as StdInstant};

use ayllu_core::{ControlBody, NodeId, ReplyBody, RequestId};

use crate::node::Node;

/// How long the node runs between checks of the answer. Arrivals wake it earlier; this only
/// bounds how late a check can be (and how late `stop` is noticed).
const SLICE: StdDuration = StdDuration::from_millis(10);

/// Why a question got no answer.
#[derive(Debug, Clone, PartialEq)]
pub enum AskError {
    /// The request could not be sent (the core refused it: for instance a node asking itself).
    NotSent(ayllu_core::Error),
    /// The asked node refused it (its error text, e.g. the rule that refused it), or it went
    /// unanswered for every resend, or the transport could not send it.
    Failed(String),
    /// The deadline passed first; whether the asked node was still heard (its HELLOs) then.
    TimedOut {
        /// The asked node was in the peer table when the wait gave up: alive but not
        /// answering, rather than gone silent.
        heard: bool,
    },
    /// The caller's `stop` said to give up.
    Stopped,
    /// The node is on virtual time, where waiting for an answer would never end.
    VirtualTime,
}

impl fmt::Display for AskError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AskError::NotSent(e) => write!(f, "not sent: {e}"),
            AskError::Failed(why) => write!(f, "{why}"),
            AskError::TimedOut { heard: true } => write!(f, "no answer in time (it is alive: HELLO heard)"),
            AskError::TimedOut { heard: false } => write!(f, "no answer in time (it has gone silent)"),
            AskError::Stopped => write!(f, "interrupted before the answer"),
            AskError::VirtualTime => {
                write!(f, "the node is on virtual time: step it and follow request_status instead of waiting")
            }
        }
    }
}

impl std::error::Error for AskError {}

impl Node {
    /// Send control request `body` to `node` and run this node until the answer comes, or
    /// `timeout` passes (see the module docs for every way it ends).
    ///
    /// ```no_run
    /// use ayllu::{ControlBody, Node, NodeId, ReplyBody};
    /// let mut tool = Node::open(NodeId(0x7fff_0001), "udp://0.0.0.0:0?discovery=239.255.0.1:7400")?;
    /// match tool.ask(NodeId(2), ControlBody::List, std::time::Duration::from_secs(3)) {
    ///     Ok(ReplyBody::Node(report)) => println!("{} behaviors", report.behaviors.len()),
    ///     Ok(other) => println!("unexpected: {other:?}"),
    ///     Err(e) => println!("n2: {e}"),
    /// }
    /// # Ok::<(), ayllu::RuntimeError>(())
    /// ```
    pub fn ask(&mut self, node: NodeId, body: ControlBody, timeout: StdDuration) -> Result<ReplyBody, AskError> {
        if !self.is_real_time() {
            return Err(AskError::VirtualTime);
        }
        let id = self.core_mut().request(node, body).map_err(AskError::NotSent)?;
        self.await_answer(node, id, Some(StdInstant::now() + timeout), &mut || false)
    }

    /// Run this node until request `id` (sent to `node`, e.g. by
    /// [`NodeCore::request_connect`](ayllu_core::NodeCore::request_connect)) is answered or
    /// fails, `deadline` passes (`None`: no deadline) or `stop()` returns true.
    pub fn await_answer(
        &mut self,
        node: NodeId,
        id: RequestId,
        deadline: Option<StdInstant>,
        stop: &mut dyn FnMut() -> bool,
    ) -> Result<ReplyBody, AskError> {
        if !self.is_real_time() {
            return Err(AskError::VirtualTime);
        }
        loop {
            if let Some(answer) = self.core_mut().take_answer(id) {
                return answer.map_err(AskError::Failed);
            }
            if stop() {
                return Err(AskError::Stopped);
            }
            let now = StdInstant::now();
            if deadline.is_some_and(|d| now >= d) {
                return Err(AskError::TimedOut { heard: self.peers().iter().any(|p| p.node == node) });
            }
            self.run_for(deadline.map_or(SLICE, |d| SLICE.min(d - now)));
        }
    }
}
