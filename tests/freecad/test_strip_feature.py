"""Headless FreeCAD tests of the ParaFab ``Strip`` feature.

Run with ``tests/freecad/run_tests.sh [BUILD_DIR]`` or, with this directory
on ``PYTHONPATH``, ``freecadcmd -t test_strip_feature``.

Paths (environment variables, all optional):

* ``PARAFAB_MODULE_DIR`` -- directory holding ``parafab*.so``
  (default ``<repo>/build/workbench/entry``);
* ``PARAFAB_WB_DIR`` -- directory holding the ``parafab_wb`` package
  (default ``<repo>/workbench/freecad/ParaFab``).

The tests need the real solver; ``import parafab`` failing is an error.
"""

import math
import os
import shutil
import sys
import tempfile
import unittest

_HERE = os.path.dirname(os.path.abspath(__file__))
_REPO = os.path.normpath(os.path.join(_HERE, os.pardir, os.pardir))


def _setup_paths():
    """Put the solver module and the workbench package first on sys.path."""
    paths = (
        os.environ.get("PARAFAB_MODULE_DIR")
        or os.path.join(_REPO, "build", "workbench", "entry"),
        os.environ.get("PARAFAB_WB_DIR")
        or os.path.join(_REPO, "workbench", "freecad", "ParaFab"),
    )
    for path in paths:
        if path not in sys.path:
            sys.path.insert(0, path)


_setup_paths()

import FreeCAD  # noqa: E402
import Part  # noqa: E402

import parafab  # noqa: E402
from parafab_wb import geometry  # noqa: E402
from parafab_wb import strip_feature  # noqa: E402

V = FreeCAD.Vector

#: Strip defaults, SI units, for independent solver calls.
E_PA = 3e9
THICKNESS_M = 0.5e-3
MIN_WIDTH_M = 10e-3
#: Simulated deviation of the cardboard arch (800 edges) as measured, times 1.5.
VALIDATION_BOUND = 2.1e-6  # measured 1.41e-6


def _spec_xy(bs, tolerance=1e-6):
    """Solver input for a B-spline lying in the global XY plane (mm -> m).

    Built directly from the curve, independently of ``parafab_wb.geometry``.
    """
    bspline = {
        "degree": bs.Degree,
        "knots": list(bs.KnotSequence),
        "poles": [[p.x * 1e-3, p.y * 1e-3] for p in bs.getPoles()],
    }
    if bs.isRational():
        bspline["weights"] = list(bs.getWeights())
    return {"curve": {"bspline": bspline},
            "material": {"E": E_PA, "thickness": THICKNESS_M},
            "min_width": MIN_WIDTH_M, "tolerance": tolerance}


def _interpolated(points):
    """Non-rational B-spline interpolating ``(x, y)`` points (mm) at z = 0."""
    bs = Part.BSplineCurve()
    bs.interpolate([V(x, y, 0) for x, y in points])
    return bs


def _convex_bspline():
    """A convex planar B-spline (no inflection), about 200 mm long."""
    return _interpolated([(0, 0), (40, 30), (90, 45), (140, 35), (180, 5)])


def _s_curve_three_inflections():
    """y = sin(x) + 0.1 x^2 on [1, 10], scaled by 20 mm.

    Its inflections (sin x = 0.2, x ~ 2.94, 6.48, 9.22) lie on a parabola,
    hence are not collinear: no straight inflection line exists.
    """
    pts = []
    for i in range(61):
        x = 1.0 + 9.0 * i / 60.0
        pts.append((20.0 * x, 20.0 * (math.sin(x) + 0.1 * x * x)))
    return _interpolated(pts)


def _bspline_from_planar(curve):
    """Rebuild a 2D ``Part.BSplineCurve`` (z = 0) from a ``PlanarCurve``."""
    knots, mults = [], []
    for k in curve.knots:
        if knots and k == knots[-1]:
            mults[-1] += 1
        else:
            knots.append(k)
            mults.append(1)
    bs = Part.BSplineCurve()
    bs.buildFromPolesMultsKnots([V(x, y, 0) for x, y in curve.poles], mults,
                                knots, False, curve.degree, curve.weights)
    return bs


def _is_error(obj):
    """True when ``obj`` is in FreeCAD's error state."""
    return "Invalid" in obj.State and not obj.isValid()


