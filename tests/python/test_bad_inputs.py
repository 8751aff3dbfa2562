"""The bad-input corpus of issue 56 (reliability), each case as the issue reports it, through the
CLI (exit status and the JSON error naming the problem) or the Python module (parafab.Error):
outputs that could be corrupted (a full disk, stdout on /dev/full, two runs into one folder, an
output over an input), inputs that crashed or ran for minutes (deep nesting, 1e400, wrongly typed
fields, counts that drive work), nonsense that was accepted (wrapped integers, negative CLI bounds,
a negative volume ratio, an indefinite solve called "ok"), and Simulation.update before run."""
import json
import os
import subprocess
import sys
import tempfile
import threading
import time
import unittest

sys.path.insert(0, os.environ.get("PARAFAB_MODULE_DIR", "build/workbench/entry"))
import parafab  # noqa: E402

CLI = os.environ.get("PARAFAB_CLI", "build/workbench/entry/parafab")
SAMPLES = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "samples")
BRACKET = os.path.join(SAMPLES, "parts", "l_bracket.step")
BOX = os.path.join(SAMPLES, "parts", "box.step")
WHEEL = os.path.join(SAMPLES, "parts", "wheel.step")


def load(*path):
    with open(os.path.join(SAMPLES, *path)) as f:
        return json.load(f)


def write(path, obj):
    with open(path, "w") as f:
        f.write(obj if isinstance(obj, str) else json.dumps(obj))
    return path


def read(path):
    with open(path) as f:
        return f.read()


def cli(*args, stdout=subprocess.PIPE):
    p = subprocess.run([CLI] + list(args), stdout=stdout, stderr=subprocess.PIPE, text=True, timeout=600)
    try:
        out = json.loads(p.stdout) if stdout == subprocess.PIPE else None
    except ValueError:
        out = p.stdout
    return p.returncode, out, p.stderr


def message(out):
    return out["error"]["message"] if isinstance(out, dict) and "error" in out else str(out)


class Outputs(unittest.TestCase):
    def setUp(self):
        self.dir = tempfile.mkdtemp()

    def test_stdout_on_a_full_device_is_not_a_success(self):
        with open("/dev/full", "w") as full:
            code, _, err = cli("strip", os.path.join(SAMPLES, "strips", "wave.json"), stdout=full)
        self.assertNotEqual(code, 0)
        self.assertIn("cannot write the result to standard output", err)

    def test_an_output_over_an_input_is_refused_before_the_work(self):
        job = write(os.path.join(self.dir, "result.json"), load("simulations", "l_bracket.json"))
        before = read(job)
        code, out, _ = cli("simulate", BRACKET, job, "-o", self.dir)
        self.assertEqual(code, 2, out)
        self.assertIn("the output %s/result.json would overwrite the input %s" % (self.dir, job), message(out))
        self.assertEqual(read(job), before)
        hist = write(os.path.join(self.dir, "history.json"), {"objective": {"type": "volume"}})
        code, out, _ = cli("optimize", WHEEL, hist, "-o", self.dir)
        self.assertEqual(code, 2, out)
        self.assertIn("would overwrite the input " + hist, message(out))
        part = os.path.join(self.dir, "box.step")
        with open(BOX) as src, open(part, "w") as dst:
            dst.write(src.read())
        code, out, _ = cli("inspect", part, "-o", part)
        self.assertEqual(code, 2, out)
        self.assertEqual(read(part), read(BOX))

    def test_two_runs_never_share_a_folder(self):
        job = write(os.path.join(self.dir, "job.json"), load("simulations", "l_bracket.json"))
        out_dir = os.path.join(self.dir, "out")
        first = subprocess.Popen([CLI, "simulate", BRACKET, job, "-o", out_dir], stdout=subprocess.PIPE,
                                 stderr=subprocess.PIPE, text=True)
        lock = os.path.join(out_dir, ".parafab.lock")
        for _ in range(200):
            if os.path.exists(lock):
                break
            time.sleep(0.02)
        self.assertTrue(os.path.exists(lock), "the first run never took the folder")
        code, out, _ = cli("simulate", BRACKET, job, "-o", out_dir)
        self.assertEqual(code, 2, out)
        self.assertIn("is being written by another parafab run", message(out))
        stdout, _ = first.communicate(timeout=600)
        self.assertEqual(first.returncode, 0, stdout[-500:])
        self.assertEqual(sorted(os.listdir(out_dir)), ["result.json", "result.vtu", "surface.vtu"])  # lock gone

    @unittest.skipUnless(os.geteuid() == 0, "mounting a small tmpfs needs root")
    def test_a_full_disk_leaves_no_partial_file(self):
        tiny = os.path.join(self.dir, "tiny")
        os.mkdir(tiny)
        if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", tiny]).returncode != 0:
            self.skipTest("cannot mount a tmpfs here")
        try:
            job = write(os.path.join(self.dir, "job.json"), load("simulations", "l_bracket.json"))
            code, out, _ = cli("simulate", BRACKET, job, "-o", tiny)
            self.assertNotEqual(code, 0, out)
            self.assertIn("cannot write", message(out))
            self.assertEqual(os.listdir(tiny), [])  # nothing under a final name, no temporary left
            code, out, _ = cli("strip", os.path.join(SAMPLES, "strips", "wave.json"), "-o", os.path.join(tiny, "big.json"))
            if code == 0:  # the result fitted: it is whole
                json.loads(read(os.path.join(tiny, "big.json")))
            else:
                self.assertEqual(os.listdir(tiny), [])
        finally:
            subprocess.run(["umount", tiny])


