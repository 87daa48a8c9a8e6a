//! Misuse of the API is reported with a clear error naming what was wrong — never a panic,
//! never a silent fix. (Rules S1–S3, S6, S7, S9, S10 as cited per test.)

use ayllu_core::*;

fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}

/// Node with `A` (class `K`: `Text` text, `Num` float, `Hot` float Max, slot `Secret`,
/// monostable `Flag`) and `B` of the same class.
fn node() -> NodeCore {
    let mut n = NodeCore::new(NodeId(1));
    let mut k = BehaviorClass::new("K");
    k.port(PortSpec::new("Text", "")).unwrap();
    k.port(PortSpec::new("Num", 0.0)).unwrap();
    k.port(PortSpec::new("Hot", 0.0).max()).unwrap();
    k.slot("Secret", 0i64).unwrap();
    k.monostable("Flag").unwrap();
    n.define(k).unwrap();
    n.create("K", "A").unwrap();
    n.create("K", "B").unwrap();
    n
}

fn connect(
    n: &mut NodeCore,
    from: (&str, &str),
    to: (&str, &str),
    kind: ConnectionKind,
) -> Result<ConnectionId, Error> {
    n.connect(&Endpoint::local(from.0, from.1), &Endpoint::local(to.0, to.1), kind, ConnectOptions::default())
}

/// The error's message mentions every one of `words`.
fn says(e: &Error, words: &[&str]) {
    let msg = e.to_string();
    for w in words {
        assert!(msg.contains(w), "`{msg}` should mention `{w}` ({e:?})");
    }
}

#[test]
fn ordered_and_summing_kinds_refuse_types_without_order_or_sum() {
    // S3: Max/Min need an ordered type, Sum a summable one.
    for (spec, kind, ty) in [
        (PortSpec::new("T", "x").max(), PortKind::Max, ValueType::Text),
        (PortSpec::new("T", Value::bytes(b"")).min(), PortKind::Min, ValueType::Bytes),
        (PortSpec::new("T", Value::vector(&[1.0])).max(), PortKind::Max, ValueType::Vector),
        (PortSpec::new("T", true).sum(), PortKind::Sum, ValueType::Bool),
        (PortSpec::new("T", "x").sum(), PortKind::Sum, ValueType::Text),
    ] {
        let mut c = BehaviorClass::new("C");
        let e = c.port(spec).unwrap_err();
        assert_eq!(e, Error::KindNotSupported { kind, ty });
        says(&e, &[&format!("{kind:?}"), ty.name()]);
        assert!(c.port_handle("T").is_none(), "a refused port is not declared");
    }
}

#[test]
fn wiring_a_text_port_to_a_float_port_is_a_type_mismatch() {
    // S1: types are checked when connecting kinds that write (Normal, OverrideIn, OverrideOut).
    let mut n = node();
    for kind in [
        ConnectionKind::Normal,
        ConnectionKind::OverrideIn(Duration::from_millis(1)),
        ConnectionKind::OverrideOut(Duration::from_millis(1)),
    ] {
        for port in ["Hot", "Num"] {
            let e = connect(&mut n, ("A", "Text"), ("B", port), kind).unwrap_err();
            assert!(
                matches!(&e, Error::TypeMismatch { expected: ValueType::Float, found: ValueType::Text, .. }),
                "{kind}: {e:?}"
            );
            says(&e, &[&format!("B.{port}"), "float", "text"]);
        }
    }
    // Kinds that never write the message need no type agreement.
    for kind in [
        ConnectionKind::Suppress(Duration::from_millis(1)),
        ConnectionKind::Inhibit(Duration::from_millis(1)),
        ConnectionKind::WriteInhibit(Duration::from_millis(1)),
    ] {
        connect(&mut n, ("A", "Text"), ("B", "Hot"), kind).unwrap();
    }
}

