//! The team's wiring as a graph: nodes, their behaviors and ports, and every connection with
//! its kind — local, remote (to a named node) and broadcast (to a group, one edge per member
//! that has the port) — with the windows open now marked. Drawn as Graphviz DOT, Mermaid, a
//! standalone SVG (laid out here, so no Graphviz is needed at run time) and an HTML page
//! around the SVG. `ayllu graph` fills it from the nodes' LIST and WHY answers.
//!
//! Promises: pure (the reports in, text out); the same reports give the same text, nodes by
//! id and connections by (owner, id); every name is escaped for the format it goes into, so
//! any behavior or port name yields a well-formed document.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use ayllu::{ConnectionKind, Endpoint, NodeId, NodeReport, PortReport};
use serde_json::{json, Value as Json};

/// The HTML page's self-check, for people and for the browser test: once loaded, the page
/// writes on its `<body>` how many edges it drew (`data-edges`), how many are active
/// (`data-active`), how many drawn elements fall outside the SVG's box (`data-outside`), the
/// script errors it saw (`data-errors`) and `data-status="drawn"`.
const PAGE_CHECK: &str = "(function(){var errs=0;window.addEventListener('error',function(){errs++;});\
window.addEventListener('load',function(){var b=document.body;try{var svg=document.querySelector('#graph svg');\
var vb=svg.viewBox.baseVal,out=0,els=svg.querySelectorAll('path.edge,rect,text,ellipse');\
for(var i=0;i<els.length;i++){var r=els[i].getBBox();\
if(r.x<-1||r.y<-1||r.x+r.width>vb.width+1||r.y+r.height>vb.height+1){out++;}}\
b.setAttribute('data-edges',svg.querySelectorAll('path.edge').length);\
b.setAttribute('data-active',svg.querySelectorAll('path.edge.active').length);\
b.setAttribute('data-outside',out);b.setAttribute('data-status','drawn');}catch(e){errs++;}\
b.setAttribute('data-errors',errs);});})();";

/// A port of the team.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct PortRef {
    /// Its node.
    pub node: NodeId,
    /// Its behavior instance.
    pub behavior: String,
    /// The port.
    pub port: String,
}

impl PortRef {
    fn id(&self) -> String {
        // Identifiers for DOT and Mermaid: letters, digits and `_` only, unique per port.
        let clean = |s: &str| -> String {
            s.bytes()
                .map(|b| if b.is_ascii_alphanumeric() { (b as char).to_string() } else { format!("_{b:02x}") })
                .collect()
        };
        format!("n{}__{}__{}", self.node.0, clean(&self.behavior), clean(&self.port))
    }
}

/// How an edge reaches its destination.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Reach {
    /// A port of the owning node.
    Local,
    /// A port of a named node.
    Remote,
    /// A member of a broadcast group (the group's name).
    Broadcast(String),
}

/// A window a connection holds open at its destination now.
#[derive(Clone, Debug, PartialEq)]
pub struct Active {
    /// The window's kind (`suppress`, `inhibit`, ...).
    pub kind: String,
    /// Seconds it stays open unless renewed.
    pub remaining: f64,
}

/// One connection, or for a group one member's share of it.
#[derive(Clone, Debug, PartialEq)]
pub struct Edge {
    /// The node that owns the connection.
    pub owner: NodeId,
    /// Its id there.
    pub conn: u64,
    /// The source port.
    pub from: PortRef,
    /// The destination port; `None` for a group with no member that has the port (drawn to
    /// the group itself).
    pub to: Option<PortRef>,
    /// Local, remote or broadcast.
    pub reach: Reach,
    /// Kind and period.
    pub kind: ConnectionKind,
    /// Priority at a Priority port.
    pub priority: i32,
    /// Messages sent so far.
    pub sent: u64,
    /// The window it holds open at `to` now, if any (from WHY).
    pub active: Option<Active>,
    /// The destination as the owner names it (`n2:OBS1.Best`, `*Peers:OBS1.Best`).
    pub target: String,
}

/// A behavior and its ports.
#[derive(Clone, Debug, PartialEq)]
pub struct Behavior {
    /// Instance name.
    pub name: String,
    /// Class name.
    pub class: String,
    /// Ports: name, kind (`normal`, `max`, ...), value type.
    pub ports: Vec<(String, String, String)>,
}

