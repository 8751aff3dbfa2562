"""The ParaFab ``Analysis`` feature: linear or hyperelastic XFEM on a solid (thesis §6.4).

``make_analysis(part_obj, fixed=["Face1"], loaded=["Face6"], force=(0, 0, -500))`` creates a
``Part::FeaturePython`` that, on recompute, exports the part's shape as BREP, runs
``parafab.simulate`` (units: mm, N, MPa, t/mm³), stores the results (``Dofs``,
``MaxDisplacement``, ``MaxVonMises``, ``Estimate``) and writes ``result.json``, ``result.vtu``
and ``surface.vtu`` into ``OutputDir`` (default: a folder named after the feature beside the
saved document). Its shape is a copy of the part, so the tree shows what was analysed.

The result is shown by a child ``Mesh::Feature`` (``ResultMesh``, see
:mod:`parafab_wb.result_display`): the part's surface moved by ``DeformationScale`` times the
displacement and coloured by von Mises stress from ``ColorScaleMin`` (blue) to
``ColorScaleMax`` (red). ``AutoScale`` picks the scale at which the largest displacement shows
as 5 % of the part's diagonal; setting ``DeformationScale`` turns it off. Neither re-runs the
solver.

The task panel (:mod:`parafab_wb.analysis_panel`) runs the ``parafab`` CLI in a separate
process instead and hands its result to :func:`apply_run`; a cancelled run changes nothing but
``Status``. A recompute runs the solver in-process; the proxy's transient ``progress``
attribute, when set, is called as ``progress(phase, fraction)`` and cancels the run by
returning False (previous results are kept, the feature is left in the error state with
``Status`` "cancelled ..." so the next recompute runs again).

FreeCAD's ``FaceN`` is ParaFab's face index N − 1 (both number faces in TopExp order).
Failures put the feature in FreeCAD's error state with the solver's message in ``Status``;
the document stays valid.
"""

import os
import tempfile

import FreeCAD
import Part

from . import feature_proxy
from . import result_display

TYPE = "ParaFab::Analysis"
VERSION = 4
_READ_ONLY, _OUTPUT = feature_proxy.READ_ONLY, feature_proxy.OUTPUT

