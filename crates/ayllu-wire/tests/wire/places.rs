//! A `MessageSink` that keeps its port messages' places from datagram to datagram, as the UDP
//! transport's inbox does (`MessageSink::port_place`): the reference the property test
//! `decoding_into_kept_places_is_decoding` and the `decode_datagram` fuzz target (which
//! includes this file by path) decode into, and compare with `decode`.

use std::sync::Arc;

use ayllu_core::PortMessage;
use ayllu_wire::{MessageSink, WireMessage};

/// The first `used` places hold this datagram's port messages, the rest earlier ones'; `got`
/// is what this datagram gave, in order.
#[derive(Default)]
pub struct Places {
    places: Vec<PortMessage>,
    used: usize,
    pub got: Vec<WireMessage>,
}

impl Places {
    /// Start the next datagram: its port messages go into the places from the first on.
    pub fn next_datagram(&mut self) {
        self.used = 0;
        self.got.clear();
    }

    fn keep(&mut self, message: PortMessage, group: Option<Arc<str>>) {
        self.got.push(match group {
            Some(group) => WireMessage::GroupPort { group, message: message.clone() },
            None => WireMessage::Port(message.clone()),
        });
        match self.places.get_mut(self.used) {
            Some(place) => *place = message,
            None => self.places.push(message),
        }
        self.used += 1;
    }
}

impl MessageSink for Places {
    fn port(&mut self, message: PortMessage, group: Option<Arc<str>>) {
        self.keep(message, group);
    }
    fn other(&mut self, message: WireMessage) {
        self.got.push(message);
    }
    fn port_place(&mut self) -> Option<&mut PortMessage> {
        self.places.get_mut(self.used)
    }
    fn port_placed(&mut self, group: Option<Arc<str>>) {
        let message = self.places[self.used].clone();
        self.keep(message, group);
    }
}
