"""Result display of an ``Analysis``: the deformed part coloured by von Mises stress.

The solver writes ``OUTDIR/surface.vtu``: the part's triangulated B-rep faces (ASCII VTK
UnstructuredGrid, ``VTK_TRIANGLE`` cells) with the point data ``displacement`` (3 components)
and ``von_mises``, and the cell data ``face`` (B-rep face index). This module

* reads that file (:func:`read_surface`; no numerics, only parsing and checks),
* builds a ``Mesh::Feature`` owned by the analysis (its ``ResultMesh`` link) whose vertices are
  ``point + scale * displacement``, one mesh vertex per VTU point in the same order,
* colours the vertices on a blue -> cyan -> green -> yellow -> red scale between the smallest
  and largest von Mises value on the surface (``VertexColors``, a ``PropertyColorList`` with one
  colour per vertex, which FreeCAD 0.20's mesh view provider shows when its ``Coloring`` is on),
* shows the scale beside it in the 3D view: ``von Mises [MPa]`` with the values at the colour
  stops (:func:`show_legend`, a :mod:`parafab_wb.legend` overlay that is visible with the mesh).

The mesh object keeps ``Displacement``, ``VonMises`` and the applied ``Scale``, so a new
deformation scale only moves the vertices (:func:`rescale`) without the files or the solver.
Works headless; view properties are only touched when ``FreeCAD.GuiUp``.
"""

import xml.etree.ElementTree as ET

import FreeCAD
import Mesh

SURFACE_FILE = "surface.vtu"
#: Automatic deformation scale: the largest displacement shows as this fraction of the
#: part's bounding-box diagonal.
AUTO_FRACTION = 0.05
#: Colour scale from the smallest (first) to the largest (last) value.
COLOR_STOPS = ((0.0, 0.0, 1.0), (0.0, 1.0, 1.0), (0.0, 1.0, 0.0), (1.0, 1.0, 0.0), (1.0, 0.0, 0.0))

#: Title (with the unit) of the colour scale shown beside the result.
LEGEND_TITLE = "von Mises [MPa]"

_VTK_TRIANGLE = 5
#: Properties added to the result ``Mesh::Feature``: (type, name, tooltip).
_MESH_PROPERTIES = (
    ("App::PropertyVectorList", "Displacement", "Displacement of each vertex [mm]"),
    ("App::PropertyFloatList", "VonMises", "von Mises stress at each vertex [MPa]"),
    ("App::PropertyColorList", "VertexColors", "Colour of each vertex (von Mises, blue = low, red = high)"),
    ("App::PropertyFloat", "Scale", "Displacement magnification applied to the vertices"),
)


class SurfaceResult(object):
    """Contents of ``surface.vtu``: lists indexed like the VTU points and cells."""

    def __init__(self, points, triangles, displacement, von_mises, face):
        self.points = points              # [(x, y, z)] undeformed
        self.triangles = triangles        # [(i, j, k)]
        self.displacement = displacement  # [(ux, uy, uz)]
        self.von_mises = von_mises        # [s]
        self.face = face                  # [B-rep face index per triangle]


def _numbers(array, convert, what, path):
    try:
        return [convert(v) for v in (array.text or "").split()]
    except ValueError as exc:
        raise ValueError("%s: bad number in %s (%s)" % (path, what, exc))


def _triples(values, count, what, path):
    if len(values) != 3 * count:
        raise ValueError("%s: %s has %d values, expected %d" % (path, what, len(values), 3 * count))
    return [tuple(values[3 * i:3 * i + 3]) for i in range(count)]


def read_surface(path):
    """Read ``surface.vtu`` written by ``parafab simulate``; raises ``ValueError`` when malformed."""
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as exc:
        raise ValueError("cannot read %s: %s" % (path, exc))
    piece = root.find("UnstructuredGrid/Piece")
    if piece is None:
        raise ValueError("%s is not a VTK UnstructuredGrid" % path)
    n_points = int(piece.get("NumberOfPoints", "0"))
    n_cells = int(piece.get("NumberOfCells", "0"))

    def named(section, name):
        for array in piece.findall(section + "/DataArray"):
            if array.get("Name") == name:
                return array
        raise ValueError("%s: no %s array '%s'" % (path, section, name))

    points_array = piece.find("Points/DataArray")
    if points_array is None:
        raise ValueError("%s: no Points" % path)
    points = _triples(_numbers(points_array, float, "Points", path), n_points, "Points", path)
    displacement = _triples(_numbers(named("PointData", "displacement"), float, "displacement", path),
                            n_points, "displacement", path)
    von_mises = _numbers(named("PointData", "von_mises"), float, "von_mises", path)
    connectivity = _numbers(named("Cells", "connectivity"), int, "connectivity", path)
    types = _numbers(named("Cells", "types"), int, "types", path)
    face = _numbers(named("CellData", "face"), int, "face", path)
    if len(von_mises) != n_points:
        raise ValueError("%s: von_mises has %d values for %d points" % (path, len(von_mises), n_points))
    if len(types) != n_cells or len(face) != n_cells or any(t != _VTK_TRIANGLE for t in types):
        raise ValueError("%s: expected %d triangles (VTK type 5) with a face index each" % (path, n_cells))
    triangles = _triples(connectivity, n_cells, "connectivity", path)
    if any(i < 0 or i >= n_points for tri in triangles for i in tri):
        raise ValueError("%s: connectivity refers to a point that does not exist" % path)
    return SurfaceResult(points, triangles, displacement, von_mises, face)


