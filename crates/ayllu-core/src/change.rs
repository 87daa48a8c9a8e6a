//! Structure changes as values: what a running process asks of its node ([`crate::Ctx::change`])
//! and what a transaction carries to each node of a team (docs/semantics.md, "Reconfiguration").
//!
//! What it promises:
//! * One vocabulary for every way structure changes: the same [`Change`] is applied by
//!   [`NodeCore::apply_change`] whether a process, a transaction or a replay asks for it, so
//!   the three cannot disagree on what a change means.
//! * [`Change::check`] refuses what is wrong whatever the node holds (empty names, a zero
//!   period, a group as a source) at once, at the call; what depends on the structure (an
//!   unknown port, a taken name) is found when the change is applied.
//! * [`NodeCore::validate_changes`] says whether a whole list would apply against the
//!   structure as it stands, without changing anything (a transaction's PREPARE).

use crate::address::{ConnectionId, Endpoint};
use crate::ble::BleConfig;
use crate::connection::{ConnectOptions, ConnectionKind};
use crate::error::Error;
use crate::node::NodeCore;

/// One structure change on one node (rule S9's operations, as a value).
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Change {
    /// Instantiate class `class` as behavior `name`.
    Create {
        /// The class (defined on the node).
        class: String,
        /// The new behavior's name.
        name: String,
    },
    /// Remove behavior `name` and every connection into or out of it.
    Remove {
        /// The behavior.
        name: String,
    },
    /// Connect a port of this node to `destination`.
    Connect {
        /// The source: a port on this node.
        source: Endpoint,
        /// The destination: a port here, on another node, or on every node of a group.
        destination: Endpoint,
        /// The connection's kind (and period).
        kind: ConnectionKind,
        /// Its priority (for Priority ports).
        priority: i32,
    },
    /// Remove connection `conn` of this node.
    Disconnect {
        /// The connection.
        conn: ConnectionId,
    },
    /// Remove every connection of this node from `source` to `destination` (how a plan names
    /// connections, since it cannot know their ids). Refused if there is none.
    DisconnectBetween {
        /// The source port, as the connection was made.
        source: Endpoint,
        /// The destination, as the connection was made.
        destination: Endpoint,
    },
    /// Join a broadcast group.
    Join {
        /// The group.
        group: String,
    },
    /// Leave a broadcast group.
    Leave {
        /// The group.
        group: String,
    },
    /// Make a behavior a member of a BLE peer group.
    BleJoin {
        /// The behavior.
        behavior: String,
        /// Its configuration.
        config: BleConfig,
    },
}

/// What an applied change produced.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Applied {
    /// Done; nothing to report.
    Done,
    /// The connection made (by [`Change::Connect`]) or removed (by [`Change::Disconnect`]).
    Connection(ConnectionId),
    /// How many connections [`Change::DisconnectBetween`] removed.
    Disconnected(usize),
}

/// A change and what became of it: what a process reads on its next activation
/// ([`crate::Ctx::changes`]).
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct ChangeOutcome {
    /// The change as requested.
    pub change: Change,
    /// What it produced, or why the node refused it.
    #[cfg_attr(feature = "serde", serde(with = "crate::node::snapshot::outcome"))]
    pub result: Result<Applied, Error>,
}

impl Change {
    /// Refuse what is wrong whatever the node holds: empty names, a zero period (D6.8), a
    /// group as a source.
    pub fn check(&self) -> Result<(), Error> {
        let named = |what: &'static str, s: &str| if s.is_empty() { Err(Error::EmptyName { what }) } else { Ok(()) };
        let endpoint = |e: &Endpoint| {
            named("behavior", e.behavior())?;
            named("port", e.port())
        };
        match self {
            Change::Create { class, name } => {
                named("behavior class", class)?;
                named("behavior", name)
            }
            Change::Remove { name } => named("behavior", name),
            Change::Connect { source, destination, kind, .. } => {
                if kind.period().is_some_and(|p| p.is_zero()) {
                    return Err(Error::ZeroPeriod { kind: *kind });
                }
                if matches!(source, Endpoint::Group { .. }) {
                    return Err(Error::GroupSource);
                }
                endpoint(source)?;
                endpoint(destination)
            }
            Change::Disconnect { .. } => Ok(()),
            Change::DisconnectBetween { source, destination } => {
                endpoint(source)?;
                endpoint(destination)
            }
            Change::Join { group } | Change::Leave { group } => named("group", group),
            Change::BleJoin { behavior, config } => {
                named("behavior", behavior)?;
                named("group", &config.group)
            }
        }
    }

    /// A one-line description (`connect A.Out -> B.In (Normal)`), for reports and errors.
    pub fn describe(&self) -> String {
        match self {
            Change::Create { class, name } => format!("create {name} ({class})"),
            Change::Remove { name } => format!("remove {name}"),
            Change::Connect { source, destination, kind, priority } => {
                format!("connect {source} -> {destination} ({}{})", kind.name(), priority_text(*priority))
            }
            Change::Disconnect { conn } => format!("disconnect #{}", conn.0),
            Change::DisconnectBetween { source, destination } => format!("disconnect {source} -> {destination}"),
            Change::Join { group } => format!("join {group}"),
            Change::Leave { group } => format!("leave {group}"),
            Change::BleJoin { behavior, config } => format!("ble_join {behavior} {}", config.group),
        }
    }
}

