//! The mapping file: which ROS 2 topics are which ports of the body (docs/ros2.md, "The
//! mapping file").
//!
//! ```toml
//! [ros2]
//! namespace = "/robot2"          # prefixed to relative topic names
//! domain = 0                     # the ROS domain id (default: $ROS_DOMAIN_ID, else 0)
//!
//! [[topic]]
//! name = "scan"                  # /robot2/scan
//! type = "sensor_msgs/msg/LaserScan"
//! direction = "in"               # topic -> ports
//! qos = "sensor_data"
//! lifespan = 0.25                # the ports go stale 0.25 s after the last sample
//! sonar = { beams = 16, rim = 0.2 }  # ranges resampled to Ayllu's sonar convention
//! fields = { ranges = "SONAR.Ranges" }
//!
//! [[topic]]
//! name = "cmd_vel"
//! type = "geometry_msgs/msg/Twist"
//! direction = "out"              # ports -> topic
//! rate = 10.0                    # Hz; without it, published whenever a port accepts a value
//! fields = { "linear.x" = "BASE.Translate", "angular.z" = "BASE.Rotate" }
//! ```
//!
//! Promises: [`Mapping::parse`] checks everything it can without a node — every key (an
//! unknown one is named, with the closest known key), every type and field path (against
//! [`crate::messages`]), every value's range — and each error names where it is
//! (`topic 2 (/robot2/scan), fields."ranges"`) and what to write instead. What depends on the
//! node (whether `BASE.Rotate` exists there and takes a float) is checked by
//! [`crate::body::Ros2Body::install`].

use std::collections::BTreeMap;
use std::fmt;
use std::time::Duration;

use crate::messages::{self, FieldKind, FieldRef, MessageType};
// Public here since mapping errors were its first use: the path stays as it was.
pub use crate::spelling::closest;

/// Longest array a sample may carry by default (`max_elements`): a 360° scan at a quarter
/// degree is 1,440 beams; 65,536 leaves room for any lidar's scan line while a forged length
/// cannot make the body allocate more than half a megabyte of floats.
pub const DEFAULT_MAX_ELEMENTS: usize = 65_536;

/// How often the node's loop looks for samples by default (`poll`, seconds): a sample waits at
/// most this long before its ports are written.
pub const DEFAULT_POLL: Duration = Duration::from_millis(2);

/// The node name the body shows to ROS 2 (`ros2 node list`) by default.
pub const DEFAULT_NODE_NAME: &str = "ayllu_body";

/// A parsed, checked mapping file.
#[derive(Clone, Debug)]
pub struct Mapping {
    /// The ROS domain id.
    pub domain: u16,
    /// The namespace relative topic names are resolved in (`/robot2`; `/` for none).
    pub namespace: String,
    /// The ROS 2 node's name.
    pub node_name: String,
    /// How often the node's loop takes samples.
    pub poll: Duration,
    /// The topics, in file order.
    pub topics: Vec<Topic>,
}

/// Which way a topic's values go.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    /// Topic -> ports: each sample writes the ports.
    In,
    /// Ports -> topic: the ports' values are published.
    Out,
}

/// ROS 2's reliability policy.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reliability {
    /// Lost samples are resent (the ROS 2 default).
    Reliable,
    /// Lost samples are lost (`sensor_data`).
    BestEffort,
}

/// ROS 2's durability policy.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Durability {
    /// Only samples published while a subscription exists reach it.
    Volatile,
    /// A late subscription gets the last `depth` samples (a latched topic).
    TransientLocal,
}

/// A topic's QoS: reliability, durability and history depth (keep last).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Qos {
    /// Reliability.
    pub reliability: Reliability,
    /// Durability.
    pub durability: Durability,
    /// History depth (keep last).
    pub depth: usize,
}

