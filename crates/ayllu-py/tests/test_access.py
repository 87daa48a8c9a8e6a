"""Open teams, bounded (docs/semantics.md D9.1-D9.3) from Python: ``Node.set_access`` and
``Node.set_limits`` seen through requests between the nodes of a deterministic team (mirrors
ayllu-core's tests/access.rs)."""

from __future__ import annotations

import pytest

import ayllu
from conftest import Relay


def team(n: int = 3) -> tuple[ayllu.Team, list[ayllu.Node]]:
    t = ayllu.Team()
    nodes = [t.add(i) for i in range(1, n + 1)]
    for node in nodes:
        node.create(Relay, "R")
    return t, nodes


def answer(t: ayllu.Team, node: ayllu.Node, request: int) -> ayllu.RequestStatus:
    for _ in range(10):
        s = node.request_status(request)
        if not s.pending:
            return s
        t.advance(0.01)
    raise AssertionError(f"request {request} still pending")


def connect(t: ayllu.Team, asker: ayllu.Node, target: int, kind: ayllu.Kind = ayllu.NORMAL) -> ayllu.RequestStatus:
    """`asker` asks node `target` to connect its R.V to asker's R.V."""
    return answer(t, asker, asker.request_connect(ayllu.remote(target, "R", "V"), ayllu.local("R", "V"), kind))


def counters(node: ayllu.Node) -> dict[str, int]:
    c: dict[str, int] = node.report().counters
    return c


def test_structure_changes_by_request_follow_the_access_rule() -> None:
    t, (me, n2, n3) = team()
    me.set_access(structure="none")
    s = connect(t, n2, 1)
    assert s.failed and s.error is not None, s
    assert "not allowed" in s.error and "n2" in s.error and "access rules" in s.error, s.error
    assert counters(me).get("not_allowed") == 1
    assert me.report().connections == []
    assert answer(t, n2, n2.request_list(1)).done, "LIST stays open"
    assert answer(t, n2, n2.request_read(1, "R", "V")).done, "READ stays open"

    me.set_access(structure=[2])
    ok = connect(t, n2, 1)
    assert ok.done, ok
    assert connect(t, n3, 1).failed
    assert len(me.report().connections) == 1
    # DISCONNECT is a structure change too.
    assert answer(t, n3, n3.request_disconnect(1, ok.result)).failed
    assert answer(t, n2, n2.request_disconnect(1, ok.result)).done
    assert me.report().connections == []


def test_port_writes_follow_the_access_rule() -> None:
    t, (me, n2, n3) = team()
    me.set_access(ports=[2])
    n3.connect(ayllu.local("R", "V"), ayllu.remote(1, "R", "V"), ayllu.override_in(5.0))
    n3.write("R", "V", 8)
    t.advance(0.02)
    assert me.read("R", "V") == 0
    assert counters(me).get("not_allowed") == 1
    assert me.why("R", "V").windows == [], "no window from a refused message"
    n2.connect(ayllu.local("R", "V"), ayllu.remote(1, "R", "V"))
    n2.write("R", "V", 7)
    t.advance(0.02)
    assert me.read("R", "V") == 7
    # The node's own code is never restricted.
    me.set_access(ports="none", structure="none")
    me.write("R", "V", 3)
    assert me.read("R", "V") == 3


def test_windows_longer_than_the_limit_are_refused_not_clamped() -> None:
    t, (me, n2, _n3) = team()
    me.set_limits(max_remote_period=1.0)
    s = connect(t, n2, 1, ayllu.override_in(2.0))
    assert s.failed and s.error is not None and "limit" in s.error and "1.000s" in s.error, s
    assert me.report().connections == []
    assert counters(me).get("not_allowed") == 1
    assert connect(t, n2, 1, ayllu.override_in(1.0)).done, "up to the limit is fine"
    # A port message opening a longer window is dropped and counted too_long.
    n2.connect(ayllu.local("R", "V"), ayllu.remote(1, "R", "V"), ayllu.inhibit(3.0))
    n2.write("R", "V", 1)
    t.advance(0.02)
    assert counters(me).get("too_long") == 1
    assert me.why("R", "V").windows == []


def test_connections_made_by_request_are_capped_per_node_and_in_all() -> None:
    t, nodes = team(4)
    me, n2, n3, n4 = nodes
    me.set_limits(remote_connections=5, remote_connections_per_node=3)
    for _ in range(3):
        assert connect(t, n2, 1).done
    s = connect(t, n2, 1)
    assert s.failed and s.error is not None and "3 per node" in s.error, s
    assert connect(t, n3, 1).done
    assert connect(t, n3, 1).done
    s = connect(t, n4, 1)
    assert s.failed and s.error is not None and "5 in all" in s.error, s
    assert counters(me).get("not_allowed") == 2
    # Connections made in code do not count and are not capped.
    for _ in range(10):
        me.connect(ayllu.local("R", "V"), ayllu.local("R", "V"))
    assert len(me.report().connections) == 15


def test_requests_over_a_senders_rate_go_unanswered_until_the_rate_allows() -> None:
    t, (me, n2, n3) = team()
    me.set_limits(requests_per_second=1, requests_burst=1)
    first, second = n2.request_list(1), n2.request_list(1)
    other = n3.request_list(1)
    t.advance(0.05)
    assert n2.request_status(first).done
    assert n2.request_status(second).pending
    assert n3.request_status(other).done, "another sender has its own rate"
    assert counters(me).get("rate_limited", 0) >= 1
    t.advance(1.2)
    assert n2.request_status(second).done, "answered once the rate allows, by a resend"


def test_defaults_are_restored_by_calls_without_arguments() -> None:
    t, (me, n2, _n3) = team()
    me.set_access(ports="none", structure="none")
    me.set_limits(max_remote_period=1.0)
    me.set_access()
    me.set_limits()
    assert connect(t, n2, 1, ayllu.override_in(600.0)).done
    assert connect(t, n2, 1, ayllu.override_in(601.0)).failed


def test_misuse_raises_the_packages_errors() -> None:
    _t, (me, _n2, _n3) = team()
    with pytest.raises(ayllu.InvalidError, match='"all", "none" or a list'):
        me.set_access(structure="some")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="ports="):
        me.set_access(ports=2.5)  # type: ignore[arg-type]
    with pytest.raises(ayllu.InvalidError, match="negative"):
        me.set_limits(max_remote_period=-1.0)
    with pytest.raises(TypeError):
        me.set_limits(5)  # type: ignore[call-arg]