/// A node of the team.
#[derive(Clone, Debug, PartialEq)]
pub struct GraphNode {
    /// Its id.
    pub id: NodeId,
    /// The name it announces (may be empty).
    pub name: String,
    /// Broadcast groups it joined.
    pub groups: Vec<String>,
    /// Its behaviors.
    pub behaviors: Vec<Behavior>,
}

/// The team's wiring.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct TeamGraph {
    /// Nodes by id.
    pub nodes: Vec<GraphNode>,
    /// Edges by (owner, connection, destination node).
    pub edges: Vec<Edge>,
}

fn kind_color(kind: ConnectionKind) -> &'static str {
    match kind {
        ConnectionKind::Normal => "#444444",
        ConnectionKind::Suppress(_) => "#c0392b",
        ConnectionKind::Inhibit(_) => "#d35400",
        ConnectionKind::OverrideIn(_) => "#2471a3",
        ConnectionKind::OverrideOut(_) => "#17a589",
        ConnectionKind::WriteInhibit(_) => "#8e44ad",
    }
}

fn port_kind_name(kind: ayllu::PortKind) -> &'static str {
    match kind {
        ayllu::PortKind::Normal => "normal",
        ayllu::PortKind::Max => "max",
        ayllu::PortKind::Min => "min",
        ayllu::PortKind::Sum => "sum",
        ayllu::PortKind::Priority => "priority",
    }
}

impl TeamGraph {
    /// The graph of the nodes that answered LIST; `names` are the names nodes announce.
    pub fn new(reports: &[NodeReport], names: &BTreeMap<NodeId, String>) -> TeamGraph {
        let mut reports: Vec<&NodeReport> = reports.iter().collect();
        reports.sort_by_key(|r| r.node);
        let nodes: Vec<GraphNode> = reports
            .iter()
            .map(|r| GraphNode {
                id: r.node,
                name: names.get(&r.node).cloned().unwrap_or_default(),
                groups: r.groups.clone(),
                behaviors: r
                    .behaviors
                    .iter()
                    .map(|b| Behavior {
                        name: b.name.clone(),
                        class: b.class.clone(),
                        ports: b
                            .ports
                            .iter()
                            .map(|p| (p.name.clone(), port_kind_name(p.kind).to_owned(), p.ty.name().to_owned()))
                            .collect(),
                    })
                    .collect(),
            })
            .collect();
        let has_port = |node: NodeId, b: &str, p: &str| {
            nodes.iter().any(|n| {
                n.id == node && n.behaviors.iter().any(|x| x.name == b && x.ports.iter().any(|(q, _, _)| q == p))
            })
        };
        let mut edges = Vec::new();
        for r in &reports {
            let mut conns = r.connections.clone();
            conns.sort_by_key(|c| c.id);
            for c in conns {
                let (Endpoint::Local { behavior, port } | Endpoint::Node { behavior, port, .. }) = &c.source else {
                    continue;
                };
                let from = PortRef { node: r.node, behavior: behavior.to_string(), port: port.to_string() };
                let edge = |to: Option<PortRef>, reach: Reach| Edge {
                    owner: r.node,
                    conn: c.id.0,
                    from: from.clone(),
                    to,
                    reach,
                    kind: c.kind,
                    priority: c.priority,
                    sent: c.sent,
                    active: None,
                    target: ayllu::team_channels::destination_text(r.node, &c.destination),
                };
                match &c.destination {
                    Endpoint::Local { behavior, port } => edges.push(edge(
                        Some(PortRef { node: r.node, behavior: behavior.to_string(), port: port.to_string() }),
                        Reach::Local,
                    )),
                    Endpoint::Node { node, behavior, port } => {
                        let reach = if *node == r.node { Reach::Local } else { Reach::Remote };
                        edges.push(edge(
                            Some(PortRef { node: *node, behavior: behavior.to_string(), port: port.to_string() }),
                            reach,
                        ))
                    }
                    Endpoint::Group { group, behavior, port } => {
                        let members: Vec<NodeId> = nodes
                            .iter()
                            .filter(|n| n.id != r.node && n.groups.iter().any(|g| **g == **group))
                            .filter(|n| has_port(n.id, behavior, port))
                            .map(|n| n.id)
                            .collect();
                        if members.is_empty() {
                            edges.push(edge(None, Reach::Broadcast(group.to_string())));
                        }
                        for m in members {
                            edges.push(edge(
                                Some(PortRef { node: m, behavior: behavior.to_string(), port: port.to_string() }),
                                Reach::Broadcast(group.to_string()),
                            ));
                        }
                    }
                }
            }
        }
        TeamGraph { nodes, edges }
    }