class StripTestCase(unittest.TestCase):
    """Base class: one fresh document per test."""

    def setUp(self):
        self.doc = FreeCAD.newDocument("ParaFabTest")
        self.tmpdir = None

    def tearDown(self):
        FreeCAD.closeDocument(self.doc.Name)
        if self.tmpdir:
            shutil.rmtree(self.tmpdir, ignore_errors=True)

    def add_shape(self, name, shape):
        """Add a ``Part::Feature`` holding ``shape``."""
        obj = self.doc.addObject("Part::Feature", name)
        obj.Shape = shape
        return obj

    def strip_on(self, name, shape, recompute=True):
        """Part feature with ``shape`` + a strip on its Edge1."""
        src = self.add_shape(name, shape)
        strip = strip_feature.make_strip(src, "Edge1")
        if recompute:
            self.doc.recompute()
        return src, strip

    def assert_feasible_strip(self, strip):
        """Common checks of a successfully designed strip."""
        self.assertEqual(strip.State, ["Up-to-date"], strip.getStatusString())
        self.assertTrue(strip.Feasible, strip.Reason)
        self.assertEqual(strip.Reason, "")
        self.assertTrue(strip.Shape.isValid())
        self.assertEqual(strip.Shape.ShapeType, "Compound")
        self.assertGreater(strip.Length.Value, 0.0)
        self.assertGreaterEqual(strip.R, 1.0 - 1e-9)
        self.assert_strip_solids(strip)

    def assert_stiffness_by_hand(self, result, bs, rel=1e-6):
        """Independent of the solver's curvature: K = (a + <b, γ>)/κ at every sample, with κ
        from FreeCAD's own curvature of ``bs`` (a curve in the frame's XY coordinates, mm) and
        the solver's line (K normalized to min 1, so the line gives K directly)."""
        a, b = result["line"]["a"], result["line"]["b"]
        kmax = max(abs(k) for k in result["curvature"])
        checked = 0
        for (x, y), K, k in zip(result["points"], result["K"], result["curvature"]):
            if abs(k) < 1e-2 * kmax:  # near a zero K is a 0/0 limit: not by hand
                continue
            u = bs.parameter(V(x * 1e3, y * 1e3, 0))
            kappa = bs.curvature(u) * 1e3  # unsigned, 1/mm -> 1/m
            self.assertAlmostEqual(abs(a + b[0] * x + b[1] * y) / kappa, K, delta=rel * K)
            checked += 1
        self.assertGreater(checked, 10)

    @staticmethod
    def mesh_volume(solid, deflection=1e-2):
        """Volume of a solid from its (watertight) triangulation: sum of the
        signed tetrahedra (origin, triangle). OpenCASCADE's own ``Volume``
        integrates faces bounded by many-knot B-spline edges with too few Gauss
        points here (1.7 % too large for the bent strip, 0.4 % too small for
        the flat one, while the mesh agrees with the integral of w h to 1e-4)."""
        points, triangles = solid.tessellate(deflection)
        return sum(points[a].dot(points[b].cross(points[c])) for a, b, c in triangles) / 6.0

    def assert_strip_solids(self, strip, rel=1e-2):
        """The flat and the bent strip are valid solids whose volume is the
        integral of w(s) h ds (scipy's cubic spline through the solver's samples,
        mm³; the trapezoidal rule is 1 % off on the 69 samples of a strip with
        R = 36)."""
        from scipy.interpolate import CubicSpline
        solids = strip.Shape.Solids
        self.assertEqual(len(solids), 2)
        result = strip.Proxy.result
        s, w = result["s"], result["width"]
        h = strip.Thickness.Value
        expected = CubicSpline(s, w).integrate(s[0], s[-1]) * 1e6 * h
        for which, solid in zip(("flat", "bent"), solids):
            self.assertTrue(solid.isValid(), which)
            self.assertEqual(solid.ShapeType, "Solid", which)
            self.assertAlmostEqual(abs(self.mesh_volume(solid)), expected, delta=rel * expected, msg=which)


class TestGeometry(StripTestCase):
    """Exactness of the edge -> planar NURBS conversion (no solver)."""

    def check_exact(self, edge, hint=None, tol=1e-9):
        """The 2D NURBS must reproduce the edge (mapped to 2D) exactly."""
        curve = geometry.planar_curve_from_edge(edge, hint)
        bs2 = _bspline_from_planar(curve)
        self.assertAlmostEqual(bs2.length(), edge.Length,
                               delta=tol * max(1.0, edge.Length))
        for i in range(21):
            p = edge.valueAt(edge.FirstParameter + (edge.LastParameter
                                                    - edge.FirstParameter) * i / 20.0)
            self.assertLess(abs(curve.frame.height(p)), 1e-7)
            x, y = curve.frame.to_2d(p)
            self.assertLess(bs2.toShape().distToShape(Part.Vertex(V(x, y, 0)))[0],
                            1e-7, "point %d off the converted curve" % i)
        return curve

    def test_circle_arc_is_rational(self):
        edge = Part.Edge(Part.Circle(V(1, 2, 3), V(0, 0, 1), 50), 0.3, 2.9)
        curve = self.check_exact(edge)
        self.assertIsNotNone(curve.weights)
        self.assertEqual(curve.degree, 2)

    def test_ellipse_arc(self):
        edge = Part.Edge(Part.Ellipse(V(0, 0, 0), 80, 30), 0.2, 2.5)
        self.check_exact(edge)

    def test_trimmed_bspline(self):
        bs = _convex_bspline()
        edge = Part.Edge(bs, 0.2 * bs.LastParameter, 0.7 * bs.LastParameter)
        curve = self.check_exact(edge)
        self.assertEqual(curve.knots[0], curve.knots[curve.degree])  # clamped

    def test_periodic_bspline_across_seam(self):
        bs = Part.BSplineCurve()
        bs.interpolate([V(0, 0, 0), V(100, 0, 0), V(100, 80, 0), V(0, 60, 0)],
                       PeriodicFlag=True)
        period = bs.LastParameter - bs.FirstParameter
        edge = Part.Edge(bs, bs.LastParameter - 0.2 * period,
                         bs.LastParameter + 0.3 * period)
        self.check_exact(edge)

    def test_tilted_plane_and_placement(self):
        edge = Part.Edge(Part.Circle(V(0, 0, 0), V(0, 0, 1), 40), 0.0, 2.0)
        edge.Placement = FreeCAD.Placement(V(5, -3, 7),
                                           FreeCAD.Rotation(V(1, 1, 0), 35))
        self.check_exact(edge)

    def test_sketch_hint_keeps_sketch_coordinates(self):
        placement = FreeCAD.Placement(V(10, 20, 30), FreeCAD.Rotation(V(1, 0, 0), 90))
        bs = _convex_bspline()
        shape = bs.toShape()
        shape.Placement = placement
        curve = geometry.planar_curve_from_edge(
            shape.Edges[0], geometry.PlaneFrame.from_placement(placement))
        for (x, y), p in zip(curve.poles, bs.getPoles()):
            self.assertAlmostEqual(x, p.x, places=9)
            self.assertAlmostEqual(y, p.y, places=9)

    def test_helix_is_not_planar(self):
        helix = Part.makeHelix(5.0, 20.0, 10.0)
        with self.assertRaisesRegex(geometry.GeometryError, "planar"):
            geometry.planar_curve_from_edge(helix.Edges[0])


