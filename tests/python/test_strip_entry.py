"""Strip entry points (Python module and CLI) against independent references.

* LP Eq. 4.4 re-solved with scipy's linprog (HiGHS) on exactly the samples ParaFab used:
  R and the line (a, b) must agree to 1e-9.
* Bad input: the CLI exits non-zero with a JSON error naming the field; the module raises
  parafab.Error (a ValueError) with the same message. Never a crash.

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
from scipy.optimize import linprog

sys.path.insert(0, os.environ.get("PARAFAB_MODULE_DIR", "build/workbench/entry"))
import parafab  # noqa: E402

CLI = os.environ.get("PARAFAB_CLI", "build/workbench/entry/parafab")
MATERIAL = {"E": 3e9, "thickness": 5e-4}


def request(points, degree=4, **extra):
    r = {"curve": {"points": points, "degree": degree}, "material": dict(MATERIAL), "min_width": 0.01}
    r.update(extra)
    return r


def scipy_stiffness_lp(result):
    """Eq. 4.4 in the variables (a, b1, b2, R) with HiGHS, rows as in the thesis:
    1 <= (a + <b, g_i>)/k_i <= R at samples, a + <b, p_j> = 0 at inflections, and the
    l'Hôpital limit <b, t_j>/k'_j within [1, R] at each inflection."""
    g = np.array(result["points"], float)
    k = np.array(result["curvature"], float)
    keep = k != 0.0  # zero-curvature points enter through their own rows
    g, k = g[keep], k[keep]
    sg, w = np.sign(k), np.abs(k)
    A_ub = [np.c_[-sg, -sg[:, None] * g, np.zeros(len(k))],          # K >= 1
            np.c_[sg, sg[:, None] * g, -w]]                             # K <= R
    b_ub = [-w, np.zeros(len(k))]
    A_eq, b_eq = [], []
    infl = result["inflections"]
    for z in infl:
        p, t, dk = np.array(z["point"]), np.array(z["tangent"]), z["dkappa_ds"]
        s, wz = math.copysign(1.0, dk), abs(dk)
        A_ub.append([[0, -s * t[0], -s * t[1], 0]]); b_ub.append([-wz])
        A_ub.append([[0, s * t[0], s * t[1], -wz]]); b_ub.append([0.0])
        A_eq.append([1, p[0], p[1], 0]); b_eq.append(0.0)
    if len(infl) > 2:  # ParaFab uses the fitted line through nearly collinear inflections
        raise ValueError("use curves with at most two inflections here")
    res = linprog(c=[0, 0, 0, 1], A_ub=np.vstack(A_ub), b_ub=np.concatenate(b_ub),
                  A_eq=np.array(A_eq) if A_eq else None, b_eq=b_eq or None,
                  bounds=[(None, None)] * 4, method="highs",
                  options={"primal_feasibility_tolerance": 1e-10, "dual_feasibility_tolerance": 1e-10})
    assert res.status == 0, res.message
    return res.x


class StripLpAgainstScipy(unittest.TestCase):
    def check(self, points, n_infl):
        r = parafab.design_strip(request(points))
        self.assertTrue(r["feasible"], r["reason"])
        self.assertEqual(len(r["inflections"]), n_infl)
        a, b1, b2, R = scipy_stiffness_lp(r)
        self.assertAlmostEqual(r["R"], R, delta=1e-9 * R)
        scale = math.hypot(a, math.hypot(b1, b2))
        mine = np.array([r["line"]["a"], *r["line"]["b"]])
        np.testing.assert_allclose(mine / np.linalg.norm(mine), np.array([a, b1, b2]) / scale, atol=1e-8)
        self.assertAlmostEqual(min(r["K"]), 1.0, delta=1e-12)
        self.assertAlmostEqual(max(r["K"]), r["R"], delta=1e-9)
        return r

    def test_elliptic_arc_matches_highs(self):
        t = np.linspace(0.2, 2.7, 120)
        r = self.check(np.c_[0.3 * np.cos(t), 0.15 * np.sin(t)].tolist(), 0)
        self.assertGreater(r["R"], 1.2)

    def test_two_inflections_match_highs(self):
        x = np.linspace(-0.8, 0.8, 200)
        self.check((0.3 * np.c_[x, x**4 - x**2]).tolist(), 2)

    def test_width_and_outline_follow_k(self):
        t = np.linspace(0.2, 2.7, 60)
        r = parafab.design_strip(request(np.c_[0.3 * np.cos(t), 0.15 * np.sin(t)].tolist()))
        np.testing.assert_allclose(r["width"], 0.01 * np.array(r["K"]), rtol=1e-14)
        h = MATERIAL["thickness"]
        np.testing.assert_allclose(r["bending_stiffness"], MATERIAL["E"] * np.array(r["width"]) * h**3 / 12, rtol=1e-14)
        outline = np.array(r["outline"])
        n = len(r["s"])
        self.assertEqual(len(outline), 2 * n)
        np.testing.assert_allclose(outline[:n, 0], r["s"])
        np.testing.assert_allclose(outline[:n, 1], -0.5 * np.array(r["width"]))
        np.testing.assert_allclose(outline[n:, 1], 0.5 * np.array(r["width"])[::-1])
        self.assertAlmostEqual(r["s"][-1], r["length"], delta=1e-15)


def run_cli(payload=None, raw=None, args=()):
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "in.json")
        if payload is not None or raw is not None:
            with open(path, "w") as f:
                f.write(raw if raw is not None else json.dumps(payload))
        p = subprocess.run([CLI, "strip", path, *args], capture_output=True, text=True, timeout=60)
        return p.returncode, p.stdout


class BadInput(unittest.TestCase):
    CASES = [
        ("empty curve", request([]), "curve.points: need at least 2 points"),
        ("one point", request([[0, 0]]), "need at least 2 points"),
        ("null coordinate", request([[0, 0], [1, None], [2, 0]]), "curve.points[1][1] is not a finite number"),
        ("repeated point", request([[0, 0], [1, 1], [1, 1], [2, 0]]), "curve.points[2] repeats curve.points[1]"),
        ("zero thickness", dict(request([[0, 0], [1, 1], [2, 0]]), material={"E": 3e9, "thickness": 0}), "material.thickness must be positive"),
        ("negative thickness", dict(request([[0, 0], [1, 1], [2, 0]]), material={"E": 3e9, "thickness": -1e-3}), "material.thickness must be positive"),
        ("3D points", request([[0, 0, 0], [1, 1, 1], [2, 0, 3]]), "must be a pair [x, y] (a plane curve)"),
        ("missing material", {"curve": {"points": [[0, 0], [1, 1]]}, "min_width": 0.01}, "missing request.material"),
        ("bad knots", {"curve": {"bspline": {"degree": 3, "knots": [0, 1], "poles": [[0, 0], [1, 1], [2, 0], [3, 1]]}},
                       "material": MATERIAL, "min_width": 0.01}, "curve.bspline.knots: expected 8 knots"),
    ]

    def test_cli_exits_nonzero_with_json_error(self):
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
                    parafab.design_strip(payload)
                self.assertIn(expected, str(ctx.exception))
                self.assertIsInstance(ctx.exception, ValueError)

    def test_module_rejects_nan(self):
        with self.assertRaises(parafab.Error) as ctx:
            parafab.design_strip(request([[0, 0], [1, float("nan")], [2, 0]]))
        self.assertIn("NaN", str(ctx.exception))

    def test_cli_rejects_nan_empty_and_missing_files(self):
        for name, raw, expected in [("NaN literal", '{"curve": {"points": [[0, 0], [1, NaN]]}}', "not valid JSON"),
                                    ("empty file", "", "is empty"),
                                    ("truncated", '{"curve": ', "not valid JSON")]:
            with self.subTest(name):
                code, out = run_cli(raw=raw)
                self.assertEqual(code, 2)
                self.assertIn(expected, json.loads(out)["error"]["message"])
        code, out = run_cli()  # file never written
        self.assertEqual(code, 2)
        self.assertIn("cannot open input file", json.loads(out)["error"]["message"])

    def test_cli_and_module_give_the_same_result(self):
        t = np.linspace(0.2, 2.7, 40)
        payload = request(np.c_[0.3 * np.cos(t), 0.15 * np.sin(t)].tolist())
        with tempfile.TemporaryDirectory() as d:
            out = os.path.join(d, "out.json")
            code, _ = run_cli(payload, args=("-o", out))
            self.assertEqual(code, 0)
            with open(out) as f:
                cli = json.load(f)
        mod = parafab.design_strip(payload)
        self.assertEqual(cli["R"], mod["R"])
        self.assertEqual(cli["K"], mod["K"])
        self.assertEqual(cli["outline"], mod["outline"])


if __name__ == "__main__":
    unittest.main()