    /// The ports whose windows say which edges are active: destinations of every connection
    /// that opens windows (every kind but normal), once each.
    pub fn ports_with_windows(&self) -> Vec<PortRef> {
        let mut v: Vec<PortRef> = self
            .edges
            .iter()
            .filter(|e| e.kind.period().is_some())
            .filter_map(|e| e.to.clone())
            .filter(|p| self.nodes.iter().any(|n| n.id == p.node))
            .collect();
        v.sort();
        v.dedup();
        v
    }

    /// Mark the edges whose windows `report` (a WHY answer) shows open.
    pub fn mark(&mut self, report: &PortReport) {
        for w in &report.windows {
            for e in &mut self.edges {
                let here = e
                    .to
                    .as_ref()
                    .is_some_and(|p| p.node == report.node && p.behavior == report.behavior && p.port == report.port);
                if here && e.owner == w.holder.node && e.conn == w.holder.conn {
                    e.active = Some(Active { kind: w.kind.name().to_owned(), remaining: w.remaining.as_secs_f64() });
                }
            }
        }
    }

    fn edge_label(e: &Edge) -> String {
        let mut label = e.kind.to_string();
        if let Reach::Broadcast(g) = &e.reach {
            label = format!("*{g} {label}");
        }
        if let Some(a) = &e.active {
            label.push_str(&format!(" ACTIVE {:.1}s", a.remaining));
        }
        label
    }

    fn node_title(n: &GraphNode) -> String {
        if n.name.is_empty() {
            format!("{}", n.id)
        } else {
            format!("{} {}", n.id, n.name)
        }
    }

    /// Graphviz DOT: a cluster per node and per behavior, a box per port, an edge per
    /// connection coloured by kind (broadcast dashed, active bold with the time left).
    pub fn dot(&self) -> String {
        let q = |s: &str| s.replace('\\', "\\\\").replace('"', "\\\"");
        let mut out = String::from(
            "digraph team {\n  rankdir=LR;\n  newrank=true;\n  compound=true;\n  node [shape=box, fontsize=10, height=0.2];\n  edge [fontsize=9];\n",
        );
        for n in &self.nodes {
            let _ = writeln!(out, "  subgraph cluster_n{} {{\n    label=\"{}\";", n.id.0, q(&Self::node_title(n)));
            for (i, b) in n.behaviors.iter().enumerate() {
                let _ = writeln!(
                    out,
                    "    subgraph cluster_n{}_b{i} {{\n      label=\"{} ({})\";",
                    n.id.0,
                    q(&b.name),
                    q(&b.class)
                );
                for (p, kind, ty) in &b.ports {
                    let r = PortRef { node: n.id, behavior: b.name.clone(), port: p.clone() };
                    let _ = writeln!(out, "      {} [label=\"{} ({kind} {ty})\"];", r.id(), q(p));
                }
                out.push_str("    }\n");
            }
            out.push_str("  }\n");
        }
        for e in &self.edges {
            let to = match &e.to {
                Some(p) => p.id(),
                None => {
                    let Reach::Broadcast(g) = &e.reach else { continue };
                    let id = group_id(g);
                    let _ = writeln!(out, "  {id} [shape=ellipse, label=\"*{}\"];", q(g));
                    id
                }
            };
            let mut attrs = vec![
                format!("label=\"{}\"", q(&Self::edge_label(e))),
                format!("color=\"{}\"", kind_color(e.kind)),
                format!("fontcolor=\"{}\"", kind_color(e.kind)),
            ];
            if matches!(e.reach, Reach::Broadcast(_)) {
                attrs.push("style=dashed".into());
            }
            if e.active.is_some() {
                attrs.push("penwidth=3".into());
            }
            let _ = writeln!(out, "  {} -> {to} [{}];", e.from.id(), attrs.join(", "));
        }
        out.push_str("}\n");
        out
    }

