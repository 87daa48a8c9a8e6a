//! The decoder: bytes from the network into a [`Datagram`], or the one [`DropReason`] it is
//! refused for.
//!
//! Promises, for any input whatsoever: no panic; no allocation beyond a constant factor of the
//! datagram's length (every length field is checked against the bytes actually present before
//! anything is allocated for it); time linear in the length (every loop consumes input).
//! A datagram is accepted or refused whole: if any message in it is malformed, none is
//! returned (N4). The checks run in the order `spec/protocol.md` ("Decoding order") gives, so
//! every implementation names the same cause for the same bytes.

use core::fmt;
use std::sync::Arc;

use ayllu_core::{
    BleConfig, Change, ConnectionId, ConnectionKind, ControlBody, Duration, Endpoint, NodeId, PortMessage, Value,
};

use crate::auth::{verify_mac, Key};
use crate::message::{conn_kind_from, endpoint_tag, reply_code, value_type, ReplyPart, WireMessage};
use crate::{
    change_tag, kind, op, COOKIE_LEN, FLAG_AUTH, HEADER_LEN, MAC_LEN, MAGIC, MAX_DATAGRAM_LEN, MAX_REPLY_PARTS,
    MESSAGE_HEADER_LEN, VERSION,
};

/// How the receiving node is configured.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ReceiverConfig {
    /// Our team id: datagrams of other teams are dropped (`wrong_team`).
    pub team: u32,
    /// The team key. `Some`: only authenticated datagrams are accepted. `None`: the team is
    /// open, and authenticated datagrams are refused (`unexpected_auth`) rather than trusted
    /// unverified.
    pub key: Option<Key>,
}

impl ReceiverConfig {
    /// An open team: anyone who can reach the node can write its ports (as in the paper).
    pub const fn open(team: u32) -> Self {
        ReceiverConfig { team, key: None }
    }
    /// An authenticated team.
    pub const fn keyed(team: u32, key: Key) -> Self {
        ReceiverConfig { team, key: Some(key) }
    }
}

/// A datagram that passed every check.
#[derive(Clone, Debug, PartialEq)]
pub struct Datagram {
    /// The sender's node id from the header (authenticated only if `authenticated`).
    pub sender: NodeId,
    /// The sender's datagram sequence number; when `authenticated`, the runtime checks it
    /// against the sender's [`crate::ReplayWindow`] before applying anything.
    pub seq: u64,
    /// The MAC was present and verified.
    pub authenticated: bool,
    /// The messages in order, including [`WireMessage::Unknown`] for each skipped one.
    pub messages: Vec<WireMessage>,
}

/// Why a whole datagram was dropped (spec "Drop causes"; `replayed` is decided by
/// [`crate::ReplayWindow`] and `unknown_kind` skips a message, not a datagram).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum DropReason {
    /// Longer than 8192 bytes.
    Oversized,
    /// Shorter than its header (and MAC), or a message running past the end.
    Truncated,
    /// The first two bytes are not `AY`: not an Ayllu datagram.
    BadMagic,
    /// A protocol version other than [`crate::VERSION`].
    BadVersion,
    /// A reserved flag bit is set.
    BadFlags,
    /// The team id differs from the receiver's: another team on the same network.
    WrongTeam,
    /// We hold a key and the datagram has no MAC.
    Unauthenticated,
    /// We hold no key and the datagram has a MAC.
    UnexpectedAuth,
    /// The MAC does not verify under our key: forged, corrupted, or another key (N5).
    BadMac,
    /// A message of a known kind breaks its layout (short body, invalid UTF-8, a byte out of
    /// range, an empty name where one is required, ...).
    Malformed,
}

impl DropReason {
    /// Every reason, in the order the spec lists them (for counters).
    pub const ALL: [DropReason; 10] = [
        DropReason::Oversized,
        DropReason::Truncated,
        DropReason::BadMagic,
        DropReason::BadVersion,
        DropReason::BadFlags,
        DropReason::WrongTeam,
        DropReason::Unauthenticated,
        DropReason::UnexpectedAuth,
        DropReason::BadMac,
        DropReason::Malformed,
    ];

    /// The counter name, as in the spec.
    pub fn name(self) -> &'static str {
        match self {
            DropReason::Oversized => "oversized",
            DropReason::Truncated => "truncated",
            DropReason::BadMagic => "bad_magic",
            DropReason::BadVersion => "bad_version",
            DropReason::BadFlags => "bad_flags",
            DropReason::WrongTeam => "wrong_team",
            DropReason::Unauthenticated => "unauthenticated",
            DropReason::UnexpectedAuth => "unexpected_auth",
            DropReason::BadMac => "bad_mac",
            DropReason::Malformed => "malformed",
        }
    }

    /// The reason named `name`, if any.
    pub fn from_name(name: &str) -> Option<DropReason> {
        DropReason::ALL.into_iter().find(|r| r.name() == name)
    }
}

impl fmt::Display for DropReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl std::error::Error for DropReason {}

