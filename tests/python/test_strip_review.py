"""Review defects of issue 13 through the entry points (Python module and CLI), against
closed forms: bending strain of an exact circular arc (h/(2r)), the refusal of a material
that would yield, ideal plasticity accepted, the composite weight per length by hand
(ρ g (h1 w1 + h2 w2)), and the perforation deviation fields.

Run with Debian's /usr/bin/python3; PARAFAB_MODULE_DIR and PARAFAB_CLI point at the build.
"""
import json
import math
import os
import subprocess
import sys
import tempfile
import unittest

sys.path.insert(0, os.environ.get("PARAFAB_MODULE_DIR", "build/workbench/entry"))
import parafab  # noqa: E402

CLI = os.environ.get("PARAFAB_CLI", "build/workbench/entry/parafab")


def arc(r=0.25, angle=2 * math.pi / 3):
    """Exact rational quadratic arc of radius r (m), centre at the origin, from angle 0."""
    w = math.cos(angle / 2)
    mid = [r * math.cos(angle / 2) / w, r * math.sin(angle / 2) / w]
    return {"bspline": {"degree": 2, "knots": [0, 0, 0, 1, 1, 1],
                        "poles": [[r, 0], mid, [r * math.cos(angle), r * math.sin(angle)]],
                        "weights": [1, w, 1]}}


def run_cli(req):
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
        json.dump(req, f)
    try:
        return subprocess.run([CLI, "strip", f.name], capture_output=True, text=True, timeout=120)
    finally:
        os.unlink(f.name)


class Strain(unittest.TestCase):
    def test_arc_strain_and_yield(self):
        h, r = 0.5e-3, 0.25
        req = {"curve": arc(r), "material": {"E": 2.8e9, "thickness": h, "yield_stress": 2.8e9 * 1.05e-3,
                                             "name": "POM 0.5 mm"}, "min_width": 0.01}
        res = parafab.design_strip(req)
        self.assertTrue(res["feasible"])
        self.assertAlmostEqual(res["strain"]["max"], h / (2 * r), delta=1e-15)
        self.assertAlmostEqual(res["strain"]["yield_ratio"], 1 / 1.05, delta=1e-12)
        req["material"]["yield_stress"] = 2.8e9 * 0.95e-3
        with self.assertRaises(parafab.Error) as cm:
            parafab.design_strip(req)
        self.assertIn('"POM 0.5 mm" yields', str(cm.exception))
        p = run_cli(req)
        self.assertEqual(p.returncode, 2, p.stdout + p.stderr)
        self.assertIn('"POM 0.5 mm" yields', json.loads(p.stdout)["error"]["message"])
        # Without a yield strain the strain is reported, the ratio is null.
        del req["material"]["yield_stress"]
        res = parafab.design_strip(req)
        self.assertIsNone(res["strain"]["yield_ratio"])

    def test_composite_strain_is_that_of_the_laminate(self):
        # Two glued 0.3 mm layers on an arc of r = 3 cm: the laminate's outer fibre lies
        # (h1 + h2)/2 from the mid-plane the stiffness (h1 + h2)³ w2 bends about, so
        # ε = 0.6e-3 / (2 · 0.03) = 0.01, 1.33 × cardboard's 0.0075: refused. Before the fix the
        # thicker layer alone gave 0.005 and the design was accepted with yield_ratio 0.667.
        h1 = h2 = 0.3e-3
        r = 0.03
        req = {"curve": arc(r), "material": {"E": 7.73e8, "thickness": h1, "yield_strain": 0.0075,
                                             "name": "Cardboard 200 gsm"},
               "min_width": 0.02, "composite": {"h1": h1, "h2": h2, "outer_width": 0.05}}
        with self.assertRaises(parafab.Error) as cm:
            parafab.design_strip(req)
        self.assertIn('"Cardboard 200 gsm" yields', str(cm.exception))
        p = run_cli(req)
        self.assertEqual(p.returncode, 2, p.stdout + p.stderr)
        self.assertIn('"Cardboard 200 gsm" yields', json.loads(p.stdout)["error"]["message"])
        # With a yield strain above it: designed, strain and ratio by the closed form.
        req["material"]["yield_strain"] = 0.0125
        res = parafab.design_strip(req)
        self.assertTrue(res["feasible"], res["reason"])
        # measured differences from the closed form: 0, 5.2e-18, 4.4e-16
        self.assertAlmostEqual(res["strain"]["thickness"], h1 + h2, delta=1e-18)
        self.assertAlmostEqual(res["strain"]["max"], (h1 + h2) / (2 * r), delta=1e-17)
        self.assertAlmostEqual(res["strain"]["yield_ratio"], (h1 + h2) / (2 * r) / 0.0125, delta=1e-15)

    def test_ideal_plasticity_is_designed(self):
        # κ = 40 > κ_lim = 20 everywhere: κ_eff constant, K constant (R = 1).
        req = {"curve": arc(0.025), "material": {"E": 3e9, "thickness": 3e-4,
                                                 "law": {"curvature_limit": 20, "hardening": 0}},
               "min_width": 0.01, "validate": True}
        res = parafab.design_strip(req)
        self.assertTrue(res["feasible"], res["reason"])
        self.assertAlmostEqual(res["R"], 1.0, delta=1e-9)
        self.assertAlmostEqual(res["max_plastic_curvature"], 40.0, delta=1e-9)
        self.assertLess(res["simulation"]["deviation"], 1e-6)


