"""Planar edge -> exact 2D NURBS data in the edge's own plane.

The solver (:mod:`parafab`) works on a planar curve given by its 2D
coordinates.  This module turns any FreeCAD edge (sketch B-spline, arc,
ellipse arc, Part edge, ...) into that description *exactly*:

1. the edge is converted to NURBS with ``Edge.toNurbs()`` (rational for
   conics, so arcs stay exact), made non-periodic and trimmed/clamped to the
   edge's parameter range with ``BSplineCurve.segment``;
2. the plane of the curve is found (an optional hint such as a sketch
   placement is preferred when it contains the curve) and every pole is
   checked to lie in it -- a NURBS curve is planar iff its poles are
   coplanar, so this test is exact;
3. the poles are expressed in an orthonormal 2D frame of that plane.

:class:`PlaneFrame` also maps 2D coordinates back to 3D, which
:mod:`parafab_wb.shapes` uses to build the result geometry.  All lengths here
are FreeCAD millimetres; the conversion to metres happens in
:meth:`PlanarCurve.to_spec`.
"""

import FreeCAD
import Part

Vector = FreeCAD.Vector

#: Scale factor from FreeCAD's internal length unit (mm) to SI metres.
MM_TO_M = 1e-3

#: Absolute planarity tolerance in mm (OCC's Precision::Confusion).
ABS_TOL = 1e-7
#: Relative planarity tolerance (times the curve's bounding-box size).
REL_TOL = 1e-9


class GeometryError(ValueError):
    """The edge cannot be used as a strip centreline (non-planar, ...)."""


def _unit(v):
    """Return ``v`` normalised (as a new vector)."""
    v = Vector(v)
    v.normalize()
    return v


class PlaneFrame(object):
    """Right-handed orthonormal frame ``(origin, xdir, ydir, normal)`` of a plane.

    ``to_2d`` and ``to_3d`` convert between 3D points and 2D plane
    coordinates (mm).  ``to_3d`` takes an optional height along ``normal``.
    """

    def __init__(self, origin, xdir, normal):
        self.normal = _unit(normal)
        x = Vector(xdir)
        x = x - self.normal * x.dot(self.normal)
        self.xdir = _unit(x)
        self.ydir = self.normal.cross(self.xdir)
        self.origin = Vector(origin)

    @classmethod
    def from_placement(cls, placement):
        """Frame of the local XY plane of ``placement`` (e.g. a sketch plane)."""
        rot = placement.Rotation
        return cls(placement.Base, rot.multVec(Vector(1, 0, 0)),
                   rot.multVec(Vector(0, 0, 1)))

    @classmethod
    def from_normal(cls, normal, point):
        """Deterministic frame of the plane through ``point`` with ``normal``.

        * horizontal planes get ``normal = +Z`` and ``xdir = +X`` (so a curve
          drawn in the XY plane keeps its x/y coordinates);
        * other planes get ``ydir`` = the projection of +Z ("up"), so that
          "below" in 2D is also below in 3D.

        The origin is the projection of the global origin onto the plane.
        """
        n = _unit(normal)
        if abs(n.z) > 1.0 - 1e-12:
            n = Vector(0, 0, 1)
            xdir = Vector(1, 0, 0)
        else:
            up = _unit(Vector(0, 0, 1) - n * n.z)
            xdir = up.cross(n)
        origin = n * Vector(point).dot(n)
        return cls(origin, xdir, n)

    def height(self, p):
        """Signed distance of 3D point ``p`` from the plane (mm)."""
        return (Vector(p) - self.origin).dot(self.normal)

    def to_2d(self, p):
        """2D plane coordinates ``(x, y)`` of 3D point ``p`` (projected)."""
        d = Vector(p) - self.origin
        return (d.dot(self.xdir), d.dot(self.ydir))

    def to_3d(self, x, y, h=0.0):
        """3D point of plane coordinates ``(x, y)`` lifted by ``h`` along the normal."""
        return self.origin + self.xdir * x + self.ydir * y + self.normal * h

    def contains(self, points, tol):
        """True when every point lies within ``tol`` of the plane."""
        return all(abs(self.height(p)) <= tol for p in points)


class PlanarCurve(object):
    """Exact planar NURBS curve in 2D plane coordinates (mm).

    Attributes: ``frame`` (:class:`PlaneFrame`), ``degree``, ``knots`` (flat
    knot vector, multiplicities repeated), ``poles`` (list of ``(x, y)``),
    ``weights`` (list, or ``None`` for a non-rational curve).
    """

    def __init__(self, frame, degree, knots, poles, weights=None):
        self.frame = frame
        self.degree = degree
        self.knots = knots
        self.poles = poles
        self.weights = weights

    def to_spec(self, scale=MM_TO_M):
        """``{"bspline": {...}}`` curve entry of the solver input, scaled to metres.

        Knots are curve parameters, not lengths, and are passed unchanged.
        """
        bspline = {
            "degree": int(self.degree),
            "knots": [float(k) for k in self.knots],
            "poles": [[x * scale, y * scale] for (x, y) in self.poles],
        }
        if self.weights is not None:
            bspline["weights"] = [float(w) for w in self.weights]
        return {"bspline": bspline}

    def bounds(self):
        """``(xmin, ymin, xmax, ymax)`` of the control polygon (contains the curve)."""
        xs = [p[0] for p in self.poles]
        ys = [p[1] for p in self.poles]
        return min(xs), min(ys), max(xs), max(ys)


