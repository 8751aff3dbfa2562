"""The ParaFab ``Strip`` feature: a bending-active strip designed on an edge.

``make_strip(owner, "EdgeN")`` creates a ``Part::FeaturePython`` whose proxy
is :class:`StripFeature`.  On recompute it

1. converts the linked edge to exact planar NURBS data
   (:mod:`parafab_wb.geometry`),
2. calls the C++ solver ``parafab.design_strip`` (SI units),
3. stores the results (``Feasible``, ``Reason``, ``R``, ``Length``) and builds
   the shape: a compound of the flat strip and the bent strip, solids of the
   strip's thickness unless ``Solids`` is False (:mod:`parafab_wb.shapes`).

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

import math
import os
import traceback

import FreeCAD
import Part

from . import geometry
from . import shapes
from . import feature_proxy
from . import plot_output

#: Proxy type tag stored in documents.
TYPE = "ParaFab::Strip"
#: Version of the stored proxy state / property set.
#: 1: edge, material (E, thickness), min width, tolerance; results Feasible, Reason, R, Length.
#: 2: gravity (direction, density), material presets, strip type (plain / composite /
#:    perforated), validation by simulation (Deviation), RFirst, TypeMessage. Version-1
#:    documents get the new properties with defaults that reproduce their design (no gravity,
#:    plain strip, no validation).
#: 3: Solids (the flat and the bent strip as solids of the strip's thickness; default True).
#:    Older documents get Solids = True: their next recompute builds solids.
#: 4: stability (thesis §4.5): Stability ("Stable" / "Unstable", the Jacobi test) and Sigma
#:    (first conjugate point, 0 when stable), read-only results; older documents get them
#:    empty and fill them on the next recompute.
VERSION = 4

#: Material presets: (E [Pa], thickness [m], density [kg/m³]). 200 gsm cardboard: h = 0.3 mm,
#: 200 g/m² → ρ = 667 kg/m³, and E = 0.773 GPa, the modulus for which βl³ = E h²/(12 ρ g)
#: equals the thesis' fit 8.86e-4 m³ (§4.4.1). POM sheet 0.5 mm: E ≈ 2.8 GPa, ρ = 1410 kg/m³
#: (βl³ ≈ 4.2e-3 m³). Birch plywood 0.8 mm: E ≈ 8 GPa, ρ ≈ 600 kg/m³ (βl³ ≈ 7.2e-2 m³).
PRESETS = {
    "Cardboard 200 gsm": (0.773e9, 0.3e-3, 667.0),
    "POM 0.5 mm": (2.8e9, 0.5e-3, 1410.0),
    "Plywood 0.8 mm": (8.0e9, 0.8e-3, 600.0),
}
#: Yield strain ε_y = σ_y/E of the presets (the bending strain h·κ/2 must stay below it):
#: cardboard 0.0075 (the thesis saw permanent bending of 200 gsm cardboard below 2 cm radius,
#: h/(2·0.02 m)); POM ≈ 65 MPa / 2.8 GPa ≈ 0.023; birch plywood ≈ 40 MPa / 8 GPa = 0.005.
PRESET_YIELD_STRAIN = {
    "Cardboard 200 gsm": 0.0075,
    "POM 0.5 mm": 0.023,
    "Plywood 0.8 mm": 0.005,
}
PRESET_NAMES = ["Custom"] + list(PRESETS)
#: g [m/s²] of the material presets' density; the in-plane part g·cos(tilt) loads the strip.
STANDARD_GRAVITY = 9.81
STRIP_TYPES = ["Plain", "Composite", "Perforated"]

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
    # ---- version 2
    ("App::PropertyEnumeration", "MaterialPreset", "Material",
     "Sets thickness, Young's modulus and density (Custom: edit them freely)", None, 0),
    ("App::PropertyFloat", "Density", "Material",
     "Density of the strip material [kg/m^3] (for gravity)", 1000.0, 0),
    ("App::PropertyBool", "Gravity", "Load",
     "Design for the strip's own weight (thesis section 4.4, LP Eq. 4.6)", False, 0),
    ("App::PropertyVector", "GravityDirection", "Load",
     "Direction of gravity (global); projected onto the curve's plane", None, 0),
    ("App::PropertyEnumeration", "StripType", "Strip",
     "Plain sheet, composite (broad + narrow strip) or perforated (diamond holes)", None, 0),
    ("App::PropertyLength", "OuterWidth", "Strip",
     "Composite: width of the broad strip; perforated: width of the strip with holes",
     "50 mm", 0),
    ("App::PropertyLength", "InnerThickness", "Strip",
     "Composite: thickness of the narrow strip (the broad one has Thickness)", "0.3 mm", 0),
    ("App::PropertyBool", "Validate", "Solver",
     "Simulate the designed strip and report its deviation from the curve", False, 0),
    ("App::PropertyFloat", "Deviation", "Results",
     "Max distance of the simulated strip from the curve / length (0: not validated)", 0.0,
     _READ_ONLY | _OUTPUT),
    ("App::PropertyFloat", "RFirst", "Results",
     "Phase-one optimum of the gravity LP before smoothing (0 without gravity)", 0.0,
     _READ_ONLY | _OUTPUT),
    ("App::PropertyString", "TypeMessage", "Results",
     "Composite / perforated design: feasibility and why not", "", _READ_ONLY | _OUTPUT),
    # ---- version 3
    ("App::PropertyBool", "Solids", "Strip",
     "Build the flat and the bent strip as solids of the strip's thickness (False: surfaces)",
     True, 0),
    # ---- version 4
    ("App::PropertyString", "Stability", "Results",
     "Stable or Unstable: the Jacobi test of the designed strip (thesis section 4.5, "
     "conjugate points of Eq. 4.7); empty when not computed", "", _READ_ONLY | _OUTPUT),
    ("App::PropertyLength", "Sigma", "Results",
     "First conjugate point (arc length from the start) of an unstable strip; 0 when stable",
     "0 mm", _READ_ONLY | _OUTPUT),
)
_ENUMERATIONS = {"MaterialPreset": PRESET_NAMES, "StripType": STRIP_TYPES}
#: Inputs whose manual change turns a preset into "Custom".
_PRESET_INPUTS = ("Thickness", "YoungsModulus", "Density")


class StripError(RuntimeError):
    """Raised from ``execute`` to put the feature in FreeCAD's error state."""


