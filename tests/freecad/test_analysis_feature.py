"""Headless FreeCAD tests of the ParaFab ``Analysis`` feature (XFEM on a solid).

Run with ``tests/freecad/run_tests.sh``; needs the real solver (PARAFAB_MODULE_DIR) and, for
the task panel's process runner, the ``parafab`` CLI beside it (or ``$PARAFAB_CLI``).
"""

import json
import os
import sys
import tempfile
import unittest
import xml.etree.ElementTree as ET

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
from parafab_wb import cli_runner  # noqa: E402
from PySide import QtCore  # noqa: E402

#: GUI modules loaded by importing the feature and its run object (FreeCAD imports the feature
#: module to restore documents, also headless: none may be needed).
_GUI_MODULES_AT_IMPORT = sorted(m for m in sys.modules if m.split(".")[0] == "FreeCADGui"
                                or m.split(".")[-1] in ("QtGui", "QtWidgets"))

#: Grid of the display/cancel tests: small, so the suite stays fast.
CELLS = 10


def _face_at(shape, axis, value):
    for i, f in enumerate(shape.Faces):
        c = f.CenterOfMass
        if abs([c.x, c.y, c.z][axis] - value) < 1e-6 and abs(abs(f.normalAt(0, 0)[axis]) - 1) < 1e-9:
            return "Face%d" % (i + 1)
    raise AssertionError("no face at axis %d = %g" % (axis, value))


def _read_vtu(path):
    """Independent reader of surface.vtu: {array name: flat list}, plus the point count."""
    piece = ET.parse(path).getroot().find("UnstructuredGrid/Piece")
    arrays = {}
    for array in piece.iter("DataArray"):
        convert = int if array.get("type", "").startswith(("Int", "UInt")) else float
        arrays[array.get("Name") or "Points"] = [convert(v) for v in array.text.split()]
    return int(piece.get("NumberOfPoints")), int(piece.get("NumberOfCells")), arrays


def _norm(x, y, z):
    return (x * x + y * y + z * z) ** 0.5


def _snapshot(doc, out_dir):
    """What a cancelled or failed run must not change: objects, inputs, results, mesh, files."""
    snap = {"objects": sorted((o.Name, o.TypeId) for o in doc.Objects)}
    for o in doc.Objects:
        if o.TypeId == "Part::FeaturePython":
            snap[o.Name] = (analysis_feature.inputs_of(o), o.Dofs, o.MaxDisplacement.Value,
                            o.MaxVonMises.Value, o.DeformationScale, o.AutoScale, o.Estimate,
                            round(o.Shape.Volume, 6) if not o.Shape.isNull() else None)
        elif o.TypeId == "Mesh::Feature":
            points, facets = o.Mesh.Topology
            snap[o.Name] = (len(points), len(facets), sum(p.x + 2 * p.y + 3 * p.z for p in points),
                            o.VertexColors[:5] if "VertexColors" in o.PropertiesList else None)
        elif hasattr(o, "Shape"):
            snap[o.Name] = (o.Shape.isValid(), round(o.Shape.Volume, 6))
    result = os.path.join(out_dir, "result.json")
    snap["result.json"] = open(result).read() if os.path.isfile(result) else None
    return snap


