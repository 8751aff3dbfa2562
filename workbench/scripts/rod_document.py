"""Build a FreeCAD document with one Rod feature per rod result (run by freecadcmd), and
export each feasible rod (deformed and straight solids) as STEP.

Environment: PARAFAB_RESULTS (folder of *.result.json and *.request.json written for
`parafab rod`), PARAFAB_DOCUMENT (the .FCStd to write). Each curve is rebuilt from the
B-spline the solver designed (output field "bspline", metres -> mm), moved to its own row
(translation along Y only, so gravity along -Z is unchanged), and a ParaFab Rod feature with
the request's settings is recomputed on it: feasible curves get the deformed rod, the
straight rod and the end frames, infeasible ones show their reason as the feature's error
state. Writes <name>.step next to the results for the feasible rods.
"""
import glob
import json
import os

import FreeCAD

from parafab_wb import geometry, rod_feature

M_TO_MM = 1000.0
folder = os.environ["PARAFAB_RESULTS"]
doc = FreeCAD.newDocument("ParaFabRods")
y_offset = 0.0
summary = []
for path in sorted(glob.glob(os.path.join(folder, "*.result.json"))):
    name = os.path.basename(path)[: -len(".result.json")]
    with open(path) as f:
        result = json.load(f)
    with open(path.replace(".result.json", ".request.json")) as f:
        request = json.load(f)
    spec = result["bspline"]
    curve = geometry.bspline_from_spec(spec, lambda p: FreeCAD.Vector(p[0] * M_TO_MM, p[1] * M_TO_MM + y_offset, p[2] * M_TO_MM))
    owner = doc.addObject("Part::Feature", name)
    owner.Shape = curve.toShape()
    rod = rod_feature.make_rod(owner, "Edge1", doc)
    rod.Label = name + "_rod"
    mat = request.get("material", {})
    if any(k in mat for k in ("E", "nu", "density")):
        rod.Material = "Custom"
        rod.YoungsModulus = FreeCAD.Units.Quantity("%r Pa" % mat.get("E", 2.3e6))
        rod.PoissonRatio = mat.get("nu", 0.48)
        rod.Density = mat.get("density", 1250.0)
    rod.MaxRadius = FreeCAD.Units.Quantity(request.get("max_radius", 0.005) * M_TO_MM, FreeCAD.Units.Length)
    rod.SectionFactor = float(request.get("section", {}).get("factor", 1.0))
    rod.WReg = float(request.get("w_reg", 0.0))
    rod.Samples = int(request.get("samples", 200))
    rod.GravityOn = bool(request.get("loads", {}).get("dead_load", False))
    rod.Validate = bool(request.get("validate", False))
    doc.recompute()
    step = ""
    if rod.Feasible:
        step = rod_feature.export_step(rod, os.path.join(folder, name + ".step"))
    summary.append((name, rod, step))
    y_offset -= owner.Shape.BoundBox.YLength + 300.0
doc.saveAs(os.environ["PARAFAB_DOCUMENT"])
for name, rod, step in summary:
    if rod.Feasible:
        deformed, straight = rod.Shape.Solids
        print("rod %-20s feasible, twist max %.3g rad/m, beta end %.4f rad, volume %.1f cm^3%s, %s"
              % (name, rod.TwistMax, rod.BetaEnd, deformed.Volume * 1e-3,
                 ", simulated deviation %.2e" % rod.Deviation if rod.Deviation >= 0 else "",
                 os.path.basename(step)))
    else:
        print("rod %-20s %s: %s" % (name, rod.Status, rod.Reason[:90]))
print("wrote", os.environ["PARAFAB_DOCUMENT"])
