//! Replay marks kept across restarts (D-N5.3): with `state=`, the newest datagram number of
//! every keyed sender and the newest signed request id of every requester are written to a
//! file at most once a second, and when the transport is dropped, and read back at start, so a
//! restarted node refuses datagrams and requests captured before it stopped. Saving is atomic
//! (a temporary file renamed over the old one); a crash loses at most the last second's marks.

use std::collections::BTreeMap;

use ayllu_core::{Duration, Instant, NodeId};
use ayllu_wire::ReplayWindow;

use crate::datagram::DatagramSocket;
use crate::transport::TransportEvent;

use super::admit::MAX_REPLAY_SENDERS;
use super::UdpTransport;

/// Replay high-water marks as saved in a state file: datagram numbers by sender (`NODE SEQ`
/// lines) and signed request ids by requester (`op NODE ID` lines), each restored as a window
/// that accepts only newer numbers.
#[derive(Default)]
pub(super) struct Marks {
    pub(super) datagrams: BTreeMap<NodeId, (ReplayWindow, Instant)>,
    pub(super) requests: BTreeMap<NodeId, ReplayWindow>,
}

/// The marks saved in `path`. A missing file is a first start; unreadable lines are skipped
/// with a warning.
pub(super) fn load_marks(path: &std::path::Path, warnings: &mut Vec<String>) -> Marks {
    let mut marks = Marks::default();
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return marks,
        Err(e) => {
            warnings.push(format!("cannot read replay marks from {}: {e}", path.display()));
            return marks;
        }
    };
    let mut bad = 0;
    for line in text.lines().take(MAX_REPLAY_SENDERS + crate::operator::MAX_REQUESTERS) {
        let (signed, line) = match line.strip_prefix("op ") {
            Some(rest) => (true, rest),
            None => (false, line),
        };
        let mut parts = line.split_whitespace();
        match (parts.next().and_then(|n| n.parse().ok()), parts.next().and_then(|q| q.parse().ok())) {
            (Some(n), Some(seq)) if signed => {
                marks.requests.insert(NodeId(n), ReplayWindow::after(seq));
            }
            (Some(n), Some(seq)) => {
                marks.datagrams.insert(NodeId(n), (ReplayWindow::after(seq), Instant::ZERO));
            }
            _ => bad += 1,
        }
    }
    if bad > 0 {
        warnings.push(format!("{bad} unreadable lines in replay marks {} were skipped", path.display()));
    }
    marks
}

impl<S: DatagramSocket> Drop for UdpTransport<S> {
    /// A node that stops cleanly saves its replay marks now (a crash loses at most the last
    /// second's: D-N5.3).
    fn drop(&mut self) {
        self.next_save = Instant::ZERO;
        let now = self.now;
        self.save_marks(now);
    }
}

impl<S: DatagramSocket> UdpTransport<S> {
    /// Write the newest accepted number of every sender to `config.state`, atomically (a
    /// temporary file renamed over the old one), if they changed and a second has passed.
    pub(super) fn save_marks(&mut self, now: Instant) {
        // Checked before the path is copied: this runs every turn.
        let signed_dirty = self.operator.as_ref().is_some_and(|g| g.dirty);
        if !(self.replay_dirty || signed_dirty) || now < self.next_save {
            return;
        }
        let Some(path) = self.config.state.clone() else { return };
        self.replay_dirty = false;
        self.next_save = now + Duration::from_secs(1);
        let mut text: String =
            self.replay.iter().filter_map(|(n, w)| w.window.newest().map(|seq| format!("{} {seq}\n", n.0))).collect();
        if let Some(gate) = &mut self.operator {
            gate.dirty = false;
            text.extend(gate.marks().map(|(n, id)| format!("op {} {id}\n", n.0)));
        }
        let tmp = path.with_extension("tmp");
        let saved = std::fs::write(&tmp, text).and_then(|()| std::fs::rename(&tmp, &path));
        match saved {
            Ok(()) => self.count("state_saved"),
            Err(e) => {
                self.count("state_error");
                if !self.state_warned {
                    self.state_warned = true;
                    self.events.push(TransportEvent::Warning(format!(
                        "cannot save replay marks to {}: {e}; a restart may accept replayed datagrams",
                        path.display()
                    )));
                }
            }
        }
    }
}
