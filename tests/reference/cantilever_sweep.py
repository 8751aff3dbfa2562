#!/usr/bin/python3
"""Mesh-refinement sweep of the CalculiX cantilever reference (not a test).

    /usr/bin/python3 tests/reference/cantilever_sweep.py [--sizes 500 250 125]
                     [--elements C3D10 C3D4] [--threads 2] [--json out.json]

Prints tip deflection (interpolated at the tip-face centre), error vs
Euler-Bernoulli (87.77 mm) and Timoshenko k=5/6 (88.84 mm), mesh size,
node count and timings.
"""
import argparse
import json
import os
import shutil
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import calculix_reference as cr  # noqa: E402
from test_calculix_reference import (L, B, H, EB, TIMO,  # noqa: E402
                                     cantilever_job)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=float, nargs="+",
                    default=[500.0, 250.0, 125.0, 100.0])
    ap.add_argument("--elements", nargs="+", default=["C3D10", "C3D4"])
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--json", help="write all results here")
    a = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix="ccxref_sweep_")
    rows = []
    try:
        step = cr.make_box_step(os.path.join(tmp, "box.step"), (L, B, H))
        print("Euler-Bernoulli %.3f mm, Timoshenko(k=5/6) %.3f mm" % (EB, TIMO))
        print("%-6s %7s %8s %8s %10s %8s %8s %7s %7s %7s %8s" % (
            "elem", "h[mm]", "nodes", "elems", "tip uz", "err EB", "err Ti",
            "mesh s", "ccx s", "tot s", "vM max"))
        for el in a.elements:
            for h in a.sizes:
                job = cantilever_job(step, h, el)
                job["solver"]["threads"] = a.threads
                r = cr.run_job(job)
                uz = -r["displacement_at"][0]["u"][2]
                print("%-6s %7.1f %8d %8d %10.4f %7.2f%% %7.2f%% %7.2f %7.2f "
                      "%7.2f %8.1f" % (
                          el, h, r["nodes"], r["elements"], uz,
                          100 * (uz / EB - 1), 100 * (uz / TIMO - 1),
                          r["mesh_seconds"], r["solve_seconds"],
                          r["total_seconds"], r["von_mises"]["max"]),
                      flush=True)
                rows.append({"element": el, "size": h, "tip_uz": uz,
                             "result": r})
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"euler_bernoulli": EB, "timoshenko": TIMO,
                       "runs": rows}, f, indent=1)


if __name__ == "__main__":
    main()
