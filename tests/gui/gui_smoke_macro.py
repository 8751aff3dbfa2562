"""GUI smoke test of the ParaFab workbench (FreeCAD macro).

Run by ``tests/gui/gui_smoke.sh`` as ``freecad gui_smoke_macro.py`` under
Xvfb, with the workbench installed in FreeCAD's user Mod directory.  Steps:

1. activate the ParaFab workbench, check its command, toolbar and menu;
2. create a sketch holding a B-spline, select its edge;
3. run ``ParaFab_Strip`` through ``FreeCADGui.runCommand``, recompute;
4. fit the view and save a screenshot; check the strip's colour is visible;
5. save, close and reopen the document; recompute.

Results go to ``$PARAFAB_ARTIFACT_DIR`` (``status.json``, ``strip.png``).
FreeCAD is then left with ``os._exit`` (0 = pass, 1 = fail), so no dialog
("save changes?") can block the run.
"""

import json
import os
import tempfile
import traceback

import FreeCAD
import FreeCADGui
import Part

ARTIFACT_DIR = os.environ.get("PARAFAB_ARTIFACT_DIR") or tempfile.mkdtemp()
STATUS_FILE = os.path.join(ARTIFACT_DIR, "status.json")
SCREENSHOT = os.path.join(ARTIFACT_DIR, "strip.png")
DOCUMENT = os.path.join(ARTIFACT_DIR, "gui_smoke.FCStd")

#: Minimum number of strip-coloured pixels expected in the screenshot.
MIN_STRIP_PIXELS = 2000


class Checks(object):
    """Named checks recorded for the status file."""

    def __init__(self):
        self.results = {}

    def __call__(self, name, condition, detail=""):
        self.results[name] = bool(condition)
        if not condition:
            raise AssertionError("%s failed %s" % (name, detail))


def strip_pixels(path):
    """Count orange (strip colour) pixels in the PNG at ``path``."""
    from PySide2 import QtGui
    image = QtGui.QImage(path)
    count = 0
    for y in range(0, image.height(), 2):
        for x in range(0, image.width(), 2):
            c = QtGui.QColor(image.pixel(x, y))
            if c.red() > 120 and c.red() - c.blue() > 80 and c.green() > 40:
                count += 1
    return count * 4


def run(check):
    """The smoke test proper; raises on the first failed check."""
    FreeCADGui.activateWorkbench("ParaFabWorkbench")
    wb = FreeCADGui.activeWorkbench()
    check("workbench_active", wb.name() == "ParaFabWorkbench", wb.name())
    check("workbench_icon", os.path.isfile(wb.Icon), wb.Icon)
    check("command_registered", "ParaFab_Strip" in FreeCADGui.listCommands())
    check("rod_command_registered", "ParaFab_Rod" in FreeCADGui.listCommands())
    check("toolbar", "ParaFab" in wb.listToolbars(), wb.listToolbars())
    check("menu", "ParaFab" in wb.listMenus(), wb.listMenus())

    doc = FreeCAD.newDocument("GuiSmoke")
    sketch = doc.addObject("Sketcher::SketchObject", "Sketch")
    bs = Part.BSplineCurve()
    bs.interpolate([FreeCAD.Vector(x, y, 0) for x, y in
                    ((0, 0), (40, 35), (100, 50), (160, 35), (200, 0))])
    sketch.addGeometry(bs, False)
    doc.recompute()

    FreeCADGui.Selection.clearSelection()
    FreeCADGui.Selection.addSelection(doc.Name, sketch.Name, "Edge1")
    FreeCADGui.updateGui()
    FreeCADGui.runCommand("ParaFab_Strip")
    doc.recompute()

    strip = doc.getObject("Strip")
    check("strip_created", strip is not None)
    check("strip_valid", strip.isValid(), strip.getStatusString())
    check("strip_feasible", strip.Feasible, strip.Reason)
    check("strip_shape", strip.Shape.isValid() and len(strip.Shape.Faces) == 2)
    check("view_provider", type(strip.ViewObject.Proxy).__name__ == "ViewProviderStrip")
    check("tree_icon", os.path.isfile(strip.ViewObject.Proxy.getIcon()))
    check("undo_available", "Bending-active strip" in doc.UndoNames, doc.UndoNames)

    FreeCADGui.Selection.clearSelection()
    gui_doc = FreeCADGui.getDocument(doc.Name)
    view = gui_doc.activeView()
    view.viewIsometric()
    view.fitAll()
    FreeCADGui.updateGui()
    view.saveImage(SCREENSHOT, 1280, 1024, "White")
    check("screenshot_written", os.path.getsize(SCREENSHOT) > 0)
    pixels = strip_pixels(SCREENSHOT)
    check("strip_visible", pixels >= MIN_STRIP_PIXELS, "(%d pixels)" % pixels)
    info = {"R": strip.R, "length_mm": strip.Length.Value, "strip_pixels": pixels}

    doc.saveAs(DOCUMENT)
    FreeCAD.closeDocument(doc.Name)
    doc = FreeCAD.openDocument(DOCUMENT)
    strip = doc.getObject("Strip")
    check("reopened_view_provider",
          type(strip.ViewObject.Proxy).__name__ == "ViewProviderStrip")
    strip.touch()
    doc.recompute()
    check("reopened_recompute", strip.isValid() and strip.Feasible,
          strip.getStatusString())
    return info


def main():
    """Run, write ``status.json``, and leave FreeCAD with the exit status."""
    check = Checks()
    status = {"status": "fail", "screenshot": SCREENSHOT}
    try:
        status["info"] = run(check)
        status["status"] = "pass"
    except Exception:
        status["error"] = traceback.format_exc()
    status["checks"] = check.results
    with open(STATUS_FILE, "w") as f:
        json.dump(status, f, indent=2)
    os._exit(0 if status["status"] == "pass" else 1)


main()