impl Qos {
    /// `rmw_qos_profile_default`: reliable, volatile, keep last 10.
    pub const DEFAULT: Qos = Qos { reliability: Reliability::Reliable, durability: Durability::Volatile, depth: 10 };
    /// `rmw_qos_profile_sensor_data`: best effort, volatile, keep last 5.
    pub const SENSOR_DATA: Qos =
        Qos { reliability: Reliability::BestEffort, durability: Durability::Volatile, depth: 5 };
    /// The profiles a mapping file may name.
    pub const PROFILES: [(&'static str, Qos); 2] = [("default", Qos::DEFAULT), ("sensor_data", Qos::SENSOR_DATA)];
}

impl fmt::Display for Qos {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let r = match self.reliability {
            Reliability::Reliable => "reliable",
            Reliability::BestEffort => "best_effort",
        };
        let d = match self.durability {
            Durability::Volatile => "volatile",
            Durability::TransientLocal => "transient_local",
        };
        write!(f, "{r}, {d}, keep last {}", self.depth)
    }
}

/// A laser scan resampled to Ayllu's sonar convention (`ayllu::stdlib`): `beams` ranges, beam
/// k pointing `k * 2π / beams` counter-clockwise from straight ahead, each the nearest reading
/// in its sector less `rim` (the robot's radius: Ayllu's ranges are from the robot's rim).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sonar {
    /// How many beams.
    pub beams: usize,
    /// Metres subtracted from every reading (never below zero).
    pub rim: f64,
}

/// One field of a topic and the port it is.
#[derive(Clone, Debug)]
pub struct FieldMap {
    /// The field's path in the message (`linear.x`).
    pub path: String,
    /// The field in the message type.
    pub field: FieldRef,
    /// The port's behavior.
    pub behavior: String,
    /// The port's name.
    pub port: String,
}

/// A constant field of published messages (`set`).
#[derive(Clone, Debug)]
pub struct Constant {
    /// The field's path.
    pub path: String,
    /// The field.
    pub field: FieldRef,
    /// Its value.
    pub value: ayllu_core::Value,
}

/// One topic of the mapping.
#[derive(Clone, Debug)]
pub struct Topic {
    /// The fully qualified ROS 2 name (`/robot2/scan`).
    pub name: String,
    /// The message type.
    pub ty: &'static MessageType,
    /// Which way values go.
    pub direction: Direction,
    /// Its QoS.
    pub qos: Qos,
    /// Out topics: published at this rate (Hz); `None`: whenever a mapped port accepts a value.
    pub rate: Option<f64>,
    /// In topics: how long the ports stay fresh after a sample (rule S4); `None`: forever.
    pub lifespan: Option<Duration>,
    /// The longest array a sample may carry; a longer one is dropped (`too_long`).
    pub max_elements: usize,
    /// In topics of type LaserScan: `ranges` resampled to Ayllu's sonar convention.
    pub sonar: Option<Sonar>,
    /// The fields and their ports.
    pub fields: Vec<FieldMap>,
    /// Out topics: constant fields.
    pub set: Vec<Constant>,
}

/// What is wrong with a mapping file: where, what, and what to write instead.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MappingError {
    /// Where in the file (`topic 2 (/robot2/scan), fields."ranges"`), or empty for the file as
    /// a whole.
    pub at: String,
    /// What is wrong and how to fix it.
    pub message: String,
}

impl fmt::Display for MappingError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.at.is_empty() {
            write!(f, "{}", self.message)
        } else {
            write!(f, "{}: {}", self.at, self.message)
        }
    }
}

impl std::error::Error for MappingError {}

fn fail<T>(at: impl Into<String>, message: impl Into<String>) -> Result<T, MappingError> {
    Err(MappingError { at: at.into(), message: message.into() })
}

/// `word` among `known`: nothing to say if it is one, else "did you mean" the closest.
fn unknown_key(at: &str, key: &str, known: &[&str]) -> MappingError {
    let hint = match closest(key, known.iter().copied()) {
        Some(k) => format!("did you mean `{k}`?"),
        None => format!("the keys here are {}", known.iter().map(|k| format!("`{k}`")).collect::<Vec<_>>().join(", ")),
    };
    MappingError { at: at.to_owned(), message: format!("unknown key `{key}`: {hint}") }
}

fn check_keys(at: &str, table: &toml::Table, known: &[&str]) -> Result<(), MappingError> {
    match table.keys().find(|k| !known.contains(&k.as_str())) {
        Some(k) => Err(unknown_key(at, k, known)),
        None => Ok(()),
    }
}

