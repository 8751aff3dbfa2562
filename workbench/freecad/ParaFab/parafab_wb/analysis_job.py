"""The inputs, the solver job and the results of an ``Analysis`` feature (thesis §6.4).

Everything of the feature but its proxy class (:mod:`parafab_wb.analysis_feature`): the
property table, the inputs as a plain dict (what the task panel edits), the ``parafab simulate``
job built from them, the size estimate, and the results written into the feature, by a
recompute (:func:`store_results`) or by a run of the CLI (:func:`apply_run`). No Qt and no
FreeCADGui: the feature module, the run object (:mod:`parafab_wb.cli_runner`) and the task panel
all import this module, and it imports none of them.

FreeCAD's ``FaceN`` is ParaFab's face index N − 1 (both number faces in TopExp order).
"""

import os
import tempfile

import FreeCAD

from . import outcome as run_outcome
from . import result_display

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
#: The first word of ``Status`` after a cancelled run (in-process or through the CLI).
CANCELLED = run_outcome.CANCELLED


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


def apply_run(obj, inputs, outcome, out_dir=None):
    """Record a run made outside a recompute (the task panel's CLI process) in feature ``obj``.

    ``outcome`` is an :class:`outcome.Outcome`: SOLVED (``inputs`` and ``outcome.result`` are
    stored and the feature is marked up to date), CANCELLED or ERROR (only ``Status`` changes:
    the document keeps its previous inputs and results).
    """
    if outcome.state == run_outcome.SOLVED:
        apply_inputs(obj, inputs)
        store_results(obj, outcome.result, out_dir)
        obj.purgeTouched()
    elif outcome.state == run_outcome.CANCELLED:
        obj.Status = "%s by the user%s" % (CANCELLED, " (previous results kept)" if obj.Dofs else "")
    else:
        obj.Status = "error: %s" % outcome.message


def cancelled_status(message):
    """``Status`` of a recompute cancelled from the progress callback (parafab.Cancelled)."""
    return "%s: %s (previous results kept)" % (CANCELLED, message)


def _default_output_dir(obj):
    doc_file = obj.Document.FileName
    base = os.path.dirname(doc_file) if doc_file else tempfile.gettempdir()
    return os.path.join(base, "%s_%s" % (obj.Document.Name, obj.Name))

