"""The size estimate before a run against what the run then has, on the eight sample parts
(hex8 on 16 / 32 / 48 cells, hex27 on 8 / 16 / 24; linear, gravity, the bottom face fixed):
estimated / solved unknowns, the fill constant C = factor bytes / (8 n^(4/3)) of CHOLMOD's exact
factor (result `solver.factor_mb`), and the estimate's peak figures (`peak_mb_min`, `peak_mb`)
over the CLI's peak resident memory (/usr/bin/time). The figures of tests/bench/README.md, "Size estimate against
measured runs" (the estimate: resources/doc/simulation.md, "Estimate first").

Usage: /usr/bin/python3 tests/bench/bench_estimate.py [--out DIR]   (about 3 min)
"""
import argparse
import json
import os
import subprocess
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, "..", ".."))
CLI = os.environ.get("PARAFAB_CLI", os.path.join(REPO, "build", "workbench", "entry", "parafab"))
PARTS = ["box", "cylinder", "l_bracket", "wrench", "ring", "half_torus", "wheel", "housing"]
GRIDS = [("hex8", 16), ("hex8", 32), ("hex8", 48), ("hex27", 8), ("hex27", 16), ("hex27", 24)]


def run(part, element, cells):
    """The result JSON and the peak MB of one CLI run, or (None, 0) when no bottom support works."""
    info = json.loads(subprocess.run([CLI, "inspect", part], capture_output=True, text=True, check=True).stdout)
    lo, hi = info["bbox"]["min"], info["bbox"]["max"]
    job = {"material": {"E": 210000, "nu": 0.3, "density": 7.85e-9}, "element": element, "grid": {"cells": cells},
           "gravity": [0, 0, -9810]}
    for point in ([0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), lo[2]], [lo[0], 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])]):
        job["supports"] = [{"point": point}]
        with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
            json.dump(job, f)
        try:
            p = subprocess.run(["/usr/bin/time", "-f", "%M", CLI, "simulate", part, f.name], capture_output=True, text=True)
        finally:
            os.unlink(f.name)
        if p.returncode == 0:
            return json.loads(p.stdout), int(p.stderr.strip().splitlines()[-1]) / 1024.0
    return None, 0.0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=os.path.join(REPO, "out", "bench"))
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    rows = []
    print("%-10s %-5s %5s %8s %9s %6s %8s %8s %13s" % ("part", "elem", "cells", "unknowns", "est/solved", "C",
                                                      "peak MB", "factor", "est peak/peak"))
    for name in PARTS:
        for element, cells in GRIDS:
            r, peak = run(os.path.join(REPO, "samples", "parts", name + ".step"), element, cells)
            if r is None:
                print("%-10s %-5s %5d  no support face found at the bottom of the bounding box" % (name, element, cells))
                continue
            n, est = r["dofs"], r["estimate"]
            C = r["solver"]["factor_mb"] * 1e6 / (8 * n ** (4 / 3))
            row = {"part": name, "element": element, "cells": cells, "unknowns": n, "peak_mb": peak,
                   "factor_mb": r["solver"]["factor_mb"], "C": C, "estimate": est,
                   "unknowns_ratio": est["unknowns"] / n, "peak_min_ratio": est["peak_mb_min"] / peak,
                   "peak_ratio": est["peak_mb"] / peak}
            rows.append(row)
            print("%-10s %-5s %5d %8d %9.2f %6.1f %8.0f %8.1f %6.2f-%.2f" % (
                name, element, cells, n, row["unknowns_ratio"], C, peak, row["factor_mb"], row["peak_min_ratio"],
                row["peak_ratio"]), flush=True)
    span = lambda key: (min(r[key] for r in rows), max(r[key] for r in rows))
    print("estimated / solved unknowns %.2f-%.2f; C %.1f-%.1f; peak_mb / peak %.2f-%.2f; peak_mb_min / peak %.2f-%.2f"
          % (span("unknowns_ratio") + span("C") + span("peak_ratio") + span("peak_min_ratio")))
    json.dump(rows, open(os.path.join(a.out, "estimate.json"), "w"), indent=2)


if __name__ == "__main__":
    main()
