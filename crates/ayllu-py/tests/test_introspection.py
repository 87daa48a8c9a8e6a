"""Introspection from Python: why() and report() as Python objects (mirrors ayllu-core's
tests/introspection.rs)."""

from __future__ import annotations

import ayllu
from conftest import link, put, wiring


def test_why_says_what_blocks_a_port_and_for_how_long() -> None:
    node = wiring(["Planner", "Bumper", "Motor"])
    link(node, "Planner", "Motor")
    stop = link(node, "Bumper", "Motor", ayllu.suppress(2.0))
    put(node, 0, "Bumper", 1)
    put(node, 500, "Planner", 4)
    r = node.why("Motor", "V")
    assert isinstance(r, ayllu.Report)
    assert r.input_blocked == "Suppressed"
    assert r.internal_output_blocked is None
    assert r.windows[0].kind == "Suppress"
    assert r.windows[0].remaining == 1.5
    assert r.windows[0].holder.conn == stop
    assert r.counters == {"suppressed": 1}
    assert (r.fresh, r.supplier) == (False, None)
    assert len(r.incoming) == 2
    assert "input     BLOCKED (suppressed)" in str(r)
    plain = r.to_dict()
    assert plain["windows"][0]["remaining"] == 1.5


def test_report_lists_behaviors_connections_and_counters() -> None:
    node = wiring(["A", "B"])
    link(node, "A", "B")
    put(node, 0, "A", 3)
    r = node.report()
    assert r.node == 1
    assert [b.name for b in r.behaviors] == ["A", "B"]
    assert r.behaviors[1].ports[3].value == 3
    assert len(r.connections) == 1
    assert r.connections[0].kind == "Normal"
