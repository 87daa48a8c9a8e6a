"""Tutorial 4, a BLE group of three robots in the simulator
(docs/tutorials/04-ble-in-the-simulator.md), in Python: the paper's setting, robot 1 killed at
30 s, BLE against Random in the same world, and who was alive and driven by what, from the trace.

Exits non-zero (an AssertionError) if what the tutorial says does not happen.
"""

from ayllu import sim


def main() -> None:
    ble = sim.Scenario.paper("BLE", seed=1).with_(duration=60.0).kill(at=30.0, robot=1)
    random = ble.with_(controller="Random")
    out = sim.run(ble, trace=True)
    base = sim.run(random)
    print(f"A_w with BLE {out.metrics['a_w']:.3f}, with Random {base.metrics['a_w']:.3f} (same world, same kill)")
    assert out.metrics["a_w"] > base.metrics["a_w"] + 0.2, "BLE observes far more than wandering"

    assert out.trace is not None  # kept because trace=True
    frame = out.trace.frame()  # one row per tick and robot
    alive = frame.groupby("robot")["alive"].min()
    print("alive at the end:", {int(r): bool(a) for r, a in alive.items()})
    assert not alive[1] and alive[2] and alive[3], "robot 1 was killed at 30 s"
    assert sim.run(ble).trace_hash == sim.run(ble).trace_hash, "a run is deterministic"


if __name__ == "__main__":
    main()
