//! `ayllu` — the command-line tool for a running Ayllu team (docs/cli.md).
//!
//! It joins the team's network as a small node of its own (udp://, an ephemeral port, a high
//! node id), finds the other nodes by their HELLO, and asks them with control requests: LIST
//! (`list NODE`), WHY (`why`), READ (`echo`, `write`: to learn a port's type), CONNECT and
//! DISCONNECT (`echo`). `write` connects a port of its own to the remote one, with any
//! connection kind, so an engineer can suppress, inhibit or override a robot's port by hand.
//! `ayllu node` runs a whole node hosting a standard controller; the multi-process tests start
//! it. `ayllu shape` (Linux) joins network namespaces through a userspace shaper that delays,
//! jitters, reorders, duplicates and drops the frames between them.
//!
//! Promises:
//! * exit code 0 when the command did what it says; 1 with one message on stderr when it could
//!   not (no such node, the node refused, a value that does not parse); 2 for usage errors;
//! * no panic ever shows a backtrace (a bug prints one line and exits 1);
//! * every wait is bounded by `--timeout`, except those the user ends (Ctrl-C, `--for`);
//!   Ctrl-C still disconnects what `echo` connected.

mod client;
mod commands;
mod controllers;
mod fail;
#[cfg(target_os = "linux")]
mod shape;
mod signals;
mod sim_cmommt;
mod sim_files;
mod sim_serve;
mod text;

use std::process::ExitCode;

use ayllu::{ConnectionId, ConnectionKind, NodeId};
use clap::{Args, Parser, Subcommand, ValueEnum};

use crate::fail::Fail;

#[derive(Parser, Debug)]
#[command(name = "ayllu", version, about = "Inspect and drive a running Ayllu team over udp://")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// How the tool reaches the team, shared by the commands that talk to it.
#[derive(Args, Debug, Clone)]
pub struct Net {
    /// This tool's own udp:// URL: where it binds, its team and key, and how it finds the
    /// nodes (discovery=, peer=ADDR:PORT, broadcast=ADDR:PORT). Default: $AYLLU_URL, else
    /// discovery on this machine (docs/cli.md).
    #[arg(long, value_name = "URL", default_value_t = ayllu::default_url())]
    pub udp: String,
    /// Give up after this many seconds (default 5; `list` without NODE listens 1.5).
    #[arg(long, value_name = "SECS", value_parser = positive_secs)]
    pub timeout: Option<f64>,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// This tool's node id (default 0x7fff0000 + the process id's low 16 bits).
    #[arg(long, value_name = "NODE", value_parser = parse_node)]
    pub id: Option<NodeId>,
}

/// `BEHAVIOR.PORT`.
#[derive(Clone, Debug, PartialEq)]
pub struct PortPath {
    pub behavior: String,
    pub port: String,
}

impl std::fmt::Display for PortPath {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}.{}", self.behavior, self.port)
    }
}

#[derive(Subcommand, Debug)]
enum SimCommand {
    /// Run W-CMOMMT (the paper's section 4) for BLE and every baseline: the paper's setting, a
    /// sweep and a robustness scenario; print the tables and write a report folder.
    Cmommt(sim_cmommt::CmommtArgs),
    /// Host a simulated world and expose each robot's body (VISION, SONAR, BASE) over udp://.
    Serve(sim_serve::ServeArgs),
    /// Run one robot's controller as its own process, driving a body that `sim serve` hosts.
    Robot(sim_serve::RobotArgs),
    /// Run one scenario written as a TOML file (any field of the simulator's scenario).
    Run(sim_files::RunArgs),
    /// Run a sweep written as a TOML file (a scenario, seeds, controllers and a grid of
    /// fields); print the means and write every run as runs.csv / runs.jsonl.
    Sweep(sim_files::SweepArgs),
}

