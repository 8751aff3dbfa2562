"""Stabilize a ``Strip`` (thesis section 4.5.4, Algorithm 4.2).

``stabilize_strip(strip, R_max)`` runs the solver's ``parafab.stabilize_strip`` on the strip's
curve (its control points move until the first conjugate point lies beyond the strip's end,
with R <= R_max) and replaces the curve in ONE undo transaction ("Stabilize strip"), exactly
like "Improve fabricability" (:func:`parafab_wb.strip_improve.replace_curve`): the poles of a
single-edge ``Part::Feature`` are replaced in place with the original kept as a hidden copy,
any other owner is left untouched and the strip relinked to a new curve. The original is
linked from ``OriginalCurve``; :func:`parafab_wb.strip_improve.restore_original` brings it
back. Stabilization neglects gravity (thesis 4.5.4): a strip with gravity is refused by the
solver with a message naming it.

Works headless; never imports ``FreeCADGui`` at import time.
"""

import FreeCAD

from . import geometry
from . import plot_output
from . import strip_feature
from . import strip_improve

TITLE = "Stabilize strip"
_READ_ONLY = 1


def _add_properties(strip):
    props = (
        ("App::PropertyBool", "StableBeforeStabilize", "Stability",
         "Jacobi verdict of the original curve (thesis 4.5.2)"),
        ("App::PropertyFloat", "SigmaBeforeStabilize", "Stability",
         "First conjugate point of the original curve [mm] (0: stable)"),
        ("App::PropertyBool", "StableAfterStabilize", "Stability",
         "Jacobi verdict of the stabilized curve"),
        ("App::PropertyFloat", "StabilizeDeviation", "Stability",
         "Max distance between the original and the stabilized curve [mm]"),
    )
    for typ, name, group, tip in props:
        if not hasattr(strip, name):
            strip.addProperty(typ, name, group, tip)
            strip.setEditorMode(name, _READ_ONLY)


def run_solver(strip, R_max=10.0, stabilize=None):
    """``(result, frame)``: the solver's strip-stabilize result (SI units) for the strip's curve,
    and the plane frame of that curve."""
    owner, edge = strip_feature._linked_edge(strip)
    curve = geometry.planar_curve_from_edge(edge, strip_feature._plane_hint(owner))
    spec = strip_feature.build_spec(strip, curve)
    spec.pop("validate", None)
    spec["stabilize"] = dict(stabilize or {})
    spec["stabilize"]["R_max"] = float(R_max)
    result = strip_feature._solver().stabilize_strip(spec)
    return result, curve.frame


def stabilize_strip(strip, R_max=10.0, stabilize=None):
    """Make the strip's curve stable by moving its control points; returns the solver result.
    A curve that is already stable (with the margin) is left alone (no transaction)."""
    result, frame = run_solver(strip, R_max, stabilize)
    if result["status"] == "already":
        return result

    def record():
        _add_properties(strip)
        strip.StableBeforeStabilize = bool(result["stable_before"])
        strip.SigmaBeforeStabilize = float(result["sigma_before"] or 0.0) / geometry.MM_TO_M
        strip.StableAfterStabilize = bool(result["stable_after"])
        strip.StabilizeDeviation = float(result["deviation"]) / geometry.MM_TO_M

    strip_improve.replace_curve(strip, result["bspline"], frame, TITLE, record, suffix="_stabilized")
    return result


def report(label, result):
    """One line for the report view."""
    def sig(key):
        v = result[key]
        return "stable" if v is None else "sigma/l %.3f" % (v / result["length"])
    return "ParaFab: %s: %s -> %s (%s), R %.3g -> %.3g, max pole move %.3g mm, deviation %.3g mm, %.3f s\n" % (
        label, sig("sigma_before"), sig("sigma_after"), result["status"], result["R_before"] or 0,
        result["R_after"] or 0, result["max_pole_move"] * 1e3, result["deviation"] * 1e3, result["seconds"])


def draw_stabilization(fig, result, title=""):
    """Curve and control polygon before and after (left), and the first conjugate point
    sigma / l of the curve and of the margin-scaled force (the objective) against the
    iteration (right): stable once no conjugate point is left before the end (drawn at 1)."""
    ax = fig.add_subplot(1, 2, 1)

    def sig(key):
        v = result[key]
        return "stable" if v is None else "sigma/l %.3f" % (v / result["length"])
    strip_improve.draw_curves(ax, result, "%s  %s -> %s, R %.3g -> %.3g, deviation %.2f mm" % (
        title, sig("sigma_before"), sig("sigma_after"), result["R_before"] or float("nan"),
        result["R_after"] or float("nan"), result["deviation"] / geometry.MM_TO_M))
    ax2 = fig.add_subplot(1, 2, 2)
    hist = result["history"]
    it = [h["iteration"] for h in hist]
    for key, style, label in (("sigma", "o-", "sigma / l"), ("sigma_margin", "s--", "sigma / l, force x (1 + margin)")):
        y = [1.0 if h[key] is None else h[key] / result["length"] for h in hist]
        ax2.plot(it, y, style, ms=3, label=label)
    ax2.axhline(1.0, color="tab:green", lw=0.8, ls=":", label="end of the strip (stable above)")
    ax2.set_xlabel("iteration")
    ax2.set_ylabel("first conjugate point / length")
    ax2.legend(fontsize=8)
    ax2.grid(True, alpha=0.3)
    return ax, ax2


def plot_stabilization(result, png_path=None, show=None, title=""):
    """Plot of a strip-stabilize result: to ``png_path`` (headless, Agg) and/or FreeCAD's Plot
    module (``show``; default when the GUI is up). Returns ``png_path``."""
    return plot_output.render(lambda fig: draw_stabilization(fig, result, title), png_path, show, (11, 4.5),
                              "Stabilize: %s" % title)
