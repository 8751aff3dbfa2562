"""Before/after chart of a shape optimization (``parafab optimize`` history) as a PNG.

Importable without FreeCAD; matplotlib's Agg backend, so it works headless. Left: each design
parameter's value before and after (mm for offsets, radii and positions, unitless for normals and
axes). Right: the objective before and after (log scale when both are positive). The history
chart (objective against iteration and time) is the engine's ``history.png``.
"""

BEFORE_AFTER = "before_after.png"


def plot_before_after(history, path, title="", rename=None):
    """Write the before/after chart of ``history`` to ``path``; returns ``path``. ``rename`` maps
    the engine's parameter names to the labels shown."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    params = history.get("parameters", [])
    n = max(len(params), 1)
    fig, axes = plt.subplots(1, 2, figsize=(9, max(2.2, 1.2 + 0.28 * n)), gridspec_kw={"width_ratios": [3, 1]})
    ax = axes[0]
    y = list(range(len(params)))
    ax.barh([v - 0.2 for v in y], [p["initial"] for p in params], 0.4, label="before", color="#aaaaaa")
    ax.barh([v + 0.2 for v in y], [p["final"] for p in params], 0.4, label="after", color="#3c9a55")
    ax.set_yticks(y)
    ax.set_yticklabels([(rename or str)(p["name"]) for p in params], fontsize=7)
    ax.invert_yaxis()
    ax.axvline(0, color="#333", lw=0.8)
    ax.legend(fontsize=8, loc="best")
    ax.set_title("design parameters", fontsize=9)
    ax.grid(axis="x", alpha=0.3)
    f0, f1 = history.get("initial_objective", 0.0), history.get("final_objective", 0.0)
    ax = axes[1]
    ax.bar([0, 1], [f0, f1], color=["#aaaaaa", "#3c9a55"])
    ax.set_xticks([0, 1])
    ax.set_xticklabels(["before", "after"], fontsize=8)
    if f0 > 0 and f1 > 0:
        ax.set_yscale("log")
    ax.set_title("objective (%s)" % history.get("objective", ""), fontsize=9)
    fig.suptitle("%s%.4g -> %.4g, volume x %.4f" % (
        (title + ": ") if title else "", f0, f1,
        history["final_volume"] / history["initial_volume"] if history.get("initial_volume") else float("nan")),
        fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
