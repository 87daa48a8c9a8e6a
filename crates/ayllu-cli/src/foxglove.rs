//! `ayllu foxglove` (the live team in Foxglove, over its WebSocket protocol) and `sim run
//! --mcap` (a run as an MCAP file): arguments and printing only; the machinery is the
//! `ayllu-foxglove` crate (docs/cli.md, "ayllu foxglove").
//!
//! `ayllu foxglove` prints, once the server listens, one JSON line saying where
//! (`{"listening":"ws://127.0.0.1:8765","port":8765,...}`, so `--port 0` can be found), then a
//! status line every `--status-ms`; it runs until `--for` ends or Ctrl-C.

use std::io::Write as _;
use std::path::PathBuf;
use std::time::{Duration as StdDuration, Instant as StdInstant};

use ayllu::NodeId;
use ayllu_foxglove::{LiveServer, WatchConfig};
use clap::Args;
use serde_json::json;

use crate::fail::Fail;
use crate::{parse_node, positive_hz, positive_secs, signals};

/// `ayllu foxglove`.
#[derive(Args, Debug)]
pub struct FoxgloveArgs {
    /// The tool's own udp:// URL, as for the other commands (team, key, discovery=, peer=);
    /// or another scheme the tool knows (zenoh:// in ayllu-zenoh, docs/zenoh.md).
    #[arg(long, value_name = "URL", default_value_t = ayllu::default_url())]
    pub udp: String,
    /// The address the WebSocket server listens on (0.0.0.0: every interface).
    #[arg(long, value_name = "ADDR", default_value = "127.0.0.1")]
    pub host: String,
    /// The WebSocket port (Foxglove's default 8765; 0: any free port, printed first).
    #[arg(long, default_value_t = 8765)]
    pub port: u16,
    /// Ask every node for all its port values (LIST) this often.
    #[arg(long, value_name = "HZ", default_value_t = 5.0, value_parser = positive_hz)]
    pub hz: f64,
    /// Ask each node at most this many WHY a second (windows and BLE claims).
    #[arg(long, value_name = "HZ", default_value_t = 20.0, value_parser = positive_hz)]
    pub why_hz: f64,
    /// Also write every channel to this new MCAP file (closed on exit).
    #[arg(long, value_name = "FILE")]
    pub mcap: Option<PathBuf>,
    /// Stop after this many seconds (default: until Ctrl-C).
    #[arg(long = "for", value_name = "SECS", value_parser = positive_secs)]
    pub for_secs: Option<f64>,
    /// Print a JSON status line this often.
    #[arg(long, value_name = "MS", default_value_t = 1000, value_parser = clap::value_parser!(u64).range(1..))]
    pub status_ms: u64,
    /// Replace the tool's own node after this many requests (0: never; for a test that a watch
    /// survives losing its node's state).
    #[arg(long, value_name = "N", default_value_t = ayllu_foxglove::team_watch::RENEW_AFTER, hide = true)]
    pub renew_after: u64,
    /// This tool's node id (default 0x7fff0000 + the process id's low 16 bits).
    #[arg(long, value_name = "NODE", value_parser = parse_node)]
    pub id: Option<NodeId>,
}

fn emit(line: &serde_json::Value) -> Result<(), Fail> {
    let mut out = std::io::stdout().lock();
    writeln!(out, "{line}")?;
    out.flush()?;
    Ok(())
}

/// `ayllu foxglove`.
pub fn serve(args: &FoxgloveArgs) -> Result<(), Fail> {
    signals::install();
    crate::client::network_url(&args.udp)?;
    let config = WatchConfig {
        url: args.udp.clone(),
        id: args.id.unwrap_or_else(crate::client::default_id),
        list_hz: args.hz,
        why_hz: args.why_hz,
        renew_after: args.renew_after,
    };
    config.check().map_err(Fail::usage)?;
    if let Some(path) = &args.mcap {
        check_new_file(path)?;
    }
    // The watcher talks to every node it hears: an --id one of them has would hide that node.
    let net = crate::Net { udp: args.udp.clone(), timeout: None, json: false, id: args.id };
    crate::client::refuse_a_heard_nodes_id(&net)?;
    let mut server = LiveServer::start(config, &args.host, args.port, args.mcap.as_deref())
        .map_err(|e| Fail::error(format!("foxglove: {e}")))?;
    let port = server.port();
    emit(&json!({
        "listening": format!("ws://{}:{port}", args.host),
        "port": port,
        "udp": server.watch().address(),
        "node": args.id.unwrap_or_else(crate::client::default_id).0,
        "mcap": args.mcap.as_ref().map(|p| p.display().to_string()),
    }))?;
    let started = StdInstant::now();
    let end = args.for_secs.map(|s| started + StdDuration::from_secs_f64(s));
    let period = StdDuration::from_millis(args.status_ms);
    let mut printed = Ok(());
    while !signals::stopped() && end.is_none_or(|e| StdInstant::now() < e) {
        let slice = end.map_or(period, |e| period.min(e.saturating_duration_since(StdInstant::now())));
        server.run_for(slice);
        let c = server.watch().counts();
        printed = emit(&json!({
            "t": (started.elapsed().as_secs_f64() * 1000.0).round() / 1000.0,
            "nodes": server.watch().nodes().iter().map(|n| n.0).collect::<Vec<_>>(),
            "topics": server.topics(),
            "published": server.published(),
            "clients": server.clients(),
            "requests": c.requests,
            "answers": c.answers,
            "failed": c.failed,
            "renewals": c.renewals,
        }));
        if printed.is_err() {
            break;
        }
    }
    // The MCAP file is finished also after Ctrl-C or a closed stdout.
    let writing = args.mcap.as_ref().map_or(String::new(), |p| format!(" (writing {})", p.display()));
    server.stop().map_err(|e| Fail::error(format!("foxglove: closing{writing}: {e}")))?;
    printed
}

/// `--mcap FILE` must be a new file the tool can create: checked (by creating it, then removing
/// it for the server to create) before anything goes on the network, so that the message names
/// the file. The server's own error for it says only what the system said.
fn check_new_file(path: &std::path::Path) -> Result<(), Fail> {
    match std::fs::OpenOptions::new().write(true).create_new(true).open(path) {
        Ok(file) => {
            drop(file);
            std::fs::remove_file(path).map_err(|e| Fail::error(format!("cannot create {}: {e}", path.display())))
        }
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Err(Fail::error(format!(
            "{} exists (an MCAP file is never replaced): move or remove it, or give --mcap another file",
            path.display()
        ))),
        Err(e) => Err(Fail::error(format!("cannot create {}: {e}", path.display()))),
    }
}

/// `sim run FILE --mcap OUT`: the run written to a new MCAP file; prints what was written on
/// stderr (stdout keeps the metrics).
pub fn run_to_mcap(
    scenario: &ayllu_sim::scenario::Scenario,
    path: &std::path::Path,
) -> Result<ayllu_sim::scenario::Outcome, Fail> {
    let (outcome, summary) =
        ayllu_foxglove::run_to_mcap(scenario, path).map_err(|e| Fail::error(format!("{}: {e}", path.display())))?;
    eprintln!(
        "wrote {}: {} frames, {} messages on {} topics (open it in Foxglove: Open local file)",
        path.display(),
        summary.frames,
        summary.messages,
        summary.topics
    );
    Ok(outcome)
}
