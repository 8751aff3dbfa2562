"""Chart of the strip LP benchmark: accuracy against time, and time against samples.
Usage: /usr/bin/python3 plot_strip_lp.py DIR  (reads DIR/strip_lp.json, writes DIR/strip_lp.png)"""
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

d = sys.argv[1] if len(sys.argv) > 1 else "."
data = json.load(open(os.path.join(d, "strip_lp.json")))
rows = data["rows"]
n = [r["samples"] for r in rows]
dual = [r["dual_seconds"] * 1e3 for r in rows]
dense = [r["dense_seconds"] * 1e3 for r in rows]
prim = [(r["samples"], r["primal_seconds"] * 1e3, r["R_relative_error"]) for r in rows if r["primal_seconds"]]
err = [max(r["R_relative_error"], 1e-16) for r in rows]

fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
ax1.loglog(dense, err, "D-", label="dense dual simplex (default)")
ax1.loglog(dual, err, "o-", label="dual form (Clp, 4 rows)")
ax1.loglog([p[1] for p in prim], [max(p[2], 1e-16) for p in prim], "s--", label="row-wise primal (Clp)")
for x, y, k in zip(dense, err, n):
    ax1.annotate(str(k), (x, y), textcoords="offset points", xytext=(4, 4), fontsize=7)
ad = data.get("adaptive", [])
if ad:
    ax1.loglog([a["seconds"] * 1e3 for a in ad], [max(a["R_relative_error"], 1e-16) for a in ad], "^:",
               label="adaptive design (tolerance → samples)")
ax1.set_xlabel("time [ms] (median)")
ax1.set_ylabel("relative error of R")
ax1.set_title("Accuracy against time")
ax1.grid(True, which="both", alpha=0.3)
ax1.legend(fontsize=8)

ax2.loglog(n, dense, "D-", label="dense dual simplex")
ax2.loglog(n, dual, "o-", label="dual form (Clp)")
ax2.loglog([p[0] for p in prim], [p[1] for p in prim], "s--", label="row-wise primal")
ax2.loglog(n, [dense[0] * k / n[0] for k in n], ":", color="gray", label="linear growth")
ax2.axhline(1.0, color="red", lw=0.8, alpha=0.5)
ax2.set_xlabel("samples")
ax2.set_ylabel("LP time [ms] (median)")
ax2.set_title("Time against samples")
ax2.grid(True, which="both", alpha=0.3)
ax2.legend(fontsize=8)
fig.suptitle("Strip LP, Eq. 4.4 (elliptic arc, reference R = %.12f)" % data["reference_R"], fontsize=10)
fig.tight_layout()
out = os.path.join(d, "strip_lp.png")
fig.savefig(out, dpi=110)
print("wrote", out)
