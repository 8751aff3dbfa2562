"""Twist plot of a rod result (:func:`parafab.design_rod`, SI units) as a PNG.

Importable without FreeCAD; uses matplotlib's Agg backend, so it works headless
(``freecadcmd`` and Debian's ``/usr/bin/python3``).  Panels: the twist rate
tau_beta(s) and the accumulated rotation beta(s) of the material frame
(thesis Eq. 5.17), and the ellipse semi-axes a(s), b(s).
"""


def plot_rod(result, path, title=""):
    """Write the twist plot of ``result`` to ``path`` (PNG); returns ``path``.

    For an infeasible result the reason is drawn instead of the curves.
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(13, 3.6))
    if result.get("twist"):
        s = result["s"]
        axes[0].plot(s, result["twist"])
        axes[0].set_title("twist rate tau_beta [rad/m]", fontsize=9)
        axes[1].plot(s, result["beta"])
        axes[1].set_title("rotation beta [rad] (end: %.4g)" % result["beta"][-1], fontsize=9)
        sec = result["section"]
        axes[2].plot(s, [1e3 * a for a in sec["a"]], label="a")
        axes[2].plot(s, [1e3 * b for b in sec["b"]], label="b")
        axes[2].legend(fontsize=8)
        axes[2].set_title("semi-axes [mm] (t/t* = %g)" % sec["factor"], fontsize=9)
        for ax in axes:
            ax.set_xlabel("s [m]")
            ax.grid(alpha=0.3)
    else:
        for ax in axes:
            ax.axis("off")
        reason = result.get("reason") or result.get("status", "")
        axes[1].text(0, 0.5, "infeasible:\n" + "\n".join(reason[i:i + 70] for i in range(0, len(reason), 70)),
                     fontsize=8, va="center")
    R = result.get("R")
    fig.suptitle("%s  L = %.3f m, R = %s, status %s" % (title, result["length"],
                                                       "-" if R is None else "%.3g" % R, result["status"]),
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