class TestStripFeature(StripTestCase):
    """The Strip feature in a document, against the real solver."""

    def test_bspline_strip_matches_solver(self):
        bs = _convex_bspline()
        src, strip = self.strip_on("Curve", bs.toShape())
        self.assert_feasible_strip(strip)
        expected = parafab.design_strip(_spec_xy(bs))
        self.assertTrue(expected["feasible"])
        self.assertAlmostEqual(strip.R, expected["R"],
                               delta=1e-9 * abs(expected["R"]))
        self.assertAlmostEqual(strip.Length.Value, expected["length"] * 1e3,
                               delta=1e-9 * expected["length"] * 1e3)
        self.assertAlmostEqual(strip.Length.Value, bs.length(),
                               delta=1e-4 * bs.length())
        self.assert_stiffness_by_hand(strip.Proxy.result, bs)
        # Flat strip in the curve's plane (z = 0), bent strip spans the width
        # along the plane normal (z).
        flat, bent = strip.Shape.Solids
        self.assertAlmostEqual(flat.BoundBox.ZLength, 0.5, places=6)  # the thickness
        self.assertAlmostEqual(flat.BoundBox.Center.z, 0.0, places=6)
        self.assertLess(flat.BoundBox.YMax, bs.toShape().BoundBox.YMin)
        self.assertGreaterEqual(bent.BoundBox.ZLength, 10.0 - 1e-6)
        self.assertAlmostEqual(bent.BoundBox.ZMin, -bent.BoundBox.ZMax, places=6)

    def test_circular_arc_R_is_one(self):
        radius, angle = 150.0, 2.0
        edge = Part.Edge(Part.Circle(V(0, 0, 0), V(0, 0, 1), radius), 0.4, 0.4 + angle)
        _, strip = self.strip_on("Arc", edge)
        self.assert_feasible_strip(strip)
        self.assertAlmostEqual(strip.R, 1.0, delta=1e-9)
        self.assertAlmostEqual(strip.Length.Value, radius * angle,
                               delta=1e-6 * radius * angle)
        # Constant curvature -> constant width: bent strip is exactly MinWidth wide.
        self.assertAlmostEqual(strip.Shape.Solids[1].BoundBox.ZLength, 10.0, places=6)

    def test_sketch_bspline_in_rotated_plane(self):
        bs = _convex_bspline()
        sketch = self.doc.addObject("Sketcher::SketchObject", "Sketch")
        sketch.Placement = FreeCAD.Placement(V(0, 50, 0),
                                             FreeCAD.Rotation(V(1, 0, 0), 90))
        sketch.addGeometry(bs, False)
        self.doc.recompute()
        strip = strip_feature.make_strip(sketch, "Edge1")
        self.doc.recompute()
        self.assert_feasible_strip(strip)
        expected = parafab.design_strip(_spec_xy(bs))
        self.assertAlmostEqual(strip.R, expected["R"], delta=1e-6 * expected["R"])
        self.assert_stiffness_by_hand(strip.Proxy.result, bs)  # sketch coordinates
        # Sketch plane is y = 50 with normal -Y: the flat strip lies in it,
        # the bent strip spans the width along Y.
        flat, bent = strip.Shape.Solids
        self.assertAlmostEqual(flat.BoundBox.YLength, 0.5, places=6)
        self.assertAlmostEqual(flat.BoundBox.Center.y, 50.0, places=6)
        self.assertGreaterEqual(bent.BoundBox.YLength, 10.0 - 1e-6)
        self.assertAlmostEqual(bent.BoundBox.Center.y, 50.0, places=6)

    def test_sketch_in_placed_body(self):
        body = self.doc.addObject("PartDesign::Body", "Body")
        body.Placement = FreeCAD.Placement(V(0, 0, 40),
                                           FreeCAD.Rotation(V(0, 0, 1), 30))
        sketch = body.newObject("Sketcher::SketchObject", "Sketch")
        sketch.addGeometry(_convex_bspline(), False)
        self.doc.recompute()
        strip = strip_feature.make_strip(sketch, "Edge1")
        self.doc.recompute()
        self.assert_feasible_strip(strip)
        # The strip follows the sketch in global coordinates (plane z = 40).
        flat, bent = strip.Shape.Solids
        self.assertAlmostEqual(flat.BoundBox.ZLength, 0.5, places=6)
        self.assertAlmostEqual(flat.BoundBox.Center.z, 40.0, places=6)
        self.assertAlmostEqual(bent.BoundBox.Center.z, 40.0, places=6)
        global_edge = sketch.Shape.Edges[0].copy()
        global_edge.Placement = body.Placement.multiply(global_edge.Placement)
        self.assertLess(bent.distToShape(global_edge)[0], 1e-6)

    def test_bent_solid_around_the_centreline(self):
        bs = _convex_bspline()
        _, strip = self.strip_on("Curve", bs.toShape())
        self.assert_feasible_strip(strip)
        flat, bent = strip.Shape.Solids
        h = strip.Thickness.Value
        # the centreline runs inside the bent solid, h/2 from both faces
        for u in (0.1, 0.3, 0.5, 0.7, 0.9):
            p = bs.value(bs.FirstParameter + u * (bs.LastParameter - bs.FirstParameter))
            self.assertTrue(bent.isInside(p, 1e-6, False), p)
            self.assertAlmostEqual(Part.Vertex(p).distToShape(bent.Shells[0])[0], 0.5 * h, delta=1e-3 * h)
        # Solids = False: the two faces of before
        strip.Solids = False
        self.doc.recompute()
        self.assertEqual(len(strip.Shape.Solids), 0)
        self.assertEqual(len(strip.Shape.Faces), 2)
        self.assertTrue(strip.Shape.isValid())

    def test_move_pole_recomputes(self):
        bs = _convex_bspline()
        src, strip = self.strip_on("Curve", bs.toShape())
        self.assert_feasible_strip(strip)
        r_before, length_before = strip.R, strip.Length.Value
        moved = bs.copy()
        moved.setPole(3, moved.getPole(3) + V(0, 25, 0))
        src.Shape = moved.toShape()
        self.assertIn("Touched", src.State)
        self.doc.recompute()
        self.assert_feasible_strip(strip)
        self.assertNotAlmostEqual(strip.R, r_before, delta=1e-9 * r_before)
        self.assertNotAlmostEqual(strip.Length.Value, length_before, places=3)
        expected = parafab.design_strip(_spec_xy(moved))
        self.assertAlmostEqual(strip.R, expected["R"], delta=1e-9 * expected["R"])
        self.assert_stiffness_by_hand(strip.Proxy.result, moved)

    def test_save_and_reopen(self):
        _, strip = self.strip_on("Curve", _convex_bspline().toShape())
        strip.Thickness = "0.8 mm"
        strip.MinWidth = "12 mm"
        self.doc.recompute()
        self.assert_feasible_strip(strip)
        r_saved = strip.R
        self.tmpdir = tempfile.mkdtemp(prefix="parafab_")
        path = os.path.join(self.tmpdir, "strip.FCStd")
        self.doc.saveAs(path)
        FreeCAD.closeDocument(self.doc.Name)

        self.doc = FreeCAD.openDocument(path)
        strip = self.doc.getObject("Strip")
        self.assertIsInstance(strip.Proxy, strip_feature.StripFeature)
        self.assertEqual(strip.Proxy.Type, strip_feature.TYPE)
        self.assertEqual(strip.Proxy.Version, strip_feature.VERSION)
        self.assertAlmostEqual(strip.Thickness.Value, 0.8)
        self.assertAlmostEqual(strip.MinWidth.Value, 12.0)
        self.assertAlmostEqual(strip.YoungsModulus.getValueAs("Pa"), 3e9)
        self.assertEqual(strip.Edge[0].Name, "Curve")
        self.assertEqual(list(strip.Edge[1]), ["Edge1"])
        self.assertTrue(strip.Feasible)
        self.assertAlmostEqual(strip.R, r_saved, delta=1e-12 * r_saved)
        strip.touch()
        self.doc.recompute()
        self.assert_feasible_strip(strip)
        self.assertAlmostEqual(strip.R, r_saved, delta=1e-12 * r_saved)

    def test_infeasible_curve(self):
        box = self.doc.addObject("Part::Box", "Box")
        bs = _s_curve_three_inflections()
        expected = parafab.design_strip(_spec_xy(bs))
        self.assertFalse(expected["feasible"])
        src, strip = self.strip_on("SCurve", bs.toShape())
        self.assertTrue(_is_error(strip))
        self.assertFalse(strip.Feasible)
        self.assertNotEqual(expected["reason"], "")
        self.assertIn(expected["reason"], strip.Reason)
        # Independent: y'' = 20 (0.2 − sin x)/400 vanishes where sin x = 0.2, x = π − 0.2014,
        # 2π + 0.2014, 3π − 0.2014 (the interpolant of 61 points moves them slightly).
        xs = [p["point"][0] * 1e3 for p in expected["inflections"]]  # mm
        self.assertEqual(len(xs), 3)
        x0 = math.asin(0.2)
        for got, want in zip(xs, (math.pi - x0, 2 * math.pi + x0, 3 * math.pi - x0)):
            self.assertAlmostEqual(got, 20.0 * want, delta=0.05)
        self.assertAlmostEqual(strip.Length.Value, expected["length"] * 1e3,
                               delta=1e-9 * expected["length"] * 1e3)
        self.assertIn(strip.Reason, strip.getStatusString())
        self.assertTrue(strip.Shape.isNull())
        for obj in (box, src):
            self.assertTrue(obj.isValid(), obj.Name)
            self.assertEqual(obj.State, ["Up-to-date"], obj.Name)
        # The document stays usable.
        box.Length = 20
        self.doc.recompute()
        self.assertAlmostEqual(box.Shape.Volume, 2000.0)

    def test_zero_thickness_is_an_error_then_recovers(self):
        _, strip = self.strip_on("Curve", _convex_bspline().toShape(),
                                 recompute=False)
        strip.Thickness = 0
        self.doc.recompute()
        self.assertTrue(_is_error(strip))
        self.assertFalse(strip.Feasible)
        self.assertIn("thickness", strip.Reason)
        self.assertTrue(strip.Shape.isNull())
        strip.Thickness = "0.5 mm"
        self.doc.recompute()
        self.assert_feasible_strip(strip)

    def test_non_planar_edges(self):
        bs3d = Part.BSplineCurve()
        bs3d.interpolate([V(0, 0, 0), V(50, 30, 10), V(100, 20, -15), V(150, 60, 5)])
        for name, shape in (("Helix", Part.makeHelix(20.0, 60.0, 15.0)),
                            ("Curve3D", bs3d.toShape())):
            _, strip = self.strip_on(name, shape)
            self.assertTrue(_is_error(strip), name)
            self.assertFalse(strip.Feasible)
            self.assertIn("planar", strip.Reason)
            self.assertTrue(strip.Shape.isNull())

    def test_missing_link_is_an_error(self):
        _, strip = self.strip_on("Curve", _convex_bspline().toShape(),
                                 recompute=False)
        strip.Edge = None
        self.doc.recompute()
        self.assertTrue(_is_error(strip))
        self.assertIn("No edge", strip.Reason)

    def test_make_strip_rejects_non_edge(self):
        src = self.add_shape("Box", Part.makeBox(1, 2, 3))
        with self.assertRaises(ValueError):
            strip_feature.make_strip(src, "Face1")


