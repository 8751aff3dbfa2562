"""Chart of bench_job_scale: median seconds of the face lookup (every face's centroid) and of
dp/dp~ at the start, each against the algorithm it replaced, over the parts' size.
Usage: /usr/bin/python3 plot_job_scale.py DIR   (reads DIR/job_scale.json, writes DIR/job_scale.png)"""
import json
import os
import sys

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

out = sys.argv[1]
with open(os.path.join(out, "job_scale.json")) as f:
    rows = sorted(json.load(f), key=lambda r: r["faces"])
# Per panel: x key, x label, title, (baseline key, label), (new key, label), ratio key.
PANELS = [("faces", "faces of the part (one lookup per face, 100 at most)", "faces named by points",
           ("lookup_seconds_scan", "scan: BRepExtrema to every face"),
           ("lookup_seconds_locator", "FaceLocator: boxes, nearest first"), "lookup_ratio"),
          ("parameters", "shape parameters", "dp\u22a5/dp\u0303 at the start (Eq. 6.29)",
           ("derivative_seconds_dense", "dense: one QR of the whole J"),
           ("derivative_seconds_grouped", "per coupled group"), "derivative_ratio")]
fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
for ax, (xkey, xlabel, title, (old, old_label), (new, new_label), ratio) in zip(axes, PANELS):
    xs = [r[xkey] for r in rows]
    ax.loglog(xs, [r[old] for r in rows], "o-", label=old_label)
    ax.loglog(xs, [r[new] for r in rows], "s-", label=new_label)
    for r, x in zip(rows, xs):
        ax.annotate("%s x%.0f" % (r["part"], r[ratio]), (x, r[old]), fontsize=7, xytext=(3, 3),
                    textcoords="offset points")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("median seconds")
    ax.set_title(title)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
fig.tight_layout()
fig.savefig(os.path.join(out, "job_scale.png"), dpi=120)
print("wrote", os.path.join(out, "job_scale.png"))
