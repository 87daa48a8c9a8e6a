//! The encoder: [`DatagramWriter`] builds one datagram, message by message, within a size
//! limit, so the runtime can batch everything bound for one destination into as few
//! datagrams as the path MTU allows (N3).
//!
//! Promises: the writer only ever holds a complete, valid datagram — a message that cannot be
//! encoded, or does not fit, leaves it exactly as it was and says why ([`EncodeError`]); what it
//! produces is accepted by [`crate::decode()`] and decodes to the messages pushed; it never
//! exceeds the limit it was given (clamped to what receivers accept).

use core::fmt;

use std::sync::Arc;

use ayllu_core::{Change, ConnectionId, ConnectionKind, ControlBody, Endpoint, NodeId, PortMessage, Value};

use crate::auth::{mac, Key};
use crate::message::{conn_kind_code, endpoint_tag, reply_code, value_type, ReplyPart, WireMessage};
use crate::{
    change_tag, kind, op, FLAG_AUTH, HEADER_LEN, MAC_LEN, MAGIC, MAX_DATAGRAM_LEN, MAX_REPLY_PARTS, MESSAGE_HEADER_LEN,
    VERSION,
};

/// Why a message was not added to a datagram.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum EncodeError {
    /// The datagram already holds messages and this one does not fit in the space left:
    /// finish this datagram and push the message into a new one.
    DoesNotFit {
        /// Bytes the message takes, with its 3-byte message header.
        needed: usize,
        /// Bytes left in this datagram.
        available: usize,
    },
    /// The message does not fit even in an empty datagram of this size limit: it cannot be sent
    /// at this MTU.
    TooLarge {
        /// Bytes the message takes, with its 3-byte message header.
        needed: usize,
        /// Bytes an empty datagram has for messages at this size limit.
        available: usize,
    },
    /// The message cannot be expressed on the wire at all (an empty or over-long name, a
    /// local endpoint, a timed connection kind with a zero period, ...). The text says which
    /// rule of `spec/protocol.md` it breaks.
    Invalid(&'static str),
    /// A report needs more than 64 REPLY parts at this MTU.
    ReportTooLarge {
        /// The report's size as JSON.
        bytes: usize,
        /// The most parts a reply may have ([`crate::MAX_REPLY_PARTS`]).
        max_parts: u16,
    },
}

impl fmt::Display for EncodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EncodeError::DoesNotFit { needed, available } => {
                write!(f, "message needs {needed} bytes, {available} left in this datagram")
            }
            EncodeError::TooLarge { needed, available } => {
                write!(f, "message needs {needed} bytes, at most {available} fit in a datagram")
            }
            EncodeError::Invalid(why) => write!(f, "message cannot be encoded: {why}"),
            EncodeError::ReportTooLarge { bytes, max_parts } => {
                write!(f, "report of {bytes} bytes needs more than {max_parts} parts")
            }
        }
    }
}

impl std::error::Error for EncodeError {}

/// Builds one datagram: header, then messages appended while they fit, then (with a key) the
/// MAC written by [`DatagramWriter::finish`].
///
/// ```
/// use ayllu_core::{ConnectionId, ConnectionKind, NodeId, PortMessage, Value};
/// use ayllu_wire::*;
///
/// let key: Key = parse_key_hex(&"2a".repeat(32)).unwrap();
/// let hello = WireMessage::Hello { interval_ms: 1000, name: "robot-1".into(), groups: vec!["Peers".into()] };
/// let port = WireMessage::Port(PortMessage {
///     conn: ConnectionId(1),
///     seq: 7,
///     behavior: "OBS1".into(),
///     port: "Best".into(),
///     kind: ConnectionKind::Normal,
///     priority: 0,
///     value: Value::Float(0.8),
/// });
/// // Everything for one destination in one datagram (N3), signed with the team key (N5).
/// let seq = first_sequence(1_700_000_000); // boot time: above any earlier run's numbers
/// let mut writer = DatagramWriter::new(7, NodeId(1), seq, Some(key), DEFAULT_MTU);
/// writer.push(&hello)?;
/// writer.push(&port)?;
/// let bytes = writer.finish();
///
/// let datagram = decode(&bytes, &ReceiverConfig::keyed(7, key)).unwrap();
/// assert!(datagram.authenticated);
/// assert_eq!((datagram.sender, datagram.seq), (NodeId(1), seq));
/// assert_eq!(datagram.messages, vec![hello, port.clone()]);
/// // Refused whole by a keyless receiver and under another key.
/// assert_eq!(decode(&bytes, &ReceiverConfig::open(7)), Err(DropReason::UnexpectedAuth));
/// assert_eq!(decode(&bytes, &ReceiverConfig::keyed(7, [0; KEY_LEN])), Err(DropReason::BadMac));
///
/// // A message that does not fit leaves the datagram as it was: send it, start another.
/// let mut small = DatagramWriter::new(7, NodeId(1), seq + 1, None, HEADER_LEN + 60);
/// small.push(&port)?;
/// assert!(matches!(small.push(&port), Err(EncodeError::DoesNotFit { .. })));
/// assert_eq!(small.message_count(), 1);
/// # Ok::<(), EncodeError>(())
/// ```
#[derive(Clone, Debug)]
pub struct DatagramWriter {
    buf: Vec<u8>,
    key: Option<Key>,
    /// The most bytes header plus messages may take: the size limit less the MAC.
    limit: usize,
    messages: usize,
}

