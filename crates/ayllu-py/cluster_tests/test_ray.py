"""Sweeps on a Ray cluster give the serial outcomes. Not in `make test`: Ray is a large install
(a wheel of about 65 MB and its dependencies) and starts slowly, so it has its own target,
`make test-ray`, which installs it into the test venv. The Dask cluster's twin runs in
`make test` (tests/test_sweep.py)."""

from __future__ import annotations

import ray

from ayllu import sim


def grid() -> list[sim.Scenario]:
    base = sim.Scenario.paper("BLE", 1).with_(duration=10.0)
    return [base.with_(seed=seed, controller=c) for seed in (1, 2) for c in ("BLE", "ForceField")]


def test_a_ray_cluster_gives_the_serial_outcomes() -> None:
    serial = [o.trace_hash for o in sim.sweep(grid(), executor="serial")]
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        assert [o.trace_hash for o in sim.sweep(grid(), executor=ray)] == serial
    finally:
        ray.shutdown()
