//! The commands that talk to a running team: `list`, `why`, `echo`, `write`.
//!
//! Each one opens the tool's node ([`Client`]), finds the node it is about by HELLO, asks
//! what it needs with control requests, and prints text or JSON on stdout (diagnostics go to
//! stderr, so stdout stays parseable). `write` does not trust a best-effort datagram blindly:
//! after sending it asks the node (WHY) whether the value or window arrived, resends a lost
//! one, and reports a refusal with the node's own reason.

use std::io::Write as _;
use std::sync::{Arc, Mutex};
use std::time::{Duration as StdDuration, Instant as StdInstant};

use ayllu::{
    BehaviorClass, ConnectOptions, ConnectionId, ConnectionKind, ControlBody, Counters, DropCause, Duration, Endpoint,
    Instant, Limits, NodeId, PortReport, PortSpec, ReplyBody, Source, Value, ValueType, WindowKind,
};
use serde_json::json;

use crate::client::{unexpected, Client, SLICE};
use crate::fail::Fail;
use crate::text::{
    human, node_report_json, node_report_text, other_report_text, parse_value, peer_json, peers_table,
    port_report_json, value_json,
};
use crate::{signals, Kind, Net, PortPath, WriteArgs};

/// Waits for a node's answer give up after this long unless `--timeout` says otherwise.
const DEFAULT_TIMEOUT: f64 = 5.0;
/// `list` without a node listens this long for HELLOs unless `--timeout` says otherwise.
const LISTEN: f64 = 1.5;
/// A write that leaves no trace on the port is sent this many times before giving up on a
/// confirmation (port messages are best effort, N1).
const WRITE_ATTEMPTS: u32 = 3;
/// How long `echo` waits for its DISCONNECT to be answered when it stops.
const DISCONNECT_WAIT: StdDuration = StdDuration::from_secs(1);

/// Print to stdout now (a reader may be waiting line by line). A closed stdout is an error.
pub(crate) fn emit(text: &str) -> Result<(), Fail> {
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())?;
    if !text.ends_with('\n') {
        out.write_all(b"\n")?;
    }
    out.flush()?;
    Ok(())
}

fn pretty(j: &serde_json::Value) -> String {
    serde_json::to_string_pretty(j).unwrap_or_else(|_| "null".to_owned())
}

/// `ayllu list`: the nodes heard within the listening time.
pub fn list_nodes(net: &Net) -> Result<(), Fail> {
    signals::install();
    let mut client = Client::open(net, LISTEN)?;
    client.listen();
    let peers = client.peers();
    if peers.is_empty() {
        // Hearing nobody is a failure a script must see (exit 1), with what to check.
        if net.json {
            emit("[]")?;
        }
        return Err(Fail::error(format!("no node heard within {}s; {}", client.timeout(), client.hint())));
    }
    if net.json {
        let now = client.node.now();
        return emit(&pretty(&json!(peers.iter().map(|p| peer_json(p, now)).collect::<Vec<_>>())));
    }
    emit(&peers_table(&peers))
}

/// `ayllu list NODE`: everything the node reports about itself (LIST).
pub fn list_node(node: NodeId, net: &Net) -> Result<(), Fail> {
    signals::install();
    let mut client = Client::open(net, DEFAULT_TIMEOUT)?;
    let peer = client.find(node)?;
    let what = format!("LIST {node}");
    match client.ask(node, ControlBody::List, &what)? {
        ReplyBody::Node(report) if net.json => emit(&pretty(&node_report_json(&report))),
        ReplyBody::Node(report) => emit(&node_report_text(&report, Some(&peer))),
        // An AylluLite node's small LIST.
        ReplyBody::OtherReport(text) if net.json => emit(&text),
        ReplyBody::OtherReport(text) => emit(&other_report_text(&text, &peer)),
        other => Err(unexpected(&what, &other)),
    }
}

/// `ayllu disconnect NODE CONN`: remove connection CONN that NODE owns (e.g. one a killed
/// `echo` left behind).
pub fn disconnect_command(node: NodeId, conn: ConnectionId, net: &Net) -> Result<(), Fail> {
    signals::install();
    let mut client = Client::open(net, DEFAULT_TIMEOUT)?;
    client.find(node)?;
    let what = format!("DISCONNECT {node}'s connection {conn}");
    let request = client.node.core_mut().request_disconnect(node, conn);
    match client.answer(node, request, &what)? {
        ReplyBody::Connection(c) if net.json => emit(&json!({"node": node.0, "disconnected": c.0}).to_string()),
        ReplyBody::Connection(c) => emit(&format!("disconnected {node}'s connection {c}")),
        other => Err(unexpected(&what, &other)),
    }
}