/// Decode one datagram as a receiver configured by `config` would.
pub fn decode(bytes: &[u8], config: &ReceiverConfig) -> Result<Datagram, DropReason> {
    decode_with(bytes, config, &mut NameCache::none(), Vec::new())
}

/// [`decode`] for a receiver that decodes datagram after datagram: names are taken from (and
/// added to) `names`, and the messages are appended to `messages` (emptied first), whose
/// allocation the caller can take back from the result. The outcome is the same as `decode`'s.
pub fn decode_with(
    bytes: &[u8],
    config: &ReceiverConfig,
    names: &mut NameCache,
    mut messages: Vec<WireMessage>,
) -> Result<Datagram, DropReason> {
    messages.clear();
    let Header { sender, seq, authenticated } = decode_into(bytes, config, names, &mut messages)?;
    Ok(Datagram { sender, seq, authenticated, messages })
}

/// A datagram's header fields, once it passed every check of the header and the MAC.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct Header {
    /// The sender's node id (authenticated only if `authenticated`).
    pub sender: NodeId,
    /// The sender's datagram sequence number (see [`Datagram::seq`]).
    pub seq: u64,
    /// The MAC was present and verified.
    pub authenticated: bool,
}

/// Where [`decode_into`] puts a datagram's messages, in their order: PORT messages as the
/// core's [`PortMessage`] (with the group, if sent to one), every other message as a
/// [`WireMessage`]. A receiver that applies port messages as they come saves building (and
/// moving, 192 bytes) a `WireMessage` for each.
pub trait MessageSink {
    /// The header, before any message: the sender is known from here on.
    fn header(&mut self, header: &Header) {
        let _ = header;
    }
    /// A PORT message; `group` is the group it was sent to (non-empty), if any.
    fn port(&mut self, message: PortMessage, group: Option<Arc<str>>);
    /// A message this sink is done with, for the next PORT message to be decoded into in
    /// place of building a new one (then [`MessageSink::port_placed`] instead of `port`), if
    /// it has one. A sink that keeps its messages' places from datagram to datagram (the UDP
    /// transport's inbox) saves moving each message and, when the place already holds the
    /// names the message carries (the usual case: a flow's datagrams look alike), taking and
    /// dropping a reference to each name: they are kept. The place is overwritten only once
    /// the whole message decoded; a malformed one leaves it as it was.
    fn port_place(&mut self) -> Option<&mut PortMessage> {
        None
    }
    /// The PORT message just decoded into [`MessageSink::port_place`]'s message; `group` as
    /// for [`MessageSink::port`].
    fn port_placed(&mut self, group: Option<Arc<str>>) {
        let _ = group;
    }
    /// Any other message, [`WireMessage::Unknown`] included.
    fn other(&mut self, message: WireMessage);
}

/// The messages as [`Datagram::messages`] has them.
impl MessageSink for Vec<WireMessage> {
    fn port(&mut self, message: PortMessage, group: Option<Arc<str>>) {
        self.push(match group {
            Some(group) => WireMessage::GroupPort { group, message },
            None => WireMessage::Port(message),
        });
    }
    fn other(&mut self, message: WireMessage) {
        self.push(message);
    }
}

/// [`decode_with`] handing each message to `sink` as it is decoded. The checks and the outcome
/// are `decode`'s; but a datagram refused for a malformed message after others may have put
/// those others in `sink` already: the caller takes them back on `Err` (a receiver applies
/// nothing from a refused datagram).
pub fn decode_into(
    bytes: &[u8],
    config: &ReceiverConfig,
    names: &mut NameCache,
    sink: &mut impl MessageSink,
) -> Result<Header, DropReason> {
    if bytes.len() > MAX_DATAGRAM_LEN {
        return Err(DropReason::Oversized);
    }
    let Some(h) = bytes.first_chunk::<HEADER_LEN>() else {
        return Err(DropReason::Truncated);
    };
    let (magic, version, flags) = ([h[0], h[1]], h[2], h[3]);
    let team = u32::from_le_bytes([h[4], h[5], h[6], h[7]]);
    let sender = u32::from_le_bytes([h[8], h[9], h[10], h[11]]);
    let seq = u64::from_le_bytes([h[12], h[13], h[14], h[15], h[16], h[17], h[18], h[19]]);
    if magic != MAGIC {
        return Err(DropReason::BadMagic);
    }
    if version != VERSION {
        return Err(DropReason::BadVersion);
    }
    if flags & !FLAG_AUTH != 0 {
        return Err(DropReason::BadFlags);
    }
    if team != config.team {
        return Err(DropReason::WrongTeam);
    }
    let has_mac = flags & FLAG_AUTH != 0;
    let end = match (&config.key, has_mac) {
        (Some(_), false) => return Err(DropReason::Unauthenticated),
        (None, true) => return Err(DropReason::UnexpectedAuth),
        (None, false) => bytes.len(),
        (Some(key), true) => {
            if bytes.len() < HEADER_LEN + MAC_LEN {
                return Err(DropReason::Truncated);
            }
            let end = bytes.len() - MAC_LEN;
            if !verify_mac(key, &bytes[..end], &bytes[end..]) {
                return Err(DropReason::BadMac);
            }
            end
        }
    };
    let header = Header { sender: NodeId(sender), seq, authenticated: has_mac };
    sink.header(&header);
    decode_messages(&bytes[HEADER_LEN..end], names, sink)?;
    Ok(header)
}

