//! Replies that do not fit one datagram: cutting a report into REPLY parts, and putting it back
//! together.
//!
//! A report (the JSON form of a `NodeReport` or `PortReport`) can be larger than a datagram.
//! [`reply_messages`] cuts it into at most 64 UTF-8 slices, each sized to fill one datagram
//! at the given MTU; every other answer is a single part. [`ReplyAssembler`] collects the parts
//! of one answer in any order, ignores repeats (the requester may ask again and get the answer
//! repeated from memory), and is bounded: it never holds more than its byte limit, however
//! many or large the parts a peer sends.

use core::fmt;

use ayllu_core::introspect::{NodeReport, PortReport};
use ayllu_core::ReplyBody;

use crate::encode::EncodeError;
use crate::message::{ReplyPart, WireMessage};
use crate::{HEADER_LEN, MAC_LEN, MAX_DATAGRAM_LEN, MAX_REPLY_PARTS, MESSAGE_HEADER_LEN};

/// REPLY fields before a report slice: id u64, status u8, part u16, parts u16, result u8,
/// slice length u16.
const REPORT_PART_OVERHEAD: usize = 8 + 1 + 2 + 2 + 1 + 2;

/// The largest report slice (or error text) one REPLY can carry in a datagram of `mtu` bytes
/// (clamped as [`crate::DatagramWriter::new`] does), with a MAC when `auth`.
pub fn report_slice_capacity(mtu: usize, auth: bool) -> usize {
    let mac = if auth { MAC_LEN } else { 0 };
    let mtu = mtu.clamp(HEADER_LEN + mac, MAX_DATAGRAM_LEN);
    mtu.saturating_sub(HEADER_LEN + mac + MESSAGE_HEADER_LEN + REPORT_PART_OVERHEAD)
}

/// The REPLY messages answering request `id` with `result`, each of which fits a datagram of
/// `mtu` bytes on its own (with a MAC when `auth`):
/// * a `NodeReport` or `PortReport` as its JSON, cut at UTF-8 character boundaries into as
///   few slices as fit (at most 64, else [`EncodeError::ReportTooLarge`]);
/// * an error as one part, its text shortened (at a character boundary) to fit, since a
///   shortened reason is more use to the requester than none;
/// * a connection or a value as one part (a value too large for the MTU is refused when it is
///   pushed into a [`crate::DatagramWriter`]).
pub fn reply_messages(
    id: u64,
    result: &Result<ReplyBody, String>,
    mtu: usize,
    auth: bool,
) -> Result<Vec<WireMessage>, EncodeError> {
    let capacity = report_slice_capacity(mtu, auth);
    let single = |payload| vec![WireMessage::Reply { id, part: 0, parts: 1, payload }];
    let json = match result {
        Err(message) => return Ok(single(ReplyPart::Error(prefix(message, capacity).to_owned()))),
        Ok(ReplyBody::Connection(c)) => return Ok(single(ReplyPart::Connection(*c))),
        Ok(ReplyBody::Value(v)) => return Ok(single(ReplyPart::Value(v.clone()))),
        Ok(ReplyBody::Node(r)) => serde_json::to_string(r),
        Ok(ReplyBody::Port(r)) => serde_json::to_string(r),
        Ok(ReplyBody::OtherReport(json)) => Ok(json.clone()),
    };
    // Serializing plain report structs to a String cannot fail (no maps with non-string keys,
    // no I/O); should it ever, say so rather than panic.
    let json = json.map_err(|_| EncodeError::Invalid("report could not be serialized as JSON"))?;
    let too_large = EncodeError::ReportTooLarge { bytes: json.len(), max_parts: MAX_REPLY_PARTS };
    let mut slices = Vec::new();
    let mut rest = json.as_str();
    while !rest.is_empty() {
        let slice = prefix(rest, capacity);
        // A capacity under 4 bytes may not hold even one character: no progress is possible.
        if slice.is_empty() || slices.len() == usize::from(MAX_REPLY_PARTS) {
            return Err(too_large);
        }
        slices.push(slice);
        rest = &rest[slice.len()..];
    }
    if slices.is_empty() {
        slices.push("");
    }
    let parts = slices.len() as u16; // at most 64
    Ok(slices
        .into_iter()
        .enumerate()
        .map(|(i, s)| WireMessage::Reply { id, part: i as u16, parts, payload: ReplyPart::Report(s.to_owned()) })
        .collect())
}

