//! The tool's own node on the team's network, and the waiting it does: for a node's HELLO,
//! for the answer to a request.
//!
//! The tool is an ordinary Ayllu node (real monotonic clock, the `--udp` URL's transport:
//! `udp://` on an ephemeral port unless told otherwise, or a registered scheme such as `zenoh://`), so the nodes it talks to need nothing special: they learn its
//! address from its first datagram and greet it at once. Every wait here ends by the
//! deadline (from `--timeout`) or Ctrl-C, whichever comes first, with a message that says
//! which step did not happen.

use std::time::{Duration as StdDuration, Instant as StdInstant};

use ayllu::transport;
use ayllu::{
    AskError, ConnectOptions, ConnectionId, ConnectionKind, ControlBody, Endpoint, MonotonicClock, Node, NodeId,
    PeerInfo, ReplyBody, RequestId,
};

use crate::fail::Fail;
use crate::signals;
use crate::Net;

/// How long the node runs between checks of what the tool waits for. Arrivals wake it
/// earlier; this only bounds how late a check can be.
pub const SLICE: StdDuration = StdDuration::from_millis(10);

/// The tool's node and the deadline of the command.
pub struct Client {
    pub node: Node,
    /// When waits give up; `None`: never (a command the user ends).
    deadline: Option<StdInstant>,
    /// The `--timeout` in force, for messages.
    timeout: f64,
    /// Whether Ctrl-C ends waits (not while cleaning up after it).
    pub honour_stop: bool,
    /// The tool's URL and team, for messages.
    url: String,
    team: u32,
    /// Whether the URL has a key= (for messages: never the key itself).
    keyed: bool,
    /// Whether the tool sends to nodes by address (`peer=`, `broadcast=`): a node that drops
    /// what it gets (another team or key) never learns the tool's address, so nothing comes
    /// back for the tool to count, and the hint has to name team/key itself.
    by_address: bool,
    /// Whether the URL asks for `discovery=` on a loopback bind (`udp://127.0.0.1:...`), where
    /// multicast HELLOs are not delivered.
    loopback_discovery: bool,
}

/// Whether `url` (`udp://HOST:PORT?...`) binds a loopback address (`127.x.x.x`, `::1`,
/// `localhost`).
fn binds_loopback(url: &str) -> bool {
    let Some(rest) = url.strip_prefix("udp://") else { return false };
    let addr = rest.split(['?', '/']).next().unwrap_or("");
    let host = addr.rsplit_once(':').map_or(addr, |(h, _)| h).trim_start_matches('[').trim_end_matches(']');
    host.eq_ignore_ascii_case("localhost") || host.parse::<std::net::IpAddr>().is_ok_and(|ip| ip.is_loopback())
}

/// `url` with the value of `key=` hidden, for messages (a key must not end up in logs).
fn redact_key(url: &str) -> String {
    let Some((head, query)) = url.split_once('?') else { return url.to_owned() };
    let parts: Vec<String> = query
        .split('&')
        .map(|p| if p.starts_with("key=") { "key=(hidden)".to_owned() } else { p.to_owned() })
        .collect();
    format!("{head}?{}", parts.join("&"))
}

/// The tool's node id unless `--id` is given: high (clear of robots' ids) and different for
/// each process, so that two tools running at once are two peers.
pub fn default_id() -> NodeId {
    NodeId(0x7fff_0000 + (std::process::id() & 0xffff))
}

/// Refuse a `--udp` URL no process outside this one could share: one without a scheme, or
/// `mem://` (in-process only). Every other scheme goes to `ayllu::transport::open`, which
/// knows `udp://` and the registered ones (`zenoh://` in `ayllu-zenoh`) and names the rest.
pub fn network_url(url: &str) -> Result<(), Fail> {
    if url.split_once("://").is_none_or(|(scheme, _)| scheme == "mem") {
        return Err(Fail::usage(format!("--udp must be a udp:// URL, got `{url}`")));
    }
    Ok(())
}

/// How long [`refuse_a_heard_nodes_id`] listens for a node with the tool's `--id`. A node
/// greets a newcomer at once (its first datagram teaches the node its address), so this only
/// bounds a slow or lossy link.
const ID_CHECK: f64 = 1.0;

/// The refusal of a tool whose id is `id`, the id of `whose`, a node it talks to: each side
/// would drop the other's datagrams as a duplicate of its own id (counted `duplicate_id`), so
/// the tool would wait for a node it can never hear, or leave it out in silence.
fn id_taken(id: NodeId, whose: &str) -> Fail {
    Fail::usage(format!(
        "--id {} is the id of {whose}: the tool is a node of the team and needs an id of its own (leave --id out and \
         it picks one)",
        id.0
    ))
}

