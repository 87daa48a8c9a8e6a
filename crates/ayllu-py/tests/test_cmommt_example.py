"""examples/cmommt/python: the paper's Fig. 2 written in Python reaches the Rust controller's
coverage, in process (the same seeds; in fact the same runs) and as separate processes against
``ayllu sim serve``, reporting to the server what its metrics need (switches, messages, bytes)
with no code of their own."""

from __future__ import annotations

import contextlib
import json
import os
import select
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Optional

from ayllu import sim

EXAMPLE = Path(__file__).resolve().parents[3] / "examples" / "cmommt" / "python"
sys.path.insert(0, str(EXAMPLE))

import fig2  # noqa: E402


def test_in_process_a_w_matches_the_rust_controller_on_the_same_seeds() -> None:
    seeds = list(range(1, 6))
    res = fig2.compare(seeds)
    rust, py = res["rust"], res["python"]
    spread = statistics.stdev(rust)
    print(f"A_w over seeds {seeds}: Rust {statistics.mean(rust):.3f} ± {spread:.3f}, Python {statistics.mean(py):.3f}")
    assert abs(statistics.mean(py) - statistics.mean(rust)) <= spread
    # Stronger: the Python controller writes what the Rust one writes, so each run is the same.
    s = sim.Scenario.paper("BLE", 3).with_(duration=60.0)
    assert sim.run(s, fig2.build).trace_hash == sim.run(s).trace_hash


def ayllu_bin() -> Optional[str]:
    env = os.environ.get("AYLLU_BIN")
    if env and Path(env).exists():
        return env
    root = Path(__file__).resolve().parents[3]
    target = Path(os.environ.get("CARGO_TARGET_DIR", root / "target"))
    for p in (target / "debug" / "ayllu", target / "release" / "ayllu"):
        if p.exists():
            return str(p)
    return shutil.which("ayllu")


class Proc:
    """A child whose stdout JSON lines are read as they come; killed at the end."""

    def __init__(self, args: list[str]) -> None:
        self.p = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=EXAMPLE)
        self.lines: list[dict[str, Any]] = []

    def wait_for(self, key: str, timeout: float) -> dict[str, Any]:
        end = time.monotonic() + timeout
        assert self.p.stdout is not None
        while time.monotonic() < end:
            for line in self.lines:
                if key in line:
                    return line
            ready, _, _ = select.select([self.p.stdout], [], [], 0.5)
            if ready:
                raw = self.p.stdout.readline()
                if raw == "" and self.p.poll() is not None:
                    break
                with contextlib.suppress(json.JSONDecodeError):
                    self.lines.append(json.loads(raw))
        err = self.p.stderr.read() if self.p.poll() is not None and self.p.stderr else ""
        raise AssertionError(f"no {key!r} line within {timeout} s; got {self.lines[-3:]}; stderr: {err}")

    def stop(self) -> tuple[int, str]:
        if self.p.poll() is None:
            self.p.terminate()
        try:
            _, err = self.p.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            self.p.kill()
            _, err = self.p.communicate()
        return self.p.returncode, err


# The world of the C and Rust process tests (crates/ayllu-c/tests/library/cmommt_team.rs): the team
# finds targets early, so 45 s show the task being done.
SEED, DURATION = 7, 45.0
MARGIN_OVER_RANDOM, MARGIN_UNDER_RUST = 0.2, 0.12


def test_as_processes_against_sim_serve_it_covers_like_the_rust_controller() -> None:
    ayllu = ayllu_bin()
    assert ayllu is not None, "the ayllu tool is not built (make test builds it first; or set AYLLU_BIN)"
    ble_metrics = sim.run(sim.Scenario.sized("BLE", 3, 4, SEED).with_(duration=DURATION)).metrics
    ble, ble_msgs = ble_metrics["a_w"], ble_metrics["msgs_per_robot_s"]
    random = max(
        sim.run(sim.Scenario.sized("Random", 3, 4, SEED).with_(duration=DURATION, controllers__wander_seed=w)).metrics[
            "a_w"
        ]
        for w in range(1, 11)
    )
    robots: list[Proc] = []
    addrs: list[str] = []
    try:
        for k in (1, 2, 3):
            peers = "&".join(f"peer={a}" for a in addrs)
            url = "udp://127.0.0.1:0" + (f"?{peers}" if peers else "")
            r = Proc([sys.executable, "robot.py", str(k), url, str(DURATION + 60), str(SEED)])
            robots.append(r)
            addrs.append(r.wait_for("listening", 60)["listening"])
        cmd = [ayllu, "sim", "serve", "--robots", "3", "--targets", "4", "--seed", str(SEED), "--wait", "20"]
        cmd += ["--duration", str(DURATION)]
        for a in addrs:
            cmd += ["--udp", f"udp://127.0.0.1:0?peer={a}"]
        server = Proc(cmd)
        done = server.wait_for("done", DURATION + 60)
        start = next(line for line in server.lines if "start" in line)
        server.stop()
        assert start["missing"] == [], f"a body never heard its Python robot: {start}"
        a_w = done["metrics"]["a_w"]
        print(f"Python team (3 processes): A_w {a_w:.3f}; in process: Rust BLE {ble:.3f}, best Random {random:.3f}")
        assert a_w >= random + MARGIN_OVER_RANDOM
        assert a_w >= ble - MARGIN_UNDER_RUST
        # What the robots report over LINK with no code of robot.py's (install_served_body
        # attaches the driver): the drive, for switches; their radio emissions and bytes, near
        # the Rust controller's in-process.
        m = done["metrics"]
        print(f"server's final metrics: {m}; radio: {done['radio']}")
        assert m["switches_per_min"] > 0, f"no switch reported by the Python robots (LINK.Drive): {done}"
        assert ble_msgs / 2 <= m["msgs_per_robot_s"] <= ble_msgs * 2, f"in-process BLE: {ble_msgs:.1}; {done}"
        assert m["bytes_per_robot_s"] > 10 * m["msgs_per_robot_s"], done
        assert done["radio"]["sent"] > 0, done
    finally:
        for r in robots:
            code, err = r.stop()
            assert code == 0, f"a Python robot exited with {code}: {err}"