fn type_name(v: &toml::Value) -> &'static str {
    v.type_str()
}

fn seconds(at: &str, v: &toml::Value, what: &str) -> Result<Duration, MappingError> {
    let s = match v {
        toml::Value::Float(x) => *x,
        toml::Value::Integer(n) => *n as f64,
        other => return fail(at, format!("{what} is seconds (a number such as 0.25), not a {}", type_name(other))),
    };
    if !(s.is_finite() && s > 0.0) {
        return fail(at, format!("{what} must be a positive number of seconds, got {s}"));
    }
    if s < 1e-6 {
        return fail(at, format!("{what} of {s} s is under a microsecond: did you mean milliseconds ({} s)?", s * 1e3));
    }
    if s > 86_400.0 {
        return fail(at, format!("{what} of {s} s is more than a day; at most 86400"));
    }
    Ok(Duration::from_secs_f64(s))
}

/// Join a topic name to the namespace as ROS 2 resolves it: `/x` is absolute, `x` is
/// `namespace/x`; `~` (private names) has no meaning for a body and is refused.
fn resolve(at: &str, namespace: &str, name: &str) -> Result<String, MappingError> {
    let valid = |s: &str| {
        !s.is_empty()
            && s.split('/').all(|part| {
                !part.is_empty()
                    && part.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
                    && !part.starts_with(|c: char| c.is_ascii_digit())
            })
    };
    let relative = name.strip_prefix('/').unwrap_or(name);
    if !valid(relative) {
        return fail(
            at,
            format!(
                "`{name}` is not a ROS 2 topic name: use letters, digits and `_` between single slashes, no part \
                 starting with a digit (e.g. `scan`, `/robot2/cmd_vel`)"
            ),
        );
    }
    if name.starts_with('/') || namespace == "/" {
        Ok(format!("/{relative}"))
    } else {
        Ok(format!("{namespace}/{relative}"))
    }
}

fn namespace(v: &toml::Value) -> Result<String, MappingError> {
    let at = "ros2.namespace";
    let Some(s) = v.as_str() else {
        return fail(at, format!("a namespace is a string such as \"/robot2\", not a {}", type_name(v)));
    };
    let trimmed = s.trim_end_matches('/');
    if trimmed.is_empty() {
        return Ok("/".to_owned());
    }
    let absolute = if trimmed.starts_with('/') { trimmed.to_owned() } else { format!("/{trimmed}") };
    // A namespace is a topic name prefix: the same rules.
    resolve(at, "/", &absolute)
}

/// The port a field maps to: `BEHAVIOR.Port`.
fn port_of(at: &str, v: &toml::Value) -> Result<(String, String), MappingError> {
    let Some(s) = v.as_str() else {
        return fail(
            at,
            format!("a port is written \"BEHAVIOR.Port\" (e.g. \"SONAR.Ranges\"), not a {}", type_name(v)),
        );
    };
    match s.split_once('.') {
        Some((b, p)) if !b.is_empty() && !p.is_empty() && !p.contains('.') => Ok((b.to_owned(), p.to_owned())),
        _ => fail(at, format!("`{s}` is not a port: write \"BEHAVIOR.Port\", e.g. \"SONAR.Ranges\"")),
    }
}

/// `fields` and `set` as written: TOML reads `linear.x = ...` as a table `linear` holding `x`,
/// and `"linear.x" = ...` as one key; both mean the path `linear.x`.
fn flatten(prefix: &str, table: &toml::Table, out: &mut Vec<(String, toml::Value)>) {
    for (k, v) in table {
        let path = if prefix.is_empty() { k.clone() } else { format!("{prefix}.{k}") };
        match v {
            toml::Value::Table(t) => flatten(&path, t, out),
            other => out.push((path, other.clone())),
        }
    }
}

fn field(at: &str, ty: &'static MessageType, path: &str) -> Result<FieldRef, MappingError> {
    ty.field(path).map_err(|e| MappingError { at: at.to_owned(), message: e.to_string() })
}