#[test]
fn writing_the_wrong_type_is_an_error_not_a_coercion() {
    // S1: never coerced.
    let mut n = node();
    let p = n.port("A", "Num").unwrap();
    let e = n.write(ms(0), p, 3i64).unwrap_err();
    assert_eq!(e, Error::TypeMismatch { what: "port A.Num".into(), expected: ValueType::Float, found: ValueType::Int });
    says(&e, &["A.Num", "float", "int"]);
    assert!(!n.fresh(p).unwrap());
}

#[test]
fn writing_nan_into_an_ordered_port_says_so() {
    // S3: NaN into Max is refused; the error names the port and the reason (not a type
    // problem: the port does hold floats).
    let mut n = node();
    let p = n.port("A", "Hot").unwrap();
    let e = n.write(ms(0), p, f64::NAN).unwrap_err();
    assert!(matches!(&e, Error::Refused { cause: DropCause::NotANumber, .. }), "{e:?}");
    says(&e, &["A.Hot", "not_a_number"]);
    assert!(!e.to_string().contains("cannot hold"), "misleading: {e}");
    assert!(!n.fresh(p).unwrap());
}

#[test]
fn writing_a_mis_shaped_vector_into_a_sum_says_so() {
    // S3 Sum: a vector of another length is a shape mismatch, named as such.
    let mut n = NodeCore::new(NodeId(1));
    let mut c = BehaviorClass::new("C");
    c.port(PortSpec::new("V", Value::vector(&[0.0, 0.0])).sum()).unwrap();
    n.define(c).unwrap();
    n.create("C", "X").unwrap();
    let p = n.port("X", "V").unwrap();
    n.write(ms(0), p, vec![1.0, 1.0]).unwrap();
    let e = n.write(ms(1), p, vec![1.0]).unwrap_err();
    assert!(matches!(&e, Error::Refused { cause: DropCause::ShapeMismatch, .. }), "{e:?}");
    says(&e, &["X.V", "shape_mismatch"]);
}

#[test]
fn connecting_unknown_behaviors_or_ports_is_reported() {
    // S9/S10: connections name things that must exist on this node.
    let mut n = node();
    let e = connect(&mut n, ("Ghost", "Num"), ("B", "Num"), ConnectionKind::Normal).unwrap_err();
    assert_eq!(e, Error::UnknownBehavior { behavior: "Ghost".into() });
    says(&e, &["Ghost"]);
    let e = connect(&mut n, ("A", "Num"), ("Phantom", "Num"), ConnectionKind::Normal).unwrap_err();
    assert_eq!(e, Error::UnknownBehavior { behavior: "Phantom".into() });
    let e = connect(&mut n, ("A", "Nope"), ("B", "Num"), ConnectionKind::Normal).unwrap_err();
    assert_eq!(e, Error::UnknownPort { behavior: "A".into(), port: "Nope".into() });
    says(&e, &["A", "Nope"]);
    let e = connect(&mut n, ("A", "Num"), ("B", "Nada"), ConnectionKind::Normal).unwrap_err();
    says(&e, &["B", "Nada"]);
    // A monostable is a register but not a port.
    let e = connect(&mut n, ("A", "Num"), ("B", "Flag"), ConnectionKind::Normal).unwrap_err();
    assert!(matches!(e, Error::UnknownPort { .. }), "{e:?}");
    assert!(n.report().connections.is_empty(), "nothing half-made");
}

#[test]
fn connecting_a_slot_is_not_a_port() {
    // S2: slots are internal to their behavior, never connectable — either end.
    let mut n = node();
    for (from, to) in [(("A", "Secret"), ("B", "Num")), (("A", "Num"), ("B", "Secret"))] {
        let e = connect(&mut n, from, to, ConnectionKind::Normal).unwrap_err();
        assert!(matches!(&e, Error::NotAPort { .. }), "{e:?}");
        says(&e, &["Secret", "slot"]);
    }
    assert!(matches!(n.port("A", "Secret"), Err(Error::NotAPort { .. })));
}