/// For the commands that talk to every node they hear rather than to nodes named on the
/// command line (`foxglove`, `record`): with `--id` given, listen briefly under another id and
/// refuse an id that a node heard there already has ([`Client::find`]'s refusal for a named
/// node). Without `--id` the tool's id is its own ([`default_id`]) and nothing is checked.
pub fn refuse_a_heard_nodes_id(net: &Net) -> Result<(), Fail> {
    let Some(id) = net.id else { return Ok(()) };
    let other = if default_id() == id { NodeId(id.0 ^ 1) } else { default_id() };
    let look = Net { udp: net.udp.clone(), timeout: Some(ID_CHECK), json: false, id: Some(other) };
    let mut client = Client::open(&look, ID_CHECK)?;
    while !client.expired() && !signals::stopped() {
        if let Some(p) = client.node.peers().into_iter().find(|p| p.node == id) {
            return Err(id_taken(id, &format!("a node heard on the network ({} at {})", p.name, p.addr)));
        }
        client.pump(SLICE);
    }
    Ok(())
}

impl Client {
    /// Join the network `net.udp` names. Waits give up after `--timeout`, else `default_timeout`.
    pub fn open(net: &Net, default_timeout: f64) -> Result<Client, Fail> {
        Client::open_with(net, default_timeout, |t| t)
    }

