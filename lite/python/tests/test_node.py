"""LiteNode tests over real UDP sockets on 127.0.0.1: two lite nodes (and, where a node's
answers are needed, a scripted fake node) exchange datagrams. They check what the module
promises: port writes with connection-kind semantics for storing, HELLO and peer learning,
requests with retries and multi-part report reassembly, and authentication with replay
protection."""

from __future__ import annotations

import dataclasses
import json
import socket
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

import ayllu_lite as al

TEAM = 42
KEY = bytes(range(1, 33))
LOOP = ("127.0.0.1", 0)
VECTORS = Path(__file__).resolve().parents[3] / "spec" / "vectors" / "vectors.json"


def wait_for(cond: Callable[[], bool], *nodes: al.LiteNode, timeout: float = 2.0) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        for n in nodes:
            n.poll(0.01)
        if cond():
            return
    raise AssertionError("condition not reached")


@pytest.fixture
def pair() -> Iterator[tuple[al.LiteNode, al.LiteNode]]:
    a = al.LiteNode(1, TEAM, bind=LOOP, name="a")
    b = al.LiteNode(2, TEAM, bind=LOOP, name="b")
    a.add_peer(2, b.address)
    b.add_peer(1, a.address)
    yield a, b
    a.close()
    b.close()


def test_normal_write_stores_and_calls_back(pair: tuple[al.LiteNode, al.LiteNode]) -> None:
    a, b = pair
    seen: list[tuple[Any, ...]] = []
    a.expose("Drive", "Speed", 0.0, on_write=lambda *args: seen.append(args))
    b.write(1, "Drive", "Speed", 1.5)
    wait_for(lambda: a.get("Drive", "Speed") == 1.5, a)
    assert seen == [("Drive", "Speed", 1.5, 2, 1)]
    assert a.ports() == {"Drive": {"Speed": 1.5}}


def test_drops_are_counted(pair: tuple[al.LiteNode, al.LiteNode]) -> None:
    a, b = pair
    a.expose("Drive", "Speed", 0.0)
    b.write(1, "Drive", "Speed", 3)  # an int into a float port
    b.write(1, "Nope", "Speed", 1.0)
    b.write(1, "Drive", "Nope", 1.0)
    wait_for(lambda: sum(a.counters.get(c, 0) for c in ("type_mismatch", "unknown_behavior", "unknown_port")) == 3, a)
    assert a.get("Drive", "Speed") == 0.0


def test_stale_port_messages_are_dropped(pair: tuple[al.LiteNode, al.LiteNode]) -> None:
    a, _ = pair
    a.expose("B", "P", 0)
    raw = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        for i, seq in enumerate((10, 9, 10, 11)):
            m = al.Port(7, seq, al.ConnKind.NORMAL, 0, 0, "B", "P", seq)
            raw.sendto(al.encode(TEAM, 9, 100 + i, [m]), a.address)
        wait_for(lambda: a.counters.get("received", 0) == 4, a)
        assert a.counters["stale"] == 2
        assert a.get("B", "P") == 11
    finally:
        raw.close()


def test_group_messages_apply_only_in_joined_groups() -> None:
    # D-S10.6: a PORT naming a group reaches every node sharing a broadcast address; only a
    # member applies it, a non-member counts not_member; a node-addressed PORT applies as before.
    a = al.LiteNode(1, TEAM, bind=LOOP, groups=("arm",))
    try:
        a.expose("B", "P", 0)
        frm = ("127.0.0.1", 9)
        to_legs = al.Port(7, 1, al.ConnKind.NORMAL, 0, 0, "B", "P", 5, group="legs")
        assert a.handle_datagram(al.encode(TEAM, 9, 100, [to_legs]), frm) is None
        assert a.counters["not_member"] == 1
        assert a.get("B", "P") == 0
        to_arm = al.Port(7, 2, al.ConnKind.NORMAL, 0, 0, "B", "P", 6, group="arm")
        a.handle_datagram(al.encode(TEAM, 9, 101, [to_arm]), frm)
        assert a.get("B", "P") == 6
        to_node = al.Port(7, 3, al.ConnKind.NORMAL, 0, 0, "B", "P", 7)
        a.handle_datagram(al.encode(TEAM, 9, 102, [to_node]), frm)
        assert a.get("B", "P") == 7
        assert a.counters["not_member"] == 1
        # The golden vector of a group message, as the Rust encoder writes it.
        vectors = json.loads(VECTORS.read_text())["vectors"]
        (v,) = (v for v in vectors if v["name"] == "port_to_group")
        (m,) = al.decode(bytes.fromhex(v["hex"]), v["team"]).messages
        assert isinstance(m, al.Port) and m.group == "arm" and m.value == 42
    finally:
        a.close()