#[test]
fn special_connections_need_a_period_above_zero() {
    // S6: every special kind needs a period; zero is an error naming the kind.
    let mut n = node();
    for kind in [
        ConnectionKind::Suppress(Duration::ZERO),
        ConnectionKind::Inhibit(Duration::ZERO),
        ConnectionKind::OverrideIn(Duration::ZERO),
        ConnectionKind::OverrideOut(Duration::ZERO),
        ConnectionKind::WriteInhibit(Duration::ZERO),
    ] {
        let e = connect(&mut n, ("A", "Num"), ("B", "Num"), kind).unwrap_err();
        assert_eq!(e, Error::ZeroPeriod { kind });
        says(&e, &[kind.name(), "period"]);
    }
}

#[test]
fn negative_or_unusable_periods_are_errors() {
    // S6/S8: a period typed wrong is reported, never wrapped to a huge one.
    let e = Duration::try_from_secs_f64(-0.5).unwrap_err();
    assert_eq!(e, Error::NegativePeriod { seconds: -0.5 });
    says(&e, &["-0.5", "negative"]);
    assert!(matches!(Duration::try_from_secs_f64(f64::NAN), Err(Error::InvalidDuration { .. })));
    assert!(matches!(Duration::try_from_secs_f64(f64::INFINITY), Err(Error::InvalidDuration { .. })));
    assert!(matches!(Duration::try_from_secs_f64(1e30), Err(Error::InvalidDuration { .. })));
    assert_eq!(Duration::try_from_secs_f64(0.2).unwrap(), Duration::from_millis(200));
}

#[test]
fn a_positive_span_under_the_clocks_resolution_is_refused_not_read_as_zero() {
    // D6.8: suppress(1e-12) used to be refused with "needs a period above zero", though the
    // period given was above zero: it had been rounded to 0 ns on the way.
    let e = Duration::try_from_secs_f64(1e-12).unwrap_err();
    assert_eq!(e, Error::BelowResolution { seconds: 1e-12 });
    says(&e, &["1e-12 s", "under 1 ns", "at least 1 ns"]);
    assert!(matches!(Duration::try_from_secs_f64(4.9e-10), Err(Error::BelowResolution { .. })));
    // Half a nanosecond and more round to the nearest nanosecond, and zero is zero.
    assert_eq!(Duration::try_from_secs_f64(5e-10).unwrap(), Duration::from_nanos(1));
    assert_eq!(Duration::try_from_secs_f64(1.4e-9).unwrap(), Duration::from_nanos(1));
    assert_eq!(Duration::try_from_secs_f64(0.0).unwrap(), Duration::ZERO);
    assert_eq!(Duration::try_from_secs_f64(-0.0).unwrap(), Duration::ZERO);
    // A rate too high for a 1 ns period is still a bad rate, said as such.
    assert!(matches!(Duration::try_from_hz(1e10), Err(Error::InvalidRate { .. })));
}

#[test]
fn wild_seconds_and_rates_print_compactly_with_the_accepted_range() {
    // A period of 1e300 s used to print as a 301-digit number of seconds, and a rate of
    // 1e-300 Hz as 300 zeros.
    let cases = [
        (Duration::try_from_secs_f64(1e300).unwrap_err(), "1e300 s", "from 0 to 18446744073 s (about 584 years)"),
        (Duration::try_from_secs_f64(-1e300).unwrap_err(), "-1e300 s", "from 0 to 18446744073 s (about 584 years)"),
        (
            Duration::try_from_secs_f64(f64::NAN).unwrap_err(),
            "NaN is not a number of seconds",
            "from 0 to 18446744073 s (about 584 years)",
        ),
        (Duration::try_from_secs_f64(-0.5).unwrap_err(), "-0.5 s", "from 0 to 18446744073 s (about 584 years)"),
        (Duration::try_from_hz(1e-300).unwrap_err(), "1e-300 Hz", "a period from 1 ns to 584 years"),
        (Duration::try_from_hz(1e300).unwrap_err(), "1e300 Hz", "a period from 1 ns to 584 years"),
    ];
    for (e, value, range) in cases {
        says(&e, &[value, range]);
        assert!(e.to_string().len() < 160, "not compact: {e}");
    }
    assert_eq!(ayllu_core::Compact(3600.0).to_string(), "3600");
    assert_eq!(ayllu_core::Compact(0.25).to_string(), "0.25");
    assert_eq!(ayllu_core::Compact(2e6).to_string(), "2e6");
    assert_eq!(ayllu_core::Compact(f64::INFINITY).to_string(), "inf");
}