def _solver():
    """The compiled solver module, with a useful error if absent."""
    return feature_proxy.solver_module(StripError)


def _linked_edge(obj):
    """``(owner, edge)`` for the ``Edge`` link of ``obj``, in global coordinates."""
    return feature_proxy.linked_edge(obj, StripError)


def _plane_hint(owner):
    """Preferred plane frame: the (global) placement plane of 2D objects
    such as sketches."""
    if owner.isDerivedFrom("Part::Part2DObject"):
        return geometry.PlaneFrame.from_placement(owner.getGlobalPlacement())
    return None


def _number(value):
    """``float(value)``, or 0.0 for ``None`` (the solver gives no R when infeasible)."""
    return 0.0 if value is None else float(value)


def gravity_in_plane(obj, frame):
    """``GravityDirection`` projected onto the curve's plane, as (x, y) in its frame."""
    g = FreeCAD.Vector(obj.GravityDirection)
    if g.Length == 0:
        raise StripError("GravityDirection must be a non-zero vector")
    g.normalize()
    x, y = g.dot(frame.xdir), g.dot(frame.ydir)
    if math.hypot(x, y) < 1e-6:
        raise StripError("GravityDirection (%g, %g, %g) is perpendicular to the curve's plane: "
                         "the weight does not bend the strip in its plane; set a direction in "
                         "the plane" % (g.x, g.y, g.z))
    return [x, y]