_PROPERTIES = (
    ("App::PropertyLink", "Part", "Analysis", "Solid to analyse", None, 0),
    ("App::PropertyStringList", "FixedFaces", "Analysis", "Faces held fixed (Face1, Face2, ...)", None, 0),
    ("App::PropertyStringList", "LoadedFaces", "Analysis", "Faces carrying the force", None, 0),
    ("App::PropertyVector", "Force", "Analysis", "Total force on the loaded faces [N]", None, 0),
    ("App::PropertyBool", "Gravity", "Analysis", "Add the part's weight (−z)", False, 0),
    ("App::PropertyPressure", "YoungsModulus", "Material", "Young's modulus", "210 GPa", 0),
    ("App::PropertyFloat", "PoissonRatio", "Material", "Poisson's ratio", 0.3, 0),
    ("App::PropertyFloat", "Density", "Material", "Density [kg/m^3]", 7850.0, 0),
    ("App::PropertyEnumeration", "Model", "Material", "Material law", None, 0),
    ("App::PropertyInteger", "Cells", "Grid", "Cells along the longest side", 8, 0),
    ("App::PropertyPath", "OutputDir", "Output", "Folder for result.json and result.vtu", "", 0),
    ("App::PropertyInteger", "Dofs", "Results", "Unknowns solved for", 0, _READ_ONLY | _OUTPUT),
    ("App::PropertyLength", "MaxDisplacement", "Results", "Largest displacement", "0 mm", _READ_ONLY | _OUTPUT),
    ("App::PropertyPressure", "MaxVonMises", "Results", "Largest von Mises stress", "0 MPa", _READ_ONLY | _OUTPUT),
    ("App::PropertyString", "Status", "Results", "Solver message or error", "", _READ_ONLY | _OUTPUT),
    # Version 2: result display and the size estimate.
    ("App::PropertyString", "Estimate", "Results", "Size of the last run: unknowns and factorization memory",
     "", _READ_ONLY | _OUTPUT),
    ("App::PropertyLink", "ResultMesh", "Results", "Deformed part coloured by von Mises stress", None,
     _READ_ONLY | _OUTPUT),
    ("App::PropertyBool", "AutoScale", "Display",
     "Choose DeformationScale so the largest displacement shows as 5 % of the part's diagonal", True, _OUTPUT),
    ("App::PropertyFloat", "DeformationScale", "Display",
     "Displacement magnification of the result mesh (setting it turns AutoScale off)", 0.0, _OUTPUT),
    ("App::PropertyPressure", "ColorScaleMin", "Display", "von Mises stress shown blue (smallest on the surface)",
     "0 MPa", _READ_ONLY | _OUTPUT),
    ("App::PropertyPressure", "ColorScaleMax", "Display", "von Mises stress shown red (largest on the surface)",
     "0 MPa", _READ_ONLY | _OUTPUT),
    # Version 3: the element (documents of versions 1-2 ran hex8 and keep it, see onDocumentRestored).
    ("App::PropertyEnumeration", "Element", "Grid",
     "hex27: triquadratic (the default, more accurate per unknown); hex8: trilinear", None, 0),
    # Version 4: how the fixed faces are held (documents of versions 1-3 ran "fixed" and keep it;
    # new analyses get "auto", the solver's default since 2026-11-28).
    ("App::PropertyEnumeration", "NitschePenalty", "Grid",
     "How the fixed faces are held on cut cells. auto (the default): local for the linear model "
     "on hex27, fixed for hex8 and for rubber. local: from each cut cell's eigenvalue, stable on cut cells but the "
     "thinnest slivers, and without locking (more accurate on coarse grids; converges where "
     "'fixed' fails with rubber, though less accurate there); fixed: penalty 100 E/h", None, 0),
)
MODELS = ["linear", "neo_hooke", "neo_hooke_isochoric", "mooney_rivlin"]
ELEMENTS = ["hex27", "hex8"]
PENALTIES = ["fixed", "local", "auto"]  # saved documents index this order: append only
#: "auto" leaves the choice to the solver: local for the linear model on hex27, fixed (β = 100)
#: for hex8 (soft with local on thin parts) and for the hyperelastic models, whose linearized
#: Nitsche terms lose accuracy with the smaller local penalty.
DEFAULT_PENALTY = "auto"

#: Material presets of the task panel: E [MPa], nu, density [kg/m^3], model.
MATERIALS = (
    ("Steel", {"E": 210000.0, "nu": 0.3, "density": 7850.0, "model": "linear"}),
    ("Aluminium", {"E": 70000.0, "nu": 0.33, "density": 2700.0, "model": "linear"}),
    ("ABS/PLA-like plastic", {"E": 2300.0, "nu": 0.35, "density": 1200.0, "model": "linear"}),
    ("Silicone rubber (neo-Hooke)", {"E": 2.3, "nu": 0.45, "density": 1100.0, "model": "neo_hooke"}),
)
CANCELLED = "cancelled"


class AnalysisError(RuntimeError):
    """Raised from ``execute`` to put the feature in FreeCAD's error state."""


def _face_indices(names, part_obj, what):
    indices = []
    n = len(part_obj.Shape.Faces)
    for name in names:
        if not name.startswith("Face") or not name[4:].isdigit() or not 1 <= int(name[4:]) <= n:
            raise AnalysisError("%s: '%s' is not a face of %s (Face1..Face%d)" % (what, name, part_obj.Label, n))
        indices.append(int(name[4:]) - 1)
    return indices


def inputs_of(obj):
    """The analysis inputs of feature ``obj`` as a plain dict (what the task panel edits)."""
    f = obj.Force
    return {"fixed": list(obj.FixedFaces), "loaded": list(obj.LoadedFaces), "force": (f.x, f.y, f.z),
            "gravity": bool(obj.Gravity), "E": float(obj.YoungsModulus.getValueAs("MPa")),
            "nu": float(obj.PoissonRatio), "density": float(obj.Density), "model": obj.Model,
            "cells": int(obj.Cells), "element": obj.Element, "nitsche_penalty": obj.NitschePenalty,
            "output_dir": obj.OutputDir}


