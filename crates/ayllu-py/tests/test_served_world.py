"""Serving a world from Python (``ayllu.sim.ServedWorld``, ``ayllu.sim.serve``): the world of
``ayllu sim serve``, hosted by this process, with one robot whose controller (the paper's Fig. 2
in Python, examples/cmommt/python/fig2.py) runs on an ``ayllu.Node`` of its own on loopback UDP,
stepped by its background thread. Every socket binds port 0: the robot's address is read back
and named in its body's URL (``peer=``)."""

from __future__ import annotations

import sys
import threading
from pathlib import Path
from typing import Any

import pytest

import ayllu
from ayllu import sim

EXAMPLE = Path(__file__).resolve().parents[3] / "examples" / "cmommt" / "python"
sys.path.insert(0, str(EXAMPLE))

import fig2  # noqa: E402

TARGETS = 4


def robot(robot_id: int, seed: int) -> ayllu.Node:
    node = ayllu.Node(robot_id, "udp://127.0.0.1:0")
    node.install_served_body(TARGETS)
    fig2.build(node, priorities=[float(p) for p in range(TARGETS, 0, -1)], claim_hz=1.0, wander_seed=seed)
    node.start()
    return node


def test_a_python_program_serves_a_world_to_a_python_robot_and_gets_its_metrics() -> None:
    node = robot(1, 7)
    try:
        scenario = sim.Scenario.sized("Random", 1, TARGETS, 7).with_(duration=3.0)
        events: list[dict[str, Any]] = []
        done = sim.serve(scenario, f"udp://127.0.0.1:0?peer={node.address()}", on_event=events.append, status_every=0.5)
    finally:
        node.close()
    start = events[0]
    assert start["start"] is True and start["missing"] == [], start
    assert (start["robots"], start["targets"], start["seed"]) == (1, TARGETS, 7)
    statuses = [e for e in events if "observed" in e]
    assert len(statuses) == 6, statuses
    assert all(s["robots"][0]["linked"] for s in statuses), statuses
    assert any(s["robots"][0]["translate"] != 0.0 for s in statuses), "the controller drives its body"
    assert events[-1] == done and done["done"] is True and done["stopped"] is False
    assert done["t"] == pytest.approx(3.0)
    assert 0.0 <= done["metrics"]["a_w"] <= 1.0, done["metrics"]
    assert statuses[-1]["a_w"] == pytest.approx(done["metrics"]["a_w"], abs=0.05)


def test_a_served_world_steps_and_stops_from_another_thread() -> None:
    scenario = sim.Scenario.sized("Random", 1, TARGETS, 1).with_(duration=60.0)
    world = sim.ServedWorld(scenario, ["udp://127.0.0.1:0"], wait=0.2)
    address = world.body_addresses()[0]
    assert address is not None and not address.endswith(":0")
    start = world.start()
    assert start["missing"] == [1]
    assert world.step() == [] and world.now == pytest.approx(0.05)
    threading.Timer(0.3, world.stop).start()
    while not world.done:
        world.step()
    done = world.finish()
    assert done["stopped"] is True and done["t"] < 30.0


def test_misuse_is_refused() -> None:
    two = sim.Scenario.sized("Random", 2, TARGETS, 1).with_(duration=5.0)
    with pytest.raises(ValueError, match="body URL"):
        sim.ServedWorld(two, "udp://127.0.0.1:7400")
    with pytest.raises(ValueError, match="3 body URLs for 2 robots"):
        sim.ServedWorld(two, ["udp://127.0.0.1:0"] * 3)
    with pytest.raises(ayllu.InvalidError, match="nope"):
        sim.ServedWorld(two, "nope")
    with pytest.raises(TypeError):
        sim.ServedWorld(two.data, "udp://127.0.0.1:0")  # type: ignore[arg-type]
