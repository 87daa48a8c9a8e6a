"""Codec tests for AylluLite Python that do not need the golden vectors: every message kind
round-trips, and each drop cause of spec/protocol.md is produced by the input the spec names.
They pin the module's reading of the spec independently of crates/ayllu-wire."""

from __future__ import annotations

import math
import struct

import pytest

import ayllu_lite as al

KEY = bytes(range(32))
TEAM = 7


def roundtrip(messages: list[al.Message], key: bytes | None = None) -> al.Datagram:
    data = al.encode(TEAM, 3, 1 << 32, messages, key=key)
    d = al.decode(data, TEAM, key)
    assert d.sender == 3 and d.seq == 1 << 32 and d.auth == (key is not None)
    assert list(d.messages) == messages
    return d


def cause(data: bytes, key: bytes | None = None, team: int = TEAM) -> str:
    with pytest.raises(al.Dropped) as e:
        al.decode(data, team, key)
    return e.value.cause


PORT = al.Port(5, 9, al.ConnKind.NORMAL, 0, -2, "B", "P", 42)


def test_every_message_kind_roundtrips() -> None:
    values: list[al.Value] = [True, False, -5, 1.5, -0.0, "żółw", b"\x00\xff", al.Vector((1.0, -2.5))]
    msgs: list[al.Message] = [
        al.Port(1, 2, k, 0 if k == al.ConnKind.NORMAL else 200_000_000, 3, "Beh", "Port", v)
        for k in al.ConnKind
        for v in values
    ]
    msgs += [
        al.Hello(1000, "robot-1", ("Peers", "Scouts")),
        al.Hello(5),
        al.Request(1, al.Op.CONNECT, "S", "p", al.Endpoint("B", "P", node=9), al.ConnKind.OVERRIDE_IN, 5, -1),
        al.Request(2, al.Op.CONNECT, "S", "p", al.Endpoint("B", "P", group="Peers")),
        al.Request(3, al.Op.DISCONNECT, conn=77),
        al.Request(4, al.Op.LIST),
        al.Request(5, al.Op.WHY, behavior="B", port="P"),
        al.Request(6, al.Op.READ, behavior="B", port="P"),
        al.Request(7, 99),
        al.Reply(1, conn=4),
        al.Reply(2, value=2.0),
        al.Reply(3, part=1, parts=3, report='{"a":'),
        al.Reply(4, error="no such port"),
        al.Request(8, al.Op.DISCONNECT, conn=3, signature=bytes(range(64))),
        al.Request(9, al.Op.LIST, signature=b"\xff" * 64),
        al.Challenge(b"0123456789abcdef"),
        al.Echo(bytes(16)),
    ]
    roundtrip(msgs)
    roundtrip(msgs[:3], KEY)


def test_nan_payload_survives() -> None:
    nan = struct.unpack("<d", struct.pack("<Q", 0x7FF0000000000123))[0]
    (m,) = al.decode(al.encode(TEAM, 1, 1, [al.Port(1, 1, al.ConnKind.NORMAL, 0, 0, "B", "P", nan)]), TEAM).messages
    assert isinstance(m, al.Port) and math.isnan(m.value)  # type: ignore[arg-type]
    assert al.value_to_json(m.value) == {"type": "float", "bits": "7ff0000000000123"}


def test_header_causes() -> None:
    good = al.encode(TEAM, 1, 1, [PORT])
    assert cause(good[:19]) == "truncated"
    assert cause(b"XY" + good[2:]) == "bad_magic"
    assert cause(good[:2] + b"\x02" + good[3:]) == "bad_version"
    assert cause(good[:3] + b"\x02" + good[4:]) == "bad_flags"
    assert cause(good, team=8) == "wrong_team"
    assert cause(good + b"\x00" * 8192) == "oversized"
    assert cause(good, KEY) == "unauthenticated"
    signed = al.encode(TEAM, 1, 1, [PORT], key=KEY)
    assert cause(signed) == "unexpected_auth"
    assert cause(signed, bytes(32)) == "bad_mac"
    assert cause(signed[:-1] + bytes([signed[-1] ^ 1]), KEY) == "bad_mac"
    assert cause(good[:20] + b"\x00" * 3 + b"\x00", None) == "truncated"  # message cut
    assert cause(good[:3] + b"\x01" + good[4:20], KEY) == "truncated"  # no room for the MAC


def test_empty_datagram_is_fine() -> None:
    assert al.decode(al.encode(TEAM, 1, 1, []), TEAM).messages == ()


