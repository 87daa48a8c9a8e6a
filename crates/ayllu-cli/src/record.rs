//! `ayllu record` and `ayllu play`: a team's port messages into an MCAP file in the team
//! channel layout (`spec/recording.md`), and a recording back into ports of a live team at
//! its pace. The machinery (the tap, the channel resolution, the file) is
//! `ayllu::team_recording`; this file parses, loops and prints.
//!
//! What `record` hears is said in docs/cli.md: the groups every node announces (joined, so
//! nodes deliver group messages to the recorder as to any member), and copies of the ports
//! `--copy` names (Normal connections CONNECTed to the recorder, removed when it stops).

use std::collections::{BTreeMap, BTreeSet};
use std::time::{Duration as StdDuration, Instant as StdInstant};

use ayllu::team_recording::{self, HeardLog, Recorder, Route, Tap, TeamWriter};
use ayllu::{
    BehaviorClass, ConnectOptions, ConnectionId, ConnectionKind, ControlBody, Endpoint, NodeId, PortSpec, ReplyBody,
    Value, ValueType,
};
use clap::Args;

use crate::client::{Client, SLICE};
use crate::commands::{disconnect, emit, read};
use crate::fail::Fail;
use crate::{parse_node, positive_secs, signals, Net, PortPath};

/// How long a request made while recording may wait for its answer.
const REQUEST_WAIT: StdDuration = StdDuration::from_secs(2);
/// How often `record` looks for new nodes (to join their groups and copy their ports).
const SURVEY: StdDuration = StdDuration::from_secs(1);
/// The recorder's own ports, one per value type, into which `--copy` connections write.
const TYPES: [ValueType; 6] =
    [ValueType::Bool, ValueType::Int, ValueType::Float, ValueType::Text, ValueType::Bytes, ValueType::Vector];

/// `[NODE:]BEHAVIOR.PORT`, `*` for any behavior or port; no node: every node.
#[derive(Clone, Debug, PartialEq)]
pub struct CopyPattern {
    pub node: Option<NodeId>,
    pub behavior: String,
    pub port: String,
}

impl std::fmt::Display for CopyPattern {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if let Some(n) = self.node {
            write!(f, "{n}:")?;
        }
        write!(f, "{}.{}", self.behavior, self.port)
    }
}

impl CopyPattern {
    fn matches(&self, node: NodeId, behavior: &str, port: &str) -> bool {
        self.node.is_none_or(|n| n == node)
            && (self.behavior == "*" || self.behavior == behavior)
            && (self.port == "*" || self.port == port)
    }
}

/// `--copy`: `OBS1.Local`, `n2:BASE.Rotate`, `*.Rotate`, `n3:*.*`.
pub fn parse_copy(s: &str) -> Result<CopyPattern, String> {
    let (node, path) = match s.split_once(':') {
        Some((n, p)) => (Some(parse_node(n)?), p),
        None => (None, s),
    };
    match path.split_once('.') {
        Some((b, p)) if !b.is_empty() && !p.is_empty() => {
            Ok(CopyPattern { node, behavior: b.to_owned(), port: p.to_owned() })
        }
        _ => Err(format!("`{s}` should be [NODE:]BEHAVIOR.PORT (`*` for any), e.g. n2:BASE.Rotate or *.Rotate")),
    }
}

#[derive(Args, Debug)]
pub struct RecordArgs {
    /// The MCAP file to write (a new file: a recording is never replaced).
    #[arg(short = 'o', long = "output", value_name = "FILE")]
    pub output: std::path::PathBuf,
    /// Also record these ports by asking their nodes for a copy (a Normal connection to the
    /// recorder): [NODE:]BEHAVIOR.PORT, `*` for any behavior or port (repeatable).
    #[arg(long, value_name = "PATTERN", value_parser = parse_copy)]
    pub copy: Vec<CopyPattern>,
    /// Do not join the groups the nodes announce (record only --copy ports).
    #[arg(long)]
    pub no_groups: bool,
    /// Stop after this many seconds (default: run until Ctrl-C).
    #[arg(long = "for", value_name = "SECS", value_parser = positive_secs)]
    pub for_secs: Option<f64>,
    #[command(flatten)]
    pub net: Net,
}

