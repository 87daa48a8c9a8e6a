"""Misuse from Python: every refused call raises a clear exception (mirrors ayllu-core's
tests/misuse.rs)."""

from __future__ import annotations

import pickle

import pytest

import ayllu
from conftest import Relay, wiring


def test_unknown_names_are_lookup_errors() -> None:
    node = wiring(["A"])
    with pytest.raises(ayllu.NotFoundError, match="Nope"):
        node.read("Nope", "V")
    with pytest.raises(ayllu.NotFoundError, match="W"):
        node.write("A", "W", 1)
    with pytest.raises(ayllu.NotFoundError):
        node.create("NoClass", "X")


def test_names_used_twice_are_refused() -> None:
    node = wiring(["A"])
    with pytest.raises(ayllu.InvalidError, match="A"):
        node.create("Relay", "A")
    with pytest.raises(ayllu.InvalidError):
        node.define(Relay)


def test_periods_and_rates_are_checked() -> None:
    node = wiring(["A", "B"])
    with pytest.raises(ayllu.InvalidError):
        node.connect(ayllu.local("A", "V"), ayllu.local("B", "V"), ayllu.suppress(0.0))
    with pytest.raises(ayllu.InvalidError):
        node.connect(ayllu.local("A", "V"), ayllu.local("B", "V"), ayllu.inhibit(-1.0))
    with pytest.raises(ValueError, match="period"):
        node.connect(ayllu.local("A", "V"), ayllu.local("B", "V"), ayllu.Kind("suppress"))
    with pytest.raises(ValueError, match="none of"):
        node.connect(ayllu.local("A", "V"), ayllu.local("B", "V"), ayllu.Kind("squash", 1.0))
    with pytest.raises(ayllu.InvalidError):
        ayllu.every(hz=0)
    with pytest.raises(ValueError):
        ayllu.every()
    # A rate whose period no clock holds is a bad rate, not a period the caller never wrote.
    for hz in (1e-300, 1e10, float("nan"), float("inf"), -1.0):
        with pytest.raises(ayllu.InvalidError, match=r"^rate .* Hz is invalid; .*from 1 ns to 584 years$") as e:
            ayllu.every(hz=hz)
        assert "1e+300 s" not in str(e.value)
    ayllu.every(hz=1e9)
    ayllu.every(hz=1e-9)


def test_a_source_must_be_local_and_types_must_match() -> None:
    node = wiring(["A", "B"])
    with pytest.raises(ayllu.InvalidError):
        node.connect(ayllu.remote(2, "A", "V"), ayllu.local("B", "V"))
    with pytest.raises(TypeError):
        node.connect("A.V", ayllu.local("B", "V"))  # type: ignore[arg-type]

    class Text(ayllu.Behavior):
        out = ayllu.Port("", name="Out")

    node.create(Text, "T")
    with pytest.raises(ayllu.ValueTypeError):
        node.connect(ayllu.local("T", "Out"), ayllu.local("B", "V"))


def test_a_manual_node_cannot_start_and_a_real_one_cannot_advance() -> None:
    with pytest.raises(ayllu.InvalidError):
        ayllu.Node(1, manual=True).start()
    with pytest.raises(ayllu.InvalidError):
        ayllu.Node(1).advance(1.0)


def test_a_closed_node_cannot_start() -> None:
    # Like every other method of a closed node; it used to start a thread that ended at once
    # while `running` said True.
    node = ayllu.Node(1)
    node.close()
    with pytest.raises(RuntimeError, match="closed"):
        node.start()
    assert not node.running


