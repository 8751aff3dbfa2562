"""`parafab inspect` (thesis §6.2.1, §6.5.1) checked from outside, on the JSON alone.

* The box's NURBS poles, evaluated here as bilinear patches, give points on the box.
* Plane-cylinder relations re-evaluated here from the faces' parameters (Fig. 6.11) vanish,
  and match the residuals the CLI reports.
* Bad input: exit code 2 and a JSON error naming the file and the problem.

Run with /usr/bin/python3; PARAFAB_CLI points at the built `parafab`.
"""
import json
import os
import subprocess
import sys
import tempfile
import unittest

CLI = os.environ.get("PARAFAB_CLI", "build/workbench/entry/parafab")
PARTS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "samples", "parts")


def inspect(*args):
    p = subprocess.run([CLI, "inspect", *args], capture_output=True, text=True, timeout=120)
    return p.returncode, json.loads(p.stdout) if p.stdout.strip() else None


def dot(a, b):
    return sum(x * y for x, y in zip(a, b))


class Inspect(unittest.TestCase):
    def test_box_patches_lie_on_the_box(self):
        code, j = inspect(os.path.join(PARTS, "box.step"))
        self.assertEqual(code, 0)
        self.assertEqual([f["type"] for f in j["faces"]], ["plane"] * 6)
        self.assertAlmostEqual(j["volume"], 24000, places=6)
        for f in j["faces"]:
            nu, nv = f["nurbs"]["count"]
            self.assertEqual(f["nurbs"]["degree"], [1, 1])
            q = f["nurbs"]["poles"]
            # Bilinear patch at its centre, perspective division, then on a box face plane.
            w = sum(q[i][3] for i in range(4)) / 4
            x = [sum(q[i][k] for i in range(4)) / 4 / w for k in range(3)]
            on_face = any(abs(x[k] - b) < 1e-9 for k in range(3) for b in (0, (40, 30, 20)[k]))
            self.assertTrue(on_face and nu == 2 and nv == 2, (x, nu, nv))
        self.assertTrue(all(abs(e["max_angle_deg"] - 90) < 1e-9 for e in j["edges"]))

    def test_bracket_relations_vanish(self):
        code, j = inspect(os.path.join(PARTS, "l_bracket.step"))
        self.assertEqual(code, 0)
        rel = j["relations"]
        self.assertEqual([r["kind"] for r in rel], ["plane-cylinder"] * 4)
        for r in rel:
            pl, cy = (j["faces"][i]["parameters"] for i in r["faces"])
            d = [a - b for a, b in zip(pl["p"], cy["c"])]
            mine = [r["sign"] * dot(d, pl["n"]) - cy["r"], dot(pl["n"], cy["d"])]
            for a, b in zip(mine, r["residuals"]):
                self.assertLess(abs(a), 1e-9)
                self.assertAlmostEqual(a, b, places=12)

    def test_choose_a_solid_and_write_a_file(self):
        path = os.path.join(PARTS, "two_blocks.step")
        code, j = inspect(path)
        self.assertEqual(code, 2)
        self.assertIn("2 solids", j["error"]["message"])
        with tempfile.TemporaryDirectory() as tmp:
            out = os.path.join(tmp, "right.json")
            code, j = inspect(path, "--solid", "1", "-o", out)
            self.assertEqual((code, j), (0, None))
            with open(out) as f:
                right = json.load(f)
        self.assertEqual(right["solid"], {"index": 1, "count": 2, "name": "right_block"})
        code, j = inspect(path, "--solid-name", "left_block")
        self.assertEqual((code, len(j["faces"])), (0, 6))

    def test_bad_input_gives_json_errors(self):
        with tempfile.TemporaryDirectory() as tmp:
            cases = {"empty.step": ("", "is empty"), "notes.step": ("hello\n", "neither STEP"),
                     "broken.step": ("ISO-10303-21;\nHEADER;\nnonsense\n", "not a readable STEP file")}
            for name, (text, expected) in cases.items():
                path = os.path.join(tmp, name)
                with open(path, "w") as f:
                    f.write(text)
                code, j = inspect(path)
                self.assertEqual(code, 2, name)
                self.assertIn(expected, j["error"]["message"])
                self.assertIn(name, j["error"]["message"])
            code, j = inspect(os.path.join(tmp, "missing.step"))
            self.assertEqual(code, 2)
            self.assertIn("not found", j["error"]["message"])


if __name__ == "__main__":
    unittest.main(argv=sys.argv)