def max_displacement(displacement):
    """Largest magnitude of the displacement vectors (tuples or FreeCAD vectors)."""
    return max([(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]) ** 0.5 for u in displacement] or [0.0])


def auto_scale(displacement, size):
    """Scale at which the largest of the ``displacement`` vectors shows as ``AUTO_FRACTION`` of
    ``size`` (mm); 1 when nothing moves."""
    umax = max_displacement(displacement)
    return AUTO_FRACTION * size / umax if umax > 0 and size > 0 else 1.0


def color(t):
    """RGB on the blue -> red scale for ``t`` in [0, 1] (clamped)."""
    t = min(max(t, 0.0), 1.0) * (len(COLOR_STOPS) - 1)
    i = min(int(t), len(COLOR_STOPS) - 2)
    f = t - i
    a, b = COLOR_STOPS[i], COLOR_STOPS[i + 1]
    return tuple(a[k] + f * (b[k] - a[k]) for k in range(3))


def colors(values, lo, hi):
    """One colour per value; ``lo`` is blue and ``hi`` red."""
    span = hi - lo
    return [color((v - lo) / span if span > 0 else 0.0) for v in values]


def _deformed_mesh(points, displacement, scale):
    return [FreeCAD.Vector(p[0] + scale * u[0], p[1] + scale * u[1], p[2] + scale * u[2])
            for p, u in zip(points, displacement)]


def _add_mesh_properties(mesh_obj):
    for ptype, name, tip in _MESH_PROPERTIES:
        if name not in mesh_obj.PropertiesList:
            mesh_obj.addProperty(ptype, name, "ParaFab", tip)
            mesh_obj.setEditorMode(name, 1)  # read-only in the property editor


def create_result_mesh(analysis):
    """A new, empty result ``Mesh::Feature`` for ``analysis`` (not linked yet)."""
    mesh_obj = analysis.Document.addObject("Mesh::Feature", analysis.Name + "Result")
    mesh_obj.Label = analysis.Label + " result"
    _add_mesh_properties(mesh_obj)
    return mesh_obj


def show_surface(mesh_obj, surface, scale):
    """Put the deformed, coloured ``surface`` into ``mesh_obj``; returns (min, max) von Mises."""
    _add_mesh_properties(mesh_obj)
    lo = min(surface.von_mises) if surface.von_mises else 0.0
    hi = max(surface.von_mises) if surface.von_mises else 0.0
    vertices = _deformed_mesh(surface.points, surface.displacement, scale)
    mesh = Mesh.Mesh((vertices, surface.triangles))
    if mesh.CountPoints != len(vertices) or mesh.CountFacets != len(surface.triangles):
        raise ValueError("the result mesh lost vertices or triangles (%d/%d points, %d/%d facets)"
                         % (mesh.CountPoints, len(vertices), mesh.CountFacets, len(surface.triangles)))
    mesh_obj.Mesh = mesh
    mesh_obj.Displacement = [FreeCAD.Vector(*u) for u in surface.displacement]
    mesh_obj.VonMises = list(surface.von_mises)
    mesh_obj.VertexColors = colors(surface.von_mises, lo, hi)
    mesh_obj.Scale = float(scale)
    _show_colors(mesh_obj)
    show_legend(mesh_obj)
    if FreeCAD.GuiUp and mesh_obj.ViewObject is not None:
        mesh_obj.ViewObject.Visibility = True
    mesh_obj.purgeTouched()
    return lo, hi


def rescale(mesh_obj, scale):
    """Move the vertices of a result mesh to ``undeformed + scale * displacement``."""
    if "Displacement" not in mesh_obj.PropertiesList or not mesh_obj.Displacement:
        return
    points, facets = mesh_obj.Mesh.Topology
    old = mesh_obj.Scale
    disp = mesh_obj.Displacement
    if len(points) != len(disp):
        return
    vertices = [p + u * (scale - old) for p, u in zip(points, disp)]
    mesh_obj.Mesh = Mesh.Mesh((vertices, facets))
    mesh_obj.Scale = float(scale)
    _show_colors(mesh_obj)
    mesh_obj.purgeTouched()


def clear(mesh_obj):
    """Empty the result mesh (after a failed run its old result would be misleading)."""
    if mesh_obj.Mesh.CountPoints:
        mesh_obj.Mesh = Mesh.Mesh()
        for name in ("Displacement", "VonMises", "VertexColors"):
            if name in mesh_obj.PropertiesList:
                setattr(mesh_obj, name, [])
        mesh_obj.purgeTouched()
    show_legend(mesh_obj)  # no values: no scale


def show_legend(mesh_obj):
    """Show the colour scale of result mesh ``mesh_obj`` in the 3D view (GUI only): the
    smallest von Mises value blue, the largest red, in MPa. Without values the scale is
    removed. Returns the legend node or ``None``."""
    if not FreeCAD.GuiUp or mesh_obj is None or getattr(mesh_obj, "ViewObject", None) is None:
        return None
    from . import legend
    values = list(getattr(mesh_obj, "VonMises", None) or [])
    if not values:
        legend.remove(mesh_obj.ViewObject)
        return None
    return legend.show(mesh_obj.ViewObject, LEGEND_TITLE, min(values), max(values), COLOR_STOPS)


def _show_colors(mesh_obj):
    if not FreeCAD.GuiUp:
        return
    vobj = mesh_obj.ViewObject
    if vobj is None:
        return
    if "Coloring" in vobj.PropertiesList:
        vobj.Coloring = False  # re-read VertexColors for the new vertices
        vobj.Coloring = True
    if "Lighting" in vobj.PropertiesList:
        vobj.Lighting = "Two side"
