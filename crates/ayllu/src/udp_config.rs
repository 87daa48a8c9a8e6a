//! The `udp://` URL: where a node binds, who it talks to, and how.
//!
//! ```text
//! udp://BIND_ADDR:PORT?team=7&key=HEX64&peer=ADDR:PORT&broadcast=ADDR:PORT
//!                     &group=NAME@ADDR:PORT&discovery=ADDR:PORT&ttl=1
//!                     &hello_ms=1000&mtu=1472&name=robot-1&spin_us=50
//! ```
//!
//! Every program (the runtime's [`default_url`], the `ayllu` tool, the AylluLite clients)
//! takes its URL from the environment variable `AYLLU_URL`, else uses [`DEFAULT_URL`]:
//! discovery by multicast with a TTL of 0, so nodes on one machine find each other with no
//! configuration and nothing leaves the machine. For a team on one subnet, set
//! `AYLLU_URL='udp://0.0.0.0:0?discovery=239.255.65.89:7390&ttl=1'` on every robot.
//!
//! * `team` (default 0): the team id; datagrams of other teams are ignored.
//! * `key`: 64 hex digits, the 32-byte team key. Without it the team is open (N5).
//! * `peer` (repeatable): addresses to announce ourselves to (bootstrap for unicast teams).
//! * `broadcast`: where group messages go when the group has no address of its own (the
//!   paper's `ayMakeBroadcast("10.255.255.255")`).
//! * `group=NAME@ADDR` (repeatable): a group's own address, broadcast or multicast (joined).
//!   A group with neither is delivered by unicast to every peer that announced it (HELLO).
//! * `discovery=ADDR:PORT`: a multicast address to which HELLOs go and on which the node
//!   listens (shared with the other nodes of the machine): nodes that hear each other's HELLO
//!   greet each other by unicast, so no peer needs to be listed.
//! * `ttl` (default 1, 0 to 255): the multicast TTL; 0 keeps discovery on this machine.
//! * `hello_ms`: liveness period (N6); peers are forgotten after three silent periods.
//! * `state=PATH` (keyed teams, or with `operator=`): a file where the node keeps, across
//!   restarts, the newest datagram number it accepted from each sender (and the newest signed
//!   request id from each requester), so that a datagram or signed request captured before a
//!   restart is not accepted after it (N5, D-N5.3).
//! * `mtu`: the largest datagram sent (batching fills datagrams up to it, N3).
//! * `spin_us` (default 50, 0 to 1000): how long a wait may poll the socket, yielding the CPU
//!   between polls, before it sleeps, while datagrams stream in less than this far apart
//!   (D-N3.4). `spin_us=0` never polls: every wait sleeps in the kernel at once (a robot
//!   computer that counts its watts more than a receiver's wake-ups).
//! * `operator=HEX64`: the operator's public key (`ayllu keygen` prints it). The node then
//!   applies structure changes (CONNECT, DISCONNECT) only when signed with the operator's
//!   secret, each once (docs/security.md). With `state=PATH` it also remembers across
//!   restarts which signed requests it applied.
//! * `operator_secret=PATH`: a file holding the operator's secret (64 hex digits, as `ayllu
//!   keygen` writes it): this program signs the structure changes it asks for. A path, not
//!   the secret itself, so that it does not show in process lists.
//!
//! Parsing never panics; every mistake is an error naming the bad part.

use std::net::{SocketAddr, ToSocketAddrs};

use ayllu_core::Duration;

use crate::error::Error;

/// Largest datagram a node sends by default: Ethernet MTU minus IPv4 and UDP headers.
pub const DEFAULT_MTU: usize = 1472;
/// Largest datagram accepted (spec/protocol.md).
pub const MAX_DATAGRAM: usize = 8192;

/// The longest a wait may poll (`spin_us`): a millisecond of a CPU per stream that stops is
/// already much for a 2-core robot computer (the issue's "no unbounded spinning").
pub const MAX_SPIN_US: u64 = 1000;

/// The environment variable every Ayllu program reads its `udp://` URL from.
pub const URL_ENV: &str = "AYLLU_URL";
/// The URL used when `AYLLU_URL` is not set: any address, a port the system chooses, team 0,
/// no key, discovery on this machine only (multicast TTL 0).
pub const DEFAULT_URL: &str = "udp://0.0.0.0:0?discovery=239.255.65.89:7390&ttl=0";

/// The URL this program should use: `AYLLU_URL` if set (and not empty), else [`DEFAULT_URL`].
pub fn default_url() -> String {
    std::env::var(URL_ENV).ok().filter(|u| !u.trim().is_empty()).unwrap_or_else(|| DEFAULT_URL.to_owned())
}

