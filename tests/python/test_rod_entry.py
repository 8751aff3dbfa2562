"""Rod entry points (Python module and CLI) against independent references.

* The line-complex LP of thesis Eq. 5.19 rebuilt in Python and solved with scipy's linprog
  (HiGHS): the Frénet data are recomputed from the returned B-spline with
  scipy.interpolate.BSpline at the returned parameters t (not taken from the result), the
  rows are built in physical units (x = (c, c̄, R)), and the optimum R / length must match
  ParaFab's normalized R; an infeasible curve must be infeasible for HiGHS too.
* A helix (a parallel curve, Prop. 7) gives zero twist and circular, constant sections.
* validate=true: the forward simulation (discrete elastic rod) of the sample designs stays
  within 1.5-2x its measured deviation (VALIDATED_DEVIATION, at most 9e-4·L) of the target.
* κ = 0: the CLI exits 2 with a JSON error naming the arc length; the module raises
  parafab.Error (a ValueError). Missing/invalid fields are named in the error.

Run with Debian's /usr/bin/python3; PARAFAB_MODULE_DIR and PARAFAB_CLI point at the build.
"""
import glob
import json
import math
import os
import re
import subprocess
import sys
import tempfile
import unittest

import numpy as np
from scipy.integrate import quad
from scipy.interpolate import BSpline
from scipy.optimize import linprog

sys.path.insert(0, os.environ.get("PARAFAB_MODULE_DIR", "build/workbench/entry"))
import parafab  # noqa: E402

CLI = os.environ.get("PARAFAB_CLI", "build/workbench/entry/parafab")
REPO = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir, os.pardir))
SAMPLES = os.path.join(REPO, "samples", "rods")


def sample(name):
    with open(os.path.join(SAMPLES, name + ".json")) as f:
        return json.load(f)


def helix_points(n=200, r=0.1, p=0.03, turns=1.5):
    t = np.linspace(0, 2 * math.pi * turns, n)
    return np.c_[r * np.cos(t), r * np.sin(t), p * t].tolist()


def frenet_from_bspline(result):
    """γ, T, N, κB and κ at the returned parameters, from the returned (non-rational) B-spline."""
    bs = result["bspline"]
    assert "weights" not in bs
    curve = BSpline(np.array(bs["knots"]), np.array(bs["poles"]), bs["degree"])
    t = np.array(result["t"])
    g, d1, d2 = curve(t), curve.derivative(1)(t), curve.derivative(2)(t)
    speed = np.linalg.norm(d1, axis=1)
    T = d1 / speed[:, None]
    wn = np.cross(d1, d2) / speed[:, None] ** 3  # κ B
    kappa = np.linalg.norm(wn, axis=1)
    B = wn / kappa[:, None]
    N = np.cross(B, T)
    return curve, g, T, N, wn, kappa


def scipy_line_complex_lp(result, w_reg=0.0):
    """Eq. 5.19 in physical units, x = (c, c̄, R): ⟨κB, c×γ + c̄⟩ ≥ 1, |⟨T, h⟩| ≤ R,
    w_reg |⟨N, h⟩| ≤ R, minimize R. ⟨v, c×γ + c̄⟩ = ⟨γ×v, c⟩ + ⟨v, c̄⟩. Returns the linprog result."""
    _, g, T, N, wn, _ = frenet_from_bspline(result)
    g = g - g.mean(axis=0)  # conditioning only: c̄ absorbs the shift
    rows = lambda v: np.c_[np.cross(g, v), v]  # noqa: E731
    n = len(g)
    zeros, ones = np.zeros((n, 1)), np.ones((n, 1))
    A = [np.c_[-rows(wn), zeros], np.c_[rows(T), -ones], np.c_[-rows(T), -ones]]
    b = [-np.ones(n), np.zeros(n), np.zeros(n)]
    if w_reg > 0:
        A += [np.c_[w_reg * rows(N), -ones], np.c_[-w_reg * rows(N), -ones]]
        b += [np.zeros(n), np.zeros(n)]
    return linprog(c=[0, 0, 0, 0, 0, 0, 1], A_ub=np.vstack(A), b_ub=np.concatenate(b),
                   bounds=[(None, None)] * 7, method="highs",
                   options={"primal_feasibility_tolerance": 1e-10, "dual_feasibility_tolerance": 1e-10})