/// An error about an unknown behavior or port, with the nearest names the node has ("did
/// you mean"), asked with LIST. Other errors pass unchanged.
fn with_suggestion(client: &mut Client, node: NodeId, path: &PortPath, fail: Fail) -> Fail {
    let unknown_port = fail.message.contains("has no port named");
    let unknown_behavior = fail.message.contains("no behavior named");
    if !unknown_port && !unknown_behavior {
        return fail;
    }
    let Ok(ReplyBody::Node(report)) = client.ask(node, ControlBody::List, &format!("LIST {node}")) else {
        return fail;
    };
    let suggestion = nearest_port(&path.behavior, &path.port, &report);
    match suggestion {
        Some(s) => Fail { message: format!("{}; did you mean `{s}`?", fail.message), code: fail.code },
        None => fail,
    }
}

/// The port of `report` nearest to `behavior.port`, as its real `BEHAVIOR.Port`: behavior and
/// port are matched together (each case-insensitively and close enough by [`distance_if_close`]),
/// so a suggestion always names a port that exists (`relay.in` gives `RELAY.In`, never the
/// nonexistent `RELAY.in`). The nearest pair wins, by the sum of both distances.
fn nearest_port(behavior: &str, port: &str, report: &ayllu::NodeReport) -> Option<String> {
    report
        .behaviors
        .iter()
        .filter_map(|b| distance_if_close(behavior, &b.name).map(|d| (d, b)))
        .flat_map(|(db, b)| {
            b.ports.iter().filter_map(move |p| {
                distance_if_close(port, &p.name).map(|dp| (db + dp, b.name.as_str(), p.name.as_str()))
            })
        })
        .min()
        .map(|(_, b, p)| format!("{b}.{p}"))
}

/// The case-insensitive edit distance from `name` to `candidate` if close enough to be a
/// likely typo: at most a third of the name's length, and at least 1 allowed.
fn distance_if_close(name: &str, candidate: &str) -> Option<usize> {
    let wanted = name.to_lowercase();
    let d = edit_distance(&wanted, &candidate.to_lowercase());
    (d <= (wanted.chars().count() / 3).max(1)).then_some(d)
}

/// Levenshtein distance between two short names.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diagonal = row[0];
        row[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let above = row[j + 1];
            row[j + 1] = (above + 1).min(row[j] + 1).min(diagonal + usize::from(ca != *cb));
            diagonal = above;
        }
    }
    row[b.len()]
}

fn ask_why(client: &mut Client, node: NodeId, path: &PortPath) -> Result<PortReport, Fail> {
    let what = format!("WHY {node}:{path}");
    let body = ControlBody::Why { behavior: path.behavior.as_str().into(), port: path.port.as_str().into() };
    match client.ask(node, body, &what) {
        Ok(ReplyBody::Port(report)) => Ok(*report),
        Ok(other) => Err(unexpected(&what, &other)),
        Err(fail) => Err(with_suggestion(client, node, path, fail)),
    }
}

/// The port's current value (READ), which tells its type.
pub(crate) fn read(client: &mut Client, node: NodeId, path: &PortPath) -> Result<Value, Fail> {
    let what = format!("READ {node}:{path}");
    let body = ControlBody::Read { behavior: path.behavior.as_str().into(), port: path.port.as_str().into() };
    match client.ask(node, body, &what) {
        Ok(ReplyBody::Value(v)) => Ok(v),
        Ok(other) => Err(unexpected(&what, &other)),
        Err(fail) => Err(with_suggestion(client, node, path, fail)),
    }
}

/// Whether a node's refusal says it is an AylluLite node, which answers READ and LIST only
/// (spec/protocol.md).
fn is_lite_refusal(fail: &Fail) -> bool {
    fail.message.contains("AylluLite")
}

