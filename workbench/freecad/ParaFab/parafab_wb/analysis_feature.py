"""The ParaFab ``Analysis`` feature: linear or hyperelastic XFEM on a solid (thesis §6.4).

``make_analysis(part_obj, fixed=["Face1"], loaded=["Face6"], force=(0, 0, -500))`` creates a
``Part::FeaturePython`` that, on recompute, exports the part's shape as BREP, runs
``parafab.simulate`` (units: mm, N, MPa, t/mm³), stores the results (``Dofs``,
``MaxDisplacement``, ``MaxVonMises``) and writes ``result.json`` and ``result.vtu`` into
``OutputDir`` (default: a folder named after the feature beside the saved document). Its
shape is the part moved by nothing: a copy, so the tree shows what was analysed.

FreeCAD's ``FaceN`` is ParaFab's face index N − 1 (both number faces in TopExp order).
Failures put the feature in FreeCAD's error state with the solver's message in ``Status``;
the document stays valid.
"""

import json
import os
import tempfile

import FreeCAD
import Part

from . import feature_proxy

TYPE = "ParaFab::Analysis"
VERSION = 1
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
    ("App::PropertyInteger", "Cells", "Grid", "Cells along the longest side", 16, 0),
    ("App::PropertyPath", "OutputDir", "Output", "Folder for result.json and result.vtu", "", 0),
    ("App::PropertyInteger", "Dofs", "Results", "Unknowns solved for", 0, _READ_ONLY | _OUTPUT),
    ("App::PropertyLength", "MaxDisplacement", "Results", "Largest displacement", "0 mm", _READ_ONLY | _OUTPUT),
    ("App::PropertyPressure", "MaxVonMises", "Results", "Largest von Mises stress", "0 MPa", _READ_ONLY | _OUTPUT),
    ("App::PropertyString", "Status", "Results", "Solver message or error", "", _READ_ONLY | _OUTPUT),
)
MODELS = ["linear", "neo_hooke", "neo_hooke_isochoric", "mooney_rivlin"]


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


def build_job(obj):
    """The parafab.simulate job (mm, N, MPa, t/mm³) for feature ``obj``."""
    if obj.Part is None:
        raise AnalysisError("No part linked: set the 'Part' property")
    if not obj.FixedFaces:
        raise AnalysisError("No fixed faces: the part would float freely (set 'FixedFaces')")
    fixed = _face_indices(obj.FixedFaces, obj.Part, "FixedFaces")
    loaded = _face_indices(obj.LoadedFaces, obj.Part, "LoadedFaces")
    area = sum(obj.Part.Shape.Faces[i].Area for i in loaded)
    force = obj.Force
    job = {
        "material": {"E": float(obj.YoungsModulus.getValueAs("MPa")), "nu": float(obj.PoissonRatio),
                     "density": float(obj.Density) * 1e-12, "model": obj.Model},
        "grid": {"cells": int(obj.Cells)},
        "supports": [{"face": i} for i in fixed],
        # The total force is spread over all loaded faces by area.
        "loads": [{"face": i, "traction": [force.x / area, force.y / area, force.z / area]} for i in loaded]
        if loaded and area > 0 else [],
    }
    if obj.Gravity:
        job["gravity"] = [0, 0, -9810.0]
    return job


class AnalysisFeature(feature_proxy.FeatureProxy):
    """Proxy of the ``Analysis`` ``Part::FeaturePython``."""

    TYPE = TYPE
    VERSION = VERSION
    PROPERTIES = _PROPERTIES
    ENUMERATIONS = {"Model": MODELS}

    def execute(self, obj):
        obj.Status = ""
        try:
            import parafab
            job = build_job(obj)
            out_dir = obj.OutputDir or _default_output_dir(obj)
            with tempfile.TemporaryDirectory() as tmp:
                brep = os.path.join(tmp, "part.brep")
                obj.Part.Shape.exportBrep(brep)
                result = parafab.simulate(brep, job, out_dir)
        except Exception as exc:  # solver errors (parafab.Error is a ValueError) and ours
            obj.Status = str(exc) or type(exc).__name__
            obj.Shape = Part.Shape()
            raise AnalysisError(obj.Status) from exc
        obj.Dofs = int(result["dofs"])
        obj.MaxDisplacement = float(result["max_displacement"])
        obj.MaxVonMises = FreeCAD.Units.Quantity("%r MPa" % result["max_von_mises"])
        obj.Status = "solved: %s" % os.path.join(out_dir, "result.vtu")
        obj.Shape = obj.Part.Shape.copy()


def _default_output_dir(obj):
    doc_file = obj.Document.FileName
    base = os.path.dirname(doc_file) if doc_file else tempfile.gettempdir()
    return os.path.join(base, "%s_%s" % (obj.Document.Name, obj.Name))


def make_analysis(part_obj, fixed, loaded=(), force=(0, 0, 0), doc=None):
    """Create an ``Analysis`` of ``part_obj`` (not recomputed; call ``doc.recompute()``)."""
    doc = doc or part_obj.Document
    obj = doc.addObject("Part::FeaturePython", "Analysis")
    AnalysisFeature(obj)
    obj.Part = part_obj
    obj.FixedFaces = list(fixed)
    obj.LoadedFaces = list(loaded)
    obj.Force = FreeCAD.Vector(*force)
    if FreeCAD.GuiUp:
        obj.ViewObject.Proxy = 0
        obj.ViewObject.ShapeColor = (0.4, 0.6, 0.9)
        part_obj.ViewObject.Visibility = False
    return obj