def _ellipse_arc_mm():
    """The cardboard test arch of the solver tests: semi-axes 200 x 120 mm, 0.2..2.9 rad."""
    pts = [(200.0 * math.cos(t), 120.0 * math.sin(t))
           for t in (0.2 + 2.7 * i / 120.0 for i in range(121))]
    return _interpolated(pts)


class TestStripVersion2(StripTestCase):
    """Gravity, presets, strip types, validation, cut sheets, version-1 documents."""

    def cardboard_strip(self, name="Arch", gravity=True):
        src, strip = self.strip_on(name, _ellipse_arc_mm().toShape(), recompute=False)
        strip.MaterialPreset = "Cardboard 200 gsm"
        strip.MinWidth = "20 mm"
        strip.Gravity = gravity
        strip.GravityDirection = V(0, -1, 0)  # the curve lies in XY; "down" is -Y
        self.doc.recompute()
        return src, strip

    def test_presets_set_the_material(self):
        _, strip = self.strip_on("Curve", _convex_bspline().toShape())
        self.assertEqual(strip.MaterialPreset, "Custom")
        for name, (E, h, rho) in strip_feature.PRESETS.items():
            strip.MaterialPreset = name
            self.assertAlmostEqual(strip.YoungsModulus.getValueAs("Pa"), E, delta=1e-6 * E)
            self.assertAlmostEqual(strip.Thickness.getValueAs("m"), h, delta=1e-12)
            self.assertAlmostEqual(strip.Density, rho)
        # The cardboard preset reproduces the thesis' gravito-bending parameter.
        E, h, rho = strip_feature.PRESETS["Cardboard 200 gsm"]
        self.assertAlmostEqual(E * h * h / (12 * rho * 9.81), 8.86e-4, delta=2e-6)
        strip.Thickness = "0.6 mm"  # editing by hand leaves the preset
        self.assertEqual(strip.MaterialPreset, "Custom")
        self.assertAlmostEqual(strip.Thickness.Value, 0.6)

    def test_a_preset_that_would_yield_is_refused(self):
        """A 120° arc of radius 15 mm: bending strain h/(2r) (closed form) is 0.8/30 = 0.0267
        for plywood 0.8 mm (yield strain 0.005: refused, 5.33x) and 0.5/30 = 0.0167 for POM
        0.5 mm (0.023: accepted, ratio 0.725). The refused strip shows the error, the document
        stays valid, and choosing POM recovers it."""
        r = 15.0
        edge = Part.Edge(Part.Circle(V(0, 0, 0), V(0, 0, 1), r), 0.2, 0.2 + 2 * math.pi / 3)
        src, strip = self.strip_on("Arc", edge, recompute=False)
        strip.MaterialPreset = "Plywood 0.8 mm"
        strip.MinWidth = "5 mm"
        self.doc.recompute()
        self.assertTrue(_is_error(strip))
        self.assertFalse(strip.Feasible)
        self.assertTrue(strip.Shape.isNull())
        self.assertIn('material "Plywood 0.8 mm" yields', strip.Reason)
        self.assertIn(strip.Reason, strip.getStatusString())
        strain = float(strip.Reason.split("h·|κ|/2 = ")[1].split()[0])
        self.assertAlmostEqual(strain, 0.8 / (2 * r), delta=5e-8)  # printed to 6 digits
        self.assertIn("exceeds its yield strain 0.005 (5.33", strip.Reason)
        self.assertTrue(src.isValid())
        self.assertEqual(src.State, ["Up-to-date"])
        strip.MaterialPreset = "POM 0.5 mm"
        self.doc.recompute()
        self.assert_feasible_strip(strip)
        self.assertAlmostEqual(strip.R, 1.0, delta=1e-6)  # a circular arc: constant K

    def test_gravity_changes_the_design(self):
        _, plain = self.cardboard_strip("Plain", gravity=False)
        _, heavy = self.cardboard_strip("Heavy", gravity=True)
        self.assert_feasible_strip(plain)
        self.assert_feasible_strip(heavy)
        self.assertGreater(abs(heavy.R - plain.R), 1e-3 * plain.R)
        self.assertGreater(heavy.RFirst, 1.0)
        self.assertEqual(plain.RFirst, 0.0)
        k0 = plain.Proxy.result["K"]
        k1 = heavy.Proxy.result["K"]
        self.assertTrue(heavy.Proxy.result["general_lp"])
        self.assertNotEqual(len(k0), 0)
        self.assertGreater(abs(max(k1) - max(k0)), 1e-3)
        # Same as the solver called directly with the projected direction and the preset.
        self.assertEqual(heavy.Proxy.result["gravity"]["direction"], [0.0, -1.0])
        self.assertAlmostEqual(heavy.Proxy.result["gravity"]["beta_l3"], 8.86e-4, delta=2e-6)

    def test_gravity_on_a_tilted_plane_loads_with_its_in_plane_component(self):
        # The arch in a plane through the x axis tilted by 60 degrees from the horizontal:
        # gravity (0, 0, -1) has the in-plane component g·sin(60°) = g·cos(30°), 30° being
        # the tilt of the plane from the vertical. Before the fix the solver received the
        # full g (the projected direction was normalized).
        shape = _ellipse_arc_mm().toShape()
        shape.rotate(V(0, 0, 0), V(1, 0, 0), 60)
        _, strip = self.strip_on("Tilted", shape, recompute=False)
        strip.MaterialPreset = "Cardboard 200 gsm"
        strip.MinWidth = "20 mm"
        strip.Gravity = True
        strip.GravityDirection = V(0, 0, -1)
        self.doc.recompute()
        self.assert_feasible_strip(strip)
        E, h, rho = strip_feature.PRESETS["Cardboard 200 gsm"]
        g_in_plane = 9.81 * math.cos(math.radians(30))
        gravity = strip.Proxy.result["gravity"]
        self.assertAlmostEqual(gravity["beta_l3"], E * h * h / (12 * rho * g_in_plane),
                               delta=1e-12 * gravity["beta_l3"])
        self.assertAlmostEqual(math.hypot(*gravity["load"]), 12 * rho * g_in_plane / (E * h * h),
                               delta=1e-9 * math.hypot(*gravity["load"]))
        # The same design as the arch in its own (XY) plane under the reduced weight.
        spec = _spec_xy(_ellipse_arc_mm())
        spec["material"] = {"E": E, "thickness": h}
        spec["min_width"] = 0.02
        spec["gravity"] = {"direction": [0, -1], "beta_l3": E * h * h / (12 * rho * g_in_plane)}
        expected = parafab.design_strip(spec)
        self.assertAlmostEqual(strip.R, expected["R"], delta=1e-6 * expected["R"])

    def test_export_after_a_change_never_writes_a_stale_sheet(self):
        # Change MinWidth without recomputing, then export: the sheet is the new design
        # (recomputed first). R does not depend on MinWidth, so the widest width is
        # MinWidth·R. Before the fix the sheet had the old 20 mm minimum width.
        _, strip = self.cardboard_strip(gravity=False)
        R = strip.R
        strip.MinWidth = "30 mm"
        self.assertIn("Touched", strip.State)
        self.tmpdir = tempfile.mkdtemp(prefix="parafab_")
        dxf, _ = strip_feature.export_cut_sheets(strip, self.tmpdir)
        self.assertEqual(strip.State, ["Up-to-date"])
        self.assertAlmostEqual(max(strip.Proxy.result["width"]), 0.03 * R, delta=1e-9)
        self.assert_dxf_reads_back(dxf, strip, max_width_mm=30.0 * R)
        # A change that makes the strip infeasible: the export refuses, with the reason.
        strip.Thickness = "0 mm"
        with self.assertRaises(strip_feature.StripError) as ctx:
            strip_feature.export_cut_sheets(strip, self.tmpdir)
        self.assertIn("no feasible design to export (recomputed)", str(ctx.exception))
        self.assertIn("material.thickness must be positive", str(ctx.exception))

    def test_gravity_perpendicular_to_the_plane_is_an_error(self):
        _, strip = self.cardboard_strip()
        strip.GravityDirection = V(0, 0, -1)
        self.doc.recompute()
        self.assertTrue(_is_error(strip))
        self.assertIn("perpendicular to the curve's plane", strip.Reason)
        strip.GravityDirection = V(0, -1, 0)
        self.doc.recompute()
        self.assert_feasible_strip(strip)

    def test_validate_reports_the_deviation(self):
        _, strip = self.cardboard_strip()
        self.assertEqual(strip.Deviation, 0.0)
        strip.Validate = True
        self.doc.recompute()
        self.assert_feasible_strip(strip)
        self.assertGreater(strip.Deviation, 0.0)
        print("\n  cardboard arch under gravity: simulated deviation %.3g" % strip.Deviation)
        self.assertLess(strip.Deviation, VALIDATION_BOUND)

    def test_strip_types_and_cut_sheets(self):
        _, strip = self.cardboard_strip()
        self.tmpdir = tempfile.mkdtemp(prefix="parafab_")
        for kind, layer in (("Plain", "OUTLINE"), ("Composite", "INNER"), ("Perforated", "HOLES")):
            strip.StripType = kind
            strip.OuterWidth = "50 mm" if kind == "Composite" else "40 mm"
            self.doc.recompute()
            self.assert_feasible_strip(strip)
            if kind != "Plain":
                self.assertIn("feasible", strip.TypeMessage)
                self.assertNotIn("infeasible", strip.TypeMessage)
            if kind == "Perforated":  # the deviation of the pattern is shown, as the solver reports it
                per = strip.Proxy.result["perforations"]
                self.assertIn("within %.2f %% of the design (sections %.2f %%)" % (
                    100 * per["interior_stiffness_deviation"], 100 * per["interior_width_deviation"]),
                    strip.TypeMessage)
                self.assertIn("the hole-free ends are up to %.0f %% stiffer" % (100 * per["end_zone_deviation"]),
                              strip.TypeMessage)
                self.assertLess(per["interior_stiffness_deviation"], per["max_stiffness_deviation"])
                self.assertLess(per["interior_width_deviation"], 0.02)
            dxf, svg = strip_feature.export_cut_sheets(strip, self.tmpdir)
            for path in (dxf, svg):
                self.assertTrue(os.path.getsize(path) > 0)
            with open(dxf) as f:
                text = f.read()
            self.assertIn("\n" + layer + "\n", text)
            self.assertIn("START clamp", text)
            self.assertIn(strip.Label, text)
            with open(svg) as f:
                self.assertIn('id="%s"' % layer, f.read())
            if kind == "Plain":
                self.assert_dxf_reads_back(dxf, strip)

    def assert_dxf_reads_back(self, path, strip, max_width_mm=None):
        """FreeCAD's own DXF importer reads the cut sheet at true scale (mm): the outline
        spans the strip's length, the clamp lines 2 mm beyond half the widest width
        (``max_width_mm``, default the widest width of the strip's result)."""
        import Import
        doc = FreeCAD.newDocument("DxfRead")
        try:
            Import.readDXF(path, doc.Name, True)
            bb = FreeCAD.BoundBox()
            for o in doc.Objects:
                if hasattr(o, "Shape") and not o.Shape.isNull() and o.Shape.Edges:
                    bb.add(o.Shape.BoundBox)
            half = 0.5 * max_width_mm if max_width_mm else 500.0 * max(strip.Proxy.result["width"])
            self.assertAlmostEqual(bb.XMin, 0.0, delta=1e-6)
            self.assertAlmostEqual(bb.XMax, strip.Length.Value, delta=1e-5)
            self.assertAlmostEqual(bb.YMax, half + 2.0, delta=1e-5)
            self.assertAlmostEqual(bb.YMin, -half - 2.0, delta=1e-5)
        finally:
            FreeCAD.closeDocument(doc.Name)

    def test_export_of_an_infeasible_strip_is_an_error(self):
        _, strip = self.strip_on("S", _s_curve_three_inflections().toShape())
        self.assertFalse(strip.Feasible)
        self.tmpdir = tempfile.mkdtemp(prefix="parafab_")
        with self.assertRaises(strip_feature.StripError):
            strip_feature.export_cut_sheets(strip, self.tmpdir)

    def test_strips_recompute_independently(self):
        src_a, a = self.strip_on("CurveA", _convex_bspline().toShape())
        src_b, b = self.cardboard_strip("CurveB")
        na, nb = a.Proxy.executions, b.Proxy.executions
        r_b = b.R
        moved = _convex_bspline()
        moved.setPole(3, moved.getPole(3) + V(0, 25, 0))
        src_a.Shape = moved.toShape()
        self.assertIn("Touched", src_a.State)
        self.assertNotIn("Touched", src_b.State)
        self.doc.recompute()
        self.assertEqual(a.Proxy.executions, na + 1)
        self.assertEqual(b.Proxy.executions, nb)   # the other strip did not recompute
        self.assertEqual(b.State, ["Up-to-date"])
        self.assertEqual(b.R, r_b)
        b.Gravity = False                          # and the other way round
        self.doc.recompute()
        self.assertEqual(a.Proxy.executions, na + 1)
        self.assertEqual(b.Proxy.executions, nb + 1)

    def test_version_1_document_still_loads(self):
        _, strip = self.strip_on("Curve", _convex_bspline().toShape())
        r_v1 = strip.R
        # What a document saved by version 1 holds: no version-2 properties, Version 1.
        for name in ("MaterialPreset", "Density", "Gravity", "GravityDirection", "StripType",
                     "OuterWidth", "InnerThickness", "Validate", "Deviation", "RFirst",
                     "TypeMessage", "Solids"):
            strip.removeProperty(name)
        strip.Proxy.VERSION = strip.Proxy.Version = 1  # the instance now saves state version 1
        self.assertEqual(strip.Proxy.__getstate__(), {"Type": strip_feature.TYPE, "Version": 1})
        self.tmpdir = tempfile.mkdtemp(prefix="parafab_")
        path = os.path.join(self.tmpdir, "v1.FCStd")
        self.doc.saveAs(path)
        FreeCAD.closeDocument(self.doc.Name)
        self.doc = FreeCAD.openDocument(path)
        strip = self.doc.getObject("Strip")
        self.assertEqual(strip.Proxy.Version, strip_feature.VERSION)  # upgraded on restore
        self.assertEqual(strip.Proxy.__getstate__()["Version"], strip_feature.VERSION)
        self.assertFalse(strip.Gravity)
        self.assertTrue(strip.Solids)  # version 3: solids from the next recompute on
        self.assertEqual(strip.StripType, "Plain")
        self.assertEqual(strip.MaterialPreset, "Custom")
        self.assertEqual(strip.GravityDirection, V(0, 0, -1))
        self.assertAlmostEqual(strip.Thickness.Value, 0.5)  # restore did not apply a preset
        strip.touch()
        self.doc.recompute()
        self.assert_feasible_strip(strip)
        self.assertAlmostEqual(strip.R, r_v1, delta=1e-12 * r_v1)

    def test_version_1_proxy_upgraded_in_place(self):
        _, strip = self.strip_on("Curve", _convex_bspline().toShape())
        for name in ("Gravity", "GravityDirection", "StripType", "Deviation"):
            strip.removeProperty(name)
        strip.Proxy.Version = 1
        strip.Proxy.onDocumentRestored(strip)
        self.assertEqual(strip.Proxy.Version, strip_feature.VERSION)
        for name in ("Gravity", "GravityDirection", "StripType", "Deviation"):
            self.assertIn(name, strip.PropertiesList)