def test_suppress_blocks_connection_writes_for_its_period(pair: tuple[al.LiteNode, al.LiteNode]) -> None:
    a, b = pair
    a.expose("B", "P", 0)
    b.write(1, "B", "P", 5, kind=al.ConnKind.SUPPRESS, period_s=0.3)  # never written itself
    b.write(1, "B", "P", 1)
    wait_for(lambda: a.counters.get("suppressed", 0) == 1, a)
    assert a.get("B", "P") == 0
    a.set("B", "P", 2)  # the lite program's own writes are never suppressed (D6.5)
    assert a.get("B", "P") == 2
    time.sleep(0.35)
    b.write(1, "B", "P", 3)
    wait_for(lambda: a.get("B", "P") == 3, a)


def test_override_in_admits_only_its_holder(pair: tuple[al.LiteNode, al.LiteNode]) -> None:
    a, b = pair
    a.expose("B", "P", 0)
    b.write(1, "B", "P", 7, kind=al.ConnKind.OVERRIDE_IN, period_s=5.0)
    b.write(1, "B", "P", 8)  # another connection: no pass
    wait_for(lambda: a.counters.get("overridden_in", 0) == 1, a)
    assert a.get("B", "P") == 7
    b.write(1, "B", "P", 9, kind=al.ConnKind.OVERRIDE_IN, period_s=5.0)  # same connection
    wait_for(lambda: a.get("B", "P") == 9, a)


def test_inhibit_and_write_inhibit_do_not_write(pair: tuple[al.LiteNode, al.LiteNode]) -> None:
    a, b = pair
    a.expose("B", "P", 0)
    received = a.counters.get("received", 0)
    b.write(1, "B", "P", 1, kind=al.ConnKind.INHIBIT, period_s=0.1)
    b.write(1, "B", "P", 2, kind=al.ConnKind.WRITE_INHIBIT, period_s=0.1)
    # Both arrived and were applied as windows, and neither wrote the value (its C twin checks
    # the same after injecting them).
    wait_for(lambda: a.counters.get("received", 0) >= received + 2, a)
    assert a.get("B", "P") == 0
    # Override-out writes: its window stops only propagation, which a lite port never does.
    b.write(1, "B", "P", 3, kind=al.ConnKind.OVERRIDE_OUT, period_s=0.1)
    wait_for(lambda: a.get("B", "P") == 3, a)


def test_hello_teaches_addresses(pair: tuple[al.LiteNode, al.LiteNode]) -> None:
    a, _ = pair
    c = al.LiteNode(3, TEAM, bind=LOOP, peers=[(1, a.address)], hello_interval_ms=50)
    try:
        c.poll(0)  # the first poll announces
        wait_for(lambda: 3 in a.peers(), a)
        assert a.peers()[3] == c.address
        a.expose("B", "P", "")
        c.expose("B", "P", "")
        a.write(3, "B", "P", "hi")
        wait_for(lambda: c.get("B", "P") == "hi", c)
        c.close()
        time.sleep(0.2)  # 3 x 50 ms without a word: forgotten (N6)
        assert 3 not in a.peers()
    finally:
        c.close()


def test_hello_announces_name_and_groups() -> None:
    raw = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    raw.bind(LOOP)
    node = al.LiteNode(5, TEAM, bind=LOOP, name="cam", groups=["Peers"], peers=[(9, raw.getsockname())])
    try:
        node.poll(0)
        data, _ = raw.recvfrom(9000)
        assert al.decode(data, TEAM).messages == (al.Hello(1000, "cam", ("Peers",)),)
        with pytest.raises(al.EncodeError):
            al.LiteNode(6, TEAM, bind=LOOP, groups=[""])
    finally:
        node.close()
        raw.close()