def build_spec(obj, curve):
    """Solver input (SI units) for feature ``obj`` and :class:`PlanarCurve` ``curve``."""
    spec = {
        "name": obj.Label,
        "curve": curve.to_spec(geometry.MM_TO_M),
        "material": {
            "E": float(obj.YoungsModulus.getValueAs("Pa")),
            "thickness": float(obj.Thickness.getValueAs("m")),
        },
        "min_width": float(obj.MinWidth.getValueAs("m")),
        "tolerance": float(obj.Tolerance),
    }
    if not hasattr(obj, "Gravity"):  # version-1 object not yet upgraded
        return spec
    if obj.MaterialPreset in PRESET_YIELD_STRAIN:  # a preset that would yield is refused
        spec["material"]["yield_strain"] = PRESET_YIELD_STRAIN[obj.MaterialPreset]
        spec["material"]["name"] = obj.MaterialPreset
    if obj.Gravity:
        # Only the in-plane component of gravity bends the strip: g·cos(tilt), with the
        # projection |(x, y)| = cos(tilt) of the unit direction (the solver normalizes the
        # direction, so the magnitude goes into g).
        x, y = gravity_in_plane(obj, curve.frame)
        in_plane = math.hypot(x, y)
        spec["gravity"] = {"direction": [x / in_plane, y / in_plane],
                           "density": float(obj.Density), "g": STANDARD_GRAVITY * in_plane}
    if obj.Validate:
        spec["validate"] = True
    if obj.StripType == "Composite":
        spec["composite"] = {"h1": spec["material"]["thickness"],
                             "h2": float(obj.InnerThickness.getValueAs("m")),
                             "outer_width": float(obj.OuterWidth.getValueAs("m"))}
    elif obj.StripType == "Perforated":
        spec["perforated"] = {"outer_width": float(obj.OuterWidth.getValueAs("m"))}
    return spec


def needs_recompute(obj):
    """True when ``obj`` or anything it depends on (the edge's owner, its sketch...) was
    changed since the last recompute, or is in an error state: its stored result is stale."""
    for o in [obj] + list(getattr(obj, "OutListRecursive", [])):
        state = getattr(o, "State", [])
        if "Touched" in state or "Invalid" in state:
            return True
    return bool(getattr(obj, "MustExecute", False))


def strip_result(obj, purpose="for this"):
    """The feasible solver result of strip ``obj``: the one of the last recompute, or (in a
    reopened document) designed anew. A strip whose inputs changed since its last recompute
    is recomputed first (never a stale result). Raises :class:`StripError` when there is no
    feasible design."""
    if needs_recompute(obj):
        obj.Document.recompute([obj])
        if needs_recompute(obj) or getattr(obj.Proxy, "result", None) is None:
            raise StripError("%s has no feasible design %s (recomputed): %s"
                             % (obj.Label, purpose, obj.Reason or obj.getStatusString()))
    result = getattr(obj.Proxy, "result", None)
    if result is None:  # not designed in this session (e.g. a reopened document)
        owner, edge = _linked_edge(obj)
        curve = geometry.planar_curve_from_edge(edge, _plane_hint(owner))
        result = _solver().design_strip(build_spec(obj, curve))
    if not result.get("feasible"):
        raise StripError("%s has no feasible design %s: %s"
                         % (obj.Label, purpose, result.get("reason") or obj.Reason))
    return result


def draw_profile(fig, result, title=""):
    """Draw the stiffness profile K(s) and the width w(s) of a feasible result into the
    matplotlib Figure ``fig`` (two axes sharing s in mm). Composite strips add the narrow
    strip's width w2(s), perforated strips the outer width."""
    s = [x * shapes.M_TO_MM for x in result["s"]]
    ax_k = fig.add_subplot(2, 1, 1)
    ax_k.plot(s, result["K"], color="tab:blue")
    ax_k.set_ylabel("K / min K")
    ax_k.set_title("%s  R = %.4g, length %.1f mm" % (title, result["R"], result["length"] * shapes.M_TO_MM),
                   fontsize=10)
    ax_k.grid(True, alpha=0.3)
    ax_w = fig.add_subplot(2, 1, 2, sharex=ax_k)
    ax_w.plot(s, [w * shapes.M_TO_MM for w in result["width"]], color="tab:orange", label="w(s)")
    composite = result.get("composite")
    if composite and composite.get("feasible") and composite.get("w2"):
        ax_w.plot(s, [w * shapes.M_TO_MM for w in composite["w2"]], color="tab:green",
                  label="w2(s), narrow strip")
        ax_w.axhline(composite["outer_width"] * shapes.M_TO_MM, color="gray", ls="--", label="broad strip")
    perforations = result.get("perforations")
    if perforations:
        ax_w.axhline(perforations["outer_width"] * shapes.M_TO_MM, color="gray", ls="--",
                     label="outer width (perforated)")
    ax_w.set_xlabel("s [mm]")
    ax_w.set_ylabel("width [mm]")
    ax_w.set_ylim(bottom=0)
    ax_w.grid(True, alpha=0.3)
    ax_w.legend(fontsize=8, loc="best")
    return ax_k, ax_w


