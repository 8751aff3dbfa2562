"""`parafab simulate --threads N`, the job's "threads" and parafab.simulate(threads=N): the
results (probes, maxima, potential) and the written result.vtu / surface.vtu are the same for
1 and 2 threads, on the L-bracket turned off the grid axes (every face cuts cells); the
thread count reaches the run; a bad count is a job error naming the field."""
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


def bracket_job(cells=12, model="linear"):
    with open(os.path.join(SAMPLES, "simulations", "l_bracket.json")) as f:
        job = json.load(f)
    job["grid"] = {"cells": cells}
    job["material"]["model"] = model
    job["load_steps"] = 2
    # Turned about the (sloped) axis through the bracket's middle: the support and load points
    # of the sample job turn with the part.
    job["rotate"] = {"axis": [1, 2, 3], "center": [30, 20, 15], "degrees": 17}
    import numpy as np
    from scipy.spatial.transform import Rotation
    axis = np.array([1.0, 2, 3]) / np.linalg.norm([1.0, 2, 3])
    R = Rotation.from_rotvec(np.radians(17) * axis).as_matrix()
    c = np.array([30.0, 20, 15])
    turn = lambda p: list(c + R @ (np.array(p, float) - c))  # noqa: E731
    job["supports"] = [{"point": turn(s["point"])} for s in job["supports"]]
    job["loads"] = [dict(l, point=turn(l["point"])) for l in job["loads"]]
    job["probes"] = [turn(p) for p in job["probes"]]
    return job


def run_cli(job, threads, out):
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
        json.dump(job, f)
    try:
        p = subprocess.run([CLI, "simulate", BRACKET, f.name, "-o", out, "--threads", str(threads)],
                           capture_output=True, text=True, timeout=300)
        return p.returncode, json.loads(p.stdout)
    finally:
        os.unlink(f.name)


def close(a, b, rel=1e-12):
    return abs(a - b) <= rel * max(abs(a), abs(b), 1e-300)


class SimulateThreads(unittest.TestCase):
    def test_cli_one_and_two_threads_give_the_same_results_and_files(self):
        job = bracket_job()
        with tempfile.TemporaryDirectory() as d1, tempfile.TemporaryDirectory() as d2:
            c1, r1 = run_cli(job, 1, d1)
            c2, r2 = run_cli(job, 2, d2)
            self.assertEqual((c1, c2), (0, 0), (r1, r2))
            self.assertEqual((r1["threads"], r2["threads"]), (1, 2))
            self.assertGreater(r1["grid"]["cut_cells"], 100)
            self.assertEqual(r1["dofs"], r2["dofs"])
            for key in ("max_displacement", "max_von_mises", "potential"):
                self.assertTrue(close(r1[key], r2[key]), (key, r1[key], r2[key]))
            for p1, p2 in zip(r1["probes"], r2["probes"]):
                for a, b in zip(p1["displacement"] + p1["stress"], p2["displacement"] + p2["stress"]):
                    self.assertTrue(close(a, b), (a, b))
            # The turned bracket still bends down at its tip (sample job: about −0.1 mm).
            self.assertLess(r1["probes"][0]["displacement"][2], -0.05)
            for name in ("result.vtu", "surface.vtu"):
                with open(os.path.join(d1, name), "rb") as f1, open(os.path.join(d2, name), "rb") as f2:
                    self.assertEqual(f1.read(), f2.read(), name)
            self.assertIn("write", r1["seconds"])
            self.assertIn("results", r1["seconds"])

    def test_python_keyword_and_newton(self):
        job = bracket_job(cells=8, model="neo_hooke")
        r1 = parafab.simulate(BRACKET, job, threads=1)
        r2 = parafab.simulate(BRACKET, job, threads=2)
        self.assertEqual((r1["threads"], r2["threads"]), (1, 2))
        self.assertEqual(r1["newton"]["iterations"], r2["newton"]["iterations"])
        for a, b in zip(r1["probes"][0]["displacement"], r2["probes"][0]["displacement"]):
            self.assertTrue(close(a, b), (a, b))

    @unittest.skipUnless(os.path.exists("/proc/cpuinfo") and "avx512f" in open("/proc/cpuinfo").read(),
                         "OpenBLAS's SkylakeX kernel needs AVX-512")
    def test_newton_converges_with_another_blas_kernel(self):
        # CHOLMOD's BLAS kernel moves the Newton iterates by round-off. With the SkylakeX kernel
        # the neo-Hooke energy's own noise (the textbook I1 - 3, ln det F: ~1e-9 relative at
        # these strains) exceeded the last step's predicted decrease and the line search failed
        # at load step 1 (CI, 2026-12-02). The same job in two processes, one forced onto
        # SkylakeX and one onto Haswell; OpenBLAS says which kernel it took (OPENBLAS_VERBOSE=2).
        code = ("import json, sys; sys.path.insert(0, %r); sys.path.insert(0, %r);"
                "import parafab, test_simulate_threads as t;"
                "r = parafab.simulate(t.BRACKET, t.bracket_job(cells=8, model='neo_hooke'), threads=1);"
                "print(json.dumps([r['newton']['iterations'], r['probes'][0]['displacement']]))"
                % (os.environ.get("PARAFAB_MODULE_DIR", "build/workbench/entry"), os.path.dirname(os.path.abspath(__file__))))
        runs = {}
        for kernel in ("SkylakeX", "Haswell"):
            env = dict(os.environ, OPENBLAS_CORETYPE=kernel, OPENBLAS_VERBOSE="2")
            p = subprocess.run(["/usr/bin/python3", "-c", code], capture_output=True, text=True, env=env, timeout=120)
            self.assertEqual(p.returncode, 0, kernel + ": " + p.stderr[-2000:])
            self.assertIn("Core: " + kernel, p.stderr, "OpenBLAS did not take the %s kernel" % kernel)
            iterations, runs[kernel] = json.loads(p.stdout.strip().splitlines()[-1])
            self.assertEqual(iterations, 6, kernel)  # measured: 3 per load step on both kernels
        for a, b in zip(runs["SkylakeX"], runs["Haswell"]):
            self.assertTrue(close(a, b, 1e-9), (a, b))  # measured: the kernels agree to 1.5e-13

    def test_bad_thread_count_is_a_job_error(self):
        job = bracket_job(cells=6)
        job["threads"] = -2
        with self.assertRaisesRegex(parafab.Error, "threads must be"):
            parafab.simulate(BRACKET, job)
        with tempfile.TemporaryDirectory() as d:
            code, out = run_cli(dict(job, threads=1), 0, d)  # --threads 0: refused by the CLI
            self.assertNotEqual(code, 0)


if __name__ == "__main__":
    unittest.main()
