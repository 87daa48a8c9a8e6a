"""Rule S3 from Python: Normal, Max, Min, Sum and Priority ports, windows and reset
(mirrors ayllu-core's tests/port_*.rs)."""

from __future__ import annotations

import math

import pytest

import ayllu


def fan_in(kind: str, default: ayllu.PortValue, k: int = 3, **opts: float) -> ayllu.Node:
    class Src(ayllu.Behavior):
        out = ayllu.Port(default, name="Out")

    class Sink(ayllu.Behavior):
        inp = ayllu.Port(default, kind=kind, name="In", **opts)

    node = ayllu.Node(1, manual=True)
    node.create(Sink, "SINK")
    for i in range(1, k + 1):
        node.create(Src, f"S{i}")
        node.connect(ayllu.local(f"S{i}", "Out"), ayllu.local("SINK", "In"), priority=i)
    return node


def test_normal_port_keeps_the_last_value() -> None:
    node = fan_in("normal", 0)
    node.write("S1", "Out", 5)
    node.write("S2", "Out", 3)
    assert node.read("SINK", "In") == 3


def test_max_starts_empty_keeps_the_maximum_and_its_supplier() -> None:
    node = fan_in("max", 0)
    assert node.get("SINK", "In") is None
    assert not node.fresh("SINK", "In")
    node.write("S1", "Out", -4)
    assert node.read("SINK", "In") == -4, "the first write sets it, even below the default"
    node.write("S2", "Out", 9)
    node.write("S3", "Out", 2)
    assert node.read("SINK", "In") == 9
    why = node.why("SINK", "In")
    assert why.counters == {"absorbed": 1}
    assert why.supplier.node == 1


def test_max_refuses_nan() -> None:
    node = fan_in("max", 0.0)
    node.write("S1", "Out", math.nan)
    assert node.why("SINK", "In").counters == {"not_a_number": 1}
    assert node.get("SINK", "In") is None


def test_min_keeps_the_minimum() -> None:
    node = fan_in("min", 0)
    for i, v in enumerate([5, -2, 7], start=1):
        node.write(f"S{i}", "Out", v)
    assert node.read("SINK", "In") == -2


def test_sum_adds_scalars_and_vectors() -> None:
    node = fan_in("sum", 0.0)
    node.write("S1", "Out", 1.5)
    node.write("S2", "Out", 2.0)
    assert node.read("SINK", "In") == 3.5
    vec = fan_in("sum", [0.0, 0.0])
    vec.write("S1", "Out", [1.0, 2.0])
    vec.write("S2", "Out", [0.5, -1.0])
    assert vec.read("SINK", "In") == [1.5, 1.0]


def test_priority_port_takes_the_highest_priority_connection() -> None:
    node = fan_in("priority", 0)
    node.write("S2", "Out", 20)
    node.write("S1", "Out", 10)
    assert node.read("SINK", "In") == 20, "priority 1 is below the holder's 2"
    node.write("S3", "Out", 30)
    assert node.read("SINK", "In") == 30


def test_window_empties_the_port_after_it_opens() -> None:
    node = fan_in("max", 0.0, window=1.0)
    node.write("S1", "Out", 3.0)
    node.set_time(0.5)
    node.write("S2", "Out", 2.0)
    assert node.read("SINK", "In") == 3.0
    node.set_time(1.2)
    node.write("S2", "Out", 2.0)
    assert node.read("SINK", "In") == 2.0, "a new window: the maximum may fall"


def test_reset_empties_an_aggregating_port() -> None:
    node = fan_in("max", 0)
    node.write("S1", "Out", 5)
    node.reset("SINK", "In")
    assert node.get("SINK", "In") is None


def test_kinds_refuse_types_they_cannot_merge() -> None:
    class Bad(ayllu.Behavior):
        name = ayllu.Port("text", kind="max", name="Name")

    # A type error, as in C (AY_ERR_TYPE): one classification, ayllu_core::ErrorKind.
    with pytest.raises(ayllu.ValueTypeError, match="Max port cannot hold text") as e:
        ayllu.Node(1, manual=True).define(Bad)
    assert isinstance(e.value, TypeError)


def test_values_are_never_coerced() -> None:
    node = fan_in("normal", 0)
    with pytest.raises(ayllu.ValueTypeError):
        node.write("S1", "Out", 1.0)
    with pytest.raises(TypeError):
        node.write("S1", "Out", object())  # type: ignore[arg-type]
    pairs: list[tuple[ayllu.PortValue, ayllu.PortValue]] = [
        (False, True),
        ("a", "b"),
        (b"x", b"yz"),
        ([0.0], [1.0, 2.0]),
    ]
    for default, v in pairs:
        n = fan_in("normal", default, k=1)
        n.write("S1", "Out", v)
        assert n.read("SINK", "In") == v
