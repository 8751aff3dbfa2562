"""Headless FreeCAD tests of "Improve fabricability" (``parafab_wb.strip_improve``).

Run with ``tests/freecad/run_tests.sh [BUILD_DIR]``. Headless documents have UndoMode 0, so
the single undo transaction cannot be undone here: the tests check the recoverable original
(hidden copy / untouched owner, ``restore_original``) instead, and the transaction itself
through ``Document.UndoNames`` where undo is available.
"""

import math
import os
import tempfile
import unittest

import test_strip_feature as base  # noqa: E402  (sets up sys.path)

import FreeCAD  # noqa: E402
import Part  # noqa: E402

import parafab  # noqa: E402
from parafab_wb import strip_feature  # noqa: E402
from parafab_wb import strip_improve  # noqa: E402

V = FreeCAD.Vector


def _arch_mm():
    """A quartic arch y = 200 exp(-x²/0.01) (x, y in mm after scaling): flat flanks far from
    the stiffness line give R ≈ 20."""
    pts = [V(x, 200.0 * math.exp(-(x * 1e-3) ** 2 / 0.01), 0)
           for x in [-100.0 + 200.0 * i / 80 for i in range(81)]]
    bs = Part.BSplineCurve()
    bs.approximate(Points=pts, DegMin=4, DegMax=4, Tolerance=0.05)
    return bs


class ImproveTest(base.StripTestCase):

    def independent_R(self, edge):
        return parafab.design_strip(base._spec_xy(edge.Curve))["R"]

    def test_improve_in_place_keeps_the_original(self):
        arch = _arch_mm()
        src, strip = self.strip_on("Arch", arch.toShape())
        self.assert_feasible_strip(strip)
        R0 = strip.R
        self.assertGreater(R0, 8)
        old_poles = [V(p) for p in src.Shape.Edges[0].Curve.getPoles()]
        target = R0 / 3
        result = strip_improve.improve_strip(strip, target)
        self.assertTrue(result["done"], result["status"])
        # The strip is redesigned on the moved poles, R ≤ target (and an independent design
        # of the owner's new edge agrees).
        self.assert_feasible_strip(strip)
        self.assertLessEqual(strip.R, target * (1 + 1e-6))
        self.assertAlmostEqual(self.independent_R(src.Shape.Edges[0]), strip.R, delta=1e-6 * strip.R)
        new_edge = src.Shape.Edges[0]
        new_poles = new_edge.Curve.getPoles()
        self.assertEqual(len(new_poles), len(old_poles))
        self.assertGreater(max((a - b).Length for a, b in zip(new_poles, old_poles)), 0.1)
        # End points kept.
        self.assertLess((new_poles[0] - old_poles[0]).Length, 1e-6)
        self.assertLess((new_poles[-1] - old_poles[-1]).Length, 1e-6)
        # The original is recoverable: a hidden copy with the old poles, linked from the strip.
        orig = strip.OriginalCurve
        self.assertIsNotNone(orig)
        self.assertNotEqual(orig.Name, src.Name)
        for a, b in zip(orig.Shape.Edges[0].Curve.getPoles(), old_poles):
            self.assertLess((a - b).Length, 1e-12)
        self.assertAlmostEqual(strip.RBeforeImprove, R0, delta=1e-6 * R0)
        self.assertGreater(strip.ImproveDeviation, 0.0)
        strip_improve.restore_original(strip)
        self.assertAlmostEqual(strip.R, R0, delta=1e-9 * R0)
        # Plot of the curve before and after.
        tmp = tempfile.mkdtemp()
        png = os.path.join(tmp, "improve.png")
        strip_improve.plot_improvement(result, png, show=False, title="Arch")
        self.assertGreater(os.path.getsize(png), 10000)
        os.remove(png)
        os.rmdir(tmp)

    def test_multi_edge_owner_is_relinked_and_kept(self):
        arch = _arch_mm()
        e = arch.toShape()
        tail = Part.LineSegment(e.Vertexes[-1].Point, e.Vertexes[-1].Point + V(0, -50, 0)).toShape()
        src = self.add_shape("Wire", Part.Wire([e, tail]))
        strip = strip_feature.make_strip(src, "Edge1")
        self.doc.recompute()
        R0 = strip.R
        before = [V(p) for p in src.Shape.Edges[0].Curve.getPoles()]
        strip_improve.improve_strip(strip, R0 / 2)
        self.assertLessEqual(strip.R, R0 / 2 * (1 + 1e-6))
        self.assertNotEqual(strip.Edge[0].Name, src.Name)  # relinked to the improved curve
        self.assertIs(strip.OriginalCurve, src)
        for a, b in zip(src.Shape.Edges[0].Curve.getPoles(), before):  # owner untouched
            self.assertEqual((a - b).Length, 0.0)
        strip_improve.restore_original(strip)
        self.assertEqual(strip.Edge[0].Name, src.Name)
        self.assertAlmostEqual(strip.R, R0, delta=1e-9 * R0)

    def test_one_transaction_when_undo_is_on(self):
        self.doc.UndoMode = 1
        src, strip = self.strip_on("Arch", _arch_mm().toShape())
        n = len(self.doc.UndoNames)
        strip_improve.improve_strip(strip, strip.R / 2)
        self.assertEqual(len(self.doc.UndoNames), n + 1)
        self.assertEqual(self.doc.UndoNames[0], strip_improve.TITLE)


if __name__ == "__main__":
    unittest.main()