fn qos(at: &str, v: &toml::Value) -> Result<Qos, MappingError> {
    let names = || Qos::PROFILES.iter().map(|(n, _)| format!("\"{n}\"")).collect::<Vec<_>>().join(", ");
    let profile = |name: &str| -> Result<Qos, MappingError> {
        match Qos::PROFILES.iter().find(|(n, _)| *n == name) {
            Some((_, q)) => Ok(*q),
            None => {
                let hint = closest(name, Qos::PROFILES.iter().map(|(n, _)| *n))
                    .map_or(String::new(), |n| format!("did you mean \"{n}\"? "));
                fail(at, format!("no QoS profile \"{name}\": {hint}the profiles are {}, or a table {{ reliability = \"reliable\" | \"best_effort\", durability = \"volatile\" | \"transient_local\", depth = N }}", names()))
            }
        }
    };
    match v {
        toml::Value::String(name) => profile(name),
        toml::Value::Table(t) => {
            check_keys(at, t, &["profile", "reliability", "durability", "depth"])?;
            let mut q = match t.get("profile") {
                Some(toml::Value::String(name)) => profile(name)?,
                Some(other) => return fail(at, format!("profile is a name ({}), not a {}", names(), type_name(other))),
                None => Qos::DEFAULT,
            };
            if let Some(r) = t.get("reliability") {
                q.reliability = match r.as_str() {
                    Some("reliable") => Reliability::Reliable,
                    Some("best_effort") => Reliability::BestEffort,
                    _ => return fail(format!("{at}.reliability"), "write \"reliable\" or \"best_effort\""),
                };
            }
            if let Some(d) = t.get("durability") {
                q.durability = match d.as_str() {
                    Some("volatile") => Durability::Volatile,
                    Some("transient_local") => Durability::TransientLocal,
                    _ => return fail(format!("{at}.durability"), "write \"volatile\" or \"transient_local\""),
                };
            }
            if let Some(d) = t.get("depth") {
                q.depth = match d.as_integer() {
                    Some(n) if (1..=10_000).contains(&n) => n as usize,
                    _ => return fail(format!("{at}.depth"), "the history depth is a whole number from 1 to 10000"),
                };
            }
            Ok(q)
        }
        other => fail(at, format!("qos is a profile name ({}) or a table, not a {}", names(), type_name(other))),
    }
}

const FILE_KEYS: [&str; 2] = ["ros2", "topic"];
const ROS2_KEYS: [&str; 4] = ["domain", "namespace", "node", "poll"];
const TOPIC_KEYS: [&str; 10] =
    ["name", "type", "direction", "qos", "rate", "lifespan", "max_elements", "sonar", "fields", "set"];

impl Mapping {
    /// Parse and check a mapping file's text; `ROS_DOMAIN_ID` is the domain when the file names
    /// none (as every ROS 2 node reads it).
    pub fn parse(text: &str) -> Result<Mapping, MappingError> {
        let env_domain = std::env::var("ROS_DOMAIN_ID").ok();
        Mapping::parse_with_domain(text, env_domain.as_deref())
    }

    /// [`Mapping::parse`] for node `node`: `{id}` anywhere in the text stands for its number
    /// (`namespace = "/robot{id}"`: one file for every robot of a fleet).
    pub fn parse_for(text: &str, node: Option<ayllu_core::NodeId>) -> Result<Mapping, MappingError> {
        match node {
            Some(id) => Mapping::parse(&text.replace("{id}", &id.0.to_string())),
            None => Mapping::parse(text),
        }
    }

