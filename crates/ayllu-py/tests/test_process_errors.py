"""A Python exception raised in a process is reported with its traceback and counted, and the
node goes on."""

from __future__ import annotations

import pytest

import ayllu


class Flaky(ayllu.Behavior):
    out = ayllu.Port(0, name="Out")
    n = ayllu.Slot(0)

    @ayllu.every(hz=10)
    def work(self, ctx: ayllu.Context) -> None:
        n = ctx.slot(self.n) + 1
        ctx.set_slot(self.n, n)
        if n % 2 == 0:
            raise ZeroDivisionError(f"activation {n} fails")
        ctx.write(self.out, n)


def test_exceptions_are_counted_and_the_node_goes_on(capsys: pytest.CaptureFixture[str]) -> None:
    node = ayllu.Node(1, manual=True)
    node.create(Flaky, "F")
    node.step()
    node.advance(0.9, tick=0.1)
    assert node.read("F", "Out") == 9, "odd activations still ran"
    assert node.process_error_counts() == {("F", "work"): 5}
    errs = node.process_errors()
    assert len(errs) == 5
    assert errs[0].behavior == "F" and errs[0].process == "work"
    assert errs[0].time == pytest.approx(0.1)
    assert "ZeroDivisionError: activation 2 fails" in errs[0].traceback
    assert "test_process_errors.py" in errs[0].traceback
    printed = capsys.readouterr().err
    assert printed.count("activation 2 fails") == 1
    assert "activation 4 fails" not in printed, "the first is printed, the rest only counted"


def test_a_type_error_in_a_process_write_is_a_clear_exception() -> None:
    class Wrong(ayllu.Behavior):
        out = ayllu.Port(0, name="Out")

        @ayllu.every(hz=1)
        def work(self, ctx: ayllu.Context) -> None:
            ctx.write(self.out, "text")

    node = ayllu.Node(1, manual=True)
    node.create(Wrong, "W")
    node.step()
    assert "ValueTypeError: port Out refused the value" in node.process_errors()[0].traceback
