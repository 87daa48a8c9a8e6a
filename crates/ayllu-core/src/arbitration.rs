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

use std::fmt;

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
/// The box holds the first window itself, the others spilled behind it, so that a port with
/// one window (a BLE claim's WriteInhibit) reads one line behind the port, not the `Vec`'s
/// header and then its buffer: two dependent misses on every refresh of a cold port.
#[derive(Clone, Default)]
pub struct Windows {
    list: Option<Box<Set>>,
}

/// The windows, in the order a plain list would hold them: `first`, then `more`.
#[derive(Clone)]
#[repr(C, align(64))]
struct Set {
    first: Window,
    more: Vec<Window>,
}

impl Set {
    fn iter(&self) -> impl Iterator<Item = &Window> {
        std::iter::once(&self.first).chain(self.more.iter())
    }
}

/// A port's windows as a checkpoint holds them: the list, in its order.
#[cfg(feature = "serde")]
impl serde::Serialize for Windows {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(self.iter())
    }
}

#[cfg(feature = "serde")]
impl<'de> serde::Deserialize<'de> for Windows {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Windows, D::Error> {
        let mut list = <Vec<Window> as serde::Deserialize>::deserialize(d)?.into_iter();
        Ok(Windows { list: list.next().map(|first| Box::new(Set { first, more: list.collect() })) })
    }
}

impl fmt::Debug for Windows {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let list: Option<Vec<Window>> = self.list.as_ref().map(|s| s.iter().copied().collect());
        f.debug_struct("Windows").field("list", &list).finish()
    }
}

impl Windows {
    /// Whether no window was ever opened here (or every one was forgotten): expired windows
    /// still count, since their slots are kept for reuse.
    pub fn is_empty(&self) -> bool {
        self.list.is_none()
    }

    fn iter(&self) -> impl Iterator<Item = &Window> {
        self.list.iter().flat_map(|s| s.iter())
    }

    /// The windows as two slices (`first`, then `more`): two plain loops where a chained
    /// iterator tested which half it was in at every step.
    fn parts(&self) -> [&[Window]; 2] {
        match &self.list {
            Some(s) => [std::slice::from_ref(&s.first), &s.more],
            None => [&[], &[]],
        }
    }

    /// Open or refresh the (kind, holder) window to last at least until `end`.
    pub fn refresh(&mut self, now: Instant, kind: WindowKind, holder: Source, end: Instant) {
        let w = Window { kind, holder, end };
        let Some(set) = self.list.as_mut() else {
            self.list = Some(Box::new(Set { first: w, more: Vec::new() }));
            return;
        };
        // The first expired slot (0: `first`, i + 1: `more[i]`) is reused.
        let mut free = None;
        let first = &mut set.first;
        if first.kind == kind && first.holder == holder {
            first.end = first.end.max(end);
            return;
        }
        if first.end <= now {
            free = Some(0);
        }
        for (i, x) in set.more.iter_mut().enumerate() {
            if x.kind == kind && x.holder == holder {
                x.end = x.end.max(end);
                return;
            }
            if x.end <= now && free.is_none() {
                free = Some(i + 1);
            }
        }
        match free {
            Some(0) => set.first = w,
            Some(i) => set.more[i - 1] = w,
            None => set.more.push(w),
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
        for w in self.parts().into_iter().flatten() {
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
        for w in self.parts().into_iter().flatten() {
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
        let mut v: Vec<Window> = self.iter().copied().filter(|w| w.end > now).collect();
        v.sort_by_key(|w| (w.end, w.kind, w.holder));
        v
    }

    /// The latest end of any open window: when this port will next be free.
    pub fn next_end(&self, now: Instant) -> Option<Instant> {
        self.iter().filter(|w| w.end > now).map(|w| w.end).max()
    }

    /// Forget windows held by a connection that has been removed.
    pub fn forget_holder(&mut self, holder: Source) {
        let Some(set) = self.list.as_mut() else { return };
        set.more.retain(|w| w.holder != holder);
        if set.first.holder == holder {
            // The list without its first: the next window moves up, in order.
            if set.more.is_empty() {
                self.list = None;
            } else {
                set.first = set.more.remove(0);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    //! The set's first window is held in the box, the others behind it: refreshing, reusing
    //! expired slots and forgetting holders must behave as one list would.

    use super::*;
    use crate::address::NodeId;

    fn src(conn: u64) -> Source {
        Source { node: NodeId(1), conn }
    }

    #[test]
    fn the_first_window_and_the_spilled_ones_behave_as_one_list() {
        let t = Instant::from_millis;
        let mut w = Windows::default();
        assert!(w.is_empty());
        w.refresh(t(0), WindowKind::WriteInhibit, src(1), t(10));
        w.refresh(t(0), WindowKind::Inhibit, src(2), t(20));
        w.refresh(t(0), WindowKind::OverrideOut, src(3), t(30));
        // Refreshing never shortens; the first window is found like the others.
        w.refresh(t(0), WindowKind::WriteInhibit, src(1), t(5));
        w.refresh(t(0), WindowKind::OverrideOut, src(3), t(35));
        let ends = |w: &Windows, now| w.active(now).iter().map(|x| (x.holder.conn, x.end)).collect::<Vec<_>>();
        assert_eq!(ends(&w, t(0)), [(1, t(10)), (2, t(20)), (3, t(35))]);
        assert_eq!(w.admit_propagation(t(0), Origin::Internal), Err(DropCause::Inhibited));
        // The first expired slot is reused: here the first window's.
        w.refresh(t(15), WindowKind::Suppress, src(4), t(40));
        assert_eq!(ends(&w, t(15)), [(2, t(20)), (3, t(35)), (4, t(40))]);
        assert_eq!(w.admit_write(t(15), src(9)), Err(DropCause::Suppressed));
        // Forgetting the first holder moves the next window up; forgetting all empties.
        w.forget_holder(src(4));
        assert_eq!(ends(&w, t(15)), [(2, t(20)), (3, t(35))]);
        assert_eq!(w.admit_write(t(15), src(9)), Ok(()));
        w.forget_holder(src(2));
        w.forget_holder(src(3));
        assert!(w.is_empty());
        assert_eq!(w.admit_propagation(t(15), Origin::Internal), Ok(()));
        assert_eq!(w.next_end(t(15)), None);
    }
}
