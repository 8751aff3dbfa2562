"""Solver result -> Part shapes for Kirchhoff rods: the deformed rod, the straight rod and
the end-frame markers.

Given a feasible :func:`parafab.design_rod` result (SI units), build

* the **deformed rod**: a solid lofted (skinned) through elliptical sections at a subsample of the
  samples; each section lies in the plane normal to the tangent at gamma(s), with
  semi-axes a, b at angle phi in the material frame (n1, n2);
* the **straight rod**: the same sections along a straight line (the undeformed,
  untwisted rod: constant material frame), laid beside the deformed rod;
* **frame markers** at the clamped ends: three axis segments (n1, n2, tangent).

Each section is the exact rational image of the unit circle under the ellipse's shape
matrix S = Q(phi) diag(a, b) Q(phi)^T in (n1, n2): S depends only on the ellipse (not on
the sign convention of phi), and the seam of every section lies near n1, so consecutive
sections stay aligned for the loft even where the ellipse is nearly circular. All
sections share one knot vector. The only arithmetic here is unit scaling and placement.
"""

import math

import FreeCAD
import Part

V = FreeCAD.Vector
#: Metres (solver) -> millimetres (FreeCAD).
M_TO_MM = 1e3
#: Loft sections of the deformed (and the straight) rod.
LOFT_SECTIONS = 41

_W = math.sqrt(0.5)
#: Rational quadratic unit circle (9 poles, seam at (1, 0)).
_CIRCLE_POLES = ((1, 0), (1, 1), (0, 1), (-1, 1), (-1, 0), (-1, -1), (0, -1), (1, -1), (1, 0))
_CIRCLE_WEIGHTS = (1, _W, 1, _W, 1, _W, 1, _W, 1)
_CIRCLE_KNOTS = (0.0, 0.25, 0.5, 0.75, 1.0)
_CIRCLE_MULTS = (3, 2, 2, 2, 3)
#: Knots inserted into every section (4 spans per quarter): the same curve, but OCC's
#: Gauss rules for volume and area (GProp) lose ~2 % on the rational 4-span tube.
_REFINE_KNOTS = tuple(k / 16.0 for k in range(1, 16) if k % 4)


def subsample(n, limit=LOFT_SECTIONS):
    """Indices of at most ``limit`` evenly spread samples of ``range(n)`` (ends included)."""
    if n <= limit:
        return list(range(n))
    step = (n - 1) / float(limit - 1)
    return sorted(set(int(round(i * step)) for i in range(limit)))


def _vec(p, scale=1.0):
    return V(p[0] * scale, p[1] * scale, p[2] * scale)


def shape_matrix(a, b, angle):
    """S = Q diag(a, b) Q^T (symmetric), Q the rotation by ``angle``."""
    c, s = math.cos(angle), math.sin(angle)
    return ((a * c * c + b * s * s, (a - b) * c * s),
            ((a - b) * c * s, a * s * s + b * c * c))


def ellipse_section(center, e1, e2, a, b, angle):
    """Closed edge of the ellipse with semi-axes ``a`` (along angle) and ``b`` in the plane
    spanned by the unit vectors ``e1``, ``e2`` (mm) through ``center``."""
    S = shape_matrix(a, b, angle)
    poles = []
    for x, y in _CIRCLE_POLES:
        u = S[0][0] * x + S[0][1] * y
        v = S[1][0] * x + S[1][1] * y
        poles.append(center + e1 * u + e2 * v)
    bs = Part.BSplineCurve()
    bs.buildFromPolesMultsKnots(poles, _CIRCLE_MULTS, _CIRCLE_KNOTS, False, 2, _CIRCLE_WEIGHTS)
    for k in _REFINE_KNOTS:
        bs.insertKnot(k, 1)
    return bs.toShape()