def edge_to_bspline(edge):
    """Exact, clamped, non-periodic ``Part.BSplineCurve`` of ``edge``'s range.

    ``Edge.toNurbs()`` keeps conics rational (exact) and keeps the edge's
    location; its curve can however be periodic or extend beyond the edge,
    so it is segmented to the edge's parameter range, which also clamps the
    knot vector.
    """
    if edge.ShapeType != "Edge":
        raise GeometryError("Expected an edge, got a %s" % edge.ShapeType)
    if edge.isNull() or edge.Length <= ABS_TOL:
        raise GeometryError("The edge is degenerate (zero length)")
    nurbs = edge.toNurbs().Edges[0]
    curve = nurbs.Curve
    if not isinstance(curve, Part.BSplineCurve):
        raise GeometryError("Cannot convert the edge (%s) to a B-spline"
                            % type(edge.Curve).__name__)
    u0, u1 = nurbs.FirstParameter, nurbs.LastParameter
    bs = curve.copy()
    if bs.isPeriodic():
        # Trim while still periodic (the range may wrap around the seam).
        bs.segment(u0, u1)
        if bs.isPeriodic():
            bs.setNotPeriodic()
        u0, u1 = bs.FirstParameter, bs.LastParameter
    u0 = max(u0, bs.FirstParameter)
    u1 = min(u1, bs.LastParameter)
    bs.segment(u0, u1)  # trims and clamps the knot vector

    # Sanity check the conversion against the converted edge itself.
    tol = max(ABS_TOL, REL_TOL * edge.BoundBox.DiagonalLength) * 10
    for t in (0.0, 0.3, 0.7, 1.0):
        u = u0 + t * (u1 - u0)
        if bs.value(u).distanceToPoint(nurbs.valueAt(u)) > tol:
            raise GeometryError("Internal error: NURBS conversion of the "
                                "edge does not reproduce it")
    return bs


def _fitted_frame(bs, poles, tol):
    """Frame of the plane containing ``bs``, or ``None`` when it is not planar."""
    plane = bs.toShape().findPlane(tol)
    if plane is not None:
        return PlaneFrame.from_normal(plane.Axis, plane.Position)
    # OCC finds no plane for straight lines: pick the "most horizontal"
    # plane containing the line.
    start, end = poles[0], max(poles, key=lambda p: p.distanceToPoint(poles[0]))
    if start.distanceToPoint(end) <= tol:
        return None
    d = _unit(end - start)
    if all(p.distanceToLine(start, d) <= tol for p in poles):
        z = Vector(0, 0, 1)
        normal = z - d * d.dot(z) if abs(d.z) < 1.0 - 1e-9 else Vector(1, 0, 0)
        return PlaneFrame.from_normal(normal, start)
    return None


def planar_curve_from_edge(edge, hint=None):
    """Convert ``edge`` to a :class:`PlanarCurve` (exact, mm).

    ``hint`` is an optional :class:`PlaneFrame` (e.g. the sketch plane);
    it is used when it contains the curve, which keeps 2D coordinates equal
    to sketch coordinates.  Otherwise the plane is fitted.

    Raises :class:`GeometryError` when the edge is not planar.
    """
    bs = edge_to_bspline(edge)
    poles = bs.getPoles()
    tol = max(ABS_TOL, REL_TOL * edge.BoundBox.DiagonalLength)
    frame = hint if hint is not None and hint.contains(poles, tol) else None
    if frame is None:
        frame = _fitted_frame(bs, poles, tol)
    if frame is None or not frame.contains(poles, tol):
        raise GeometryError(
            "The edge is not planar: a bending-active strip needs a planar "
            "curve (the poles of its NURBS do not lie in one plane)")
    weights = bs.getWeights() if bs.isRational() else None
    return PlanarCurve(frame, bs.Degree, list(bs.KnotSequence),
                       [frame.to_2d(p) for p in poles], weights)


def bspline_from_spec(spec, pole_to_point):
    """A ``Part.BSplineCurve`` from the solvers' JSON B-spline (``degree``, flat ``knots`` with
    repeats, ``poles``, optional ``weights``); ``pole_to_point`` maps each JSON pole (metres,
    2D or 3D) to a ``FreeCAD.Vector`` (mm, placed)."""
    knots, mults = [], []
    for k in spec["knots"]:
        if knots and abs(k - knots[-1]) < 1e-15:
            mults[-1] += 1
        else:
            knots.append(k)
            mults.append(1)
    curve = Part.BSplineCurve()
    curve.buildFromPolesMultsKnots([pole_to_point(p) for p in spec["poles"]], mults, knots, False,
                                   spec["degree"], spec.get("weights"))
    return curve
