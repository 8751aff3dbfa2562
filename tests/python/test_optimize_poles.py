"""`parafab optimize` on the poles of a free-form face (thesis §6.5.1, issue 12): the bump block
(samples/parts/bump_block.step: a 60 x 40 block whose top is a cubic B-spline face with 6 x 5
poles) clamped at x = 0 and pulled down by 500 N at x = 60, its compliance minimized on the z of
six interior poles (the rows i = 2 near the clamp and i = 5 near the load) with the volume bounded
by the original's. Independent checks: the poles of the written STEP read back by OCCT
(`parafab.inspect_part`), OCCT's volume of the written STEP, a fresh `parafab simulate` of both
parts on other grids, the symmetry of the design in y (the part and its load are symmetric), and
the exact gradient of the poles against the semi-analytic one (two perturbed re-cut models)."""
import os
import shutil
import sys
import tempfile
import unittest

sys.path.insert(0, os.environ.get("PARAFAB_MODULE_DIR", "build/workbench/entry"))
import parafab  # noqa: E402
from optimize_cli import cli  # noqa: E402

SAMPLES = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "samples")
BUMP = os.path.join(SAMPLES, "parts", "bump_block.step")

# hex8 throughout: the optimizer's default element, and the fresh simulations that check it use
# the same element on grids of their own.
ELASTIC = {"material": {"E": 210000, "nu": 0.3}, "element": "hex8",
           "supports": [{"point": [0, 20, 5]}],
           "loads": [{"point": [60, 20, 5], "force": [0, 0, -500]}]}
POLES = [(i, j) for i in (2, 5) for j in (2, 3, 4)]


def job(top, **extra):
    j = dict(ELASTIC, objective={"type": "compliance"}, grid={"cells": 8, "method": "face"},
             parameters=[{"face": top, "parameter": "pole %d %d z" % p} for p in POLES],
             constraints=[{"type": "volume", "max_ratio": 1.0}], max_iterations=8, bound=1.0)
    j.update(extra)
    return j


def top_face(path):
    faces = parafab.inspect_part(path)["faces"]
    tops = [f for f in faces if f["type"] == "bspline"]
    assert len(tops) == 1, [f["type"] for f in faces]
    return tops[0]


