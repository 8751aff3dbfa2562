"""Run-level behaviour of `parafab optimize` (issue 12) on the L-bracket (base 60 x 40 x 8 mm,
two through bolt holes r = 4 at (40, 12) and (40, 28), inner fillet r = 5), checked against
closed forms and OCCT's mass properties of the written STEP:
- contradictory user constraints: no parameters satisfy them all, so the nearest valid model
  (tangencies kept, the user constraints in least squares) is written as nearest_valid.step,
  never as optimized.step, and the run is an input error naming what stays violated;
- an iterate whose B-rep fails OCCT's checker (a hole grown through the plate's side and into
  its neighbour) is rejected, the run says so and ends on the last valid model; so is one that
  intersects itself where that checker sees nothing (a blind hole deepened through the far wall);
- "parameters": "auto" end to end: every parameter of every face that is neither supported nor
  loaded, tied by the tangencies, under a volume bound; the written part is stiffer by a fresh
  hex27 simulation on its own grid and by Gmsh + CalculiX, and within the bound by OCCT's volume."""
import hashlib
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

sys.path.insert(0, os.environ.get("PARAFAB_MODULE_DIR", "build/workbench/entry"))
import parafab  # noqa: E402
from optimize_cli import cli  # noqa: E402

SAMPLES = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "samples")
BRACKET = os.path.join(SAMPLES, "parts", "l_bracket.step")
CALCULIX = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "reference", "calculix_reference.py")
THICKNESS = 8.0  # the base plate the bolt holes go through (mm)
HOLE_1 = {"point": [44, 12, 4], "parameter": "radius"}  # on the hole at (40, 12), r = 4
HOLE_2 = {"point": [44, 28, 4], "parameter": "radius"}
ELASTIC = {"material": {"E": 210000, "nu": 0.3}, "element": "hex8",
           "supports": [{"point": [0, 20, 30]}],             # the upright's outer face x = 0
           "loads": [{"point": [60, 20, 4], "force": [0, 0, -500]}]}  # the base's end face x = 60
FILLET = {"point": [13 - 5 / math.sqrt(2), 20, 13 - 5 / math.sqrt(2)], "parameter": "radius"}  # axis (13, y, 13), r = 5


def sha(path):
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def face_index(path, center, radius):
    """Index of the cylinder with axis through `center` (x, y) and `radius`."""
    for f in parafab.inspect_part(path)["faces"]:
        p = f["parameters"]
        if f["type"] == "cylinder" and abs(p["r"] - radius) < 1e-6 and \
                math.hypot(p["c"][0] - center[0], p["c"][1] - center[1]) < 1e-6:
            return f["index"]
    raise AssertionError("no cylinder r = %g at %s" % (radius, center))


def face_index_plane(faces, normal, offset):
    """Index of the plane n·X = offset with unit normal ±`normal` among inspect_part's faces."""
    for f in faces:
        if f["type"] == "plane":
            n, p = f["parameters"]["n"], f["parameters"]["p"]
            if abs(abs(sum(a * b for a, b in zip(n, normal))) - 1) < 1e-9 and \
                    abs(sum(a * b for a, b in zip(normal, p)) - offset) < 1e-6:
                return f["index"]
    raise AssertionError("no plane %s . X = %g" % (normal, offset))


