"""Solver result -> Part shapes: the flat strip and the bent strip.

Given a feasible :func:`parafab.design_strip` result (SI units) and the
:class:`~parafab_wb.geometry.PlaneFrame` of the curve, build

* the **flat strip**: a planar face bounded by the two sides of the
  ``outline`` (interpolated B-splines) and two straight end edges, laid out
  in the curve's plane below the curve;
* the **bent strip**: the ruled surface between ``gamma(s) + w(s)/2 n`` and
  ``gamma(s) - w(s)/2 n`` (``n`` = plane normal): the strip is bent in the
  plane of the curve, so its width is perpendicular to that plane.

With a thickness ``h`` both become solids (OpenCASCADE does the geometry):
the flat face is extruded along the plane normal from ``-h/2`` to ``+h/2``,
the bent face is offset by ``-h/2`` along its normal and that offset is
thickened by ``h`` (``makeOffsetShape(..., fill=True)``), so the centreline
lies in the middle of both solids and the volume is ``∫ w(s) h ds``.

Side curves interpolate a subsample of at most :data:`MAX_EDGE_POINTS`
samples.  The only arithmetic here is unit scaling and placement.
"""

import math

import Part

#: Metres (solver) -> millimetres (FreeCAD).
M_TO_MM = 1e3
#: Maximum number of samples interpolated per side edge.
MAX_EDGE_POINTS = 200


def subsample(n, limit=MAX_EDGE_POINTS):
    """Indices of at most ``limit`` evenly spread samples of ``range(n)``.

    The first and last index are always included.
    """
    if n <= limit:
        return list(range(n))
    step = (n - 1) / float(limit - 1)
    return sorted(set(int(round(i * step)) for i in range(limit)))


def _strictly_increasing(params, points, eps):
    """Drop samples whose parameter does not increase by more than ``eps``."""
    out_p, out_x = [], []
    for u, p in zip(params, points):
        if out_p and u - out_p[-1] <= eps:
            continue
        out_p.append(u)
        out_x.append(p)
    return out_p, out_x


def interpolated_edge(points, params):
    """Edge of the B-spline interpolating 3D ``points`` at ``params``."""
    if len(points) < 2:
        raise ValueError("Need at least two samples to build a strip edge")
    if len(points) == 2:
        return Part.LineSegment(points[0], points[1]).toShape()
    bs = Part.BSplineCurve()
    bs.interpolate(Points=points, Parameters=params)
    return bs.toShape()


def _outline_sides(outline):
    """Split the closed outline into its upper (y > 0) and lower (y < 0) sides.

    Each side is returned as a list of ``(x, y)`` sorted by x.  This does
    not depend on where the polygon starts or on its orientation.
    """
    upper = sorted((float(x), float(y)) for x, y in outline if y > 0)
    lower = sorted((float(x), float(y)) for x, y in outline if y < 0)
    if len(upper) < 2 or len(lower) < 2:
        raise ValueError("The solver returned a degenerate strip outline")
    return upper, lower


def flat_strip_face(outline, frame, offset, scale=M_TO_MM):
    """Planar face of the flat strip.

    ``outline`` is the solver's closed polygon (strip frame, metres),
    ``offset`` the ``(dx, dy)`` position (mm, plane coordinates) of the
    strip frame origin in the curve's plane.
    """
    dx, dy = offset
    sides = []
    for side in _outline_sides(outline):
        eps = 1e-9 * (side[-1][0] - side[0][0])
        xs, pts = _strictly_increasing([x for x, _ in side], side, eps)
        idx = subsample(len(pts))
        pts3 = [frame.to_3d(dx + pts[i][0] * scale, dy + pts[i][1] * scale)
                for i in idx]
        sides.append(interpolated_edge(pts3, [xs[i] * scale for i in idx]))
    upper, lower = sides
    ends = [Part.LineSegment(upper.Vertexes[0].Point, lower.Vertexes[0].Point).toShape(),
            Part.LineSegment(upper.Vertexes[-1].Point, lower.Vertexes[-1].Point).toShape()]
    wire = Part.Wire([upper, ends[1], lower, ends[0]])  # connected in this order
    return Part.Face(wire)


def bent_strip_face(points, s, width, frame, scale=M_TO_MM):
    """Ruled face of the strip bent onto the curve ``points`` (metres, 2D)."""
    if not (len(points) == len(s) == len(width)):
        raise ValueError("The solver returned samples of different lengths")
    idx = subsample(len(s))
    params, top, bottom = [], [], []
    for i in idx:
        x, y = points[i]
        h = 0.5 * width[i] * scale
        top.append(frame.to_3d(x * scale, y * scale, h))
        bottom.append(frame.to_3d(x * scale, y * scale, -h))
        params.append(s[i] * scale)
    return Part.makeRuledSurface(interpolated_edge(top, params),
                                 interpolated_edge(bottom, params))


def flat_layout_offset(points, width, length, scale=M_TO_MM):
    """Where to put the flat strip: below the curve, left-aligned with it.

    Returns ``(dx, dy)`` in mm plane coordinates with a gap of
    ``max(0.1 * length, max width)`` between curve and strip.
    """
    xmin = min(p[0] for p in points) * scale
    ymin = min(p[1] for p in points) * scale
    wmax = max(width) * scale
    gap = max(0.1 * length * scale, wmax)
    return xmin, ymin - gap - 0.5 * wmax