def body(kind: int, b: bytes) -> bytes:
    return al.encode(TEAM, 1, 1, []) + bytes([kind]) + struct.pack("<H", len(b)) + b


def port_body(kind: int = 0, period: int = 0, beh: bytes = b"\x01B", value: bytes = b"\x01" + bytes(8)) -> bytes:
    return struct.pack("<QQBQi", 1, 1, kind, period, 0) + beh + b"\x01P" + value


def test_malformed_bodies() -> None:
    assert cause(body(1, port_body()[:-1])) == "malformed"  # shorter than its fields
    assert cause(body(1, port_body(kind=6, period=1))) == "malformed"
    assert cause(body(1, port_body(kind=1, period=0))) == "malformed"
    assert cause(body(1, port_body(kind=0, period=1))) == "malformed"
    assert cause(body(1, port_body(beh=b"\x00"))) == "malformed"
    assert cause(body(1, port_body(beh=b"\x01\xff"))) == "malformed"  # invalid UTF-8
    assert cause(body(1, port_body(value=b"\x00\x02"))) == "malformed"  # bool 2
    assert cause(body(1, port_body(value=b"\x06"))) == "malformed"  # value type 6
    assert cause(body(2, struct.pack("<IBB", 0, 0, 0))) == "malformed"  # HELLO interval 0
    assert cause(body(2, struct.pack("<IB", 5, 0))) == "malformed"  # HELLO without its group count
    assert cause(body(2, struct.pack("<IBBB", 5, 0, 1, 0))) == "malformed"  # empty group name
    assert cause(body(0x11, struct.pack("<QBHH", 1, 1, 0, 2) + b"\x00\x00")) == "malformed"  # error in parts
    assert cause(body(0x10, struct.pack("<QB", 1, 1) + b"\x00\x00\x00")) == "malformed"  # endpoint tag 0
    reply = struct.pack("<QBHH", 1, 0, 0, 1)
    assert cause(body(0x11, struct.pack("<QBHH", 1, 2, 0, 1) + b"\x00\x00")) == "malformed"  # status
    assert cause(body(0x11, struct.pack("<QBHH", 1, 0, 0, 0) + b"\x01" + bytes(8))) == "malformed"  # 0 parts
    assert cause(body(0x11, struct.pack("<QBHH", 1, 0, 1, 1) + b"\x01" + bytes(8))) == "malformed"  # part>=parts
    assert cause(body(0x11, struct.pack("<QBHH", 1, 0, 0, 65) + b"\x03\x00\x00")) == "malformed"  # 65 parts
    assert cause(body(0x11, reply + b"\x04")) == "malformed"  # result 4
    assert cause(body(1, port_body())[:-1]) == "truncated"  # message runs past the end


def test_unknown_kinds_and_ops_are_skipped_not_dropped() -> None:
    data = body(0x7F, b"abc") + bytes([1]) + struct.pack("<H", len(port_body())) + port_body()
    d = al.decode(data, TEAM)
    assert d.messages[0] == al.Unknown(0x7F, 3)
    assert isinstance(d.messages[1], al.Port)
    (req,) = al.decode(body(0x10, struct.pack("<QB", 9, 200) + b"junk"), TEAM).messages
    assert req == al.Request(9, 200)


def test_extra_body_bytes_are_ignored() -> None:
    (m,) = al.decode(body(2, struct.pack("<I", 10) + b"\x01x\x00" + b"future"), TEAM).messages
    assert m == al.Hello(10, "x")


def test_encoder_refuses_what_decoders_drop() -> None:
    bad: list[al.Message] = [
        al.Port(1, 1, al.ConnKind.NORMAL, 5, 0, "B", "P", 1),
        al.Port(1, 1, al.ConnKind.SUPPRESS, 0, 0, "B", "P", 1),
        al.Port(1, 1, al.ConnKind.NORMAL, 0, 0, "", "P", 1),
        al.Port(1, 1, al.ConnKind.NORMAL, 0, 0, "B" * 256, "P", 1),
        al.Port(1, 1, al.ConnKind.NORMAL, 0, 0, "B", "P", 1 << 63),
        al.Port(1, 1, al.ConnKind.NORMAL, 0, 1 << 31, "B", "P", 1),
        al.Hello(0),
        al.Hello(5, "x", ("",)),
        al.Reply(1, parts=2, error="x"),
        al.Reply(1, part=1, parts=1, report=""),
        al.Reply(1, parts=2, conn=1),
        al.Reply(1),
        al.Request(1, al.Op.CONNECT, "S", "p", al.Endpoint("B", "P", group="")),
    ]
    for m in bad:
        with pytest.raises(al.EncodeError):
            al.encode(TEAM, 1, 1, [m])
    with pytest.raises(al.EncodeError):
        al.encode(TEAM, 1, 1, [al.Port(1, 1, al.ConnKind.NORMAL, 0, 0, "B", "P", "x" * 2000)], limit=al.MTU)


