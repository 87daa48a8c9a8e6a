"""Aggregation is order-independent (mirrors ayllu-core's tests/aggregation_properties.rs):
whatever order the same values arrive in, a Max, Min or Sum port ends with the same value and,
for Max and Min, the same supplier (ties go to the smaller source). Seeded random orders."""

from __future__ import annotations

import random

import pytest

from fan_in import FanIn


@pytest.mark.parametrize("kind", ["max", "min", "sum"])
def test_the_result_does_not_depend_on_arrival_order(kind: str) -> None:
    rng = random.Random(7)
    for _ in range(40):
        k = rng.randint(2, 6)
        values = [rng.choice([-3, 0, 2, 2, 5, 9]) for _ in range(k)]
        results = set()
        for _ in range(5):
            order = list(range(k))
            rng.shuffle(order)
            r = FanIn(0, kind, k=k)
            for t, i in enumerate(order):
                r.send(i, t, values[i])
            supplier = r.supplier_conn() if kind != "sum" else None
            results.add((r.read(), supplier))
        assert len(results) == 1, f"{kind} of {values}: {results}"
        (value, supplier) = results.pop()
        expected = max(values) if kind == "max" else min(values) if kind == "min" else sum(values)
        assert value == expected
        if supplier is not None:
            r0 = FanIn(0, kind, k=k)
            first = values.index(expected)
            assert supplier == r0.conns[first], "ties go to the smaller source"