/// The names a receiver decoded recently, so that names a peer sends again and again (its
/// destination behaviors and ports) become shared `Arc<str>`s rather than one allocation and
/// one UTF-8 check per message. Bounded whatever arrives: [`NameCache::SETS`] sets of two
/// names of at most 255 bytes; a name that is not in its set replaces the older of the two.
///
/// A lookup is meant to cost a small fraction of an allocation: the bytes are hashed a word
/// at a time, each slot keeps its name's hash beside it so a slot holding another name is
/// passed over without reading that name, and a short name is compared in place. A PORT's
/// two names lie side by side in its body, so they are looked up as one: a second table of as
/// many sets holds (behavior, port) pairs, keyed by those bytes, and a repeated destination
/// costs one lookup instead of two.
#[derive(Clone, Debug)]
pub struct NameCache {
    /// `2 * SETS` entries, or none for a cache that keeps nothing.
    slots: Vec<Option<NameSlot>>,
    /// `2 * SETS` (behavior, port) pairs, or none.
    pairs: Vec<Option<PairSlot>>,
}

/// A PORT's destination names, with the hash of the bytes that spell both ([`name_hash`] of
/// `[len][behavior][len][port]`).
#[derive(Clone, Debug)]
struct PairSlot {
    hash: u64,
    behavior: Arc<str>,
    port: Arc<str>,
}

impl PairSlot {
    /// Whether `span` spells this pair: `[len][behavior][len][port]`.
    #[inline(always)]
    fn spelled_by(&self, span: &[u8]) -> bool {
        let (b, p) = (self.behavior.as_bytes(), self.port.as_bytes());
        span.len() == b.len() + p.len() + 2
            && same_bytes(&span[1..=b.len()], b)
            && same_bytes(&span[b.len() + 2..], p)
            && usize::from(span[0]) == b.len()
            && usize::from(span[b.len() + 1]) == p.len()
    }
}

/// One cached name with the hash of its bytes ([`name_hash`]).
#[derive(Clone, Debug)]
struct NameSlot {
    hash: u64,
    name: Arc<str>,
}

impl Default for NameCache {
    fn default() -> Self {
        NameCache::new()
    }
}

impl NameCache {
    /// Number of sets (of two names each).
    pub const SETS: usize = 256;

    /// An empty cache of [`NameCache::SETS`] sets (about 12 KiB of slots, names besides).
    pub fn new() -> Self {
        NameCache { slots: vec![None; 2 * NameCache::SETS], pairs: vec![None; 2 * NameCache::SETS] }
    }

    /// A cache that keeps nothing (one-off decoding).
    fn none() -> Self {
        NameCache { slots: Vec::new(), pairs: Vec::new() }
    }

    /// The name `bytes` spell, if they are UTF-8. The hit is inlined into the decoder; the
    /// miss (an allocation anyway) is not.
    #[inline(always)]
    fn intern(&mut self, bytes: &[u8]) -> Option<Arc<str>> {
        let hash = name_hash(bytes);
        // The top bits: they depend on every byte of the name (a product's low bits do not).
        let set = 2 * ((hash >> (64 - NameCache::SETS.trailing_zeros())) as usize % NameCache::SETS);
        if let Some(pair) = self.slots.get(set..set + 2) {
            for slot in pair.iter().flatten() {
                if slot.hash == hash && same_bytes(slot.name.as_bytes(), bytes) {
                    return Some(slot.name.clone());
                }
            }
        }
        self.insert(set, hash, bytes)
    }

    /// The (behavior, port) pair that `span` (`[len][behavior][len][port]`, as a PORT body
    /// has them) spells, with each name's own checks (non-empty, UTF-8) made when the pair was
    /// first kept: a pair in the cache was checked then.
    #[inline(always)]
    fn intern_pair(&mut self, span: &[u8]) -> Option<(Arc<str>, Arc<str>)> {
        let hash = name_hash(span);
        let set = 2 * ((hash >> (64 - NameCache::SETS.trailing_zeros())) as usize % NameCache::SETS);
        if let Some(pair) = self.pairs.get(set..set + 2) {
            for slot in pair.iter().flatten() {
                if slot.hash == hash && slot.spelled_by(span) {
                    return Some((slot.behavior.clone(), slot.port.clone()));
                }
            }
        }
        self.insert_pair(set, hash, span)
    }