fn no_connection(source: &Endpoint, destination: &Endpoint) -> Error {
    Error::NoConnectionBetween { source: source.to_string(), destination: destination.to_string() }
}

fn priority_text(p: i32) -> String {
    if p == 0 {
        String::new()
    } else {
        format!(", priority {p}")
    }
}

impl NodeCore {
    /// Apply one structure change now, as the matching call would (`create`, `remove`,
    /// `connect`, ...), journaled as that call. Processes do not call this: their changes are
    /// applied when they return (docs/semantics.md, R1).
    pub fn apply_change(&mut self, change: &Change) -> Result<Applied, Error> {
        change.check()?;
        match change {
            Change::Create { class, name } => self.create(class, name).map(|_| Applied::Done),
            Change::Remove { name } => self.remove(name).map(|()| Applied::Done),
            Change::Connect { source, destination, kind, priority } => {
                // A port of this node named with its id (as a plan sends it) is made a local
                // connection, the same as one made in code.
                let destination = match destination {
                    Endpoint::Node { node, behavior, port } if *node == self.id() => {
                        Endpoint::Local { behavior: behavior.clone(), port: port.clone() }
                    }
                    other => other.clone(),
                };
                self.connect(source, &destination, *kind, ConnectOptions { priority: *priority })
                    .map(Applied::Connection)
            }
            Change::Disconnect { conn } => self.disconnect(*conn).map(|()| Applied::Connection(*conn)),
            Change::DisconnectBetween { source, destination } => {
                let ids = self.connections_between(source, destination);
                if ids.is_empty() {
                    return Err(no_connection(source, destination));
                }
                for &id in &ids {
                    self.disconnect(id)?;
                }
                Ok(Applied::Disconnected(ids.len()))
            }
            Change::Join { group } => {
                self.join(group);
                Ok(Applied::Done)
            }
            Change::Leave { group } => {
                self.leave(group);
                Ok(Applied::Done)
            }
            Change::BleJoin { behavior, config } => self.ble_join(behavior, config).map(|_| Applied::Done),
        }
    }

    /// The ids of this node's connections from `source` to `destination`, as they were made
    /// (a source named with this node's id matches the same port named locally).
    pub fn connections_between(&self, source: &Endpoint, destination: &Endpoint) -> Vec<ConnectionId> {
        let me = self.id();
        let local = |e: &Endpoint| match e {
            Endpoint::Node { node, behavior, port } if *node == me => Endpoint::local(behavior, port),
            other => other.clone(),
        };
        let (source, destination) = (local(source), local(destination));
        self.connection_infos()
            .into_iter()
            .filter(|c| local(&c.source) == source && local(&c.destination) == destination)
            .map(|c| c.id)
            .collect()
    }

