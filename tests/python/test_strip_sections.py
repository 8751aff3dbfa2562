"""Strips from plane sections (thesis §4.8.2): `parafab.strip_sections` / `parafab sections`.

Closed forms: the cylinder of samples/parts/cylinder.step (r = 15 mm, axis z) cut by planes
z = const gives circles; split at y = 0 each half is a semicircle of length 15π mm, and a
circle is an equilibrium of a constant-stiffness strip, so R = 1 and the line's b = 0."""
import json
import math
import os
import subprocess
import sys
import tempfile
import unittest

sys.path.insert(0, os.environ.get("PARAFAB_MODULE_DIR", "build/workbench/entry"))
import parafab  # noqa: E402

REPO = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
CYLINDER = os.path.join(REPO, "samples", "parts", "cylinder.step")
CLI = os.environ.get("PARAFAB_CLI", os.path.join(REPO, "build", "workbench", "entry", "parafab"))
STRIP = {"material": {"E": 2.8e9, "thickness": 0.0005}, "min_width": 0.01, "tolerance": 1e-6}


class StripSections(unittest.TestCase):
    def test_split_circles_are_semicircles_with_constant_stiffness(self):
        job = {"planes": {"normal": [0, 0, 1], "offsets": [5, 20, 35]},
               "split": {"normal": [0, 1, 0], "offset": 0}, "samples": 80, "strip": STRIP}
        r = parafab.strip_sections(CYLINDER, job)
        self.assertEqual(len(r["curves"]), 6)
        self.assertEqual((r["designed"], r["infeasible"], r["failed"]), (6, 0, 0))
        for c in r["curves"]:
            for p in c["points"]:  # on the cylinder and in the plane
                self.assertAlmostEqual(math.hypot(p[0], p[1]), 15.0, delta=1e-6)
                self.assertAlmostEqual(p[2], c["offset"], delta=1e-9)
            self.assertAlmostEqual(c["length"], 15e-3 * math.pi, delta=1e-6 * 15e-3 * math.pi)
            s = c["strip"]
            self.assertTrue(s["feasible"], s.get("reason"))
            self.assertAlmostEqual(s["R"], 1.0, delta=1e-4)
            self.assertAlmostEqual(s["length"], 15e-3 * math.pi, delta=1e-5 * 15e-3 * math.pi)

    def test_closed_curves_missing_planes_and_bad_jobs(self):
        r = parafab.strip_sections(CYLINDER, {"planes": {"normal": [0, 0, 1], "offsets": [20, 100]}, "strip": STRIP})
        self.assertEqual(r["empty_planes"], [1])  # z = 100 misses the 40 mm cylinder
        self.assertEqual(len(r["curves"]), 1)
        self.assertTrue(r["curves"][0]["closed"])
        self.assertIn("closed section curve", r["curves"][0]["strip"]["error"]["message"])
        for job, field in [({"planes": {"normal": [0, 0, 0]}}, "planes.normal"),
                           ({"planes": {"count": 0}}, "planes.count"),
                           ({"split": {"normal": [0, 1]}}, "split"),
                           ({"samples": 3}, "samples"),
                           ({"units": "inch"}, "units"),
                           ({"strip": {"curve": {}}}, "strip.curve")]:
            with self.assertRaises(parafab.Error) as cm:
                parafab.strip_sections(CYLINDER, job)
            self.assertIn(field, str(cm.exception))

    def test_cli_writes_the_same_json_and_fails_with_a_json_error(self):
        with tempfile.TemporaryDirectory() as tmp:
            job = os.path.join(tmp, "job.json")
            with open(job, "w") as f:
                json.dump({"planes": {"normal": [0, 0, 1], "count": 2},
                           "split": {"normal": [0, 1, 0], "offset": 0}, "strip": STRIP}, f)
            out = subprocess.run([CLI, "sections", CYLINDER, job], capture_output=True, text=True)
            self.assertEqual(out.returncode, 0, out.stdout + out.stderr)
            self.assertEqual(json.loads(out.stdout)["designed"], 4)
            with open(job, "w") as f:
                json.dump({"planes": {"normal": "z"}}, f)
            out = subprocess.run([CLI, "sections", CYLINDER, job], capture_output=True, text=True)
            self.assertEqual(out.returncode, 2)
            self.assertIn("planes.normal", json.loads(out.stdout)["error"]["message"])


if __name__ == "__main__":
    unittest.main()