LP_TOLERANCE = 1e-10  # the primal/dual feasibility tolerance given to HiGHS above


class LineComplexLpAgainstScipy(unittest.TestCase):
    def check(self, request, w_reg, second_stage=False):
        request = dict(request, w_reg=w_reg, validate=False, stiffness_ratio_stage=second_stage)
        r = parafab.design_rod(request)
        self.assertTrue(r["feasible"], r["reason"])
        # The returned Frénet data agree with the independent evaluation.
        curve, g, T, N, wn, kappa = frenet_from_bspline(r)
        np.testing.assert_allclose(r["points"], g, atol=1e-12)
        np.testing.assert_allclose(r["tangent"], T, atol=1e-9)
        np.testing.assert_allclose(r["normal"], N, atol=1e-7)
        np.testing.assert_allclose(r["curvature"], kappa, rtol=1e-9)
        speed = lambda u: np.linalg.norm(curve.derivative(1)(u))  # noqa: E731
        for i in (len(r["s"]) // 3, len(r["s"]) - 1):
            s = quad(speed, r["t"][0], r["t"][i], limit=400, epsabs=1e-12)[0]
            self.assertAlmostEqual(r["s"][i], s, delta=1e-8 * r["length"])
        res = scipy_line_complex_lp(r, w_reg)
        self.assertEqual(res.status, 0, res.message)
        R = res.x[6] / r["length"]
        if second_stage:  # the stiffness-ratio stage may use the slack R ≤ R*(1 + 1e-7)
            slack = r["lp"]["twist_slack_relative"]
            self.assertGreaterEqual(r["R"], R * (1 - 1e-9) - 1e-12)
            self.assertLessEqual(r["R"], R * (1 + slack + 1e-9) + 1e-11)
        else:
            # Near R = 0 (parallel curves) both optima are known only to the LPs' feasibility
            # tolerance (1e-10 here): they differed by 4e-11 at R = 1.4e-8 on one CPU.
            self.assertAlmostEqual(r["R"], R, delta=1e-9 * R + LP_TOLERANCE)
        # ParaFab's normalized complex satisfies the same rows: min ⟨κB, h⟩ = 1 and the
        # twist objective within the second stage's slack of the optimum.
        c, cb = np.array(r["lp"]["c"]), np.array(r["lp"]["c_bar"])
        h = np.cross(c, np.array(r["points"])) + cb
        self.assertAlmostEqual(np.min(np.sum(wn * h, axis=1)), 1.0, delta=1e-9)
        obj = np.max(np.abs(np.sum(T * h, axis=1)))
        if w_reg > 0:
            obj = max(obj, w_reg * np.max(np.abs(np.sum(N * h, axis=1))))
        self.assertAlmostEqual(obj / r["length"], r["R"], delta=1e-9 * max(R, 1e-3))
        print("\n[lp] %s w_reg %g stage 2 %d: ParaFab R %.12g, HiGHS R %.12g, rel. diff %.1e (%d samples)"
              % (request.get("name", "helix"), w_reg, second_stage, r["R"], R, r["R"] / R - 1, len(r["s"])),
              file=sys.stderr)
        return r, R

    def test_sculpture_segments_match_highs(self):
        for k in range(3):
            for w_reg in (0.0, 1.0):
                for second_stage in (False, True):
                    with self.subTest(segment=k, w_reg=w_reg, second_stage=second_stage):
                        r, R = self.check(sample("sculpture_segment_%d" % k), w_reg, second_stage)
                        self.assertGreater(R, 0.01)

    def test_plane_arc_and_helix_are_parallel_for_highs(self):
        _, R = self.check(sample("plane_arc"), 0.0)
        self.assertLess(R, 1e-6)
        _, R = self.check({"curve": {"points": helix_points()}}, 0.0)
        self.assertLess(R, 1e-6)

    def test_infeasible_curve_is_infeasible_for_highs(self):
        r = parafab.design_rod(sample("infeasible_fourier"))
        self.assertFalse(r["feasible"])
        self.assertEqual(r["status"], "infeasible")
        self.assertIn("binding samples at s =", r["reason"])
        self.assertTrue(2 <= len(r["where"]["s"]) <= 7)
        res = scipy_line_complex_lp(r)
        self.assertEqual(res.status, 2, res.message)  # infeasible
        # The binding samples alone are infeasible for HiGHS too.
        keep = r["lp"]["binding_samples"]
        sub = dict(r, t=[r["t"][i] for i in keep])
        self.assertEqual(scipy_line_complex_lp(sub).status, 2)
        # Dropping any one of them makes the binormal rows feasible (a minimal conflict).
        for j in range(len(keep)):
            sub = dict(r, t=[r["t"][i] for i in keep if i != keep[j]])
            self.assertEqual(scipy_line_complex_lp(sub).status, 0)


class HelixThroughJson(unittest.TestCase):
    def test_zero_twist_and_circular_constant_sections(self):
        r = parafab.design_rod({"curve": {"points": helix_points()}, "max_radius": 0.004, "samples": 300,
                                "section": {"factor": 1.0}})
        self.assertTrue(r["feasible"], r["reason"])
        L = r["length"]
        twist = np.array(r["twist"])
        a, b = np.array(r["section"]["a"]), np.array(r["section"]["b"])
        print("\n[helix] max|twist|·L %.2e rad, |beta_end| %.2e rad, a/b - 1 max %.2e, a spread %.2e"
              % (np.max(np.abs(twist)) * L, abs(r["beta"][-1]), np.max(a / b - 1), np.ptp(a) / a.mean()),
              file=sys.stderr)
        self.assertLess(np.max(np.abs(twist)) * L, 1e-4)
        self.assertLess(abs(r["beta"][-1]), 1e-4)
        np.testing.assert_allclose(a / b, 1.0, atol=1e-4)            # circular (t = t*)
        # Constant along the helix up to the interpolant's curvature error near the free ends.
        self.assertLess(np.ptp(a) / a.mean(), 1e-3)
        self.assertAlmostEqual(a.max(), 0.004, delta=1e-9)            # max_radius = √(ab)
        np.testing.assert_allclose(r["section"]["area"], math.pi * a * b, rtol=1e-12)
        np.testing.assert_allclose(r["section"]["J"], math.pi * a**3 * b**3 / (a**2 + b**2), rtol=1e-9)
        # End frames: orthonormal (n1, n2, T), at the curve ends.
        for end, i in zip(r["end_frames"], (0, -1)):
            F = np.array([end["n1"], end["n2"], end["tangent"]])
            np.testing.assert_allclose(F @ F.T, np.eye(3), atol=1e-12)
            self.assertAlmostEqual(np.linalg.det(F), 1.0, delta=1e-12)
            np.testing.assert_allclose(end["position"], r["points"][i], atol=0)

    def test_default_section_factor_is_stable_and_the_most_circular_is_not(self):
        """Stability verdict (Hessian inertia of the discrete rod) against the forward
        simulation, which leaves an unstable equilibrium: the default design of the helix
        (section factor 4) is stable and reproduced, the most circular one (1) is not."""
        for factor in (None, 1.0):
            req = {"curve": {"points": helix_points()}, "max_radius": 0.004, "validate": True}
            if factor is not None:
                req["section"] = {"factor": factor}
            r = parafab.design_rod(req)
            st, sim = r["stability"], r["simulation"]
            print("\n[rod stability] factor %s: stable %s, %d negative, deviation/L %.2e"
                  % (r["section"]["factor"], st["stable"], st["negative"], sim["deviation"]), file=sys.stderr)
            self.assertEqual(st["method"], "hessian_at_equilibrium")
            self.assertEqual(st["zero"], 0)
            at_target = parafab.design_rod(dict(req, stability_at="target"))["stability"]
            self.assertEqual(at_target["method"], "hessian")
            if factor is None:
                self.assertEqual(r["section"]["factor"], 4.0)
                self.assertTrue(st["stable"])
                self.assertTrue(at_target["stable"])
                self.assertEqual(st["negative"], 0)
                self.assertLess(st["equilibrium_distance"], 1e-4)
                self.assertLess(sim["deviation"], 1e-4)
            else:
                self.assertFalse(st["stable"])
                self.assertFalse(at_target["stable"])
                self.assertGreater(at_target["negative"], 0)
                self.assertGreater(st["equilibrium_distance"], 0.01)  # the rod leaves the target
                self.assertIn("leaves the target", st["message"])
                self.assertEqual(st["verdict"], "unstable")
                self.assertTrue(st["moved_away"])
                self.assertGreater(sim["deviation"], 0.01)
        with self.assertRaises(parafab.Error) as cm:
            parafab.design_rod({"curve": {"points": helix_points()}, "stability_at": "middle"})
        self.assertIn("stability_at", str(cm.exception))
        r = parafab.design_rod({"curve": {"points": helix_points()}, "stability": False})
        self.assertIsNone(r["stability"])

    def test_coarse_rod_that_moved_away_gets_its_inertia(self):
        """sculpture_segment_0 with stability_edges 50: the coarse rod's equilibrium lies
        1.30e-3 L from the target (beyond max_distance 1e-3). Before the fix the verdict was
        "unstable" ("leaves the target") with no Hessian computed (negative 0, min_relative
        null); now the inertia at the reached equilibrium is computed (positive definite),
        the verdict is "moved_away", and the Hessian at the target agrees it is stable."""
        req = sample("sculpture_segment_0")
        req["stability_edges"] = 50
        st = parafab.design_rod(req)["stability"]
        self.assertEqual(st["method"], "hessian_at_equilibrium")
        self.assertEqual(st["verdict"], "moved_away")
        self.assertTrue(st["moved_away"])
        self.assertTrue(st["equilibrium_stable"])
        self.assertFalse(st["stable"])  # the design is not reproduced within 1e-3 L
        self.assertEqual((st["negative"], st["zero"]), (0, 0))
        self.assertGreater(st["min_relative"], 0)  # measured 3.58e-8
        self.assertAlmostEqual(st["equilibrium_distance"], 1.304e-3, delta=2e-6)  # measured 1.3043e-3
        self.assertIn("moved away", st["message"])
        # Independent verdicts: the Hessian at the target at the same 50 edges, and the
        # equilibrium verdict at the default 100 edges (distance 6.06e-4 < 1e-3).
        self.assertTrue(parafab.design_rod(dict(req, stability_at="target"))["stability"]["stable"])
        del req["stability_edges"]
        fine = parafab.design_rod(req)["stability"]
        self.assertEqual(fine["verdict"], "stable")
        self.assertFalse(fine["moved_away"])
        self.assertLess(fine["equilibrium_distance"], 1e-3)

    def test_section_factor_elongates_along_bending_axis(self):
        r = parafab.design_rod({"curve": {"points": helix_points()}, "section": {"factor": 4.0}})
        a, b = np.array(r["section"]["a"]), np.array(r["section"]["b"])
        self.assertTrue(np.all(a / b > 1.5))
        self.assertLess(np.max(np.abs(r["twist"])) * r["length"], 1e-4)

    def test_rational_bspline_circle_arc(self):
        # Quarter circle r = 0.2 m in z = 0.5 as FreeCAD gives it (rational quadratic).
        w = math.sqrt(0.5)
        req = {"curve": {"bspline": {"degree": 2, "knots": [0, 0, 0, 1, 1, 1],
                                     "poles": [[0.2, 0, 0.5], [0.2, 0.2, 0.5], [0, 0.2, 0.5]],
                                     "weights": [1, w, 1]}}}
        r = parafab.design_rod(req)
        self.assertTrue(r["feasible"], r["reason"])
        self.assertAlmostEqual(r["length"], math.pi * 0.1, delta=1e-12)
        np.testing.assert_allclose(r["curvature"], 5.0, rtol=1e-9)
        self.assertLess(r["R"], 1e-7)
        self.assertEqual(r["bspline"]["weights"], [1, w, 1])


# Deviation / L of the forward simulation per validated sample, measured 2026-11-28 (helix
# 1.32e-5, plane_arc 5.95e-5, sculpture_segment_0 6.06e-4, _1 2.71e-4, _2 2.83e-4): bounds at
# about 1.5-2x the measured figure (before: 1e-3 for all, up to 76x the measured figure).
VALIDATED_DEVIATION = {"helix": 2.5e-5, "plane_arc": 1.2e-4, "sculpture_segment_0": 9e-4,
                       "sculpture_segment_1": 5e-4, "sculpture_segment_2": 5e-4}


class ValidateBySimulation(unittest.TestCase):
    def test_samples_are_reproduced_by_the_forward_simulation(self):
        for path in sorted(glob.glob(os.path.join(SAMPLES, "*.json"))):
            req = json.load(open(path))
            if not req.get("validate"):
                continue
            name = os.path.basename(path)[:-5]
            with self.subTest(name):
                r = parafab.design_rod(req)
                self.assertTrue(r["feasible"], r["reason"])
                sim = r["simulation"]
                print("\n[validate] %-20s deviation/L %.2e (%.3f mm), %d Newton iterations, load iterations %d"
                      % (name, sim["deviation"], sim["max_distance"] * 1e3, sim["iterations"],
                         r["load_iterations"]["iterations"]), file=sys.stderr)
                self.assertTrue(sim["converged"], sim["message"])
                self.assertIn(name, VALIDATED_DEVIATION, "a new validated sample: measure its deviation")
                self.assertLessEqual(sim["deviation"], VALIDATED_DEVIATION[name])
                if req.get("loads", {}).get("dead_load"):
                    hist = r["load_iterations"]["history"]
                    self.assertLess(hist[-1], 1e-10)
                    self.assertGreater(r["load_iterations"]["iterations"], 1)

    def test_design_without_dead_load_sags(self):
        req = sample("sculpture_segment_1")
        req["loads"] = {"dead_load": False}
        r = parafab.design_rod(req)
        # Simulated with the same (empty) loads it is reproduced; the contrast case (design
        # without, simulation with gravity) is in the C++ suite.
        self.assertLess(r["simulation"]["deviation"], 4e-4)  # measured 2.50e-4 (2026-11-28)
        self.assertEqual(r["load_iterations"]["iterations"], 0)


def run_cli(payload=None, raw=None, args=()):
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "in.json")
        if payload is not None or raw is not None:
            with open(path, "w") as f:
                f.write(raw if raw is not None else json.dumps(payload))
        p = subprocess.run([CLI, "rod", path, *args], capture_output=True, text=True, timeout=120)
        return p.returncode, p.stdout


