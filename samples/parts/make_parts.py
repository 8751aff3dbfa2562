# Regenerates the STEP sample parts in samples/parts with FreeCAD's Part workbench: the
# X-CAD inputs of thesis ch. 6 (B-rep solids with fillets, holes, slots, tori; §6.2.1).
#
#   freecadcmd samples/parts/make_parts.py
#   PARAFAB_PARTS_DIR=/tmp/parts freecadcmd -c "exec(open('samples/parts/make_parts.py').read())"
#
# Output: PARAFAB_PARTS_DIR, default samples/parts under the current directory. Sizes in mm.
# The tests (tests/occ_bridge) check the radii used here; keep them in sync.
import os

import FreeCAD
import Import
import Part

V = FreeCAD.Vector
Z = V(0, 0, 1)


def vertical_edges(shape, pred):
    """Edges parallel to z whose midpoint satisfies pred(x, y)."""
    out = []
    for e in shape.Edges:
        a, b = e.Vertexes[0].Point, e.Vertexes[-1].Point
        if e.Curve.TypeId == "Part::GeomLine" and abs(a.x - b.x) < 1e-9 and abs(a.y - b.y) < 1e-9:
            if pred(a.x, a.y):
                out.append(e)
    return out


def edges_where(shape, pred):
    """Edges whose midpoint m satisfies pred(m)."""
    return [e for e in shape.Edges if pred(e.valueAt(0.5 * (e.FirstParameter + e.LastParameter)))]


def box():
    return Part.makeBox(40, 30, 20)


def cylinder():
    return Part.makeCylinder(15, 40)  # radius 15


def l_bracket(hole_radius=4):
    # L profile in xz: base 60 x 8, upright 8 x 50, extruded 40 along y; two bolt holes r=4
    # (l_bracket_holes5: the same part after a parameter edit, holes r=5, for re-cutting).
    base = Part.makeBox(60, 40, 8)
    upright = Part.makeBox(8, 40, 50)
    s = base.fuse(upright).removeSplitter()
    inner = edges_where(s, lambda m: abs(m.x - 8) < 1e-6 and abs(m.z - 8) < 1e-6)   # concave
    outer = edges_where(s, lambda m: abs(m.x) < 1e-6 and abs(m.z) < 1e-6)           # convex
    s = s.makeFillet(5, inner)      # inner fillet radius 5
    s = s.makeFillet(12, outer)     # outer fillet radius 12
    for y in (12, 28):
        s = s.cut(Part.makeCylinder(hole_radius, 20, V(40, y, -5), Z))
    return s


def wrench():
    # Handle with a stadium slot, round head with an open jaw, ring end with a hole; 6 mm thick.
    t = 6
    handle = Part.makeBox(80, 14, t, V(0, -7, 0))
    head = Part.makeCylinder(16, t, V(80, 0, 0), Z)
    ring = Part.makeCylinder(10, t, V(0, 0, 0), Z)
    s = handle.fuse(head).fuse(ring).removeSplitter()
    # Concave handle/head and handle/ring junctions: fillet radius 4.
    s = s.makeFillet(4, vertical_edges(s, lambda x, y: abs(abs(y) - 7) < 1e-6 and x > 1))
    jaw = Part.makeBox(20, 10, t + 2, V(84, -5, -1))
    s = s.cut(jaw)
    slot = Part.makeBox(30, 6, t + 2, V(25, -3, -1))
    slot = slot.fuse(Part.makeCylinder(3, t + 2, V(25, 0, -1), Z))
    slot = slot.fuse(Part.makeCylinder(3, t + 2, V(55, 0, -1), Z)).removeSplitter()
    s = s.cut(slot).cut(Part.makeCylinder(5, t + 2, V(0, 0, -1), Z))
    # Convex jaw mouth edges: fillet radius 1.5.
    s = s.makeFillet(1.5, vertical_edges(s, lambda x, y: x > 94 and abs(abs(y) - 5) < 1e-6))
    return s.removeSplitter()


def ring():
    # Annulus (outer radius 30, inner 20) extruded 10 along z.
    disc = Part.Face(Part.Wire(Part.makeCircle(30)))
    annulus = disc.cut(Part.Face(Part.Wire(Part.makeCircle(20)))).Faces[0]
    return annulus.extrude(V(0, 0, 10))


def half_torus():
    # Torus major radius 30, minor 8, swept over 180 degrees.
    return Part.makeTorus(30, 8, V(0, 0, 0), Z, -180, 180, 180)


def wheel():
    # Hub and rim joined by five spokes at irregular angles and widths; 10 mm thick.
    t = 10
    rim = Part.makeCylinder(50, t).cut(Part.makeCylinder(42, t))
    hub = Part.makeCylinder(12, t).cut(Part.makeCylinder(5, t))
    s = rim.fuse(hub)
    for angle, width in ((0, 8), (65, 6), (140, 10), (200, 6), (290, 8)):
        spoke = Part.makeBox(34, width, t, V(10, -width / 2.0, 0))
        spoke.rotate(V(0, 0, 0), Z, angle)
        s = s.fuse(spoke)
    return s.removeSplitter()


