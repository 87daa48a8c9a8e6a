"""Reconfiguration from Python (docs/semantics.md R1-R12): a process asks for structure
changes through its ctx, applied when it returns; its next activation reads their outcomes;
a behavior hands its task to a successor and removes itself; a behavior of a Python class
created by a process runs its Python processes; a plan applied from one node to another over
loopback UDP switches it, and a bad port name aborts it. Mirrors
crates/ayllu-core/tests/rules/structure_from_process.rs and crates/ayllu/tests/runtime/transaction_*.rs."""

from __future__ import annotations

from typing import Any, Optional

import pytest

import ayllu


class Sink(ayllu.Behavior):
    inp = ayllu.Port(0, name="In")
    count = ayllu.Port(0, name="Count")

    @ayllu.on_write(inp)
    def counted(self, ctx: ayllu.Context) -> None:
        ctx.write(self.count, ctx.read(self.count) + 1)


SEEN: list[Any] = []


class Boss(ayllu.Behavior):
    go = ayllu.Port(0, name="Go")
    out = ayllu.Port(0, name="Out")

    @ayllu.on_write(go)
    def steer(self, ctx: ayllu.Context) -> None:
        SEEN.append(ctx.changes())
        g = ctx.read(self.go)
        if g == 1:
            assert ctx.create("Sink", "Helper") == 0
            assert ctx.connect(("Boss", "Out"), ("Helper", "In")) == 1
            ctx.create("NoSuchClass", "Ghost")
            with pytest.raises(ayllu.AylluError):
                ctx.create("Sink", "")
            SEEN.append(("helper while running", ctx.behavior))
        if g == 3:
            ctx.create("Boss", "Boss2")
            ctx.connect(("Boss2", "Out"), ("Helper", "In"))
            ctx.remove(ctx.behavior)
        ctx.write(self.out, 10 * g)


def test_a_process_recruits_reads_outcomes_and_hands_over() -> None:
    SEEN.clear()
    node = ayllu.Node(1, manual=True)
    node.define(Sink)
    node.define(Boss)
    node.create(Boss, "Boss")
    node.write("Boss", "Go", 1)
    node.step()
    assert SEEN[0] == [], "no outcomes before any change"
    assert node.get("Helper", "In") is None, "the wave ran before the connection existed (R4)"
    node.set_time(0.01)
    node.write("Boss", "Go", 2)
    node.step()
    outcomes = SEEN[2]
    assert [o[1] is None for o in outcomes] == [True, True, False]
    assert outcomes[1][2] is not None and outcomes[1][2] > 0, "the new connection's id"
    assert "NoSuchClass" in (outcomes[2][1] or "")
    assert node.read("Helper", "In") == 20
    node.step()
    assert node.read("Helper", "Count") == 1, "the created Python behavior runs its process"
    node.set_time(0.02)
    node.write("Boss", "Go", 3)
    node.step()
    assert node.read("Helper", "In") == 30, "its last write crossed before it went (R3)"
    with pytest.raises(ayllu.AylluError):
        node.read("Boss", "Go")
    node.set_time(0.03)
    node.write("Boss2", "Out", 7)
    assert node.read("Helper", "In") == 7


def test_ctx_outside_its_process_refuses() -> None:
    held: list[ayllu.Context] = []

    class Keeper(ayllu.Behavior):
        go = ayllu.Port(0, name="Go")

        @ayllu.on_write(go)
        def keep(self, ctx: ayllu.Context) -> None:
            held.append(ctx)

    node = ayllu.Node(1, manual=True)
    node.create(Keeper, "K")
    node.write("K", "Go", 1)
    node.step()
    with pytest.raises(RuntimeError):
        held[0].create("Keeper", "K2")


def _relay(node: ayllu.Node) -> None:
    node.define(Sink)
    node.create(Sink, "A")
    node.create(Sink, "B")
    node.connect(("A", "Count"), ("B", "In"))


PLAN = """
hold = 3.0
[[node]]
id = 2
changes = [
  { op = "disconnect", from = "A.Count", to = "B.In" },
  { op = "connect", from = "A.In", to = "B.In", kind = "suppress", period = 0.5 },
]
"""


def _team() -> tuple[ayllu.Node, ayllu.Node]:
    part = ayllu.Node(2, "udp://127.0.0.1:0")
    _relay(part)
    part.start()
    address: Optional[str] = part.address()
    assert address is not None
    # A request to a node not greeted yet waits for its greeting (D-S10.2): no wait here.
    coordinator = ayllu.Node(9, f"udp://127.0.0.1:0?peer={address}")
    coordinator.start()
    return part, coordinator


def test_a_plan_switches_the_node_it_names_and_a_bad_port_aborts_it() -> None:
    part, coordinator = _team()
    try:
        bad = coordinator.apply(PLAN.replace("A.In", "A.Inn"))
        assert bad["outcome"] == "aborted", bad
        assert bad["nodes"][0]["refused"] and "Inn" in bad["nodes"][0]["prepare_error"]
        kinds = [c.kind for c in part.report().connections]
        assert kinds == ["Normal"], kinds
        report = coordinator.apply(PLAN)
        assert report["outcome"] == "switched", report
        conns = part.report().connections
        assert len(conns) == 1, conns
        assert "In" in str(conns[0].source) and "Suppress" in str(conns[0].kind), conns
        with pytest.raises(ValueError):
            coordinator.apply("[[node]]\nid = 9\n")
    finally:
        coordinator.stop()
        part.stop()
