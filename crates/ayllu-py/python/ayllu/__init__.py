"""Ayllu for Python: port-arbitrated behaviors, nodes, teams and the multi-robot simulator.

Behaviors are classes whose ports, slots and monostables are class attributes and whose
processes are decorated methods; nodes run them on the real clock (a background thread) or on
a manual clock (deterministic); connections pass, suppress, inhibit and override messages.
Every rule is decided by the Rust core (``ayllu-core``); this package declares, wires, drives
time and reads results.

>>> import ayllu
>>> class Relay(ayllu.Behavior):
...     inp = ayllu.Port(0.0, name="In")
...     out = ayllu.Port(0.0, name="Out")
...     @ayllu.on_write(inp)
...     def forward(self, ctx: ayllu.Context) -> None:
...         ctx.write(self.out, 2 * ctx.read(self.inp))
>>> node = ayllu.Node(1, manual=True)
>>> _ = node.create(Relay, "R")
>>> node.write("R", "In", 21.0)
>>> _ = node.step()
>>> node.read("R", "Out")
42.0
"""

from __future__ import annotations

import atexit
from typing import Any, Callable, NamedTuple, Optional, TypeVar, Union

from ayllu import _native
from ayllu._native import (
    DROP_CAUSES,
    AylluError,
    Context,
    InvalidError,
    NetworkError,
    Node,
    NodeBusyError,
    NotFoundError,
    PortHandle,
    Team,
    ValueTypeError,
    check_recording,
    check_team,
    default_url,
    why_team,
)
from ayllu._native import MonoDecl as Monostable
from ayllu._native import PortDecl as Port
from ayllu._native import SlotDecl as Slot
from ayllu.report import ProcessError, Report, RequestStatus

# Background threads of started nodes must not run Python code while the interpreter shuts
# down: stop them first.
atexit.register(_native.stop_all)

__all__ = [
    "DROP_CAUSES",
    "NORMAL",
    "AylluError",
    "Behavior",
    "Context",
    "Endpoint",
    "InvalidError",
    "Kind",
    "Monostable",
    "NetworkError",
    "Node",
    "NodeBusyError",
    "NotFoundError",
    "Port",
    "PortHandle",
    "ProcessError",
    "Report",
    "RequestStatus",
    "Slot",
    "Team",
    "ValueTypeError",
    "broadcast",
    "check_recording",
    "check_team",
    "default_url",
    "every",
    "inhibit",
    "local",
    "on_monostable",
    "on_write",
    "override_in",
    "override_out",
    "remote",
    "suppress",
    "why_team",
    "write_inhibit",
]


class Endpoint(NamedTuple):
    """A port to connect: on this node, on node ``node``, or on every node of ``group``."""

    behavior: str
    port: str
    node: Optional[int] = None
    group: Optional[str] = None


def local(behavior: str, port: str) -> Endpoint:
    """A port of a behavior on this node."""
    return Endpoint(behavior, port)


def remote(node: int, behavior: str, port: str) -> Endpoint:
    """A port of a behavior on node ``node`` (messages go over the transport)."""
    return Endpoint(behavior, port, node=node)


def broadcast(group: str, behavior: str, port: str) -> Endpoint:
    """The port of that behavior on every node in broadcast group ``group``."""
    return Endpoint(behavior, port, group=group)


class Kind(NamedTuple):
    """A connection kind and its period in seconds (None for Normal)."""

    name: str
    period: Optional[float] = None


NORMAL = Kind("normal")
"""Write the message into the destination (unless it is suppressed) and propagate it."""


def suppress(period: float) -> Kind:
    """Do not write; block every connection write into the destination for ``period`` s."""
    return Kind("suppress", period)


def inhibit(period: float) -> Kind:
    """Do not write; block all propagation out of the destination for ``period`` s."""
    return Kind("inhibit", period)


def override_in(period: float) -> Kind:
    """Write and propagate; for ``period`` s only this connection may write the destination."""
    return Kind("override-in", period)


def override_out(period: float) -> Kind:
    """Write and propagate; for ``period`` s only values along this connection propagate out."""
    return Kind("override-out", period)


def write_inhibit(period: float) -> Kind:
    """Do not write; for ``period`` s the destination's own behavior's writes do not propagate."""
    return Kind("write-inhibit", period)


F = TypeVar("F", bound=Callable[..., Any])

# The longest span a node's clock holds: 2**64 - 1 nanoseconds, about 584 years.
_MAX_SECONDS = 18446744073.709553


