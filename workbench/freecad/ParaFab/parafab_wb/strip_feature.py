"""The ParaFab ``Strip`` feature: a bending-active strip designed on an edge.

``make_strip(owner, "EdgeN")`` creates a ``Part::FeaturePython`` whose proxy
is :class:`StripFeature`.  On recompute it

1. converts the linked edge to exact planar NURBS data
   (:mod:`parafab_wb.geometry`),
2. calls the C++ solver ``parafab.design_strip`` (SI units),
3. stores the results (``Feasible``, ``Reason``, ``R``, ``Length``) and builds
   the shape: a compound of the flat strip and the bent strip
   (:mod:`parafab_wb.shapes`).

Failures (non-planar edge, invalid input rejected by the solver, infeasible
curve, missing solver module) never crash FreeCAD: ``Feasible`` becomes
False, ``Reason`` holds the message, the shape is emptied and ``execute``
raises :class:`StripError`, which FreeCAD turns into the object's error
state (``'Invalid' in obj.State``, message in ``obj.getStatusString()``)
while the rest of the document recomputes normally.

The strip's shape is built in global coordinates (the edge of a sketch
inside a placed Body is moved accordingly), so the ``Strip`` belongs at the
document root, where :func:`make_strip` puts it.

Works headless (``freecadcmd``): the view provider is only created when
``FreeCAD.GuiUp``.  This module must not import ``FreeCADGui`` at import
time because FreeCAD imports it to restore saved documents.
"""

import traceback

import FreeCAD
import Part

from . import geometry
from . import icon_path
from . import shapes
from . import feature_proxy

#: Proxy type tag stored in documents.
TYPE = "ParaFab::Strip"
#: Version of the stored proxy state / property set.
VERSION = 1

# Property status bits (App::PropertyType): read-only in the editor, and
# "output" (changing it does not touch the object).
_READ_ONLY = 1
_OUTPUT = 8

#: (type, name, group, tooltip, default, attributes)
_PROPERTIES = (
    # Global link scope: the edge may belong to a sketch inside a Body.
    ("App::PropertyLinkSubGlobal", "Edge", "Strip",
     "Planar edge used as the strip centreline", None, 0),
    ("App::PropertyLength", "Thickness", "Material",
     "Strip thickness", "0.5 mm", 0),
    ("App::PropertyPressure", "YoungsModulus", "Material",
     "Young's modulus of the strip material", "3 GPa", 0),
    ("App::PropertyLength", "MinWidth", "Strip",
     "Minimum strip width (where the curvature is smallest)", "10 mm", 0),
    ("App::PropertyFloat", "Tolerance", "Solver",
     "Relative tolerance on R", 1e-6, 0),
    ("App::PropertyBool", "Feasible", "Results",
     "True when the curve can be realised by a bent strip", False,
     _READ_ONLY | _OUTPUT),
    ("App::PropertyString", "Reason", "Results",
     "Why the design failed (empty when feasible)", "",
     _READ_ONLY | _OUTPUT),
    ("App::PropertyFloat", "R", "Results",
     "Stiffness ratio R computed by the solver (0 when not computed)", 0.0,
     _READ_ONLY | _OUTPUT),
    ("App::PropertyLength", "Length", "Results",
     "Arc length of the centreline", "0 mm", _READ_ONLY | _OUTPUT),
)


class StripError(RuntimeError):
    """Raised from ``execute`` to put the feature in FreeCAD's error state."""


def _solver():
    """Import the compiled solver module, with a useful error if absent."""
    try:
        import parafab
    except ImportError as exc:
        raise StripError("The ParaFab solver module 'parafab' cannot be "
                         "imported (%s); is the workbench installed?" % exc)
    return parafab


def _linked_edge(obj):
    """Return ``(owner, edge)`` for the ``Edge`` link of ``obj``."""
    link = obj.Edge
    if not link or link[0] is None or not link[1]:
        raise StripError("No edge linked: set the 'Edge' property")
    owner, subs = link
    sub = subs[0]
    try:
        edge = owner.Shape.getElement(sub)
    except Exception as exc:  # OCC / FreeCAD raise various types here
        raise StripError("Cannot get %s of %s: %s" % (sub, owner.Label, exc))
    if edge.ShapeType != "Edge":
        raise StripError("%s of %s is not an edge" % (sub, owner.Label))
    # owner.Shape is expressed in the owner's container (e.g. a PartDesign
    # Body); move the edge to global coordinates.
    container = owner.getGlobalPlacement().multiply(owner.Placement.inverse())
    if not container.isIdentity():
        edge = edge.copy()
        edge.Placement = container.multiply(edge.Placement)
    return owner, edge