def apply_inputs(obj, inputs):
    """Write ``inputs`` (see :func:`inputs_of`) into feature ``obj``."""
    obj.FixedFaces = list(inputs["fixed"])
    obj.LoadedFaces = list(inputs["loaded"])
    obj.Force = FreeCAD.Vector(*inputs["force"])
    obj.Gravity = bool(inputs["gravity"])
    obj.YoungsModulus = FreeCAD.Units.Quantity("%r MPa" % float(inputs["E"]))
    obj.PoissonRatio = float(inputs["nu"])
    obj.Density = float(inputs["density"])
    obj.Model = inputs["model"]
    obj.Cells = int(inputs["cells"])
    obj.Element = inputs.get("element", ELEMENTS[0])
    obj.NitschePenalty = inputs.get("nitsche_penalty", DEFAULT_PENALTY)
    obj.OutputDir = inputs.get("output_dir") or ""


def job_from_inputs(part_obj, inputs):
    """The parafab.simulate job (mm, N, MPa, t/mm³) for ``inputs`` on ``part_obj``."""
    if part_obj is None:
        raise AnalysisError("No part linked: set the 'Part' property")
    if not inputs["fixed"]:
        raise AnalysisError("No fixed faces: the part would float freely (set 'FixedFaces')")
    fixed = _face_indices(inputs["fixed"], part_obj, "FixedFaces")
    loaded = _face_indices(inputs["loaded"], part_obj, "LoadedFaces")
    area = sum(part_obj.Shape.Faces[i].Area for i in loaded)
    fx, fy, fz = inputs["force"]
    job = {
        "material": {"E": float(inputs["E"]), "nu": float(inputs["nu"]),
                     "density": float(inputs["density"]) * 1e-12, "model": inputs["model"]},
        "element": inputs.get("element", ELEMENTS[0]),
        "grid": {"cells": int(inputs["cells"])},
        "supports": [{"face": i} for i in fixed],
        # The total force is spread over all loaded faces by area.
        "loads": [{"face": i, "traction": [fx / area, fy / area, fz / area]} for i in loaded]
        if loaded and area > 0 else [],
    }
    penalty = inputs.get("nitsche_penalty", DEFAULT_PENALTY)
    if penalty != "auto":
        job["nitsche_penalty"] = penalty
    if inputs["gravity"]:
        job["gravity"] = [0, 0, -9810.0]
    return job


def build_job(obj):
    """The parafab.simulate job (mm, N, MPa, t/mm³) for feature ``obj``."""
    return job_from_inputs(obj.Part, inputs_of(obj))


def estimate(part_obj, cells, element=ELEMENTS[0]):
    """``(unknowns, factor_mb)`` of a run with ``cells`` ``element`` cells along the longest side.

    Shown by the task panel before a run; the solver's own estimate
    (``parafab.Simulation(...).estimate()``, the figures it refuses a run with), on the part
    exported as BREP. ``(0, 0)`` when the part cannot be read.
    """
    import parafab
    job = {"material": {"E": 1.0, "nu": 0.3}, "element": element, "grid": {"cells": max(int(cells), 1)},
           "supports": [{"face": 0}]}
    try:
        with tempfile.TemporaryDirectory() as tmp:
            brep = os.path.join(tmp, "part.brep")
            part_obj.Shape.exportBrep(brep)
            est = parafab.Simulation(brep, job).estimate()
    except Exception:  # an invalid part: the run itself reports why
        return 0.0, 0.0
    return float(est["unknowns"]), float(est["factor_mb"])


def output_dir(obj, inputs=None):
    """Where the results of ``obj`` go: ``OutputDir`` or a folder beside the document."""
    folder = (inputs or {}).get("output_dir") if inputs else obj.OutputDir
    return folder or _default_output_dir(obj)


def is_cancelled(message):
    """True for parafab's "simulation cancelled by the user" error."""
    return "cancelled by the user" in message


