#!/usr/bin/python3
"""Validation of the CalculiX reference route (calculix_reference.py).

Run:  /usr/bin/python3 tests/reference/test_calculix_reference.py [-v]
Needs `gmsh` and `ccx` on PATH (Debian packages gmsh, calculix-ccx); the
tests are skipped if either is missing. Exit status is non-zero on failure.

Cantilever 8000 x 1000 x 1000 mm, steel E = 210000 MPa, nu = 0.3, face x=0
fully fixed, 9 MN in -z on face x=8000 (FreeCAD CalculiX cantilever example):
  Euler-Bernoulli  d = F L^3 / (3 E I)              = 87.77 mm
  Timoshenko       d + F L / (k G A), k = 5/6       = 88.84 mm
The clamped 3D end (no warping, no Poisson contraction) sits between the two.
"""

import os
import shutil
import sys
import tempfile
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import calculix_reference as cr  # noqa: E402

L, B, H = 8000.0, 1000.0, 1000.0
E, NU, F = 210000.0, 0.3, 9.0e6
I = B * H ** 3 / 12.0
EB = F * L ** 3 / (3 * E * I)
G = E / (2 * (1 + NU))
TIMO = EB + F * L / (5.0 / 6.0 * G * B * H)

HAVE_TOOLS = bool(shutil.which("gmsh") and shutil.which("ccx"))


def cantilever_job(step, size, element="C3D10", **extra):
    job = {
        "step": step,
        "mesh": {"size": size, "element": element},
        "material": {"E": E, "nu": NU},
        "boundary_conditions": [
            {"name": "clamp", "type": "fixed",
             "select": {"plane": {"axis": "x", "value": 0.0}}},
            {"name": "tip", "type": "load", "force": [0.0, 0.0, -F],
             "select": {"plane": {"axis": "x", "value": L}}},
        ],
        "probes": [[L, B / 2, H / 2]],
        "solver": {"threads": 2},
    }
    job.update(extra)
    return job


