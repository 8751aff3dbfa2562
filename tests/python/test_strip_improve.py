"""strip-improve entry points (CLI and Python module) against independent references.

The result B-spline is re-evaluated with scipy (scipy.interpolate.BSpline): end points and end
tangents of the input kept, the arc length kept (scipy quad), the inflections (brentq on
det(γ', γ'')) on the input's inflection line, all to 1e-9 of the length; R of the new curve
re-designed by `design_strip`; the CLI and the module give the same result; bad input gives a
JSON error naming the field (exit 2) / parafab.Error.

Run with Debian's /usr/bin/python3; PARAFAB_MODULE_DIR and PARAFAB_CLI point at the build.
"""
import json
import math
import os
import subprocess
import sys
import tempfile
import unittest

import numpy as np
from scipy.integrate import quad
from scipy.interpolate import BSpline
from scipy.optimize import brentq

sys.path.insert(0, os.environ.get("PARAFAB_MODULE_DIR", "build/workbench/entry"))
import parafab  # noqa: E402

CLI = os.environ.get("PARAFAB_CLI", "build/workbench/entry/parafab")


def s_curve_points():
    """y = 0.25 (u⁴ − u²), u = x/0.25, x ∈ [−0.2, 0.2]: two inflections at u = ±1/√6."""
    xs = np.linspace(-0.2, 0.2, 200)
    u = xs / 0.25
    return [[float(x), float(0.25 * (v ** 4 - v ** 2))] for x, v in zip(xs, u)]


def request(**improve):
    return {"curve": {"points": s_curve_points()}, "material": {"E": 3e9, "thickness": 5e-4},
            "min_width": 0.01, "improve": dict({"fair": {"poles": 14, "fairness": 0}}, **improve)}


def spline(bs):
    return BSpline(np.array(bs["knots"]), np.array(bs["poles"]), bs["degree"])


def inflections(c):
    d1, d2 = c.derivative(1), c.derivative(2)
    t0, t1 = c.t[c.k], c.t[-c.k - 1]
    det = lambda t: float(np.cross(d1(t), d2(t)))
    ts = np.linspace(t0, t1, 2001)
    v = [det(t) for t in ts]
    return [brentq(det, ts[i], ts[i + 1], xtol=1e-15) for i in range(len(ts) - 1) if v[i] * v[i + 1] < 0]


def length(c):
    d1 = c.derivative(1)
    t0, t1 = c.t[c.k], c.t[-c.k - 1]
    br = sorted(set(c.t[c.k:-c.k]))
    return sum(quad(lambda t: np.linalg.norm(d1(t)), a, b, epsabs=1e-14, epsrel=1e-13)[0]
               for a, b in zip(br[:-1], br[1:]))