#[derive(Subcommand, Debug)]
enum Command {
    /// List the nodes heard on the network, or describe one node (behaviors, ports,
    /// connections, groups, counters).
    List {
        /// A node id (`3`, `n3` or `0x3`). Without it, list every node heard.
        #[arg(value_parser = parse_node)]
        node: Option<NodeId>,
        #[command(flatten)]
        net: Net,
    },
    /// Explain one port: value, supplier, freshness, windows, what is blocked, counters.
    Why {
        /// The node: its id (3, n3 or 0x3).
        #[arg(value_parser = parse_node)]
        node: NodeId,
        /// BEHAVIOR.PORT
        #[arg(value_parser = parse_port_path)]
        target: PortPath,
        #[command(flatten)]
        net: Net,
    },
    /// Print the values a port sends, as they arrive (connects to it; disconnects on exit).
    Echo {
        /// The node: its id (3, n3 or 0x3).
        #[arg(value_parser = parse_node)]
        node: NodeId,
        /// BEHAVIOR.PORT
        #[arg(value_parser = parse_port_path)]
        target: PortPath,
        /// Stop after this many values (it is an error if fewer arrive before --timeout).
        #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
        count: Option<u64>,
        #[command(flatten)]
        net: Net,
    },
    /// Remove a connection a node owns (`list NODE` shows them; e.g. one a killed `echo` left).
    Disconnect {
        /// The node: its id (3, n3 or 0x3).
        #[arg(value_parser = parse_node)]
        node: NodeId,
        /// The connection's id on that node (`c4` or `4`).
        #[arg(value_parser = parse_connection)]
        connection: ConnectionId,
        #[command(flatten)]
        net: Net,
    },
    /// Write a port along a connection of any kind (once, or repeatedly to hold an
    /// inhibition or override by hand).
    Write(WriteArgs),
    /// Run a node hosting a standard controller, printing a JSON status line periodically.
    Node(NodeArgs),
    /// Make an operator key pair: the secret goes to a new file FILE (for tools:
    /// `operator_secret=FILE` in their URL); the public key is printed (for robots:
    /// `operator=KEY`, so that only the operator may rewire them).
    Keygen {
        /// Where to write the secret (must not exist yet).
        file: std::path::PathBuf,
    },
    /// The simulator: the paper's multi-target observation task (`cmommt`), and the
    /// distributed mode (`serve` the world, run each `robot` controller as its own process).
    #[command(subcommand)]
    Sim(SimCommand),
    /// Join network namespaces through TAP interfaces and pass the frames between them with
    /// seeded delay, jitter, reordering, duplication and loss (a userspace netem; needs root).
    #[cfg(target_os = "linux")]
    Shape(shape::ShapeArgs),
}

#[derive(Args, Debug)]
pub struct WriteArgs {
    /// The node: its id (3, n3 or 0x3).
    #[arg(value_parser = parse_node)]
    pub node: NodeId,
    /// BEHAVIOR.PORT
    #[arg(value_parser = parse_port_path)]
    pub target: PortPath,
    /// The value, read as the port's type: true/false, 42, 0.5, text, bytes as hex
    /// (0a0b or 0x0a0b), a vector as a comma list (1,2.5,3).
    #[arg(allow_hyphen_values = true)]
    pub value: String,
    /// The connection kind.
    #[arg(long, value_enum, default_value_t = Kind::Normal)]
    pub kind: Kind,
    /// The kind's period in seconds (every kind but normal; default 1).
    #[arg(long, value_name = "SECS", allow_negative_numbers = true, value_parser = positive_secs)]
    pub period: Option<f64>,
    /// The priority of the values at a Priority port.
    #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
    pub priority: i32,
    /// Write again this many times a second (until --for ends or Ctrl-C).
    #[arg(long, value_name = "HZ", value_parser = positive_secs)]
    pub repeat_hz: Option<f64>,
    /// How long to keep writing with --repeat-hz.
    #[arg(long = "for", value_name = "SECS", value_parser = positive_secs, requires = "repeat_hz")]
    pub for_secs: Option<f64>,
    #[command(flatten)]
    pub net: Net,
}

/// Connection kinds as typed on the command line.
#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum Kind {
    Normal,
    Suppress,
    Inhibit,
    OverrideIn,
    OverrideOut,
    WriteInhibit,
}

impl Kind {
    pub fn with_period(self, period: ayllu::Duration) -> ConnectionKind {
        match self {
            Kind::Normal => ConnectionKind::Normal,
            Kind::Suppress => ConnectionKind::Suppress(period),
            Kind::Inhibit => ConnectionKind::Inhibit(period),
            Kind::OverrideIn => ConnectionKind::OverrideIn(period),
            Kind::OverrideOut => ConnectionKind::OverrideOut(period),
            Kind::WriteInhibit => ConnectionKind::WriteInhibit(period),
        }
    }
}

