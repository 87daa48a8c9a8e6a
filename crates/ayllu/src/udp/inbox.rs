//! The inbox: the messages a turn received and has not handed to the node yet, in the order
//! they came, and the places of the ones it has handed over, kept for the next datagram.
//!
//! Why the places are kept: a flow's datagrams look alike (the same connections, to the same
//! ports), so the next datagram's port messages are decoded into the places the last one's
//! took (`ayllu_wire::MessageSink::port_place`): no message is moved in or dropped, and a
//! place that already holds the names a message carries keeps them, where a new message took
//! a reference to each name from the name cache and dropped it once applied. What a kept place
//! holds is bounded by what one refill put in the inbox (it reads until one datagram put
//! something there: at most one datagram's messages, 8 KiB of values at most, besides the
//! messages that waited for the checks); a control message's place is emptied once handed
//! over, so a large reply does not stay.

use ayllu_core::{ControlBody, ControlMessage, Message, NodeId, PortMessage};

/// Messages received and not handed over yet: `places[head..end]`, oldest first; the places
/// after `end` are free, holding what was handed over before (or refused).
#[derive(Default)]
pub(super) struct Inbox {
    places: Vec<(NodeId, Message)>,
    head: usize,
    end: usize,
}

/// What a handed-over control message's place holds: nothing allocated.
fn empty_place() -> (NodeId, Message) {
    (NodeId(0), Message::Control(ControlMessage { id: 0, body: ControlBody::List }))
}

impl Inbox {
    pub(super) fn is_empty(&self) -> bool {
        self.head == self.end
    }

    /// Where the next message goes: a mark to [`Inbox::truncate`] back to.
    pub(super) fn end(&self) -> usize {
        self.end
    }

    /// Take back the messages from `mark` (an [`Inbox::end`]) on: a refused datagram's.
    pub(super) fn truncate(&mut self, mark: usize) {
        self.end = mark.clamp(self.head, self.end);
    }

    pub(super) fn push_back(&mut self, from: NodeId, message: Message) {
        match self.places.get_mut(self.end) {
            Some(place) => *place = (from, message),
            None => self.places.push((from, message)),
        }
        self.end += 1;
    }

    /// The next free place, if it holds a port message, for the next one to be decoded into
    /// (then [`Inbox::commit`]).
    #[inline(always)]
    pub(super) fn port_place(&mut self) -> Option<&mut PortMessage> {
        match self.places.get_mut(self.end) {
            Some((_, Message::Port(p))) => Some(p),
            _ => None,
        }
    }

    /// The message decoded into [`Inbox::port_place`] came from `from` and waits now.
    #[inline(always)]
    pub(super) fn commit(&mut self, from: NodeId) {
        if let Some(place) = self.places.get_mut(self.end) {
            place.0 = from;
            self.end += 1;
        }
    }

    /// The oldest message, moved out (its place keeps nothing).
    pub(super) fn pop_front(&mut self) -> Option<(NodeId, Message)> {
        if self.is_empty() {
            return None;
        }
        let taken = std::mem::replace(&mut self.places[self.head], empty_place());
        self.head += 1;
        if self.head == self.end {
            (self.head, self.end) = (0, 0);
        }
        Some(taken)
    }

    /// Hand `f` each message where it lies, oldest first, then empty the inbox; port messages'
    /// places are kept for the next datagram, control messages' emptied.
    #[inline(always)]
    pub(super) fn each_then_empty(&mut self, mut f: impl FnMut(NodeId, &Message)) {
        for place in &mut self.places[self.head..self.end] {
            f(place.0, &place.1);
            if matches!(place.1, Message::Control(_)) {
                *place = empty_place();
            }
        }
        (self.head, self.end) = (0, 0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ayllu_core::{ConnectionId, ConnectionKind, Value};

    fn port(seq: u64) -> Message {
        Message::Port(PortMessage {
            conn: ConnectionId(1),
            seq,
            behavior: "R".into(),
            port: "In".into(),
            kind: ConnectionKind::Normal,
            priority: 0,
            value: Value::Int(0),
        })
    }

    fn seqs(inbox: &mut Inbox) -> Vec<u64> {
        let mut got = Vec::new();
        inbox.each_then_empty(|_, m| {
            got.push(match m {
                Message::Port(p) => p.seq,
                Message::Control(c) => c.id,
            })
        });
        got
    }

    /// Messages come out in order whichever way they went in (pushed, or decoded into a kept
    /// place), a truncated tail does not come out, and a place is offered only once free.
    #[test]
    fn places_are_reused_in_order() {
        let mut inbox = Inbox::default();
        assert!(inbox.port_place().is_none(), "nothing to reuse yet");
        inbox.push_back(NodeId(1), port(1));
        inbox.push_back(NodeId(1), Message::Control(ControlMessage { id: 2, body: ControlBody::List }));
        inbox.push_back(NodeId(1), port(3));
        assert!(inbox.port_place().is_none(), "no free place");
        assert_eq!(seqs(&mut inbox), [1, 2, 3]);
        // The first place is a port's: decoded into, from another sender.
        inbox.port_place().expect("a port message's place").seq = 4;
        inbox.commit(NodeId(7));
        // The second was a control message's: emptied, not offered.
        assert!(inbox.port_place().is_none());
        let mark = inbox.end();
        inbox.push_back(NodeId(7), port(5));
        inbox.truncate(mark);
        assert_eq!(inbox.end(), 1, "the refused message is taken back");
        let mut from = Vec::new();
        inbox.each_then_empty(|f, _| from.push(f));
        assert_eq!(from, [NodeId(7)]);
        inbox.push_back(NodeId(1), port(6));
        inbox.push_back(NodeId(1), port(7));
        assert_eq!(inbox.pop_front().map(|(_, m)| m), Some(port(6)));
        assert_eq!(seqs(&mut inbox), [7]);
        assert!(inbox.is_empty() && inbox.pop_front().is_none());
    }
}