class StripImproveEntry(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.req = request()
        cls.result = parafab.strip_improve(cls.req, target_R=3.0)

    def test_reaches_the_target_and_design_agrees(self):
        r = self.result
        self.assertTrue(r["done"], r["status"])
        self.assertGreater(r["R_initial"], 3.0)
        self.assertLessEqual(r["R"], r["R_estimate"])
        self.assertLessEqual(r["R_estimate"], 3.0)
        self.assertEqual(r["R_upper"], r["R_estimate"])  # deprecated alias
        # A finer design (the solver's default tolerance 1e-6) lies in [R, R_estimate] of the
        # result's 1e-3 design here; R_estimate is an estimate, not a certified bound.
        again = parafab.design_strip({"curve": {"bspline": r["bspline"]}, "material": {"E": 3e9, "thickness": 5e-4},
                                      "min_width": 0.01})
        self.assertGreaterEqual(again["R"], r["R"] * (1 - 1e-9))
        self.assertLessEqual(again["R"], r["R_estimate"] * (1 + 1e-9))
        self.assertAlmostEqual(r["design"]["R"], r["R"], delta=1e-9 * r["R"])
        self.assertEqual(r["inflections"], 2)
        self.assertGreater(len(r["history"]), 1)
        self.assertGreater(r["max_pole_move"], 0)
        self.assertEqual(r["fair"]["inflections"], 2)

    def test_constraints_hold_by_scipy(self):
        r = self.result
        a, b = spline(r["original_bspline"]), spline(r["bspline"])
        L = length(a)
        ta0, ta1 = a.t[a.k], a.t[-a.k - 1]
        tb0, tb1 = b.t[b.k], b.t[-b.k - 1]
        self.assertLess(np.linalg.norm(a(ta0) - b(tb0)), 1e-10 * L)
        self.assertLess(np.linalg.norm(a(ta1) - b(tb1)), 1e-10 * L)
        for ta, tb in ((ta0, tb0), (ta1, tb1)):
            u, v = a.derivative(1)(ta), b.derivative(1)(tb)
            self.assertLess(abs(np.cross(u, v)) / (np.linalg.norm(u) * np.linalg.norm(v)), 1e-10)
            self.assertGreater(np.dot(u, v), 0)
        self.assertLess(abs(length(b) - L), 1e-9 * L)
        ia, ib = inflections(a), inflections(b)
        self.assertEqual(len(ia), 2)
        self.assertEqual(len(ib), 2)
        p, q = a(ia[0]), a(ia[1])
        n = np.array([-(q - p)[1], (q - p)[0]]) / np.linalg.norm(q - p)
        for t in ib:
            self.assertLess(abs(np.dot(b(t) - p, n)), 1e-9 * L)
        # The sampled deviation is a lower bound of the true Hausdorff distance and close to it.
        pa = a(np.linspace(ta0, ta1, 3000))
        pb = b(np.linspace(tb0, tb1, 3000))
        d = np.sqrt(((pa[:, None, :] - pb[None, :, :]) ** 2).sum(-1))
        h = max(d.min(1).max(), d.min(0).max())
        self.assertAlmostEqual(r["deviation"], h, delta=0.02 * h + 1e-6 * L)

    def test_points_deviation_by_scipy(self):
        # With points input the descent starts from the fair fit; points_deviation measures the
        # result against the points themselves, fit_points_deviation the fit (dense scipy
        # sampling, 20001 points: a bound from above close to the true distance).
        r = self.result
        P = np.array(s_curve_points())
        L = r["length"]
        for key, bs in (("points_deviation", r["bspline"]), ("fit_points_deviation", r["original_bspline"])):
            c = spline(bs)
            q = c(np.linspace(c.t[c.k], c.t[-c.k - 1], 20001))
            d = np.sqrt(((P[:, None, :] - q[None, :, :]) ** 2).sum(-1)).min(1).max()
            self.assertLessEqual(r[key], d * (1 + 1e-9), key)
            self.assertGreater(r[key], d - 2e-6 * L, key)  # the sampling error of d: ≲ (L/20000)²κ
        self.assertAlmostEqual(r["points_deviation_relative"], r["points_deviation"] / L, delta=1e-15)
        self.assertLess(r["fit_points_deviation"], 1e-4 * L)  # the fair fit follows the points
        self.assertGreater(r["points_deviation"], r["fit_points_deviation"])  # the curve was moved

    def test_stability_verdict_agrees_with_the_hessian_inertia(self):
        # The result carries the Jacobi verdict (of the requested design); the simulator's
        # constrained Hessian inertia on the same curve is the independent check.
        r = self.result
        st = r["stability"]
        self.assertIsInstance(st["stable"], bool)
        self.assertEqual(st, r["design"]["stability"])
        self.assertEqual(len(st["s"]), len(st["Z"]))
        check = parafab.strip_stability({"curve": {"bspline": r["bspline"]}, "material": {"E": 3e9, "thickness": 5e-4},
                                         "min_width": 0.01})["stability"]
        self.assertEqual(check["eigenvalue"]["stable"], st["stable"])
        self.assertEqual(check["stable"], st["stable"])
        # Without material (no requested design) the verdict is of the improved curve's Eq. 4.4
        # design; "stability": false leaves it out.
        bare = {"curve": {"bspline": r["original_bspline"]}, "improve": {"max_iterations": 2}}
        out = parafab.strip_improve(bare, target_R=3.0)
        self.assertIsNone(out["design"])
        self.assertIsInstance(out["stability"]["stable"], bool)
        again = parafab.strip_stability({"curve": {"bspline": out["bspline"]}, "material": {"E": 3e9, "thickness": 5e-4},
                                         "min_width": 0.01})["stability"]
        self.assertEqual(again["eigenvalue"]["stable"], out["stability"]["stable"])
        self.assertIsNone(out["points_deviation"])
        bare["stability"] = False
        self.assertIsNone(parafab.strip_improve(bare, target_R=3.0)["stability"])

    def test_cli_matches_module(self):
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "in.json")
            with open(path, "w") as f:
                json.dump(self.req, f)
            out = subprocess.run([CLI, "strip-improve", path, "--target-R", "3"], capture_output=True, text=True)
            self.assertEqual(out.returncode, 0, out.stdout + out.stderr)
            cli = json.loads(out.stdout)
        self.assertEqual(cli["bspline"]["poles"], self.result["bspline"]["poles"])
        self.assertEqual(cli["R"], self.result["R"])

    def test_bad_input(self):
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "in.json")
            with open(path, "w") as f:
                json.dump(request(p="x"), f)
            out = subprocess.run([CLI, "strip-improve", path], capture_output=True, text=True)
            self.assertEqual(out.returncode, 2)
            self.assertIn("improve.p", json.loads(out.stdout)["error"]["message"])
        with self.assertRaises(parafab.Error) as ctx:
            parafab.strip_improve(request(unknown=1))
        self.assertIn("improve.unknown", str(ctx.exception))
        with self.assertRaises(parafab.Error):
            parafab.strip_improve(request(), target_R=0.5)


