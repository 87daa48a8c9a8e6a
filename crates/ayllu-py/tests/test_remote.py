"""Remote and broadcast endpoints on a deterministic team (mirrors ayllu-core's
tests/remote.rs through ayllu's Lockstep-like Team)."""

from __future__ import annotations

import ayllu
from conftest import Relay


def team(n: int = 3) -> tuple[ayllu.Team, list[ayllu.Node]]:
    t = ayllu.Team()
    nodes = [t.add(i) for i in range(1, n + 1)]
    for node in nodes:
        node.create(Relay, "R")
        node.join("Peers")
    return t, nodes


def test_normal_to_a_node_crosses_the_network_in_the_next_step() -> None:
    t, (a, b, _c) = team()
    a.connect(ayllu.local("R", "V"), ayllu.remote(2, "R", "V"))
    a.write("R", "V", 42)
    t.step()
    assert b.read("R", "V") == 42
    assert a.stats()["sent"] == 1


def test_broadcast_reaches_every_member_of_the_group() -> None:
    t, (a, b, c) = team()
    a.connect(ayllu.local("R", "V"), ayllu.broadcast("Peers", "R", "V"))
    a.write("R", "V", 7)
    t.advance(0.02)
    assert (b.read("R", "V"), c.read("R", "V")) == (7, 7)


def test_a_remote_suppress_uses_the_receivers_clock() -> None:
    t, (a, b, _c) = team()
    a.connect(ayllu.local("R", "V"), ayllu.remote(2, "R", "V"), ayllu.suppress(0.1))
    a.write("R", "V", 1)
    t.advance(0.01)
    b.write("R", "V", 5)
    assert b.read("R", "V") == 5, "its own writes pass a suppression"
    why = b.why("R", "V")
    assert why.input_blocked == "Suppressed"
    t.advance(0.1)
    assert b.why("R", "V").input_blocked is None


def test_a_killed_node_stops_and_the_team_goes_on() -> None:
    t, (a, b, c) = team()
    a.connect(ayllu.local("R", "V"), ayllu.broadcast("Peers", "R", "V"))
    assert t.kill(2)
    assert [n.id for n in t.nodes] == [1, 3]
    a.write("R", "V", 9)
    t.advance(0.02)
    assert c.read("R", "V") == 9
    try:
        b.read("R", "V")
    except RuntimeError as e:
        assert "closed" in str(e)
    else:
        raise AssertionError("a killed node is closed")