class TestStripProfilePlot(StripTestCase):
    """plot_profile: K(s) and w(s) as a PNG, headless (matplotlib's Agg canvas)."""

    cardboard_strip = TestStripVersion2.cardboard_strip

    def png(self, strip, name):
        if not self.tmpdir:
            self.tmpdir = tempfile.mkdtemp(prefix="parafab_")
        path = os.path.join(self.tmpdir, name)
        self.assertEqual(strip_feature.plot_profile(strip, path), path)
        with open(path, "rb") as f:
            self.assertEqual(f.read(8), b"\x89PNG\r\n\x1a\n")
        self.assertGreater(os.path.getsize(path), 10000)
        return path

    def test_plain_and_composite_profiles(self):
        _, strip = self.cardboard_strip()
        self.assert_feasible_strip(strip)
        self.png(strip, "plain.png")
        strip.StripType = "Composite"
        strip.OuterWidth = "50 mm"
        self.doc.recompute()
        self.assert_feasible_strip(strip)
        self.png(strip, "composite.png")

    def test_reopened_document_is_designed_again(self):
        _, strip = self.cardboard_strip()
        strip.Proxy.result = None  # what a reopened document holds
        self.png(strip, "again.png")

    def test_infeasible_strip_is_an_error(self):
        _, strip = self.strip_on("S", _s_curve_three_inflections().toShape())
        self.assertFalse(strip.Feasible)
        with self.assertRaises(strip_feature.StripError) as cm:
            strip_feature.plot_profile(strip, os.path.join(tempfile.gettempdir(), "never.png"))
        self.assertIn("no feasible design to plot", str(cm.exception))


