//! `ayllu hz NODE BEHAVIOR.PORT`: the rate of a port's messages, its jitter, its gaps and the
//! messages lost on the way, like `ros2 topic hz`. It connects the port to one of its own as
//! `echo` does (CONNECT, DISCONNECT on exit), watches the arrivals through a
//! `team_recording::Tap` (which sees the connection's sequence numbers, hence losses) and
//! feeds `crate::rate`.

use std::time::{Duration as StdDuration, Instant as StdInstant};

use crate::rate::{Arrival, RateReport, RateWindow};
use ayllu::team_recording::{HeardLog, Tap};
use ayllu::{BehaviorClass, NodeId, PortSpec, Value};
use clap::Args;

use crate::client::{Client, SLICE};
use crate::commands::{disconnect, emit, read};
use crate::fail::Fail;
use crate::{parse_node, parse_port_path, positive_secs, signals, Net, PortPath};

#[derive(Args, Debug)]
pub struct HzArgs {
    /// The node: its id (3, n3 or 0x3).
    #[arg(value_parser = parse_node)]
    pub node: NodeId,
    /// BEHAVIOR.PORT
    #[arg(value_parser = parse_port_path)]
    pub target: PortPath,
    /// Figures over the last N messages.
    #[arg(long, default_value_t = 10_000, value_parser = clap::value_parser!(u64).range(2..=10_000_000))]
    pub window: u64,
    /// Print a report this often.
    #[arg(long, value_name = "SECS", default_value_t = 1.0, value_parser = positive_secs)]
    pub every: f64,
    /// A gap is an interval longer than this many times the median interval.
    #[arg(long, default_value_t = 3.0, value_parser = positive_secs)]
    pub gap_factor: f64,
    /// Stop after this many messages.
    #[arg(long, value_parser = clap::value_parser!(u64).range(2..))]
    pub count: Option<u64>,
    /// Stop after this many seconds (default: run until Ctrl-C or --count).
    #[arg(long = "for", value_name = "SECS", value_parser = positive_secs)]
    pub for_secs: Option<f64>,
    #[command(flatten)]
    pub net: Net,
}

fn report_text(r: &RateReport, total: u64) -> String {
    let mut s = format!(
        "average rate: {:.3}\n\tmin: {:.4}s max: {:.4}s std dev: {:.5}s window: {}\n\tmessages: {total}, lost: {}, out of order: {}, gaps: {}",
        r.rate_hz, r.min, r.max, r.std_dev, r.count, r.lost, r.out_of_order, r.gaps.len()
    );
    for g in r.gaps.iter().rev().take(3) {
        s.push_str(&format!("\n\tgap of {:.3}s at {:.3}s", g.length, g.after));
    }
    s
}

fn report_json(r: &RateReport, total: u64, t: f64) -> String {
    serde_json::json!({
        "t": (t * 1000.0).round() / 1000.0, "rate_hz": r.rate_hz, "mean": r.mean, "min": r.min, "max": r.max,
        "std_dev": r.std_dev, "median": r.median, "window": r.count, "messages": total, "lost": r.lost,
        "out_of_order": r.out_of_order,
        "gaps": r.gaps.iter().map(|g| serde_json::json!({"after": g.after, "length": g.length})).collect::<Vec<_>>(),
    })
    .to_string()
}

/// `ayllu hz NODE BEHAVIOR.PORT`.
pub fn hz(args: &HzArgs) -> Result<(), Fail> {
    let (node, path, net) = (args.node, &args.target, &args.net);
    signals::install();
    let mut log = HeardLog::default();
    let mut client = Client::open_with(net, 5.0, |t| {
        let (tap, heard) = Tap::new(t);
        log = heard;
        tap
    })?;
    client.find(node)?;
    let ty = read(&mut client, node, path)?.ty();
    let mut class = BehaviorClass::new("Hz");
    class.port(PortSpec::new("In", Value::zero(ty)))?;
    client.node.define(class)?;
    client.node.create("Hz", "HZ")?;
    let conn = client.copy_port(node, (&path.behavior, &path.port), ("HZ", "In"))?;
    eprintln!("hz: {node}:{path} ({ty}) -> {}:HZ.In as {node}'s connection {conn}", client.id());

    let started = StdInstant::now();
    let t0 = ayllu::team_recording::unix_nanos_now();
    let end = args.for_secs.map(|s| started + StdDuration::from_secs_f64(s));
    client.set_deadline(end);
    let every = StdDuration::from_secs_f64(args.every);
    let mut next_report = started + every;
    let window_len = usize::try_from(args.window).unwrap_or(usize::MAX);
    let mut window = RateWindow::new(window_len, args.gap_factor);
    let mut total = 0u64;
    let mut printed = Ok(());
    'run: while !client.expired() && !signals::stopped() {
        client.pump(SLICE);
        for h in log.take() {
            if h.from != node || h.conn != conn.0 {
                continue;
            }
            // Arrival times from the tap's wall clock, in seconds since hz connected.
            let t = h.unix_nanos.saturating_sub(t0) as f64 / 1e9;
            window.push(Arrival { t, seq: Some(h.seq) });
            total += 1;
            if args.count.is_some_and(|n| total >= n) {
                break 'run;
            }
        }
        if StdInstant::now() >= next_report {
            next_report += every;
            if window.len() < 2 {
                eprintln!("hz: {total} messages so far");
                continue;
            }
            let r = window.report();
            printed = if net.json {
                emit(&report_json(&r, total, started.elapsed().as_secs_f64()))
            } else {
                emit(&report_text(&r, total))
            };
            if printed.is_err() {
                break;
            }
        }
    }
    disconnect(&mut client, node, conn);
    printed?;
    if window.len() < 2 {
        return Err(Fail::error(format!("{total} message(s) arrived from {node}:{path}: no rate to report")));
    }
    let r = window.report();
    let out = if net.json {
        report_json(&r, total, started.elapsed().as_secs_f64())
    } else {
        format!("final: {}", report_text(&r, total))
    };
    emit(&out)
}
