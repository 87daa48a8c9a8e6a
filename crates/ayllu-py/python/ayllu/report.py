"""Reports as Python objects: ``why()``, ``report()`` and ``ble_status()`` answers, where a
control request stands, and the exceptions processes raised.

A :class:`Report` gives attribute access to the Rust report's fields (``r.input_blocked``,
``r.windows[0].remaining``); instants and durations are seconds (floats), counters are dicts
from cause name to count (non-zero causes only), and ``str(r)`` is the text ``ayllu why``
prints when the report has one.
"""

from __future__ import annotations

import json
from typing import Any, NamedTuple, Optional


class ProcessError(NamedTuple):
    """A Python exception raised inside a process (counted; the node went on)."""

    behavior: str
    process: str
    time: float
    traceback: str


class RequestStatus(NamedTuple):
    """Where a control request this node sent stands (``Node.request_status``).

    ``state`` is ``"pending"`` (``sends``: times sent so far; resent every 200 ms, 25 times at
    most), ``"done"`` (``result``: a connection id for CONNECT and DISCONNECT, the value for
    READ, a :class:`Report` for LIST and WHY) or ``"failed"`` (``error``: the receiver's reason,
    e.g. the access rule or limit that refused it, or that no answer came).
    """

    state: str
    sends: int = 0
    result: Any = None
    error: Optional[str] = None

    @property
    def pending(self) -> bool:
        """Not answered yet."""
        return self.state == "pending"

    @property
    def done(self) -> bool:
        """Answered: ``result`` holds what the request returned."""
        return self.state == "done"

    @property
    def failed(self) -> bool:
        """Refused, or never answered: ``error`` says why."""
        return self.state == "failed"


class Report:
    """A report: attribute access to its fields; ``to_dict()`` for plain data."""

    def __init__(self, fields: dict[str, Any], text: Optional[str] = None) -> None:
        self._fields = fields
        self._text = text

    def __getattr__(self, name: str) -> Any:
        try:
            return self._fields[name]
        except KeyError:
            raise AttributeError(f"report has no field {name!r}; it has {sorted(self._fields)}") from None

    def __getitem__(self, name: str) -> Any:
        return self._fields[name]

    def __contains__(self, name: object) -> bool:
        return name in self._fields

    def to_dict(self) -> dict[str, Any]:
        """The report as plain dicts and lists."""
        return _plain(self._fields)  # type: ignore[no-any-return]

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Report) and self._fields == other._fields

    def __repr__(self) -> str:
        return f"Report({self._fields!r})"

    def __str__(self) -> str:
        return self._text if self._text is not None else json.dumps(self.to_dict(), indent=2, default=str)


def _plain(v: Any) -> Any:
    if isinstance(v, Report):
        return {k: _plain(x) for k, x in v._fields.items()}
    if isinstance(v, list):
        return [_plain(x) for x in v]
    if isinstance(v, dict):
        return {k: _plain(x) for k, x in v.items()}
    return v


def _convert(v: Any) -> Any:
    from ayllu._native import DROP_CAUSES

    if isinstance(v, dict):
        keys = set(v)
        if keys == {"nanos"}:
            return v["nanos"] / 1e9
        if keys == {"counts"} and isinstance(v["counts"], list) and len(v["counts"]) == len(DROP_CAUSES):
            return {c: n for c, n in zip(DROP_CAUSES, v["counts"]) if n}
        if keys == {"node", "conn"}:
            return Report({"node": v["node"], "conn": v["conn"]})
        if len(keys) == 1:
            (k,) = keys
            # Enums with data (a value, a window kind with period): {"Float": 1.0} -> 1.0
            inner = v[k]
            if k in ("Bool", "Int", "Float", "Text", "Vector"):
                return _convert(inner)
            if k == "Bytes":
                return bytes(inner)
        return Report({k: _convert(x) for k, x in v.items()})
    if isinstance(v, list):
        return [_convert(x) for x in v]
    return v


def from_json(text_json: str, text: Optional[str] = None) -> Report:
    """The report in ``text_json`` (the core's serde JSON) with seconds, dicts and values."""
    r = _convert(json.loads(text_json))
    if isinstance(r, Report):
        r._text = text
        return r
    return Report({"value": r}, text)