class TestStripsFromSections(StripTestCase):
    """Strips from sections: a cylinder r = 15 mm cut by planes z = const and split at y = 0
    gives semicircles, each an equilibrium of a constant-stiffness strip (R = 1)."""

    def test_cylinder_sections_give_semicircle_strips(self):
        from parafab_wb import sections
        cyl = self.add_shape("Cylinder", Part.makeCylinder(15, 40))
        group, report = sections.strips_from_sections(cyl, (0, 0, 1), 3, split=((0, 1, 0), 0.0))
        self.assertEqual(report["designed"], 6)
        strips = [o for o in group.Group if o.TypeId == "Part::FeaturePython"]
        self.assertEqual(len(strips), 6)
        for strip in strips:
            self.assert_feasible_strip(strip)
            self.assertAlmostEqual(strip.R, 1.0, delta=1e-3)
            self.assertAlmostEqual(strip.Length.Value, 15 * math.pi, delta=1e-3)
        self.assertTrue(all(o.isValid() for o in self.doc.Objects))

    def test_unsplit_closed_sections_are_reported_not_stripped(self):
        from parafab_wb import sections
        cyl = self.add_shape("Cylinder", Part.makeCylinder(15, 40))
        group, report = sections.strips_from_sections(cyl, (0, 0, 1), 2)
        self.assertEqual(len(group.Group), 0)
        self.assertEqual(report["failed"], 2)
        self.assertIn("closed section curve", report["curves"][0]["strip"]["error"]["message"])


