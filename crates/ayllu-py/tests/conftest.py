"""Fixtures shared by the rule tests: the core's `common` fixtures, from Python.

A node on a manual clock with class ``Relay`` (one int port ``V``, Normal, default 0) and one
Relay per name; time in milliseconds. Time moves only when a test says so.
"""

from __future__ import annotations

from typing import Optional

import ayllu

V = "V"


class Relay(ayllu.Behavior):
    v = ayllu.Port(0, name=V)


def wiring(names: list[str], node_id: int = 1) -> ayllu.Node:
    node = ayllu.Node(node_id, manual=True)
    node.define(Relay)
    for n in names:
        node.create("Relay", n)
    return node


def link(node: ayllu.Node, src: str, dst: str, kind: Optional[ayllu.Kind] = None) -> int:
    return node.connect(ayllu.local(src, V), ayllu.local(dst, V), kind)


def put(node: ayllu.Node, t_ms: float, name: str, v: int) -> None:
    """``name.V := v`` at ``t_ms`` milliseconds, as ``name``'s own behavior would write it."""
    node.set_time(t_ms / 1000)
    node.write(name, V, v)


def value(node: ayllu.Node, name: str) -> int:
    return node.read(name, V)  # type: ignore[no-any-return]


def accepted(node: ayllu.Node, name: str) -> int:
    return node.why(name, V).accepted  # type: ignore[no-any-return]


def dropped(node: ayllu.Node, name: str, cause: str) -> int:
    return node.why(name, V).counters.get(cause, 0)  # type: ignore[no-any-return]