class AnalysisFeature(feature_proxy.FeatureProxy):
    """Proxy of the ``Analysis`` ``Part::FeaturePython``."""

    TYPE = TYPE
    VERSION = VERSION
    PROPERTIES = _PROPERTIES
    ENUMERATIONS = {"Model": MODELS, "Element": ELEMENTS, "NitschePenalty": PENALTIES}

    #: Transient (not saved): ``progress(phase, fraction)`` during an in-process run;
    #: returning False cancels it.
    progress = None
    _quiet = False

    def __init__(self, obj):
        super(AnalysisFeature, self).__init__(obj)
        obj.NitschePenalty = DEFAULT_PENALTY  # new analyses; restored ones keep theirs

    def onDocumentRestored(self, obj):
        had_element = "Element" in obj.PropertiesList
        had_penalty = "NitschePenalty" in obj.PropertiesList
        super(AnalysisFeature, self).onDocumentRestored(obj)
        if not had_element:  # saved before the element choice: those runs were hex8; keep their results
            obj.Element = "hex8"
        if not had_penalty:  # saved before the penalty choice: those runs held faces by β E/h
            obj.NitschePenalty = "fixed"
        if FreeCAD.GuiUp and obj.ViewObject is not None and not obj.ViewObject.Proxy:
            ViewProviderAnalysis(obj.ViewObject)  # documents saved before the task panel existed

    def onChanged(self, obj, prop):
        if self._quiet or prop not in ("DeformationScale", "AutoScale") or "Restore" in obj.State:
            return
        if not hasattr(obj, "ResultMesh") or obj.ResultMesh is None:
            return
        if prop == "DeformationScale":
            self._set_quietly(obj, "AutoScale", False)
            result_display.rescale(obj.ResultMesh, obj.DeformationScale)
        elif obj.AutoScale:
            mesh = obj.ResultMesh
            scale = result_display.auto_scale(getattr(mesh, "Displacement", []),
                                              obj.Part.Shape.BoundBox.DiagonalLength if obj.Part else 0.0)
            self._set_quietly(obj, "DeformationScale", scale)
            result_display.rescale(mesh, scale)

    def _set_quietly(self, obj, prop, value):
        self._quiet = True
        try:
            setattr(obj, prop, value)
        finally:
            self._quiet = False

    def _report(self, phase, fraction):
        if self.progress is not None:
            return self.progress(phase, fraction) is not False
        FreeCAD.Console.PrintLog("ParaFab: %s %.0f %%\n" % (phase, 100 * fraction))
        return True

    def execute(self, obj):
        obj.Status = ""
        try:
            import parafab
            job = build_job(obj)
            out_dir = output_dir(obj)
            with tempfile.TemporaryDirectory() as tmp:
                brep = os.path.join(tmp, "part.brep")
                obj.Part.Shape.exportBrep(brep)
                result = parafab.simulate(brep, job, out_dir, progress=self._report)
            store_results(obj, result, out_dir)
        except Exception as exc:  # solver errors (parafab.Error is a ValueError) and ours
            message = str(exc) or type(exc).__name__
            if is_cancelled(message):
                # Keep the previous results; the error state makes the next recompute run again.
                obj.Status = "%s: %s (previous results kept)" % (CANCELLED, message)
            else:
                obj.Status = message
                obj.Shape = Part.Shape()
                if getattr(obj, "ResultMesh", None) is not None:
                    result_display.clear(obj.ResultMesh)
            raise AnalysisError(obj.Status) from exc

    def update_display(self, obj, surface):
        """Show ``surface`` (a :class:`result_display.SurfaceResult`) in the result mesh at the
        current or automatic scale; returns the (min, max) von Mises of the colour scale."""
        scale = obj.DeformationScale
        if obj.AutoScale or scale <= 0:
            scale = result_display.auto_scale(surface.displacement, obj.Part.Shape.BoundBox.DiagonalLength)
        self._set_quietly(obj, "DeformationScale", scale)
        if obj.ResultMesh is None:
            obj.ResultMesh = result_display.create_result_mesh(obj)
        lo, hi = result_display.show_surface(obj.ResultMesh, surface, scale)
        obj.ColorScaleMin = FreeCAD.Units.Quantity("%r MPa" % lo)
        obj.ColorScaleMax = FreeCAD.Units.Quantity("%r MPa" % hi)
        return lo, hi