    /// A pair not in the cache: each name through [`NameCache::intern`], the pair kept.
    #[cold]
    #[inline(never)]
    fn insert_pair(&mut self, set: usize, hash: u64, span: &[u8]) -> Option<(Arc<str>, Arc<str>)> {
        let lb = usize::from(*span.first()?);
        let behavior = self.intern(span.get(1..=lb)?).filter(|n| !n.is_empty())?;
        let port = self.intern(span.get(lb + 2..)?).filter(|n| !n.is_empty())?;
        if let Some(pair) = self.pairs.get_mut(set..set + 2) {
            pair[1] = pair[0].take();
            pair[0] = Some(PairSlot { hash, behavior: behavior.clone(), port: port.clone() });
        }
        Some((behavior, port))
    }

    /// A name not in the cache: checked, allocated and kept (unless the cache keeps nothing).
    #[cold]
    #[inline(never)]
    fn insert(&mut self, set: usize, hash: u64, bytes: &[u8]) -> Option<Arc<str>> {
        let name: Arc<str> = Arc::from(core::str::from_utf8(bytes).ok()?);
        if let Some(pair) = self.slots.get_mut(set..set + 2) {
            pair[1] = pair[0].take();
            pair[0] = Some(NameSlot { hash, name: name.clone() });
        }
        Some(name)
    }
}

// The set index takes the hash's top bits: SETS must be a power of two.
const _: () = assert!(NameCache::SETS.is_power_of_two() && NameCache::SETS > 1);

/// A hash of a name's bytes, a word at a time (names are short: most are one or two words).
/// Not for adversaries: a collision only costs a cache miss, never a wrong name, since the
/// bytes are compared too.
#[inline(always)]
fn name_hash(bytes: &[u8]) -> u64 {
    const K: u64 = 0x9e37_79b9_7f4a_7c15;
    let n = bytes.len();
    let mut h = (n as u64).wrapping_mul(K);
    let mut words = bytes.chunks_exact(8);
    for w in &mut words {
        h = (h ^ word(w)).wrapping_mul(K).rotate_left(29);
    }
    // The last bytes in one or two loads, overlapping what came before (the length is in the
    // hash, so a hash still depends on every byte) rather than one step per byte.
    let tail = match n {
        0 => 0,
        1..=3 => u64::from(bytes[0]) | u64::from(bytes[n / 2]) << 8 | u64::from(bytes[n - 1]) << 16,
        4..=7 => u64::from(half(&bytes[..4])) | u64::from(half(&bytes[n - 4..])) << 32,
        _ if words.remainder().is_empty() => 0,
        _ => word(&bytes[n - 8..]),
    };
    (h ^ tail).wrapping_mul(K)
}

/// Eight bytes (exactly) as a little-endian word.
#[inline(always)]
fn word(b: &[u8]) -> u64 {
    u64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]])
}

/// Four bytes (exactly) as a little-endian word.
#[inline(always)]
fn half(b: &[u8]) -> u32 {
    u32::from_le_bytes([b[0], b[1], b[2], b[3]])
}

/// `a == b`, compared in place for short names (a call to `memcmp` costs more than the bytes):
/// two loads from each side, overlapping when the length is not a whole number of them.
#[inline(always)]
fn same_bytes(a: &[u8], b: &[u8]) -> bool {
    let n = a.len();
    if n != b.len() {
        return false;
    }
    match n {
        0 => true,
        1..=3 => a[0] == b[0] && a[n / 2] == b[n / 2] && a[n - 1] == b[n - 1],
        4..=7 => half(&a[..4]) == half(&b[..4]) && half(&a[n - 4..]) == half(&b[n - 4..]),
        8..=16 => word(&a[..8]) == word(&b[..8]) && word(&a[n - 8..]) == word(&b[n - 8..]),
        _ => a == b,
    }
}

/// Every message of the messages area into `out`, or the reason the datagram is dropped.
fn decode_messages(mut area: &[u8], names: &mut NameCache, out: &mut impl MessageSink) -> Result<(), DropReason> {
    while !area.is_empty() {
        if area.len() < MESSAGE_HEADER_LEN {
            return Err(DropReason::Truncated);
        }
        let code = area[0];
        let length = u16::from_le_bytes([area[1], area[2]]);
        let rest = &area[MESSAGE_HEADER_LEN..];
        let Some(body) = rest.get(..usize::from(length)) else {
            return Err(DropReason::Truncated);
        };
        area = &rest[usize::from(length)..];
        if code == kind::PORT {
            if let Some(place) = out.port_place() {
                let group = decode_port_into(body, names, place).ok_or(DropReason::Malformed)?;
                out.port_placed(group);
            } else {
                let (message, group) = decode_port(body, names).ok_or(DropReason::Malformed)?;
                out.port(message, group);
            }
            continue;
        }
        let message = match code {
            kind::HELLO => decode_hello(body, names),
            kind::REQUEST => decode_request(body, names),
            kind::REPLY => decode_reply(body, names),
            kind::CHALLENGE => decode_cookie(body).map(|cookie| WireMessage::Challenge { cookie }),
            kind::ECHO => decode_cookie(body).map(|cookie| WireMessage::Echo { cookie }),
            _ => Some(WireMessage::Unknown { code, length }),
        };
        out.other(message.ok_or(DropReason::Malformed)?);
    }
    Ok(())
}