def _plane_hint(owner):
    """Preferred plane frame: the (global) placement plane of 2D objects
    such as sketches."""
    if owner.isDerivedFrom("Part::Part2DObject"):
        return geometry.PlaneFrame.from_placement(owner.getGlobalPlacement())
    return None


def _number(value):
    """``float(value)``, or 0.0 for ``None`` (the solver gives no R when infeasible)."""
    return 0.0 if value is None else float(value)


def build_spec(obj, curve):
    """Solver input (SI units) for feature ``obj`` and :class:`PlanarCurve` ``curve``."""
    return {
        "curve": curve.to_spec(geometry.MM_TO_M),
        "material": {
            "E": float(obj.YoungsModulus.getValueAs("Pa")),
            "thickness": float(obj.Thickness.getValueAs("m")),
        },
        "min_width": float(obj.MinWidth.getValueAs("m")),
        "tolerance": float(obj.Tolerance),
    }


class StripFeature(feature_proxy.FeatureProxy):
    """Proxy of the ``Strip`` ``Part::FeaturePython`` object."""

    TYPE = TYPE
    VERSION = VERSION
    PROPERTIES = _PROPERTIES

    # -- recompute ---------------------------------------------------------

    def execute(self, obj):
        """Recompute the strip; on failure set the results and raise."""
        obj.Feasible = False
        obj.Reason = ""
        obj.R = 0.0
        obj.Length = 0.0
        try:
            self._design(obj)
        except Exception as exc:
            if not isinstance(exc, (StripError, ValueError)):
                # Unexpected: keep the full traceback in the report view.
                FreeCAD.Console.PrintError(traceback.format_exc())
            message = str(exc) or type(exc).__name__
            obj.Feasible = False
            obj.Reason = message
            obj.Shape = Part.Shape()
            raise StripError(message) from exc

    def _design(self, obj):
        """Run the solver and build the shape; raises on any failure."""
        owner, edge = _linked_edge(obj)
        curve = geometry.planar_curve_from_edge(edge, _plane_hint(owner))
        result = _solver().design_strip(build_spec(obj, curve))
        obj.R = _number(result.get("R"))
        obj.Length = _number(result.get("length")) * shapes.M_TO_MM
        if not result["feasible"]:
            raise StripError("Infeasible curve: %s"
                             % (result.get("reason") or "no reason given"))
        obj.Shape = shapes.strip_shape(result, curve.frame)
        obj.Feasible = True
        obj.Reason = ""


class ViewProviderStrip(object):
    """View provider of the ``Strip`` feature (GUI only)."""

    def __init__(self, vobj):
        vobj.Proxy = self

    def attach(self, vobj):
        """Called when the view provider is created or restored."""
        self.Object = vobj.Object

    def getIcon(self):
        """Tree icon."""
        return icon_path("ParaFab_Strip.svg")

    def __getstate__(self):
        """Nothing to store."""
        return None

    def __setstate__(self, state):
        """Nothing to restore."""
        return None

    dumps = __getstate__
    loads = __setstate__


def make_strip(edge_owner_obj, subname, doc=None):
    """Create a ``Strip`` feature on edge ``subname`` (e.g. ``"Edge1"``) of an object.

    ``doc`` defaults to the owner's document.  The new object is not
    recomputed; call ``doc.recompute()``.  Returns the new object.
    """
    if not isinstance(subname, str) or not subname.startswith("Edge"):
        raise ValueError("subname must name an edge, e.g. 'Edge1' (got %r)"
                         % (subname,))
    if doc is None:
        doc = edge_owner_obj.Document
    obj = doc.addObject("Part::FeaturePython", "Strip")
    StripFeature(obj)
    obj.Edge = (edge_owner_obj, [subname])
    if FreeCAD.GuiUp:
        ViewProviderStrip(obj.ViewObject)
        obj.ViewObject.ShapeColor = (0.96, 0.65, 0.14)
        obj.ViewObject.LineColor = (0.35, 0.20, 0.0)
    return obj