class Inputs(unittest.TestCase):
    def setUp(self):
        self.dir = tempfile.mkdtemp()

    def refused(self, args, text, expected, after=()):
        """`parafab ARGS JOB AFTER` with TEXT as the job: exit 2 and EXPECTED in the message."""
        path = write(os.path.join(self.dir, "job.json"), text)
        code, out, _ = cli(*(list(args) + [path] + list(after)))
        self.assertEqual(code, 2, str(out)[:500])
        self.assertIn(expected, message(out))
        return message(out)

    def test_deep_nesting_is_refused_not_a_crash(self):
        deep = '{"material": {"E": 1, "nu": 0.3}, "probes": ' + "[" * 200000 + "]" * 200000 + "}"  # 400 kB
        self.refused(["simulate", BOX], deep, "nests objects or lists deeper than 64 levels")
        nested = []
        for _ in range(1000):
            nested = [nested]
        with self.assertRaises(parafab.Error) as e:
            parafab.simulate(BOX, {"material": {"E": 1}, "probes": nested})
        self.assertIn("deeper than 64 levels", str(e.exception))

    def test_numbers_out_of_range_and_wrong_types_name_the_field(self):
        self.refused(["simulate", BOX], '{"material": {"E": 1e400}}', "number overflow parsing '1e400'")
        sim = load("simulations", "l_bracket.json")
        for field, value, expected in [("grid", [], "grid must be a JSON object"),
                                       ("material", 5, "material must be a JSON object"),
                                       ("probes", "x", "probes must be a list"),
                                       ("gravity", [0, 0], "gravity must be [x, y, z]")]:
            self.refused(["simulate", BRACKET], dict(sim, **{field: value}), expected)
            with self.assertRaises(parafab.Error):
                parafab.simulate(BRACKET, dict(sim, **{field: value}))
        self.refused(["revolution"], dict(load("revolution", "dome.json"), points=2 ** 32 + 401),
                     "points must be an integer")

    def test_counts_that_drive_work_are_bounded(self):
        self.refused(["rod"], dict(load("rods", "helix.json"), validate=True, validate_edges=100000),
                     "validate_edges must be an integer 3..")
        self.refused(["revolution"], dict(load("revolution", "dome.json"), points=10 ** 8), "points must be an integer 2..")
        sections = load("sections", "cylinder.json")
        sections["planes"] = {"normal": [0, 0, 1], "count": 100000}
        self.refused(["sections", os.path.join(SAMPLES, "parts", "cylinder.step")], sections,
                     "planes.count must be an integer 1..")

    def test_nonsense_bounds_are_refused(self):
        code, out, _ = cli("strip-improve", os.path.join(SAMPLES, "strips", "wave.json"), "--target-R", "-1")
        self.assertEqual(code, 2, out)
        self.assertIn("--target-R", message(out))
        code, out, _ = cli("strip-stabilize", os.path.join(SAMPLES, "strips", "unstable_wave.json"), "--R-max", "-3")
        self.assertEqual(code, 2, out)
        self.assertIn("--R-max", message(out))
        job = {"objective": {"type": "volume"}, "constraints": [{"type": "volume", "max_ratio": -1}]}
        self.refused(["optimize", WHEEL], job, "constraints[0].max_ratio must be a positive ratio V / V0, got -1",
                     ["-o", os.path.join(self.dir, "o")])

    def test_close_points_are_not_called_repeats(self):
        req = load("strips", "wave.json")
        req["curve"] = {"points": [[0, 0], [1e-13, 0], [1, 0.2], [2, 0]]}  # distinct, 1e-13 of 2.2 apart
        msg = self.refused(["strip"], req, "curve.points[1] lies 1e-13 from curve.points[0]")
        self.assertNotIn("repeats", msg)
        req["curve"] = {"points": [[0, 0], [0, 0], [1, 0.2], [2, 0]]}
        self.refused(["strip"], req, "curve.points[1] repeats curve.points[0]")

    def test_a_folder_is_not_called_empty(self):
        code, out, _ = cli("strip", self.dir)
        self.assertEqual(code, 2, out)
        self.assertIn("is a folder, not a file", message(out))


