"""Robustness study through the strip JSON (thesis §4.7.2, Fig. 4.15): "robustness": true or an
options object adds result["robustness"] = {baseline, worst_deviation, worst_case, edges,
seconds, cases[]}.

* The baseline (no defect) reproduces the target within 1.5x its measured deviation.
* The weight +50 % case of a strip designed under gravity deviates more than the baseline, and
  a larger angle defect more than a smaller one; cases without gravity have no weight case.
* Every case carries the simulated nodes (edges + 1), starting at the clamp; the baseline's
  distance to the target recomputed from them matches max_distance.
* Options map onto the study (custom fractions, edges); bad options name the field.
* plot_robustness.py writes a PNG.

Run with Debian's /usr/bin/python3; PARAFAB_MODULE_DIR points at the build.
"""
import json
import math
import os
import subprocess
import sys
import tempfile
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, "..", ".."))
sys.path.insert(0, os.environ.get("PARAFAB_MODULE_DIR", "build/workbench/entry"))
import parafab  # noqa: E402

SAMPLES = os.path.join(REPO, "samples", "strips")
PLOT = os.path.join(REPO, "workbench", "scripts", "plot_robustness.py")


def sample(name, **extra):
    with open(os.path.join(SAMPLES, name + ".json")) as f:
        r = json.load(f)
    r.pop("validate", None)
    r.update(extra)
    return r


def target_nodes(result, edges):
    """The target curve at arc lengths l k / edges: scipy's cubic splines x(s), y(s) through the
    result's samples."""
    from scipy.interpolate import CubicSpline
    s, pts = result["s"], result["points"]
    fx, fy = CubicSpline(s, [p[0] for p in pts]), CubicSpline(s, [p[1] for p in pts])
    t = [result["length"] * k / edges for k in range(edges + 1)]
    return [[float(x), float(y)] for x, y in zip(fx(t), fy(t))]


def case(result, name):
    for c in result["robustness"]["cases"]:
        if c["name"] == name:
            return c
    raise AssertionError("no case %s in %s" % (name, [c["name"] for c in result["robustness"]["cases"]]))


#: Measured baseline deviation of the plain design at 400 edges, times 1.5.
PLAIN_400_BOUND = 9e-6  # measured 5.8e-6