SAMPLES = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "samples", "strips")


def sample(name):
    with open(os.path.join(SAMPLES, name + ".json")) as f:
        return json.load(f)


def run_cli(req, *args):
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "in.json")
        with open(path, "w") as f:
            json.dump(req, f)
        return subprocess.run([CLI, "strip-improve", path, *args], capture_output=True, text=True)


class RequestedDesign(unittest.TestCase):
    """`done` is the requested design's. The descent lowers R of LP Eq. 4.4 (clamped ends,
    no natural curvature, linear law); before the fix a request with the end free in x
    (quartic_bspline) reported R 1.73 -> 1.198 and done: true while the design it asked for
    went 16.7 -> 89.6, and gravity_one_inflection at target 1.5 reported done: true with
    R_gravity 6.93 > 1.5."""

    def test_other_lps_are_refused_naming_the_field(self):
        for field, change in (("boundary", lambda r: r.update(boundary={"end": {"free_x": True}})),
                              ("natural_curvature", lambda r: r.update(natural_curvature=2.0)),
                              ("material.law", lambda r: r["material"].update(law={"cubic": 1e-4}))):
            req = sample("quartic_bspline")
            change(req)
            with self.assertRaises(parafab.Error) as ctx:
                parafab.strip_improve(req, target_R=1.3)
            self.assertTrue(str(ctx.exception).startswith(field + ": "), str(ctx.exception))
            self.assertIn("LP Eq. 4.4", str(ctx.exception))
            out = run_cli(req, "--target-R", "1.3")
            self.assertEqual(out.returncode, 2, out.stdout + out.stderr)
            self.assertTrue(json.loads(out.stdout)["error"]["message"].startswith(field + ": "))
        req = sample("quartic_bspline")
        req["boundary"] = {"end": {"free_x": True}}
        self.assertIn('{"end":{"free_x":true}}', str(self._error(req)))
        # Gravity needs the material to be designed.
        req = sample("gravity_one_inflection")
        del req["material"]
        self.assertIn("gravity: ", str(self._error(req)))

    def _error(self, req):
        with self.assertRaises(parafab.Error) as ctx:
            parafab.strip_improve(req, target_R=1.5)
        return ctx.exception

    def test_gravity_done_is_that_of_the_gravity_design(self):
        req = sample("gravity_one_inflection")
        req.pop("validate", None)
        r = parafab.strip_improve(req, target_R=1.5)
        # Eq. 4.4 reached the target, the gravity design (Eq. 4.6 afterwards) did not.
        self.assertLessEqual(r["R_estimate"], 1.5)
        self.assertGreater(r["R_gravity"], 1.5)
        self.assertFalse(r["done"])
        self.assertEqual(r["status"], "target_without_gravity")
        self.assertIn("R_gravity", r["message"])
        # Independent of strip-improve: the gravity design of the returned curve.
        again = dict(req, curve={"bspline": r["bspline"]}, tolerance=1e-3, max_samples=4097)
        self.assertEqual(parafab.design_strip(again)["R"], r["R_gravity"])
        # A target the gravity design meets at the start: done, R_gravity <= target.
        easy = parafab.strip_improve(req, target_R=8.0)
        self.assertTrue(easy["done"], easy["status"] + " " + easy["message"])
        self.assertLessEqual(easy["R_gravity"], 8.0)
        self.assertEqual(easy["status"], "already")


if __name__ == "__main__":
    unittest.main()
