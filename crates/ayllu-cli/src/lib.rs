//! `ayllu` — the command-line tool for a running Ayllu team (docs/cli.md). `src/main.rs` only
//! calls [`cli_main`]; the tool lives in this library so that its argument parsing can be
//! driven from outside the binary (the `cli_args` fuzz target, property tests).
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
//! * argument parsing ([`parse_args`] and the value parsers it uses) never panics, whatever
//!   the arguments, and every number it accepts converts to a duration without panicking;
//! * every wait is bounded by `--timeout`, except those the user ends (Ctrl-C, `--for`);
//!   Ctrl-C still disconnects what `echo` connected.

mod apply;
mod client;
mod commands;
mod controllers;
mod fail;
#[cfg(feature = "foxglove")]
mod foxglove;
mod graph;
mod hz;
mod rate;
mod record;
mod replay;
#[cfg(target_os = "linux")]
mod shape;
#[cfg(target_os = "linux")]
mod shaper;
mod signals;
mod sim_cmommt;
mod sim_files;
mod sim_serve;
mod team_graph;
mod text;

use std::process::ExitCode;

use ayllu::{ConnectionId, ConnectionKind, NodeId};
use clap::{Args, Parser, Subcommand, ValueEnum};

use crate::fail::Fail;

pub use crate::text::parse_value;

/// The parsed command line: which command, with which arguments ([`parse_args`]).
#[derive(Parser, Debug)]
#[command(name = "ayllu", version, about = "Inspect and drive a running Ayllu team over udp://")]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// Parse a command line (`argv[0]` is the program's name) as the `ayllu` binary does. `--help`
/// and `--version` come back as errors too (clap's `DisplayHelp`, `DisplayVersion`). Never
/// panics, whatever the arguments (the `cli_args` fuzz target and a property test drive it).
pub fn parse_args<I, T>(argv: I) -> Result<Cli, clap::Error>
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    ArgParser::new().parse(argv)
}

/// The argument parser, built once and used for many command lines: what [`parse_args`] does,
/// without rebuilding clap's description of every command each time (most of the cost of a
/// parse; the fuzz target parses millions).
pub struct ArgParser(clap::Command);

impl ArgParser {
    /// The parser for every `ayllu` command.
    pub fn new() -> ArgParser {
        use clap::CommandFactory;
        ArgParser(Cli::command())
    }

    /// Parse one command line, as [`parse_args`].
    pub fn parse<I, T>(&mut self, argv: I) -> Result<Cli, clap::Error>
    where
        I: IntoIterator<Item = T>,
        T: Into<std::ffi::OsString> + Clone,
    {
        use clap::FromArgMatches;
        // What clap's `Parser::try_parse_from` does, on a command kept between calls.
        let mut matches = self.0.try_get_matches_from_mut(argv)?;
        Cli::from_arg_matches_mut(&mut matches).map_err(|e| e.format(&mut self.0))
    }
}