/// `ayllu why NODE BEHAVIOR.PORT`.
pub fn why(node: NodeId, path: &PortPath, net: &Net) -> Result<(), Fail> {
    signals::install();
    let mut client = Client::open(net, DEFAULT_TIMEOUT)?;
    client.find(node)?;
    let report = ask_why(&mut client, node, path)?;
    if net.json {
        emit(&pretty(&port_report_json(&report)))
    } else {
        emit(&report.to_string())
    }
}

/// `ayllu echo NODE BEHAVIOR.PORT`: connect the port to one of ours and print what arrives.
pub fn echo(node: NodeId, path: &PortPath, count: Option<u64>, net: &Net) -> Result<(), Fail> {
    signals::install();
    let mut client = Client::open(net, DEFAULT_TIMEOUT)?;
    client.find(node)?;
    let ty = read(&mut client, node, path)?.ty();

    // A local port of the same type, and a process that records every value it accepts.
    let arrived: Arc<Mutex<Vec<(Instant, Value)>>> = Arc::default();
    let sink = arrived.clone();
    let mut class = BehaviorClass::new("Echo");
    let input = class.port(PortSpec::new("In", Value::zero(ty)))?;
    class.on_write("Record", input, move |ctx| {
        let value = ctx.read(input);
        sink.lock().unwrap_or_else(|e| e.into_inner()).push((ctx.now(), value));
    })?;
    client.node.define(class)?;
    client.node.create("Echo", "ECHO")?;

    let conn = client.copy_port(node, (&path.behavior, &path.port), ("ECHO", "In"))?;
    eprintln!("echo: {node}:{path} ({ty}) -> {}:ECHO.In as {node}'s connection {conn}", client.id());
    if net.timeout.is_none() {
        // Without --timeout, echo runs until --count values or Ctrl-C.
        client.set_deadline(None);
    }

    let started = client.node.now();
    let mut got = 0u64;
    let mut printed: Result<(), Fail> = Ok(());
    'run: while !client.expired() && !signals::stopped() {
        client.pump(SLICE);
        let batch: Vec<(Instant, Value)> = std::mem::take(&mut *arrived.lock().unwrap_or_else(|e| e.into_inner()));
        for (t, v) in batch {
            // Milliseconds are plenty for people and scripts; nanosecond digits are noise.
            let secs = (t.saturating_since(started).as_secs_f64() * 1000.0).round() / 1000.0;
            let line = if net.json {
                json!({"t": secs, "node": node.0, "port": path.to_string(), "type": ty.name(), "value": value_json(&v)})
                    .to_string()
            } else {
                format!("{secs:>9.3}  {}", human(&v))
            };
            printed = emit(&line);
            got += 1;
            if printed.is_err() || count.is_some_and(|n| got >= n) {
                break 'run;
            }
        }
    }

    // Leave the node as we found it, also after Ctrl-C or a closed stdout.
    disconnect(&mut client, node, conn);
    printed?;
    match count {
        Some(n) if got < n => {
            let why =
                if signals::stopped() { "before Ctrl-C".to_owned() } else { format!("within {}s", client.timeout()) };
            Err(Fail::error(format!("only {got} of {n} values arrived from {node}:{path} {why}")))
        }
        _ => Ok(()),
    }
}

pub(crate) fn disconnect(client: &mut Client, node: NodeId, conn: ConnectionId) {
    client.honour_stop = false;
    client.set_deadline(Some(StdInstant::now() + DISCONNECT_WAIT));
    let request = client.node.core_mut().request_disconnect(node, conn);
    if let Err(e) = client.answer(node, request, &format!("DISCONNECT {node}'s connection {conn}")) {
        eprintln!("ayllu: warning: {}; the connection may stay on {node}", e.message);
    }
}

