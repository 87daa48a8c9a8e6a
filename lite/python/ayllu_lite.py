"""AylluLite for Python: a one-file client of the Ayllu wire protocol, version 1.

What it is for: letting a program that is not an Ayllu node (a planner, a vision process, a
test harness, a joystick) take part in an Ayllu team -- the paper's "AylluLite" (Werger,
*Ayllu*, section 3): expose ports that Ayllu nodes write, write Ayllu nodes' ports with any
connection kind, and ask nodes to connect, read, explain (WHY) and list.

What it promises:

* Bytes on the wire follow ``spec/protocol.md`` exactly; ``decode`` drops what the spec drops,
  with the spec's cause names (``Dropped.cause``), and ``encode`` refuses (``EncodeError``) what
  a decoder would drop, so nothing this module sends is malformed.
* Python 3.11 standard library only; this file can be copied on its own into any program.
* Lite ports are plain registers (Normal ports): they have no aggregation, no priority and no
  outgoing connections, so inhibition, override-out and write-inhibition (which only stop
  *propagation*) have nothing to act on. The windows that decide *storing* are honoured as
  ``docs/semantics.md`` S6 says: a suppress window blocks every connection write, and open
  override-in windows admit only their holders. Suppress, inhibit and write-inhibit messages
  never write the value.
* With a team key every datagram sent is authenticated, and every datagram received must carry
  a valid MAC and a sequence number not seen before (replay window of 64 per sender).
* Return routability (spec, "CHALLENGE and ECHO"): every CHALLENGE received is answered at once
  with an ECHO of its cookie, to the address it came from, and the requests waiting on that
  address are sent again then (once each), so a node that limits what it sends to unproven
  addresses answers them in full; retries go on as before. The lite node's own answers (READ,
  LIST, error replies) are single datagrams held to the spec's 3x rule: the bytes answered to
  an address are at most 3 times the bytes received from it (a table of
  :data:`BUDGET_TABLE_MAX` addresses). It sends no CHALLENGE, so an answer over the budget is
  not sent (``counters["amplification_limited"]``) and goes out at a later retry of the request,
  once the retries have brought the budget up to it (see lite/README.md).
* Operator signatures: with ``operator_secret`` (or ``operator_secret=FILE`` in the URL) every
  CONNECT and DISCONNECT is signed (Ed25519, RFC 8032, computed here with the standard library)
  for its receiving node, as nodes started with ``operator=`` require.
"""

from __future__ import annotations

import dataclasses
import enum
import hashlib
import hmac
import ipaddress
import json
import math
import os
import select
import socket
import struct
import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

__all__ = [
    "AMPLIFICATION_FACTOR",
    "AUTH",
    "BUDGET_TABLE_MAX",
    "CONN_KINDS",
    "COOKIE_LEN",
    "DEFAULT_URL",
    "HEADER_LEN",
    "MAC_LEN",
    "MAX_DATAGRAM",
    "MTU",
    "SIGNATURE_LEN",
    "Challenge",
    "ConnKind",
    "Connection",
    "Datagram",
    "Dropped",
    "Echo",
    "EncodeError",
    "Endpoint",
    "Hello",
    "LiteNode",
    "Message",
    "Op",
    "Port",
    "ReplayWindow",
    "Reply",
    "Request",
    "RequestFailed",
    "RequestTimeout",
    "Unknown",
    "Value",
    "Vector",
    "decode",
    "default_url",
    "encode",
    "encode_message",
    "is_nan",
    "key_from_hex",
    "mac",
    "message_from_json",
    "message_to_json",
    "operator_public_key",
    "parse_url",
    "random_key",
    "read_operator_secret",
    "sign_request",
    "signed_request_bytes",
    "value_from_json",
    "value_to_json",
]

# ---------------------------------------------------------------------------------------------
# Constants from spec/protocol.md
# ---------------------------------------------------------------------------------------------

MAGIC = b"AY"
VERSION = 1
AUTH = 0x01
HEADER_LEN = 20
MAC_LEN = 16
MAX_DATAGRAM = 8192
MTU = 1472

KIND_PORT = 0x01
KIND_HELLO = 0x02
KIND_REQUEST = 0x10
KIND_REPLY = 0x11
KIND_CHALLENGE = 0x12
KIND_ECHO = 0x13

#: Bytes of a CHALLENGE / ECHO cookie.
COOKIE_LEN = 16
#: Bytes of an operator signature, and the tag byte that introduces one after a REQUEST's
#: arguments (spec, "Operator signature").
SIGNATURE_LEN = 64
SIGNATURE_TAG = 1
_SIGNED_CONTEXT = b"ayllu operator request v1\0"

_VT_BOOL, _VT_INT, _VT_FLOAT, _VT_TEXT, _VT_BYTES, _VT_VECTOR = range(6)
_EP_NODE, _EP_GROUP = 1, 2
_RESULT_CONNECTION, _RESULT_VALUE, _RESULT_REPORT = 1, 2, 3
MAX_PARTS = 64

#: How often an unanswered request is sent again, and how many sends at most (N2).
RETRY_INTERVAL_S = 0.2
RETRY_LIMIT = 25
#: How many answered requests a node remembers (spec); the lite node answers only reads.
_ANSWERED_MAX = 1024
#: Bounded memory for the per-(sender, connection) newest sequence numbers (N1).
_SEQ_TABLE_MAX = 16384
#: Return routability (spec, "CHALLENGE and ECHO"): the bytes a node answers an address with are
#: at most this many times the bytes it received from it.
AMPLIFICATION_FACTOR = 3
#: Addresses whose answer budget a :class:`LiteNode` remembers; beyond it the least recently
#: heard is replaced (and starts over from nothing if it comes back, so nothing exceeds 3x).
BUDGET_TABLE_MAX = 256

#: The longest HELLO period a peer is believed (ms), as the Rust node's (60 s).
MAX_PEER_INTERVAL_MS = 60_000

#: The most nodes remembered as heard; past it the one heard longest ago is forgotten
#: (counted ``peer_evicted``), as the Rust node's peer table is bounded (1,024).
MAX_HEARD = 1024

_I64_MIN, _I64_MAX = -(1 << 63), (1 << 63) - 1
_I32_MIN, _I32_MAX = -(1 << 31), (1 << 31) - 1
_U64_MAX = (1 << 64) - 1


class ConnKind(enum.IntEnum):
    """The connection kinds of ``docs/semantics.md`` S6, with their wire codes."""

    NORMAL = 0
    SUPPRESS = 1
    INHIBIT = 2
    OVERRIDE_IN = 3
    OVERRIDE_OUT = 4
    WRITE_INHIBIT = 5

    @property
    def wire_name(self) -> str:
        """The name used in the golden vectors (``override-in``)."""
        return self.name.lower().replace("_", "-")

    @classmethod
    def from_name(cls, name: str) -> ConnKind:
        """Parse a wire name (``override-in``) or a Python name (``OVERRIDE_IN``)."""
        return cls[name.upper().replace("-", "_")]


CONN_KINDS: tuple[ConnKind, ...] = tuple(ConnKind)


class Op(enum.IntEnum):
    """REQUEST operations."""

    CONNECT = 1
    DISCONNECT = 2
    LIST = 3
    WHY = 4
    READ = 5


_OPS = frozenset(Op)


class Vector(tuple[float, ...]):
    """A float vector value. A plain tuple or list of floats is also accepted when sending."""

    __slots__ = ()


#: A port value: bool, int (i64), float (f64), text, bytes, or a float vector.
Value = bool | int | float | str | bytes | Vector


class Dropped(Exception):
    """A datagram (or message) that is not applied, with its drop cause from the spec (N4)."""

    def __init__(self, cause: str, detail: str = "") -> None:
        super().__init__(f"{cause}: {detail}" if detail else cause)
        self.cause = cause
        self.detail = detail


class EncodeError(ValueError):
    """A message that a conforming decoder would drop, refused before it is sent."""


class RequestTimeout(TimeoutError):
    """No complete answer after every retry (N2)."""


class RequestFailed(RuntimeError):
    """The node answered the request with an error REPLY; the message says why."""


# ---------------------------------------------------------------------------------------------
# Messages
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Endpoint:
    """A CONNECT destination: exactly one of ``node`` or ``group`` is set."""

    behavior: str
    port: str
    node: int | None = None
    group: str | None = None


@dataclass(frozen=True)
class Port:
    """PORT: a value travelling along a connection (``period_ns`` is 0 only for NORMAL).

    ``group`` is the group the message was sent to, or None for a message to a node; a node
    that has not joined it drops the message (``not_member``, docs/semantics.md D-S10.6)."""

    conn: int
    seq: int
    conn_kind: ConnKind
    period_ns: int
    priority: int
    behavior: str
    port: str
    value: Value
    group: str | None = None


@dataclass(frozen=True)
class Hello:
    """HELLO: liveness announcement, with the broadcast groups the sender has joined (so a
    node can deliver a group's messages by unicast where broadcast is unavailable)."""

    interval_ms: int
    name: str = ""
    groups: tuple[str, ...] = ()


@dataclass(frozen=True)
class Request:
    """REQUEST. ``op`` is an :class:`Op` or, when decoded, any other operation code.

    CONNECT uses ``src_behavior``, ``src_port``, ``destination``, ``conn_kind``, ``period_ns``
    and ``priority``; DISCONNECT uses ``conn``; WHY and READ use ``behavior`` and ``port``.
    ``signature`` is the operator's Ed25519 signature (64 bytes, sent after the arguments), or
    None; see :func:`sign_request`. Requests of unknown operations carry none.
    """

    id: int
    op: int
    src_behavior: str = ""
    src_port: str = ""
    destination: Endpoint | None = None
    conn_kind: ConnKind = ConnKind.NORMAL
    period_ns: int = 0
    priority: int = 0
    conn: int = 0
    behavior: str = ""
    port: str = ""
    signature: bytes | None = None


