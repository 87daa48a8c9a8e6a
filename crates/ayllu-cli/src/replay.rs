//! `ayllu replay FILE [--at T] why|list|echo|check`: a node's flight recording (`ayllu node
//! --record FILE`, `Node::record`) played back, answering as the live node would have at a
//! past instant. `ayllu replay FILE FILE... check` (or a folder) checks a team's recordings as
//! one system ([`ayllu::team_replay`]). The replay engine is the library's ([`ayllu::replay`]); this only parses,
//! and prints with the printers of the live `why`, `list` and `echo`, so a replayed answer
//! reads like a live one.
//!
//! Times (`--at`, `--from`, `--to`) are the node's own clock: seconds since it started, as
//! its status lines and `echo` print them (`12.5`, `12.5s`, `1500ms`).

use std::path::PathBuf;

use ayllu::replay::{Ending, Recording, Replay};
use ayllu::{Duration, Instant, NodeId};
use clap::{Args, Subcommand};
use serde_json::json;

use crate::commands::emit;
use crate::fail::Fail;
use crate::text::{human, node_report_json, node_report_text, port_report_json, value_json};
use crate::{parse_port_path, PortPath};

#[derive(Args, Debug)]
// `replay a.mcap b.mcap check`: the files end where a subcommand's name begins.
#[command(subcommand_precedence_over_arg = true)]
pub struct ReplayArgs {
    /// The recording: its first segment (`run.mcap`; `run.1.mcap`, ... are read after it).
    /// Several recordings, or a folder of them, are a team's: `check` replays them as one
    /// system (clocks aligned from the messages, every remote value matched with its sending).
    #[arg(required = true, num_args = 1.., value_name = "FILE")]
    pub files: Vec<PathBuf>,
    /// The instant to answer at, on the node's clock (`12.5`, `12.5s`, `1500ms`); default:
    /// the end of the recording.
    #[arg(long, value_name = "T", value_parser = parse_time, global = true)]
    pub at: Option<Instant>,
    /// Print JSON instead of text.
    #[arg(long, global = true)]
    pub json: bool,
    #[command(subcommand)]
    pub what: ReplayCommand,
}

#[derive(Subcommand, Debug)]
pub enum ReplayCommand {
    /// Explain one port as the live node would have at --at: value, supplier, windows (kind,
    /// holder, time left), what was blocked, counters.
    Why {
        /// BEHAVIOR.PORT
        #[arg(value_parser = parse_port_path)]
        target: PortPath,
        /// With a team's recordings: the node asked (its id, `2` or `n2`); --at is on its clock.
        #[arg(long, value_name = "ID", value_parser = parse_node)]
        node: Option<NodeId>,
        /// With a team's recordings: how many messages away to follow the causes (a window's
        /// holder, a value's sender, what their process read), into the other robots'
        /// recordings.
        #[arg(long, value_name = "N", default_value_t = 2)]
        depth: usize,
    },
    /// Describe the whole node as it was at --at.
    List,
    /// Print the values a port accepted between --from and --to (node time), as `echo` does.
    Echo {
        /// BEHAVIOR.PORT
        #[arg(value_parser = parse_port_path)]
        target: PortPath,
        /// From this instant (default: the start).
        #[arg(long, value_name = "T", value_parser = parse_time)]
        from: Option<Instant>,
        /// To this instant, included (default: --at, else the end).
        #[arg(long, value_name = "T", value_parser = parse_time)]
        to: Option<Instant>,
    },
    /// Replay the whole recording and check it: every accepted value reproduced bit for bit.
    /// With a team's recordings: each node's replay, their clocks against the first's (with a
    /// bound), and every remote value accepted matched with its sending (same value, sent no
    /// later, accepted once); exit 1 naming what does not hold.
    Check {
        /// With a team's recordings: also write every value their ports accepted, on one
        /// timeline (the first recording's clock), as an MCAP file Foxglove opens.
        #[arg(long, value_name = "FILE")]
        mcap: Option<PathBuf>,
    },
}

/// `2` or `n2`: a node id.
fn parse_node(s: &str) -> Result<NodeId, String> {
    s.trim().trim_start_matches('n').parse().map(NodeId).map_err(|_| format!("`{s}` is not a node id (e.g. 2 or n2)"))
}

