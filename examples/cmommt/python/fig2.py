"""The paper's Fig. 2 in Python: observers in a subsumption chain over WANDER, each layer
cross-inhibited across robots by BLE (with the errata of docs/semantics.md fixed, as in
``ayllu::stdlib``).

``build(robot)`` builds it on one robot's node: a simulated robot (``ayllu.sim.RobotBuilder``,
see ``python -m fig2`` / ``run(...)`` below) or a robot of its own process (an ``ayllu.Node``
with a served body, see ``robot.py``). It writes exactly what the Rust controller
(``ayllu_sim::controller::build`` with ``Controller::Ble``) writes, in the same order, so on
the same seed the two runs are the same run.
"""

from __future__ import annotations

from typing import Any, Optional

import ayllu
from ayllu import sim

VISION_LIFESPAN = 0.25
"""How long a camera reading stays fresh (s): a little over two frames at 10 Hz."""
OVERRIDE_PERIOD = 0.2
"""The subsumption period between observer layers (s)."""
GROUP = "Peers"
"""The BLE group every layer joins."""


class Observer(ayllu.Behavior):
    """Fig. 2's ``ObserveTarget``: at 20 Hz, if its target is in view, turn towards it and offer
    the target's apparent height (larger = closer) as BLE eligibility."""

    target_x = ayllu.Port(0.0, lifespan=VISION_LIFESPAN, name="TargetX")
    target_y = ayllu.Port(0.0, lifespan=VISION_LIFESPAN, name="TargetY")
    rotate = ayllu.Port(0.0, name="Rotate")
    offered = ayllu.Slot(0.0, name="Offered")
    offered_at = ayllu.Slot(-1.0, name="OfferedAt")

    @ayllu.every(hz=20)
    def turn_to_target(self, ctx: ayllu.Context) -> None:
        bearing, height = ctx.get(self.target_x), ctx.get(self.target_y)
        if bearing is None or height is None:
            return  # errata: no output when the target is not seen
        ctx.write(self.rotate, -bearing)
        ctx.write(self.LOCAL, height)
        ctx.set_slot(self.offered, height)
        ctx.set_slot(self.offered_at, ctx.now)


def make_observer(robot: Any, num: int, next_layer: str, claim_hz: float) -> None:
    """The paper's ``MakeObserver(num, next)``: ``OBS{num}`` fed target ``num`` from VISION,
    overriding ``next_layer.Rotate``, in the layer's BLE group."""
    name = f"OBS{num}"
    robot.create(Observer, name)
    robot.connect(ayllu.local("VISION", f"Target{num}Angle"), ayllu.local(name, "TargetX"))
    robot.connect(ayllu.local("VISION", f"Target{num}Bottom"), ayllu.local(name, "TargetY"))
    robot.connect(ayllu.local(name, "Rotate"), ayllu.local(next_layer, "Rotate"), ayllu.override_out(OVERRIDE_PERIOD))
    robot.ble_join(name, GROUP, "Rotate", claim_hz)


def build(
    robot: Any,
    priorities: Optional[list[float]] = None,
    claim_hz: Optional[float] = None,
    wander_seed: Optional[int] = None,
) -> sim.BrainSpec:
    """Fig. 2 on ``robot`` (its body VISION, SONAR, BASE already there). The arguments default
    to the simulator's (``robot.priorities``, ...), which a served robot's node does not have."""
    prios = priorities if priorities is not None else robot.priorities
    hz = claim_hz if claim_hz is not None else robot.claim_hz
    seed = wander_seed if wander_seed is not None else robot.wander_seed
    m = len(prios)
    # The same body-level behaviors as every controller (the standard library's).
    robot.define_stdlib("SafeVelocity")
    robot.define_stdlib("RandomWander", hz=10.0, seed=seed)
    robot.create("SafeVelocity", "VEL")
    robot.create("RandomWander", "WANDER")
    robot.connect(ayllu.local("SONAR", "Ranges"), ayllu.local("VEL", "Ranges"))
    robot.connect(ayllu.local("VEL", "Translate"), ayllu.local("BASE", "Translate"))
    robot.connect(ayllu.local("WANDER", "Rotate"), ayllu.local("BASE", "Rotate"))
    robot.define(Observer)
    # Lowest layer first, so that each layer's next exists when it is made.
    for num in range(m, 0, -1):
        make_observer(robot, num, "WANDER" if num == m else f"OBS{num + 1}", hz)
    return sim.chain([(f"OBS{n}", "Rotate") for n in range(1, m + 1)])


def compare(seeds: list[int], duration: float = 300.0) -> dict[str, list[float]]:
    """A_w of the Rust BLE controller and of this one on the paper's setting, seed by seed."""
    out: dict[str, list[float]] = {"rust": [], "python": []}
    for seed in seeds:
        s = sim.Scenario.paper("BLE", seed).with_(duration=duration)
        out["rust"].append(sim.run(s).metrics["a_w"])
        out["python"].append(sim.run(s, build).metrics["a_w"])
    return out


if __name__ == "__main__":
    import statistics

    res = compare(list(range(1, 11)))
    for who, aw in res.items():
        print(f"{who:7} A_w = {statistics.mean(aw):.3f} ± {statistics.stdev(aw):.3f}  ({len(aw)} seeds)")
