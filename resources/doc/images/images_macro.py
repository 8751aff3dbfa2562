"""FreeCAD macro of make_images.sh: rod.png and optimize.png (the GUI smoke test makes the others).

Run under Xvfb as ``freecad images_macro.py`` with the workbench installed in FreeCAD's user Mod
folder, as tests/gui/gui_smoke.sh runs its macro. Environment: PARAFAB_ARTIFACT_DIR (output),
PARAFAB_SAMPLES_DIR, PARAFAB_WRENCH_OUT (the folder ``parafab optimize`` wrote for the main
job's wrench: ``history.json``, ``optimized.step``).

* rod.png: a ``Rod`` feature with its defaults (SectionFactor 4: the stable helix rod of
  tests/freecad/test_rod_feature.py) on the curve of ``samples/rods/helix.json`` (metres,
  interpolated here in mm): the designed rod, the straight rod and the clamp frames.
* optimize.png: the wrench before (grey, moved aside) and after, the optimized solid added by
  the workbench's own ``optimize_feature.add_result`` (faces coloured by how far they moved,
  with the colour scale ``Face moved [mm]``), as "Optimize shape" adds it.

Writes ``images_status.json`` and leaves FreeCAD with ``os._exit`` (0 = both pictures made).
"""
import json
import os
import traceback

import FreeCAD
import FreeCADGui
import Part

OUT = os.environ["PARAFAB_ARTIFACT_DIR"]
SAMPLES = os.environ["PARAFAB_SAMPLES_DIR"]
WRENCH_OUT = os.environ["PARAFAB_WRENCH_OUT"]


def screenshot(doc, name):
    view = FreeCADGui.getDocument(doc.Name).activeView()
    view.viewIsometric()
    view.fitAll()
    FreeCADGui.updateGui()
    path = os.path.join(OUT, name)
    view.saveImage(path, 1280, 1024, "White")
    return path


def rod_picture():
    from parafab_wb import rod_feature
    with open(os.path.join(SAMPLES, "rods", "helix.json")) as f:
        points = json.load(f)["curve"]["points"]
    doc = FreeCAD.newDocument("Rod")
    curve = Part.BSplineCurve()
    curve.interpolate([FreeCAD.Vector(*(1000.0 * c for c in p)) for p in points])
    owner = doc.addObject("Part::Feature", "Helix")
    owner.Shape = curve.toShape()
    rod = rod_feature.make_rod(owner, "Edge1", doc)
    doc.recompute()
    if not rod.Feasible or len(rod.Shape.Solids) != 2:
        raise AssertionError("rod: feasible %s, %d solids: %s" % (rod.Feasible, len(rod.Shape.Solids),
                                                                    rod.getStatusString()))
    return {"rod": screenshot(doc, "rod.png"), "rod_R": rod.R}


def optimize_picture():
    from parafab_wb import optimize_feature
    with open(os.path.join(WRENCH_OUT, "history.json")) as f:
        history = json.load(f)
    doc = FreeCAD.newDocument("Wrench")
    part = doc.addObject("Part::Feature", "Wrench")
    part.Shape = Part.read(os.path.join(SAMPLES, "parts", "wrench.step"))
    doc.recompute()
    new = optimize_feature.add_result(part, history, WRENCH_OUT)
    moved = list(new.FaceMoved)
    if not moved or max(moved) <= 0:
        raise AssertionError("no face moved: %s" % moved)
    # Before beside after: the original opaque and grey, one wrench width (+ a gap) away.
    box = part.Shape.BoundBox
    part.Placement.Base = FreeCAD.Vector(0, -(box.YLength + 0.3 * box.YLength), 0)
    part.ViewObject.Transparency = 0
    part.ViewObject.ShapeColor = (0.75, 0.75, 0.75)
    doc.recompute()
    return {"optimize": screenshot(doc, "optimize.png"), "face_moved_max_mm": max(moved),
            "objective": [history.get("initial_objective"), history.get("final_objective")]}


def main():
    status = {"status": "fail"}
    try:
        FreeCADGui.activateWorkbench("ParaFabWorkbench")
        info = rod_picture()
        info.update(optimize_picture())
        status = {"status": "pass", "info": info}
    except Exception:
        status["error"] = traceback.format_exc()
    with open(os.path.join(OUT, "images_status.json"), "w") as f:
        json.dump(status, f, indent=2)
    os._exit(0 if status["status"] == "pass" else 1)


main()