/// `12.5`, `12.5s`, `1500ms`, `250us`, `100ns`: a node time.
pub fn parse_time(s: &str) -> Result<Instant, String> {
    let t = s.trim();
    let (number, scale) = if let Some(n) = t.strip_suffix("ms") {
        (n, 1e-3)
    } else if let Some(n) = t.strip_suffix("us") {
        (n, 1e-6)
    } else if let Some(n) = t.strip_suffix("ns") {
        (n, 1e-9)
    } else if let Some(n) = t.strip_suffix('s') {
        (n, 1.0)
    } else {
        (t, 1.0)
    };
    let x: f64 = number.trim().parse().map_err(|_| format!("`{s}` is not a time (e.g. 12.5s or 1500ms)"))?;
    // The value in seconds, printed compactly (`1e300 s`, not the core's 301 digits).
    let secs = x * scale;
    if !secs.is_finite() || secs < 0.0 || Duration::try_from_secs_f64(secs).is_err() {
        return Err(format!(
            "`{s}` ({} s) is not a time on the node's clock: times are seconds since the node's start, from 0 to \
             {LATEST_SECS} s (about 584 years)",
            crate::compact(secs)
        ));
    }
    let d = Duration::try_from_secs_f64(secs).map_err(|e| format!("`{s}`: {e}"))?;
    Ok(Instant::ZERO + d)
}

/// The latest whole second a node's clock holds (nanoseconds in 64 bits).
const LATEST_SECS: u64 = u64::MAX / 1_000_000_000;

fn secs(t: Instant) -> f64 {
    (t.as_secs_f64() * 1000.0).round() / 1000.0
}

/// `echo --from` after the end of its range (`--to`, else `--at`): an empty range is a mistake
/// in the arguments, refused before the file is read.
fn check_range(args: &ReplayArgs) -> Result<(), Fail> {
    let ReplayCommand::Echo { from: Some(from), to, .. } = &args.what else { return Ok(()) };
    let (name, to) = match (to, args.at) {
        (Some(to), _) => ("--to", *to),
        (None, Some(at)) => ("--at", at),
        (None, None) => return Ok(()),
    };
    if *from > to {
        return Err(Fail::usage(format!(
            "--from {from} is after {name} {to}: nothing lies between them; give --from at or before {name}"
        )));
    }
    Ok(())
}

/// The refusal of `--at` after the last instant a recording with a hole, a capped one or a
/// cut one tells about (spec/flight-recorder.md, "Replay": a replay never goes past it). The
/// node's life after it was not recorded (or the node died there): answering "at T" would
/// show windows lapsed and values aging as if it had lived on with no input, which is not
/// what happened, so there is no answer, only the instants there are answers for.
fn past_the_last_known(rec: &Recording, at: Instant, last: Instant) -> Fail {
    let why = match (&rec.gap, &rec.ending) {
        (Some((seq, _)), _) => format!("it has a hole at entry {seq}"),
        (None, Ending::Capped { .. }) => "it reached its size cap".to_owned(),
        _ => "it was cut short: the node was killed, or the file cut".to_owned(),
    };
    // Milliseconds, as everywhere in `replay`, unless they would print the two the same.
    let digits = if secs(at) == secs(last) { 9 } else { 3 };
    Fail::error(format!(
        "--at {:.digits$}s is after {:.digits$}s, the last instant this recording tells about ({why}): a replay never \
         answers past it; ask at or before that instant (without --at, replay answers at it)",
        at.as_secs_f64(),
        last.as_secs_f64()
    ))
}

/// The recordings `files` name: each file, and in each folder its recordings by their first
/// segment's name (`NAME.mcap` for `NAME.mcap` and `NAME.N.mcap`: a rolling recording may have
/// deleted its first segment), in name order.
fn recordings(files: &[PathBuf]) -> Result<Vec<PathBuf>, Fail> {
    let mut out = Vec::new();
    for f in files {
        if !f.is_dir() {
            out.push(f.clone());
            continue;
        }
        let mut found: Vec<PathBuf> = std::fs::read_dir(f)
            .map_err(|e| Fail::error(format!("{}: {e}", f.display())))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "mcap"))
            .map(|p| {
                // `run.1.mcap` is a later segment of `run.mcap`, read with it.
                let stem = p.file_stem().and_then(|s| s.to_str()).unwrap_or("");
                match stem.rsplit_once('.') {
                    Some((name, n)) if !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()) => {
                        p.with_file_name(format!("{name}.mcap"))
                    }
                    _ => p,
                }
            })
            .collect();
        found.sort();
        found.dedup();
        if found.is_empty() {
            return Err(Fail::error(format!("{}: no recording (*.mcap) in this folder", f.display())));
        }
        found.sort();
        out.extend(found);
    }
    Ok(out)
}

