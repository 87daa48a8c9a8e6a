"""The book's pictures, drawn from what the runtime does: `python scripts/book/pictures.py OUTDIR`.

For each connection kind, a node on a manual clock runs the same script of writes on a real core
(the `ayllu` package): a port D is written along a Normal connection by OTHER every 0.2 s (odd
tenths) and by its own behavior's 5 Hz process (even tenths); D passes its values on to OUT; at
1.0 s the connection under study (SRC -> D, period 1 s) carries one value. After every write the
script asks the core what happened (D's and OUT's counters, accepted values, open windows) and
draws that, not what the rules say should happen: if the runtime changed, the picture would.

Also draws the cross-subsumption diagram (the paper's Fig. 1) from the structure of two robots
built by the runtime's own BLE (`ble_join`), read back from `report()`.

Writes `timeline-<kind>.svg` for each kind and `cross-subsumption.svg`. Deterministic: the same
runtime gives the same files byte for byte (no clock, no randomness).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from html import escape
from pathlib import Path

import ayllu

KINDS = {
    "suppress": ayllu.suppress,
    "inhibit": ayllu.inhibit,
    "override_in": ayllu.override_in,
    "override_out": ayllu.override_out,
    "write_inhibit": ayllu.write_inhibit,
}
END = 3.0  # seconds shown
FIRE_AT = 1.0  # when SRC's connection carries its value
PERIOD = 1.0  # the window it opens

PASS, REFUSED, STORED_ONLY, WINDOW = "#2e7d32", "#c62828", "#ef6c00", "#1565c0"


class Port(ayllu.Behavior):
    p = ayllu.Port(0, name="P")


class Own(ayllu.Behavior):
    """D: its own 5 Hz process writes P (the behavior's own writes)."""

    p = ayllu.Port(0, name="P")

    @ayllu.every(hz=5)
    def write(self, ctx: ayllu.Context) -> None:
        ctx.write(self.p, 100 + round(ctx.now * 10))


@dataclass
class Event:
    """One write into D and its fate, as the core reported it."""

    t: float
    lane: str  # "connection", "own" or "src"
    stored: bool
    passed: bool
    cause: str = ""


@dataclass
class Timeline:
    kind: str
    events: list[Event] = field(default_factory=list)
    windows: list[tuple[float, float, str]] = field(default_factory=list)


def snapshot(node: ayllu.Node) -> tuple[dict[str, int], int, int]:
    """D's counters and accepted values, and OUT's accepted values, now."""
    d = node.why("D", "P")
    return dict(d.counters), d.accepted, node.why("OUT", "P").accepted


def fate(node: ayllu.Node, before: tuple[dict[str, int], int, int]) -> tuple[bool, bool, str]:
    """(written into D, passed on to OUT, the counters that grew) since the snapshot."""
    counters, accepted, out = snapshot(node)
    grew = [name for name, n in counters.items() if n > before[0].get(name, 0) and name != "absorbed"]
    return accepted > before[1], out > before[2], ",".join(grew)


def run(kind: str) -> Timeline:
    node = ayllu.Node(1, manual=True)
    node.create(Port, "SRC")
    node.create(Port, "OTHER")
    node.create(Own, "D")
    node.create(Port, "OUT")
    node.connect(ayllu.local("OTHER", "P"), ayllu.local("D", "P"))
    node.connect(ayllu.local("D", "P"), ayllu.local("OUT", "P"))
    node.connect(ayllu.local("SRC", "P"), ayllu.local("D", "P"), KINDS[kind](PERIOD))
    line = Timeline(kind)
    opened: dict[str, float] = {}
    for tenth in range(round(END * 10) + 1):
        t = tenth / 10
        before = snapshot(node)
        node.set_time(t)  # D's own process runs here on even tenths
        if tenth % 2 == 0:
            line.events.append(Event(t, "own", *fate(node, before)))
        if abs(t - FIRE_AT) < 1e-9:
            before = snapshot(node)
            node.write("SRC", "P", 7)
            line.events.append(Event(t, "src", *fate(node, before)))
        if tenth % 2 == 1:
            before = snapshot(node)
            node.write("OTHER", "P", tenth)
            line.events.append(Event(t, "connection", *fate(node, before)))
        open_now = {w.kind: t + w.remaining for w in node.why("D", "P").windows}
        for k, ends in open_now.items():
            opened.setdefault(k, t)
            if ends <= t + 0.1 + 1e-9 or tenth == round(END * 10):
                line.windows.append((opened.pop(k), min(ends, END), k))
    return line


# ----- drawing -------------------------------------------------------------------------------

W, LEFT, RIGHT = 720, 190, 20
LANES = [
    ("window", "window on D"),
    ("src", "SRC's value (the kind)"),
    ("connection", "OTHER -> D (Normal)"),
    ("own", "D's own process"),
]
ROW = 34


def x(t: float) -> float:
    return LEFT + (W - LEFT - RIGHT) * t / END


def mark(e: Event, y: float) -> str:
    cx = x(e.t)
    if e.lane == "src" and not e.stored:
        title = f"{e.t:.1f} s: opens the window; the value itself is not written"
        return (
            f'<path d="M{cx},{y - 8} L{cx + 8},{y} L{cx},{y + 8} L{cx - 8},{y} z" fill="{WINDOW}">'
            f"<title>{escape(title)}</title></path>"
        )
    if not e.stored:
        colour, title = REFUSED, f"{e.t:.1f} s: refused ({e.cause})"
        return (
            f'<g><title>{escape(title)}</title><line x1="{cx - 6}" y1="{y - 6}" x2="{cx + 6}" y2="{y + 6}" '
            f'stroke="{colour}" stroke-width="3"/><line x1="{cx - 6}" y1="{y + 6}" x2="{cx + 6}" y2="{y - 6}" '
            f'stroke="{colour}" stroke-width="3"/></g>'
        )
    if e.passed:
        title = f"{e.t:.1f} s: stored and passed on"
        return f'<circle cx="{cx}" cy="{y}" r="6" fill="{PASS}"><title>{escape(title)}</title></circle>'
    title = f"{e.t:.1f} s: stored, not passed on ({e.cause or 'nothing to pass'})"
    return (
        f'<circle cx="{cx}" cy="{y}" r="6" fill="white" stroke="{STORED_ONLY}" stroke-width="3">'
        f"<title>{escape(title)}</title></circle>"
    )


def svg_timeline(line: Timeline) -> str:
    h = 40 + ROW * len(LANES) + 84
    out = [
        f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {W} {h}" width="{W}" height="{h}" '
        f'font-family="sans-serif" font-size="13" role="img" aria-label="timeline of {line.kind}">',
        f'<rect width="{W}" height="{h}" fill="white"/>',
        f'<text x="10" y="22" font-weight="bold">{escape(line.kind)}({PERIOD:g} s) from SRC into D, '
        f"fired at {FIRE_AT:g} s</text>",
    ]
    for i, (lane, label) in enumerate(LANES):
        y = 40 + ROW * i + ROW / 2
        out.append(f'<text x="10" y="{y + 4}">{escape(label)}</text>')
        out.append(f'<line x1="{LEFT}" y1="{y}" x2="{W - RIGHT}" y2="{y}" stroke="#ccc"/>')
        if lane == "window":
            for start, end, k in line.windows:
                out.append(
                    f'<rect x="{x(start)}" y="{y - 9}" width="{x(end) - x(start)}" height="18" '
                    f'fill="#90caf9"><title>{escape(k)} window {start:.1f}-{end:.1f} s</title></rect>'
                )
                out.append(f'<text x="{x(start) + 4}" y="{y + 4}" font-size="11">{escape(k)}</text>')
        for e in line.events:
            if e.lane == lane:
                out.append(mark(e, y))
    axis = 40 + ROW * len(LANES) + 8
    out.append(f'<line x1="{LEFT}" y1="{axis}" x2="{W - RIGHT}" y2="{axis}" stroke="#555"/>')
    for s in range(round(END) + 1):
        out.append(f'<text x="{x(s) - 8}" y="{axis + 16}">{s} s</text>')
    legend = axis + 36
    out.append(
        f'<circle cx="{LEFT}" cy="{legend - 4}" r="6" fill="{PASS}"/>'
        f'<text x="{LEFT + 10}" y="{legend}">stored, passed on</text>'
    )
    out.append(
        f'<circle cx="{LEFT + 150}" cy="{legend - 4}" r="6" fill="white" stroke="{STORED_ONLY}" '
        f'stroke-width="3"/><text x="{LEFT + 160}" y="{legend}">stored, not passed on</text>'
    )
    out.append(
        f'<text x="{LEFT + 330}" y="{legend}" fill="{REFUSED}" font-weight="bold">x</text>'
        f'<text x="{LEFT + 342}" y="{legend}">refused (not stored)</text>'
    )
    out.append(
        f'<path d="M{LEFT},{legend + 10} l8,8 l-8,8 l-8,-8 z" fill="{WINDOW}"/>'
        f'<text x="{LEFT + 10}" y="{legend + 22}">opens the window; the value itself is not written</text>'
    )
    out.append("</svg>\n")
    return "\n".join(out)


def cross_subsumption() -> str:
    """Fig. 1: two robots, each with observer layers OBS1, OBS2 over WANDER in a subsumption
    chain, each layer BLE-joined across robots; the wiring is read back from the nodes."""
    team = ayllu.Team()
    robots = [team.add(1), team.add(2)]
    layers = ["OBS1", "OBS2"]
    for r in robots:
        for b in [*layers, "WANDER", "BASE"]:
            r.create(Port, b)
        r.connect(ayllu.local("WANDER", "P"), ayllu.local("BASE", "P"))
        r.connect(ayllu.local("OBS2", "P"), ayllu.local("BASE", "P"), ayllu.override_in(0.2))
        r.connect(ayllu.local("OBS1", "P"), ayllu.local("BASE", "P"), ayllu.override_in(0.2))
        for b in layers:
            r.ble_join(b, "Peers", "P", 1.0)
    team.advance(0.1)
    # What the nodes say they hold: (node, source behavior, destination, kind) per connection.
    wiring = []
    for r in robots:
        report = r.report()
        for c in report.connections:
            d = c.to_dict()
            src = next(iter(d["source"].values()))["behavior"]
            where, dst = next(iter(d["destination"].items()))
            kind = d["kind"] if isinstance(d["kind"], str) else next(iter(d["kind"]))
            wiring.append((report.node, src, where, dst["behavior"], kind))
    w, h = 720, 350
    col = {1: 190, 2: 530}
    row = {"OBS1": 70, "OBS2": 140, "WANDER": 210, "BASE": 290}
    out = [
        f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {w} {h}" width="{w}" height="{h}" '
        'font-family="sans-serif" font-size="13" role="img" aria-label="cross-subsumption">',
        f'<rect width="{w}" height="{h}" fill="white"/>',
        '<defs><marker id="a" viewBox="0 0 10 10" refX="9" refY="5" markerWidth="7" markerHeight="7" '
        'orient="auto-start-reverse"><path d="M0,0 L10,5 L0,10 z" fill="#333"/></marker></defs>',
    ]
    for rid, cx in col.items():
        out.append(f'<text x="{cx - 30}" y="30" font-weight="bold">robot {rid}</text>')
        for b, cy in row.items():
            out.append(
                f'<rect x="{cx - 60}" y="{cy - 16}" width="120" height="32" rx="6" fill="#e3f2fd" '
                f'stroke="#1565c0"/><text x="{cx - 50}" y="{cy + 5}">{b}</text>'
            )
    drawn, ble = 0, set()
    for node, sb, where, db, kind in wiring:
        cx = col[node]
        if where == "Group" and kind == "WriteInhibit":
            ble.add((node, sb))  # the claim that cross-inhibits this layer on the peers
            continue
        if where != "Local" or db != "BASE" or sb not in row:
            continue
        side = -1 if node == 1 else 1  # curves on the outer side of each robot
        edge = cx + side * 60
        reach = {"OBS1": 70, "OBS2": 40, "WANDER": 0}[sb]
        if sb == "WANDER":
            path = f"M{cx},{row[sb] + 16} L{cx},{row['BASE'] - 16}"
        else:
            bend = edge + side * reach
            path = f"M{edge},{row[sb]} C{bend},{row[sb]} {bend},{row['BASE']} {edge},{row['BASE']}"
        out.append(
            f'<path d="{path}" fill="none" stroke="#333" marker-end="url(#a)"><title>'
            f"{sb} -> {db} ({kind})</title></path>"
        )
        if kind == "OverrideIn":
            my = (row[sb] + row["BASE"]) / 2
            sx = edge + side * reach * 0.75
            out.append(
                f'<circle cx="{sx}" cy="{my}" r="9" fill="white" stroke="#333"/>'
                f'<text x="{sx - 4}" y="{my + 4}" font-size="11">S</text>'
            )
        drawn += 1
    for b in sorted({layer for _, layer in ble}):
        y = row[b]
        out.append(
            f'<line x1="{col[1] + 60}" y1="{y}" x2="{col[2] - 60}" y2="{y}" stroke="#c62828" '
            f'stroke-width="2" stroke-dasharray="6 4" marker-start="url(#a)" marker-end="url(#a)"/>'
        )
        out.append(f'<text x="{(col[1] + col[2]) / 2 - 30}" y="{y - 6}" fill="#c62828">BLE: {b}</text>')
    out.append(
        f'<text x="10" y="{h - 24}" font-size="12">S: the higher layer overrides the lower ones into BASE '
        "(OverrideIn, Brooks's suppression): subsumption inside a robot.</text>"
    )
    out.append(
        f'<text x="10" y="{h - 8}" font-size="12">Dashed: cross-inhibition between robots, one BLE group '
        "per layer (the Broadcast of Local Eligibility).</text>"
    )
    out.append("</svg>\n")
    assert drawn == 6 and len(ble) == 4, f"expected 3 arrows and 2 BLE claims per robot: {wiring}"
    return "\n".join(out)


def main(outdir: Path) -> None:
    outdir.mkdir(parents=True, exist_ok=True)
    for kind in KINDS:
        (outdir / f"timeline-{kind}.svg").write_text(svg_timeline(run(kind)))
    (outdir / "cross-subsumption.svg").write_text(cross_subsumption())


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "docs/img"))