/// The longest prefix of `s` of at most `max` bytes that ends on a character boundary.
fn prefix(s: &str, max: usize) -> &str {
    if s.len() <= max {
        return s;
    }
    let mut end = max;
    while !s.is_char_boundary(end) {
        end -= 1;
    }
    &s[..end]
}

/// Why a reply could not be assembled. The requester should treat the request as failed (or
/// ask again): the parts it received do not make an answer.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum AssembleError {
    /// A part out of range, or parts that disagree on how many there are or on what they
    /// carry.
    Inconsistent,
    /// The parts together exceed the assembler's byte limit.
    TooLarge {
        /// The assembler's limit, in bytes.
        limit: usize,
    },
    /// The slices concatenated are not the JSON of a `NodeReport` or `PortReport`.
    BadReport(String),
}

impl fmt::Display for AssembleError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AssembleError::Inconsistent => f.write_str("reply parts disagree"),
            AssembleError::TooLarge { limit } => write!(f, "reply exceeds {limit} bytes"),
            AssembleError::BadReport(why) => write!(f, "report is not valid: {why}"),
        }
    }
}

impl std::error::Error for AssembleError {}

/// Collects the REPLY parts of the answer to one request and rebuilds the core's result.
#[derive(Clone, Debug)]
pub struct ReplyAssembler {
    limit: usize,
    /// One slot per part once the first report part told how many there are.
    slices: Vec<Option<String>>,
    bytes: usize,
    done: bool,
}

impl Default for ReplyAssembler {
    fn default() -> Self {
        ReplyAssembler::new()
    }
}

impl ReplyAssembler {
    /// The default byte limit: 64 parts of the largest datagram a receiver accepts. No honest
    /// reply is larger.
    pub const DEFAULT_LIMIT: usize = MAX_REPLY_PARTS as usize * MAX_DATAGRAM_LEN;

    /// An assembler with [`ReplyAssembler::DEFAULT_LIMIT`].
    pub fn new() -> Self {
        ReplyAssembler::with_limit(Self::DEFAULT_LIMIT)
    }

    /// An assembler that refuses replies larger than `limit` bytes of report text.
    pub fn with_limit(limit: usize) -> Self {
        ReplyAssembler { limit, slices: Vec::new(), bytes: 0, done: false }
    }

    /// Bytes of report text held so far (to bound what all assemblies together hold).
    pub fn bytes(&self) -> usize {
        self.bytes
    }

    /// True once a complete reply was returned by [`ReplyAssembler::push`].
    pub fn is_done(&self) -> bool {
        self.done
    }

