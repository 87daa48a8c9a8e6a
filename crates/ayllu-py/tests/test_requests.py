"""Control requests to other nodes (N2) on a deterministic team: CONNECT, DISCONNECT, LIST,
WHY and READ through ``Node.request_*``, their answers through ``Node.request_status``
(mirrors ayllu-core's tests/remote.rs and tests/access.rs where they apply)."""

from __future__ import annotations

import pytest

import ayllu
from conftest import Relay


def team() -> tuple[ayllu.Team, ayllu.Node, ayllu.Node]:
    """Nodes 1 and 2, each with Relays R and S (int port V)."""
    t = ayllu.Team()
    a, b = t.add(1), t.add(2)
    for n in (a, b):
        n.create(Relay, "R")
        n.create(Relay, "S")
    return t, a, b


def answer(t: ayllu.Team, node: ayllu.Node, request: int) -> ayllu.RequestStatus:
    """Step the team until `request` is no longer pending (one round trip is a few steps)."""
    for _ in range(10):
        s = node.request_status(request)
        if not s.pending:
            return s
        t.advance(0.01)
    raise AssertionError(f"request {request} still pending: {node.request_status(request)}")


def test_a_request_is_pending_once_sent_then_done() -> None:
    t, a, _b = team()
    r = a.request_read(2, "R", "V")
    s = a.request_status(r)
    assert s == ayllu.RequestStatus("pending", 1)
    assert s.pending and not s.done and not s.failed
    s = answer(t, a, r)
    assert s.done and s.result == 0 and s.error is None


def test_request_connect_makes_the_connection_on_the_source_node_and_values_flow() -> None:
    t, a, b = team()
    r = a.request_connect(ayllu.remote(2, "R", "V"), ayllu.local("S", "V"))
    s = answer(t, a, r)
    assert s.done, s
    conn = s.result
    assert isinstance(conn, int)
    (c,) = b.report().connections
    assert (c.id, c.requested_by, c.kind) == (conn, 1, "Normal")
    assert c.destination.Node.to_dict() == {"node": 1, "behavior": "S", "port": "V"}
    assert a.report().connections == [], "the connection belongs to node 2"
    b.write("R", "V", 7)
    t.advance(0.02)
    assert a.read("S", "V") == 7
    why = a.why("S", "V")
    assert why.supplier.to_dict() == {"node": 2, "conn": conn}


def test_request_connect_takes_a_kind_and_a_priority() -> None:
    t, a, b = team()
    r = a.request_connect(ayllu.remote(2, "R", "V"), ayllu.remote(1, "S", "V"), ayllu.suppress(0.5), priority=3)
    assert answer(t, a, r).done
    (c,) = b.report().connections
    assert (c.kind.to_dict(), c.priority) == ({"Suppress": 0.5}, 3)


def test_request_disconnect_removes_it() -> None:
    t, a, b = team()
    conn = answer(t, a, a.request_connect(ayllu.remote(2, "R", "V"), ayllu.local("S", "V"))).result
    s = answer(t, a, a.request_disconnect(2, conn))
    assert s.done and s.result == conn, "DISCONNECT answers with the removed connection"
    assert b.report().connections == []
    b.write("R", "V", 9)
    t.advance(0.02)
    assert a.read("S", "V") == 0
    s = answer(t, a, a.request_disconnect(2, conn))
    assert s.failed and s.error is not None and str(conn) in s.error, s


def test_request_list_why_and_read_return_reports_and_values() -> None:
    t, a, b = team()
    b.write("R", "V", 5)
    listed = answer(t, a, a.request_list(2)).result
    assert isinstance(listed, ayllu.Report)
    assert listed.node == 2
    assert sorted(x.name for x in listed.behaviors) == ["R", "S"]
    why = answer(t, a, a.request_why(2, "R", "V")).result
    assert isinstance(why, ayllu.Report)
    assert why.value == 5 and why.fresh
    assert why.supplier == b.why("R", "V").supplier
    assert str(why).startswith("n2:R.V")
    assert answer(t, a, a.request_read(2, "R", "V")).result == 5


def test_a_request_about_what_does_not_exist_fails_with_the_receivers_reason() -> None:
    t, a, _b = team()
    s = answer(t, a, a.request_read(2, "Nobody", "V"))
    assert s.failed and s.error is not None and "Nobody" in s.error
    s = answer(t, a, a.request_connect(ayllu.remote(2, "R", "Nope"), ayllu.local("S", "V")))
    assert s.failed and s.error is not None and "Nope" in s.error


def test_a_request_to_a_node_that_does_not_exist_fails_after_its_retries() -> None:
    # N2: resent every 200 ms, 25 sends, then failed.
    t, a, _b = team()
    r = a.request_list(9)
    t.advance(1.0)
    s = a.request_status(r)
    assert s.pending and 5 <= s.sends <= 6, s
    t.advance(5.0)
    s = a.request_status(r)
    assert s.failed and s.error == "no answer from n9 after 25 tries", s


def test_misuse_raises_the_packages_errors() -> None:
    _t, a, _b = team()
    with pytest.raises(ayllu.InvalidError, match="source"):
        a.request_connect(ayllu.local("R", "V"), ayllu.remote(2, "S", "V"))
    with pytest.raises(ayllu.InvalidError):
        a.request_connect(ayllu.broadcast("G", "R", "V"), ayllu.local("S", "V"))
    with pytest.raises(TypeError, match="endpoint"):
        a.request_connect("R.V", ayllu.local("S", "V"))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="period"):
        a.request_connect(ayllu.remote(2, "R", "V"), ayllu.local("S", "V"), ("suppress", None))
    with pytest.raises(ayllu.NotFoundError, match="never sent"):
        a.request_status(12345)
