"""Headless FreeCAD tests of the ParaFab ``Analysis`` feature (XFEM on a solid).

Run with ``tests/freecad/run_tests.sh``; needs the real solver (PARAFAB_MODULE_DIR).
"""

import os
import sys
import tempfile
import unittest

_HERE = os.path.dirname(os.path.abspath(__file__))
_REPO = os.path.normpath(os.path.join(_HERE, os.pardir, os.pardir))
for _p in (os.environ.get("PARAFAB_MODULE_DIR") or os.path.join(_REPO, "build", "workbench", "entry"),
           os.environ.get("PARAFAB_WB_DIR") or os.path.join(_REPO, "workbench", "freecad", "ParaFab")):
    if _p not in sys.path:
        sys.path.insert(0, _p)

import FreeCAD  # noqa: E402
import Part  # noqa: E402
import parafab  # noqa: E402
from parafab_wb import analysis_feature  # noqa: E402


def _face_at(shape, axis, value):
    for i, f in enumerate(shape.Faces):
        c = f.CenterOfMass
        if abs([c.x, c.y, c.z][axis] - value) < 1e-6 and abs(abs(f.normalAt(0, 0)[axis]) - 1) < 1e-9:
            return "Face%d" % (i + 1)
    raise AssertionError("no face at axis %d = %g" % (axis, value))


class AnalysisFeatureTest(unittest.TestCase):
    def setUp(self):
        self.doc = FreeCAD.newDocument("ParaFabAnalysisTest")
        self.tmp = tempfile.mkdtemp()
        self.beam = self.doc.addObject("Part::Feature", "Beam")
        self.beam.Shape = Part.makeBox(200, 20, 20)

    def tearDown(self):
        FreeCAD.closeDocument(self.doc.Name)

    def make(self, **kw):
        fixed = kw.pop("fixed", [_face_at(self.beam.Shape, 0, 0)])
        a = analysis_feature.make_analysis(self.beam, fixed, [_face_at(self.beam.Shape, 0, 200)], (0, 0, -100))
        a.OutputDir = self.tmp
        a.Cells = 20
        for k, v in kw.items():
            setattr(a, k, v)
        self.doc.recompute()
        return a

    def test_cantilever_matches_the_module_and_beam_theory(self):
        a = self.make()
        self.assertNotIn("Invalid", a.State, a.Status)
        self.assertTrue(os.path.isfile(os.path.join(self.tmp, "result.vtu")))
        # The same job through the module directly (FreeCAD FaceN = ParaFab face N − 1).
        brep = os.path.join(self.tmp, "beam.brep")
        self.beam.Shape.exportBrep(brep)
        direct = parafab.simulate(brep, analysis_feature.build_job(a))
        self.assertAlmostEqual(a.MaxDisplacement.Value, direct["max_displacement"], delta=1e-9)
        # Euler–Bernoulli tip deflection P L³ / 3EI = 100·200³/(3·210000·20⁴/12) = 0.0952 mm.
        self.assertGreater(a.MaxDisplacement.Value, 0.85 * 0.0952)
        self.assertLess(a.MaxDisplacement.Value, 1.10 * 0.0952)
        self.assertGreater(a.Dofs, 100)

    def test_errors_leave_the_document_valid(self):
        a = self.make(fixed=[])
        self.assertIn("Invalid", a.State)
        self.assertIn("float freely", a.Status)
        b = self.make(fixed=["Face99"])
        self.assertIn("Invalid", b.State)
        self.assertIn("Face99", b.Status)
        self.assertTrue(self.beam.Shape.isValid())
        b.FixedFaces = [_face_at(self.beam.Shape, 0, 0)]
        self.doc.recompute()
        self.assertNotIn("Invalid", b.State, b.Status)

    def test_save_and_reopen(self):
        a = self.make()
        path = os.path.join(self.tmp, "analysis.FCStd")
        self.doc.saveAs(path)
        FreeCAD.closeDocument(self.doc.Name)
        self.doc = FreeCAD.openDocument(path)
        a = self.doc.getObject("Analysis")
        self.assertEqual(a.Proxy.Type, analysis_feature.TYPE)
        a.touch()
        self.doc.recompute()
        self.assertNotIn("Invalid", a.State, a.Status)


if __name__ == "__main__":
    unittest.main()
