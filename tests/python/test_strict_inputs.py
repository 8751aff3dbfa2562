"""Strict inputs (issue 53, "Inputs and faults"): every request and job is checked against its
known keys before it is parsed (workbench/entry/request_schema.cpp). Each case is one the issue
names, run through the CLI (exit 2 and a JSON error naming the key and the nearest known one)
or the Python module (parafab.Error): unknown keys at the top and nested, whole-number fields,
estimates that never overflow, a face both supported and loaded, an output folder that cannot
be written (refused before any work), fixed_faces by point, and resources/doc/json-reference.md
current with the key tables."""
import json
import os
import re
import subprocess
import sys
import tempfile
import time
import unittest

sys.path.insert(0, os.environ.get("PARAFAB_MODULE_DIR", "build/workbench/entry"))
import parafab  # noqa: E402

CLI = os.environ.get("PARAFAB_CLI", "build/workbench/entry/parafab")
ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
SAMPLES = os.path.join(ROOT, "samples")
BRACKET = os.path.join(SAMPLES, "parts", "l_bracket.step")
WHEEL = os.path.join(SAMPLES, "parts", "wheel.step")


def load(*path):
    with open(os.path.join(SAMPLES, *path)) as f:
        return json.load(f)


def cli(args, job, extra=()):
    """(exit code, JSON output, seconds) of `parafab ARGS[0] [ARGS[1]] JOB EXTRA`."""
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
        json.dump(job, f)
    try:
        t0 = time.monotonic()
        p = subprocess.run([CLI] + list(args) + [f.name] + list(extra), capture_output=True, text=True, timeout=600)
        return p.returncode, json.loads(p.stdout), time.monotonic() - t0
    finally:
        os.unlink(f.name)


def error_of(out):
    return out["error"]["message"] if isinstance(out, dict) and "error" in out else None


class UnknownKeys(unittest.TestCase):
    def assertRefused(self, args, job, message, extra=()):
        code, out, _ = cli(args, job, extra)
        self.assertEqual(code, 2, out)
        self.assertEqual(out["error"]["kind"], "invalid_input")
        self.assertIn(message, error_of(out))
        return error_of(out)

    def test_simulation_job_misspelt_grid(self):
        job = dict(load("simulations", "l_bracket.json"), griid={"cells": 4})
        self.assertRefused(["simulate", BRACKET], job, 'griid: unknown key in the simulation job, did you mean "grid"?')

    def test_strip_request_misspelt_tolerance(self):
        req = dict(load("strips", "wave.json"), tolerence=1e-3)
        self.assertRefused(["strip"], req, 'tolerence: unknown key in the strip request, did you mean "tolerance"?')

    def test_nested_keys_are_checked(self):
        sim = load("simulations", "l_bracket.json")
        sim["material"] = dict(sim["material"], nuu=0.3)
        self.assertRefused(["simulate", BRACKET], sim, 'material.nuu: unknown key in the simulation job, did you mean "nu"?')
        sim = load("simulations", "l_bracket.json")
        sim["supports"] = [dict(sim["supports"][0], displacment=[0, 0, 0])]
        self.assertRefused(["simulate", BRACKET], sim, 'supports[0].displacment: unknown key in the simulation job, '
                                                       'did you mean "displacement"?')
        opt = {"objective": {"type": "volume", "denisty": 1}, "parameters": "auto"}
        self.assertRefused(["optimize", WHEEL], opt, 'objective.denisty: unknown key in the optimization job, '
                                                     'did you mean "density"?', ["-o", tempfile.mkdtemp()])
        opt = {"objective": {"type": "sum", "terms": [{"type": "volume", "wieght": 2}]}}
        self.assertRefused(["optimize", WHEEL], opt, 'objective.terms[0].wieght: unknown key in the optimization job, '
                                                     'did you mean "weight"?', ["-o", tempfile.mkdtemp()])
        # A simulation job reused as an optimization job: its simulation-only keys are named.
        opt = dict(load("simulations", "l_bracket.json"), objective={"type": "compliance"})
        self.assertRefused(["optimize", BRACKET], opt, "probes: unknown key in the optimization job (a simulation-job "
                                                       "key it does not use: remove it)", ["-o", tempfile.mkdtemp()])
        rod = dict(load("rods", "helix.json"), stabilty=False)
        self.assertRefused(["rod"], rod, 'stabilty: unknown key in the rod request, did you mean "stability"?')
        improve = dict(load("strips", "wave.json"), improve={"target_r": 3})
        self.assertRefused(["strip-improve"], improve, 'improve.target_r: unknown key in the strip-improve request, '
                                                       'did you mean "target_R"?')
        # A key of strip-improve is not one of the plain strip request.
        self.assertRefused(["strip"], improve, 'improve: unknown key in the strip request')

    def test_a_key_near_none_lists_the_known_ones(self):
        msg = self.assertRefused(["strip"], dict(load("strips", "wave.json"), zzqqxx=1),
                                 "zzqqxx: unknown key in the strip request (known here: curve, material, min_width")
        self.assertNotIn("did you mean", msg)

    def test_python_module_raises_the_same(self):
        job = dict(load("simulations", "l_bracket.json"), griid={"cells": 4})
        with self.assertRaises(parafab.Error) as e:
            parafab.simulate(BRACKET, job)
        self.assertIn('did you mean "grid"?', str(e.exception))
        with self.assertRaises(parafab.Error) as e:
            parafab.design_rod(dict(load("rods", "helix.json"), sampels=50))
        self.assertIn('sampels: unknown key in the rod request, did you mean "samples"?', str(e.exception))

    def test_cancel_is_typed_and_callbacks_must_say_yes_or_no(self):
        job = load("simulations", "l_bracket.json")
        with self.assertRaises(parafab.Cancelled) as e:  # a parafab.Error, told apart by its type
            parafab.simulate(BRACKET, job, progress=lambda phase, fraction: phase != "cut")
        self.assertIsInstance(e.exception, parafab.Error)
        self.assertIn("during cut", str(e.exception))
        with self.assertRaises(parafab.Error) as e:
            parafab.simulate(BRACKET, job, progress=lambda phase, fraction: "stop")
        self.assertNotIsInstance(e.exception, parafab.Cancelled)
        self.assertIn("the progress callback must return True, False or None, got 'stop'", str(e.exception))

    def test_every_sample_passes(self):
        # The samples hold every documented top-level key they use; a schema that forgot one
        # would refuse them here (and in the main job).
        for name in sorted(os.listdir(os.path.join(SAMPLES, "strips"))):
            code, out, _ = cli(["strip"], load("strips", name))
            self.assertNotIn("unknown key", str(error_of(out)), name)
        for name in sorted(os.listdir(os.path.join(SAMPLES, "rods"))):
            if name.endswith(".json"):
                code, out, _ = cli(["rod"], dict(load("rods", name), samples=40, stability=False))
                self.assertNotIn("unknown key", str(error_of(out)), name)