// Body decoders return `None` for malformed bodies. Bytes after the known fields are ignored:
// fields are only ever appended to a kind, so an older receiver reads a newer sender's prefix.

fn decode_port(body: &[u8], names: &mut NameCache) -> Option<(PortMessage, Option<Arc<str>>)> {
    let mut r = Reader::new(body, names);
    let conn = ConnectionId(r.u64()?);
    let seq = r.u64()?;
    let kind = r.kind()?;
    let priority = r.i32()?;
    let (behavior, port) = r.name_pair()?;
    let value = r.value()?;
    let message = PortMessage { conn, seq, behavior, port, kind, priority, value };
    // The optional group (D-S10.6): read only when what follows the value is a whole str8 of
    // UTF-8. Anything else there is ignored as a later field would be, so bodies that were
    // valid before the field existed (trailing bytes included) decode as they always did; an
    // empty group means "sent to a node" and lets later fields follow.
    // Most port messages end with their value: nothing to look up then.
    if r.buf.is_empty() {
        return Some((message, None));
    }
    match r.str8() {
        Some(group) if !group.is_empty() => Some((message, Some(group))),
        _ => Some((message, None)),
    }
}

/// [`decode_port`] into `place`, which is overwritten only once the whole body decoded: the
/// same message, and the same refusals, whatever `place` held. Its names are kept when they
/// spell the body's (no lookup, no reference taken or dropped); otherwise they come from
/// `names` as `decode_port`'s do. Numbers are read in place (a call to `Reader::value` cost
/// as much as the rest of the fields).
fn decode_port_into(body: &[u8], names: &mut NameCache, place: &mut PortMessage) -> Option<Option<Arc<str>>> {
    let mut r = Reader::new(body, names);
    let conn = ConnectionId(r.u64()?);
    let seq = r.u64()?;
    let kind = r.kind()?;
    let priority = r.i32()?;
    let lb = usize::from(*r.buf.first()?);
    let lp = usize::from(*r.buf.get(lb + 1)?);
    let span = r.take(lb + lp + 2)?;
    let (b, p) = (place.behavior.as_bytes(), place.port.as_bytes());
    // Names a decoded message holds are never empty, but the place is the sink's: checked.
    let same_names = lb == b.len()
        && lp == p.len()
        && lb != 0
        && lp != 0
        && same_bytes(&span[1..lb + 1], b)
        && same_bytes(&span[lb + 2..], p);
    let fresh_names = if same_names { None } else { Some(r.names.intern_pair(span)?) };
    let value = match r.buf.first() {
        Some(&value_type::INT) if r.buf.len() >= 9 => {
            r.buf = &r.buf[1..];
            Value::Int(r.i64()?)
        }
        Some(&value_type::FLOAT) if r.buf.len() >= 9 => {
            r.buf = &r.buf[1..];
            Value::Float(r.f64()?)
        }
        _ => r.value()?,
    };
    // The optional group, as `decode_port` reads it.
    let group = if r.buf.is_empty() {
        None
    } else {
        match r.str8() {
            Some(group) if !group.is_empty() => Some(group),
            _ => None,
        }
    };
    if let Some((behavior, port)) = fresh_names {
        place.behavior = behavior;
        place.port = port;
    }
    place.conn = conn;
    place.seq = seq;
    place.kind = kind;
    place.priority = priority;
    place.value = value;
    Some(group)
}

fn decode_hello(body: &[u8], names: &mut NameCache) -> Option<WireMessage> {
    let mut r = Reader::new(body, names);
    let interval_ms = r.u32()?;
    if interval_ms == 0 {
        return None;
    }
    let name = r.str8()?;
    let n = r.u8()?;
    let mut groups = Vec::new();
    for _ in 0..n {
        groups.push(r.name()?);
    }
    Some(WireMessage::Hello { interval_ms, name, groups })
}

fn decode_request(body: &[u8], names: &mut NameCache) -> Option<WireMessage> {
    let mut r = Reader::new(body, names);
    let id = r.u64()?;
    let body = match r.u8()? {
        op::CONNECT => {
            let source_behavior = r.str8()?;
            let source_port = r.str8()?;
            let destination = r.endpoint()?;
            let kind = r.kind()?;
            let priority = r.i32()?;
            ControlBody::Connect { source_behavior, source_port, destination, kind, priority }
        }
        op::DISCONNECT => ControlBody::Disconnect { conn: ConnectionId(r.u64()?) },
        op::LIST => ControlBody::List,
        op::WHY => ControlBody::Why { behavior: r.str8()?, port: r.str8()? },
        op::READ => ControlBody::Read { behavior: r.str8()?, port: r.str8()? },
        op::PREPARE => {
            let txn = r.u64()?;
            let hold = Duration::from_nanos(r.u64()?);
            let n = r.u8()?;
            let mut changes = Vec::with_capacity(usize::from(n));
            for _ in 0..n {
                changes.push(r.change()?);
            }
            ControlBody::Prepare { txn, changes, hold }
        }
        op::COMMIT => ControlBody::Commit { txn: r.u64()?, delay: Duration::from_nanos(r.u64()?) },
        op::ABORT => ControlBody::Abort { txn: r.u64()? },
        // Not malformed: the receiver answers "unknown operation" (spec, REQUEST).
        other => return Some(WireMessage::UnknownRequest { id, op: other }),
    };
    // An optional signature after the arguments (fields are only ever appended; anything
    // else there is ignored, as in every message).
    let signature = match r.u8() {
        Some(crate::operator::SIGNATURE_TAG) => r.array::<{ crate::operator::SIGNATURE_LEN }>(),
        _ => None,
    };
    Some(WireMessage::Request { id, body, signature })
}

