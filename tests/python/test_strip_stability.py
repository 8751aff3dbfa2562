"""Strip stability entry points (thesis §4.5): `parafab.strip_stability` and
`parafab strip-stability` against an independent reference.

* Reference: the constrained eigenvalue test rebuilt in numpy/scipy -- the discrete bending
  energy of §4.6.1 at the target curve (elastica integrated by scipy's solve_ivp, 400 equal
  edges), the designed K interpolated at the nodes, λ from the returned line (λ = R b), the
  Hessian projected onto the null space of the end-point constraints (scipy.linalg.null_space)
  and its smallest eigenvalue. Inflectional elastica (K ≡ 1) with 2 inflections are stable,
  with 3 unstable.
* Bad input: the CLI exits non-zero with a JSON error naming the field; the module raises.
"""
import json
import math
import os
import subprocess
import sys
import tempfile
import unittest

import numpy as np
from scipy.integrate import solve_ivp
from scipy.linalg import null_space

sys.path.insert(0, os.environ.get("PARAFAB_MODULE_DIR", "build/workbench/entry"))
import parafab  # noqa: E402

CLI = os.environ.get("PARAFAB_CLI", "build/workbench/entry/parafab")


def elastica(half, amplitude=0.5, P=100.0):
    """κ' = -P sin α from α(0) = 0, κ(0) = 2√P sin(amplitude/2), cut at the half-th zero of α.
    Returns a function s -> (x, y) (dense output) and the length."""
    k0 = 2 * math.sqrt(P) * math.sin(amplitude / 2)

    def f(s, q):
        return [math.cos(q[2]), math.sin(q[2]), q[3], -P * math.sin(q[2])]

    def zero(s, q):
        return q[2]
    zero.direction = 0
    sol = solve_ivp(f, (0, 10), [0, 0, 0, k0], events=zero, dense_output=True, rtol=1e-12, atol=1e-12)
    ends = [t for t in sol.t_events[0] if t > 1e-9]
    length = ends[half - 1]
    return (lambda s: sol.sol(s)[:2].T), length


def request(half):
    xy, length = elastica(half)
    pts = xy(np.linspace(0, length, 401)).tolist()
    return {"curve": {"points": pts, "degree": 5}, "material": {"E": 3e9, "thickness": 5e-4},
            "min_width": 0.01}, xy, length


def numpy_min_eigenvalue(result, xy, length, N=400):
    """Smallest eigenvalue of the discrete energy Hessian on the constraint tangent space."""
    h = length / N
    nodes = xy(np.linspace(0, length, N + 1))
    d = np.diff(nodes, axis=0)
    alpha = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    K = np.interp(np.linspace(0, length, N + 1), result["s"], result["K"])
    w = np.full(N + 1, h)
    w[0] = w[-1] = h / 2
    c = K / w
    b = np.array(result["line"]["b"])
    lam = np.array([-b[1], b[0]])
    t = np.c_[np.cos(alpha), np.sin(alpha)]
    H = np.diag(c[:-1] + c[1:] - h * t @ lam) - np.diag(c[1:-1], 1) - np.diag(c[1:-1], -1)
    C = h * np.c_[-np.sin(alpha), np.cos(alpha)].T
    Z = null_space(C)
    return np.linalg.eigvalsh(Z.T @ H @ Z)[0]


class StripStability(unittest.TestCase):
    def test_verdicts_agree_with_numpy_constrained_hessian(self):
        for half, expect_stable in ((2, True), (3, False)):
            req, xy, length = request(half)
            r = parafab.strip_stability(req)
            self.assertTrue(r["feasible"], r["reason"])
            st = r["stability"]
            plain = parafab.design_strip(req)  # K(s) and the line of the same design
            mu = numpy_min_eigenvalue(plain, xy, length)
            print("\n[strip-stability] elastica, %d inflections: %s, sigma %s, eigenvalue test %s, "
                  "numpy min eigenvalue %.4g, Jacobi %.3f ms"
                  % (half, "stable" if st["stable"] else "unstable", st["sigma"], st["eigenvalue"]["stable"], mu,
                     1e3 * st["seconds"]), file=sys.stderr)
            self.assertEqual(st["stable"], expect_stable)
            self.assertEqual(st["stable"], mu > 0)
            self.assertEqual(st["eigenvalue"]["stable"], mu > 0)
            self.assertTrue(st["agree"])
            self.assertEqual(st["method"], "jacobi")
            self.assertEqual(len(st["s"]), len(st["Z"]))
            if expect_stable:
                self.assertIsNone(st["sigma"])
            else:
                self.assertGreater(st["sigma"], 0)
                self.assertLess(st["sigma"], length)
                # Z changes sign at σ.
                s, Z = np.array(st["s"]), np.array(st["Z"])
                self.assertGreater(Z[(s < st["sigma"]) & (s > 0.1 * length)].min(), 0)
                self.assertLess(Z[s > st["sigma"]].min(), 0)
            # design_strip carries the Jacobi verdict too (no eigenvalue test there).
            self.assertEqual(plain["stability"]["stable"], expect_stable)
            self.assertNotIn("eigenvalue", plain["stability"])

    def test_cli_matches_module_and_rejects_bad_input(self):
        req, _, _ = request(3)
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "in.json")
            with open(path, "w") as f:
                json.dump(req, f)
            p = subprocess.run([CLI, "strip-stability", path], capture_output=True, text=True, timeout=120)
            self.assertEqual(p.returncode, 0, p.stdout + p.stderr)
            out = json.loads(p.stdout)
            mod = parafab.strip_stability(req)
            self.assertEqual(out["stability"]["stable"], mod["stability"]["stable"])
            self.assertAlmostEqual(out["stability"]["sigma"], mod["stability"]["sigma"], delta=1e-12)
            bad = dict(req, stability={"edges": 2})
            with open(path, "w") as f:
                json.dump(bad, f)
            p = subprocess.run([CLI, "strip-stability", path], capture_output=True, text=True, timeout=120)
            self.assertEqual(p.returncode, 2)
            err = json.loads(p.stdout)["error"]
            self.assertIn("stability.edges", err["message"])
        with self.assertRaises(parafab.Error) as cm:
            parafab.strip_stability(dict(req, stability={"egdes": 100}))
        self.assertIn("stability.egdes", str(cm.exception))


if __name__ == "__main__":
    unittest.main()