class Numbers(unittest.TestCase):
    def test_whole_numbers(self):
        job = load("simulations", "l_bracket.json")
        job["grid"] = dict(job.get("grid", {}), cells=2.5)
        code, out, _ = cli(["simulate", BRACKET], job)
        self.assertEqual(code, 2, out)
        self.assertIn("grid.cells must be an integer (a whole number), got 2.5", error_of(out))
        code, out, _ = cli(["strip"], dict(load("strips", "wave.json"), samples=100.5))
        self.assertEqual(code, 2, out)
        self.assertIn("samples must be an integer (a whole number), got 100.5", error_of(out))
        # 4.0 is a whole number: it runs as 4 (the estimate only, no solve).
        job["grid"]["cells"] = 4.0
        code, out, _ = cli(["simulate", BRACKET], job, ["--estimate"])
        self.assertEqual(code, 0, out)

    def test_estimates_never_overflow(self):
        job = load("simulations", "l_bracket.json")
        job["grid"] = dict(job.get("grid", {}), cells=1000000)
        code, out, _ = cli(["simulate", BRACKET], job)
        self.assertEqual(code, 2, out)
        self.assertIn("grid.cells must be an integer 1..100000, got 1000000", error_of(out))
        # The largest allowed grid: refused by the estimate, with figures that are positive.
        job["grid"]["cells"] = 100000
        code, out, _ = cli(["simulate", BRACKET], job)
        self.assertEqual(code, 2, out)
        msg = error_of(out)
        print("cells 100000:", msg)
        self.assertNotIn("-9223372036854775808", msg)
        figures = re.findall(r"about (\S+) MB", msg)
        self.assertTrue(figures, msg)
        for x in figures:
            self.assertGreater(float(x), 1e6, msg)  # hundreds of terabytes at least, written as 2.1e+09 etc.
        code, est, _ = cli(["simulate", BRACKET], job, ["--estimate"])
        self.assertEqual(code, 0, est)
        self.assertFalse(est["fits"])
        self.assertGreater(est["unknowns"], 1e12)