    /// Whether every change of `changes` would apply, in order, against this node's structure
    /// as it stands (a transaction's PREPARE): the first refusal, with its position, or `Ok`.
    /// Nothing is changed: the list is tried on a model of the node's structure (its behaviors
    /// and their classes, which are in a BLE group, its connections) plus what the list itself
    /// creates, removes, connects and disconnects, with the same checks as the changes' own
    /// functions (R8: a part that prepared switches whole; an outside test found a BLE join of
    /// a behavior already in a group, and one at a rate of NaN, prepared and then refused at
    /// the switch).
    pub fn validate_changes(&self, changes: &[Change]) -> Result<(), (usize, Error)> {
        let me = self.id();
        let local = |e: &Endpoint| match e {
            Endpoint::Node { node, behavior, port } if *node == me => Endpoint::local(behavior, port),
            other => other.clone(),
        };
        let mut created: Vec<(&str, &str)> = Vec::new();
        let mut removed: Vec<&str> = Vec::new();
        // Behaviors this list put in a BLE group (each name until it is removed or re-created).
        let mut ble_joined: Vec<&str> = Vec::new();
        // The node's connections this list removes, and those it makes: their ids (numbered
        // on from the node's next, as `connect` will) and local endpoints.
        let mut gone: Vec<ConnectionId> = Vec::new();
        let mut made: Vec<(ConnectionId, Endpoint, Endpoint)> = Vec::new();
        let mut next_id = self.next_connection_id();
        let existing = self.connection_infos();
        let class_of = |name: &str, created: &[(&str, &str)], removed: &[&str]| -> Option<String> {
            if let Some((_, class)) = created.iter().rev().find(|(n, _)| *n == name) {
                return Some((*class).to_owned());
            }
            if removed.contains(&name) {
                return None;
            }
            self.behavior_ref(name).ok().and_then(|_| self.class_name_of(name))
        };
        let touches = |e: &Endpoint, name: &str| matches!(e, Endpoint::Local { behavior, .. } if &**behavior == name);
        for (i, change) in changes.iter().enumerate() {
            change.check().map_err(|e| (i, e))?;
            // The type of a port of this node (`None` for another node's or a group's).
            let port_of = |e: &Endpoint, created: &[(&str, &str)], removed: &[&str]| -> Result<Option<_>, Error> {
                let remote = match e {
                    Endpoint::Node { node, .. } => *node != me,
                    Endpoint::Group { .. } => true,
                    Endpoint::Local { .. } => false,
                };
                if remote {
                    return Ok(None);
                }
                let class = class_of(e.behavior(), created, removed)
                    .ok_or_else(|| Error::UnknownBehavior { behavior: e.behavior().to_owned() })?;
                match self.class_port_type(&class, e.port()) {
                    Some(ty) => Ok(Some(ty)),
                    None if self.has_class(&class) => {
                        Err(Error::UnknownPort { behavior: e.behavior().to_owned(), port: e.port().to_owned() })
                    }
                    None => Err(Error::UnknownClass { class }),
                }
            };
            match change {
                Change::Create { class, name } => {
                    if !self.has_class(class) {
                        return Err((i, Error::UnknownClass { class: class.clone() }));
                    }
                    if class_of(name, &created, &removed).is_some() {
                        return Err((i, Error::DuplicateName { what: "behavior", name: name.clone() }));
                    }
                    created.push((name, class));
                }
                Change::Remove { name } => {
                    if class_of(name, &created, &removed).is_none() {
                        return Err((i, Error::UnknownBehavior { behavior: name.clone() }));
                    }
                    created.retain(|(n, _)| n != name);
                    removed.push(name);
                    ble_joined.retain(|n| n != name);
                    // Its connections go with it (`remove`), from it and to it.
                    for c in &existing {
                        if (touches(&local(&c.source), name) || touches(&local(&c.destination), name))
                            && !gone.contains(&c.id)
                        {
                            gone.push(c.id);
                        }
                    }
                    made.retain(|(_, s, d)| !touches(s, name) && !touches(d, name));
                }
                Change::Connect { source, destination, kind, .. } => {
                    if matches!(source, Endpoint::Node { node, .. } if *node != me) {
                        return Err((
                            i,
                            Error::NotLocal { what: format!("the source {source} of a change on node {me}") },
                        ));
                    }
                    let from = port_of(source, &created, &removed).map_err(|e| (i, e))?;
                    let to = port_of(destination, &created, &removed).map_err(|e| (i, e))?;
                    // As `connect` refuses it (D6.7).
                    if let (Some(found), Some(expected)) = (from, to) {
                        if kind.writes() && found != expected {
                            let what = format!("port {}.{}", destination.behavior(), destination.port());
                            return Err((i, Error::TypeMismatch { what, expected, found }));
                        }
                    }
                    made.push((ConnectionId(next_id), local(source), local(destination)));
                    next_id += 1;
                }
                Change::Disconnect { conn } => {
                    if let Some(k) = made.iter().position(|(id, _, _)| id == conn) {
                        made.remove(k);
                    } else if self.connection(*conn).is_none() || gone.contains(conn) {
                        return Err((i, Error::UnknownConnection { id: conn.0 }));
                    } else {
                        gone.push(*conn);
                    }
                }
                Change::DisconnectBetween { source, destination } => {
                    let (s, d) = (local(source), local(destination));
                    let mut ids: Vec<ConnectionId> = self.connections_between(source, destination);
                    ids.retain(|id| !gone.contains(id));
                    let before = made.len();
                    made.retain(|(_, ms, md)| !(*ms == s && *md == d));
                    if ids.is_empty() && made.len() == before {
                        return Err((i, no_connection(source, destination)));
                    }
                    gone.extend(ids);
                }
                Change::Join { .. } | Change::Leave { .. } => {}
                Change::BleJoin { behavior, config } => {
                    crate::ble::check_ble_config(config).map_err(|e| (i, e))?;
                    let class = class_of(behavior, &created, &removed)
                        .ok_or_else(|| (i, Error::UnknownBehavior { behavior: behavior.clone() }))?;
                    if self.class_port(&class, &config.output) != Some(true) {
                        return Err((
                            i,
                            Error::UnknownPort { behavior: behavior.clone(), port: config.output.clone() },
                        ));
                    }
                    let new_here = created.iter().any(|(n, _)| n == behavior);
                    if ble_joined.contains(&behavior.as_str()) || (!new_here && self.in_ble_group(behavior)) {
                        let reason = format!("`{behavior}` already belongs to a BLE group");
                        return Err((i, Error::Ble { reason }));
                    }
                    ble_joined.push(behavior);
                    // `ble_join` connects Local to the group's Best and Inhibit to the group's
                    // output, in that order.
                    for (port, to) in
                        [(crate::behavior::LOCAL, crate::behavior::BEST), (crate::behavior::INHIBIT, &*config.output)]
                    {
                        let destination = Endpoint::group(&config.group, behavior, to);
                        made.push((ConnectionId(next_id), Endpoint::local(behavior, port), destination));
                        next_id += 1;
                    }
                }
            }
        }
        Ok(())
    }
}