#[test]
fn rates_must_be_finite_and_above_zero() {
    // S7: ratepersecond(0), negative, NaN or infinite rates are errors; so are rates whose
    // period a Duration cannot hold (D7.4: a period error for a period never written misled).
    for hz in [0.0, -1.0, -0.0, f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 1e-300, 1e-11, 1e300] {
        let mut c = BehaviorClass::new("C");
        let e = c.every_hz("P", hz, |_| {}).unwrap_err();
        assert!(matches!(e, Error::InvalidRate { .. }), "{hz}: {e:?}");
        says(&e, &["rate", "Hz"]);
        assert!(c.processes().is_empty());
        assert!(matches!(Duration::try_from_hz(hz), Err(Error::InvalidRate { .. })));
    }
    let e = BehaviorClass::new("C").every_hz("P", -2.5, |_| {}).unwrap_err();
    says(&e, &["-2.5"]);
    // A zero period given directly is refused too.
    let mut c = BehaviorClass::new("C");
    assert!(c.process("P", Trigger::Periodic(Duration::ZERO), |_| {}).is_err());
}

#[test]
fn duplicate_names_are_refused() {
    // S9: classes, behaviors, registers and processes are named once.
    let mut n = node();
    let e = n.define(BehaviorClass::new("K")).unwrap_err();
    assert_eq!(e, Error::DuplicateName { what: "behavior class", name: "K".into() });
    says(&e, &["K", "behavior class"]);
    let e = n.create("K", "A").unwrap_err();
    assert_eq!(e, Error::DuplicateName { what: "behavior", name: "A".into() });
    says(&e, &["`A`"]);
    let mut c = BehaviorClass::new("C");
    c.port(PortSpec::new("X", 0i64)).unwrap();
    for e in
        [c.port(PortSpec::new("X", 0.0)).unwrap_err(), c.slot("X", 0i64).unwrap_err(), c.monostable("X").unwrap_err()]
    {
        assert!(matches!(&e, Error::DuplicateName { what: "register", .. }), "{e:?}");
        says(&e, &["C.X"]);
    }
    c.every_hz("P", 1.0, |_| {}).unwrap();
    let e = c.every_hz("P", 2.0, |_| {}).unwrap_err();
    assert!(matches!(&e, Error::DuplicateName { what: "process", .. }), "{e:?}");
    says(&e, &["C.P", "process"]);
    n.add_process("A", "Q", Trigger::Periodic(Duration::from_secs(1)), |_| {}).unwrap();
    let e = n.add_process("A", "Q", Trigger::Periodic(Duration::from_secs(1)), |_| {}).unwrap_err();
    says(&e, &["A.Q"]);
}

#[test]
fn empty_and_unknown_names_are_refused() {
    // S9: names must be non-empty and classes defined before use.
    let mut n = node();
    assert!(matches!(n.create("Nope", "X"), Err(Error::UnknownClass { .. })));
    says(&n.create("Nope", "X").unwrap_err(), &["Nope"]);
    assert!(matches!(n.create("K", ""), Err(Error::EmptyName { .. })));
    assert!(matches!(n.define(BehaviorClass::new("")), Err(Error::EmptyName { .. })));
    assert!(matches!(BehaviorClass::new("C").port(PortSpec::new("", 0i64)), Err(Error::EmptyName { .. })));
    let e = n
        .connect(
            &Endpoint::local("A", "Num"),
            &Endpoint::node(NodeId(2), "", "Num"),
            ConnectionKind::Normal,
            ConnectOptions::default(),
        )
        .unwrap_err();
    assert!(matches!(e, Error::EmptyName { what: "behavior" }), "{e:?}");
}