class Robustness(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.gravity = parafab.design_strip(sample("gravity_ellipse_cardboard", robustness=True))
        cls.plain = parafab.design_strip(sample("double_inflection", robustness={
            "angle_deg": 5, "plastic_fractions": [0.25], "stiffness_change": 0.25, "edges": 400}))

    def test_fields(self):
        rb = self.gravity["robustness"]
        for key in ("baseline", "worst_deviation", "worst_case", "edges", "seconds", "cases"):
            self.assertIn(key, rb)
        self.assertEqual(rb["edges"], 800)
        names = [c["name"] for c in rb["cases"]]
        print("\n  " + "\n  ".join("%-26s %-16s %+6g deviation %.3g%s" % (
            c["name"], c["parameter"], c["value"], c["deviation"], "" if c["converged"] else " (not converged)")
            for c in rb["cases"]))
        self.assertEqual(names, ["baseline", "stiffness_range+50%", "stiffness_range-50%", "gravity+50%",
                                 "gravity-50%", "end_angles_opened_10deg", "end_angles_closed_10deg",
                                 "plastic_top_25%", "plastic_top_50%"])
        for c in rb["cases"]:
            for key in ("name", "parameter", "value", "deviation", "max_distance", "converged", "message",
                        "nodes"):
                self.assertIn(key, c)
            self.assertEqual(len(c["nodes"]), rb["edges"] + 1, c["name"])
            # the clamped start stays where the target starts; the distance to the target, recomputed
            # here from the nodes at the same arc length, is at most max_distance
            self.assertLess(math.dist(c["nodes"][0], self.gravity["points"][0]), 1e-9)
        base = case(self.gravity, "baseline")
        worst = max(math.dist(p, q) for p, q in zip(base["nodes"], target_nodes(self.gravity, rb["edges"])))
        self.assertAlmostEqual(worst, base["max_distance"], delta=1e-6 * self.gravity["length"])
        self.assertEqual(case(self.gravity, "gravity+50%")["parameter"], "gravity")
        self.assertAlmostEqual(case(self.gravity, "gravity+50%")["value"], 0.5)
        self.assertAlmostEqual(case(self.gravity, "end_angles_closed_10deg")["value"], -10.0)
        self.assertAlmostEqual(case(self.gravity, "plastic_top_50%")["value"], 0.5)
        self.assertGreater(case(self.gravity, "plastic_top_25%")["curvature_limit"],
                           case(self.gravity, "plastic_top_50%")["curvature_limit"])

    def test_baseline_and_defects(self):
        rb = self.gravity["robustness"]
        base = case(self.gravity, "baseline")
        self.assertTrue(base["converged"], base["message"])
        self.assertEqual(rb["baseline"], base["deviation"])
        self.assertLessEqual(rb["baseline"], 3e-6)  # measured 2.0e-6 at 800 edges
        heavy = case(self.gravity, "gravity+50%")
        self.assertTrue(heavy["converged"], heavy["message"])
        self.assertGreater(heavy["deviation"], 10 * rb["baseline"])
        for name in ("stiffness_range+50%", "stiffness_range-50%", "gravity-50%",
                     "end_angles_opened_10deg", "end_angles_closed_10deg"):
            c = case(self.gravity, name)
            self.assertTrue(c["converged"], c["message"])
            self.assertGreater(c["deviation"], rb["baseline"], name)

    def test_options(self):
        rb = self.plain["robustness"]
        self.assertEqual(rb["edges"], 400)
        print("\n  400 edges, baseline deviation %.3g" % rb["baseline"])
        self.assertLessEqual(rb["baseline"], PLAIN_400_BOUND)
        names = [c["name"] for c in rb["cases"]]
        self.assertEqual(names, ["baseline", "stiffness_range+25%", "stiffness_range-25%",
                                 "end_angles_opened_5deg", "end_angles_closed_5deg", "plastic_top_25%"])
        # a 5° clamp error moves the strip less than a 10° one
        ten = parafab.design_strip(sample("double_inflection", robustness={"plastic_fractions": [], "edges": 400}))
        self.assertLess(case(self.plain, "end_angles_opened_5deg")["deviation"],
                        case(ten, "end_angles_opened_10deg")["deviation"])

    def test_off_and_infeasible(self):
        self.assertNotIn("robustness", parafab.design_strip(sample("elliptic_arc", robustness=False)))
        self.assertIsNone(parafab.design_strip(sample("infeasible_crossing", robustness=True))["robustness"])

    def test_bad_options_name_the_field(self):
        for value, needle in (("yes", "robustness must be true, false or"),
                              ({"stiffness": 0.5}, "robustness.stiffness: unknown key"),
                              ({"stiffness_change": 1.5}, "robustness.stiffness_change must lie in (0, 1), got 1.5"),
                              ({"gravity_change": "x"}, "robustness.gravity_change must be a number"),
                              ({"angle_deg": 0}, "robustness.angle_deg must lie in (0, 90), got 0"),
                              ({"plastic_fractions": [0.25, 1]}, "robustness.plastic_fractions[1] must lie in (0, 1)"),
                              ({"plastic_hardening": -1}, "robustness.plastic_hardening must be positive"),
                              ({"edges": 3}, "robustness.edges must be an integer 4..100000, got 3")):
            with self.subTest(value=value):
                with self.assertRaises(parafab.Error) as cm:
                    parafab.design_strip(sample("elliptic_arc", robustness=value))
                self.assertIn(needle, str(cm.exception))

    def test_plot(self):
        with tempfile.TemporaryDirectory() as d:
            res, png = os.path.join(d, "r.json"), os.path.join(d, "r.png")
            with open(res, "w") as f:
                json.dump([self.gravity, self.plain], f)
            p = subprocess.run(["/usr/bin/python3", PLOT, res, png], capture_output=True, text=True, timeout=120)
            self.assertEqual(p.returncode, 0, p.stderr)
            self.assertGreater(os.path.getsize(png), 10000)
            with open(png, "rb") as f:
                self.assertEqual(f.read(8), b"\x89PNG\r\n\x1a\n")
            with open(res, "w") as f:
                json.dump(parafab.design_strip(sample("elliptic_arc")), f)
            p = subprocess.run(["/usr/bin/python3", PLOT, res, png], capture_output=True, text=True, timeout=120)
            self.assertNotEqual(p.returncode, 0)
            self.assertIn("no \"robustness\"", p.stderr)


if __name__ == "__main__":
    unittest.main()