def plot_profile(obj, png_path=None, show=None):
    """K(s) and w(s) of strip ``obj``: written to ``png_path`` (headless, matplotlib's Agg
    canvas, no pyplot state) when given, and shown in FreeCAD's Plot module when ``show``
    (default: when the GUI is up and Plot imports). Returns ``png_path``."""
    result = strip_result(obj, "to plot")
    return plot_output.render(lambda fig: draw_profile(fig, result, obj.Label), png_path, show, (8, 6),
                              "Strip profile: %s" % obj.Label)


def draw_stability(fig, result, title=""):
    """Draw the normalized stability determinant Z(s) of a feasible result (thesis Fig. 4.9)
    into the matplotlib Figure ``fig``, with the conjugate point sigma marked when unstable."""
    st = result.get("stability")
    if not st:
        raise StripError("the result has no stability field")
    s = [x * shapes.M_TO_MM for x in st["s"]]
    ax = fig.add_subplot(1, 1, 1)
    ax.plot(s, st["Z"], color="tab:green" if st["stable"] else "tab:red")
    ax.axhline(0.0, color="gray", lw=0.8)
    if st.get("sigma") is not None:
        ax.axvline(st["sigma"] * shapes.M_TO_MM, color="tab:orange", ls="--",
                   label="sigma = %.1f mm" % (st["sigma"] * shapes.M_TO_MM))
        ax.legend(fontsize=8, loc="best")
    ax.set_xlabel("s [mm]")
    ax.set_ylabel("Z(s) (normalized)")
    ax.set_title("%s  %s (Jacobi test, %d constraint(s))"
                 % (title, "stable" if st["stable"] else "unstable", st.get("constraints", 2)),
                 fontsize=10)
    ax.grid(True, alpha=0.3)
    return ax


def plot_stability(obj, png_path=None, show=None):
    """Z(s) of strip ``obj`` (thesis Fig. 4.9, sigma marked when unstable): written to
    ``png_path`` when given and shown in FreeCAD's Plot module when ``show`` (default: when the
    GUI is up). Returns ``png_path``. Raises :class:`StripError` when the strip has no feasible
    design or no stability result."""
    result = strip_result(obj, "to plot")
    return plot_output.render(lambda fig: draw_stability(fig, result, obj.Label), png_path, show, (8, 4),
                              "Strip stability: %s" % obj.Label)


def export_cut_sheets(obj, directory):
    """Write ``<Label>.dxf`` and ``<Label>.svg`` (flat outline at true scale, mm) of strip
    ``obj`` into ``directory``; returns the two paths. Raises :class:`StripError` when the
    strip has no feasible design."""
    result = strip_result(obj, "to export")
    safe = "".join(c if c.isalnum() or c in "-_." else "_" for c in obj.Label) or obj.Name
    paths = []
    for ext in ("dxf", "svg"):
        path = os.path.join(directory, safe + "." + ext)
        _solver().export_strip_outline(result, path)
        paths.append(path)
    return paths