@unittest.skipUnless(HAVE_TOOLS, "gmsh and/or ccx not installed")
class CantileverTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="ccxref_test_")
        cls.step = cr.make_box_step(os.path.join(cls.tmp, "box.step"),
                                    (L, B, H))

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def test_tet10_tip_deflection(self):
        r = cr.run_job(cantilever_job(self.step, 250.0))
        self.assertEqual(r["status"], "ok")
        self.assertEqual(r["element_type"], "C3D10")
        p = r["displacement_at"][0]
        self.assertEqual(p["method"], "interpolated")
        uz = -p["u"][2]
        print("\n  tet10 h=250: %d nodes, tip uz = %.3f mm (EB %.2f, Timo %.2f)"
              ", %.1f s" % (r["nodes"], uz, EB, TIMO, r["total_seconds"]))
        self.assertAlmostEqual(uz / EB, 1.0, delta=0.03)
        self.assertLess(uz, TIMO * 1.01)
        # equilibrium: reaction at the clamp equals the applied load
        rz = r["reactions"]["clamp"][2]
        self.assertAlmostEqual(rz / F, 1.0, places=6)
        # root bending stress M c / I = 432 MPa (von Mises ~ sigma_xx there)
        self.assertAlmostEqual(r["von_mises"]["max"] / (F * L * H / 2 / I),
                               1.0, delta=0.1)
        self.assertAlmostEqual(r["selections"]["tip"]["area"], B * H,
                               delta=1e-6 * B * H)
        # compliance f^T u of the nodal loads: F times the tip deflection
        # (measured ratio 1.000057: the face's mean vs its centre)
        self.assertAlmostEqual(r["compliance"] / (F * uz), 1.0, delta=1e-4)

    def test_tet4_stiffer_and_line(self):
        job = cantilever_job(self.step, 250.0, "C3D4",
                             line={"from": [0, B / 2, H], "to": [L, B / 2, H],
                                   "n": 5})
        r = cr.run_job(job)
        uz = -r["displacement_at"][0]["u"][2]
        print("\n  tet4  h=250: %d nodes, tip uz = %.3f mm (locking)"
              % (r["nodes"], uz))
        self.assertEqual(r["element_type"], "C3D4")
        self.assertLess(uz, EB)          # linear tets lock in bending
        self.assertGreater(uz, 0.3 * EB)
        self.assertEqual(len(r["line"]["von_mises"]), 5)
        self.assertEqual(r["line"]["u"][0], [0.0, 0.0, 0.0])

    def test_gravity(self):
        rho, g = 7.85e-9, 9810.0          # t/mm^3, mm/s^2
        job = cantilever_job(self.step, 250.0)
        job["material"]["density"] = rho
        job["boundary_conditions"] = job["boundary_conditions"][:1] + [
            {"name": "g", "type": "gravity", "acceleration": [0, 0, -g]}]
        r = cr.run_job(job)
        self.assertNotIn("compliance", r)  # a *DLOAD: f^T u of the nodal loads would be wrong
        w = rho * g * B * H
        ref = w * L ** 4 / (8 * E * I)    # Euler-Bernoulli, 2.25 mm
        uz = -r["displacement_at"][0]["u"][2]
        print("\n  gravity: tip uz = %.4f mm (EB %.4f)" % (uz, ref))
        self.assertAlmostEqual(uz / ref, 1.0, delta=0.04)
        # ccx's RF is the internal nodal force: the share of the body load
        # acting on the clamped nodes themselves is not in it (~0.5 % here)
        self.assertAlmostEqual(r["reactions"]["clamp"][2] / (w * L), 1.0,
                               delta=0.02)

    def _bar_job(self, material, ux=1.0):
        # statically determinate supports -> homogeneous uniaxial stress
        return {
            "step": self.step,
            "mesh": {"size": 500.0, "element": "C3D10"},
            "material": material,
            "boundary_conditions": [
                {"name": "x0", "type": "displacement", "value": [0, None, None],
                 "select": {"plane": {"axis": "x", "value": 0.0}}},
                {"name": "a", "type": "fixed",
                 "select": {"box": {"min": [0, 0, 0], "max": [0, 0, 0]}}},
                {"name": "b", "type": "displacement", "value": [None, None, 0],
                 "select": {"box": {"min": [0, B, 0], "max": [0, B, 0]}}},
                {"name": "c", "type": "displacement", "value": [None, 0, None],
                 "select": {"box": {"min": [0, 0, H], "max": [0, 0, H]}}},
                {"name": "pull", "type": "displacement",
                 "value": [ux, None, None],
                 "select": {"plane": {"axis": "x", "value": L}}},
            ],
            "probes": [[L, B, H]],
        }

    def test_displacement_bc_uniaxial(self):
        r = cr.run_job(self._bar_job({"E": E, "nu": NU}))
        eps = 1.0 / L
        self.assertEqual(r["selections"]["a"]["nodes"], 1)
        self.assertAlmostEqual(r["reactions"]["pull"][0] / (E * B * H * eps),
                               1.0, places=5)
        u = r["displacement_at"][0]["u"]
        self.assertAlmostEqual(u[0], 1.0, places=6)
        self.assertAlmostEqual(u[1] / (-NU * eps * B), 1.0, places=4)
        self.assertAlmostEqual(r["von_mises"]["max"] / (E * eps), 1.0,
                               places=4)

    def test_neo_hooke_small_strain_matches_linear(self):
        r = cr.run_job(self._bar_job({"model": "neo_hooke", "E": E, "nu": NU},
                                     ux=0.08))   # strain 1e-5
        eps = 0.08 / L
        self.assertEqual(r["status"], "ok")
        self.assertAlmostEqual(r["reactions"]["pull"][0] / (E * B * H * eps),
                               1.0, delta=1e-3)



def _geo_to_step(tmp, name, geo_body):
    import subprocess
    geo = os.path.join(tmp, name + ".geo")
    with open(geo, "w") as f:
        f.write('SetFactory("OpenCASCADE");\n' + geo_body)
    step = os.path.join(tmp, name + ".step")
    subprocess.run(["gmsh", geo, "-0", "-format", "step", "-o", step],
                   check=True, capture_output=True)
    return step