@dataclass(frozen=True)
class Reply:
    """REPLY: exactly one of ``error``, ``conn``, ``value``, ``report`` is set."""

    id: int
    part: int = 0
    parts: int = 1
    error: str | None = None
    conn: int | None = None
    value: Value | None = None
    report: str | None = None

    @property
    def ok(self) -> bool:
        return self.error is None


@dataclass(frozen=True)
class Unknown:
    """A message of a kind this decoder does not know: skipped and counted (``unknown_kind``)."""

    code: int
    length: int


@dataclass(frozen=True)
class Challenge:
    """CHALLENGE: "echo this cookie". A node sends it instead of an answer too large for an
    address it has not proven (return routability), and with the HELLO that greets a new peer.
    :class:`LiteNode` answers every one with an :class:`Echo` of the same cookie."""

    cookie: bytes


@dataclass(frozen=True)
class Echo:
    """ECHO: a CHALLENGE's cookie (16 bytes) sent back unchanged."""

    cookie: bytes


Message = Port | Hello | Request | Reply | Challenge | Echo | Unknown


@dataclass(frozen=True)
class Datagram:
    """A decoded datagram: who sent it, its sequence number, and its messages in order."""

    team: int
    sender: int
    seq: int
    auth: bool
    messages: tuple[Message, ...]


# ---------------------------------------------------------------------------------------------
# Encoding
# ---------------------------------------------------------------------------------------------


def _u(fmt: str, v: int, lo: int, hi: int, what: str) -> bytes:
    if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
        raise EncodeError(f"{what} out of range: {v!r}")
    return struct.pack(fmt, v)


def _u8(v: int, what: str) -> bytes:
    return _u("<B", v, 0, 0xFF, what)


def _u16(v: int, what: str) -> bytes:
    return _u("<H", v, 0, 0xFFFF, what)


def _u32(v: int, what: str) -> bytes:
    return _u("<I", v, 0, 0xFFFFFFFF, what)


def _u64(v: int, what: str) -> bytes:
    return _u("<Q", v, 0, _U64_MAX, what)


def _i32(v: int, what: str) -> bytes:
    return _u("<i", v, _I32_MIN, _I32_MAX, what)


def _str8(s: str, what: str, nonempty: bool = False) -> bytes:
    b = s.encode("utf-8")
    if len(b) > 0xFF:
        raise EncodeError(f"{what} longer than 255 bytes")
    if nonempty and not b:
        raise EncodeError(f"{what} must not be empty")
    return bytes([len(b)]) + b


def _str16(s: str, what: str) -> bytes:
    b = s.encode("utf-8")
    if len(b) > 0xFFFF:
        raise EncodeError(f"{what} longer than 65535 bytes")
    return struct.pack("<H", len(b)) + b


def _encode_value(v: Value) -> bytes:
    # bool before int: bool is a subclass of int in Python, and the two are different types here.
    if isinstance(v, bool):
        return bytes([_VT_BOOL, 1 if v else 0])
    if isinstance(v, int):
        if not _I64_MIN <= v <= _I64_MAX:
            raise EncodeError(f"int value outside i64: {v}")
        return bytes([_VT_INT]) + struct.pack("<q", v)
    if isinstance(v, float):
        return bytes([_VT_FLOAT]) + struct.pack("<d", v)
    if isinstance(v, str):
        return bytes([_VT_TEXT]) + _str16(v, "text value")
    if isinstance(v, (bytes, bytearray, memoryview)):
        b = bytes(v)
        if len(b) > 0xFFFF:
            raise EncodeError("bytes value longer than 65535 bytes")
        return bytes([_VT_BYTES]) + struct.pack("<H", len(b)) + b
    if isinstance(v, (tuple, list)):
        if len(v) > 0xFF:
            raise EncodeError("vector longer than 255 floats")
        if not all(isinstance(x, float) for x in v):
            raise EncodeError("vector elements must be floats")
        return bytes([_VT_VECTOR, len(v)]) + struct.pack(f"<{len(v)}d", *v)
    raise EncodeError(f"not a port value: {type(v).__name__}")


def _encode_endpoint(e: Endpoint) -> bytes:
    if (e.node is None) == (e.group is None):
        raise EncodeError("endpoint needs exactly one of node and group")
    if e.node is not None:
        head = bytes([_EP_NODE]) + _u32(e.node, "endpoint node")
    else:
        assert e.group is not None
        head = bytes([_EP_GROUP]) + _str8(e.group, "endpoint group", nonempty=True)
    return head + _str8(e.behavior, "endpoint behavior") + _str8(e.port, "endpoint port")


def _period_ns(period_s: float) -> int:
    """``period_s`` seconds as nanoseconds, refusing what no period can be (as Ayllu's
    ``Duration::try_from_secs_f64`` does): NaN, infinities, negatives, a positive period under
    1 ns, and one of 584 years or more (beyond a u64 of nanoseconds). 0 is left to
    :func:`_check_period` (the period of a normal connection, and only of one)."""
    accepted = "a finite number of seconds from 1 ns to 584 years (0 for a normal connection)"
    if isinstance(period_s, bool) or not isinstance(period_s, (int, float)):
        raise TypeError(f"period_s must be {accepted}, not {type(period_s).__name__}")
    if not math.isfinite(period_s) or period_s < 0:
        raise EncodeError(f"period_s={period_s!r} is refused: periods are {accepted}")
    ns = period_s * 1e9
    if ns >= _U64_MAX:
        raise EncodeError(f"period_s={period_s:g} is refused: periods are {accepted}")
    if period_s > 0 and round(ns) == 0:
        raise EncodeError(f"period_s={period_s:g} is refused (under 1 ns): periods are {accepted}")
    return round(ns)


def _check_period(kind: ConnKind, period_ns: int) -> bytes:
    kind = ConnKind(kind)
    if (kind == ConnKind.NORMAL) != (period_ns == 0):
        raise EncodeError("period must be 0 for normal connections and only for them")
    return bytes([kind]) + _u64(period_ns, "period")


def _encode_body(m: Message) -> tuple[int, bytes]:
    if isinstance(m, Port):
        body = (
            _u64(m.conn, "conn")
            + _u64(m.seq, "seq")
            + _check_period(m.conn_kind, m.period_ns)
            + _i32(m.priority, "priority")
            + _str8(m.behavior, "behavior", nonempty=True)
            + _str8(m.port, "port", nonempty=True)
            + _encode_value(m.value)
        )
        if m.group is not None:
            body += _str8(m.group, "group", nonempty=True)
        return KIND_PORT, body
    if isinstance(m, Hello):
        if m.interval_ms <= 0:
            raise EncodeError("HELLO interval must be above zero")
        if len(m.groups) > 0xFF:
            raise EncodeError("HELLO lists more than 255 groups")
        groups = b"".join(_str8(g, "group", nonempty=True) for g in m.groups)
        head = _u32(m.interval_ms, "interval") + _str8(m.name, "hello name")
        return KIND_HELLO, head + bytes([len(m.groups)]) + groups
    if isinstance(m, Request):
        body = _u64(m.id, "request id") + _u8(int(m.op), "op")
        if m.op == Op.CONNECT:
            if m.destination is None:
                raise EncodeError("CONNECT needs a destination")
            body += (
                _str8(m.src_behavior, "source behavior")
                + _str8(m.src_port, "source port")
                + _encode_endpoint(m.destination)
                + _check_period(m.conn_kind, m.period_ns)
                + _i32(m.priority, "priority")
            )
        elif m.op == Op.DISCONNECT:
            body += _u64(m.conn, "conn")
        elif m.op in (Op.WHY, Op.READ):
            body += _str8(m.behavior, "behavior") + _str8(m.port, "port")
        # LIST and operations unknown to this module carry no arguments.
        if m.signature is not None:
            if len(m.signature) != SIGNATURE_LEN:
                raise EncodeError(f"an operator signature is {SIGNATURE_LEN} bytes")
            if m.op not in _OPS:
                raise EncodeError("a request of an unknown operation carries no signature")
            body += bytes([SIGNATURE_TAG]) + bytes(m.signature)
        return KIND_REQUEST, body
    if isinstance(m, (Challenge, Echo)):
        if len(m.cookie) != COOKIE_LEN:
            raise EncodeError(f"a cookie is {COOKIE_LEN} bytes")
        return (KIND_CHALLENGE if isinstance(m, Challenge) else KIND_ECHO), bytes(m.cookie)
    if isinstance(m, Reply):
        if not 1 <= m.parts <= MAX_PARTS or not 0 <= m.part < m.parts:
            raise EncodeError("REPLY part must be below parts, and parts in 1..=64")
        results = [x is not None for x in (m.error, m.conn, m.value, m.report)]
        if sum(results) != 1:
            raise EncodeError("REPLY needs exactly one of error, conn, value, report")
        if m.report is None and m.parts != 1:
            raise EncodeError("only report replies have several parts (errors have one)")
        body = _u64(m.id, "reply id")
        if m.error is not None:
            return KIND_REPLY, body + bytes([1]) + _u16(m.part, "part") + _u16(m.parts, "parts") + _str16(
                m.error, "error message"
            )
        body += bytes([0]) + _u16(m.part, "part") + _u16(m.parts, "parts")
        if m.conn is not None:
            body += bytes([_RESULT_CONNECTION]) + _u64(m.conn, "conn")
        elif m.report is not None:
            body += bytes([_RESULT_REPORT]) + _str16(m.report, "report")
        else:
            assert m.value is not None
            body += bytes([_RESULT_VALUE]) + _encode_value(m.value)
        return KIND_REPLY, body
    raise EncodeError(f"cannot encode {type(m).__name__}")


def encode_message(m: Message) -> bytes:
    """One message with its kind and length header."""
    kind, body = _encode_body(m)
    if len(body) > 0xFFFF:
        raise EncodeError("message body longer than 65535 bytes")
    return bytes([kind]) + struct.pack("<H", len(body)) + body