    /// Mermaid `flowchart LR`: a subgraph per node and per behavior; active edges thick.
    pub fn mermaid(&self) -> String {
        // Mermaid labels are quoted; `"` cannot be escaped inside them, `#quot;` is its entity.
        let q = |s: &str| s.replace('"', "#quot;");
        let mut out = String::from("flowchart LR\n");
        for n in &self.nodes {
            let _ = writeln!(out, "  subgraph n{}[\"{}\"]", n.id.0, q(&Self::node_title(n)));
            for (i, b) in n.behaviors.iter().enumerate() {
                let _ = writeln!(out, "    subgraph n{}_b{i}[\"{} ({})\"]", n.id.0, q(&b.name), q(&b.class));
                for (p, kind, ty) in &b.ports {
                    let r = PortRef { node: n.id, behavior: b.name.clone(), port: p.clone() };
                    let _ = writeln!(out, "      {}[\"{} ({kind} {ty})\"]", r.id(), q(p));
                }
                out.push_str("    end\n");
            }
            out.push_str("  end\n");
        }
        for e in &self.edges {
            let to = match &e.to {
                Some(p) => p.id(),
                None => {
                    let Reach::Broadcast(g) = &e.reach else { continue };
                    let id = group_id(g);
                    let _ = writeln!(out, "  {id}((\"*{}\"))", q(g));
                    id
                }
            };
            let arrow = match (&e.reach, e.active.is_some()) {
                (_, true) => "==",
                (Reach::Broadcast(_), false) => "-.",
                _ => "--",
            };
            let head = if arrow == "-." {
                ".->"
            } else if arrow == "==" {
                "==>"
            } else {
                "-->"
            };
            let _ = writeln!(out, "  {} {arrow} \"{}\" {head} {to}", e.from.id(), q(&Self::edge_label(e)));
        }
        out
    }

    /// The graph as JSON: `{"nodes":[...],"edges":[...]}`.
    pub fn json(&self) -> Json {
        let port = |p: &PortRef| json!({"node": p.node.0, "behavior": p.behavior, "port": p.port});
        json!({
            "nodes": self.nodes.iter().map(|n| json!({
                "node": n.id.0, "name": n.name, "groups": n.groups,
                "behaviors": n.behaviors.iter().map(|b| json!({
                    "name": b.name, "class": b.class,
                    "ports": b.ports.iter().map(|(p, k, t)| json!({"name": p, "kind": k, "type": t})).collect::<Vec<_>>(),
                })).collect::<Vec<_>>(),
            })).collect::<Vec<_>>(),
            "edges": self.edges.iter().map(|e| json!({
                "owner": e.owner.0, "conn": e.conn, "from": port(&e.from), "to": e.to.as_ref().map(port),
                "target": e.target,
                "reach": match &e.reach { Reach::Local => "local".to_owned(), Reach::Remote => "remote".to_owned(), Reach::Broadcast(g) => format!("broadcast:{g}") },
                "kind": e.kind.name(), "period": e.kind.period().map(|p| p.as_secs_f64()),
                "priority": e.priority, "sent": e.sent,
                "active": e.active.as_ref().map(|a| json!({"kind": a.kind, "remaining": a.remaining})),
            })).collect::<Vec<_>>(),
        })
    }

