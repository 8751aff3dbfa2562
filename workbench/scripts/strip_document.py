"""Build a FreeCAD document with one strip feature per strip result (run by freecadcmd).

Environment: PARAFAB_RESULTS (folder of *.result.json written by `parafab strip`),
PARAFAB_DOCUMENT (the .FCStd to write). Each curve is rebuilt from the B-spline the solver
designed (output field "bspline", metres → mm), placed in its own row of the XY plane, and a
ParaFab Strip feature is recomputed on it: feasible curves get the flat and bent strips,
infeasible ones show their reason as the feature's error state.
"""
import glob
import json
import os

import FreeCAD

from parafab_wb import geometry
from parafab_wb.strip_feature import make_strip

M_TO_MM = 1000.0
results = sorted(glob.glob(os.path.join(os.environ["PARAFAB_RESULTS"], "*.result.json")))
doc = FreeCAD.newDocument("ParaFabStrips")
y_offset = 0.0
summary = []
for path in results:
    name = os.path.basename(path)[: -len(".result.json")]
    with open(path) as f:
        result = json.load(f)
    spec = result["bspline"]
    curve = geometry.bspline_from_spec(spec, lambda p: FreeCAD.Vector(p[0] * M_TO_MM, p[1] * M_TO_MM + y_offset, 0))
    owner = doc.addObject("Part::Feature", name)
    owner.Shape = curve.toShape()
    strip = make_strip(owner, "Edge1", doc)
    strip.Label = name + "_strip"
    with open(path.replace(".result.json", ".request.json")) as f:
        request = json.load(f)
    strip.Thickness = FreeCAD.Units.Quantity(request["material"]["thickness"] * M_TO_MM, FreeCAD.Units.Length)
    strip.YoungsModulus = FreeCAD.Units.Quantity("%r Pa" % request["material"]["E"])
    strip.MinWidth = FreeCAD.Units.Quantity(request["min_width"] * M_TO_MM, FreeCAD.Units.Length)
    strip.Tolerance = request.get("tolerance", 1e-6)
    # Issue 5 fields: gravity (direction in the XY plane of the document, density from the
    # material or from beta_l3 = E h^2 / (12 rho g)), composite / perforated, validation.
    gravity = request.get("gravity")
    if gravity:
        mat = request["material"]
        dx, dy = gravity.get("direction", [0.0, -1.0])
        strip.Gravity = True
        strip.GravityDirection = FreeCAD.Vector(dx, dy, 0)
        strip.Density = float(gravity.get("density") or mat.get("density") or
                              mat["E"] * mat["thickness"] ** 2 / (12 * gravity.get("g", 9.81) * gravity["beta_l3"]))
    for kind in ("composite", "perforated"):
        if kind in request:
            strip.StripType = kind.capitalize()
            strip.OuterWidth = FreeCAD.Units.Quantity(request[kind]["outer_width"] * M_TO_MM, FreeCAD.Units.Length)
            if kind == "composite":
                strip.InnerThickness = FreeCAD.Units.Quantity(request[kind]["h2"] * M_TO_MM, FreeCAD.Units.Length)
    strip.Validate = bool(request.get("validate"))
    doc.recompute()
    summary.append((name, strip.Feasible, strip.R, strip.Reason, strip.Deviation))
    bb = owner.Shape.BoundBox
    y_offset -= bb.YLength + 400.0
doc.saveAs(os.environ["PARAFAB_DOCUMENT"])
for name, ok, R, reason, deviation in summary:
    print("strip %-26s %s%s" % (name, ("feasible, R = %.6f" % R) if ok else "infeasible: " + reason[:90],
                                 ", simulated deviation %.2e" % deviation if deviation else ""))
print("wrote", os.environ["PARAFAB_DOCUMENT"])