/// What a WHY report says about one of our writes.
#[derive(Debug, PartialEq)]
enum Verdict {
    /// The value (and the kind's window) is there, from us.
    Confirmed,
    /// The port would not take the value: why.
    Refused(DropCause),
    /// No trace: lost, or already replaced by another writer.
    Unseen,
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

fn judge(report: &PortReport, kind: ConnectionKind, me: Source) -> Verdict {
    let window = window_kind(kind).is_none_or(|k| report.windows.iter().any(|w| w.kind == k && w.holder == me));
    let supplied = !kind.writes() || report.supplier == Some(me);
    if window && supplied {
        return Verdict::Confirmed;
    }
    if kind.writes() && window {
        // `input_blocked` is for a connection without a pass; our own override-in holds one,
        // so only a suppression refuses it.
        let cause = match kind {
            ConnectionKind::OverrideIn(_) => report.input_blocked.filter(|c| *c == DropCause::Suppressed),
            _ => report.input_blocked,
        };
        if let Some(cause) = cause {
            return Verdict::Refused(cause);
        }
    }
    Verdict::Unseen
}

/// What a node refuses before a port message reaches the port: the message leaves no trace on
/// the port, no answer comes back (port messages have none), and the node only counts it,
/// node-wide, under one of these.
const NODE_REFUSALS: [DropCause; 2] = [DropCause::TooLong, DropCause::NotAllowed];

/// Whether the node counted this write's resends as refused before the port ([`NODE_REFUSALS`]).
/// Its counters (LIST) are read after the first unseen send (`counts` keeps them, with how many
/// sends had gone), and again after each resend: a cause that rose by at least the resends is
/// the node's reason. Another sender's refusals can only add to the count, and a resend lost on
/// the way adds nothing, so a loss is never taken for a refusal. A node that does not answer
/// LIST gives no reason (`None`).
fn dropped_by_node(
    client: &mut Client,
    node: NodeId,
    counts: &mut Option<(Counters, u32)>,
    sent: u32,
) -> Option<DropCause> {
    let now = match client.ask(node, ControlBody::List, &format!("LIST {node}")) {
        Ok(ReplyBody::Node(report)) => report.counters,
        _ => return None,
    };
    let (before, sent_before) = counts.replace((now.clone(), sent))?;
    let resends = u64::from(sent - sent_before);
    NODE_REFUSALS.into_iter().find(|&c| now.get(c).saturating_sub(before.get(c)) >= resends)
}

/// The message for a write the node refused before its port, with what to change.
fn node_refusal(
    node: NodeId,
    path: &PortPath,
    value: &Value,
    kind: ConnectionKind,
    cause: DropCause,
    me: NodeId,
) -> String {
    let why = match (cause, kind.period()) {
        (DropCause::TooLong, Some(period)) => format!(
            "its {} window of {period} is longer than the node takes from the network (its --max-window, {} \
             unless set); use a shorter --period",
            kind.name(),
            Limits::default().max_remote_period
        ),
        (DropCause::NotAllowed, _) => {
            format!("the node does not let {me} write its ports (its --allow-write)")
        }
        _ => "the node refused it before the port".to_owned(),
    };
    format!("{node}:{path} refused {}: {why}; counted as `{cause}` (see `ayllu list {}`)", human(value), node.0)
}

/// The windows behind a refusal, for the message: "suppress by n7/c1 for 2.1s more".
fn blockers(report: &PortReport, cause: DropCause) -> String {
    let kind = match cause {
        DropCause::Suppressed => WindowKind::Suppress,
        DropCause::OverriddenIn => WindowKind::OverrideIn,
        _ => return String::new(),
    };
    let held: Vec<String> = report
        .windows
        .iter()
        .filter(|w| w.kind == kind)
        .map(|w| format!("{} by {} for {} more", w.kind.name(), w.holder, w.remaining))
        .collect();
    if held.is_empty() {
        String::new()
    } else {
        format!(": {}", held.join("; "))
    }
}

/// The end of `write` to an AylluLite node, which has no WHY: the value is checked by READ
/// (a lite port has no windows to check), and the answer says "unconfirmed (lite)" when READ
/// does not show it. Exit 0 either way: the datagram went out.
fn write_lite(
    client: &mut Client,
    args: &WriteArgs,
    value: &Value,
    kind: ConnectionKind,
    me: Source,
    ty: ValueType,
) -> Result<(), Fail> {
    let (node, path) = (args.node, &args.target);
    let confirmed = kind.writes() && read(client, node, path).is_ok_and(|v| v == *value);
    let verdict = if confirmed { "confirmed by READ (lite)" } else { "unconfirmed (lite)" };
    if args.net.json {
        return emit(
            &json!({
                "node": node.0, "port": path.to_string(), "type": ty.name(), "value": value_json(value),
                "kind": kind.name(), "source": me.to_string(), "sent": 1, "confirmed": confirmed, "lite": true,
            })
            .to_string(),
        );
    }
    emit(&format!(
        "wrote {} to {node}:{path} along {kind} as {me}: {verdict} ({node} is an AylluLite node: no WHY)",
        human(value)
    ))
}

/// `ayllu write NODE BEHAVIOR.PORT VALUE`.
pub fn write(args: &WriteArgs) -> Result<(), Fail> {
    let (node, path, net) = (args.node, &args.target, &args.net);
    let kind = match (args.kind, args.period) {
        (Kind::Normal, Some(_)) => {
            return Err(Fail::usage(
                "--period applies to suppress, inhibit, override-in, override-out and write-inhibit, not normal",
            ))
        }
        (Kind::Normal, None) => ConnectionKind::Normal,
        (k, p) => k.with_period(Duration::try_from_secs_f64(p.unwrap_or(1.0))?),
    };
    if let (Some(hz), Some(period)) = (args.repeat_hz, kind.period()) {
        if period.as_secs_f64() < 1.0 / hz {
            eprintln!(
                "ayllu: warning: the {} window ({period}) is shorter than the gap between writes ({:.3}s): \
                 it will lapse between them",
                kind.name(),
                1.0 / hz
            );
        }
    }
    signals::install();
    let mut client = Client::open(net, DEFAULT_TIMEOUT)?;
    client.find(node)?;
    let ty: ValueType = read(&mut client, node, path)?.ty();
    let value = parse_value(ty, &args.value).map_err(|e| {
        Fail::error(format!("cannot use `{}` as a value of {node}:{path}, which holds {ty}: {e}", args.value))
    })?;

    // Our side of the connection: a port of the same type, connected to theirs.
    let mut class = BehaviorClass::new("Writer");
    class.port(PortSpec::new("Out", Value::zero(ty)))?;
    client.node.define(class)?;
    client.node.create("Writer", "WRITE")?;
    let conn = client.node.core_mut().connect(
        &Endpoint::local("WRITE", "Out"),
        &Endpoint::node(node, &path.behavior, &path.port),
        kind,
        ConnectOptions { priority: args.priority },
    )?;
    let me = Source::connection(client.id(), conn);

    // Send, then ask whether it arrived; resend what was lost.
    let mut sent = 0u32;
    let mut report;
    let mut node_counts = None;
    loop {
        client.node.write("WRITE", "Out", value.clone())?;
        sent += 1;
        report = match ask_why(&mut client, node, path) {
            Ok(r) => r,
            Err(fail) if is_lite_refusal(&fail) => {
                return write_lite(&mut client, args, &value, kind, me, ty);
            }
            Err(fail) => return Err(fail),
        };
        match judge(&report, kind, me) {
            Verdict::Confirmed => break,
            Verdict::Refused(cause) => {
                return Err(Fail::error(format!(
                    "{node}:{path} refused {value}: its input is blocked ({cause}{}); counted as `{cause}` \
                     (see `ayllu why {node} {path}`)",
                    blockers(&report, cause)
                )));
            }
            Verdict::Unseen => {
                if let Some(cause) = dropped_by_node(&mut client, node, &mut node_counts, sent) {
                    return Err(Fail::error(node_refusal(node, path, &value, kind, cause, client.id())));
                }
                if sent >= WRITE_ATTEMPTS || client.expired() {
                    break;
                }
            }
        }
    }
    let confirmed = judge(&report, kind, me) == Verdict::Confirmed;

    // Hold: write again at the requested rate.
    let mut repeated = 0u64;
    let started = StdInstant::now();
    if let Some(hz) = args.repeat_hz {
        client.set_deadline(args.for_secs.map(|s| started + StdDuration::from_secs_f64(s)));
        let interval = StdDuration::from_secs_f64(1.0 / hz);
        let mut next = started + interval;
        'hold: loop {
            loop {
                let now = StdInstant::now();
                if client.expired() || signals::stopped() {
                    break 'hold;
                }
                if now >= next {
                    break;
                }
                client.pump((next - now).min(SLICE));
            }
            client.node.write("WRITE", "Out", value.clone())?;
            repeated += 1;
            // Late (a slow machine): keep the rate, do not burst to catch up.
            next = (next + interval).max(StdInstant::now());
        }
        // Send the last one before leaving.
        client.node.run_for(StdDuration::ZERO);
    }