    /// A standalone SVG: one column per node, behaviors stacked as boxes listing their ports,
    /// connections as curves between the ports (coloured by kind; broadcast dashed; active
    /// thick, labelled with the time left), a legend at the bottom.
    pub fn svg(&self) -> String {
        const COL_W: f64 = 230.0;
        const GAP: f64 = 170.0;
        const ROW: f64 = 16.0;
        const HEAD: f64 = 20.0;
        const TOP: f64 = 40.0;
        let esc = |s: &str| s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;");
        let mut body = String::new();
        let mut anchors: BTreeMap<PortRef, (f64, f64, usize)> = BTreeMap::new();
        let mut group_anchor: BTreeMap<String, (f64, f64)> = BTreeMap::new();
        let mut height: f64 = TOP;
        for (col, n) in self.nodes.iter().enumerate() {
            let x = 20.0 + col as f64 * (COL_W + GAP);
            let mut y = TOP;
            let _ = writeln!(
                body,
                "<text x=\"{:.1}\" y=\"{:.1}\" class=\"node\">{}</text>",
                x,
                y - 12.0,
                esc(&Self::node_title(n))
            );
            for b in &n.behaviors {
                let h = HEAD + ROW * b.ports.len() as f64 + 4.0;
                let _ = writeln!(
                    body,
                    "<rect x=\"{x:.1}\" y=\"{y:.1}\" width=\"{COL_W:.1}\" height=\"{h:.1}\" rx=\"4\" class=\"behavior\"/>\
                     <text x=\"{:.1}\" y=\"{:.1}\" class=\"bname\">{} ({})</text>",
                    x + 6.0,
                    y + 14.0,
                    esc(&b.name),
                    esc(&b.class)
                );
                for (i, (p, kind, ty)) in b.ports.iter().enumerate() {
                    let py = y + HEAD + ROW * i as f64 + ROW / 2.0;
                    let _ = writeln!(
                        body,
                        "<text x=\"{:.1}\" y=\"{:.1}\" class=\"port\">{} <tspan class=\"ty\">{kind} {ty}</tspan></text>",
                        x + 12.0,
                        py + 4.0,
                        esc(p)
                    );
                    anchors.insert(PortRef { node: n.id, behavior: b.name.clone(), port: p.clone() }, (x, py, col));
                }
                y += h + 10.0;
            }
            height = height.max(y);
        }
        let mut extra_col = self.nodes.len();
        for e in &self.edges {
            if let (None, Reach::Broadcast(g)) = (&e.to, &e.reach) {
                if !group_anchor.contains_key(g) {
                    let x = 20.0 + extra_col as f64 * (COL_W + GAP);
                    let y = TOP + 20.0 * group_anchor.len() as f64;
                    extra_col += 1;
                    group_anchor.insert(g.clone(), (x, y));
                    let _ = writeln!(
                        body,
                        "<ellipse cx=\"{:.1}\" cy=\"{y:.1}\" rx=\"50\" ry=\"12\" class=\"group\"/><text x=\"{:.1}\" y=\"{:.1}\" class=\"port\" text-anchor=\"middle\">*{}</text>",
                        x + 50.0,
                        x + 50.0,
                        y + 4.0,
                        esc(g)
                    );
                }
            }
        }
        // Room on the right for the last column's loops (same-node edges) and their labels.
        let width = 40.0 + extra_col.max(1) as f64 * (COL_W + GAP) - GAP + 140.0;
        let mut loops = 0usize;
        for e in &self.edges {
            let Some(&(sx, sy, scol)) = anchors.get(&e.from) else { continue };
            let (tx, ty, tcol) = match &e.to {
                Some(p) => match anchors.get(p) {
                    Some(a) => *a,
                    None => continue,
                },
                None => {
                    let Reach::Broadcast(g) = &e.reach else { continue };
                    let (gx, gy) = group_anchor[g];
                    (gx, gy, usize::MAX)
                }
            };
            let (x1, x2, path) = if tcol == scol {
                // Same node: a loop out to the right of the column.
                loops += 1;
                let x1 = sx + COL_W;
                let bulge = x1 + 30.0 + 12.0 * (loops % 6) as f64;
                (x1, x1, format!("M{x1:.1},{sy:.1} C{bulge:.1},{sy:.1} {bulge:.1},{ty:.1} {x1:.1},{ty:.1}"))
            } else if tcol > scol {
                let (x1, x2) = (sx + COL_W, tx);
                let c = (x2 - x1) / 2.0;
                (x1, x2, format!("M{x1:.1},{sy:.1} C{:.1},{sy:.1} {:.1},{ty:.1} {x2:.1},{ty:.1}", x1 + c, x2 - c))
            } else {
                let (x1, x2) = (sx, tx + COL_W);
                let c = (x1 - x2) / 2.0;
                (x1, x2, format!("M{x1:.1},{sy:.1} C{:.1},{sy:.1} {:.1},{ty:.1} {x2:.1},{ty:.1}", x1 - c, x2 + c))
            };
            let mut class = String::from("edge");
            if matches!(e.reach, Reach::Broadcast(_)) {
                class.push_str(" broadcast");
            }
            if e.active.is_some() {
                class.push_str(" active");
            }
            let color = kind_color(e.kind);
            let _ = writeln!(
                body,
                "<path d=\"{path}\" class=\"{class}\" stroke=\"{color}\" marker-end=\"url(#arrow)\"><title>{}: {}.{} -&gt; {} ({})</title></path>",
                esc(&format!("{}/c{}", e.owner, e.conn)),
                esc(&e.from.behavior),
                esc(&e.from.port),
                esc(&e.target),
                esc(&Self::edge_label(e))
            );
            if e.kind.period().is_some() || e.active.is_some() {
                let (lx, ly) =
                    if tcol == scol { (x1 + 34.0, (sy + ty) / 2.0) } else { ((x1 + x2) / 2.0, (sy + ty) / 2.0 - 3.0) };
                let _ = writeln!(
                    body,
                    "<text x=\"{lx:.1}\" y=\"{ly:.1}\" class=\"elabel\" fill=\"{color}\" text-anchor=\"middle\">{}</text>",
                    esc(&Self::edge_label(e))
                );
            }
        }
        let legend_y = height + 20.0;
        let mut legend = String::new();
        for (i, kind) in [
            ConnectionKind::Normal,
            ConnectionKind::Suppress(ayllu::Duration::ZERO),
            ConnectionKind::Inhibit(ayllu::Duration::ZERO),
            ConnectionKind::OverrideIn(ayllu::Duration::ZERO),
            ConnectionKind::OverrideOut(ayllu::Duration::ZERO),
            ConnectionKind::WriteInhibit(ayllu::Duration::ZERO),
        ]
        .into_iter()
        .enumerate()
        {
            let x = 20.0 + 120.0 * i as f64;
            let _ = writeln!(
                legend,
                "<line x1=\"{x:.1}\" y1=\"{legend_y:.1}\" x2=\"{:.1}\" y2=\"{legend_y:.1}\" class=\"edge\" stroke=\"{}\"/>\
                 <text x=\"{:.1}\" y=\"{:.1}\" class=\"port\">{}</text>",
                x + 30.0,
                kind_color(kind),
                x + 35.0,
                legend_y + 4.0,
                kind.name()
            );
        }
        let _ = writeln!(
            legend,
            "<text x=\"20\" y=\"{:.1}\" class=\"port\">dashed: broadcast (group) · thick: window open now (ACTIVE, time left)</text>",
            legend_y + 22.0
        );
        let total_h = legend_y + 36.0;
        format!(
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{width:.0}\" height=\"{total_h:.0}\" viewBox=\"0 0 {width:.0} {total_h:.0}\" font-family=\"sans-serif\">\n\
             <defs><marker id=\"arrow\" viewBox=\"0 0 10 10\" refX=\"10\" refY=\"5\" markerWidth=\"6\" markerHeight=\"6\" orient=\"auto-start-reverse\"><path d=\"M0,0 L10,5 L0,10 z\" fill=\"context-stroke\"/></marker>\n\
             <style>.node{{font-size:14px;font-weight:bold}} .behavior{{fill:#f7f7f7;stroke:#888}} .bname{{font-size:11px;font-weight:bold}} \
             .port{{font-size:10px}} .ty{{fill:#888}} .group{{fill:#fff;stroke:#555;stroke-dasharray:4 2}} .edge{{fill:none;stroke-width:1.3;opacity:0.8}} \
             .broadcast{{stroke-dasharray:5 3}} .active{{stroke-width:3.5;opacity:1}} .elabel{{font-size:9px}}</style></defs>\n\
             {body}{legend}</svg>\n"
        )
    }

