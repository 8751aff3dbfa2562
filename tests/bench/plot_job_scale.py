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
fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4.2))
faces = [r["faces"] for r in rows]
a.loglog(faces, [r["lookup_seconds_scan"] for r in rows], "o-", label="scan: BRepExtrema to every face")
a.loglog(faces, [r["lookup_seconds_locator"] for r in rows], "s-", label="FaceLocator: boxes, nearest first")
a.set_xlabel("faces of the part (one lookup per face, 100 at most)")
a.set_ylabel("median seconds, all lookups")
a.set_title("faces named by points")
params = [r["parameters"] for r in rows]
b.loglog(params, [r["derivative_seconds_dense"] for r in rows], "o-", label="dense: one QR of the whole J")
b.loglog(params, [r["derivative_seconds_grouped"] for r in rows], "s-", label="per coupled group")
b.set_xlabel("shape parameters")
b.set_ylabel("median seconds")
b.set_title("dp\u22a5/dp\u0303 at the start (Eq. 6.29)")
for ax, key, xs in ((a, "lookup_ratio", faces), (b, "derivative_ratio", params)):
    for r, x in zip(rows, xs):
        ax.annotate("%s x%.0f" % (r["part"], r[key]), (x, r[key.replace("ratio", "seconds_") +
                    ("scan" if key == "lookup_ratio" else "dense")]), fontsize=7, xytext=(3, 3),
                    textcoords="offset points")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
fig.tight_layout()
fig.savefig(os.path.join(out, "job_scale.png"), dpi=120)
print("wrote", os.path.join(out, "job_scale.png"))
