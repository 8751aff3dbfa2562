"""The grid chosen from an accuracy target (job "grid": {"target": e}): grids refined by 1.5
until the Richardson estimate of the probes' relative error is below e. Checked against an
independent conforming reference (Gmsh + CalculiX tet10, h = 3 mm, itself within 1.3 % of
h = 1.5 mm) on the L-bracket job: the true error must not exceed the estimate, for the default
element (hex27, whose grids start at 4 cells) and for hex8 (from 8 cells)."""
import json
import os
import subprocess
import sys
import unittest

sys.path.insert(0, os.environ.get("PARAFAB_MODULE_DIR", "build/workbench/entry"))
import parafab  # noqa: E402

REPO = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
PART = os.path.join(REPO, "samples", "parts", "l_bracket.step")
JOB = os.path.join(REPO, "samples", "simulations", "l_bracket.json")
REF = os.path.join(REPO, "tests", "reference", "calculix_reference.py")
# CalculiX tet10 h = 1.5 mm on the same job (tests/python/test_simulate.py, CCX_TIP; 5 min to run),
# 1.3 % from the h = 3 mm run this test makes itself.
CCX_TIP_1_5 = -0.11056


def job(grid):
    with open(JOB) as f:
        j = json.load(f)
    j["grid"] = grid
    return j


class AccuracyTarget(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        out = subprocess.run(["/usr/bin/python3", REF, JOB, "--parafab", PART, "--size", "3", "--quiet"],
                             capture_output=True, text=True, check=True).stdout
        cls.u_ref = json.loads(out)["displacement_at"][0]["u"][2]

    def run_target(self, element, first_levels):
        j = job({"target": 0.15, "max_cells": 40})
        if element:
            j["element"] = element
        r = parafab.simulate(PART, j)
        a = r["accuracy"]
        cells = [lv["cells"] for lv in a["levels"]]
        tip = r["probes"][0]["displacement"][2]
        true_error = max(abs(tip - u) / abs(u) for u in (self.u_ref, CCX_TIP_1_5))
        print("%s: levels %s, estimated error %.3f, true error against CalculiX tet10 h = 3 / 1.5 mm %.4f / %.4f"
              % (r["element"], cells, a["estimated_error"], abs(tip - self.u_ref) / abs(self.u_ref),
                 abs(tip - CCX_TIP_1_5) / abs(CCX_TIP_1_5)))
        self.assertTrue(a["met"], a["stopped"])
        self.assertLessEqual(a["estimated_error"], 0.15)
        self.assertEqual(cells[:3], first_levels)  # refined by 1.5 from half the default grid
        self.assertEqual(r["grid"]["cells"][0], cells[-1])  # the result is the finest grid's
        self.assertLessEqual(true_error, a["estimated_error"])
        # One symbolic analysis per level (each grid has its own pattern), none repeated.
        self.assertEqual(r["solver"]["analyses"], len(cells))
        self.assertTrue(all(lv["analyze_seconds"] > 0 for lv in a["levels"]))
        return r, true_error, abs(tip - CCX_TIP_1_5) / abs(CCX_TIP_1_5)

    def test_target_picks_the_grid_and_bounds_the_true_error(self):
        # The default element, hex27 (with its default local clamp penalty), from 4 cells:
        # measured levels 4, 6, 9, 14, estimate 8.3 %, true error 1.09 % / 0.22 % against
        # CalculiX h = 3 / 1.5 mm (the h = 3 mm reference is itself 0.9 % from the finer one;
        # with the fixed penalty, the default until 2026-11-28: 0.66 % / 0.65 %). hex8 (fixed
        # penalty) from 8 cells: 8, 12, 18, 27, estimate 10.5 %, true error 5.2 % / 6.4 %. The
        # estimate bounds the larger of the two; the finer reference's error is asserted.
        r27, e27, fine27 = self.run_target(None, [4, 6, 9])
        self.assertEqual(r27["element"], "hex27")
        self.assertEqual(r27["nitsche_penalty"], "local")
        r8, e8, fine8 = self.run_target("hex8", [8, 12, 18])
        self.assertEqual(r8["nitsche_penalty"], "fixed")
        self.assertLess(fine27, 0.003)
        self.assertLess(e27, 0.012)
        self.assertGreater(e8, 0.05)

    def test_unreachable_target_is_reported_not_met(self):
        r = parafab.simulate(PART, job({"target": 1e-4, "max_cells": 7}))
        a = r["accuracy"]
        self.assertFalse(a["met"])
        self.assertIn("max_cells", a["stopped"])
        self.assertEqual([lv["cells"] for lv in a["levels"]], [4, 6])
        self.assertIsNone(a["estimated_error"])  # two grids give a change, not an estimate

    def test_bad_targets_name_the_field(self):
        for grid, text in [({"target": 2}, "grid.target"), ({"target": 0.1, "cell_size": 2}, "grid.cell_size")]:
            with self.assertRaises(parafab.Error) as cm:
                parafab.simulate(PART, job(grid))
            self.assertIn(text, str(cm.exception))


if __name__ == "__main__":
    unittest.main()
