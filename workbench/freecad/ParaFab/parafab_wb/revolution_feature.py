"""The ParaFab ``RevolutionStrips`` feature: a surface of revolution covered by n strips
without gaps (thesis §4.8.4).

Its meridian solves ⟨e₁,γ⟩κ = a + ⟨b,γ⟩ from a start point and angle (``parafab.revolution_strips``,
CVODE); the axis is the document's z axis, the meridian lies in the xz plane. The Shape is a
compound of the surface (the meridian revolved), the n bent strips (flat planks tangent
along n meridians, width 2 x tan(π/n)) and their flat outlines laid out beside the surface.
Solver units are metres; FreeCAD's mm are converted here. Errors put the feature in
FreeCAD's error state with the message in ``Status``.
"""

import math

import FreeCAD
import Part

from . import feature_proxy

V = FreeCAD.Vector
_READ_ONLY, _OUTPUT = feature_proxy.READ_ONLY, feature_proxy.OUTPUT

_PROPERTIES = (
    ("App::PropertyFloat", "A", "Meridian", "a in ⟨e1,γ⟩κ = a + ⟨b,γ⟩ (dimensionless)", 0.0, 0),
    ("App::PropertyFloat", "B1", "Meridian", "b₁ [1/m]", 10.0, 0),
    ("App::PropertyFloat", "B2", "Meridian", "b₂ [1/m]", 0.0, 0),
    ("App::PropertyLength", "StartRadius", "Meridian", "Distance of the start point from the axis", "100 mm", 0),
    ("App::PropertyLength", "StartHeight", "Meridian", "Height of the start point", "0 mm", 0),
    ("App::PropertyAngle", "StartAngle", "Meridian", "Angle of the meridian at the start (90°: upwards)", 90.0, 0),
    ("App::PropertyLength", "MeridianLength", "Meridian", "Arc length of the meridian", "120 mm", 0),
    ("App::PropertyInteger", "Strips", "Strips", "Strips around the axis", 12, 0),
    ("App::PropertyPressure", "YoungsModulus", "Strips", "Young's modulus", "2.8 GPa", 0),
    ("App::PropertyLength", "Thickness", "Strips", "Strip thickness", "0.5 mm", 0),
    ("App::PropertyFloat", "R", "Results", "max width / min width", 0.0, _READ_ONLY | _OUTPUT),
    ("App::PropertyBool", "Complete", "Results", "The meridian did not meet the axis", False, _READ_ONLY | _OUTPUT),
    ("App::PropertyString", "Status", "Results", "Solver message or error", "", _READ_ONLY | _OUTPUT),
)


class RevolutionError(RuntimeError):
    """Raised from ``execute`` to put the feature in FreeCAD's error state."""


def job_of(obj):
    """The parafab.revolution_strips job (metres) of ``obj``."""
    return {"a": float(obj.A), "b": [float(obj.B1), float(obj.B2)],
            "start": [obj.StartRadius.getValueAs("m").Value, obj.StartHeight.getValueAs("m").Value],
            "start_angle_deg": float(obj.StartAngle.getValueAs("deg").Value),
            "length": obj.MeridianLength.getValueAs("m").Value, "strips": int(obj.Strips), "points": 81,
            "material": {"E": obj.YoungsModulus.getValueAs("Pa").Value, "thickness": obj.Thickness.getValueAs("m").Value}}


def shapes_of(result, strips):
    """(surface, bent strips, flat outlines) in mm from the solver's result."""
    pts = [V(1000 * x, 0, 1000 * z) for x, z in result["meridian"]["points"]]
    meridian = Part.BSplineCurve()
    meridian.interpolate(pts)
    surface = meridian.toShape().revolve(V(0, 0, 0), V(0, 0, 1), 360)
    widths = [1000 * w for w in result["strips"]["width"]]
    bent = []
    for k in range(strips):
        phi = 2 * math.pi * k / strips
        c, s = math.cos(phi), math.sin(phi)
        t = V(-s, c, 0)  # along the parallel circles: the strip's width direction
        centre = [V(p.x * c, p.x * s, p.z) for p in pts]
        edges = []
        for sign in (1, -1):
            side = Part.BSplineCurve()
            side.interpolate([q + t * (0.5 * sign * w) for q, w in zip(centre, widths)])
            edges.append(side.toShape())
        bent.append(Part.makeRuledSurface(edges[0], edges[1]))
    outline = [V(1000 * x, 1000 * y, 0) for x, y in result["strips"]["outline"]]
    offset = V(0, -2.5 * max(p.x for p in pts) - max(widths), 0)
    flat = Part.Face(Part.makePolygon([p + offset for p in outline] + [outline[0] + offset]))
    return surface, bent, flat


class RevolutionFeature(feature_proxy.FeatureProxy):
    """Proxy of the ``RevolutionStrips`` ``Part::FeaturePython``."""

    TYPE = "ParaFab::RevolutionStrips"
    VERSION = 1
    PROPERTIES = _PROPERTIES

    def execute(self, obj):
        obj.Status = ""
        try:
            import parafab
            if obj.Strips < 3:
                raise RevolutionError("Strips must be at least 3, got %d" % obj.Strips)
            result = parafab.revolution_strips(job_of(obj))
            surface, bent, flat = shapes_of(result, int(obj.Strips))
        except Exception as exc:
            obj.Status = str(exc) or type(exc).__name__
            obj.Shape = Part.Shape()
            raise RevolutionError(obj.Status) from exc
        obj.R = float(result["strips"]["R"])
        obj.Complete = bool(result["meridian"]["complete"])
        obj.Status = "" if obj.Complete else result["meridian"]["message"] or "the meridian meets the axis"
        obj.Shape = Part.makeCompound([surface] + bent + [flat])


def make_revolution_strips(doc):
    """Create a ``RevolutionStrips`` feature with default parameters (not recomputed)."""
    obj = doc.addObject("Part::FeaturePython", "RevolutionStrips")
    RevolutionFeature(obj)
    if FreeCAD.GuiUp:
        obj.ViewObject.Proxy = 0
        obj.ViewObject.ShapeColor = (0.96, 0.65, 0.14)
    return obj
