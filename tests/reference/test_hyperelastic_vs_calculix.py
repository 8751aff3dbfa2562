#!/usr/bin/python3
"""Hyperelastic XFEM (parafab) vs. CalculiX: clamped rubber block in compression.

Run:  /usr/bin/python3 tests/reference/test_hyperelastic_vs_calculix.py [-v]
Needs the built parafab python module (build/workbench/entry) and `gmsh` + `ccx`
on PATH; skipped otherwise. About 46 s of CPU (210 s wall on the loaded shared machine, 2026-11-23),
plus ~30 s for TurnedBlockAtTwelveCellsTest (no CalculiX; most of it a Newton run that fails)
and ~5 s for the turned block at 12 cells with the local Nitsche penalty.

Block 20 x 20 x 20 mm, silicone-like E = 2.3 MPa, nu = 0.45. Face z = 0 fully
fixed, face z = 20 gets the prescribed displacement (0, 0, -4) with x and y
held (20 % compression, clamped so the sides barrel). Quantity compared:
the lateral bulge u_x at (20, 10, 10) (mid-height, centre of the face x = 20)
and at (20, 20, 10) (mid-height on the vertical edge).

  parafab:  "neo_hooke_isochoric" (= CalculiX *HYPERELASTIC, NEO HOOKE with
            C10 = G/2, D1 = 2/K), 4 load steps, grids of 8 and 12 cells.
  CalculiX: Gmsh C3D10, size 4 and 2.5 mm, NLGEOM, probes interpolated in the
            tet10 of the reference (undeformed) mesh.

Measured (2 threads):                        u_x(20,10,10)  u_x(20,20,10)
  parafab neo-Hooke   cells  8 / 12 / 16     1.3593/1.3577/1.3538  1.1851/1.1821/1.1792
  CalculiX neo-Hooke  h 4 / 2.5 / 1.6 mm     1.3618/1.3525/1.3418  1.1939/1.1850/1.1722
  parafab linear      cells  8 / 12          1.1299/1.1212         1.0226/1.0141
  CalculiX linear     h 4 / 2.5 / 1.6 mm     1.1226/1.1171/1.1127  1.0169/1.0114/1.0061
  parafab turned 21° about (1, 0.6, 0.3), grid shifted, 8 cells (254 cut cells):
    neo-Hooke 1.3520 / 1.1707, linear 1.1315 / 1.0239: within 0.04-1.3 % of
    CalculiX h = 2.5 (TURN_TOL = 1.5 %). At 12 cells Newton does not converge on
    the turned block: Nitsche beta = 100 is not coercive on some cut cells there (the
    linear run reports an indefinite stiffness, solved by LU), so the neo-Hooke energy is not
    convex near them (resources/doc/simulation.md, "Hyperelastic laws, Nitsche β and the local penalty"; beta = 1000 converges but locks the clamp).
    With "nitsche_penalty": "local" (each clamped cut cell's penalty from its flux eigenvalue)
    the turned block at 12 cells converges in 12 Newton iterations: neo-Hooke 1.3585 / 1.1964,
    linear 1.1273 / 1.0233, within 0.4-1.2 % of CalculiX h = 2.5 (TURN_TOL).
(cells 16 and h 1.6 are too slow for this test and only quoted here.)

Tolerance: both discretisations are still drifting down by ~0.3-0.8 % per
refinement level (the clamped, nearly incompressible edges are singular;
CalculiX moves more per level than parafab), so the codes differ by 0.2-0.5 %
at the test resolutions and by ~1 % at the finest pair above. TOL = 2 % covers
that discretisation error but still catches a wrong material law: the
neo-Hooke bulge is 21 % (mid-face) / 17 % (edge) larger than the linear one
in both codes (ratios 1.211/1.166 parafab, 1.211/1.172 CalculiX), far
outside TOL. The Newton iteration (3 iterations per load step,
residual ~1e-7) and CalculiX's convergence tolerance (tightened to 1e-7 via
*CONTROLS: identical .dat displacements) do not contribute; parafab's answer
does not depend on the number of load steps (1, 4, 8 give the same digits),
and Nitsche beta = 1000 moves it by < 0.2 %.
"""

import math
import os
import shutil
import sys
import tempfile
import time
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(ROOT, "build", "workbench", "entry"))
import calculix_reference as cr  # noqa: E402
import numpy as np  # noqa: E402

try:
    import parafab  # noqa: E402
except ImportError:  # not built
    parafab = None

HAVE_TOOLS = bool(shutil.which("gmsh") and shutil.which("ccx"))

SIDE, E, NU, DZ = 20.0, 2.3, 0.45, -4.0
PROBES = [[SIDE, SIDE / 2, SIDE / 2],      # mid-face bulge
          [SIDE, SIDE, SIDE / 2]]          # edge bulge