class TestRevolutionStrips(StripTestCase):
    """Surface of revolution strips: b = (10/m, 0), a = 0 from r = 100 mm is a sphere."""

    def test_sphere_surface_and_strips(self):
        from parafab_wb import revolution_feature
        obj = revolution_feature.make_revolution_strips(self.doc)
        obj.Strips = 8
        self.doc.recompute()
        self.assertEqual(obj.State, ["Up-to-date"], obj.Status)
        self.assertTrue(obj.Complete)
        faces = obj.Shape.Faces
        surface = [f for f in faces if f.Surface.TypeId != "Part::GeomPlane" and abs(f.Area) > 0]
        # the surface: a spherical zone of radius 100 mm from the equator over 120 mm of meridian
        zone = 2 * math.pi * 100 * 100 * math.sin(1.2)
        self.assertAlmostEqual(obj.Shape.Faces[0].Area, zone, delta=2e-3 * zone)
        self.assertEqual(len(faces), 1 + 8 + 1)
        self.assertGreater(obj.R, 1.0)
        self.assertAlmostEqual(obj.R, 1.0 / math.cos(1.2), delta=1e-6)  # x from 100 to 100 cos(1.2)
        self.assertTrue(len(surface) >= 1)

    def test_bad_strip_count_is_an_error_and_recovers(self):
        from parafab_wb import revolution_feature
        obj = revolution_feature.make_revolution_strips(self.doc)
        obj.Strips = 2
        self.doc.recompute()
        self.assertTrue(_is_error(obj))
        self.assertIn("at least 3", obj.Status)
        obj.Strips = 6
        self.doc.recompute()
        self.assertEqual(obj.State, ["Up-to-date"], obj.Status)