@unittest.skipUnless(HAVE_TOOLS, "gmsh and/or ccx not installed")
class GeometryVariantsTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="ccxref_test2_")

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def test_round_bar_curved_tet10(self):
        """Curved B-rep faces: tet10 midside nodes on the cylinder."""
        import math
        r0 = 500.0
        step = _geo_to_step(self.tmp, "cyl",
                            "Cylinder(1) = {0,0,0, %g,0,0, %g};\n" % (L, r0))
        job = cantilever_job(step, 250.0)
        job["probes"] = [[L, 0.0, 0.0]]          # axis at y = z = 0
        r = cr.run_job(job)
        ref = F * L ** 3 / (3 * E * math.pi * r0 ** 4 / 4)     # 149.0 mm
        uz = -r["displacement_at"][0]["u"][2]
        self.assertEqual(r["displacement_at"][0]["method"], "interpolated")
        self.assertAlmostEqual(uz / ref, 1.0, delta=0.03)
        self.assertAlmostEqual(r["selections"]["tip"]["area"] /
                               (math.pi * r0 ** 2), 1.0, delta=1e-3)
        self.assertAlmostEqual(r["reactions"]["clamp"][2] / F, 1.0, places=6)

    def test_multi_solid_needs_fragment(self):
        step = _geo_to_step(self.tmp, "two",
                            "Box(1) = {0,0,0, %g,%g,%g};\n"
                            "Box(2) = {%g,0,0, %g,%g,%g};\n"
                            % (L / 2, B, H, L / 2, L / 2, B, H))
        job = cantilever_job(step, 250.0)
        with self.assertRaises(cr.ReferenceError):
            cr.run_job(job)
        job["mesh"]["fragment"] = True
        r = cr.run_job(job)
        uz = -r["displacement_at"][0]["u"][2]
        self.assertAlmostEqual(uz / EB, 1.0, delta=0.03)


SAMPLES = os.path.join(HERE, "..", "..", "samples")


@unittest.skipUnless(HAVE_TOOLS, "gmsh and/or ccx not installed")
class ParafabJobTest(unittest.TestCase):
    def test_l_bracket_sample_job(self):
        """samples/simulations/l_bracket.json translated: faces picked by
        point, force spread as traction, gravity, probes."""
        import json
        with open(os.path.join(SAMPLES, "simulations", "l_bracket.json")) as f:
            pjob = json.load(f)
        job = cr.from_parafab_job(
            pjob, os.path.join(SAMPLES, "parts", "l_bracket.step"), 4.0)
        r = cr.run_job(job)
        sel = r["selections"]
        self.assertAlmostEqual(sel["support0"]["area"], 40 * 38, delta=1e-6)
        self.assertAlmostEqual(sel["load0"]["area"], 40 * 8, delta=1e-6)
        # reaction = 500 N + self weight (~2.3 N, less the share on the wall)
        self.assertTrue(501.5 < r["reactions"]["support0"][2] < 503.0,
                        r["reactions"])
        # converged tet10 value is about -0.111 mm (h = 1.5 mm: -0.1106)
        uz = r["displacement_at"][0]["u"][2]
        self.assertAlmostEqual(uz / -0.111, 1.0, delta=0.04)
        # parafab face index k is gmsh surface k + 1
        job2 = cr.from_parafab_job({"material": {"E": 210000.0},
                                    "supports": [{"face": 4}],
                                    "loads": [{"face": 3,
                                               "force": [0, 0, -500]}],
                                    "probes": pjob["probes"]},
                                   os.path.join(SAMPLES, "parts",
                                                "l_bracket.step"), 4.0)
        r2 = cr.run_job(job2)
        self.assertAlmostEqual(r2["selections"]["support0"]["area"], 1520.0,
                               delta=1e-6)
        self.assertAlmostEqual(r2["selections"]["load0"]["area"], 320.0,
                               delta=1e-6)


if __name__ == "__main__":
    prog = unittest.main(exit=False, verbosity=2 if "-v" in sys.argv else 1)
    sys.exit(0 if prog.result.wasSuccessful() else 1)
