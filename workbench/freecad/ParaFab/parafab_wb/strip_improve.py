"""Improve the fabricability of a ``Strip`` (thesis section 4.6.2).

``improve_strip(strip, target_R)`` runs the solver's ``parafab.strip_improve`` on the strip's
curve and replaces the curve in ONE undo transaction ("Improve fabricability"):

* an edge owned by a plain ``Part::Feature`` holding that single edge gets its shape replaced
  by the improved B-spline (its poles moved; the placement kept);
* any other owner (a sketch, a parametric feature, a multi-edge shape) is left untouched and
  hidden, and the strip is relinked to a new ``Part::Feature`` holding the improved curve.

Either way the original stays recoverable: a hidden ``Part::Feature`` "<Label> (original)"
(or the untouched owner itself) is linked from the strip's ``OriginalCurve`` property, and
:func:`restore_original` relinks / restores it. With the GUI, Edit > Undo reverts the whole
change at once. :func:`plot_improvement` draws the curve (and its control polygon) before and
after.

Works headless; never imports ``FreeCADGui`` at import time.
"""

import FreeCAD
import Part

from . import geometry
from . import strip_feature
from . import plot_output

TITLE = "Improve fabricability"
_READ_ONLY = 1


def _add_properties(strip):
    """The fabricability properties of a strip (added on first use)."""
    props = (
        ("App::PropertyLink", "OriginalCurve", "Fabricability",
         "Hidden copy (or untouched owner) of the curve before 'Improve fabricability'"),
        ("App::PropertyString", "OriginalEdge", "Fabricability",
         "Sub-element of the original curve the strip was linked to"),
        ("App::PropertyFloat", "RBeforeImprove", "Fabricability",
         "Stiffness ratio R of the original curve"),
        ("App::PropertyFloat", "ImproveDeviation", "Fabricability",
         "Max distance between the original and the improved curve [mm]"),
    )
    for typ, name, group, tip in props:
        if not hasattr(strip, name):
            strip.addProperty(typ, name, group, tip)
            if name != "OriginalCurve":
                strip.setEditorMode(name, _READ_ONLY)


def run_solver(strip, target_R=3.5, improve=None):
    """``(result, frame)``: the solver's strip-improve result (SI units) for the strip's curve,
    and the plane frame of that curve."""
    owner, edge = strip_feature._linked_edge(strip)
    curve = geometry.planar_curve_from_edge(edge, strip_feature._plane_hint(owner))
    spec = strip_feature.build_spec(strip, curve)
    spec["improve"] = dict(improve or {})
    spec["improve"]["target_R"] = float(target_R)
    result = strip_feature._solver().strip_improve(spec)
    return result, curve.frame


def _edge_from_result(spec, frame):
    to_mm = 1.0 / geometry.MM_TO_M
    return geometry.bspline_from_spec(
        spec, lambda p: frame.to_3d(p[0] * to_mm, p[1] * to_mm)).toShape()


def replace_curve(strip, bspline, frame, title, record=None, suffix="_improved"):
    """Replace the strip's curve by the solver B-spline ``bspline`` (SI units, plane ``frame``)
    in ONE transaction ``title``: the owner's shape in place (single-edge ``Part::Feature``,
    original copied to a hidden "<Label> (original)") or a new holder ``<Name><suffix>`` the
    strip is relinked to (any other owner, left untouched). ``record()`` runs first inside the
    transaction (e.g. to set properties). The strip recomputes."""
    owner, sub = strip.Edge[0], strip.Edge[1][0]
    doc = strip.Document
    new_edge = _edge_from_result(bspline, frame)

    def apply():
        _add_properties(strip)
        if record is not None:
            record()
        in_place = owner.TypeId == "Part::Feature" and len(owner.Shape.Edges) == 1
        if in_place:
            original = doc.addObject("Part::Feature", owner.Name + "_original")
            original.Label = owner.Label + " (original)"
            original.Shape = owner.Shape.copy()
            local = new_edge.transformGeometry(owner.Placement.inverse().toMatrix())
            local.Placement = owner.Placement
            owner.Shape = local
        else:
            original = owner
            holder = doc.addObject("Part::Feature", owner.Name + suffix)
            holder.Label = owner.Label + " (%s)" % suffix.lstrip("_")
            holder.Shape = new_edge
            strip.Edge = (holder, ["Edge1"])
        strip.OriginalCurve = original
        strip.OriginalEdge = sub if not in_place else "Edge1"
        if FreeCAD.GuiUp and getattr(original, "ViewObject", None) is not None:
            original.ViewObject.Visibility = False
        doc.recompute()

    doc.openTransaction(title)
    try:
        apply()
    except Exception:
        doc.abortTransaction()
        raise
    doc.commitTransaction()


