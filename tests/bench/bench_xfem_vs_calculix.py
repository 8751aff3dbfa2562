"""XFEM (`parafab simulate`) against Gmsh + CalculiX tet10 on the same part and job: probe
displacement error against a fine conforming reference, and wall time of both routes
(meshing included for CalculiX, cutting and rule construction included for XFEM), as the grid
or mesh is refined. Writes DIR/xfem_vs_calculix.json and .png.

Cases: the filleted L-bracket job (samples/simulations/l_bracket.json), and the cantilever box
8000 × 1000 × 1000 mm of the issue (E = 210 GPa, ν = 0.3, 9 MN on the free end, the other end
clamped; Euler–Bernoulli 87.7 mm), probe at the centre of the free end.

Usage: /usr/bin/python3 tests/bench/bench_xfem_vs_calculix.py [--case l_bracket|cantilever] [--quick] [--out DIR]
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, "..", ".."))
CLI = os.environ.get("PARAFAB_CLI", os.path.join(REPO, "build", "workbench", "entry", "parafab"))
REF = os.path.join(REPO, "tests", "reference", "calculix_reference.py")
PART = os.path.join(REPO, "samples", "parts", "l_bracket.step")
JOB = os.path.join(REPO, "samples", "simulations", "l_bracket.json")


def use_cantilever(tmp):
    """Point PART and JOB at the cantilever box (written by Gmsh's OCC kernel)."""
    global PART, JOB
    sys.path.insert(0, os.path.join(REPO, "tests", "reference"))
    import calculix_reference as cr
    PART = cr.make_box_step(os.path.join(tmp, "cantilever.step"), (8000.0, 1000.0, 1000.0))
    JOB = os.path.join(tmp, "cantilever.json")
    json.dump({"material": {"E": 210000, "nu": 0.3},
               "supports": [{"point": [0, 500, 500]}],
               "loads": [{"point": [8000, 500, 500], "force": [0, 0, -9e6]}],
               "probes": [[8000, 500, 500]]}, open(JOB, "w"))


def xfem(cells):
    job = json.load(open(JOB))
    job["grid"] = {"cells": cells}
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
        json.dump(job, f)
    t0 = time.perf_counter()
    out = subprocess.run([CLI, "simulate", PART, f.name], capture_output=True, text=True, check=True).stdout
    wall = time.perf_counter() - t0
    os.unlink(f.name)
    d = json.loads(out)
    return {"route": "xfem", "resolution": cells, "unknowns": d["dofs"], "seconds": wall,
            "u_probe": d["probes"][0]["displacement"][2], "parts": d["seconds"]}


def calculix(size):
    t0 = time.perf_counter()
    out = subprocess.run(["/usr/bin/python3", REF, JOB, "--parafab", PART, "--size", str(size), "--quiet"],
                         capture_output=True, text=True, check=True).stdout
    wall = time.perf_counter() - t0
    d = json.loads(out)
    return {"route": "calculix_tet10", "resolution": size, "unknowns": 3 * d["nodes"], "seconds": wall,
            "u_probe": d["displacement_at"][0]["u"][2],
            "parts": {"mesh": d["mesh_seconds"], "solve": d["solve_seconds"]}}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--case", choices=["l_bracket", "cantilever"], default="l_bracket")
    ap.add_argument("--out", default=os.path.join(REPO, "out", "bench"))
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    if a.case == "cantilever":
        use_cantilever(tempfile.mkdtemp(prefix="parafab_cantilever_"))
        ref_size = 100.0
        grids, sizes = [4, 8, 16, 32], [1000, 500, 250, 150]
    else:
        ref_size = 2.0 if a.quick else 1.5
        grids = [8, 16] if a.quick else [8, 12, 16, 24, 32]
        sizes = [6, 4] if a.quick else [8, 6, 4, 3, 2]
    reference = calculix(ref_size)
    rows = [xfem(c) for c in grids]
    rows += [calculix(s) for s in sizes]
    for r in rows:
        r["error"] = abs(r["u_probe"] - reference["u_probe"]) / abs(reference["u_probe"])
        print("%-15s %5s  %7d unknowns  %7.2f s  probe u_z %.5f  error %.2e" % (
            r["route"], r["resolution"], r["unknowns"], r["seconds"], r["u_probe"], r["error"]))
    data = {"case": a.case, "part": PART, "job": json.load(open(JOB)), "reference": reference, "rows": rows}
    name = "xfem_vs_calculix" if a.case == "l_bracket" else "xfem_vs_calculix_" + a.case
    json.dump(data, open(os.path.join(a.out, name + ".json"), "w"), indent=2)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for route, style in [("xfem", "o-"), ("calculix_tet10", "s--")]:
        rr = [r for r in rows if r["route"] == route]
        ax.loglog([r["seconds"] for r in rr], [r["error"] for r in rr], style,
                  label="XFEM hex8 (cut + rules + solve)" if route == "xfem" else "Gmsh + CalculiX tet10 (mesh + solve)")
        for r in rr:
            ax.annotate(str(r["resolution"]), (r["seconds"], r["error"]), fontsize=7, xytext=(3, 3), textcoords="offset points")
    ax.set_xlabel("wall time [s]")
    ax.set_ylabel("relative error of the probe displacement")
    ax.set_title("%s: XFEM vs conforming FEM (reference: tet10, h = %g mm)" % (a.case, ref_size), fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(a.out, name + ".png"), dpi=110)
    print("wrote", os.path.join(a.out, name + ".png"))


if __name__ == "__main__":
    sys.exit(main())
