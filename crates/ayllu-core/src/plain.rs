//! The plain path: a write and its Normal hops when there is nothing to check.
//!
//! Most ports of a running team are Normal, trigger no process and never see a window. For
//! such a *plain* port ([`PortState::is_plain`]) the general path (`write_internal`,
//! `deliver`) reduces to the merge and the wave marks (and, along a connection to another
//! node, the numbered message into the outbox), so [`NodeCore::write`], a process's
//! [`Ctx::write`](crate::Ctx::write) and the propagation loop take it here: the handle is resolved once, a hop into a plain port that
//! passes nothing on is the merge and the marks, and the first edge that needs more hands the
//! rest of the wave to the general loop at exactly that edge.
//!
//! What it promises: the same outcome as the general path, bit for bit (values, suppliers,
//! times, counters, wave marks, the order of the wave), and no allocation. The flag `plain`
//! is kept up to date wherever triggers, guards or windows change (creation, `add_process`, a
//! window opening in `deliver`, `disconnect`, a restore), and checked against the port in debug builds. The
//! journal (the flight recorder's tap) records here what the general path would record, in
//! the same order: a write from outside and its acceptance as one record (the merge stores the
//! value itself), each hop's acceptance. The tests below compare the two paths, journals
//! included, on nodes whose `general_only` switch keeps them off this one.

use crate::address::{ConnectionId, Source};
use crate::connection::ConnectionKind;
use crate::journal::{journal_value, JournalValue};
use crate::node::{NodeCore, PortRef, PortState};
use crate::port::PortKind;
use crate::value::Value;

impl PortState {
    /// A Normal port with no triggered process, no window (none was ever opened, or every
    /// one was forgotten) and no periodic process it guards (D7.5): accepting a value is the
    /// merge and the marks, nothing to queue or tell the schedule, and nothing blocks the value
    /// on its way in or out. The hop's fast path takes such ports (`NodeCore::write_plain`,
    /// `NodeCore::hop_plain`); the flag `plain` caches this.
    pub(crate) fn is_plain(&self) -> bool {
        self.cell.kind == PortKind::Normal && self.triggers.is_empty() && self.windows.is_empty() && !self.guarded
    }

    /// Recompute `plain` after the triggers or the windows changed.
    pub(crate) fn refresh_plain(&mut self) {
        self.plain = self.is_plain();
    }
}

impl NodeCore {
    /// The fast path of [`NodeCore::write`]: a plain port ([`PortState::is_plain`]) and a value
    /// of its type. The handle is resolved once, the merge is the Normal one, and nothing can
    /// refuse the value or block its propagation, so this is exactly what `write_internal`
    /// does for such a port. Returns `false`, having changed nothing, when the general path must
    /// take the write (a stale handle included, so that its error is the general path's).
    #[inline(always)]
    pub(crate) fn write_plain(&mut self, port: PortRef, value: &Value) -> bool {
        let (b, p, id) = (port.b, port.port.0, Some(port.id));
        if self.journal.is_none() {
            self.write_plain_at::<false>(b, p, id, value)
        } else {
            self.write_plain_at::<true>(b, p, id, value)
        }
    }

    /// [`NodeCore::write_plain`] into port `p` of the behavior in slot `b`, if its id is `id`
    /// (`None`: whichever lives there, as for a process writing its own behavior's port).
    /// `JOURNAL`: whether the journal runs (checked once by the caller, so that the path with
    /// the journal off is compiled without its checks).
    #[inline(always)]
    pub(crate) fn write_plain_at<const JOURNAL: bool>(
        &mut self,
        b: u32,
        p: u16,
        id: Option<u64>,
        value: &Value,
    ) -> bool {
        if !self.plain_allowed() {
            return false;
        }
        let Some(beh) = self.behaviors.get_mut(b as usize).and_then(Option::as_mut) else { return false };
        let Some(ps) = beh.ports.get_mut(usize::from(p)) else { return false };
        if id.is_some_and(|id| id != beh.id) || !ps.plain || value.ty() != ps.cell.value.ty() {
            return false;
        }
        debug_assert!(ps.is_plain(), "a port's plain flag was not refreshed after a structure change");
        self.wave += 1;
        ps.cell.accept_normal(self.now, value, Source::internal(self.id));
        ps.visited = self.wave;
        ps.accepted += 1;
        if JOURNAL {
            if let Some(j) = self.journal.as_deref_mut() {
                // A write from outside is journaled with its acceptance (the general path makes
                // the two entries in a row); a process's write was journaled by its `Ctx`.
                let what = if id.is_some() { JournalValue::WriteAccepted } else { JournalValue::Accepted };
                journal_value(j, self.now, what, (b, beh.id), (&beh.name, &beh.class), p, value);
            }
        }
        // The port now holds `value` itself, so its edges carry the argument: no copy of it.
        // Leaf hops are taken here; the first edge that needs more hands the rest of the wave
        // to the general loop at exactly that edge (same order, same checks).
        let me = self.id;
        let mut next = 0u32;
        loop {
            let Some(edge) = self.behaviors[b as usize]
                .as_ref()
                .and_then(|beh| beh.ports[usize::from(p)].out.get(next as usize).copied())
            else {
                return true;
            };
            let from = Source::connection(me, ConnectionId(edge.id));
            match edge.local {
                Some((db, dp))
                    if edge.kind == ConnectionKind::Normal && self.hop_plain::<JOURNAL>(db, dp, from, value) =>
                {
                    next += 1
                }
                // A remote edge ends in a message: nothing on this node can refuse or block it
                // (the port is plain), so it is sent from here, as the general loop would.
                None => {
                    self.send_along(edge, value.clone());
                    next += 1
                }
                Some(_) => {
                    self.propagate_from_edge(b, p, next);
                    return true;
                }
            }
        }
    }

