"""Rule D3.7 from Python: aggregating ports follow their holder (mirrors ayllu-core's
tests/holder_release.rs)."""

from __future__ import annotations

from fan_in import FanIn


def test_a_stale_priority_holder_releases_the_port() -> None:
    r = FanIn(0, "priority", priorities=[9, 3], lifespan=0.1)
    r.send(0, 0, 90)
    r.send(1, 50, 30)
    assert r.read() == 90, "still fresh: the higher priority holds"
    assert r.why().counters == {"absorbed": 1}
    r.at(100)
    assert r.why().empty, "released at last write + lifespan"
    assert r.node.get("AGG", "In") is None
    r.send(1, 500, 31)
    assert (r.read(), r.supplier_conn()) == (31, r.conns[1])
    r.send(0, 5001, 91)
    assert (r.read(), r.supplier_conn()) == (91, r.conns[0]), "the old holder outranks again"


def test_a_stale_max_or_min_holder_releases_the_port() -> None:
    for kind, high, low, expect in [("max", 9.0, 3.0, 3.0), ("min", 3.0, 9.0, 9.0)]:
        r = FanIn(0.0, kind, lifespan=0.1)
        r.send(0, 0, high)
        r.send(1, 99, low)
        assert r.read() == high
        r.send(1, 100, low)
        assert r.read() == expect, "at 100 ms the stale extreme no longer counts"
        assert r.supplier_conn() == r.conns[1]
        assert r.propagated() == 2


def test_a_stale_sum_starts_again() -> None:
    r = FanIn(0, "sum", lifespan=0.1)
    r.send(0, 0, 5)
    r.send(1, 60, 5)
    r.send(0, 150, 1)
    assert r.read() == 11
    r.send(1, 300, 2)
    assert r.read() == 2


def test_a_renewing_priority_holder_keeps_the_port_across_window_boundaries() -> None:
    r = FanIn(0, "priority", priorities=[9, 3], window=0.1)
    for k in range(100):
        r.send(0, 10 * k, 900 + k)
        r.send(1, 10 * k + 5, 300 + k)
        assert r.supplier_conn() == r.conns[0]
        assert r.tap() == 900 + k
    assert r.propagated() == 100, "only the holder's values reached the tap"
    r.send(1, 1085, 1)
    assert r.supplier_conn() == r.conns[0], "lease still running at 1085 ms"
    r.send(1, 1090, 2)
    assert (r.read(), r.supplier_conn()) == (2, r.conns[1])


def test_removing_the_supplying_connection_releases_the_port() -> None:
    r = FanIn(0, "priority", priorities=[9, 3])
    r.send(0, 0, 90)
    r.send(1, 1, 30)
    r.node.disconnect(r.conns[0])
    assert r.why().empty
    r.send(1, 2, 31)
    assert (r.read(), r.supplier_conn()) == (31, r.conns[1])