    /// [`Client::open`] with the transport wrapped by `wrap` (`record` and `hz` put a
    /// `team_recording::Tap` around it to see the port messages that arrive). Any scheme
    /// `ayllu::transport::open` knows: `udp://`, and those another crate registered
    /// (`zenoh://` in the `ayllu-zenoh` tool, docs/zenoh.md), whose own error says where a
    /// missing scheme lives. `mem://` is in-process only: a tool on it would reach nobody, so
    /// it is refused like a URL without a scheme.
    pub fn open_with<T: ayllu::Transport + 'static>(
        net: &Net,
        default_timeout: f64,
        wrap: impl FnOnce(Box<dyn ayllu::Transport>) -> T,
    ) -> Result<Client, Fail> {
        network_url(&net.udp)?;
        let id = net.id.unwrap_or_else(default_id);
        let team = transport::url_setting(&net.udp, "team").and_then(|t| t.parse().ok()).unwrap_or(0);
        let transport = transport::open_named(&net.udp, id, "ayllu-cli")?;
        let timeout = net.timeout.unwrap_or(default_timeout);
        Ok(Client {
            node: Node::new(MonotonicClock::new(), wrap(transport)),
            deadline: Some(StdInstant::now() + StdDuration::from_secs_f64(timeout)),
            timeout,
            honour_stop: true,
            url: redact_key(&net.udp),
            team,
            keyed: transport::url_setting(&net.udp, "key").is_some_and(|k| !k.is_empty()),
            by_address: ["peer", "broadcast"].iter().any(|o| transport::url_setting(&net.udp, o).is_some()),
            loopback_discovery: transport::url_setting(&net.udp, "discovery").is_some() && binds_loopback(&net.udp),
        })
    }

    pub fn id(&self) -> NodeId {
        self.node.id()
    }

    pub fn timeout(&self) -> f64 {
        self.timeout
    }

    /// Wait without end (until Ctrl-C), or until `deadline`.
    pub fn set_deadline(&mut self, deadline: Option<StdInstant>) {
        self.deadline = deadline;
    }

    pub fn expired(&self) -> bool {
        self.deadline.is_some_and(|d| StdInstant::now() >= d)
    }

    /// Run the node for at most `slice` (less if the deadline is nearer).
    pub fn pump(&mut self, slice: StdDuration) {
        let slice = match self.deadline {
            Some(d) => slice.min(d.saturating_duration_since(StdInstant::now())),
            None => slice,
        };
        self.node.run_for(slice);
    }

    /// Run the node until the deadline (or Ctrl-C).
    pub fn listen(&mut self) {
        while !self.expired() && !signals::stopped() {
            self.pump(SLICE * 5);
        }
    }

    /// The peers heard so far, by id.
    pub fn peers(&self) -> Vec<PeerInfo> {
        let mut peers = self.node.peers();
        peers.sort_by_key(|p| p.node);
        peers
    }

    /// Wait for `node`'s HELLO (or any datagram from it), so that requests have an address.
    /// The tool's own id cannot be asked about: each side would drop the other's datagrams as
    /// a duplicate of its own id, and the wait would end in a timeout that blames the URL.
    pub fn find(&mut self, node: NodeId) -> Result<PeerInfo, Fail> {
        if node == self.id() {
            return Err(id_taken(node, "the node asked about"));
        }
        loop {
            if let Some(p) = self.node.peers().into_iter().find(|p| p.node == node) {
                return Ok(p);
            }
            if self.expired() || signals::stopped() {
                return Err(self.unheard(node));
            }
            self.pump(SLICE);
        }
    }

    fn unheard(&self, node: NodeId) -> Fail {
        let peers = self.peers();
        let heard = if peers.is_empty() {
            "heard no node at all".to_owned()
        } else {
            let list: Vec<String> = peers.iter().map(|p| format!("{} at {}", p.node, p.addr)).collect();
            format!("heard {}", list.join(", "))
        };
        Fail::error(format!(
            "unknown node {node}: no HELLO from it within {}s ({heard}); {}",
            self.timeout,
            self.hint()
        ))
    }

    /// What to check when nodes are not heard: a wrong team or key if the traffic shows one
    /// (the transport counts such datagrams before dropping them), else where to look.
    pub fn hint(&self) -> String {
        let counted =
            |cause: &str| self.node.transport_counters().iter().find(|(c, _)| c == cause).map_or(0, |(_, n)| *n);
        let mut found = Vec::new();
        if counted("wrong_team") > 0 {
            found.push(format!(
                "heard {} datagrams of another team: the nodes use a different team= than this tool's {}",
                counted("wrong_team"),
                self.team
            ));
        }
        if counted("unexpected_auth") > 0 {
            found.push(format!(
                "heard {} authenticated datagrams: the team has a key; give it with key= in --udp or AYLLU_URL",
                counted("unexpected_auth")
            ));
        }
        if counted("unauthenticated") > 0 {
            found.push(format!(
                "heard {} datagrams without a MAC: the nodes have no key, this tool has one",
                counted("unauthenticated")
            ));
        }
        if counted("bad_mac") > 0 {
            found.push(format!("heard {} datagrams with a bad MAC: the nodes use another key", counted("bad_mac")));
        }
        if counted("duplicate_id") > 0 {
            found.push(format!(
                "heard {} datagrams from another node with this tool's id {}: ids must be unique in a team, so each \
                 side drops the other's; give the tool another --id (or leave it out and it picks one)",
                counted("duplicate_id"),
                self.id().0
            ));
        }
        if !found.is_empty() {
            return found.join("; ");
        }
        let mut hint = format!(
            "check the node id and the URL (--udp or AYLLU_URL, now `{}`): discovery= only finds nodes that use \
             the same discovery address (and ttl=1 across machines), else give peer=ADDR:PORT or broadcast=ADDR:PORT",
            self.url
        );
        if self.loopback_discovery {
            // A socket bound to a loopback address gets no multicast: the nodes' HELLOs never
            // arrive (only nodes that heard the tool's own HELLO answer it).
            hint.push_str(
                "; this tool binds a loopback address, where discovery HELLOs (multicast) do not arrive: bind \
                 0.0.0.0 (udp://0.0.0.0:0?discovery=...) or give peer=ADDR:PORT",
            );
        }
        if self.by_address {
            // What the counters above show when the nodes' HELLOs reach the tool cannot show
            // here: a node of another team or key drops the tool's datagrams and never answers.
            hint.push_str(&format!(
                "; and team/key: a node whose team= or key= differs from this tool's (team {}, {}) drops its \
                 datagrams without answering",
                self.team,
                if self.keyed { "a key" } else { "no key" }
            ));
        }
        hint
    }

    /// Send a control request to `node` and wait for its answer. `what` names the request in
    /// messages ("WHY n1:BASE.Rotate").
    pub fn ask(&mut self, node: NodeId, body: ControlBody, what: &str) -> Result<ReplyBody, Fail> {
        let id = self.node.core_mut().request(node, body)?;
        self.answer(node, id, what)
    }

    /// Ask `node` to copy its port `behavior.port` to this tool's port `to_behavior.to_port`
    /// along a Normal connection (how `echo`, `hz` and `record` listen to a port), and wait
    /// for the connection's id on `node`.
    pub fn copy_port(
        &mut self,
        node: NodeId,
        (behavior, port): (&str, &str),
        (to_behavior, to_port): (&str, &str),
    ) -> Result<ConnectionId, Fail> {
        let what = format!("CONNECT {node}:{behavior}.{port} -> {}:{to_behavior}.{to_port}", self.id());
        let request = self.node.core_mut().request_connect(
            &Endpoint::node(node, behavior, port),
            &Endpoint::local(to_behavior, to_port),
            ConnectionKind::Normal,
            ConnectOptions::default(),
        )?;
        match self.answer(node, request, &what)? {
            ReplyBody::Connection(c) => Ok(c),
            other => Err(unexpected(&what, &other)),
        }
    }

    /// Wait for the answer to request `id` sent to `node` (`ayllu::Node::await_answer`, until
    /// the command's deadline or Ctrl-C), with messages that name the request and the node.
    pub fn answer(&mut self, node: NodeId, id: RequestId, what: &str) -> Result<ReplyBody, Fail> {
        let honour_stop = self.honour_stop;
        let answer = self.node.await_answer(node, id, self.deadline, &mut || honour_stop && signals::stopped());
        answer.map_err(|e| match e {
            AskError::Failed(text) => Fail::error(format!("{what}: {node} says: {text}")),
            AskError::Stopped => Fail::error(format!("{what}: interrupted before {node} answered")),
            AskError::TimedOut { heard } => Fail::error(format!(
                "{what}: no answer from {node} within {}s ({})",
                self.timeout,
                if heard { "it is alive (HELLO heard) but did not answer" } else { "it has gone silent" }
            )),
            AskError::NotSent(e) => Fail::error(format!("{what}: {e}")),
            AskError::VirtualTime => Fail::error(format!("{what}: {e}")),
        })
    }
}

/// A request answered with a body its command does not expect (a node of another version).
pub(crate) fn unexpected(what: &str, body: &ReplyBody) -> Fail {
    Fail::error(format!("{what}: unexpected answer {body:?}"))
}
