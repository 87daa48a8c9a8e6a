//! What one message of a datagram says, as a value: [`WireMessage`].
//!
//! The core's messages ([`PortMessage`], [`ControlBody`]) are carried as they are; the wire adds
//! only what exists on the wire alone: HELLO, requests with an operation this node does not
//! know, REPLY parts (a report may span up to 64 datagrams) and skipped messages of unknown
//! kinds. Converting a core [`Message`] is [`WireMessage::from_core`]; the code tables shared by
//! encoder and decoder live here so that the two cannot disagree.

use std::sync::Arc;

use ayllu_core::{ConnectionId, ConnectionKind, ControlBody, Duration, Message, PortMessage, Value};

use crate::encode::EncodeError;
use crate::COOKIE_LEN;

/// One message of a datagram.
#[derive(Clone, Debug, PartialEq)]
pub enum WireMessage {
    /// PORT (0x01): a value travelling along a connection to one node.
    Port(PortMessage),
    /// PORT (0x01) sent to a group: the value and the group's name (the optional `group` field,
    /// appended). A node that has not joined `group` drops it (`not_member`, D-S10.6): a
    /// broadcast or a team-wide key reaches non-members too. Decoded from a PORT whose group
    /// field is present and non-empty; encoded with it.
    GroupPort {
        /// The group the message was sent to (non-empty, at most 255 bytes).
        group: Arc<str>,
        /// The value and where it goes on each member.
        message: PortMessage,
    },
    /// HELLO (0x02): liveness announcement and the sender's broadcast groups.
    Hello {
        /// How often the sender announces itself, in milliseconds (> 0); it is forgotten after
        /// three silent intervals (N6).
        interval_ms: u32,
        /// A human name for tools (`robot-1`); may be empty.
        name: Arc<str>,
        /// The broadcast groups the sender has joined, so group messages can be unicast to it
        /// where broadcast does not reach (D-S10.1).
        groups: Vec<Arc<str>>,
    },
    /// REQUEST (0x10) with a known operation. `body` is never [`ControlBody::Reply`], and a
    /// `Connect` destination is never [`ayllu_core::Endpoint::Local`].
    Request {
        /// Chosen by the requester, unique among its requests; repeats reuse it (N2).
        id: u64,
        /// What is asked.
        body: ControlBody,
        /// The operator's signature of this request ([`crate::operator`]), sent after the
        /// arguments; receivers that require none ignore it.
        signature: Option<crate::operator::OperatorSignature>,
    },
    /// REQUEST with an operation code this implementation does not know. The receiver answers
    /// it with an error REPLY (`unknown operation`) rather than dropping it, so that tools can
    /// tell an old node from a lost request. Its arguments, if any, are not kept.
    UnknownRequest {
        /// The request's id, for the error reply.
        id: u64,
        /// The operation code this implementation does not know.
        op: u8,
    },
    /// REPLY (0x11): part `part` of `parts` of the answer to request `id`.
    Reply {
        /// The id of the request this answers.
        id: u64,
        /// This part's index, 0-based, below `parts`.
        part: u16,
        /// How many parts the answer has (1 to [`crate::MAX_REPLY_PARTS`]; 1 unless a report).
        parts: u16,
        /// What this part carries.
        payload: ReplyPart,
    },
    /// CHALLENGE (0x12): "echo this cookie to prove you receive at the address you send
    /// from". Sent, instead of an answer too large for it, to a requester whose address is
    /// not proven (no amplification, `spec/protocol.md` "Return routability").
    Challenge {
        /// Opaque to the requester; only its sender can check it.
        cookie: [u8; COOKIE_LEN],
    },
    /// ECHO (0x13): the answer to a CHALLENGE, the cookie sent back unchanged.
    Echo {
        /// The cookie the CHALLENGE carried.
        cookie: [u8; COOKIE_LEN],
    },
    /// A message of an unknown kind, skipped using its length. Decode-only: it is reported so
    /// the receiver can count it (`unknown_kind`); the encoder refuses it (it has no body).
    Unknown {
        /// The unknown kind byte.
        code: u8,
        /// The length of the body that was skipped, in bytes.
        length: u16,
    },
}