def test_times_and_spans_out_of_range_are_refused_in_their_own_words() -> None:
    node = ayllu.Node(2, manual=True)
    too_long = r"^seconds = 1e300 s is too long: a span of time is from 0 to 18446744073 s"
    with pytest.raises(ayllu.InvalidError, match=too_long):
        node.advance(1e300)
    with pytest.raises(ValueError, match=r"^tick must be at least 1 ns \(1e-9 s\), not 1e-12 s"):
        node.advance(1.0, tick=1e-12)
    with pytest.raises(ValueError, match="tick must be at least 1 ns"):
        node.advance(1.0, tick=-0.5)
    with pytest.raises(ValueError, match="tick must be at least 1 ns"):
        ayllu.Team().advance(1.0, tick=0.0)
    node.advance(1e-6, tick=1e-9)
    with pytest.raises(ayllu.InvalidError, match=r"^time -1 s is not on the node's clock: times are seconds since"):
        node.set_time(-1.0)
    with pytest.raises(ayllu.InvalidError, match="not on the node's clock"):
        node.set_time(float("nan"))
    with pytest.raises(ayllu.InvalidError, match="too long"):
        node.run_for(1e300)
    assert node.now == pytest.approx(1e-6)


def test_advance_refuses_bad_seconds_naming_its_argument_not_a_period() -> None:
    # advance(-1) used to say "period of -1 s is negative; periods must be above zero".
    range_ = r"a span of time is (finite, )?from 0 to 18446744073 s \(about 584 years\)"
    for advance in (ayllu.Node(5, manual=True).advance, ayllu.Team().advance):
        for bad, says in ((-1.0, "-1 s is negative"), (float("nan"), "NaN is not a number of seconds")):
            with pytest.raises(ayllu.InvalidError, match=rf"^seconds = {says}: {range_}$") as e:
                advance(bad)
            assert "period" not in str(e.value)
    # Other spans name theirs too, compactly.
    node = ayllu.Node(6, manual=True)
    with pytest.raises(ayllu.InvalidError, match=r"^period = 1e300 s is too long: a span of time is from 0"):
        node.connect(ayllu.local("A", "x"), ayllu.local("B", "y"), ayllu.suppress(1e300))
    with pytest.raises(ayllu.InvalidError, match=r"^tick = inf is not a number of seconds: a span of time is finite"):
        node.advance(1.0, tick=float("inf"))


def test_a_period_under_one_nanosecond_is_refused_as_such() -> None:
    # suppress(1e-12) used to say "a suppress connection needs a period above zero" (D6.8).
    node = ayllu.Node(7, manual=True)
    with pytest.raises(ayllu.InvalidError, match=r"^period = 1e-12 s is above zero but under 1 ns") as e:
        node.connect(ayllu.local("A", "x"), ayllu.local("B", "y"), ayllu.suppress(1e-12))
    assert "at least 1 ns" in str(e.value)


def test_invalid_not_found_and_value_type_errors_are_also_the_matching_builtins() -> None:
    # errors.rs promised it; InvalidError used to derive from AylluError only.
    for cls, builtin in (
        (ayllu.InvalidError, ValueError),
        (ayllu.NotFoundError, LookupError),
        (ayllu.ValueTypeError, TypeError),
    ):
        assert issubclass(cls, ayllu.AylluError)
        assert issubclass(cls, builtin)
        assert cls.__module__ == "ayllu._native"
    node = ayllu.Node(7, manual=True)
    with pytest.raises(ValueError, match="seconds = -1 s is negative"):
        node.advance(-1.0)
    with pytest.raises(LookupError):
        node.read("NoSuchBehavior", "P")
    # Raised from Rust, the class is the one the module exports, and it pickles.
    try:
        node.advance(-1.0)
    except ValueError as e:
        assert type(e) is ayllu.InvalidError
        again = pickle.loads(pickle.dumps(e))
        assert type(again) is ayllu.InvalidError and str(again) == str(e)


def test_run_for_refuses_negative_and_nan_seconds() -> None:
    # They used to run nothing, in silence.
    node = ayllu.Node(3)
    try:
        for bad in (float("nan"), -1.0, float("-inf")):
            with pytest.raises(ValueError, match="run_for takes seconds of at least 0"):
                node.run_for(bad)
        with pytest.raises(ayllu.InvalidError, match="seconds = inf is not a number of seconds"):
            node.run_for(float("inf"))
        node.run_for(0.0)
    finally:
        node.close()
    with pytest.raises(ValueError, match="run_for takes seconds of at least 0"):
        ayllu.Node(4, manual=True).run_for(-1.0)


