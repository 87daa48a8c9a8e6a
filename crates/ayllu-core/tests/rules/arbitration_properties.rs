//! Property tests of arbitration (rule S6) over random schedules of writes, special messages
//! and time steps: a port D fed by sources of chosen kinds, D -> E Normal.
//!
//! The only model kept beside the node is the refresh rule itself — per holder,
//! `end := max(end, t + p)` — and every check compares what the node did against it.

use crate::common;

use std::sync::Arc;

use ayllu_core::*;
use common::*;
use proptest::prelude::*;

#[derive(Copy, Clone, Debug)]
enum Step {
    /// Let this many milliseconds pass.
    Wait(u64),
    /// Source `i` writes its port, which sends along its connection into D.
    Send(usize),
    /// D's own behavior writes D.
    Own,
}

fn steps(sources: usize, len: usize) -> impl Strategy<Value = Vec<Step>> {
    let step = prop_oneof![
        3 => (0u64..60).prop_map(Step::Wait),
        4 => (0..sources).prop_map(Step::Send),
        2 => Just(Step::Own),
    ];
    proptest::collection::vec(step, 1..len)
}

fn window_kind(kind: ConnectionKind) -> Option<WindowKind> {
    match kind {
        ConnectionKind::Normal => None,
        ConnectionKind::Suppress(_) => Some(WindowKind::Suppress),
        ConnectionKind::Inhibit(_) => Some(WindowKind::Inhibit),
        ConnectionKind::OverrideIn(_) => Some(WindowKind::OverrideIn),
        ConnectionKind::OverrideOut(_) => Some(WindowKind::OverrideOut),
        ConnectionKind::WriteInhibit(_) => Some(WindowKind::WriteInhibit),
    }
}

/// What one step did to D and E.
#[derive(Debug)]
struct Seen {
    value: i64,
    d_took: bool,
    e_took: bool,
    d: i64,
    e: i64,
}

/// The node under test and the window ends the refresh rule predicts, per source.
struct Rig {
    node: NodeCore,
    kinds: Vec<ConnectionKind>,
    ends: Vec<Instant>,
    now: Instant,
    next_value: i64,
}

impl Rig {
    fn new(kinds: &[ConnectionKind]) -> Rig {
        let names: Vec<String> = (0..kinds.len()).map(source).collect();
        let mut all: Vec<&str> = names.iter().map(String::as_str).collect();
        all.extend(["D", "E"]);
        let mut node = wiring(&all);
        for (name, kind) in names.iter().zip(kinds) {
            link(&mut node, name, "D", *kind);
        }
        link(&mut node, "D", "E", ConnectionKind::Normal);
        Rig { node, kinds: kinds.to_vec(), ends: vec![Instant::ZERO; kinds.len()], now: Instant::ZERO, next_value: 1 }
    }

    /// Whether source `i` holds an open window now.
    fn holds(&self, i: usize) -> bool {
        window_kind(self.kinds[i]).is_some() && self.ends[i] > self.now
    }

    /// Whether any window of `kind` is open now.
    fn open(&self, kind: WindowKind) -> bool {
        (0..self.kinds.len()).any(|i| window_kind(self.kinds[i]) == Some(kind) && self.holds(i))
    }

    fn latest_end(&self) -> Instant {
        self.ends.iter().copied().max().unwrap_or(Instant::ZERO)
    }

    fn run(&mut self, step: Step) -> Seen {
        let (d0, e0) = (accepted(&self.node, "D"), accepted(&self.node, "E"));
        let written = self.next_value;
        self.next_value += 1;
        match step {
            Step::Wait(n) => {
                self.now += ms(n);
                self.node.poll(self.now);
            }
            Step::Send(i) => {
                if let Some(p) = self.kinds[i].period() {
                    self.ends[i] = self.ends[i].max(self.now + p);
                }
                put(&mut self.node, self.now, &source(i), written);
            }
            Step::Own => put(&mut self.node, self.now, "D", written),
        }
        Seen {
            value: written,
            d_took: accepted(&self.node, "D") > d0,
            e_took: accepted(&self.node, "E") > e0,
            d: value(&self.node, "D"),
            e: value(&self.node, "E"),
        }
    }
}

