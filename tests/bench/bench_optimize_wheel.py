#!/usr/bin/python3
"""Wheel balancing on its own CAD parameters (thesis §6.6, Table 6.1 "asymmetric wheel", mass
properties only: the compliance part needs the elasticity derivatives, not done yet).
14 design parameters of samples/parts/wheel.step: the offsets of the 10 spoke side planes and
the radii of the hub hole, hub, rim inside and rim outside (hub and rim-inside arcs tied). Objective: |c⊥|², the centre of
mass's squared distance from the z axis. Reports iterations, seconds per iteration and the
offset reached; writes DIR/optimize_wheel.json and the run's history.png/optimized.step.
Usage: bench_optimize_wheel.py [--quick] [--out DIR]"""
import argparse
import json
import math
import os
import sys
import time

sys.path.insert(0, os.environ.get("PARAFAB_MODULE_DIR", "build/workbench/entry"))
import parafab  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
WHEEL = os.path.join(HERE, "..", "..", "samples", "parts", "wheel.step")

ap = argparse.ArgumentParser()
ap.add_argument("--quick", action="store_true")
ap.add_argument("--out", default=".")
args = ap.parse_args()
os.makedirs(args.out, exist_ok=True)

faces = parafab.inspect_part(WHEEL)["faces"]
params = []
for f in faces:
    p = f["parameters"]
    if f["type"] == "plane" and abs(p["n"][2]) < 0.5:
        params.append({"face": f["index"], "parameter": "offset"})
# Radii: hub hole (5) and rim outside (50) are one face each; the hub (12) and the rim inside
# (42) are split by the spokes into arcs, tied into one design variable each.
ties = []
for r in (5, 12, 42, 50):
    group = [{"face": f["index"], "parameter": "radius"} for f in faces
             if f["type"] == "cylinder" and abs(f["parameters"]["r"] - r) < 1e-6]
    params.append(group[0])
    if len(group) > 1:
        ties.append(group)
job = {"ties": ties, "objective": {"type": "center_of_mass", "axis": {"point": [0, 0, 0], "direction": [0, 0, 1]}},
       "parameters": params, "max_iterations": 2 if args.quick else 40, "relative_improvement": 1e-9,
       "bound": 0.3}
t0 = time.time()
h = parafab.optimize(WHEEL, job, out_dir=os.path.join(args.out, "optimize_wheel"))
wall = time.time() - t0
n = len(h["iterations"]) - 1
summary = {
    "parameters": len(params),
    "iterations": n,
    "evaluations": h["evaluations"],
    "invalid_models": h["invalid_models"],
    "status": h["status"],
    "seconds": wall,
    "seconds_per_iteration": h["seconds"] / max(n, 1),
    "initial_offset_mm": math.sqrt(h["initial_objective"]),
    "final_offset_mm": math.sqrt(h["final_objective"]),
    "volume_ratio": h["final_volume"] / h["initial_volume"],
    "tangency_residual_max": h["tangency_residual_max"],
    "thesis": {"initial_offset_mm": 9.9, "final_offset_mm": "< 0.1", "seconds_per_iteration": 70,
               "note": "thesis run includes compliance; this one mass properties only"},
}
with open(os.path.join(args.out, "optimize_wheel.json"), "w") as f:
    json.dump({"summary": summary, "history": h}, f, indent=2)
print(json.dumps(summary, indent=2))