def mac(key: bytes, data: bytes) -> bytes:
    """The datagram MAC: HMAC-SHA256 of ``data`` under the team key, first 16 bytes."""
    return hmac.new(key, data, hashlib.sha256).digest()[:MAC_LEN]


def encode(
    team: int,
    sender: int,
    seq: int,
    messages: Iterable[Message],
    *,
    key: bytes | None = None,
    limit: int = MAX_DATAGRAM,
) -> bytes:
    """A whole datagram. With ``key`` it carries AUTH and a MAC.

    ``limit`` bounds the result (default: what receivers accept); pass :data:`MTU` to stay
    within the default path MTU.
    """
    if key is not None and len(key) != 32:
        raise EncodeError("team keys are 32 bytes")
    head = (
        MAGIC
        + bytes([VERSION, AUTH if key is not None else 0])
        + _u32(team, "team")
        + _u32(sender, "sender")
        + _u64(seq, "sequence")
    )
    out = head + b"".join(encode_message(m) for m in messages)
    if key is not None:
        out += mac(key, out)
    if len(out) > limit:
        raise EncodeError(f"datagram of {len(out)} bytes exceeds {limit}")
    return out


# ---------------------------------------------------------------------------------------------
# Decoding
# ---------------------------------------------------------------------------------------------


class _Reader:
    """Reads one message body; running past its end is ``malformed`` (body shorter than fields)."""

    __slots__ = ("buf", "end", "pos")

    def __init__(self, buf: bytes, pos: int, end: int) -> None:
        self.buf, self.pos, self.end = buf, pos, end

    def take(self, n: int) -> bytes:
        if self.end - self.pos < n:
            raise Dropped("malformed", "body shorter than its fields")
        b = self.buf[self.pos : self.pos + n]
        self.pos += n
        return b

    def unpack(self, fmt: str) -> Any:
        return struct.unpack(fmt, self.take(struct.calcsize(fmt)))[0]

    def u8(self) -> int:
        return int(self.unpack("<B"))

    def u16(self) -> int:
        return int(self.unpack("<H"))

    def u32(self) -> int:
        return int(self.unpack("<I"))

    def u64(self) -> int:
        return int(self.unpack("<Q"))

    def i32(self) -> int:
        return int(self.unpack("<i"))

    def text(self, n: int) -> str:
        try:
            return self.take(n).decode("utf-8")
        except UnicodeDecodeError:
            raise Dropped("malformed", "invalid UTF-8") from None

    def str8(self, nonempty: bool = False) -> str:
        s = self.text(self.u8())
        if nonempty and not s:
            raise Dropped("malformed", "empty name")
        return s

    def str16(self) -> str:
        return self.text(self.u16())

    def optional_group(self) -> str | None:
        """PORT's appended group: a whole non-empty str8 of UTF-8 after the value, else None
        (an empty one, or bytes that are not a whole str8, are ignored as a later field)."""
        if self.pos >= self.end:
            return None
        n = self.buf[self.pos]
        if self.end - self.pos - 1 < n:
            return None
        try:
            group = self.buf[self.pos + 1 : self.pos + 1 + n].decode("utf-8")
        except UnicodeDecodeError:
            return None
        self.pos += 1 + n
        return group or None

    def kind_period(self) -> tuple[ConnKind, int]:
        code, period = self.u8(), self.u64()
        if code > ConnKind.WRITE_INHIBIT:
            raise Dropped("malformed", f"connection kind {code}")
        kind = ConnKind(code)
        if (kind == ConnKind.NORMAL) != (period == 0):
            raise Dropped("malformed", "period 0 is for normal connections only")
        return kind, period

    def value(self) -> Value:
        t = self.u8()
        if t == _VT_BOOL:
            b = self.u8()
            if b > 1:
                raise Dropped("malformed", f"bool {b}")
            return b == 1
        if t == _VT_INT:
            return int(self.unpack("<q"))
        if t == _VT_FLOAT:
            return float(self.unpack("<d"))
        if t == _VT_TEXT:
            return self.str16()
        if t == _VT_BYTES:
            return bytes(self.take(self.u16()))
        if t == _VT_VECTOR:
            n = self.u8()
            return Vector(struct.unpack(f"<{n}d", self.take(8 * n)))
        raise Dropped("malformed", f"value type {t}")

    def endpoint(self) -> Endpoint:
        tag = self.u8()
        if tag == _EP_NODE:
            node = self.u32()
            return Endpoint(self.str8(), self.str8(), node=node)
        if tag == _EP_GROUP:
            group = self.str8(nonempty=True)
            return Endpoint(self.str8(), self.str8(), group=group)
        raise Dropped("malformed", f"endpoint tag {tag}")


def _decode_message(kind: int, r: _Reader) -> Message:
    if kind == KIND_PORT:
        conn, seq = r.u64(), r.u64()
        ck, period = r.kind_period()
        priority = r.i32()
        behavior, port = r.str8(nonempty=True), r.str8(nonempty=True)
        value = r.value()
        return Port(conn, seq, ck, period, priority, behavior, port, value, r.optional_group())
    if kind == KIND_HELLO:
        interval = r.u32()
        if interval == 0:
            raise Dropped("malformed", "HELLO interval 0")
        name = r.str8()
        groups = tuple(r.str8(nonempty=True) for _ in range(r.u8()))
        return Hello(interval, name, groups)
    if kind == KIND_REQUEST:
        rid, op = r.u64(), r.u8()
        if op == Op.CONNECT:
            sb, sp = r.str8(), r.str8()
            dest = r.endpoint()
            ck, period = r.kind_period()
            req = Request(rid, Op.CONNECT, sb, sp, dest, ck, period, r.i32())
        elif op == Op.DISCONNECT:
            req = Request(rid, Op.DISCONNECT, conn=r.u64())
        elif op in (Op.WHY, Op.READ):
            req = Request(rid, Op(op), behavior=r.str8(), port=r.str8())
        elif op == Op.LIST:
            req = Request(rid, Op.LIST)  # no arguments
        else:
            # An unknown op is decoded (and answered with an error by a node) rather than
            # dropped, so tools can tell an old node from a lost request. Its arguments, and
            # so where a signature would start, are unknown.
            return Request(rid, op)
        # An optional operator signature after the arguments. Anything else there, or a tag
        # without 64 bytes after it, is ignored like any extra body bytes.
        if r.end - r.pos >= 1 + SIGNATURE_LEN and r.buf[r.pos] == SIGNATURE_TAG:
            r.take(1)
            req = dataclasses.replace(req, signature=bytes(r.take(SIGNATURE_LEN)))
        return req
    if kind in (KIND_CHALLENGE, KIND_ECHO):
        cookie = bytes(r.take(COOKIE_LEN))
        return Challenge(cookie) if kind == KIND_CHALLENGE else Echo(cookie)
    if kind == KIND_REPLY:
        rid, status, part, parts = r.u64(), r.u8(), r.u16(), r.u16()
        if status > 1:
            raise Dropped("malformed", f"reply status {status}")
        if not 1 <= parts <= MAX_PARTS or part >= parts:
            raise Dropped("malformed", f"reply part {part} of {parts}")
        if status == 1:
            if parts != 1:
                raise Dropped("malformed", "only reports have several parts")
            return Reply(rid, part, parts, error=r.str16())
        result = r.u8()
        if result == _RESULT_REPORT:
            return Reply(rid, part, parts, report=r.str16())
        if parts != 1:
            raise Dropped("malformed", "only reports have several parts")
        if result == _RESULT_CONNECTION:
            return Reply(rid, part, parts, conn=r.u64())
        if result == _RESULT_VALUE:
            return Reply(rid, part, parts, value=r.value())
        raise Dropped("malformed", f"reply result {result}")
    raise AssertionError("unreachable: caller handles unknown kinds")


_KNOWN_KINDS = frozenset((KIND_PORT, KIND_HELLO, KIND_REQUEST, KIND_REPLY, KIND_CHALLENGE, KIND_ECHO))


def decode(data: bytes, team: int, key: bytes | None = None) -> Datagram:
    """Decode and verify one datagram for a receiver of ``team`` holding ``key`` (or open).

    Raises :class:`Dropped` with the spec's cause; nothing of a dropped datagram is returned.
    Messages of unknown kinds come back as :class:`Unknown` (the caller counts them as
    ``unknown_kind``). Replay protection needs state: see :class:`ReplayWindow`.
    """
    data = bytes(data)
    n = len(data)
    if n > MAX_DATAGRAM:
        raise Dropped("oversized")
    if n < HEADER_LEN:
        raise Dropped("truncated", "shorter than the header")
    if data[0:2] != MAGIC:
        raise Dropped("bad_magic")
    if data[2] != VERSION:
        raise Dropped("bad_version")
    flags = data[3]
    if flags & ~AUTH:
        raise Dropped("bad_flags")
    dteam, sender, seq = struct.unpack_from("<IIQ", data, 4)
    if dteam != team:
        raise Dropped("wrong_team")
    auth = bool(flags & AUTH)
    end = n
    if auth:
        if key is None:
            raise Dropped("unexpected_auth")
        if n < HEADER_LEN + MAC_LEN:
            raise Dropped("truncated", "no room for the MAC")
        end = n - MAC_LEN
        if not hmac.compare_digest(mac(key, data[:end]), data[end:]):
            raise Dropped("bad_mac")
    elif key is not None:
        raise Dropped("unauthenticated")
    messages: list[Message] = []
    pos = HEADER_LEN
    while pos < end:
        if end - pos < 3:
            raise Dropped("truncated", "message header cut")
        kind = data[pos]
        (length,) = struct.unpack_from("<H", data, pos + 1)
        body = pos + 3
        if body + length > end:
            raise Dropped("truncated", "message runs past the end")
        if kind in _KNOWN_KINDS:
            # Extra body bytes are ignored: fields are only ever appended.
            messages.append(_decode_message(kind, _Reader(data, body, body + length)))
        else:
            messages.append(Unknown(kind, length))
        pos = body + length
    return Datagram(team, sender, seq, auth, tuple(messages))