#[derive(Args, Debug)]
pub struct PlayArgs {
    /// A recording in the team channel layout (`ayllu record`'s MCAP).
    pub file: std::path::PathBuf,
    /// Play only these topics (repeatable; default: every team channel in the file).
    #[arg(long, value_name = "TOPIC")]
    pub topic: Vec<String>,
    /// Send a topic's values to another port: TOPIC=NODE:BEHAVIOR.PORT (repeatable; default:
    /// the port the topic names).
    #[arg(long = "to", value_name = "TOPIC=NODE:B.P", value_parser = parse_mapping)]
    pub to: Vec<(String, NodeId, PortPath)>,
    /// Play this many times faster than recorded (0.5: half as fast).
    #[arg(long, default_value_t = 1.0, value_parser = positive_secs)]
    pub speed: f64,
    #[command(flatten)]
    pub net: Net,
}

/// `--to TOPIC=NODE:BEHAVIOR.PORT`.
pub fn parse_mapping(s: &str) -> Result<(String, NodeId, PortPath), String> {
    let (topic, dest) = s.split_once('=').ok_or_else(|| format!("`{s}` should be TOPIC=NODE:BEHAVIOR.PORT"))?;
    let (node, path) = dest.split_once(':').ok_or_else(|| format!("`{dest}` should be NODE:BEHAVIOR.PORT"))?;
    Ok((topic.to_owned(), parse_node(node)?, crate::parse_port_path(path)?))
}

fn io_fail(what: &str, path: &std::path::Path, e: std::io::Error) -> Fail {
    Fail::error(format!("{what} {}: {e}", path.display()))
}

/// Ask with a short deadline of its own, then give the command its deadline back.
fn ask_briefly(client: &mut Client, node: NodeId, body: ControlBody, what: &str) -> Result<ReplyBody, Fail> {
    client.set_deadline(Some(StdInstant::now() + REQUEST_WAIT));
    let answer = client.ask(node, body, what);
    client.set_deadline(None);
    answer
}

