"""Chart of the fabricability benchmark (flower-pot set, thesis §4.8.2): R reached against time
per curve, and time beside shape change per curve.
Usage: /usr/bin/python3 plot_strip_improve.py DIR  (reads DIR/strip_improve.json, writes DIR/strip_improve.png)"""
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

d = sys.argv[1] if len(sys.argv) > 1 else "."
data = json.load(open(os.path.join(d, "strip_improve.json")))
curves = data["curves"]
fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.4))
for c in curves:
    t = [h["seconds"] * 1e3 for h in c["history"]]
    R = [h["R"] for h in c["history"]]
    ax1.semilogy(t, R, "-", lw=1, label="curve %d" % c["index"])
ax1.axhline(data["target_R"], color="red", lw=0.8, ls="--", label="target R = %.1f" % data["target_R"])
ax1.set_xlabel("time [ms] (one run)")
ax1.set_ylabel("R of the current line on the samples")
ax1.set_title("R reached against time (total %.2f s, thesis 13 s)" % data["total_seconds"])
ax1.grid(True, which="both", alpha=0.3)
ax1.legend(fontsize=6, ncol=2)
idx = [c["index"] for c in curves]
ax2.bar([i - 0.2 for i in idx], [c["seconds"] * 1e3 for c in curves], width=0.4, label="time [ms] (median)")
ax2.set_xlabel("curve")
ax2.set_ylabel("time [ms]")
ax2.axhline(250, color="red", lw=0.8, ls="--")
ax3 = ax2.twinx()
ax3.bar([i + 0.2 for i in idx], [c["deviation_relative"] * 100 for c in curves], width=0.4, color="C2",
        label="deviation [% of length]")
ax3.set_ylabel("curve deviation [% of length]")
ax2.set_title("Time and shape change per curve (R₀ %.0f–%.0f)" %
              (min(c["R_initial"] for c in curves), max(c["R_initial"] for c in curves)))
h1, l1 = ax2.get_legend_handles_labels()
h2, l2 = ax3.get_legend_handles_labels()
ax2.legend(h1 + h2, l1 + l2, fontsize=8)
fig.tight_layout()
out = os.path.join(d, "strip_improve.png")
fig.savefig(out, dpi=110)
print("wrote", out)