def test_list_report_text_matches_the_c_implementation(pair: tuple[al.LiteNode, al.LiteNode]) -> None:
    # The same exposures as lite/c/tests/test_node.c, which checks the same text.
    a, b = pair
    a.expose("Cam", "State", "ready")
    a.expose("Cam", "On", True)
    a.expose('Arm "2"', "Joint", 4)
    a.start()
    r = b.request(1, al.Request(0, al.Op.LIST))
    assert r.report == (
        '{"node":1,"lite":true,"behaviors":[{"name":"Cam","ports":["State","On"]},'
        '{"name":"Arm \\"2\\"","ports":["Joint"]}]}'
    )


def test_lite_answers_read_and_list_and_refuses_the_rest(pair: tuple[al.LiteNode, al.LiteNode]) -> None:
    a, b = pair
    a.expose("Cam", "Target", al.Vector((1.0, 2.0)))
    a.start()
    assert b.read(1, "Cam", "Target") == (1.0, 2.0)
    assert b.list_node(1)["behaviors"] == [{"name": "Cam", "ports": ["Target"]}]
    with pytest.raises(al.RequestFailed, match="not supported"):
        b.connect(1, "Cam", "Target", "X", "Y")
    with pytest.raises(al.RequestFailed, match="no port"):
        b.read(1, "Cam", "Nope")
    with pytest.raises(al.RequestFailed, match="unknown operation"):
        b._answer(1, al.Request(0, 77))
    a.expose("Cam", "Log", "x" * 2000)  # a value never travels in parts
    with pytest.raises(al.RequestFailed, match="too large"):
        b.read(1, "Cam", "Log")
    with pytest.raises(al.EncodeError):
        b.write(1, "Cam", "Log", "y" * 2000)


def _lite_with_a_large_list(node_id: int, key: bytes | None = None, **kwargs: Any) -> al.LiteNode:
    """A lite node whose LIST answer is several times a LIST request, with a 400-byte text port."""
    lite = al.LiteNode(node_id, TEAM, key=key, bind=LOOP, **kwargs)
    for port in ("LeftWheelSpeed", "RightWheelSpeed", "BatteryVoltage", "Temperature"):
        lite.expose("Drive", port, 0.0)
    for port in ("Heading", "Odometry"):
        lite.expose("Nav", port, 0.0)
    lite.expose("Log", "Text", "x" * 400)
    return lite


def _datagrams(sock: socket.socket, key: bytes | None = None) -> list[tuple[int, al.Datagram]]:
    """Every datagram waiting at ``sock`` (or arriving within 0.2 s), with its size."""
    got: list[tuple[int, al.Datagram]] = []
    sock.settimeout(0.2)
    while True:
        try:
            data = sock.recv(9000)
        except TimeoutError:
            return got
        got.append((len(data), al.decode(data, TEAM, key)))


def test_a_forged_request_is_answered_within_three_times_what_its_address_sent() -> None:
    # Return routability (spec, "CHALLENGE and ECHO"): a forger writes a victim's address as the
    # source of requests; the lite node sends that address at most 3x the bytes it received
    # from it. It sends no CHALLENGE: an answer over the budget is not sent, and is counted.
    lite = _lite_with_a_large_list(1)
    victim = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    victim.bind(LOOP)
    at = victim.getsockname()
    try:
        forged = al.encode(TEAM, 66, 1, [al.Request(1000, al.Op.LIST)])
        assert len(forged) == 32
        assert lite.handle_datagram(forged, at) is None
        assert lite.counters["amplification_limited"] == 1
        got = _datagrams(victim)
        # Only the greeting a node heard for the first time gets (one per node id, as Ayllu
        # nodes do): no answer.
        assert [type(m) for _, d in got for m in d.messages] == [al.Hello]

        # A flood at the same victim, LISTs and READs of the 400-byte text: the answers that go
        # out stay within 3x of what came "from" the victim.
        sent_in = len(forged)
        for i in range(2, 60):
            read = al.Request(1000 + i, al.Op.READ, behavior="Log", port="Text")
            op = al.Request(1000 + i, al.Op.LIST) if i % 2 else read
            data = al.encode(TEAM, 66, i, [op])
            sent_in += len(data)
            lite.handle_datagram(data, at)
        answers = [(size, d) for size, d in _datagrams(victim) if any(isinstance(m, al.Reply) for m in d.messages)]
        answered = sum(size for size, _ in answers)
        assert 0 < answered <= al.AMPLIFICATION_FACTOR * sent_in, (answered, sent_in)
        assert lite.counters["amplification_limited"] > 30
        assert lite.counters["amplification_limited"] + len(answers) == 59
    finally:
        victim.close()
        lite.close()