/// A parsed `udp://` URL.
#[derive(Clone, Debug, PartialEq)]
pub struct UdpConfig {
    /// Where the node's own socket binds (port 0: the system chooses; see `Node::address`).
    pub bind: SocketAddr,
    /// The team id; datagrams of other teams are dropped (`wrong_team`).
    pub team: u32,
    /// The 32-byte team key: with it every datagram is authenticated (N5); without, the team is open.
    pub key: Option<[u8; 32]>,
    /// Addresses greeted with HELLO at start and every period (bootstrap for unicast teams).
    pub peers: Vec<SocketAddr>,
    /// Where group messages go when the group has no address of its own.
    pub broadcast: Option<SocketAddr>,
    /// Groups with an address of their own (broadcast or multicast), by name.
    pub groups: Vec<(String, SocketAddr)>,
    /// Multicast address for HELLOs (zero-config discovery), listened on.
    pub discovery: Option<SocketAddr>,
    /// Multicast TTL (0: this machine only).
    pub ttl: u32,
    /// Where the replay high-water marks survive restarts (keyed teams; D-N5.3).
    pub state: Option<std::path::PathBuf>,
    /// Liveness period (N6); a peer silent for three of its periods is forgotten.
    pub hello_interval: Duration,
    /// The largest datagram sent (N3 batches up to it).
    pub mtu: usize,
    /// The name announced in HELLO.
    pub name: String,
    /// The operator's public key: structure changes must be signed by its secret.
    pub operator: Option<ayllu_wire::OperatorPublic>,
    /// The operator's secret, to sign the structure changes this node requests.
    pub operator_secret: Option<ayllu_wire::OperatorSecret>,
    /// How long a wait may poll the socket while datagrams stream in, before it sleeps
    /// (D-N3.4; [`crate::datagram::SPIN`] by default); zero never polls.
    pub spin: std::time::Duration,
}

impl UdpConfig {
    /// A config bound to `bind` with defaults for everything else.
    pub fn new(bind: SocketAddr) -> UdpConfig {
        UdpConfig {
            bind,
            team: 0,
            key: None,
            peers: Vec::new(),
            broadcast: None,
            groups: Vec::new(),
            discovery: None,
            ttl: 1,
            state: None,
            hello_interval: Duration::from_millis(1000),
            mtu: DEFAULT_MTU,
            name: String::new(),
            operator: None,
            operator_secret: None,
            spin: crate::datagram::SPIN,
        }
    }

    /// Parse a `udp://` URL (module docs); the error names the bad part. Never panics.
    pub fn parse(url: &str) -> Result<UdpConfig, Error> {
        let bad = |reason: String| Error::BadUrl { url: url.to_owned(), reason };
        let rest = url.strip_prefix("udp://").ok_or_else(|| bad("expected udp://HOST:PORT".into()))?;
        let (addr, query) = rest.split_once('?').unwrap_or((rest, ""));
        let mut config = UdpConfig::new(resolve(addr).map_err(bad)?);
        for pair in query.split('&').filter(|p| !p.is_empty()) {
            let (k, v) = pair.split_once('=').ok_or_else(|| bad(format!("`{pair}` is not key=value")))?;
            match k {
                "team" => config.team = decimal(v).ok_or_else(|| bad(format!("team `{v}` is not a u32")))?,
                "key" => config.key = Some(parse_key(v).map_err(bad)?),
                "peer" => config.peers.push(resolve(v).map_err(bad)?),
                "broadcast" => config.broadcast = Some(resolve(v).map_err(bad)?),
                "group" => {
                    let (name, a) =
                        v.split_once('@').ok_or_else(|| bad(format!("group `{v}` should be NAME@ADDR:PORT")))?;
                    if name.is_empty() || name.len() > 255 {
                        return Err(bad(format!("group name `{name}` must be 1 to 255 bytes")));
                    }
                    config.groups.push((name.to_owned(), resolve(a).map_err(bad)?));
                }
                "discovery" => {
                    let a = resolve(v).map_err(bad)?;
                    if !a.ip().is_multicast() {
                        return Err(bad(format!("discovery `{v}` must be a multicast address (224.0.0.0/4)")));
                    }
                    config.discovery = Some(a);
                }
                "ttl" => {
                    config.ttl = decimal(v)
                        .filter(|t| *t <= 255)
                        .ok_or_else(|| bad(format!("ttl `{v}` must be a number from 0 to 255")))?;
                }
                "state" => {
                    if v.is_empty() {
                        return Err(bad("state needs a file path".into()));
                    }
                    config.state = Some(v.into());
                }
                "hello_ms" => {
                    let ms: u64 = decimal(v).ok_or_else(|| bad(format!("hello_ms `{v}` is not a number")))?;
                    if ms == 0 || ms > u64::from(u32::MAX) {
                        return Err(bad("hello_ms must be between 1 and 4294967295".into()));
                    }
                    config.hello_interval = Duration::from_millis(ms);
                }
                "mtu" => {
                    let mtu: usize = decimal(v).ok_or_else(|| bad(format!("mtu `{v}` is not a number")))?;
                    if !(64..=MAX_DATAGRAM).contains(&mtu) {
                        return Err(bad(format!("mtu must be between 64 and {MAX_DATAGRAM}")));
                    }
                    config.mtu = mtu;
                }
                "operator" => {
                    config.operator = Some(ayllu_wire::OperatorPublic::from_hex(v).ok_or_else(|| {
                        bad(format!(
                            "operator `{v}` is not an operator public key (64 hex digits, as `ayllu keygen` prints)"
                        ))
                    })?);
                }
                "operator_secret" => config.operator_secret = Some(read_operator_secret(v).map_err(bad)?),
                "spin_us" => {
                    let us: u64 = decimal(v)
                        .filter(|us| *us <= MAX_SPIN_US)
                        .ok_or_else(|| bad(format!("spin_us `{v}` must be a number from 0 to {MAX_SPIN_US}")))?;
                    config.spin = std::time::Duration::from_micros(us);
                }
                "name" => {
                    if v.len() > 255 {
                        return Err(bad("name must be at most 255 bytes".into()));
                    }
                    config.name = v.to_owned();
                }
                other => return Err(bad(format!("unknown option `{other}`"))),
            }
        }
        Ok(config)
    }
}

