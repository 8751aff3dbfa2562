"""Headless FreeCAD tests of the ParaFab ``Rod`` feature (Kirchhoff rods, thesis ch. 5).

Run with ``tests/freecad/run_tests.sh [BUILD_DIR]`` or, with this directory on
``PYTHONPATH``, ``freecadcmd -t test_rod_feature``.  Environment as in
test_strip_feature.py (PARAFAB_MODULE_DIR, PARAFAB_WB_DIR).

Independent checks: the solver is called directly with a spec built here from the
edge's B-spline (not through ``parafab_wb``); the solid's volume is compared with
the trapezoidal integral of pi*a*b over s from that result.
"""

import json
import math
import os
import shutil
import sys
import tempfile
import unittest

_HERE = os.path.dirname(os.path.abspath(__file__))
_REPO = os.path.normpath(os.path.join(_HERE, os.pardir, os.pardir))


def _setup_paths():
    paths = (
        os.environ.get("PARAFAB_MODULE_DIR") or os.path.join(_REPO, "build", "workbench", "entry"),
        os.environ.get("PARAFAB_WB_DIR") or os.path.join(_REPO, "workbench", "freecad", "ParaFab"),
    )
    for path in paths:
        if path not in sys.path:
            sys.path.insert(0, path)


_setup_paths()

import FreeCAD  # noqa: E402
import Part  # noqa: E402

import parafab  # noqa: E402
from parafab_wb import rod_feature  # noqa: E402

V = FreeCAD.Vector


def _interpolated(points_mm):
    bs = Part.BSplineCurve()
    bs.interpolate([V(*p) for p in points_mm])
    return bs


def _helix(r=100.0, p=30.0, turns=1.5, n=90):
    return _interpolated([(r * math.cos(t), r * math.sin(t), p * t)
                          for t in (2 * math.pi * turns * i / (n - 1) for i in range(n))])


def _sculpture_segment(k, n=121, scale=200.0):
    pts = []
    for i in range(n):
        u = (k + i / (n - 1.0)) * 4 * math.pi / 3
        pts.append((scale * (math.cos(u) + 0.25 * math.cos(u / 2 + 0.45)),
                    scale * (math.sin(u) + 0.25 * math.sin(u / 2 + 0.45)), scale * 0.4 * math.cos(1.5 * u)))
    return _interpolated(pts)


def _infeasible_fourier():
    with open(os.path.join(_REPO, "samples", "rods", "infeasible_fourier.json")) as f:
        return _interpolated([(1e3 * x, 1e3 * y, 1e3 * z) for x, y, z in json.load(f)["curve"]["points"]])


def _spec(bs, **extra):
    """Solver input from a Part.BSplineCurve in mm, built here (not by parafab_wb)."""
    spline = {"degree": bs.Degree, "knots": list(bs.KnotSequence),
              "poles": [[q.x * 1e-3, q.y * 1e-3, q.z * 1e-3] for q in bs.getPoles()]}
    if bs.isRational():
        spline["weights"] = list(bs.getWeights())
    # The Rod feature's default SectionFactor is 4, as in the JSON input.
    spec = {"curve": {"bspline": spline}, "max_radius": 0.005, "samples": 200, "section": {"factor": 4.0}}
    spec.update(extra)
    return spec


def _volume_mm3(result):
    s, A = result["s"], result["section"]["area"]
    return 1e9 * sum(0.5 * (A[i] + A[i - 1]) * (s[i] - s[i - 1]) for i in range(1, len(s)))


def _mesh_volume(solid, deflection):
    """Volume of the tessellated solid (divergence theorem over its triangles): an
    independent check of OCC's GProp volume, which loses up to ~1 % on the skinned tube.
    The inscribed mesh is smaller by ~(2/3)·deflection/radius."""
    import numpy as np
    points, triangles = solid.tessellate(deflection)
    P = np.array([(p.x, p.y, p.z) for p in points])
    T = np.array(triangles)
    return float(np.einsum("ij,ij->i", P[T[:, 0]], np.cross(P[T[:, 1]], P[T[:, 2]])).sum()) / 6.0


def _is_error(obj):
    return "Invalid" in obj.State and not obj.isValid()