/// `ayllu record -o FILE`.
pub fn record(args: &RecordArgs) -> Result<(), Fail> {
    signals::install();
    // A recording is never replaced (as `node --record`, `sim run --mcap`, `foxglove --mcap` and
    // `keygen` never replace their files): checked before anything goes on the network.
    let file = std::fs::OpenOptions::new().write(true).create_new(true).open(&args.output).map_err(|e| {
        if e.kind() == std::io::ErrorKind::AlreadyExists {
            Fail::error(format!(
                "{} exists (a recording is never replaced): move or remove it, or record into another file",
                args.output.display()
            ))
        } else {
            io_fail("cannot create", &args.output, e)
        }
    })?;
    let mut log = HeardLog::default();
    // The recorder hears every node: an --id one of them has would leave that node out.
    let opened = crate::client::refuse_a_heard_nodes_id(&args.net).and_then(|()| {
        Client::open_with(&args.net, 5.0, |t| {
            let (tap, heard) = Tap::new(t);
            log = heard;
            tap
        })
    });
    let mut client = match opened {
        Ok(client) => client,
        Err(e) => {
            // Nothing was recorded: the empty file would only block the next attempt.
            drop(file);
            let _ = std::fs::remove_file(&args.output);
            return Err(e);
        }
    };
    let writer =
        TeamWriter::new(std::io::BufWriter::new(file)).map_err(|e| io_fail("cannot write", &args.output, e))?;
    let mut recorder = Recorder::new(writer);

    // The recorder's own ports for copies, one per type.
    let mut class = BehaviorClass::new("Recorder");
    for ty in TYPES {
        class.port(PortSpec::new(ty.name(), Value::zero(ty)))?;
    }
    client.node.define(class)?;
    client.node.create("Recorder", "REC")?;

    let started = StdInstant::now();
    let end = args.for_secs.map(|s| started + StdDuration::from_secs_f64(s));
    client.set_deadline(None);
    eprintln!(
        "record: {} as {} into {}{}",
        if args.no_groups { "copies only" } else { "every group the nodes announce, and copies" },
        client.id(),
        args.output.display(),
        end.map_or(" until Ctrl-C".to_owned(), |_| format!(" for {}s", args.for_secs.unwrap_or(0.0)))
    );

    let mut known: BTreeSet<NodeId> = BTreeSet::new();
    let mut joined: BTreeSet<String> = BTreeSet::new();
    let mut copies: Vec<(NodeId, ConnectionId)> = Vec::new();
    let mut patterns = CopyWatch::new(&args.copy);
    let mut next_survey = StdInstant::now();
    let mut failure: Option<Fail> = None;
    // Whether any node was heard at all (a node heard and gone again counts).
    let mut heard_a_node = false;
    while !signals::stopped() && end.is_none_or(|e| StdInstant::now() < e) {
        client.pump(SLICE);
        if let Err(e) = recorder.heard(log.take()) {
            failure = Some(io_fail("cannot write", &args.output, e));
            break;
        }
        if StdInstant::now() >= next_survey {
            next_survey = StdInstant::now() + SURVEY;
            let peers = client.peers();
            heard_a_node |= !peers.is_empty();
            // A node that went silent is surveyed again when it comes back (a restarted node
            // has new connections, and lost the copies it was asked for).
            known.retain(|n| peers.iter().any(|p| p.node == *n));
            for peer in peers {
                if !args.no_groups {
                    for g in &peer.groups {
                        if joined.insert(g.clone()) {
                            client.node.join(g);
                            eprintln!("record: joined group {g} (announced by {})", peer.node);
                        }
                    }
                }
                if known.insert(peer.node) {
                    survey(&mut client, &mut recorder, &mut patterns, peer.node, &mut copies);
                }
            }
        }
        for node in recorder.wanted_lists() {
            match ask_briefly(&mut client, node, ControlBody::List, &format!("LIST {node}")) {
                Ok(ReplyBody::Node(report)) => recorder.learn(&report),
                _ => recorder.list_failed(node),
            }
        }
    }

    for (node, conn) in copies {
        disconnect(&mut client, node, conn);
    }
    let unmatched = patterns.unmatched();
    for (pattern, why) in &unmatched {
        if !why.is_empty() {
            eprintln!("ayllu: warning: --copy {pattern} copied nothing: {why}");
        }
    }
    if let Err(e) = recorder.heard(log.take()).and_then(|_| recorder.finish()) {
        return Err(failure.unwrap_or_else(|| io_fail("cannot write", &args.output, e)));
    }
    if let Some(f) = failure {
        return Err(f);
    }
    heard_a_node |= !client.peers().is_empty() || recorder.messages() > 0;
    if !heard_a_node {
        // As `list` and every other command: hearing nobody is a failure a script must see
        // (exit 1), with the causes to check. The file holds nothing, and left there it would
        // only block the next attempt with the same name.
        let _ = std::fs::remove_file(&args.output);
        return Err(Fail::error(format!(
            "no node heard while recording ({:.1}s): removed the empty {}; {}",
            started.elapsed().as_secs_f64(),
            args.output.display(),
            client.hint()
        )));
    }
    let channels = recorder.per_channel();
    let summary = format!(
        "recorded {} messages on {} channels in {:.1}s to {}{}",
        recorder.messages(),
        channels.len(),
        started.elapsed().as_secs_f64(),
        args.output.display(),
        if recorder.unresolved() > 0 {
            format!(" ({} on connections never resolved, under /nN/_cC/...)", recorder.unresolved())
        } else {
            String::new()
        }
    );
    if args.net.json {
        let per: serde_json::Map<String, serde_json::Value> =
            channels.iter().map(|(t, n)| (t.clone(), serde_json::json!(n))).collect();
        return emit(
            &serde_json::json!({"file": args.output.display().to_string(), "messages": recorder.messages(),
                "unresolved": recorder.unresolved(), "secs": started.elapsed().as_secs_f64(), "channels": per,
                "unmatched": unmatched.iter().map(|(p, _)| p.to_string()).collect::<Vec<_>>()})
            .to_string(),
        );
    }
    let mut text = summary;
    for (topic, n) in channels {
        text.push_str(&format!("\n  {topic:<40} {n}"));
    }
    emit(&text)
}

