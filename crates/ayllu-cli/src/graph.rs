//! `ayllu graph`: the team's wiring (behaviors, ports, connections with their kinds; remote
//! and broadcast edges; windows open now) as DOT, Mermaid, SVG, HTML or JSON, like rqt_graph.
//! It listens for HELLOs, asks every node heard for LIST, asks WHY of the ports where
//! windowed connections land, and hands the answers to `crate::team_graph`.

use std::collections::BTreeMap;

use crate::team_graph::TeamGraph;
use ayllu::{ControlBody, NodeId, NodeReport, ReplyBody};
use clap::{Args, ValueEnum};

use crate::client::Client;
use crate::commands::emit;
use crate::fail::Fail;
use crate::{parse_node, signals, Net};

/// What `graph` prints.
#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum Format {
    Dot,
    Mermaid,
    Svg,
    Html,
    Json,
}

#[derive(Args, Debug)]
pub struct GraphArgs {
    /// Only these nodes (default: every node heard).
    #[arg(value_parser = parse_node)]
    pub nodes: Vec<NodeId>,
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Dot)]
    pub format: Format,
    /// Write to this file instead of stdout.
    #[arg(short = 'o', long = "output", value_name = "FILE")]
    pub output: Option<std::path::PathBuf>,
    /// How long to listen for nodes before asking them (seconds).
    #[arg(long, value_name = "SECS", default_value_t = 1.5, value_parser = crate::positive_secs)]
    pub listen: f64,
    #[command(flatten)]
    pub net: Net,
}

/// `ayllu graph`.
pub fn graph(args: &GraphArgs) -> Result<(), Fail> {
    signals::install();
    let mut client = Client::open(&args.net, args.listen)?;
    // A node named twice (`2 n2 0x2`) is drawn once.
    let mut nodes: Vec<NodeId> = Vec::new();
    for n in &args.nodes {
        if !nodes.contains(n) {
            nodes.push(*n);
        }
    }
    if nodes.is_empty() {
        client.listen();
        // Other tools (this one's siblings: ids from 0x7fff0000, name ayllu-cli) are not the team.
        nodes = client.peers().iter().filter(|p| p.name != "ayllu-cli").map(|p| p.node).collect();
        if nodes.is_empty() {
            return Err(Fail::error(format!("no node heard within {}s; {}", args.listen, client.hint())));
        }
    }
    client.set_deadline(Some(
        std::time::Instant::now() + std::time::Duration::from_secs_f64(args.net.timeout.unwrap_or(5.0)),
    ));
    let mut reports: Vec<NodeReport> = Vec::new();
    for node in &nodes {
        client.find(*node)?;
        match client.ask(*node, ControlBody::List, &format!("LIST {node}"))? {
            ReplyBody::Node(r) => reports.push(*r),
            _ => eprintln!("graph: {node} is an AylluLite node (no connections to draw); left out"),
        }
    }
    let names: BTreeMap<NodeId, String> = client.peers().into_iter().map(|p| (p.node, p.name)).collect();
    let mut g = TeamGraph::new(&reports, &names);
    for port in g.ports_with_windows() {
        let body = ControlBody::Why { behavior: port.behavior.as_str().into(), port: port.port.as_str().into() };
        match client.ask(port.node, body, &format!("WHY {}:{}.{}", port.node, port.behavior, port.port)) {
            Ok(ReplyBody::Port(r)) => g.mark(&r),
            Ok(_) => {}
            Err(e) => eprintln!("ayllu: warning: {} (its windows are not marked)", e.message),
        }
    }
    let text = match args.format {
        Format::Dot => g.dot(),
        Format::Mermaid => g.mermaid(),
        Format::Svg => g.svg(),
        Format::Html => g.html(&format!("Ayllu team: {} nodes, {} connections", g.nodes.len(), g.edges.len())),
        Format::Json => serde_json::to_string_pretty(&g.json()).unwrap_or_default(),
    };
    match &args.output {
        Some(path) => {
            std::fs::write(path, text).map_err(|e| Fail::error(format!("cannot write {}: {e}", path.display())))?;
            let active = g.edges.iter().filter(|e| e.active.is_some()).count();
            emit(&format!(
                "wrote {} ({} nodes, {} edges, {active} with a window open)",
                path.display(),
                g.nodes.len(),
                g.edges.len()
            ))
        }
        None => emit(&text),
    }
}