    if net.json {
        return emit(
            &json!({
                "node": node.0,
                "port": path.to_string(),
                "type": ty.name(),
                "value": value_json(&value),
                "kind": kind.name(),
                "period": kind.period().map(|p| p.as_secs_f64()),
                "priority": args.priority,
                "source": me.to_string(),
                "sent": u64::from(sent) + repeated,
                "confirmed": confirmed,
                "held_secs": args.repeat_hz.map(|_| started.elapsed().as_secs_f64()),
            })
            .to_string(),
        );
    }
    // A priority other than the default decides at a Priority port (D3.3): said, as the
    // holder's is when the write did not take.
    let at = if args.priority == 0 { String::new() } else { format!(" at priority {}", args.priority) };
    let mut line = format!("wrote {} to {node}:{path} along {kind}{at} as {me}: ", human(&value));
    if confirmed {
        line.push_str("confirmed");
    } else {
        let holder = report.supplier.map_or("nobody".to_owned(), |s| s.to_string());
        let holder = match report.supplier_priority {
            Some(p) => format!("{holder} at priority {p}"),
            None => holder,
        };
        line.push_str(&format!(
            "sent {sent} times, not confirmed (the port holds {} from {holder}; \
             a busy port may have replaced it, an aggregating one may have kept its own)",
            report.value
        ));
    }
    if args.repeat_hz.is_some() {
        line.push_str(&format!("; then {repeated} more over {:.1}s", started.elapsed().as_secs_f64()));
    }
    emit(&line)
}

