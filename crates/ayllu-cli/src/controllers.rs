//! `ayllu node`: one real node process hosting a standard controller, reporting its state as
//! one JSON line per status period on stdout — what the multi-process tests start and read.
//! The first line, printed once the socket is bound, says where the node listens
//! (`{"listening":"127.0.0.1:45125","node":1}`), so a node bound to port 0 can be found.
//!
//! * `cross-subsumption`: the stdlib controller of the paper's Fig. 2
//!   ([`ayllu::stdlib::cross_subsumption`], BLE group `Peers`). Its VISION ports are fed at
//!   10 Hz from `--sight` (target n at bearing 0.1·n rad, as in the in-process tests), so a
//!   node "sees" what the table says. Status:
//!   `{"t","node","drive","rotate","claims","peers","tools","counters"}` where `drive` is the layer
//!   whose observer turns BASE (0 = WANDER; null when BASE.Rotate is a value no layer writes,
//!   e.g. an override by hand) and `claims` the layers this node currently claims (BLE).
//! * `relay`: behaviors `RELAY` (int) and `FRELAY` (float), each `In -> (process) -> Out ->
//!   (connection) -> Aux`, for trying every connection kind by hand. Status:
//!   `{"t","node","relay":{..},"frelay":{..},"peers","tools","counters"}`.
//!
//! `peers` are the team members heard recently (node ids); the `ayllu` tool invocations heard
//! (`why`, `list`, `write`, ...) are left out of it, as `list` and `graph` leave them out, and
//! only counted in `tools`.
//!
//! Times are the node's own clock (seconds since it started).

use std::io::Write as _;
use std::time::{Duration as StdDuration, Instant as StdInstant};

use ayllu::stdlib::{base_class, cross_subsumption, sonar_class, wander_avoid, BASE, SONAR, VISION, WANDER_TURN};
use ayllu::{
    Access, Allow, BehaviorClass, ConnectionKind, Endpoint, Limits, MonotonicClock, Node, PortSpec, RecordOptions,
    Value,
};
use serde_json::{json, Map, Value as Json};

use crate::fail::Fail;
use crate::text::{counted, listening_json, round3, value_json};
use crate::{signals, Controller, NodeArgs};

/// The BLE group of the cross-subsumption layers.
const GROUP: &str = "Peers";
/// VISION is fed this often (the tests' 10 Hz camera).
const VISION_PERIOD: StdDuration = StdDuration::from_millis(100);

/// The bearing at which target `n` is seen.
fn bearing(target: u32) -> f64 {
    0.1 * f64::from(target)
}

/// Which layer drives the robot, from BASE.Rotate: observer n turns by `-bearing(n)`, WANDER
/// by [`WANDER_TURN`] (0 = WANDER). `None` for a value no layer writes (e.g. an engineer's
/// override by hand).
fn driving_layer(rotate: f64, layers: u32) -> Option<u32> {
    if rotate == WANDER_TURN {
        return Some(0);
    }
    (1..=layers).find(|&n| (rotate + bearing(n)).abs() < 1e-9)
}

/// RELAY / FRELAY: `In` triggers a copy to `Out`; `Out` feeds `Aux` by a local connection, so
/// `Aux` shows what `Out` let through.
fn relay_class(name: &str, zero: Value) -> Result<BehaviorClass, ayllu::Error> {
    let mut c = BehaviorClass::new(name);
    let input = c.port(PortSpec::new("In", zero.clone()))?;
    let out = c.port(PortSpec::new("Out", zero.clone()))?;
    c.port(PortSpec::new("Aux", zero))?;
    c.on_write("Copy", input, move |ctx| {
        let v = ctx.read(input);
        // A refusal here is counted on the port; nothing else to do.
        let _ = ctx.write(out, v);
    })?;
    Ok(c)
}

fn setup_relay(node: &mut Node) -> Result<(), Fail> {
    for (class, name, zero) in [("Relay", "RELAY", Value::Int(0)), ("FloatRelay", "FRELAY", Value::Float(0.0))] {
        node.define(relay_class(class, zero)?)?;
        node.create(class, name)?;
        node.connect(&Endpoint::local(name, "Out"), &Endpoint::local(name, "Aux"), ConnectionKind::Normal)?;
    }
    Ok(())
}

