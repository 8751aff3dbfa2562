"""The PETSc solver of the XFEM systems ("solver": {"type": "petsc"}: CG + smoothed-aggregation
AMG with the rigid-body near-nullspace) against CHOLMOD's Cholesky on the L-bracket turned off
the grid axes (every face cuts cells), hex8 and hex27; `mpirun -np 2` against the serial solve;
the optimizer's adjoint solves through PETSc; and what a user gets where the iterative solve
fails (too few iterations, an unknown PETSc type)."""
import json
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.environ.get("PARAFAB_MODULE_DIR", "build/workbench/entry"))
import parafab  # noqa: E402
from optimize_cli import cli  # noqa: E402
from test_simulate_threads import BRACKET, CLI, bracket_job  # noqa: E402

MPIRUN = shutil.which("mpirun")


def run(args, job, out=None, timeout=600):
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
        json.dump(job, f)
    try:
        cmd = args + ["simulate", BRACKET, f.name] + (["-o", out] if out else [])
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
        return p.returncode, p.stdout, p.stderr
    finally:
        os.unlink(f.name)


def solved(job, solver, args=None, out=None):
    j = dict(job, solver=solver, threads=1)
    code, stdout, stderr = run(args or [CLI], j, out)
    assert code == 0, (code, stdout, stderr)
    return json.loads(stdout)


def rel(a, b):
    return abs(a - b) / max(abs(a), abs(b), 1e-300)


def probe_gap(r1, r2):
    """Largest displacement difference at the probes over the largest probe displacement."""
    scale = max(max(abs(c) for c in p["displacement"]) for p in r1["probes"])
    return max(abs(a - b) for p1, p2 in zip(r1["probes"], r2["probes"])
               for a, b in zip(p1["displacement"], p2["displacement"])) / scale


class PetscAgainstCholmod(unittest.TestCase):
    def test_hex8_and_hex27_agree_with_the_factorization(self):
        for element, cells in (("hex8", 16), ("hex27", 8)):
            job = dict(bracket_job(cells), element=element)
            ref = solved(job, {"type": "cholmod"})
            it = solved(job, {"type": "petsc", "rtol": 1e-10})
            self.assertEqual(ref["solver"]["method"], "cholesky")
            self.assertEqual(it["solver"]["method"], "petsc")
            self.assertEqual(it["solver"]["krylov"], "cg+gamg")
            self.assertEqual(it["dofs"], ref["dofs"])
            self.assertLessEqual(it["solver"]["residual"], 1e-10)
            # CG's residual of 1e-10 left the potential within 3e-12 and the fields within 8e-12
            # of CHOLMOD's on these grids (tests/bench/README.md, "The solve at scale").
            self.assertLess(rel(it["potential"], ref["potential"]), 1e-10, element)
            self.assertLess(probe_gap(it, ref), 1e-9, element)
            self.assertLess(rel(it["max_von_mises"], ref["max_von_mises"]), 1e-9, element)

    @unittest.skipUnless(MPIRUN, "no mpirun")
    def test_two_ranks_give_the_serial_answer_and_write_once(self):
        job = dict(bracket_job(16), element="hex8")
        ref = solved(job, {"type": "cholmod"})
        serial = solved(job, {"type": "petsc", "rtol": 1e-10})
        mpi = [MPIRUN, "--allow-run-as-root", "--oversubscribe", "-np", "2", CLI]
        with tempfile.TemporaryDirectory() as d:
            two = solved(job, {"type": "petsc", "rtol": 1e-10}, args=mpi, out=d)
            self.assertEqual(sorted(os.listdir(d)), ["result.json", "result.vtu", "surface.vtu"])
        self.assertEqual(two["solver"]["ranks"], 2)
        self.assertEqual(serial["solver"]["ranks"], 1)
        self.assertLess(rel(two["potential"], ref["potential"]), 1e-10)
        self.assertLess(probe_gap(two, ref), 1e-9)
        self.assertLess(probe_gap(two, serial), 1e-9)

    @unittest.skipUnless(MPIRUN, "no mpirun")
    def test_auto_takes_petsc_under_mpirun(self):
        job = dict(bracket_job(8), element="hex8")
        mpi = [MPIRUN, "--allow-run-as-root", "--oversubscribe", "-np", "2", CLI]
        r = solved(job, {"type": "auto"}, args=mpi)
        self.assertEqual(r["solver"]["method"], "petsc")
        self.assertEqual(r["solver"]["ranks"], 2)
        self.assertEqual(solved(job, {"type": "auto"})["solver"]["method"], "cholesky")

    def test_python_module_solves_by_cholmod_and_names_the_cli_for_petsc(self):
        job = dict(bracket_job(8), element="hex8", threads=1)
        auto = parafab.simulate(BRACKET, dict(job, solver={"type": "auto", "petsc_from": 0}))
        self.assertEqual(auto["solver"]["method"], "cholesky")
        with self.assertRaises(parafab.Error) as e:
            parafab.simulate(BRACKET, dict(job, solver={"type": "petsc"}))
        self.assertIn("runs in the CLI", str(e.exception))