impl DatagramWriter {
    /// A datagram from `sender` of `team` with sequence number `seq` (strictly increasing per
    /// sender, see the spec), authenticated when `key` is given, at most `mtu` bytes long.
    ///
    /// `mtu` is clamped to `HEADER_LEN (+ MAC_LEN)..=MAX_DATAGRAM_LEN`: a datagram always has
    /// its header, and one larger than receivers accept would be dropped as `oversized`.
    pub fn new(team: u32, sender: NodeId, seq: u64, key: Option<Key>, mtu: usize) -> Self {
        DatagramWriter::with_buffer(Vec::new(), team, sender, seq, key, mtu)
    }

    /// [`DatagramWriter::new`] writing into `buf` (emptied first): a sender that keeps the
    /// buffers [`DatagramWriter::finish`] returned, once sent, allocates nothing per datagram.
    pub fn with_buffer(mut buf: Vec<u8>, team: u32, sender: NodeId, seq: u64, key: Option<Key>, mtu: usize) -> Self {
        let mac_len = if key.is_some() { MAC_LEN } else { 0 };
        let limit = mtu.clamp(HEADER_LEN + mac_len, MAX_DATAGRAM_LEN) - mac_len;
        let mut header = [0u8; HEADER_LEN];
        header[..2].copy_from_slice(&MAGIC);
        header[2] = VERSION;
        header[3] = if key.is_some() { FLAG_AUTH } else { 0 };
        header[4..8].copy_from_slice(&team.to_le_bytes());
        header[8..12].copy_from_slice(&sender.0.to_le_bytes());
        header[12..].copy_from_slice(&seq.to_le_bytes());
        buf.clear();
        buf.reserve(limit + mac_len);
        buf.extend_from_slice(&header);
        DatagramWriter { buf, key, limit, messages: 0 }
    }

    /// Append `message`. On error the datagram is unchanged: [`EncodeError::DoesNotFit`]
    /// means "start a new datagram", anything else means the message can never be sent as is.
    pub fn push(&mut self, message: &WireMessage) -> Result<(), EncodeError> {
        let start = self.buf.len();
        self.buf.push(message.kind_code());
        self.buf.extend_from_slice(&[0, 0]);
        if let Err(e) = encode_body(&mut self.buf, message) {
            self.buf.truncate(start);
            return Err(e);
        }
        self.close_message(start)
    }

    /// Append a PORT message to a node (`group` is `None`) or to `group`: what
    /// [`DatagramWriter::push`] does with [`WireMessage::Port`] and [`WireMessage::GroupPort`],
    /// the same bytes, without building either. A sender holds a core [`PortMessage`]; wrapping
    /// it in a `WireMessage` (192 bytes) only to encode and drop it cost a tenth of a batched
    /// port message's sending.
    pub fn push_port(&mut self, message: &PortMessage, group: Option<&str>) -> Result<(), EncodeError> {
        let start = self.buf.len();
        self.buf.extend_from_slice(&[kind::PORT, 0, 0]);
        if let Err(e) = encode_port_to(&mut self.buf, message, group) {
            self.buf.truncate(start);
            return Err(e);
        }
        self.close_message(start)
    }