fn source(i: usize) -> String {
    format!("S{i}")
}

fn period() -> impl Strategy<Value = Duration> {
    (1u64..150).prop_map(ms)
}

/// One source of every kind (periods chosen at random) plus two Normal sources.
fn every_kind() -> impl Strategy<Value = Vec<ConnectionKind>> {
    (period(), period(), period(), period(), period(), period(), period()).prop_map(|(a, b, c, d, e, f, g)| {
        vec![
            ConnectionKind::Suppress(a),
            ConnectionKind::Inhibit(b),
            ConnectionKind::OverrideIn(c),
            ConnectionKind::OverrideIn(d),
            ConnectionKind::OverrideOut(e),
            ConnectionKind::OverrideOut(f),
            ConnectionKind::WriteInhibit(g),
            ConnectionKind::Normal,
            ConnectionKind::Normal,
        ]
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// (1) S6 Suppress / Inhibit: while a Suppress window is open no connection writes D
    /// (pass holders included), though D's own behavior still does; while an Inhibit window
    /// is open nothing at all leaves D.
    #[test]
    fn nothing_crosses_an_active_suppress_or_inhibit(kinds in every_kind(), plan in steps(9, 60)) {
        let mut rig = Rig::new(&kinds);
        for step in plan {
            let seen = rig.run(step);
            if rig.open(WindowKind::Suppress) {
                match step {
                    Step::Send(_) => prop_assert!(!seen.d_took, "suppressed D took {seen:?}"),
                    Step::Own => prop_assert!(seen.d_took && seen.d == seen.value, "own write refused {seen:?}"),
                    Step::Wait(_) => {}
                }
            }
            if rig.open(WindowKind::Inhibit) {
                prop_assert!(!seen.e_took, "inhibited D propagated {seen:?}");
            }
        }
    }

    /// (2) S6 overrides: while an OverrideIn window is open only its holders write D; while an
    /// OverrideOut window is open only values arriving along its holders leave D. With
    /// several overrides the passes add up (union).
    #[test]
    fn only_pass_holders_cross_an_override(
        periods in (period(), period(), period(), period()),
        plan in steps(6, 60),
    ) {
        let kinds = [
            ConnectionKind::OverrideIn(periods.0),
            ConnectionKind::OverrideIn(periods.1),
            ConnectionKind::OverrideOut(periods.2),
            ConnectionKind::OverrideOut(periods.3),
            ConnectionKind::Normal,
            ConnectionKind::Normal,
        ];
        let mut rig = Rig::new(&kinds);
        for step in plan {
            let seen = rig.run(step);
            if let Step::Send(i) = step {
                let may_write = !rig.open(WindowKind::OverrideIn) || (rig.holds(i) && i < 2);
                prop_assert_eq!(seen.d_took, may_write, "write into D {:?}", seen);
                if seen.d_took {
                    prop_assert_eq!(seen.d, seen.value);
                }
                if i < 2 {
                    // An OverrideIn message always opens its own pass first, then writes.
                    prop_assert!(rig.holds(i) && seen.d_took && seen.d == seen.value, "{:?}", seen);
                }
            }
            if let Step::Own = step {
                prop_assert!(seen.d_took, "own writes are never blocked by overrides");
            }
            if seen.e_took {
                prop_assert_eq!(seen.e, seen.value, "what leaves D is the value just written");
            }
            let propagates = seen.d_took
                && (!rig.open(WindowKind::OverrideOut)
                    || matches!(step, Step::Send(i) if (2..4).contains(&i) && rig.holds(i)));
            prop_assert_eq!(seen.e_took, propagates, "propagation out of D {:?}", seen);
        }
    }

    /// (3) S6 WriteInhibit: while open, D's own writes are stored but not propagated; writes
    /// arriving through connections are stored and propagated as always.
    #[test]
    fn write_inhibit_blocks_only_internal_writes(p in period(), q in period(), plan in steps(3, 60)) {
        let kinds = [ConnectionKind::WriteInhibit(p), ConnectionKind::WriteInhibit(q), ConnectionKind::Normal];
        let mut rig = Rig::new(&kinds);
        for step in plan {
            let seen = rig.run(step);
            match step {
                Step::Own => {
                    prop_assert!(seen.d_took && seen.d == seen.value);
                    prop_assert_eq!(seen.e_took, !rig.open(WindowKind::WriteInhibit), "{:?}", seen);
                }
                Step::Send(2) => {
                    prop_assert!(seen.d_took && seen.e_took && seen.e == seen.value, "{:?}", seen);
                }
                Step::Send(_) => prop_assert!(!seen.d_took && !seen.e_took, "m is not written {:?}", seen),
                Step::Wait(_) => prop_assert!(!seen.d_took && !seen.e_took),
            }
        }
    }

    /// (4) S6: a window that is not refreshed lapses; from its end on D passes values again,
    /// from connections and from its own behavior alike.
    #[test]
    fn unrefreshed_windows_lapse(kinds in every_kind(), plan in steps(9, 40), extra in 0u64..20) {
        let mut rig = Rig::new(&kinds);
        for step in plan {
            rig.run(step);
        }
        let wait = rig.latest_end().saturating_since(rig.now) + ms(extra);
        rig.run(Step::Wait(wait.as_nanos() / 1_000_000));
        prop_assert!(rig.now >= rig.latest_end());
        let why = rig.node.why("D", V).unwrap();
        prop_assert!(why.windows.is_empty(), "{:?}", why.windows);
        prop_assert_eq!(why.input_blocked, None);
        prop_assert_eq!(why.internal_output_blocked, None);
        prop_assert_eq!(why.connection_output_blocked, None);
        let normal = kinds.len() - 1;
        let seen = rig.run(Step::Send(normal));
        prop_assert!(seen.d_took && seen.e_took && seen.e == seen.value, "{:?}", seen);
        let seen = rig.run(Step::Own);
        prop_assert!(seen.d_took && seen.e_took && seen.e == seen.value, "{:?}", seen);
    }

    /// (5) S6/S8: windows are refreshed, never shortened — even when the same holder later
    /// sends a shorter period (a remote holder's message carries its period).
    #[test]
    fn windows_are_never_shortened(
        kind in 0usize..5,
        arrivals in proptest::collection::vec((0u64..80, 1u64..150), 1..20),
        probe in 0u64..400,
    ) {
        let make = |p: Duration| match kind {
            0 => ConnectionKind::Suppress(p),
            1 => ConnectionKind::Inhibit(p),
            2 => ConnectionKind::OverrideIn(p),
            3 => ConnectionKind::OverrideOut(p),
            _ => ConnectionKind::WriteInhibit(p),
        };
        let mut node = wiring(&["D", "E"]);
        link(&mut node, "D", "E", ConnectionKind::Normal);
        let (peer, conn) = (NodeId(9), ConnectionId(5));
        let holder = Source::connection(peer, conn);
        let message = |seq: u64, kind: ConnectionKind| Message::Port(PortMessage {
            conn,
            seq,
            behavior: Arc::from("D"),
            port: Arc::from(V),
            kind,
            priority: 0,
            value: Value::Int(-1),
        });
        let (mut now, mut end) = (Instant::ZERO, Instant::ZERO);
        for (seq, (dt, p)) in arrivals.iter().enumerate() {
            now += ms(*dt);
            let before = end;
            end = end.max(now + ms(*p));
            node.receive(now, peer, message(seq as u64 + 1, make(ms(*p))));
            let why = node.why("D", V).unwrap();
            let mine: Vec<Instant> = why.windows.iter().filter(|w| w.holder == holder).map(|w| w.ends).collect();
            prop_assert_eq!(mine, vec![end]);
            prop_assert!(end >= before);
        }
        // Probe some time later: the port is blocked exactly while now < end.
        node.poll(now + ms(probe));
        let why = node.why("D", V).unwrap();
        let blocked = why.input_blocked.is_some() || why.internal_output_blocked.is_some();
        prop_assert_eq!(blocked, now + ms(probe) < end);
    }
}