/// A number in a URL: ASCII decimal digits only, then `T`'s own range. `str::parse` would also
/// take a leading `+`, which AylluLite's parsers refuse; one grammar for every parser
/// (`spec/vectors/urls.json`).
fn decimal<T: std::str::FromStr>(v: &str) -> Option<T> {
    if v.is_empty() || !v.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    v.parse().ok()
}

fn resolve(addr: &str) -> Result<SocketAddr, String> {
    if let Ok(a) = addr.parse::<SocketAddr>() {
        return Some(a).filter(SocketAddr::is_ipv4).ok_or_else(|| format!("`{addr}` has no IPv4 address"));
    }
    // Only a name goes to the system resolver (and so maybe to DNS): text with no letter that
    // is not an address literal (`1..2:80`, `300.1.1.1:5`) is refused here, without traffic.
    let host = addr.rsplit_once(':').map_or(addr, |(h, _)| h);
    if !host.chars().any(|c| c.is_ascii_alphabetic()) {
        return Err(format!("`{addr}` is not HOST:PORT (an IPv4 address or a host name, and a port)"));
    }
    addr.to_socket_addrs()
        .map_err(|e| format!("`{addr}` is not HOST:PORT ({e})"))?
        .find(SocketAddr::is_ipv4)
        .ok_or_else(|| format!("`{addr}` has no IPv4 address"))
}

/// The operator secret in file `path` (64 hex digits, surrounding white space ignored).
pub fn read_operator_secret(path: &str) -> Result<ayllu_wire::OperatorSecret, String> {
    if path.is_empty() {
        return Err("operator_secret needs the path of a file that holds the secret".into());
    }
    let text = std::fs::read_to_string(path).map_err(|e| format!("cannot read the operator secret {path}: {e}"))?;
    let seed = parse_key(text.trim()).map_err(|e| format!("operator secret {path}: {e}"))?;
    Ok(ayllu_wire::OperatorSecret::from_seed(&seed))
}