    /// An HTML page: the SVG, and a table of every connection (kind, reach, sent, active).
    pub fn html(&self, title: &str) -> String {
        let esc = |s: &str| s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;");
        let mut rows = String::new();
        for e in &self.edges {
            let reach = match &e.reach {
                Reach::Local => "local".to_owned(),
                Reach::Remote => "remote".to_owned(),
                Reach::Broadcast(g) => format!("broadcast *{g}"),
            };
            let to = e.to.as_ref().map_or(e.target.clone(), |p| format!("{}:{}.{}", p.node, p.behavior, p.port));
            let active = e.active.as_ref().map_or(String::new(), |a| format!("{} {:.1}s", a.kind, a.remaining));
            let _ = writeln!(
                rows,
                "<tr><td>{}/c{}</td><td>{}:{}.{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                e.owner,
                e.conn,
                e.from.node,
                esc(&e.from.behavior),
                esc(&e.from.port),
                esc(&to),
                esc(&e.kind.to_string()),
                reach,
                e.sent,
                active
            );
        }
        format!(
            "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{t}</title>\
             <style>body{{font-family:sans-serif;margin:1em}} table{{border-collapse:collapse;font-size:12px}} \
             td,th{{border:1px solid #ccc;padding:2px 6px;text-align:left}}</style>\n<script>{CHECK}</script></head>\n<body>\n<h1>{t}</h1>\n\
             <div id=\"graph\">{svg}</div>\n<h2>Connections</h2>\n<table id=\"connections\"><tr><th>connection</th><th>from</th>\
             <th>to</th><th>kind</th><th>reach</th><th>sent</th><th>window open</th></tr>\n{rows}</table>\n</body></html>\n",
            t = esc(title),
            svg = self.svg(),
            CHECK = PAGE_CHECK
        )
    }
}

