#!/usr/bin/python3
"""Chart of bench_shape_gradient: max relative error of the exact mass-property shape
derivatives against central FD of OCCT mass properties, per FD step. Usage: DIR"""
import json
import math
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

d = sys.argv[1]
rows = json.load(open(d + "/shape_gradient.json"))
fig, ax = plt.subplots(figsize=(6, 4))
for r in rows:
    pts = [(h, e) for h, e in zip(r["steps"], r["max_relative_error"]) if e is not None and not math.isnan(e) and e > 0]
    if pts:
        ax.loglog(*zip(*pts), "o-", label="%s: %s" % (r["part"], r["parameter"]))
ax.axhline(1e-4, color="gray", ls="--", lw=1, label="1e-4 (test bound)")
ax.set_xlabel("central FD step")
ax.set_ylabel("max relative error, 10 moments")
ax.set_title("Hadamard shape derivatives vs FD of OCCT mass properties")
ax.grid(True, which="both", alpha=0.3)
ax.legend(fontsize=7)
fig.tight_layout()
fig.savefig(d + "/shape_gradient.png", dpi=110)