PF_CELLS = (8, 12)
CCX_SIZES = (4.0, 2.5)
TOL = 0.02            # relative, see docstring
TURN_TOL = 0.015      # turned block against CalculiX h = 2.5 (measured: see docstring)
MIN_NONLINEAR = 0.10  # neo-Hooke bulge at least 10 % above linear


# The turned variant: the block turned TURN_DEG about a skew axis through its centre and the
# grid shifted, so that every face cuts cells; prescribed displacement and probes turned with it,
# the bulge read along the turned x axis.
TURN_AXIS, TURN_DEG = (1.0, 0.6, 0.3), 21.0
TURN_CELLS = 8   # at 12 cells Newton does not converge on the turned block (beta = 100 not coercive there)
TURN_ORIGIN = [0.37, 0.61, 0.13]   # grid planes through these points (mm)


def rotation(axis, degrees):
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    a = math.radians(degrees)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(a) * K + (1 - math.cos(a)) * K @ K


def parafab_job(cells, model, turned=False):
    R = rotation(TURN_AXIS, TURN_DEG if turned else 0.0)
    c = np.full(3, SIDE / 2)
    turn = lambda p: (c + R @ (np.asarray(p, float) - c)).tolist()  # noqa: E731
    job = {
        "material": {"E": E, "nu": NU, "density": 1.1e-9, "model": model},
        # hex8: the figures above are its; hex27 Newton on these grids would not fit the CI budget.
        "element": "hex8",
        "grid": {"cells": cells},
        "supports": [{"point": turn([SIDE / 2, SIDE / 2, 0.0])},
                     {"point": turn([SIDE / 2, SIDE / 2, SIDE]),
                      "displacement": (R @ [0.0, 0.0, DZ]).tolist()}],
        "loads": [],
        "load_steps": 4,
        "probes": [turn(p) for p in PROBES],
    }
    if turned:
        job["rotate"] = {"axis": list(TURN_AXIS), "center": c.tolist(), "degrees": TURN_DEG}
        job["grid"]["origin"] = TURN_ORIGIN
    return job


def local(u, turned):
    """Displacement in the block's own axes."""
    return (rotation(TURN_AXIS, TURN_DEG if turned else 0.0).T @ np.asarray(u)).tolist()


def ccx_job(step, size, model):
    return {
        "step": step,
        "mesh": {"size": size, "element": "C3D10"},
        "material": {"model": model, "E": E, "nu": NU},
        "boundary_conditions": [
            {"name": "bottom", "type": "fixed",
             "select": {"plane": {"axis": "z", "value": 0.0}}},
            {"name": "top", "type": "displacement", "value": [0.0, 0.0, DZ],
             "select": {"plane": {"axis": "z", "value": SIDE}}},
        ],
        "probes": PROBES,
        "solver": {"threads": 2},
    }


def rel(a, b):
    return abs(a - b) / abs(b)