    /// [`Mapping::parse`] with the environment's `ROS_DOMAIN_ID` given (for tests).
    pub fn parse_with_domain(text: &str, env_domain: Option<&str>) -> Result<Mapping, MappingError> {
        if let Some(line) = text.lines().position(|l| l.contains("{id}")) {
            return fail(
                format!("line {}", line + 1),
                "`{id}` stands for the node's id, and this mapping is read without one: install it on a node \
                 (ayllu node --ros2, ayInitRos2Body), or write the number",
            );
        }
        let file: toml::Table = text.parse().map_err(|e: toml::de::Error| MappingError {
            at: String::new(),
            message: format!("not valid TOML: {}", e.to_string().trim_end()),
        })?;
        check_keys("", &file, &FILE_KEYS)?;
        let ros2 = match file.get("ros2") {
            None => toml::Table::new(),
            Some(toml::Value::Table(t)) => t.clone(),
            Some(other) => return fail("ros2", format!("[ros2] is a table, not a {}", type_name(other))),
        };
        check_keys("[ros2]", &ros2, &ROS2_KEYS)?;
        let domain = match (ros2.get("domain"), env_domain) {
            // ROS 2 accepts 0-232 on Linux (the port arithmetic of the RTPS spec runs out above).
            (Some(v), _) => match v.as_integer() {
                Some(d) if (0..=232).contains(&d) => d as u16,
                _ => return fail("ros2.domain", "the ROS domain id is a whole number from 0 to 232"),
            },
            (None, Some(env)) if !env.trim().is_empty() => match env.trim().parse::<u16>() {
                Ok(d) if d <= 232 => d,
                _ => return fail("ROS_DOMAIN_ID", format!("`{env}` is not a domain id (0 to 232)")),
            },
            _ => 0,
        };
        let namespace = ros2.get("namespace").map(namespace).transpose()?.unwrap_or_else(|| "/".to_owned());
        let node_name = match ros2.get("node") {
            None => DEFAULT_NODE_NAME.to_owned(),
            Some(toml::Value::String(s))
                if !s.is_empty()
                    && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
                    && !s.starts_with(|c: char| c.is_ascii_digit()) =>
            {
                s.clone()
            }
            Some(_) => {
                return fail("ros2.node", "a ROS 2 node name: letters, digits and `_`, not starting with a digit")
            }
        };
        let poll = ros2.get("poll").map(|v| seconds("ros2.poll", v, "poll")).transpose()?.unwrap_or(DEFAULT_POLL);
        let topics = match file.get("topic") {
            None => return fail("", "no [[topic]]: a body maps at least one topic (see docs/ros2.md)"),
            Some(toml::Value::Array(a)) => a,
            Some(_) => return fail("topic", "topics are written [[topic]] (an array of tables)"),
        };
        let mut parsed = Vec::with_capacity(topics.len());
        for (i, t) in topics.iter().enumerate() {
            let toml::Value::Table(t) = t else {
                return fail(format!("topic {}", i + 1), "each topic is a [[topic]] table");
            };
            parsed.push(Mapping::topic(i + 1, t, &namespace)?);
        }
        // One port fed by two topics would change value at each one's rate, with no rule saying
        // which wins: that is what a connection kind is for, so it is refused here.
        let mut written: BTreeMap<(String, String), String> = BTreeMap::new();
        for t in parsed.iter().filter(|t| t.direction == Direction::In) {
            for f in &t.fields {
                if let Some(other) = written.insert((f.behavior.clone(), f.port.clone()), t.name.clone()) {
                    return fail(
                        format!("topic {}", t.name),
                        format!(
                            "{}.{} is already written by {other}: give each topic its own ports, and join them with \
                             connections (an override or a Max port says which wins)",
                            f.behavior, f.port
                        ),
                    );
                }
            }
        }
        let mut names = BTreeMap::new();
        for t in &parsed {
            if let Some(d) = names.insert(t.name.clone(), t.direction) {
                if d == t.direction {
                    return fail(
                        format!("topic {}", t.name),
                        "this topic is mapped twice the same way: merge the two [[topic]] tables",
                    );
                }
            }
        }
        Ok(Mapping { domain, namespace, node_name, poll, topics: parsed })
    }

