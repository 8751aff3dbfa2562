#!/usr/bin/python3
"""Two routes to the same compliance shape optimization (issue 12: "compare with the route a
FreeCAD user has today"): the L-bracket of bench_optimize_compliance.py (steel, support on the
upright's back, 500 N down on the base end), design = the two bolt-hole radii, V <= 1.005 V0.

  A  `parafab optimize` (thesis §6.5): XFEM on a fixed 8-cell face-route grid, exact gradient
     (rule derivatives; semi-analytic until 2026-11-27), L-BFGS + augmented Lagrangian for the
     volume bound.
  B  the route without ParaFab's gradient: scipy SLSQP (the volume bound as a constraint) with
     forward-difference gradients; every evaluation applies the radii and writes the STEP
     (`parafab optimize` with "start", max_iterations 0 and no chart: projection + write-back
     only, the analogue of a FreeCAD recompute), meshes it with Gmsh tet10 and solves it with CalculiX
     (tests/reference/calculix_reference.py), compliance f^T u of the nodal loads; the volume
     from OCCT (the written STEP). FD step 0.05 mm: remeshing noise makes smaller steps useless
     (measured dC/dr 3.8 at h = 0.001 mm, 0.95 at 0.01, 0.68 at 0.05).

`--case bump`: the same two routes on a free-form face (samples/parts/bump_block.step, clamped
at x = 0, 500 N down at x = 60, V <= V0), design = the z of six interior poles of its B-spline
top (rows i = 2 and 5; tests/python/test_optimize_poles.py), each within [0, 2 z0].

Each route's objective is its own discretization of C, so the common target is a relative
reduction: 90 % of the smaller of the two routes' final reductions. Reported: time and
evaluations to reach it, time per evaluation, final C of both results and of the original by
one common reference (CalculiX tet10 on a fine mesh), OCCT volume ratios. Writes
DIR/optimize_routes.json and DIR/optimize_routes.png (objective reduction vs time).
Usage: PARAFAB_CLI=build/workbench/entry/parafab /usr/bin/python3 tests/bench/bench_optimize_routes.py [--quick] [--case bracket|bump] [--out DIR]
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np
from scipy.optimize import minimize

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, "..", ".."))
sys.path.insert(0, os.path.join(REPO, "tests", "reference"))
import calculix_reference as cr  # noqa: E402

BRACKET = os.path.join(REPO, "samples", "parts", "l_bracket.step")
CLI = os.environ.get("PARAFAB_CLI", os.path.join(REPO, "build", "workbench", "entry", "parafab"))

ap = argparse.ArgumentParser()
ap.add_argument("--quick", action="store_true")
ap.add_argument("--out", default=".")
ap.add_argument("--case", choices=("bracket", "bump"), default="bracket")
args = ap.parse_args()
os.makedirs(args.out, exist_ok=True)

if args.case == "bracket":
    PART = BRACKET
    ELASTIC = {"material": {"E": 210000, "nu": 0.3}, "supports": [{"point": [0, 20, 30]}],
               "loads": [{"point": [60, 20, 4], "force": [0, 0, -500]}]}
    DESIGN = [{"point": [44, 12, 4], "parameter": "radius"}, {"point": [44, 28, 4], "parameter": "radius"}]
    X0, BOUNDS = [4.0, 4.0], [(2.4, 5.6)] * 2
    RATIO = 1.005
    A_OPTIONS = {"first_step": 0.5, "bound": 0.4}
    TITLE = "L-bracket hole radii, V <= %.3f V0" % RATIO
else:
    PART = os.path.join(REPO, "samples", "parts", "bump_block.step")
    ELASTIC = {"material": {"E": 210000, "nu": 0.3}, "supports": [{"point": [0, 20, 5]}],
               "loads": [{"point": [60, 20, 5], "force": [0, 0, -500]}]}
    POLES = [(i, j) for i in (2, 5) for j in (2, 3, 4)]
    DESIGN = [{"face": 2, "parameter": "pole %d %d z" % p} for p in POLES]
    X0 = [15.1 if i == 2 else 18.4 for i, _ in POLES]
    BOUNDS = [(0.0, 2 * z) for z in X0]
    RATIO = 1.0
    A_OPTIONS = {"bound": 1.0}
    TITLE = "bump block, z of six B-spline poles, V <= V0"
ITERATIONS = 2 if args.quick else 8
MESH = 6.0 if args.quick else 4.0        # route B's Gmsh size (mm)
REFERENCE = 4.0 if args.quick else 2.0   # the common reference's Gmsh size (mm)
FD_STEP = 0.05                           # mm
work = tempfile.mkdtemp(prefix="optroutes_")


def cli(argv, job):
    path = os.path.join(work, "job.json")
    with open(path, "w") as f:
        json.dump(job, f)
    p = subprocess.run([CLI] + argv[:2] + [path] + argv[2:], capture_output=True, text=True, timeout=1200)
    out = json.loads(p.stdout)
    if p.returncode != 0:
        raise RuntimeError("parafab %s failed: %s" % (argv[0], out))
    return out


def calculix_compliance(step, size):
    res = cr.run_job(cr.from_parafab_job(ELASTIC, step, size))
    return res["compliance"], res["nodes"]


# --- route A ------------------------------------------------------------------------------
out_a = os.path.join(args.out, "optimize_routes_A")
t0 = time.time()
h = cli(["optimize", PART, "-o", out_a],
        dict(ELASTIC, objective={"type": "compliance"}, grid={"cells": 8}, parameters=DESIGN,
             constraints=[{"type": "volume", "max_ratio": RATIO}], max_iterations=ITERATIONS, **A_OPTIONS))
wall_a = time.time() - t0
startup_a = wall_a - h["seconds"]  # process start, STEP read, face model: before the history's clock
trace_a = [(startup_a + it["seconds"], it["objective"], it["constraint_violation"]) for it in h["iterations"]]
route_a = {"status": h["status"], "evaluations": h["evaluations"], "seconds": wall_a,
           "seconds_per_evaluation": h["seconds"] / h["evaluations"], "initial": h["initial_objective"],
           "final": h["final_objective"], "final_violation": h["final_violation"],
           "design": [p["final"] for p in h["parameters"]], "step": h["optimized_step"],
           "volume_ratio": h["final_volume"] / h["initial_volume"], "gradient": h["gradient"]}

# --- route B ------------------------------------------------------------------------------
cache = {}
evals_b = []   # (seconds since start, C, V) of every evaluation
t0_b = time.time()


def evaluate(x):
    key = tuple(np.round(x, 12))
    if key not in cache:
        d = os.path.join(work, "eval%d" % len(evals_b))
        hb = cli(["optimize", PART, "-o", d],
                 dict(ELASTIC, objective={"type": "volume"}, parameters=DESIGN, start=list(map(float, x)),
                      max_iterations=0, bound=A_OPTIONS["bound"], chart=False))
        c, _ = calculix_compliance(hb["optimized_step"], MESH)
        cache[key] = (c, hb["final_volume"], hb["optimized_step"])
        evals_b.append((time.time() - t0_b, c, hb["final_volume"]))
    return cache[key]


x0 = np.array(X0)
C0, V0, _ = evaluate(x0)


def gradients(x):
    c, v, _ = evaluate(x)
    gc, gv = np.zeros(len(x)), np.zeros(len(x))
    for k in range(len(x)):
        xk = x.copy()
        xk[k] += FD_STEP
        ck, vk, _ = evaluate(xk)
        gc[k], gv[k] = (ck - c) / FD_STEP, (vk - v) / FD_STEP
    return gc, gv


trace_b = [(evals_b[0][0], C0, 0.0)]


def record(x):
    c, v, _ = evaluate(x)
    trace_b.append((time.time() - t0_b, c, max(0.0, v / V0 / RATIO - 1)))


run = minimize(lambda x: evaluate(x)[0] / C0, x0, jac=lambda x: gradients(x)[0] / C0, method="SLSQP",
               bounds=BOUNDS, callback=record, options={"maxiter": ITERATIONS, "ftol": 1e-6},
               constraints=[{"type": "ineq", "fun": lambda x: RATIO - evaluate(x)[1] / V0,
                             "jac": lambda x: -gradients(x)[1] / V0}])
wall_b = time.time() - t0_b
cb, vb, step_b = evaluate(run.x)
shutil.copy(step_b, os.path.join(args.out, "optimize_routes_B.step"))
route_b = {"status": run.message, "evaluations": len(evals_b), "seconds": wall_b,
           "seconds_per_evaluation": wall_b / len(evals_b), "initial": C0, "final": cb,
           "final_violation": max(0.0, vb / V0 / RATIO - 1), "volume_ratio": vb / V0, "design": list(map(float, run.x)),
           "mesh_size": MESH, "fd_step": FD_STEP}

# --- common target, common reference ------------------------------------------------------
# An iterate counts only when feasible (relative violation <= 1e-6): the augmented Lagrangian's
# early iterates (and SLSQP's) may lie above the bound, where C is lower.
FEASIBLE = 1e-6
red = lambda trace, c0: [(t, 1 - c / c0, v <= FEASIBLE) for t, c, v in trace]  # noqa: E731
red_a, red_b = red(trace_a, route_a["initial"]), red(trace_b, C0)
route_a["reduction"], route_b["reduction"] = 1 - route_a["final"] / route_a["initial"], 1 - cb / C0
target = 0.9 * min(route_a["reduction"], route_b["reduction"])
for route, trace in ((route_a, red_a), (route_b, red_b)):
    hit = next(((t, i) for i, (t, r, ok) in enumerate(trace) if ok and r >= target), None)
    route["seconds_to_target"] = hit[0] if hit else None
    route["iterations_to_target"] = hit[1] if hit else None
first = route_b["seconds_to_target"]
route_b["evaluations_to_target"] = None if first is None else sum(1 for t, _, _ in evals_b if t <= first + 1e-9)
route_a["evaluations_to_target"] = None if route_a["iterations_to_target"] is None else \
    h["iterations"][route_a["iterations_to_target"]].get("evaluations")
ref = {}
for name, step in (("original", PART), ("A", route_a["step"]), ("B", step_b)):
    t = time.time()
    c, nodes = calculix_compliance(step, REFERENCE)
    ref[name] = {"compliance": c, "nodes": nodes, "seconds": time.time() - t}
for name, route in (("A", route_a), ("B", route_b)):
    route["reference_compliance"] = ref[name]["compliance"]
    route["reference_reduction"] = 1 - ref[name]["compliance"] / ref["original"]["compliance"]
shutil.rmtree(work, ignore_errors=True)

summary = {"target_reduction": target, "reference_mesh_size": REFERENCE, "reference": ref, "A": route_a, "B": route_b,
           "trace_A": red_a, "trace_B": red_b, "quick": args.quick, "case": args.case}
with open(os.path.join(args.out, "optimize_routes.json"), "w") as f:
    json.dump(summary, f, indent=2)

import matplotlib  # noqa: E402
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
fig, ax = plt.subplots(figsize=(6.4, 4))
for trace, mark, label in ((red_a, "o", "A: parafab optimize (XFEM 8 cells, %s gradient)" % h["gradient"]),
                           (red_b, "s", "B: SLSQP, forward differences, Gmsh tet10 %.0f mm + CalculiX" % MESH)):
    line, = ax.plot([t for t, _, _ in trace], [100 * r for _, r, _ in trace], mark + "-", mfc="none", label=label)
    ax.plot([t for t, _, ok in trace if ok], [100 * r for _, r, ok in trace if ok], mark, color=line.get_color())
ax.axhline(100 * target, color="gray", ls=":", label="common target (90 % of the smaller final reduction)")
ax.set_xlabel("wall time (s)")
ax.set_ylabel("compliance reduction, own model (%); filled: feasible")
ax.set_title(TITLE)
ax.legend(fontsize=7)
fig.tight_layout()
fig.savefig(os.path.join(args.out, "optimize_routes.png"), dpi=120)

print("| route | status | evaluations | s/evaluation | s to target (evaluations) | total s | own C reduction | "
      "reference C (CalculiX %.0f mm) | reference reduction | V/V0 |" % REFERENCE)
for name, r in (("A", route_a), ("B", route_b)):
    print("| %s | %s | %d | %.2f | %s (%s) | %.1f | %.2f %% | %.3f | %.2f %% | %.6f |" % (
        name, r["status"], r["evaluations"], r["seconds_per_evaluation"],
        "%.1f" % r["seconds_to_target"] if r["seconds_to_target"] is not None else "-",
        r["evaluations_to_target"], r["seconds"],
        100 * r["reduction"], r["reference_compliance"], 100 * r["reference_reduction"],
        r["volume_ratio"]))
print("target reduction %.3f %%, original reference C %.3f" % (100 * target, ref["original"]["compliance"]))