/// The DOT/Mermaid id of a broadcast group's node: the name in hex, since group names may hold
/// characters neither format allows in an id.
fn group_id(group: &str) -> String {
    format!("group_{}", group.bytes().map(|b| format!("{b:02x}")).collect::<String>())
}
#[cfg(test)]
mod tests {
    use super::*;
    use ayllu::{BehaviorClass, ConnectOptions, Duration, Instant, NodeCore, PortSpec, Value};

    fn team() -> Vec<NodeReport> {
        let mut cores: Vec<NodeCore> = (1..=2).map(|i| NodeCore::new(NodeId(i))).collect();
        for c in &mut cores {
            let mut class = BehaviorClass::new("Obs\"erver");
            // `Local` is every behavior's own (BLE, rule S11).
            class.port(PortSpec::new("Rot<ate>", Value::Float(0.0))).unwrap();
            c.define(class).unwrap();
            c.create("Obs\"erver", "OBS1").unwrap();
            c.join("Peers");
        }
        let o = ConnectOptions::default();
        cores[0]
            .connect(
                &Endpoint::local("OBS1", "Local"),
                &Endpoint::group("Peers", "OBS1", "Rot<ate>"),
                ConnectionKind::Inhibit(Duration::from_secs(2)),
                o,
            )
            .unwrap();
        cores[1]
            .connect(
                &Endpoint::local("OBS1", "Local"),
                &Endpoint::node(NodeId(1), "OBS1", "Local"),
                ConnectionKind::Normal,
                o,
            )
            .unwrap();
        cores.iter().map(|c| c.report()).collect()
    }

    #[test]
    fn edges_cover_remote_and_broadcast_connections_and_mark_windows() {
        let mut g = TeamGraph::new(&team(), &BTreeMap::from([(NodeId(1), "robot-1".to_owned())]));
        assert_eq!(g.nodes.len(), 2);
        assert_eq!(g.edges.len(), 2);
        let b = &g.edges[0];
        assert_eq!(b.reach, Reach::Broadcast("Peers".into()));
        assert_eq!(b.to.as_ref().unwrap().node, NodeId(2));
        assert_eq!(g.edges[1].reach, Reach::Remote);
        assert_eq!(g.ports_with_windows().len(), 1);
        let mut why = NodeCore::new(NodeId(2));
        let mut class = BehaviorClass::new("X");
        class.port(PortSpec::new("Rot<ate>", Value::Float(0.0))).unwrap();
        why.define(class).unwrap();
        why.create("X", "OBS1").unwrap();
        let mut report = why.why_at(Instant::ZERO, "OBS1", "Rot<ate>").unwrap();
        report.windows.push(ayllu::WindowReport {
            kind: ayllu::WindowKind::Inhibit,
            holder: ayllu::Source { node: NodeId(1), conn: g.edges[0].conn },
            ends: Instant::from_secs(2),
            remaining: Duration::from_secs(2),
        });
        g.mark(&report);
        assert!(g.edges[0].active.is_some() && g.edges[1].active.is_none());
        let dot = g.dot();
        assert!(dot.contains("penwidth=3") && dot.contains("style=dashed") && dot.contains("Obs\\\"erver"), "{dot}");
        assert!(g.mermaid().contains("==>"));
        let svg = g.svg();
        assert!(svg.contains("Rot&lt;ate&gt;") && !svg.contains("Rot<ate>"));
        assert!(g.html("team").starts_with("<!DOCTYPE html>"));
        assert_eq!(g.json()["edges"][0]["reach"], json!("broadcast:Peers"));
    }
}