class StripFeature(feature_proxy.FeatureProxy):
    """Proxy of the ``Strip`` ``Part::FeaturePython`` object."""

    TYPE = TYPE
    VERSION = VERSION
    PROPERTIES = _PROPERTIES
    ENUMERATIONS = _ENUMERATIONS

    #: Transient (not saved): the last solver result, and how often execute ran.
    result = None
    executions = 0
    _quiet = False

    def __init__(self, obj):
        super(StripFeature, self).__init__(obj)
        if obj.GravityDirection.Length == 0:
            obj.GravityDirection = FreeCAD.Vector(0, 0, -1)

    def onDocumentRestored(self, obj):
        """Version 1 -> 2: add the new properties (defaults keep the old design)."""
        missing_direction = "GravityDirection" not in obj.PropertiesList
        super(StripFeature, self).onDocumentRestored(obj)
        if missing_direction:
            obj.GravityDirection = FreeCAD.Vector(0, 0, -1)

    def onChanged(self, obj, prop):
        """Material presets: choosing one sets thickness, E and density; editing those by
        hand switches the preset to Custom."""
        if self._quiet or "Restore" in obj.State or not hasattr(obj, "MaterialPreset"):
            return
        if prop == "MaterialPreset" and obj.MaterialPreset in PRESETS:
            E, h, rho = PRESETS[obj.MaterialPreset]
            self._quiet = True
            try:
                obj.YoungsModulus = FreeCAD.Units.Quantity("%r Pa" % E)
                obj.Thickness = FreeCAD.Units.Quantity(h * 1e3, FreeCAD.Units.Length)
                obj.Density = rho
            finally:
                self._quiet = False
        elif prop in _PRESET_INPUTS and obj.MaterialPreset != "Custom":
            self._quiet = True
            try:
                obj.MaterialPreset = "Custom"
            finally:
                self._quiet = False

    # -- recompute ---------------------------------------------------------

    def execute(self, obj):
        """Recompute the strip; on failure set the results and raise."""
        self.executions = self.executions + 1
        self.result = None
        obj.Feasible = False
        obj.Reason = ""
        obj.R = 0.0
        obj.Length = 0.0
        if hasattr(obj, "Deviation"):
            obj.Deviation = 0.0
            obj.RFirst = 0.0
            obj.TypeMessage = ""
        if hasattr(obj, "Stability"):
            obj.Stability = ""
            obj.Sigma = 0.0
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
        obj.Shape = shapes.strip_shape(result, curve.frame,
                                       solid=bool(getattr(obj, "Solids", True)))
        obj.Feasible = True
        obj.Reason = ""
        self.result = result
        stability = result.get("stability")
        if stability and hasattr(obj, "Stability"):
            obj.Stability = "Stable" if stability["stable"] else "Unstable"
            obj.Sigma = _number(stability.get("sigma")) * shapes.M_TO_MM
        if not hasattr(obj, "Deviation"):
            return
        obj.RFirst = _number(result.get("R_first")) if result.get("general_lp") else 0.0
        sim = result.get("simulation")
        if sim:
            obj.Deviation = _number(sim.get("deviation"))
            if not sim.get("converged"):
                FreeCAD.Console.PrintWarning("ParaFab: %s: the validation did not converge: %s\n"
                                             % (obj.Label, sim.get("message")))
        part = result.get("composite") or result.get("perforations")
        if part is not None:
            kind = "composite" if result.get("composite") else "perforated"
            if part.get("feasible") and kind == "perforated":
                # How far the hole pattern is from the designed stiffness (the solver's report):
                # inside the perforated range, and at the hole-free ends.
                obj.TypeMessage = (
                    "perforated strip feasible; inside the holes the stiffness over one pitch is "
                    "within %.2f %% of the design (sections %.2f %%); the hole-free ends are up to "
                    "%.0f %% stiffer" % (100 * part["interior_stiffness_deviation"],
                                         100 * part["interior_width_deviation"],
                                         100 * part["end_zone_deviation"]))
            elif part.get("feasible"):
                obj.TypeMessage = "%s strip feasible" % kind
            else:
                obj.TypeMessage = "%s strip infeasible: %s" % (kind, part.get("message", ""))


class ViewProviderStrip(feature_proxy.IconViewProvider):
    """View provider of the ``Strip`` feature (GUI only)."""

    ICON = "ParaFab_Strip.svg"


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