fn decode_cookie(body: &[u8]) -> Option<[u8; COOKIE_LEN]> {
    body.get(..COOKIE_LEN)?.try_into().ok()
}

fn decode_reply(body: &[u8], names: &mut NameCache) -> Option<WireMessage> {
    let mut r = Reader::new(body, names);
    let id = r.u64()?;
    let status = r.u8()?;
    let part = r.u16()?;
    let parts = r.u16()?;
    if parts == 0 || parts > MAX_REPLY_PARTS || part >= parts {
        return None;
    }
    let payload = match status {
        reply_code::STATUS_ERROR => ReplyPart::Error(r.str16()?.to_owned()),
        reply_code::STATUS_OK => match r.u8()? {
            reply_code::RESULT_CONNECTION => ReplyPart::Connection(ConnectionId(r.u64()?)),
            reply_code::RESULT_VALUE => ReplyPart::Value(r.value()?),
            reply_code::RESULT_REPORT => ReplyPart::Report(r.str16()?.to_owned()),
            _ => return None,
        },
        _ => return None,
    };
    // Only a report is ever cut into parts.
    if parts != 1 && !matches!(payload, ReplyPart::Report(_)) {
        return None;
    }
    Some(WireMessage::Reply { id, part, parts, payload })
}

/// A cursor over a body. Every read checks the bytes are there first and returns `None` when
/// they are not, so nothing is allocated for a length the input cannot back.
struct Reader<'a, 'n> {
    buf: &'a [u8],
    names: &'n mut NameCache,
}