HELIX = {"curve": {"points": helix_points(40)}}


def with_(**changes):
    r = json.loads(json.dumps(HELIX))
    r.update(changes)
    return r


class BadInput(unittest.TestCase):
    CASES = [
        ("missing curve", {"material": {"E": 1e6}}, "missing request.curve"),
        ("curve without data", {"curve": {}}, "curve must hold either \"bspline\""),
        ("2D points", {"curve": {"points": [[0, 0], [1, 1], [2, 0]]}}, "curve.points[0] must be a triple [x, y, z]"),
        ("one point", {"curve": {"points": [[0, 0, 0]]}}, "curve.points: need at least 2 points"),
        ("null coordinate", {"curve": {"points": [[0, 0, 0], [1, None, 0], [2, 0, 1]]}},
         "curve.points[1][1] is not a finite number"),
        ("repeated point", {"curve": {"points": [[0, 0, 0], [1, 1, 0], [1, 1, 0], [2, 0, 1]]}},
         "curve.points[2] repeats curve.points[1]"),
        ("degree", {"curve": {"points": helix_points(40), "degree": 9}}, "curve.degree must be an integer 1..7, got 9"),
        ("bad knots", {"curve": {"bspline": {"degree": 3, "knots": [0, 1],
                                             "poles": [[0, 0, 0], [1, 1, 0], [2, 0, 1], [3, 1, 1]]}}},
         "curve.bspline.knots: expected 8 knots"),
        ("missing poles", {"curve": {"bspline": {"degree": 3, "knots": [0, 1]}}}, "missing curve.bspline.poles"),
        ("negative weight", {"curve": {"bspline": {"degree": 1, "knots": [0, 0, 1, 1], "poles": [[0, 0, 0], [1, 0, 0]],
                                                   "weights": [1, -2]}}}, "curve.bspline.weights[1] must be positive"),
        ("negative E", with_(material={"E": -1}), "material.E must be > 0, got -1"),
        ("nu", with_(material={"nu": 0.7}), "material.nu must be in (-1, 0.5], got 0.7"),
        ("density string", with_(material={"density": "heavy"}), "material.density must be a number, got \"heavy\""),
        ("preset", with_(material={"preset": "steel"}), "material.preset must be \"SmoothSil 960\""),
        ("zero radius", with_(max_radius=0), "max_radius must be > 0, got 0"),
        ("negative w_reg", with_(w_reg=-1), "w_reg must be >= 0, got -1"),
        ("section factor", with_(section={"factor": 0}), "section.factor must be > 0, got 0"),
        ("samples", with_(samples=2), "samples must be an integer 3..100000, got 2"),
        ("samples float", with_(samples=10.5), "samples must be an integer"),
        ("gravity", with_(loads={"dead_load": True, "gravity": [0, -9.81]}), "loads.gravity must be [x, y, z] (three numbers), got [0,-9.81]"),
        ("dead_load", with_(loads={"dead_load": "yes"}), "loads.dead_load must be true or false"),
        ("point load s", with_(loads={"point_loads": [{"s": 5.0, "force": [0, 0, -1]}]}),
         "loads.point_loads[0].s must be in [0, length"),
        ("point load force", with_(loads={"point_loads": [{"s": 0.1}]}), "missing loads.point_loads[0].force"),
        ("validate", with_(validate=1), "validate must be true or false"),
        ("kappa = 0 (straight line)", {"curve": {"points": [[0, 0, 0], [1, 1, 1], [2, 2, 2], [3, 3, 3]]}},
         "curve: curvature vanishes at arc length s ="),
    ]

    def test_cli_exits_2_with_json_error(self):
        for name, payload, expected in self.CASES:
            with self.subTest(name):
                code, out = run_cli(payload)
                self.assertEqual(code, 2, out)
                err = json.loads(out)["error"]
                self.assertIn(expected, err["message"])
                self.assertEqual(err["kind"], "invalid_input")

    def test_module_raises_parafab_error(self):
        for name, payload, expected in self.CASES:
            with self.subTest(name):
                with self.assertRaises(parafab.Error) as ctx:
                    parafab.design_rod(payload)
                self.assertIn(expected, str(ctx.exception))
                self.assertIsInstance(ctx.exception, ValueError)

    def test_kappa_zero_error_names_the_inflection(self):
        path = os.path.join(SAMPLES, "invalid", "kappa_zero.json")
        p = subprocess.run([CLI, "rod", path], capture_output=True, text=True, timeout=60)
        self.assertEqual(p.returncode, 2, p.stdout)
        msg = json.loads(p.stdout)["error"]["message"]
        s = float(re.search(r"arc length s = ([0-9.e+-]+) m", msg).group(1))
        # The S-curve 0.2 (x, x³ − x) is point-symmetric: the inflection is at half its length.
        req = json.load(open(path))
        pts = np.array(req["curve"]["points"])
        half = 0.5 * np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1))
        print("\n[kappa = 0] %s (half chord length %.6f m)" % (msg, half), file=sys.stderr)
        self.assertAlmostEqual(s, half, delta=1e-3 * half)
        with self.assertRaises(parafab.Error):
            parafab.design_rod(req)

    def test_cli_rejects_nan_empty_and_missing_files(self):
        for name, raw, expected in [("NaN literal", '{"curve": {"points": [[0, 0, 0], [1, NaN, 0]]}}', "not valid JSON"),
                                    ("empty file", "", "is empty")]:
            with self.subTest(name):
                code, out = run_cli(raw=raw)
                self.assertEqual(code, 2)
                self.assertIn(expected, json.loads(out)["error"]["message"])
        code, out = run_cli()
        self.assertEqual(code, 2)
        self.assertIn("cannot open input file", json.loads(out)["error"]["message"])
        with self.assertRaises(parafab.Error) as ctx:
            parafab.design_rod({"curve": {"points": [[0, 0, 0], [1, float("nan"), 0], [2, 0, 1]]}})
        self.assertIn("NaN", str(ctx.exception))

    def test_infeasible_is_a_result_not_an_error(self):
        code, out = run_cli(sample("infeasible_fourier"))
        self.assertEqual(code, 0)
        r = json.loads(out)
        self.assertFalse(r["feasible"])
        self.assertIsNone(r["R"])

    def test_cli_and_module_give_the_same_result(self):
        payload = sample("sculpture_segment_2")
        with tempfile.TemporaryDirectory() as d:
            out = os.path.join(d, "out.json")
            code, _ = run_cli(payload, args=("-o", out))
            self.assertEqual(code, 0)
            with open(out) as f:
                cli = json.load(f)
        mod = parafab.design_rod(payload)
        for key in ("R", "c", "c_bar", "twist", "section", "end_frames"):
            self.assertEqual(cli[key], mod[key], key)
        self.assertEqual(cli["simulation"]["deviation"], mod["simulation"]["deviation"])


if __name__ == "__main__":
    unittest.main()
