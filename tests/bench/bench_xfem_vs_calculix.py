"""XFEM (`parafab simulate`) against Gmsh + CalculiX tet10 on the same part and job: probe
displacement error against a fine conforming reference, and wall time of both routes
(meshing included for CalculiX, cutting and rule construction included for XFEM), as the grid
or mesh is refined. Writes DIR/xfem_vs_calculix.json and .png.

Usage: /usr/bin/python3 tests/bench/bench_xfem_vs_calculix.py [--quick] [--out DIR]
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
    ap.add_argument("--out", default=os.path.join(REPO, "out", "bench"))
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    ref_size = 2.0 if a.quick else 1.5
    reference = calculix(ref_size)
    rows = [xfem(c) for c in ([8, 16] if a.quick else [8, 12, 16, 24, 32])]
    rows += [calculix(s) for s in ([6, 4] if a.quick else [8, 6, 4, 3, 2])]
    for r in rows:
        r["error"] = abs(r["u_probe"] - reference["u_probe"]) / abs(reference["u_probe"])
        print("%-15s %5s  %7d unknowns  %7.2f s  probe u_z %.5f  error %.2e" % (
            r["route"], r["resolution"], r["unknowns"], r["seconds"], r["u_probe"], r["error"]))
    data = {"part": "l_bracket", "probe": [60, 20, 4], "reference": reference, "rows": rows}
    json.dump(data, open(os.path.join(a.out, "xfem_vs_calculix.json"), "w"), indent=2)
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
    ax.set_title("L-bracket: XFEM vs conforming FEM (reference: tet10, h = %g mm)" % ref_size, fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(a.out, "xfem_vs_calculix.png"), dpi=110)
    print("wrote", os.path.join(a.out, "xfem_vs_calculix.png"))


if __name__ == "__main__":
    sys.exit(main())
