"""`parafab simulate` (CLI) and parafab.simulate (Python): the L-bracket sample job against
CalculiX (tet10 on a Gmsh mesh of the same STEP), outputs written, a hyperelastic job against
the linear solve at small strain, and job errors that name the field (CLI: exit 2 and a JSON
error)."""
import json
import os
import subprocess
import sys
import tempfile
import unittest

sys.path.insert(0, os.environ.get("PARAFAB_MODULE_DIR", "build/workbench/entry"))
import parafab  # noqa: E402

CLI = os.environ.get("PARAFAB_CLI", "build/workbench/entry/parafab")
SAMPLES = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "samples")
BRACKET = os.path.join(SAMPLES, "parts", "l_bracket.step")
# CalculiX tet10 on the Gmsh mesh of l_bracket.step, h = 1.5 mm, the sample job (tests/bench/README.md,
# "XFEM against Gmsh + CalculiX"; re-measured with
#   /usr/bin/python3 tests/reference/calculix_reference.py samples/simulations/l_bracket.json \
#       --parafab samples/parts/l_bracket.step --size 1.5 --quiet
# probe (60, 20, 4): u_z = CCX_TIP).
CCX_TIP = -0.11056
HEX27_NEWTON_TOL = 5e-4  # measured 3.5e-5 and 1.5e-4 at the two probes (hex8: 1.3e-4)
XFEM_16_ERROR = 0.0064  # measured: the sample's 16-cell grid (hex27, the default element, local penalty) is stiff by this much
XFEM_16_FIXED_ERROR = 0.0161  # the same with "nitsche_penalty": "fixed" (β = 100, the default until 2026-11-28)


def run(part, job, out=None):
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
        json.dump(job, f)
    try:
        args = [CLI, "simulate", part, f.name] + (["-o", out] if out else [])
        p = subprocess.run(args, capture_output=True, text=True, timeout=300)
        return p.returncode, json.loads(p.stdout)
    finally:
        os.unlink(f.name)