class ReplayWindow:
    """One sender's replay window (N5): the newest accepted sequence number and a bitmap of
    the 64 before it. Only call :meth:`accept` after the MAC was verified, so forged
    datagrams cannot move the window."""

    __slots__ = ("bits", "newest")

    def __init__(self) -> None:
        self.newest: int | None = None
        self.bits = 0  # bit i set: newest - 1 - i was accepted

    def accept(self, seq: int) -> bool:
        """Record ``seq`` and return True, or return False if it is a replay (or too old)."""
        if self.newest is None or seq > self.newest:
            if self.newest is not None:
                shift = seq - self.newest
                self.bits = ((self.bits << shift) | (1 << (shift - 1))) & _U64_MAX if shift <= 64 else 0
            self.newest = seq
            return True
        diff = self.newest - seq
        if diff == 0 or diff > 64 or self.bits & (1 << (diff - 1)):
            return False
        self.bits |= 1 << (diff - 1)
        return True


# ---------------------------------------------------------------------------------------------
# Operator signatures (spec/protocol.md, "Operator signature"): Ed25519, RFC 8032
# ---------------------------------------------------------------------------------------------
#
# The standard library has no Ed25519, so signing is done here with Python integers, following
# RFC 8032 section 5.1 (points in extended coordinates). Only signing is needed: AylluLite never
# verifies (a lite node applies no CONNECT or DISCONNECT). Python integers are not
# constant-time, so the time a signature takes may depend on the secret: sign on the operator's
# own machine, not where others can time it closely.

