"""Chart of the rod design benchmark: time per stage and deviation against samples.
Usage: /usr/bin/python3 plot_rod.py DIR  (reads DIR/rod.json, writes DIR/rod.png)"""
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

d = sys.argv[1] if len(sys.argv) > 1 else "."
data = json.load(open(os.path.join(d, "rod.json")))
fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
for c in data["curves"]:
    rows = c["rows"]
    n = [r["samples"] for r in rows]
    k = c["segment"]
    ax1.loglog(n, [r["total_seconds"] * 1e3 for r in rows], "o-", label=f"segment {k}: total")
    ax1.loglog(n, [r["lp_seconds"] * 1e3 for r in rows], "s--", label=f"segment {k}: LP")
    ax1.loglog(n, [r["dead_load_seconds"] * 1e3 for r in rows], "^:", label=f"segment {k}: dead load")
    ax2.loglog(n, [r["deviation_over_length"] for r in rows], "o-", label=f"segment {k}")
    ax2.loglog(n, [r["deviation_over_length_inextensible"] for r in rows], "s--",
               label=f"segment {k}, inextensible")
ax1.axhline(data["goal_seconds_at_400"] * 1e3, color="gray", lw=0.8)
ax1.set_xlabel("samples")
ax1.set_ylabel("time [ms] (median)")
ax1.legend(fontsize=6)
ax2.set_xlabel("samples")
ax2.set_ylabel("max deviation / length (simulation with gravity)")
ax2.legend(fontsize=6)
fig.suptitle(data["curve"], fontsize=9)
fig.tight_layout()
out = os.path.join(d, "rod.png")
fig.savefig(out, dpi=120)
print("wrote", out)
