"""Rule S7 from Python: periodic and triggered processes, slots and monostables (rule S2);
mirrors ayllu-core's tests/process_*.rs and tests/monostable.rs."""

from __future__ import annotations

import ayllu


class Ticker(ayllu.Behavior):
    count = ayllu.Slot(0)
    out = ayllu.Port(0, name="Out")

    @ayllu.every(hz=10)
    def tick(self, ctx: ayllu.Context) -> None:
        n = ctx.slot(self.count) + 1
        ctx.set_slot(self.count, n)
        ctx.write(self.out, n)


def test_a_periodic_process_runs_at_its_rate_phase_locked_to_creation() -> None:
    node = ayllu.Node(1, manual=True)
    node.create(Ticker, "T")
    node.advance(1.0, tick=0.01)
    assert node.read("T", "Out") == 11, "at 0, 0.1, ..., 1.0 s"
    proc = node.report().behaviors[0].processes[0]
    assert (proc.name, proc.runs, proc.overruns) == ("tick", 11, 0)


def test_a_late_step_skips_missed_activations_and_counts_overruns() -> None:
    node = ayllu.Node(1, manual=True)
    node.create(Ticker, "T")
    node.step()
    node.set_time(0.55)
    assert node.read("T", "Out") == 2, "one activation for the late poll, not a burst"
    assert node.report().behaviors[0].processes[0].overruns == 4


def test_step_returns_the_next_deadline() -> None:
    node = ayllu.Node(1, manual=True)
    node.create(Ticker, "T")
    assert node.step() == 0.1


class Echo(ayllu.Behavior):
    inp = ayllu.Port(0, name="In")
    out = ayllu.Port(0, name="Out")
    calls = ayllu.Slot(0)

    @ayllu.on_write(inp)
    def react(self, ctx: ayllu.Context) -> None:
        ctx.set_slot(self.calls, ctx.slot(self.calls) + 1)
        ctx.write(self.out, ctx.read(self.inp) * 10)


def test_a_triggered_process_runs_at_the_next_step_after_its_port_accepts() -> None:
    node = ayllu.Node(1, manual=True)
    node.create(Echo, "E")
    node.write("E", "In", 4)
    assert node.read("E", "Out") == 0, "processes run only inside step (rule S7)"
    node.step()
    assert node.read("E", "Out") == 40
    node.step()
    assert node.report().behaviors[0].slots == [["calls", 1]]


class Backoff(ayllu.Behavior):
    hit = ayllu.Port(False, name="Hit")
    state = ayllu.Port(False, name="State")
    backing = ayllu.Monostable(name="Backing")

    @ayllu.on_write(hit)
    def bump(self, ctx: ayllu.Context) -> None:
        ctx.trigger(self.backing, 2.0)

    @ayllu.on_monostable(backing)
    def show(self, ctx: ayllu.Context) -> None:
        ctx.write(self.state, ctx.is_high(self.backing))


def test_a_monostable_is_high_for_its_period_and_triggers_on_both_edges() -> None:
    node = ayllu.Node(1, manual=True)
    node.create(Backoff, "B")
    node.write("B", "Hit", True)
    node.step()
    assert node.monostable("B", "Backing")
    node.step()
    assert node.read("B", "State") is True
    node.set_time(1.0)
    node.trigger("B", "Backing", 0.5)
    assert node.monostable("B", "Backing"), "never shortened: end = max(end, now + p)"
    node.set_time(2.0)
    assert not node.monostable("B", "Backing")
    node.step()
    assert node.read("B", "State") is False


def test_processes_see_the_node_and_their_behavior() -> None:
    seen: list[tuple[int, str, float]] = []

    class Who(ayllu.Behavior):
        @ayllu.every(period=0.5)
        def look(self, ctx: ayllu.Context) -> None:
            seen.append((ctx.node, ctx.behavior, ctx.now))

    node = ayllu.Node(7, manual=True)
    node.create(Who, "W1")
    node.step()
    node.advance(0.5, tick=0.25)
    assert seen == [(7, "W1", 0.0), (7, "W1", 0.5)]


def test_each_behavior_has_its_own_python_object() -> None:
    class Counter(ayllu.Behavior):
        def __init__(self) -> None:
            self.n = 0

        @ayllu.every(hz=1)
        def count(self, ctx: ayllu.Context) -> None:
            self.n += 1

    node = ayllu.Node(1, manual=True)
    a = node.create(Counter, "A")
    node.advance(1.0, tick=0.5)
    b = node.create(Counter, "B")
    node.step()
    assert (a.n, b.n) == (2, 1)
    assert node.behavior("A") is a


def test_a_subclass_inherits_declarations_and_may_override_processes() -> None:
    class Base(ayllu.Behavior):
        out = ayllu.Port(0, name="Out")

        @ayllu.every(hz=1)
        def work(self, ctx: ayllu.Context) -> None:
            ctx.write(self.out, 1)

    class Derived(Base, name="Derived"):
        extra = ayllu.Port(0.0, name="Extra")

        @ayllu.every(hz=1)
        def work(self, ctx: ayllu.Context) -> None:
            ctx.write(self.out, 2)
            ctx.write(self.extra, 0.5)

    node = ayllu.Node(1, manual=True)
    node.create(Base, "B")
    node.create(Derived, "D")
    node.step()
    assert (node.read("B", "Out"), node.read("D", "Out"), node.read("D", "Extra")) == (1, 2, 0.5)
    assert [p.name for p in node.report().behaviors[1].ports][3:] == ["Out", "Extra"]
    assert len(node.report().behaviors[1].processes) == 1


class Watcher(ayllu.Behavior):
    seen = ayllu.Port(0.0, lifespan=0.15, name="Seen")
    runs = ayllu.Slot(0)

    @ayllu.every(hz=10, while_fresh=seen)
    def look(self, ctx: ayllu.Context) -> None:
        ctx.set_slot(self.runs, ctx.slot(self.runs) + 1)


def test_a_process_while_fresh_runs_only_at_due_times_its_port_is_fresh() -> None:
    # D7.5: due every 0.1 s from 0; `Seen` fresh for 0.15 s after a write at 0 and at 0.45.
    node = ayllu.Node(1, manual=True)
    node.create(Watcher, "W")
    node.write("W", "Seen", 1.0)
    node.advance(0.45, tick=0.05)
    node.write("W", "Seen", 2.0)
    node.advance(0.55, tick=0.05)
    proc = node.report().behaviors[0].processes[0]
    assert (proc.runs, proc.overruns) == (3, 0), "activated at 0, 0.1 and 0.5 only"
    assert node.report().behaviors[0].slots == [["runs", 3]]


def test_while_fresh_takes_a_port_of_the_class() -> None:
    import pytest

    with pytest.raises(TypeError):
        ayllu.every(hz=10, while_fresh="Seen")  # type: ignore[arg-type]

    other = ayllu.Port(0.0, name="Elsewhere")

    class Stranger(ayllu.Behavior):
        mine = ayllu.Port(0.0, name="Mine")

        @ayllu.every(hz=10, while_fresh=other)
        def look(self, ctx: ayllu.Context) -> None:
            pass

    with pytest.raises(ayllu.InvalidError, match="port of another class"):
        ayllu.Node(1, manual=True).create(Stranger, "S")