@pytest.mark.parametrize("key", [None, KEY], ids=["open", "keyed"])
def test_a_real_requester_gets_a_large_answer_at_a_retry(key: bytes | None) -> None:
    # A real requester's retries add to its budget: an answer larger than 3x one request goes
    # out at a retry, at the latest the first whose total reaches a third of it (the HELLOs the
    # two exchange when they first hear each other count too). An authenticated request proves
    # nothing to a lite node (it cannot tell a replay from before its restart), so the keyed
    # team is held to the same rule.
    lite = _lite_with_a_large_list(1, key)
    asker = al.LiteNode(2, TEAM, key=key, bind=LOOP, hello_interval_ms=600_000)
    try:
        lite.start()
        asker.poll()  # its first HELLO goes nowhere: it knows no peer yet
        report = asker.list_node(lite.address)
        assert report["behaviors"][0]["ports"][:2] == ["LeftWheelSpeed", "RightWheelSpeed"]
        request = len(al.encode(TEAM, 2, 1, [al.Request(1, al.Op.LIST)], key=key))
        text = json.dumps(report, separators=(",", ":"))
        answer = len(al.encode(TEAM, 1, 1, [al.Reply(1, report=text)], key=key))
        sends = -(-answer // (al.AMPLIFICATION_FACTOR * request))
        assert answer > al.AMPLIFICATION_FACTOR * request and sends > 1
        limited = lite.counters["amplification_limited"]
        assert 1 <= limited <= sends - 1, (limited, sends)
        # A READ whose answer is within 3x is answered at the first send.
        assert asker.read(lite.address, "Nav", "Heading") == 0.0
        assert lite.counters["amplification_limited"] == limited
        # The 400-byte text (a 440-byte answer to a 40-byte READ), after what was left of the
        # budget is spent: at a retry too.
        assert asker.read(lite.address, "Log", "Text") == "x" * 400
        assert lite.counters["amplification_limited"] > limited
        ((received, answered),) = lite._budgets.values()
        assert answered <= al.AMPLIFICATION_FACTOR * received
    finally:
        asker.close()
        lite.close()


def test_the_budget_table_is_bounded_and_replaces_the_least_recently_heard() -> None:
    lite = al.LiteNode(1, TEAM, bind=LOOP)
    try:
        empty = al.encode(TEAM, 66, 1, [])
        first = ("127.0.0.1", 1)
        lite.handle_datagram(empty, first)
        for port in range(2, al.BUDGET_TABLE_MAX + 1):
            lite.handle_datagram(empty, ("127.0.0.1", port))
        lite.handle_datagram(empty, first)  # heard again: now the most recent
        lite.handle_datagram(empty, ("127.0.0.2", 1))
        assert len(lite._budgets) == al.BUDGET_TABLE_MAX
        assert first in lite._budgets and ("127.0.0.1", 2) not in lite._budgets
        assert lite._budgets[first] == [2 * len(empty), 0]
    finally:
        lite.close()


class FakeNode:
    """A scripted Ayllu node on a raw socket: answers requests with `answer(request)` ->
    list of replies, and can ignore the first few requests or leave out parts once. With
    `cookie`, it answers an address that has not echoed the cookie only with a CHALLENGE, as a
    node limiting amplification does (spec, "Return routability")."""

    def __init__(
        self,
        answer: Callable[[al.Request], list[al.Reply]],
        ignore: int = 0,
        key: bytes | None = None,
        cookie: bytes | None = None,
    ):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(LOOP)
        self.sock.settimeout(0.05)
        self.address = self.sock.getsockname()
        self.answer, self.ignore, self.key, self.cookie = answer, ignore, key, cookie
        self.requests: list[al.Request] = []
        self.omit_part_once: int | None = None
        self.echoes: list[tuple[tuple[str, int], bytes]] = []  # (from, cookie)
        self.proven: set[tuple[str, int]] = set()
        self.challenged = 0
        self.seq = 1 << 32
        self.stop = False
        self.thread = threading.Thread(target=self.run, daemon=True)
        self.thread.start()

    def run(self) -> None:
        while not self.stop:
            try:
                data, addr = self.sock.recvfrom(9000)
            except (TimeoutError, OSError):
                continue
            for m in al.decode(data, TEAM, self.key).messages:
                if isinstance(m, al.Echo):
                    self.echoes.append((addr, m.cookie))
                    if m.cookie == self.cookie:
                        self.proven.add(addr)
                if not isinstance(m, al.Request):
                    continue
                self.requests.append(m)
                if len(self.requests) <= self.ignore:
                    continue
                if self.cookie is not None and addr not in self.proven:
                    self.challenged += 1
                    self.seq += 1
                    self.sock.sendto(al.encode(TEAM, 50, self.seq, [al.Challenge(self.cookie)], key=self.key), addr)
                    continue
                for r in self.answer(m):
                    if r.part == self.omit_part_once:
                        self.omit_part_once = None
                        continue
                    self.seq += 1
                    self.sock.sendto(al.encode(TEAM, 50, self.seq, [r], key=self.key), addr)

    def close(self) -> None:
        self.stop = True
        self.thread.join()
        self.sock.close()


def test_requests_are_retried_until_answered() -> None:
    node = FakeNode(lambda r: [al.Reply(r.id, conn=12)], ignore=2)
    lite = al.LiteNode(9, TEAM, bind=LOOP)
    try:
        conn = lite.connect(
            node.address, "Observer", "Rotate", "Motor", "Turn", kind=al.ConnKind.OVERRIDE_IN, period_s=0.2, priority=3
        )
        assert conn == 12
        assert len(node.requests) == 3
        assert len({r.id for r in node.requests}) == 1  # the same id every time (idempotent)
        r = node.requests[0]
        assert r.destination == al.Endpoint("Motor", "Turn", node=9)
        assert (r.conn_kind, r.period_ns, r.priority) == (al.ConnKind.OVERRIDE_IN, 200_000_000, 3)
    finally:
        lite.close()
        node.close()


def test_request_gives_up_after_the_retry_limit(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(al, "RETRY_INTERVAL_S", 0.02)
    monkeypatch.setattr(al, "RETRY_LIMIT", 4)
    node = FakeNode(lambda r: [], ignore=1000)
    lite = al.LiteNode(9, TEAM, bind=LOOP)
    try:
        with pytest.raises(al.RequestTimeout, match="4 tries"):
            lite.read(node.address, "B", "P")
        assert len(node.requests) == 4
    finally:
        lite.close()
        node.close()


def test_multipart_report_is_reassembled_and_missing_parts_asked_again() -> None:
    report = json.dumps({"node": 50, "behaviors": [{"name": f"B{i}", "text": "ñ" * 40} for i in range(30)]})
    chunks = [report[i : i + 400] for i in range(0, len(report), 400)]

    def answer(r: al.Request) -> list[al.Reply]:
        return [al.Reply(r.id, part=i, parts=len(chunks), report=c) for i, c in enumerate(chunks)]

    node = FakeNode(answer, key=KEY)
    node.omit_part_once = 1
    lite = al.LiteNode(9, TEAM, bind=LOOP, key=KEY)
    try:
        lite.start()  # the background thread handles the replies this time
        assert lite.list_node(node.address) == json.loads(report)
        assert len(node.requests) == 2
    finally:
        lite.close()
        node.close()


def test_challenge_is_echoed_and_the_report_still_reassembles(monkeypatch: pytest.MonkeyPatch) -> None:
    # Retries are 10 s apart here, so the answer can only come in time if the ECHO went out
    # and the request was sent again at once, as the CHALLENGE asks.
    monkeypatch.setattr(al, "RETRY_INTERVAL_S", 10.0)
    report = json.dumps({"node": 50, "behaviors": [{"name": f"B{i}", "text": "x" * 50} for i in range(40)]})
    chunks = [report[i : i + 500] for i in range(0, len(report), 500)]
    assert len(chunks) > 1

    def answer(r: al.Request) -> list[al.Reply]:
        return [al.Reply(r.id, part=i, parts=len(chunks), report=c) for i, c in enumerate(chunks)]

    cookie = b"0123456789abcdef"
    node = FakeNode(answer, cookie=cookie)
    lite = al.LiteNode(9, TEAM, bind=LOOP)
    try:
        r = lite.request(node.address, al.Request(0, al.Op.LIST), timeout=3.0)
        assert json.loads(r.report or "") == json.loads(report)
        # One ECHO, from the lite node's address, with the CHALLENGE's cookie; then the same
        # request once more, answered in full and reassembled.
        assert node.echoes == [(lite.address, cookie)]
        assert node.challenged == 1
        assert len(node.requests) == 2
        assert len({r.id for r in node.requests}) == 1
        assert lite.counters["challenged"] == 1
    finally:
        lite.close()
        node.close()


def test_echo_goes_to_the_address_the_challenge_came_from() -> None:
    # The CHALLENGE arrives from another address than the one the request went to: the ECHO
    # goes back to where the CHALLENGE came from, at once, in its own datagram.
    node = FakeNode(lambda r: [], ignore=1000, key=KEY)
    other = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    other.bind(LOOP)
    other.settimeout(2.0)
    lite = al.LiteNode(9, TEAM, bind=LOOP, key=KEY, peers=[(50, node.address)])
    try:
        cookie = bytes(range(100, 116))
        dropped = lite.handle_datagram(al.encode(TEAM, 50, 7, [al.Challenge(cookie)], key=KEY), other.getsockname())
        assert dropped is None
        data, addr = other.recvfrom(9000)
        assert addr == lite.address
        d = al.decode(data, TEAM, KEY)
        assert d.sender == 9 and d.messages == (al.Echo(cookie),)
        # An ECHO received (a lite node sends no CHALLENGE) is ignored, not an unknown kind.
        assert lite.handle_datagram(al.encode(TEAM, 50, 8, [al.Echo(cookie)], key=KEY), other.getsockname()) is None
        assert "unknown_kind" not in lite.counters
    finally:
        lite.close()
        node.close()
        other.close()


def test_operator_secret_signs_structure_changes_for_the_receiver() -> None:
    seed = b"\x11" * 32
    node = FakeNode(lambda r: [al.Reply(r.id, conn=12) if r.op == al.Op.CONNECT else al.Reply(r.id, value=1)])
    lite = al.LiteNode(3, TEAM, bind=LOOP, operator_secret=seed, peers=[(50, node.address)])
    try:
        assert lite.connect(50, "S", "P", "B", "Q") == 12
        assert lite.read(node.address, "S", "P") == 1
        lite.disconnect(node.address, 12)  # by address: the receiver's id comes from the peers
        connect, read, disconnect = node.requests
        for r in (connect, disconnect):
            unsigned = dataclasses.replace(r, signature=None)
            assert r.signature == al.sign_request(seed, TEAM, 3, 50, unsigned).signature
        assert read.signature is None  # only structure changes are signed
        with pytest.raises(LookupError, match="receiver's node id"):
            lite.disconnect(("127.0.0.1", 9), 12)
    finally:
        lite.close()
        node.close()


def test_keyed_team_authenticates_and_refuses_replays() -> None:
    a = al.LiteNode(1, TEAM, bind=LOOP, key=KEY)
    b = al.LiteNode(2, TEAM, bind=LOOP, key=KEY)
    intruder = al.LiteNode(3, TEAM, bind=LOOP, key=bytes(32))
    open_node = al.LiteNode(4, TEAM, bind=LOOP)
    try:
        a.expose("B", "P", 0)
        b.write(a.address, "B", "P", 1)
        wait_for(lambda: a.get("B", "P") == 1, a)
        intruder.write(a.address, "B", "P", 2)
        open_node.write(a.address, "B", "P", 3)
        wait_for(lambda: a.counters.get("bad_mac") == 1 and a.counters.get("unauthenticated") == 1, a)
        # Capture one of b's datagrams and send it twice: the second is a replay.
        raw = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        raw.bind(LOOP)
        b.write(raw.getsockname(), "B", "P", 4)
        data, _ = raw.recvfrom(9000)
        raw.sendto(data, a.address)
        raw.sendto(data, a.address)
        raw.close()
        wait_for(lambda: a.counters.get("replayed") == 1, a)
        assert a.get("B", "P") == 4
    finally:
        for n in (a, b, intruder, open_node):
            n.close()


@pytest.mark.parametrize("node_id", [0, -1, 1 << 32])
def test_a_node_id_outside_1_to_u32_max_is_refused(node_id: int) -> None:
    # 0 is reserved (libayllu's ay_node_new and AylluLite C refuse it too).
    with pytest.raises(ValueError, match=r"node id must be from 1 to 4294967295 \(0 is reserved\)"):
        al.LiteNode(node_id, TEAM, bind=LOOP)


UNUSABLE_PERIODS = [float("nan"), float("inf"), -float("inf"), -1.0, 1e300, 584 * 366 * 86400.0, 1e-12]


@pytest.mark.parametrize("period_s", UNUSABLE_PERIODS)
def test_an_unusable_period_is_refused_naming_the_argument_and_the_range(
    pair: tuple[al.LiteNode, al.LiteNode], period_s: float
) -> None:
    a = pair[0]
    needle = r"period_s=.* is refused.*from 1 ns to 584 years"
    with pytest.raises(al.EncodeError, match=needle):
        a.connection(2, "b", "p", kind=al.ConnKind.SUPPRESS, period_s=period_s)
    with pytest.raises(al.EncodeError, match=needle):
        a.write(2, "b", "p", 1, kind=al.ConnKind.SUPPRESS, period_s=period_s)
    with pytest.raises(al.EncodeError, match=needle):
        a.connect(2, "s", "o", "b", "p", kind=al.ConnKind.SUPPRESS, period_s=period_s)
    with pytest.raises(TypeError, match="period_s must be a finite number of seconds"):
        a.connection(2, "b", "p", kind=al.ConnKind.SUPPRESS, period_s="0.5")  # type: ignore[arg-type]
    # The largest and smallest usable periods still pass.
    a.connection(2, "b", "p", kind=al.ConnKind.SUPPRESS, period_s=1e-9)
    a.connection(2, "b", "p", kind=al.ConnKind.SUPPRESS, period_s=584 * 365 * 86400.0)


def test_a_forged_hello_cannot_keep_an_address_for_months_or_grow_memory() -> None:
    """A HELLO announcing 0xFFFFFFFF ms is believed up to 60 s, as by the Rust node, and a flood
    of invented ids keeps at most MAX_HEARD of them (the one heard longest ago goes)."""
    now = [0.0]
    node = al.LiteNode(1, TEAM, bind=LOOP, clock=lambda: now[0])
    try:
        forged = ("127.0.0.9", 9)
        hello = al.encode(TEAM, 77, 1, [al.Hello(0xFFFFFFFF, "forger", ())])
        assert node.handle_datagram(hello, forged) is None
        assert 77 in node.peers()
        now[0] = 3 * 60.0 + 1.0  # three of the capped period, not three of 49 days
        assert 77 not in node.peers()
        for sender in range(1000, 1000 + al.MAX_HEARD + 50):
            node.handle_datagram(al.encode(TEAM, sender, 1, [al.Hello(1000, "", ())]), forged)
        assert len(node.peers()) <= al.MAX_HEARD
        assert node.counters.get("peer_evicted", 0) >= 50
    finally:
        node.close()
