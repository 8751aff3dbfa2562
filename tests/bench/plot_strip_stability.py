"""Chart of bench_strip_stability: time per strip of the Jacobi test against the constrained
eigenvalue test (simulation + inertia) at each simulator resolution, log scale.
Usage: plot_strip_stability.py DIR  (reads DIR/strip_stability.json, writes DIR/strip_stability.png)"""
import json
import sys

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt

d = sys.argv[1]
data = json.load(open(d + "/strip_stability.json"))
strips = data["strips"]
names = [s["name"] + (" (U)" if not s["stable"] else "") for s in strips]
x = range(len(strips))
fig, ax = plt.subplots(figsize=(10, 5))
ax.bar([i - 0.3 for i in x], [s["jacobi_ms"] for s in strips], width=0.2,
       label="Jacobi, %d edges" % strips[0]["jacobi_edges"])
edges = [e["edges"] for e in strips[0]["eigen"]]
for k, n in enumerate(edges):
    ax.bar([i - 0.1 + 0.2 * k for i in x], [s["eigen"][k]["total_ms"] for s in strips], width=0.2,
           label="simulation + Hessian inertia, %d edges" % n)
ax.axhline(5.0, color="red", ls="--", lw=1, label="goal 5 ms")
ax.set_yscale("log")
ax.set_xticks(list(x))
ax.set_xticklabels(names, rotation=30, ha="right", fontsize=8)
ax.set_ylabel("time per strip [ms] (median of %d)" % data["repeats"])
ax.legend(fontsize=8)
ax.set_title("Strip stability: Jacobi test vs constrained eigenvalue test ((U): unstable)")
fig.tight_layout()
fig.savefig(d + "/strip_stability.png", dpi=100)
print("wrote", d + "/strip_stability.png")
