"""Rule S4 from Python: lifespans (mirrors ayllu-core's tests/freshness.rs)."""

from __future__ import annotations

import ayllu


class Eye(ayllu.Behavior):
    angle = ayllu.Port(0.0, lifespan=0.25, name="Angle")


def test_a_port_goes_absent_after_its_lifespan() -> None:
    node = ayllu.Node(1, manual=True)
    node.create(Eye, "E")
    assert node.get("E", "Angle") is None, "never written: not fresh"
    node.write("E", "Angle", 0.3)
    node.set_time(0.249)
    assert node.get("E", "Angle") == 0.3
    node.set_time(0.25)
    assert node.get("E", "Angle") is None
    assert node.read("E", "Angle") == 0.3, "read ignores freshness"
    assert not node.why("E", "Angle").fresh


def test_a_process_sees_absence_as_none() -> None:
    seen: list[object] = []

    class Observer(ayllu.Behavior):
        angle = ayllu.Port(0.0, lifespan=0.1, name="Angle")

        @ayllu.every(hz=10)
        def look(self, ctx: ayllu.Context) -> None:
            seen.append(ctx.get(self.angle))

    node = ayllu.Node(1, manual=True)
    node.create(Observer, "O")
    node.write("O", "Angle", 1.0)
    node.step()
    node.advance(0.2, tick=0.1)
    assert seen == [1.0, None, None]
