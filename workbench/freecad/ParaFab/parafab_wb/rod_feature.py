"""The ParaFab ``Rod`` feature: a Kirchhoff rod designed on a space-curve edge (thesis ch. 5).

``make_rod(owner, "EdgeN")`` creates a ``Part::FeaturePython`` whose proxy is
:class:`RodFeature`.  On recompute it

1. converts the linked edge (any 3D edge: B-spline, arc, helix, ...) to exact NURBS data
   (:func:`parafab_wb.geometry.edge_to_bspline`, rational where FreeCAD's is),
2. calls the C++ solver ``parafab.design_rod`` (SI units: the edge is in mm),
3. stores the results (``Feasible``, ``Status``, ``R``, ``TwistMax``, ``BetaEnd``, the
   clamped end frames ``StartFrame``/``EndFrame`` as placements with axes (n1, n2,
   tangent), ``Deviation`` when ``Validate``) and builds the shape: a compound of the
   deformed rod (a solid through the rotated elliptical sections along the curve), the
   straight undeformed rod laid beside it, and frame markers at the clamped ends
   (:mod:`parafab_wb.rod_shapes`),
4. writes the twist plot (PNG, headless matplotlib) to ``PlotFile`` when it is set.

Failures (κ = 0 somewhere, infeasible curve, invalid input, missing solver module) never
crash FreeCAD: ``Feasible`` becomes False, ``Reason`` holds the message, the shape is
emptied and ``execute`` raises :class:`RodError` (the object's error state) while the rest
of the document recomputes normally.

:func:`export_step` writes both rods (deformed and straight solids) to a STEP file;
:func:`write_twist_plot` writes the twist plot on demand.  Works headless; the view
provider is only created when ``FreeCAD.GuiUp``.
"""

import traceback

import FreeCAD
import Part

from . import feature_proxy
from . import geometry
from . import rod_shapes

#: Proxy type tag stored in documents.
TYPE = "ParaFab::Rod"
#: Version of the stored proxy state / property set.
VERSION = 2  # 2: Stability results, SectionFactor default 4

_RO = feature_proxy.READ_ONLY | feature_proxy.OUTPUT

#: Material presets (SI): name -> (E [Pa], nu, density [kg/m^3]).
PRESETS = {"SmoothSil 960": (2.3e6, 0.48, 1250.0)}
MATERIALS = ["SmoothSil 960", "Custom"]