def test_a_process_calling_its_node_is_told_to_use_ctx() -> None:
    node = ayllu.Node(1, manual=True)

    class Reentrant(ayllu.Behavior):
        @ayllu.every(hz=1)
        def poke(self, ctx: ayllu.Context) -> None:
            node.write("R", "Local", 1.0)

    node.create(Reentrant, "R")
    node.step()
    errors = node.process_errors()
    assert len(errors) == 1
    assert "NodeBusyError" in errors[0].traceback and "use its ctx" in errors[0].traceback


def test_a_ctx_kept_after_its_process_returned_is_refused() -> None:
    kept: list[ayllu.Context] = []

    class Keeper(ayllu.Behavior):
        @ayllu.every(hz=1)
        def keep(self, ctx: ayllu.Context) -> None:
            kept.append(ctx)

    node = ayllu.Node(1, manual=True)
    node.create(Keeper, "K")
    node.step()
    with pytest.raises(RuntimeError, match="returned"):
        kept[0].now  # noqa: B018


def test_a_declaration_shared_at_two_positions_is_refused() -> None:
    shared = ayllu.Port(0, name="Shared")

    class First(ayllu.Behavior):
        s = shared

    class Second(ayllu.Behavior):
        other = ayllu.Port(0, name="Other")
        s = shared

    node = ayllu.Node(1, manual=True)
    node.define(First)
    with pytest.raises(ayllu.InvalidError, match="another position"):
        node.define(Second)


def test_bad_urls_and_duplicate_nodes_are_refused() -> None:
    with pytest.raises(ayllu.InvalidError, match="unknown transport"):
        ayllu.Node(1, "bogus://x")
    with pytest.raises(ayllu.InvalidError, match="HOST:PORT"):
        ayllu.Node(1, "udp://not-an-address")
    team = ayllu.Team()
    team.add(1)
    with pytest.raises(ayllu.InvalidError, match="already"):
        team.add(1)


def test_errors_are_sorted_as_the_c_library_sorts_them() -> None:
    # One classification (ayllu_core::ErrorKind) gives C its status and Python its class; the C
    # twin is test_misuse.c's "sorted as Python" checks. A slot named as a port was
    # InvalidError here and AY_ERR_UNKNOWN in C; a vector Sum without a shape was InvalidError
    # here and AY_ERR_TYPE in C.
    class Holder(ayllu.Behavior):
        count = ayllu.Slot(0, name="Count")
        out = ayllu.Port(0, name="Out")

    node = ayllu.Node(1, manual=True)
    node.create(Holder, "H")
    with pytest.raises(ayllu.NotFoundError, match="is a slot") as e:
        node.connect(ayllu.local("H", "Count"), ayllu.local("H", "Out"))
    assert isinstance(e.value, LookupError)

    class Shapeless(ayllu.Behavior):
        total = ayllu.Port([], kind="sum", name="Total")

    with pytest.raises(ayllu.ValueTypeError, match="takes its shape from its default") as t:
        node.create(Shapeless, "S")
    assert isinstance(t.value, TypeError)


def test_a_period_on_a_normal_connection_is_refused_as_in_c() -> None:
    # It used to be ignored in silence here, while C and the tool refused it
    # (ConnectionKind::from_parts decides for both).
    node = wiring(["A", "B"])
    with pytest.raises(ayllu.InvalidError, match="Normal connection has no period") as e:
        node.connect(ayllu.local("A", "V"), ayllu.local("B", "V"), ayllu.Kind("normal", 0.5))
    assert isinstance(e.value, ValueError)
    node.connect(ayllu.local("A", "V"), ayllu.local("B", "V"), ayllu.NORMAL)