class Geometry(unittest.TestCase):
    def test_a_self_intersecting_solid_is_refused_by_inspect(self):
        # A bow-tie prism: its wire crosses itself. FreeCAD's isValid() says so, but the STEP read
        # back passes BRepCheck; OCCT's Boolean check (BRepAlgoAPI_Check) finds the crossing faces.
        d = tempfile.mkdtemp()
        step = os.path.join(d, "bowtie.step")
        script = os.path.join(d, "make.py")
        write(script, "import Part, FreeCAD\nV = FreeCAD.Vector\n"
                      "w = Part.makePolygon([V(0,0,0), V(10,10,0), V(10,0,0), V(0,10,0), V(0,0,0)])\n"
                      "Part.Face(w).extrude(V(0,0,5)).exportStep(%r)\n" % step)
        subprocess.run(["freecadcmd", script], capture_output=True, timeout=120, env=dict(os.environ, HOME=d))
        self.assertTrue(os.path.exists(step), "FreeCADCmd did not write the bow-tie")
        code, out, _ = cli("inspect", step)
        self.assertEqual(code, 2, str(out)[:300])
        self.assertIn("the solid intersects itself", message(out))
        code, out, _ = cli("inspect", BRACKET)  # a valid part passes the same check
        self.assertEqual(code, 0, str(out)[:300])


class Results(unittest.TestCase):
    def test_an_indefinite_solve_is_not_ok(self):
        # Nitsche beta = 0.1 (hex8): the stiffness is indefinite, LU solves it (test_simulate.py).
        job = dict(load("simulations", "l_bracket.json"), element="hex8", nitsche_beta=0.1, grid={"cells": 8})
        r = parafab.simulate(BRACKET, job)
        self.assertEqual(r["status"], "indefinite", r["message"])
        self.assertIn("not positive definite", r["message"])
        self.assertEqual(parafab.simulate(BRACKET, dict(job, nitsche_beta=100))["status"], "ok")

    def test_update_before_run_simulates_the_new_part(self):
        job = {"material": {"E": 210000, "nu": 0.3}, "grid": {"cells": 6},
               "supports": [{"point": [0, 20, 30]}], "loads": [{"point": [60, 20, 4], "force": [0, 0, -500]}]}
        holes = os.path.join(SAMPLES, "parts", "l_bracket_holes5.step")
        s = parafab.Simulation(BRACKET, job)
        updated = s.update(holes)
        fresh = parafab.simulate(holes, job)
        self.assertEqual(updated["mass_properties"]["volume"], fresh["mass_properties"]["volume"])
        self.assertNotEqual(updated["mass_properties"]["volume"], parafab.simulate(BRACKET, job)["mass_properties"]["volume"])

    def test_two_threads_read_step_files_at_once(self):
        errors, results = [], []

        def read():
            try:
                results.append(parafab.inspect_part(BRACKET)["volume"])
            except Exception as e:  # noqa: BLE001
                errors.append(e)

        threads = [threading.Thread(target=read) for _ in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        self.assertEqual(errors, [])
        self.assertEqual(len(set(results)), 1)


if __name__ == "__main__":
    unittest.main()