    fn topic(n: usize, t: &toml::Table, namespace: &str) -> Result<Topic, MappingError> {
        let raw_name = t.get("name").and_then(toml::Value::as_str);
        let mut at = match raw_name {
            Some(name) => format!("topic {n} ({name})"),
            None => format!("topic {n}"),
        };
        check_keys(&at, t, &TOPIC_KEYS)?;
        let Some(raw_name) = raw_name else {
            return fail(at, "every topic has a `name` (e.g. name = \"scan\", or \"/robot2/scan\")");
        };
        let name = resolve(&format!("{at}.name"), namespace, raw_name)?;
        at = format!("topic {n} ({name})");
        let ty = match t.get("type").and_then(toml::Value::as_str) {
            None => return fail(&at, "every topic has a `type`, e.g. type = \"sensor_msgs/msg/LaserScan\""),
            Some(s) => match messages::message_type(s) {
                Some(ty) => ty,
                None => {
                    let known: Vec<&str> = messages::message_types().map(|m| m.name()).collect();
                    // `Twist` or `geometry_msgs/Twist` (ROS 1 style) for `geometry_msgs/msg/Twist`.
                    let short = s.rsplit('/').next().unwrap_or(s);
                    let by_short = known.iter().find(|k| k.rsplit('/').next() == Some(short));
                    let hint = match by_short.copied().or_else(|| closest(s, known.iter().copied())) {
                        Some(k) => format!("did you mean \"{k}\"?"),
                        None => format!("the types known are {}", known.join(", ")),
                    };
                    return fail(format!("{at}.type"), format!("`{s}` is not a message type the body knows: {hint}"));
                }
            },
        };
        let direction =
            match t.get("direction").and_then(toml::Value::as_str) {
                Some("in") => Direction::In,
                Some("out") => Direction::Out,
                Some(other) => {
                    return fail(
                        format!("{at}.direction"),
                        format!("`{other}` is no direction: \"in\" (topic -> ports) or \"out\" (ports -> topic)"),
                    )
                }
                None => return fail(
                    &at,
                    "every topic has a `direction`: \"in\" (the topic writes ports: sensors) or \"out\" (ports are \
                     published: motors)",
                ),
            };
        let qos = t.get("qos").map(|v| qos(&format!("{at}.qos"), v)).transpose()?.unwrap_or(match direction {
            // What ROS 2 drivers publish sensors with, and what a reader must accept to hear
            // both best-effort and reliable writers.
            Direction::In => Qos::SENSOR_DATA,
            Direction::Out => Qos::DEFAULT,
        });
        let rate = match t.get("rate") {
            None => None,
            Some(_) if direction == Direction::In => {
                return fail(
                    format!("{at}.rate"),
                    "rate is for \"out\" topics: an \"in\" topic is read as its samples come",
                )
            }
            Some(v) => match v.as_float().or_else(|| v.as_integer().map(|i| i as f64)) {
                Some(hz) if hz.is_finite() && hz > 0.0 && hz <= 1000.0 => Some(hz),
                _ => return fail(format!("{at}.rate"), "rate is in Hz, a number above 0 and at most 1000"),
            },
        };
        let lifespan =
            match t.get("lifespan") {
                None => None,
                Some(_) if direction == Direction::Out => return fail(
                    format!("{at}.lifespan"),
                    "lifespan is for \"in\" topics (how long a sample stays fresh); an \"out\" topic's ports are the \
                     controller's",
                ),
                Some(v) => Some(seconds(&format!("{at}.lifespan"), v, "lifespan")?),
            };
        let max_elements = match t.get("max_elements") {
            None => DEFAULT_MAX_ELEMENTS,
            Some(v) => match v.as_integer() {
                Some(m) if (1..=16_777_216).contains(&m) => m as usize,
                _ => return fail(format!("{at}.max_elements"), "a whole number from 1 to 16777216"),
            },
        };
        let sonar = match t.get("sonar") {
            None => None,
            Some(toml::Value::Table(s)) => {
                let sat = format!("{at}.sonar");
                check_keys(&sat, s, &["beams", "rim"])?;
                if ty.name() != "sensor_msgs/msg/LaserScan" || direction != Direction::In {
                    return fail(
                        sat,
                        "sonar resamples an \"in\" sensor_msgs/msg/LaserScan's ranges; this topic is none",
                    );
                }
                let beams = match s.get("beams").and_then(toml::Value::as_integer) {
                    Some(b) if (1..=4096).contains(&b) => b as usize,
                    _ => return fail(format!("{sat}.beams"), "how many beams, a whole number from 1 to 4096"),
                };
                let rim = match s.get("rim") {
                    None => 0.0,
                    Some(v) => match v.as_float().or_else(|| v.as_integer().map(|i| i as f64)) {
                        Some(r) if r.is_finite() && r >= 0.0 => r,
                        _ => return fail(format!("{sat}.rim"), "the robot's radius in metres, 0 or more"),
                    },
                };
                Some(Sonar { beams, rim })
            }
            Some(_) => return fail(format!("{at}.sonar"), "sonar is a table: sonar = { beams = 16, rim = 0.2 }"),
        };
        let fields = match t.get("fields") {
            Some(toml::Value::Table(f)) => {
                let mut flat = Vec::new();
                flatten("", f, &mut flat);
                let mut out = Vec::with_capacity(flat.len());
                for (path, v) in flat {
                    let fat = format!("{at}, fields.\"{path}\"");
                    let field = field(&fat, ty, &path)?;
                    let (behavior, port) = port_of(&fat, &v)?;
                    if sonar.is_some() && path == "ranges" && field.kind() != FieldKind::Floats {
                        return fail(fat, "sonar needs `ranges` mapped to a vector port");
                    }
                    out.push(FieldMap { path, field, behavior, port });
                }
                out
            }
            Some(_) => {
                return fail(
                    format!("{at}.fields"),
                    "fields is a table of field = \"BEHAVIOR.Port\", e.g. fields = { ranges = \"SONAR.Ranges\" }",
                )
            }
            None => Vec::new(),
        };
        if fields.is_empty() {
            let some: Vec<String> = ty.leaves().into_iter().take(6).collect();
            return fail(
                at,
                format!(
                    "no fields mapped: add fields = {{ \"FIELD\" = \"BEHAVIOR.Port\" }} with fields of {} such as {}",
                    ty.name(),
                    some.join(", ")
                ),
            );
        }
        let set = match t.get("set") {
            None => Vec::new(),
            Some(_) if direction == Direction::In => {
                return fail(
                    format!("{at}.set"),
                    "set gives constant fields of published messages: only for \"out\" topics",
                )
            }
            Some(toml::Value::Table(s)) => {
                let mut flat = Vec::new();
                flatten("", s, &mut flat);
                let mut out = Vec::with_capacity(flat.len());
                for (path, v) in flat {
                    let sat = format!("{at}, set.\"{path}\"");
                    let field = field(&sat, ty, &path)?;
                    let value = constant(&sat, &v)?;
                    let mut probe = ty.default_sample();
                    if let Err(e) = probe.set(&field, &value) {
                        return fail(sat, e.to_string());
                    }
                    out.push(Constant { path, field, value });
                }
                out
            }
            Some(_) => {
                return fail(
                    format!("{at}.set"),
                    "set is a table of field = value, e.g. set = { \"header.frame_id\" = \"base_link\" }",
                )
            }
        };
        for c in &set {
            if fields.iter().any(|f| f.path == c.path) {
                return fail(
                    format!("{at}, set.\"{}\"", c.path),
                    "this field is also mapped to a port: keep one of the two",
                );
            }
        }
        Ok(Topic { name, ty, direction, qos, rate, lifespan, max_elements, sonar, fields, set })
    }
}

/// A constant as a port value.
fn constant(at: &str, v: &toml::Value) -> Result<ayllu_core::Value, MappingError> {
    use ayllu_core::Value;
    Ok(match v {
        toml::Value::Boolean(b) => Value::Bool(*b),
        toml::Value::Integer(i) => Value::Int(*i),
        toml::Value::Float(x) => Value::Float(*x),
        toml::Value::String(s) => Value::from(s.as_str()),
        toml::Value::Array(a) => {
            let mut xs = Vec::with_capacity(a.len());
            for x in a {
                match x.as_float().or_else(|| x.as_integer().map(|i| i as f64)) {
                    Some(x) => xs.push(x),
                    None => return fail(at, "an array constant holds numbers only"),
                }
            }
            Value::vector(&xs)
        }
        other => {
            return fail(
                at,
                format!("a constant is a number, a bool, a string or an array of numbers, not a {}", type_name(other)),
            )
        }
    })
}