@unittest.skipUnless(HAVE_TOOLS, "gmsh and/or ccx not installed")
@unittest.skipUnless(parafab is not None, "parafab module not built")
class ClampedRubberBlockTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="hyper_vs_ccx_")
        cls.step = cr.make_box_step(os.path.join(cls.tmp, "block.step"),
                                    (SIDE, SIDE, SIDE))
        cls.pf, cls.ccx, cls.newton = {}, {}, {}
        cls.turned, cls.turned_cut_cells = {}, {}
        cls.turned_local, cls.turned_local_run = {}, {}
        cls.seconds = {}
        for model, ccx_model in (("neo_hooke_isochoric", "neo_hooke"),
                                 ("linear", "linear")):
            for n in PF_CELLS:
                t0 = time.time()
                r = parafab.simulate(cls.step, parafab_job(n, model))
                cls.seconds[("pf", model, n)] = time.time() - t0
                cls.pf[model, n] = [p["displacement"] for p in r["probes"]]
                cls.newton[model, n] = r.get("newton")
            t0 = time.time()
            r = parafab.simulate(cls.step, parafab_job(TURN_CELLS, model, turned=True))
            cls.seconds[("pf", model, "turned")] = time.time() - t0
            cls.turned[model] = [local(p["displacement"], True) for p in r["probes"]]
            cls.turned_cut_cells[model] = r["grid"]["cut_cells"]
            # 12 cells turned, where the fixed beta fails (TurnedBlockAtTwelveCellsTest), with
            # the penalty from each clamped cut cell's eigenvalue.
            job = parafab_job(12, model, turned=True)
            job["nitsche_penalty"] = "local"
            t0 = time.time()
            r = parafab.simulate(cls.step, job)
            cls.seconds[("pf", model, "turned local")] = time.time() - t0
            cls.turned_local[model] = [local(p["displacement"], True) for p in r["probes"]]
            cls.turned_local_run[model] = r
            for h in CCX_SIZES:
                r = cr.run_job(ccx_job(cls.step, h, ccx_model))
                if r.get("status") != "ok":
                    raise RuntimeError("CalculiX failed: %s" % r)
                cls.seconds[("ccx", model, h)] = r["total_seconds"]
                cls.ccx[model, h] = r["displacement_at"]
        cls.print_table()

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    @classmethod
    def print_table(cls):
        print("\n  clamped rubber block, 20 % compression: u_x [mm] at"
              " (20,10,10) / (20,20,10)")
        for model in ("neo_hooke_isochoric", "linear"):
            for n in PF_CELLS:
                u = cls.pf[model, n]
                print("  parafab  %-20s cells %4d : %.4f  %.4f   (%.1f s)"
                      % (model, n, u[0][0], u[1][0],
                         cls.seconds[("pf", model, n)]))
            u = cls.turned[model]
            print("  parafab  %-20s turned %4d: %.4f  %.4f   (%.1f s, %d cut cells)"
                  % (model, TURN_CELLS, u[0][0], u[1][0],
                     cls.seconds[("pf", model, "turned")], cls.turned_cut_cells[model]))
            u = cls.turned_local[model]
            print("  parafab  %-20s turned   12: %.4f  %.4f   (%.1f s, local Nitsche penalty)"
                  % (model, u[0][0], u[1][0], cls.seconds[("pf", model, "turned local")]))
            for h in CCX_SIZES:
                p = cls.ccx[model, h]
                print("  calculix %-20s h %7.1f : %.4f  %.4f   (%.1f s)"
                      % ("neo_hooke" if model != "linear" else model, h,
                         p[0]["u"][0], p[1]["u"][0],
                         cls.seconds[("ccx", model, h)]))

    # ------------------------------------------------------------------
    def test_probes_interpolated(self):
        for key, probes in self.ccx.items():
            for p in probes:
                self.assertEqual(p["method"], "interpolated", key)

    def test_newton_converges(self):
        for n in PF_CELLS:
            nw = self.newton["neo_hooke_isochoric", n]
            self.assertIsNotNone(nw)
            self.assertEqual(nw["load_steps"], 4)
            self.assertLessEqual(nw["iterations"], 4 * 6)
            res = nw["residuals"]
            self.assertLess(res[-1], 1e-5 * max(res))

    def test_symmetry_and_midplane(self):
        # the problem is symmetric about z = 10 (also for finite strain):
        # u_z(z = 10) = DZ / 2; the edge probe is on the diagonal: u_x = u_y
        for key, u in self.pf.items():
            self.assertAlmostEqual(u[0][2], DZ / 2, delta=1e-3, msg=key)
            self.assertAlmostEqual(u[1][0], u[1][1], delta=1e-3, msg=key)
        for key, p in self.ccx.items():
            self.assertAlmostEqual(p[0]["u"][2], DZ / 2, delta=0.02, msg=key)

    def test_bulge_grid_converged(self):
        # parafab itself: refinement 8 -> 12 cells changes the bulge < 1 %
        for model in ("neo_hooke_isochoric", "linear"):
            a, b = self.pf[model, PF_CELLS[0]], self.pf[model, PF_CELLS[1]]
            for i in range(2):
                self.assertLess(rel(a[i][0], b[i][0]), 0.01, (model, i))

    def _compare(self, model):
        for n, h in zip(PF_CELLS, CCX_SIZES):
            for i in range(2):
                upf = self.pf[model, n][i][0]
                uccx = self.ccx[model, h][i]["u"][0]
                self.assertGreater(upf, 0.0)
                self.assertLess(rel(upf, uccx), TOL,
                                "%s probe %s: parafab(%d) %.4f vs ccx(%.1f)"
                                " %.4f" % (model, PROBES[i], n, upf, h, uccx))

    def test_turned_block_cuts_cells_and_matches_calculix(self):
        # turned in the grid: the same bulge as CalculiX on the block (which does not turn)
        h = CCX_SIZES[-1]
        for model in ("neo_hooke_isochoric", "linear"):
            self.assertGreater(self.turned_cut_cells[model], 0)
            for i in range(2):
                upf, uccx = self.turned[model][i][0], self.ccx[model, h][i]["u"][0]
                self.assertLess(rel(upf, uccx), TURN_TOL,
                                "%s turned, probe %s: parafab(%d) %.4f vs ccx(%.1f) %.4f"
                                % (model, PROBES[i], TURN_CELLS, upf, h, uccx))

    def test_local_penalty_converges_on_the_turned_block_at_12_cells(self):
        # Where the fixed beta = 100 is not coercive (TurnedBlockAtTwelveCellsTest): with the
        # local penalty the linear matrix is positive definite, Newton converges, and both
        # models match CalculiX h = 2.5 within TURN_TOL (measured: see the docstring).
        self.assertNotIn("not positive definite", self.turned_local_run["linear"]["message"] or "")
        nw = self.turned_local_run["neo_hooke_isochoric"]["newton"]
        self.assertLessEqual(nw["iterations"], 4 * 4)  # measured 12
        h = CCX_SIZES[-1]
        for model in ("neo_hooke_isochoric", "linear"):
            for i in range(2):
                upf, uccx = self.turned_local[model][i][0], self.ccx[model, h][i]["u"][0]
                self.assertLess(rel(upf, uccx), TURN_TOL,
                                "%s turned local, probe %s: parafab(12) %.4f vs ccx(%.1f) %.4f"
                                % (model, PROBES[i], upf, h, uccx))

    def test_neo_hooke_bulge_matches_calculix(self):
        self._compare("neo_hooke_isochoric")

    def test_linear_bulge_matches_calculix(self):
        self._compare("linear")

    def test_nonlinear_effect_visible(self):
        n, h = PF_CELLS[-1], CCX_SIZES[-1]
        for i in range(2):
            r_pf = (self.pf["neo_hooke_isochoric", n][i][0]
                    / self.pf["linear", n][i][0])
            r_ccx = (self.ccx["neo_hooke_isochoric", h][i]["u"][0]
                     / self.ccx["linear", h][i]["u"][0])
            print("  probe %s: neo-Hooke / linear bulge = %.3f (parafab),"
                  " %.3f (calculix)" % (PROBES[i], r_pf, r_ccx))
            self.assertGreater(r_pf, 1.0 + MIN_NONLINEAR)
            self.assertGreater(r_ccx, 1.0 + MIN_NONLINEAR)
            # and parafab reproduces CalculiX's nonlinear amplification
            self.assertLess(rel(r_pf, r_ccx), TOL)


