"""Chart of the cut-cell benchmark: per-cell error against time per cell, linear against
parabolic boundary segments, for several grids (cf. thesis Fig. 6.13).
Usage: /usr/bin/python3 plot_cut_cells.py DIR  (reads DIR/cut_cells.json, writes DIR/cut_cells.png)"""
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

d = sys.argv[1] if len(sys.argv) > 1 else "."
data = json.load(open(os.path.join(d, "cut_cells.json")))
fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.5))
groups = {}
for r in data["sweep"]:
    groups.setdefault((r["part"], r["cells"], r["order"]), []).append(r)
for (part, cells, order), rows in sorted(groups.items()):
    rows.sort(key=lambda r: -r["segment_tolerance"])  # along the sweep: coarse to fine
    style = "o-" if order == 2 else "s--"
    label = "%s, %d cells, %s" % (part, cells, "parabolic" if order == 2 else "linear")
    ax1.loglog([r["seconds_per_cell"] * 1e3 for r in rows], [max(r["max"], 1e-17) for r in rows], style, label=label, ms=4)
ax1.set_xlabel("time per cut cell [ms] (cut + rules)")
ax1.set_ylabel("max error / cell volume (monomials ≤ degree 2)")
ax1.set_title("Accuracy against time (segment tolerance 1e-2 → 1e-10)")
ax1.grid(True, which="both", alpha=0.3)
ax1.legend(fontsize=6)
parts = data["parts"]
x = range(len(parts))
w = 0.2
ax2.bar([i - 1.5 * w for i in x], [p["face"]["cut_seconds_per_cell"] * 1e3 for p in parts], w, label="cut by face, per cell")
ax2.bar([i - 0.5 * w for i in x], [p["splitter"]["cut_seconds_per_cell"] * 1e3 for p in parts], w, label="cut by OCCT splitter, per cell")
ax2.bar([i + 0.5 * w for i in x], [p["face"]["rules_seconds_per_cell"] * 1e3 for p in parts], w, label="moment-fitted rules, per cell")
ax2.bar([i + 1.5 * w for i in x], [p["boolean_seconds_per_cell"] * 1e3 for p in parts], w, label="OCCT Boolean + GProp per cell")
ax2.set_xticks(list(x))
ax2.set_xticklabels([p["part"] + (" *" if p["face"]["fell_back"] else "") for p in parts], rotation=30, fontsize=8)
ax2.set_ylabel("ms per cut cell (median over %d repeats)" % data.get("repeats", 1))
ax2.set_yscale("log")
ax2.set_title("Time per cell, %d cells along the longest side (* face route fell back)" % data["cells_longest"])
ax2.legend(fontsize=7)
a = data["all"]
fig.suptitle("Cut-cell quadrature vs OCCT Boolean per cell over %d cells: face route %.1f× faster (median error %.1e, "
             "max %.1e), splitter route %.1f× (median %.1e, max %.1e)"
             % (a["cells"], a["face"]["speedup"], a["face"]["median"], a["face"]["max"],
                a["splitter"]["speedup"], a["splitter"]["median"], a["splitter"]["max"]), fontsize=9)
fig.tight_layout()
out = os.path.join(d, "cut_cells.png")
fig.savefig(out, dpi=110)
print("wrote", out)