if __name__ == "__main__":
    unittest.main()


def _elastica_mm(half, amplitude=0.5, P=100.0, steps=4000):
    """Inflectional elastica (K = const) with ``half`` inflections, in mm (pure-Python RK4:
    kappa' = -P sin(alpha) from alpha(0) = 0, cut at the half-th zero of alpha)."""
    k0 = 2 * math.sqrt(P) * math.sin(amplitude / 2)

    def f(q):
        return (math.cos(q[2]), math.sin(q[2]), q[3], -P * math.sin(q[2]))
    h = 1e-4
    q = (0.0, 0.0, 0.0, k0)
    pts, crossings, i = [(0.0, 0.0)], 0, 0
    while True:
        k1 = f(q)
        k2 = f(tuple(a + h / 2 * b for a, b in zip(q, k1)))
        k3 = f(tuple(a + h / 2 * b for a, b in zip(q, k2)))
        k4 = f(tuple(a + h * b for a, b in zip(q, k3)))
        qn = tuple(a + h / 6 * (b + 2 * c + 2 * d + e) for a, b, c, d, e in zip(q, k1, k2, k3, k4))
        i += 1
        if i > 1 and (q[2] > 0) != (qn[2] > 0):
            crossings += 1
            if crossings == half:
                t = q[2] / (q[2] - qn[2])
                pts.append((1e3 * (q[0] + t * (qn[0] - q[0])), 1e3 * (q[1] + t * (qn[1] - q[1]))))
                break
        q = qn
        if i % 40 == 0:
            pts.append((1e3 * q[0], 1e3 * q[1]))
    return _interpolated(pts)


class TestStripStability(StripTestCase):
    """Stability (thesis section 4.5): read-only Stable/Unstable and Sigma, the Z(s) plot."""

    def test_stable_and_unstable_elastica(self):
        _, stable = self.strip_on("TwoInflections", _elastica_mm(2).toShape())
        _, unstable = self.strip_on("ThreeInflections", _elastica_mm(3).toShape())
        self.assert_feasible_strip(stable)
        self.assert_feasible_strip(unstable)
        self.assertEqual(stable.Stability, "Stable")
        self.assertEqual(stable.Sigma.Value, 0.0)
        self.assertEqual(unstable.Stability, "Unstable")
        self.assertGreater(unstable.Sigma.Value, 0.5 * unstable.Length.Value)
        self.assertLess(unstable.Sigma.Value, unstable.Length.Value)
        for prop in ("Stability", "Sigma"):
            self.assertIn("ReadOnly", unstable.getTypeOfProperty(prop))
        # Independent of the Jacobi test: the simulator's constrained Hessian inertia of the
        # same designs (parafab.strip_stability) gives the same verdicts.
        for strip, expect in ((stable, True), (unstable, False)):
            r = parafab.strip_stability(_spec_xy(strip.Edge[0].Shape.Edges[0].Curve))
            self.assertEqual(r["stability"]["eigenvalue"]["stable"], expect)
            if not expect:
                self.assertAlmostEqual(r["stability"]["sigma"] * 1e3, unstable.Sigma.Value,
                                       delta=2e-3 * unstable.Length.Value)
        self.tmpdir = tempfile.mkdtemp(prefix="parafab_")
        path = os.path.join(self.tmpdir, "z.png")
        self.assertEqual(strip_feature.plot_stability(unstable, path), path)
        with open(path, "rb") as f:
            self.assertEqual(f.read(8), b"\x89PNG\r\n\x1a\n")
        self.assertGreater(os.path.getsize(path), 10000)
