"""The simulator from Python: scenarios, determinism, metrics as plain data, per-tick traces,
the baselines, and a Python controller beside the Rust ones."""

from __future__ import annotations

import time

import numpy as np
import pandas as pd
import pytest

import ayllu
from ayllu import sim


def short(controller: str = "BLE", seed: int = 1, duration: float = 20.0) -> sim.Scenario:
    return sim.Scenario.paper(controller, seed).with_(duration=duration)


def test_a_run_is_deterministic_and_metrics_are_plain_data() -> None:
    a, b = sim.run(short()), sim.run(short())
    assert a.trace_hash == b.trace_hash
    assert a.metrics == b.metrics
    assert isinstance(a.metrics["a_w"], float) and 0.0 <= a.metrics["a_w"] <= 1.0
    assert set(a.radio) == {"sent", "delivered", "lost", "cut", "bytes"}
    assert a.radio["bytes"] > 0, "BLE talks: its bytes on the radio are counted"
    assert len(a.coverage["t"]) == len(a.coverage["weighted"]) == 101, "a frame every 0.2 s, and t=0"
    assert sim.run(short(seed=2)).trace_hash != a.trace_hash


@pytest.mark.parametrize("controller", sim.CONTROLLERS)
def test_every_baseline_runs(controller: str) -> None:
    out = sim.run(short(controller))
    assert 0.0 <= out.metrics["a_w"] <= 1.0
    assert out.process_errors == []


def test_scenarios_set_every_field_of_the_rust_type() -> None:
    base = sim.Scenario.sized("BLE", robots=4, targets=3, seed=5)
    s = (
        base.with_(duration=10.0, radio__loss=0.3, **{"radio.delay": 0.05, "radio.range": 6.0})
        .kill(at=5.0, robot=2)
        .kill(at=7.0)
        .partition(2.0, 4.0, island=[1, 2])
        .target(0, speed=0.0, priority=9.0)
    )
    assert base.data["radio"]["loss"] == 0.0, "each change returns a new scenario"
    assert s.data["radio"]["loss"] == 0.3 and s.data["radio"]["range"] == 6.0
    assert s.data["kills"] == [{"at": 5.0, "robot": 2}, {"at": 7.0, "robot": None}]
    out = sim.run(s, trace=True)
    assert out.radio["lost"] > 0 and out.radio["cut"] > 0
    assert out.trace is not None
    alive = out.trace.arrays()["alive"]
    assert alive[-1].tolist() == [True, False, True, False] or alive[-1].sum() == 2
    with pytest.raises(KeyError, match=r"radio\.los"):
        base.with_(radio__los=0.1)
    with pytest.raises(ValueError, match="unknown controller"):
        sim.Scenario.paper("Nope", 1)


def test_a_target_index_that_names_no_target_is_an_index_error() -> None:
    # Python's negative indexing would change the last target instead of refusing.
    base = sim.Scenario.sized("BLE", robots=2, targets=3, seed=1)
    for index in (-1, 3, 99):
        with pytest.raises(IndexError, match=f"no target {index}: the scenario has 3, numbered from 0"):
            base.target(index, speed=9.0)
    assert base.target(2, speed=9.0).data["world"]["targets"][2]["speed"] == 9.0


def test_a_recording_has_every_frame() -> None:
    out = sim.run(short(duration=2.0).with_(record=True))
    assert out.recording is not None
    assert len(out.recording["frames"]) == 11
    assert out.recording["frames"][0]["robots"][0].keys() >= {"x", "y", "theta", "drive", "claims"}


def test_per_tick_traces_as_numpy_arrays_and_a_dataframe() -> None:
    out = sim.run(short(duration=1.0), trace=True)
    assert out.trace is not None
    arr = out.trace.arrays()
    assert arr["t"].shape == (21,) and arr["x"].shape == (21, 3) and arr["target_x"].shape == (21, 4)
    assert np.allclose(np.diff(arr["t"]), 0.05)
    df = out.trace.frame()
    assert isinstance(df, pd.DataFrame) and len(df) == 63
    assert list(df.columns) == ["t", "robot", "x", "y", "theta", "alive", "drive"]
    cov = out.coverage_frame()
    assert list(cov.columns) == ["t", "observed", "weighted"]
    assert sim.run(short(duration=1.0)).trace_hash == out.trace_hash, "tracing changes nothing"