def store_results(obj, result, out_dir):
    """Put a solver ``result`` (and ``out_dir/surface.vtu``) into feature ``obj``."""
    surface = result_display.read_surface(os.path.join(out_dir, result_display.SURFACE_FILE))
    obj.Dofs = int(result["dofs"])
    obj.MaxDisplacement = float(result["max_displacement"])
    obj.MaxVonMises = FreeCAD.Units.Quantity("%r MPa" % result["max_von_mises"])
    est = result.get("estimate") or {}
    obj.Estimate = ("%d unknowns, %.0f MB" % (est["unknowns"], est["factor_mb"])
                    if "unknowns" in est and "factor_mb" in est else "")
    lo, hi = obj.Proxy.update_display(obj, surface)
    obj.Status = ("solved: %s; von Mises %.3g MPa (blue) to %.3g MPa (red) on the surface, deformation x %.3g"
                  % (os.path.join(out_dir, "result.vtu"), lo, hi, obj.DeformationScale))
    obj.Shape = obj.Part.Shape.copy()
    if FreeCAD.GuiUp and obj.ViewObject is not None:
        obj.ViewObject.DisplayMode = "Wireframe"  # the undeformed outline around the coloured mesh
        obj.Part.ViewObject.Visibility = False


def apply_run(obj, inputs, outcome, result=None, out_dir=None, message=""):
    """Record a run made outside a recompute (the task panel's CLI process) in feature ``obj``.

    ``outcome`` is "solved" (``inputs`` and ``result`` are stored and the feature is marked up to
    date), CANCELLED or "error" (only ``Status`` changes: the document keeps its previous inputs
    and results).
    """
    if outcome == "solved":
        apply_inputs(obj, inputs)
        store_results(obj, result, out_dir)
        obj.purgeTouched()
    elif outcome == CANCELLED:
        obj.Status = "%s by the user%s" % (CANCELLED, " (previous results kept)" if obj.Dofs else "")
    else:
        obj.Status = "error: %s" % message


class ViewProviderAnalysis(feature_proxy.IconViewProvider):
    """View provider of the ``Analysis`` feature (GUI only): icon, the result mesh as its child,
    and the task panel on double-click."""

    ICON = "ParaFab_Analysis.svg"

    def claimChildren(self):
        mesh = getattr(self.Object, "ResultMesh", None)
        return [mesh] if mesh is not None else []

    def updateData(self, obj, prop):
        # The colour scale lives in the view only: put it back when a document is reopened.
        if prop in ("ResultMesh", "ColorScaleMax"):
            result_display.show_legend(getattr(obj, "ResultMesh", None))

    def finishRestoring(self):
        obj = getattr(self, "Object", None)
        if obj is not None:
            result_display.show_legend(getattr(obj, "ResultMesh", None))

    def setEdit(self, vobj, mode=0):
        if mode != 0:
            return None
        from . import analysis_panel
        return analysis_panel.open_panel(vobj.Object)

    def unsetEdit(self, vobj, mode=0):
        if mode != 0:
            return None
        import FreeCADGui
        FreeCADGui.Control.closeDialog()
        return True

    def doubleClicked(self, vobj):
        import FreeCADGui
        FreeCADGui.getDocument(vobj.Object.Document.Name).setEdit(vobj.Object.Name, 0)
        return True

    def onDelete(self, vobj, subelements):
        mesh = getattr(vobj.Object, "ResultMesh", None)
        if mesh is not None:
            vobj.Object.ResultMesh = None
            mesh.Document.removeObject(mesh.Name)
        return True



def _default_output_dir(obj):
    doc_file = obj.Document.FileName
    base = os.path.dirname(doc_file) if doc_file else tempfile.gettempdir()
    return os.path.join(base, "%s_%s" % (obj.Document.Name, obj.Name))


def make_analysis(part_obj, fixed, loaded=(), force=(0, 0, 0), doc=None):
    """Create an ``Analysis`` of ``part_obj`` and its (empty) result mesh; not recomputed, call
    ``doc.recompute()`` or run it from the task panel. The part stays visible (its faces are
    picked in the 3D view) until results are shown."""
    doc = doc or part_obj.Document
    obj = doc.addObject("Part::FeaturePython", "Analysis")
    AnalysisFeature(obj)
    obj.Part = part_obj
    obj.FixedFaces = list(fixed)
    obj.LoadedFaces = list(loaded)
    obj.Force = FreeCAD.Vector(*force)
    obj.ResultMesh = result_display.create_result_mesh(obj)
    if FreeCAD.GuiUp:
        ViewProviderAnalysis(obj.ViewObject)
        obj.ViewObject.ShapeColor = (0.4, 0.6, 0.9)
    return obj
