"""The core's ``fan_in`` fixture from Python: sources S0..Sk-1 (port ``Out``), each connected to
``AGG.In`` (the port under test) with its own priority, and ``AGG.In`` connected to
``TAP.In`` (what propagated). Time in milliseconds, on a manual clock."""

from __future__ import annotations

from typing import Any, Optional

import ayllu


class FanIn:
    def __init__(
        self, default: ayllu.PortValue, kind: str, k: int = 2, priorities: Optional[list[int]] = None, **opts: float
    ) -> None:
        class Src(ayllu.Behavior):
            out = ayllu.Port(default, name="Out")

        class Agg(ayllu.Behavior):
            inp = ayllu.Port(default, kind=kind, name="In", **opts)

        class Tap(ayllu.Behavior):
            inp = ayllu.Port(default, name="In")

        self.node = ayllu.Node(1, manual=True)
        self.node.create(Agg, "AGG")
        self.node.create(Tap, "TAP")
        self.node.connect(ayllu.local("AGG", "In"), ayllu.local("TAP", "In"))
        prios = priorities or [0] * k
        self.conns = []
        for i, p in enumerate(prios):
            self.node.create(Src, f"S{i}")
            self.conns.append(self.node.connect(ayllu.local(f"S{i}", "Out"), ayllu.local("AGG", "In"), priority=p))

    def send(self, i: int, t_ms: float, v: ayllu.PortValue) -> None:
        self.node.set_time(t_ms / 1000)
        self.node.write(f"S{i}", "Out", v)

    def at(self, t_ms: float) -> None:
        self.node.set_time(t_ms / 1000)

    def read(self) -> Any:
        return self.node.read("AGG", "In")

    def tap(self) -> Any:
        return self.node.read("TAP", "In")

    def why(self) -> ayllu.Report:
        return self.node.why("AGG", "In")

    def supplier_conn(self) -> Optional[int]:
        s = self.why().supplier
        return None if s is None else int(s.conn)

    def propagated(self) -> int:
        return int(self.node.why("TAP", "In").accepted)