    /// [`DatagramWriter::push_port`] from `templates`: the same bytes and the same errors, but
    /// what does not change from one message of a connection to the next (everything but the
    /// sequence number and the value) is copied whole from the connection's template, made at
    /// its first message. A turn's encoding then costs one copy, two writes and the value per
    /// message instead of the fields and names one by one.
    pub fn push_port_with(
        &mut self,
        templates: &mut PortTemplates,
        message: &PortMessage,
        group: Option<&str>,
    ) -> Result<(), EncodeError> {
        // A group's name follows the value: its messages (rare on the hot path) are built whole.
        if group.is_some() {
            return self.push_port(message, group);
        }
        let template = templates.get(message)?;
        let start = self.buf.len();
        // A number is written here in one step (a call to `put_value` cost as much as the
        // rest of the message); every other value as `push_port` writes it.
        let number = match message.value {
            Value::Int(i) => Some((value_type::INT, i.to_le_bytes())),
            Value::Float(x) => Some((value_type::FLOAT, x.to_bits().to_le_bytes())),
            _ => None,
        };
        if let (Some((tag, bytes)), Some(block)) = (number, template.block()) {
            // The usual message, whole in a block of fixed size: checked as `close_message`
            // checks, made on the stack and copied in one piece of that size (no call).
            let needed = template.len + 9;
            let (available, alone) = (self.limit - start, self.limit - HEADER_LEN);
            if needed > alone {
                return Err(EncodeError::TooLarge { needed, available: alone });
            }
            if needed > available {
                return Err(EncodeError::DoesNotFit { needed, available });
            }
            let mut m = *block;
            m[1..3].copy_from_slice(&((needed - MESSAGE_HEADER_LEN) as u16).to_le_bytes());
            m[SEQ_AT..SEQ_AT + 8].copy_from_slice(&message.seq.to_le_bytes());
            m[template.len] = tag;
            m[template.len + 1..needed].copy_from_slice(&bytes);
            if self.buf.capacity() - start >= BLOCK {
                self.buf.extend_from_slice(&m);
                self.buf.truncate(start + needed);
            } else {
                self.buf.extend_from_slice(&m[..needed]);
            }
            self.messages += 1;
            return Ok(());
        }
        self.buf.extend_from_slice(&template.bytes);
        self.buf[start + SEQ_AT..start + SEQ_AT + 8].copy_from_slice(&message.seq.to_le_bytes());
        if let Some((tag, bytes)) = number {
            let mut field = [tag; 9];
            field[1..].copy_from_slice(&bytes);
            self.buf.extend_from_slice(&field);
        } else if let Err(e) = put_value(&mut self.buf, &message.value) {
            self.buf.truncate(start);
            return Err(e);
        }
        self.close_message(start)
    }

    /// Append a message of any `kind` with a ready-made `body`, unchecked. For tests, tools and
    /// conformance vectors that need input no encoder produces (unknown kinds, extra trailing
    /// bytes, malformed bodies); the runtime uses [`DatagramWriter::push`].
    pub fn push_raw(&mut self, kind: u8, body: &[u8]) -> Result<(), EncodeError> {
        let start = self.buf.len();
        self.buf.push(kind);
        self.buf.extend_from_slice(&[0, 0]);
        self.buf.extend_from_slice(body);
        self.close_message(start)
    }

    /// Check the message that starts at `start` fits, write its length, or take it back.
    fn close_message(&mut self, start: usize) -> Result<(), EncodeError> {
        let needed = self.buf.len() - start;
        let body_len = needed - MESSAGE_HEADER_LEN;
        let available = self.limit - start;
        let alone = self.limit - HEADER_LEN;
        if needed > alone {
            self.buf.truncate(start);
            return Err(EncodeError::TooLarge { needed, available: alone });
        }
        if needed > available {
            self.buf.truncate(start);
            return Err(EncodeError::DoesNotFit { needed, available });
        }
        // The limit is at most MAX_DATAGRAM_LEN (8192), so a body that fits has a u16 length.
        self.buf[start + 1..start + 3].copy_from_slice(&(body_len as u16).to_le_bytes());
        self.messages += 1;
        Ok(())
    }

    /// Number of messages pushed so far.
    pub fn message_count(&self) -> usize {
        self.messages
    }

    /// True when no message has been pushed (the datagram is a bare header).
    pub fn is_empty(&self) -> bool {
        self.messages == 0
    }

    /// Bytes of the datagram so far (header and messages), without the MAC.
    pub fn encoded_len(&self) -> usize {
        self.buf.len()
    }

    /// Bytes still free for messages (each message takes 3 header bytes plus its body).
    pub fn remaining(&self) -> usize {
        self.limit - self.buf.len()
    }

    /// The finished datagram, with its MAC when the writer has a key.
    pub fn finish(mut self) -> Vec<u8> {
        if let Some(key) = &self.key {
            let tag = mac(key, &self.buf);
            self.buf.extend_from_slice(&tag);
        }
        self.buf
    }
}

