"""The simulator from Python: build scenarios, run them (built-in or Python controllers), get
metrics as plain data and per-tick traces as NumPy arrays or a pandas DataFrame, and sweep.

Every run is ``ayllu-sim``'s own, on virtual time: the same scenario gives the same outcome
(the same ``trace_hash``) as the Rust simulator, on any machine.

>>> from ayllu import sim
>>> s = sim.Scenario.paper("BLE", seed=1).with_(duration=20.0)
>>> out = sim.run(s)
>>> 0.0 <= out.metrics["a_w"] <= 1.0
True
>>> out.trace_hash == sim.run(s).trace_hash
True
"""

from __future__ import annotations

import copy
import json
import math
import os
from collections.abc import Iterable, Sequence
from concurrent.futures import Executor, ProcessPoolExecutor
from dataclasses import dataclass, field
from typing import Any, Callable, Optional, Union

from ayllu import _native

__all__ = [
    "CONTROLLERS",
    "MAX_TRACE_VALUES",
    "Outcome",
    "RobotBuilder",
    "Scenario",
    "ServedWorld",
    "Trace",
    "chain",
    "drive",
    "run",
    "serve",
    "sweep",
]

RobotBuilder = _native.RobotBuilder
CONTROLLERS: list[str] = list(_native.controller_names())
"""The built-in controllers: BLE (the paper's Fig. 2), Random, Local, ForceField, Centralized, Planner (the
study's six), then BLE-lean and BLE-seek (docs/cmommt.md)."""

MAX_TRACE_VALUES: float = _native.MAX_TRACE_VALUES
"""The most values ``run(..., trace=True)`` keeps: ticks x (1 + 5 x robots + 2 x targets), 2e7
(about 800 MB at its peak). A run whose trace would hold more is refused with a
``ValueError`` before it starts: record it (the scenario's ``record``) or stream its trace to a
file with ``ayllu sim run FILE --trace T.csv`` (docs/python.md)."""

BrainSpec = Optional[tuple[str, Any]]
Controller = Callable[[Any], BrainSpec]
"""A Python controller: called once per robot with its :class:`RobotBuilder` (or an
``ayllu.Node`` when the robot is its own process); builds behaviors and connections on it and
returns how the harness tells which target drives the robot: None, :func:`drive` or
:func:`chain`."""


def drive(behavior: str, port: str) -> tuple[str, tuple[str, str]]:
    """The robot is driven by the target whose id (1-based; 0: none) this int port holds."""
    return ("drive", (behavior, port))


def chain(layers: Sequence[tuple[str, str]]) -> tuple[str, list[tuple[str, str]]]:
    """Observer layers, highest first: layer n drives while its port was written within the
    override period (the Fig. 2 chain)."""
    return ("chain", [tuple(layer) for layer in layers])  # type: ignore[misc]


def _variant(name: str) -> str:
    """A controller's name as the scenario's data spells it (``Ble``), from any case."""
    for c in CONTROLLERS:
        if c.lower() == str(name).lower():
            return "Ble" if c == "BLE" else c
    raise ValueError(f"unknown controller {name!r}: one of {', '.join(CONTROLLERS)}")


def _display(variant: str) -> str:
    return "BLE" if variant == "Ble" else variant