class CompositeWeight(unittest.TestCase):
    def test_weight_per_length_of_both_layers(self):
        rho, g, h1, h2, w1 = 667.0, 9.81, 3e-4, 3e-4, 0.05
        t = [0.2 + 2.7 * i / 400 for i in range(401)]
        req = {"curve": {"points": [[0.2 * math.cos(x), 0.12 * math.sin(x)] for x in t]},
               "material": {"E": 0.773e9, "thickness": h1, "density": rho},
               "gravity": {"direction": [0, -1]}, "min_width": 0.01,
               "composite": {"h1": h1, "h2": h2, "outer_width": w1}, "validate": True}
        res = parafab.design_strip(req)
        self.assertTrue(res["feasible"], res["reason"])
        self.assertTrue(res["composite"]["feasible"], res["composite"]["message"])
        for q, w2 in zip(res["weight_per_length"], res["composite"]["w2"]):
            expected = rho * g * (h1 * w1 + h2 * w2)
            self.assertAlmostEqual(q, expected, delta=1e-9 * expected)
        self.assertGreater(res["weight_iterations"], 1)
        self.assertLess(res["simulation"]["deviation"], 5e-6)


class PerforationDeviation(unittest.TestCase):
    def test_deviation_fields_are_reported(self):
        t = [0.2 + 2.7 * i / 400 for i in range(401)]
        req = {"curve": {"points": [[0.2 * math.cos(x), 0.12 * math.sin(x)] for x in t]},
               "material": {"E": 3e9, "thickness": 5e-4}, "min_width": 0.02,
               "perforated": {"outer_width": 0.04, "min_ligament": 1e-3}}
        res = parafab.design_strip(req)
        p = res["perforations"]
        self.assertTrue(p["feasible"], p["message"])
        # The ends carry no holes: the end zones are stiffer by w/w_K − 1 ≥ 0.04/max(w_K) − 1.
        widths = res["width"]
        self.assertGreaterEqual(p["end_zone_deviation"], 0.04 / max(widths[0], widths[-1]) - 1 - 1e-9)
        for key in ("max_width_deviation", "max_stiffness_deviation"):
            self.assertGreater(p[key], 0)
            self.assertGreaterEqual(p[key + "_s"], 0)
            self.assertLessEqual(p[key + "_s"], res["length"])
        # Inside the perforated range the pattern's own error, smaller than the maxima that the
        # hole-free ends set.
        for key in ("width", "stiffness"):
            inner = p["interior_%s_deviation" % key]
            self.assertGreater(inner, 0)
            self.assertLess(inner, p["max_%s_deviation" % key])
            self.assertGreaterEqual(p["interior_%s_deviation_s" % key], p["from"])
            self.assertLessEqual(p["interior_%s_deviation_s" % key], p["to"])


class EndZeros(unittest.TestCase):
    def test_points_whose_curvature_vanishes_at_the_start(self):
        """y = a sin(x/a) from x = 0 to 1.5 pi a, as 121 points (quartic interpolation): the start
        is a zero of the curvature on the line the LP chooses through the inflection at x = pi a
        (closed form: the line y = 0), so it is listed as kind "end" at s = 0; before the fix
        it was not listed. The CLI gives the same zeros."""
        a = 0.05
        pts = [[a * t, a * math.sin(t)] for t in (1.5 * math.pi * i / 120 for i in range(121))]
        req = {"curve": {"points": pts}, "material": {"E": 3e9, "thickness": 5e-4}, "min_width": 0.01}
        res = parafab.design_strip(req)
        self.assertTrue(res["feasible"], res["reason"])
        zeros = res["inflections"]
        self.assertEqual([z["kind"] for z in zeros], ["end", "inflection"])
        self.assertEqual(zeros[0]["s"], 0.0)
        self.assertAlmostEqual(zeros[1]["point"][0], a * math.pi, delta=1e-6 * a)
        self.assertAlmostEqual(zeros[1]["point"][1], 0.0, delta=1e-6 * a)
        line = res["line"]  # a + <b, x> = 0 is y = 0: b along y, a = 0
        self.assertLess(abs(line["b"][0]) / abs(line["b"][1]), 1e-4)
        self.assertLess(abs(line["a"]) / (abs(line["b"][1]) * res["length"]), 1e-4)
        out = run_cli(req)
        self.assertEqual(out.returncode, 0, out.stderr)
        self.assertEqual([z["kind"] for z in json.loads(out.stdout)["inflections"]], ["end", "inflection"])


if __name__ == "__main__":
    unittest.main()