class Faces(unittest.TestCase):
    def test_supported_and_loaded_face(self):
        job = load("simulations", "l_bracket.json")
        support = job["supports"][0]
        same_face = {k: v for k, v in support.items() if k in ("face", "point")}
        job["loads"] = job["loads"] + [dict(same_face, traction=[0, 0, -1])]
        code, out, _ = cli(["simulate", BRACKET], job)
        self.assertEqual(code, 2, out)
        self.assertRegex(error_of(out), r"supports\[0\] and loads\[%d\] are both on face \d+" % (len(job["loads"]) - 1))

    def test_fixed_faces_by_point(self):
        faces = parafab.inspect_part(WHEEL)["faces"]
        plane = next(f for f in faces if f["type"] == "plane" and abs(f["parameters"]["n"][2]) < 0.5)
        # A point inside the plane face: the middle of its (u, v) box on p + u x + v (n × x).
        o, n, x = plane["parameters"]["p"], plane["parameters"]["n"], plane["parameters"]["x"]
        y = [n[1] * x[2] - n[2] * x[1], n[2] * x[0] - n[0] * x[2], n[0] * x[1] - n[1] * x[0]]
        u0, u1, v0, v1 = plane["uv_bounds"]
        u, v = (u0 + u1) / 2, (v0 + v1) / 2
        point = [o[k] + u * x[k] + v * y[k] for k in range(3)]
        out_dirs = [tempfile.mkdtemp() for _ in range(3)]
        base = {"objective": {"type": "volume"}, "parameters": "auto", "max_iterations": 0, "chart": False}
        names = []
        for d, fixed in zip(out_dirs, [None, [plane["index"]], [{"point": point}]]):
            job = dict(base) if fixed is None else dict(base, fixed_faces=fixed)
            code, h, _ = cli(["optimize", WHEEL], job, ["-o", d])
            self.assertEqual(code, 0, h)
            names.append([p["name"] for p in h["parameters"]])
        self.assertEqual(names[1], names[2])  # the point names the same face as its index
        self.assertLess(len(names[1]), len(names[0]))  # and that face's parameters left the design
        code, out, _ = cli(["optimize", WHEEL], dict(base, fixed_faces=["top"]), ["-o", out_dirs[0]])
        self.assertEqual(code, 2, out)
        self.assertIn('fixed_faces[0] must be a face index, {"face": i} or {"point": [x, y, z]}', error_of(out))


class OutputFolder(unittest.TestCase):
    def test_unwritable_folder_is_an_input_error_before_the_work(self):
        with tempfile.TemporaryDirectory() as d:
            blocker = os.path.join(d, "file")
            open(blocker, "w").close()
            target = os.path.join(blocker, "out")  # under a file: cannot be made
            job = load("simulations", "l_bracket.json")
            code, out, seconds = cli(["simulate", BRACKET], job, ["-o", target])
            self.assertEqual(code, 2, out)
            self.assertIn("output folder " + target + " cannot be written", error_of(out))
            code, out, _ = cli(["optimize", WHEEL], {"objective": {"type": "volume"}}, ["-o", target])
            self.assertEqual(code, 2, out)
            self.assertIn("output folder " + target + " cannot be written", error_of(out))
            code, out, _ = cli(["simulate", BRACKET], job, ["-o", blocker])
            self.assertEqual(code, 2, out)
            self.assertIn("output folder " + blocker + " cannot be written: it is a file", error_of(out))
            self.assertEqual(os.listdir(d), ["file"])  # nothing written beside


class CorruptStep(unittest.TestCase):
    """Two corruptions tests/fuzz/fuzz_inputs.cpp found crashing OCCT 7.6's STEP translator."""

    def inspect(self, text):
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "part.step")
            with open(path, "w") as f:
                f.write(text)
            p = subprocess.run([CLI, "inspect", path], capture_output=True, text=True, timeout=120)
            return p.returncode, json.loads(p.stdout)

    def test_missing_entity_is_refused_by_the_load_check(self):
        with open(os.path.join(SAMPLES, "parts", "cylinder.step")) as f:
            lines = [l for l in f.read().split("\n") if not l.startswith("#87 = ")]  # a LINE a pcurve needs
        code, out = self.inspect("\n".join(lines))
        self.assertEqual(code, 2, out)
        self.assertIn("is not a valid STEP file", error_of(out))
        self.assertIn("Unresolved Reference", error_of(out))

    def test_reference_of_the_wrong_type_is_an_input_error_not_a_crash(self):
        with open(os.path.join(SAMPLES, "parts", "cylinder.step")) as f:
            text = f.read()
        bad = "#86 = DEFINITIONAL_REPRESENTATION('',(#17),#91);"  # a pcurve pointing at a non-curve
        text = text.replace("#86 = DEFINITIONAL_REPRESENTATION('',(#87),#91);", bad)
        self.assertIn(bad, text)
        code, out = self.inspect(text)
        self.assertEqual(code, 2, out)
        self.assertIn("crashes OpenCASCADE's reader", error_of(out))


class Reference(unittest.TestCase):
    def test_json_reference_is_current(self):
        p = subprocess.run([CLI, "reference"], capture_output=True, text=True)
        self.assertEqual(p.returncode, 0, p.stderr)
        with open(os.path.join(ROOT, "resources", "doc", "json-reference.md")) as f:
            committed = f.read()
        self.assertEqual(p.stdout, parafab.json_reference())
        self.assertEqual(committed, p.stdout, "resources/doc/json-reference.md is stale: regenerate it with "
                                              "`parafab reference -o resources/doc/json-reference.md`")
        # Every key the samples use at the top level is documented.
        for sub in ["strips", "rods", "simulations", "optimizations", "sections", "revolution"]:
            for name in os.listdir(os.path.join(SAMPLES, sub)):
                if name.endswith(".json"):
                    for key in load(sub, name):
                        self.assertIn("| `%s` |" % key, committed, (sub, name, key))


if __name__ == "__main__":
    unittest.main()