class Scenario:
    """A scenario: every field of ``ayllu_sim::scenario::Scenario`` as plain data (``data``).

    Change it with :meth:`with_` (dotted paths: ``with_(**{"radio.loss": 0.1})`` or
    ``with_(radio__loss=0.1)``), :meth:`kill`, :meth:`partition` and :meth:`target`; each
    returns a new scenario, so one base can seed a sweep.
    """

    def __init__(self, data: dict[str, Any]) -> None:
        self.data = data

    @classmethod
    def sized(cls, controller: str, robots: int, targets: int, seed: int) -> Scenario:
        """``robots`` robots, ``targets`` targets (priorities targets..1), 300 s, the paper's
        density, no loss."""
        return cls(json.loads(_native.scenario_json(controller, robots, targets, seed)))

    @classmethod
    def paper(cls, controller: str, seed: int) -> Scenario:
        """The paper's setting: 3 robots, 4 targets, the 8 m x 8 m lab, 300 s, no loss."""
        return cls.sized(controller, 3, 4, seed)

    def with_(self, **fields: Any) -> Scenario:
        """A copy with fields set; a key is a field path with ``.`` or ``__`` between parts."""
        data = copy.deepcopy(self.data)
        for raw, value in fields.items():
            parts = raw.replace("__", ".").split(".")
            key = ".".join(parts)
            node: Any = data
            for p in parts[:-1]:
                if p not in node:
                    raise KeyError(f"scenario has no field {key!r} (no {p!r})")
                node = node[p]
            if parts[-1] not in node:
                raise KeyError(f"scenario has no field {key!r}; fields here: {sorted(node)}")
            if key == "controller":
                value = _variant(value)
            node[parts[-1]] = value
        return Scenario(data)

    def kill(self, at: float, robot: Optional[int] = None) -> Scenario:
        """A copy with a robot failing at ``at`` s (``robot`` None: the most useful one)."""
        s = self.with_()
        s.data["kills"].append({"at": at, "robot": robot})
        return s

    def partition(self, start: float, end: float, island: Iterable[int]) -> Scenario:
        """A copy where robots ``island`` hear only each other from ``start`` to ``end`` s."""
        s = self.with_()
        s.data["radio"]["partitions"].append({"start": start, "end": end, "island": list(island)})
        return s

    def target(self, index: int, **fields: Any) -> Scenario:
        """A copy with target ``index`` (0-based) changed: ``priority``, ``speed``, ``motion``.
        ``IndexError`` for an index that names no target (a negative one too: counting from
        the end would change another target than the one meant)."""
        s = self.with_()
        targets = s.data["world"]["targets"]
        if not 0 <= index < len(targets):
            raise IndexError(f"no target {index}: the scenario has {len(targets)}, numbered from 0")
        t = targets[index]
        for k, v in fields.items():
            if k not in t:
                raise KeyError(f"a target has no field {k!r}; it has {sorted(t)}")
            t[k] = v
        return s

    @property
    def controller(self) -> str:
        """The controller's name as tables print it (BLE, Random, ...)."""
        return _display(str(self.data["controller"]))

    @property
    def seed(self) -> int:
        return int(self.data["seed"])

    @property
    def robots(self) -> int:
        return int(self.data["robots"])

    @property
    def duration(self) -> float:
        return float(self.data["duration"])

    def to_json(self) -> str:
        """The scenario's data as the simulator reads it. JSON has no NaN or infinity: they are
        written as the strings ``"NaN"``, ``"inf"``, ``"-inf"``, which the simulator reads back,
        so that its bounds refuse them with the field's name."""
        return json.dumps(_json_safe(self.data), allow_nan=False)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Scenario) and self.data == other.data

    def __repr__(self) -> str:
        return (
            f"Scenario({self.controller}, robots={self.robots}, targets={len(self.data['world']['targets'])}, "
            f"seed={self.seed}, duration={self.duration}, loss={self.data['radio']['loss']})"
        )


