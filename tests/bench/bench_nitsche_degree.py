"""What the patch rules on curved clamped faces cost (LinearXfemOptions::dirichlet_surface_degree,
job key "nitsche_surface_degree"; default 8 since 2026-12-02, 5 before): the wheel sample held
at its hub hole (a cylinder), 2 kN on the rim, aluminium, hex8, one thread, `parafab simulate`
at degrees 5, 8 and 12 on 16 and 24 cells. Medians over repeats (the degrees interleaved),
assembly and wall time as ratios against degree 5 in the same run. What the degree buys is the
shape gradient's agreement with the solver on curved supports, measured by
ShapeCompliance.ASupportsOwnMotionHasAnExactGradient (optimization.md, "A support's own motion"); the
compliance is printed to show how little the solution itself moves.
Usage: /usr/bin/python3 tests/bench/bench_nitsche_degree.py [--repeats N] [--out DIR]"""
import argparse
import json
import os
import statistics
import subprocess
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, "..", ".."))
CLI = os.environ.get("PARAFAB_CLI", os.path.join(REPO, "build", "workbench", "entry", "parafab"))
WHEEL = os.path.join(REPO, "samples", "parts", "wheel.step")

ap = argparse.ArgumentParser()
ap.add_argument("--repeats", type=int, default=5)
ap.add_argument("--degrees", type=int, nargs="+", default=[5, 8, 12])
ap.add_argument("--cells", type=int, nargs="+", default=[16, 24])
ap.add_argument("--out", default=".")
args = ap.parse_args()

faces = json.loads(subprocess.run([CLI, "inspect", WHEEL], capture_output=True, text=True, check=True).stdout)["faces"]
hub = next(f["index"] for f in faces if f["type"] == "cylinder" and abs(f["parameters"]["r"] - 5) < 1e-6)
rim = next(f["index"] for f in faces if f["type"] == "cylinder" and abs(f["parameters"]["r"] - 50) < 1e-6)

rows = []
for cells in args.cells:
    runs = {d: [] for d in args.degrees}
    for rep in range(args.repeats):
        for d in (args.degrees if rep % 2 == 0 else list(reversed(args.degrees))):
            job = {"material": {"E": 70000, "nu": 0.33, "density": 2.7e-6}, "element": "hex8", "threads": 1,
                   "grid": {"cells": cells}, "nitsche_surface_degree": d,
                   "supports": [{"face": hub}], "loads": [{"face": rim, "force": [0, -2000, 0]}]}
            with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
                json.dump(job, f)
            t = time.perf_counter()
            p = subprocess.run(["taskset", "-c", "0", CLI, "simulate", WHEEL, f.name], capture_output=True, text=True)
            wall = time.perf_counter() - t
            os.unlink(f.name)
            if p.returncode != 0:
                raise SystemExit("simulate failed at degree %d, %d cells: %s" % (d, cells, p.stdout or p.stderr))
            r = json.loads(p.stdout)
            runs[d].append({"wall": wall, "assemble": r["seconds"]["assemble"], "compliance": -2 * r["potential"]})
    base = runs[args.degrees[0]]
    a0 = statistics.median(x["assemble"] for x in base)
    w0 = statistics.median(x["wall"] for x in base)
    c0 = base[0]["compliance"]
    for d in args.degrees:
        a = statistics.median(x["assemble"] for x in runs[d])
        w = statistics.median(x["wall"] for x in runs[d])
        row = {"cells": cells, "degree": d, "assemble_median_s": a, "wall_median_s": w,
               "assemble_ratio": a / a0, "wall_ratio": w / w0, "compliance": runs[d][0]["compliance"],
               "compliance_change_vs_first": runs[d][0]["compliance"] / c0 - 1}
        rows.append(row)
        print("%2d cells, degree %2d: assembly %.4f s (x%.2f), wall %.3f s (x%.2f), compliance %.9g (%+.2e)" % (
            cells, d, a, a / a0, w, w / w0, row["compliance"], row["compliance_change_vs_first"]))

os.makedirs(args.out, exist_ok=True)
with open(os.path.join(args.out, "nitsche_degree.json"), "w") as f:
    json.dump({"part": "wheel", "support": "hub hole (cylinder)", "element": "hex8", "threads": 1,
               "repeats": args.repeats, "rows": rows}, f, indent=2)

import matplotlib  # noqa: E402
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

fig, ax = plt.subplots(figsize=(5.5, 3.6))
for cells in args.cells:
    rs = [r for r in rows if r["cells"] == cells]
    ax.plot([r["degree"] for r in rs], [r["assemble_ratio"] for r in rs], "o-", label="assembly, %d cells" % cells)
    ax.plot([r["degree"] for r in rs], [r["wall_ratio"] for r in rs], "s--", label="simulate wall, %d cells" % cells)
ax.set_xlabel("patch rule degree on the clamped hub hole")
ax.set_ylabel("time / time at degree %d" % args.degrees[0])
ax.set_title("wheel, hex8, one thread (medians of %d)" % args.repeats)
ax.grid(alpha=0.3)
ax.legend(fontsize=8)
fig.tight_layout()
fig.savefig(os.path.join(args.out, "nitsche_degree.png"), dpi=120)
print("wrote", os.path.join(args.out, "nitsche_degree.json"), "and nitsche_degree.png")