class OptimizeRun(unittest.TestCase):
    def setUp(self):
        self.dir = tempfile.mkdtemp()
        self.part = os.path.join(self.dir, "l_bracket.step")
        shutil.copy(BRACKET, self.part)
        self.v0 = parafab.integrate_part(self.part, cells=4)["occt"]["volume"]

    def tearDown(self):
        shutil.rmtree(self.dir)

    def test_contradictory_ties_write_the_nearest_valid_model_and_name_the_violations(self):
        # Hole 2 (r = 4) and the inner fillet (r = 5) are fixed; hole 1's radius is tied to both.
        # No model has 4 = r1 = 5; the least squares of r1 − 4 and r1 − 5 is r1 = 4.5, both ties
        # violated by 0.5, every tangency kept.
        hole2 = face_index(self.part, (40, 28), 4.0)
        fillet = [f["index"] for f in parafab.inspect_part(self.part)["faces"]
                  if f["type"] == "cylinder" and abs(f["parameters"]["r"] - 5) < 1e-6]
        self.assertEqual(len(fillet), 1)
        before = sha(self.part)
        out = os.path.join(self.dir, "out")
        job = {"objective": {"type": "volume"}, "parameters": [HOLE_1], "fixed_faces": [hole2, fillet[0]],
               "ties": [[HOLE_1, HOLE_2, FILLET]], "max_iterations": 5}
        code, err = cli(["optimize", self.part, "-o", out], job)
        self.assertEqual(code, 2, err)
        message = err["error"]["message"]
        self.assertIn("cannot all hold", message)
        self.assertIn("nearest valid model", message)
        self.assertEqual(message.count("'tie "), 2, message)
        self.assertIn("nearest_valid.step", message)
        self.assertEqual(sha(self.part), before)  # the original is never touched
        self.assertFalse(os.path.exists(os.path.join(out, "optimized.step")))
        with open(os.path.join(out, "history.json")) as f:
            h = json.load(f)
        self.assertEqual(h["status"], "infeasible_constraints")
        self.assertEqual(h["iterations"], [])
        values = sorted(v["value"] for v in h["violated_constraints"])
        self.assertEqual(len(values), 2)
        self.assertAlmostEqual(values[0], -0.5, delta=1e-9)
        self.assertAlmostEqual(values[1], 0.5, delta=1e-9)
        self.assertAlmostEqual(h["parameters"][0]["final"], 4.5, delta=1e-9)
        self.assertLess(h["tangency_residual_max"], 1e-12)  # measured 1.1e-14
        # Independent: the written STEP as OCCT reads it. Hole 1 at r = 4.5, the rest as read.
        step = os.path.join(out, "nearest_valid.step")
        self.assertEqual(face_index(step, (40, 12), 4.5), face_index(self.part, (40, 12), 4.0))
        self.assertEqual(face_index(step, (40, 28), 4.0), hole2)
        self.assertEqual(len(parafab.inspect_part(step)["faces"]), len(parafab.inspect_part(self.part)["faces"]))
        v = parafab.integrate_part(step, cells=4)["occt"]["volume"]
        self.assertAlmostEqual(v, self.v0 - math.pi * (4.5 ** 2 - 4.0 ** 2) * THICKNESS, delta=1e-9 * self.v0)
        # The same ties with the fillet free hold (r1 = r2 = rf = 4): an ordinary run, exit 0.
        job_ok = dict(job, fixed_faces=[hole2], max_iterations=0)
        code, h = cli(["optimize", self.part, "-o", os.path.join(self.dir, "ok")], job_ok)
        self.assertEqual(code, 0, h)
        self.assertAlmostEqual(h["parameters"][0]["final"], 4.0, delta=1e-9)

    def test_an_iterate_failing_the_checker_is_rejected_and_the_last_valid_model_kept(self):
        # Minimizing the volume grows hole 1 (bounds up to r = 16). At r = 12 it reaches the
        # plate's side y = 0 and hole 2 (centres 16 apart, 12 + 4): beyond, the top and bottom
        # faces' wires intersect and OCCT's checker refuses the written B-rep
        # (BRepCheck_IntersectingWires). Those steps are rejected, counted and named; the run
        # ends on a valid part just below r = 12 (measured 100 of 111 evaluations rejected,
        # r = 11.999992).
        before = sha(self.part)
        out = os.path.join(self.dir, "grow")
        job = {"objective": {"type": "volume"}, "parameters": [HOLE_1], "bound": 3.0, "first_step": 12.0,
               "max_iterations": 20}
        code, h = cli(["optimize", self.part, "-o", out], job)
        self.assertEqual(code, 0, h)
        self.assertEqual(sha(self.part), before)
        self.assertGreaterEqual(h["invalid_models"], 1, h)
        self.assertTrue(any("invalid B-rep update" in n and "BRepCheck" in n for n in h["notes"]), h["notes"])
        r = h["parameters"][0]["final"]
        self.assertGreater(r, 11.999)
        self.assertLess(r, 12.0)
        # Independent: OCCT's volume of the written STEP against the closed form at that radius,
        # and the hole as OCCT reads it.
        step = os.path.join(out, "optimized.step")
        v = parafab.integrate_part(step, cells=4)["occt"]["volume"]
        self.assertAlmostEqual(v, self.v0 - math.pi * (r ** 2 - 4.0 ** 2) * THICKNESS, delta=1e-9 * self.v0)
        self.assertAlmostEqual(h["final_objective"], v, delta=1e-9 * self.v0)
        face_index(step, (40, 12), r)

    def test_a_self_intersecting_iterate_is_rejected_and_the_last_valid_model_kept(self):
        # Minimizing the volume deepens the blind hole of samples/parts/blind_hole_block.step
        # (r = 5, floor at z = 10 in a 40 x 40 x 20 block). At z = 0 its floor reaches the
        # block's bottom face; beyond, the two cross away from any shared edge, a solid
        # BRepCheck_Analyzer passes (ShapeModify.BlindHoleDeepens...): the write-back's
        # self-interference test refuses those steps and the run ends on the last valid model
        # (measured: 73 of 83 evaluations rejected, floor at z = 6.1e-5).
        part = os.path.join(SAMPLES, "parts", "blind_hole_block.step")
        before = sha(part)
        out = os.path.join(self.dir, "deepen")
        job = {"objective": {"type": "volume"}, "parameters": [{"point": [20, 20, 10], "parameter": "offset"}],
               "bound": 3.0, "first_step": 12.0, "max_iterations": 20}
        code, h = cli(["optimize", part, "-o", out], job)
        self.assertEqual(code, 0, h)
        self.assertEqual(sha(part), before)
        self.assertAlmostEqual(h["invalid_models"], 73, delta=5)  # of 83 evaluations (measured)
        self.assertTrue(any("intersects itself: self-interference between face" in n for n in h["notes"]), h["notes"])
        z = abs(h["parameters"][0]["final"])  # the floor's height (offset = n · X, n = ±z)
        self.assertGreater(z, 0)
        self.assertLess(z, 2e-4)  # measured 6.1e-5
        # Independent: OCCT's volume of the written STEP against the closed form at that depth,
        # with the hole's radius as written (the projection may move it by about 1e-7).
        step = os.path.join(out, "optimized.step")
        r = [f["parameters"]["r"] for f in parafab.inspect_part(step)["faces"] if f["type"] == "cylinder"]
        self.assertEqual(len(r), 1)
        self.assertAlmostEqual(r[0], 5.0, delta=2e-7)
        v = parafab.integrate_part(step, cells=4)["occt"]["volume"]
        self.assertAlmostEqual(v, 40 * 40 * 20 - math.pi * r[0] ** 2 * (20 - z), delta=1e-9 * v)
        self.assertAlmostEqual(h["final_objective"], v, delta=1e-9 * v)

    def test_auto_parameters_end_to_end(self):
        faces = parafab.inspect_part(self.part)["faces"]
        held = {f["index"] for f in faces if f["type"] == "plane" and abs(abs(f["parameters"]["n"][0]) - 1) < 1e-12
                and f["parameters"]["p"][0] in (0.0, 60.0)}  # the support's and the load's faces
        self.assertEqual(len(held), 2)
        free = [f for f in faces if f["index"] not in held]
        self.assertTrue(all(f["type"] in ("plane", "cylinder") for f in free))
        out = os.path.join(self.dir, "auto")
        job = dict(ELASTIC, objective={"type": "compliance"}, grid={"cells": 8}, parameters="auto",
                   constraints=[{"type": "volume", "max_ratio": 1.0}], max_iterations=10)
        # Along the way CHOLMOD warns twice ("matrix not positive definite", handled by the LU
        # fallback); the JSON on stdout must stay clean (those warnings went to stdout before).
        code, h = cli(["optimize", self.part, "-o", out], job)
        self.assertEqual(code, 0, h)
        # Discrete switches frozen during line searches; accepted points whose own switches
        # differ are evaluated again (measured 3 of 10).
        self.assertTrue(h["freeze_switches"])
        self.assertGreaterEqual(h["switch_refreshes"], 1)
        self.assertEqual(h["nitsche_surface_degree"], 8)  # the curved clamps' rules (optimization.md)
        # Every block parameter of every free face (plane: n, d; cylinder: c, a, r), none of the held ones.
        self.assertEqual(len(h["parameters"]), sum(4 if f["type"] == "plane" else 7 for f in free))
        designed = {int(p["name"].split()[1]) for p in h["parameters"]}
        self.assertEqual(designed, {f["index"] for f in free})
        self.assertEqual(h["gradient"], "exact")
        self.assertLess(h["tangency_residual_max"], 1e-12)  # measured 1.8e-15
        # Measured (2026-12-01, the line search's cubic backtracking): 40.729 -> 19.175 (-53 %) on
        # the optimizer's 8-cell grid in 10 iterations and 49 evaluations, V 0.958 V0 (with
        # halving: 20.993, 0.931 V0).
        self.assertLess(h["final_objective"], 0.5 * h["initial_objective"])
        self.assertAlmostEqual(h["final_volume"] / h["initial_volume"], 0.958, delta=0.005)
        # What the design did, read from the written STEP's planes (parafab.inspect_part): the
        # base thickens towards y = 40 (top and bottom tilt across), and the upright's inner face
        # tilts until the upright ends in a knife edge at its top, 0.046 mm wide at y = 20
        # (the clamped back face x = 0 carries it; compliance does not ask for material there):
        # a valid solid (OCCT's checker and the self-interference test pass it; the planes do
        # not cross inside the part), but not one to make. Measured: base 8.37 / 16.35 mm at
        # (30, 0) / (30, 40); the upright's top 0.046 mm wide at y = 20, its face 1.58 mm²
        # (320 mm² before).
        result = parafab.inspect_part(os.path.join(out, "optimized.step"))["faces"]
        planes = {f["index"]: f["parameters"] for f in result if f["type"] == "plane"}

        def coordinate(face, axis, at):  # the plane's coordinate `axis` at the other two given
            n, p = planes[face]["n"], planes[face]["p"]
            return p[axis] - sum(n[k] * (at[k] - p[k]) for k in range(3) if k != axis) / n[axis]
        bottom, top, inner, upright_top = (face_index_plane(faces, n, d)
                                           for n, d in (((0, 0, 1), 0), ((0, 0, 1), 8), ((1, 0, 0), 8), ((0, 0, 1), 50)))
        thickness = [coordinate(top, 2, (30, y, 0)) - coordinate(bottom, 2, (30, y, 0)) for y in (0, 40)]
        self.assertAlmostEqual(thickness[0], 8.37, delta=0.05)
        self.assertAlmostEqual(thickness[1], 16.35, delta=0.05)
        x, z = 8.0, 50.0  # the upright's inner top edge at y = 20: on the inner face and the top
        for _ in range(50):
            z = coordinate(upright_top, 2, (x, 20, 0))
            x = coordinate(inner, 0, (0, 20, z))
        self.assertGreater(x, 0)  # inside: the back face is x = 0
        self.assertAlmostEqual(x, 0.046, delta=0.005)
        self.assertAlmostEqual(result[upright_top]["area"], 1.58, delta=0.15)
        # The same run with each model's own switches: the same iterates (the refreshes only
        # re-decide at accepted points), fewer evaluations.
        code, own = cli(["optimize", self.part, "-o", out + "_own"], dict(job, freeze_switches=False))
        self.assertEqual(code, 0, own)
        self.assertEqual((own["freeze_switches"], own["switch_refreshes"]), (False, 0))
        self.assertEqual(len(own["iterations"]), len(h["iterations"]))
        for a, b in zip(own["iterations"], h["iterations"]):
            self.assertAlmostEqual(a["objective"], b["objective"], delta=1e-9 * h["initial_objective"])
        self.assertEqual(h["evaluations"], own["evaluations"] + h["switch_refreshes"])
        code, err = cli(["optimize", self.part, "-o", out + "_bad"], dict(job, freeze_switches="yes"))
        self.assertEqual(code, 2)
        self.assertIn("freeze_switches must be true or false", err["error"]["message"])
        step = os.path.join(out, "optimized.step")
        v = parafab.integrate_part(step, cells=4)["occt"]["volume"]
        self.assertLessEqual(v, self.v0 * (1 + 1e-6))
        self.assertAlmostEqual(v, h["final_volume"], delta=1e-6 * self.v0)
        # Independent: fresh hex27 simulations of both parts on 16 cells (each on its own grid).
        # Measured 54.669 -> 27.287 (ratio 0.4991; 0.5384 with the halving line search).
        c = []
        for p in (self.part, step):
            code, r = cli(["simulate", p], dict(ELASTIC, element="hex27", grid={"cells": 16, "method": "face"}))
            self.assertEqual(code, 0, r)
            c.append(-2 * r["potential"])
        self.assertLess(c[1], 0.52 * c[0])
        # Independent: Gmsh + CalculiX tet10 (h = 2 mm) of both STEP files. Measured 54.826 ->
        # 27.481 (ratio 0.5012, 0.4 % from the fresh hex27 ratio).
        with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
            json.dump({k: ELASTIC[k] for k in ("material", "supports", "loads")}, f)
        try:
            ccx = []
            for p in (self.part, step):
                run = subprocess.run(["/usr/bin/python3", CALCULIX, f.name, "--parafab", p, "--size", "2", "--quiet"],
                                     capture_output=True, text=True, check=True, timeout=600)
                ccx.append(json.loads(run.stdout)["compliance"])
        finally:
            os.unlink(f.name)
        print("fresh hex27 %.3f -> %.3f (%.4f), CalculiX %.3f -> %.3f (%.4f)" % (c[0], c[1], c[1] / c[0], ccx[0], ccx[1],
                                                                             ccx[1] / ccx[0]))
        self.assertLess(ccx[1], 0.52 * ccx[0])
        self.assertAlmostEqual(ccx[1] / ccx[0], c[1] / c[0], delta=0.01)


if __name__ == "__main__":
    unittest.main()