class RodTestCase(unittest.TestCase):
    def setUp(self):
        self.doc = FreeCAD.newDocument("ParaFabRodTest")
        self.tmpdir = tempfile.mkdtemp(prefix="parafab_rod_")

    def tearDown(self):
        FreeCAD.closeDocument(self.doc.Name)
        shutil.rmtree(self.tmpdir, ignore_errors=True)

    def rod_on(self, name, shape, recompute=True, **props):
        src = self.doc.addObject("Part::Feature", name)
        src.Shape = shape
        rod = rod_feature.make_rod(src, "Edge1")
        for k, v in props.items():
            setattr(rod, k, v)
        if recompute:
            self.doc.recompute()
        return src, rod

    def assert_feasible_rod(self, rod, expected=None, mesh_check=False):
        self.assertEqual(rod.State, ["Up-to-date"], rod.getStatusString())
        self.assertTrue(rod.Feasible, rod.Reason)
        self.assertEqual(rod.Status, "ok")
        self.assertTrue(rod.Shape.isValid())
        self.assertEqual(len(rod.Shape.Solids), 2)
        for solid in rod.Shape.Solids:
            self.assertTrue(solid.isValid())
            self.assertTrue(solid.Shells[0].isClosed())
        if expected is not None:
            self.assertAlmostEqual(rod.Length.Value, expected["length"] * 1e3, delta=1e-9 * rod.Length.Value)
            self.assertAlmostEqual(rod.TwistMax, max(abs(t) for t in expected["twist"]), delta=1e-9)
            # The loft: volume = ∫ π a b ds for sections normal to the centreline (Pappus).
            vol = _volume_mm3(expected)
            deformed, straight = rod.Shape.Solids
            radius = 1e3 * max(expected["section"]["a"])
            mesh = _mesh_volume(deformed, 0.01 * radius) if mesh_check else float("nan")
            print("\n[rod] %s: V/∫πab ds - 1: deformed %.2e (tessellated %.2e), straight %.2e; L %.1f mm, "
                  "twist max %.3g rad/m" % (rod.Edge[0].Name, deformed.Volume / vol - 1, mesh / vol - 1,
                                           straight.Volume / vol - 1, rod.Length.Value, rod.TwistMax),
                  file=sys.stderr)
            if mesh_check:
                self.assertAlmostEqual(mesh / vol, 1.0, delta=0.006)
            else:
                # OCC's GProp volume of the skinned, twisted tube loses up to 1.15e-2 (sculpture
                # segment at SectionFactor 4, tessellated -4.5e-3): the mesh check is the tight one.
                self.assertAlmostEqual(deformed.Volume / vol, 1.0, delta=0.01)
            self.assertAlmostEqual(straight.Volume / vol, 1.0, delta=0.01)
            # Clamped end frames: at the curve's ends, z axis = tangent.
            for placement, end in ((rod.StartFrame, expected["end_frames"][0]),
                                   (rod.EndFrame, expected["end_frames"][1])):
                self.assertLess((placement.Base - V(*end["position"]) * 1e3).Length, 1e-9)
                z = placement.Rotation.multVec(V(0, 0, 1))
                x = placement.Rotation.multVec(V(1, 0, 0))
                self.assertLess((z - V(*end["tangent"])).Length, 1e-9)
                self.assertLess((x - V(*end["n1"])).Length, 1e-9)