#[test]
fn a_group_cannot_be_a_source() {
    // S10: (group, behavior, port) is only ever a destination.
    let mut n = node();
    let e = n
        .connect(
            &Endpoint::group("Peers", "A", "Num"),
            &Endpoint::local("B", "Num"),
            ConnectionKind::Normal,
            ConnectOptions::default(),
        )
        .unwrap_err();
    assert_eq!(e, Error::GroupSource);
    says(&e, &["group", "source"]);
    // Another node's port as a source needs a request, and the error says so.
    let e = n
        .connect(
            &Endpoint::node(NodeId(9), "A", "Num"),
            &Endpoint::local("B", "Num"),
            ConnectionKind::Normal,
            ConnectOptions::default(),
        )
        .unwrap_err();
    assert!(matches!(e, Error::NotLocal { .. }), "{e:?}");
    says(&e, &["n9:A.Num", "request_connect"]);
}

#[test]
fn windows_belong_to_aggregating_ports_and_must_be_above_zero() {
    // S3/S4: a window on a Normal port is an error that points to lifespans; zero windows and
    // lifespans are refused.
    let mut c = BehaviorClass::new("C");
    let e = c.port(PortSpec::new("N", 0.0).window(Duration::from_millis(10))).unwrap_err();
    assert_eq!(e, Error::WindowOnNormalPort { port: "N".into() });
    says(&e, &["`N`", "lifespan"]);
    let e = c.port(PortSpec::new("M", 0.0).max().window(Duration::ZERO)).unwrap_err();
    assert_eq!(e, Error::ZeroWindow { port: "M".into() });
    says(&e, &["`M`"]);
    assert!(matches!(c.port(PortSpec::new("L", 0.0).lifespan(Duration::ZERO)), Err(Error::ZeroWindow { .. })));
    for kind in [PortKind::Max, PortKind::Min, PortKind::Sum, PortKind::Priority] {
        let name = format!("W{}", kind.name());
        c.port(PortSpec::new(&name, 0.0).kind(kind).window(Duration::from_millis(10))).unwrap();
    }
}

#[test]
fn disconnecting_an_unknown_connection_is_reported() {
    // S9: unknown (or already removed) connection ids are errors naming the id.
    let mut n = node();
    let e = n.disconnect(ConnectionId(4_242)).unwrap_err();
    assert_eq!(e, Error::UnknownConnection { id: 4_242 });
    says(&e, &["4242"]);
    let c = connect(&mut n, ("A", "Num"), ("B", "Num"), ConnectionKind::Normal).unwrap();
    n.disconnect(c).unwrap();
    assert_eq!(n.disconnect(c), Err(Error::UnknownConnection { id: c.0 }));
}

#[test]
fn processes_must_name_registers_of_their_behavior() {
    // S7: a trigger on a port or monostable the behavior does not have is an error.
    let mut c = BehaviorClass::new("C");
    let e = c.on_write("P", Port(99), |_| {}).unwrap_err();
    assert!(matches!(e, Error::UnknownPort { .. }), "{e:?}");
    says(&e, &["C", "99"]);
    let e = c.on_monostable("P", Mono(0), |_| {}).unwrap_err();
    assert!(matches!(e, Error::UnknownPort { .. }), "{e:?}");
    let mut n = node();
    assert!(matches!(
        n.add_process("Ghost", "P", Trigger::Periodic(Duration::from_secs(1)), |_| {}),
        Err(Error::UnknownBehavior { .. })
    ));
}

