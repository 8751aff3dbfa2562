"""Chart of bench_piece_changes: |relative compliance jump| where a cut cell's pieces change,
against the position along each design line, with what a continuous objective would move over
the bisection interval; refused bisections marked on the axis.
Usage: /usr/bin/python3 plot_piece_changes.py DIR   (reads DIR/piece_changes.json, writes DIR/piece_changes.png)"""
import json
import os
import sys

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

out = sys.argv[1]
with open(os.path.join(out, "piece_changes.json")) as f:
    rows = json.load(f)
entries = list(dict.fromkeys(r["entry"] for r in rows))
fig, ax = plt.subplots(figsize=(7.0, 4.2))
for k, name in enumerate(entries):
    ok = [r for r in rows if r["entry"] == name and "relative_jump" in r]
    bad = [r for r in rows if r["entry"] == name and "relative_jump" not in r]
    color = "C%d" % k
    if ok:
        ax.semilogy([r["at"] for r in ok], [abs(r["relative_jump"]) for r in ok], "o", color=color, label=name + ": jump")
        ax.semilogy([r["at"] for r in ok], [r["relative_slope_times_interval"] for r in ok], "_", color=color, ms=12)
    if bad:
        ax.semilogy([r["near"] for r in bad], [1e-11] * len(bad), "x", color=color,
                    label=name + ": bisection met a refused cut")
ax.set_xlabel("design entry change [mm]")
ax.set_ylabel("|ΔC| / C at the change (— : slope × interval)")
ax.set_title("Turned L-bracket: compliance jumps where cells' pieces change")
ax.grid(alpha=0.3, which="both")
ax.legend(fontsize=7)
fig.tight_layout()
fig.savefig(os.path.join(out, "piece_changes.png"), dpi=120)
print("wrote", os.path.join(out, "piece_changes.png"))