#: (type, name, group, tooltip, default, attributes)
_PROPERTIES = (
    ("App::PropertyLinkSubGlobal", "Edge", "Rod", "Space-curve edge used as the rod centreline", None, 0),
    ("App::PropertyEnumeration", "Material", "Material",
     "Material preset, or Custom to use YoungsModulus, PoissonRatio and Density", None, 0),
    ("App::PropertyPressure", "YoungsModulus", "Material", "Young's modulus (Material = Custom)", "2.3 MPa", 0),
    ("App::PropertyFloat", "PoissonRatio", "Material", "Poisson's ratio (Material = Custom)", 0.48, 0),
    ("App::PropertyFloat", "Density", "Material", "Density in kg/m^3 (Material = Custom)", 1250.0, 0),
    ("App::PropertyBool", "GravityOn", "Loads",
     "Design under the rod's own weight (gravity 9.81 m/s^2 along global -Z)", False, 0),
    ("App::PropertyLength", "MaxRadius", "Rod", "Largest mean section radius sqrt(a b)", "5 mm", 0),
    ("App::PropertyFloat", "SectionFactor", "Rod",
     "t/t*: 1 = the most circular ellipse; > 1 elongates it along the bending axis (more stable; 4 = the solver default, stable on the sample helix)", 4.0, 0),
    ("App::PropertyFloat", "WReg", "Solver", "Regularization weight w_reg of Eq. 5.19b (>= 0)", 0.0, 0),
    ("App::PropertyInteger", "Samples", "Solver", "Samples along the curve (equal arc length)", 200, 0),
    ("App::PropertyBool", "Validate", "Solver",
     "Forward-simulate the designed rod (discrete elastic rod) and report Deviation", False, 0),
    ("App::PropertyFile", "PlotFile", "Output", "Write the twist plot (PNG) here on every recompute", "", 0),
    ("App::PropertyBool", "Feasible", "Results", "True when a rod realises the curve", False, _RO),
    ("App::PropertyString", "Status", "Results", "ok, infeasible, load_infeasible, not_converged or error", "", _RO),
    ("App::PropertyString", "Reason", "Results", "Why the design failed (empty when feasible)", "", _RO),
    ("App::PropertyFloat", "R", "Results", "Normalized twist objective R of Eq. 5.19 (0 for a parallel curve)", 0.0, _RO),
    ("App::PropertyLength", "Length", "Results", "Arc length of the centreline", "0 mm", _RO),
    ("App::PropertyFloat", "TwistMax", "Results", "Largest |twist rate tau_beta| along the rod [rad/m]", 0.0, _RO),
    ("App::PropertyFloat", "BetaEnd", "Results",
     "Rotation beta of the material frame at the end relative to the parallel frame [rad]", 0.0, _RO),
    ("App::PropertyPlacement", "StartFrame", "Results",
     "Clamp at s = 0: origin at the end point, axes x = n1, y = n2, z = tangent", None, _RO),
    ("App::PropertyPlacement", "EndFrame", "Results",
     "Clamp at s = L: origin at the end point, axes x = n1, y = n2, z = tangent", None, _RO),
    ("App::PropertyInteger", "LoadIterations", "Results", "Dead-load fixed-point iterations", 0, _RO),
    ("App::PropertyFloat", "Deviation", "Results",
     "Validate: max distance of the simulated rod from the curve / length (-1 when not simulated)", -1.0, _RO),
    ("App::PropertyString", "Stability", "Results",
     "Stable, Unstable or Moved away (stable where the rod settles, but more than 1e-3 of the length "
     "from the target): inertia of the discrete rod's energy Hessian at the equilibrium reached from the "
     "design (thesis section 4.5.1 on the rod of section 5.7.4); empty when not designed", "", _RO),
    ("App::PropertyInteger", "NegativeEigenvalues", "Results",
     "Number of negative eigenvalues of that Hessian (0 when stable)", 0, _RO),
    ("App::PropertyFloat", "MinRelativeEigenvalue", "Results",
     "Smallest eigenvalue of that Hessian over its largest diagonal entry (near 0: close to buckling; "
     "0 when the simulation from the target does not converge)", 0.0, _RO),
    ("App::PropertyFloat", "EquilibriumDistance", "Results",
     "Distance of the discrete rod's equilibrium, found from the target, to the target / length "
     "(large: the rod leaves, unstable; -1 when not computed)", -1.0, _RO),
)


class RodError(RuntimeError):
    """Raised from ``execute`` to put the feature in FreeCAD's error state."""


def _solver():
    """The compiled solver module, with a useful error if absent."""
    return feature_proxy.solver_module(RodError)


def _linked_edge(obj):
    """The linked edge in global coordinates."""
    return feature_proxy.linked_edge(obj, RodError)[1]


def curve_spec(edge, scale=geometry.MM_TO_M):
    """``{"bspline": {degree, knots, poles, weights?}}`` of ``edge`` (metres)."""
    bs = geometry.edge_to_bspline(edge)
    spec = {"degree": bs.Degree, "knots": list(bs.KnotSequence),
            "poles": [[p.x * scale, p.y * scale, p.z * scale] for p in bs.getPoles()]}
    if bs.isRational():
        spec["weights"] = list(bs.getWeights())
    return {"bspline": spec}


def build_spec(obj, edge):
    """Solver input (SI units) for feature ``obj`` on ``edge``."""
    if obj.Material in PRESETS:
        material = {"preset": obj.Material}
    else:
        material = {"E": float(obj.YoungsModulus.getValueAs("Pa")), "nu": float(obj.PoissonRatio),
                    "density": float(obj.Density)}
    return {
        "curve": curve_spec(edge),
        "material": material,
        "max_radius": float(obj.MaxRadius.getValueAs("m")),
        "section": {"factor": float(obj.SectionFactor)},
        "w_reg": float(obj.WReg),
        "samples": int(obj.Samples),
        "loads": {"dead_load": bool(obj.GravityOn), "gravity": [0.0, 0.0, -9.81]},
        "validate": bool(obj.Validate),
    }


def design(obj):
    """Run the solver for ``obj``'s current inputs; returns the result dict."""
    return _solver().design_rod(build_spec(obj, _linked_edge(obj)))


