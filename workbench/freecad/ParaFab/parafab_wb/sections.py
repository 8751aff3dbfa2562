"""Strips from sections (thesis §4.8.2): plane sections of a surface or solid, one ``Strip``
feature per section curve.

``strips_from_sections(shape_obj, normal=(0, 0, 1), count=5, split=None)`` calls
``parafab.strip_sections`` on the object's shape (exported as BREP, FreeCAD's mm), then adds
a group ``Sections`` holding, for every curve, a ``Part::Feature`` with the section as a
B-spline edge through the solver's samples and a ``Strip`` feature on that edge (so each
strip recomputes, can be edited and exported like any other). Closed curves that were not
split are skipped and listed in the returned report with the solver's message.
"""

import os
import tempfile

import FreeCAD
import Part

from . import geometry
from . import strip_feature


def section_job(normal, count=None, offsets=None, split=None, samples=60):
    """The ``parafab.strip_sections`` job (part in mm) for the given plane family."""
    planes = {"normal": [float(c) for c in normal]}
    if offsets:
        planes["offsets"] = [float(o) for o in offsets]
    else:
        planes["count"] = int(count or 5)
    job = {"planes": planes, "samples": int(samples), "units": "mm",
           "strip": {"material": {"E": 2.8e9, "thickness": 0.0005}, "min_width": 0.01}}
    if split:
        split_normal, split_offset = split
        job["split"] = {"normal": [float(c) for c in split_normal], "offset": float(split_offset)}
    return job


def _spline_in_space(bspline, frame):
    """The solver's quartic B-spline (2D, metres, in the section plane's frame) as a 3D
    ``Part.BSplineCurve`` in mm: the curve the strip was designed for, not a re-fit."""
    o, u, v = (FreeCAD.Vector(*frame[k]) for k in ("origin", "u", "v"))
    return geometry.bspline_from_spec(bspline, lambda p: o + u * (1000.0 * p[0]) + v * (1000.0 * p[1]))


def strips_from_sections(shape_obj, normal=(0, 0, 1), count=5, offsets=None, split=None, samples=60, doc=None):
    """Create section curves and their strips; returns ``(group, report)`` where ``report``
    is the solver's JSON (``curves[i].strip`` holds each design or its error)."""
    import parafab
    doc = doc or shape_obj.Document
    with tempfile.TemporaryDirectory() as tmp:
        brep = os.path.join(tmp, "shape.brep")
        shape_obj.Shape.exportBrep(brep)
        report = parafab.strip_sections(brep, section_job(normal, count, offsets, split, samples))
    group = doc.addObject("App::DocumentObjectGroup", "Sections")
    for c in report["curves"]:
        if c["closed"]:
            continue  # a closed loop has no ends to clamp: reported, not turned into a strip
        design = c["strip"]
        if "bspline" not in design:  # invalid input for the solver: keep the samples' curve
            spline = Part.BSplineCurve()
            spline.interpolate([FreeCAD.Vector(*p) for p in c["points"]])
        else:
            spline = _spline_in_space(design["bspline"], c["frame"])
        curve_obj = doc.addObject("Part::Feature", "Section")
        curve_obj.Label = "Section_plane%d_piece%d" % (c["plane"], c["piece"])
        curve_obj.Shape = spline.toShape()
        group.addObject(curve_obj)
        strip = strip_feature.make_strip(curve_obj, "Edge1", doc)
        group.addObject(strip)
    doc.recompute()
    return group, report