impl<'a> Reader<'a, '_> {
    fn new<'n>(buf: &'a [u8], names: &'n mut NameCache) -> Reader<'a, 'n> {
        Reader { buf, names }
    }

    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        if n > self.buf.len() {
            return None;
        }
        let (head, tail) = self.buf.split_at(n);
        self.buf = tail;
        Some(head)
    }

    fn array<const N: usize>(&mut self) -> Option<[u8; N]> {
        self.take(N)?.try_into().ok()
    }

    fn u8(&mut self) -> Option<u8> {
        Some(self.array::<1>()?[0])
    }
    fn u16(&mut self) -> Option<u16> {
        self.array().map(u16::from_le_bytes)
    }
    fn u32(&mut self) -> Option<u32> {
        self.array().map(u32::from_le_bytes)
    }
    fn u64(&mut self) -> Option<u64> {
        self.array().map(u64::from_le_bytes)
    }
    fn i32(&mut self) -> Option<i32> {
        self.array().map(i32::from_le_bytes)
    }
    fn i64(&mut self) -> Option<i64> {
        self.array().map(i64::from_le_bytes)
    }
    fn f64(&mut self) -> Option<f64> {
        // From bits: NaN payloads and -0.0 survive.
        self.u64().map(f64::from_bits)
    }

    fn utf8(&mut self, n: usize) -> Option<&'a str> {
        core::str::from_utf8(self.take(n)?).ok()
    }
    // Inlined into its callers: a call's register saving cost as much as a cached name.
    #[inline(always)]
    fn str8(&mut self) -> Option<Arc<str>> {
        let n = self.u8()?;
        let bytes = self.take(usize::from(n))?;
        self.names.intern(bytes)
    }
    /// A behavior, port or group name: a non-empty str8.
    fn name(&mut self) -> Option<Arc<str>> {
        self.str8().filter(|s| !s.is_empty())
    }
    /// Two names side by side (a PORT's behavior and port), looked up as one.
    #[inline(always)]
    fn name_pair(&mut self) -> Option<(Arc<str>, Arc<str>)> {
        let lb = usize::from(*self.buf.first()?);
        let lp = usize::from(*self.buf.get(lb + 1)?);
        let span = self.take(lb + lp + 2)?;
        self.names.intern_pair(span)
    }
    fn str16(&mut self) -> Option<&'a str> {
        let n = self.u16()?;
        self.utf8(usize::from(n))
    }
    fn bytes16(&mut self) -> Option<&'a [u8]> {
        let n = self.u16()?;
        self.take(usize::from(n))
    }

    /// Connection kind byte and period, validated together.
    fn kind(&mut self) -> Option<ConnectionKind> {
        let code = self.u8()?;
        let period = self.u64()?;
        conn_kind_from(code, period)
    }

    fn value(&mut self) -> Option<Value> {
        Some(match self.u8()? {
            value_type::BOOL => match self.u8()? {
                0 => Value::Bool(false),
                1 => Value::Bool(true),
                _ => return None,
            },
            value_type::INT => Value::Int(self.i64()?),
            value_type::FLOAT => Value::Float(self.f64()?),
            value_type::TEXT => Value::Text(Arc::from(self.str16()?)),
            value_type::BYTES => Value::Bytes(Arc::from(self.bytes16()?)),
            value_type::VECTOR => {
                let n = usize::from(self.u8()?);
                let raw = self.take(n * 8)?;
                let xs: Vec<f64> = raw
                    .chunks_exact(8)
                    .map(|c| f64::from_bits(u64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]])))
                    .collect();
                Value::Vector(Arc::from(xs))
            }
            _ => return None,
        })
    }

    /// One change of a PREPARE; names are non-empty, endpoints never local.
    fn change(&mut self) -> Option<Change> {
        Some(match self.u8()? {
            change_tag::CREATE => Change::Create { class: self.name()?.to_string(), name: self.name()?.to_string() },
            change_tag::REMOVE => Change::Remove { name: self.name()?.to_string() },
            change_tag::CONNECT => Change::Connect {
                source: self.endpoint()?,
                destination: self.endpoint()?,
                kind: self.kind()?,
                priority: self.i32()?,
            },
            change_tag::DISCONNECT => Change::Disconnect { conn: ConnectionId(self.u64()?) },
            change_tag::DISCONNECT_BETWEEN => {
                Change::DisconnectBetween { source: self.endpoint()?, destination: self.endpoint()? }
            }
            change_tag::JOIN => Change::Join { group: self.name()?.to_string() },
            change_tag::LEAVE => Change::Leave { group: self.name()?.to_string() },
            change_tag::BLE_JOIN => Change::BleJoin {
                behavior: self.name()?.to_string(),
                config: BleConfig {
                    group: self.name()?.to_string(),
                    output: self.name()?.to_string(),
                    claim_rate_hz: self.f64()?,
                    inhibit_period: Duration::from_nanos(self.u64()?),
                    network_delay: Duration::from_nanos(self.u64()?),
                },
            },
            _ => return None,
        })
    }

    fn endpoint(&mut self) -> Option<Endpoint> {
        match self.u8()? {
            endpoint_tag::NODE => {
                Some(Endpoint::Node { node: NodeId(self.u32()?), behavior: self.str8()?, port: self.str8()? })
            }
            endpoint_tag::GROUP => {
                Some(Endpoint::Group { group: self.name()?, behavior: self.str8()?, port: self.str8()? })
            }
            // Tag 0 ("local") is never sent; anything else is unknown.
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const OPEN: ReceiverConfig = ReceiverConfig { team: 7, key: None };

    fn header(flags: u8) -> Vec<u8> {
        let mut b = vec![0x41, 0x59, 1, flags];
        b.extend_from_slice(&7u32.to_le_bytes());
        b.extend_from_slice(&1u32.to_le_bytes());
        b.extend_from_slice(&5u64.to_le_bytes());
        b
    }

    #[test]
    fn header_checks_in_order() {
        assert_eq!(decode(&[0; 8193], &OPEN), Err(DropReason::Oversized));
        assert_eq!(decode(&[0x41, 0x59], &OPEN), Err(DropReason::Truncated));
        assert_eq!(decode(&header(0), &OPEN).unwrap().messages, vec![]);
        let mut b = header(0);
        b[1] = 0x58;
        assert_eq!(decode(&b, &OPEN), Err(DropReason::BadMagic));
        let mut b = header(0);
        b[2] = 2;
        assert_eq!(decode(&b, &OPEN), Err(DropReason::BadVersion));
        assert_eq!(decode(&header(0x80), &OPEN), Err(DropReason::BadFlags));
        assert_eq!(decode(&header(0), &ReceiverConfig { team: 8, key: None }), Err(DropReason::WrongTeam));
        let keyed = ReceiverConfig { team: 7, key: Some([1; 32]) };
        assert_eq!(decode(&header(0), &keyed), Err(DropReason::Unauthenticated));
        assert_eq!(decode(&header(1), &OPEN), Err(DropReason::UnexpectedAuth));
        assert_eq!(decode(&header(1), &keyed), Err(DropReason::Truncated));
        let mut b = header(1);
        b.extend_from_slice(&[0; 16]);
        assert_eq!(decode(&b, &keyed), Err(DropReason::BadMac));
    }

    #[test]
    fn messages_area() {
        let mut b = header(0);
        b.extend_from_slice(&[0x7f, 0, 0, 0x7e, 2, 0, 9, 9]);
        let d = decode(&b, &OPEN).unwrap();
        assert_eq!(
            d.messages,
            vec![WireMessage::Unknown { code: 0x7f, length: 0 }, WireMessage::Unknown { code: 0x7e, length: 2 }]
        );
        let mut t = b.clone();
        t.push(1);
        assert_eq!(decode(&t, &OPEN), Err(DropReason::Truncated), "partial message header");
        let mut t = b.clone();
        t.extend_from_slice(&[0x7f, 1, 0]);
        assert_eq!(decode(&t, &OPEN), Err(DropReason::Truncated), "body past the end");
        let mut t = b;
        t.extend_from_slice(&[kind::PORT, 0, 0]);
        assert_eq!(decode(&t, &OPEN), Err(DropReason::Malformed), "empty PORT body");
    }

    #[test]
    fn names_round_trip() {
        for r in DropReason::ALL {
            assert_eq!(DropReason::from_name(r.name()), Some(r));
        }
    }

    fn port(behavior: &str, port: &str, seq: u64) -> WireMessage {
        WireMessage::Port(PortMessage {
            conn: ConnectionId(1),
            seq,
            behavior: behavior.into(),
            port: port.into(),
            kind: ConnectionKind::Normal,
            priority: 0,
            value: Value::Int(1),
        })
    }

    #[test]
    fn the_name_cache_spreads_similar_names_and_finds_long_ones() {
        // Names that differ only in their last bytes (p00, p01, ...) must not share a set, or
        // a receiver of 64 such ports would miss again and again.
        let mut names = NameCache::new();
        let sets: std::collections::HashSet<u64> =
            (0..64).map(|i| name_hash(format!("p{i:02}").as_bytes()) >> 56).collect();
        assert!(sets.len() > 40, "64 names in {} sets", sets.len());
        // Every length around the word size and past the in-place comparison, twice: the
        // second lookup hands out the first one's name.
        for n in 0..=40 {
            let name = "x".repeat(n) + "y";
            let a = names.intern(name.as_bytes()).unwrap();
            let b = names.intern(name.as_bytes()).unwrap();
            assert!(Arc::ptr_eq(&a, &b) && *a == *name);
            // A name one byte different is a different name.
            let other = "x".repeat(n) + "z";
            assert_eq!(&*names.intern(other.as_bytes()).unwrap(), other);
            let mut middle = name.clone().into_bytes();
            middle[n / 2] = b'w';
            assert!(!same_bytes(name.as_bytes(), &middle) && same_bytes(&middle, &middle.clone()));
        }
        assert_eq!(names.intern(&[0xff, 0xfe]), None, "not UTF-8");
        // Pairs: the same bytes cut differently are different pairs; a pair with an empty or
        // non-UTF-8 name is refused every time, cached or not.
        let ab_c = names.intern_pair(&[2, b'a', b'b', 1, b'c']).unwrap();
        let a_bc = names.intern_pair(&[1, b'a', 2, b'b', b'c']).unwrap();
        assert_eq!((&*ab_c.0, &*ab_c.1, &*a_bc.0, &*a_bc.1), ("ab", "c", "a", "bc"));
        let again = names.intern_pair(&[2, b'a', b'b', 1, b'c']).unwrap();
        assert!(Arc::ptr_eq(&again.0, &ab_c.0) && Arc::ptr_eq(&again.1, &ab_c.1));
        for _ in 0..2 {
            assert_eq!(names.intern_pair(&[0, 1, b'c']), None);
            assert_eq!(names.intern_pair(&[1, b'a', 0]), None);
            assert_eq!(names.intern_pair(&[1, 0xff, 1, b'c']), None);
        }
    }

    #[test]
    fn decoding_with_a_name_cache_gives_what_decode_gives() {
        let mut names = NameCache::new();
        let mut reuse = Vec::new();
        // Far more names than the cache holds, so entries are replaced all along; every
        // datagram also repeats a name, and ends with a malformed one now and then.
        for i in 0..(4 * NameCache::SETS) as u64 {
            let b = format!("B{}", i % 7);
            let p = format!("port-{i}");
            let mut w = crate::DatagramWriter::new(7, NodeId(1), i, None, 1400);
            w.push(&port(&b, &p, i)).unwrap();
            w.push(&port(&b, "In", i)).unwrap();
            if i % 50 == 0 {
                w.push_raw(kind::PORT, &[1, 2, 3]).unwrap();
            }
            let bytes = w.finish();
            let got = decode_with(&bytes, &OPEN, &mut names, std::mem::take(&mut reuse));
            assert_eq!(got, decode(&bytes, &OPEN));
            if let Ok(d) = got {
                reuse = d.messages;
            }
        }
        // A name seen before is handed out again, not allocated again.
        let bytes = crate::encode_datagram(7, NodeId(1), 1, None, &[port("B1", "In", 1), port("B1", "In", 2)]).unwrap();
        let d = decode_with(&bytes, &OPEN, &mut names, Vec::new()).unwrap();
        let (WireMessage::Port(a), WireMessage::Port(b)) = (&d.messages[0], &d.messages[1]) else { unreachable!() };
        assert!(Arc::ptr_eq(&a.behavior, &b.behavior) && Arc::ptr_eq(&a.port, &b.port));
    }
}