_ED_P = 2**255 - 19
_ED_L = 2**252 + 27742317777372353535851937790883648493
_ED_D = -121665 * pow(121666, -1, _ED_P) % _ED_P
_ED_SQRT_M1 = pow(2, (_ED_P - 1) // 4, _ED_P)
_EdPoint = tuple[int, int, int, int]  # X, Y, Z, T with x = X/Z, y = Y/Z, x*y = T/Z


def _ed_add(a: _EdPoint, b: _EdPoint) -> _EdPoint:
    p = _ED_P
    aa = (a[1] - a[0]) * (b[1] - b[0]) % p
    bb = (a[1] + a[0]) * (b[1] + b[0]) % p
    cc = 2 * a[3] * b[3] * _ED_D % p
    dd = 2 * a[2] * b[2] % p
    e, f, g, h = bb - aa, dd - cc, dd + cc, bb + aa
    return (e * f % p, g * h % p, f * g % p, e * h % p)


def _ed_mul(k: int, pt: _EdPoint) -> _EdPoint:
    acc: _EdPoint = (0, 1, 1, 0)
    while k:
        if k & 1:
            acc = _ed_add(acc, pt)
        pt = _ed_add(pt, pt)
        k >>= 1
    return acc


def _ed_encode(pt: _EdPoint) -> bytes:
    zinv = pow(pt[2], -1, _ED_P)
    x, y = pt[0] * zinv % _ED_P, pt[1] * zinv % _ED_P
    return (y | (x & 1) << 255).to_bytes(32, "little")


def _ed_base() -> _EdPoint:
    y = 4 * pow(5, -1, _ED_P) % _ED_P
    xx = (y * y - 1) * pow(_ED_D * y * y + 1, -1, _ED_P) % _ED_P
    x = pow(xx, (_ED_P + 3) // 8, _ED_P)
    if (x * x - xx) % _ED_P:
        x = x * _ED_SQRT_M1 % _ED_P
    if x & 1:
        x = _ED_P - x  # the base point's x is even
    return (x, y, 1, x * y % _ED_P)


_ED_B = _ed_base()


def _ed_secret(seed: bytes) -> tuple[int, bytes]:
    if len(seed) != 32:
        raise ValueError("an operator secret is a 32-byte seed (64 hex digits)")
    h = hashlib.sha512(seed).digest()
    a = int.from_bytes(h[:32], "little")
    a = (a & ((1 << 254) - 8)) | (1 << 254)
    return a, h[32:]


def _ed_hash(*parts: bytes) -> int:
    return int.from_bytes(hashlib.sha512(b"".join(parts)).digest(), "little") % _ED_L


def operator_public_key(seed: bytes) -> bytes:
    """The 32-byte Ed25519 public key of an operator secret (its 32-byte seed): what nodes
    are given (``--operator-key``-style options print and take it as 64 hex digits)."""
    a, _ = _ed_secret(seed)
    return _ed_encode(_ed_mul(a, _ED_B))


def _ed_sign(seed: bytes, message: bytes) -> bytes:
    a, prefix = _ed_secret(seed)
    public = _ed_encode(_ed_mul(a, _ED_B))
    r = _ed_hash(prefix, message)
    big_r = _ed_encode(_ed_mul(r, _ED_B))
    s = (r + _ed_hash(big_r, public, message) * a) % _ED_L
    return big_r + s.to_bytes(32, "little")


def signed_request_bytes(team: int, requester: int, receiver: int, request: Request) -> bytes:
    """What an operator signature covers: a context string, the team, the requester's and the
    **receiver's** node ids (u32 each), then the REQUEST body from ``id`` through the last
    argument (without any signature). So a signed request cannot be moved to another team,
    node or requester."""
    if request.op not in _OPS:
        raise EncodeError("only requests of known operations are signed")
    _, body = _encode_body(dataclasses.replace(request, signature=None))
    return _SIGNED_CONTEXT + _u32(team, "team") + _u32(requester, "requester") + _u32(receiver, "receiver") + body


def sign_request(seed: bytes, team: int, requester: int, receiver: int, request: Request) -> Request:
    """``request`` with the operator signature of secret ``seed`` (32 bytes) for node
    ``receiver``, sent by node ``requester`` in ``team``. Sign after the id is final: the id
    is signed too. Deterministic (RFC 8032), so the same inputs give the same bytes."""
    return dataclasses.replace(
        request, signature=_ed_sign(seed, signed_request_bytes(team, requester, receiver, request))
    )


# ---------------------------------------------------------------------------------------------
# The JSON form of spec/conformance.md (golden vectors; handy for tools and logs)
# ---------------------------------------------------------------------------------------------


def _bits(f: float) -> str:
    return struct.pack(">d", f).hex()


def _from_bits(h: str) -> float:
    return float(struct.unpack(">d", bytes.fromhex(h))[0])


def value_to_json(v: Value) -> dict[str, Any]:
    """A value in the vectors' JSON form (floats by their bits)."""
    if isinstance(v, bool):
        return {"type": "bool", "v": v}
    if isinstance(v, int):
        return {"type": "int", "v": v}
    if isinstance(v, float):
        return {"type": "float", "bits": _bits(v)}
    if isinstance(v, str):
        return {"type": "text", "v": v}
    if isinstance(v, (bytes, bytearray)):
        return {"type": "bytes", "hex": bytes(v).hex()}
    return {"type": "vector", "bits": [_bits(x) for x in v]}


def value_from_json(j: dict[str, Any]) -> Value:
    """Inverse of :func:`value_to_json`."""
    t = j["type"]
    if t == "bool":
        return bool(j["v"])
    if t == "int":
        return int(j["v"])
    if t == "float":
        return _from_bits(j["bits"])
    if t == "text":
        return str(j["v"])
    if t == "bytes":
        return bytes.fromhex(j["hex"])
    if t == "vector":
        return Vector(_from_bits(b) for b in j["bits"])
    raise ValueError(f"value type {t!r}")


def _endpoint_to_json(e: Endpoint) -> dict[str, Any]:
    d: dict[str, Any] = {"node": e.node} if e.node is not None else {"group": e.group}
    d.update(behavior=e.behavior, port=e.port)
    return d


_OP_NAMES = {Op.CONNECT: "connect", Op.DISCONNECT: "disconnect", Op.LIST: "list", Op.WHY: "why", Op.READ: "read"}


def message_to_json(m: Message) -> dict[str, Any]:
    """A message in the vectors' JSON form."""
    if isinstance(m, Port):
        return {
            "kind": "port",
            "conn": m.conn,
            "seq": m.seq,
            "conn_kind": ConnKind(m.conn_kind).wire_name,
            "period_ns": m.period_ns,
            "priority": m.priority,
            "behavior": m.behavior,
            "port": m.port,
            "value": value_to_json(m.value),
            **({} if m.group is None else {"group": m.group}),
        }
    if isinstance(m, Hello):
        return {"kind": "hello", "interval_ms": m.interval_ms, "name": m.name, "groups": list(m.groups)}
    if isinstance(m, Request):
        d: dict[str, Any] = {"kind": "request", "id": m.id}
        if m.op in _OP_NAMES:
            d["op"] = _OP_NAMES[Op(m.op)]
        else:
            d.update(op="unknown", code=int(m.op))
        if m.op == Op.CONNECT:
            assert m.destination is not None
            d.update(
                src_behavior=m.src_behavior,
                src_port=m.src_port,
                destination=_endpoint_to_json(m.destination),
                conn_kind=ConnKind(m.conn_kind).wire_name,
                period_ns=m.period_ns,
                priority=m.priority,
            )
        elif m.op == Op.DISCONNECT:
            d["conn"] = m.conn
        elif m.op in (Op.WHY, Op.READ):
            d.update(behavior=m.behavior, port=m.port)
        if m.signature is not None:
            d["signature_hex"] = m.signature.hex()
        return d
    if isinstance(m, Challenge):
        return {"kind": "challenge", "cookie_hex": m.cookie.hex()}
    if isinstance(m, Echo):
        return {"kind": "echo", "cookie_hex": m.cookie.hex()}
    if isinstance(m, Reply):
        d = {"kind": "reply", "id": m.id, "status": "ok" if m.ok else "error", "part": m.part, "parts": m.parts}
        if m.error is not None:
            d["message"] = m.error
        elif m.conn is not None:
            d["result"] = {"connection": m.conn}
        elif m.report is not None:
            d["result"] = {"report": m.report}
        else:
            assert m.value is not None
            d["result"] = {"value": value_to_json(m.value)}
        return d
    return {"kind": "unknown", "code": m.code, "length": m.length}


def message_from_json(j: dict[str, Any]) -> Message:
    """Inverse of :func:`message_to_json`."""
    k = j["kind"]
    if k == "port":
        return Port(
            j["conn"],
            j["seq"],
            ConnKind.from_name(j["conn_kind"]),
            j["period_ns"],
            j["priority"],
            j["behavior"],
            j["port"],
            value_from_json(j["value"]),
            j.get("group"),
        )
    if k == "hello":
        return Hello(j["interval_ms"], j["name"], tuple(j["groups"]))
    if k == "request":
        name = j["op"]
        op: int = j["code"] if name == "unknown" else Op[name.upper()]
        sig = bytes.fromhex(j["signature_hex"]) if "signature_hex" in j else None
        if op == Op.CONNECT:
            dj = j["destination"]
            dest = Endpoint(dj["behavior"], dj["port"], node=dj.get("node"), group=dj.get("group"))
            return Request(
                j["id"],
                op,
                j["src_behavior"],
                j["src_port"],
                dest,
                ConnKind.from_name(j["conn_kind"]),
                j["period_ns"],
                j["priority"],
                signature=sig,
            )
        if op == Op.DISCONNECT:
            return Request(j["id"], op, conn=j["conn"], signature=sig)
        if op in (Op.WHY, Op.READ):
            return Request(j["id"], op, behavior=j["behavior"], port=j["port"], signature=sig)
        return Request(j["id"], op, signature=sig)
    if k in ("challenge", "echo"):
        cookie = bytes.fromhex(j["cookie_hex"])
        return Challenge(cookie) if k == "challenge" else Echo(cookie)
    if k == "reply":
        base = {"id": j["id"], "part": j["part"], "parts": j["parts"]}
        if j["status"] == "error":
            return Reply(**base, error=j["message"])
        res = j["result"]
        if "connection" in res:
            return Reply(**base, conn=res["connection"])
        if "report" in res:
            return Reply(**base, report=res["report"])
        return Reply(**base, value=value_from_json(res["value"]))
    if k == "unknown":
        return Unknown(j["code"], j["length"])
    raise ValueError(f"message kind {k!r}")


# ---------------------------------------------------------------------------------------------
# The lite node
# ---------------------------------------------------------------------------------------------

Address = tuple[str, int]
#: ``on_write(behavior, port, value, sender_node, conn)``: called after a PORT message stored
#: a value in an exposed port.
WriteCallback = Callable[[str, str, Value, int, int], None]


def _boot_base() -> int:
    # spec: start at boot_seconds << 32 so that a restarted client's numbers exceed its old
    # ones. Used for datagram sequence numbers, request ids and per-connection sequence
    # numbers alike, since receivers remember all three across our restart. The low 32 bits
    # carry the fraction of the second, so a client restarted within the same second (a
    # script run twice) still starts above its previous run unless that run sent more
    # messages than the fraction advanced.
    ns = time.time_ns()
    return ((ns // 1_000_000_000) << 32) | (((ns % 1_000_000_000) << 32) // 1_000_000_000)


def _type_name(v: Value) -> str:
    return str(value_to_json(v)["type"])


@dataclass
class _LitePort:
    value: Value
    on_write: WriteCallback | None
    writes: int = 0
    # (kind, (sender, conn)) -> end of the window, monotonic ns. Only the windows that decide
    # storing are kept: lite ports never propagate (see the module docstring).
    windows: dict[tuple[ConnKind, tuple[int, int]], int] = field(default_factory=dict)

    def refresh(self, kind: ConnKind, holder: tuple[int, int], end: int) -> None:
        key = (kind, holder)
        self.windows[key] = max(self.windows.get(key, 0), end)  # refresh, never shorten (D6.1)

    def admit(self, now: int, holder: tuple[int, int]) -> str | None:
        """Why a connection write from ``holder`` is not stored now (truth table 1), or None."""
        for key, end in list(self.windows.items()):
            if end <= now:
                del self.windows[key]
        if any(k == ConnKind.SUPPRESS for k, _ in self.windows):
            return "suppressed"
        passes = {h for k, h in self.windows if k == ConnKind.OVERRIDE_IN}
        if passes and holder not in passes:
            return "overridden_in"
        return None


class Connection:
    """A connection from this lite node to a port on an Ayllu node.

    It owns a connection id and its own sequence numbers (N1), so the receiver can drop late
    duplicates and know who holds a pass. Create with :meth:`LiteNode.connection`.
    """

    def __init__(
        self,
        node: LiteNode,
        to: int | Address,
        behavior: str,
        port: str,
        kind: ConnKind,
        period_ns: int,
        priority: int,
        conn: int,
    ) -> None:
        self._node, self.to, self.behavior, self.port = node, to, behavior, port
        self.kind, self.period_ns, self.priority, self.conn = ConnKind(kind), period_ns, priority, conn
        self.seq = _boot_base()
        # Fail now rather than at the first send.
        _check_period(self.kind, period_ns)
        _str8(behavior, "behavior", nonempty=True)
        _str8(port, "port", nonempty=True)

    def send(self, value: Value) -> None:
        """Send one value along the connection (best effort: a lost value is not resent).

        Raises :class:`EncodeError` for a value a receiver would drop or that does not fit in
        one datagram of the node's MTU (values are never fragmented)."""
        with self._node._lock:
            self.seq += 1
            msg = Port(self.conn, self.seq, self.kind, self.period_ns, self.priority, self.behavior, self.port, value)
            self._node._send([msg], self._node._resolve(self.to))


@dataclass
class _Pending:
    request: Request
    to: Address
    sends: int = 0
    next_send: float = 0.0
    parts: dict[int, Reply] = field(default_factory=dict)
    done: Reply | None = None  # the single-part answer, or the assembled report
    failed: str | None = None
    hurried: bool = False  # sent again at once after an ECHO (once per request)


class LiteNode:
    """An AylluLite participant: node id, team, optional key, and a UDP socket it owns.

    Thread-safety: every public method may be called from any thread. Incoming datagrams are
    handled by :meth:`poll`, called by you or by the background thread of :meth:`start`; write
    callbacks run on whichever thread polls, with no lock held.
    """

    def __init__(
        self,
        node_id: int,
        team: int = 0,
        *,
        key: bytes | None = None,
        bind: Address = ("0.0.0.0", 0),
        peers: Iterable[tuple[int, Address]] = (),
        bootstrap: Iterable[Address] = (),
        broadcast: Address | None = None,
        discovery: Address | None = None,
        ttl: int = 1,
        name: str = "",
        groups: Iterable[str] = (),
        hello_interval_ms: int = 1000,
        clock: Callable[[], float] = time.monotonic,
        operator_secret: bytes | None = None,
        mtu: int = MTU,
    ) -> None:
        if not 64 <= mtu <= MAX_DATAGRAM:
            raise ValueError(f"mtu must be between 64 and {MAX_DATAGRAM}")
        #: The largest datagram this node sends (the URL's ``mtu``, as full nodes have it).
        self.mtu = mtu
        if key is not None and len(key) != 32:
            raise ValueError("team keys are 32 bytes (64 hex digits)")
        if operator_secret is not None:
            _ed_secret(operator_secret)  # refuse a bad seed now
        #: The operator's secret (the 32-byte Ed25519 seed), or None. With it, CONNECT and
        #: DISCONNECT requests are signed, as nodes given the operator's public key require.
        self.operator_secret = operator_secret
        if isinstance(node_id, bool) or not isinstance(node_id, int) or not 1 <= node_id <= 0xFFFFFFFF:
            # As libayllu and AylluLite C: 0 is reserved (no node; "nobody" in reports).
            raise ValueError(f"node id must be from 1 to 4294967295 (0 is reserved), not {node_id!r}")
        _u32(team, "team")
        if hello_interval_ms <= 0:
            raise ValueError("hello interval must be above zero")
        self.node_id, self.team, self.key, self.name = node_id, team, key, name
        self.hello_interval_ms = hello_interval_ms
        #: Groups announced in HELLO: nodes without broadcast then send group traffic here.
        self.groups = tuple(groups)
        encode_message(Hello(hello_interval_ms, name, self.groups))  # refuse bad names now
        self._clock = clock
        self._lock = threading.RLock()
        self._answered = threading.Condition(self._lock)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(bind)
        self.broadcast = broadcast
        if broadcast is not None:
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST, 1)
        #: Addresses greeted without knowing their node id (``peer=`` in a URL).
        self.bootstrap = tuple(bootstrap)
        #: The multicast discovery address (HELLOs go there), and the socket that hears it:
        #: shared with the other programs of this machine (SO_REUSEADDR), as Ayllu nodes do.
        self.discovery = discovery
        self._discovery_sock: socket.socket | None = None
        if discovery is not None:
            if not 0 <= ttl <= 255:
                raise ValueError("ttl must be from 0 to 255")
            self.sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, ttl)
            d = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            d.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            d.bind(discovery)
            group = struct.pack("4s4s", socket.inet_aton(discovery[0]), socket.inet_aton("0.0.0.0"))
            d.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, group)
            self._discovery_sock = d
        base = _boot_base()
        self._seq = base
        self._next_id = base
        self._next_conn = 1
        self._ports: dict[str, dict[str, _LitePort]] = {}
        self._static_peers: dict[int, Address] = dict(peers)
        # node id -> (address, last heard on our clock, hello interval in seconds)
        self._heard: dict[int, tuple[Address, float, float]] = {}
        self._replay: dict[int, ReplayWindow] = {}
        self._newest_seq: dict[tuple[int, int], int] = {}
        self._pending: dict[int, _Pending] = {}
        self._writers: dict[tuple[Any, ...], Connection] = {}
        # Return routability: address -> [bytes received from it, bytes answered to it], least
        # recently heard first (at most BUDGET_TABLE_MAX addresses).
        self._budgets: OrderedDict[Address, list[int]] = OrderedDict()
        self._next_hello = 0.0
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        #: Drop counters by cause name (N4), plus ``received``, ``sent``, ``send_failed``,
        #: ``challenged`` and ``amplification_limited`` (answers not sent: over the 3x rule).
        self.counters: dict[str, int] = {}

    @classmethod
    def from_url(cls, node_id: int, url: str | None = None, **kwargs: Any) -> LiteNode:
        """A lite node configured by a ``udp://`` URL, as every Ayllu program is: ``url``, else
        the environment variable ``AYLLU_URL``, else :data:`DEFAULT_URL` (discovery on this
        machine). Understood: the bind address, ``team``, ``key``, ``peer`` (repeatable),
        ``broadcast``, ``discovery``, ``ttl``, ``hello_ms``, ``name``, ``mtu``. Keyword arguments
        override the URL's settings. ``operator_secret=PATH`` signs structure changes; a node's
        ``operator=`` key is accepted (a lite node applies no structure change), and so are
        ``group=``, ``state=`` and ``spin_us=`` (a full node's; a lite node sends to nodes, keeps
        its windows in memory and never polls). The rules are every Ayllu parser's
        (``spec/vectors/urls.json``)."""
        options = parse_url(url if url is not None else default_url())
        options.update(kwargs)
        return cls(node_id, **options)

    # ----- lifecycle ---------------------------------------------------------------------

    @property
    def address(self) -> Address:
        """The local address of the socket (useful after binding port 0)."""
        host, port = self.sock.getsockname()[:2]
        return (host, port)

    def start(self) -> None:
        """Handle incoming datagrams, HELLOs and retries on a background thread."""
        with self._lock:
            if self._thread is not None:
                return
            self._stop.clear()
            self._thread = threading.Thread(target=self._run, name=f"ayllu-lite-{self.node_id}", daemon=True)
            self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            self.poll(0.05)

    def close(self) -> None:
        """Stop the background thread (if any) and close the socket."""
        self._stop.set()
        t = self._thread
        if t is not None and t is not threading.current_thread():
            t.join()
        self._thread = None
        self.sock.close()
        if self._discovery_sock is not None:
            self._discovery_sock.close()

    def __enter__(self) -> LiteNode:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ----- exposed ports -----------------------------------------------------------------

    def expose(self, behavior: str, port: str, default: Value, on_write: WriteCallback | None = None) -> None:
        """Expose ``behavior.port`` to Ayllu nodes. Its type is the default's type (S1):
        values of another type are dropped as ``type_mismatch``."""
        _str8(behavior, "behavior", nonempty=True)
        _str8(port, "port", nonempty=True)
        _encode_value(default)
        with self._lock:
            self._ports.setdefault(behavior, {})[port] = _LitePort(default, on_write)

    def get(self, behavior: str, port: str) -> Value:
        """The current value of an exposed port."""
        with self._lock:
            return self._ports[behavior][port].value

    def set(self, behavior: str, port: str, value: Value) -> None:
        """Set an exposed port locally (as its own behavior would: windows do not apply)."""
        with self._lock:
            p = self._ports[behavior][port]
            if _type_name(value) != _type_name(p.value):
                raise TypeError(f"{behavior}.{port} holds {_type_name(p.value)}, not {_type_name(value)}")
            p.value = value

    def ports(self) -> dict[str, dict[str, Value]]:
        """A snapshot of every exposed port: behavior -> port -> value."""
        with self._lock:
            return {b: {p: lp.value for p, lp in ps.items()} for b, ps in self._ports.items()}

    # ----- peers -------------------------------------------------------------------------

    def add_peer(self, node_id: int, address: Address) -> None:
        """Configure a peer: it receives our HELLOs and can be named by node id."""
        with self._lock:
            self._static_peers[node_id] = address

    def peers(self) -> dict[int, Address]:
        """Configured peers and the nodes heard from recently (N6), by node id."""
        with self._lock:
            self._expire_peers(self._clock())
            out = {n: a for n, (a, _, _) in self._heard.items()}
            out.update(self._static_peers)
            return out

    def _expire_peers(self, now: float) -> None:
        for n, (_, last, interval) in list(self._heard.items()):
            if now - last > 3 * interval:
                del self._heard[n]

    def _node_at(self, to: int | Address) -> int:
        """The node id of a request's target: given, or the node configured or heard at
        that address."""
        if not isinstance(to, tuple):
            return to
        for n, a in self._static_peers.items():
            if a == to:
                return n
        for n, (a, _, _) in self._heard.items():
            if a == to:
                return n
        raise LookupError(f"a signed request needs its receiver's node id: no node known at {to}")

    def _resolve(self, to: int | Address) -> Address:
        if isinstance(to, tuple):
            return to
        if to in self._static_peers:
            return self._static_peers[to]
        if to in self._heard:
            return self._heard[to][0]
        raise LookupError(f"no address known for node {to}: add_peer() it or wait for its HELLO")

    # ----- sending -----------------------------------------------------------------------

    def _count(self, what: str) -> None:
        self.counters[what] = self.counters.get(what, 0) + 1

    def _send(self, messages: Sequence[Message], to: Address, *, answer: bool = False) -> None:
        """Send ``messages`` in one datagram to ``to``. An ``answer`` goes only if it fits in
        what ``to`` may still be sent (:meth:`_may_answer`); if not it is counted
        ``amplification_limited`` and dropped."""
        with self._lock:
            data = encode(self.team, self.node_id, self._seq + 1, messages, key=self.key, limit=self.mtu)
            if answer and not self._may_answer(to, len(data)):
                self._count("amplification_limited")
                return
            self._seq += 1
            try:
                self.sock.sendto(data, to)
            except OSError:
                # UDP is best effort (N1): an unreachable peer must not stop the poll loop.
                self._count("send_failed")
                return
            self._count("sent")

    def _heard_from(self, addr: Address, size: int) -> None:
        """A datagram of ``size`` bytes from ``addr`` was accepted: it may be answered with 3x
        that. A new address beyond the table's size replaces the least recently heard one."""
        b = self._budgets.get(addr)
        if b is None:
            if len(self._budgets) >= BUDGET_TABLE_MAX:
                self._budgets.popitem(last=False)
            b = self._budgets[addr] = [0, 0]
        else:
            self._budgets.move_to_end(addr)
        b[0] += size

    def _may_answer(self, to: Address, size: int) -> bool:
        """Whether an answer of ``size`` bytes fits in ``to``'s budget (spec, "CHALLENGE and
        ECHO": at most 3x the bytes received from it, less those answered); if so it is
        charged. A lite node sends no CHALLENGE, so no address is ever proven to it."""
        b = self._budgets.get(to)
        if b is None or b[1] + size > AMPLIFICATION_FACTOR * b[0]:
            return False
        b[1] += size
        return True

    def send_hello(self) -> None:
        """Announce this node now to every configured and known peer and the broadcast address."""
        with self._lock:
            targets = set(self.peers().values())
            targets.update(self.bootstrap)
            if self.broadcast is not None:
                targets.add(self.broadcast)
            if self.discovery is not None:
                targets.add(self.discovery)
            hello = Hello(self.hello_interval_ms, self.name, self.groups)
            for t in targets:
                self._send([hello], t)
            self._next_hello = self._clock() + self.hello_interval_ms / 1000

    def connection(
        self,
        to: int | Address,
        behavior: str,
        port: str,
        *,
        kind: ConnKind = ConnKind.NORMAL,
        period_s: float = 0.0,
        priority: int = 0,
    ) -> Connection:
        """A new connection from this node to ``behavior.port`` on node ``to`` (a node id or
        an address). Special kinds need ``period_s > 0``; normal needs 0. A period that is
        NaN, infinite, negative, under 1 ns or 584 years or more is refused with
        :class:`EncodeError` (a ``ValueError``) naming ``period_s`` and that range."""
        period_ns = _period_ns(period_s)
        with self._lock:
            conn = self._next_conn
            self._next_conn += 1
            return Connection(self, to, behavior, port, kind, period_ns, priority, conn)

    def write(
        self,
        to: int | Address,
        behavior: str,
        port: str,
        value: Value,
        *,
        kind: ConnKind = ConnKind.NORMAL,
        period_s: float = 0.0,
        priority: int = 0,
    ) -> None:
        """Write a remote port. Repeated writes with the same target, kind, period and priority
        travel along one connection, so they hold the same pass on the receiver."""
        key = (to, behavior, port, ConnKind(kind), _period_ns(period_s), priority)
        with self._lock:
            c = self._writers.get(key)
            if c is None:
                c = self._writers[key] = self.connection(
                    to, behavior, port, kind=kind, period_s=period_s, priority=priority
                )
        c.send(value)

    # ----- requests (N2) -----------------------------------------------------------------

    def request(self, to: int | Address, request: Request, timeout: float | None = None) -> Reply:
        """Send a request and wait for its complete answer, retrying every 200 ms up to 25
        sends. ``request.id`` is replaced by a fresh id. Returns the reply (for reports: one
        reply whose ``report`` is the reassembled text). Raises :class:`RequestTimeout`.

        With an operator secret, CONNECT and DISCONNECT are signed for the receiving node
        (``to``, or the node known at that address; :class:`LookupError` if none is). A
        CHALLENGE from the node is answered with an ECHO at once and the request sent again
        (spec, "Return routability"), so large answers arrive without waiting for a retry."""
        with self._lock:
            rid = self._next_id
            self._next_id += 1
            req = dataclasses.replace(request, id=rid, signature=None)
            if self.operator_secret is not None and req.op in (Op.CONNECT, Op.DISCONNECT):
                req = sign_request(self.operator_secret, self.team, self.node_id, self._node_at(to), req)
            encode_message(req)  # refuse a bad request before it is remembered
            p = self._pending[rid] = _Pending(req, self._resolve(to))
            self._flush_requests()
        deadline = None if timeout is None else self._clock() + timeout
        try:
            while True:
                with self._lock:
                    if p.done is not None:
                        return p.done
                    if p.failed is not None:
                        raise RequestTimeout(p.failed)
                    if deadline is not None and self._clock() >= deadline:
                        raise RequestTimeout(f"request {rid}: no answer within {timeout} s")
                    wait = max(0.0, min(p.next_send - self._clock(), RETRY_INTERVAL_S))
                    if deadline is not None:
                        wait = max(0.0, min(wait, deadline - self._clock()))
                    if self._thread is not None and self._thread is not threading.current_thread():
                        self._answered.wait(wait or 0.01)
                        continue
                self.poll(wait or 0.001)
        finally:
            with self._lock:
                self._pending.pop(rid, None)

    def _flush_requests(self) -> None:
        now = self._clock()
        for p in self._pending.values():
            if p.done is not None or p.failed is not None or p.next_send > now:
                continue
            if p.sends >= RETRY_LIMIT:
                p.failed = f"request {p.request.id}: no answer after {p.sends} tries"
                self._answered.notify_all()
                continue
            p.sends += 1
            p.next_send = now + RETRY_INTERVAL_S
            self._send([p.request], p.to)

    def _answer(self, to: int | Address, request: Request) -> Reply:
        r = self.request(to, request)
        if r.error is not None:
            raise RequestFailed(r.error)
        return r

    def connect(
        self,
        to: int | Address,
        src_behavior: str,
        src_port: str,
        dest_behavior: str,
        dest_port: str,
        *,
        kind: ConnKind = ConnKind.NORMAL,
        period_s: float = 0.0,
        priority: int = 0,
    ) -> int:
        """Ask node ``to`` to connect its ``src_behavior.src_port`` to this lite node's
        ``dest_behavior.dest_port`` (expose it first). Returns the node's connection id."""
        dest = Endpoint(dest_behavior, dest_port, node=self.node_id)
        req = Request(0, Op.CONNECT, src_behavior, src_port, dest, ConnKind(kind), _period_ns(period_s), priority)
        conn = self._answer(to, req).conn
        if conn is None:
            raise RequestFailed("CONNECT answered without a connection id")
        return conn

    def connect_endpoint(
        self,
        to: int | Address,
        src_behavior: str,
        src_port: str,
        destination: Endpoint,
        *,
        kind: ConnKind = ConnKind.NORMAL,
        period_s: float = 0.0,
        priority: int = 0,
    ) -> int:
        """Ask node ``to`` to connect its port to any node or group endpoint."""
        period_ns = _period_ns(period_s)
        req = Request(0, Op.CONNECT, src_behavior, src_port, destination, ConnKind(kind), period_ns, priority)
        conn = self._answer(to, req).conn
        if conn is None:
            raise RequestFailed("CONNECT answered without a connection id")
        return conn

    def disconnect(self, to: int | Address, conn: int) -> None:
        """Ask node ``to`` to remove its connection ``conn``."""
        self._answer(to, Request(0, Op.DISCONNECT, conn=conn))

    def read(self, to: int | Address, behavior: str, port: str) -> Value:
        """The current value of a port on node ``to``."""
        r = self._answer(to, Request(0, Op.READ, behavior=behavior, port=port))
        if r.value is None:
            raise RequestFailed("READ answered without a value")
        return r.value

    def why(self, to: int | Address, behavior: str, port: str) -> Any:
        """The node's ``PortReport`` for ``behavior.port``, as parsed JSON."""
        r = self._answer(to, Request(0, Op.WHY, behavior=behavior, port=port))
        return json.loads(r.report or "null")

    def list_node(self, to: int | Address) -> Any:
        """The node's ``NodeReport``, as parsed JSON."""
        r = self._answer(to, Request(0, Op.LIST))
        return json.loads(r.report or "null")

    # ----- receiving ---------------------------------------------------------------------

    def poll(self, timeout: float = 0.0) -> int:
        """Handle the datagrams that arrive within ``timeout`` seconds (at least those already
        waiting), then send due HELLOs and retries. Returns how many datagrams were handled."""
        handled = 0
        end = self._clock() + timeout
        while True:
            left = max(0.0, end - self._clock())
            socks = [self.sock] if self._discovery_sock is None else [self.sock, self._discovery_sock]
            try:
                ready, _, _ = select.select(socks, [], [], left if handled == 0 else 0)
            except (OSError, ValueError):
                break  # closed underneath us
            if not ready:
                break
            try:
                data, addr = ready[0].recvfrom(MAX_DATAGRAM + 1)
            except (BlockingIOError, OSError):
                break
            self.handle_datagram(data, (addr[0], addr[1]))
            handled += 1
        with self._lock:
            now = self._clock()
            if now >= self._next_hello:
                self.send_hello()
            self._flush_requests()
        return handled

    def handle_datagram(self, data: bytes, addr: Address) -> Dropped | None:
        """Apply one datagram received from ``addr``; returns the drop, if it was dropped.

        Public so that a program with its own socket loop can feed datagrams in.
        """
        calls: list[tuple[WriteCallback, tuple[str, str, Value, int, int]]] = []
        with self._lock:
            try:
                d = decode(data, self.team, self.key)
                if d.auth and not self._replay.setdefault(d.sender, ReplayWindow()).accept(d.seq):
                    raise Dropped("replayed")
            except Dropped as e:
                self._count(e.cause)
                return e
            if d.sender == self.node_id:
                return None  # our own broadcast coming back: a group excludes its sender
            self._count("received")
            self._heard_from(addr, len(data))  # before its requests are answered: they may use it
            now = self._clock()
            self._expire_peers(now)
            new_peer = d.sender not in self._heard and d.sender not in self._static_peers
            _, _, interval = self._heard.get(d.sender, (addr, now, 1.0))
            for m in d.messages:
                if isinstance(m, Hello):
                    # Believed up to the Rust node's bound: a forged HELLO announcing
                    # 0xFFFFFFFF ms would keep its address greeted for months.
                    interval = min(m.interval_ms, MAX_PEER_INTERVAL_MS) / 1000
            if new_peer and len(self._heard) >= MAX_HEARD:
                # A flood of invented ids must not grow memory: the one heard longest ago goes.
                oldest = min(self._heard, key=lambda n: self._heard[n][1])
                del self._heard[oldest]
                self._count("peer_evicted")
            self._heard[d.sender] = (addr, now, interval)
            replies: list[Reply] = []
            for m in d.messages:
                if isinstance(m, Port):
                    if m.group is not None and m.group not in self.groups:
                        # Sent to a group we have not joined: a shared broadcast address
                        # reaches us anyway, and S10 says only members apply it (D-S10.6).
                        self._count("not_member")
                    else:
                        self._apply_port(d.sender, m, calls)
                elif isinstance(m, Reply):
                    self._apply_reply(m)
                elif isinstance(m, Request):
                    replies.append(self._serve(m))
                elif isinstance(m, Challenge):
                    self._echo(m, addr)
                elif isinstance(m, Unknown):
                    self._count("unknown_kind")
                # An ECHO needs nothing: a lite node sends no CHALLENGE (its answers keep to the
                # 3x budget instead), so it has no cookie to check.
            for r in replies:
                # Each within the 3x budget of the address (spec, "CHALLENGE and ECHO"); one
                # over it is counted and not sent, and a retry of the request may carry it.
                try:
                    self._send([r], addr, answer=True)
                except EncodeError:
                    # A value too large for one datagram: say so rather than stay silent and
                    # make the requester retry 25 times.
                    self._send([Reply(r.id, error="answer too large for one datagram")], addr, answer=True)
            if new_peer:
                # Greet a node heard for the first time at once (as Ayllu nodes do, N6), so a
                # node that found us by discovery can address us without waiting a period.
                self._send([Hello(self.hello_interval_ms, self.name, self.groups)], addr)
        for cb, args in calls:
            cb(*args)
        return None

    def _echo(self, m: Challenge, addr: Address) -> None:
        # Return routability: send the cookie back at once, to the address the CHALLENGE came
        # from (never larger than the CHALLENGE, so no one can use this to amplify). Then the
        # requests waiting on that node go again now rather than at their next retry: the
        # node, its address proven, answers them in full. Only once per request, so forged
        # CHALLENGEs cannot make us repeat a request more often than the retries do.
        self._count("challenged")
        self._send([Echo(m.cookie)], addr)
        now = self._clock()
        for p in self._pending.values():
            if p.to == addr and p.done is None and p.failed is None and p.sends > 0 and not p.hurried:
                p.hurried = True
                p.next_send = now
        self._flush_requests()

    def _apply_port(self, sender: int, m: Port, calls: list[Any]) -> None:
        # Same order as the core's receive (docs/semantics.md, order of checks): stale,
        # unknown names, the connection's own window, storing, type.
        key = (sender, m.conn)
        newest = self._newest_seq.get(key)
        if newest is not None and m.seq <= newest:
            self._count("stale")
            return
        if newest is None and len(self._newest_seq) >= _SEQ_TABLE_MAX:
            self._newest_seq.clear()
        self._newest_seq[key] = m.seq
        ports = self._ports.get(m.behavior)
        if ports is None:
            self._count("unknown_behavior")
            return
        p = ports.get(m.port)
        if p is None:
            self._count("unknown_port")
            return
        now = round(self._clock() * 1e9)  # periods are measured on our own clock (S8)
        holder = (sender, m.conn)
        if m.conn_kind != ConnKind.NORMAL:
            p.refresh(m.conn_kind, holder, now + m.period_ns)
        if m.conn_kind in (ConnKind.SUPPRESS, ConnKind.INHIBIT, ConnKind.WRITE_INHIBIT):
            return  # these kinds never write the value
        blocked = p.admit(now, holder)
        if blocked is not None:
            self._count(blocked)
            return
        if _type_name(m.value) != _type_name(p.value):
            self._count("type_mismatch")
            return
        p.value = m.value
        p.writes += 1
        if p.on_write is not None:
            calls.append((p.on_write, (m.behavior, m.port, m.value, sender, m.conn)))

    def _apply_reply(self, m: Reply) -> None:
        p = self._pending.get(m.id)
        if p is None or p.done is not None:
            return  # a late duplicate of something already answered
        if m.report is None:
            p.done = m
        else:
            p.parts[m.part] = m
            if len(p.parts) == m.parts and all(i in p.parts for i in range(m.parts)):
                text = "".join(p.parts[i].report or "" for i in range(m.parts))
                p.done = Reply(m.id, 0, 1, report=text)
            else:
                # Ask again soon for the missing parts: the node answers from memory.
                p.next_send = min(p.next_send, self._clock() + RETRY_INTERVAL_S)
        self._answered.notify_all()

    def _serve(self, m: Request) -> Reply:
        # A lite node owns no connections and no behaviors beyond its exposed registers, so it
        # answers READ and a small LIST, and refuses the rest. Reads are idempotent, so there
        # is nothing to remember between repeats.
        if m.op == Op.READ:
            p = self._ports.get(m.behavior, {}).get(m.port)
            if p is None:
                return Reply(m.id, error=f"no port {m.behavior}.{m.port}")
            return Reply(m.id, value=p.value)
        if m.op == Op.LIST:
            # Behaviors in order of first exposure, ports in order of exposure: the same text
            # the C implementation gives.
            report = {
                "node": self.node_id,
                "lite": True,
                "behaviors": [{"name": b, "ports": list(ps)} for b, ps in self._ports.items()],
            }
            text = json.dumps(report, separators=(",", ":"), ensure_ascii=False)
            if len(text.encode()) > MTU - 100:
                return Reply(m.id, error="report too large for an AylluLite node")
            return Reply(m.id, report=text)
        if m.op in (Op.CONNECT, Op.DISCONNECT, Op.WHY):
            return Reply(m.id, error="not supported by an AylluLite node")
        return Reply(m.id, error="unknown operation")


#: The environment variable every Ayllu program reads its ``udp://`` URL from.
URL_ENV = "AYLLU_URL"
#: The URL when ``AYLLU_URL`` is not set: any address, a port the system chooses, team 0, no
#: key, discovery by multicast with TTL 0 (this machine only) -- the same default as the Rust
#: runtime and the ``ayllu`` tool.
DEFAULT_URL = "udp://0.0.0.0:0?discovery=239.255.65.89:7390&ttl=0"


def default_url() -> str:
    """``AYLLU_URL`` if set and not empty, else :data:`DEFAULT_URL`."""
    return os.environ.get(URL_ENV, "").strip() or DEFAULT_URL


def _decimal(text: str) -> int | None:
    """A number in a URL: ASCII decimal digits only (no sign, no space), as every Ayllu parser
    reads it (``spec/vectors/urls.json``)."""
    if not text or not all("0" <= c <= "9" for c in text):
        return None
    return int(text)


def _hex32(text: str) -> bytes | None:
    """64 ASCII hex digits as 32 bytes, else ``None``."""
    if len(text) != 64 or any(c not in "0123456789abcdefABCDEF" for c in text):
        return None
    return bytes.fromhex(text)


def _address(text: str, what: str) -> Address:
    """``HOST:PORT`` with an IPv4 host: a dotted-quad literal, or a name (text with a letter)
    for the system's resolver; the rules of the full nodes' parser (``udp_config.rs``)."""
    host, sep, port_text = text.rpartition(":")
    port = _decimal(port_text)
    if host.startswith("[") and host.endswith("]") and port is not None and port <= 65535:
        raise ValueError(f"{what} `{text}` has no IPv4 address")
    if not sep or not host or port is None or port > 65535:
        raise ValueError(f"{what} `{text}` is not HOST:PORT (an IPv4 address or a host name, and a port)")
    try:
        return (str(ipaddress.IPv4Address(host)), port)
    except ValueError:
        pass
    # Only a name goes to the resolver (and so maybe to DNS): `1..2` or `127.1` is refused here.
    if not any(c.isascii() and c.isalpha() for c in host):
        raise ValueError(f"{what} `{text}` is not HOST:PORT (an IPv4 address or a host name, and a port)")
    try:
        return (socket.gethostbyname(host), port)
    except (OSError, UnicodeError) as e:
        raise ValueError(f"{what} `{text}` is not HOST:PORT ({e})") from None


def parse_url(url: str) -> dict[str, Any]:
    """The :class:`LiteNode` keyword arguments a ``udp://`` URL gives (the options of
    ``crates/ayllu/src/udp_config.rs``, with the same rules: ``spec/vectors/urls.json``).
    Raises ``ValueError`` naming the bad part. ``group``, ``state``, ``operator`` and
    ``spin_us`` are a full node's: checked, not returned."""
    if not url.startswith("udp://"):
        raise ValueError(f"`{url}`: expected udp://HOST:PORT?...")
    rest = url[len("udp://") :]
    addr, _, query = rest.partition("?")
    out: dict[str, Any] = {"bind": _address(addr, "bind address"), "bootstrap": []}
    for pair in filter(None, query.split("&")):
        k, sep, v = pair.partition("=")
        if not sep:
            raise ValueError(f"`{pair}` is not key=value")
        n = _decimal(v)
        if k == "team":
            if n is None or n >= 1 << 32:
                raise ValueError(f"team `{v}` is not a u32")
            out["team"] = n
        elif k == "key":
            key = _hex32(v)
            if key is None:
                raise ValueError("key must be 64 hex digits")
            out["key"] = key
        elif k == "peer":
            out["bootstrap"].append(_address(v, "peer"))
        elif k == "broadcast":
            out["broadcast"] = _address(v, "broadcast")
        elif k == "group":
            # A group's own address is where a full node sends that group's messages; a lite
            # node sends to nodes, so it only checks the form.
            name, at, where = v.partition("@")
            if not at:
                raise ValueError(f"group `{v}` should be NAME@ADDR:PORT")
            if not 1 <= len(name.encode()) <= 255:
                raise ValueError(f"group name `{name}` must be 1 to 255 bytes")
            _address(where, "group address")
        elif k == "discovery":
            a = _address(v, "discovery")
            if not 224 <= int(a[0].split(".")[0]) <= 239:
                raise ValueError(f"discovery `{v}` must be a multicast address (224.0.0.0/4)")
            out["discovery"] = a
        elif k == "ttl":
            if n is None or n > 255:
                raise ValueError(f"ttl `{v}` must be a number from 0 to 255")
            out["ttl"] = n
        elif k == "hello_ms":
            if n is None or not 0 < n < 1 << 32:
                raise ValueError("hello_ms must be between 1 and 4294967295")
            out["hello_interval_ms"] = n
        elif k == "name":
            if len(v.encode()) > 255:
                raise ValueError("name must be at most 255 bytes")
            out["name"] = v
        elif k == "mtu":
            if n is None or not 64 <= n <= MAX_DATAGRAM:
                raise ValueError(f"mtu must be between 64 and {MAX_DATAGRAM}")
            out["mtu"] = n
        elif k == "state":
            # Replay marks kept across restarts (D-N5.3) belong to full nodes; a lite client
            # sharing the same AYLLU_URL accepts the option and keeps its windows in memory.
            if not v:
                raise ValueError("state needs a file path")
        elif k == "operator":
            # A node's operator public key: what it requires of structure changes it applies.
            # A lite node applies none (it refuses CONNECT and DISCONNECT), so it only checks
            # the form (a full node also checks that it is a valid Ed25519 point).
            if _hex32(v) is None:
                raise ValueError("operator must be 64 hex digits (the public key `ayllu keygen` prints)")
        elif k == "operator_secret":
            out["operator_secret"] = read_operator_secret(v)
        elif k == "spin_us":
            # How long a full node's wait may poll (D-N3.4). A lite node never polls: it
            # checks the form, so that one AYLLU_URL serves both.
            if n is None or n > 1000:
                raise ValueError(f"spin_us `{v}` must be a number from 0 to 1000")
        else:
            raise ValueError(f"unknown option `{k}`")
    return out


def read_operator_secret(path: str) -> bytes:
    """The operator secret (the 32-byte Ed25519 seed) from file ``path``: 64 hex digits, as
    ``ayllu keygen`` writes it, surrounding white space ignored. A path rather than the secret
    itself, so that it does not show in process lists."""
    if not path:
        raise ValueError("operator_secret needs the path of a file that holds the secret")
    try:
        with open(path, encoding="ascii") as f:
            text = f.read().strip()
    except (OSError, UnicodeDecodeError) as e:
        raise ValueError(f"cannot read the operator secret {path}: {e}") from None
    seed = _hex32(text)
    if seed is None:
        raise ValueError(f"operator secret {path}: must be 64 hex digits")
    return seed


def key_from_hex(text: str) -> bytes:
    """A team key from its 64-hex-digit form (what tools accept)."""
    key = bytes.fromhex(text.strip())
    if len(key) != 32:
        raise ValueError("team keys are 32 bytes (64 hex digits)")
    return key


def random_key() -> bytes:
    """A fresh 32-byte team key."""
    return os.urandom(32)


def is_nan(v: Value) -> bool:
    """True for a float NaN (useful because NaN != NaN when comparing port values)."""
    return isinstance(v, float) and math.isnan(v)