/// Encode `messages` into one datagram of at most [`MAX_DATAGRAM_LEN`] bytes. A convenience for
/// tools and tests; the runtime batches with a [`DatagramWriter`] at the path MTU.
pub fn encode_datagram(
    team: u32,
    sender: NodeId,
    seq: u64,
    key: Option<Key>,
    messages: &[WireMessage],
) -> Result<Vec<u8>, EncodeError> {
    let mut w = DatagramWriter::new(team, sender, seq, key, MAX_DATAGRAM_LEN);
    for m in messages {
        w.push(m)?;
    }
    Ok(w.finish())
}

/// Bytes `message` takes in a datagram, its 3-byte message header included (to budget what is
/// sent before sending it).
pub fn encoded_len(message: &WireMessage) -> Result<usize, EncodeError> {
    let mut buf = Vec::new();
    encode_body(&mut buf, message)?;
    Ok(MESSAGE_HEADER_LEN + buf.len())
}

fn encode_body(buf: &mut Vec<u8>, message: &WireMessage) -> Result<(), EncodeError> {
    match message {
        WireMessage::Port(p) => encode_port_to(buf, p, None),
        WireMessage::GroupPort { group, message } => encode_port_to(buf, message, Some(group)),
        WireMessage::Hello { interval_ms, name, groups } => {
            if *interval_ms == 0 {
                return Err(EncodeError::Invalid("HELLO interval_ms must be above zero"));
            }
            buf.extend_from_slice(&interval_ms.to_le_bytes());
            put_str8(buf, name, NonEmpty::No)?;
            let n = u8::try_from(groups.len()).map_err(|_| EncodeError::Invalid("HELLO lists at most 255 groups"))?;
            buf.push(n);
            for g in groups {
                put_str8(buf, g, NonEmpty::Yes)?;
            }
            Ok(())
        }
        WireMessage::Request { id, body, signature } => {
            buf.extend_from_slice(&id.to_le_bytes());
            put_request(buf, body)?;
            if let Some(sig) = signature {
                buf.push(crate::operator::SIGNATURE_TAG);
                buf.extend_from_slice(sig);
            }
            Ok(())
        }
        WireMessage::Challenge { cookie } | WireMessage::Echo { cookie } => {
            buf.extend_from_slice(cookie);
            Ok(())
        }
        WireMessage::UnknownRequest { id, op } => {
            if (op::CONNECT..=op::ABORT).contains(op) {
                return Err(EncodeError::Invalid("UnknownRequest with a known operation code"));
            }
            buf.extend_from_slice(&id.to_le_bytes());
            buf.push(*op);
            Ok(())
        }
        WireMessage::Reply { id, part, parts, payload } => {
            if *parts == 0 || *parts > MAX_REPLY_PARTS || part >= parts {
                return Err(EncodeError::Invalid("REPLY needs 1 <= parts <= 64 and part < parts"));
            }
            if *parts != 1 && !matches!(payload, ReplyPart::Report(_)) {
                return Err(EncodeError::Invalid("only a report REPLY has more than one part"));
            }
            buf.extend_from_slice(&id.to_le_bytes());
            let status =
                if matches!(payload, ReplyPart::Error(_)) { reply_code::STATUS_ERROR } else { reply_code::STATUS_OK };
            buf.push(status);
            buf.extend_from_slice(&part.to_le_bytes());
            buf.extend_from_slice(&parts.to_le_bytes());
            match payload {
                ReplyPart::Error(message) => put_str16(buf, message.as_bytes()),
                ReplyPart::Connection(c) => {
                    buf.push(reply_code::RESULT_CONNECTION);
                    buf.extend_from_slice(&c.0.to_le_bytes());
                    Ok(())
                }
                ReplyPart::Value(v) => {
                    buf.push(reply_code::RESULT_VALUE);
                    put_value(buf, v)
                }
                ReplyPart::Report(slice) => {
                    buf.push(reply_code::RESULT_REPORT);
                    put_str16(buf, slice.as_bytes())
                }
            }
        }
        WireMessage::Unknown { .. } => Err(EncodeError::Invalid("an unknown message kind has no body to send")),
    }
}