fn counters_json(node: &Node) -> Json {
    let transport: Map<String, Json> = node.transport_counters().into_iter().map(|(k, v)| (k, json!(v))).collect();
    let body: Map<String, Json> = node.core().body_counters().iter().map(|(k, v)| (k.clone(), json!(v))).collect();
    json!({"core": counted(&node.core().counters()), "transport": transport, "body": body})
}

fn relay_json(node: &Node, behavior: &str) -> Json {
    let mut m = Map::new();
    for port in ["In", "Out", "Aux"] {
        m.insert(port.to_owned(), node.read(behavior, port).map_or(Json::Null, |v| value_json(&v)));
    }
    Json::Object(m)
}

/// The name every `ayllu` tool invocation announces (`Client::open` in client.rs), which is
/// how `graph` leaves the tools out of the team too.
const TOOL_NAME: &str = "ayllu-cli";

/// The status line's `peers`: the team members heard recently, without the `ayllu` tool
/// invocations that asked this node something (each a peer of its own, ids from 0x7fff0000,
/// which would drown the robots after a few queries); those are only counted (`tools`).
fn peers_and_tools(node: &Node) -> (Vec<u32>, usize) {
    let (tools, peers): (Vec<_>, Vec<_>) = node.peers().into_iter().partition(|p| p.name == TOOL_NAME);
    (peers.iter().map(|p| p.node.0).collect(), tools.len())
}

fn status(node: &Node, args: &NodeArgs) -> Json {
    let (peers, tools) = peers_and_tools(node);
    let t = round3(node.now().as_secs_f64());
    match args.controller {
        Controller::CrossSubsumption => {
            let rotate = node.read(BASE, "Rotate").ok().and_then(|v| v.as_float()).unwrap_or(0.0);
            let claims: Vec<u32> = (1..=args.layers)
                .filter(|n| node.core().ble_status(&format!("OBS{n}")).ok().flatten().is_some_and(|s| s.claiming))
                .collect();
            json!({
                "t": t,
                "node": node.id().0,
                "drive": driving_layer(rotate, args.layers),
                "rotate": rotate,
                "claims": claims,
                "peers": peers,
                "tools": tools,
                "counters": counters_json(node),
            })
        }
        Controller::Relay => json!({
            "t": t,
            "node": node.id().0,
            "relay": relay_json(node, "RELAY"),
            "frelay": relay_json(node, "FRELAY"),
            "peers": peers,
            "tools": tools,
            "counters": counters_json(node),
        }),
        Controller::Wander => {
            let read = |b: &str, p: &str| {
                node.read(b, p).ok().and_then(|v| v.as_float()).map_or(Json::Null, |x| json!(round3(x)))
            };
            json!({
                "t": t,
                "node": node.id().0,
                "translate": read(BASE, "Translate"),
                "rotate": read(BASE, "Rotate"),
                "sonar_fresh": node.fresh(SONAR, "Ranges").unwrap_or(false),
                "avoiding": node.why(BASE, "Rotate").ok().is_some_and(|r| !r.windows.is_empty()),
                "peers": peers,
                "tools": tools,
                "counters": counters_json(node),
            })
        }
    }
}

fn feed_vision(node: &mut Node, args: &NodeArgs) -> Result<(), Fail> {
    for &(target, height) in &args.sight.0 {
        node.write(VISION, &format!("Target{target}Angle"), bearing(target))?;
        node.write(VISION, &format!("Target{target}Bottom"), height)?;
    }
    Ok(())
}

/// `--record FILE` never replaces a recording, as `sim run --mcap` and `keygen` never replace
/// their files: a robot restarted with the same command line would otherwise lose the flight
/// recording of the run before, the one wanted after a crash. The runtime (`Node::record`)
/// removes the segments that follow FILE (`FILE.1.mcap`, ...) so that they are not read as this
/// recording's; they belong to the earlier recording too, so they are refused as well.
fn refuse_existing_recording(path: &std::path::Path) -> Result<(), Fail> {
    // A rolling recording may have lost its first segments: any segment of the name counts.
    let mut numbers = ayllu::recording::segment_numbers(path);
    numbers.extend([0, 1]);
    for n in numbers {
        let segment = ayllu::recording::segment_path(path, n);
        if segment.symlink_metadata().is_ok() {
            return Err(Fail::error(format!(
                "{} exists (a flight recording is never replaced): move or remove it, or record into another file",
                segment.display()
            )));
        }
    }
    Ok(())
}