class TestRodFeature(RodTestCase):
    def test_helix_rod_matches_solver(self):
        bs = _helix()
        _, rod = self.rod_on("Helix", bs.toShape())
        expected = parafab.design_rod(_spec(bs))
        self.assert_feasible_rod(rod, expected, mesh_check=True)
        self.assertLess(rod.TwistMax * rod.Length.Value * 1e-3, 1e-3)  # a parallel curve
        self.assertAlmostEqual(rod.R, expected["R"], delta=1e-12)
        # The straight rod lies beside (below in Y) the deformed one.
        deformed, straight = rod.Shape.Solids
        self.assertLess(straight.BoundBox.YMax, deformed.BoundBox.YMin)
        self.assertAlmostEqual(straight.BoundBox.XLength, rod.Length.Value, delta=0.05 * rod.Length.Value)

    def test_default_helix_rod_is_stable_and_factor_one_is_not(self):
        """The default SectionFactor (4) gives a stable helix rod; factor 1 (most circular) an
        unstable one. Independent check: the forward simulation (Validate) stays on the curve
        for the stable rod and leaves it for the unstable one (resources/doc/rods.md: 9.9e-6 and 0.49 L)."""
        _, rod = self.rod_on("Helix", _helix().toShape(), Validate=True)
        self.assertAlmostEqual(rod.SectionFactor, 4.0)
        self.assert_feasible_rod(rod)
        self.assertEqual(rod.Stability, "Stable")
        self.assertEqual(rod.NegativeEigenvalues, 0)
        self.assertGreater(rod.MinRelativeEigenvalue, 0.0)
        self.assertLess(rod.EquilibriumDistance, 1e-4)
        self.assertLess(rod.Deviation, 1e-4)
        rod.SectionFactor = 1.0
        self.doc.recompute()
        self.assert_feasible_rod(rod)
        self.assertEqual(rod.Stability, "Unstable")
        self.assertGreater(rod.EquilibriumDistance, 0.1)  # the rod leaves the target
        self.assertGreater(rod.Deviation, 0.1)

    def test_sculpture_segment_under_gravity_is_validated(self):
        bs = _sculpture_segment(1)
        _, rod = self.rod_on("Segment", bs.toShape(), GravityOn=True, MaxRadius="25 mm", Validate=True,
                             Samples=400)
        expected = parafab.design_rod(_spec(bs, max_radius=0.025, samples=400, validate=True,
                                            loads={"dead_load": True, "gravity": [0, 0, -9.81]}))
        self.assert_feasible_rod(rod, expected)
        self.assertGreater(rod.LoadIterations, 1)
        self.assertEqual(rod.LoadIterations, expected["load_iterations"]["iterations"])
        self.assertGreaterEqual(rod.Deviation, 0.0)
        self.assertLess(rod.Deviation, 4.5e-4)  # measured 2.67e-4 (2026-11-28); before: 1e-3
        self.assertAlmostEqual(rod.Deviation, expected["simulation"]["deviation"], delta=1e-12)
        self.assertGreater(rod.TwistMax, 1.0)

    def test_recomputes_when_the_curve_changes(self):
        src, rod = self.rod_on("Curve", _sculpture_segment(0).toShape())
        self.assert_feasible_rod(rod)
        length, twist, volume = rod.Length.Value, rod.TwistMax, rod.Shape.Solids[0].Volume
        changed = _sculpture_segment(2)
        src.Shape = changed.toShape()
        self.assertIn("Touched", src.State)
        self.doc.recompute()
        expected = parafab.design_rod(_spec(changed))
        self.assert_feasible_rod(rod, expected, mesh_check=True)
        self.assertNotAlmostEqual(rod.Length.Value, length, places=3)
        self.assertNotAlmostEqual(rod.TwistMax, twist, places=6)
        self.assertNotAlmostEqual(rod.Shape.Solids[0].Volume, volume, delta=1e-6 * volume)

    def test_rational_tilted_circle_arc(self):
        arc = Part.ArcOfCircle(Part.Circle(V(10, 20, 30), V(0.3, -0.5, 0.8), 80.0), 0.2, 2.5)
        _, rod = self.rod_on("Arc", arc.toShape())
        self.assert_feasible_rod(rod)
        self.assertLess(rod.TwistMax, 1e-6)
        self.assertAlmostEqual(rod.Length.Value, 80.0 * 2.3, delta=1e-6)

    def test_save_and_reopen(self):
        _, rod = self.rod_on("Helix", _helix().toShape(), SectionFactor=4.0, MaxRadius="4 mm")
        self.assert_feasible_rod(rod)
        r_saved, twist_saved, volume = rod.R, rod.TwistMax, rod.Shape.Solids[0].Volume
        path = os.path.join(self.tmpdir, "rod.FCStd")
        self.doc.saveAs(path)
        FreeCAD.closeDocument(self.doc.Name)
        self.doc = FreeCAD.openDocument(path)
        rod = self.doc.getObject("Rod")
        self.assertIsInstance(rod.Proxy, rod_feature.RodFeature)
        self.assertEqual(rod.Proxy.Type, rod_feature.TYPE)
        self.assertEqual(rod.Material, "SmoothSil 960")
        self.assertAlmostEqual(rod.SectionFactor, 4.0)
        self.assertAlmostEqual(rod.MaxRadius.Value, 4.0)
        self.assertEqual(rod.Edge[0].Name, "Helix")
        self.assertTrue(rod.Feasible)
        self.assertEqual(len(rod.Shape.Solids), 2)
        rod.touch()
        self.doc.recompute()
        self.assert_feasible_rod(rod)
        self.assertAlmostEqual(rod.R, r_saved, delta=1e-15)
        self.assertAlmostEqual(rod.TwistMax, twist_saved, delta=1e-12)
        self.assertAlmostEqual(rod.Shape.Solids[0].Volume, volume, delta=1e-9 * volume)

    def test_infeasible_curve_is_an_error_state(self):
        box = self.doc.addObject("Part::Box", "Box")
        bs = _infeasible_fourier()
        expected = parafab.design_rod(_spec(bs, samples=400))
        self.assertFalse(expected["feasible"])
        src, rod = self.rod_on("Fourier", bs.toShape(), Samples=400)
        self.assertTrue(_is_error(rod))
        self.assertFalse(rod.Feasible)
        self.assertEqual(rod.Status, "infeasible")
        self.assertIn("binding samples at s =", rod.Reason)
        self.assertIn(rod.Reason, rod.getStatusString())
        self.assertTrue(rod.Shape.isNull())
        for obj in (box, src):
            self.assertTrue(obj.isValid(), obj.Name)
        box.Length = 20
        self.doc.recompute()
        self.assertAlmostEqual(box.Shape.Volume, 2000.0)
        with self.assertRaises(rod_feature.RodError):
            rod_feature.export_step(rod, os.path.join(self.tmpdir, "none.step"))

    def test_kappa_zero_is_an_error_then_recovers(self):
        src, rod = self.rod_on("Line", Part.LineSegment(V(0, 0, 0), V(100, 50, 20)).toShape())
        self.assertTrue(_is_error(rod))
        self.assertEqual(rod.Status, "error")
        self.assertIn("curvature vanishes at arc length s =", rod.Reason)
        src.Shape = _helix().toShape()
        self.doc.recompute()
        self.assert_feasible_rod(rod)

    def test_invalid_input_names_the_field(self):
        _, rod = self.rod_on("Helix", _helix().toShape(), recompute=False, Material="Custom", PoissonRatio=0.7)
        self.doc.recompute()
        self.assertTrue(_is_error(rod))
        self.assertIn("material.nu", rod.Reason)
        rod.PoissonRatio = 0.3
        rod.YoungsModulus = "5 MPa"
        self.doc.recompute()
        self.assert_feasible_rod(rod)
        spec = rod_feature.build_spec(rod, rod.Edge[0].Shape.Edges[0])
        self.assertEqual(spec["material"], {"E": 5e6, "nu": 0.3, "density": 1250.0})

    def test_step_export_and_twist_plot(self):
        _, rod = self.rod_on("Segment", _sculpture_segment(0).toShape())
        self.assert_feasible_rod(rod)
        step = rod_feature.export_step(rod, os.path.join(self.tmpdir, "rods.step"))
        back = Part.read(step)
        self.assertEqual(len(back.Solids), 2)
        for a, b in zip(sorted(s.Volume for s in back.Solids), sorted(s.Volume for s in rod.Shape.Solids)):
            self.assertAlmostEqual(a, b, delta=1e-3 * b)
        png = rod_feature.write_twist_plot(rod, os.path.join(self.tmpdir, "twist.png"))
        with open(png, "rb") as f:
            self.assertEqual(f.read(8), b"\x89PNG\r\n\x1a\n")
        # PlotFile: the plot is rewritten on every recompute.
        rod.PlotFile = os.path.join(self.tmpdir, "auto.png")
        self.doc.recompute()
        self.assertGreater(os.path.getsize(rod.PlotFile), 1000)

    def test_make_rod_rejects_non_edge(self):
        src = self.doc.addObject("Part::Feature", "Box")
        src.Shape = Part.makeBox(1, 2, 3)
        with self.assertRaises(ValueError):
            rod_feature.make_rod(src, "Face1")


if __name__ == "__main__":
    unittest.main()
