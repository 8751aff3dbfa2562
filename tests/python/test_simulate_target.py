"""The grid chosen from an accuracy target (job "grid": {"target": e}): grids refined by 1.5
until the Richardson estimate of the probes' relative error is below e. Checked against an
independent conforming reference (Gmsh + CalculiX tet10, h = 3 mm, itself within 1.3 % of
h = 1.5 mm) on the L-bracket job: the true error must not exceed the estimate."""
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


def job(grid):
    with open(JOB) as f:
        j = json.load(f)
    j["grid"] = grid
    return j


class AccuracyTarget(unittest.TestCase):
    def test_target_picks_the_grid_and_bounds_the_true_error(self):
        r = parafab.simulate(PART, job({"target": 0.15, "max_cells": 40}))
        a = r["accuracy"]
        cells = [lv["cells"] for lv in a["levels"]]
        print("levels", cells, "estimated error %.3f" % a["estimated_error"])
        self.assertTrue(a["met"], a["stopped"])
        self.assertLessEqual(a["estimated_error"], 0.15)
        self.assertEqual(cells[:3], [8, 12, 18])  # refined by 1.5 from 8
        self.assertEqual(r["grid"]["cells"][0], cells[-1])  # the result is the finest grid's
        out = subprocess.run(["/usr/bin/python3", REF, JOB, "--parafab", PART, "--size", "3", "--quiet"],
                             capture_output=True, text=True, check=True).stdout
        u_ref = json.loads(out)["displacement_at"][0]["u"][2]
        true_error = abs(r["probes"][0]["displacement"][2] - u_ref) / abs(u_ref)
        print("true error against CalculiX tet10 h = 3 mm: %.3f" % true_error)
        self.assertLessEqual(true_error, a["estimated_error"])

    def test_unreachable_target_is_reported_not_met(self):
        r = parafab.simulate(PART, job({"target": 1e-4, "max_cells": 14}))
        a = r["accuracy"]
        self.assertFalse(a["met"])
        self.assertIn("max_cells", a["stopped"])
        self.assertEqual([lv["cells"] for lv in a["levels"]], [8, 12])
        self.assertIsNone(a["estimated_error"])  # two grids give a change, not an estimate

    def test_bad_targets_name_the_field(self):
        for grid, text in [({"target": 2}, "grid.target"), ({"target": 0.1, "cell_size": 2}, "grid.cell_size")]:
            with self.assertRaises(parafab.Error) as cm:
                parafab.simulate(PART, job(grid))
            self.assertIn(text, str(cm.exception))


if __name__ == "__main__":
    unittest.main()