#[derive(Args, Debug)]
pub struct NodeArgs {
    /// This node's id.
    #[arg(long, value_parser = parse_node)]
    pub id: NodeId,
    /// The node's udp:// URL (bind address, team, key, discovery=, peer=, broadcast=,
    /// hello_ms=, name=). Default: $AYLLU_URL, else discovery on this machine.
    #[arg(long, value_name = "URL", default_value_t = ayllu::default_url())]
    pub udp: String,
    /// What the node runs.
    #[arg(long, value_enum, default_value_t = Controller::CrossSubsumption)]
    pub controller: Controller,
    /// cross-subsumption: how many observer layers (targets).
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..=64))]
    pub layers: u32,
    /// cross-subsumption: how often each layer's BLE select runs (claims are renewed).
    #[arg(long, value_name = "HZ", default_value_t = 1.0, value_parser = positive_secs)]
    pub claim_hz: f64,
    /// cross-subsumption: what this robot sees, as TARGET:HEIGHT pairs ("1:0.9,2:0.5"); the
    /// bearing of target n is 0.1*n rad. Fed to VISION at 10 Hz.
    #[arg(long, value_name = "T:H,...", default_value = "", value_parser = parse_sight)]
    pub sight: Sight,
    /// Print a JSON status line this often.
    #[arg(long, value_name = "MS", default_value_t = 200, value_parser = clap::value_parser!(u64).range(1..))]
    pub status_ms: u64,
    /// Stop after this many seconds (default: run until killed or Ctrl-C).
    #[arg(long = "for", value_name = "SECS", value_parser = positive_secs)]
    pub for_secs: Option<f64>,
    /// Which nodes may write this node's ports: `all` (the paper's open team), `none`, or node
    /// ids (`7,8`).
    #[arg(long, value_name = "WHO", default_value = "all", value_parser = parse_allow)]
    pub allow_write: ayllu::Allow,
    /// Which nodes may change this node's structure by request (CONNECT, DISCONNECT): `all`,
    /// `none`, or node ids.
    #[arg(long, value_name = "WHO", default_value = "all", value_parser = parse_allow)]
    pub allow_rewire: ayllu::Allow,
    /// The longest window a message from the network may open (longer ones are refused and
    /// counted as too_long).
    #[arg(long, value_name = "SECS", default_value_t = 600.0, value_parser = positive_secs)]
    pub max_window: f64,
}

/// The controllers `ayllu node` can host.
#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum Controller {
    /// The paper's Fig. 2: VISION, BASE, WANDER and observer layers cross-inhibited by BLE.
    CrossSubsumption,
    /// RELAY (int) and FRELAY (float): In -> (process) -> Out -> (connection) -> Aux.
    Relay,
}

/// `--sight`: (target, apparent height) pairs.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Sight(pub Vec<(u32, f64)>);

fn parse_node(s: &str) -> Result<NodeId, String> {
    let digits = s.strip_prefix('n').unwrap_or(s);
    let parsed = match digits.strip_prefix("0x").or_else(|| digits.strip_prefix("0X")) {
        Some(hex) => u32::from_str_radix(hex, 16),
        None => digits.parse::<u32>(),
    };
    parsed.map(NodeId).map_err(|_| format!("`{s}` is not a node id (a number: 3, n3 or 0x3)"))
}

fn parse_allow(s: &str) -> Result<ayllu::Allow, String> {
    match s {
        "all" => Ok(ayllu::Allow::Everyone),
        "none" => Ok(ayllu::Allow::Nobody),
        ids => ids.split(',').map(|id| parse_node(id.trim())).collect::<Result<_, _>>().map(ayllu::Allow::Only),
    }
}

fn parse_connection(s: &str) -> Result<ConnectionId, String> {
    s.strip_prefix('c')
        .unwrap_or(s)
        .parse::<u64>()
        .map(ConnectionId)
        .map_err(|_| format!("`{s}` is not a connection id (a number: 4 or c4)"))
}

fn parse_port_path(s: &str) -> Result<PortPath, String> {
    match s.split_once('.') {
        Some((b, p)) if !b.is_empty() && !p.is_empty() => Ok(PortPath { behavior: b.to_owned(), port: p.to_owned() }),
        _ => Err(format!("`{s}` should be BEHAVIOR.PORT, e.g. BASE.Rotate")),
    }
}

/// The largest number of seconds (or hertz) an argument takes: about 31 years, far beyond
/// any run, and small enough for every duration type (1e300 used to panic).
const MAX_SECS: f64 = 1e9;

/// Seconds (or hertz): finite, above zero, at most [`MAX_SECS`].
fn positive_secs(s: &str) -> Result<f64, String> {
    let x: f64 = s.parse().map_err(|_| format!("`{s}` is not a number"))?;
    if !x.is_finite() || x <= 0.0 {
        return Err(format!("must be greater than 0 (got {s})"));
    }
    if x > MAX_SECS {
        return Err(format!("must be at most {MAX_SECS:e} (got {s})"));
    }
    Ok(x)
}

