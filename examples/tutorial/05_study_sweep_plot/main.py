"""Tutorial 5, a study with a sweep and a plot (docs/tutorials/05-study-sweep-plot.md), in
Python: weighted coverage against radio loss for BLE and Random, three seeds per point, run on
a process pool by `sim.sweep` (same outcomes as a serial run), plotted with matplotlib.

Run: `python main.py [PLOT.png]`. Exits non-zero if what the tutorial says does not happen.
"""

import statistics
import sys

import matplotlib

matplotlib.use("Agg")  # no display needed
import matplotlib.pyplot as plt

from ayllu import sim

LOSSES = [0.0, 0.3, 0.6, 0.9]
SEEDS = [1, 2, 3]


def main(plot: str) -> None:
    fig, ax = plt.subplots(figsize=(5.6, 3.6))
    means = {}
    for controller in ["BLE", "Random"]:
        grid = [
            sim.Scenario.paper(controller, seed).with_(duration=60.0, radio__loss=loss)
            for loss in LOSSES
            for seed in SEEDS
        ]
        a_w = [o.metrics["a_w"] for o in sim.sweep(grid, workers=2)]
        means[controller] = [statistics.mean(a_w[i * len(SEEDS) : (i + 1) * len(SEEDS)]) for i in range(len(LOSSES))]
        for loss, m in zip(LOSSES, means[controller]):
            print(f"{controller:<6} loss {loss:.1f}: A_w {m:.3f}")
        ax.plot(LOSSES, means[controller], marker="o", label=controller)
    ax.set_xlabel("radio loss")
    ax.set_ylabel("A_w (weighted coverage)")
    ax.set_ylim(0, 1)
    ax.legend()
    fig.tight_layout()
    fig.savefig(plot, dpi=100)
    print(f"plot: {plot}")
    assert all(b > r for b, r in zip(means["BLE"], means["Random"])), "BLE beats wandering at every loss"


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "coverage_vs_loss.png")