#[test]
fn bad_handles_inside_a_process_are_refused_not_panics() {
    // S2/S7: a handle that does not belong to the running behavior is refused by cause.
    let mut n = NodeCore::new(NodeId(1));
    let mut c = BehaviorClass::new("C");
    let s = c.slot("S", 0i64).unwrap();
    let out = c.port(PortSpec::new("Out", Value::text(""))).unwrap();
    c.every_hz("P", 1.0, move |ctx| {
        let bad_port = ctx.write(Port(500), 1i64);
        let bad_slot = ctx.set_slot(Slot(500), 1i64).is_err();
        let bad_type = ctx.set_slot(s, "text").is_err();
        let read = ctx.read(Port(500));
        let get = ctx.get(Port(500));
        ctx.reset(Port(500));
        ctx.trigger(Mono(500), Duration::from_secs(1));
        let high = ctx.is_high(Mono(500));
        ctx.write(out, format!("{bad_port:?} {bad_slot} {bad_type} {read} {get:?} {high}")).unwrap();
    })
    .unwrap();
    n.define(c).unwrap();
    n.create("C", "X").unwrap();
    n.poll(ms(0));
    let v = n.read(n.port("X", "Out").unwrap()).unwrap();
    assert_eq!(v, Value::text("Err(UnknownPort) true true false None false"));
}

#[test]
fn every_error_has_a_message() {
    // Errors are std errors with non-empty, distinct messages.
    let errors: Vec<Error> = vec![
        Error::UnknownClass { class: "K".into() },
        Error::UnknownBehavior { behavior: "B".into() },
        Error::UnknownPort { behavior: "B".into(), port: "P".into() },
        Error::NotAPort { behavior: "B".into(), name: "S".into() },
        Error::UnknownConnection { id: 3 },
        Error::UnknownProcess { behavior: "B".into(), process: "Q".into() },
        Error::DuplicateName { what: "behavior", name: "B".into() },
        Error::EmptyName { what: "port" },
        Error::TypeMismatch { what: "port B.P".into(), expected: ValueType::Int, found: ValueType::Text },
        Error::KindNotSupported { kind: PortKind::Sum, ty: ValueType::Bool },
        Error::ZeroPeriod { kind: ConnectionKind::Inhibit(Duration::ZERO) },
        Error::NegativePeriod { seconds: -1.0 },
        Error::InvalidDuration { seconds: f64::NAN },
        Error::InvalidRate { hz: 0.0 },
        Error::ZeroWindow { port: "P".into() },
        Error::WindowOnNormalPort { port: "P".into() },
        Error::GroupSource,
        Error::NotLocal { what: "x".into() },
        Error::TooManyRegisters { behavior: "B".into() },
        Error::Ble { reason: "r".into() },
        Error::Refused { what: "port B.P".into(), cause: DropCause::NotANumber },
    ];
    let msgs: Vec<String> = errors.iter().map(|e| (e as &dyn std::error::Error).to_string()).collect();
    for (e, m) in errors.iter().zip(&msgs) {
        assert!(m.len() > 10, "{e:?} -> `{m}`");
    }
    let mut uniq = msgs.clone();
    uniq.sort();
    uniq.dedup();
    assert_eq!(uniq.len(), msgs.len());
}

#[test]
fn a_periodic_process_with_a_zero_period_is_refused_with_a_clear_error() {
    // S7: the error names the process and says what is wrong (it used to say "rate of inf Hz").
    let mut c = BehaviorClass::new("C");
    let err = c.process("Tick", Trigger::Periodic(Duration::ZERO), |_| {}).unwrap_err();
    assert!(matches!(err, Error::ZeroProcessPeriod { .. }), "{err:?}");
    let text = err.to_string();
    assert!(text.contains("C.Tick") && text.contains("period above zero"), "{text}");
    assert!(!text.contains("inf"), "{text}");
}