def housing():
    # Open-bottom shell 60 x 40 x 30 (wall 3) with rounded vertical corners (radius 6),
    # four cooling fins on top and a round boss with a fillet at its base (torus).
    outer = Part.makeBox(60, 40, 30)
    outer = outer.makeFillet(6, vertical_edges(outer, lambda x, y: True))
    inner = Part.makeBox(54, 34, 28, V(3, 3, -1))
    inner = inner.makeFillet(3, vertical_edges(inner, lambda x, y: True))
    s = outer.cut(inner)
    for i in range(4):
        s = s.fuse(Part.makeBox(2, 30, 8, V(8 + 8 * i, 5, 30)))
    s = s.fuse(Part.makeCylinder(6, 10, V(48, 20, 30), Z)).removeSplitter()
    base = edges_where(s, lambda m: abs(m.z - 30) < 1e-6 and abs((m - V(48, 20, 30)).Length - 6) < 1e-6)
    s = s.makeFillet(2, base)  # boss base fillet: torus, major radius 8, minor 2
    return s.removeSplitter()


def plate_holes():
    # Plate 160 x 100 x 5 with an 8 x 5 grid of holes, radius 5, pitch 20 (thesis Table 6.1:
    # "plate with a grid of holes"; the hole radii are the design variables).
    s = Part.makeBox(160, 100, 5)
    for i in range(8):
        for j in range(5):
            s = s.cut(Part.makeCylinder(5, 5, V(10 + 20 * i, 10 + 20 * j, 0), Z))
    return s.removeSplitter()


def bridge_holes():
    # Plate 200 x 80 x 2.5 with a 20 x 8 grid of square holes, side 5.5, pitch 10 (thesis
    # Table 6.1 and Fig. 6.18, "topology optimization": 20 x 8 square holes whose side lengths,
    # n = 160, are the design variables; each pitch cell's solid fraction 1 - 0.55^2 = 0.6975,
    # near the thesis's 0.7). On an 80-cell grid each pitch cell is a 4 x 4 block of elements,
    # as in the thesis's 80 x 1 x 32 grid, and the hole walls (2.25 and 7.75 in each cell) lie
    # off the grid planes.
    holes = [Part.makeBox(5.5, 5.5, 2.5, V(2.25 + 10 * i, 2.25 + 10 * j, 0))
             for i in range(20) for j in range(8)]
    return Part.makeBox(200, 80, 2.5).cut(Part.makeCompound(holes)).removeSplitter()


def flange():
    # Disc radius 50, 8 thick, bore radius 12, six bolt holes radius 5 on the circle of radius
    # 32 about z, one at +x and the others its copies turned by 60° steps (the rotational
    # pattern of `parafab optimize`'s "rotations").
    s = Part.makeCylinder(50, 8).cut(Part.makeCylinder(12, 8))
    for k in range(6):
        hole = Part.makeCylinder(5, 8, V(32, 0, 0), Z)
        hole.rotate(V(0, 0, 0), Z, 60 * k)
        s = s.cut(hole)
    return s.removeSplitter()


def bump_block():
    # A block 60 x 40 whose top is a free-form face: the cubic x cubic B-spline with 6 x 5 poles
    # on the regular grid x = 12 i, y = 10 j, z = 12 + 0.05 x, the 12 interior poles raised by
    # 2 + 0.5 i (a bump rising towards +x); the sides and the bottom are planes. The top's
    # boundary rows of poles lie in the side planes, so its edges are its iso-curves and moving
    # an interior pole leaves them alone (`parafab optimize` parameters "pole i j z").
    poles = []
    for i in range(6):
        row = []
        for j in range(5):
            x, y = 12.0 * i, 10.0 * j
            z = 12.0 + 0.05 * x + ((2.0 + 0.5 * i) if 0 < i < 5 and 0 < j < 4 else 0.0)
            row.append(V(x, y, z))
        poles.append(row)
    surf = Part.BSplineSurface()
    surf.buildFromPolesMultsKnots(poles, [4, 1, 1, 4], [4, 1, 4], [0, 1.0 / 3, 2.0 / 3, 1], [0, 0.5, 1],
                                  False, False, 3, 3)
    top = surf.toShape()
    corners = [V(0, 0, 0), V(60, 0, 0), V(60, 40, 0), V(0, 40, 0)]
    up = [surf.value(u, v) for u, v in ((0, 0), (1, 0), (1, 1), (0, 1))]
    isos = [surf.vIso(0).toShape(), surf.uIso(1).toShape(), surf.vIso(1).toShape(), surf.uIso(0).toShape()]
    faces = [top, Part.Face(Part.makePolygon(corners + [corners[0]]))]
    for k in range(4):
        a, b = k, (k + 1) % 4
        faces.append(Part.Face(Part.Wire(Part.__sortEdges__([
            Part.makeLine(corners[a], corners[b]), Part.makeLine(corners[b], up[b]), isos[k],
            Part.makeLine(up[a], corners[a])]))))
    shell = Part.Shell(faces)
    shell.sewShape()
    solid = Part.Solid(shell)
    if solid.Volume < 0:
        solid.reverse()
    return solid


