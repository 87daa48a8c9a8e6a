"""Rules S5 and S9 from Python: waves, cycles, and behaviors created and removed while running
(mirrors ayllu-core's tests/propagation.rs and tests/structure.rs)."""

from __future__ import annotations

import pytest

import ayllu
from conftest import dropped, link, put, value, wiring


def test_a_cycle_terminates_each_port_written_once_per_wave() -> None:
    node = wiring(["A", "B", "C"])
    link(node, "A", "B")
    link(node, "B", "C")
    link(node, "C", "A")
    put(node, 0, "A", 1)
    assert [value(node, n) for n in "ABC"] == [1, 1, 1]
    assert dropped(node, "A", "wave_revisit") == 1


def test_fan_out_reaches_every_destination() -> None:
    node = wiring(["S", "D1", "D2", "D3"])
    for d in ("D1", "D2", "D3"):
        link(node, "S", d)
    put(node, 0, "S", 8)
    assert [value(node, d) for d in ("D1", "D2", "D3")] == [8, 8, 8]


def test_removing_a_behavior_removes_its_connections() -> None:
    node = wiring(["A", "B", "C"])
    link(node, "A", "B")
    link(node, "B", "C")
    node.remove("B")
    assert len(node.report().connections) == 0
    with pytest.raises(ayllu.NotFoundError):
        node.read("B", "V")
    node.create("Relay", "B")
    put(node, 0, "A", 1)
    assert value(node, "B") == 0, "a new B is not wired by the old connections"


def test_a_stale_port_handle_is_refused() -> None:
    node = wiring(["A"])
    h = node.port("A", "V")
    h.write(3)
    assert h.read() == 3
    node.remove("A")
    node.create("Relay", "A")
    with pytest.raises(ayllu.NotFoundError):
        h.write(4)