def test_a_trace_is_bounded_and_a_run_that_would_exceed_it_is_refused_before_it_starts() -> None:
    # The trace used to grow with the run, without limit.
    assert sim.MAX_TRACE_VALUES == 2e7
    # The paper's setting keeps 1 + 5 x 3 + 2 x 4 = 24 values a tick: 1e6 s is 2e7 + 1 ticks.
    called = []

    def never(robot: sim.RobotBuilder) -> sim.BrainSpec:
        called.append(robot.id)
        return None

    for controller in (None, never):
        start = time.monotonic()
        with pytest.raises(ValueError) as e:
            sim.run(short(duration=1e6), controller, trace=True)
        assert time.monotonic() - start < 5.0, "refused before running"
        msg = str(e.value)
        assert msg.startswith("trace=True would keep 4.8e8 values (20000001 ticks x 24 values"), msg
        assert "more than 2e7 (sim.MAX_TRACE_VALUES" in msg
        assert "record=True" in msg and "ayllu sim run FILE --trace T.csv" in msg
    assert called == []
    # A large team reaches the bound sooner: 1000 robots, 4 targets (5009 values a tick).
    with pytest.raises(ValueError, match=r"^trace=True would keep 2\.0\d*e7 values \(4001 ticks x 5009 values"):
        sim.run(sim.Scenario.sized("BLE", 1000, 4, 1).with_(duration=200.0), trace=True)
    # A scenario out of its own bounds is refused by its field first, trace or not.
    with pytest.raises(ValueError, match=r"^duration: "):
        sim.run(short(duration=float("nan")), trace=True)


class Spinner(ayllu.Behavior):
    """Turns left at 10 Hz: a minimal Python controller."""

    rotate = ayllu.Port(0.0, name="Rotate")

    @ayllu.every(hz=10)
    def spin(self, ctx: ayllu.Context) -> None:
        ctx.write(self.rotate, 0.5)


def spinner(robot: sim.RobotBuilder) -> sim.BrainSpec:
    robot.create(Spinner, "SPIN")
    robot.connect(ayllu.local("SPIN", "Rotate"), ayllu.local("BASE", "Rotate"))
    assert robot.priorities == [4.0, 3.0, 2.0, 1.0]
    return None


def test_threads_give_the_same_run() -> None:
    # 120 robots: two shares of 60 (a thread takes at least 50 robots).
    s = sim.Scenario.sized("BLE", 120, 5, 3).with_(duration=4.0)
    one, two = sim.run(s), sim.run(s, threads=2)
    assert one.trace_hash == two.trace_hash
    assert one.metrics == two.metrics and one.radio == two.radio
    with pytest.raises(ValueError, match="at least 1"):
        sim.run(s, threads=0)
    with pytest.raises(ValueError, match="built-in controller"):
        sim.run(short("Random", duration=1.0), spinner, threads=2)


def test_a_python_controller_runs_beside_the_rust_ones() -> None:
    s = short("Random", duration=5.0)
    out = sim.run(s, spinner, trace=True)
    assert out.trace is not None
    theta = out.trace.arrays()["theta"]
    assert np.all(np.diff(np.unwrap(theta[:, 0]))[2:] > 0), "the robot turns left all the time"
    assert out.trace_hash == sim.run(s, spinner).trace_hash
    assert out.trace_hash != sim.run(s).trace_hash


def test_a_python_controller_that_raises_is_reported() -> None:
    def broken(robot: sim.RobotBuilder) -> sim.BrainSpec:
        raise RuntimeError("cannot build")

    with pytest.raises(RuntimeError, match="cannot build"):
        sim.run(short(), broken)

    class Faulty(ayllu.Behavior):
        @ayllu.every(hz=1)
        def fail(self, ctx: ayllu.Context) -> None:
            raise ValueError("in a process")

    def faulty(robot: sim.RobotBuilder) -> sim.BrainSpec:
        robot.create(Faulty, "F")
        return None

    out = sim.run(short(duration=2.0), faulty)
    assert len(out.process_errors) == 9, "3 robots x 3 activations (0, 1, 2 s)"
    robot, behavior, process, _t, tb = out.process_errors[0]
    assert (robot, behavior, process) == (1, "F", "fail") and "ValueError: in a process" in tb


def test_a_builder_kept_after_its_call_is_refused() -> None:
    kept: list[sim.RobotBuilder] = []

    def keeper(robot: sim.RobotBuilder) -> sim.BrainSpec:
        kept.append(robot)
        return None

    sim.run(short(duration=0.1), keeper)
    with pytest.raises(RuntimeError, match="returned"):
        kept[0].join("Peers")