/// Which `--copy` patterns matched a port, so that one that matches none is said: at once for
/// a pattern naming a node, as soon as that node's ports are known; at the end for the others
/// (a node heard later could have had the port).
struct CopyWatch<'a> {
    patterns: &'a [CopyPattern],
    matched: Vec<bool>,
    /// Patterns already warned about (at their node's survey).
    warned: Vec<bool>,
    /// Every node surveyed (its ports looked at).
    surveyed: BTreeSet<NodeId>,
}

impl<'a> CopyWatch<'a> {
    fn new(patterns: &'a [CopyPattern]) -> CopyWatch<'a> {
        CopyWatch {
            patterns,
            matched: vec![false; patterns.len()],
            warned: vec![false; patterns.len()],
            surveyed: BTreeSet::new(),
        }
    }

    /// `node`'s ports were looked at; `hits[i]` says whether pattern i matched one of them.
    fn surveyed(&mut self, node: NodeId, hits: &[bool]) {
        self.surveyed.insert(node);
        for (i, p) in self.patterns.iter().enumerate() {
            self.matched[i] |= hits[i];
            if p.node == Some(node) && !self.matched[i] && !self.warned[i] {
                self.warned[i] = true;
                eprintln!("ayllu: warning: --copy {p} matches no port of {node}: nothing is copied for it");
            }
        }
    }

    /// The patterns that matched no port, each with what to say now (empty: said already).
    fn unmatched(&self) -> Vec<(&'a CopyPattern, String)> {
        let heard: Vec<String> = self.surveyed.iter().map(|n| n.to_string()).collect();
        (0..self.patterns.len())
            .filter(|&i| !self.matched[i])
            .map(|i| {
                let p = &self.patterns[i];
                let why = match p.node {
                    _ if self.warned[i] => String::new(),
                    Some(n) => format!("{n} was not heard, or gave no list of its ports, while recording"),
                    None if heard.is_empty() => "no node was heard while recording".to_owned(),
                    None => format!("no port of the nodes heard ({}) matches it", heard.join(", ")),
                };
                (p, why)
            })
            .collect()
    }
}

/// A new node: learn its connections, and ask for the copies `--copy` names.
fn survey(
    client: &mut Client,
    recorder: &mut Recorder<std::io::BufWriter<std::fs::File>>,
    watch: &mut CopyWatch,
    node: NodeId,
    copies: &mut Vec<(NodeId, ConnectionId)>,
) {
    let patterns = watch.patterns;
    let report = match ask_briefly(client, node, ControlBody::List, &format!("LIST {node}")) {
        Ok(ReplyBody::Node(report)) => report,
        Ok(_) => return, // An AylluLite node: no connections to learn, no CONNECT.
        Err(e) => {
            eprintln!("ayllu: warning: {}", e.message);
            return;
        }
    };
    recorder.learn(&report);
    let hits: Vec<bool> = patterns
        .iter()
        .map(|c| report.behaviors.iter().any(|b| b.ports.iter().any(|p| c.matches(node, &b.name, &p.name))))
        .collect();
    watch.surveyed(node, &hits);
    for b in &report.behaviors {
        for p in &b.ports {
            if !patterns.iter().any(|c| c.matches(node, &b.name, &p.name)) {
                continue;
            }
            client.set_deadline(Some(StdInstant::now() + REQUEST_WAIT));
            let answer = client.copy_port(node, (&b.name, &p.name), ("REC", p.ty.name()));
            client.set_deadline(None);
            match answer {
                Ok(conn) => {
                    let to = format!("{}:REC.{}", client.id(), p.ty.name());
                    recorder.learn_route(node, conn.0, Route { behavior: b.name.clone(), port: p.name.clone(), to });
                    copies.push((node, conn));
                    eprintln!("record: copying {node}:{}.{} as {node}'s connection {conn}", b.name, p.name);
                }
                Err(e) => eprintln!("ayllu: warning: {}", e.message),
            }
        }
    }
}

/// `ayllu play FILE`.
pub fn play(args: &PlayArgs) -> Result<(), Fail> {
    signals::install();
    let bytes = std::fs::read(&args.file).map_err(|e| io_fail("cannot read", &args.file, e))?;
    // Both kinds of recording are `.mcap` files: a flight recording holds one node's inputs,
    // not team channel messages, and is read by `replay`; say so rather than "nothing to play".
    if ayllu::replay::is_flight_recording(&bytes) {
        return Err(Fail::error(format!(
            "{}: a flight recording of one node (made by `ayllu node --record`), not a team recording: ask it with \
             `ayllu replay` (why, list, echo or check); `ayllu play` plays the team recordings of `ayllu record`",
            args.file.display()
        )));
    }
    let mut recorded = team_recording::read_recording(&bytes).map_err(|e| io_fail("cannot read", &args.file, e))?;
    let known_topics: BTreeSet<String> = recorded.iter().map(|r| r.channel.topic()).collect();
    for t in args.topic.iter().chain(args.to.iter().map(|(t, _, _)| t)) {
        if !known_topics.contains(t) {
            return Err(Fail::error(format!(
                "{} has no topic {t} (it has: {})",
                args.file.display(),
                known_topics.iter().cloned().collect::<Vec<_>>().join(", ")
            )));
        }
    }
    if !args.topic.is_empty() {
        recorded.retain(|r| args.topic.contains(&r.channel.topic()));
    }
    if recorded.is_empty() {
        return Err(Fail::error(format!("{} holds no team channel message to play", args.file.display())));
    }

    // Each topic's destination, and a port of ours connected to it.
    let mut client = Client::open(&args.net, 5.0)?;
    let mut ports: BTreeMap<String, String> = BTreeMap::new();
    let topics: BTreeSet<(String, ValueType, NodeId, String, String)> = recorded
        .iter()
        .map(|r| {
            let t = r.channel.topic();
            match args.to.iter().find(|(m, _, _)| *m == t) {
                Some((_, n, p)) => (t, r.channel.ty, *n, p.behavior.clone(), p.port.clone()),
                None => (t, r.channel.ty, r.channel.node, r.channel.behavior.clone(), r.channel.port.clone()),
            }
        })
        .collect();
    for (i, (topic, ty, node, behavior, port)) in topics.iter().enumerate() {
        client.find(*node)?;
        let path = PortPath { behavior: behavior.clone(), port: port.clone() };
        let theirs = read(&mut client, *node, &path)?.ty();
        if theirs != *ty {
            return Err(Fail::error(format!("{topic} holds {ty} values but {node}:{path} holds {theirs}")));
        }
        let name = format!("PLAY{i}");
        let mut class = BehaviorClass::new(&format!("Player{i}"));
        class.port(PortSpec::new("Out", Value::zero(*ty)))?;
        client.node.define(class)?;
        client.node.create(&format!("Player{i}"), &name)?;
        client.node.core_mut().connect(
            &Endpoint::local(&name, "Out"),
            &Endpoint::node(*node, behavior, port),
            ConnectionKind::Normal,
            ConnectOptions::default(),
        )?;
        eprintln!("play: {topic} -> {node}:{path}");
        ports.insert(topic.clone(), name);
    }

    let offsets = team_recording::playback_offsets(&recorded, args.speed);
    client.set_deadline(None);
    let started = StdInstant::now();
    let mut sent = 0u64;
    for (r, due) in recorded.iter().zip(offsets) {
        loop {
            let now = started.elapsed();
            if signals::stopped() {
                break;
            }
            if now >= due {
                break;
            }
            client.pump((due - now).min(SLICE));
        }
        if signals::stopped() {
            break;
        }
        client.node.write(&ports[&r.channel.topic()], "Out", r.value.clone())?;
        // Each value leaves now, as it was heard: two values due at once would otherwise merge
        // in our port (newest wins) and the first would never be sent.
        client.node.run_for(StdDuration::ZERO);
        sent += 1;
    }
    let span = (recorded.last().map_or(0, |r| r.log_time) - recorded[0].log_time) as f64 / 1e9;
    let line = format!(
        "played {sent} of {} messages on {} topics in {:.2}s (recorded over {span:.2}s, speed {})",
        recorded.len(),
        ports.len(),
        started.elapsed().as_secs_f64(),
        args.speed
    );
    if args.net.json {
        return emit(
            &serde_json::json!({"sent": sent, "messages": recorded.len(), "topics": ports.len(),
                "secs": started.elapsed().as_secs_f64(), "recorded_secs": span, "speed": args.speed})
            .to_string(),
        );
    }
    emit(&line)
}
