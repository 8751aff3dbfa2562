"""The element of a simulation job ("element": "hex8" | "hex27") through parafab.Simulation and
the CLI: the turned cantilever of the issue (8000 × 1000 × 1000 mm, 9 MN; every face cuts cells)
against Gmsh + CalculiX tet10 (h = 150 mm, computed once here), hex27 with a hyperelastic law,
hex27 with an accuracy target, and a wrong element named in the error."""
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
REF = os.path.join(REPO, "tests", "reference")
sys.path.insert(0, REF)
import calculix_reference as cr  # noqa: E402

CLI = os.environ.get("PARAFAB_CLI", os.path.join(REPO, "build", "workbench", "entry", "parafab"))
AXIS, CENTER, DEGREES = [0.3, 0.5, 1.0], [4000.0, 500.0, 500.0], 12.0


def rotation(axis, degrees):
    n = math.sqrt(sum(a * a for a in axis))
    x, y, z = (a / n for a in axis)
    t = math.radians(degrees)
    c, s, C = math.cos(t), math.sin(t), 1 - math.cos(t)
    return [[c + x * x * C, x * y * C - z * s, x * z * C + y * s],
            [y * x * C + z * s, c + y * y * C, y * z * C - x * s],
            [z * x * C - y * s, z * y * C + x * s, c + z * z * C]]


R = rotation(AXIS, DEGREES)


def turn(p):
    d = [p[i] - CENTER[i] for i in range(3)]
    return [CENTER[i] + sum(R[i][j] * d[j] for j in range(3)) for i in range(3)]


def unturn_vector(u):
    return [sum(R[j][i] * u[j] for j in range(3)) for i in range(3)]


def turned_job(**extra):
    j = {"material": {"E": 210000, "nu": 0.3},
         "rotate": {"axis": AXIS, "center": CENTER, "degrees": DEGREES},
         "supports": [{"point": turn([0, 500, 500])}],
         "loads": [{"point": turn([8000, 500, 500]), "force": [R[i][2] * -9e6 for i in range(3)]}],
         "probes": [turn([8000, 500, 500])]}
    j.update(extra)
    return j


class SimulationElement(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="parafab_element_")
        cls.part = cr.make_box_step(os.path.join(cls.tmp, "cantilever.step"), (8000.0, 1000.0, 1000.0))
        job = os.path.join(cls.tmp, "cantilever.json")
        with open(job, "w") as f:
            json.dump({"material": {"E": 210000, "nu": 0.3}, "supports": [{"point": [0, 500, 500]}],
                       "loads": [{"point": [8000, 500, 500], "force": [0, 0, -9e6]}],
                       "probes": [[8000, 500, 500]]}, f)
        out = subprocess.run(["/usr/bin/python3", os.path.join(REF, "calculix_reference.py"), job, "--parafab",
                              cls.part, "--size", "150", "--quiet"], capture_output=True, text=True, check=True).stdout
        cls.u_ref = json.loads(out)["displacement_at"][0]["u"][2]
        print("CalculiX tet10 h = 150 mm: tip u_z %.4f mm" % cls.u_ref)

    def tip(self, result):
        return unturn_vector(result["probes"][0]["displacement"])[2]

    def test_hex27_beats_hex8_on_the_same_grid_against_calculix(self):
        errors = {}
        for element in ["hex8", "hex27"]:
            r = parafab.Simulation(self.part, turned_job(element=element, grid={"cells": 8})).run()
            self.assertEqual(r["element"], element)
            errors[element] = abs(self.tip(r) - self.u_ref) / abs(self.u_ref)
            print("%s, 8 cells: %d dofs, tip %.4f mm, error %.2e" % (element, r["dofs"], self.tip(r), errors[element]))
        self.assertLess(errors["hex27"], 0.006)  # measured 4.5e-3 (hex8: 4.2e-2)
        self.assertLess(errors["hex27"], 0.2 * errors["hex8"])

    def test_cli_runs_hex27_and_names_a_wrong_element(self):
        path = os.path.join(self.tmp, "job27.json")
        with open(path, "w") as f:
            json.dump(turned_job(element="hex27", grid={"cells": 4}), f)
        out = json.loads(subprocess.run([CLI, "simulate", self.part, path], capture_output=True, text=True,
                                        check=True).stdout)
        self.assertEqual(out["element"], "hex27")
        with open(path, "w") as f:
            json.dump(turned_job(element="hex20", grid={"cells": 4}), f)
        p = subprocess.run([CLI, "simulate", self.part, path], capture_output=True, text=True)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("element", p.stdout + p.stderr)
        self.assertIn("hex20", p.stdout + p.stderr)
        with self.assertRaises(parafab.Error) as cm:
            parafab.Simulation(self.part, turned_job(element=27))
        self.assertIn("element", str(cm.exception))

    def test_hex27_hyperelastic_matches_linear_at_small_load(self):
        # A 10× smaller load (tip ≈ 8.8 mm, rotations ≈ 2e-3): neo-Hooke and linear agree to
        # O(rotation²). (At 1000× smaller loads, Newton stalls on the round-off floor of the
        # gradient, ≈ 3e-5 N, above its relative tolerance 1e-9 × 9 kN.)
        small = turned_job(element="hex27", grid={"cells": 4})
        small["loads"][0]["force"] = [f / 10 for f in small["loads"][0]["force"]]
        small["nitsche_penalty"] = "fixed"  # neo-Hooke's default; the linear model's is local
        lin = parafab.Simulation(self.part, small).run()
        small["material"]["model"] = "neo_hooke"
        small["load_steps"] = 1
        hyper = parafab.Simulation(self.part, small).run()
        print("hex27 small load: linear %.6e, neo-Hooke %.6e mm" % (self.tip(lin), self.tip(hyper)))
        self.assertAlmostEqual(self.tip(hyper) / self.tip(lin), 1.0, delta=1e-5)  # measured 2.2e-6
        self.assertAlmostEqual(10 * self.tip(lin) / self.u_ref, 1.0, delta=0.02)
        self.assertEqual(hyper["element"], "hex27")

    def test_hex27_accuracy_target(self):
        r = parafab.Simulation(self.part, turned_job(element="hex27", grid={"target": 0.02, "cells": 4,
                                                                             "max_cells": 16})).run()
        a = r["accuracy"]
        true_error = abs(self.tip(r) - self.u_ref) / abs(self.u_ref)
        print("hex27 target 0.02: levels", [lv["cells"] for lv in a["levels"]],
              "estimated %.3g, true %.3g" % (a["estimated_error"], true_error))
        self.assertTrue(a["met"], a["stopped"])
        self.assertLessEqual(true_error, a["estimated_error"])


if __name__ == "__main__":
    unittest.main()
