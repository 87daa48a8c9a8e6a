"""Rule S6 from Python: every connection kind with its period (mirrors ayllu-core's
tests/connection_*.rs)."""

from __future__ import annotations

import ayllu
from conftest import accepted, dropped, link, put, value, wiring


def test_normal_writes_and_propagates() -> None:
    node = wiring(["A", "B", "C"])
    link(node, "A", "B")
    link(node, "B", "C")
    put(node, 0, "A", 5)
    assert (value(node, "B"), value(node, "C")) == (5, 5)
    assert accepted(node, "C") == 1


def suppressed() -> tuple[ayllu.Node, int]:
    node = wiring(["S", "A", "D", "E"])
    s = link(node, "S", "D", ayllu.suppress(0.1))
    link(node, "A", "D")
    link(node, "D", "E")
    return node, s


def test_suppress_message_is_not_written() -> None:
    node, _ = suppressed()
    put(node, 0, "S", 7)
    assert value(node, "D") == 0
    assert accepted(node, "D") == 0
    assert node.why("D", "V").last_accepted is None


def test_suppress_blocks_every_connection_write_for_the_period() -> None:
    node, s = suppressed()
    put(node, 0, "A", 1)
    put(node, 10, "S", 0)
    put(node, 20, "A", 2)
    put(node, 109, "A", 3)
    assert (value(node, "D"), value(node, "E")) == (1, 1)
    assert dropped(node, "D", "suppressed") == 2
    why = node.why("D", "V")
    assert len(why.windows) == 1
    assert why.windows[0].holder.conn == s
    assert why.windows[0].ends == 0.110
    assert why.input_blocked == "Suppressed"
    assert "BLOCKED (suppressed)" in str(why)


def test_suppress_lapses_after_the_period_and_is_refreshed() -> None:
    node, _ = suppressed()
    put(node, 0, "S", 0)
    put(node, 80, "S", 0)
    put(node, 150, "A", 1)
    assert value(node, "D") == 0, "refreshed at 80 ms: blocked until 180 ms"
    put(node, 180, "A", 2)
    assert (value(node, "D"), value(node, "E")) == (2, 2)


def test_suppress_does_not_block_the_behaviors_own_write() -> None:
    node, _ = suppressed()
    put(node, 0, "S", 0)
    put(node, 10, "D", 4)
    assert (value(node, "D"), value(node, "E")) == (4, 4)


def test_inhibit_blocks_propagation_not_the_write() -> None:
    node = wiring(["I", "A", "D", "E"])
    link(node, "I", "D", ayllu.inhibit(0.1))
    link(node, "A", "D")
    link(node, "D", "E")
    put(node, 0, "I", 9)
    put(node, 10, "A", 3)
    assert (value(node, "D"), value(node, "E")) == (3, 0)
    assert dropped(node, "D", "inhibited") == 1
    put(node, 100, "A", 4)
    assert value(node, "E") == 4


def test_override_in_replaces_the_input_for_the_period() -> None:
    node = wiring(["O", "A", "D", "E"])
    link(node, "O", "D", ayllu.override_in(0.1))
    link(node, "A", "D")
    link(node, "D", "E")
    put(node, 0, "O", 7)
    assert (value(node, "D"), value(node, "E")) == (7, 7)
    put(node, 50, "A", 1)
    assert value(node, "D") == 7
    assert dropped(node, "D", "overridden_in") == 1
    put(node, 60, "O", 8)
    assert value(node, "D") == 8, "the holder writes through its own window"
    put(node, 160, "A", 2)
    assert value(node, "D") == 2


def test_override_out_passes_only_its_own_values() -> None:
    node = wiring(["O", "A", "D", "E"])
    link(node, "O", "D", ayllu.override_out(0.1))
    link(node, "A", "D")
    link(node, "D", "E")
    put(node, 0, "O", 7)
    assert value(node, "E") == 7
    put(node, 50, "A", 1)
    assert (value(node, "D"), value(node, "E")) == (1, 7)
    assert dropped(node, "D", "overridden_out") == 1
    put(node, 100, "A", 2)
    assert value(node, "E") == 2


def test_write_inhibit_stops_only_the_behaviors_own_writes() -> None:
    node = wiring(["W", "A", "D", "E"])
    link(node, "W", "D", ayllu.write_inhibit(0.1))
    link(node, "A", "D")
    link(node, "D", "E")
    put(node, 0, "W", 1)
    put(node, 10, "D", 5)
    assert (value(node, "D"), value(node, "E")) == (5, 0)
    assert dropped(node, "D", "write_inhibited") == 1
    put(node, 20, "A", 6)
    assert value(node, "E") == 6, "values arriving through connections still propagate"


def test_disconnect_ends_the_connection() -> None:
    node = wiring(["A", "B"])
    c = link(node, "A", "B")
    node.disconnect(c)
    put(node, 0, "A", 3)
    assert value(node, "B") == 0
    try:
        node.disconnect(c)
    except ayllu.NotFoundError as e:
        assert "connection" in str(e)
    else:
        raise AssertionError("a removed connection cannot be removed again")
