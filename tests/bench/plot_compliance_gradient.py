#!/usr/bin/python3
"""Chart of bench_compliance_gradient's output: relative difference between each route's
compliance gradient and the pipeline's central differences, against the step H.
Usage: plot_compliance_gradient.py DIR   (reads DIR/compliance_gradient.json, writes DIR/compliance_gradient.png)"""
import json
import os
import sys

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

out = sys.argv[1]
rows = json.load(open(os.path.join(out, "compliance_gradient.json")))
fig, ax = plt.subplots(figsize=(6.4, 4.4))
for row in rows:
    line, = ax.loglog(row["steps"], row["relative_difference_exact"], "o-", mfc="none", label=row["entry"] + ": exact")
    ax.loglog(row["steps"], row["relative_difference_semi_analytic"], "s:", mfc="none", color=line.get_color(),
              label="semi-analytic")
ax.set_xlabel("central-difference step H [mm]")
ax.set_ylabel("|gradient − FD(H)| / |FD(H)|")
ax.set_title("Turned L-bracket, compliance on 10 cells: gradient routes against the pipeline", fontsize=9)
ax.grid(True, which="both", alpha=0.3)
ax.legend(fontsize=6, ncol=2)
fig.tight_layout()
fig.savefig(os.path.join(out, "compliance_gradient.png"), dpi=120)
