#!/usr/bin/python3
"""Compliance shape optimization of the L-bracket (thesis §6.5.3; samples/simulations/l_bracket.json
supports and load, steel, face-route grid kept fixed for the run). Runs:
  holes:   the two bolt-hole radii, volume <= 1.005 V0 (the case of tests/python/test_optimize_compliance.py)
  holes+fillets: the hole radii and both fillet radii, volume <= V0
at 8 and 12 cells. Reports seconds per iteration and per evaluation (an evaluation = one solve +
2 x (design variables) perturbed re-cuts for the semi-analytic gradient), the ratio to a plain
`parafab simulate` of the part on the same cell count (median of 3, same run), the objective
reduction, and the fresh-simulation check (compliance of the written STEP / original at 16 cells).
Writes DIR/optimize_compliance.json and the runs' history.png. Usage: [--quick] [--out DIR]"""
import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
BRACKET = os.path.join(HERE, "..", "..", "samples", "parts", "l_bracket.step")
CLI = os.environ.get("PARAFAB_CLI", "build/workbench/entry/parafab")

ap = argparse.ArgumentParser()
ap.add_argument("--quick", action="store_true")
ap.add_argument("--out", default=".")
args = ap.parse_args()
os.makedirs(args.out, exist_ok=True)

ELASTIC = {"material": {"E": 210000, "nu": 0.3}, "element": "hex8", "supports": [{"point": [0, 20, 30]}],
           "loads": [{"point": [60, 20, 4], "force": [0, 0, -500]}]}
r = math.sqrt(0.5)
HOLES = [{"point": [44, 12, 4], "parameter": "radius"}, {"point": [44, 28, 4], "parameter": "radius"}]
FILLETS = [{"point": [13 - 5 * r, 20, 13 - 5 * r], "parameter": "radius"},
           {"point": [12 - 12 * r, 20, 12 - 12 * r], "parameter": "radius"}]
RUNS = [("holes", HOLES, 1.005, 8)] if args.quick else [
    ("holes", HOLES, 1.005, 8), ("holes", HOLES, 1.005, 12),
    ("holes+fillets", HOLES + FILLETS, 1.0, 8), ("holes+fillets", HOLES + FILLETS, 1.0, 12)]


def cli(argv, job):
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
        json.dump(job, f)
    try:
        t = time.time()
        p = subprocess.run([CLI] + argv[:2] + [f.name] + argv[2:], capture_output=True, text=True, timeout=1200)
        return json.loads(p.stdout), time.time() - t
    finally:
        os.unlink(f.name)


def compliance(part, cells):
    res, _ = cli(["simulate", part], dict(ELASTIC, grid={"cells": cells, "method": "face"}))
    return -2 * res["potential"]


rows = []
for name, params, ratio, cells in RUNS:
    out = os.path.join(args.out, "optimize_compliance_%s_%d" % (name.replace("+", "_"), cells))
    job = dict(ELASTIC, objective={"type": "compliance"}, grid={"cells": cells}, parameters=params,
               constraints=[{"type": "volume", "max_ratio": ratio}], max_iterations=2 if args.quick else 6,
               first_step=0.5, bound=0.4)
    h, wall = cli(["optimize", BRACKET, "-o", out], job)
    base = statistics.median(cli(["simulate", BRACKET], dict(ELASTIC, grid={"cells": cells, "method": "face"}))[1]
                             for _ in range(1 if args.quick else 3))
    n = max(len(h["iterations"]) - 1, 1)
    row = {"run": name, "cells": cells, "design_variables": len(params), "volume_bound": ratio,
           "status": h["status"], "iterations": len(h["iterations"]) - 1, "evaluations": h["evaluations"],
           "seconds": h["seconds"], "seconds_per_iteration": h["seconds"] / n,
           "seconds_per_evaluation": h["seconds"] / max(h["evaluations"], 1),
           "simulate_seconds_median": base,
           "evaluation_over_simulate": h["seconds"] / max(h["evaluations"], 1) / base,
           "initial_compliance": h["initial_objective"], "final_compliance": h["final_objective"],
           "reduction": 1 - h["final_objective"] / h["initial_objective"],
           "volume_ratio": h["final_volume"] / h["initial_volume"],
           "gradient": h["gradient"], "exact_derivatives": h.get("exact_derivatives", 0),
           "topology_switches": h.get("topology_switches", 0), "tangency_residual_max": h["tangency_residual_max"]}
    if not args.quick:
        row["fresh_16_cells_ratio"] = compliance(os.path.join(out, "optimized.step"), 16) / compliance(BRACKET, 16)
    rows.append(row)
    print(json.dumps(row))
with open(os.path.join(args.out, "optimize_compliance.json"), "w") as f:
    json.dump(rows, f, indent=2)
print("| run | cells | iterations | evaluations | s/iteration | s/evaluation | evaluation / simulate | C reduction | V/V0 | fresh 16-cell C ratio |")
for w in rows:
    print("| %s | %d | %d | %d | %.2f | %.2f | %.1f | %.2f %% | %.4f | %s |" % (
        w["run"], w["cells"], w["iterations"], w["evaluations"], w["seconds_per_iteration"], w["seconds_per_evaluation"],
        w["evaluation_over_simulate"], 100 * w["reduction"], w["volume_ratio"],
        "%.4f" % w["fresh_16_cells_ratio"] if "fresh_16_cells_ratio" in w else "-"))