/// `--ros2 FILE`: the ROS 2 body the mapping file describes, attached to the node.
#[cfg(feature = "ros2")]
fn install_ros2(node: &mut Node, args: &NodeArgs) -> Result<(), Fail> {
    match &args.ros2 {
        Some(path) => ayllu_ros2::install_file(node, path).map_err(|e| Fail::error(e.to_string())),
        None => Ok(()),
    }
}

#[cfg(feature = "ros2")]
fn check_ros2(args: &NodeArgs) -> Result<(), Fail> {
    match &args.ros2 {
        Some(path) => ayllu_ros2::read_mapping(path, Some(args.id)).map(|_| ()).map_err(|e| Fail::error(e.to_string())),
        None => Ok(()),
    }
}

#[cfg(not(feature = "ros2"))]
fn check_ros2(args: &NodeArgs) -> Result<(), Fail> {
    install_ros2_missing(args)
}

#[cfg(not(feature = "ros2"))]
fn install_ros2(_node: &mut Node, args: &NodeArgs) -> Result<(), Fail> {
    install_ros2_missing(args)
}

#[cfg(not(feature = "ros2"))]
fn install_ros2_missing(args: &NodeArgs) -> Result<(), Fail> {
    match &args.ros2 {
        Some(_) => Err(Fail::error(ROS2_MISSING)),
        None => Ok(()),
    }
}

/// What a tool built without the ROS 2 body says when asked for one.
#[cfg(not(feature = "ros2"))]
pub const ROS2_MISSING: &str = "this ayllu was built without the ROS 2 body: build it with `make ros2` \
     (target/ros2/release/ayllu; docs/ros2.md)";

/// `ayllu node`.
pub fn run(args: &NodeArgs) -> Result<(), Fail> {
    if let Some(&(t, _)) = args.sight.0.iter().find(|(t, _)| *t > args.layers) {
        return Err(Fail::usage(format!("--sight names target {t}, but there are only {} layers", args.layers)));
    }
    crate::client::network_url(&args.udp)?;
    if let Some(path) = &args.record {
        refuse_existing_recording(path)?;
    }
    // A mistake in the mapping file is reported before anything opens.
    check_ros2(args)?;
    let open = ayllu::transport::url_setting(&args.udp, "key").is_none();
    let transport = ayllu::transport::open_named(&args.udp, args.id, &format!("node-{}", args.id.0))?;
    let mut node = Node::new(MonotonicClock::new(), transport);
    if let Some(path) = &args.record {
        // Before anything is declared: the replay rebuilds the node from its first definition.
        let mut options =
            args.record_max_bytes.map_or_else(RecordOptions::default, |n| RecordOptions::default().max_bytes(n));
        if let Some(secs) = args.record_last {
            options = options.keep_last(std::time::Duration::from_secs_f64(secs));
        }
        node.record(path, options)?;
    }
    node.core_mut().set_access(Access { ports: args.allow_write.clone(), structure: args.allow_rewire.clone() });
    let max_remote_period = ayllu::Duration::try_from_secs_f64(args.max_window)?;
    node.core_mut().set_limits(Limits { max_remote_period, ..Limits::default() });
    if open && (args.allow_write == Allow::Everyone || args.allow_rewire == Allow::Everyone) {
        eprintln!(
            "ayllu: warning: open team (no key= in the URL): anyone who can reach {} may write this node's ports \
             and rewire it; give the team a key, and narrow --allow-write / --allow-rewire",
            node.address().unwrap_or_default()
        );
    }
    match args.controller {
        Controller::CrossSubsumption => {
            let groups = cross_subsumption(node.core_mut(), args.layers, GROUP, args.claim_hz)?;
            for w in groups.iter().flat_map(|g| &g.warnings) {
                eprintln!("ayllu: warning: {w}");
            }
            // The body binds to the VISION and BASE the controller made.
            install_ros2(&mut node, args)?;
        }
        Controller::Relay => {
            setup_relay(&mut node)?;
            install_ros2(&mut node, args)?;
        }
        Controller::Wander => {
            // The body first: it makes the SONAR and BASE its mapping names; a node without one
            // gets the stdlib's (written by hand, `ayllu write`).
            install_ros2(&mut node, args)?;
            let core = node.core_mut();
            if core.behavior_ref(SONAR).is_err() {
                core.define(sonar_class(16, 5.0)?)?;
                core.create("Sonar", SONAR)?;
            }
            if core.behavior_ref(BASE).is_err() {
                core.define(base_class()?)?;
                core.create("Base", BASE)?;
            }
            wander_avoid(core, args.seed)?;
        }
    }
    signals::install();
    let ran = run_loop(&mut node, args);
    if let Some(stats) = node.stop_recording() {
        let dropped = stats.dropped_queue + stats.dropped_journal + stats.dropped_cap;
        eprintln!(
            "ayllu: recorded {} entries ({} bytes, {} segment(s)) into {}{}",
            stats.written,
            stats.bytes,
            stats.segments,
            args.record.as_deref().map_or(String::new(), |p| p.display().to_string()),
            if dropped > 0 { format!("; {dropped} entries not recorded (cap or slow disk)") } else { String::new() }
        );
        if let Some(secs) = args.record_last {
            eprintln!(
                "ayllu: rolling recording: kept {} segment(s), the last {secs} s or a little more; {} older deleted",
                stats.segments.saturating_sub(stats.deleted),
                stats.deleted
            );
        }
        if let Some(e) = stats.error {
            eprintln!("ayllu: warning: recording failed: {e}");
        }
    }
    ran
}