    /// One Normal hop into local port (b, p) by the fast path: a plain port
    /// ([`PortState::is_plain`]) that passes nothing on, not yet written in this wave, taking a
    /// value of its type. Then nothing can refuse the value and nothing follows from it, so
    /// this is exactly what `deliver` does for it. Returns `false`, having changed nothing,
    /// when `deliver` must take the hop. `JOURNAL` as for [`NodeCore::write_plain_at`].
    #[inline(always)]
    pub(crate) fn hop_plain<const JOURNAL: bool>(&mut self, b: u32, p: u16, from: Source, value: &Value) -> bool {
        if !self.plain_allowed() {
            return false;
        }
        let Some(beh) = self.behaviors.get_mut(b as usize).and_then(Option::as_mut) else { return false };
        let Some(ps) = beh.ports.get_mut(usize::from(p)) else { return false };
        if !ps.plain || !ps.out.is_empty() || ps.visited == self.wave || value.ty() != ps.cell.value.ty() {
            return false;
        }
        debug_assert!(ps.is_plain(), "a port's plain flag was not refreshed after a structure change");
        ps.cell.accept_normal(self.now, value, from);
        ps.visited = self.wave;
        ps.accepted += 1;
        if JOURNAL {
            if let Some(j) = self.journal.as_deref_mut() {
                journal_value(j, self.now, JournalValue::Accepted, (b, beh.id), (&beh.name, &beh.class), p, value);
            }
        }
        true
    }

    /// [`NodeCore::hop_plain`] where the journal was not checked yet (the general loop).
    #[inline(always)]
    pub(crate) fn hop_plain_checked(&mut self, b: u32, p: u16, from: Source, value: &Value) -> bool {
        if self.journal.is_none() {
            self.hop_plain::<false>(b, p, from, value)
        } else {
            self.hop_plain::<true>(b, p, from, value)
        }
    }

    /// Whether the plain path may be taken: always, but in the tests that compare it with the
    /// general one.
    #[inline(always)]
    fn plain_allowed(&self) -> bool {
        #[cfg(test)]
        if self.general_only {
            return false;
        }
        true
    }
}

#[cfg(test)]
mod tests {
    //! The plain path against the general one: the same operations on three nodes, one kept on
    //! the general path (`general_only`), one on the plain path where it can be taken, and one
    //! on the plain path with the journal on, must leave the same node: every port's value,
    //! supplier, time, windows, counters and acceptance count, every process's runs, the
    //! outgoing messages and every result; and the two journals must hold the same entries.

    use proptest::prelude::*;

    use crate::*;

    const BEHAVIORS: [&str; 4] = ["X0", "X1", "X2", "X3"];
    /// (behavior, port): ints, then one text port (its value an `Arc`, assigned by clone).
    const PORTS: [(&str, &str); 10] = [
        ("X0", "A"),
        ("X0", "B"),
        ("X1", "A"),
        ("X1", "B"),
        ("X2", "A"),
        ("X2", "B"),
        ("X3", "A"),
        ("X3", "B"),
        ("X0", "T"),
        ("X2", "C"),
    ];