def blind_hole_block():
    # Block 40 x 40 x 20 with a blind hole r = 5 from the top down to z = 10: deepened past the
    # bottom face, its floor would cross that face away from any shared edge (a solid OCCT's
    # BRepCheck_Analyzer passes; the write-back's self-interference test refuses it).
    return Part.makeBox(40, 40, 20).cut(Part.makeCylinder(5, 10, V(20, 20, 10), Z))


def countersunk_pin_block():
    # Block 60 x 40 x 12 with a countersunk hole (cylinder r = 4 through, cone of semi-angle 45
    # degrees from r = 4 at z = 8 to r = 8 at the top) at (15, 20), and a round-ended pin at
    # (42, 20): a cylinder r = 6 from the top up to z = 24 capped by a hemisphere r = 6 (centre
    # z = 24, tangent to the cylinder). The cone's and the sphere's parameters (semi-angle, radius,
    # centre) are design entries of the optimizer; the pin's tangency ties sphere and cylinder.
    s = Part.makeBox(60, 40, 12)
    s = s.cut(Part.makeCylinder(4, 20, V(15, 20, -4), Z))
    s = s.cut(Part.makeCone(4, 10, 6, V(15, 20, 8), Z))
    pin = Part.makeCylinder(6, 14, V(42, 20, 10), Z).fuse(Part.makeSphere(6, V(42, 20, 24)))
    return s.fuse(pin).removeSplitter()


PARTS = {"box": box, "cylinder": cylinder, "l_bracket": l_bracket, "wrench": wrench,
         "ring": ring, "half_torus": half_torus, "wheel": wheel, "housing": housing,
         "l_bracket_holes5": lambda: l_bracket(5), "plate_holes": plate_holes,
         "bridge_holes": bridge_holes,
         "flange": flange, "bump_block": bump_block, "blind_hole_block": blind_hole_block,
         "countersunk_pin_block": countersunk_pin_block}
# PARAFAB_PARTS_ONLY="a,b" regenerates only those parts.
only = [n for n in os.environ.get("PARAFAB_PARTS_ONLY", "").split(",") if n]

out_dir = os.environ.get("PARAFAB_PARTS_DIR", os.path.join("samples", "parts"))
os.makedirs(out_dir, exist_ok=True)
for name, make in PARTS.items():
    if only and name not in only:
        continue
    shape = make()
    if not shape.isValid() or len(shape.Solids) != 1:
        raise RuntimeError("%s: invalid shape or not one solid (%d solids)" % (name, len(shape.Solids)))
    path = os.path.join(out_dir, name + ".step")
    shape.Solids[0].exportStep(path)
    print("%-11s %3d faces  volume %10.1f mm^3  -> %s" % (name, len(shape.Faces), shape.Volume, path))

if only:
    raise SystemExit(0)

# Two named solids in one file (STEP products named by the objects' labels): for choosing a
# solid by index or name.
doc = FreeCAD.newDocument("two_blocks")
left = doc.addObject("Part::Feature", "left_block")
left.Shape = Part.makeBox(20, 20, 10)
right = doc.addObject("Part::Feature", "right_block")
right.Shape = Part.makeCylinder(8, 10, V(40, 10, 0))
doc.recompute()
Import.export([left, right], os.path.join(out_dir, "two_blocks.step"))
FreeCAD.closeDocument(doc.Name)
print("two_blocks: left_block (box) and right_block (cylinder r=8)")


# A scanned-like sheet (thesis §4.8.2: strips from sections of a measured surface): the
# B-spline surface interpolating z = 30 sin(pi x / 100) on a 21 x 13 grid over
# [0, 100] x [0, 60] mm, each grid point lifted by a deterministic "scan noise" of at most
# 0.15 mm. Its sections y = const are noisy arcs: the quartic interpolation of their points
# has spurious inflections, the fair fit of the sections job removes them.
def noisy_sheet():
    import math
    rows = []
    for i in range(21):
        x = 5.0 * i
        row = []
        for j in range(13):
            y = 5.0 * j
            noise = 0.15 * math.sin(12.9898 * i + 78.233 * j + 0.5 * i * j)
            row.append(V(x, y, 30.0 * math.sin(math.pi * x / 100.0) + noise))
        rows.append(row)
    surf = Part.BSplineSurface()
    surf.interpolate(rows)
    return surf.toShape()


sheet = noisy_sheet()
if not sheet.isValid():
    raise RuntimeError("noisy_sheet: invalid face")
# Surfaces (not solids) go beside the parts, in samples/surfaces: the parts are solids.
surf_dir = os.path.join(os.path.dirname(os.path.abspath(out_dir)), "surfaces")
os.makedirs(surf_dir, exist_ok=True)
sheet.exportStep(os.path.join(surf_dir, "noisy_sheet.step"))
print("noisy_sheet: one B-spline face, %.1f mm^2" % sheet.Area)