@unittest.skipUnless(parafab is not None, "parafab module not built")
class TurnedBlockAtTwelveCellsTest(unittest.TestCase):
    """Where the hyperelastic path fails, and why (resources/doc/simulation.md, "Hyperelastic laws"): on the turned block
    at 12 cells Nitsche's default beta = 100 is not coercive on some cut cells of the clamped
    faces. The linear solve says so and still gives the aligned grid's bulge (LU); neo-Hooke does
    not converge and says so; beta = 1000 makes the matrix positive definite and neo-Hooke
    converge, but locks the clamp (the linear bulge grows by ~1.9 %). The cure, the local
    penalty, is checked against CalculiX in ClampedRubberBlockTest."""

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="hyper_turned12_")
        cls.step = cr.make_box_step(os.path.join(cls.tmp, "block.step"), (SIDE, SIDE, SIDE))

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def run_job(self, model, beta, load_steps=4):
        job = parafab_job(12, model, turned=True)
        job["nitsche_beta"] = beta
        job["load_steps"] = load_steps
        return parafab.simulate(self.step, job)

    def test_default_beta_is_not_coercive_there_and_neo_hooke_says_it_did_not_converge(self):
        lin = self.run_job("linear", 100)
        self.assertIn("not positive definite", lin["message"])
        self.assertIn('"nitsche_penalty": "local"', lin["message"])  # the message names the cure
        bulge = local(lin["probes"][0]["displacement"], True)[0]
        self.assertAlmostEqual(bulge, 1.1212, delta=0.002)  # the aligned 12-cell grid's (docstring)
        # Two load steps: the line search fails in the first (19 s; with four, 50 Newton
        # iterations at load step 3 take 46 s and end the same way).
        with self.assertRaises(parafab.Error) as e:
            self.run_job("neo_hooke_isochoric", 100, load_steps=2)
        self.assertIn("did not converge", str(e.exception))
        self.assertIn('"nitsche_penalty": "local"', str(e.exception))

    def test_beta_1000_converges_but_locks_the_clamp(self):
        lin = self.run_job("linear", 1000)
        self.assertNotIn("not positive definite", lin["message"] or "")
        bulge = local(lin["probes"][0]["displacement"], True)[0]
        soft = local(self.run_job("linear", 100)["probes"][0]["displacement"], True)[0]
        print("\n[turned 12 cells] linear bulge with beta 1000: %.4f mm, beta 100: %.4f mm" % (bulge, soft))
        self.assertGreater(bulge / soft, 1.015)  # measured 1.1423 / 1.1211 = 1.019
        nh = self.run_job("neo_hooke_isochoric", 1000)
        self.assertLessEqual(nh["newton"]["iterations"], 16)  # measured 12
        self.assertGreater(local(nh["probes"][0]["displacement"], True)[0] / bulge, 1 + MIN_NONLINEAR)


if __name__ == "__main__":
    unittest.main(verbosity=2)
