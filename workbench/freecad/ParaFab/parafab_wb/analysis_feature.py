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
process instead (:class:`parafab_wb.cli_runner.AnalysisRun`) and hands its outcome to
:func:`apply_run`; a cancelled run changes nothing but ``Status``. A recompute runs the solver
in-process; the proxy's transient ``progress`` attribute, when set, is called as
``progress(phase, fraction)`` and cancels the run by returning False (``parafab.simulate`` then
raises ``parafab.Cancelled``: previous results are kept, the feature is left in the error state
with ``Status`` "cancelled ..." so the next recompute runs again).

This module is the document object only (the ``AnalysisFeature`` proxy and
:func:`make_analysis`); the inputs, job and results are :mod:`parafab_wb.analysis_job` (its
names are re-exported here), the view provider :mod:`parafab_wb.analysis_view` (GUI only,
imported only when the GUI is up). Neither Qt nor FreeCADGui is imported here: FreeCAD imports
this module to restore documents, also headless.

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
from .analysis_job import (  # noqa: F401  (re-exported: the feature's API before analysis_job)
    CANCELLED, DEFAULT_PENALTY, ELEMENTS, MATERIALS, MODELS, PENALTIES, AnalysisError, apply_inputs, apply_run,
    build_job, cancelled_status, estimate, inputs_of, job_from_inputs, output_dir, store_results)

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
            _view_provider()(obj.ViewObject)  # documents saved before the task panel existed

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
        cancelled = None
        try:
            parafab = feature_proxy.solver_module(AnalysisError)
            job = build_job(obj)
            out_dir = output_dir(obj)
            with tempfile.TemporaryDirectory() as tmp:
                brep = os.path.join(tmp, "part.brep")
                obj.Part.Shape.exportBrep(brep)
                try:
                    result = parafab.simulate(brep, job, out_dir, progress=self._report)
                except parafab.Cancelled as exc:  # the progress callback returned False
                    cancelled = exc
            if cancelled is None:
                store_results(obj, result, out_dir)
        except Exception as exc:  # solver errors (parafab.Error is a ValueError) and ours
            obj.Status = str(exc) or type(exc).__name__
            obj.Shape = Part.Shape()
            if getattr(obj, "ResultMesh", None) is not None:
                result_display.clear(obj.ResultMesh)
            raise AnalysisError(obj.Status) from exc
        if cancelled is not None:
            # Keep the previous results; the error state makes the next recompute run again.
            obj.Status = cancelled_status(str(cancelled))
            raise AnalysisError(obj.Status) from cancelled

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


def _view_provider():
    """The view provider class (GUI only; imported here, never at module level)."""
    from . import analysis_view
    return analysis_view.ViewProviderAnalysis


def __getattr__(name):
    """``ViewProviderAnalysis``: documents saved before the view provider moved to
    :mod:`parafab_wb.analysis_view` name it ``parafab_wb.analysis_feature.ViewProviderAnalysis``."""
    if name == "ViewProviderAnalysis":
        return _view_provider()
    raise AttributeError("module %r has no attribute %r" % (__name__, name))


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
        _view_provider()(obj.ViewObject)
        obj.ViewObject.ShapeColor = (0.4, 0.6, 0.9)
    return obj
