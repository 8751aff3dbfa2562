"""Validation convergence of strip designs (issue 5: "Forward simulator ... Goal: <= 1e-3 on all
samples, converging under refinement"): every feasible request in samples/strips/*.json is
designed once per run with "validate": {"edges": N} for N in EDGES, and the simulated curve is
compared with the target (deviation = max distance / length, computed by the solver) and with
the finest simulation (self-convergence: the nodes of N edges are every (N_max/N)-th node of
N_max edges, both uniform in arc length).

Time: the simulator's own seconds (median over --repeats runs) and the wall time of the whole
design_strip call (median), so the design cost is visible apart from the simulation.

Usage: /usr/bin/python3 tests/bench/bench_strip_validation.py [--quick] [--repeats 3] [--out DIR]
Writes DIR/strip_validation.json and DIR/strip_validation.png; prints a table.
PARAFAB_MODULE_DIR points at the built module (default build/workbench/entry).
"""
import argparse
import copy
import glob
import json
import math
import os
import statistics
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, "..", ".."))
sys.path.insert(0, os.environ.get("PARAFAB_MODULE_DIR", os.path.join(REPO, "build", "workbench", "entry")))
import parafab  # noqa: E402

EDGES = [50, 100, 200, 400, 800, 1600]
QUICK_EDGES = [50, 100, 200]
GOAL = 1e-3


def run(request, edges, repeats):
    req = copy.deepcopy(request)
    req["validate"] = {"edges": edges}
    # Composite / perforated layouts do not change the simulated profile: leave them out.
    req.pop("composite", None)
    req.pop("perforated", None)
    walls, sims, res = [], [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        res = parafab.design_strip(req)
        walls.append(time.perf_counter() - t0)
        sims.append(res["simulation"]["seconds"])
    return res, statistics.median(sims), statistics.median(walls)


def self_error(nodes, finest, length):
    """max_k |x_N[k] - x_fine[k r]| / length, r = N_fine / N."""
    n, m = len(nodes) - 1, len(finest) - 1
    if m % n:
        return None
    r = m // n
    return max(math.hypot(p[0] - finest[k * r][0], p[1] - finest[k * r][1]) for k, p in enumerate(nodes)) / length


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="edges 50..200, 1 repeat, 3 samples")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", default=os.path.join(REPO, "out", "bench"))
    ap.add_argument("--samples", default=os.path.join(REPO, "samples", "strips"))
    a = ap.parse_args()
    edges = QUICK_EDGES if a.quick else EDGES
    repeats = 1 if a.quick else a.repeats
    os.makedirs(a.out, exist_ok=True)
    files = sorted(glob.glob(os.path.join(a.samples, "*.json")))
    if a.quick:
        files = [f for f in files if os.path.basename(f) in
                 ("elliptic_arc.json", "gravity_one_inflection.json", "wave.json")]
    curves, skipped = [], []
    for path in files:
        name = os.path.splitext(os.path.basename(path))[0]
        request = json.load(open(path))
        probe = parafab.design_strip({k: v for k, v in request.items() if k != "validate"})
        if not probe["feasible"]:
            skipped.append({"name": name, "reason": probe["reason"]})
            continue
        rows = []
        for n in edges:
            res, sim_s, wall_s = run(request, n, repeats)
            sim = res["simulation"]
            rows.append({"edges": n, "deviation": sim["deviation"], "max_distance": sim["max_distance"],
                         "converged": sim["converged"], "iterations": sim["iterations"],
                         "load_steps": sim["load_steps"], "sim_seconds": sim_s, "wall_seconds": wall_s,
                         "nodes": sim["nodes"]})
        finest = rows[-1]["nodes"]
        for r in rows:
            r["self_error"] = self_error(r["nodes"], finest, res["length"]) if r is not rows[-1] else None
        for r in rows:
            del r["nodes"]
        curves.append({"name": name, "length": res["length"], "R": res["R"], "samples": res["diagnostics"]["samples"],
                       "gravity": res["gravity"] is not None, "inflections": len(res["inflections"]), "rows": rows})

    data = {"edges": edges, "repeats": repeats, "goal": GOAL, "curves": curves, "skipped": skipped}
    with open(os.path.join(a.out, "strip_validation.json"), "w") as f:
        json.dump(data, f, indent=1)

    print("%-26s %6s %11s %11s %5s %6s %10s %10s" % ("sample", "edges", "deviation", "vs finest", "conv", "iters",
                                                     "sim [ms]", "wall [ms]"))
    worst = 0.0
    for c in curves:
        for r in c["rows"]:
            worst = max(worst, r["deviation"] if r["deviation"] is not None else math.inf)
            se = "%11.2e" % r["self_error"] if r["self_error"] is not None else "%11s" % "-"
            print("%-26s %6d %11.2e %s %5s %6d %10.2f %10.2f" % (c["name"], r["edges"], r["deviation"], se,
                                                                 "yes" if r["converged"] else "NO", r["iterations"],
                                                                 1e3 * r["sim_seconds"], 1e3 * r["wall_seconds"]))
    for s in skipped:
        print("%-26s infeasible, skipped (%s)" % (s["name"], s["reason"][:60]))
    ok = all(r["converged"] and r["deviation"] <= GOAL for c in curves for r in c["rows"])
    print("worst deviation %.2e over %d samples x %d edge counts: %s the goal %.0e"
          % (worst, len(curves), len(edges), "meets" if ok else "MISSES", GOAL))
    plot(data, os.path.join(a.out, "strip_validation.png"))
    return 0 if ok else 1


def plot(data, png):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.6))
    for i, c in enumerate(data["curves"]):
        color = "C%d" % (i % 10)
        n = [r["edges"] for r in c["rows"]]
        dev = [max(r["deviation"], 1e-16) for r in c["rows"]]
        t = [1e3 * r["sim_seconds"] for r in c["rows"]]
        label = c["name"] + (" (gravity)" if c["gravity"] else "")
        ax1.loglog(n, dev, "o-", color=color, label=label)
        se = [(r["edges"], r["self_error"]) for r in c["rows"] if r["self_error"]]
        if se:
            ax1.loglog([p[0] for p in se], [p[1] for p in se], ":", color=color, alpha=0.7)
        ax2.loglog(t, dev, "o-", color=color, label=label)
    n = data["edges"]
    ax1.loglog(n, [1e-3 * (n[0] / k) ** 2 for k in n], "--", color="gray", lw=0.8, label="O(N⁻²)")
    for ax in (ax1, ax2):
        ax.axhline(data["goal"], color="red", lw=0.8, alpha=0.6)
        ax.grid(True, which="both", alpha=0.3)
        ax.set_ylabel("deviation (max distance / length)")
    ax1.set_xlabel("edges of the simulated rod")
    ax1.set_title("Deviation against edges (dotted: against the finest run)")
    ax2.set_xlabel("simulation time [ms] (median of %d)" % data["repeats"])
    ax2.set_title("Deviation against time")
    ax1.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(png, dpi=120)


if __name__ == "__main__":
    sys.exit(main())