/// PORT, the message sent most, with the checks (and errors) of the field-by-field encoders:
/// the fixed-size fields are laid out in one array and everything is appended after a single
/// reservation, rather than with a capacity check and a copy per field.
/// A PORT body, to a node (`group` is `None`) or to a group (the optional field appended):
/// the one encoding of both [`DatagramWriter::push`] and [`DatagramWriter::push_port`].
#[inline(always)]
fn encode_port_to(buf: &mut Vec<u8>, p: &PortMessage, group: Option<&str>) -> Result<(), EncodeError> {
    encode_port(buf, p)?;
    match group {
        Some(group) => put_str8(buf, group, NonEmpty::Yes),
        None => Ok(()),
    }
}

fn encode_port(buf: &mut Vec<u8>, p: &PortMessage) -> Result<(), EncodeError> {
    encode_port_head(buf, p)?;
    put_value(buf, &p.value)
}

/// Where a PORT message's sequence number lies, from the start of its message header (after
/// the kind, the length and the connection id).
const SEQ_AT: usize = MESSAGE_HEADER_LEN + 8;

/// A PORT body up to its value: the connection, the sequence number, the kind, the priority
/// and the names.
fn encode_port_head(buf: &mut Vec<u8>, p: &PortMessage) -> Result<(), EncodeError> {
    let (code, period) = conn_kind_code(p.kind);
    if code != 0 && period == 0 {
        return Err(EncodeError::Invalid("a timed connection kind needs a period above zero"));
    }
    let name = |s: &str| -> Result<u8, EncodeError> {
        if s.is_empty() {
            return Err(EncodeError::Invalid("behavior, port and group names are not empty"));
        }
        u8::try_from(s.len()).map_err(|_| EncodeError::Invalid("names are at most 255 bytes"))
    };
    let (behavior_len, port_len) = (name(&p.behavior)?, name(&p.port)?);
    let mut fixed = [0u8; 29];
    fixed[..8].copy_from_slice(&p.conn.0.to_le_bytes());
    fixed[8..16].copy_from_slice(&p.seq.to_le_bytes());
    fixed[16] = code;
    fixed[17..25].copy_from_slice(&period.to_le_bytes());
    fixed[25..].copy_from_slice(&p.priority.to_le_bytes());
    // Scalars need at most 9 bytes; longer values reserve again in `put_value`.
    buf.reserve(fixed.len() + 2 + p.behavior.len() + p.port.len() + 9);
    buf.extend_from_slice(&fixed);
    buf.push(behavior_len);
    buf.extend_from_slice(p.behavior.as_bytes());
    buf.push(port_len);
    buf.extend_from_slice(p.port.as_bytes());
    Ok(())
}

/// Per connection, a PORT message's bytes but its sequence number and value (the message
/// header with a zero length, the fields, the names), for [`DatagramWriter::push_port_with`].
/// A sender keeps one for all its datagrams. Bounded: [`PortTemplates::SLOTS`] templates of
/// at most 547 bytes, one slot per connection id modulo that number; a connection whose slot
/// holds another's takes it over.
///
/// A template stands for a message only if the message carries the very name strings it was
/// made from (`Arc` pointers, kept alive by the template, so an address cannot be reused by
/// another name) and the same connection, kind and priority: everything its bytes hold.
#[derive(Clone, Debug, Default)]
pub struct PortTemplates {
    /// `SLOTS` slots once the first template is made, none before.
    slots: Vec<Option<PortTemplate>>,
}

#[derive(Clone, Debug)]
struct PortTemplate {
    conn: ConnectionId,
    behavior: Arc<str>,
    port: Arc<str>,
    kind: ConnectionKind,
    priority: i32,
    /// The template's bytes.
    bytes: Vec<u8>,
    /// Its length.
    len: usize,
    /// The same bytes at the start of a [`BLOCK`], when they leave room for a number there.
    block: Option<[u8; BLOCK]>,
}

/// The bytes a usual port message (short names, a number) is written in at once.
const BLOCK: usize = 64;

impl PortTemplate {
    fn block(&self) -> Option<&[u8; BLOCK]> {
        self.block.as_ref()
    }
}

impl PortTemplates {
    /// Number of templates kept at most.
    pub const SLOTS: usize = 256;

    /// No template yet.
    pub fn new() -> Self {
        PortTemplates::default()
    }

    /// The template for `m`'s connection, made (and checked: the errors of
    /// [`DatagramWriter::push_port`]) if the slot holds none for it.
    #[inline(always)]
    fn get(&mut self, m: &PortMessage) -> Result<&PortTemplate, EncodeError> {
        let i = (m.conn.0 as usize) % PortTemplates::SLOTS;
        let hit = matches!(self.slots.get(i), Some(Some(t))
            if t.conn == m.conn
                && Arc::ptr_eq(&t.behavior, &m.behavior)
                && Arc::ptr_eq(&t.port, &m.port)
                && t.kind == m.kind
                && t.priority == m.priority);
        if !hit {
            self.make(i, m)?;
        }
        match self.slots.get(i) {
            Some(Some(t)) => Ok(t),
            _ => unreachable!("made just above"),
        }
    }

