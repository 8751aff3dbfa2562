"""Run by FreeCADCmd inside tests/package/test_package.py: the installed workbench, headless.

FreeCADCmd runs this file with the installed workbench folder on sys.path (``-P``) and the
installed module's folder on PYTHONPATH; it writes what it found as JSON to
``$PARAFAB_CHECK_OUT`` (FreeCADCmd's exit status does not report a script's exceptions, so the
test reads this file; a missing file or an ``error`` entry is a failure).
"""

import json
import os
import subprocess
import traceback

report = {}
try:
    import FreeCAD
    import Part

    import parafab
    import parafab_wb
    from parafab_wb import cli_runner, strip_feature

    wb_dir = os.environ["PARAFAB_WB_DIR"]
    report["module"] = os.path.realpath(parafab.__file__)
    report["workbench"] = os.path.realpath(parafab_wb.__file__)
    report["icon"] = parafab_wb.icon_path("ParaFab_Workbench.svg")

    # The CLI the task panels run, and what it says of itself.
    cli = cli_runner.find_cli()
    report["cli"] = cli
    report["cli_real"] = os.path.realpath(cli) if cli else None
    if cli:
        report["cli_version"] = json.loads(subprocess.run([cli, "version"], check=True,
                                                          capture_output=True, text=True).stdout)

    # package.xml as FreeCAD's start-up reads it (FreeCADInit.py/FreeCADGuiInit.py: skipped
    # unless supportsCurrentFreeCAD(); Init.py/InitGui.py run from the workbench's subdirectory).
    meta = FreeCAD.Metadata(os.path.join(wb_dir, "package.xml"))
    wbs = meta.Content.get("workbench", [])
    report["metadata"] = {
        "name": meta.Name, "version": meta.Version, "license": [dict(x) for x in meta.License],
        "supported": meta.supportsCurrentFreeCAD(), "icon": meta.Icon,
        "workbenches": [{"name": w.Name, "classname": w.Classname, "icon": w.Icon,
                         "supported": w.supportsCurrentFreeCAD(),
                         "dir": os.path.join(wb_dir, w.Subdirectory or w.Name)} for w in wbs],
    }

    # A strip feature on a circular arc (r = 150 mm, 2 rad): R = 1 and a constant width,
    # the minimum width (10 mm), whatever the solver; the length is r * angle.
    doc = FreeCAD.newDocument("PackageCheck")
    src = doc.addObject("Part::Feature", "Arc")
    src.Shape = Part.Edge(Part.Circle(FreeCAD.Vector(0, 0, 0), FreeCAD.Vector(0, 0, 1), 150.0), 0.4, 2.4)
    strip = strip_feature.make_strip(src, "Edge1")
    doc.recompute()
    shape = strip.Shape
    report["strip"] = {
        "state": list(strip.State), "feasible": bool(strip.Feasible), "reason": strip.Reason,
        "R": strip.R, "length_mm": strip.Length.Value, "valid": shape.isValid(),
        "solids": len(shape.Solids),
        "bent_width_mm": shape.Solids[1].BoundBox.ZLength if len(shape.Solids) == 2 else None,
    }
    FreeCAD.closeDocument(doc.Name)
except Exception:
    report["error"] = traceback.format_exc()

with open(os.environ["PARAFAB_CHECK_OUT"], "w") as f:
    json.dump(report, f, indent=1)
