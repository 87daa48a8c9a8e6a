"""Rule S11 from Python: BLE in one call (mirrors ayllu-core's tests/ble.rs)."""

from __future__ import annotations

from typing import Optional

import pytest

import ayllu


class Worker(ayllu.Behavior):
    """Offers eligibility ``elig`` (None: none) at 10 Hz and writes Out = its node id."""

    out = ayllu.Port(0, name="Out")

    @ayllu.every(hz=10)
    def work(self, ctx: ayllu.Context) -> None:
        e = ELIGIBILITY.get(ctx.node)
        if e is not None:
            ctx.write(self.LOCAL, e)
        ctx.write(self.out, ctx.node)


ELIGIBILITY: dict[int, Optional[float]] = {}


class Sink(ayllu.Behavior):
    inp = ayllu.Port(0, name="In")


def ble_team(elig: list[Optional[float]]) -> tuple[ayllu.Team, list[ayllu.Node]]:
    ELIGIBILITY.clear()
    t = ayllu.Team()
    nodes = []
    for i, e in enumerate(elig, start=1):
        ELIGIBILITY[i] = e
        n = t.add(i)
        n.create(Worker, "W")
        n.create(Sink, "SINK")
        n.connect(ayllu.local("W", "Out"), ayllu.local("SINK", "In"))
        g = n.ble_join("W", "Peers", "Out", 2.0)
        assert set(g) >= {"eligibility", "inhibition", "warnings"}
        nodes.append(n)
    return t, nodes


def test_ties_go_to_the_lower_node_id() -> None:
    t, nodes = ble_team([0.5, 0.5, None])
    t.advance(3.0)
    assert [s.claiming for s in (n.ble_status("W") for n in nodes) if s is not None] == [True, False, False]


def test_ble_ports_are_implicit_and_reserved() -> None:
    class Bad(ayllu.Behavior):
        best = ayllu.Port(0.0, name="Best")

    with pytest.raises(ayllu.InvalidError, match="BLE"):
        ayllu.Node(1, manual=True).define(Bad)
    node = ayllu.Node(1, manual=True)
    node.create(Sink, "S")
    names = [p.name for p in node.report().behaviors[0].ports]
    assert names[:3] == ["Local", "Inhibit", "Best"]


def test_the_highest_eligibility_claims_and_inhibits_its_peers() -> None:
    t, nodes = ble_team([0.2, 0.9, 0.5])
    t.advance(3.0)
    statuses = [n.ble_status("W") for n in nodes]
    assert [s.claiming for s in statuses if s is not None] == [False, True, False]
    assert statuses[0] is not None and statuses[0].inhibited_by
    assert nodes[0].why("W", "Out").internal_output_blocked == "WriteInhibited"


def test_ble_misuse_is_reported() -> None:
    node = ayllu.Node(1, manual=True)
    node.create(Sink, "S")
    with pytest.raises(ayllu.NotFoundError):
        node.ble_join("S", "Peers", "Nope", 1.0)
    with pytest.raises(ayllu.InvalidError):
        node.ble_join("S", "Peers", "In", 0.0)


def test_the_period_check_warns_for_the_papers_fig_2_numbers() -> None:
    node = ayllu.Node(1, manual=True)
    node.create(Sink, "S")
    g = node.ble_join("S", "Peers", "In", 1.0, inhibit_period=0.5)
    assert len(g["warnings"]) == 1
    assert node.warnings() == g["warnings"]