def _app():
    return QtCore.QCoreApplication.instance() or QtCore.QCoreApplication([])


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

    def assertMeshShows(self, a, scale):
        """Every mesh vertex is the surface.vtu point moved by ``scale`` times its displacement."""
        n, cells, vtu = _read_vtu(os.path.join(self.tmp, "surface.vtu"))
        mesh = a.ResultMesh.Mesh
        self.assertEqual(mesh.CountPoints, n)
        self.assertEqual(mesh.CountFacets, cells)
        self.assertEqual(len(a.ResultMesh.Displacement), n)
        umax = max(_norm(*vtu["displacement"][3 * i:3 * i + 3]) for i in range(n))
        points = mesh.Topology[0]
        worst = 0.0
        for i, q in enumerate(points):
            x, y, z = vtu["Points"][3 * i:3 * i + 3]
            ux, uy, uz = vtu["displacement"][3 * i:3 * i + 3]
            # The mesh stores single precision: compare the displacement it shows, relative to umax.
            worst = max(worst, _norm((q.x - x) / scale - ux, (q.y - y) / scale - uy, (q.z - z) / scale - uz))
        self.assertLess(worst, 1e-3 * umax + 1e-5 * a.Part.Shape.BoundBox.DiagonalLength / scale)
        # Facets are the VTU triangles, in order.
        conn = vtu["connectivity"]
        for k in (0, cells // 2, cells - 1):
            self.assertEqual(tuple(mesh.Topology[1][k]), tuple(conn[3 * k:3 * k + 3]))
        return n, vtu, umax

    def test_deformed_mesh_shows_surface_vtu_scaled_and_coloured(self):
        a = self.make(Cells=CELLS)
        self.assertNotIn("Invalid", a.State, a.Status)
        self.assertIsNotNone(a.ResultMesh)
        self.assertEqual(a.ResultMesh.TypeId, "Mesh::Feature")
        self.assertTrue(a.AutoScale)
        n, vtu, umax = self.assertMeshShows(a, a.DeformationScale)
        # Automatic scale: the largest surface displacement shows as 5 % of the diagonal.
        diag = self.beam.Shape.BoundBox.DiagonalLength
        self.assertAlmostEqual(a.DeformationScale * umax, 0.05 * diag, delta=1e-9 * diag)
        # The largest displacement shown is result.json's (the surface agrees within a few %).
        with open(os.path.join(self.tmp, "result.json")) as f:
            result = json.load(f)
        self.assertAlmostEqual(a.MaxDisplacement.Value, result["max_displacement"], delta=1e-9)
        self.assertAlmostEqual(a.MaxVonMises.getValueAs("MPa"), result["max_von_mises"], delta=1e-6)
        self.assertAlmostEqual(umax, result["max_displacement"], delta=0.05 * result["max_displacement"])
        self.assertIn("%d unknowns" % result["estimate"]["unknowns"], a.Estimate)
        # Colours: blue at the smallest von Mises on the surface, red at the largest.
        vm = vtu["von_mises"]
        self.assertEqual(len(a.ResultMesh.VertexColors), n)
        self.assertAlmostEqual(a.ColorScaleMin.getValueAs("MPa"), min(vm), delta=1e-9)
        self.assertAlmostEqual(a.ColorScaleMax.getValueAs("MPa"), max(vm), delta=1e-9)
        lo, hi = vm.index(min(vm)), vm.index(max(vm))
        self.assertEqual(a.ResultMesh.VertexColors[hi][:3], (1.0, 0.0, 0.0))
        self.assertEqual(a.ResultMesh.VertexColors[lo][:3], (0.0, 0.0, 1.0))
        self.assertIn("(blue)", a.Status)
        self.assertIn("(red)", a.Status)
        # A new scale moves the vertices only: no re-solve, AutoScale off; AutoScale restores it.
        auto = a.DeformationScale
        a.DeformationScale = 10.0
        self.assertFalse(a.AutoScale)
        self.assertNotIn("Touched", a.State)
        self.assertMeshShows(a, 10.0)
        a.AutoScale = True
        self.assertAlmostEqual(a.DeformationScale, auto, delta=1e-9 * auto)
        self.assertMeshShows(a, auto)
        self.assertEqual(self.doc.recompute(), 0)  # nothing left to recompute

    def test_fem_result_viewer_reads_the_vtu_files(self):
        """FreeCAD's FEM post-processing pipeline (VTK) reads result.vtu and surface.vtu."""
        self.make()
        try:
            import Fem  # noqa: F401
        except ImportError:
            self.skipTest("FreeCAD's Fem module is not available")
        for name in ("result.vtu", "surface.vtu"):
            pipeline = self.doc.addObject("Fem::FemPostPipeline", "Pipeline")
            pipeline.read(os.path.join(self.tmp, name))
            self.doc.recompute()
            self.assertEqual(pipeline.State, ["Up-to-date"], name)
            self.assertTrue(all(o.isValid() for o in self.doc.Objects), name)

    def test_fem_result_object_reads_surface_vtu(self):
        """FreeCAD FEM's result object (Fem.readResult, what its result viewer shows: colour by von
        Mises, animate by displacement) takes surface.vtu's fields at every vertex."""
        self.make()
        try:
            import Fem
            import ObjectsFem
        except ImportError:
            self.skipTest("FreeCAD's Fem module is not available")
        path = os.path.join(self.tmp, "surface.vtu")
        result = ObjectsFem.makeResultMechanical(self.doc, "FemResult")
        Fem.readResult(path, result.Name)
        self.doc.recompute()
        points, _, arrays = _read_vtu(path)
        vm, d = arrays["von_mises"], arrays["displacement"]
        self.assertEqual(len(result.vonMises), points)
        self.assertEqual(len(result.DisplacementVectors), points)
        self.assertAlmostEqual(max(result.vonMises), max(vm), delta=1e-6 * max(vm))
        largest = max(_norm(*d[3 * i:3 * i + 3]) for i in range(points))
        self.assertAlmostEqual(max(v.Length for v in result.DisplacementVectors), largest, delta=1e-6 * largest)

    def test_estimate_matches_the_solver(self):
        a = self.make(Cells=CELLS)
        with open(os.path.join(self.tmp, "result.json")) as f:
            est = json.load(f)["estimate"]
        unknowns, mb = analysis_feature.estimate(self.beam, CELLS)
        self.assertAlmostEqual(unknowns, est["unknowns"], delta=1e-6 * est["unknowns"])
        self.assertAlmostEqual(mb, est["factor_mb"], delta=1e-6 * est["factor_mb"])
        self.assertTrue(a.Estimate)

    def test_cancel_in_process_keeps_the_previous_results(self):
        a = self.make(Cells=CELLS)
        self.assertNotIn("Invalid", a.State, a.Status)
        before = _snapshot(self.doc, self.tmp)
        phases = []

        def cancel_at_cut(phase, fraction):
            phases.append((phase, fraction))
            return phase != "cut"  # False: parafab.simulate raises "simulation cancelled by the user"
        a.Proxy.progress = cancel_at_cut
        a.Gravity = True
        self.doc.recompute()
        self.assertEqual([p for p, _ in phases], ["read", "cut"])
        self.assertIn("Invalid", a.State)  # needs a new run: the next recompute solves again
        self.assertTrue(a.Status.startswith("cancelled"), a.Status)
        self.assertIn("previous results kept", a.Status)
        after = _snapshot(self.doc, self.tmp)
        after[a.Name][0]["gravity"] = False  # the one input changed on purpose
        self.assertEqual(after, before)
        a.Proxy.progress = None
        self.doc.recompute()
        self.assertNotIn("Invalid", a.State, a.Status)
        self.assertTrue(a.Status.startswith("solved"), a.Status)

    def test_panel_process_runs_the_cli_and_cancels_cleanly(self):
        _app()
        cli = cli_runner.find_cli()
        self.assertTrue(cli and os.access(cli, os.X_OK), "parafab CLI not found (PARAFAB_CLI)")
        a = analysis_feature.make_analysis(self.beam, [_face_at(self.beam.Shape, 0, 0)])
        a.OutputDir = self.tmp
        self.doc.recompute()  # no load: solves to zero displacement
        inputs = analysis_feature.inputs_of(a)
        inputs.update(loaded=[_face_at(self.beam.Shape, 0, 200)], force=(0, 0, -100), cells=CELLS)

        # Solved through the CLI: inputs and results land in the feature, nothing left to recompute.
        progress = []
        outcome = cli_runner.run_blocking(cli_runner.AnalysisRun(a, inputs), 120000,
                                          lambda p, f: progress.append((p, f)))
        self.assertEqual(outcome.state, cli_runner.SOLVED, outcome.message)
        self.assertEqual([p for p, _ in progress][:2], ["read", "cut"])
        self.assertEqual(sorted(f for _, f in progress), [f for _, f in progress])
        self.assertEqual(a.Cells, CELLS)
        self.assertEqual(list(a.LoadedFaces), inputs["loaded"])
        self.assertNotIn("Touched", a.State)
        self.assertEqual(a.MaxDisplacement.Value, outcome.result["max_displacement"])
        self.assertAlmostEqual(a.MaxDisplacement.Value, 0.0952, delta=0.15 * 0.0952)
        self.assertMeshShows(a, a.DeformationScale)
        self.assertEqual(self.doc.recompute(), 0)

        # Cancelled (the process is killed at its first progress line): only Status changes.
        before = _snapshot(self.doc, self.tmp)
        run = cli_runner.AnalysisRun(a, dict(inputs, cells=CELLS + 2, gravity=True))
        run.progress.connect(lambda phase, fraction: run.cancel())
        outcome = cli_runner.run_blocking(run, 120000)
        self.assertEqual(outcome.state, cli_runner.CANCELLED)
        self.assertEqual(_snapshot(self.doc, self.tmp), before)
        self.assertTrue(a.Status.startswith("cancelled by the user"), a.Status)
        self.assertNotIn("Invalid", a.State)
        self.assertNotIn("Touched", a.State)

        # Refused by the CLI (JSON error on stdout, exit status 2): the message, nothing else.
        outcome = cli_runner.run_blocking(cli_runner.AnalysisRun(a, dict(inputs, nu=0.6)), 120000)
        self.assertEqual(outcome.state, cli_runner.ERROR)
        self.assertIn("material.nu", outcome.message)
        self.assertIn("material.nu", a.Status)
        self.assertEqual(_snapshot(self.doc, self.tmp), before)
        # Rejected before starting (no such face).
        outcome = cli_runner.run_blocking(cli_runner.AnalysisRun(a, dict(inputs, fixed=["Face99"])), 120000)
        self.assertEqual(outcome.state, cli_runner.ERROR)
        self.assertIn("Face99", outcome.message)
        self.assertEqual(_snapshot(self.doc, self.tmp), before)

    def test_feature_and_run_object_load_without_gui(self):
        self.assertFalse(FreeCAD.GuiUp)
        self.assertEqual(_GUI_MODULES_AT_IMPORT, [])
        # Documents saved before the view provider moved to analysis_view name it by its old path.
        from parafab_wb import analysis_view
        self.assertIs(analysis_feature.ViewProviderAnalysis, analysis_view.ViewProviderAnalysis)
        with self.assertRaises(AttributeError):
            analysis_feature.NoSuchName

    def test_find_cli(self):
        old = os.environ.get("PARAFAB_CLI")
        try:
            os.environ.pop("PARAFAB_CLI", None)
            found = cli_runner.find_cli()
            self.assertTrue(found and os.path.basename(found) == "parafab", found)
            os.environ["PARAFAB_CLI"] = found
            self.assertEqual(cli_runner.find_cli(), os.path.abspath(found))
            os.environ["PARAFAB_CLI"] = os.path.join(self.tmp, "missing")
            self.assertIsNone(cli_runner.find_cli())
        finally:
            if old is None:
                os.environ.pop("PARAFAB_CLI", None)
            else:
                os.environ["PARAFAB_CLI"] = old

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

    def test_version_1_document_gets_a_result_mesh(self):
        a = self.make(Cells=CELLS)
        # What a document saved before the result display looks like.
        mesh = a.ResultMesh
        a.ResultMesh = None
        self.doc.removeObject(mesh.Name)
        for name in ("Estimate", "ResultMesh", "AutoScale", "DeformationScale", "ColorScaleMin", "ColorScaleMax"):
            a.removeProperty(name)
        a.Proxy.Version = 1
        a.Proxy.onDocumentRestored(a)
        self.assertEqual(a.Proxy.Version, analysis_feature.VERSION)
        self.assertTrue(a.AutoScale)
        a.touch()
        self.doc.recompute()
        self.assertNotIn("Invalid", a.State, a.Status)
        self.assertIsNotNone(a.ResultMesh)
        self.assertMeshShows(a, a.DeformationScale)
        self.assertEqual(self.doc.recompute(), 0)

    def test_document_from_before_the_element_choice_keeps_hex8(self):
        fresh = analysis_feature.make_analysis(self.beam, [_face_at(self.beam.Shape, 0, 0)])
        self.assertEqual((fresh.Element, fresh.Cells), ("hex27", 8))  # the defaults of a new analysis
        self.doc.removeObject(fresh.ResultMesh.Name)
        self.doc.removeObject(fresh.Name)
        a = self.make(Cells=CELLS)
        hex27 = a.MaxDisplacement.Value
        # What a document saved by version 2 looks like: no Element; its runs were hex8.
        a.removeProperty("Element")
        a.Proxy.Version = 2
        a.Proxy.onDocumentRestored(a)
        self.assertEqual(a.Element, "hex8")
        a.touch()
        self.doc.recompute()
        self.assertNotIn("Invalid", a.State, a.Status)
        brep = os.path.join(self.tmp, "beam.brep")
        self.beam.Shape.exportBrep(brep)
        job = analysis_feature.build_job(a)
        self.assertEqual(job["element"], "hex8")
        self.assertAlmostEqual(a.MaxDisplacement.Value, parafab.simulate(brep, job)["max_displacement"], delta=1e-9)
        self.assertNotAlmostEqual(a.MaxDisplacement.Value, hex27, delta=1e-6)

    def test_local_clamp_penalty_reaches_the_solver(self):
        # NitschePenalty (version 4): "auto" for a new analysis (the solver's default: local for
        # this linear model; no key in the job), "fixed" for documents of version 3 (what they
        # ran); "fixed" goes into the job and changes the answer (another penalty on the
        # clamped end).
        a = self.make(Cells=CELLS)
        self.assertEqual(a.NitschePenalty, "auto")
        self.assertNotIn("nitsche_penalty", analysis_feature.build_job(a))
        auto = a.MaxDisplacement.Value
        brep = os.path.join(self.tmp, "beam.brep")
        self.beam.Shape.exportBrep(brep)
        r = parafab.simulate(brep, dict(analysis_feature.build_job(a), nitsche_penalty="local"))
        self.assertAlmostEqual(auto, r["max_displacement"], delta=1e-9)  # auto is local here
        a.NitschePenalty = "fixed"
        self.doc.recompute()
        self.assertNotIn("Invalid", a.State, a.Status)
        job = analysis_feature.build_job(a)
        self.assertEqual(job["nitsche_penalty"], "fixed")
        r = parafab.simulate(brep, job)
        self.assertEqual(r["nitsche_penalty"], "fixed")
        self.assertAlmostEqual(a.MaxDisplacement.Value, r["max_displacement"], delta=1e-9)
        self.assertGreater(abs(a.MaxDisplacement.Value / auto - 1), 1e-4)
        print("\n[analysis] beam tip, fixed penalty %.6f mm, local %.6f mm" % (a.MaxDisplacement.Value, auto))
        # A document saved by version 3 (no NitschePenalty) gets "fixed", what it ran.
        a.removeProperty("NitschePenalty")
        a.Proxy.Version = 3
        a.Proxy.onDocumentRestored(a)
        self.assertEqual(a.NitschePenalty, "fixed")

    def test_reopened_document_from_before_the_element_choice_is_not_touched(self):
        a = self.make(Cells=CELLS)
        a.removeProperty("Element")  # as saved by version 2
        path = os.path.join(self.tmp, "version2.FCStd")
        self.doc.saveAs(path)
        FreeCAD.closeDocument(self.doc.Name)
        self.doc = FreeCAD.openDocument(path)
        a = self.doc.getObject("Analysis")
        self.assertEqual(a.Element, "hex8")
        self.assertNotIn("Touched", a.State)  # its results stand until the user recomputes
        self.assertGreater(a.MaxDisplacement.Value, 0)

    def test_save_and_reopen(self):
        a = self.make()
        path = os.path.join(self.tmp, "analysis.FCStd")
        self.doc.saveAs(path)
        FreeCAD.closeDocument(self.doc.Name)
        self.doc = FreeCAD.openDocument(path)
        a = self.doc.getObject("Analysis")
        self.assertEqual(a.Proxy.Type, analysis_feature.TYPE)
        self.assertEqual(a.Proxy.__getstate__(), {"Type": analysis_feature.TYPE,
                                                  "Version": analysis_feature.VERSION})
        # The result mesh, its data and the scale survive the reload; rescaling still works.
        self.assertIsNotNone(a.ResultMesh)
        self.assertGreater(a.ResultMesh.Mesh.CountPoints, 0)
        self.assertEqual(len(a.ResultMesh.VertexColors), a.ResultMesh.Mesh.CountPoints)
        self.assertAlmostEqual(a.ResultMesh.Scale, a.DeformationScale, delta=1e-9 * a.DeformationScale)
        a.DeformationScale = 3.0
        self.assertMeshShows(a, 3.0)
        a.touch()
        self.doc.recompute()
        self.assertNotIn("Invalid", a.State, a.Status)


if __name__ == "__main__":
    unittest.main()
