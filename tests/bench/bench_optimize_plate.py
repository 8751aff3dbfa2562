#!/usr/bin/python3
"""Compliance of a plate with a grid of holes on its 40 hole radii (thesis Table 6.1, "plate with
a grid of holes": there about 160 parameters and 50 s per iteration on one core).

samples/parts/plate_holes.step: 160 x 100 x 5 mm, 8 x 5 holes of radius 5 mm. Steel, clamped at
x = 0, 5 kN down (-y) on the face x = 160 (in-plane bending), volume <= start. `parafab
optimize` with the 40 radii as design variables on a 32-cell grid, one augmented-Lagrangian
round of --iterations L-BFGS steps, one thread. Reported: seconds per evaluation (simulation +
semi-analytic gradient) and per iteration, the compliance reduction, and the written part
checked afresh by `parafab.simulate` on 48 cells (C = -2 potential) and by Gmsh + CalculiX
tet10 (h = 4 mm) before and after (tests/bench/compliance_case.py).

The route without ParaFab's gradient is timed as one Gmsh + CalculiX tet10 run of the plate
(h = 4 mm, meshing included) times 41: the cost of one forward-difference gradient over 40
radii (an estimate from one measured run, labelled as such).

Usage: PARAFAB_MODULE_DIR=build/workbench/entry /usr/bin/python3 tests/bench/bench_optimize_plate.py
           [--quick] [--iterations N] [--out DIR]       writes DIR/optimize_plate.json
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import compliance_case  # noqa: E402

PLATE = os.path.join(compliance_case.REPO, "samples", "parts", "plate_holes.step")
SIM = {"material": {"E": 210000, "nu": 0.3},
       "supports": [{"point": [0, 50, 2.5]}],
       "loads": [{"point": [160, 50, 2.5], "force": [0, -5000, 0]}]}


def main():
    a = compliance_case.arguments(4)
    holes = [{"point": [15 + 20 * i, 10 + 20 * j, 2.5], "parameter": "radius"} for i in range(8) for j in range(5)]
    job = dict(SIM, grid={"cells": 32}, objective={"type": "compliance"}, parameters=holes,
               constraints=[{"type": "volume", "max_ratio": 1.0}],
               max_iterations=1 if a.quick else a.iterations, max_outer=1, threads=1)
    h, summary = compliance_case.run(PLATE, SIM, job, os.path.join(a.out, "optimize_plate"), 48,
                                     None if a.quick else 4)
    radii = [p["final"] for p in h["parameters"]]
    summary["radii"] = {"min": min(radii), "max": max(radii)}
    summary["thesis"] = {"parameters": 160, "seconds_per_iteration": 50}
    compliance_case.report(a.out, "optimize_plate", h, summary)


if __name__ == "__main__":
    sys.exit(main())
