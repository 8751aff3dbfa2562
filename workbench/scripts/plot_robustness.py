"""Chart of a strip robustness study (thesis §4.7.2, Fig. 4.15): for each design result that
carries "robustness" (request field "robustness": true or {...}), one column: the curve with
its curvature normals, the stiffness profile K(s), one row per defect with the target (dashed)
and the simulated strips (light: smaller / closing / top 25 %, dark: larger / opening /
top 50 %), and the deviation of every case from the target as bars, with the baseline and the
1e-3 goal as lines. Cases whose simulation did not converge are hatched / dotted (their
curve and deviation are those of the last continuation step).

Usage: /usr/bin/python3 plot_robustness.py RESULT.json [RESULT2.json ...] OUT.png
(a RESULT file may also hold a JSON list of results; Debian's matplotlib, headless)."""
import json
import math
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

GROUPS = [("stiffness_range", "stiffness\nrange ±", "Greens"), ("gravity", "weight ±", "Blues"),
          ("end_angles", "clamp\nangles ±", "Oranges"), ("plastic", "plastic\ntop", "Purples")]


def load(paths):
    results = []
    for p in paths:
        d = json.load(open(p))
        for r in d if isinstance(d, list) else [d]:
            if not r.get("robustness"):
                raise SystemExit("%s: no \"robustness\" in the result (request it with \"robustness\": true)" % p)
            results.append(r)
    return results


def label(c):
    v = c["value"]
    if c["parameter"] in ("stiffness_range", "gravity"):
        return "%+d %%" % round(100 * v)
    if c["parameter"] == "end_angles":
        return "%s %g°" % ("opened" if v > 0 else "closed", abs(v))
    return "%d %%" % round(100 * v)


def plot(results, png):
    n = len(results)
    rows = 3 + len(GROUPS)
    fig, axes = plt.subplots(rows, n, figsize=(4.6 * n, 3.0 * rows), squeeze=False,
                             gridspec_kw={"height_ratios": [1.1, 0.8] + [1.0] * len(GROUPS) + [1.3]})
    for j, r in enumerate(results):
        rb = r["robustness"]
        name = r.get("name", "strip %d" % (j + 1))
        ax = axes[0][j]
        pts = r["points"]
        xs, ys = [p[0] for p in pts], [p[1] for p in pts]
        ax.plot(xs, ys, "k-", lw=1.5)
        # curvature normals (comb), scaled to 15 % of the length at the largest |κ|
        kmax = max(abs(k) for k in r["curvature"]) or 1.0
        step = max(1, len(pts) // 60)
        for i in range(0, len(pts), step):
            if i + 1 < len(pts):
                tx, ty = xs[i + 1] - xs[i], ys[i + 1] - ys[i]
            else:
                tx, ty = xs[i] - xs[i - 1], ys[i] - ys[i - 1]
            t = math.hypot(tx, ty) or 1.0
            a = 0.15 * r["length"] * r["curvature"][i] / kmax
            ax.plot([xs[i], xs[i] - a * ty / t], [ys[i], ys[i] + a * tx / t], "-", color="tab:red", lw=0.5)
        for z in r["inflections"]:
            ax.plot(*z["point"], "bx")
        ax.set_aspect("equal")
        ax.set_title("%s\nR = %.3f, length %.3f m" % (name, r["R"], r["length"]), fontsize=9)
        ax = axes[1][j]
        ax.plot(r["s"], r["K"], "k-")
        ax.set_xlabel("s [m]")
        ax.set_ylabel("K / min K")
        ax.set_title("stiffness profile", fontsize=9)
        for g, (key, title, cmap) in enumerate(GROUPS):
            ax = axes[2 + g][j]
            cases = sorted((c for c in rb["cases"] if c["parameter"] == key), key=lambda c: c["value"])
            ax.plot(xs, ys, "k--", lw=1.0, label="target")
            colors = plt.get_cmap(cmap)([0.45 + 0.45 * k / max(1, len(cases) - 1) for k in range(len(cases))])
            for c, col in zip(cases, colors):
                if c.get("nodes"):
                    ax.plot([p[0] for p in c["nodes"]], [p[1] for p in c["nodes"]], "-" if c["converged"] else ":",
                            color=col, lw=1.5, label="%s (%.1e)" % (label(c), c["deviation"]))
            ax.set_aspect("equal", adjustable="datalim")
            ax.set_title(title.replace("\n", " ").replace(" ±", "") + ("" if cases else ": no case (no gravity)"),
                         fontsize=9)
            if cases:
                ax.legend(fontsize=6, loc="best")
        ax = axes[-1][j]
        x, ticks, tick_labels = 0.0, [], []
        for key, title, cmap in GROUPS:
            cases = [c for c in rb["cases"] if c["parameter"] == key]
            if not cases:
                continue
            cases.sort(key=lambda c: c["value"])
            colors = plt.get_cmap(cmap)([0.45 + 0.45 * k / max(1, len(cases) - 1) for k in range(len(cases))])
            for c, col in zip(cases, colors):
                dev = c["deviation"] if c["deviation"] is not None else float("nan")
                ax.bar(x, max(dev, 1e-12), color=col, edgecolor="k", lw=0.5,
                       hatch=None if c["converged"] else "//")
                ax.text(x, max(dev, 1e-12) * 1.15, "%.1e" % dev, ha="center", fontsize=6, rotation=90)
                ticks.append(x)
                tick_labels.append(title.replace("±", "") + "\n" + label(c) if c is cases[0] else label(c))
                x += 1
            x += 0.6
        ax.set_yscale("log")
        devs = [c["deviation"] for c in rb["cases"] if c["deviation"]] + ([rb["baseline"]] if rb["baseline"] else [])
        ax.set_ylim(min(devs) / 3, max(devs) * 6)  # the baseline line, and room for the value labels
        if rb["baseline"]:
            ax.axhline(rb["baseline"], color="gray", ls="--", lw=0.8, label="baseline %.1e" % rb["baseline"])
        ax.axhline(1e-3, color="red", lw=0.8, alpha=0.6, label="1e-3")
        ax.set_xticks(ticks)
        ax.set_xticklabels(tick_labels, fontsize=7)
        ax.set_ylabel("deviation (max distance / length)")
        ax.set_title("defects (%d edges; hatched: not converged)" % rb["edges"], fontsize=9)
        ax.legend(fontsize=7, loc="lower right")
        ax.grid(True, axis="y", which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(png, dpi=110)


def main(argv):
    if len(argv) < 3:
        raise SystemExit(__doc__)
    plot(load(argv[1:-1]), argv[-1])


if __name__ == "__main__":
    main(sys.argv)
