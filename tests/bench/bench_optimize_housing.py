#!/usr/bin/python3
"""Compliance of the motor housing on its four fin thicknesses, each fin kept symmetric about
its mid-plane (thesis Table 6.1, "motor housing, compliance with symmetric fins": 4 parameters,
86 s per iteration on one core, compliance -6.7 %; the thesis's part is not ours).

samples/parts/housing.step: open-bottom aluminium shell 60 x 40 x 30 mm, wall 3, four fins
2 x 30 x 8 mm on the top plate, a filleted boss. The bottom rim (face 27) is clamped, the top
plate (face 0) carries 1 MPa downwards (it bends across the fins). Design variables: the offset
of each fin's -x side face (faces 10, 14, 18, 22); its +x face (13, 17, 21, 25) is mirrored
about the fin's mid-plane (`mirrors`), so a fin grows or shrinks on both sides. Volume <= start
(augmented Lagrangian, one round of --iterations L-BFGS steps), 16 cells, one thread.

Reported: seconds per evaluation (simulation + semi-analytic gradient) and per iteration, the
compliance change on the optimizer's grid and in a fresh `parafab.simulate` of the written part
on 24 cells (C = -2 potential) and by Gmsh + CalculiX tet10 (h = 2 mm) before and after, the
fin thicknesses, and the route without ParaFab's gradient:
one Gmsh + CalculiX tet10 run (h = 2 mm, meshing included) times 5, the cost of a forward
difference gradient over 4 parameters (an estimate from one measured run, labelled as such).

Usage: PARAFAB_MODULE_DIR=build/workbench/entry /usr/bin/python3 tests/bench/bench_optimize_housing.py
           [--quick] [--iterations N] [--out DIR]       writes DIR/optimize_housing.json
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import compliance_case  # noqa: E402

HOUSING = os.path.join(compliance_case.REPO, "samples", "parts", "housing.step")
SIM = {"material": {"E": 70000, "nu": 0.33}, "element": "hex8",
       "supports": [{"face": 27}],
       "loads": [{"face": 0, "traction": [0, 0, -1.0]}]}
# (-x face, +x face, mid-plane x) of each fin, as make_parts.py builds them (x = 8 + 8 i, 2 thick)
FINS = [(10, 13, 9.0), (14, 17, 17.0), (18, 21, 25.0), (22, 25, 33.0)]


def main():
    a = compliance_case.arguments(6)
    job = dict(SIM, grid={"cells": 16}, objective={"type": "compliance", "gradient": a.gradient},
               parameters=[{"face": lo, "parameter": "offset"} for lo, _, _ in FINS],
               mirrors=[{"faces": [lo, hi], "plane": {"normal": [1, 0, 0], "offset": mid}} for lo, hi, mid in FINS],
               constraints=[{"type": "volume", "max_ratio": 1.0}],
               max_iterations=1 if a.quick else a.iterations, max_outer=1, threads=1)
    h, summary = compliance_case.run(HOUSING, SIM, job, os.path.join(a.out, "optimize_housing"), 24,
                                     None if a.quick else 2)
    # A fin's thickness: its mirrored +x face is at 2 mid - offset, so thickness = 2 (mid - offset).
    summary["fin_thickness"] = [2 * (mid - p["final"]) for (_, _, mid), p in zip(FINS, h["parameters"])]
    summary["thesis"] = {"parameters": 4, "seconds_per_iteration": 86, "compliance_change": -0.067}
    compliance_case.report(a.out, "optimize_housing", h, summary)


if __name__ == "__main__":
    sys.exit(main())