def improve_strip(strip, target_R=3.5, improve=None):
    """Lower the strip's stiffness ratio to ``target_R`` by moving its curve's control points;
    returns the solver result. The document change is one transaction; the strip recomputes."""
    r_before = float(strip.R) if strip.Feasible else 0.0
    result, frame = run_solver(strip, target_R, improve)

    def record():
        # The strip's own R (its tolerance), else the improvement's estimate.
        strip.RBeforeImprove = r_before or float(result["R_initial"] or 0.0)
        strip.ImproveDeviation = float(result["deviation"]) / geometry.MM_TO_M

    replace_curve(strip, result["bspline"], frame, TITLE, record)
    return result


def restore_original(strip):
    """Put the original curve back (one transaction): the owner's shape from the hidden copy,
    or the strip relinked to the untouched original owner."""
    if not getattr(strip, "OriginalCurve", None):
        raise strip_feature.StripError("%s has no original curve to restore" % strip.Label)
    doc = strip.Document
    original = strip.OriginalCurve
    owner = strip.Edge[0]
    doc.openTransaction("Restore original curve")
    try:
        if original.Name == owner.Name + "_original":
            owner.Shape = original.Shape.copy()
        else:
            strip.Edge = (original, [strip.OriginalEdge])
        doc.recompute()
    except Exception:
        doc.abortTransaction()
        raise
    doc.commitTransaction()


def _samples(spec, n=300):
    bs = geometry.bspline_from_spec(spec, lambda p: FreeCAD.Vector(p[0], p[1], 0))
    pts = bs.discretize(n)
    return [p.x / geometry.MM_TO_M for p in pts], [p.y / geometry.MM_TO_M for p in pts]


def draw_curves(ax, result, title=""):
    """The curve and its control polygon before (light) and after (dark) into ``ax``: a
    strip-improve or strip-stabilize result (``original_bspline``, ``bspline``)."""
    for key, color, label in (("original_bspline", "#8fd18f", "before"), ("bspline", "#1b6e1b", "after")):
        x, y = _samples(result[key])
        ax.plot(x, y, color=color, lw=2, label=label)
        px = [p[0] / geometry.MM_TO_M for p in result[key]["poles"]]
        py = [p[1] / geometry.MM_TO_M for p in result[key]["poles"]]
        ax.plot(px, py, "o--", color=color, lw=0.7, ms=3)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=8)
    ax.grid(True, alpha=0.3)


def draw_improvement(fig, result, title=""):
    """Curve and control polygon before (light) and after (dark), and R against time."""
    ax = fig.add_subplot(1, 2, 1)
    draw_curves(ax, result, "%s  R %.3g -> %.3g, deviation %.2f mm" % (
        title, result["R_initial"] or float("nan"), result["R"] or float("nan"),
        result["deviation"] / geometry.MM_TO_M))
    ax2 = fig.add_subplot(1, 2, 2)
    hist = result["history"]
    ax2.semilogy([h["seconds"] * 1e3 for h in hist], [h["R"] for h in hist], ".-")
    ax2.axhline(result["target_R"], color="red", ls="--", lw=0.8)
    ax2.set_xlabel("time [ms]")
    ax2.set_ylabel("R")
    ax2.grid(True, which="both", alpha=0.3)
    return ax, ax2


def plot_improvement(result, png_path=None, show=None, title=""):
    """Plot of a strip-improve result: to ``png_path`` (headless, Agg) and/or FreeCAD's Plot
    module (``show``; default when the GUI is up)."""
    return plot_output.render(lambda fig: draw_improvement(fig, result, title), png_path, show, (11, 4.5),
                              "Fabricability: %s" % title)