/// `ayllu replay` of a team's recordings: `check`, and `why --node N` followed across robots.
fn run_team(args: &ReplayArgs, files: &[PathBuf]) -> Result<(), Fail> {
    let mut recs = Vec::new();
    for f in files {
        let rec = Recording::open(f)?;
        eprintln!(
            "replay: {} — node {}, {} entries, {:.3}s of node time",
            f.display(),
            rec.node,
            rec.entries.len(),
            secs(rec.end())
        );
        recs.push(rec);
    }
    match &args.what {
        ReplayCommand::Check { mcap } => {
            let team = ayllu::team_replay::Team::open(recs);
            if let Some(path) = mcap {
                let n = team.write_timeline(path).map_err(|e| Fail::error(format!("{}: {e}", path.display())))?;
                eprintln!("replay: {n} accepted values on one timeline in {}", path.display());
            }
            let team = team.check();
            if args.json {
                emit(&team.to_json().to_string())?;
            } else {
                emit(team.to_string().trim_end())?;
            }
            if team.passed() {
                Ok(())
            } else {
                Err(Fail::error(format!(
                    "the team's recordings do not hold together: {} finding(s), {} remote value(s) unexplained",
                    team.findings.len(),
                    team.unexplained()
                )))
            }
        }
        ReplayCommand::Why { target, node, depth } => {
            let Some(node) = *node else {
                return Err(Fail::usage(format!(
                    "{} recordings: say which node's port with --node ID (--at is on its clock)",
                    files.len()
                )));
            };
            // Default: the last instant the node's recording tells about, as for one recording.
            let at = args.at.unwrap_or_else(|| {
                recs.iter().find(|r| r.node == node).map_or(Instant::ZERO, |r| r.last_known().unwrap_or(r.end()))
            });
            let team = ayllu::team_replay::Team::open(recs);
            let chain = team.why(node, at, &target.behavior, &target.port, *depth)?;
            if args.json {
                emit(&chain.to_json().to_string())
            } else {
                emit(chain.to_string().trim_end())
            }
        }
        _ => Err(Fail::usage(format!(
            "{} recordings: a team replay answers `check` and `why --node ID` (list and echo take one recording: its \
             node's)",
            files.len()
        ))),
    }
}