class OptimizePoles(unittest.TestCase):
    def setUp(self):
        self.dir = tempfile.mkdtemp()
        self.top = top_face(BUMP)["index"]

    def tearDown(self):
        shutil.rmtree(self.dir)

    def fresh_ratios(self, step, elastic):
        """Compliance C = -2 potential of the written STEP over the original's, by fresh
        simulations of both on 10 and 14 cells (grids of their own) with the job `elastic`."""
        ratios = []
        for cells in (10, 14):
            c = []
            for p in (BUMP, step):
                code, r = cli(["simulate", p], dict(elastic, grid={"cells": cells}))
                self.assertEqual(code, 0, r)
                # The face route holds: its rules match OCCT's adaptive volume of a B-spline face
                # (the fixed-rule volume, 1e-5 off, once failed this part's volume check).
                self.assertEqual(r["grid"]["retry_reason"], "", r["grid"])
                self.assertEqual(r["nitsche_penalty"], elastic.get("nitsche_penalty", "fixed"))
                c.append(-2 * r["potential"])
            ratios.append(c[1] / c[0])
        return ratios

    def test_compliance_falls_on_the_poles_and_the_written_step_carries_them(self):
        out = os.path.join(self.dir, "out")
        code, h = cli(["optimize", BUMP, "-o", out], job(self.top))
        self.assertEqual(code, 0, h)
        # Interior poles: their basis functions vanish on the support's and load's edges, so every
        # derivative takes the exact route (V_n = R_ij n_z on the patches).
        self.assertEqual(h["gradient"], "exact")
        self.assertEqual(h["exact_derivatives"], len(POLES) * h["evaluations"])
        self.assertEqual(h["invalid_models"], 0)
        # Measured 9.3564 -> 7.3190 (-21.8 %) in 8 iterations: the clamp-side row rises from 15.1
        # to 25.1-28.0, the load-side row sinks from 18.4 to 3.5-5.9.
        self.assertLess(h["final_objective"], 0.80 * h["initial_objective"])
        final = {p["name"]: p["final"] for p in h["parameters"]}
        name = "face %d bspline pole %%d %%d z" % self.top
        for j in (2, 3, 4):
            self.assertGreater(final[name % (2, j)], 20.0)
            self.assertLess(final[name % (5, j)], 10.0)
        for i in (2, 5):  # symmetric in y: rows j = 2 and j = 4 alike (measured to 1e-10)
            self.assertAlmostEqual(final[name % (i, 2)], final[name % (i, 4)], delta=1e-9)
        # Independent: OCCT reads the written STEP back; its top surface has the final poles.
        step = os.path.join(out, "optimized.step")
        face = top_face(step)
        self.assertEqual(face["pole_count"], [6, 5])
        poles = face["nurbs"]["poles"]  # the face spans its whole surface: the same poles
        for (i, j) in POLES:
            q = poles[(i - 1) * 5 + (j - 1)]
            self.assertAlmostEqual(q[2] / q[3], final[name % (i, j)], delta=1e-9)
        # Independent: OCCT's volume of the written STEP within the bound (measured 0.983 V0).
        v0 = parafab.integrate_part(BUMP, cells=4)["occt"]["volume"]
        v = parafab.integrate_part(step, cells=4)["occt"]["volume"]
        self.assertLessEqual(v, v0 * (1 + 1e-6))
        self.assertAlmostEqual(v, h["final_volume"], delta=1e-6 * v0)
        # Independent: fresh simulations of both parts on their own grids.
        ratios = self.fresh_ratios(step, ELASTIC)
        print("\n[optimize poles] %.6g -> %.6g; fresh ratios %s" % (h["initial_objective"], h["final_objective"],
                                                                   ", ".join("%.4f" % x for x in ratios)), file=sys.stderr)
        for x in ratios:
            self.assertLess(x, 0.78)  # measured 0.7521, 0.7604

    def test_with_the_local_penalty_every_pole_is_exact_and_a_fresh_simulation_agrees(self):
        # "nitsche_penalty": "local": the clamped cut cells' penalty changes with the poles whose
        # basis functions reach them (the clamp-side row i = 2); the exact route differentiates it
        # (dΛ of compliance_gradient; until 2026-11-28 those entries took the semi-analytic route).
        # Judged by fresh simulations with the same penalty on other grids. (On 2026-11-27 the
        # fixed-penalty optimizer's design was judged 0.81 of the start by fresh local
        # simulations, 0.75 by fixed ones: the clamp model, not the optimizer, sets how much of
        # the gain a simulation sees.)
        out = os.path.join(self.dir, "local")
        local = dict(ELASTIC, nitsche_penalty="local")
        code, h = cli(["optimize", BUMP, "-o", out], dict(job(self.top), nitsche_penalty="local"))
        self.assertEqual(code, 0, h)
        self.assertEqual(h["gradient"], "exact")
        self.assertEqual(h["exact_derivatives"], 6 * h["evaluations"])
        self.assertEqual(h["semi_analytic_derivatives"], 0)
        self.assertEqual(h["invalid_models"], 0)
        step = os.path.join(out, "optimized.step")
        ratios = self.fresh_ratios(step, local)
        print("\n[optimize poles, local penalty] %.6g -> %.6g (%.4f); fresh ratios %s" % (
            h["initial_objective"], h["final_objective"], h["final_objective"] / h["initial_objective"],
            ", ".join("%.4f" % x for x in ratios)), file=sys.stderr)
        # Measured 9.3734 -> 7.3545 (0.7846) on the optimizer's 8 cells; fresh 0.8111 / 0.8055 on
        # 10 / 14 cells (the fixed penalty's run: 0.782 and 0.752 / 0.760 by fixed-penalty
        # simulations).
        for x in ratios:
            self.assertLess(x, 0.82)
        code, err = cli(["optimize", BUMP, "-o", os.path.join(self.dir, "bad")],
                        dict(job(self.top), nitsche_penalty="local", nitsche_beta=100))
        self.assertEqual(code, 2)
        self.assertIn("nitsche_beta sets the fixed penalty", err["error"]["message"])

    def test_exact_and_semi_analytic_pole_gradients_agree(self):
        # Measured on the start (8 cells): -0.139937971 / -0.139937795 (clamp side) and
        # -0.00904316169 / -0.00904311609 (load side): 1.3e-6 and 5.0e-6 apart (the bump block
        # turned off the grid agrees with the pipeline's differences to 1.4e-8 / 3.7e-8 by the
        # exact route: tests/occ_bridge/bspline_poles_test.cpp).
        grads = {}
        for route in ("exact", "semi-analytic"):
            j = job(self.top, max_iterations=0, objective={"type": "compliance", "gradient": route},
                    parameters=[{"face": self.top, "parameter": "pole 2 3 z"}, {"face": self.top, "parameter": "pole 5 3 z"}])
            code, h = cli(["optimize", BUMP, "-o", os.path.join(self.dir, route)], j)
            self.assertEqual(code, 0, h)
            self.assertEqual(h["gradient"], route)
            grads[route] = [p["gradient_initial"] for p in h["parameters"]]
        for e, s in zip(grads["exact"], grads["semi-analytic"]):
            self.assertLess(abs(e - s), 1e-5 * abs(s))

    def test_a_pole_outside_the_net_is_named(self):
        code, err = cli(["optimize", BUMP, "-o", os.path.join(self.dir, "bad")],
                        job(self.top, parameters=[{"face": self.top, "parameter": "pole 7 1 z"}]))
        self.assertEqual(code, 2)
        self.assertIn("i in 1..6 and j in 1..5", err["error"]["message"])
        code, err = cli(["optimize", BUMP, "-o", os.path.join(self.dir, "bad")],
                        job(self.top, parameters=[{"face": self.top, "parameter": "radius"}]))
        self.assertEqual(code, 2)
        self.assertIn("pole i j x|y|z", err["error"]["message"])

    def test_chart_false_writes_no_chart(self):
        base = {"objective": {"type": "volume"}, "parameters": [{"face": self.top, "parameter": "pole 3 2 z"}],
                "start": [16.0], "max_iterations": 0}
        out = os.path.join(self.dir, "nochart")
        code, h = cli(["optimize", BUMP, "-o", out], dict(base, chart=False))
        self.assertEqual(code, 0, h)
        self.assertIsNone(h["chart"])
        self.assertFalse(os.path.exists(os.path.join(out, "history.png")))
        self.assertTrue(os.path.exists(os.path.join(out, "optimized.step")))
        code, err = cli(["optimize", BUMP, "-o", os.path.join(self.dir, "bad")], dict(base, chart="no"))
        self.assertEqual(code, 2)
        self.assertIn("chart must be true or false", err["error"]["message"])

    def test_a_boundary_pole_moved_off_its_side_plane_is_an_invalid_model(self):
        # Where the write-back fails: pole (1, 3) lies in the clamped side x = 0; moved along x
        # the top's boundary leaves that plane between the fixed corners (+x: a gap; -x: the
        # plane meets the surface only along its border, which OCCT's intersector does not
        # return). The model is invalid and says which edge; an optimizer step there is
        # rejected and shortened (`invalid_models`), a given start is an error.
        for x in (-0.5, 0.5):
            code, err = cli(["optimize", BUMP, "-o", os.path.join(self.dir, "off")],
                            {"objective": {"type": "volume"}, "parameters": [{"face": self.top, "parameter": "pole 1 3 x"}],
                             "start": [x], "max_iterations": 0})
            self.assertEqual(code, 2, err)
            self.assertIn("no longer intersect", err["error"]["message"])


if __name__ == "__main__":
    unittest.main()