def test_replay_window() -> None:
    w = al.ReplayWindow()
    assert w.accept(100)
    assert not w.accept(100)
    assert w.accept(98) and not w.accept(98)
    assert w.accept(101)
    assert w.accept(101 - 64)  # the 64th before the newest is still in the window
    assert not w.accept(101 - 65)  # older than the window
    assert w.accept(1000) and w.accept(999) and not w.accept(101)


def test_signatures_and_cookies_follow_the_spec() -> None:
    # A signature is sig_tag 1 and 64 bytes after the arguments; anything else there (another
    # tag, or a tag without 64 bytes) is ignored like any extra body bytes.
    req = al.Request(8, al.Op.READ, behavior="B", port="P")
    plain = al.encode_message(req)
    signed = al.encode_message(al.Request(8, al.Op.READ, behavior="B", port="P", signature=bytes(64)))
    assert signed[3:] == plain[3:] + b"\x01" + bytes(64)
    head = al.encode(TEAM, 3, 1, [])

    def with_body(body: bytes, kind: int = al.KIND_REQUEST) -> bytes:
        return head + bytes([kind]) + struct.pack("<H", len(body)) + body

    for extra in (b"\x02" + bytes(64), b"\x01" + bytes(63)):
        assert al.decode(with_body(plain[3:] + extra), TEAM).messages == (req,)
    with pytest.raises(al.EncodeError):
        al.encode_message(al.Request(1, al.Op.LIST, signature=bytes(63)))
    with pytest.raises(al.EncodeError):
        al.encode_message(al.Request(1, 99, signature=bytes(64)))  # unknown op: no signature
    # A cookie is 16 bytes: a shorter body is malformed, a longer one has extra bytes ignored.
    assert cause(with_body(bytes(15), al.KIND_CHALLENGE)) == "malformed"
    assert cause(with_body(bytes(15), al.KIND_ECHO)) == "malformed"
    assert al.decode(with_body(b"c" * 16 + b"more", al.KIND_ECHO), TEAM).messages == (al.Echo(b"c" * 16),)
    with pytest.raises(al.EncodeError):
        al.encode_message(al.Challenge(bytes(17)))


def test_operator_signatures_are_rfc8032_ed25519() -> None:
    # RFC 8032, section 7.1, TEST 1 (the empty message) and TEST 2 (one byte).
    seed = bytes.fromhex("9d61b19deffd5a60ba844af492ec2cc44449c5697b326919703bac031cae7f60")
    assert al.operator_public_key(seed).hex() == "d75a980182b10ab7d54bfed3c964073a0ee172f3daa62325af021a68f707511a"
    assert al._ed_sign(seed, b"").hex() == (
        "e5564300c360ac729086e2cc806e828a84877f1eb8e5d974d873e065"
        "224901555fb8821590a33bacc61e39701cf9b46bd25bf5f0595bbe24655141438e7a100b"
    )
    seed2 = bytes.fromhex("4ccd089b28ff96da9db6c346ec114e0f5b8a319f35aba624da8cf6ed4fb8a6fb")
    assert al.operator_public_key(seed2).hex() == "3d4017c3e843895a92b70aa74d1b7ebc9c982ccf2ec4968cc0cd55f12af4660c"
    assert al._ed_sign(seed2, b"\x72").hex() == (
        "92a009a9f0d4cab8720e820b5f642540a2b27b5416503f8fb3762223ebdb69da"
        "085ac1e43e15996e458f3613d0f11d8c387b2eaeb4302aeeb00d291612bb0c00"
    )
    # The signed bytes bind team, requester and receiver (the golden vectors check the rest).
    req = al.Request(77, al.Op.DISCONNECT, conn=4)
    one = al.sign_request(bytes(32), 9, 1, 2, req).signature
    assert one is not None and len(one) == 64
    for team, requester, receiver in ((8, 1, 2), (9, 3, 2), (9, 1, 3)):
        assert al.sign_request(bytes(32), team, requester, receiver, req).signature != one
    assert al.signed_request_bytes(9, 1, 2, req)[:26] == b"ayllu operator request v1\0"
    with pytest.raises(ValueError):
        al.operator_public_key(bytes(31))
