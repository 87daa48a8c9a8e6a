//! Arbitration windows on a port: suppression, inhibition, write-inhibition and overrides
//! (rule S6), and the two questions every message asks of them.
//!
//! * [`Windows::admit_write`] — may this *connection* write the port now? (Suppress blocks
//!   every connection; OverrideIn blocks every connection but its pass holders.)
//! * [`Windows::admit_propagation`] — may the value just written leave the port along its
//!   outgoing connections? (Inhibit blocks all; OverrideOut blocks all but values that arrived
//!   along a pass holder; WriteInhibit blocks the behavior's own writes.)
//!
//! Windows are keyed by (kind, holder). Arriving again *refreshes*: `end := max(end, t + p)`,
//! never shortened. Expired windows are simply ignored and their slots reused, so a port that
//! is arbitrated steadily stops allocating after its first windows.

use crate::address::Source;
use crate::counters::DropCause;
use crate::time::Instant;

/// Which effect a window has.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum WindowKind {
    /// Opened by a Suppress connection: no connection may write the port, pass holders included
    /// (D6.4); the behavior's own writes still may (D6.5).
    Suppress,
    /// Opened by an Inhibit connection: nothing propagates out of the port, pass holders
    /// included; what arrives is still stored (D6.4, D6.6).
    Inhibit,
    /// Opened by a WriteInhibit connection (a BLE claim, S11): the behavior's own writes are
    /// stored but do not propagate; values arriving along connections still do.
    WriteInhibit,
    /// The holder has the only pass to *write* the port.
    OverrideIn,
    /// Values arriving along the holder are the only ones that *propagate*.
    OverrideOut,
}

impl WindowKind {
    /// The kind as reports and `ayllu why` print it (`override-in`).
    pub fn name(self) -> &'static str {
        match self {
            WindowKind::Suppress => "suppress",
            WindowKind::Inhibit => "inhibit",
            WindowKind::WriteInhibit => "write-inhibit",
            WindowKind::OverrideIn => "override-in",
            WindowKind::OverrideOut => "override-out",
        }
    }
}

/// One active (or expired) window.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Window {
    /// What the window blocks.
    pub kind: WindowKind,
    /// The connection that opened it (and holds the pass, for overrides).
    pub holder: Source,
    /// When the window closes, on this node's clock: it is open while `now < end`. Refreshed by
    /// its holder's messages, never shortened (D6.1).
    pub end: Instant,
}

/// Where a value being written into a port came from.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Origin {
    /// A process of the port's own behavior (or the application, on its behalf).
    Internal,
    /// A message along a connection.
    Connection(Source),
}

/// The windows of one port. Usually empty; checks on an empty set are a single branch.
///
/// One word (boxed, allocated by the first window), not a `Vec`'s three: a port's windows sit
/// in the port's first cache line with what every message reads (`crate::node::PortState`).
#[derive(Clone, Debug, Default)]
pub struct Windows {
    // The box is the point: one word in the port, the `Vec` behind it only once a window opens.
    #[allow(clippy::box_collection)]
    list: Option<Box<Vec<Window>>>,
}

impl Windows {
    /// Whether no window was ever opened here (or every one was forgotten): expired windows
    /// still count, since their slots are kept for reuse.
    pub fn is_empty(&self) -> bool {
        self.list.as_ref().is_none_or(|l| l.is_empty())
    }

    fn list(&self) -> &[Window] {
        self.list.as_deref().map_or(&[], Vec::as_slice)
    }

    /// Open or refresh the (kind, holder) window to last at least until `end`.
    pub fn refresh(&mut self, now: Instant, kind: WindowKind, holder: Source, end: Instant) {
        let list = self.list.get_or_insert_with(Box::default);
        let mut free = None;
        for (i, w) in list.iter_mut().enumerate() {
            if w.kind == kind && w.holder == holder {
                w.end = w.end.max(end);
                return;
            }
            if w.end <= now && free.is_none() {
                free = Some(i);
            }
        }
        let w = Window { kind, holder, end };
        match free {
            Some(i) => list[i] = w,
            None => list.push(w),
        }
    }

    /// May a connection write from `by` be stored now?
    #[inline]
    pub fn admit_write(&self, now: Instant, by: Source) -> Result<(), DropCause> {
        if self.is_empty() {
            return Ok(());
        }
        let mut overridden = false;
        let mut has_pass = false;
        for w in self.list() {
            if w.end <= now {
                continue;
            }
            match w.kind {
                WindowKind::Suppress => return Err(DropCause::Suppressed),
                WindowKind::OverrideIn => {
                    overridden = true;
                    has_pass |= w.holder == by;
                }
                _ => {}
            }
        }
        if overridden && !has_pass {
            return Err(DropCause::OverriddenIn);
        }
        Ok(())
    }

    /// May a value that was just stored, coming from `origin`, propagate out now?
    #[inline]
    pub fn admit_propagation(&self, now: Instant, origin: Origin) -> Result<(), DropCause> {
        if self.is_empty() {
            return Ok(());
        }
        let mut overridden = false;
        let mut has_pass = false;
        let mut write_inhibited = false;
        for w in self.list() {
            if w.end <= now {
                continue;
            }
            match w.kind {
                WindowKind::Inhibit => return Err(DropCause::Inhibited),
                WindowKind::OverrideOut => {
                    overridden = true;
                    has_pass |= origin == Origin::Connection(w.holder);
                }
                WindowKind::WriteInhibit => write_inhibited = true,
                _ => {}
            }
        }
        if overridden && !has_pass {
            return Err(DropCause::OverriddenOut);
        }
        if write_inhibited && origin == Origin::Internal {
            return Err(DropCause::WriteInhibited);
        }
        Ok(())
    }

    /// The windows still open at `now`, soonest-ending first.
    pub fn active(&self, now: Instant) -> Vec<Window> {
        let mut v: Vec<Window> = self.list().iter().copied().filter(|w| w.end > now).collect();
        v.sort_by_key(|w| (w.end, w.kind, w.holder));
        v
    }

    /// The latest end of any open window: when this port will next be free.
    pub fn next_end(&self, now: Instant) -> Option<Instant> {
        self.list().iter().filter(|w| w.end > now).map(|w| w.end).max()
    }

    /// Forget windows held by a connection that has been removed.
    pub fn forget_holder(&mut self, holder: Source) {
        if let Some(list) = &mut self.list {
            list.retain(|w| w.holder != holder);
        }
    }
}
