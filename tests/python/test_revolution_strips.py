"""Surfaces of revolution tiled by strips (thesis §4.8.4): parafab.revolution_strips and
`parafab revolution`. Closed form: a = 0, b = (1/ρ, 0) from (ρ, 0) going up gives x κ = x/ρ,
so κ = 1/ρ: the meridian is a circle of radius ρ about the origin (a sphere), and the n
strips have widths 2 x tan(π/n), so R = max x / min x."""
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
CLI = os.environ.get("PARAFAB_CLI", os.path.join(REPO, "build", "workbench", "entry", "parafab"))
RHO = 0.1


class RevolutionStrips(unittest.TestCase):
    def test_sphere_meridian_and_its_strips(self):
        length = 0.4 * math.pi * RHO  # 72° of the meridian, from the equator up
        r = parafab.revolution_strips({"a": 0, "b": [1 / RHO, 0], "start": [RHO, 0], "length": length,
                                       "strips": 8, "points": 101})
        m = r["meridian"]
        self.assertTrue(m["complete"], m["message"])
        for (x, y), s in zip(m["points"], m["s"]):
            self.assertAlmostEqual(math.hypot(x, y), RHO, delta=1e-8 * RHO)  # CVODE rtol 1e-10
            self.assertAlmostEqual(math.atan2(y, x), s / RHO, delta=1e-7)
        for k in m["curvature"]:
            self.assertAlmostEqual(k, 1 / RHO, delta=1e-9 / RHO)
        st = r["strips"]
        for (x, _), w in zip(m["points"], st["width"]):
            self.assertAlmostEqual(w, 2 * x * math.tan(math.pi / 8), delta=1e-12)
        xs = [p[0] for p in m["points"]]
        self.assertAlmostEqual(st["R"], max(xs) / min(xs), delta=1e-9)

    def test_meridian_reaching_the_axis_is_reported_incomplete(self):
        r = parafab.revolution_strips({"a": 0, "b": [1 / RHO, 0], "start": [RHO, 0], "length": 3 * RHO})
        m = r["meridian"]  # the quarter circle meets the axis at s = πρ/2 < 3ρ
        self.assertFalse(m["complete"])
        self.assertAlmostEqual(m["reached_length"], 0.5 * math.pi * RHO, delta=1e-4 * RHO)

    def test_bad_fields_are_named(self):
        for job, field in [({"start": [0, 0]}, "start[0]"), ({"length": -1}, "length"), ({"strips": 2}, "strips"),
                           ({"b": [1]}, "b"), ({"material": {"E": 0}}, "material.E")]:
            with self.assertRaises(parafab.Error) as cm:
                parafab.revolution_strips(job)
            self.assertIn(field, str(cm.exception))
        with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
            json.dump({"strips": 1}, f)
        out = subprocess.run([CLI, "revolution", f.name], capture_output=True, text=True)
        os.unlink(f.name)
        self.assertEqual(out.returncode, 2)
        self.assertIn("strips", json.loads(out.stdout)["error"]["message"])


if __name__ == "__main__":
    unittest.main()