impl Default for ArgParser {
    fn default() -> ArgParser {
        ArgParser::new()
    }
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
    /// Apply structure changes on several nodes all at once, or on none (a plan file:
    /// docs/cli.md "ayllu apply").
    Apply {
        /// The plan: a TOML file of changes per node.
        plan: std::path::PathBuf,
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
    /// Record the team's port messages into an MCAP file (channels per node, behavior, port;
    /// opens in Foxglove): every group the nodes announce, and copies of chosen ports.
    Record(record::RecordArgs),
    /// Send a recording back into ports of a live team at its recorded pace (or faster).
    Play(record::PlayArgs),
    /// Print the team's wiring (behaviors, ports, connections, windows open now) as DOT,
    /// Mermaid, SVG, HTML or JSON.
    Graph(graph::GraphArgs),
    /// Print the rate, jitter, gaps and losses of a port's messages.
    Hz(hz::HzArgs),
    /// Play a node's flight recording (`node --record`) back and answer `why`, `list` or
    /// `echo` as the node would have at a past instant (--at); `check` verifies it. Given a
    /// team's recordings: `check` them as one system, `why --node` across the robots.
    Replay(replay::ReplayArgs),
    /// Serve the team to Foxglove over its WebSocket protocol: port values, windows and BLE
    /// claims as topics (ws://HOST:PORT; docs/cli.md).
    #[cfg(feature = "foxglove")]
    Foxglove(foxglove::FoxgloveArgs),
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
    #[arg(long, value_name = "HZ", value_parser = positive_hz)]
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
    #[arg(long, value_name = "HZ", default_value_t = 1.0, value_parser = positive_hz)]
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
    /// Record everything that enters the node's core into this MCAP file (a flight
    /// recording: Foxglove opens it; `ayllu replay FILE` plays it back).
    #[arg(long, value_name = "FILE")]
    pub record: Option<std::path::PathBuf>,
    /// Cap the recording at this many bytes (all segments together; default 1 GiB); segments
    /// are at most 64 MiB (FILE, FILE.1.mcap, ...). Recording stops at the cap.
    #[arg(long, value_name = "N", requires = "record", value_parser = clap::value_parser!(u64).range(65_536..))]
    pub record_max_bytes: Option<u64>,
    /// Keep only about the last SECS of the recording (node time): a rolling flight recorder
    /// for a robot that records all the time. Every SECS/4 (at least 1 s) it checkpoints the
    /// node and deletes what lies before the window; `ayllu replay FILE` replays from the
    /// oldest checkpoint kept.
    #[arg(long, value_name = "SECS", requires = "record", value_parser = positive_secs)]
    pub record_last: Option<f64>,
    /// The robot's body is behind ROS 2 topics, as this mapping file says (docs/ros2.md):
    /// sensors' topics write its ports, its motor ports are published. Needs the tool built
    /// with ROS 2 (`make ros2`).
    #[arg(long, value_name = "FILE")]
    pub ros2: Option<std::path::PathBuf>,
    /// wander: the seed of the random wander (with the node id).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// The controllers `ayllu node` can host.
#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum Controller {
    /// The paper's Fig. 2: VISION, BASE, WANDER and observer layers cross-inhibited by BLE.
    CrossSubsumption,
    /// RELAY (int) and FRELAY (float): In -> (process) -> Out -> (connection) -> Aux.
    Relay,
    /// Subsumption on a body's SONAR and BASE: safe velocity drives, a random wander turns,
    /// AVOID overrides the turn near obstacles (`ayllu::stdlib::wander_avoid`).
    Wander,
}

/// `--sight`: (target, apparent height) pairs.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Sight(pub Vec<(u32, f64)>);

/// A node id: `3`, `n3` or `0x3`.
pub fn parse_node(s: &str) -> Result<NodeId, String> {
    let digits = s.strip_prefix('n').unwrap_or(s);
    let parsed = match digits.strip_prefix("0x").or_else(|| digits.strip_prefix("0X")) {
        Some(hex) => u32::from_str_radix(hex, 16),
        None => digits.parse::<u32>(),
    };
    parsed.map(NodeId).map_err(|_| format!("`{s}` is not a node id (a number: 3, n3 or 0x3)"))
}

/// Who may write or rewire: `all`, `none`, or node ids (`7,8`).
pub fn parse_allow(s: &str) -> Result<ayllu::Allow, String> {
    match s {
        "all" => Ok(ayllu::Allow::Everyone),
        "none" => Ok(ayllu::Allow::Nobody),
        ids => ids.split(',').map(|id| parse_node(id.trim())).collect::<Result<_, _>>().map(ayllu::Allow::Only),
    }
}

/// A connection id: `4` or `c4`.
pub fn parse_connection(s: &str) -> Result<ConnectionId, String> {
    s.strip_prefix('c')
        .unwrap_or(s)
        .parse::<u64>()
        .map(ConnectionId)
        .map_err(|_| format!("`{s}` is not a connection id (a number: 4 or c4)"))
}

/// `BEHAVIOR.PORT`, both halves non-empty.
pub fn parse_port_path(s: &str) -> Result<PortPath, String> {
    match s.split_once('.') {
        Some((b, p)) if !b.is_empty() && !p.is_empty() => Ok(PortPath { behavior: b.to_owned(), port: p.to_owned() }),
        _ => Err(format!("`{s}` should be BEHAVIOR.PORT, e.g. BASE.Rotate")),
    }
}

/// A number as a message prints it: the core's [`ayllu_core::Compact`] (plainly for everyday
/// sizes, in exponent form for the very large and the very small: `1e300`, not its 301
/// digits), so the tool, C and Python print the same number the same way.
pub fn compact(x: f64) -> String {
    ayllu_core::Compact(x).to_string()
}

/// Seconds: what the core's `Duration::try_from_positive_secs` takes (above zero, from 1 ns
/// to about 584 years), refused in its words, as C and Python refuse them.
pub fn positive_secs(s: &str) -> Result<f64, String> {
    let x: f64 = s.parse().map_err(|_| format!("`{s}` is not a number"))?;
    ayllu::Duration::try_from_positive_secs(x).map_err(|e| e.to_string())?;
    Ok(x)
}

/// A rate in hertz: what the core's `Duration::try_from_hz` takes (finite, above zero, with a
/// period from 1 ns to about 584 years), refused in its words.
pub fn positive_hz(s: &str) -> Result<f64, String> {
    let hz: f64 = s.parse().map_err(|_| format!("`{s}` is not a number"))?;
    ayllu::Duration::try_from_hz(hz).map_err(|e| e.to_string())?;
    Ok(hz)
}

/// `--sight`: `TARGET:HEIGHT` pairs separated by commas; targets count from 1, heights are
/// finite.
pub fn parse_sight(s: &str) -> Result<Sight, String> {
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
        Command::Apply { plan, net } => apply::apply_command(&plan, &net),
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
        Command::Record(args) => record::record(&args),
        Command::Play(args) => record::play(&args),
        Command::Graph(args) => graph::graph(&args),
        Command::Hz(args) => hz::hz(&args),
        Command::Replay(args) => replay::run(&args),
        #[cfg(feature = "foxglove")]
        Command::Foxglove(args) => foxglove::serve(&args),
    }
}

