"""PNG charts of strip results: K(s), w(s) and the flat outline (Debian's matplotlib).
Usage: /usr/bin/python3 plot_strips.py DIR   (reads DIR/*.result.json, writes DIR/*.png)"""
import glob
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

for path in sorted(glob.glob(os.path.join(sys.argv[1], "*.result.json"))):
    r = json.load(open(path))
    name = os.path.basename(path)[: -len(".result.json")]
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.6))
    pts = r["points"] if r["feasible"] else r["bspline"]["poles"]
    ax = axes[0]
    ax.plot([p[0] for p in pts], [p[1] for p in pts], "-" if r["feasible"] else "o--", lw=1.5)
    for z in r["inflections"]:
        ax.plot(*z["point"], "rx")
    ax.set_aspect("equal")
    ax.set_title("curve [m]" + ("" if r["feasible"] else " (control polygon)"), fontsize=9)
    if r["feasible"]:
        axes[1].plot(r["s"], r["K"], label="K / min K")
        axes[1].set_xlabel("s [m]")
        axes[1].set_title("stiffness, R = %.4f" % r["R"], fontsize=9)
        outline = r["outline"] + r["outline"][:1]
        axes[2].fill([p[0] * 1e3 for p in outline], [p[1] * 1e3 for p in outline], alpha=0.6)
        axes[2].set_aspect("equal")
        axes[2].set_xlabel("s [mm]")
        axes[2].set_title("flat strip outline [mm] (width %.1f–%.1f mm)"
                          % (min(r["width"]) * 1e3, max(r["width"]) * 1e3), fontsize=9)
    else:
        for ax in axes[1:]:
            ax.axis("off")
        axes[1].text(0, 0.5, "infeasible:\n" + "\n".join(r["reason"][i:i + 60] for i in range(0, len(r["reason"]), 60)),
                     fontsize=9, va="center")
    fig.suptitle(name, fontsize=10)
    fig.tight_layout()
    fig.savefig(path.replace(".result.json", ".png"), dpi=100)
    plt.close(fig)
    print("wrote", path.replace(".result.json", ".png"))