    #[cold]
    #[inline(never)]
    fn make(&mut self, i: usize, m: &PortMessage) -> Result<(), EncodeError> {
        let mut bytes = vec![kind::PORT, 0, 0];
        encode_port_head(&mut bytes, m)?;
        if self.slots.is_empty() {
            self.slots = vec![None; PortTemplates::SLOTS];
        }
        self.slots[i] = Some(PortTemplate {
            conn: m.conn,
            behavior: m.behavior.clone(),
            port: m.port.clone(),
            kind: m.kind,
            priority: m.priority,
            len: bytes.len(),
            block: (bytes.len() + 9 <= BLOCK).then(|| {
                let mut block = [0; BLOCK];
                block[..bytes.len()].copy_from_slice(&bytes);
                block
            }),
            bytes,
        });
        Ok(())
    }
}

pub(crate) fn put_request(buf: &mut Vec<u8>, body: &ControlBody) -> Result<(), EncodeError> {
    match body {
        ControlBody::Connect { source_behavior, source_port, destination, kind, priority } => {
            buf.push(op::CONNECT);
            put_str8(buf, source_behavior, NonEmpty::No)?;
            put_str8(buf, source_port, NonEmpty::No)?;
            put_endpoint(buf, destination)?;
            put_kind(buf, *kind)?;
            buf.extend_from_slice(&priority.to_le_bytes());
            Ok(())
        }
        ControlBody::Disconnect { conn } => {
            buf.push(op::DISCONNECT);
            buf.extend_from_slice(&conn.0.to_le_bytes());
            Ok(())
        }
        ControlBody::List => {
            buf.push(op::LIST);
            Ok(())
        }
        ControlBody::Why { behavior, port } => {
            buf.push(op::WHY);
            put_str8(buf, behavior, NonEmpty::No)?;
            put_str8(buf, port, NonEmpty::No)
        }
        ControlBody::Read { behavior, port } => {
            buf.push(op::READ);
            put_str8(buf, behavior, NonEmpty::No)?;
            put_str8(buf, port, NonEmpty::No)
        }
        ControlBody::Prepare { txn, changes, hold } => {
            buf.push(op::PREPARE);
            buf.extend_from_slice(&txn.to_le_bytes());
            buf.extend_from_slice(&hold.as_nanos().to_le_bytes());
            let n = u8::try_from(changes.len())
                .map_err(|_| EncodeError::Invalid("a PREPARE carries at most 255 changes"))?;
            buf.push(n);
            for c in changes {
                put_change(buf, c)?;
            }
            Ok(())
        }
        ControlBody::Commit { txn, delay } => {
            buf.push(op::COMMIT);
            buf.extend_from_slice(&txn.to_le_bytes());
            buf.extend_from_slice(&delay.as_nanos().to_le_bytes());
            Ok(())
        }
        ControlBody::Abort { txn } => {
            buf.push(op::ABORT);
            buf.extend_from_slice(&txn.to_le_bytes());
            Ok(())
        }
        ControlBody::Reply { .. } => {
            Err(EncodeError::Invalid("a reply is sent as REPLY parts (reply_messages), not as a REQUEST"))
        }
    }
}