/// The `ayllu` binary: parse the process's arguments, run the command, and give the exit code
/// (0 done, 1 failed, 2 usage).
pub fn cli_main() -> ExitCode {
    // A bug must not print a backtrace at an engineer: one line, exit 1.
    std::panic::set_hook(Box::new(|info| {
        // writeln!, not eprintln!: with stderr closed the latter panics again, inside the hook,
        // and aborts (`ayllu ... 2>&1 | head -1` died by SIGABRT).
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), "ayllu: internal error: {info}");
        std::process::exit(1);
    }));
    let cli = match parse_args(std::env::args_os()) {
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
        // 1e11 s: beyond the 584 years (18446744073 s) a duration holds.
        for bad in ["0", "-1", "nan", "inf", "x", "1e300", "1e11"] {
            assert!(positive_secs(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn numbers_out_of_range_print_compactly_with_the_range() {
        // The core's words, the same the C and Python APIs give (Duration::try_from_positive_secs).
        let core = |x: f64| ayllu::Duration::try_from_positive_secs(x).unwrap_err().to_string();
        for (text, x) in [("1e300", 1e300), ("-1e300", -1e300), ("0", 0.0), ("1e-300", 1e-300), ("nan", f64::NAN)] {
            assert_eq!(positive_secs(text), Err(core(x)), "{text}");
        }
        assert!(core(1e300).contains("1e300 s is too long"), "{}", core(1e300));
        assert!(core(-1e300).contains("-1e300 s is negative"), "{}", core(-1e300));
        // Seconds under the clock's 1 ns would round to none.
        assert!(core(1e-300).contains("under 1 ns, the clock's resolution"), "{}", core(1e-300));
        assert_eq!(positive_hz("1e-300"), Err(ayllu::Duration::try_from_hz(1e-300).unwrap_err().to_string()));
        assert_eq!(positive_secs("1e-9"), Ok(1e-9));
        assert_eq!(compact(12.5), "12.5");
        assert_eq!(compact(1e297), "1e297");
        assert_eq!(compact(f64::NAN), "NaN");
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
    fn rates_give_periods_that_are_durations() {
        assert_eq!(positive_hz("0.5"), Ok(0.5));
        // 1e-11 Hz: a period of 1e11 s, beyond the 584 years a duration holds.
        for bad in ["0", "-1", "nan", "inf", "1e300", "1e-300", "1e-11"] {
            assert!(positive_hz(bad).is_err(), "{bad}");
        }
        // `write` turns --repeat-hz into its interval: 1e-300 Hz used to panic there.
        let argv = ["ayllu", "write", "3", "A.B", "1", "--kind", "suppress", "--repeat-hz", "1e-300"];
        assert!(parse_args(argv).is_err());
    }

    /// What the commands do with a number an argument parser accepted must not panic either:
    /// seconds become durations, rates become periods.
    fn check_accepted(text: &str) {
        if let Ok(x) = positive_secs(text) {
            assert!(std::time::Duration::try_from_secs_f64(x).is_ok(), "{text}");
            assert!(ayllu::Duration::try_from_secs_f64(x).is_ok(), "{text}");
        }
        if let Ok(hz) = positive_hz(text) {
            assert!(std::time::Duration::try_from_secs_f64(1.0 / hz).is_ok(), "{text}");
            assert!(ayllu::Duration::try_from_hz(hz).is_ok(), "{text}");
        }
        let _ = (parse_node(text), parse_allow(text), parse_connection(text), parse_port_path(text));
        let _ = parse_sight(text);
        for ty in [
            ayllu::ValueType::Bool,
            ayllu::ValueType::Int,
            ayllu::ValueType::Float,
            ayllu::ValueType::Text,
            ayllu::ValueType::Bytes,
            ayllu::ValueType::Vector,
        ] {
            let _ = parse_value(ty, text);
        }
    }

    thread_local! {
        static REUSED: std::cell::RefCell<ArgParser> = std::cell::RefCell::new(ArgParser::new());
    }

    /// Words the parser knows, so arbitrary command lines reach past the subcommand.
    fn word() -> impl proptest::strategy::Strategy<Value = String> {
        use proptest::prelude::*;
        prop_oneof![
            proptest::sample::select(vec![
                "list",
                "why",
                "echo",
                "write",
                "disconnect",
                "apply",
                "node",
                "sim",
                "cmommt",
                "serve",
                "robot",
                "run",
                "sweep",
                "keygen",
                "shape",
                "record",
                "play",
                "graph",
                "hz",
                "-o",
                "--copy",
                "--no-groups",
                "--topic",
                "--to",
                "--speed",
                "--format",
                "--listen",
                "--window",
                "--every",
                "--gap-factor",
                "mermaid",
                "*.*",
                "n2:B.P",
                "/n1/B/P=n2:B.P",
                "foxglove",
                "--mcap",
                "--host",
                "--port",
                "--hz",
                "--why-hz",
                "replay",
                "check",
                "--at",
                "--from",
                "--record",
                "--record-max-bytes",
                "--record-last",
                "12.5s",
                "--netns",
                "--udp",
                "--timeout",
                "--json",
                "--id",
                "--count",
                "--kind",
                "--period",
                "--priority",
                "--repeat-hz",
                "--for",
                "--controller",
                "--layers",
                "--claim-hz",
                "--sight",
                "--status-ms",
                "--allow-write",
                "--allow-rewire",
                "--max-window",
                "--help",
                "--version",
                "suppress",
                "relay",
                "n3",
                "0x3",
                "c4",
                "B.P",
                "1e300",
                "-1e300",
                "1e-300",
                "nan",
                "-0",
                "1:0.5",
                "all",
                "7,8",
                "=",
            ])
            .prop_map(str::to_owned),
            ".*",
            "[-+0-9.eE:,xn]{0,12}",
        ]
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(1024))]

        /// Every value parser takes any text without panicking, and what it accepts converts.
        #[test]
        fn value_parsers_never_panic(text in ".*", number in "[-+0-9.eE]{0,12}") {
            check_accepted(&text);
            check_accepted(&number);
        }

        /// Any command line is parsed or refused, never a panic (clap's own consistency checks
        /// included, which run on the first parse in a debug build).
        #[test]
        fn any_command_line_is_parsed_or_refused(words in proptest::collection::vec(word(), 0..8)) {
            let argv: Vec<String> = std::iter::once("ayllu".to_owned()).chain(words.iter().cloned()).collect();
            let fresh = parse_args(&argv).map(|cli| format!("{cli:?}")).map_err(|e| e.kind());
            // A parser kept between command lines (the fuzz target's) parses as a fresh one.
            let reused = REUSED.with(|p| p.borrow_mut().parse(&argv).map(|cli| format!("{cli:?}")).map_err(|e| e.kind()));
            proptest::prop_assert_eq!(fresh, reused);
            for w in &words {
                check_accepted(w);
            }
        }
    }

    #[test]
    fn the_argument_definitions_are_consistent() {
        use clap::CommandFactory;
        Cli::command().debug_assert();
    }
}