/// What one REPLY part carries.
#[derive(Clone, Debug, PartialEq)]
pub enum ReplyPart {
    /// Status 1: why the request failed.
    Error(String),
    /// Result 1 (CONNECT, DISCONNECT).
    Connection(ConnectionId),
    /// Result 2 (READ).
    Value(Value),
    /// Result 3 (LIST, WHY): one UTF-8 slice of the JSON form of a `NodeReport` or
    /// `PortReport`; the slices of all parts, concatenated in part order, are the document.
    Report(String),
}

impl WireMessage {
    /// The kind byte this message is sent under.
    pub fn kind_code(&self) -> u8 {
        match self {
            WireMessage::Port(_) | WireMessage::GroupPort { .. } => crate::kind::PORT,
            WireMessage::Hello { .. } => crate::kind::HELLO,
            WireMessage::Request { .. } | WireMessage::UnknownRequest { .. } => crate::kind::REQUEST,
            WireMessage::Reply { .. } => crate::kind::REPLY,
            WireMessage::Challenge { .. } => crate::kind::CHALLENGE,
            WireMessage::Echo { .. } => crate::kind::ECHO,
            WireMessage::Unknown { code, .. } => *code,
        }
    }

    /// The wire messages that carry a core message: one for a port message or a request; for a
    /// reply, as many REPLY parts as its report needs to fit datagrams of `mtu` bytes (with
    /// room for a MAC when `auth`), see [`crate::reply_messages`].
    pub fn from_core(message: &Message, mtu: usize, auth: bool) -> Result<Vec<WireMessage>, EncodeError> {
        match message {
            Message::Port(p) => Ok(vec![WireMessage::Port(p.clone())]),
            Message::Control(c) => match &c.body {
                ControlBody::Reply { result } => crate::reply::reply_messages(c.id, result, mtu, auth),
                body => Ok(vec![WireMessage::Request { id: c.id, body: body.clone(), signature: None }]),
            },
        }
    }
}

/// Connection kind codes, in the order of the PORT `kind` field.
pub(crate) fn conn_kind_code(kind: ConnectionKind) -> (u8, u64) {
    let code = match kind {
        ConnectionKind::Normal => 0,
        ConnectionKind::Suppress(_) => 1,
        ConnectionKind::Inhibit(_) => 2,
        ConnectionKind::OverrideIn(_) => 3,
        ConnectionKind::OverrideOut(_) => 4,
        ConnectionKind::WriteInhibit(_) => 5,
    };
    (code, kind.period().map_or(0, Duration::as_nanos))
}

/// The connection kind for a `kind` byte and `period`, or `None` if the pair is malformed: an
/// unknown code, a Normal with a period, or a timed kind without one (a zero window would
/// mean "do nothing", which no sender intends and the core refuses to create).
pub(crate) fn conn_kind_from(code: u8, period: u64) -> Option<ConnectionKind> {
    let p = Duration::from_nanos(period);
    let kind = match code {
        0 => ConnectionKind::Normal,
        1 => ConnectionKind::Suppress(p),
        2 => ConnectionKind::Inhibit(p),
        3 => ConnectionKind::OverrideIn(p),
        4 => ConnectionKind::OverrideOut(p),
        5 => ConnectionKind::WriteInhibit(p),
        _ => return None,
    };
    let valid = match kind {
        ConnectionKind::Normal => period == 0,
        _ => period != 0,
    };
    valid.then_some(kind)
}

/// Value type codes.
pub(crate) mod value_type {
    pub const BOOL: u8 = 0;
    pub const INT: u8 = 1;
    pub const FLOAT: u8 = 2;
    pub const TEXT: u8 = 3;
    pub const BYTES: u8 = 4;
    pub const VECTOR: u8 = 5;
}

/// REPLY status and result codes.
pub(crate) mod reply_code {
    pub const STATUS_OK: u8 = 0;
    pub const STATUS_ERROR: u8 = 1;
    pub const RESULT_CONNECTION: u8 = 1;
    pub const RESULT_VALUE: u8 = 2;
    pub const RESULT_REPORT: u8 = 3;
}

/// Endpoint tags (0, "local", is never sent).
pub(crate) mod endpoint_tag {
    pub const NODE: u8 = 1;
    pub const GROUP: u8 = 2;
}