/// `ayllu replay`.
pub fn run(args: &ReplayArgs) -> Result<(), Fail> {
    check_range(args)?;
    let files = recordings(&args.files)?;
    if files.len() > 1 {
        return run_team(args, &files);
    }
    let file = &files[0];
    let rec = Recording::open(file)?;
    if let ReplayCommand::Why { node: Some(node), .. } = &args.what {
        if *node != rec.node {
            return Err(Fail::usage(format!(
                "--node {node}: {} is a recording of {}; give {node}'s recording too (a team replay follows causes \
                 across recordings)",
                file.display(),
                rec.node
            )));
        }
    }
    let end = rec.end();
    // A recording with a hole, or capped or cut, tells nothing after its last known instant:
    // the default instant is that one, and a later --at is refused (see `past_the_last_known`).
    let last_known = rec.last_known();
    let at = args.at.unwrap_or(last_known.unwrap_or(end));
    let ending = match &rec.gap {
        Some((seq, t)) => format!("{}, with a hole at entry {seq} (t={:.3}s): replayed up to it", rec.ending, secs(*t)),
        None => rec.ending.to_string(),
    };
    let mut known = last_known.map_or(String::new(), |last| {
        format!("; it tells about the node up to t={:.3}s, and a replay answers no later", secs(last))
    });
    if let Some(c) = &rec.checkpoint {
        known.push_str(&format!(
            "; rolling: it starts from its checkpoint at t={:.3}s (entry {}), what came before was not kept",
            secs(c.at),
            c.seq
        ));
    }
    eprintln!(
        "replay: {} — node {}, {} entries in {} segment(s), {:.3}s of node time, {ending}{known}",
        file.display(),
        rec.node,
        rec.entries.len(),
        rec.segments.len(),
        secs(end)
    );
    if !matches!(args.what, ReplayCommand::Check { .. }) {
        if let Some(last) = last_known.filter(|&last| at > last) {
            return Err(past_the_last_known(&rec, at, last));
        }
    }
    if at > end && !matches!(args.what, ReplayCommand::Check { .. }) {
        eprintln!("replay: warning: --at {:.3}s is after the recording's end ({:.3}s)", secs(at), secs(end));
    }
    let mut replay = Replay::new(&rec);
    match &args.what {
        ReplayCommand::Why { target, .. } => {
            let report = replay.why_at(at, &target.behavior, &target.port)?;
            if args.json {
                emit(&serde_json::to_string_pretty(&port_report_json(&report)).unwrap_or_default())
            } else {
                emit(&report.to_string())
            }
        }
        ReplayCommand::List => {
            let report = replay.list_at(at)?;
            if args.json {
                emit(&serde_json::to_string_pretty(&node_report_json(&report)).unwrap_or_default())
            } else {
                emit(&node_report_text(&report, None))
            }
        }
        ReplayCommand::Echo { target, from, to } => {
            let from = from.unwrap_or(Instant::ZERO);
            let to = to.or(args.at).unwrap_or(end);
            if from > end {
                eprintln!(
                    "replay: warning: --from {:.3}s is after the recording's end ({:.3}s)",
                    secs(from),
                    secs(end)
                );
            }
            replay.run_until(to).map_err(|d| Fail::error(d.to_string()))?;
            let core = replay.core();
            core.port(&target.behavior, &target.port)?;
            let ty = core.read(core.port(&target.behavior, &target.port)?)?.ty();
            for a in replay.accepted() {
                if a.at < from || a.at > to || *a.behavior != *target.behavior || a.port != target.port {
                    continue;
                }
                let line = if args.json {
                    json!({"t": secs(a.at), "node": rec.node.0, "port": target.to_string(), "type": ty.name(),
                           "value": value_json(&a.value)})
                    .to_string()
                } else {
                    format!("{:>9.3}  {}", secs(a.at), human(&a.value))
                };
                emit(&line)?;
            }
            Ok(())
        }
        ReplayCommand::Check { mcap } => {
            if mcap.is_some() {
                return Err(Fail::usage("--mcap writes a team's timeline: give two recordings or more"));
            }
            replay.run_to_end().map_err(|d| Fail::error(d.to_string()))?;
            let complete = rec.ending == Ending::Closed && rec.gap.is_none();
            let line = if args.json {
                json!({"node": rec.node.0, "entries": rec.entries.len(), "accepted_checked": replay.checked(),
                       "start": secs(rec.start()), "checkpoint_entry": rec.checkpoint.as_ref().map(|c| c.seq),
                       "end": secs(end), "ending": ending, "complete": complete})
                .to_string()
            } else {
                let from = rec
                    .checkpoint
                    .as_ref()
                    .map_or(String::new(), |c| format!("from its checkpoint at t={:.3}s ", secs(c.at)));
                format!(
                    "replayed {from}to t={:.3}s: {} accepted values reproduced bit for bit; recording {ending}",
                    secs(replay.reached().min(end)),
                    replay.checked()
                )
            };
            emit(&line)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_parse_in_seconds_and_with_units() {
        assert_eq!(parse_time("12.5"), Ok(Instant::from_millis(12_500)));
        assert_eq!(parse_time("12.5s"), Ok(Instant::from_millis(12_500)));
        assert_eq!(parse_time("1500ms"), Ok(Instant::from_millis(1500)));
        assert_eq!(parse_time("250us"), Ok(Instant::from_micros(250)));
        assert!(parse_time("-1").is_err());
        assert!(parse_time("soon").is_err());
        assert!(parse_time("1e300").is_err());
        assert!(parse_time("NaN").is_err());
    }

    #[test]
    fn times_beyond_the_clock_are_printed_compactly_with_the_range() {
        let e = parse_time("1e300").unwrap_err();
        assert_eq!(
            e,
            "`1e300` (1e300 s) is not a time on the node's clock: times are seconds since the node's start, from 0 \
             to 18446744073 s (about 584 years)"
        );
        assert!(parse_time("1e300ms").unwrap_err().contains("(1e297 s)"));
        assert!(parse_time("-1").unwrap_err().contains("(-1 s) is not a time on the node's clock"));
        assert!(parse_time("18446744073s").is_ok());
        assert!(parse_time("18446744074s").is_err());
    }
}