/// One change of a PREPARE: its tag, then its fields (spec/protocol.md "PREPARE").
fn put_change(buf: &mut Vec<u8>, c: &Change) -> Result<(), EncodeError> {
    match c {
        Change::Create { class, name } => {
            buf.push(change_tag::CREATE);
            put_str8(buf, class, NonEmpty::Yes)?;
            put_str8(buf, name, NonEmpty::Yes)
        }
        Change::Remove { name } => {
            buf.push(change_tag::REMOVE);
            put_str8(buf, name, NonEmpty::Yes)
        }
        Change::Connect { source, destination, kind, priority } => {
            buf.push(change_tag::CONNECT);
            put_endpoint(buf, source)?;
            put_endpoint(buf, destination)?;
            put_kind(buf, *kind)?;
            buf.extend_from_slice(&priority.to_le_bytes());
            Ok(())
        }
        Change::Disconnect { conn } => {
            buf.push(change_tag::DISCONNECT);
            buf.extend_from_slice(&conn.0.to_le_bytes());
            Ok(())
        }
        Change::DisconnectBetween { source, destination } => {
            buf.push(change_tag::DISCONNECT_BETWEEN);
            put_endpoint(buf, source)?;
            put_endpoint(buf, destination)
        }
        Change::Join { group } => {
            buf.push(change_tag::JOIN);
            put_str8(buf, group, NonEmpty::Yes)
        }
        Change::Leave { group } => {
            buf.push(change_tag::LEAVE);
            put_str8(buf, group, NonEmpty::Yes)
        }
        Change::BleJoin { behavior, config } => {
            buf.push(change_tag::BLE_JOIN);
            put_str8(buf, behavior, NonEmpty::Yes)?;
            put_str8(buf, &config.group, NonEmpty::Yes)?;
            put_str8(buf, &config.output, NonEmpty::Yes)?;
            buf.extend_from_slice(&config.claim_rate_hz.to_bits().to_le_bytes());
            buf.extend_from_slice(&config.inhibit_period.as_nanos().to_le_bytes());
            buf.extend_from_slice(&config.network_delay.as_nanos().to_le_bytes());
            Ok(())
        }
    }
}

fn put_endpoint(buf: &mut Vec<u8>, e: &Endpoint) -> Result<(), EncodeError> {
    match e {
        Endpoint::Local { .. } => {
            Err(EncodeError::Invalid("a local endpoint is never sent: it means different things on each side"))
        }
        Endpoint::Node { node, behavior, port } => {
            buf.push(endpoint_tag::NODE);
            buf.extend_from_slice(&node.0.to_le_bytes());
            put_str8(buf, behavior, NonEmpty::No)?;
            put_str8(buf, port, NonEmpty::No)
        }
        Endpoint::Group { group, behavior, port } => {
            buf.push(endpoint_tag::GROUP);
            put_str8(buf, group, NonEmpty::Yes)?;
            put_str8(buf, behavior, NonEmpty::No)?;
            put_str8(buf, port, NonEmpty::No)
        }
    }
}

/// The connection kind byte and its period.
fn put_kind(buf: &mut Vec<u8>, kind: ayllu_core::ConnectionKind) -> Result<(), EncodeError> {
    let (code, period) = conn_kind_code(kind);
    if code != 0 && period == 0 {
        return Err(EncodeError::Invalid("a timed connection kind needs a period above zero"));
    }
    buf.push(code);
    buf.extend_from_slice(&period.to_le_bytes());
    Ok(())
}

#[inline]
fn put_value(buf: &mut Vec<u8>, v: &Value) -> Result<(), EncodeError> {
    match v {
        Value::Bool(b) => {
            buf.push(value_type::BOOL);
            buf.push(u8::from(*b));
        }
        Value::Int(i) => {
            buf.push(value_type::INT);
            buf.extend_from_slice(&i.to_le_bytes());
        }
        Value::Float(x) => {
            buf.push(value_type::FLOAT);
            // Bits, not the number: NaN payloads and -0.0 are preserved.
            buf.extend_from_slice(&x.to_bits().to_le_bytes());
        }
        Value::Text(s) => {
            buf.push(value_type::TEXT);
            put_str16(buf, s.as_bytes())?;
        }
        Value::Bytes(b) => {
            buf.push(value_type::BYTES);
            put_str16(buf, b)?;
        }
        Value::Vector(xs) => {
            buf.push(value_type::VECTOR);
            let n =
                u8::try_from(xs.len()).map_err(|_| EncodeError::Invalid("a vector value has at most 255 floats"))?;
            buf.push(n);
            for x in xs.iter() {
                buf.extend_from_slice(&x.to_bits().to_le_bytes());
            }
        }
    }
    Ok(())
}

#[derive(Copy, Clone, PartialEq, Eq)]
enum NonEmpty {
    Yes,
    No,
}

fn put_str8(buf: &mut Vec<u8>, s: &str, non_empty: NonEmpty) -> Result<(), EncodeError> {
    if non_empty == NonEmpty::Yes && s.is_empty() {
        return Err(EncodeError::Invalid("behavior, port and group names are not empty"));
    }
    let n = u8::try_from(s.len()).map_err(|_| EncodeError::Invalid("names are at most 255 bytes"))?;
    buf.push(n);
    buf.extend_from_slice(s.as_bytes());
    Ok(())
}

