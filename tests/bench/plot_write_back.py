"""Chart of bench_write_back: median seconds per B-rep write-back against the part's face count,
without a self-interference test, with the face-pair test and with the full test it replaced.
Usage: /usr/bin/python3 plot_write_back.py DIR   (reads DIR/write_back.json, writes DIR/write_back.png)"""
import json
import os
import sys

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

out = sys.argv[1]
with open(os.path.join(out, "write_back.json")) as f:
    rows = sorted(json.load(f), key=lambda r: r["faces"])
fig, ax = plt.subplots(figsize=(6.4, 4.2))
faces = [r["faces"] for r in rows]
ax.plot(faces, [1e3 * r["seconds_without"] for r in rows], "o-", label="write-back + BRepCheck_Analyzer")
ax.plot(faces, [1e3 * r["seconds_with"] for r in rows], "s-", label="+ face-pair self-interference test")
ax.plot(faces, [1e3 * r["seconds_full"] for r in rows], "^--", label="+ full test (BOPAlgo_ArgumentAnalyzer)")
for r in rows:
    ax.annotate("%s x%.1f / x%.1f" % (r["part"], r["ratio"], r["ratio_full"]), (r["faces"], 1e3 * r["seconds_full"]),
                fontsize=7, xytext=(3, 3), textcoords="offset points")
ax.set_xscale("log"), ax.set_yscale("log")
ax.set_xlabel("faces of the part")
ax.set_ylabel("median ms per write-back")
ax.set_title("B-rep write-back, every radius (bridge: plane offset) +0.05 mm")
ax.grid(alpha=0.3)
ax.legend()
fig.tight_layout()
fig.savefig(os.path.join(out, "write_back.png"), dpi=120)
print("wrote", os.path.join(out, "write_back.png"))