fn run_loop(node: &mut Node, args: &NodeArgs) -> Result<(), Fail> {
    let start = StdInstant::now();
    let end = args.for_secs.map(|s| start + StdDuration::from_secs_f64(s));
    let status_period = StdDuration::from_millis(args.status_ms);
    let feeds = args.controller == Controller::CrossSubsumption && !args.sight.0.is_empty();
    let mut next_vision = start;
    let mut next_status = start + status_period;
    let mut out = std::io::stdout().lock();
    writeln!(out, "{}", listening_json(node))?;
    out.flush()?;
    // Warnings already printed (set-up warnings were printed by `run`).
    let mut warned = node.core().warnings().len();
    loop {
        let now = StdInstant::now();
        if signals::stopped() || end.is_some_and(|e| now >= e) {
            return Ok(());
        }
        if feeds && now >= next_vision {
            feed_vision(node, args)?;
            next_vision = (next_vision + VISION_PERIOD).max(now);
        }
        if now >= next_status {
            // Warnings that appeared since (another node with our id, a self-triggering
            // process, ...) go to stderr as they come, not only into reports.
            for w in &node.core().warnings()[warned..] {
                eprintln!("ayllu: warning: {w}");
            }
            warned = node.core().warnings().len();
            // A reader that went away (closed pipe) ends the node: nobody is watching.
            writeln!(out, "{}", status(node, args))?;
            out.flush()?;
            next_status = (next_status + status_period).max(now);
        }
        let mut until = next_status;
        if feeds {
            until = until.min(next_vision);
        }
        if let Some(e) = end {
            until = until.min(e);
        }
        node.run_for(until.saturating_duration_since(StdInstant::now()));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ayllu::NodeId;

    #[test]
    fn the_driving_layer_is_decoded_from_rotate() {
        assert_eq!(driving_layer(WANDER_TURN, 4), Some(0));
        assert_eq!(driving_layer(-0.1, 4), Some(1));
        assert_eq!(driving_layer(-bearing(3), 4), Some(3));
        assert_eq!(driving_layer(-0.5, 4), None, "no fifth layer");
        assert_eq!(driving_layer(0.5, 4), None);
    }

    #[test]
    fn the_relay_copies_in_to_out_and_out_to_aux() {
        let mut node = Node::open(NodeId(1), "mem://cli-relay-unit").unwrap();
        setup_relay(&mut node).unwrap();
        node.write("RELAY", "In", 7i64).unwrap();
        node.write("FRELAY", "In", 2.5).unwrap();
        node.step();
        assert_eq!(node.read("RELAY", "Aux").unwrap(), Value::Int(7));
        assert_eq!(node.read("FRELAY", "Aux").unwrap(), Value::Float(2.5));
    }
}
