"""Figures for the sample parts (cf. thesis Table 6.1): grid, cut cells, subvolumes, DOFs,
time of cutting, rule construction, assembly and solve, and peak memory, for a linear
simulation under gravity with the lowest face (by a point at the bottom of the bounding box)
held fixed. Usage: /usr/bin/python3 tests/bench/bench_simulate_parts.py [--cells N] [--out DIR]"""
import argparse
import json
import os
import re
import subprocess
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, "..", ".."))
CLI = os.environ.get("PARAFAB_CLI", os.path.join(REPO, "build", "workbench", "entry", "parafab"))


def run(part, cells):
    info = json.loads(subprocess.run([CLI, "inspect", part], capture_output=True, text=True, check=True).stdout)
    lo, hi = info["bbox"]["min"], info["bbox"]["max"]
    # The support: the face nearest the bottom centre of the bounding box, else any face touching it.
    # hex8, the element of this benchmark's figures in tests/bench/README.md (the default is hex27 since 2026-11-27).
    job = {"material": {"E": 210000, "nu": 0.3, "density": 7.85e-9}, "element": "hex8", "grid": {"cells": cells},
           "gravity": [0, 0, -9810]}
    candidates = [[0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), lo[2]], [lo[0], 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])]]
    for point in candidates:
        job["supports"] = [{"point": point}]
        with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
            json.dump(job, f)
        p = subprocess.run(["/usr/bin/time", "-v", CLI, "simulate", part, f.name], capture_output=True, text=True)
        os.unlink(f.name)
        if p.returncode == 0:
            d = json.loads(p.stdout)
            rss = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", p.stderr).group(1))
            return d, rss / 1024.0
    return None, 0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cells", type=int, default=16)
    ap.add_argument("--out", default=os.path.join(REPO, "out", "bench"))
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    rows = []
    print("%-11s %-11s %5s %5s %7s %7s %7s %8s %7s %8s  %s" % ("part", "grid", "cut", "subv", "dofs", "cut s", "rules s",
                                                           "assem s", "solve s", "peak MB", "route"))
    for name in ["box", "cylinder", "l_bracket", "wrench", "ring", "half_torus", "wheel", "housing"]:
        d, mb = run(os.path.join(REPO, "samples", "parts", name + ".step"), a.cells)
        if d is None:
            print("%-11s no support face found at the bottom of the bounding box" % name)
            continue
        s, g = d["seconds"], d["grid"]
        route = g.get("method", "?") + (" (shifted grid: %s)" % g["retry_reason"][:70] if g.get("retry_reason") else "")
        print("%-11s %-11s %5d %5d %7d %7.2f %7.2f %8.2f %7.2f %8.0f  %s" % (name, "x".join(map(str, g["cells"])), g["cut_cells"],
              g["subvolumes"], d["dofs"], s["cut"], s["rules"], s["assemble"], s["solve"], mb, route))
        rows.append({"part": name, "grid": g, "dofs": d["dofs"], "seconds": s, "peak_mb": mb})
    json.dump(rows, open(os.path.join(a.out, "simulate_parts.json"), "w"), indent=2)


if __name__ == "__main__":
    main()
