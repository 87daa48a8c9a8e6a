//! What leaves in a turn, and how: messages for one address share datagrams up to the MTU
//! (N3), and at the end of the turn a turn's datagrams for one address leave in one system
//! call when their sizes allow ([`Train`]: UDP GSO on Linux, D-N3.3). The bytes on the wire
//! are exactly those of separate sends; buffers of sent datagrams are kept for the next turn,
//! so a turn allocates nothing to send.

use std::net::SocketAddr;

use ayllu_core::PortMessage;
use ayllu_wire::{DatagramWriter, EncodeError, PortTemplates, WireMessage};

use crate::datagram::DatagramSocket;
use crate::transport::TransportEvent;

use super::counters::Hot;
use super::peers::discovery_warning;
use super::UdpTransport;

/// Sent datagrams' buffers kept for reuse (one per destination of a turn is plenty).
const SPARE_BUFFERS: usize = 8;
/// Datagrams sent as one train at most (the kernel's limit on UDP GSO segments was 64 before
/// Linux 6.6), and bytes in one train at most (one IPv4 UDP payload, with room to spare).
const TRAIN_DATAGRAMS: usize = 64;
const TRAIN_BYTES: usize = 65_000;

/// A turn's finished datagrams for one address, back to back, that leave together at the end
/// of the turn ([`Transport::flush`](crate::Transport::flush)) in one system call (`DatagramSocket::send_segments`:
/// UDP GSO on Linux): each is `segment` bytes long but the last, which may be shorter, so the
/// kernel cuts the train into the very same datagrams. A datagram that does not fit this shape
/// sends the train before it at once and starts the next. The bytes on the wire are those of
/// separate sends; only the number of system calls changes (docs/performance.md).
pub(super) struct Train {
    to: SocketAddr,
    bytes: Vec<u8>,
    segment: usize,
    count: usize,
    /// A shorter datagram ended it: nothing more may follow.
    closed: bool,
}

impl Train {
    /// Whether a datagram of `len` bytes may follow in this train.
    fn takes(&self, len: usize) -> bool {
        !self.closed && len <= self.segment && self.count < TRAIN_DATAGRAMS && self.bytes.len() + len <= TRAIN_BYTES
    }
}

impl<S: DatagramSocket> UdpTransport<S> {
    fn writer(&mut self) -> DatagramWriter {
        let buf = self.spare.pop().unwrap_or_default();
        let w = DatagramWriter::with_buffer(buf, self.config.team, self.id, self.seq, self.config.key, self.config.mtu);
        self.seq += 1;
        w
    }

    /// Append a message to the open datagram for `addr`; a full datagram is finished and queued
    /// for the end of the turn.
    pub(super) fn push(&mut self, addr: SocketAddr, message: &WireMessage) {
        self.push_with(addr, |w, _| w.push(message));
    }

    /// [`UdpTransport::push`] for a port message, encoded from the core's own message and the
    /// connection's template (the same bytes, [`PortTemplates`]).
    pub(super) fn push_port(&mut self, addr: SocketAddr, message: &PortMessage, group: Option<&str>) {
        self.push_with(addr, |w, templates| w.push_port_with(templates, message, group));
    }

    /// Add one message, written by `encode`, to the turn's datagram for `addr`; a full datagram
    /// leaves and the message starts the next.
    #[inline(always)]
    fn push_with(
        &mut self,
        addr: SocketAddr,
        encode: impl Fn(&mut DatagramWriter, &mut PortTemplates) -> Result<(), EncodeError>,
    ) {
        let i = match self.batches.iter().position(|(a, _)| *a == addr) {
            Some(i) => i,
            None => {
                let w = self.writer();
                self.batches.push((addr, w));
                self.batches.len() - 1
            }
        };
        match encode(&mut self.batches[i].1, &mut self.templates) {
            Ok(()) => {}
            Err(EncodeError::DoesNotFit { .. }) => {
                let fresh = self.writer();
                let full = std::mem::replace(&mut self.batches[i].1, fresh);
                self.transmit(addr, full);
                if encode(&mut self.batches[i].1, &mut self.templates).is_err() {
                    self.count("too_large");
                }
            }
            Err(EncodeError::TooLarge { .. }) | Err(EncodeError::ReportTooLarge { .. }) => self.count("too_large"),
            Err(EncodeError::Invalid(_)) => self.count("unencodable"),
        }
    }

    /// Finish `w` and queue it to leave at the end of the turn with the turn's other datagrams
    /// for `addr`, in one system call when their sizes allow (see [`Train`]).
    pub(super) fn transmit(&mut self, addr: SocketAddr, w: DatagramWriter) {
        if w.is_empty() {
            return;
        }
        let bytes = w.finish();
        let len = bytes.len();
        if let Some(i) = self.trains.iter().position(|t| t.to == addr) {
            if self.trains[i].takes(len) {
                let train = &mut self.trains[i];
                train.bytes.extend_from_slice(&bytes);
                train.count += 1;
                train.closed = len < train.segment;
                self.keep_buffer(bytes);
                return;
            }
            // Sizes or room do not allow: what is queued leaves now, in order, and a new train
            // starts with this datagram.
            let full = self.trains.swap_remove(i);
            self.send_train(full);
        }
        self.trains.push(Train { to: addr, bytes, segment: len, count: 1, closed: false });
    }

    /// Send a train's datagrams: one `send_to`, or one `send_segments` for several.
    pub(super) fn send_train(&mut self, train: Train) {
        let Train { to, bytes, segment, count, .. } = train;
        let sent =
            if count == 1 { self.socket.send_to(&bytes, to) } else { self.socket.send_segments(&bytes, segment, to) };
        match sent {
            Ok(()) => self.count_hot(Hot::DatagramsSent, count as u64),
            Err(e) => {
                self.count("send_error");
                if Some(to) == self.config.discovery && !self.discovery_failed {
                    self.discovery_failed = true;
                    self.events.push(TransportEvent::Warning(discovery_warning(&self.config, &e.to_string())));
                }
            }
        }
        self.keep_buffer(bytes);
    }

    /// Keep a sent datagram's buffer for the next ones: a loop turn then allocates nothing to
    /// send.
    fn keep_buffer(&mut self, bytes: Vec<u8>) {
        if self.spare.len() < SPARE_BUFFERS {
            self.spare.push(bytes);
        }
    }
}