fn parse_sight(s: &str) -> Result<Sight, String> {
    let mut pairs = Vec::new();
    for item in s.split(',').map(str::trim).filter(|i| !i.is_empty()) {
        let (t, h) = item.split_once(':').ok_or_else(|| format!("`{item}` should be TARGET:HEIGHT"))?;
        let t: u32 = t.trim().parse().map_err(|_| format!("target `{t}` is not a number"))?;
        let h: f64 = h.trim().parse().map_err(|_| format!("height `{h}` is not a number"))?;
        if t == 0 || !h.is_finite() {
            return Err(format!("`{item}`: targets count from 1 and heights must be finite"));
        }
        pairs.push((t, h));
    }
    Ok(Sight(pairs))
}

fn run(cli: Cli) -> Result<(), Fail> {
    match cli.command {
        Command::List { node: None, net } => commands::list_nodes(&net),
        Command::List { node: Some(node), net } => commands::list_node(node, &net),
        Command::Why { node, target, net } => commands::why(node, &target, &net),
        Command::Echo { node, target, count, net } => commands::echo(node, &target, count, &net),
        Command::Write(args) => commands::write(&args),
        Command::Disconnect { node, connection, net } => commands::disconnect_command(node, connection, &net),
        Command::Node(args) => controllers::run(&args),
        Command::Keygen { file } => {
            let public = ayllu::operator::keygen(&file)?;
            println!("{public}");
            eprintln!(
                "secret written to {} (keep it off the robots); give robots operator={public} in their udp:// URL, \
                 and tools operator_secret={} in theirs",
                file.display(),
                file.display()
            );
            Ok(())
        }
        Command::Sim(SimCommand::Cmommt(args)) => sim_cmommt::run(&args),
        Command::Sim(SimCommand::Serve(args)) => sim_serve::serve(&args),
        Command::Sim(SimCommand::Robot(args)) => sim_serve::robot(&args),
        Command::Sim(SimCommand::Run(args)) => sim_files::run_file(&args),
        Command::Sim(SimCommand::Sweep(args)) => sim_files::sweep_file(&args),
        #[cfg(target_os = "linux")]
        Command::Shape(args) => shape::run(&args),
    }
}

fn main() -> ExitCode {
    // A bug must not print a backtrace at an engineer: one line, exit 1.
    std::panic::set_hook(Box::new(|info| {
        // writeln!, not eprintln!: with stderr closed the latter panics again, inside the hook,
        // and aborts (`ayllu ... 2>&1 | head -1` died by SIGABRT).
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), "ayllu: internal error: {info}");
        std::process::exit(1);
    }));
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let _ = e.print();
            // --help and --version are not errors.
            return ExitCode::from(if e.use_stderr() { 2 } else { 0 });
        }
    };
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(fail) => {
            if !fail.message.is_empty() {
                use std::io::Write as _;
                let _ = writeln!(std::io::stderr(), "ayllu: {}", fail.message);
            }
            ExitCode::from(fail.code)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn node_ids_parse_in_three_spellings() {
        assert_eq!(parse_node("3"), Ok(NodeId(3)));
        assert_eq!(parse_node("n3"), Ok(NodeId(3)));
        assert_eq!(parse_node("0x7fff0001"), Ok(NodeId(0x7fff_0001)));
        assert!(parse_node("robot").is_err());
        assert!(parse_node("-1").is_err());
    }

    #[test]
    fn port_paths_need_both_halves() {
        assert_eq!(
            parse_port_path("BASE.Rotate").unwrap(),
            PortPath { behavior: "BASE".into(), port: "Rotate".into() }
        );
        for bad in ["BASE", ".Rotate", "BASE.", ""] {
            assert!(parse_port_path(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn periods_must_be_positive() {
        assert_eq!(positive_secs("0.5"), Ok(0.5));
        for bad in ["0", "-1", "nan", "inf", "x", "1e300", "1e10"] {
            assert!(positive_secs(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn access_rules_parse() {
        assert_eq!(parse_allow("all"), Ok(ayllu::Allow::Everyone));
        assert_eq!(parse_allow("none"), Ok(ayllu::Allow::Nobody));
        assert_eq!(parse_allow("7, n8"), Ok(ayllu::Allow::Only(vec![NodeId(7), NodeId(8)])));
        assert!(parse_allow("robots").is_err());
    }

    #[test]
    fn sight_tables_parse() {
        assert_eq!(parse_sight("1:0.9, 2:0.5").unwrap(), Sight(vec![(1, 0.9), (2, 0.5)]));
        assert_eq!(parse_sight("").unwrap(), Sight(vec![]));
        for bad in ["1", "x:0.5", "1:y", "0:0.5"] {
            assert!(parse_sight(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn the_argument_definitions_are_consistent() {
        use clap::CommandFactory;
        Cli::command().debug_assert();
    }
}