    /// The parts still missing of a multi-part report (empty before the first part arrives).
    pub fn missing(&self) -> impl Iterator<Item = u16> + '_ {
        self.slices.iter().enumerate().filter(|(_, s)| s.is_none()).map(|(i, _)| i as u16)
    }

    /// Add part `part` of `parts`. Returns the request's result once every part is in
    /// (`Err(text)` for an error reply), `None` while parts are missing. Repeated parts, and
    /// parts after the answer was complete, are ignored.
    #[allow(clippy::type_complexity)]
    pub fn push(
        &mut self,
        part: u16,
        parts: u16,
        payload: ReplyPart,
    ) -> Result<Option<Result<ReplyBody, String>>, AssembleError> {
        if self.done {
            return Ok(None);
        }
        if parts == 0 || parts > MAX_REPLY_PARTS || part >= parts {
            return Err(AssembleError::Inconsistent);
        }
        let single = match payload {
            ReplyPart::Report(slice) => return self.push_slice(part, parts, slice),
            ReplyPart::Error(message) => Err(message),
            ReplyPart::Connection(c) => Ok(ReplyBody::Connection(c)),
            ReplyPart::Value(v) => Ok(ReplyBody::Value(v)),
        };
        // Only reports come in parts; anything else alone is the whole answer.
        if parts != 1 || !self.slices.is_empty() {
            return Err(AssembleError::Inconsistent);
        }
        self.done = true;
        Ok(Some(single))
    }

    #[allow(clippy::type_complexity)]
    fn push_slice(
        &mut self,
        part: u16,
        parts: u16,
        slice: String,
    ) -> Result<Option<Result<ReplyBody, String>>, AssembleError> {
        if self.slices.is_empty() {
            self.slices = vec![None; usize::from(parts)];
        } else if self.slices.len() != usize::from(parts) {
            return Err(AssembleError::Inconsistent);
        }
        let slot = &mut self.slices[usize::from(part)];
        if slot.is_some() {
            return Ok(None);
        }
        self.bytes = self.bytes.saturating_add(slice.len());
        if self.bytes > self.limit {
            return Err(AssembleError::TooLarge { limit: self.limit });
        }
        *slot = Some(slice);
        if self.slices.iter().any(Option::is_none) {
            return Ok(None);
        }
        let json: String = self.slices.iter().flatten().map(String::as_str).collect();
        self.done = true;
        self.slices = Vec::new();
        parse_report(&json).map(|body| Some(Ok(body)))
    }
}