#[cfg(test)]
mod tests {
    use super::*;
    use ayllu::{PortKind, WindowReport};

    fn report(windows: Vec<WindowReport>, supplier: Option<Source>, input_blocked: Option<DropCause>) -> PortReport {
        PortReport {
            node: NodeId(1),
            now: Instant::ZERO,
            behavior: "B".into(),
            port: "P".into(),
            kind: PortKind::Normal,
            ty: ValueType::Int,
            value: Value::Int(0),
            fresh: true,
            empty: false,
            last_accepted: None,
            supplier,
            supplier_priority: None,
            released_in: None,
            accepted: 0,
            windows,
            input_blocked,
            internal_output_blocked: None,
            connection_output_blocked: None,
            counters: Counters::default(),
            incoming: vec![],
            outgoing: vec![],
            triggers: vec![],
        }
    }

    fn window(kind: WindowKind, holder: Source) -> WindowReport {
        WindowReport { kind, holder, ends: Instant::from_secs(1), remaining: Duration::from_secs(1) }
    }

    const ME: Source = Source { node: NodeId(9), conn: 1 };
    const OTHER: Source = Source { node: NodeId(8), conn: 1 };
    const P: Duration = Duration::from_secs(1);

    #[test]
    fn a_normal_write_is_confirmed_by_its_supplier_and_refused_by_a_block() {
        assert_eq!(judge(&report(vec![], Some(ME), None), ConnectionKind::Normal, ME), Verdict::Confirmed);
        assert_eq!(judge(&report(vec![], Some(OTHER), None), ConnectionKind::Normal, ME), Verdict::Unseen);
        let suppressed = report(vec![window(WindowKind::Suppress, OTHER)], None, Some(DropCause::Suppressed));
        assert_eq!(judge(&suppressed, ConnectionKind::Normal, ME), Verdict::Refused(DropCause::Suppressed));
    }

    #[test]
    fn windowed_kinds_are_confirmed_by_their_window() {
        let r = report(vec![window(WindowKind::Inhibit, ME)], None, None);
        assert_eq!(judge(&r, ConnectionKind::Inhibit(P), ME), Verdict::Confirmed);
        assert_eq!(judge(&r, ConnectionKind::Suppress(P), ME), Verdict::Unseen);
        let ours = report(vec![window(WindowKind::OverrideIn, ME)], Some(ME), Some(DropCause::OverriddenIn));
        assert_eq!(judge(&ours, ConnectionKind::OverrideIn(P), ME), Verdict::Confirmed);
        // Our override-in opened but a suppression refused the value itself.
        let both = report(
            vec![window(WindowKind::OverrideIn, ME), window(WindowKind::Suppress, OTHER)],
            None,
            Some(DropCause::Suppressed),
        );
        assert_eq!(judge(&both, ConnectionKind::OverrideIn(P), ME), Verdict::Refused(DropCause::Suppressed));
    }
}
