#!/usr/bin/python3
"""Chart of bench_compliance_gradient's (or bench_target_gradient's) output: relative difference
between each route's gradient and the pipeline's central differences, against the step H.
Usage: plot_compliance_gradient.py DIR [NAME]   (reads DIR/NAME.json, writes DIR/NAME.png; NAME
compliance_gradient by default, or target_gradient)"""
import json
import os
import sys

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

out = sys.argv[1]
name = sys.argv[2] if len(sys.argv) > 2 else "compliance_gradient"
rows = json.load(open(os.path.join(out, name + ".json")))
fig, ax = plt.subplots(figsize=(6.4, 5.4))
for row in rows:
    if "relative_difference_adjoint" in row:  # bench_target_gradient: the adjoint route, and linear the exact one
        if "relative_difference_exact" in row:
            line, = ax.loglog(row["steps"], row["relative_difference_exact"], "o-", mfc="none",
                              label=row["entry"] + ": exact")
            ax.loglog(row["steps"], row["relative_difference_adjoint"], "s:", mfc="none", color=line.get_color(),
                      label="semi-analytic")
        else:
            ax.loglog(row["steps"], row["relative_difference_adjoint"], "^--", mfc="none",
                      label=row["entry"] + ": semi-analytic")
        continue
    line, = ax.loglog(row["steps"], row["relative_difference_exact"], "o-", mfc="none", label=row["entry"] + ": exact")
    ax.loglog(row["steps"], row["relative_difference_semi_analytic"], "s:", mfc="none", color=line.get_color(),
              label="semi-analytic")
ax.set_xlabel("central-difference step H [mm]")
ax.set_ylabel("|gradient − FD(H)| / |FD(H)|")
ax.set_title("Turned L-bracket, %s on 10 cells: gradient against the pipeline"
             % ("target (base top face)" if name == "target_gradient" else "compliance"), fontsize=9)
ax.grid(True, which="both", alpha=0.3)
ax.legend(fontsize=6, ncol=2, loc="upper center", bbox_to_anchor=(0.5, -0.14))
fig.tight_layout()
fig.savefig(os.path.join(out, name + ".png"), dpi=120)
