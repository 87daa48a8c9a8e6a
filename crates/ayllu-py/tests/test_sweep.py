"""Sweeps: a local process pool by default, a Dask cluster when given one; the outcomes are
those of a serial run."""

from __future__ import annotations

from ayllu import sim
from test_sim import spinner


def grid() -> list[sim.Scenario]:
    base = sim.Scenario.paper("BLE", 1).with_(duration=10.0)
    return [base.with_(seed=seed, controller=c) for seed in (1, 2) for c in ("BLE", "ForceField")]


def hashes(outs: list[sim.Outcome]) -> list[str]:
    return [o.trace_hash for o in outs]


def test_a_local_process_pool_gives_the_serial_outcomes() -> None:
    serial = sim.sweep(grid(), executor="serial")
    assert len(set(hashes(serial))) == 4
    assert hashes(sim.sweep(grid(), workers=2)) == hashes(serial)
    assert [o.metrics for o in sim.sweep(grid(), workers=2)] == [o.metrics for o in serial]


def test_a_python_controller_sweeps_too() -> None:
    scen = [sim.Scenario.paper("Random", s).with_(duration=3.0) for s in (1, 2)]
    assert hashes(sim.sweep(scen, spinner, workers=2)) == hashes(sim.sweep(scen, spinner, executor="serial"))


def test_a_dask_cluster_gives_the_serial_outcomes() -> None:
    from distributed import Client, LocalCluster

    serial = sim.sweep(grid(), executor="serial")
    with (
        LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster,
        Client(cluster) as client,
    ):
        assert hashes(sim.sweep(grid(), executor=client)) == hashes(serial)