/// 64 hex digits to a 32-byte key.
pub fn parse_key(hex: &str) -> Result<[u8; 32], String> {
    if hex.len() != 64 {
        return Err(format!("key must be 64 hex digits, got {}", hex.len()));
    }
    // Checked first: slicing non-ASCII text by bytes would panic, and from_str_radix would
    // take "+f" as a number.
    if !hex.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err("key must be hex digits (0-9, a-f)".to_owned());
    }
    let mut key = [0u8; 32];
    for (i, byte) in key.iter_mut().enumerate() {
        *byte = u8::from_str_radix(&hex[2 * i..2 * i + 2], 16).map_err(|_| "key must be hex digits".to_owned())?;
    }
    Ok(key)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_full_url_parses() {
        let key = "00112233445566778899aabbccddeeff00112233445566778899aabbccddeeff";
        let c = UdpConfig::parse(&format!(
            "udp://127.0.0.1:7400?team=7&key={key}&peer=127.0.0.1:7401&peer=127.0.0.1:7402&broadcast=127.255.255.255:7400&group=Peers@239.1.2.3:7500&hello_ms=250&mtu=1200&name=r1"
        ))
        .unwrap();
        assert_eq!(c.bind, "127.0.0.1:7400".parse().unwrap());
        assert_eq!(c.team, 7);
        assert_eq!(c.key.unwrap()[1], 0x11);
        assert_eq!(c.peers.len(), 2);
        assert_eq!(c.groups, vec![("Peers".to_owned(), "239.1.2.3:7500".parse().unwrap())]);
        assert_eq!(c.hello_interval, Duration::from_millis(250));
        assert_eq!((c.mtu, c.name.as_str()), (1200, "r1"));
    }

    #[test]
    fn the_default_url_discovers_on_this_machine_only() {
        let c = UdpConfig::parse(DEFAULT_URL).unwrap();
        assert_eq!(c.bind, "0.0.0.0:0".parse().unwrap(), "any address, a port the system chooses");
        assert_eq!(c.discovery, Some("239.255.65.89:7390".parse().unwrap()));
        assert_eq!((c.ttl, c.team, c.key), (0, 0, None), "TTL 0: nothing leaves the machine; team 0, open");
        let c = UdpConfig::parse("udp://0.0.0.0:0?discovery=239.255.65.89:7390&ttl=1").unwrap();
        assert_eq!(c.ttl, 1);
        assert_eq!(UdpConfig::parse("udp://0.0.0.0:0").unwrap().ttl, 1, "ttl defaults to 1 when not given");
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(2048))]

        /// The parser never panics (it promises so): every option with values of every shape,
        /// non-ASCII included, and keys of any text. Values hold no letters, and `resolve` asks
        /// the resolver only for names, so nothing is looked up (DNS): the test stays off the
        /// network.
        #[test]
        fn any_text_is_parsed_or_refused_never_a_panic(
            pairs in proptest::collection::vec((
                proptest::sample::select(vec![
                    "team", "key", "peer", "broadcast", "group", "discovery", "ttl", "hello_ms", "mtu", "name",
                    "spin_us", "x",
                ]),
                "[0-9.:@é+\\- ]{0,24}",
            ), 0..6),
            key in "[0-9a-fA-F+é ]{0,70}",
            junk in "[=&?0-9.:é]{0,30}",
        ) {
            let query: Vec<String> = pairs.iter().map(|(k, v)| format!("{k}={v}")).collect();
            let _ = UdpConfig::parse(&format!("udp://127.0.0.1:7400?{}", query.join("&")));
            let _ = UdpConfig::parse(&format!("udp://127.0.0.1:7400?key={key}"));
            let _ = UdpConfig::parse(&format!("udp://{junk}"));
        }
    }

    #[test]
    fn spin_us_sets_how_long_a_wait_may_poll() {
        let at = |q: &str| UdpConfig::parse(&format!("udp://127.0.0.1:1{q}")).unwrap().spin;
        assert_eq!(at(""), crate::datagram::SPIN);
        assert_eq!(at("?spin_us=0"), std::time::Duration::ZERO);
        assert_eq!(at("?spin_us=1000"), std::time::Duration::from_micros(1000));
    }

    #[test]
    fn mistakes_are_named() {
        for (url, needle) in [
            ("udp://nowhere", "HOST:PORT"),
            ("udp://127.0.0.1:1?team=x", "team"),
            ("udp://127.0.0.1:1?key=abc", "64 hex"),
            ("udp://127.0.0.1:1?key=zz112233445566778899aabbccddeeff00112233445566778899aabbccddeeff", "hex"),
            ("udp://127.0.0.1:1?group=Peers", "NAME@ADDR"),
            ("udp://127.0.0.1:1?hello_ms=0", "hello_ms"),
            ("udp://127.0.0.1:1?mtu=10", "mtu"),
            ("udp://127.0.0.1:1?colour=blue", "unknown option"),
            ("udp://127.0.0.1:1?key=+0112233445566778899aabbccddeeff00112233445566778899aabbccddeeff", "hex"),
            ("udp://127.0.0.1:1?key=ééééééééééééééééééééééééééééééééé", "64 hex"),
            ("udp://127.0.0.1:1?key=éééééééééééééééééééééééééééééééé", "hex"),
            ("udp://127.0.0.1:1?discovery=127.0.0.1:7400", "multicast"),
            ("udp://127.0.0.1:1?ttl=256", "ttl"),
            ("udp://127.0.0.1:1?ttl=-1", "ttl"),
            ("udp://127.0.0.1:1?spin_us=1001", "spin_us"),
            ("udp://127.0.0.1:1?spin_us=-1", "spin_us"),
            ("tcp://127.0.0.1:1", "udp://"),
        ] {
            let e = UdpConfig::parse(url).unwrap_err().to_string();
            assert!(e.contains(needle), "{url}: {e}");
        }
    }
}