/// `str16` and `bytes16` share a layout; text is valid UTF-8 by construction (`&str`).
fn put_str16(buf: &mut Vec<u8>, b: &[u8]) -> Result<(), EncodeError> {
    let n = u16::try_from(b.len()).map_err(|_| EncodeError::Invalid("text and bytes are at most 65535 bytes"))?;
    buf.extend_from_slice(&n.to_le_bytes());
    buf.extend_from_slice(b);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use ayllu_core::{ConnectionId, ConnectionKind, Duration, PortMessage};

    fn port(value: Value) -> WireMessage {
        WireMessage::Port(PortMessage {
            conn: ConnectionId(1),
            seq: 1,
            behavior: "B".into(),
            port: "P".into(),
            kind: ConnectionKind::Normal,
            priority: 0,
            value,
        })
    }

    #[test]
    fn header_layout() {
        let w = DatagramWriter::new(0x0403_0201, NodeId(0x0807_0605), 0x100f_0e0d_0c0b_0a09, None, 100);
        assert_eq!(
            w.finish(),
            [0x41, 0x59, 1, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16],
            "magic, version, flags, team, sender, seq — all little-endian"
        );
    }

    #[test]
    fn refused_messages_leave_the_datagram_unchanged() {
        // A PORT with an int takes 45 bytes: one fits in 100, a second does not.
        let mut w = DatagramWriter::new(1, NodeId(1), 1, None, 100);
        w.push(&port(Value::Int(1))).unwrap();
        let before = w.clone().finish();
        assert!(matches!(w.push(&port(Value::Int(2))), Err(EncodeError::DoesNotFit { .. })));
        assert!(matches!(w.push(&port(Value::text(&"x".repeat(100)))), Err(EncodeError::TooLarge { .. })));
        let bad = WireMessage::Port(PortMessage {
            kind: ConnectionKind::Suppress(Duration::ZERO),
            ..match port(Value::Int(0)) {
                WireMessage::Port(p) => p,
                _ => unreachable!(),
            }
        });
        assert!(matches!(w.push(&bad), Err(EncodeError::Invalid(_))));
        assert!(matches!(w.push(&WireMessage::Unknown { code: 9, length: 0 }), Err(EncodeError::Invalid(_))));
        assert_eq!(w.message_count(), 1);
        assert_eq!(w.finish(), before);
    }

    #[test]
    fn push_port_refuses_what_push_refuses() {
        let WireMessage::Port(good) = port(Value::Int(1)) else { unreachable!() };
        let no_behavior = PortMessage { behavior: "".into(), ..good.clone() };
        let no_port = PortMessage { port: "".into(), ..good.clone() };
        let no_period = PortMessage { kind: ConnectionKind::Suppress(Duration::ZERO), ..good.clone() };
        let long_name = PortMessage { port: "p".repeat(256).into(), ..good.clone() };
        let mut w = DatagramWriter::new(7, NodeId(1), 1, None, 1472);
        let mut v = w.clone();
        for (m, group) in [
            (&no_behavior, None),
            (&no_port, None),
            (&no_period, None),
            (&long_name, None),
            (&good, Some("")),
            (&good, Some(&*"g".repeat(256))),
        ] {
            let wire = match group {
                Some(g) => WireMessage::GroupPort { group: g.into(), message: m.clone() },
                None => WireMessage::Port(m.clone()),
            };
            let (a, b) = (w.push(&wire), v.push_port(m, group));
            assert!(matches!(a, Err(EncodeError::Invalid(_))), "{a:?}");
            assert_eq!(a, b);
        }
        assert!(v.is_empty());
        assert_eq!(w.finish(), v.finish());
    }

    #[test]
    fn mtu_is_clamped_and_respected() {
        let mut w = DatagramWriter::new(1, NodeId(1), 1, Some([7; 32]), 100_000);
        assert_eq!(w.remaining(), MAX_DATAGRAM_LEN - MAC_LEN - HEADER_LEN);
        while w.push(&port(Value::Int(1))).is_ok() {}
        assert!(w.finish().len() <= MAX_DATAGRAM_LEN);
        let w = DatagramWriter::new(1, NodeId(1), 1, Some([7; 32]), 0);
        assert_eq!(w.remaining(), 0);
        assert_eq!(w.finish().len(), HEADER_LEN + MAC_LEN);
    }

    #[test]
    fn body_length_limit() {
        let mut w = DatagramWriter::new(1, NodeId(1), 1, None, MAX_DATAGRAM_LEN);
        let err = w.push(&port(Value::bytes(&[0; 70_000]))).unwrap_err();
        assert_eq!(err, EncodeError::Invalid("text and bytes are at most 65535 bytes"));
    }
}
