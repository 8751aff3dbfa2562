"""Chart of the stability-recovery benchmark (Algorithm 4.2): σ/l of the margin state against
time per curve, and the median time per curve beside the goal.
Usage: /usr/bin/python3 plot_strip_stabilize.py DIR  (reads DIR/strip_stabilize.json, writes DIR/strip_stabilize.png)"""
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

d = sys.argv[1] if len(sys.argv) > 1 else "."
data = json.load(open(os.path.join(d, "strip_stabilize.json")))
curves = [c for c in data["curves"] if not c["stable_before"]]
fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.4))
for c in curves:
    h = [x for x in c["history"] if x["sigma_margin"] is not None]
    ax1.plot([x["seconds"] * 1e3 for x in h], [x["sigma_margin"] for x in h], ".-", lw=1,
             label="curve %d (A/c %.1f, end 2pi+%.1f)" % (c["index"], c["amplitude"], c["end"]))
ax1.axhline(1.0, color="red", lw=0.8, ls="--", label="sigma = l")
ax1.set_xlabel("time [ms] (one run)")
ax1.set_ylabel("sigma / l (force x 1.05)")
ax1.set_title("Conjugate point pushed out of (0, l]")
ax1.grid(True, alpha=0.3)
ax1.legend(fontsize=6)
idx = [c["index"] for c in curves]
ax2.bar(idx, [c["seconds"] * 1e3 for c in curves], width=0.6, label="stabilize_strip (median; green: stable, grey: stalled on R_max)",
        color=["#2a9d4b" if c["done"] else "#999999" for c in curves])
ax2.axhline(data["goal_seconds"] * 1e3, color="red", lw=0.8, ls="--", label="goal 250 ms")
ax2.set_xlabel("curve")
ax2.set_ylabel("time [ms]")
ax2.set_title("median %.0f ms, max %.0f ms per curve" % (1e3 * data["median_seconds"], 1e3 * data["max_seconds"]))
ax2.legend(fontsize=8)
ax2.grid(True, alpha=0.3)
fig.tight_layout()
fig.savefig(os.path.join(d, "strip_stabilize.png"), dpi=100)