def every(
    *, hz: Optional[float] = None, period: Optional[float] = None, while_fresh: Optional[Port] = None
) -> Callable[[F], F]:
    """A periodic process: ``hz`` activations a second, or one every ``period`` seconds,
    phase-locked to the behavior's creation (rule S7). With ``while_fresh=port`` (a port of
    the same class) it is activated only at the due times at which that port holds a fresh
    value; at the others it is not run and not counted (D7.5) — for a process that does
    nothing without that port's value."""
    if (hz is None) == (period is None):
        raise ValueError("give exactly one of hz= or period=")
    if while_fresh is not None and not isinstance(while_fresh, Port):
        raise TypeError(f"while_fresh takes a Port declared in the class body, not {while_fresh!r}")
    if hz is not None:
        # The rate's period must be a duration too (1 ns to 584 years), said as a bad rate:
        # hz=1e-300 used to be refused as a period of 1e300 s the caller never wrote.
        if not (1.0 / _MAX_SECONDS <= hz <= 1e9):
            raise InvalidError(
                f"rate {hz:g} Hz is invalid; rates must be finite and above zero, with a period from 1 ns to 584 years"
            )
        period = 1.0 / hz

    def mark(fn: F) -> F:
        if while_fresh is None:
            fn.__ayllu_process__ = ("every", period)  # type: ignore[attr-defined]
        else:
            fn.__ayllu_process__ = ("every_while_fresh", (period, while_fresh))  # type: ignore[attr-defined]
        return fn

    return mark


def on_write(port: Port) -> Callable[[F], F]:
    """A process that runs whenever ``port`` (of the same class) accepts a value."""
    if not isinstance(port, Port):
        raise TypeError(f"on_write takes a Port declared in the class body, not {port!r}")

    def mark(fn: F) -> F:
        fn.__ayllu_process__ = ("on_write", port)  # type: ignore[attr-defined]
        return fn

    return mark


def on_monostable(mono: Monostable) -> Callable[[F], F]:
    """A process that runs whenever monostable ``mono`` rises or falls."""
    if not isinstance(mono, Monostable):
        raise TypeError(f"on_monostable takes a Monostable declared in the class body, not {mono!r}")

    def mark(fn: F) -> F:
        fn.__ayllu_process__ = ("on_monostable", mono)  # type: ignore[attr-defined]
        return fn

    return mark


class Behavior:
    """Base class of behaviors. Declare ``Port``, ``Slot`` and ``Monostable`` class attributes
    and processes decorated with ``every``, ``on_write`` or ``on_monostable``; each process is
    called as ``process(self, ctx)`` where ``self`` is the behavior's Python object (one per
    created behavior) and ``ctx`` its :class:`Context`. The class name is the Ayllu class name
    unless ``name = "..."`` is given as a class keyword. Every class also has the BLE ports
    ``Local``, ``Inhibit`` and ``Best`` (rule S11); those names are reserved.
    """

    LOCAL = 0
    """The implicit BLE port ``Local`` (this behavior's eligibility), for ``ctx.write``."""
    INHIBIT = 1
    """The implicit BLE port ``Inhibit`` (written when this behavior claims its task)."""
    BEST = 2
    """The implicit BLE port ``Best`` (the best eligibility heard from peers, Max)."""

    __ayllu__: tuple[str, list[Port], list[Slot], list[Monostable], list[tuple[str, str, Any, Callable[..., Any]]]]

    def __init_subclass__(cls, name: Optional[str] = None, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        # Base classes first; a subclass's attribute of the same name replaces the base's.
        decls: dict[str, Union[Port, Slot, Monostable]] = {}
        procs: dict[str, tuple[str, str, Any, Callable[..., Any]]] = {}
        for klass in reversed(cls.__mro__):
            for attr, value in vars(klass).items():
                if isinstance(value, (Port, Slot, Monostable)):
                    decls[attr] = value
                    continue
                mark = getattr(value, "__ayllu_process__", None)
                if mark is not None:
                    procs[attr] = (attr, mark[0], mark[1], value)
                elif attr in procs:
                    del procs[attr]  # overridden by a plain method: no longer a process
        ports = [d for d in decls.values() if isinstance(d, Port)]
        slots = [d for d in decls.values() if isinstance(d, Slot)]
        monos = [d for d in decls.values() if isinstance(d, Monostable)]
        cls.__ayllu__ = (name or cls.__name__, ports, slots, monos, list(procs.values()))


PortValue = Union[bool, int, float, str, bytes, list[float]]
"""What a register holds: bool, int, float, str, bytes or a vector (list of floats)."""
