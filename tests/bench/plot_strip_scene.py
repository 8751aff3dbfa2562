"""Chart of the 31-strip scene benchmark (thesis §4.8.1, Fig. 4.17): the scene's wall time by
route and by phase, and per strip its R, sample count, design time and simulated deviation.
Usage: /usr/bin/python3 plot_strip_scene.py DIR  (reads DIR/strip_scene.json, writes DIR/strip_scene.png)"""
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

d = sys.argv[1] if len(sys.argv) > 1 else "."
data = json.load(open(os.path.join(d, "strip_scene.json")))
rows = [r for r in data["per_strip"] if r["feasible"]]
idx = [r["index"] for r in rows]

fig, ((ax1, ax2), (ax3, ax4)) = plt.subplots(2, 2, figsize=(11, 7.5))

routes = [("serial loop", data["scene_seconds_median"]),
          ("design_strips\n%d threads" % data["threads"], data["parallel_scene_seconds_median"]),
          ("cold-started\nLPs", data["cold_start_scene_seconds_median"]),
          ("interpolated\nquintics", data["interpolated_scene_seconds_median"])]
ax1.bar([r[0] for r in routes], [1e3 * r[1] for r in routes], color=["C0", "C1", "C2", "C3"])
for k, (_, t) in enumerate(routes):
    ax1.annotate("%.1f" % (1e3 * t), (k, 1e3 * t), ha="center", va="bottom", fontsize=8)
ax1.axhline(30, color="red", lw=0.8, alpha=0.6, label="goal 30 ms")
ax1.set_ylabel("scene wall time [ms] (median of %d)" % data["repeats"])
ax1.set_title("Whole scene (%d strips, gravity)" % data["strips"])
ax1.legend(fontsize=8)
ax1.tick_params(axis="x", labelsize=8)

phases = data["phases_seconds_median"]
ax2.barh(list(phases.keys()), [1e3 * v for v in phases.values()], color="C0")
ax2.set_xlabel("time per phase over the scene [ms] (median)")
ax2.set_title("Phases (serial loop)")
ax2.invert_yaxis()

ax3.plot(idx, [r["R"] for r in rows], "o-", ms=3, label="R (gravity LP, Eq. 4.6)")
ax3.set_xlabel("strip index (rotation −0.35 … 0.35 rad)")
ax3.set_ylabel("R")
ax3b = ax3.twinx()
ax3b.plot(idx, [r["samples"] for r in rows], "s:", ms=3, color="C1", label="samples")
ax3b.set_ylabel("LP samples", color="C1")
ax3.set_title("Per strip: R and sample count")
ax3.grid(True, alpha=0.3)
ax3.legend(loc="upper left", fontsize=8)

ax4.semilogy(idx, [1e3 * r["total_seconds"] for r in rows], "o-", ms=3, label="design time [ms]")
ax4.semilogy(idx, [max(r["deviation"], 1e-16) for r in rows], "s--", ms=3,
             label="simulated deviation / length")
ax4.set_xlabel("strip index")
ax4.set_title("Per strip: time and simulated deviation")
ax4.grid(True, which="both", alpha=0.3)
ax4.legend(fontsize=8)

fig.suptitle("Strip scene benchmark: %d/%d feasible, worst deviation %.2g" %
             (data["feasible"], data["strips"], data["worst_deviation"]), fontsize=10)
fig.tight_layout()
out = os.path.join(d, "strip_scene.png")
fig.savefig(out, dpi=110)
print("wrote", out)