class RodFeature(feature_proxy.FeatureProxy):
    """Proxy of the ``Rod`` ``Part::FeaturePython`` object."""

    TYPE = TYPE
    VERSION = VERSION
    PROPERTIES = _PROPERTIES
    ENUMERATIONS = {"Material": MATERIALS}

    def execute(self, obj):
        """Recompute the rod; on failure set the results and raise."""
        obj.Feasible = False
        obj.Status = ""
        obj.Reason = ""
        obj.R = 0.0
        obj.Length = 0.0
        obj.TwistMax = 0.0
        obj.BetaEnd = 0.0
        obj.LoadIterations = 0
        obj.Deviation = -1.0
        obj.Stability = ""
        obj.NegativeEigenvalues = 0
        obj.MinRelativeEigenvalue = 0.0
        obj.EquilibriumDistance = -1.0
        try:
            self._design(obj)
        except Exception as exc:
            if not isinstance(exc, (RodError, ValueError)):
                FreeCAD.Console.PrintError(traceback.format_exc())
            message = str(exc) or type(exc).__name__
            obj.Feasible = False
            obj.Status = obj.Status or "error"
            obj.Reason = message
            obj.Shape = Part.Shape()
            raise RodError(message) from exc

    def _design(self, obj):
        result = design(obj)
        obj.Status = result["status"]
        obj.Length = float(result["length"]) * rod_shapes.M_TO_MM
        obj.R = float(result["R"] or 0.0)
        obj.LoadIterations = int(result["load_iterations"]["iterations"])
        if obj.PlotFile:
            from . import rod_plot
            rod_plot.plot_rod(result, obj.PlotFile, obj.Label)
        if not result["feasible"]:
            raise RodError("Infeasible curve (%s): %s" % (result["status"], result.get("reason") or "no reason given"))
        obj.TwistMax = max(abs(t) for t in result["twist"])
        obj.BetaEnd = float(result["beta"][-1])
        obj.StartFrame = rod_shapes.end_placement(result["end_frames"][0])
        obj.EndFrame = rod_shapes.end_placement(result["end_frames"][1])
        if result.get("simulation"):
            obj.Deviation = float(result["simulation"]["deviation"])
        stability = result.get("stability")
        if stability:
            # "Moved away": stable where the rod settles, but farther than 1e-3 L from the
            # target (e.g. a coarse stability discretization)
            obj.Stability = {"stable": "Stable", "moved_away": "Moved away"}.get(
                stability.get("verdict"), "Stable" if stability["stable"] else "Unstable")
            obj.NegativeEigenvalues = int(stability["negative"])
            # null when the rod leaves the target (no equilibrium near it to take the Hessian at)
            mr = stability.get("min_relative")
            obj.MinRelativeEigenvalue = float(mr) if mr is not None else 0.0
            ed = stability.get("equilibrium_distance")
            obj.EquilibriumDistance = float(ed) if ed is not None else -1.0
        obj.Shape = rod_shapes.rod_shape(result)
        obj.Feasible = True
        obj.Reason = ""


def write_twist_plot(obj, path):
    """Write the twist plot of the rod ``obj`` (its current inputs) to ``path`` (PNG)."""
    from . import rod_plot
    return rod_plot.plot_rod(design(obj), path, obj.Label)


def export_step(obj, path):
    """Export the deformed and the straight rod of ``obj`` (two solids, mm) to STEP."""
    solids = obj.Shape.Solids if not obj.Shape.isNull() else []
    if len(solids) != 2:
        raise RodError("%s has no designed rod to export (recompute it; Reason: %s)"
                       % (obj.Label, obj.Reason or "-"))
    Part.makeCompound(solids).exportStep(path)
    return path


class ViewProviderRod(feature_proxy.IconViewProvider):
    """View provider of the ``Rod`` feature (GUI only)."""

    ICON = "ParaFab_Rod.svg"


def make_rod(edge_owner_obj, subname, doc=None):
    """Create a ``Rod`` feature on edge ``subname`` (e.g. ``"Edge1"``) of an object.

    The new object is not recomputed; call ``doc.recompute()``.  Returns it.
    """
    if not isinstance(subname, str) or not subname.startswith("Edge"):
        raise ValueError("subname must name an edge, e.g. 'Edge1' (got %r)" % (subname,))
    if doc is None:
        doc = edge_owner_obj.Document
    obj = doc.addObject("Part::FeaturePython", "Rod")
    RodFeature(obj)
    obj.Edge = (edge_owner_obj, [subname])
    if FreeCAD.GuiUp:
        ViewProviderRod(obj.ViewObject)
        obj.ViewObject.ShapeColor = (0.55, 0.75, 0.95)
        obj.ViewObject.LineColor = (0.1, 0.2, 0.4)
    return obj