class Simulate(unittest.TestCase):
    def test_bracket_sample_writes_outputs(self):
        with open(os.path.join(SAMPLES, "simulations", "l_bracket.json")) as f:
            job = json.load(f)
        with tempfile.TemporaryDirectory() as d:
            code, out = run(BRACKET, job, d)
            self.assertEqual(code, 0, out)
            self.assertTrue(os.path.getsize(os.path.join(d, "result.vtu")) > 1000)
            with open(os.path.join(d, "result.json")) as f:
                self.assertEqual(json.load(f)["dofs"], out["dofs"])
        # Against CalculiX: triquadratic hexahedra (the default element) with the default local
        # clamp penalty on 16 cells are stiff by the measured XFEM_16_ERROR (the fixed penalty
        # β = 100: XFEM_16_FIXED_ERROR; trilinear ones were 12.7 %); the bands are ± 0.3 %.
        tip = out["probes"][0]["displacement"][2]
        error = 1 - tip / CCX_TIP
        fixed = parafab.simulate(BRACKET, dict(job, nitsche_penalty="fixed"))
        fixed_error = 1 - fixed["probes"][0]["displacement"][2] / CCX_TIP
        print("bracket tip u_z %.5f mm, CalculiX %.5f mm: %.2f %% stiff (fixed penalty: %.2f %%)"
              % (tip, CCX_TIP, 100 * error, 100 * fixed_error))
        self.assertEqual(out["element"], "hex27")
        self.assertEqual(out["nitsche_penalty"], "local")
        self.assertEqual(out["nitsche_surface_degree"], 8)
        self.assertGreater(error, XFEM_16_ERROR - 0.003)
        self.assertLess(error, XFEM_16_ERROR + 0.003)
        self.assertEqual(fixed["nitsche_penalty"], "fixed")
        self.assertGreater(fixed_error, XFEM_16_FIXED_ERROR - 0.003)
        self.assertLess(fixed_error, XFEM_16_FIXED_ERROR + 0.003)
        mod = parafab.simulate(BRACKET, job)
        self.assertAlmostEqual(mod["probes"][0]["displacement"][2], tip, delta=1e-12)

    def test_the_job_cuts_by_face_and_refuses_the_splitter(self):
        # The face route is the only route (its solution equals the splitter's to 4.9e-13:
        # FaceCut.GridModelOnTheFaceRouteMatchesTheSplitterModel); the splitter and its blocks
        # are refused with the reason.
        with open(os.path.join(SAMPLES, "simulations", "l_bracket.json")) as f:
            job = json.load(f)
        job["grid"] = {"cells": 8}
        r = parafab.simulate(BRACKET, job)
        self.assertEqual(r["grid"]["method"], "face")
        self.assertEqual(r["grid"]["retry_reason"], "")
        self.assertEqual(r["grid"]["grid_shift"], [0.0, 0.0, 0.0])
        job["grid"]["method"] = "face"
        self.assertEqual(parafab.simulate(BRACKET, job)["probes"][0]["displacement"], r["probes"][0]["displacement"])
        for bad, field in (({"method": "splitter"}, "grid.method"), ({"block_cells": 4}, "grid.block_cells")):
            job["grid"] = dict({"cells": 8}, **bad)
            with self.assertRaises(parafab.Error) as e:
                parafab.simulate(BRACKET, job)
            self.assertIn(field, str(e.exception))
            self.assertIn("tests' reference", str(e.exception))

    def test_hyperelastic_job_runs_newton(self):
        with open(os.path.join(SAMPLES, "simulations", "l_bracket.json")) as f:
            job = json.load(f)
        job["grid"] = {"cells": 10}
        job["material"]["model"] = "neo_hooke"
        job["load_steps"] = 2
        # The hyperelastic models' default clamp penalty is fixed (β = 100): the linear solve
        # compared with it must hold the clamp the same way.
        job["nitsche_penalty"] = "fixed"
        # The default element, hex27: Newton's deflection equals the linear solve's at small strain.
        r27 = parafab.simulate(BRACKET, job)
        self.assertEqual(r27["element"], "hex27")
        self.assertLess(r27["newton"]["residuals"][-1], 1e-6 * max(r27["newton"]["residuals"]))
        job["material"]["model"] = "linear"
        lin27 = parafab.simulate(BRACKET, job)
        for p, q in zip(r27["probes"], lin27["probes"]):
            print("hex27 probe %s: neo-Hooke u_z %.6f, linear %.6f (ratio %.5f)"
                  % (p["point"], p["displacement"][2], q["displacement"][2], p["displacement"][2] / q["displacement"][2]))
            self.assertAlmostEqual(p["displacement"][2] / q["displacement"][2], 1.0, delta=HEX27_NEWTON_TOL)
        # hex8 (plain hexahedra in Newton, incompatible modes in the linear solve).
        job["material"]["model"] = "neo_hooke"
        job["element"] = "hex8"
        r = parafab.simulate(BRACKET, job)
        self.assertEqual(r["material_model"], "neo_hooke")
        self.assertGreaterEqual(r["newton"]["iterations"], 2)
        self.assertLess(r["newton"]["residuals"][-1], 1e-6 * max(r["newton"]["residuals"]))
        # Small strains (500 N on steel): the same deflection as plain linear hexahedra (Newton
        # has no incompatible modes) within 5e-4, at every probe.
        job["material"]["model"] = "linear"
        job["incompatible_modes"] = False
        lin = parafab.simulate(BRACKET, job)
        for p, q in zip(r["probes"], lin["probes"]):
            print("probe %s: neo-Hooke u_z %.6f, linear hex8 %.6f (ratio %.5f)"
                  % (p["point"], p["displacement"][2], q["displacement"][2], p["displacement"][2] / q["displacement"][2]))
            self.assertLess(p["displacement"][2], 0)
            self.assertAlmostEqual(p["displacement"][2] / q["displacement"][2], 1.0, delta=5e-4)  # measured 1.3e-4
        # and the linear solve is not the same code path in disguise: incompatible modes change it
        job["incompatible_modes"] = True
        modes = parafab.simulate(BRACKET, job)
        print("with incompatible modes: %.6f" % modes["probes"][0]["displacement"][2])
        self.assertGreater(abs(modes["probes"][0]["displacement"][2] / lin["probes"][0]["displacement"][2] - 1), 0.01)

    def test_nitsche_beta_too_small_is_reported_and_large_is_stable(self):
        with open(os.path.join(SAMPLES, "simulations", "l_bracket.json")) as f:
            job = json.load(f)
        job["grid"] = {"cells": 12}
        # hex8: on these cut clamps hex27 locks at large beta (test_simulate_clamp_beta.py).
        job["element"] = "hex8"
        tip = {}
        for beta in (0.1, 100, 1e3, 1e5):
            job["nitsche_beta"] = beta
            r = parafab.simulate(BRACKET, job)
            tip[beta] = r["probes"][0]["displacement"][2]
            if beta < 1:  # unstable Nitsche: indefinite matrix, reported, solved by LU
                self.assertIn("not positive definite", r["message"])
            else:
                self.assertEqual(r["message"], "")
        # Stable range: the clamp converges to strong enforcement, without locking here.
        self.assertLess(abs(tip[100] - tip[1e5]) / abs(tip[1e5]), 0.01)
        self.assertLess(abs(tip[1e3] - tip[1e5]) / abs(tip[1e5]), 0.001)

    def test_estimate_counts_the_cells_the_part_occupies(self):
        # The size before a run, from the part's volume and area: unknowns m^3 V/h^3 + b m^2 A/h^2,
        # the factor 8 C n^(4/3) bytes with C = 26 (compact parts) and 7 (thin-walled), the rest of
        # the run 5 / 9 kB per unknown. Against what the run then has: its unknowns, CHOLMOD's
        # factor size and the CLI's peak resident memory (/usr/bin/time). Measured on the bracket
        # (2026-11-28): unknowns 1.26 / 1.21 / 1.17 x, compact factor 2.5 / 2.5 / 2.3 x CHOLMOD's,
        # peak 1.19 / 1.51 / 1.33 x (compact) and 1.03 / 0.98 / 1.16 x (thin-walled) the measured.
        with open(os.path.join(SAMPLES, "simulations", "l_bracket.json")) as f:
            job = json.load(f)
        for element, cells in (("hex8", 16), ("hex8", 32), ("hex27", 8)):
            job.update(element=element, grid={"cells": cells})
            est = parafab.Simulation(BRACKET, job).estimate()
            with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
                json.dump(job, f)
            try:
                # /usr/bin/time measures the CLI alone: a child forked from this (by now large)
                # Python process would count the parent's pages in its ru_maxrss.
                p = subprocess.run(["/usr/bin/time", "-f", "%M", CLI, "simulate", BRACKET, f.name], capture_output=True,
                                   text=True, timeout=300)
            finally:
                os.unlink(f.name)
            self.assertEqual(p.returncode, 0, p.stderr)
            r = json.loads(p.stdout)
            peak = int(p.stderr.strip().splitlines()[-1]) / 1024.0  # kB → MB
            print("%s %d cells: unknowns %.0f estimated / %d solved (%.2f); factor %.0f MB estimated (compact) / "
                  "%.1f MB CHOLMOD (%.2f); peak %.0f-%.0f MB estimated / %.0f MB measured (%.2f-%.2f)" % (
                      element, cells, est["unknowns"], r["dofs"], est["unknowns"] / r["dofs"], est["factor_mb"],
                      r["solver"]["factor_mb"], est["factor_mb"] / r["solver"]["factor_mb"], est["peak_mb_min"],
                      est["peak_mb"], peak, est["peak_mb_min"] / peak, est["peak_mb"] / peak))
            self.assertGreaterEqual(est["unknowns"], r["dofs"])
            self.assertLessEqual(est["unknowns"], 1.4 * r["dofs"])
            self.assertGreater(est["factor_mb"], r["solver"]["factor_mb"])  # the compact figure: an upper one
            self.assertLess(est["factor_mb"], 3.0 * r["solver"]["factor_mb"])
            self.assertGreaterEqual(est["peak_mb"], peak)
            self.assertLessEqual(est["peak_mb"], 1.8 * peak)
            self.assertGreater(est["peak_mb_min"], 0.85 * peak)
            self.assertLess(est["peak_mb_min"], 1.3 * peak)
            self.assertEqual(est["fits"], True)

    def test_memory_limit_refuses_before_the_run_or_before_the_factorization(self):
        # memory_limit_mb (default 70 % of the memory). The box on 32 hex8 cells: 42,075 unknowns,
        # a 238 MB factor, a 454 MB peak; estimated 340 MB (thin-walled figure) to 580 MB (compact).
        # 100 MB: refused before anything runs. 400 MB: the thin-walled figure passes, and CHOLMOD's
        # analysis then finds factor + resident memory above 400 MB: refused before the factorization.
        box = os.path.join(SAMPLES, "parts", "box.step")
        job = {"material": {"E": 210000, "nu": 0.3}, "element": "hex8", "grid": {"cells": 32},
               "supports": [{"point": [20, 15, 0]}], "gravity": [0, 0, -9810]}
        est = parafab.Simulation(box, dict(job, memory_limit_mb=400)).estimate()
        self.assertEqual(est["limit_mb"], 400)
        self.assertLess(est["peak_mb_min"], 400)
        self.assertGreater(est["peak_mb"], 400)
        self.assertEqual((est["fits"], est["may_fit"]), (False, True))
        for limit, expected in ((100, "this grid needs at least about"), (400, "sparse Cholesky factor of these 42075 unknowns needs")):
            with self.subTest(limit=limit):
                code, out = run(box, dict(job, memory_limit_mb=limit))
                self.assertEqual(code, 2, out)
                self.assertIn(expected, out["error"]["message"])
                self.assertIn("memory_limit_mb", out["error"]["message"])
                with self.assertRaises(parafab.Error):
                    parafab.simulate(box, dict(job, memory_limit_mb=limit))
        r = parafab.simulate(box, dict(job, memory_limit_mb=2000))  # room enough: solved
        self.assertEqual(r["dofs"], 42075)
        self.assertGreater(r["solver"]["factor_mb"], 200)

    def test_job_errors_name_the_field(self):
        base = {"material": {"E": 210000, "nu": 0.3}, "supports": [{"point": [0, 20, 30]}]}
        cases = [
            ({"material": {"E": 210000}}, "supports"),
            (dict(base, material={"E": -1}), "material.E"),
            (dict(base, material={"E": 1, "nu": 0.5}), "material.nu"),
            (dict(base, supports=[{"face": 99}]), "face 99 does not exist"),
            (dict(base, supports=[{"point": [500, 500, 500]}]), "no face"),
            (dict(base, loads=[{"face": 0}]), "loads[0] needs"),
            (dict(base, grid={"cells": 100000}), "memory"),
            (dict(base, memory_limit_mb=0), "memory_limit_mb must be positive"),
            (dict(base, material={"E": 1, "nu": 0.3, "model": "ogden"}), "ogden"),
            (dict(base, nitsche_penalty="strong"), "nitsche_penalty must be"),
            (dict(base, nitsche_beta=0), "nitsche_beta must be positive"),
            (dict(base, nitsche_penalty="local", nitsche_beta=1000), "nitsche_beta sets the fixed penalty"),
            (dict(base, nitsche_penalty="local", nitsche_local_factor=0.5), "nitsche_local_factor must be > 1"),
            (dict(base, nitsche_penalty="fixed", nitsche_local_factor=4), "nitsche_local_factor applies to"),
            (dict(base, nitsche_surface_degree=1), "nitsche_surface_degree must be an integer 2..20"),
            (dict(base, nitsche_surface_degree=8.5), "nitsche_surface_degree must be an integer"),
        ]
        for job, expected in cases:
            with self.subTest(expected):
                code, out = run(BRACKET, job)
                self.assertEqual(code, 2, out)
                self.assertIn(expected, out["error"]["message"])
                with self.assertRaises(parafab.Error):
                    parafab.simulate(BRACKET, job)


if __name__ == "__main__":
    unittest.main()
