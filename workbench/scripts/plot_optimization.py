#!/usr/bin/python3
"""Chart of a shape optimization history (parafab optimize): objective against iteration and
against time. Usage: plot_optimization.py history.json out.png"""
import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main(history_path, png_path):
    with open(history_path) as f:
        h = json.load(f)
    its = h["iterations"]
    k = [it.get("iteration", i) for i, it in enumerate(its)]
    f_ = [it["objective"] for it in its]
    t = [it["seconds"] for it in its]
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.5))
    # A log axis only where the objective spans a decade or more: over a narrower range its
    # minor ticks get labels like 1.04e-3, 1.02e-3 stacked on each other.
    log = all(v > 0 for v in f_) and max(f_) > 10 * min(f_)
    for ax, x, label in ((axes[0], k, "iteration"), (axes[1], t, "time [s]")):
        ax.plot(x, f_, "o-", ms=3)
        ax.set_xlabel(label)
        ax.set_ylabel("objective (%s)" % h.get("objective", ""))
        if log:
            ax.set_yscale("log")
        ax.grid(True, alpha=0.3)
    fig.suptitle("%s: %.4g -> %.4g (%d iterations, %s)" % (
        h.get("objective", ""), h["initial_objective"], h["final_objective"], len(its) - 1, h.get("status", "")))
    fig.tight_layout()
    fig.savefig(png_path, dpi=110)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