/// A report's JSON as the core's reply. The two report shapes are disjoint (a `NodeReport`
/// has `groups` and `behaviors`, a `PortReport` has `behavior` and `port`, each required), so
/// trying one and then the other cannot confuse them. Any other JSON object (an AylluLite
/// node's LIST) is kept as text, [`ReplyBody::OtherReport`]; text that is not a JSON object is
/// refused.
fn parse_report(json: &str) -> Result<ReplyBody, AssembleError> {
    if let Ok(node) = serde_json::from_str::<NodeReport>(json) {
        return Ok(ReplyBody::Node(Box::new(node)));
    }
    match serde_json::from_str::<PortReport>(json) {
        Ok(port) => Ok(ReplyBody::Port(Box::new(port))),
        Err(e) => match serde_json::from_str::<serde_json::Value>(json) {
            Ok(serde_json::Value::Object(_)) => Ok(ReplyBody::OtherReport(json.to_owned())),
            _ => Err(AssembleError::BadReport(e.to_string())),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ayllu_core::{BehaviorClass, ConnectionId, NodeCore, NodeId, PortSpec, Value};

    fn node() -> NodeCore {
        let mut node = NodeCore::new(NodeId(3));
        let mut class = BehaviorClass::new("Observer");
        class.port(PortSpec::new("Rotate", 0.5)).unwrap();
        class.port(PortSpec::new("Label", "ünïcødé ✓")).unwrap();
        node.define(class).unwrap();
        for i in 0..12 {
            node.create("Observer", &format!("OBS{i}")).unwrap();
        }
        node
    }

    fn assemble(messages: Vec<WireMessage>) -> Result<ReplyBody, String> {
        let mut a = ReplyAssembler::new();
        let mut out = None;
        // Reverse order and a repeat: order and duplicates must not matter.
        let first = messages[0].clone();
        for m in messages.into_iter().rev().chain([first]) {
            let WireMessage::Reply { part, parts, payload, .. } = m else { panic!("not a reply") };
            if let Some(r) = a.push(part, parts, payload).unwrap() {
                assert!(out.is_none());
                out = Some(r);
            }
        }
        out.expect("complete")
    }

    #[test]
    fn node_report_round_trips_in_parts() {
        let report = node().report();
        let result = Ok(ReplyBody::Node(Box::new(report)));
        for (mtu, auth) in [(1472, false), (1472, true), (200, true), (8192, false)] {
            let msgs = reply_messages(9, &result, mtu, auth).unwrap();
            assert!(msgs.len() <= 64);
            for m in &msgs {
                let mut w = crate::DatagramWriter::new(1, NodeId(1), 1, auth.then_some([0; 32]), mtu);
                w.push(m).unwrap();
            }
            if mtu == 200 {
                assert!(msgs.len() > 2, "a small MTU needs several parts");
            }
            assert_eq!(assemble(msgs), result);
        }
    }

    #[test]
    fn port_report_round_trips() {
        let result = Ok(ReplyBody::Port(Box::new(node().why("OBS1", "Label").unwrap())));
        assert_eq!(assemble(reply_messages(2, &result, 100, false).unwrap()), result);
    }

    #[test]
    fn too_many_parts() {
        let result = Ok(ReplyBody::Node(Box::new(node().report())));
        assert!(matches!(reply_messages(1, &result, 60, false), Err(EncodeError::ReportTooLarge { .. })));
        assert!(matches!(reply_messages(1, &result, 0, false), Err(EncodeError::ReportTooLarge { .. })));
    }

    #[test]
    fn single_part_answers() {
        let long = "é".repeat(5000);
        let msgs = reply_messages(4, &Err(long), 1472, true).unwrap();
        let WireMessage::Reply { payload: ReplyPart::Error(e), .. } = &msgs[0] else { panic!() };
        assert_eq!(e.len(), report_slice_capacity(1472, true) / 2 * 2);
        let mut w = crate::DatagramWriter::new(1, NodeId(1), 1, Some([0; 32]), 1472);
        w.push(&msgs[0]).unwrap();
        assert_eq!(
            assemble(reply_messages(4, &Ok(ReplyBody::Connection(ConnectionId(8))), 1472, false).unwrap()),
            Ok(ReplyBody::Connection(ConnectionId(8)))
        );
        assert_eq!(
            assemble(reply_messages(4, &Ok(ReplyBody::Value(Value::Int(-1))), 1472, false).unwrap()),
            Ok(ReplyBody::Value(Value::Int(-1)))
        );
        assert_eq!(assemble(reply_messages(4, &Err("no".into()), 1472, false).unwrap()), Err("no".into()));
    }

    #[test]
    fn a_lite_nodes_list_is_kept_as_another_report() {
        // An AylluLite node answers LIST with its own small object (spec/protocol.md).
        let lite = r#"{"node":77,"lite":true,"behaviors":[{"name":"Drive","ports":["Speed"]}]}"#;
        let mut a = ReplyAssembler::new();
        assert_eq!(a.push(0, 1, ReplyPart::Report(lite.into())), Ok(Some(Ok(ReplyBody::OtherReport(lite.to_owned())))));
        // And it goes out again as it came.
        let parts = reply_messages(9, &Ok(ReplyBody::OtherReport(lite.to_owned())), 1472, false).unwrap();
        assert_eq!(assemble(parts), Ok(ReplyBody::OtherReport(lite.to_owned())));
    }

    #[test]
    fn assembler_refuses_inconsistent_and_oversized_input() {
        let mut a = ReplyAssembler::new();
        assert_eq!(a.push(0, 0, ReplyPart::Report("x".into())), Err(AssembleError::Inconsistent));
        assert_eq!(a.push(3, 3, ReplyPart::Report("x".into())), Err(AssembleError::Inconsistent));
        assert_eq!(a.push(0, 3, ReplyPart::Report("[".into())), Ok(None));
        assert_eq!(a.missing().collect::<Vec<_>>(), vec![1, 2]);
        assert_eq!(a.push(1, 4, ReplyPart::Report("x".into())), Err(AssembleError::Inconsistent));
        assert_eq!(a.push(1, 3, ReplyPart::Error("x".into())), Err(AssembleError::Inconsistent));
        assert_eq!(a.push(1, 3, ReplyPart::Report("]".into())), Ok(None));
        // JSON, but not an object: no report of any shape.
        assert!(matches!(a.push(2, 3, ReplyPart::Report(" ".into())), Err(AssembleError::BadReport(_))));

        let mut a = ReplyAssembler::with_limit(10);
        assert_eq!(a.push(0, 2, ReplyPart::Report("0123456".into())), Ok(None));
        assert_eq!(a.push(1, 2, ReplyPart::Report("0123456".into())), Err(AssembleError::TooLarge { limit: 10 }));
    }
}