#: Tolerance of OpenCASCADE's offsets (mm).
OFFSET_TOLERANCE = 1e-4


def flat_strip_solid(face, frame, thickness):
    """The flat face extruded by ``thickness`` (mm) along the plane normal,
    centred on the plane."""
    n = frame.normal
    solid = face.copy()
    solid.translate(n * (-0.5 * thickness))
    solid = solid.extrude(n * thickness)
    if solid.ShapeType != "Solid" or not solid.isValid():
        raise ValueError("Cannot extrude the flat strip by its thickness %g mm" % thickness)
    return solid


def bent_strip_solid(face, thickness):
    """The bent (ruled) face thickened by ``thickness`` (mm) along its normal,
    centred on the face."""
    try:
        mid = face.makeOffsetShape(-0.5 * thickness, OFFSET_TOLERANCE)
        solid = mid.makeOffsetShape(thickness, OFFSET_TOLERANCE, fill=True)
    except Exception as exc:  # Part.OCCError and friends
        raise ValueError("Cannot thicken the bent strip by %g mm: %s" % (thickness, exc))
    if solid.ShapeType == "Compound" and len(solid.Solids) == 1:
        solid = solid.Solids[0]
    if solid.ShapeType != "Solid" or not solid.isValid() or solid.Volume <= 0:
        raise ValueError("Cannot thicken the bent strip by %g mm (a curvature radius below "
                         "half the thickness?)" % thickness)
    return solid


def bent_strip_solid_from_samples(points, s, width, frame, thickness, scale=M_TO_MM):
    """The bent strip built directly as a solid: the centre curve offset by
    ``+-thickness/2`` along its in-plane normal, each side ``+-width/2`` along
    the plane normal; four ruled faces and two planar end caps, sewn.

    Used when OCCT's offset of the bent face fails, which happens when the
    width varies steeply (stabilized designs, whose width peaks near the
    inflections). Requires every curvature radius above ``thickness/2``.
    """
    if not (len(points) == len(s) == len(width)):
        raise ValueError("The solver returned samples of different lengths")
    n = len(points)
    if n < 3:
        raise ValueError("Need at least three samples to thicken the bent strip")
    idx = subsample(n)
    half = 0.5 * thickness
    corners = [[], [], [], []]  # (+t, +w), (+t, -w), (-t, +w), (-t, -w)
    params = []
    for i in idx:
        a, b = max(i - 1, 0), min(i + 1, n - 1)
        tx = (points[b][0] - points[a][0]) * scale
        ty = (points[b][1] - points[a][1]) * scale
        norm = math.hypot(tx, ty)
        if norm == 0.0:
            raise ValueError("Cannot thicken the bent strip: repeated sample at s = %g m" % s[i])
        nx, ny = -ty / norm, tx / norm
        x, y = points[i][0] * scale, points[i][1] * scale
        w = 0.5 * width[i] * scale
        for k, (st, sw) in enumerate(((1, 1), (1, -1), (-1, 1), (-1, -1))):
            corners[k].append(frame.to_3d(x + st * half * nx, y + st * half * ny, sw * w))
        params.append(s[i] * scale)
    e = [interpolated_edge(c, params) for c in corners]
    faces = [Part.makeRuledSurface(e[0], e[1]), Part.makeRuledSurface(e[2], e[3]),
             Part.makeRuledSurface(e[0], e[2]), Part.makeRuledSurface(e[1], e[3])]
    for j in (0, -1):
        quad = [corners[0][j], corners[1][j], corners[3][j], corners[2][j], corners[0][j]]
        faces.append(Part.Face(Part.makePolygon(quad)))
    shell = Part.makeShell(faces)
    shell.sewShape()
    try:
        solid = Part.makeSolid(Part.Shell(shell.Faces) if shell.ShapeType != "Shell" else shell)
    except Exception as exc:
        raise ValueError("Cannot thicken the bent strip by %g mm: %s" % (thickness, exc))
    if solid.Volume < 0:
        solid.reverse()
    if not solid.isValid() or solid.Volume <= 0:
        raise ValueError("Cannot thicken the bent strip by %g mm (a curvature radius below "
                         "half the thickness?)" % thickness)
    return solid


def strip_shape(result, frame, scale=M_TO_MM, solid=True):
    """Compound ``[flat strip, bent strip]`` of a feasible result: solids of
    the result's ``thickness`` when ``solid`` (the default), else faces."""
    offset = flat_layout_offset(result["points"], result["width"],
                                result["length"], scale)
    flat = flat_strip_face(result["outline"], frame, offset, scale)
    bent = bent_strip_face(result["points"], result["s"], result["width"],
                           frame, scale)
    if solid:
        h = float(result["thickness"]) * scale
        flat = flat_strip_solid(flat, frame, h)
        try:
            bent = bent_strip_solid(bent, h)
        except ValueError:
            bent = bent_strip_solid_from_samples(result["points"], result["s"],
                                                 result["width"], frame, h, scale)
    return Part.makeCompound([flat, bent])