    #[derive(Clone, Debug)]
    enum Op {
        Connect {
            from: usize,
            to: usize,
            kind: u8,
            remote: bool,
        },
        Disconnect(usize),
        /// Connect again what the i-th connection connects (a second edge into the same port:
        /// the second write of a wave is a revisit).
        Duplicate(usize),
        Write(usize, i64),
        WriteText(u8),
        WriteFloat(usize),
        AddProcess(usize),
        Reset(usize),
        Recreate(usize),
        Poll,
        Advance(u64),
    }

    fn op() -> impl Strategy<Value = Op> {
        prop_oneof![
            6 => (0..PORTS.len(), 0..PORTS.len(), 0u8..12, proptest::bool::weighted(0.1))
                .prop_map(|(from, to, kind, remote)| Op::Connect { from, to, kind, remote }),
            1 => (0usize..8).prop_map(Op::Disconnect),
            2 => (0usize..8).prop_map(Op::Duplicate),
            10 => (0..PORTS.len(), -3i64..3).prop_map(|(p, v)| Op::Write(p, v)),
            2 => (0u8..3).prop_map(Op::WriteText),
            1 => (0..PORTS.len()).prop_map(Op::WriteFloat),
            1 => (0..PORTS.len()).prop_map(Op::AddProcess),
            1 => (0..PORTS.len()).prop_map(Op::Reset),
            1 => (0..BEHAVIORS.len()).prop_map(Op::Recreate),
            2 => Just(Op::Poll),
            2 => (1u64..150).prop_map(Op::Advance),
        ]
    }

    fn kind(k: u8) -> ConnectionKind {
        let d = Duration::from_millis(100);
        match k {
            0 => ConnectionKind::Suppress(d),
            1 => ConnectionKind::Inhibit(d),
            2 => ConnectionKind::OverrideIn(d),
            3 => ConnectionKind::OverrideOut(d),
            4 => ConnectionKind::WriteInhibit(d),
            _ => ConnectionKind::Normal,
        }
    }

    fn node() -> NodeCore {
        let mut node = NodeCore::new(NodeId(1));
        let mut plain = BehaviorClass::new("Plain");
        plain.port(PortSpec::new("A", 0i64)).unwrap();
        plain.port(PortSpec::new("B", 0i64)).unwrap();
        plain.port(PortSpec::new("T", "")).unwrap();
        plain.port(PortSpec::new("C", 0i64)).unwrap();
        node.define(plain).unwrap();
        // A port with a triggered process (B, a Max port, follows A plus one; C, a plain port
        // unless a process is added to it, A minus one).
        let mut busy = BehaviorClass::new("Busy");
        let a = busy.port(PortSpec::new("A", 0i64)).unwrap();
        let b = busy.port(PortSpec::new("B", 0i64).max()).unwrap();
        busy.port(PortSpec::new("T", "")).unwrap();
        let c = busy.port(PortSpec::new("C", 0i64)).unwrap();
        busy.on_write("Follow", a, move |ctx| {
            let v = ctx.int(a).unwrap_or(0);
            let _ = ctx.write(b, v + 1);
            let _ = ctx.write(c, v - 1);
        })
        .unwrap();
        node.define(busy).unwrap();
        for name in BEHAVIORS {
            node.create(class_of(name), name).unwrap();
        }
        node
    }

