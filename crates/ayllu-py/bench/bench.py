"""Benchmarks of the Python package (``make bench-python``; not part of the tests).

Each figure is printed beside a baseline measured in the same run: a plain Python function
call (``f(x)`` returning its argument), so the numbers can be read on any machine. Measured:

* a port write from Python (through a resolved ``PortHandle``, and by name);
* a Python process activation (a periodic process whose body does one ``ctx.write``);
* a simulation step with the Python Fig. 2 controller, beside the Rust one's;
* the CPU a real-clock node running one 100 Hz Python process costs (process CPU time over
  wall time), beside an idle real-clock node.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Callable

import ayllu
from ayllu import sim

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "examples" / "cmommt" / "python"))
import fig2

REPEATS = 5


def per_call(fn: Callable[[int], None], n: int) -> float:
    """Best of REPEATS of the mean seconds per call of ``fn(n)`` (which makes n calls)."""
    best = float("inf")
    for _ in range(REPEATS):
        t0 = time.perf_counter()
        fn(n)
        best = min(best, (time.perf_counter() - t0) / n)
    return best


def plain(x: float) -> float:
    return x


def baseline(n: int) -> None:
    f = plain
    for _ in range(n):
        f(1.0)


class Sink(ayllu.Behavior):
    out = ayllu.Port(0.0, name="Out")


class Writer(ayllu.Behavior):
    out = ayllu.Port(0.0, name="Out")

    @ayllu.every(hz=100)
    def work(self, ctx: ayllu.Context) -> None:
        ctx.write(self.out, 1.0)


def bench_writes() -> tuple[float, float]:
    node = ayllu.Node(1, manual=True)
    node.create(Sink, "S")
    h = node.port("S", "Out")

    def by_handle(n: int) -> None:
        w = h.write
        for _ in range(n):
            w(1.0)

    def by_name(n: int) -> None:
        w = node.write
        for _ in range(n):
            w("S", "Out", 1.0)

    return per_call(by_handle, 200_000), per_call(by_name, 200_000)


def bench_activation() -> tuple[float, float]:
    """Seconds per activation of a 100 Hz Python process, and per step of the same node with
    the process removed (what the activation adds is the difference)."""
    behaviors = 100

    def run(with_process: bool) -> float:
        node = ayllu.Node(1, manual=True)
        for i in range(behaviors):
            node.create(Writer if with_process else Sink, f"W{i}")
        node.step()
        steps = 200
        t0 = time.perf_counter()
        node.advance(steps * 0.01, tick=0.01)
        dt = time.perf_counter() - t0
        return dt / (steps * behaviors)

    best_with = min(run(True) for _ in range(REPEATS))
    best_without = min(run(False) for _ in range(REPEATS))
    return best_with, best_without


def bench_sim_step() -> tuple[float, float]:
    s = sim.Scenario.paper("BLE", 1).with_(duration=300.0)
    ticks = round(300.0 / 0.05)

    def timed(controller: object) -> float:
        best = float("inf")
        for _ in range(3):
            t0 = time.perf_counter()
            sim.run(s, controller)  # type: ignore[arg-type]
            best = min(best, time.perf_counter() - t0)
        return best / ticks

    return timed(fig2.build), timed(None)


def bench_cpu_100hz(seconds: float = 3.0) -> tuple[float, float]:
    def cpu_share(cls: type) -> float:
        node = ayllu.Node(1)
        node.create(cls, "W")
        node.start()
        time.sleep(0.2)
        c0, w0 = time.process_time(), time.perf_counter()
        time.sleep(seconds)
        c1, w1 = time.process_time(), time.perf_counter()
        runs = node.report().behaviors[0].processes
        node.close()
        if runs:
            assert runs[0].runs > 0
        return (c1 - c0) / (w1 - w0)

    return cpu_share(Writer), cpu_share(Sink)


def main() -> None:
    base = per_call(baseline, 1_000_000)
    print(f"baseline: a plain Python function call            {base * 1e9:8.1f} ns")
    handle, name = bench_writes()
    print(f"port write from Python (PortHandle.write)         {handle * 1e9:8.1f} ns  ({handle / base:.1f} x the call)")
    print(f"port write from Python (Node.write by name)       {name * 1e9:8.1f} ns  ({name / base:.1f} x the call)")
    act, idle = bench_activation()
    print(
        f"Python process activation (one ctx.write)         {(act - idle) * 1e9:8.1f} ns  "
        f"({(act - idle) / base:.1f} x the call; step with no process {idle * 1e9:.1f} ns per behavior)"
    )
    py_step, rust_step = bench_sim_step()
    print(
        f"simulation step, Python Fig. 2 (3 robots)         {py_step * 1e6:8.2f} us  "
        f"(Rust Fig. 2 {rust_step * 1e6:.2f} us; {py_step / base:.0f} x the call; "
        f"{0.05 / py_step:.0f}x real time)"
    )
    busy, quiet = bench_cpu_100hz()
    print(
        f"real-clock node, one 100 Hz Python process       {busy * 100:8.2f} % of a core  "
        f"(idle real-clock node {quiet * 100:.2f} %)"
    )
    print(f"(best of {REPEATS}; Python {sys.version.split()[0]})")


if __name__ == "__main__":
    main()