def _loft(edges, params):
    """Solid skinned through the section ``edges`` (shared knots and weights) at the
    parameters ``params`` (arc length, mm): each pole path across the sections is
    interpolated by a cubic B-spline (same knots for all), giving a surface rational in
    the section direction that passes exactly through every ellipse; end caps are the
    planar first and last sections, sewn into a closed shell. (OCC's ThruSections,
    Part.makeLoft, folds the surface where the sections twist along a long rod: volume
    off by up to 60 % on the light-sculpture segments.)"""
    poles = [e.Curve.getPoles() for e in edges]
    weights = edges[0].Curve.getWeights()
    paths = []
    for j in range(len(weights)):
        c = Part.BSplineCurve()
        c.interpolate(Points=[p[j] for p in poles], Parameters=params)
        paths.append(c.getPoles())
    sec = edges[0].Curve
    surf = Part.BSplineSurface()
    surf.buildFromPolesMultsKnots(
        [[paths[j][i] for j in range(len(weights))] for i in range(len(paths[0]))],
        c.getMultiplicities(), sec.getMultiplicities(), c.getKnots(), sec.getKnots(),
        False, False, c.Degree, sec.Degree,
        [list(weights) for _ in range(len(paths[0]))])
    caps = [Part.Face(Part.Wire(surf.uIso(u).toShape())) for u in (params[0], params[-1])]
    shell = Part.Shell([surf.toShape()] + caps)
    shell.sewShape()
    if shell.ShapeType != "Shell":
        shell = Part.Shell(shell.Faces)
    solid = Part.Solid(shell)
    if solid.Volume < 0:
        solid.reverse()
    return solid


def deformed_rod(result, indices, scale=M_TO_MM):
    """Solid through the sections at ``indices`` along the designed curve."""
    sec = result["section"]
    edges = []
    for i in indices:
        edges.append(ellipse_section(_vec(result["points"][i], scale), _vec(result["n1"][i]),
                                     _vec(result["n2"][i]), sec["a"][i] * scale, sec["b"][i] * scale,
                                     sec["angle"][i]))
    return _loft(edges, [result["s"][i] * scale for i in indices])


def straight_rod(result, indices, origin, scale=M_TO_MM):
    """The undeformed rod: straight along +X from ``origin`` (mm), material frame
    (n1, n2) = (Y, Z) everywhere (no natural twist)."""
    sec = result["section"]
    edges = []
    for i in indices:
        center = origin + V(result["s"][i] * scale, 0, 0)
        edges.append(ellipse_section(center, V(0, 1, 0), V(0, 0, 1), sec["a"][i] * scale,
                                     sec["b"][i] * scale, sec["angle"][i]))
    return _loft(edges, [result["s"][i] * scale for i in indices])


def straight_origin(result, scale=M_TO_MM):
    """Where the straight rod starts: below the deformed rod's bounding box in Y, with a gap
    of 0.1·length + 4·max(a)."""
    pts = result["points"]
    gap = 0.1 * result["length"] * scale + 4 * max(result["section"]["a"]) * scale
    return V(min(p[0] for p in pts) * scale, min(p[1] for p in pts) * scale - gap,
             min(p[2] for p in pts) * scale)


def end_placement(frame, scale=M_TO_MM):
    """Placement of a clamped end: origin at the end point, axes (n1, n2, tangent)."""
    x, y, z = frame["n1"], frame["n2"], frame["tangent"]
    m = FreeCAD.Matrix(x[0], y[0], z[0], frame["position"][0] * scale,
                       x[1], y[1], z[1], frame["position"][1] * scale,
                       x[2], y[2], z[2], frame["position"][2] * scale,
                       0, 0, 0, 1)
    return FreeCAD.Placement(m)


def frame_marker(frame, length, scale=M_TO_MM):
    """Three segments from the end point along n1, n2 and the tangent (``length`` mm)."""
    p = _vec(frame["position"], scale)
    return Part.makeCompound([Part.LineSegment(p, p + _vec(frame[k]) * length).toShape()
                              for k in ("n1", "n2", "tangent")])


def rod_shapes(result, scale=M_TO_MM, sections=LOFT_SECTIONS):
    """``(deformed solid, straight solid, [start marker, end marker])`` of a feasible result."""
    idx = subsample(len(result["s"]), sections)
    deformed = deformed_rod(result, idx, scale)
    straight = straight_rod(result, idx, straight_origin(result, scale), scale)
    length = 3 * max(result["section"]["a"]) * scale
    markers = [frame_marker(f, length, scale) for f in result["end_frames"]]
    return deformed, straight, markers


def rod_shape(result, scale=M_TO_MM, sections=LOFT_SECTIONS):
    """Compound [deformed rod, straight rod, start frame, end frame]."""
    deformed, straight, markers = rod_shapes(result, scale, sections)
    return Part.makeCompound([deformed, straight] + markers)