    fn class_of(behavior: &str) -> &'static str {
        if behavior == "X2" {
            "Busy"
        } else {
            "Plain"
        }
    }

    /// Apply `op` to `node`; what it returned, as text (errors included).
    fn apply(node: &mut NodeCore, now: &mut Instant, op: &Op) -> String {
        match *op {
            Op::Connect { from, to, kind: k, remote } => {
                let (sb, sp) = PORTS[from];
                let (db, dp) = PORTS[to];
                let destination = if remote { Endpoint::node(NodeId(9), db, dp) } else { Endpoint::local(db, dp) };
                format!(
                    "{:?}",
                    node.connect(&Endpoint::local(sb, sp), &destination, kind(k), ConnectOptions::default())
                )
            }
            Op::Disconnect(i) => {
                let conns = node.report().connections;
                match conns.get(i % conns.len().max(1)) {
                    Some(c) => format!("{:?}", node.disconnect(c.id)),
                    None => "none".into(),
                }
            }
            Op::Duplicate(i) => {
                let conns = node.report().connections;
                match conns.get(i % conns.len().max(1)) {
                    Some(c) => format!(
                        "{:?}",
                        node.connect(&c.source, &c.destination, c.kind, ConnectOptions { priority: c.priority })
                    ),
                    None => "none".into(),
                }
            }
            Op::Write(p, v) => format!("{:?}", node.write_named(*now, PORTS[p].0, PORTS[p].1, v)),
            Op::WriteText(t) => {
                let text = ["a", "bb", "ccc"][usize::from(t)];
                format!("{:?}", node.write_named(*now, "X0", "T", Value::text(text)))
            }
            Op::WriteFloat(p) => format!("{:?}", node.write_named(*now, PORTS[p].0, PORTS[p].1, 1.5)),
            Op::AddProcess(p) => {
                let (b, port) = PORTS[p];
                let handle = node.port(b, port).unwrap().port();
                let name = format!("On{port}{}", now.as_nanos());
                format!("{:?}", node.add_process(b, &name, Trigger::OnWrite(handle), |_| {}))
            }
            Op::Reset(p) => format!("{:?}", node.port(PORTS[p].0, PORTS[p].1).and_then(|r| node.reset(r))),
            Op::Recreate(b) => {
                let name = BEHAVIORS[b];
                format!("{:?} {:?}", node.remove(name), node.create(class_of(name), name).map(|_| ()))
            }
            Op::Poll => format!("{:?}", node.poll(*now)),
            Op::Advance(ms) => {
                *now += Duration::from_millis(ms);
                String::new()
            }
        }
    }

    /// Everything a node shows of itself, as text.
    fn state(node: &mut NodeCore) -> String {
        let mut s = format!("{:?}\n", node.report());
        for (b, p) in PORTS {
            s += &format!("{:?}\n", node.why(b, p));
        }
        while let Some(out) = node.pop_outgoing() {
            s += &format!("{out:?}\n");
        }
        s
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]
        #[test]
        fn the_plain_path_leaves_the_node_the_general_path_leaves(
            ops in proptest::collection::vec(op(), 1..60),
            capacity in 1usize..48,
        ) {
            let (mut general, mut plain, mut journaled) = (node(), node(), node());
            general.general_only = true;
            // A small journal fills within one operation at times: the two paths must lose the
            // same entries at its edge.
            general.start_journal(capacity);
            journaled.start_journal(capacity);
            let (mut t_general, mut t_plain, mut t_journaled) = (Instant::ZERO, Instant::ZERO, Instant::ZERO);
            let (mut by_general, mut by_plain) = (Vec::new(), Vec::new());
            for op in &ops {
                let a = apply(&mut general, &mut t_general, op);
                let b = apply(&mut plain, &mut t_plain, op);
                let c = apply(&mut journaled, &mut t_journaled, op);
                prop_assert_eq!(&a, &b, "result of {:?}", op);
                prop_assert_eq!(&a, &c, "result of {:?} (journaled)", op);
                let state_general = state(&mut general);
                prop_assert_eq!(&state_general, &state(&mut plain), "after {:?}", op);
                prop_assert_eq!(&state_general, &state(&mut journaled), "after {:?} (journaled)", op);
                general.take_journal(&mut by_general);
                journaled.take_journal(&mut by_plain);
                prop_assert_eq!(format!("{by_general:?}"), format!("{by_plain:?}"), "journal of {:?}", op);
                by_general.clear();
                by_plain.clear();
            }
        }
    }

    /// The flag follows the structure: a trigger, a window, and the window's connection gone.
    #[test]
    fn the_plain_flag_follows_triggers_and_windows() {
        let mut node = node();
        let plain = |node: &NodeCore, b: &str, p: &str| {
            let r = node.port(b, p).unwrap();
            let ps = node.resolve(r).unwrap();
            assert_eq!(ps.plain, ps.is_plain());
            ps.plain
        };
        assert!(plain(&node, "X0", "A"));
        assert!(!plain(&node, "X2", "A"), "a port with a triggered process");
        assert!(!plain(&node, "X2", "B"), "a Max port");
        let id = node
            .connect(
                &Endpoint::local("X0", "A"),
                &Endpoint::local("X1", "A"),
                ConnectionKind::Suppress(Duration::from_millis(10)),
                ConnectOptions::default(),
            )
            .unwrap();
        assert!(plain(&node, "X1", "A"), "no window until the first message");
        node.write_named(Instant::ZERO, "X0", "A", 1i64).unwrap();
        assert!(!plain(&node, "X1", "A"), "a window opened");
        node.disconnect(id).unwrap();
        assert!(plain(&node, "X1", "A"), "its holder is gone");
        let handle = node.port("X1", "B").unwrap().port();
        node.add_process("X1", "Watch", Trigger::OnWrite(handle), |_| {}).unwrap();
        assert!(!plain(&node, "X1", "B"), "a process added later");
    }
}
