#!/usr/bin/python3
"""Compliance of a plate with a grid of holes on its 40 hole radii (thesis Table 6.1, "plate with
a grid of holes": there about 160 parameters and 50 s per iteration on one core).

samples/parts/plate_holes.step: 160 x 100 x 5 mm, 8 x 5 holes of radius 5 mm. Steel, clamped at
x = 0, 5 kN down (-y) on the face x = 160 (in-plane bending), volume <= start. `parafab
optimize` with the 40 radii as design variables on a 32-cell grid, one augmented-Lagrangian
round of --iterations L-BFGS steps, one thread. Reported: seconds per evaluation (simulation +
gradient, by default the exact route) and per iteration, the compliance reduction, and the written part
checked afresh by `parafab.simulate` on 48 cells (C = -2 potential) and by Gmsh + CalculiX
tet10 (h = 4 mm) before and after (tests/bench/compliance_case.py).

The route without ParaFab's gradient is timed as one Gmsh + CalculiX tet10 run of the plate
(h = 4 mm, meshing included) times 41: the cost of one forward-difference gradient over 40
radii (an estimate from one measured run, labelled as such).

With --positions each hole's centre (axis point x, y, within 2 mm of its start) is a design
variable too: 120 parameters, the count where the thesis' case sits, to show what a gradient
whose cost does not grow with the parameter count gives.

Usage: PARAFAB_MODULE_DIR=build/workbench/entry /usr/bin/python3 tests/bench/bench_optimize_plate.py
           [--quick] [--iterations N] [--gradient exact|semi-analytic] [--positions] [--out DIR]
       writes DIR/optimize_plate.json (DIR/optimize_plate_positions.json with --positions)
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import compliance_case  # noqa: E402

PLATE = os.path.join(compliance_case.REPO, "samples", "parts", "plate_holes.step")
SIM = {"material": {"E": 210000, "nu": 0.3}, "element": "hex8",
       "supports": [{"point": [0, 50, 2.5]}],
       "loads": [{"point": [160, 50, 2.5], "force": [0, -5000, 0]}]}


def main():
    a = compliance_case.arguments(4, positions=True)
    centres = [(10 + 20 * i, 10 + 20 * j) for i in range(8) for j in range(5)]
    holes = [{"point": [x + 5, y, 2.5], "parameter": "radius"} for x, y in centres]  # a point on the hole
    if a.positions:  # 120 parameters: each hole also moves in the plate, by 2 mm at most
        holes += [{"point": [x + 5, y, 2.5], "parameter": "axis point " + c, "min": v - 2, "max": v + 2}
                  for x, y in centres for c, v in (("x", x), ("y", y))]
    job = dict(SIM, grid={"cells": 32}, objective={"type": "compliance", "gradient": a.gradient}, parameters=holes,
               constraints=[{"type": "volume", "max_ratio": 1.0}],
               max_iterations=1 if a.quick else a.iterations, max_outer=1, threads=1)
    name = "optimize_plate_positions" if a.positions else "optimize_plate"
    h, summary = compliance_case.run(PLATE, SIM, job, os.path.join(a.out, name), 48, None if a.quick else 4)
    radii = [p["final"] for p in h["parameters"] if p["name"].endswith("radius")]
    summary["radii"] = {"min": min(radii), "max": max(radii)}
    summary["thesis"] = {"parameters": 160, "seconds_per_iteration": 50}
    if a.positions:
        moves = [abs(p["final"] - p["initial"]) for p in h["parameters"] if " axis point " in p["name"]]
        summary["largest_centre_move"] = max(moves)
    compliance_case.report(a.out, name, h, summary)


if __name__ == "__main__":
    sys.exit(main())
