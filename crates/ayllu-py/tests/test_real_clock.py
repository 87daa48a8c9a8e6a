"""Nodes on the real clock: a background thread runs processes; Python keeps control.
Timing never decides a verdict: waits are generous and only bound how long the test may take."""

from __future__ import annotations

import time

import pytest

import ayllu


class Counter(ayllu.Behavior):
    out = ayllu.Port(0, name="Out")
    n = ayllu.Slot(0)

    @ayllu.every(hz=100)
    def tick(self, ctx: ayllu.Context) -> None:
        n = ctx.slot(self.n) + 1
        ctx.set_slot(self.n, n)
        ctx.write(self.out, n)


def wait_for(cond: object, timeout: float = 20.0) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if callable(cond) and cond():
            return
        time.sleep(0.01)
    raise AssertionError("condition not met in time")


def test_a_started_node_runs_its_processes_in_the_background() -> None:
    node = ayllu.Node(1)
    node.create(Counter, "C")
    node.start()
    assert node.running
    wait_for(lambda: node.read("C", "Out") >= 5)
    node.write("C", "Out", -100)  # Python calls go in while the node runs
    node.stop()
    assert not node.running
    frozen = node.read("C", "Out")
    time.sleep(0.05)
    assert node.read("C", "Out") == frozen, "stopped: nothing runs"
    node.close()


def test_run_for_steps_in_the_foreground() -> None:
    node = ayllu.Node(1)
    node.create(Counter, "C")
    node.run_for(0.1)
    assert node.read("C", "Out") >= 1


def test_two_real_nodes_over_udp_loopback() -> None:
    a = ayllu.Node(1, "udp://127.0.0.1:0")
    addr = a.address()
    assert addr is not None and addr.startswith("127.0.0.1:")
    b = ayllu.Node(2, f"udp://127.0.0.1:0?peer={addr}")
    for n in (a, b):
        n.create(Counter, "C")
    b.connect(ayllu.local("C", "Out"), ayllu.remote(1, "C", "Out"), ayllu.override_in(0.5))
    a.start()
    b.start()
    try:
        wait_for(lambda: a.why("C", "Out").windows != [])
    finally:
        a.close()
        b.close()


def test_a_program_may_exit_with_its_nodes_running() -> None:
    import subprocess
    import sys

    code = (
        "import time, ayllu\n"
        "class C(ayllu.Behavior):\n"
        "    @ayllu.every(hz=100)\n"
        "    def t(self, ctx): pass\n"
        "n = ayllu.Node(1); n.create(C, 'C'); n.start(); time.sleep(0.1); print('bye')\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert (out.returncode, out.stdout) == (0, "bye\n"), out.stderr


def test_default_url_is_ayllu_url_else_the_machine_local_default(monkeypatch: pytest.MonkeyPatch) -> None:
    # The URL every Ayllu program uses when told nothing else (docs/cli.md), from the runtime.
    monkeypatch.setenv("AYLLU_URL", "udp://127.0.0.1:0?team=3")
    assert ayllu.default_url() == "udp://127.0.0.1:0?team=3"
    node = ayllu.Node(1, ayllu.default_url())
    assert node.address() is not None and node.address().startswith("127.0.0.1:")  # type: ignore[union-attr]
    node.close()
    monkeypatch.delenv("AYLLU_URL")
    assert ayllu.default_url() == "udp://0.0.0.0:0?discovery=239.255.65.89:7390&ttl=0"