def _json_safe(value: Any) -> Any:
    """``value`` with every non-finite float spelled as the simulator reads it (see
    :meth:`Scenario.to_json`)."""
    if isinstance(value, float) and not math.isfinite(value):
        return "NaN" if math.isnan(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    return value


@dataclass
class Trace:
    """Per-tick state of a run (``run(..., trace=True)``): ``t`` (s, one per tick from 0) and,
    per tick and robot, ``x``, ``y``, ``theta``, ``alive``, ``drive`` (the target driving it, 0
    none); per tick and target ``target_x``, ``target_y``. Flat lists, tick-major."""

    t: list[float]
    robots: int
    targets: int
    x: list[float]
    y: list[float]
    theta: list[float]
    alive: list[bool]
    drive: list[int]
    target_x: list[float]
    target_y: list[float]

    def arrays(self) -> dict[str, Any]:
        """NumPy arrays: ``t`` (ticks,), robot fields (ticks, robots), target fields (ticks,
        targets). Needs numpy."""
        import numpy as np

        n = len(self.t)
        out: dict[str, Any] = {"t": np.asarray(self.t)}
        for name in ("x", "y", "theta", "alive", "drive"):
            out[name] = np.asarray(getattr(self, name)).reshape(n, self.robots)
        for name in ("target_x", "target_y"):
            out[name] = np.asarray(getattr(self, name)).reshape(n, self.targets)
        return out

    def frame(self) -> Any:
        """A pandas DataFrame, one row per (tick, robot): t, robot (node id), x, y, theta,
        alive, drive. Needs pandas."""
        import pandas as pd

        n, r = len(self.t), self.robots
        return pd.DataFrame(
            {
                "t": [t for t in self.t for _ in range(r)],
                "robot": [i + 1 for _ in range(n) for i in range(r)],
                "x": self.x,
                "y": self.y,
                "theta": self.theta,
                "alive": self.alive,
                "drive": self.drive,
            }
        )


@dataclass
class Outcome:
    """A run's results as plain data: ``metrics`` (a_w, a, top_k, redundant, switches_per_min,
    recover_s, msgs_per_robot_s, ...: docs/cmommt.md), ``trace_hash`` (SHA-256 of every frame),
    ``radio`` (sent, delivered, lost, cut, bytes), ``coverage`` (per frame: t, observed, weighted),
    ``recording`` (every frame, if the scenario's ``record`` is set), ``trace`` (if asked) and
    ``process_errors`` (Python controllers: exceptions their processes raised, counted)."""

    metrics: dict[str, Any]
    trace_hash: str
    radio: dict[str, int]
    coverage: dict[str, list[Any]]
    recording: Optional[dict[str, Any]] = None
    trace: Optional[Trace] = None
    process_errors: list[tuple[int, str, str, float, str]] = field(default_factory=list)

    def coverage_frame(self) -> Any:
        """Coverage per frame as a pandas DataFrame (t, observed, weighted). Needs pandas."""
        import pandas as pd

        return pd.DataFrame(self.coverage)


def run(
    scenario: Scenario,
    controller: Optional[Controller] = None,
    *,
    trace: bool = False,
    threads: int = 1,
) -> Outcome:
    """Run ``scenario`` to its end: with its built-in controller, or with ``controller`` (a
    Python controller) on every robot. ``trace=True`` also keeps the per-tick state, up to
    :data:`MAX_TRACE_VALUES` values (a longer or larger run is refused before it starts).

    ``threads``: up to this many threads share each tick's robots (built-in controllers
    only; a thread takes at least 50 robots). The outcome is the same bit for bit whatever
    the number; a large team finishes sooner. ``ValueError`` if it is below 1, or above 1
    with a Python ``controller``.

    ``TypeError`` if ``scenario`` is not a :class:`Scenario`; ``ValueError`` naming the field
    if one is out of the simulator's bounds (docs/cmommt.md, "What a scenario may hold"), before
    anything runs."""
    if not isinstance(scenario, Scenario):
        raise TypeError(f"sim.run takes a sim.Scenario, got {type(scenario).__name__}")
    out_json, tr, errs = _native.run_scenario(scenario.to_json(), controller, trace, threads)
    o = json.loads(out_json)
    return Outcome(
        metrics=o["metrics"],
        trace_hash=o["trace_hash"],
        radio=o["radio"],
        coverage=o["coverage"],
        recording=o.get("recording"),
        trace=Trace(**tr) if tr is not None else None,
        process_errors=[tuple(e) for e in errs],  # type: ignore[misc]
    )


def _run_one(job: tuple[Scenario, Optional[Controller]]) -> Outcome:
    return run(job[0], job[1])


def sweep(
    scenarios: Iterable[Scenario],
    controller: Optional[Controller] = None,
    *,
    executor: Union[str, Executor, Any, None] = None,
    workers: Optional[int] = None,
) -> list[Outcome]:
    """Run every scenario and return the outcomes in the same order. Deterministic: the
    outcomes are those of a serial run, wherever they ran.

    ``executor``: None for a local process pool (``workers`` processes, default the CPU
    count); ``"serial"`` to run here; any ``concurrent.futures.Executor``; a Dask
    ``distributed.Client`` (runs on its cluster); or the ``ray`` module after
    ``ray.init()``. A Python ``controller`` must be picklable (a module-level function or
    class) to leave this process.
    """
    jobs = [(s, controller) for s in scenarios]
    if executor == "serial":
        return [_run_one(j) for j in jobs]
    if executor is None:
        with ProcessPoolExecutor(max_workers=workers or os.cpu_count() or 1) as pool:
            return list(pool.map(_run_one, jobs))
    if isinstance(executor, Executor):
        return list(executor.map(_run_one, jobs))
    engine: Any = executor
    kind = type(engine).__module__.split(".")[0]
    if kind == "distributed":  # a Dask client
        futures = engine.map(_run_one, jobs, pure=False)
        return list(engine.gather(futures))
    if getattr(engine, "__name__", "") == "ray":
        remote = engine.remote(_run_one)
        return list(engine.get([remote.remote(j) for j in jobs]))
    raise TypeError(f"executor must be None, 'serial', an Executor, a dask Client or the ray module; got {executor!r}")


class ServedWorld:
    """A world served to robots whose controllers run elsewhere: the simulator's distributed
    mode, what ``ayllu sim serve`` runs (``ayllu_sim::served_world``; docs/python.md, "Serving a
    world"). The world is the in-process one for ``scenario`` (its world, team, seed, duration
    and kills), paced on the real clock; each robot K's body is a node (id 1000 + K) on its URL
    that feeds the sensors of node K and takes its motor commands, wherever node K runs: an
    ``ayllu sim robot`` process, or an ``ayllu.Node`` with ``install_served_body``.

    ``urls``: one per robot, or one for all in which ``{i}`` stands for the robot's number (one
    URL without ``{i}`` for several bodies must bind port 0); a body greets the addresses its URL
    names (``peer=``, ``broadcast=``). ``until_stopped``: serve until :meth:`stop` rather than for
    the scenario's duration. ``wait``: seconds :meth:`start` waits for every body to hear its
    controller. ``status_every``: world seconds between status events.

    Events are the dicts of ``ayllu sim serve``'s JSON lines: ``{"start": True, ...}``,
    ``{"t": .., "kill": K}``, status ``{"t": .., "observed": .., "weighted": .., "a_w": ..,
    "robots": [...]}`` and ``{"done": True, ..., "metrics": {...}}``. ``ayllu.InvalidError`` (a
    ``ValueError``) for a scenario out of bounds or URLs that do not fit the team,
    ``ayllu.NetworkError`` for a socket the system refuses.
    """

    def __init__(
        self,
        scenario: Scenario,
        urls: Union[str, Sequence[str]],
        *,
        until_stopped: bool = False,
        wait: float = 10.0,
        status_every: float = 1.0,
    ) -> None:
        if not isinstance(scenario, Scenario):
            raise TypeError(f"ServedWorld takes a sim.Scenario, got {type(scenario).__name__}")
        urls = [urls] if isinstance(urls, str) else list(urls)
        self._world = _native.ServedWorld(
            scenario.to_json(), urls, until_stopped=until_stopped, wait=wait, status_every=status_every
        )

    def body_addresses(self) -> list[Optional[str]]:
        """Where each body's node listens (``ip:port``), robot 1 first."""
        return self._world.body_addresses()

    def linked(self) -> list[bool]:
        """Whether each body hears its controller now."""
        return self._world.linked()

    def start(self) -> dict[str, Any]:
        """Wait for the robots (at most ``wait`` seconds), start the clock: the start event."""
        return dict(json.loads(self._world.start()))

    def step(self) -> list[dict[str, Any]]:
        """One tick (50 ms of world time, paced on the real clock): its kill and status events."""
        return [json.loads(e) for e in self._world.step()]

    @property
    def done(self) -> bool:
        """Whether the run is over: its duration served, or stopped."""
        return self._world.done

    @property
    def now(self) -> float:
        """World seconds served so far."""
        return self._world.now

    def finish(self) -> dict[str, Any]:
        """End the run (stopping it if needed): the done event, with ``metrics``."""
        return dict(json.loads(self._world.finish()))

    def stop(self) -> None:
        """Ask the world to stop; callable from any thread."""
        self._world.stop()

    def run(self, on_event: Optional[Callable[[dict[str, Any]], None]] = None) -> dict[str, Any]:
        """Start, step to the end, finish, handing every event to ``on_event`` as it comes;
        return the done event. Ctrl-C (``KeyboardInterrupt``) stops the run, which still
        finishes with its metrics (``"stopped": True``)."""
        emit = on_event or (lambda _e: None)
        try:
            emit(self.start())
            while not self.done:
                for e in self.step():
                    emit(e)
        except KeyboardInterrupt:
            self.stop()
        done = self.finish()
        emit(done)
        return done


def serve(
    scenario: Scenario,
    urls: Union[str, Sequence[str]],
    *,
    on_event: Optional[Callable[[dict[str, Any]], None]] = None,
    until_stopped: bool = False,
    wait: float = 10.0,
    status_every: float = 1.0,
) -> dict[str, Any]:
    """Serve ``scenario``'s world to robots on ``urls`` to its end (:class:`ServedWorld`):
    ``ayllu sim serve`` from Python. Returns the done event (``metrics``: the in-process ones)."""
    world = ServedWorld(scenario, urls, until_stopped=until_stopped, wait=wait, status_every=status_every)
    return world.run(on_event)