class OptimizeThroughPetsc(unittest.TestCase):
    def test_adjoint_gradient_and_iterates_match_cholmod(self):
        # The compliance objective's gradient needs an adjoint solve (LinearXfemResult::solve_again),
        # which the PETSc path runs on the same matrix and preconditioner.
        from test_optimize_compliance import BRACKET as PART, JOB
        runs = {}
        for name in ("cholmod", "petsc"):
            job = dict(JOB, max_iterations=2, threads=1, solver={"type": name, "rtol": 1e-11})
            with tempfile.TemporaryDirectory() as d:
                code, out = cli(["optimize", PART, "-o", d], job)
            self.assertEqual(code, 0, out)
            runs[name] = out
        a, b = runs["cholmod"], runs["petsc"]
        for pa, pb in zip(a["parameters"], b["parameters"]):
            self.assertLess(rel(pa["gradient_initial"], pb["gradient_initial"]), 1e-6, (pa, pb))
            self.assertLess(abs(pa["final"] - pb["final"]), 1e-6, (pa, pb))
        self.assertEqual(len(a["iterations"]), len(b["iterations"]))
        for ia, ib in zip(a["iterations"], b["iterations"]):
            self.assertLess(rel(ia["objective"], ib["objective"]), 1e-8)


class PetscFailures(unittest.TestCase):
    def test_too_few_iterations_is_a_clear_failure(self):
        job = dict(bracket_job(12), element="hex8", threads=1,
                   solver={"type": "petsc", "pc": "jacobi", "max_iterations": 5})
        code, stdout, _ = run([CLI], job)
        out = json.loads(stdout)
        self.assertNotEqual(code, 0, out)
        text = json.dumps(out)
        self.assertIn("did not converge", text)
        self.assertIn("cholmod", text)  # names the way out

    def test_indefinite_system_auto_falls_back_and_petsc_says_why(self):
        # 26 cells: a sliver cut cell under the fixed Nitsche penalty leaves K indefinite (CHOLMOD
        # falls back to LU and says so); CG + GAMG breaks down on it.
        job = dict(bracket_job(26), element="hex8", threads=1)
        auto = solved(job, {"type": "auto", "petsc_from": 0})
        self.assertEqual(auto["solver"]["method"], "cholesky after petsc")
        self.assertIn("not positive definite", auto["solver"]["fallback"])
        self.assertEqual(auto["status"], "indefinite")
        code, stdout, _ = run([CLI], dict(job, solver={"type": "petsc"}))
        self.assertEqual(code, 2)
        message = json.loads(stdout)["error"]["message"]
        self.assertIn("not positive definite", message)
        self.assertIn("nitsche_penalty", message)

    def test_unknown_petsc_type_names_the_field(self):
        job = dict(bracket_job(8), element="hex8", solver={"type": "petsc", "pc": "no_such_pc"})
        code, stdout, _ = run([CLI], job)
        self.assertEqual(code, 2)
        self.assertIn("no_such_pc", json.loads(stdout)["error"]["message"])

    def test_bad_solver_fields(self):
        for solver, words in (({"type": "mumps"}, "solver.type"), ({"type": "petsc", "rtol": 2}, "solver.rtol"),
                              ({"typ": "petsc"}, "did you mean \"type\"")):
            code, stdout, _ = run([CLI], dict(bracket_job(8), solver=solver))
            self.assertEqual(code, 2, stdout)
            self.assertIn(words, json.loads(stdout)["error"]["message"])


if __name__ == "__main__":
    unittest.main()
